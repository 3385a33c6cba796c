/* init.c - initial canonical Gaussians from the views' depth (or the frustum when there is none).
 *
 * Moving pixels come from colour alone (off the pixel's temporal median, depth/moving_mask.h):
 * monocular depth flickers everywhere, so a depth test would call the whole scene dynamic.
 * A pixel that never moves is back-projected once; a pixel that moves at some frames gives a
 * DYNAMIC point at each of those frames (the object where it is then) and one static point
 * from a frame where it shows the background. The two sets are voxel-downsampled apart, the
 * dynamic one to its own share of the budget, so the moving objects get Gaussians at every
 * place they visit however small they are in the frame. Dynamic points make movable Gaussians
 * (sent through the network); static ones never are.
 */
#include "train/train_internal.h"
#include "splat/sh.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/mathx.h"
#include "depth/moving_mask.h"
#include "proxy/outpaint.h"


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

/* Colour threshold for the trainer's moving pixels: a little below the evaluation's 0.12 so
 * faint parts of a mover (shadows, soft edges) go to the network too, dilated 3 px. */
#define INIT_MOVING_THRESH 0.08f
#define INIT_MOVING_DILATE 3

/* The view's static background: each pixel's colour and depth at the first frame it is not
 * moving (depth 0 where it always moves or never has valid depth). */
static void background_image(const train_view *v, int F, size_t px, const uint8_t *moving, float *bg_rgb,
                             float *bg_depth)
{
    for (size_t p = 0; p < px; p++) {
        bg_depth[p] = 0;
        for (int k = 0; k < 3; k++) bg_rgb[3 * p + k] = 0;
        for (int f = 0; f < F; f++) {
            size_t q = (size_t)f * px + p;
            float d = train_view_depth(v, q);
            if (moving[q] || !(d > 0) || (v->mask && !v->mask[q])) continue;
            for (int k = 0; k < 3; k++) bg_rgb[3 * p + k] = v->rgb[q * 3 + k] / 255.0f;
            bg_depth[p] = d;
            break;
        }
    }
}

/* Back-projects the depth of view vi (every `stride` pixels): static pixels once, moving ones
 * at each frame they move (dynamic) plus once as background (static). Proxy views give static
 * points only, from a frame where the pixel is not moving: their colours and masks change from
 * frame to frame where a disocclusion moves, and the real view already places the movers.
 * bg_rgb (H,W,3) / bg_depth (H,W), when not NULL, receive the view's static background. */
static pg_status points_from_depth(const train_set *ts, int vi, int stride, point_list *pts, float *bg_rgb,
                                   float *bg_depth)
{
    const train_view *v = &ts->views[vi];
    int W = ts->width, H = ts->height, F = ts->frames;
    int real = v->role == IO_ROLE_REAL;
    size_t px = (size_t)W * H;
    uint8_t *moving = pg_malloc((size_t)F * px, "init moving masks");
    if (!moving) return PG_ERR_NOMEM;
    pg_status st = depth_moving_masks(v->rgb, F, W, H, INIT_MOVING_THRESH, INIT_MOVING_DILATE, moving);
    if (bg_rgb) background_image(v, F, px, moving, bg_rgb, bg_depth);
    for (int y = stride / 2; y < H && !st; y += stride)
        for (int x = stride / 2; x < W && !st; x += stride) {
            size_t p = (size_t)y * W + x;
            int background_done = 0;
            for (int f = 0; f < F && !st; f++) {
                size_t q = (size_t)f * px + p;
                int dyn = moving[q];
                if ((!dyn && background_done) || (dyn && !real)) continue;
                float d = train_view_depth(v, q);
                if (!(d > 0) || (v->mask && !v->mask[q])) continue;
                float X[3], c[3];
                pg_camera_unproject(&v->cam, x + 0.5f, y + 0.5f, d, X);
                for (int k = 0; k < 3; k++) c[k] = v->rgb[q * 3 + k] / 255.0f;
                st = points_push(pts, X, c, dyn);
                background_done |= !dyn;
                if (!real && background_done) break;
            }
        }
    free(moving);
    return st;
}

