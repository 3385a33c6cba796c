/* refine.c - edge-aware depth refinement backends (see refine.h). */
#include "depth/refine.h"
#include "depth/align.h"
#include "depth/plane.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define REFINE_MAX_RADIUS 16

void depth_refine_defaults(depth_refine_params *p)
{
    p->radius = 9;
    p->sigma_color = 0.08f;
    p->sigma_space = 4.0f;
    p->edge_thresh = 0.03f;
    p->band_radius = 1;
    p->depth_weight = 0.15f;
    p->guide_blur = 0.0f;
}

static const char *const refine_names[DEPTH_REFINE_COUNT] = { "none", "edge-snap", "bilateral" };
_Static_assert(sizeof refine_names / sizeof refine_names[0] == DEPTH_REFINE_COUNT, "one name per refine kind");

depth_refine_kind depth_refine_kind_parse(const char *name)
{
    for (int k = 0; k < DEPTH_REFINE_COUNT; k++)
        if (strcmp(name, refine_names[k]) == 0) return (depth_refine_kind)k;
    return DEPTH_REFINE_COUNT;
}

const char *depth_refine_kind_name(depth_refine_kind kind)
{
    return kind >= 0 && kind < DEPTH_REFINE_COUNT ? refine_names[kind] : "unknown";
}

static void get_params(const void *ctx, depth_refine_params *p)
{
    if (ctx) *p = *(const depth_refine_params *)ctx;
    else depth_refine_defaults(p);
    if (p->radius < 1) p->radius = 1;
    if (p->radius > REFINE_MAX_RADIUS) p->radius = REFINE_MAX_RADIUS;
    if (p->band_radius < 0) p->band_radius = 0;
    if (p->sigma_color <= 0) p->sigma_color = 1e-3f;
    if (p->sigma_space <= 0) p->sigma_space = 1e-3f;
}

static pg_status refine_none(void *ctx, const pg_image *rgb, const float *din, float *dout)
{
    (void)ctx;
    size_t n = (size_t)rgb->width * rgb->height;
    for (size_t k = 0; k < n; k++) dout[k] = depth_valid(din[k]) ? din[k] : 0.0f;
    return PG_OK;
}

static inline float color_dist2(const pg_image *rgb, size_t a, size_t b)
{
    const int C = rgb->channels;
    float s = 0.0f;
    for (int c = 0; c < C; c++) {
        float d = rgb->data[a * C + c] - rgb->data[b * C + c];
        s += d * d;
    }
    return C >= 3 ? s / 3.0f : s;
}

/* Blurred-edge band: large second difference of the (validity-normalised, lightly smoothed)
 * log-depth along any of four directions, dilated. Slopes have zero second difference, so
 * tilted planes are not flagged; steps are, on both sides of their inflection point. */
pg_status depth_refine_band(const depth_refine_params *p, const float *depth, int W, int H, unsigned char *band)
{
    const size_t n = (size_t)W * H;
    float *buf = pg_malloc(sizeof(float) * n * 4, "refine band buffers");
    unsigned char *e8 = pg_malloc(n, "refine band buffers");
    if (!buf || !e8) {
        free(buf);
        free(e8);
        return PG_ERR_NOMEM;
    }
    float *lv = buf, *v = buf + n, *tmp = buf + 2 * n, *ls = buf + 3 * n;
    for (size_t k = 0; k < n; k++) {
        int ok = depth_valid(depth[k]);
        v[k] = ok ? 1.0f : 0.0f;
        lv[k] = ok ? logf(depth[k]) : 0.0f;
    }
    depth_plane_gaussian_blur(lv, W, H, 1.0f, tmp, lv);
    depth_plane_gaussian_blur(v, W, H, 1.0f, tmp, v);
    for (size_t k = 0; k < n; k++) ls[k] = v[k] > 0.5f ? lv[k] / v[k] : NAN;
    static const int dirs[4][2] = { { 2, 0 }, { 0, 2 }, { 2, 2 }, { 2, -2 } };
    #pragma omp parallel for schedule(static)
    for (int y = 0; y < H; y++) {
        for (int x = 0; x < W; x++) {
            size_t k = (size_t)y * W + x;
            float e = 0.0f;
            for (int d = 0; d < 4 && !isnan(ls[k]); d++) {
                int xa = x + dirs[d][0], ya = y + dirs[d][1], xb = x - dirs[d][0], yb = y - dirs[d][1];
                if (xa < 0 || xb < 0 || xa >= W || xb >= W || ya < 0 || yb < 0 || ya >= H || yb >= H) continue;
                float a = ls[(size_t)ya * W + xa], b = ls[(size_t)yb * W + xb];
                if (isnan(a) || isnan(b)) continue;
                float s = fabsf(a + b - 2.0f * ls[k]) * (d >= 2 ? 0.5f : 1.0f); /* diagonals are 2x longer^2 */
                if (s > e) e = s;
            }
            e8[k] = e > p->edge_thresh;
        }
    }
    depth_mask_dilate(e8, W, H, p->band_radius, band);
    for (size_t k = 0; k < n; k++) band[k] = band[k] && depth_valid(depth[k]);
    free(buf);
    free(e8);
    return PG_OK;
}

