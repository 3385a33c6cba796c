/* ops_matmul.c - MatMul (numpy semantics, batch broadcast) and Gemm on cblas_sgemm, or on the
 * deformation network's AVX-512 f32 kernel for the A * B^T products of convolutions.
 * OpenBLAS runs single-threaded per call (nn_graph_run sets it); the threads split the work:
 * one big product along its rows, a batch of products (attention heads) one product per thread. */
#include "nn/nn_ops.h"

#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include <cblas.h>

#include "deform/gemm_amx.h"

static int forced_openblas; /* written by tests only, outside parallel regions */

void nn_gemm_force_openblas(int on) { forced_openblas = on; }

/* Read on every call (from any thread: nothing is cached, so nothing races); a getenv per
 * product is nothing next to the product. */
const char *nn_gemm_kernel(void)
{
    const char *env = getenv("PG_NN_GEMM");
    if (forced_openblas || (env && strcmp(env, "openblas") == 0)) return "openblas";
#if defined(__x86_64__) && defined(__GNUC__)
    if (__builtin_cpu_supports("avx512f")) return "avx512";
#endif
    return "openblas";
}

static int forced_conv_f32; /* tests only, as above */

void nn_conv_force_f32(int on) { forced_conv_f32 = on; }

int nn_conv_bf16(void)
{
    const char *env = getenv("PG_NN_GEMM");
    if (forced_conv_f32 || forced_openblas || (env && (strcmp(env, "openblas") == 0 || strcmp(env, "f32") == 0)))
        return 0;
    return gemm_bf16_backend() == GEMM_BF16_AMX; /* AVX512-BF16 measured slower than f32 (docs/nn.md) */
}

const char *nn_conv_kernel(void)
{
    return nn_conv_bf16() ? gemm_bf16_name(gemm_bf16_backend()) : nn_gemm_kernel();
}

/* C = A * B^T (beta 0) on gemm_f32, which reads B as (K, N) rows padded to 16 columns: B is
 * copied transposed (K x N, a 1/M share of the product's work). OpenBLAS picks its kernels from
 * the CPU model or OPENBLAS_CORETYPE; an environment pinned to its AVX2 "Haswell" kernels ran
 * PyDNet++ at 274-293 ms a frame on a Zen 5 that does it in 191-201 here (docs/nn.md). Returns 0
 * when the copy cannot be allocated (the caller falls back to OpenBLAS). */
static int own_gemm_nt(int M, int N, int K, const float *A, int lda, const float *B, int ldb, float *C, int ldc)
{
    const int ldt = (N + 15) & ~15;
    float *bt = malloc((size_t)K * ldt * sizeof(float));
    if (!bt) return 0;
    for (int k = 0; k < K; k++) {
        float *row = bt + (size_t)k * ldt;
        for (int n = 0; n < N; n++) row[n] = B[(size_t)n * ldb + k];
        for (int n = N; n < ldt; n++) row[n] = 0.0f;
    }
    gemm_amx_epilogue e;
    memset(&e, 0, sizeof e);
    e.c = C;
    e.ldc = ldc;
    gemm_f32(A, lda, bt, ldt, M, N, K, &e);
    free(bt);
    return 1;
}

void nn_sgemm1(int trans_a, int trans_b, int M, int N, int K, const float *A, int lda, const float *B, int ldb,
               float beta, float *C, int ldc)
{
    if (M <= 0 || N <= 0) return;
    if (K <= 0) {
        for (int i = 0; i < M; i++) for (int j = 0; j < N; j++) C[(size_t)i * ldc + j] *= beta;
        return;
    }
    if (!trans_a && trans_b && beta == 0.0f && strcmp(nn_gemm_kernel(), "avx512") == 0 &&
        own_gemm_nt(M, N, K, A, lda, B, ldb, C, ldc))
        return;
    cblas_sgemm(CblasRowMajor, trans_a ? CblasTrans : CblasNoTrans, trans_b ? CblasTrans : CblasNoTrans, M, N, K, 1.0f,
                A, lda, B, ldb, beta, C, ldc);
}

