/* gemm_amx.h - bf16 matrix multiply on Intel AMX tiles (f32 accumulation), for the MLP layers.
 *
 * C (M, N) = or += A (M, K) * B (K, N), where A and B were first packed to bf16:
 *   A: row-major (Mp, Kp) with Mp = round_up(M, 32), Kp = round_up(K, 32), zero padded;
 *   B: "VNNI" pairs (Kp/2, Np, 2) with Np = round_up(N, 32): Bp[(k/2)*Np*2 + n*2 + k%2] = b(k, n).
 * The packers take any strides (a(i,k) = src[i*rs + k*cs]), so transposed operands need no copy
 * beforehand. bf16 keeps 8 mantissa bits: products carry ~0.4% relative rounding, sums are exact
 * f32. Use gemm_amx_available() first; everything here is a no-op-safe stub on other CPUs.
 */
#ifndef PG_DEFORM_GEMM_AMX_H
#define PG_DEFORM_GEMM_AMX_H

#include <stddef.h>
#include <stdint.h>

/* 1 if the CPU has AMX-BF16 and the kernel granted this process the tile state (asked once). */
int gemm_amx_available(void);

static inline int gemm_amx_round(int x) { return (x + 31) & ~31; }
/* Sizes (in uint16 elements) of the packed operands. */
static inline size_t gemm_amx_a_size(int M, int K) { return (size_t)gemm_amx_round(M) * gemm_amx_round(K); }
static inline size_t gemm_amx_b_size(int K, int N) { return (size_t)gemm_amx_round(K) * gemm_amx_round(N); }

void gemm_amx_pack_a(uint16_t *dst, const float *src, long rs, long cs, int M, int K);
void gemm_amx_pack_b(uint16_t *dst, const float *src, long rs, long cs, int K, int N);

/* C (row stride ldc) = Ap * Bp (accumulate = 0) or += (accumulate = 1). Only the M x N valid part of
 * C is written. */
void gemm_amx_run(float *C, int ldc, const uint16_t *Ap, const uint16_t *Bp, int M, int N, int K, int accumulate);
/* Same, then C = max(C + bias, 0) (relu) or C + bias per 32x32 block while it is hot; bias (N). */
void gemm_amx_run_bias(float *C, int ldc, const uint16_t *Ap, const uint16_t *Bp, int M, int N, int K,
                       int accumulate, const float *bias, int relu);

#endif
