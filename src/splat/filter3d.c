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

void splat_filter3d_fit_init(float *log_scales, float *opacity, const float *var, int n)
{
    #pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) {
        if (!(var[i] > 0)) continue;
        float *ls = log_scales + 3 * (size_t)i, keep = 1.0f;
        const float floor_ls = 0.5f * logf(var[i]);
        for (int k = 0; k < 3; k++) {
            ls[k] = fmaxf(ls[k], floor_ls);
            const float s2 = expf(2.0f * ls[k]);
            keep *= s2 / (s2 + var[i]);
        }
        const float a = 1.0f / (1.0f + expf(-opacity[i])), raised = fminf(a / sqrtf(keep), 0.99f);
        opacity[i] = logf(raised / (1.0f - raised));
    }
}

/* What forward and backward share for one Gaussian: w_k = var / (s_k^2 + var) (the filtered
 * log-scale is 0.5 log(s_k^2 + var)), rho = prod s_k / sqrt(s_k^2 + var), the opacity a and the
 * complements 1 - a and 1 - a rho (each formed without cancellation, so opacities near 1 keep
 * their precision). This runs over every Gaussian at every rendered time. */
typedef struct {
    float log_q[3], w[3], log_rho, rho, a, na, na_filtered;
} filter_terms;

/* log(1 + e^x) without overflow or underflow */
static float softplusf(float x)
{
    return x > 20.0f ? x : x < -20.0f ? expf(x) : log1pf(expf(x));
}

/* In logs throughout: the deformation can push a log-scale past +-44, where s^2 overflows or
 * underflows float (tabletop_dev at 160x120 went NaN at step ~415 that way). With
 * d_k = log var - 2 log s_k: w_k = sigmoid(d_k), log q_k = 2 log s_k + softplus(d_k) and
 * log rho = -1/2 sum softplus(d_k). */
static void filter_terms_of(const float ls[3], float o, float var, filter_terms *f)
{
    const float lv = logf(var);
    float log_keep = 0.0f;
    for (int k = 0; k < 3; k++) {
        const float d = lv - 2.0f * ls[k], sp = softplusf(d);
        f->w[k] = 1.0f / (1.0f + expf(-d));
        f->log_q[k] = 2.0f * ls[k] + sp;
        log_keep -= sp;
    }
    f->log_rho = 0.5f * log_keep;
    f->rho = expf(f->log_rho);
    /* 1 - rho = (1 - keep) / (1 + rho), 1 - keep = 1 - prod (1 - w_k) nested */
    const float lost = f->w[0] + (1.0f - f->w[0]) * (f->w[1] + (1.0f - f->w[1]) * f->w[2]);
    const float one_minus_rho = lost / (1.0f + f->rho);
    const float e = expf(-o);
    f->a = 1.0f / (1.0f + e);
    f->na = e < INFINITY ? e / (1.0f + e) : 1.0f;
    f->na_filtered = f->na + f->a * one_minus_rho;
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
        filter_terms f;
        filter_terms_of(ls, opacity[i], var[i], &f);
        for (int k = 0; k < 3; k++) ls[k] = 0.5f * f.log_q[k];
        /* a rho far below 1 (a needle the deformation squeezed to e^-36 on two axes): a rho under
         * float made the opacity -inf; logit(a rho) = log a + log rho to float precision there */
        const float o = opacity[i], log_a_rho = f.log_rho - softplusf(-o);
        opacity[i] = log_a_rho > -30.0f ? logf(f.a * f.rho / f.na_filtered) : log_a_rho;
    }
}

/* With a' = a rho the filtered opacity: d log s'_k / d log s_k = 1 - w_k, d log rho / d log s_k =
 * w_k, d o' / d log rho = 1 / (1 - a'), d o' / d o = (1 - a) / (1 - a'). */
void splat_filter3d_backward(const float *saved, const float *var, int n, float *d_log_scales, float *d_opacity)
{
    #pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) {
        if (!(var[i] > 0)) continue;
        const float *ls = saved + 4 * (size_t)i;
        filter_terms f;
        filter_terms_of(ls, ls[3], var[i], &f);
        const float g_o = d_opacity[i], inv_na = 1.0f / f.na_filtered;
        float *g = d_log_scales + 3 * (size_t)i;
        for (int k = 0; k < 3; k++) g[k] = g[k] * (1.0f - f.w[k]) + g_o * f.w[k] * inv_na;
        d_opacity[i] = g_o * f.na * inv_na;
    }
}
