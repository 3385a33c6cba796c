/* poses.c - proxy camera placement (hemisphere cap) and the evaluation-only pose-scale fit. */
#include "proxy/poses.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/mathx.h"

static int depth_valid(float d) { return isfinite(d) && d > 0; }

/* Median of the valid entries of depth (n values); 0 when none is valid. */
static pg_status median_valid(const float *depth, size_t n, float *median)
{
    float *tmp = pg_malloc(n * sizeof(float), "median buffer");
    if (!tmp) return PG_ERR_NOMEM;
    size_t k = 0;
    for (size_t i = 0; i < n; i++)
        if (depth_valid(depth[i])) tmp[k++] = depth[i];
    *median = 0;
    if (k > 0) {
        qsort(tmp, k, sizeof(float), pg_cmp_float);
        *median = tmp[k / 2];
    }
    free(tmp);
    return PG_OK;
}

pg_status proxy_scene_center(const pg_camera *real, const float *depth, float depth_scale, float center[3],
                             float *radius)
{
    if (!real || !depth || !(depth_scale > 0)) return pg_fail(PG_ERR_ARG, "proxy_scene_center: bad arguments");
    float med;
    PG_TRY(median_valid(depth, (size_t)real->width * real->height, &med));
    if (!(med > 0)) return pg_fail(PG_ERR_ARG, "scene centre: the depth map has no valid pixel");
    float Xc[3] = { 0, 0, med * depth_scale };
    pg_camera_cam_to_world(real, Xc, center);
    *radius = med * depth_scale;
    return PG_OK;
}

pg_status proxy_poses_hemisphere(const pg_camera *real, const float center[3], int m, float max_angle_deg,
                                 pg_camera *out)
{
    if (m < 1 || m > 10000) return pg_fail(PG_ERR_ARG, "hemisphere poses: number of cameras %d not in 1..10000", m);
    if (!(max_angle_deg > 0 && max_angle_deg < 90))
        return pg_fail(PG_ERR_ARG, "hemisphere poses: max angle %g deg not in (0, 90)", max_angle_deg);
    float eye0[3], back[3], right[3], down[3], up[3];
    pg_camera_center(real, eye0);
    vec3_sub(back, eye0, center);
    float radius = vec3_norm(back);
    if (!(radius > 0)) return pg_fail(PG_ERR_ARG, "hemisphere poses: the centre coincides with the camera");
    vec3_scale(back, back, 1.0f / radius);
    /* Rows of R are the camera axes in world coordinates. */
    for (int j = 0; j < 3; j++) {
        right[j] = real->R[j];
        down[j] = real->R[3 + j];
        up[j] = -down[j];
    }
    const double golden = PG_PI * (3.0 - sqrt(5.0));
    for (int j = 0; j < m; j++) {
        double theta = max_angle_deg * PG_PI / 180.0 * sqrt((j + 1.0) / m);
        double phi = j * golden;
        float dir[3], eye[3];
        for (int k = 0; k < 3; k++)
            dir[k] = (float)(cos(theta) * back[k] + sin(theta) * (cos(phi) * right[k] + sin(phi) * down[k]));
        vec3_normalize(dir);
        for (int k = 0; k < 3; k++) eye[k] = center[k] + radius * dir[k];
        out[j] = *real;
        pg_camera_look_at(&out[j], eye, center, up);
    }
    return PG_OK;
}

float proxy_camera_angle_deg(const pg_camera *a, const pg_camera *b)
{
    /* The optical axis in world coordinates is the third row of R. */
    float c = a->R[6] * b->R[6] + a->R[7] * b->R[7] + a->R[8] * b->R[8];
    return (float)(acos(clampf(c, -1.0f, 1.0f)) * 180.0 / PG_PI);
}

