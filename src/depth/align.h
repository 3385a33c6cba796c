/* align.h - robust per-frame scale and shift of depth against a reference frame.
 *
 * Fits D_ref ~ alpha D_i + beta on static pixels, in DEPTH space with relative residuals
 * r = (alpha D_i + beta - D_ref) / D_ref. Why depth space: the product stage needs
 * D' = alpha D + beta in depth units (back-projection), and monocular-depth errors (noise,
 * per-frame drift) are multiplicative, so dividing by D_ref makes residuals comparably sized at
 * all distances (an unweighted depth fit lets the far background dominate; an inverse-depth fit
 * lets the near foreground dominate and its affine form is not D' = alpha D + beta).
 * Robustness: iteratively reweighted least squares with Tukey's biweight (c = 4.685 robust
 * sigmas, sigma from the median absolute residual), started from the median depth ratio.
 * When the static depths span too narrow a range (relative spread < min_spread) the shift is
 * not identifiable and only the scale is fitted.
 */
#ifndef PG_DEPTH_ALIGN_H
#define PG_DEPTH_ALIGN_H

#include <stddef.h>
#include "core/status.h"

typedef struct {
    int iterations;     /* IRLS iterations (default 12) */
    int fit_shift;      /* 0: scale only (default 1) */
    float min_spread;   /* min relative std of D_i on the mask to fit a shift (default 0.05) */
    long min_pixels;    /* fewer usable pixels -> PG_ERR_ARG (default 50) */
} depth_align_params;

typedef struct {
    double alpha, beta;
    double resid_before;  /* median |D_i - D_ref| / D_ref on the used pixels */
    double resid_after;   /* median |alpha D_i + beta - D_ref| / D_ref */
    long used;            /* pixels in mask with valid depth in both frames */
    long inliers;         /* pixels with non-zero final weight */
    int shift_fitted;
} depth_align_result;

void depth_align_defaults(depth_align_params *p);

/* d_i, d_ref: (n) depth (<= 0 or non-finite = invalid); mask: (n) 1 = use (NULL: all).
 * Fails with PG_ERR_ARG when fewer than min_pixels are usable (out->used says how many). */
pg_status depth_align_fit(const depth_align_params *p, const float *d_i, const float *d_ref,
                          const unsigned char *mask, size_t n, depth_align_result *out);

/* dst = alpha src + beta where src is valid and the result positive, else 0. */
void depth_align_apply(const float *src, size_t n, double alpha, double beta, float *dst);

static inline int depth_valid(float d) { return d > 0.0f && d < 3.0e38f; }

#endif