/* bias (one value per column, NULL: none) and activation on rows [r0, r1) x columns [c0, c1) of C. */
static void epilogue(float *C, int ldc, int r0, int r1, int c0, int c1, const float *bias, nn_activation act, float alpha)
{
    for (int r = r0; r < r1; r++) {
        float *row = C + (size_t)r * ldc;
        if (bias) for (int j = c0; j < c1; j++) row[j] += bias[j];
        nn_apply_act(row + c0, (size_t)(c1 - c0), act, alpha);
    }
}

void nn_sgemm_epilogue(int trans_a, int trans_b, int M, int N, int K, const float *A, int lda, const float *B, int ldb,
                       float beta, float *C, int ldc, const float *bias, nn_activation act, float act_alpha)
{
    int nt = omp_get_max_threads();
    double flops = 2.0 * M * N * (double)K;
    if (nt <= 1 || flops < NN_PAR_FLOPS) {
        nn_sgemm1(trans_a, trans_b, M, N, K, A, lda, B, ldb, beta, C, ldc);
        if (bias || act != NN_ACT_NONE) epilogue(C, ldc, 0, M, 0, N, bias, act, act_alpha);
        return;
    }
    /* about four blocks per thread, handed out dynamically: a thread that the OS parks for a while
     * (the cores are often shared) leaves its remaining blocks to the others; each block's bias and
     * activation are applied while it is still in cache */
    int split_m = M >= 64 * nt;
    int total = split_m ? M : N, align = split_m ? 16 : 64;
    int step = (total + 4 * nt - 1) / (4 * nt);
    step = (step + align - 1) / align * align;
    if (step < (split_m ? 64 : 256)) step = split_m ? 64 : 256;
    int blocks = (total + step - 1) / step;
    #pragma omp parallel for schedule(dynamic, 1) num_threads(nt)
    for (int blk = 0; blk < blocks; blk++) {
        int s = blk * step, e = s + step < total ? s + step : total;
        if (split_m) {
            nn_sgemm1(trans_a, trans_b, e - s, N, K, trans_a ? A + s : A + (size_t)s * lda, lda, B, ldb, beta,
                      C + (size_t)s * ldc, ldc);
            if (bias || act != NN_ACT_NONE) epilogue(C, ldc, s, e, 0, N, bias, act, act_alpha);
        } else {
            nn_sgemm1(trans_a, trans_b, M, e - s, K, A, lda, trans_b ? B + (size_t)s * ldb : B + s, ldb, beta, C + s, ldc);
            if (bias || act != NN_ACT_NONE) epilogue(C, ldc, 0, M, s, e, bias, act, act_alpha);
        }
    }
}

void nn_sgemm(int trans_a, int trans_b, int M, int N, int K, const float *A, int lda, const float *B, int ldb,
              float beta, float *C, int ldc)
{
    nn_sgemm_epilogue(trans_a, trans_b, M, N, K, A, lda, B, ldb, beta, C, ldc, NULL, NN_ACT_NONE, 0.0f);
}

size_t nn_scratch_matmul(const nn_graph *g, const nn_node *n) { (void)g; (void)n; return 0; }

/* numpy matmul shapes (1-D operands promoted); attr trans_b reads b as (..., N, K); an optional
 * third input is a bias of N values added to every row (fused by nn_exec.c). */
