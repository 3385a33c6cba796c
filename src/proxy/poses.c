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
    float *zbuf;                    /* (H,W) scratch */
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

/* Photometric cost of scale s: every valid real pixel is projected into each target; if it is the
 * front-most surface there (z-buffer test) its colour is compared with the bilinearly sampled
 * target colour. Sampling the target (instead of splatting the source) keeps the cost smooth in s. */
static void scale_cost(scale_level *L, float s, float *cost, float *coverage)
{
    int W = L->real.width, H = L->real.height;
    double sum = 0;
    long used = 0, total = 0;
    for (int k = 0; k < L->n; k++) {
        const pg_camera *dst = &L->targets[k];
        for (size_t i = 0; i < (size_t)W * H; i++) L->zbuf[i] = FLT_MAX;
        for (int pass = 0; pass < 2; pass++) {
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
                    if (pass == 0) {
                        if (z < L->zbuf[o]) L->zbuf[o] = z;
                        continue;
                    }
                    if (z > L->zbuf[o] * 1.02f) continue; /* occluded in the target */
                    float t[3];
                    sample_bilinear(L->target_rgb[k], W, H, uv[0], uv[1], t);
                    const float *p = L->rgb + ((size_t)v * W + u) * 3;
                    sum += fabsf(t[0] - p[0]) + fabsf(t[1] - p[1]) + fabsf(t[2] - p[2]);
                    used++;
                }
            }
        }
        total += (long)W * H;
    }
    *coverage = total > 0 ? (float)used / total : 0;
    /* Too few overlapping pixels means the scale is implausible: make it lose. */
    *cost = used > 16 && *coverage > 0.05f ? (float)(sum / (3.0 * used)) : 1.0f;
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
    if (opt.coarse_steps < 3) opt.coarse_steps = 3;

    pg_status st = PG_OK;
    int w = W / 2, h = H / 2;
    float *rgb2 = NULL, *depth2 = NULL, *zbuf = NULL;
    float **trgb2 = pg_calloc((size_t)n, sizeof(float *), "target pointers");
    pg_camera *tcam2 = pg_calloc((size_t)n, sizeof(pg_camera), "target cameras");
    if (!trgb2 || !tcam2) { st = PG_ERR_NOMEM; goto done; }
    rgb2 = downsample(rgb, W, H, 3, 0);
    depth2 = downsample(depth, W, H, 1, 1);
    zbuf = pg_malloc((size_t)W * H * sizeof(float), "scale fit z-buffer");
    if (!rgb2 || !depth2 || !zbuf) { st = PG_ERR_NOMEM; goto done; }
    for (int k = 0; k < n; k++) {
        trgb2[k] = downsample(target_rgb[k], W, H, 3, 0);
        if (!trgb2[k]) { st = PG_ERR_NOMEM; goto done; }
        tcam2[k] = targets[k];
        pg_camera_resize(&tcam2[k], w, h);
    }
    pg_camera real2 = *real;
    pg_camera_resize(&real2, w, h);
    scale_level coarse = { real2, rgb2, depth2, n, tcam2, (const float *const *)trgb2, zbuf };
    scale_level fine = { *real, rgb, depth, n, targets, target_rgb, zbuf };

    /* Coarse grid in log s at half resolution. */
    double l0 = log(opt.scale_min), l1 = log(opt.scale_max);
    int best = 0, evals = 0;
    float best_cost = FLT_MAX;
    for (int i = 0; i < opt.coarse_steps; i++) {
        float s = (float)exp(l0 + (l1 - l0) * i / (opt.coarse_steps - 1)), c, cov;
        scale_cost(&coarse, s, &c, &cov);
        evals++;
        if (c < best_cost) { best_cost = c; best = i; }
    }
    /* Golden-section search at full resolution on the bracket around the best grid point. */
    double step = (l1 - l0) / (opt.coarse_steps - 1);
    double a = l0 + (best - 1) * step, b = l0 + (best + 1) * step;
    const double gr = 0.5 * (sqrt(5.0) - 1.0);
    double x1 = b - gr * (b - a), x2 = a + gr * (b - a);
    float f1, f2, cov;
    scale_cost(&fine, (float)exp(x1), &f1, &cov);
    scale_cost(&fine, (float)exp(x2), &f2, &cov);
    evals += 2;
    for (int i = 0; i < opt.refine_steps; i++) {
        if (f1 < f2) {
            b = x2; x2 = x1; f2 = f1;
            x1 = b - gr * (b - a);
            scale_cost(&fine, (float)exp(x1), &f1, &cov);
        } else {
            a = x1; x1 = x2; f1 = f2;
            x2 = a + gr * (b - a);
            scale_cost(&fine, (float)exp(x2), &f2, &cov);
        }
        evals++;
    }
    float s = (float)exp(0.5 * (a + b));
    report->scale = s;
    scale_cost(&fine, s, &report->cost, &report->coverage);
    report->evaluations = evals + 1;
done:
    if (trgb2)
        for (int k = 0; k < n; k++) free(trgb2[k]);
    free(trgb2);
    free(tcam2);
    free(rgb2);
    free(depth2);
    free(zbuf);
    return st;
}
