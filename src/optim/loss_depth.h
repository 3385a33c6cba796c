/* loss_depth.h - scale-and-shift-invariant L2 depth loss with its backward.
 *
 * For a rendered depth map pred (n pixels) and a reference depth target, the per-image scale s and
 * shift b minimising sum_valid w_i (s*pred + b - target)^2 are solved in closed form (double
 * precision weighted normal equations); the loss is
 *     L = 1/(2W) * sum_valid w_i (s*pred_i + b - target_i)^2,    W = sum_valid w_i.
 * A pixel is valid when mask == NULL or mask[i] > 0.5, and both pred and target are finite; its
 * weight w_i is mask[i] (1 without a mask), so a 0/1 mask is the plain mean over valid pixels.
 * Because (s, b) minimise L, dL/ds = dL/db = 0 at the optimum (envelope theorem), so the gradient
 * with s and b held fixed, dL/dpred_i = s * w_i * r_i / W, is the exact total gradient.
 * If pred is (nearly) constant on the valid set the scale is undetermined; then s = 1 and b is the
 * mean residual, which keeps a useful gradient. Fewer than 2 valid pixels give loss 0.
 *
 *   optim_ssi_depth fit;
 *   float l = optim_ssi_depth_forward(&fit, pred, target, mask, H * W);
 *   optim_ssi_depth_backward(d_pred, lambda_depth, &fit, pred, target, mask, H * W);
 */
#ifndef PG_OPTIM_LOSS_DEPTH_H
#define PG_OPTIM_LOSS_DEPTH_H

typedef struct {
    double scale, shift; /* fitted s, b */
    long valid;          /* M: the number of valid pixels */
    double weight;       /* W: the sum of their weights */
    float loss;
} optim_ssi_depth;

/* Fits s, b and returns the loss (also stored in fit->loss). Can't fail. */
float optim_ssi_depth_forward(optim_ssi_depth *fit, const float *pred, const float *target, const float *mask,
                              long n);
/* d_pred[i] += scale * s * w_i * (s*pred_i + b - target_i) / W on valid pixels, with s, b from the forward. */
void optim_ssi_depth_backward(float *d_pred, float scale, const optim_ssi_depth *fit, const float *pred,
                              const float *target, const float *mask, long n);

#endif
