/* blas_kernels.c - makes OpenBLAS run the kernels this CPU can run.
 *
 * OpenBLAS as Debian builds it (DYNAMIC_ARCH) picks its kernels once, when the library is loaded,
 * from the CPU's family and model numbers. A CPU newer than the library is not in its table and
 * gets the SSE3 "Prescott" kernels: Debian 12's 0.3.21 on a 5th-generation Xeon (family 6, model
 * 207) ran the depth network 3.6x slower than with its AVX-512 kernels (docs/nn.md). The choice
 * can only be made before the library loads (OPENBLAS_CORETYPE), so when the library fell back to
 * an old core and the CPU has AVX2 + FMA or AVX-512, the process runs itself again with the
 * variable set to the best core its features allow. A user's own OPENBLAS_CORETYPE is kept.
 */
#include "cli/cli.h"

#include <cblas.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* The OpenBLAS core for this CPU's features (GCC's checks include the OS's AVX state). */
static const char *core_for_cpu(void)
{
    if (__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
        __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("fma"))
        return "SkylakeX";
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma")) return "Haswell";
    return NULL;
}

/* Cores whose kernels use AVX2 + FMA or better: the library knew the CPU. */
static int core_is_current(const char *core)
{
    static const char *const current[] = { "Haswell", "SkylakeX", "Cooperlake", "SapphireRapids", "Zen" };
    for (size_t i = 0; i < sizeof current / sizeof current[0]; i++)
        if (strcmp(core, current[i]) == 0) return 1;
    return 0;
}

const char *cli_blas_core(void)
{
    const char *core = openblas_get_corename();
    return core ? core : "unknown";
}

void cli_blas_use_cpu_kernels(char **argv)
{
    if (getenv("OPENBLAS_CORETYPE")) return;
    const char *want = core_for_cpu();
    if (!want || core_is_current(cli_blas_core())) return;
    if (setenv("OPENBLAS_CORETYPE", want, 1) != 0) return;
    execv("/proc/self/exe", argv);
    unsetenv("OPENBLAS_CORETYPE"); /* no exec (no /proc): carry on with the library's choice */
}
