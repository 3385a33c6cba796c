/* mask.c - proxy validity masks from a depth-mesh coverage test (see mask.h). */
#include "proxy/mask.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/mathx.h"

proxy_mask_options proxy_default_mask_options(void)
{
    proxy_mask_options o = { 0.5f, 0.04f, 2.5f, 0.02f, 0.5f };
    return o;
}

typedef struct {
    float x, y, z; /* target pixel coordinates (continuous) and camera depth */
    int ok;
    int margin;    /* the source pixel lies in the outpainted margin */
    const float *rgb; /* the source pixel's colour (NULL when colours are not rendered) */
} proj_vertex;

/* min and max of finite coordinates: fminf/fmaxf are library calls here (their NaN rules keep the
 * compiler from inlining them), a tenth of the proxies stage's time in these two loops */
static inline float min2(float a, float b) { return a < b ? a : b; }
static inline float max2(float a, float b) { return a > b ? a : b; }

static int edge_ok(const proj_vertex *a, const proj_vertex *b, float da, float db, const proxy_mask_options *o)
{
    float lo = min2(da, db), hi = max2(da, db);
    if (hi - lo > o->edge_rel * lo) return 0;
    float dx = a->x - b->x, dy = a->y - b->y;
    return dx * dx + dy * dy <= o->stretch_max * o->stretch_max;
}

/* Scan-converts one triangle into the z-buffer: pixel centres inside (top-left-inclusive enough for
 * a coverage test), depth interpolated as 1/z, which is linear in screen space. margin (may be
 * NULL) records whether the nearest triangle touches the outpainted margin. */
static void raster_triangle(const proj_vertex *a, const proj_vertex *b, const proj_vertex *c, int W, int H,
                            float *zbuf, unsigned char *margin, float *rgb)
{
    const unsigned char from_margin = (unsigned char)(a->margin || b->margin || c->margin);
    float minx = min2(a->x, min2(b->x, c->x)), maxx = max2(a->x, max2(b->x, c->x));
    float miny = min2(a->y, min2(b->y, c->y)), maxy = max2(a->y, max2(b->y, c->y));
    int x0 = (int)ceilf(minx - 0.5f), x1 = (int)floorf(maxx - 0.5f);
    int y0 = (int)ceilf(miny - 0.5f), y1 = (int)floorf(maxy - 0.5f);
    if (x0 < 0) x0 = 0;
    if (y0 < 0) y0 = 0;
    if (x1 > W - 1) x1 = W - 1;
    if (y1 > H - 1) y1 = H - 1;
    if (x0 > x1 || y0 > y1) return;
    float area = (b->x - a->x) * (c->y - a->y) - (b->y - a->y) * (c->x - a->x);
    if (fabsf(area) < 1e-12f) return;
    float inv_area = 1.0f / area;
    float iza = 1.0f / a->z, izb = 1.0f / b->z, izc = 1.0f / c->z;
    const float eps = 1e-4f; /* shared edges: both neighbours may cover, which is harmless here */
    for (int y = y0; y <= y1; y++) {
        float py = y + 0.5f;
        for (int x = x0; x <= x1; x++) {
            float px = x + 0.5f;
            float w0 = ((b->x - px) * (c->y - py) - (b->y - py) * (c->x - px)) * inv_area;
            float w1 = ((c->x - px) * (a->y - py) - (c->y - py) * (a->x - px)) * inv_area;
            float w2 = 1.0f - w0 - w1;
            if (w0 < -eps || w1 < -eps || w2 < -eps) continue;
            float z = 1.0f / (w0 * iza + w1 * izb + w2 * izc);
            float *zb = &zbuf[(size_t)y * W + x];
            if (*zb == 0 || z < *zb) {
                *zb = z;
                if (margin) margin[(size_t)y * W + x] = from_margin;
                if (rgb) {
                    /* perspective-correct: attributes over z are linear on screen */
                    float pa = w0 * iza * z, pb = w1 * izb * z, pc = w2 * izc * z;
                    float *o = rgb + ((size_t)y * W + x) * 3;
                    for (int k = 0; k < 3; k++) o[k] = pa * a->rgb[k] + pb * b->rgb[k] + pc * c->rgb[k];
                }
            }
        }
    }
}