pg_status proxy_forward_warp(const pg_camera *src, const float *rgb, const float *depth, float depth_scale,
                             const pg_camera *dst, float *out_rgb, float *out_depth)
{
    int W = src->width, H = src->height, W2 = dst->width, H2 = dst->height;
    float *zbuf = pg_malloc((size_t)W2 * H2 * sizeof(float), "warp z-buffer");
    if (!zbuf) return PG_ERR_NOMEM;
    for (size_t i = 0; i < (size_t)W2 * H2; i++) zbuf[i] = FLT_MAX;
    if (out_rgb) memset(out_rgb, 0, (size_t)W2 * H2 * 3 * sizeof(float));
    for (int v = 0; v < H; v++) {
        for (int u = 0; u < W; u++) {
            float d = depth[(size_t)v * W + u];
            if (!depth_valid(d)) continue;
            float X[3], uv[2];
            pg_camera_unproject(src, u + 0.5f, v + 0.5f, d * depth_scale, X);
            float z = pg_camera_project(dst, X, uv);
            if (!(z > 1e-6f)) continue;
            int x = (int)floorf(uv[0]), y = (int)floorf(uv[1]);
            if (x < 0 || y < 0 || x >= W2 || y >= H2) continue;
            size_t o = (size_t)y * W2 + x;
            if (z < zbuf[o]) {
                zbuf[o] = z;
                if (out_rgb)
                    for (int c = 0; c < 3; c++) out_rgb[o * 3 + c] = rgb[((size_t)v * W + u) * 3 + c];
            }
        }
    }
    if (out_depth)
        for (size_t i = 0; i < (size_t)W2 * H2; i++) out_depth[i] = zbuf[i] == FLT_MAX ? 0 : zbuf[i];
    free(zbuf);
    return PG_OK;
}

proxy_scale_options proxy_default_scale_options(void)
{
    proxy_scale_options o = { 0, 0, 48, 24 };
    return o;
}

/* One pyramid level of the fit: the real RGB-D frame and the targets at some resolution. */
typedef struct {
    pg_camera real;
    const float *rgb, *depth; /* (H,W,3), (H,W) */
    int n;
    const pg_camera *targets;
    const float *const *target_rgb; /* n x (H,W,3) */
    const float *chance;            /* n: mean |real - target| of unrelated pixel pairs */
    float *zbuf, *uv;               /* (H,W), (H,W,2) scratch: front-most warped point per target pixel */
    int *src;                       /* (H,W) scratch: its real pixel, -1 where nothing landed */
} scale_level;

/* Bilinear RGB sample at continuous pixel coordinate (x, y) (pixel centres at +0.5). */
static void sample_bilinear(const float *img, int W, int H, float x, float y, float out[3])
{
    x -= 0.5f;
    y -= 0.5f;
    int x0 = (int)floorf(x), y0 = (int)floorf(y);
    float ax = x - x0, ay = y - y0;
    int x1 = clampi(x0 + 1, 0, W - 1), y1 = clampi(y0 + 1, 0, H - 1);
    x0 = clampi(x0, 0, W - 1);
    y0 = clampi(y0, 0, H - 1);
    const float *p00 = img + ((size_t)y0 * W + x0) * 3, *p01 = img + ((size_t)y0 * W + x1) * 3;
    const float *p10 = img + ((size_t)y1 * W + x0) * 3, *p11 = img + ((size_t)y1 * W + x1) * 3;
    for (int c = 0; c < 3; c++)
        out[c] = (1 - ay) * ((1 - ax) * p00[c] + ax * p01[c]) + ay * ((1 - ax) * p10[c] + ax * p11[c]);
}

static float rgb_l1(const float *a, const float *b)
{
    return fabsf(a[0] - b[0]) + fabsf(a[1] - b[1]) + fabsf(a[2] - b[2]);
}

/* What an unexplained target pixel costs: the real and target frames compared half a frame apart,
 * i.e. the error of pairing pixels that have nothing to do with each other. */