pg_status nn_infer_matmul(nn_graph *g, nn_node *n)
{
    nn_tensor *a = nn_in(g, n, 0), *b = nn_in(g, n, 1), *bias = nn_in(g, n, 2);
    if (!b) return nn_node_fail(n, "second input missing");
    if (a->ndim < 1 || b->ndim < 1) return nn_node_fail(n, "scalar operand");
    if (n->attr.trans_a) return nn_node_fail(n, "trans_a is not supported");
    int tb = n->attr.trans_b;
    if (tb && b->ndim < 2) return nn_node_fail(n, "trans_b needs a 2-D or larger b");
    int64_t K = a->dims[a->ndim - 1];
    int64_t Kb = b->ndim == 1 ? b->dims[0] : tb ? b->dims[b->ndim - 1] : b->dims[b->ndim - 2];
    if (K != Kb) return nn_node_fail(n, "inner dims differ (%lld vs %lld)", (long long)K, (long long)Kb);
    int ba = a->ndim > 2 ? a->ndim - 2 : 0, bb = b->ndim > 2 ? b->ndim - 2 : 0;
    int nb = ba > bb ? ba : bb;
    int64_t dims[NN_MAX_DIMS + 2];
    int nd = 0;
    for (int i = 0; i < nb; i++) {
        int ia = i - (nb - ba), ib = i - (nb - bb);
        int64_t da = ia >= 0 ? a->dims[ia] : 1, db = ib >= 0 ? b->dims[ib] : 1;
        if (da != db && da != 1 && db != 1) return nn_node_fail(n, "batch dims do not broadcast");
        dims[nd++] = da == 1 ? db : da;
    }
    if (a->ndim >= 2) dims[nd++] = a->dims[a->ndim - 2];
    if (b->ndim >= 2) dims[nd++] = tb ? b->dims[b->ndim - 2] : b->dims[b->ndim - 1];
    if (nd > NN_MAX_DIMS) return nn_node_fail(n, "too many dims");
    int64_t N = b->ndim >= 2 ? dims[nd - 1] : 1;
    if (bias && (nn_shape_count(bias->ndim, bias->dims) != N || b->ndim < 2))
        return nn_node_fail(n, "bias has %lld values for %lld columns", (long long)nn_shape_count(bias->ndim, bias->dims), (long long)N);
    return nn_set_output(g, n, 0, nd, dims);
}

/* Adds bias (N) to each of rows rows of y (N wide) and applies the activation. */
static void bias_act(float *y, int64_t rows, int N, const float *bias, const nn_attrs *a)
{
    #pragma omp parallel for schedule(static) if (rows * N >= NN_PAR_MEMORY)
    for (int64_t r = 0; r < rows; r++) {
        float *yr = y + r * N;
        if (bias) for (int j = 0; j < N; j++) yr[j] += bias[j];
        nn_apply_act(yr, (size_t)N, a->act, a->act_alpha);
    }
}

void nn_run_matmul(const nn_ctx *c, const nn_node *n)
{
    nn_graph *g = c->g;
    const nn_tensor *ta = nn_in(g, n, 0), *tb = nn_in(g, n, 1), *ty = nn_out(g, n, 0);
    const float *a = nn_in_data(c, n, 0), *b = nn_in_data(c, n, 1), *bias = nn_in_data(c, n, 2);
    float *y = nn_out_data(c, n, 0);
    int trb = n->attr.trans_b;
    int M = ta->ndim >= 2 ? (int)ta->dims[ta->ndim - 2] : 1;
    int K = (int)ta->dims[ta->ndim - 1];
    int N = tb->ndim >= 2 ? (int)(trb ? tb->dims[tb->ndim - 2] : tb->dims[tb->ndim - 1]) : 1;
    int ldb = tb->ndim >= 2 ? (int)tb->dims[tb->ndim - 1] : 1;
    int ba = ta->ndim > 2 ? ta->ndim - 2 : 0, bb = tb->ndim > 2 ? tb->ndim - 2 : 0;
    int64_t count_a = nn_shape_count(ba, ta->dims), count_b = nn_shape_count(bb, tb->dims);
    if (count_b == 1) {
        /* B shared by every batch: one product with the batches stacked as rows, bias and
         * activation applied per block */
        nn_sgemm_epilogue(0, trb, (int)(count_a * M), N, K, a, K, b, ldb, 0.0f, y, N, bias, n->attr.act, n->attr.act_alpha);
        return;
    } else {
        int nb = ty->ndim - (ta->ndim >= 2) - (tb->ndim >= 2);
        int64_t batch = nn_shape_count(nb, ty->dims);
        /* strides of each batch dim in a and b (0 where broadcast) */
        int64_t sa[NN_MAX_DIMS], sb[NN_MAX_DIMS], acc_a = (int64_t)M * K, acc_b = (int64_t)K * N;
        for (int i = nb - 1; i >= 0; i--) {
            int ia = i - (nb - ba), ib = i - (nb - bb);
            int64_t da = ia >= 0 ? ta->dims[ia] : 1, db = ib >= 0 ? tb->dims[ib] : 1;
            sa[i] = da == 1 ? 0 : acc_a;
            sb[i] = db == 1 ? 0 : acc_b;
            acc_a *= da;
            acc_b *= db;
        }
        #pragma omp parallel for schedule(dynamic, 1) if (2.0 * batch * M * N * K >= NN_PAR_FLOPS)
        for (int64_t p = 0; p < batch; p++) {
            int64_t rem = p, oa = 0, ob = 0;
            for (int i = nb - 1; i >= 0; i--) {
                int64_t idx = rem % ty->dims[i];
                rem /= ty->dims[i];
                oa += idx * sa[i];
                ob += idx * sb[i];
            }
            nn_sgemm1(0, trb, M, N, K, a + oa, K, b + ob, ldb, 0.0f, y + p * (int64_t)M * N, N);
        }
    }
    if (bias || n->attr.act != NN_ACT_NONE) bias_act(y, nn_shape_count(ty->ndim, ty->dims) / N, N, bias, &n->attr);
}

