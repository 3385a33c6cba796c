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

#include <math.h>
#include <string.h>

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

/* e^x to within a few float ulps for x <= 88, flushed to e^-87 below -87 (softmax only needs
 * x <= 0), NaN for NaN: 2^n * e^r with |r| <= ln2/2 and the degree-7 Taylor polynomial of e^r (remainder
 * < 6e-9 relative). Plain arithmetic so `omp simd` loops vectorise it. */
static inline __attribute__((always_inline)) float nn_exp(float x)
{
    float in = x;
    x = x > -87.0f ? x : -87.0f; /* NaN too: the int conversion below must see a finite value */
    x = x < 88.0f ? x : 88.0f;
    /* n = round(x / ln2) by the 1.5 * 2^23 trick (floorf would stop gcc vectorising) */
    float n = (x * 1.44269504089f + 12582912.0f) - 12582912.0f;
    float r = fmaf(n, -0.693145751953125f, x);   /* ln2 split in two for an exact product */
    r = fmaf(n, -1.42860682030941723212e-6f, r);
    float p = 1.0f / 5040;
    p = fmaf(p, r, 1.0f / 720);
    p = fmaf(p, r, 1.0f / 120);
    p = fmaf(p, r, 1.0f / 24);
    p = fmaf(p, r, 1.0f / 6);
    p = fmaf(p, r, 0.5f);
    p = fmaf(p, r, 1.0f);
    p = fmaf(p, r, 1.0f);
    int32_t bits = ((int32_t)n + 127) << 23;
    float scale;
    memcpy(&scale, &bits, sizeof scale);
    return in == in ? p * scale : in;
}

/* Sum of n floats in 16 interleaved partial sums (vectorises without -ffast-math). */
static inline float nn_sum(const float *x, int64_t n)
{
    float acc[16] = { 0 };
    int64_t i = 0;
    for (; i + 16 <= n; i += 16)
        for (int j = 0; j < 16; j++) acc[j] += x[i + j];
    float s = 0;
    for (; i < n; i++) s += x[i];
    for (int j = 0; j < 16; j++) s += acc[j];
    return s;
}

/* erf(x): the Taylor series to x^11 for |x| < 0.5 (relative error < 1e-7, where the result is
 * small), Hastings' approximation (Abramowitz & Stegun 7.1.26, absolute error <= 1.5e-7) above.
 * Both are computed and one selected, so loops over it still vectorise. */
static inline __attribute__((always_inline)) float nn_erf(float x)
{
    float a = fabsf(x), t = 1.0f / fmaf(0.3275911f, a, 1.0f);
    float p = fmaf(fmaf(fmaf(fmaf(1.061405429f, t, -1.453152027f), t, 1.421413741f), t, -0.284496736f), t, 0.254829592f) * t;
    float big = 1.0f - p * nn_exp(-a * a);
    big = x < 0 ? -big : big;
    float x2 = x * x;
    float s = fmaf(fmaf(fmaf(fmaf(fmaf(-1.0f / 1320, x2, 1.0f / 216), x2, -1.0f / 42), x2, 1.0f / 10), x2, -1.0f / 3), x2, 1.0f);
    float small = 1.12837916709551257f * x * s;
    return a < 0.5f ? small : big;
}

/* Element counts below which an op runs on one thread. A fork/join costs a few microseconds on
 * idle cores and whole scheduler time slices when the cores are shared with other jobs (a thread
 * waits at the join for a partner that is not running), so memory-bound ops (copies, broadcasts,
 * bias adds) only fork for large tensors; compute-bound ones (exp, erf) fork sooner. */
#define NN_PAR_MEMORY ((int64_t)1 << 21)
#define NN_PAR_COMPUTE ((int64_t)1 << 18)
#define NN_PAR_FLOPS 1e7 /* GEMM-like ops: about 0.1 ms on one core */

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
/* nn_sgemm plus C[i][j] += bias[j] (bias may be NULL) and an activation, applied per block. */
void nn_sgemm_epilogue(int trans_a, int trans_b, int M, int N, int K, const float *A, int lda, const float *B, int ldb,
                       float beta, float *C, int ldc, const float *bias, nn_activation act, float act_alpha);
