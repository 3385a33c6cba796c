/* gemm_f32fma.c - micro-kernels for the packed bf16 GEMM (gemm_amx.h) on CPUs without any bf16
 * arithmetic: AVX-512F (16 lanes) and AVX2+FMA (8 lanes). The operands stay in the bf16 layouts
 * the network's epilogues write (half the memory traffic of f32, nothing repacked); each loaded
 * VNNI vector is widened in registers - a bf16 is the top half of an f32, so the even k of a pair
 * is the 32-bit lane shifted left by 16 and the odd k the lane with its low half cleared - and
 * multiplied with f32 FMAs. Sums are f32 as in the bf16 kernels, so results agree with them to
 * the order of the two products of a pair.
 */
#include "deform/gemm_amx.h"

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>

#define F512_TARGET __attribute__((target("avx512f,avx512bw,avx512vl,avx2,fma")))
#define F256_TARGET __attribute__((target("avx2,fma")))

/* 8 rows x 32 columns: 16 zmm accumulators, 4 widened B vectors, 2 widened A broadcasts. */
static F512_TARGET void micro_avx512f(const uint16_t *A, int lda, const uint16_t *B, int ldb, int K, int rows, int nv,
                                      float *v, int ldv, int accumulate)
{
    __m512 acc[8][2];
    for (int r = 0; r < 8; r++)
        for (int q = 0; q < 2; q++)
            acc[r][q] = accumulate && r < rows && q < nv ? _mm512_loadu_ps(v + (size_t)r * ldv + 16 * q) : _mm512_setzero_ps();
    const uint32_t *a32[8];
    for (int r = 0; r < 8; r++) a32[r] = (const uint32_t *)(A + (size_t)(r < rows ? r : 0) * lda);
    const __m512i odd = _mm512_set1_epi32((int)0xFFFF0000u);
    for (int p = 0; p < K / 2; p++) {
        const uint16_t *bp = B + (size_t)p * ldb;
        __m512i b0 = _mm512_loadu_si512(bp), b1 = nv > 1 ? _mm512_loadu_si512(bp + 32) : b0;
        __m512 b0e = _mm512_castsi512_ps(_mm512_slli_epi32(b0, 16)), b0o = _mm512_castsi512_ps(_mm512_and_si512(b0, odd));
        __m512 b1e = _mm512_castsi512_ps(_mm512_slli_epi32(b1, 16)), b1o = _mm512_castsi512_ps(_mm512_and_si512(b1, odd));
        #pragma GCC unroll 8
        for (int r = 0; r < 8; r++) {
            __m512i a = _mm512_set1_epi32((int)a32[r][p]);
            __m512 ae = _mm512_castsi512_ps(_mm512_slli_epi32(a, 16)), ao = _mm512_castsi512_ps(_mm512_and_si512(a, odd));
            acc[r][0] = _mm512_fmadd_ps(ao, b0o, _mm512_fmadd_ps(ae, b0e, acc[r][0]));
            if (nv > 1) acc[r][1] = _mm512_fmadd_ps(ao, b1o, _mm512_fmadd_ps(ae, b1e, acc[r][1]));
        }
    }
    for (int r = 0; r < rows; r++)
        for (int q = 0; q < nv; q++) _mm512_storeu_ps(v + (size_t)r * ldv + 16 * q, acc[r][q]);
}

/* 4 rows x 16 columns per pass (8 ymm accumulators, 4 widened B, 2 widened A: 14 of 16
 * registers), one pass per 16-column half. */
static F256_TARGET void micro_avx2(const uint16_t *A, int lda, const uint16_t *B, int ldb, int K, int rows, int nv,
                                   float *v, int ldv, int accumulate)
{
    const __m256i odd = _mm256_set1_epi32((int)0xFFFF0000u);
    const uint32_t *a32[4];
    for (int r = 0; r < 4; r++) a32[r] = (const uint32_t *)(A + (size_t)(r < rows ? r : 0) * lda);
    for (int q = 0; q < nv; q++) {
        __m256 acc[4][2];
        for (int r = 0; r < 4; r++)
            for (int h = 0; h < 2; h++)
                acc[r][h] = accumulate && r < rows ? _mm256_loadu_ps(v + (size_t)r * ldv + 16 * q + 8 * h) : _mm256_setzero_ps();
        for (int p = 0; p < K / 2; p++) {
            const uint16_t *bp = B + (size_t)p * ldb + 32 * q;
            __m256i b0 = _mm256_loadu_si256((const __m256i *)bp), b1 = _mm256_loadu_si256((const __m256i *)(bp + 16));
            __m256 b0e = _mm256_castsi256_ps(_mm256_slli_epi32(b0, 16)), b0o = _mm256_castsi256_ps(_mm256_and_si256(b0, odd));
            __m256 b1e = _mm256_castsi256_ps(_mm256_slli_epi32(b1, 16)), b1o = _mm256_castsi256_ps(_mm256_and_si256(b1, odd));
            #pragma GCC unroll 4
            for (int r = 0; r < 4; r++) {
                __m256i a = _mm256_set1_epi32((int)a32[r][p]);
                __m256 ae = _mm256_castsi256_ps(_mm256_slli_epi32(a, 16)), ao = _mm256_castsi256_ps(_mm256_and_si256(a, odd));
                acc[r][0] = _mm256_fmadd_ps(ao, b0o, _mm256_fmadd_ps(ae, b0e, acc[r][0]));
                acc[r][1] = _mm256_fmadd_ps(ao, b1o, _mm256_fmadd_ps(ae, b1e, acc[r][1]));
            }
        }
        for (int r = 0; r < rows; r++)
            for (int h = 0; h < 2; h++) _mm256_storeu_ps(v + (size_t)r * ldv + 16 * q + 8 * h, acc[r][h]);
    }
}

const gemm_micro_kernel gemm_kernel_avx512f = { micro_avx512f, 8, gemm_block_epilogue_avx2 };
const gemm_micro_kernel gemm_kernel_avx2 = { micro_avx2, 4, gemm_block_epilogue_avx2 };
#else
const gemm_micro_kernel gemm_kernel_avx512f = { 0, 8, 0 }, gemm_kernel_avx2 = { 0, 4, 0 };
#endif