typedef struct { float v, w; } vw_pair;

/* Stable sort of a[0..m) by v (tmp: m pairs), all v positive and finite: an LSD radix sort on the
 * float bits (which order like the values), a byte per pass, the four histograms from one read
 * and a pass skipped when one bucket holds every key (depths in a window share their top bits).
 * A stable sort's order is unique, so the refined depth is the same to the bit as with any other
 * (glibc's qsort, a merge sort, before); branch-free passes instead of the comparisons a merge
 * sort mispredicts (the sort was most of the refinement in perf). */
static void sort_vw_stable(vw_pair *a, vw_pair *tmp, int m)
{
    if (m < 2) return;
    int count[4][256];
    memset(count, 0, sizeof count);
    for (int i = 0; i < m; i++) {
        uint32_t u;
        memcpy(&u, &a[i].v, sizeof u);
        for (int b = 0; b < 4; b++) count[b][(u >> (8 * b)) & 255]++;
    }
    vw_pair *src = a, *dst = tmp;
    for (int b = 0; b < 4; b++) {
        int *c = count[b], total = 0;
        uint32_t first;
        memcpy(&first, &a[0].v, sizeof first);
        if (c[(first >> (8 * b)) & 255] == m) continue;
        for (int d = 0; d < 256; d++) {
            int n = c[d];
            c[d] = total;
            total += n;
        }
        for (int i = 0; i < m; i++) {
            uint32_t u;
            memcpy(&u, &src[i].v, sizeof u);
            dst[c[(u >> (8 * b)) & 255]++] = src[i];
        }
        vw_pair *t = src; src = dst; dst = t;
    }
    if (src != a) memcpy(a, src, sizeof(vw_pair) * (size_t)m);
}

/* Edge snapping: every band pixel takes the colour- and distance-weighted median of the depths
 * that confident neighbours (valid, outside the band) predict for it. Each neighbour predicts
 * with its own local plane (depth + gradient * offset), so creases and tilted surfaces next to a
 * band keep their slope instead of being flattened to a constant. */
