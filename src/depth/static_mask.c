/* static_mask.c - static masks and dynamic probability from flow, colour and occlusion cues. */
#include "depth/static_mask.h"
#include "depth/plane.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void depth_static_defaults(depth_static_params *p)
{
    p->flow_thresh = 0.6f;
    p->color_thresh = 0.05f;
    p->color_blur = 1.0f;
    p->texture_thresh = 0.004f; /* Panoptic's gym floor ~0.0017 (90 % below 0.0035), textured renders >= 0.004 at the 5th percentile */
    p->open_radius = 1;
    p->close_radius = 2;
    p->dilate_radius = 0;
}

/* Smooth 0 -> 1 ramp with value 0.5 at t, 0 below t/2 and 1 above 3t/2. */
static inline float soft_step(float v, float t)
{
    float s = (v - 0.5f * t) / t;
    if (s <= 0.0f) return 0.0f;
    if (s >= 1.0f) return 1.0f;
    return s * s * (3.0f - 2.0f * s);
}

/* How observable motion is at each pixel: the mean gradient magnitude of the (blurred) grey
 * frame over a small neighbourhood. Where it is near the noise level the flow is unobservable
 * (the aperture problem) and what the solver puts there is its smoothness term dragging a
 * passing object's motion across the surface; the forward-backward check fails there for the
 * same reason. gray is overwritten with the map; gx, gy are (H,W) scratch. */
static void texture_map(float *gray, int W, int H, float *gx, float *gy)
{
    const size_t n = (size_t)W * H;
    depth_plane_gradient(gray, W, H, gx, gy);
    for (size_t k = 0; k < n; k++) gx[k] = sqrtf(gx[k] * gx[k] + gy[k] * gy[k]);
    depth_plane_gaussian_blur(gx, W, H, 1.5f, gy, gray);
}

static int mask_channels(const pg_image *img) { return img->channels >= 3 ? 3 : 1; }

pg_status depth_mask_reference_create(const depth_static_params *p, const pg_image *img_ref,
                                        depth_mask_reference *ref)
{
    memset(ref, 0, sizeof *ref);
    const int W = img_ref->width, H = img_ref->height, C = mask_channels(img_ref);
    const size_t n = (size_t)W * H;
    const int gate = p->texture_thresh > 0.0f;
    float *blurred = pg_malloc(sizeof(float) * n * C, "static mask reference");
    float *work = pg_malloc(sizeof(float) * n * 3, "static mask reference");
    float *texture = gate ? pg_malloc(sizeof(float) * n, "static mask reference") : NULL;
    if (!blurred || !work || (gate && !texture)) {
        free(blurred);
        free(work);
        free(texture);
        return PG_ERR_NOMEM;
    }
    float *mean = work, *tmp = work + n, *tmp2 = work + 2 * n;
    memset(mean, 0, sizeof(float) * n);
    for (int c = 0; c < C; c++) {
        float *plane = blurred + (size_t)c * n;
        for (size_t k = 0; k < n; k++) plane[k] = img_ref->data[k * img_ref->channels + c];
        depth_plane_gaussian_blur(plane, W, H, p->color_blur, tmp, plane);
        for (size_t k = 0; k < n; k++) mean[k] += plane[k] / (float)C;
    }
    if (gate) {
        texture_map(mean, W, H, tmp, tmp2);
        memcpy(texture, mean, sizeof(float) * n);
    }
    free(work);
    *ref = (depth_mask_reference){W, H, C, blurred, texture};
    return PG_OK;
}

void depth_mask_reference_free(depth_mask_reference *ref)
{
    free(ref->blurred);
    free(ref->texture);
    memset(ref, 0, sizeof *ref);
}

