/* mlp.c - Linear (+ReLU) layers on cblas_sgemm, and the naive reference (see mlp.h). */
#include "deform/mlp.h"

#include <cblas.h>
#include <stddef.h>

/* y = max(y + b, 0) or y + b, row by row (the chunk is still in cache after the GEMM). */
static void mlp_bias_act(float *y, int ldy, const float *b, int M, int out, int relu)
{
    for (int m = 0; m < M; m++) {
        float *r = y + (size_t)m * ldy;
        if (relu) {
            #pragma omp simd
            for (int o = 0; o < out; o++) {
                float v = r[o] + b[o];
                r[o] = v > 0.0f ? v : 0.0f;
            }
        } else {
            #pragma omp simd
            for (int o = 0; o < out; o++) r[o] += b[o];
        }
    }
}

void mlp_linear_forward(float *y, int ldy, const float *x, int ldx, const float *w, const float *b, int M, int in,
                        int out, int relu)
{
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasTrans, M, out, in, 1.0f, x, ldx, w, in, 0.0f, y, ldy);
    mlp_bias_act(y, ldy, b, M, out, relu);
}

/* Column sums of d_y into d_b, and the ReLU mask applied to d_y in place. */
static void mlp_mask_and_bias(float *d_b, float *d_y, int lddy, const float *y, int ldy, int M, int out, int relu)
{
    for (int m = 0; m < M; m++) {
        float *g = d_y + (size_t)m * lddy;
        if (relu) {
            const float *r = y + (size_t)m * ldy;
            #pragma omp simd
            for (int o = 0; o < out; o++) g[o] = r[o] > 0.0f ? g[o] : 0.0f;
        }
        #pragma omp simd
        for (int o = 0; o < out; o++) d_b[o] += g[o];
    }
}

void mlp_linear_backward(float *d_x, int lddx, float *d_w, float *d_b, float *d_y, int lddy, const float *y,
                         int ldy, const float *x, int ldx, const float *w, int M, int in, int out, int relu)
{
    mlp_mask_and_bias(d_b, d_y, lddy, y, ldy, M, out, relu);
    /* d_w (out, in) += d_y^T (out, M) x (M, in) */
    cblas_sgemm(CblasRowMajor, CblasTrans, CblasNoTrans, out, in, M, 1.0f, d_y, lddy, x, ldx, 1.0f, d_w, in);
    /* d_x (M, in) = d_y (M, out) w (out, in) */
    if (d_x)
        cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, M, in, out, 1.0f, d_y, lddy, w, in, 0.0f, d_x, lddx);
}

void mlp_linear_forward_ref(float *y, int ldy, const float *x, int ldx, const float *w, const float *b, int M,
                            int in, int out, int relu)
{
    for (int m = 0; m < M; m++)
        for (int o = 0; o < out; o++) {
            double s = b[o];
            for (int i = 0; i < in; i++) s += (double)x[(size_t)m * ldx + i] * w[(size_t)o * in + i];
            float v = (float)s;
            y[(size_t)m * ldy + o] = relu && v < 0.0f ? 0.0f : v;
        }
}

void mlp_linear_backward_ref(float *d_x, int lddx, float *d_w, float *d_b, float *d_y, int lddy, const float *y,
                             int ldy, const float *x, int ldx, const float *w, int M, int in, int out, int relu)
{
    mlp_mask_and_bias(d_b, d_y, lddy, y, ldy, M, out, relu);
    for (int o = 0; o < out; o++)
        for (int i = 0; i < in; i++) {
            double s = 0;
            for (int m = 0; m < M; m++) s += (double)d_y[(size_t)m * lddy + o] * x[(size_t)m * ldx + i];
            d_w[(size_t)o * in + i] += (float)s;
        }
    if (d_x)
        for (int m = 0; m < M; m++)
            for (int i = 0; i < in; i++) {
                double s = 0;
                for (int o = 0; o < out; o++) s += (double)d_y[(size_t)m * lddy + o] * w[(size_t)o * in + i];
                d_x[(size_t)m * lddx + i] = (float)s;
            }
}