static pg_status refine_edge_snap(void *ctx, const pg_image *rgb, const float *din, float *dout)
{
    depth_refine_params p;
    get_params(ctx, &p);
    const int W = rgb->width, H = rgb->height, R = p.radius;
    const size_t n = (size_t)W * H;
    unsigned char *band = pg_malloc(n, "refine band");
    float *buf = pg_malloc(sizeof(float) * n * 4, "refine gradients");
    if (!band || !buf) {
        free(band);
        free(buf);
        return PG_ERR_NOMEM;
    }
    pg_status st = depth_refine_band(&p, din, W, H, band);
    /* Optionally compute colour weights on a blurred guide (against render noise or video
     * compression; off by default: it did not help on the sample data). */
    pg_image guide = { 0 };
    const pg_image *gp = rgb;
    if (!st && p.guide_blur > 0.0f) {
        st = pg_image_copy(&guide, rgb);
        gp = &guide;
    }
    if (!st && p.guide_blur > 0.0f) {
        float *plane = pg_malloc(sizeof(float) * n * 2, "refine guide");
        if (!plane) st = PG_ERR_NOMEM;
        for (int c = 0; c < guide.channels && !st; c++) {
            for (size_t k = 0; k < n; k++) plane[k] = rgb->data[k * guide.channels + c];
            depth_plane_gaussian_blur(plane, W, H, p.guide_blur, plane + n, plane);
            for (size_t k = 0; k < n; k++) guide.data[k * guide.channels + c] = plane[k];
        }
        free(plane);
    }
    if (st) {
        pg_image_destroy(&guide);
        free(band);
        free(buf);
        return st;
    }
    /* Gradients of the lightly smoothed depth, only where the whole stencil is confident. */
    float *sm = buf, *tmp = buf + n, *gx = buf + 2 * n, *gy = buf + 3 * n;
    for (size_t k = 0; k < n; k++) sm[k] = depth_valid(din[k]) ? din[k] : 0.0f;
    depth_plane_gaussian_blur(sm, W, H, 1.0f, tmp, sm);
    #pragma omp parallel for schedule(static)
    for (int y = 0; y < H; y++) {
        for (int x = 0; x < W; x++) {
            size_t k = (size_t)y * W + x;
            gx[k] = gy[k] = 0.0f;
            int ok = 1;
            for (int d = -2; d <= 2 && ok; d++) {
                int xx = x + d, yy = y + d;
                if (xx < 0 || xx >= W || yy < 0 || yy >= H) { ok = 0; break; }
                size_t a = (size_t)y * W + xx, b = (size_t)yy * W + x;
                ok = !band[a] && !band[b] && depth_valid(din[a]) && depth_valid(din[b]);
            }
            if (!ok) continue;
            gx[k] = (sm[k + 2] - sm[k - 2]) * 0.25f;
            gy[k] = (sm[k + 2 * (size_t)W] - sm[k - 2 * (size_t)W]) * 0.25f;
        }
    }
    float sw[2 * REFINE_MAX_RADIUS + 1];
    for (int i = -R; i <= R; i++) sw[i + R] = expf(-0.5f * i * i / (p.sigma_space * p.sigma_space));
    const float ic = 0.5f / (p.sigma_color * p.sigma_color);
    const int cap = (2 * R + 1) * (2 * R + 1);
    int failed = 0;
    #pragma omp parallel
    {
        vw_pair *pairs = malloc(sizeof(vw_pair) * 2 * (size_t)cap); /* the pairs, then the sort's scratch */
        if (!pairs) {
            #pragma omp critical(refine_nomem)
            failed = 1;
        }
        #pragma omp for schedule(dynamic, 4)
        for (int y = 0; y < H; y++) {
            for (int x = 0; x < W; x++) {
                size_t k = (size_t)y * W + x;
                float d = depth_valid(din[k]) ? din[k] : 0.0f;
                if (!band[k] || !pairs) {
                    dout[k] = d;
                    continue;
                }
                int m = 0;
                float total = 0.0f;
                for (int dy = -R; dy <= R; dy++) {
                    int yy = y + dy;
                    if (yy < 0 || yy >= H) continue;
                    for (int dx = -R; dx <= R; dx++) {
                        int xx = x + dx;
                        if (xx < 0 || xx >= W) continue;
                        size_t q = (size_t)yy * W + xx;
                        if (band[q] || !depth_valid(din[q])) continue;
                        float v = din[q] - gx[q] * dx - gy[q] * dy;
                        if (!depth_valid(v)) continue;
                        float w = sw[dx + R] * sw[dy + R] * expf(-ic * color_dist2(gp, k, q));
                        pairs[m].v = v;
                        pairs[m].w = w;
                        total += w;
                        m++;
                    }
                }
                if (m == 0 || total < 1e-8f) {
                    dout[k] = d;
                    continue;
                }
                sort_vw_stable(pairs, pairs + cap, m);
                /* Depth likelihood: the blurred value itself says which side of the step the pixel
                 * is on (the true edge is where the blur crosses the midpoint), so candidates close
                 * to it gain weight. Its width follows the local step height (10th-90th percentile
                 * of the candidates); near the midpoint both sides tie and colour decides. */
                float range = pairs[(m * 9) / 10].v - pairs[m / 10].v;
                float sd = p.depth_weight * range, floor_sd = 0.005f * d;
                if (sd < floor_sd) sd = floor_sd;
                if (p.depth_weight > 0.0f && sd > 0.0f) {
                    const float id = 0.5f / (sd * sd);
                    total = 0.0f;
                    for (int j = 0; j < m; j++) {
                        float dv = pairs[j].v - d;
                        pairs[j].w *= expf(-id * dv * dv);
                        total += pairs[j].w;
                    }
                }
                if (total < 1e-20f) {
                    dout[k] = d;
                    continue;
                }
                float acc = 0.0f, half = 0.5f * total;
                int j = 0;
                while (j < m - 1 && acc + pairs[j].w < half) acc += pairs[j++].w;
                dout[k] = pairs[j].v;
            }
        }
        free(pairs);
    }
    pg_image_destroy(&guide);
    free(band);
    free(buf);
    if (failed) return pg_fail(PG_ERR_NOMEM, "edge-snap refinement: out of memory");
    return PG_OK;
}

