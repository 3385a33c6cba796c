/* gemm_avx512f32.c - the f32 GEMMs of the network's bf16 path (gemm_amx.h): its first layer and the
 * heads' forward, whose bf16 roundings cost most of the bf16-vs-f32 output agreement for little
 * of the time (docs/deform.md). AVX-512F, which every bf16 backend implies.
 *
 * Micro-kernel: up to 8 rows x 48 columns of f32 accumulators (24 zmm). Per k the B vectors are
 * loaded once and each row's A value is broadcast, as in gemm_avx512bf16.c.
 */
#include "deform/gemm_amx.h"

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>

#define F32_TARGET __attribute__((target("avx512f")))

/* The first n of 16 lanes. */
static inline __mmask16 lanes(int n) { return n >= 16 ? (__mmask16)0xFFFF : (__mmask16)((1u << n) - 1); }

/* rows (8 or fewer) x ncols (at most 16 * nv) of A*B (+ bias[j] if bias) into v (row stride ldv).
 * Inlined with a constant nv, so the accumulators stay in registers. */
static inline __attribute__((always_inline)) F32_TARGET void micro_f32(const float *A, int lda, const float *B, int ldb,
                                                                       int K, int rows, int nv, int ncols,
                                                                       const float *bias, float *v, int ldv)
{
    __m512 acc[8][3];
    for (int q = 0; q < 3; q++) {
        __m512 init = bias && q < nv ? _mm512_maskz_loadu_ps(lanes(ncols - 16 * q), bias + 16 * q) : _mm512_setzero_ps();
        for (int r = 0; r < 8; r++) acc[r][q] = init;
    }
    const float *a[8];
    for (int r = 0; r < 8; r++) a[r] = A + (size_t)(r < rows ? r : 0) * lda;
    for (int k = 0; k < K; k++) {
        const float *bk = B + (size_t)k * ldb;
        __m512 b0 = _mm512_loadu_ps(bk);
        __m512 b1 = nv > 1 ? _mm512_loadu_ps(bk + 16) : b0, b2 = nv > 2 ? _mm512_loadu_ps(bk + 32) : b0;
        #pragma GCC unroll 8
        for (int r = 0; r < 8; r++) {
            __m512 x = _mm512_set1_ps(a[r][k]);
            acc[r][0] = _mm512_fmadd_ps(x, b0, acc[r][0]);
            if (nv > 1) acc[r][1] = _mm512_fmadd_ps(x, b1, acc[r][1]);
            if (nv > 2) acc[r][2] = _mm512_fmadd_ps(x, b2, acc[r][2]);
        }
    }
    for (int r = 0; r < rows; r++)
        for (int q = 0; q < nv; q++) _mm512_mask_storeu_ps(v + (size_t)r * ldv + 16 * q, lanes(ncols - 16 * q), acc[r][q]);
}

F32_TARGET void gemm_f32(const float *A, int lda, const float *B, int ldb, int M, int N, int K, const gemm_amx_epilogue *e)
{
    if (M <= 0 || N <= 0 || K <= 0) return;
    if (e->c) { /* f32 output straight into C: column blocks of up to 48, row blocks of 8 */
        for (int j = 0; j < N; j += 48) {
            const int nc = N - j < 48 ? N - j : 48;
            const float *bias = e->bias ? e->bias + j : NULL;
            for (int i = 0; i < M; i += 8) {
                const float *ai = A + (size_t)i * lda;
                const int rows = M - i < 8 ? M - i : 8;
                float *ci = e->c + (size_t)i * e->ldc + j;
                if (nc > 32) micro_f32(ai, lda, B + j, ldb, K, rows, 3, nc, bias, ci, e->ldc);
                else if (nc > 16) micro_f32(ai, lda, B + j, ldb, K, rows, 2, nc, bias, ci, e->ldc);
                else micro_f32(ai, lda, B + j, ldb, K, rows, 1, nc, bias, ci, e->ldc);
            }
        }
        return;
    }
    /* bf16 outputs: whole 32x32 blocks through the shared epilogue (the callers pad M and N to 32) */
    float blk[32 * 32] __attribute__((aligned(64)));
    for (int j = 0; j < N; j += 32)
        for (int i = 0; i < M; i += 32) {
            for (int r = 0; r < 32; r += 8)
                micro_f32(A + (size_t)(i + r) * lda, lda, B + j, ldb, K, 8, 2, 32, NULL, blk + r * 32, 32);
            gemm_block_epilogue(e, blk, i, j);
        }
}

