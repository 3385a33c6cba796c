/* ops_conv_depthwise.c - the NHWC depthwise convolution (group = input channels = output
 * channels: MobileNet-style models such as FastDepth), any kernel, stride, dilation, padding.
 *
 * im2col + GEMM degenerates here into one GEMM of one output channel per group, so this kernel
 * works on pixels instead: for each output pixel, for each kernel tap inside the image, the C
 * contiguous input channels times that tap's C weights are added to C accumulators - a loop over
 * channels the compiler vectorises. Each thread first copies the weights from O1HW into its
 * scratch as (tap, channel), then takes whole output rows (threads write separate rows; no
 * atomics). nn_conv_reference (ops_conv.c) is the oracle test_nn_kernels checks it against. */
#include "nn/nn_ops.h"

#include <omp.h>

int nn_conv_depthwise_applies(const nn_graph *g, const nn_node *n)
{
    const nn_tensor *x = &g->tensors[n->inputs[0]], *w = &g->tensors[n->inputs[1]];
    return n->attr.layout == NN_LAYOUT_NHWC && x->ndim == 4 && n->attr.group > 1 && n->attr.group == x->dims[3] && w->dims[0] == x->dims[3];
}

size_t nn_scratch_conv_depthwise(const nn_graph *g, const nn_node *n)
{
    const nn_tensor *w = &g->tensors[n->inputs[1]];
    return (size_t)(w->dims[0] * w->dims[2] * w->dims[3]) + (size_t)w->dims[0]; /* weights (tap, C) + accumulators (C) */
}

/* One output row oy of image ni: y (OW, C). */
static void depthwise_row(float *restrict y, const float *restrict x, const float *restrict wt, const float *restrict bias,
                          float *restrict acc, int H, int W, int C, int OW, int kh, int kw, int oy, const nn_attrs *a)
{
    for (int ox = 0; ox < OW; ox++) {
        for (int c = 0; c < C; c++) acc[c] = bias ? bias[c] : 0.0f;
        for (int i = 0; i < kh; i++) {
            int iy = oy * a->stride[0] - a->pads[0] + i * a->dilation[0];
            if (iy < 0 || iy >= H) continue;
            for (int j = 0; j < kw; j++) {
                int ix = ox * a->stride[1] - a->pads[1] + j * a->dilation[1];
                if (ix < 0 || ix >= W) continue;
                const float *xp = x + ((size_t)iy * W + ix) * C, *wp = wt + ((size_t)i * kw + j) * C;
                for (int c = 0; c < C; c++) acc[c] += xp[c] * wp[c];
            }
        }
        memcpy(y + (size_t)ox * C, acc, (size_t)C * sizeof(float));
    }
    nn_apply_act(y, (size_t)OW * C, a->act, a->act_alpha);
}

void nn_run_conv_depthwise(const nn_ctx *c, const nn_node *n)
{
    const nn_tensor *tx = nn_in(c->g, n, 0), *tw = nn_in(c->g, n, 1), *ty = nn_out(c->g, n, 0);
    const float *x = nn_in_data(c, n, 0), *w = nn_in_data(c, n, 1), *bias = nn_in_data(c, n, 2);
    float *y = nn_out_data(c, n, 0);
    int N = (int)tx->dims[0], H = (int)tx->dims[1], W = (int)tx->dims[2], C = (int)tx->dims[3];
    int OH = (int)ty->dims[1], OW = (int)ty->dims[2], kh = (int)tw->dims[2], kw = (int)tw->dims[3];
    int rows = N * OH;
    double flops = 2.0 * rows * OW * (double)C * kh * kw;
    #pragma omp parallel if (flops >= NN_PAR_FLOPS)
    {
        float *wt = c->scratch + (size_t)omp_get_thread_num() * c->scratch_floats, *acc = wt + (size_t)kh * kw * C;
        for (int ch = 0; ch < C; ch++)
            for (int t = 0; t < kh * kw; t++) wt[(size_t)t * C + ch] = w[(size_t)ch * kh * kw + t];
        #pragma omp for schedule(static)
        for (int r = 0; r < rows; r++) {
            int ni = r / OH, oy = r % OH;
            depthwise_row(y + (size_t)r * OW * C, x + (size_t)ni * H * W * C, wt, bias, acc, H, W, C, OW, kh, kw, oy, &n->attr);
        }
    }
}