pg_status depth_static_mask(const depth_static_params *p, const pg_image *img_i, const depth_mask_reference *ref,
                            const float *flow_i, const float *conf_i, float *prob, unsigned char *mask)
{
    const int W = img_i->width, H = img_i->height, C = mask_channels(img_i);
    if (ref->width != W || ref->height != H || ref->channels != C)
        return pg_fail(PG_ERR_SIZE, "static mask: frame is %d x %d x %d, the reference %d x %d x %d", W, H, C,
                       ref->width, ref->height, ref->channels);
    const int gate = p->texture_thresh > 0.0f;
    if (gate && !ref->texture)
        return pg_fail(PG_ERR_ARG, "static mask: the reference was made without the texture gate");
    const size_t n = (size_t)W * H;
    float *buf = pg_malloc(sizeof(float) * n * 4, "static mask buffers");
    unsigned char *m8 = pg_malloc(n * 2, "static mask buffers");
    if (!buf || !m8) {
        free(buf);
        free(m8);
        return PG_ERR_NOMEM;
    }
    float *diff = buf, *tex_i = buf + n, *a = buf + 2 * n, *b = buf + 3 * n;
    /* Mean absolute colour difference of the blurred frames (blur tames noise and compression). */
    memset(diff, 0, sizeof(float) * n);
    memset(tex_i, 0, sizeof(float) * n);
    for (int c = 0; c < C; c++) {
        const float *r = ref->blurred + (size_t)c * n;
        for (size_t k = 0; k < n; k++) a[k] = img_i->data[k * img_i->channels + c];
        depth_plane_gaussian_blur(a, W, H, p->color_blur, b, a);
        for (size_t k = 0; k < n; k++) {
            diff[k] += fabsf(a[k] - r[k]) / (float)C;
            tex_i[k] += a[k] / (float)C;
        }
    }
    if (gate) texture_map(tex_i, W, H, a, b); /* the blurred channels are done with */
    const float *tex_ref = ref->texture;
    unsigned char *dyn = m8, *tmp8 = m8 + n;
    for (size_t k = 0; k < n; k++) {
        float mag = hypotf(flow_i[2 * k], flow_i[2 * k + 1]);
        float pf = soft_step(mag, p->flow_thresh);
        float pc = soft_step(diff[k], p->color_thresh);
        float po = conf_i ? 1.0f - conf_i[k] : 0.0f;
        float pm = 1.0f - (1.0f - pf) * (1.0f - po);
        if (gate) pm *= soft_step(tex_i[k] > tex_ref[k] ? tex_i[k] : tex_ref[k], p->texture_thresh);
        float pd = 1.0f - (1.0f - pm) * (1.0f - pc);
        if (!(pd >= 0.0f)) pd = 1.0f; /* NaN flow from a plugged-in backend counts as dynamic */
        if (prob) prob[k] = pd;
        dyn[k] = pd >= 0.5f;
    }
    /* Opening removes isolated dynamic specks, closing fills holes inside moving objects. */
    if (p->open_radius > 0) {
        depth_mask_erode(dyn, W, H, p->open_radius, tmp8);
        depth_mask_dilate(tmp8, W, H, p->open_radius, dyn);
    }
    if (p->close_radius > 0) {
        depth_mask_dilate(dyn, W, H, p->close_radius, tmp8);
        depth_mask_erode(tmp8, W, H, p->close_radius, dyn);
    }
    if (p->dilate_radius > 0) {
        depth_mask_dilate(dyn, W, H, p->dilate_radius, tmp8);
        memcpy(dyn, tmp8, n);
    }
    for (size_t k = 0; k < n; k++) mask[k] = !dyn[k];
    free(buf);
    free(m8);
    return PG_OK;
}

double depth_mask_iou(const unsigned char *a, const unsigned char *b, size_t n)
{
    size_t inter = 0, uni = 0;
    for (size_t k = 0; k < n; k++) {
        int x = a[k] != 0, y = b[k] != 0;
        inter += x && y;
        uni += x || y;
    }
    return uni ? (double)inter / uni : 1.0;
}
