/* gemm_blocked.c - the blocking loop of the SIMD bf16-operand GEMM backends (gemm_amx.h) that are
 * built from a register micro-kernel: AVX512-BF16, AVX-512F and AVX2 (AMX has its own tile loop).
 *
 * Column blocks of 32 are the outer loop so the B panel (K x 32 bf16) stays in L1 while the row
 * blocks stream past it; each 32x32 block is finished by the backend's epilogue while it is in L1.
 */
#include "deform/gemm_amx.h"

void gemm_blocked(const uint16_t *A, int lda, const uint16_t *B, int ldb, int M, int N, int K,
                  const gemm_amx_epilogue *e, const gemm_micro_kernel *k)
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
                for (int r = 0; r < mr; r += k->rows)
                    k->micro(A + (size_t)(i + r) * lda, lda, bj, ldb, K, mr - r < k->rows ? mr - r : k->rows, nv,
                             cb + (size_t)r * e->ldc, e->ldc, e->accumulate);
                if (e->bias)
                    for (int r = 0; r < mr; r++) {
                        float *c = cb + (size_t)r * e->ldc;
                        for (int q = 0; q < 16 * nv; q++) c[q] += e->bias[j + q];
                    }
                continue;
            }
            /* bf16 outputs: whole 32x32 blocks (the callers pad M and N to 32) */
            for (int r = 0; r < 32; r += k->rows)
                k->micro(A + (size_t)(i + r) * lda, lda, bj, ldb, K, k->rows, 2, blk + r * 32, 32, 0);
            k->epilogue(e, blk, i, j);
        }
    }
}
