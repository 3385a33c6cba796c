/* gemm_amx.c - bf16 AMX matrix multiply with fused epilogues (see gemm_amx.h).
 *
 * Blocking: 32x32 output blocks held in four 16x16 f32 tiles (tmm0-3), two A tiles (tmm4-5, 16 rows
 * x 32 bf16) and two B tiles (tmm6-7, 16 pair-rows x 16 columns) per 32-deep K step. Column blocks
 * are the outer loop so the B panel (K x 32) stays in L1 while the row blocks stream past it.
 */
#include "deform/gemm_amx.h"

#include <string.h>

#if defined(__x86_64__) && defined(__GNUC__)
#include <cpuid.h>
#include <immintrin.h>
#include <sys/syscall.h>
#include <unistd.h>
#define PG_HAVE_AMX_BUILD 1
#endif

#define ARCH_REQ_XCOMP_PERM 0x1023
#define XFEATURE_XTILEDATA 18

static int amx_state = -1; /* -1 unknown, 0 no, 1 yes */

int gemm_amx_available(void)
{
#ifdef PG_HAVE_AMX_BUILD
    if (amx_state >= 0) return amx_state;
    unsigned a, b, c, d;
    int ok = __get_cpuid_count(7, 0, &a, &b, &c, &d) && (d & (1u << 22)) && (d & (1u << 24));
    /* Linux keeps the 8 KB tile state off until the process asks for it (once per process). */
    if (ok) ok = syscall(SYS_arch_prctl, ARCH_REQ_XCOMP_PERM, XFEATURE_XTILEDATA) == 0;
    amx_state = ok;
    return ok;
#else
    return 0;
#endif
}

#ifdef PG_HAVE_AMX_BUILD
#define PACK_TARGET __attribute__((target("avx512f,avx512bw,avx512vl,avx512bf16")))

/* Transposes 16 rows of 16 floats in registers (lane i of r[q] -> lane q of r[i]): unpacks of 32-
 * and 64-bit pairs, then a 4x4 transpose of the 128-bit lanes. */
static inline PACK_TARGET void transpose16(__m512 r[16])
{
    __m512 t[16], s[16];
    for (int p = 0; p < 8; p++) {
        t[2 * p] = _mm512_unpacklo_ps(r[2 * p], r[2 * p + 1]);
        t[2 * p + 1] = _mm512_unpackhi_ps(r[2 * p], r[2 * p + 1]);
    }
    for (int g = 0; g < 4; g++) { /* 128-bit lane l of s[4g + c]: rows 4g .. 4g+3 of column 4l + c */
        __m512d lo = _mm512_castps_pd(t[4 * g]), hi = _mm512_castps_pd(t[4 * g + 1]);
        __m512d lo2 = _mm512_castps_pd(t[4 * g + 2]), hi2 = _mm512_castps_pd(t[4 * g + 3]);
        s[4 * g] = _mm512_castpd_ps(_mm512_unpacklo_pd(lo, lo2));
        s[4 * g + 1] = _mm512_castpd_ps(_mm512_unpackhi_pd(lo, lo2));
        s[4 * g + 2] = _mm512_castpd_ps(_mm512_unpacklo_pd(hi, hi2));
        s[4 * g + 3] = _mm512_castpd_ps(_mm512_unpackhi_pd(hi, hi2));
    }
    for (int c = 0; c < 4; c++) { /* column 4l + c = lane l of s[c], s[4 + c], s[8 + c], s[12 + c] */
        __m512 x0 = _mm512_shuffle_f32x4(s[c], s[4 + c], 0x44), x1 = _mm512_shuffle_f32x4(s[c], s[4 + c], 0xEE);
        __m512 x2 = _mm512_shuffle_f32x4(s[8 + c], s[12 + c], 0x44), x3 = _mm512_shuffle_f32x4(s[8 + c], s[12 + c], 0xEE);
        r[c] = _mm512_shuffle_f32x4(x0, x2, 0x88);
        r[4 + c] = _mm512_shuffle_f32x4(x0, x2, 0xDD);
        r[8 + c] = _mm512_shuffle_f32x4(x1, x3, 0x88);
        r[12 + c] = _mm512_shuffle_f32x4(x1, x3, 0xDD);
    }
}

/* A (Mp, Kp) from a transposed src (a(i, q) = src[q*cs + i]; Mp, Kp multiples of 16), 16x16 blocks
 * at a time: 16 rows of src (masked to i < M, zero for q >= K) transposed in registers. The
 * transposing packs (features, d_out) measured 2.6x faster than with a gather per 16 values. */
