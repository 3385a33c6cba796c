/* filter3d.c - the 3D smoothing filter: per-Gaussian variance from the training cameras, and the
 * filtered scales and opacity forward and backward (see filter3d.h for the model). */
#include "splat/filter3d.h"

#include <math.h>
#include <stddef.h>

void splat_filter3d_compute(const float *means, int n, const pg_camera *cams, int ncam, float *var)
{
    #pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) {
        float seen = INFINITY, front = INFINITY;
        for (int c = 0; c < ncam; c++) {
            const pg_camera *cam = &cams[c];
            float x[3];
            pg_camera_world_to_cam(cam, means + 3 * (size_t)i, x);
            if (!(x[2] > 1e-6f)) continue;
            const float foot = x[2] / fmaxf(cam->fx, cam->fy);
            front = fminf(front, foot);
            const float u = cam->fx * x[0] / x[2] + cam->cx, v = cam->fy * x[1] / x[2] + cam->cy;
            const float mx = 0.15f * cam->width, my = 0.15f * cam->height;
            if (u >= -mx && u <= cam->width + mx && v >= -my && v <= cam->height + my) seen = fminf(seen, foot);
        }
        const float foot = seen < INFINITY ? seen : front;
        var[i] = foot < INFINITY ? SPLAT_FILTER3D_VAR * foot * foot : 0.0f;
    }
}

/* log(sigmoid(x)) without overflow */
static float log_sigmoid(float x) { return x > 0 ? -log1pf(expf(-x)) : x - log1pf(expf(x)); }

/* One axis: the filtered log-scale and w = var / (s^2 + var), from exponents that are never
 * positive (a scale far below or far above the filter stays finite). */
static float filtered_log_scale(float ls, float log_var, float *w)
{
    const float e = 2.0f * ls - log_var; /* log(s^2 / var) */
    if (e > 0) {
        const float r = expf(-e);
        *w = r / (1.0f + r);
        return ls + 0.5f * log1pf(r);
    }
    const float r = expf(e);
    *w = 1.0f / (1.0f + r);
    return 0.5f * (log_var + log1pf(r));
}

/* The filtered opacity's complement 1 - sigmoid(o) rho, accurate when both are near 1. */
static float filtered_opacity_complement(float o, float log_rho)
{
    const float a = 1.0f / (1.0f + expf(-o)), na = 1.0f / (1.0f + expf(o));
    return na + a * -expm1f(log_rho);
}

void splat_filter3d_forward(float *log_scales, float *opacity, const float *var, int n, float *saved)
{
    #pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) {
        float *ls = log_scales + 3 * (size_t)i;
        if (saved) {
            for (int k = 0; k < 3; k++) saved[4 * (size_t)i + k] = ls[k];
            saved[4 * (size_t)i + 3] = opacity[i];
        }
        if (!(var[i] > 0)) continue;
        const float log_var = logf(var[i]);
        float log_rho = 0, w;
        for (int k = 0; k < 3; k++) {
            const float f = filtered_log_scale(ls[k], log_var, &w);
            log_rho += ls[k] - f;
            ls[k] = f;
        }
        const float o = opacity[i];
        opacity[i] = log_sigmoid(o) + log_rho - logf(filtered_opacity_complement(o, log_rho));
    }
}

/* With a' = sigmoid(o) rho the filtered opacity and w_k = var / (s_k^2 + var):
 *   d log s'_k / d log s_k = 1 - w_k,  d log rho / d log s_k = w_k,
 *   d o' / d log rho = 1 / (1 - a'),  d o' / d o = (1 - a) / (1 - a'). */
void splat_filter3d_backward(const float *saved, const float *var, int n, float *d_log_scales, float *d_opacity)
{
    #pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) {
        if (!(var[i] > 0)) continue;
        const float *ls = saved + 4 * (size_t)i;
        const float o = ls[3];
        const float log_var = logf(var[i]);
        float w[3], log_rho = 0;
        for (int k = 0; k < 3; k++) log_rho += ls[k] - filtered_log_scale(ls[k], log_var, &w[k]);
        const float inv_na2 = 1.0f / filtered_opacity_complement(o, log_rho);
        const float g_o = d_opacity[i];
        float *g = d_log_scales + 3 * (size_t)i;
        for (int k = 0; k < 3; k++) g[k] = g[k] * (1.0f - w[k]) + g_o * w[k] * inv_na2;
        d_opacity[i] = g_o * inv_na2 / (1.0f + expf(o));
    }
}
