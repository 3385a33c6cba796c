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

void gemm_amx_pack_a(uint16_t *dst, int ld, int Mp, int Kp, const float *src, long rs, long cs, int M, int K)
{
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

/* The bf16 epilogue of one 32x32 block v (row stride 32, modified in place) at C position (i, j). */
static void block_epilogue(const gemm_amx_epilogue *e, float *v, int i, int j)
{
    for (int r = 0; r < 32; r++) {
        float *b = v + r * 32;
        if (e->bias) {
            const float *bj = e->bias + j;
            #pragma omp simd
            for (int q = 0; q < 32; q++) b[q] += bj[q];
        }
        if (e->relu) {
            #pragma omp simd
            for (int q = 0; q < 32; q++) b[q] = b[q] > 0.0f ? b[q] : 0.0f;
        }
        if (e->mask) {
            const uint16_t *mk = e->mask + (size_t)(i + r) * e->ldmask + j;
            #pragma omp simd
            for (int q = 0; q < 32; q++) b[q] = mk[q] ? b[q] : 0.0f;
        }
        if (e->rm) {
            uint16_t *o = e->rm + (size_t)(i + r) * e->ldrm + j;
            #pragma omp simd
            for (int q = 0; q < 32; q++) o[q] = gemm_amx_bf16(b[q]);
        }
    }
    if (e->colsum) {
        int nr = e->rows - i < 32 ? e->rows - i : 32;
        float *cs = e->colsum + j;
        for (int r = 0; r < nr; r++) {
            const float *b = v + r * 32;
            #pragma omp simd
            for (int q = 0; q < 32; q++) cs[q] += b[q];
        }
    }
    if (e->vn)
        for (int r = 0; r < 32; r += 2) {
            uint32_t *o = (uint32_t *)(e->vn + (size_t)((i + r) / 2) * e->ldvn + 2 * j);
            const float *b0 = v + r * 32, *b1 = b0 + 32;
            #pragma omp simd
            for (int q = 0; q < 32; q++) o[q] = (uint32_t)gemm_amx_bf16(b0[q]) | (uint32_t)gemm_amx_bf16(b1[q]) << 16;
        }
    if (e->tr)
        for (int q = 0; q < 32; q++) {
            uint16_t *o = e->tr + (size_t)(j + q) * e->ldtr + i;
            #pragma omp simd
            for (int r = 0; r < 32; r++) o[r] = gemm_amx_bf16(v[r * 32 + q]);
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
    for (int j = 0; j < N; j += 32) {
        for (int i = 0; i < M; i += 32) {
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
            block_epilogue(e, blk, i, j);
        }
    }
    _tile_release();
}
#else
void gemm_amx(const uint16_t *A, int lda, const uint16_t *B, int ldb, int M, int N, int K, const gemm_amx_epilogue *e)
{
    (void)A; (void)lda; (void)B; (void)ldb; (void)M; (void)N; (void)K; (void)e;
    (void)block_epilogue;
}
#endif
