/* gemm_amx.c - bf16 AMX matrix multiply (see gemm_amx.h).
 *
 * Blocking: 32x32 output blocks held in four 16x16 f32 tiles (tmm0-3), two A tiles (tmm4-5, 16 rows
 * x 32 bf16) and two B tiles (tmm6-7, 16 pair-rows x 16 columns) per 32-deep K step.
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
    /* Linux keeps the 8 KB tile state off until the process asks for it. */
    if (ok) ok = syscall(SYS_arch_prctl, ARCH_REQ_XCOMP_PERM, XFEATURE_XTILEDATA) == 0;
    amx_state = ok;
    return ok;
#else
    return 0;
#endif
}

/* f32 -> bf16, round to nearest even (inputs here are finite). */
static inline uint16_t f2bf(float f)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    u += 0x7FFFu + ((u >> 16) & 1u);
    return (uint16_t)(u >> 16);
}

void gemm_amx_pack_a(uint16_t *dst, const float *src, long rs, long cs, int M, int K)
{
    int Mp = gemm_amx_round(M), Kp = gemm_amx_round(K);
    for (int i = 0; i < Mp; i++) {
        uint16_t *row = dst + (size_t)i * Kp;
        int k = 0;
        if (i < M) {
            const float *s = src + i * rs;
            if (cs == 1) {
                #pragma omp simd
                for (int q = 0; q < K; q++) row[q] = f2bf(s[q]);
            } else {
                for (int q = 0; q < K; q++) row[q] = f2bf(s[q * cs]);
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
        if (cs == 1 && 2 * kk + 1 < K) {
            /* two contiguous source rows interleaved as 32-bit pairs: vectorises */
            const float *s0 = src + 2 * kk * rs, *s1 = s0 + rs;
            uint32_t *r32 = (uint32_t *)row;
            #pragma omp simd
            for (int n = 0; n < N; n++) r32[n] = (uint32_t)f2bf(s0[n]) | ((uint32_t)f2bf(s1[n]) << 16);
            for (int n = N; n < Np; n++) r32[n] = 0;
            continue;
        }
        for (int e = 0; e < 2; e++) {
            int k = 2 * kk + e;
            if (k < K) {
                const float *s = src + k * rs;
                for (int n = 0; n < N; n++) row[2 * n + e] = f2bf(s[n * cs]);
                for (int n = N; n < Np; n++) row[2 * n + e] = 0;
            } else {
                for (int n = 0; n < Np; n++) row[2 * n + e] = 0;
            }
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

/* C block rows [i, i+mi), cols [j, j+nj): c = max(c + bias, 0) or c + bias, while it is in L1. */
static inline void block_epilogue(float *C, int ldc, int i, int j, int mi, int nj, const float *bias, int relu)
{
    const float *bj = bias + j;
    for (int r = 0; r < mi; r++) {
        float *c = C + (size_t)(i + r) * ldc + j;
        if (relu) {
            #pragma omp simd
            for (int q = 0; q < nj; q++) {
                float v = c[q] + bj[q];
                c[q] = v > 0.0f ? v : 0.0f;
            }
        } else {
            #pragma omp simd
            for (int q = 0; q < nj; q++) c[q] += bj[q];
        }
    }
}

void gemm_amx_run(float *C, int ldc, const uint16_t *Ap, const uint16_t *Bp, int M, int N, int K, int accumulate)
{
    gemm_amx_run_bias(C, ldc, Ap, Bp, M, N, K, accumulate, NULL, 0);
}

__attribute__((target("amx-tile,amx-bf16"))) void gemm_amx_run_bias(float *C, int ldc, const uint16_t *Ap,
                                                                     const uint16_t *Bp, int M, int N, int K,
                                                                     int accumulate, const float *bias, int relu)
{
    const int Kp = gemm_amx_round(K), Np = gemm_amx_round(N), Mp = gemm_amx_round(M);
    amx_tilecfg cfg;
    memset(&cfg, 0, sizeof(cfg));
    cfg.palette_id = 1;
    for (int t = 0; t < 8; t++) {
        cfg.rows[t] = 16;
        cfg.colsb[t] = 64;
    }
    _tile_loadconfig(&cfg);
    float blk[32 * 32] __attribute__((aligned(64)));
    const long a_stride = (long)Kp * 2, b_stride = (long)Np * 4;
    for (int i = 0; i < Mp; i += 32) {
        for (int j = 0; j < Np; j += 32) {
            /* full 32x32 blocks load/store C directly; ragged edges go through blk */
            const int full = i + 32 <= M && j + 32 <= N;
            float *cb = C + (size_t)i * ldc + j;
            const long c_stride = (long)ldc * 4;
            if (full && accumulate) {
                _tile_loadd(0, cb, c_stride);
                _tile_loadd(1, cb + 16, c_stride);
                _tile_loadd(2, cb + (size_t)16 * ldc, c_stride);
                _tile_loadd(3, cb + (size_t)16 * ldc + 16, c_stride);
            } else {
                _tile_zero(0);
                _tile_zero(1);
                _tile_zero(2);
                _tile_zero(3);
            }
            for (int k = 0; k < Kp; k += 32) {
                const uint16_t *a0 = Ap + (size_t)i * Kp + k;
                const uint16_t *b0 = Bp + (size_t)(k / 2) * Np * 2 + (size_t)j * 2;
                _tile_loadd(4, a0, a_stride);
                _tile_loadd(5, a0 + (size_t)16 * Kp, a_stride);
                _tile_loadd(6, b0, b_stride);
                _tile_loadd(7, b0 + 32, b_stride);
                _tile_dpbf16ps(0, 4, 6);
                _tile_dpbf16ps(1, 4, 7);
                _tile_dpbf16ps(2, 5, 6);
                _tile_dpbf16ps(3, 5, 7);
            }
            if (full) {
                _tile_stored(0, cb, c_stride);
                _tile_stored(1, cb + 16, c_stride);
                _tile_stored(2, cb + (size_t)16 * ldc, c_stride);
                _tile_stored(3, cb + (size_t)16 * ldc + 16, c_stride);
                if (bias) block_epilogue(C, ldc, i, j, 32, 32, bias, relu);
                continue;
            }
            _tile_stored(0, blk, 128);
            _tile_stored(1, blk + 16, 128);
            _tile_stored(2, blk + 16 * 32, 128);
            _tile_stored(3, blk + 16 * 32 + 16, 128);
            int mi = M - i < 32 ? M - i : 32, nj = N - j < 32 ? N - j : 32;
            for (int r = 0; r < mi; r++) {
                float *c = C + (size_t)(i + r) * ldc + j;
                const float *s = blk + r * 32;
                if (accumulate) {
                    #pragma omp simd
                    for (int q = 0; q < nj; q++) c[q] += s[q];
                } else {
                    memcpy(c, s, (size_t)nj * sizeof(float));
                }
            }
            if (bias) block_epilogue(C, ldc, i, j, mi, nj, bias, relu);
        }
    }
    _tile_release();
}
#else
void gemm_amx_run_bias(float *C, int ldc, const uint16_t *Ap, const uint16_t *Bp, int M, int N, int K,
                       int accumulate, const float *bias, int relu)
{
    (void)C; (void)ldc; (void)Ap; (void)Bp; (void)M; (void)N; (void)K; (void)accumulate; (void)bias; (void)relu;
}

void gemm_amx_run(float *C, int ldc, const uint16_t *Ap, const uint16_t *Bp, int M, int N, int K, int accumulate)
{
    (void)C; (void)ldc; (void)Ap; (void)Bp; (void)M; (void)N; (void)K; (void)accumulate;
}
#endif