/* Lane-wise products of output o's K inputs x and weights w, summed over the K/16 vectors. */
static inline __attribute__((always_inline)) F32_TARGET __m512 dot16(const float *x, const float *w, int K)
{
    const int K16 = K & ~15;
    __m512 acc = _mm512_setzero_ps();
    for (int k = 0; k < K16; k += 16) acc = _mm512_fmadd_ps(_mm512_loadu_ps(x + k), _mm512_loadu_ps(w + k), acc);
    if (K16 < K) {
        const __mmask16 tail = lanes(K - K16);
        acc = _mm512_fmadd_ps(_mm512_maskz_loadu_ps(tail, x + K16), _mm512_maskz_loadu_ps(tail, w + K16), acc);
    }
    return acc;
}

/* Each output's lane sums come out of a transposing tree (45 shuffles and adds for 16 outputs)
 * instead of 16 separate horizontal sums, which measured twice as slow. */
F32_TARGET void gemm_f32_dots(const float *A, int lda, const float *B, const int *koff, const float *bias, int M, int N,
                              int K, float *c, int ldc)
{
    const __mmask16 out = lanes(N);
    const __m512 b = _mm512_maskz_loadu_ps(out, bias), zero = _mm512_setzero_ps();
    for (int i = 0; i < M; i++) {
        const float *ai = A + (size_t)i * lda;
        __m512 w[8], x[4], y[2];
        #pragma GCC unroll 8
        for (int p = 0; p < 8; p++) { /* 128-bit lane l of w[p]: lane l's partial sums of outputs 2p, 2p+1 */
            const int o = 2 * p;
            __m512 u = o < N ? dot16(ai + koff[o], B + (size_t)o * K, K) : zero;
            __m512 v = o + 1 < N ? dot16(ai + koff[o + 1], B + (size_t)(o + 1) * K, K) : zero;
            w[p] = _mm512_add_ps(_mm512_unpacklo_ps(u, v), _mm512_unpackhi_ps(u, v));
        }
        #pragma GCC unroll 4
        for (int q = 0; q < 4; q++) { /* lane l: lane l's sums of outputs 4q .. 4q+3 */
            __m512d e = _mm512_castps_pd(w[2 * q]), f = _mm512_castps_pd(w[2 * q + 1]);
            x[q] = _mm512_add_ps(_mm512_castpd_ps(_mm512_unpacklo_pd(e, f)), _mm512_castpd_ps(_mm512_unpackhi_pd(e, f)));
        }
        #pragma GCC unroll 2
        for (int s = 0; s < 2; s++) /* lanes: (0+1, 2+3) of x[2s], then of x[2s+1] */
            y[s] = _mm512_add_ps(_mm512_shuffle_f32x4(x[2 * s], x[2 * s + 1], _MM_SHUFFLE(2, 0, 2, 0)),
                                 _mm512_shuffle_f32x4(x[2 * s], x[2 * s + 1], _MM_SHUFFLE(3, 1, 3, 1)));
        /* lane l: the sums of outputs 4l .. 4l+3 */
        __m512 r = _mm512_add_ps(_mm512_shuffle_f32x4(y[0], y[1], _MM_SHUFFLE(2, 0, 2, 0)),
                                 _mm512_shuffle_f32x4(y[0], y[1], _MM_SHUFFLE(3, 1, 3, 1)));
        _mm512_mask_storeu_ps(c + (size_t)i * ldc, out, _mm512_add_ps(r, b));
    }
}
#else
void gemm_f32(const float *A, int lda, const float *B, int ldb, int M, int N, int K, const gemm_amx_epilogue *e)
{
    (void)A; (void)lda; (void)B; (void)ldb; (void)M; (void)N; (void)K; (void)e;
}

void gemm_f32_dots(const float *A, int lda, const float *B, const int *koff, const float *bias, int M, int N, int K,
                   float *c, int ldc)
{
    (void)A; (void)lda; (void)B; (void)koff; (void)bias; (void)M; (void)N; (void)K; (void)c; (void)ldc;
}
#endif
