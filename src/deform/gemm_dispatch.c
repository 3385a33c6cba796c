/* gemm_dispatch.c - which bf16 GEMM backend the deformation network uses, chosen at run time from
 * the CPU (one binary for every x86-64 CPU): AMX-BF16 tiles, else AVX512-BF16 vdpbf16ps, else
 * none (the network's f32 path on OpenBLAS). PG_KERNELS=amx|avx512bf16|f32 forces one (an
 * unsupported choice falls back to the best supported one), PG_NO_AMX=1 skips AMX. */
#include "core/status.h"
#include "deform/gemm_amx.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#if defined(__x86_64__) && defined(__GNUC__)
#include <cpuid.h>
#endif

static int backend = -1; /* gemm_bf16_kind once chosen */

/* AVX512-BF16 (CPUID.(7,1):EAX[5]) with the AVX-512 subsets the kernels use, enabled by the OS. */
static int cpu_has_avx512bf16(void)
{
#if defined(__x86_64__) && defined(__GNUC__)
    unsigned a, b, c, d;
    if (!__builtin_cpu_supports("avx512f") || !__builtin_cpu_supports("avx512bw") || !__builtin_cpu_supports("avx512vl"))
        return 0;
    return __get_cpuid_count(7, 1, &a, &b, &c, &d) && (a & (1u << 5));
#else
    return 0;
#endif
}

int gemm_bf16_supported(gemm_bf16_kind k)
{
    switch (k) {
    case GEMM_BF16_NONE: return 1;
    case GEMM_BF16_AMX: return gemm_amx_available();
    case GEMM_BF16_AVX512: return cpu_has_avx512bf16();
    }
    return 0;
}

const char *gemm_bf16_name(gemm_bf16_kind k)
{
    static const char *names[] = { "f32", "amx", "avx512bf16" };
    return (unsigned)k < 3 ? names[k] : "?";
}

static gemm_bf16_kind choose(void)
{
    const char *force = getenv("PG_KERNELS"), *no_amx = getenv("PG_NO_AMX");
    int amx_ok = !(no_amx && strcmp(no_amx, "0") != 0) && gemm_bf16_supported(GEMM_BF16_AMX);
    gemm_bf16_kind best = amx_ok ? GEMM_BF16_AMX : gemm_bf16_supported(GEMM_BF16_AVX512) ? GEMM_BF16_AVX512 : GEMM_BF16_NONE;
    if (!force || !*force) return best;
    for (int k = GEMM_BF16_NONE; k <= GEMM_BF16_AVX512; k++)
        if (strcmp(force, gemm_bf16_name((gemm_bf16_kind)k)) == 0) {
            if (gemm_bf16_supported((gemm_bf16_kind)k) && (k != GEMM_BF16_AMX || amx_ok)) return (gemm_bf16_kind)k;
            pg_warn("PG_KERNELS=%s is not supported by this CPU; using %s", force,
                    gemm_bf16_name(best));
            return best;
        }
    pg_warn("PG_KERNELS=%s is not one of f32, amx, avx512bf16; using %s", force,
            gemm_bf16_name(best));
    return best;
}

gemm_bf16_kind gemm_bf16_backend(void)
{
    if (backend < 0) backend = choose();
    return (gemm_bf16_kind)backend;
}

int gemm_bf16_force(gemm_bf16_kind k)
{
    if (!gemm_bf16_supported(k)) return -1;
    backend = k;
    return 0;
}

void gemm_bf16(const uint16_t *A, int lda, const uint16_t *B, int ldb, int M, int N, int K, const gemm_amx_epilogue *e)
{
    if (gemm_bf16_backend() == GEMM_BF16_AMX) gemm_amx(A, lda, B, ldb, M, N, K, e);
    else gemm_avx512bf16(A, lda, B, ldb, M, N, K, e);
}
