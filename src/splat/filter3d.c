/* filter3d.c - the 3D smoothing filter: per-Gaussian variance from the training cameras, and the
 * filtered scales and opacity forward and backward (see filter3d.h for the model). */
#include "splat/filter3d.h"

#include <math.h>
#include <stddef.h>

#include "splat/filter3d_kernels.h"
#include "splat/raster.h"

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

/* log(1 + e^x) and the logistic sigmoid of x from one exponential, e = e^-|x| (never overflows):
 * this runs for every Gaussian at every rendered time, so each transcendental counts. */
static inline void softplus_sigmoid(float x, float *sp, float *sig)
{
    const float e = expf(-fabsf(x)), inv = 1.0f / (1.0f + e);
    *sp = fmaxf(x, 0.0f) + log1pf(e);
    *sig = x >= 0.0f ? inv : e * inv;
}

/* In logs throughout: the deformation can push a log-scale past +-44, where s^2 overflows or
 * underflows float (tabletop_dev at 160x120 went NaN at step ~415 that way). With
 * d_k = log var - 2 log s_k: w_k = var / (s_k^2 + var) = sigmoid(d_k), the filtered log-scale is
 * log s_k + softplus(d_k) / 2 and log rho = -1/2 sum softplus(d_k). The opacity a = sigmoid(o),
 * 1 - a and 1 - a rho = (1 - a) + a (1 - rho) are formed without cancellation, so opacities near 1
 * keep their precision. What the backward needs is saved (w_k, (1 - a) / (1 - a rho),
 * 1 / (1 - a rho)), so it runs without a transcendental. */
static inline void filter_row_forward(float *log_scales, float *opacity, const float *var, int i, float *saved)
{
    if (!(var[i] > 0)) return;
    float *ls = log_scales + 3 * (size_t)i, w[3], log_keep = 0.0f;
    const float lv = logf(var[i]);
    for (int k = 0; k < 3; k++) {
        float sp;
        softplus_sigmoid(lv - 2.0f * ls[k], &sp, &w[k]);
        ls[k] += 0.5f * sp;
        log_keep -= sp;
    }
    const float log_rho = 0.5f * log_keep, rho = expf(log_rho);
    /* 1 - rho = (1 - keep) / (1 + rho), 1 - keep = 1 - prod (1 - w_k) nested */
    const float lost = w[0] + (1.0f - w[0]) * (w[1] + (1.0f - w[1]) * w[2]);
    const float o = opacity[i], eo = expf(-fabsf(o)), inv = 1.0f / (1.0f + eo);
    const float a = o >= 0.0f ? inv : eo * inv, na = o >= 0.0f ? eo * inv : inv;
    const float na_filtered = na + a * (lost / (1.0f + rho));
    /* a rho far below 1 (a needle the deformation squeezed to e^-36 on two axes): a rho under
     * float made the opacity -inf; logit(a rho) = log a + log rho to float precision there */
    const float log_a_rho = log_rho - (fmaxf(-o, 0.0f) + log1pf(eo));
    opacity[i] = log_a_rho > -30.0f ? logf(a * rho / na_filtered) : log_a_rho;
    if (saved) {
        float *sv = saved + SPLAT_FILTER3D_SAVED * (size_t)i;
        sv[0] = w[0], sv[1] = w[1], sv[2] = w[2];
        sv[3] = na / na_filtered;
        sv[4] = 1.0f / na_filtered;
    }
}

/* The kernel family the forward uses: the rasterizer's (PG_RASTER chooses), unless a test set one. */
static int filter_kernel = -1;

void splat_filter3d_set_kernel(splat_kernel_kind k) { filter_kernel = splat_kernel_supported(k) ? (int)k : -1; }

static int use_avx512(void)
{
#if defined(__x86_64__) && defined(__GNUC__)
    int k = filter_kernel >= 0 ? filter_kernel : (int)splat_kernel_default();
    return k == SPLAT_KERNEL_AVX512;
#else
    return 0;
#endif
}

/* Rows i0 .. i0+n-1, or rows[0 .. n-1] when rows is set, 16 at a time on AVX-512. */
static void forward_rows(float *log_scales, float *opacity, const float *var, const int *rows, int n, float *saved)
{
#if defined(__x86_64__) && defined(__GNUC__)
    if (use_avx512()) {
        const int blocks = (n + 15) / 16;
        #pragma omp parallel for schedule(static)
        for (int b = 0; b < blocks; b++) {
            const int k0 = 16 * b, m = n - k0 < 16 ? n - k0 : 16;
            splat_filter3d_forward16_avx512(log_scales, opacity, var, rows ? rows + k0 : NULL, k0, m, saved);
        }
        return;
    }
#endif
    #pragma omp parallel for schedule(static)
    for (int k = 0; k < n; k++) filter_row_forward(log_scales, opacity, var, rows ? rows[k] : k, saved);
}

void splat_filter3d_forward(float *log_scales, float *opacity, const float *var, int n, float *saved)
{
    forward_rows(log_scales, opacity, var, NULL, n, saved);
}

void splat_filter3d_forward_rows(float *log_scales, float *opacity, const float *var, const int *rows, int nrows,
                                 float *saved)
{
    forward_rows(log_scales, opacity, var, rows, nrows, saved);
}

/* With a' = a rho the filtered opacity: d log s'_k / d log s_k = 1 - w_k, d log rho / d log s_k =
 * w_k, d o' / d log rho = 1 / (1 - a'), d o' / d o = (1 - a) / (1 - a'). */
static inline void filter_row_backward(const float *saved, const float *var, int i, float *d_log_scales, float *d_opacity)
{
    if (!(var[i] > 0)) return;
    const float *sv = saved + SPLAT_FILTER3D_SAVED * (size_t)i;
    const float g_o = d_opacity[i];
    float *g = d_log_scales + 3 * (size_t)i;
    for (int k = 0; k < 3; k++) g[k] = g[k] * (1.0f - sv[k]) + g_o * sv[k] * sv[4];
    d_opacity[i] = g_o * sv[3];
}

void splat_filter3d_backward(const float *saved, const float *var, int n, float *d_log_scales, float *d_opacity)
{
    #pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++) filter_row_backward(saved, var, i, d_log_scales, d_opacity);
}

void splat_filter3d_backward_rows(const float *saved, const float *var, const int *rows, int nrows,
                                  float *d_log_scales, float *d_opacity)
{
    #pragma omp parallel for schedule(static)
    for (int k = 0; k < nrows; k++) filter_row_backward(saved, var, rows[k], d_log_scales, d_opacity);
}