static float chance_error(const float *rgb, const float *target, size_t N)
{
    double sum = 0;
    for (size_t i = 0; i < N; i++) sum += rgb_l1(rgb + 3 * i, target + 3 * ((i + N / 2) % N));
    return N ? (float)(sum / (3.0 * N)) : 1.0f;
}

/* Photometric cost of scale s, counted in the targets' pixels: every valid real pixel is projected
 * into each target, the front-most one per target pixel is compared with the target colour sampled
 * bilinearly where it lands (sampling the target keeps the cost smooth in s), and the target pixels
 * nothing lands on cost the chance error. A mean over covered pixels alone let a wrong scale win by
 * piling the whole real frame onto a few target pixels that happen to match (Panoptic with
 * FastDepth's depth fitted 0.24 of the true size, issue 28); here such a scale explains little of
 * any target and scores near chance. */
static void scale_cost(scale_level *L, float s, float *cost, float *coverage)
{
    int W = L->real.width, H = L->real.height;
    size_t N = (size_t)W * H;
    double sum = 0;
    long covered = 0, total = 0;
    for (int k = 0; k < L->n; k++) {
        const pg_camera *dst = &L->targets[k];
        for (size_t i = 0; i < N; i++) L->zbuf[i] = FLT_MAX, L->src[i] = -1;
        for (int v = 0; v < H; v++) {
            for (int u = 0; u < W; u++) {
                float d = L->depth[(size_t)v * W + u];
                if (!depth_valid(d)) continue;
                float X[3], uv[2];
                pg_camera_unproject(&L->real, u + 0.5f, v + 0.5f, d * s, X);
                float z = pg_camera_project(dst, X, uv);
                if (!(z > 1e-6f)) continue;
                int x = (int)floorf(uv[0]), y = (int)floorf(uv[1]);
                if (x < 0 || y < 0 || x >= W || y >= H) continue;
                size_t o = (size_t)y * W + x;
                if (z >= L->zbuf[o]) continue;
                L->zbuf[o] = z;
                L->src[o] = v * W + u;
                L->uv[2 * o] = uv[0], L->uv[2 * o + 1] = uv[1];
            }
        }
        long hit = 0;
        double err = 0;
        for (size_t o = 0; o < N; o++) {
            if (L->src[o] < 0) continue;
            float t[3];
            sample_bilinear(L->target_rgb[k], W, H, L->uv[2 * o], L->uv[2 * o + 1], t);
            err += rgb_l1(t, L->rgb + 3 * (size_t)L->src[o]) / 3.0;
            hit++;
        }
        sum += err + (double)L->chance[k] * (double)(N - hit);
        covered += hit;
        total += (long)N;
    }
    *coverage = total > 0 ? (float)covered / total : 0;
    *cost = total > 0 ? (float)(sum / total) : 1.0f;
}

/* 2x box downsampling of an (H,W,C) image (odd edges dropped). */
static float *downsample(const float *img, int W, int H, int C, int depth_mode)
{
    int w = W / 2, h = H / 2;
    float *out = pg_malloc((size_t)w * h * C * sizeof(float), "downsampled image");
    if (!out) return NULL;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            for (int c = 0; c < C; c++) {
                float s = 0;
                int n = 0;
                for (int dy = 0; dy < 2; dy++)
                    for (int dx = 0; dx < 2; dx++) {
                        float val = img[(((size_t)(2 * y + dy)) * W + 2 * x + dx) * C + c];
                        if (depth_mode && !depth_valid(val)) continue;
                        s += val;
                        n++;
                    }
                out[((size_t)y * w + x) * C + c] = n ? s / n : 0;
            }
    return out;
}

/* Level `L` as the 2x box-downsampled copy of `finer` (cameras resized, chance errors measured
 * at that size); the caller frees the owned arrays with free_level. */