/* Random points in the frusta of the training views between near and far (uniform in
 * inverse depth), coloured from frame 0; all dynamic since nothing is known. */
static pg_status points_from_frustum(train_session *s, point_list *pts, int n)
{
    const train_set *ts = s->ts;
    float zn = ts->near_z > 0 ? ts->near_z : 0.5f, zf = ts->far_z > zn ? ts->far_z : zn * 20;
    int nv = 0;
    for (int i = 0; i < ts->num_views; i++) nv += ts->views[i].role != IO_ROLE_TEST;
    for (int k = 0; k < n; k++) {
        int pick = (int)pg_rng_below(&s->rng, (uint32_t)nv), vi = 0;
        for (int i = 0; i < ts->num_views; i++)
            if (ts->views[i].role != IO_ROLE_TEST && pick-- == 0) {
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
        if (v->role == IO_ROLE_TEST || v->depth) continue;
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

/* Hash table of voxel keys shared by the searches below (sized for every point). */
typedef struct {
    uint64_t *keys;
    uint8_t *used;
    size_t size;
    uint32_t *slot; /* (points) the table slot of each point's voxel */
} voxel_table;

static size_t voxel_lookup(const voxel_table *t, uint64_t k)
{
    size_t h = hash64(k) & (t->size - 1);
    while (t->used[h] && t->keys[h] != k) h = (h + 1) & (t->size - 1);
    return h;
}

/* Puts the points with dyn == want into voxels of size vox; fills their slot; returns the
 * number of distinct voxels. */
static size_t voxel_assign(voxel_table *t, const point_list *p, int want, const float lo[3], float vox)
{
    memset(t->used, 0, t->size);
    size_t uniq = 0;
    for (size_t i = 0; i < p->n; i++) {
        if (p->dyn[i] != want) continue;
        uint64_t k = voxel_key(p->xyz + 3 * i, lo, vox);
        size_t h = voxel_lookup(t, k);
        if (!t->used[h]) {
            t->used[h] = 1;
            t->keys[h] = k;
            uniq++;
        }
        t->slot[i] = (uint32_t)h;
    }
    return uniq;
}

/* Voxel size giving between 85 % and 100 % of `target` voxels for the points with dyn == want
 * (the table holds that assignment on return); *uniq gets the voxel count. */
static float voxel_search(voxel_table *t, const point_list *p, int want, const float lo[3], float diag, int target,
                          size_t *uniq)
{
    float vox = diag / sqrtf((float)target) + 1e-6f;
    for (int iter = 0; iter < 12; iter++) {
        *uniq = voxel_assign(t, p, want, lo, vox);
        float ratio = (float)*uniq / (float)target;
        if (ratio <= 1.0f && (ratio > 0.85f || iter == 11)) break;
        vox *= ratio > 1 ? sqrtf(ratio) * 1.02f : fmaxf(sqrtf(ratio), 0.5f);
        if (iter == 11) {
            vox *= 1.3f;
            *uniq = voxel_assign(t, p, want, lo, vox);
        }
    }
    return vox;
}

/* Static points right next to moving ones (the same or a neighbouring dynamic voxel) become
 * dynamic: the inside of a uniformly coloured mover does not change colour, yet moves. */
static void promote_near_dynamic(voxel_table *t, point_list *p, const float lo[3], float vox)
{
    voxel_assign(t, p, 1, lo, vox);
    for (size_t i = 0; i < p->n; i++) {
        if (p->dyn[i]) continue;
        const float *x = p->xyz + 3 * i;
        int near = 0;
        for (int d = 0; d < 27 && !near; d++) {
            float y[3] = { x[0] + (d % 3 - 1) * vox, x[1] + (d / 3 % 3 - 1) * vox, x[2] + (d / 9 - 1) * vox };
            near = t->used[voxel_lookup(t, voxel_key(y, lo, vox))];
        }
        p->dyn[i] = (uint8_t)(near ? 2 : 0); /* 2: promoted, becomes 1 after the loop */
    }
    for (size_t i = 0; i < p->n; i++) p->dyn[i] = p->dyn[i] != 0;
}

/* Row r of the session's Gaussians: an isotropic, unrotated Gaussian with SH DC colour sh0. */
static void put_isotropic(train_session *s, int r, const float mean[3], const float sh0[3], float log_s,
                          float opacity_logit, int is_static)
{
    for (int k = 0; k < 3; k++) {
        s->g.means[3 * r + k] = mean[k];
        s->g.log_scales[3 * r + k] = log_s;
        splat_gaussians_sh(&s->g, (size_t)r)[k] = sh0[k];
    }
    s->g.quats[4 * r] = 1.0f;
    s->g.opacity[r] = opacity_logit;
    s->is_static[r] = (uint8_t)is_static;
}

/* One Gaussian per voxel of the points with dyn == want (after voxel_assign): mean position and
 * colour, isotropic scale 0.6 voxel, opacity 0.3. Appends at row *n. */
static pg_status voxels_to_gaussians(train_session *s, const voxel_table *t, const point_list *p, int want, float vox,
                                     int *n)
{
    double *acc = pg_calloc(t->size * 7, sizeof(double), "init voxel sums");
    if (!acc) return PG_ERR_NOMEM;
    for (size_t i = 0; i < p->n; i++) {
        if (p->dyn[i] != want) continue;
        double *a = acc + (size_t)t->slot[i] * 7;
        for (int k = 0; k < 3; k++) {
            a[k] += p->xyz[3 * i + k];
            a[3 + k] += p->rgb[3 * i + k];
        }
        a[6] += 1;
    }
    float log_s = logf(0.6f * vox), opacity_logit = logf(0.3f / 0.7f);
    for (size_t h = 0; h < t->size; h++) {
        if (!t->used[h]) continue;
        const double *a = acc + h * 7;
        float mean[3], sh0[3];
        for (int k = 0; k < 3; k++) {
            mean[k] = (float)(a[k] / a[6]);
            sh0[k] = (float)((a[3 + k] / a[6] - 0.5) / SPLAT_SH_C0);
        }
        put_isotropic(s, (*n)++, mean, sh0, log_s, opacity_logit, !want);
    }
    free(acc);
    return PG_OK;
}

/* Novel views turned further than any proxy camera look past the real frame, where no view put
 * anything, and would show the background colour (black wedges). The real view's static
 * background is continued past its borders (proxy/outpaint.h: planes continue, colours blur out)
 * and the continuation gets one static Gaussian per block, wide and opaque enough to close the
 * gaps between blocks. Proxies that see the margin refine it; elsewhere it stays the best guess. */
#define INIT_MARGIN_PAD 0.5f  /* margin on each side, fraction of the larger frame side */
#define INIT_MARGIN_BLOCKS 40 /* block side = larger frame side / this */
#define INIT_MARGIN_OPACITY 0.9f

static int margin_block(const pg_camera *cam)
{
    int side = cam->width > cam->height ? cam->width : cam->height;
    return side / INIT_MARGIN_BLOCKS > 2 ? side / INIT_MARGIN_BLOCKS : 2;
}

static pg_status margin_points(const pg_camera *cam, const float *bg_rgb, const float *bg_depth, point_list *out)
{
    int W = cam->width, H = cam->height, side = W > H ? W : H, B = margin_block(cam);
    int pad = (int)ceilf(INIT_MARGIN_PAD * side / B) * B, W2 = W + 2 * pad, H2 = H + 2 * pad;
    float *rgb2 = pg_malloc((size_t)W2 * H2 * 3 * sizeof(float), "init margin rgb");
    float *depth2 = pg_malloc((size_t)W2 * H2 * sizeof(float), "init margin depth");
    pg_status st = rgb2 && depth2 ? proxy_outpaint(W, H, bg_rgb, bg_depth, pad, rgb2, depth2) : PG_ERR_NOMEM;
    for (int by = 0; by + B <= H2 && !st; by += B)
        for (int bx = 0; bx + B <= W2 && !st; bx += B) {
            float u = bx + 0.5f * B - pad, w = by + 0.5f * B - pad; /* block centre, real-view pixels */
            if (u >= 0 && u < W && w >= 0 && w < H) continue;
            double c[3] = { 0, 0, 0 }, d = 0;
            int nd = 0;
            for (int y = by; y < by + B; y++)
                for (int x = bx; x < bx + B; x++) {
                    size_t q = (size_t)y * W2 + x;
                    if (!(depth2[q] > 0)) continue;
                    for (int k = 0; k < 3; k++) c[k] += rgb2[3 * q + k];
                    d += depth2[q];
                    nd++;
                }
            if (nd < B * B / 2) continue;
            float X[3], col[3] = { (float)(c[0] / nd), (float)(c[1] / nd), (float)(c[2] / nd) };
            pg_camera_unproject(cam, u, w, (float)(d / nd), X);
            st = points_push(out, X, col, 0);
        }
    free(rgb2);
    free(depth2);
    return st;
}

/* Appends the margin points as static Gaussians at row *n: std 0.6 block (in the world, at the
 * point's depth in the real view), opacity INIT_MARGIN_OPACITY. */
static void margin_to_gaussians(train_session *s, const pg_camera *cam, const point_list *m, int *n)
{
    float opacity_logit = logf(INIT_MARGIN_OPACITY / (1 - INIT_MARGIN_OPACITY)), B = (float)margin_block(cam);
    for (size_t i = 0; i < m->n; i++) {
        float uv[2], z = pg_camera_project(cam, m->xyz + 3 * i, uv);
        float sh0[3];
        for (int k = 0; k < 3; k++) sh0[k] = (m->rgb[3 * i + k] - 0.5f) / SPLAT_SH_C0;
        put_isotropic(s, (*n)++, m->xyz + 3 * i, sh0, logf(0.6f * B * fmaxf(z, 1e-6f) / cam->fx), opacity_logit, 1);
    }
}

/* Share of the initial budget for the moving points (when there are enough of them). */
#define INIT_DYNAMIC_SHARE 0.35f

pg_status train_init_gaussians(train_session *s)
{
    const train_set *ts = s->ts;
    point_list pts = {0}, margin = {0};
    voxel_table t = {0};
    float *bg_rgb = NULL, *bg_depth = NULL;
    int margin_view = -1;
    pg_status st = PG_OK;
    int target = s->cfg.init_points < s->cfg.max_gaussians ? s->cfg.init_points : s->cfg.max_gaussians;
    if (target < 16) target = 16;

    /* budget: at most ~3M candidate points */
    size_t cand = 0;
    for (int i = 0; i < ts->num_views; i++)
        if (ts->views[i].depth && ts->views[i].role != IO_ROLE_TEST)
            cand += (size_t)ts->width * ts->height * 2;
    int stride = 1;
    while (cand / ((size_t)stride * stride) > 3000000) stride++;
    for (int i = 0; i < ts->num_views && margin_view < 0; i++)
        if (ts->views[i].depth && ts->views[i].role == IO_ROLE_REAL) margin_view = i;
    if (margin_view >= 0) {
        size_t px = (size_t)ts->width * ts->height;
        bg_rgb = pg_malloc(px * 3 * sizeof(float), "init background rgb");
        bg_depth = pg_malloc(px * sizeof(float), "init background depth");
        if (!bg_rgb || !bg_depth) st = PG_ERR_NOMEM;
    }
    for (int i = 0; i < ts->num_views && !st; i++)
        if (ts->views[i].depth && ts->views[i].role != IO_ROLE_TEST)
            st = points_from_depth(ts, i, stride, &pts, i == margin_view ? bg_rgb : NULL, bg_depth);
    if (!st && margin_view >= 0) st = margin_points(&ts->views[margin_view].cam, bg_rgb, bg_depth, &margin);
    if (!st && pts.n < (size_t)target / 4) st = points_from_frustum(s, &pts, target - (int)pts.n);
    if (!st && pts.n > 0) st = points_fill_uncovered(s, &pts);
    if (st) goto done;
    if (pts.n == 0) {
        st = pg_fail(PG_ERR_ARG, "init: no points to start from");
        goto done;
    }

    float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
    double cen[3] = {0, 0, 0};
    size_t ndyn_pts = 0;
    for (size_t i = 0; i < pts.n; i++) {
        ndyn_pts += pts.dyn[i] != 0;
        for (int a = 0; a < 3; a++) {
            float x = pts.xyz[3 * i + a];
            lo[a] = fminf(lo[a], x);
            hi[a] = fmaxf(hi[a], x);
            cen[a] += x;
        }
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

    t.size = 1;
    while (t.size < pts.n * 2) t.size <<= 1;
    t.keys = pg_malloc(t.size * sizeof(uint64_t), "init voxel keys");
    t.used = pg_malloc(t.size, "init voxel table");
    t.slot = pg_malloc(pts.n * sizeof(uint32_t), "init voxel slots");
    if (!t.keys || !t.used || !t.slot) {
        st = PG_ERR_NOMEM;
        goto done;
    }
    float diag = 0;
    for (int a = 0; a < 3; a++) diag += (hi[a] - lo[a]) * (hi[a] - lo[a]);
    diag = sqrtf(diag);

    size_t udyn = 0, ustat = 0;
    float vox_dyn = 0;
    int target_dyn = ndyn_pts > 0 ? (int)(INIT_DYNAMIC_SHARE * target) : 0;
    if (target_dyn > 0) {
        vox_dyn = voxel_search(&t, &pts, 1, lo, diag, target_dyn, &udyn);
        promote_near_dynamic(&t, &pts, lo, vox_dyn);
        vox_dyn = voxel_search(&t, &pts, 1, lo, diag, target_dyn, &udyn);
        if ((st = train_resize_all(s, (int)udyn))) goto done;
        int n = 0;
        if ((st = voxels_to_gaussians(s, &t, &pts, 1, vox_dyn, &n))) goto done;
    }
    int target_stat = target - (int)udyn > 16 ? target - (int)udyn : 16;
    float vox_stat = voxel_search(&t, &pts, 0, lo, diag, target_stat, &ustat);
    if (udyn + ustat > (size_t)s->cfg.max_gaussians) {
        st = pg_fail(PG_ERR_INTERNAL, "init: voxel downsampling kept %zu points", udyn + ustat);
        goto done;
    }
    size_t nmargin = margin.n < (size_t)s->cfg.max_gaussians - (udyn + ustat) ? margin.n : 0;
    if ((st = train_resize_all(s, (int)(udyn + ustat + nmargin)))) goto done;
    int n = (int)udyn;
    if (ustat > 0 && (st = voxels_to_gaussians(s, &t, &pts, 0, vox_stat, &n))) goto done;
    if (nmargin > 0) margin_to_gaussians(s, &ts->views[margin_view].cam, &margin, &n);
    s->g.sh_degree = 0;
done:
    free(pts.xyz);
    free(pts.rgb);
    free(pts.dyn);
    free(margin.xyz);
    free(margin.rgb);
    free(margin.dyn);
    free(bg_rgb);
    free(bg_depth);
    free(t.keys);
    free(t.used);
    free(t.slot);
    return st;
}
