/* train_loss.h - loss terms of one training image (value returned, gradient added). */
#ifndef PG_TRAIN_LOSS_H
#define PG_TRAIN_LOSS_H

#include <stddef.h>

/* weight * mean over valid pixels and channels of |rgb - target|; d_rgb (H,W,3) += gradient.
 * mask (H,W) may be NULL (all valid). */
float train_l1_forward_backward(const float *rgb, const float *target, const float *mask, int w, int h, float weight,
                                float *d_rgb);
/* weight * scale-and-shift-invariant L2 between rendered depth (H,W) and target (H,W, 0 =
 * invalid), normalised by the target variance; d_depth (H,W) += gradient. */
float train_ssi_depth_forward_backward(const float *depth, const float *target, const float *mask, int w, int h,
                                       float weight, float *d_depth);

#endif