static pg_status downsample_level(const scale_level *finer, scale_level *L)
{
    int W = finer->real.width, H = finer->real.height, n = finer->n;
    *L = *finer;
    pg_camera_resize(&L->real, W / 2, H / 2);
    float **trgb = pg_calloc((size_t)n, sizeof(float *), "scale fit targets");
    pg_camera *tcam = pg_calloc((size_t)n, sizeof(pg_camera), "scale fit cameras");
    float *chance = pg_calloc((size_t)n, sizeof(float), "scale fit chance errors");
    L->rgb = downsample(finer->rgb, W, H, 3, 0);
    L->depth = downsample(finer->depth, W, H, 1, 1);
    L->targets = tcam, L->target_rgb = (const float *const *)trgb, L->chance = chance;
    if (!trgb || !tcam || !chance || !L->rgb || !L->depth) return PG_ERR_NOMEM;
    for (int k = 0; k < n; k++) {
        if (!(trgb[k] = downsample(finer->target_rgb[k], W, H, 3, 0))) return PG_ERR_NOMEM;
        tcam[k] = finer->targets[k];
        pg_camera_resize(&tcam[k], W / 2, H / 2);
        chance[k] = chance_error(L->rgb, trgb[k], (size_t)(W / 2) * (H / 2));
    }
    return PG_OK;
}

static void free_level(scale_level *L)
{
    if (L->target_rgb)
        for (int k = 0; k < L->n; k++) free((void *)L->target_rgb[k]);
    free((void *)L->target_rgb);
    free((void *)L->targets);
    free((void *)L->chance);
    free((void *)L->rgb);
    free((void *)L->depth);
}

/* Golden-section search for the cheapest log-scale in [a, b] on one level; returns its centre. */
static double golden_search(scale_level *L, double a, double b, int iters, int *evals)
{
    const double gr = 0.5 * (sqrt(5.0) - 1.0);
    double x1 = b - gr * (b - a), x2 = a + gr * (b - a);
    float f1, f2, cov;
    scale_cost(L, (float)exp(x1), &f1, &cov);
    scale_cost(L, (float)exp(x2), &f2, &cov);
    *evals += 2;
    for (int i = 0; i < iters; i++, (*evals)++) {
        if (f1 < f2) {
            b = x2, x2 = x1, f2 = f1;
            x1 = b - gr * (b - a);
            scale_cost(L, (float)exp(x1), &f1, &cov);
        } else {
            a = x1, x1 = x2, f1 = f2;
            x2 = a + gr * (b - a);
            scale_cost(L, (float)exp(x2), &f2, &cov);
        }
    }
    return 0.5 * (a + b);
}

/* Coarse to fine: a dense log grid on the quarter-size images (downsampling widens the basin of
 * the right scale: on wide baselines it is only +-3 % wide at full size, narrower than a coarse
 * grid's step), golden-section search at half size around the best grid point, then at full size
 * within +-4 %. */
