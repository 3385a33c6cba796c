/* loss_depth.c - scale-and-shift-invariant L2 depth loss (see loss_depth.h). */
#include "optim/loss_depth.h"

#include <math.h>

static int ssi_valid(const float *pred, const float *target, const float *mask, long i)
{
    return (!mask || mask[i] > 0.5f) && isfinite(pred[i]) && isfinite(target[i]);
}
static double ssi_weight(const float *mask, long i) { return mask ? mask[i] : 1.0; }

float optim_ssi_depth_forward(optim_ssi_depth *fit, const float *pred, const float *target, const float *mask,
                              long n)
{
    fit->scale = 1.0;
    fit->shift = 0.0;
    fit->valid = 0;
    fit->weight = 0;
    fit->loss = 0.0f;
    /* Centred sums for a well-conditioned solve: first the means, then the (co)variances. */
    double sp = 0, st = 0, W = 0;
    long M = 0;
    for (long i = 0; i < n; i++) {
        if (!ssi_valid(pred, target, mask, i)) continue;
        double w = ssi_weight(mask, i);
        sp += w * pred[i];
        st += w * target[i];
        W += w;
        M++;
    }
    if (M < 2) return 0.0f;
    double mp = sp / W, mt = st / W, vpp = 0, vpt = 0;
    for (long i = 0; i < n; i++) {
        if (!ssi_valid(pred, target, mask, i)) continue;
        double w = ssi_weight(mask, i), dp = pred[i] - mp, dt = target[i] - mt;
        vpp += w * dp * dp;
        vpt += w * dp * dt;
    }
    /* Degenerate (constant prediction): keep s = 1 so the gradient still pushes pred toward target. */
    double s = vpp > 1e-12 * (mp * mp + 1.0) * W ? vpt / vpp : 1.0;
    double b = mt - s * mp;
    double loss = 0;
    for (long i = 0; i < n; i++) {
        if (!ssi_valid(pred, target, mask, i)) continue;
        double r = s * pred[i] + b - target[i];
        loss += ssi_weight(mask, i) * r * r;
    }
    fit->scale = s;
    fit->shift = b;
    fit->valid = M;
    fit->weight = W;
    fit->loss = (float)(loss / (2.0 * W));
    return fit->loss;
}

void optim_ssi_depth_backward(float *d_pred, float scale, const optim_ssi_depth *fit, const float *pred,
                              const float *target, const float *mask, long n)
{
    if (fit->valid < 2) return;
    double s = fit->scale, b = fit->shift, g = scale * s / fit->weight;
    for (long i = 0; i < n; i++) {
        if (!ssi_valid(pred, target, mask, i)) continue;
        d_pred[i] += (float)(g * ssi_weight(mask, i) * (s * pred[i] + b - target[i]));
    }
}