pg_status nn_infer_gemm(nn_graph *g, nn_node *n)
{
    nn_tensor *a = nn_in(g, n, 0), *b = nn_in(g, n, 1), *cc = nn_in(g, n, 2);
    if (!b || a->ndim != 2 || b->ndim != 2) return nn_node_fail(n, "operands must be 2-D");
    int64_t M = n->attr.trans_a ? a->dims[1] : a->dims[0], K = n->attr.trans_a ? a->dims[0] : a->dims[1];
    int64_t Kb = n->attr.trans_b ? b->dims[1] : b->dims[0], N = n->attr.trans_b ? b->dims[0] : b->dims[1];
    if (K != Kb) return nn_node_fail(n, "inner dims differ (%lld vs %lld)", (long long)K, (long long)Kb);
    if (cc) {
        if (cc->ndim > 2) return nn_node_fail(n, "C has more than 2 dims");
        int64_t cm = cc->ndim == 2 ? cc->dims[0] : 1, cn = cc->ndim >= 1 ? cc->dims[cc->ndim - 1] : 1;
        if ((cm != 1 && cm != M) || (cn != 1 && cn != N)) return nn_node_fail(n, "C does not broadcast to (%lld, %lld)", (long long)M, (long long)N);
    }
    return nn_set_output(g, n, 0, 2, (int64_t[]){ M, N });
}

void nn_run_gemm(const nn_ctx *c, const nn_node *n)
{
    nn_graph *g = c->g;
    const nn_tensor *ta = nn_in(g, n, 0), *tb = nn_in(g, n, 1), *tc = nn_in(g, n, 2), *ty = nn_out(g, n, 0);
    const float *a = nn_in_data(c, n, 0), *b = nn_in_data(c, n, 1), *cc = nn_in_data(c, n, 2);
    float *y = nn_out_data(c, n, 0);
    int M = (int)ty->dims[0], N = (int)ty->dims[1], K = (int)(n->attr.trans_a ? ta->dims[0] : ta->dims[1]);
    float alpha = n->attr.alpha, beta = n->attr.beta;
    nn_sgemm(n->attr.trans_a, n->attr.trans_b, M, N, K, a, (int)ta->dims[1], b, (int)tb->dims[1], 0.0f, y, N);
    int64_t cm = 1, cn = 1;
    if (tc) { cm = tc->ndim == 2 ? tc->dims[0] : 1; cn = tc->ndim >= 1 ? tc->dims[tc->ndim - 1] : 1; }
    if (alpha != 1.0f || (tc && beta != 0.0f))
        for (int i = 0; i < M; i++)
            for (int j = 0; j < N; j++)
                y[(size_t)i * N + j] = alpha * y[(size_t)i * N + j] + (tc ? beta * cc[(cm == 1 ? 0 : i) * cn + (cn == 1 ? 0 : j)] : 0.0f);
    nn_apply_act(y, (size_t)M * N, n->attr.act, n->attr.act_alpha);
}

