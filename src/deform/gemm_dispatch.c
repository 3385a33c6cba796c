/* gemm_dispatch.c - which packed GEMM backend the deformation network uses, chosen at run time from
 * the CPU (one binary for every x86-64 CPU): AMX-BF16 tiles, else AVX512-BF16 vdpbf16ps, else f32
 * FMAs on the same bf16 operands with AVX-512F or AVX2, else none (the network's f32 path on
 * OpenBLAS). PG_KERNELS=amx|avx512bf16|avx512f|avx2|f32 forces one (an unsupported choice falls
 * back to the best supported one), PG_NO_AMX=1 skips AMX. */
#include "deform/gemm_amx.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#if defined(__x86_64__) && defined(__GNUC__)
#include <cpuid.h>
#define PG_X86 1
#endif

static int backend = -1; /* gemm_bf16_kind once chosen */
static int has_bf16 = -1;

/* AVX512-BF16 (CPUID.(7,1):EAX[5]) with the AVX-512 subsets the kernels use, enabled by the OS. */
int gemm_cpu_has_avx512bf16(void)
{
    if (has_bf16 >= 0) return has_bf16;
    has_bf16 = 0;
#ifdef PG_X86
    unsigned a, b, c, d;
    if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512vl"))
        has_bf16 = __get_cpuid_count(7, 1, &a, &b, &c, &d) && (a & (1u << 5));
#endif
    return has_bf16;
}

int gemm_bf16_supported(gemm_bf16_kind k)
{
#ifdef PG_X86
    switch (k) {
    case GEMM_BF16_NONE: return 1;
    case GEMM_BF16_AMX: return gemm_amx_available();
    case GEMM_BF16_AVX512: return gemm_cpu_has_avx512bf16();
    case GEMM_BF16_AVX512F:
        return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
               __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("fma");
    case GEMM_BF16_AVX2: return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
    default: return 0;
    }
#else
    return k == GEMM_BF16_NONE;
#endif
}

const char *gemm_bf16_name(gemm_bf16_kind k)
{
    static const char *names[GEMM_BF16_KINDS] = { "f32", "amx", "avx512bf16", "avx512f", "avx2" };
    return (unsigned)k < GEMM_BF16_KINDS ? names[k] : "?";
}

static gemm_bf16_kind choose(void)
{
    const char *force = getenv("PG_KERNELS"), *no_amx = getenv("PG_NO_AMX");
    int amx_ok = !(no_amx && strcmp(no_amx, "0") != 0) && gemm_bf16_supported(GEMM_BF16_AMX);
    /* fastest first (measured: docs/deform.md) */
    static const gemm_bf16_kind order[] = { GEMM_BF16_AMX, GEMM_BF16_AVX512, GEMM_BF16_AVX512F, GEMM_BF16_AVX2 };
    gemm_bf16_kind best = GEMM_BF16_NONE;
    for (size_t o = 0; o < sizeof(order) / sizeof(order[0]) && best == GEMM_BF16_NONE; o++)
        if ((order[o] != GEMM_BF16_AMX || amx_ok) && gemm_bf16_supported(order[o])) best = order[o];
    if (!force || !*force) return best;
    for (int k = 0; k < GEMM_BF16_KINDS; k++)
        if (strcmp(force, gemm_bf16_name((gemm_bf16_kind)k)) == 0) {
            if (gemm_bf16_supported((gemm_bf16_kind)k) && (k != GEMM_BF16_AMX || amx_ok)) return (gemm_bf16_kind)k;
            fprintf(stderr, "prodygs: warning: PG_KERNELS=%s is not supported by this CPU; using %s\n", force,
                    gemm_bf16_name(best));
            return best;
        }
    fprintf(stderr, "prodygs: warning: PG_KERNELS=%s is not one of f32, amx, avx512bf16, avx512f, avx2; using %s\n",
            force, gemm_bf16_name(best));
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
    switch (gemm_bf16_backend()) {
    case GEMM_BF16_AMX: gemm_amx(A, lda, B, ldb, M, N, K, e); break;
    case GEMM_BF16_AVX512: gemm_blocked(A, lda, B, ldb, M, N, K, e, &gemm_kernel_avx512bf16); break;
    case GEMM_BF16_AVX512F: gemm_blocked(A, lda, B, ldb, M, N, K, e, &gemm_kernel_avx512f); break;
    case GEMM_BF16_AVX2: gemm_blocked(A, lda, B, ldb, M, N, K, e, &gemm_kernel_avx2); break;
    default: break;
    }
}