static PACK_TARGET void pack_a_transposed(uint16_t *dst, int ld, int Mp, int Kp, const float *src, long cs, int M, int K)
{
    for (int i0 = 0; i0 < Mp; i0 += 16) {
        const __mmask16 mi = M - i0 >= 16 ? (__mmask16)0xFFFF : M > i0 ? (__mmask16)((1u << (M - i0)) - 1) : 0;
        for (int q0 = 0; q0 < Kp; q0 += 16) {
            __m512 r[16];
            for (int q = 0; q < 16; q++)
                r[q] = q0 + q < K && mi ? _mm512_maskz_loadu_ps(mi, src + (size_t)(q0 + q) * cs + i0) : _mm512_setzero_ps();
            transpose16(r);
            for (int i = 0; i < 16; i++)
                _mm256_storeu_si256((__m256i *)(dst + (size_t)(i0 + i) * ld + q0), (__m256i)_mm512_cvtneps_pbh(r[i]));
        }
    }
}
#endif

void gemm_amx_pack_a(uint16_t *dst, int ld, int Mp, int Kp, const float *src, long rs, long cs, int M, int K)
{
#ifdef PG_HAVE_AMX_BUILD
    if (rs == 1 && cs != 1 && Mp % 16 == 0 && Kp % 16 == 0 && gemm_bf16_backend() != GEMM_BF16_NONE) {
        pack_a_transposed(dst, ld, Mp, Kp, src, cs, M, K); /* every bf16 backend implies AVX512-BF16 */
        return;
    }
#endif
    for (int i = 0; i < Mp; i++) {
        uint16_t *row = dst + (size_t)i * ld;
        int k = 0;
        if (i < M) {
            const float *s = src + i * rs;
            if (cs == 1) {
                #pragma omp simd
                for (int q = 0; q < K; q++) row[q] = gemm_amx_bf16(s[q]);
            } else {
                for (int q = 0; q < K; q++) row[q] = gemm_amx_bf16(s[q * cs]);
            }
            k = K;
        }
        for (; k < Kp; k++) row[k] = 0;
    }
}

void gemm_amx_pack_b(uint16_t *dst, const float *src, long rs, long cs, int K, int N)
{
    int Kp = gemm_amx_round(K), Np = gemm_amx_round(N);
    for (int kk = 0; kk < Kp / 2; kk++) {
        uint16_t *row = dst + (size_t)kk * Np * 2;
        for (int e = 0; e < 2; e++) {
            int k = 2 * kk + e;
            const float *s = src + k * rs;
            for (int n = 0; n < Np; n++) row[2 * n + e] = k < K && n < N ? gemm_amx_bf16(s[n * cs]) : 0;
        }
    }
}

#ifdef PG_HAVE_AMX_BUILD
typedef struct {
    uint8_t palette_id;
    uint8_t start_row;
    uint8_t reserved[14];
    uint16_t colsb[16];
    uint8_t rows[16];
} __attribute__((packed, aligned(64))) amx_tilecfg;

/* Bias of f32 rows [i, i+16), columns [j, j+16). */
static void tile_bias(const gemm_amx_epilogue *e, int i, int j)
{
    for (int r = 0; r < 16; r++) {
        float *c = e->c + (size_t)(i + r) * e->ldc + j;
        #pragma omp simd
        for (int q = 0; q < 16; q++) c[q] += e->bias[j + q];
    }
}

/* A 16-wide edge of an f32 output: the column strip [j0, j0+16) over rows [i0, end) (rows = 0), or
 * the row strip [i0, i0+16) over columns [j0, end) (rows = 1), as 16x16 tiles in groups of up to
 * three that share their A (row strip) or B (column strip) operand, so the three accumulation
 * chains interleave instead of waiting on each other. */
static __attribute__((target("amx-tile,amx-bf16"))) void edge_strip(const uint16_t *A, int lda, const uint16_t *B,
                                                                    int ldb, int K, const gemm_amx_epilogue *e, int i0,
                                                                    int j0, int end, int rows)
{
    const long a_stride = (long)lda * 2, b_stride = (long)ldb * 2, c_stride = (long)e->ldc * 4;
    for (int x = rows ? j0 : i0; x < end; x += 48) {
        const int nt = end - x >= 48 ? 3 : (end - x) / 16;
        float *c[3] = { NULL, NULL, NULL };
        for (int t = 0; t < nt; t++)
            c[t] = rows ? e->c + (size_t)i0 * e->ldc + x + 16 * t : e->c + (size_t)(x + 16 * t) * e->ldc + j0;
        if (e->accumulate) {
            _tile_loadd(0, c[0], c_stride);
            if (nt > 1) _tile_loadd(1, c[1], c_stride);
            if (nt > 2) _tile_loadd(2, c[2], c_stride);
        } else {
            _tile_zero(0);
            _tile_zero(1);
            _tile_zero(2);
        }
        for (int k = 0; k < K; k += 32) {
            if (rows) { /* shared A rows i0, B columns x + 16t */
                const uint16_t *b0 = B + (size_t)(k / 2) * ldb + (size_t)x * 2;
                _tile_loadd(4, A + (size_t)i0 * lda + k, a_stride);
                _tile_loadd(5, b0, b_stride);
                _tile_dpbf16ps(0, 4, 5);
                if (nt > 1) {
                    _tile_loadd(6, b0 + 32, b_stride);
                    _tile_dpbf16ps(1, 4, 6);
                }
                if (nt > 2) {
                    _tile_loadd(7, b0 + 64, b_stride);
                    _tile_dpbf16ps(2, 4, 7);
                }
            } else { /* shared B columns j0, A rows x + 16t */
                const uint16_t *a0 = A + (size_t)x * lda + k;
                _tile_loadd(4, B + (size_t)(k / 2) * ldb + (size_t)j0 * 2, b_stride);
                _tile_loadd(5, a0, a_stride);
                _tile_dpbf16ps(0, 5, 4);
                if (nt > 1) {
                    _tile_loadd(6, a0 + (size_t)16 * lda, a_stride);
                    _tile_dpbf16ps(1, 6, 4);
                }
                if (nt > 2) {
                    _tile_loadd(7, a0 + (size_t)32 * lda, a_stride);
                    _tile_dpbf16ps(2, 7, 4);
                }
            }
        }
        _tile_stored(0, c[0], c_stride);
        if (nt > 1) _tile_stored(1, c[1], c_stride);
        if (nt > 2) _tile_stored(2, c[2], c_stride);
        if (e->bias)
            for (int t = 0; t < nt; t++) tile_bias(e, rows ? i0 : x + 16 * t, rows ? x + 16 * t : j0);
    }
}

