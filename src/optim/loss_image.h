/* loss_image.h - photometric losses on float images: L1, SSIM and D-SSIM, each with a backward.
 *
 * Images are (H, W, C) interleaved floats (pg_image layout). The optional mask is (H, W), values in
 * [0, 1], shared by all channels; NULL means every pixel counts with weight 1. Masked losses are
 * weighted means: sum(mask * term) / (C * sum(mask)), so a half-valid proxy view gives a loss on the
 * same scale as a full one. A mask that sums to zero gives loss 0 and no gradient.
 *
 * Backward functions ADD scale * dLoss/dpred into d_pred (scale is the loss weight, e.g. 0.8 for
 * L1 and 0.2 for D-SSIM); they never touch target or mask gradients.
 *
 *   optim_ssim_ws *ws;
 *   optim_ssim_create(&ws, H, W, C);
 *   float l1 = optim_l1_forward(pred, gt, mask, H, W, C);
 *   float ssim = optim_ssim_forward(ws, pred, gt, mask, H, W, C);   // keeps what backward needs
 *   optim_l1_backward(d_pred, 0.8f, pred, gt, mask, H, W, C);
 *   optim_ssim_backward(ws, d_pred, -0.2f, pred, gt, mask, H, W, C); // d(1 - ssim) = -d ssim
 *   optim_ssim_destroy(ws);
 */
#ifndef PG_OPTIM_LOSS_IMAGE_H
#define PG_OPTIM_LOSS_IMAGE_H

#include "core/status.h"

/* SSIM constants (Wang et al. 2004, as in the 3DGS reference). */
#define OPTIM_SSIM_TAPS 11
#define OPTIM_SSIM_SIGMA 1.5
#define OPTIM_SSIM_C1 (0.01 * 0.01)
#define OPTIM_SSIM_C2 (0.03 * 0.03)

/* Mean absolute error (masked weighted mean, see above). Can't fail. */
float optim_l1_forward(const float *pred, const float *target, const float *mask, int H, int W, int C);
/* d_pred += scale * dL1/dpred (sign(pred - target) * mask / norm; 0 where equal). */
void optim_l1_backward(float *d_pred, float scale, const float *pred, const float *target, const float *mask,
                       int H, int W, int C);

/* Workspace for SSIM: blurred moments of the last forward plus scratch; sized for one image size. */
typedef struct optim_ssim_ws optim_ssim_ws;

/* Allocates a workspace for (H, W, C) images. Fails with PG_ERR_ARG / PG_ERR_NOMEM. */
pg_status optim_ssim_create(optim_ssim_ws **ws, int H, int W, int C);
/* Frees the workspace; accepts NULL. */
void optim_ssim_destroy(optim_ssim_ws *ws);
/* Makes ws the workspace of an H x W image (same channels) inside the size it was created for, so
 * images of changing sizes (training crops) share one set of buffers. */
pg_status optim_ssim_reshape(optim_ssim_ws *ws, int H, int W);

/* Mean SSIM between pred and target: separable 11-tap Gaussian (sigma 1.5) with zero padding
 * ('same' size, like conv2d(padding=5) in the 3DGS reference), per channel, averaged over pixels and
 * channels (mask-weighted if mask != NULL). Stores the blurred moments in ws for the backward.
 * H, W, C must match the workspace (returns NaN otherwise). */
float optim_ssim_forward(optim_ssim_ws *ws, const float *pred, const float *target, const float *mask,
                         int H, int W, int C);
/* d_pred += scale * dSSIM/dpred, using the moments of the last forward on the same inputs.
 * For D-SSIM = 1 - SSIM pass -weight. */
void optim_ssim_backward(optim_ssim_ws *ws, float *d_pred, float scale, const float *pred, const float *target,
                         const float *mask, int H, int W, int C);

/* Convenience: D-SSIM = 1 - SSIM (forward only; use optim_ssim_backward with a negated scale). */
float optim_dssim_forward(optim_ssim_ws *ws, const float *pred, const float *target, const float *mask,
                          int H, int W, int C);

/* The normalised 11-tap Gaussian window (sums to 1), exposed for tests. */
void optim_ssim_window(float w[OPTIM_SSIM_TAPS]);

#endif
