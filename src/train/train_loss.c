/* train_loss.c - the photometric + depth loss of one training image, with its gradient.
 *
 * L = L1_masked + gamma * (1 - SSIM_masked) + lambda_d * L_ssi_depth
 * The SSI depth term fits a per-image scale/shift (s, b) of the rendered depth to the target
 * on valid pixels in closed form, and divides by the target's variance so the weight does not
 * depend on the depth units. (s, b) are optimal, so their own derivatives vanish (envelope
 * theorem) and dL/d(depth_i) = 2 s (s d_i + b - t_i) / (n var).
 */
#include "train/train_loss.h"

#include <math.h>
#include <string.h>

float train_l1_forward_backward(const float *rgb, const float *target, const float *mask, int w, int h, float weight,
                                float *d_rgb)
{
    size_t px = (size_t)w * h;
    double n = 0, sum = 0;
    for (size_t i = 0; i < px; i++) n += mask ? mask[i] : 1.0f;
    if (n < 1) return 0;
    float g = (float)(weight / (3.0 * n));
    for (size_t i = 0; i < px; i++) {
        float mk = mask ? mask[i] : 1.0f;
        if (mk <= 0) continue;
        for (int c = 0; c < 3; c++) {
            float r = rgb[i * 3 + c] - target[i * 3 + c];
            sum += mk * fabsf(r);
            d_rgb[i * 3 + c] += r > 0 ? g * mk : (r < 0 ? -g * mk : 0.0f);
        }
    }
    return (float)(weight * sum / (3.0 * n));
}

float train_ssi_depth_forward_backward(const float *depth, const float *target, const float *mask, int w, int h,
                                       float weight, float *d_depth)
{
    size_t px = (size_t)w * h;
    double n = 0, sx = 0, sy = 0, sxx = 0, sxy = 0, syy = 0;
    for (size_t i = 0; i < px; i++) {
        if (!(target[i] > 0) || (mask && mask[i] <= 0.5f)) continue;
        double x = depth[i], y = target[i];
        n += 1;
        sx += x;
        sy += y;
        sxx += x * x;
        sxy += x * y;
        syy += y * y;
    }
    if (n < 16) return 0;
    double mx = sx / n, my = sy / n;
    double vx = sxx / n - mx * mx, vy = syy / n - my * my, cxy = sxy / n - mx * my;
    if (vy <= 1e-12) return 0;
    double s = vx > 1e-12 ? cxy / vx : 0.0;
    double b = my - s * mx;
    double loss = 0;
    double g = 2.0 * weight / (n * vy);
    for (size_t i = 0; i < px; i++) {
        if (!(target[i] > 0) || (mask && mask[i] <= 0.5f)) continue;
        double r = s * depth[i] + b - target[i];
        loss += r * r;
        d_depth[i] += (float)(g * s * r);
    }
    return (float)(weight * loss / (n * vy));
}