/* The same on one thread (inside a parallel region). */
void nn_sgemm1(int trans_a, int trans_b, int M, int N, int K, const float *A, int lda, const float *B, int ldb,
               float beta, float *C, int ldc);
/* The kernel nn_sgemm1 runs for A * B^T products with beta 0 (every convolution's): "avx512" (the
 * deformation network's f32 GEMM) on CPUs with AVX-512F, else "openblas"; PG_NN_GEMM=openblas or
 * nn_gemm_force_openblas(1) (tests) forces OpenBLAS. Other products always run on OpenBLAS. */
const char *nn_gemm_kernel(void);
void nn_gemm_force_openblas(int on);
/* The NHWC convolutions (the TFLite graphs: PyDNet++, FastDepth) run as bf16 products with f32
 * sums on AMX tiles (gemm_amx.h) when the CPU has them and the deformation network's backend is
 * AMX: 1 here. PG_NN_GEMM=f32 (or openblas), PG_KERNELS=f32|avx512bf16, PG_NO_AMX=1 or
 * nn_conv_force_f32(1) (tests) keep them f32. nn_conv_kernel() names what they run: "amx" or
 * nn_gemm_kernel()'s name. */
int nn_conv_bf16(void);
const char *nn_conv_kernel(void);
void nn_conv_force_f32(int on);

/* Per-op functions, one family per file. */
#define NN_DECLARE_OP(x) pg_status nn_infer_##x(nn_graph *g, nn_node *n); void nn_run_##x(const nn_ctx *c, const nn_node *n);
NN_DECLARE_OP(conv) NN_DECLARE_OP(conv_transpose)           /* ops_conv.c */
NN_DECLARE_OP(matmul) NN_DECLARE_OP(gemm)                   /* ops_matmul.c */
NN_DECLARE_OP(binary) NN_DECLARE_OP(unary) NN_DECLARE_OP(requantize) /* ops_elementwise.c */
NN_DECLARE_OP(layer_norm) NN_DECLARE_OP(softmax) NN_DECLARE_OP(reduce_mean) /* ops_norm.c */
NN_DECLARE_OP(reshape) NN_DECLARE_OP(transpose) NN_DECLARE_OP(slice) NN_DECLARE_OP(concat)
NN_DECLARE_OP(gather) NN_DECLARE_OP(expand) NN_DECLARE_OP(pad)  /* ops_shape.c */
NN_DECLARE_OP(resize)                                           /* ops_resize.c */
NN_DECLARE_OP(attention)                                        /* ops_matmul.c */
size_t nn_scratch_attention(const nn_graph *g, const nn_node *n);
size_t nn_scratch_conv(const nn_graph *g, const nn_node *n);
size_t nn_scratch_conv_transpose(const nn_graph *g, const nn_node *n);
size_t nn_scratch_matmul(const nn_graph *g, const nn_node *n);
size_t nn_scratch_resize(const nn_graph *g, const nn_node *n);
size_t nn_scratch_requantize(const nn_graph *g, const nn_node *n);
/* NHWC group-1 Conv with (ky, kx, c)-ordered patches (ops_conv_nhwc.c, from nn-tflite); nn_run_conv
 * and nn_scratch_conv dispatch to it when nn_conv_nhwc_applies. */
int nn_conv_nhwc_applies(const nn_graph *g, const nn_node *n);
size_t nn_scratch_conv_nhwc(const nn_graph *g, const nn_node *n);
void nn_run_conv_nhwc(const nn_ctx *c, const nn_node *n);

/* NHWC depthwise Conv (group = C = O) over pixels (ops_conv_depthwise.c); nn_run_conv and
 * nn_scratch_conv dispatch to it when nn_conv_depthwise_applies. */
int nn_conv_depthwise_applies(const nn_graph *g, const nn_node *n);
size_t nn_scratch_conv_depthwise(const nn_graph *g, const nn_node *n);
void nn_run_conv_depthwise(const nn_ctx *c, const nn_node *n);

/* Scalar reference kernels, test oracles for the fast ones (NCHW, group, dilation). */
void nn_conv_reference(float *y, const float *x, const float *w, const float *b, int N, int C, int H, int W,
                       int O, int OH, int OW, const nn_attrs *a);

#endif
