/* gemm_avx512bf16.c - the bf16 GEMM of gemm_amx.h on AVX512-BF16 (vdpbf16ps) for CPUs without
 * AMX, on the same packed operands and with the same epilogues, so deform_amx.c runs unchanged.
 *
 * Micro-kernel: 8 rows x 32 columns of f32 accumulators (16 zmm). Per K pair the two B vectors
 * (16 columns x 2 k each, exactly the VNNI pairs of the packed B) are loaded once and each row's
 * A pair is broadcast as one 32-bit lane; vdpbf16ps adds both products. Column blocks are the
 * outer loop so the B panel (K x 32 bf16) stays in L1 while the row blocks stream past it.
 */
#include "deform/gemm_amx.h"

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#include <string.h>

#define BF16_TARGET __attribute__((target("avx512f,avx512bw,avx512vl,avx512bf16")))

/* rows (8 or fewer) x (16 * nv) block of A*B at (i, j): acc rows of v (row stride ldv, f32), loaded
 * from v first when accumulate. */
static inline BF16_TARGET void micro_8xN(const uint16_t *A, int lda, const uint16_t *B, int ldb, int K, int rows,
                                          int nv, float *v, int ldv, int accumulate)
{
    __m512 acc[8][2];
    for (int r = 0; r < 8; r++)
        for (int q = 0; q < 2; q++)
            acc[r][q] = accumulate && r < rows && q < nv ? _mm512_loadu_ps(v + (size_t)r * ldv + 16 * q) : _mm512_setzero_ps();
    const uint32_t *a32[8];
    for (int r = 0; r < 8; r++) a32[r] = (const uint32_t *)(A + (size_t)(r < rows ? r : 0) * lda);
    for (int p = 0; p < K / 2; p++) {
        const uint16_t *bp = B + (size_t)p * ldb;
        __m512bh b0 = (__m512bh)_mm512_loadu_si512(bp);
        __m512bh b1 = nv > 1 ? (__m512bh)_mm512_loadu_si512(bp + 32) : b0;
        #pragma GCC unroll 8
        for (int r = 0; r < 8; r++) {
            __m512bh a = (__m512bh)_mm512_set1_epi32((int)a32[r][p]);
            acc[r][0] = _mm512_dpbf16_ps(acc[r][0], a, b0);
            if (nv > 1) acc[r][1] = _mm512_dpbf16_ps(acc[r][1], a, b1);
        }
    }
    for (int r = 0; r < rows; r++)
        for (int q = 0; q < nv; q++) _mm512_storeu_ps(v + (size_t)r * ldv + 16 * q, acc[r][q]);
}

BF16_TARGET void gemm_avx512bf16(const uint16_t *A, int lda, const uint16_t *B, int ldb, int M, int N, int K,
                                 const gemm_amx_epilogue *e)
{
    if (M <= 0 || N <= 0 || K <= 0) return;
    float blk[32 * 32] __attribute__((aligned(64)));
    for (int j = 0; j < N; j += 32) {
        const int nv = N - j >= 32 ? 2 : 1; /* N is a multiple of 16 */
        const uint16_t *bj = B + (size_t)j * 2;
        for (int i = 0; i < M; i += 32) {
            const int mr = M - i >= 32 ? 32 : M - i;
            if (e->c) { /* f32 output straight into C, then the bias */
                float *cb = e->c + (size_t)i * e->ldc + j;
                for (int r = 0; r < mr; r += 8)
                    micro_8xN(A + (size_t)(i + r) * lda, lda, bj, ldb, K, mr - r < 8 ? mr - r : 8, nv,
                              cb + (size_t)r * e->ldc, e->ldc, e->accumulate);
                if (e->bias)
                    for (int r = 0; r < mr; r++) {
                        float *c = cb + (size_t)r * e->ldc;
                        for (int q = 0; q < 16 * nv; q++) c[q] += e->bias[j + q];
                    }
                continue;
            }
            /* bf16 outputs: whole 32x32 blocks (the callers pad M and N to 32) */
            for (int r = 0; r < 32; r += 8) micro_8xN(A + (size_t)(i + r) * lda, lda, bj, ldb, K, 8, 2, blk + r * 32, 32, 0);
            gemm_block_epilogue(e, blk, i, j);
        }
    }
}
#else
void gemm_avx512bf16(const uint16_t *A, int lda, const uint16_t *B, int ldb, int M, int N, int K,
                     const gemm_amx_epilogue *e)
{
    (void)A; (void)lda; (void)B; (void)ldb; (void)M; (void)N; (void)K; (void)e;
}
#endif
