/* align.c - robust scale/shift alignment of one depth frame to the reference (see align.h). */
#include "depth/align.h"
#include "core/mathx.h"

#include <math.h>
#include <stdlib.h>

void depth_align_defaults(depth_align_params *p)
{
    p->iterations = 12;
    p->fit_shift = 1;
    p->min_spread = 0.05f;
    p->min_pixels = 50;
}

/* Median of v[0..m) (reorders v). */
static double median_inplace(double *v, size_t m)
{
    double hi = pg_select_kth(v, m, m / 2);
    if (m % 2) return hi;
    double lo = v[0];
    for (size_t k = 1; k < m / 2; k++)
        if (v[k] > lo) lo = v[k];
    return 0.5 * (lo + hi);
}

pg_status depth_align_fit(const depth_align_params *p, const float *d_i, const float *d_ref,
                          const unsigned char *mask, size_t n, depth_align_result *out)
{
    out->alpha = 1.0;
    out->beta = 0.0;
    out->resid_before = out->resid_after = 0.0;
    out->used = out->inliers = 0;
    out->shift_fitted = 0;
    size_t m = 0;
    for (size_t k = 0; k < n; k++)
        if ((!mask || mask[k]) && depth_valid(d_i[k]) && depth_valid(d_ref[k])) m++;
    out->used = (long)m;
    if ((long)m < p->min_pixels || m < 3)
        return pg_fail(PG_ERR_ARG, "depth alignment: only %zu usable static pixels (need %ld)", m, p->min_pixels);
    /* Compact copies: x = D_i, y = D_ref, plus a scratch array for medians. */
    double *buf = pg_malloc(sizeof(double) * m * 3, "depth alignment buffers");
    if (!buf) return PG_ERR_NOMEM;
    double *x = buf, *y = buf + m, *r = buf + 2 * m;
    size_t j = 0;
    for (size_t k = 0; k < n; k++)
        if ((!mask || mask[k]) && depth_valid(d_i[k]) && depth_valid(d_ref[k])) {
            x[j] = d_i[k];
            y[j] = d_ref[k];
            j++;
        }
    for (size_t k = 0; k < m; k++) r[k] = fabs(x[k] - y[k]) / y[k];
    out->resid_before = median_inplace(r, m);

    /* Start: median ratio (scale only), robust to any outlier fraction below 50 %. */
    for (size_t k = 0; k < m; k++) r[k] = y[k] / x[k];
    double alpha = median_inplace(r, m), beta = 0.0;

    /* Relative spread of D_i decides whether the shift is identifiable. */
    double mean = 0, var = 0;
    for (size_t k = 0; k < m; k++) mean += x[k];
    mean /= m;
    for (size_t k = 0; k < m; k++) var += (x[k] - mean) * (x[k] - mean);
    var /= m;
    int fit_shift = p->fit_shift && sqrt(var) > p->min_spread * mean;

    long inliers = (long)m;
    for (int it = 0; it < p->iterations; it++) {
        for (size_t k = 0; k < m; k++) r[k] = fabs((alpha * x[k] + beta - y[k]) / y[k]);
        double sigma = 1.4826 * median_inplace(r, m);
        if (sigma < 1e-6) sigma = 1e-6;
        const double c = 4.685 * sigma;
        /* Weighted normal equations of min sum w_k ((alpha x + beta - y) / y)^2. */
        double sxx = 0, sx = 0, s1 = 0, sxy = 0, sy = 0;
        inliers = 0;
        for (size_t k = 0; k < m; k++) {
            double res = (alpha * x[k] + beta - y[k]) / y[k];
            if (fabs(res) >= c) continue;
            double t = res / c, w = (1 - t * t) * (1 - t * t) / (y[k] * y[k]);
            sxx += w * x[k] * x[k];
            sx += w * x[k];
            s1 += w;
            sxy += w * x[k] * y[k];
            sy += w * y[k];
            inliers++;
        }
        if (inliers < 3 || sxx <= 0) break;
        double na, nb;
        double det = sxx * s1 - sx * sx;
        if (fit_shift && det > 1e-12 * sxx * s1) {
            na = (sxy * s1 - sx * sy) / det;
            nb = (sxx * sy - sx * sxy) / det;
        } else {
            na = sxy / sxx;
            nb = 0.0;
        }
        if (!(na > 0) || !isfinite(nb)) {
            /* A non-positive scale means the shift ran away: keep scale only. */
            fit_shift = 0;
            na = sxy / sxx;
            nb = 0.0;
        }
        int done = fabs(na - alpha) < 1e-9 * fabs(alpha) && fabs(nb - beta) < 1e-9 * (fabs(beta) + mean * alpha);
        alpha = na;
        beta = nb;
        if (done) break;
    }
    for (size_t k = 0; k < m; k++) r[k] = fabs((alpha * x[k] + beta - y[k]) / y[k]);
    out->resid_after = median_inplace(r, m);
    out->alpha = alpha;
    out->beta = beta;
    out->inliers = inliers;
    out->shift_fitted = fit_shift;
    free(buf);
    return PG_OK;
}

void depth_align_apply(const float *src, size_t n, double alpha, double beta, float *dst)
{
    for (size_t k = 0; k < n; k++) {
        float v = depth_valid(src[k]) ? (float)(alpha * src[k] + beta) : 0.0f;
        dst[k] = depth_valid(v) ? v : 0.0f;
    }
}