/* Joint bilateral filter over valid pixels (radius from params, spatial sigma radius / 2). */
static pg_status refine_bilateral(void *ctx, const pg_image *rgb, const float *din, float *dout)
{
    depth_refine_params p;
    get_params(ctx, &p);
    const int W = rgb->width, H = rgb->height, R = p.radius < 4 ? p.radius : 4;
    const float ss = 0.5f * R > 1.0f ? 0.5f * R : 1.0f, ic = 0.5f / (p.sigma_color * p.sigma_color);
    #pragma omp parallel for schedule(static)
    for (int y = 0; y < H; y++) {
        for (int x = 0; x < W; x++) {
            size_t k = (size_t)y * W + x;
            if (!depth_valid(din[k])) {
                dout[k] = 0.0f;
                continue;
            }
            float acc = 0.0f, tw = 0.0f;
            for (int dy = -R; dy <= R; dy++) {
                int yy = y + dy;
                if (yy < 0 || yy >= H) continue;
                for (int dx = -R; dx <= R; dx++) {
                    int xx = x + dx;
                    if (xx < 0 || xx >= W) continue;
                    size_t q = (size_t)yy * W + xx;
                    if (!depth_valid(din[q])) continue;
                    float w = expf(-0.5f * (dx * dx + dy * dy) / (ss * ss) - ic * color_dist2(rgb, k, q));
                    acc += w * din[q];
                    tw += w;
                }
            }
            dout[k] = acc / tw;
        }
    }
    return PG_OK;
}

depth_refine_backend depth_refine_backend_get(depth_refine_kind kind, const depth_refine_params *params)
{
    depth_refine_backend be = { refine_names[DEPTH_REFINE_NONE], refine_none, NULL };
    if (kind == DEPTH_REFINE_EDGE_SNAP) be = (depth_refine_backend){ refine_names[kind], refine_edge_snap, (void *)params };
    if (kind == DEPTH_REFINE_BILATERAL) be = (depth_refine_backend){ refine_names[kind], refine_bilateral, (void *)params };
    return be;
}

pg_status depth_refine_run(const depth_refine_backend *be, const pg_image *rgb, const float *depth_in, float *depth_out)
{
    if (!be || !be->refine) return pg_fail(PG_ERR_ARG, "depth refinement: no backend");
    if (depth_in == depth_out) return pg_fail(PG_ERR_ARG, "depth refinement: input and output must differ");
    return be->refine(be->ctx, rgb, depth_in, depth_out);
}
