/* gemm_epilogue.c - the epilogue shared by the bf16 GEMM backends (gemm_amx.h): bias, ReLU, mask
 * and column sums on one 32x32 f32 block, written once in the bf16 layouts the next GEMMs read (or
 * in f32, the input of the f32 heads). Runs only on CPUs with AVX512-BF16 (every bf16 backend
 * implies it). */
#include "deform/gemm_amx.h"

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>

#define EPI_TARGET __attribute__((target("avx512f,avx512bw,avx512vl,avx512bf16")))

/* Two f32 halves -> 32 bf16 (round to nearest even, as gemm_amx_bf16 for normal numbers). */
static inline EPI_TARGET __m512i to_bf16(__m512 lo, __m512 hi) { return (__m512i)_mm512_cvtne2ps_pbh(hi, lo); }

/* The epilogue of one 32x32 block v (row stride 32) at C position (i, j). Pairs of rows are
 * processed together: their bf16 values interleaved as 32-bit pairs are the VNNI output, and the
 * same pairs gathered down a column give the transposed output. */
EPI_TARGET void gemm_block_epilogue(const gemm_amx_epilogue *e, const float *v, int i, int j)
{
    __m512 b0 = _mm512_setzero_ps(), b1 = b0, zero = b0, cs0 = b0, cs1 = b0;
    if (e->bias) {
        b0 = _mm512_loadu_ps(e->bias + j);
        b1 = _mm512_loadu_ps(e->bias + j + 16);
    }
    if (e->colsum) {
        cs0 = _mm512_loadu_ps(e->colsum + j);
        cs1 = _mm512_loadu_ps(e->colsum + j + 16);
    }
    const int nr = e->rows - i;
    /* 32-bit lane p of vector k = (row 2p, row 2p+1) of column 16k + p: the VNNI interleave */
    const __m512i ilo = _mm512_set_epi16(47, 15, 46, 14, 45, 13, 44, 12, 43, 11, 42, 10, 41, 9, 40, 8, 39, 7, 38, 6, 37,
                                         5, 36, 4, 35, 3, 34, 2, 33, 1, 32, 0);
    const __m512i ihi = _mm512_add_epi16(ilo, _mm512_set1_epi16(16));
    uint32_t pairs[16 * 32] __attribute__((aligned(64))); /* (row pair, column) */
    for (int r = 0; r < 32; r += 2) {
        __m512i h[2];
        for (int s = 0; s < 2; s++) {
            const float *row = v + (r + s) * 32;
            __m512 x0 = _mm512_add_ps(_mm512_load_ps(row), b0), x1 = _mm512_add_ps(_mm512_load_ps(row + 16), b1);
            if (e->relu) {
                x0 = _mm512_max_ps(x0, zero);
                x1 = _mm512_max_ps(x1, zero);
            }
            if (e->mask) {
                __m512i mk = _mm512_loadu_si512(e->mask + (size_t)(i + r + s) * e->ldmask + j);
                __mmask32 k = _mm512_test_epi16_mask(mk, mk);
                x0 = _mm512_maskz_mov_ps((__mmask16)k, x0);
                x1 = _mm512_maskz_mov_ps((__mmask16)(k >> 16), x1);
            }
            if (e->colsum && r + s < nr) {
                cs0 = _mm512_add_ps(cs0, x0);
                cs1 = _mm512_add_ps(cs1, x1);
            }
            if (e->f) {
                float *o = e->f + (size_t)(i + r + s) * e->ldf + j;
                _mm512_storeu_ps(o, x0);
                _mm512_storeu_ps(o + 16, x1);
            }
            h[s] = to_bf16(x0, x1);
            if (e->rm) _mm512_storeu_si512(e->rm + (size_t)(i + r + s) * e->ldrm + j, h[s]);
        }
        if (e->vn || e->tr) {
            __m512i p0 = _mm512_permutex2var_epi16(h[0], ilo, h[1]), p1 = _mm512_permutex2var_epi16(h[0], ihi, h[1]);
            if (e->vn) {
                uint16_t *o = e->vn + (size_t)((i + r) / 2) * e->ldvn + 2 * j;
                _mm512_storeu_si512(o, p0);
                _mm512_storeu_si512(o + 32, p1);
            }
            _mm512_store_si512(pairs + (r / 2) * 32, p0);
            _mm512_store_si512(pairs + (r / 2) * 32 + 16, p1);
        }
    }
    if (e->colsum) {
        _mm512_storeu_ps(e->colsum + j, cs0);
        _mm512_storeu_ps(e->colsum + j + 16, cs1);
    }
    if (e->tr) {
        const __m512i idx = _mm512_mullo_epi32(_mm512_set_epi32(15, 14, 13, 12, 11, 10, 9, 8, 7, 6, 5, 4, 3, 2, 1, 0),
                                               _mm512_set1_epi32(32));
        for (int q = 0; q < 32; q++)
            _mm512_storeu_si512(e->tr + (size_t)(j + q) * e->ldtr + i, _mm512_i32gather_epi32(idx, pairs + q, 4));
    }
}
#else
void gemm_block_epilogue(const gemm_amx_epilogue *e, const float *v, int i, int j)
{
    (void)e; (void)v; (void)i; (void)j;
}
#endif
