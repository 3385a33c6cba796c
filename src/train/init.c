/* init.c - initial canonical Gaussians from the views' depth (or the frustum when there is none).
 *
 * Every frame's depth is back-projected (static pixels only from frame 0), then voxel-
 * downsampled so the moving objects are covered at every position they visit. A pixel is
 * dynamic when its depth or colour changes over the video; voxels holding a dynamic point
 * get a dynamic flag, the others are static and are never sent through the network.
 */
#include "train/train_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/mathx.h"

#define SH_C0 0.28209479177387814f

typedef struct {
    float *xyz;   /* (n, 3) */
    float *rgb;   /* (n, 3) */
    uint8_t *dyn; /* (n) */
    size_t n, cap;
} point_list;

static pg_status points_push(point_list *p, const float x[3], const float c[3], int dyn)
{
    if (p->n == p->cap) {
        size_t nc = p->cap ? p->cap * 2 : 65536;
        float *a = realloc(p->xyz, nc * 3 * sizeof(float));
        if (!a) return pg_fail(PG_ERR_NOMEM, "init: out of memory for points");
        p->xyz = a;
        float *b = realloc(p->rgb, nc * 3 * sizeof(float));
        if (!b) return pg_fail(PG_ERR_NOMEM, "init: out of memory for points");
        p->rgb = b;
        uint8_t *d = realloc(p->dyn, nc);
        if (!d) return pg_fail(PG_ERR_NOMEM, "init: out of memory for points");
        p->dyn = d;
        p->cap = nc;
    }
    memcpy(p->xyz + 3 * p->n, x, 3 * sizeof(float));
    memcpy(p->rgb + 3 * p->n, c, 3 * sizeof(float));
    p->dyn[p->n] = (uint8_t)dyn;
    p->n++;
    return PG_OK;
}

/* Back-projects the depth of view vi (every `stride` pixels). */
static pg_status points_from_depth(const train_set *ts, int vi, int stride, point_list *pts)
{
    const train_view *v = &ts->views[vi];
    int W = ts->width, H = ts->height, F = ts->frames;
    size_t px = (size_t)W * H;
    for (int y = stride / 2; y < H; y += stride)
        for (int x = stride / 2; x < W; x += stride) {
            size_t p = (size_t)y * W + x;
            /* dynamic: depth or colour differs from frame 0 somewhere in the video */
            int dyn = 0;
            float d0 = v->depth[p];
            const uint8_t *c0 = v->rgb + p * 3;
            for (int f = 1; f < F && !dyn; f++) {
                float df = v->depth[(size_t)f * px + p];
                const uint8_t *cf = v->rgb + ((size_t)f * px + p) * 3;
                int dc = abs(cf[0] - c0[0]) + abs(cf[1] - c0[1]) + abs(cf[2] - c0[2]);
                if ((d0 > 0) != (df > 0) || (d0 > 0 && fabsf(df - d0) > 0.03f * d0) || dc > 3 * 25) dyn = 1;
            }
            for (int f = 0; f < (dyn ? F : 1); f++) {
                size_t q = (size_t)f * px + p;
                float d = v->depth[q];
                if (!(d > 0) || (v->mask && !v->mask[q])) continue;
                float X[3], c[3];
                pg_camera_unproject(&v->cam, x + 0.5f, y + 0.5f, d, X);
                for (int k = 0; k < 3; k++) c[k] = v->rgb[q * 3 + k] / 255.0f;
                PG_TRY(points_push(pts, X, c, dyn));
            }
        }
    return PG_OK;
}

/* Random points in the frusta of the training views between near and far (uniform in
 * inverse depth), coloured from frame 0; all dynamic since nothing is known. */
static pg_status points_from_frustum(train_session *s, point_list *pts, int n)
{
    const train_set *ts = s->ts;
    float zn = ts->near_z > 0 ? ts->near_z : 0.5f, zf = ts->far_z > zn ? ts->far_z : zn * 20;
    int nv = 0;
    for (int i = 0; i < ts->num_views; i++) nv += ts->views[i].role != TRAIN_ROLE_TEST;
    for (int k = 0; k < n; k++) {
        int pick = (int)pg_rng_below(&s->rng, (uint32_t)nv), vi = 0;
        for (int i = 0; i < ts->num_views; i++)
            if (ts->views[i].role != TRAIN_ROLE_TEST && pick-- == 0) {
                vi = i;
                break;
            }
        const train_view *v = &ts->views[vi];
        float u = (float)pg_rng_uniform(&s->rng) * ts->width, w = (float)pg_rng_uniform(&s->rng) * ts->height;
        float inv = 1.0f / zf + (float)pg_rng_uniform(&s->rng) * (1.0f / zn - 1.0f / zf);
        float X[3], c[3];
        pg_camera_unproject(&v->cam, u, w, 1.0f / inv, X);
        size_t q = (size_t)(int)w * ts->width + (int)u;
        for (int j = 0; j < 3; j++) c[j] = v->rgb[q * 3 + j] / 255.0f;
        PG_TRY(points_push(pts, X, c, 1));
    }
    return PG_OK;
}