__attribute__((target("amx-tile,amx-bf16"))) void gemm_amx(const uint16_t *A, int lda, const uint16_t *B, int ldb,
                                                            int M, int N, int K, const gemm_amx_epilogue *e)
{
    if (M <= 0 || N <= 0 || K <= 0) return;
    amx_tilecfg cfg;
    memset(&cfg, 0, sizeof(cfg));
    cfg.palette_id = 1;
    for (int t = 0; t < 8; t++) {
        cfg.rows[t] = 16;
        cfg.colsb[t] = 64;
    }
    _tile_loadconfig(&cfg);
    float blk[32 * 32] __attribute__((aligned(64)));
    const long a_stride = (long)lda * 2, b_stride = (long)ldb * 2, c_stride = (long)e->ldc * 4;
    const int M32 = M & ~31, N32 = N & ~31;
    for (int j = 0; j < N32; j += 32) {
        for (int i = 0; i < M32; i += 32) {
            float *cb = e->c ? e->c + (size_t)i * e->ldc + j : NULL;
            if (cb && e->accumulate) {
                _tile_loadd(0, cb, c_stride);
                _tile_loadd(1, cb + 16, c_stride);
                _tile_loadd(2, cb + (size_t)16 * e->ldc, c_stride);
                _tile_loadd(3, cb + (size_t)16 * e->ldc + 16, c_stride);
            } else {
                _tile_zero(0);
                _tile_zero(1);
                _tile_zero(2);
                _tile_zero(3);
            }
            const uint16_t *a0 = A + (size_t)i * lda, *b0 = B + (size_t)j * 2;
            for (int k = 0; k < K; k += 32) {
                _tile_loadd(4, a0 + k, a_stride);
                _tile_loadd(5, a0 + (size_t)16 * lda + k, a_stride);
                _tile_loadd(6, b0 + (size_t)(k / 2) * ldb, b_stride);
                _tile_loadd(7, b0 + (size_t)(k / 2) * ldb + 32, b_stride);
                _tile_dpbf16ps(0, 4, 6);
                _tile_dpbf16ps(1, 4, 7);
                _tile_dpbf16ps(2, 5, 6);
                _tile_dpbf16ps(3, 5, 7);
            }
            if (cb) {
                _tile_stored(0, cb, c_stride);
                _tile_stored(1, cb + 16, c_stride);
                _tile_stored(2, cb + (size_t)16 * e->ldc, c_stride);
                _tile_stored(3, cb + (size_t)16 * e->ldc + 16, c_stride);
                if (e->bias)
                    for (int r = 0; r < 32; r++) {
                        float *c = cb + (size_t)r * e->ldc;
                        const float *bj = e->bias + j;
                        #pragma omp simd
                        for (int q = 0; q < 32; q++) c[q] += bj[q];
                    }
                continue;
            }
            _tile_stored(0, blk, 128);
            _tile_stored(1, blk + 16, 128);
            _tile_stored(2, blk + 16 * 32, 128);
            _tile_stored(3, blk + 16 * 32 + 16, 128);
            gemm_block_epilogue(e, blk, i, j);
        }
    }
    if (N32 < N) edge_strip(A, lda, B, ldb, K, e, 0, N32, M, 0);
    if (M32 < M) edge_strip(A, lda, B, ldb, K, e, M32, 0, N32, 1);
    _tile_release();
}
#else
void gemm_amx(const uint16_t *A, int lda, const uint16_t *B, int ldb, int M, int N, int K, const gemm_amx_epilogue *e)
{
    (void)A; (void)lda; (void)B; (void)ldb; (void)M; (void)N; (void)K; (void)e;
}
#endif
