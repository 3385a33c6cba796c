/* loss_reg.h - K-Planes regularisers on one feature plane, each with its backward.
 *
 * A plane is (H, W, C) floats: H rows, W columns, C channels per texel (the layout src/deform uses:
 * rows run along the plane's second axis, which is time for the (x,t), (y,t), (z,t) planes).
 * Definitions follow K-Planes / 4DGaussians:
 *   TV           = 2 * ( sum (p[i+1,j]-p[i,j])^2 / (C (H-1) W) + sum (p[i,j+1]-p[i,j])^2 / (C H (W-1)) )
 *   time smooth  = mean over C (H-2) W of (p[i+1,j] - 2 p[i,j] + p[i-1,j])^2       (along rows = time)
 *   L1-to-one    = mean over C H W of |1 - p|
 * Backward functions ADD scale * dLoss/dplane into d_plane. Sizes too small for a term give 0.
 * All are deterministic (per-row sums added in row order; backward rows never share writes).
 * Forward functions return NaN only if a small row-sum buffer cannot be allocated.
 */
#ifndef PG_OPTIM_LOSS_REG_H
#define PG_OPTIM_LOSS_REG_H

float optim_plane_tv_forward(const float *plane, int H, int W, int C);
void optim_plane_tv_backward(float *d_plane, float scale, const float *plane, int H, int W, int C);

float optim_plane_time_smooth_forward(const float *plane, int H, int W, int C);
void optim_plane_time_smooth_backward(float *d_plane, float scale, const float *plane, int H, int W, int C);

float optim_plane_l1_one_forward(const float *plane, int H, int W, int C);
void optim_plane_l1_one_backward(float *d_plane, float scale, const float *plane, int H, int W, int C);

#endif
