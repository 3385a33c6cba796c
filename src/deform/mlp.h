/* mlp.h - fully connected layer (Linear, optional fused ReLU) forward/backward over rows of points.
 *
 * Shapes (row-major, one row per point, PyTorch weight convention):
 *     x (M, in) with row stride ldx, w (out, in), b (out), y (M, out) with row stride ldy
 *     y = x w^T + b, then y = max(y, 0) if relu
 * The BLAS path uses cblas_sgemm (single-threaded per call: the network parallelises over chunks
 * of points itself, which keeps the results deterministic). The _ref functions are plain loops, kept
 * as the test oracle.
 */
#ifndef PG_DEFORM_MLP_H
#define PG_DEFORM_MLP_H


void mlp_linear_forward(float *y, int ldy, const float *x, int ldx, const float *w, const float *b, int M, int in,
                        int out, int relu);
/* Backward. If relu, d_y is first multiplied in place by (y > 0) (y = the forward's output).
 * d_x (M, in, stride ldx; may be NULL) is OVERWRITTEN (it is a per-chunk scratch, not a gradient
 * accumulator); d_w (out, in) and d_b (out) are ADDED to. */
void mlp_linear_backward(float *d_x, int lddx, float *d_w, float *d_b, float *d_y, int lddy, const float *y,
                         int ldy, const float *x, int ldx, const float *w, int M, int in, int out, int relu);

void mlp_linear_forward_ref(float *y, int ldy, const float *x, int ldx, const float *w, const float *b, int M,
                            int in, int out, int relu);
void mlp_linear_backward_ref(float *d_x, int lddx, float *d_w, float *d_b, float *d_y, int lddy, const float *y,
                             int ldy, const float *x, int ldx, const float *w, int M, int in, int out, int relu);

#endif
