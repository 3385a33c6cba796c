/* nn_ops.h - the op table and what kernels share (private to src/nn).
 *
 * Each op has an infer function (checks its inputs, normalises its attributes - negative axes,
 * Reshape's 0 and -1 - and sets its outputs' shapes), a run function, and optionally the scratch
 * it needs per thread. nn_ops[] in nn_exec.c is in nn_op order; a static_assert ties it to
 * NN_OP_COUNT. Kernels split their work over OpenMP threads by output slices (no atomics) and
 * call OpenBLAS single-threaded from inside those slices.
 */
#ifndef PG_NN_OPS_H
#define PG_NN_OPS_H

#include "nn/nn_graph.h"

typedef struct {
    nn_graph *g;
    float *scratch;          /* scratch_floats per thread, thread t at scratch + t * scratch_floats */
    size_t scratch_floats;
} nn_ctx;

typedef struct {
    const char *name;
    int min_inputs, max_inputs;
    pg_status (*infer)(nn_graph *g, nn_node *n);
    void (*run)(const nn_ctx *c, const nn_node *n);
    size_t (*scratch)(const nn_graph *g, const nn_node *n); /* floats per thread; NULL: none */
} nn_op_info;

extern const nn_op_info nn_ops[NN_OP_COUNT];

static inline nn_tensor *nn_in(nn_graph *g, const nn_node *n, int i)
{
    return i < n->num_inputs && n->inputs[i] >= 0 ? &g->tensors[n->inputs[i]] : NULL;
}
static inline nn_tensor *nn_out(nn_graph *g, const nn_node *n, int i) { return &g->tensors[n->outputs[i]]; }
static inline float *nn_in_data(const nn_ctx *c, const nn_node *n, int i)
{
    return i < n->num_inputs && n->inputs[i] >= 0 ? nn_graph_data(c->g, n->inputs[i]) : NULL;
}
static inline float *nn_out_data(const nn_ctx *c, const nn_node *n, int i) { return nn_graph_data(c->g, n->outputs[i]); }

/* Sets the shape of output i, checking the limits; fails naming the node. */
pg_status nn_set_output(nn_graph *g, const nn_node *n, int i, int ndim, const int64_t *dims);
/* Fails "node 'name' (Op): message" with PG_ERR_FORMAT. */
pg_status nn_node_fail(const nn_node *n, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
/* Normalises an axis in [-ndim, ndim) to [0, ndim); -1 if out of range. */
int nn_axis(int64_t axis, int ndim);
/* Applies a fused activation in place to n floats. */
void nn_apply_act(float *x, size_t n, nn_activation act, float alpha);

/* C[M,N] = A[M,K] * B[K,N] (+ beta*C), row-major with leading dims, either operand transposed;
 * split over the OpenMP threads along M (or N when M is small). Called outside parallel regions. */
void nn_sgemm(int trans_a, int trans_b, int M, int N, int K, const float *A, int lda, const float *B, int ldb,
              float beta, float *C, int ldc);
/* The same on one thread (inside a parallel region). */
void nn_sgemm1(int trans_a, int trans_b, int M, int N, int K, const float *A, int lda, const float *B, int ldb,
               float beta, float *C, int ldc);

/* Per-op functions, one family per file. */
#define NN_DECLARE_OP(x) pg_status nn_infer_##x(nn_graph *g, nn_node *n); void nn_run_##x(const nn_ctx *c, const nn_node *n);
NN_DECLARE_OP(conv) NN_DECLARE_OP(conv_transpose)           /* ops_conv.c */
NN_DECLARE_OP(matmul) NN_DECLARE_OP(gemm)                   /* ops_matmul.c */
NN_DECLARE_OP(binary) NN_DECLARE_OP(unary)                  /* ops_elementwise.c */
NN_DECLARE_OP(layer_norm) NN_DECLARE_OP(softmax) NN_DECLARE_OP(reduce_mean) /* ops_norm.c */
NN_DECLARE_OP(reshape) NN_DECLARE_OP(transpose) NN_DECLARE_OP(slice) NN_DECLARE_OP(concat)
NN_DECLARE_OP(gather) NN_DECLARE_OP(expand) NN_DECLARE_OP(pad)  /* ops_shape.c */
NN_DECLARE_OP(resize)                                           /* ops_resize.c */
size_t nn_scratch_conv(const nn_graph *g, const nn_node *n);
size_t nn_scratch_conv_transpose(const nn_graph *g, const nn_node *n);
size_t nn_scratch_matmul(const nn_graph *g, const nn_node *n);
size_t nn_scratch_resize(const nn_graph *g, const nn_node *n);
/* NHWC group-1 Conv with (ky, kx, c)-ordered patches (ops_conv_nhwc.c, from nn-tflite); nn_run_conv
 * and nn_scratch_conv dispatch to it when nn_conv_nhwc_applies. */
int nn_conv_nhwc_applies(const nn_graph *g, const nn_node *n);
size_t nn_scratch_conv_nhwc(const nn_graph *g, const nn_node *n);
void nn_run_conv_nhwc(const nn_ctx *c, const nn_node *n);

/* Scalar reference kernels, test oracles for the fast ones (NCHW, group, dilation). */
void nn_conv_reference(float *y, const float *x, const float *w, const float *b, int N, int C, int H, int W,
                       int O, int OH, int OW, const nn_attrs *a);

#endif