/* Views without depth (e.g. the other real cameras of a dataset) may see parts of the scene no
 * depth map covers. Blocks of their frame 0 that no point projects into get random points along
 * the pixel rays between near and far (uniform in inverse depth), coloured from the pixel;
 * multi-view training sorts out their depth. Dynamic when the pixel's colour changes. */
static pg_status points_fill_uncovered(train_session *s, point_list *pts)
{
    const train_set *ts = s->ts;
    const int B = 8, per_block = 6;
    int W = ts->width, H = ts->height, bw = (W + B - 1) / B, bh = (H + B - 1) / B;
    size_t px = (size_t)W * H;
    float zn = ts->near_z > 0 ? ts->near_z : 0.5f, zf = ts->far_z > zn ? ts->far_z : zn * 20;
    uint8_t *cov = pg_malloc((size_t)bw * bh, "init coverage");
    if (!cov) return PG_ERR_NOMEM;
    size_t n0 = pts->n;
    pg_status st = PG_OK;
    for (int vi = 0; vi < ts->num_views && !st; vi++) {
        const train_view *v = &ts->views[vi];
        if (v->role == TRAIN_ROLE_TEST || v->depth) continue;
        memset(cov, 0, (size_t)bw * bh);
        for (size_t i = 0; i < n0; i++) {
            float uv[2];
            if (pg_camera_project(&v->cam, pts->xyz + 3 * i, uv) <= 0) continue;
            int bx = (int)floorf(uv[0] / B), by = (int)floorf(uv[1] / B);
            if (bx >= 0 && bx < bw && by >= 0 && by < bh) cov[by * bw + bx] = 1;
        }
        for (int by = 0; by < bh && !st; by++)
            for (int bx = 0; bx < bw && !st; bx++) {
                if (cov[by * bw + bx]) continue;
                for (int k = 0; k < per_block && !st; k++) {
                    float u = (bx + (float)pg_rng_uniform(&s->rng)) * B, w = (by + (float)pg_rng_uniform(&s->rng)) * B;
                    if (u >= W) u = W - 0.5f;
                    if (w >= H) w = H - 0.5f;
                    float inv = 1.0f / zf + (float)pg_rng_uniform(&s->rng) * (1.0f / zn - 1.0f / zf);
                    float X[3], c[3];
                    pg_camera_unproject(&v->cam, u, w, 1.0f / inv, X);
                    size_t q = (size_t)(int)w * W + (int)u;
                    for (int j = 0; j < 3; j++) c[j] = v->rgb[q * 3 + j] / 255.0f;
                    int dyn = 0;
                    for (int f = 1; f < ts->frames && !dyn; f++) {
                        const uint8_t *cf = v->rgb + ((size_t)f * px + q) * 3, *c0 = v->rgb + q * 3;
                        dyn = abs(cf[0] - c0[0]) + abs(cf[1] - c0[1]) + abs(cf[2] - c0[2]) > 3 * 25;
                    }
                    st = points_push(pts, X, c, dyn);
                }
            }
    }
    free(cov);
    return st;
}

static uint64_t voxel_key(const float x[3], const float lo[3], float vox)
{
    uint64_t k = 0;
    for (int a = 0; a < 3; a++) {
        long q = (long)floorf((x[a] - lo[a]) / vox);
        if (q < 0) q = 0;
        if (q > 0x1FFFFF) q = 0x1FFFFF;
        k = (k << 21) | (uint64_t)q;
    }
    return k;
}

static uint64_t hash64(uint64_t x)
{
    x ^= x >> 33;
    x *= 0xff51afd7ed558ccdULL;
    x ^= x >> 33;
    x *= 0xc4ceb9fe1a85ec53ULL;
    x ^= x >> 33;
    return x;
}

/* Fills slot[] (one per point) with the hash-table slot of its voxel; returns unique count. */
static size_t voxel_assign(const point_list *p, const float lo[3], float vox, uint64_t *keys, uint8_t *used,
                           size_t tsize, uint32_t *slot)
{
    memset(used, 0, tsize);
    size_t uniq = 0;
    for (size_t i = 0; i < p->n; i++) {
        uint64_t k = voxel_key(p->xyz + 3 * i, lo, vox);
        size_t h = hash64(k) & (tsize - 1);
        while (used[h] && keys[h] != k) h = (h + 1) & (tsize - 1);
        if (!used[h]) {
            used[h] = 1;
            keys[h] = k;
            uniq++;
        }
        slot[i] = (uint32_t)h;
    }
    return uniq;
}