pg_status proxy_fit_pose_scale(const pg_camera *real, const float *rgb, const float *depth, int n,
                               const pg_camera *targets, const float *const *target_rgb,
                               const proxy_scale_options *opt_in, proxy_scale_report *report)
{
    proxy_scale_options opt = opt_in ? *opt_in : proxy_default_scale_options();
    if (n < 1) return pg_fail(PG_ERR_ARG, "pose scale fit: no training camera to fit against");
    int W = real->width, H = real->height;
    for (int k = 0; k < n; k++)
        if (targets[k].width != W || targets[k].height != H)
            return pg_fail(PG_ERR_SIZE, "pose scale fit: camera %d is %dx%d, the real camera %dx%d", k,
                           targets[k].width, targets[k].height, W, H);
    if (opt.scale_min <= 0 || opt.scale_max <= opt.scale_min) {
        opt.scale_min = 0.125f;
        opt.scale_max = 8.0f;
    }
    double l0 = log(opt.scale_min), l1 = log(opt.scale_max);
    int steps = (int)ceil((l1 - l0) / 0.03) + 1; /* 3 % apart at the coarsest level */
    if (steps < opt.coarse_steps) steps = opt.coarse_steps;
    if (steps < 3) steps = 3;

    pg_status st = PG_OK;
    enum { LEVELS = 3 };
    scale_level lv[LEVELS];
    memset(lv, 0, sizeof lv);
    int levels = 1;
    float *chance = pg_calloc((size_t)n, sizeof(float), "scale fit chance errors");
    float *zbuf = pg_malloc((size_t)W * H * sizeof(float), "scale fit z-buffer");
    float *uv = pg_malloc((size_t)W * H * 2 * sizeof(float), "scale fit warp coordinates");
    int *src = pg_malloc((size_t)W * H * sizeof(int), "scale fit source pixels");
    if (!chance || !zbuf || !uv || !src) { st = PG_ERR_NOMEM; goto done; }
    for (int k = 0; k < n; k++) chance[k] = chance_error(rgb, target_rgb[k], (size_t)W * H);
    lv[0] = (scale_level){ *real, rgb, depth, n, targets, target_rgb, chance, zbuf, uv, src };
    while (levels < LEVELS && lv[levels - 1].real.width >= 32 && lv[levels - 1].real.height >= 32) {
        st = downsample_level(&lv[levels - 1], &lv[levels]);
        levels++;
        if (st) goto done;
    }

    /* the grid's deepest local minima, each refined: a basin that looks best at quarter size is not
     * always the deepest at full size (FastDepth on tabletop_dev: 3.12 vs 1.77) */
    enum { CANDIDATES = 3 };
    scale_level *coarsest = &lv[levels - 1];
    float *grid = pg_malloc((size_t)steps * sizeof(float), "scale fit grid");
    if (!grid) { st = PG_ERR_NOMEM; goto done; }
    int evals = 0;
    for (int i = 0; i < steps; i++, evals++) {
        float cov;
        scale_cost(coarsest, (float)exp(l0 + (l1 - l0) * i / (steps - 1)), &grid[i], &cov);
    }
    int cand[CANDIDATES], nc = 0;
    for (int i = 0; i < steps; i++) {
        if ((i > 0 && grid[i - 1] < grid[i]) || (i + 1 < steps && grid[i + 1] <= grid[i])) continue;
        if (nc < CANDIDATES) cand[nc++] = i;
        else if (grid[i] < grid[cand[CANDIDATES - 1]]) cand[CANDIDATES - 1] = i;
        else continue;
        for (int j = nc - 1; j > 0 && grid[cand[j]] < grid[cand[j - 1]]; j--) {
            int tmp = cand[j];
            cand[j] = cand[j - 1], cand[j - 1] = tmp;
        }
    }
    free(grid);
    double step = (l1 - l0) / (steps - 1), best_x = l0;
    float best_cost = FLT_MAX, best_coverage = 0;
    for (int c = 0; c < nc; c++) {
        double x = l0 + cand[c] * step;
        if (levels > 2) x = golden_search(&lv[1], x - 2 * step, x + 2 * step, opt.refine_steps / 2, &evals);
        x = golden_search(&lv[0], x - log(1.04), x + log(1.04), opt.refine_steps, &evals);
        float cost, cov;
        scale_cost(&lv[0], (float)exp(x), &cost, &cov);
        evals++;
        if (cost < best_cost) best_cost = cost, best_coverage = cov, best_x = x;
    }
    report->scale = (float)exp(best_x);
    report->cost = best_cost;
    report->coverage = best_coverage;
    report->evaluations = evals;
done:
    for (int l = 1; l < levels; l++) free_level(&lv[l]);
    free(chance);
    free(zbuf);
    free(uv);
    free(src);
    return st;
}

void proxy_shift_disparity(float *depth, size_t n, float shift)
{
    if (shift == 0) return;
    for (size_t i = 0; i < n; i++) {
        if (!depth_valid(depth[i])) continue;
        float den = 1.0f + shift * depth[i];
        depth[i] = den > 0 ? depth[i] / den : 0.0f;
    }
}
