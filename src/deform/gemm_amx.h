/* gemm_amx.h - bf16 matrix multiply on Intel AMX tiles (f32 accumulation), for the MLP layers.
 *
 * C (M, N) = A (M, K) * B (K, N) with K a multiple of 32 and M, N multiples of 32 (multiples of 16
 * for an f32 output); callers pad with zeros:
 *   A: bf16 row-major, row stride lda (elements);
 *   B: bf16 "VNNI" pairs of rows: b(k, n) at B[(k/2)*ldb + 2n + k%2] (ldb = 2 * padded width).
 * Sub-blocks of a bigger operand are plain pointer offsets (A + k0, B + (k0/2)*ldb + 2*n0).
 * The result goes through an epilogue (gemm_amx_epilogue) applied per 32x32 block while it is in
 * L1, so a layer's output is written once, already converted to the bf16 layouts the next GEMMs
 * read. bf16 keeps 8 mantissa bits: products carry ~0.4% relative rounding, sums are exact f32.
 * Use gemm_amx_available() first; on other CPUs gemm_amx is a no-op stub.
 */
#ifndef PG_DEFORM_GEMM_AMX_H
#define PG_DEFORM_GEMM_AMX_H

#include <stddef.h>
#include <stdint.h>

/* 1 if the CPU has AMX-BF16 and the kernel granted this process the tile state (asked once). */
int gemm_amx_available(void);

static inline int gemm_amx_round(int x) { return (x + 31) & ~31; }

/* f32 -> bf16, round to nearest even (inputs here are finite). */
static inline uint16_t gemm_amx_bf16(float f)
{
    union { float f; uint32_t u; } v = { f };
    v.u += 0x7FFFu + ((v.u >> 16) & 1u);
    return (uint16_t)(v.u >> 16);
}

/* Packers from f32 with any strides (a(i,k) = src[i*rs + k*cs]). pack_a writes A row-major
 * (Mp, Kp) with row stride ld, zero outside (M, K); pack_b writes B as VNNI pairs
 * (round(K)/2, round(N), 2), zero padded. */
void gemm_amx_pack_a(uint16_t *dst, int ld, int Mp, int Kp, const float *src, long rs, long cs, int M, int K);
void gemm_amx_pack_b(uint16_t *dst, const float *src, long rs, long cs, int K, int N);

/* What happens to each block of the product v = A*B. Either an f32 output (c != NULL: c = v or
 * c += v (accumulate), then c += bias[j] if bias), or the epilogue of
 *     v = v + bias[j] (bias != NULL), v = max(v, 0) (relu), v = 0 where mask(i, j) == 0 (mask != NULL),
 * written as bf16 to any of rm (row-major), tr (transposed: tr[j*ldtr + i]) and vn (VNNI pairs of
 * rows: vn[(i/2)*ldvn + 2j + i%2]), and as f32 to f (row-major); colsum[j] += sum of v over rows
 * i < rows. All pointers are relative to the block (0, 0) of C, strides in elements. */
typedef struct {
    float *c;
    int ldc, accumulate;
    const float *bias;
    int relu;
    const uint16_t *mask;
    int ldmask;
    float *colsum;
    int rows;
    uint16_t *rm, *tr, *vn;
    int ldrm, ldtr, ldvn;
    float *f;
    int ldf;
} gemm_amx_epilogue;

void gemm_amx(const uint16_t *A, int lda, const uint16_t *B, int ldb, int M, int N, int K, const gemm_amx_epilogue *e);
/* The same product and epilogues on AVX512-BF16 (vdpbf16ps) for CPUs without AMX
 * (gemm_avx512bf16.c); M and N multiples of 16 for an f32 output, of 32 for bf16 outputs. */
void gemm_avx512bf16(const uint16_t *A, int lda, const uint16_t *B, int ldb, int M, int N, int K,
                     const gemm_amx_epilogue *e);
/* f32 products for the bf16 path's first layer and heads (gemm_avx512f32.c, AVX-512F), where bf16
 * roundings cost most of the accuracy for little of the time (docs/deform.md). gemm_f32: the same
 * product and epilogues with A f32 row-major (lda) and B f32 row-major (K, N) with row stride ldb
 * (columns up to N rounded to 16 read: zero padded); an f32 output is c = v (+ bias), any M and N,
 * no accumulate; bf16 outputs need M and N multiples of 32. gemm_f32_dots: N <= 16 outputs that
 * each read their own K inputs (the small heads of a block-diagonal layer),
 *     c[i*ldc + o] = bias[o] + sum_k A[i*lda + koff[o] + k] * B[o*K + k]   (i < M, o < N). */
void gemm_f32(const float *A, int lda, const float *B, int ldb, int M, int N, int K, const gemm_amx_epilogue *e);
void gemm_f32_dots(const float *A, int lda, const float *B, const int *koff, const float *bias, int M, int N, int K,
                   float *c, int ldc);
/* The epilogue (bf16 and f32 outputs) of one 32x32 f32 block v (row stride 32) at C position (i, j)
 * (gemm_epilogue.c). */
void gemm_block_epilogue(const gemm_amx_epilogue *e, const float *v, int i, int j);

/* Backends, chosen once at run time (gemm_dispatch.c): the best the CPU has, or PG_KERNELS=amx|
 * avx512bf16|f32 (PG_NO_AMX=1 skips AMX). GEMM_BF16_NONE: no bf16 GEMM; the network runs in f32. */
typedef enum { GEMM_BF16_NONE = 0, GEMM_BF16_AMX, GEMM_BF16_AVX512 } gemm_bf16_kind;
gemm_bf16_kind gemm_bf16_backend(void);
int gemm_bf16_supported(gemm_bf16_kind k);
const char *gemm_bf16_name(gemm_bf16_kind k);
/* Tests and benchmarks: use backend k from now on (-1 if the CPU lacks it). */
int gemm_bf16_force(gemm_bf16_kind k);
/* gemm_amx or gemm_avx512bf16, whichever the backend is (not for GEMM_BF16_NONE). */
void gemm_bf16(const uint16_t *A, int lda, const uint16_t *B, int ldb, int M, int N, int K, const gemm_amx_epilogue *e);

#endif