/* ---- fused attention ---- */

#define ATTN_ROWS 128 /* query rows per block: the (128, N) score block stays in L2 */

pg_status nn_infer_attention(nn_graph *g, nn_node *n)
{
    nn_tensor *q = nn_in(g, n, 0), *k = nn_in(g, n, 1), *v = nn_in(g, n, 2);
    int nd = q->ndim;
    if (nd < 2 || k->ndim != nd || v->ndim != nd) return nn_node_fail(n, "q, k, v must have the same rank >= 2");
    for (int i = 0; i < nd - 2; i++)
        if (k->dims[i] != q->dims[i] || v->dims[i] != q->dims[i]) return nn_node_fail(n, "batch dims differ");
    if (k->dims[nd - 1] != q->dims[nd - 1] || v->dims[nd - 2] != k->dims[nd - 2]) return nn_node_fail(n, "q, k, v sizes disagree");
    int64_t dims[NN_MAX_DIMS];
    for (int i = 0; i < nd; i++) dims[i] = q->dims[i];
    dims[nd - 1] = v->dims[nd - 1];
    return nn_set_output(g, n, 0, nd, dims);
}

size_t nn_scratch_attention(const nn_graph *g, const nn_node *n)
{
    const nn_tensor *k = &g->tensors[n->inputs[1]];
    return (size_t)ATTN_ROWS * (size_t)k->dims[k->ndim - 2];
}

void nn_run_attention(const nn_ctx *c, const nn_node *n)
{
    const nn_tensor *tq = nn_in(c->g, n, 0), *tk = nn_in(c->g, n, 1), *tv = nn_in(c->g, n, 2);
    const float *q = nn_in_data(c, n, 0), *k = nn_in_data(c, n, 1), *v = nn_in_data(c, n, 2);
    float *y = nn_out_data(c, n, 0);
    int nd = tq->ndim;
    int M = (int)tq->dims[nd - 2], D = (int)tq->dims[nd - 1], N = (int)tk->dims[nd - 2], E = (int)tv->dims[nd - 1];
    int64_t batch = nn_shape_count(nd - 2, tq->dims), blocks = (M + ATTN_ROWS - 1) / ATTN_ROWS;
    #pragma omp parallel for schedule(dynamic, 1) if (4.0 * batch * M * N * (D + E) / 2 >= NN_PAR_FLOPS)
    for (int64_t job = 0; job < batch * blocks; job++) {
        int64_t b = job / blocks;
        int r0 = (int)(job % blocks) * ATTN_ROWS, rows = M - r0 < ATTN_ROWS ? M - r0 : ATTN_ROWS;
        float *s = c->scratch + (size_t)omp_get_thread_num() * c->scratch_floats; /* (rows, N) */
        nn_sgemm1(0, 1, rows, N, D, q + (b * M + r0) * (int64_t)D, D, k + b * (int64_t)N * D, D, 0.0f, s, N);
        for (int r = 0; r < rows; r++) {
            float *sr = s + (size_t)r * N, mx = -INFINITY;
            for (int i = 0; i < N; i++) mx = sr[i] > mx ? sr[i] : mx;
            for (int i = 0; i < N; i++) sr[i] = nn_exp(sr[i] - mx);
            float inv = 1.0f / nn_sum(sr, N);
            for (int i = 0; i < N; i++) sr[i] *= inv;
        }
        nn_sgemm1(0, 0, rows, E, N, s, N, v + b * (int64_t)N * E, E, 0.0f, y + (b * M + r0) * (int64_t)E, E);
    }
}
