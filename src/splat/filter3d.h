/* filter3d.h - the 3D smoothing filter of anti-aliased splatting (Mip-Splatting, Yu et al. 2024).
 *
 * A Gaussian no view trained at a finer scale than one pixel is convolved with an isotropic 3D
 * Gaussian of variance var = SPLAT_FILTER3D_VAR x (z / f)^2, where z / f is its smallest pixel
 * footprint over the training cameras: Sigma' = Sigma + var I keeps the rotation and turns each
 * scale s into sqrt(s^2 + var), and the opacity is multiplied by rho = prod s / sqrt(s^2 + var) so
 * the splat's integral is kept. A Gaussian thinner than a training pixel then renders as what the
 * training views saw, at any output size, instead of a needle. The filter is a per-Gaussian
 * constant: training recomputes it from the canonical means on a schedule (src/train) and the
 * checkpoint stores it.
 */
#ifndef PG_FILTER3D_H
#define PG_FILTER3D_H

#include "core/camera.h"

/* the filter's variance in squared training pixels: the smallest of 0.1, 0.15, 0.2 (Mip-Splatting's)
 * whose renders at 2x and 4x the training size are no worse than the training-size render upscaled
 * (0.1 was 0.2 dB under); smaller is sharper at the training camera (docs/viewer.md) */
#define SPLAT_FILTER3D_VAR 0.15f

/* var[i] for the n means from the ncam training cameras: the smallest footprint over the cameras
 * that see the point (in front, inside the frustum widened by 15 % on each side); over the
 * cameras it is in front of when none sees it; 0 when it is behind them all. */
void splat_filter3d_compute(const float *means, int n, const pg_camera *cams, int ncam, float *var);

/* In place, for freshly initialised Gaussians: each scale raised to at least the filter's std and
 * the opacity raised so the filtered Gaussian draws with the opacity it was initialised with
 * (capped at 0.99). Initial Gaussians smaller than a training pixel would otherwise start at a
 * fraction of their opacity (a fifth at 64x48) and the first hundreds of steps would only win it
 * back. */
void splat_filter3d_fit_init(float *log_scales, float *opacity, const float *var, int n);

/* floats per Gaussian the forward saves for the backward */
#define SPLAT_FILTER3D_SAVED 5

/* In place: log_scales (n, 3) and opacity logits (n) become the filtered ones. saved
 * (n, SPLAT_FILTER3D_SAVED) keeps what the backward needs (NULL: rendering only). */
void splat_filter3d_forward(float *log_scales, float *opacity, const float *var, int n, float *saved);
/* In place: the gradients d_log_scales (n, 3) and d_opacity (n) of the filtered values become
 * those of the unfiltered ones, from what the forward saved. */
void splat_filter3d_backward(const float *saved, const float *var, int n, float *d_log_scales, float *d_opacity);
/* The same over the listed rows only (training filters the rows the deformation changed). */
void splat_filter3d_forward_rows(float *log_scales, float *opacity, const float *var, const int *rows, int nrows,
                                 float *saved);
void splat_filter3d_backward_rows(const float *saved, const float *var, const int *rows, int nrows,
                                  float *d_log_scales, float *d_opacity);

#endif
