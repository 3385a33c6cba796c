/* gemm_avx512bf16.c - the bf16 GEMM's micro-kernel on AVX512-BF16 (vdpbf16ps) for CPUs without
 * AMX, on the same packed operands as the AMX path (gemm_amx.h), driven by gemm_blocked.
 *
 * 8 rows x 32 columns of f32 accumulators (16 zmm). Per K pair the two B vectors (16 columns x 2 k
 * each, exactly the VNNI pairs of the packed B) are loaded once and each row's A pair is broadcast
 * as one 32-bit lane; vdpbf16ps adds both products.
 */
#include "deform/gemm_amx.h"

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>

#define BF16_TARGET __attribute__((target("avx512f,avx512bw,avx512vl,avx512bf16")))

static BF16_TARGET void micro_8x32(const uint16_t *A, int lda, const uint16_t *B, int ldb, int K, int rows, int nv,
                                   float *v, int ldv, int accumulate)
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

const gemm_micro_kernel gemm_kernel_avx512bf16 = { micro_8x32, 8, gemm_block_epilogue_avx512bf16 };
#else
const gemm_micro_kernel gemm_kernel_avx512bf16 = { 0, 8, 0 };
#endif
