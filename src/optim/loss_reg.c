/* loss_reg.c - K-Planes regularisers (see loss_reg.h).
 *
 * The HexPlane has ~2.5 M plane values and these run every iteration, so every loop is a
 * vectorisable pass over one row, rows run in parallel, and the forward sums go through per-row
 * partial sums added in row order (the result does not depend on the thread count). Backward
 * passes compute each output element once (gather form), so rows never share writes.
 */
#include "optim/loss_reg.h"

#include <math.h>
#include <stddef.h>
#include <stdlib.h>

/* Sums rows[0..H) in order; frees rows. */
static double sum_rows(double *rows, int H)
{
    double t = 0;
    for (int i = 0; i < H; i++) t += rows[i];
    free(rows);
    return t;
}

/* Row-parallel threshold: tiny planes (tests) stay serial. */
#define PAR_MIN 65536

float optim_plane_tv_forward(const float *p, int H, int W, int C)
{
    size_t row = (size_t)W * C;
    double *th = malloc(2 * (size_t)(H > 0 ? H : 1) * sizeof(double));
    if (!th) return NAN;
    double *tw = th + H;
    #pragma omp parallel for schedule(static) if ((size_t)H * row > PAR_MIN)
    for (int i = 0; i < H; i++) {
        const float *r = p + i * row;
        float sh = 0, sw = 0;
        if (i + 1 < H) {
            const float *r1 = r + row;
            #pragma omp simd reduction(+ : sh)
            for (size_t e = 0; e < row; e++) {
                float d = r1[e] - r[e];
                sh += d * d;
            }
        }
        #pragma omp simd reduction(+ : sw)
        for (size_t e = 0; e < row - C; e++) {
            float d = r[e + C] - r[e];
            sw += d * d;
        }
        th[i] = sh;
        tw[i] = sw;
    }
    double sh = 0, sw = 0;
    for (int i = 0; i < H; i++) {
        sh += th[i];
        sw += tw[i];
    }
    free(th);
    double out = 0;
    if (H > 1) out += sh / ((double)C * (H - 1) * W);
    if (W > 1) out += sw / ((double)C * H * (W - 1));
    return (float)(2.0 * out);
}

void optim_plane_tv_backward(float *d, float scale, const float *p, int H, int W, int C)
{
    size_t row = (size_t)W * C;
    float gh = H > 1 ? (float)(4.0 * scale / ((double)C * (H - 1) * W)) : 0.0f;
    float gw = W > 1 ? (float)(4.0 * scale / ((double)C * H * (W - 1))) : 0.0f;
    #pragma omp parallel for schedule(static) if ((size_t)H * row > PAR_MIN)
    for (int i = 0; i < H; i++) {
        const float *r = p + i * row;
        float *dr = d + i * row;
        /* vertical neighbours: + gh (p - up) - gh (down - p) */
        if (i > 0) {
            const float *u = r - row;
            #pragma omp simd
            for (size_t e = 0; e < row; e++) dr[e] += gh * (r[e] - u[e]);
        }
        if (i + 1 < H) {
            const float *dn = r + row;
            #pragma omp simd
            for (size_t e = 0; e < row; e++) dr[e] -= gh * (dn[e] - r[e]);
        }
        /* horizontal neighbours (texels C apart) */
        #pragma omp simd
        for (size_t e = C; e < row; e++) dr[e] += gw * (r[e] - r[e - C]);
        #pragma omp simd
        for (size_t e = 0; e < row - C; e++) dr[e] -= gw * (r[e + C] - r[e]);
    }
}

float optim_plane_time_smooth_forward(const float *p, int H, int W, int C)
{
    if (H < 3) return 0.0f;
    size_t row = (size_t)W * C;
    double *rs = malloc((size_t)H * sizeof(double));
    if (!rs) return NAN;
    rs[0] = rs[H - 1] = 0;
    #pragma omp parallel for schedule(static) if ((size_t)H * row > PAR_MIN)
    for (int i = 1; i < H - 1; i++) {
        const float *r = p + i * row;
        float t = 0;
        #pragma omp simd reduction(+ : t)
        for (size_t e = 0; e < row; e++) {
            float s = r[e + row] - 2.0f * r[e] + r[e - row];
            t += s * s;
        }
        rs[i] = t;
    }
    return (float)(sum_rows(rs, H) / ((double)C * (H - 2) * W));
}

void optim_plane_time_smooth_backward(float *d, float scale, const float *p, int H, int W, int C)
{
    if (H < 3) return;
    size_t row = (size_t)W * C;
    float g = (float)(2.0 * scale / ((double)C * (H - 2) * W));
    /* dL/dp[i] = g (s[i-1] - 2 s[i] + s[i+1]) over the second differences s[c], 1 <= c <= H-2 */
    #pragma omp parallel for schedule(static) if ((size_t)H * row > PAR_MIN)
    for (int i = 0; i < H; i++) {
        float *dr = d + i * row;
        for (int c = i - 1; c <= i + 1; c++) {
            if (c < 1 || c + 1 >= H) continue;
            const float *r = p + c * row;
            float w = c == i ? -2.0f * g : g;
            #pragma omp simd
            for (size_t e = 0; e < row; e++) dr[e] += w * (r[e + row] - 2.0f * r[e] + r[e - row]);
        }
    }
}

float optim_plane_l1_one_forward(const float *p, int H, int W, int C)
{
    size_t row = (size_t)W * C, n = (size_t)H * row;
    if (!n) return 0.0f;
    double *rs = malloc((size_t)H * sizeof(double));
    if (!rs) return NAN;
    #pragma omp parallel for schedule(static) if (n > PAR_MIN)
    for (int i = 0; i < H; i++) {
        const float *r = p + i * row;
        float t = 0;
        #pragma omp simd reduction(+ : t)
        for (size_t e = 0; e < row; e++) t += fabsf(1.0f - r[e]);
        rs[i] = t;
    }
    return (float)(sum_rows(rs, H) / n);
}

void optim_plane_l1_one_backward(float *d, float scale, const float *p, int H, int W, int C)
{
    size_t n = (size_t)H * W * C;
    if (!n) return;
    float g = (float)(scale / (double)n);
    #pragma omp parallel for simd schedule(static) if (n > PAR_MIN)
    for (size_t k = 0; k < n; k++) d[k] += p[k] > 1.0f ? g : (p[k] < 1.0f ? -g : 0.0f);
}