pg_status train_init_gaussians(train_session *s)
{
    const train_set *ts = s->ts;
    point_list pts = {0};
    pg_status st = PG_OK;
    uint64_t *keys = NULL;
    uint8_t *used = NULL;
    uint32_t *slot = NULL;
    double *acc = NULL;
    int target = s->cfg.init_points < s->cfg.max_gaussians ? s->cfg.init_points : s->cfg.max_gaussians;
    if (target < 16) target = 16;

    /* budget: at most ~3M candidate points */
    size_t cand = 0;
    for (int i = 0; i < ts->num_views; i++)
        if (ts->views[i].depth && ts->views[i].role != TRAIN_ROLE_TEST)
            cand += (size_t)ts->width * ts->height * (size_t)ts->frames;
    int stride = 1;
    while (cand / ((size_t)stride * stride) > 3000000) stride++;
    for (int i = 0; i < ts->num_views && !st; i++)
        if (ts->views[i].depth && ts->views[i].role != TRAIN_ROLE_TEST) st = points_from_depth(ts, i, stride, &pts);
    if (!st && pts.n < (size_t)target / 4) st = points_from_frustum(s, &pts, target - (int)pts.n);
    if (!st && pts.n > 0) st = points_fill_uncovered(s, &pts);
    if (st) goto done;
    if (pts.n == 0) {
        st = pg_fail(PG_ERR_ARG, "init: no points to start from");
        goto done;
    }

    float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
    double cen[3] = {0, 0, 0};
    for (size_t i = 0; i < pts.n; i++)
        for (int a = 0; a < 3; a++) {
            float x = pts.xyz[3 * i + a];
            lo[a] = fminf(lo[a], x);
            hi[a] = fmaxf(hi[a], x);
            cen[a] += x;
        }
    double r2 = 0;
    for (int a = 0; a < 3; a++) cen[a] /= (double)pts.n;
    for (size_t i = 0; i < pts.n; i++)
        for (int a = 0; a < 3; a++) {
            double dx = pts.xyz[3 * i + a] - cen[a];
            r2 += dx * dx;
        }
    for (int a = 0; a < 3; a++) s->center[a] = (float)cen[a];
    s->extent = ts->has_scene && ts->radius > 0 ? ts->radius : (float)sqrt(r2 / (double)pts.n) * 1.1f;
    if (!(s->extent > 0)) s->extent = 1.0f;

    size_t tsize = 1;
    while (tsize < pts.n * 2) tsize <<= 1;
    keys = pg_malloc(tsize * sizeof(uint64_t), "init voxel keys");
    used = pg_malloc(tsize, "init voxel table");
    slot = pg_malloc(pts.n * sizeof(uint32_t), "init voxel slots");
    if (!keys || !used || !slot) {
        st = PG_ERR_NOMEM;
        goto done;
    }
    float diag = 0;
    for (int a = 0; a < 3; a++) diag += (hi[a] - lo[a]) * (hi[a] - lo[a]);
    float vox = sqrtf(diag) / sqrtf((float)target) + 1e-6f;
    size_t uniq = 0;
    for (int iter = 0; iter < 12; iter++) {
        uniq = voxel_assign(&pts, lo, vox, keys, used, tsize, slot);
        float ratio = (float)uniq / (float)target;
        if (ratio > 0.85f && ratio <= 1.0f) break;
        vox *= ratio > 1 ? sqrtf(ratio) * 1.02f : fmaxf(sqrtf(ratio), 0.5f);
        if (iter == 11 && uniq > (size_t)target) {
            vox *= 1.3f;
            uniq = voxel_assign(&pts, lo, vox, keys, used, tsize, slot);
        }
    }
    if (uniq > (size_t)s->cfg.max_gaussians) {
        st = pg_fail(PG_ERR_INTERNAL, "init: voxel downsampling kept %zu points", uniq);
        goto done;
    }

    /* accumulate per slot: x y z r g b count dyn */
    acc = pg_calloc(tsize * 8, sizeof(double), "init voxel sums");
    if (!acc) {
        st = PG_ERR_NOMEM;
        goto done;
    }
    for (size_t i = 0; i < pts.n; i++) {
        double *a = acc + (size_t)slot[i] * 8;
        for (int k = 0; k < 3; k++) {
            a[k] += pts.xyz[3 * i + k];
            a[3 + k] += pts.rgb[3 * i + k];
        }
        a[6] += 1;
        if (pts.dyn[i]) a[7] = 1;
    }
    if ((st = train_resize_all(s, (int)uniq))) goto done;
    int n = 0, ndyn = 0;
    float log_s = logf(0.6f * vox);
    float opacity_logit = logf(0.3f / 0.7f);
    for (size_t h = 0; h < tsize; h++) {
        if (!used[h]) continue;
        const double *a = acc + h * 8;
        for (int k = 0; k < 3; k++) {
            s->g.means[3 * n + k] = (float)(a[k] / a[6]);
            s->g.log_scales[3 * n + k] = log_s;
            s->g.sh[(size_t)n * PG_SH_COEFFS * 3 + k] = (float)((a[3 + k] / a[6] - 0.5) / SH_C0);
        }
        s->g.quats[4 * n] = 1.0f;
        s->g.opacity[n] = opacity_logit;
        s->is_static[n] = a[7] == 0;
        ndyn += a[7] != 0;
        n++;
    }
    s->g.sh_degree = 0;
    (void)ndyn;
done:
    free(pts.xyz);
    free(pts.rgb);
    free(pts.dyn);
    free(keys);
    free(used);
    free(slot);
    free(acc);
    return st;
}