pg_status proxy_mesh_depth(const pg_camera *src, const float *depth, int pad, const pg_camera *dst,
                           const proxy_mask_options *opt, float *zmesh, unsigned char *margin, const float *rgb,
                           float *rgb_out)
{
    int W = src->width, H = src->height, W2 = dst->width, H2 = dst->height;
    memset(zmesh, 0, (size_t)W2 * H2 * sizeof(float));
    if (margin) memset(margin, 0, (size_t)W2 * H2);
    if (rgb_out) memset(rgb_out, 0, (size_t)W2 * H2 * 3 * sizeof(float));
    /* Two rows of projected vertices at a time keep the memory at O(W). */
    proj_vertex *rows = pg_malloc((size_t)2 * W * sizeof(proj_vertex), "mesh vertex rows");
    if (!rows) return PG_ERR_NOMEM;
    for (int v = 0; v < H; v++) {
        proj_vertex *cur = rows + (size_t)(v & 1) * W, *prev = rows + (size_t)((v + 1) & 1) * W;
        for (int u = 0; u < W; u++) {
            float d = depth[(size_t)v * W + u];
            proj_vertex *p = &cur[u];
            p->ok = 0;
            if (!(isfinite(d) && d > 0)) continue;
            float X[3], uv[2];
            pg_camera_unproject(src, u + 0.5f, v + 0.5f, d, X);
            float z = pg_camera_project(dst, X, uv);
            if (!(z > 1e-6f)) continue;
            p->x = uv[0];
            p->y = uv[1];
            p->z = z;
            p->ok = 1;
            p->margin = u < pad || v < pad || u >= W - pad || v >= H - pad;
            p->rgb = rgb ? rgb + ((size_t)v * W + u) * 3 : NULL;
        }
        if (v == 0) continue;
        const float *drow = depth + (size_t)v * W, *dprev = depth + (size_t)(v - 1) * W;
        for (int u = 0; u + 1 < W; u++) {
            /* quad corners: a=(u,v-1) b=(u+1,v-1) c=(u,v) d=(u+1,v) */
            const proj_vertex *a = &prev[u], *b = &prev[u + 1], *c = &cur[u], *d = &cur[u + 1];
            float da = dprev[u], db = dprev[u + 1], dc = drow[u], dd = drow[u + 1];
            int ab = a->ok && b->ok && edge_ok(a, b, da, db, opt);
            int ac = a->ok && c->ok && edge_ok(a, c, da, dc, opt);
            int bd = b->ok && d->ok && edge_ok(b, d, db, dd, opt);
            int cd = c->ok && d->ok && edge_ok(c, d, dc, dd, opt);
            int bc = b->ok && c->ok && edge_ok(b, c, db, dc, opt);
            int ad = a->ok && d->ok && edge_ok(a, d, da, dd, opt);
            /* Split along whichever diagonal is intact, so a corner behind an edge does not kill the
             * whole quad. */
            if (bc) {
                if (ab && ac) raster_triangle(a, b, c, W2, H2, zmesh, margin, rgb_out);
                if (bd && cd) raster_triangle(b, d, c, W2, H2, zmesh, margin, rgb_out);
            } else if (ad) {
                if (ab && bd) raster_triangle(a, b, d, W2, H2, zmesh, margin, rgb_out);
                if (ac && cd) raster_triangle(a, d, c, W2, H2, zmesh, margin, rgb_out);
            }
        }
    }
    free(rows);
    return PG_OK;
}

static unsigned char margin_value(const proxy_mask_options *opt)
{
    return (unsigned char)lroundf(clampf(opt->margin_weight, 0, 1) * PROXY_MASK_REAL);
}

float proxy_mask_mesh(int width, int height, const float *zmesh, const unsigned char *margin,
                      const proxy_mask_options *opt, unsigned char *mask)
{
    size_t n = (size_t)width * height, valid = 0;
    const unsigned char mv = margin_value(opt);
    for (size_t i = 0; i < n; i++) {
        int ok = zmesh[i] > 0;
        if (mask) mask[i] = !ok ? 0 : (margin && margin[i]) ? mv : PROXY_MASK_REAL;
        valid += ok;
    }
    return n ? (float)valid / n : 0;
}

float proxy_mask_combine(int width, int height, const float *alpha, const float *depth_norm, const float *zmesh,
                         const unsigned char *margin, const proxy_mask_options *opt, unsigned char *mask)
{
    size_t n = (size_t)width * height, valid = 0;
    const unsigned char mv = margin_value(opt);
    for (size_t i = 0; i < n; i++) {
        int ok = alpha[i] > opt->alpha_min && zmesh[i] > 0 &&
                 fabsf(depth_norm[i] - zmesh[i]) <= opt->depth_tol * zmesh[i];
        mask[i] = !ok ? 0 : (margin && margin[i]) ? mv : PROXY_MASK_REAL;
        valid += ok;
    }
    return n ? (float)valid / n : 0;
}
