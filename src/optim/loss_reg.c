/* loss_reg.c - K-Planes regularisers (see loss_reg.h). Planes are small (<= ~1M floats), so these
 * run serially; the sums are in double so the result does not depend on the thread count. */
#include "optim/loss_reg.h"

#include <math.h>
#include <stddef.h>

float optim_plane_tv_forward(const float *p, int H, int W, int C)
{
    double th = 0, tw = 0;
    size_t row = (size_t)W * C;
    for (int i = 0; i < H; i++) {
        const float *r = p + i * row;
        if (i + 1 < H) {
            const float *r1 = r + row;
            for (size_t e = 0; e < row; e++) {
                double d = r1[e] - r[e];
                th += d * d;
            }
        }
        for (size_t e = 0; e + C < row; e++) {
            double d = r[e + C] - r[e];
            tw += d * d;
        }
    }
    double out = 0;
    if (H > 1) out += th / ((double)C * (H - 1) * W);
    if (W > 1) out += tw / ((double)C * H * (W - 1));
    return (float)(2.0 * out);
}

void optim_plane_tv_backward(float *d, float scale, const float *p, int H, int W, int C)
{
    size_t row = (size_t)W * C;
    float gh = H > 1 ? (float)(4.0 * scale / ((double)C * (H - 1) * W)) : 0.0f;
    float gw = W > 1 ? (float)(4.0 * scale / ((double)C * H * (W - 1))) : 0.0f;
    for (int i = 0; i < H; i++) {
        const float *r = p + i * row;
        float *dr = d + i * row;
        for (size_t e = 0; e < row; e++) {
            float g = 0;
            if (i + 1 < H) g -= gh * (r[e + row] - r[e]);
            if (i > 0) g += gh * (r[e] - r[e - row]);
            if (e + C < row) g -= gw * (r[e + C] - r[e]);
            if (e >= (size_t)C) g += gw * (r[e] - r[e - C]);
            dr[e] += g;
        }
    }
}

float optim_plane_time_smooth_forward(const float *p, int H, int W, int C)
{
    if (H < 3) return 0.0f;
    size_t row = (size_t)W * C;
    double t = 0;
    for (int i = 1; i + 1 < H; i++)
        for (size_t e = 0; e < row; e++) {
            size_t k = i * row + e;
            double s = (double)p[k + row] - 2.0 * p[k] + p[k - row];
            t += s * s;
        }
    return (float)(t / ((double)C * (H - 2) * W));
}

void optim_plane_time_smooth_backward(float *d, float scale, const float *p, int H, int W, int C)
{
    if (H < 3) return;
    size_t row = (size_t)W * C;
    double g = 2.0 * scale / ((double)C * (H - 2) * W);
    /* Gather form (each output written once): dL/dp[i] = g (s[i-1] - 2 s[i] + s[i+1]) over valid s. */
    for (int i = 0; i < H; i++)
        for (size_t e = 0; e < row; e++) {
            double acc = 0;
            for (int c = i - 1; c <= i + 1; c++) {
                if (c < 1 || c + 1 >= H) continue;
                size_t k = c * row + e;
                double s = (double)p[k + row] - 2.0 * p[k] + p[k - row];
                acc += (c == i ? -2.0 : 1.0) * s;
            }
            d[i * row + e] += (float)(g * acc);
        }
}

float optim_plane_l1_one_forward(const float *p, int H, int W, int C)
{
    size_t n = (size_t)H * W * C;
    if (!n) return 0.0f;
    double t = 0;
    for (size_t k = 0; k < n; k++) t += fabs(1.0 - p[k]);
    return (float)(t / n);
}

void optim_plane_l1_one_backward(float *d, float scale, const float *p, int H, int W, int C)
{
    size_t n = (size_t)H * W * C;
    if (!n) return;
    float g = (float)(scale / (double)n);
    for (size_t k = 0; k < n; k++) d[k] += p[k] > 1.0f ? g : (p[k] < 1.0f ? -g : 0.0f);
}
