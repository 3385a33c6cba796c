/* load_env.c - settings two libraries read only when they are loaded, made before they are.
 *
 * OpenBLAS as Debian builds it (DYNAMIC_ARCH) picks its kernels once, when the library is loaded,
 * from the CPU's family and model numbers. A CPU newer than the library is not in its table and
 * gets the SSE3 "Prescott" kernels: Debian 12's 0.3.21 on a 5th-generation Xeon (family 6, model
 * 207) ran the depth network 3.0x slower than with its AVX-512 kernels (docs/nn.md). When the
 * library fell back to an old core and the CPU has AVX2 + FMA or AVX-512, OPENBLAS_CORETYPE is set
 * to the best core its features allow.
 *
 * libgomp spins at every barrier for a while before it sleeps (OMP_WAIT_POLICY unset). When
 * another program holds a core, a thread then spins through the time slice its partner needs: a
 * training iteration took 1.2-1.6x as long next to other jobs; on an idle machine spinning is up
 * to ~8 % faster (docs/train.md). So OMP_WAIT_POLICY is set to passive when the machine is busy
 * at start (1-minute load average of half a core or more).
 *
 * Both are read from the environment at load time, so when either is missing the process runs
 * itself again with them set (once: the second run finds them). A user's own values are kept.
 */
#include "cli/cli.h"

#include <cblas.h>
#include <stdio.h>
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

/* Whether other programs keep a core busy now. */
static int machine_busy(void)
{
    FILE *f = fopen("/proc/loadavg", "r");
    double load = 0;
    int got = f && fscanf(f, "%lf", &load) == 1;
    if (f) fclose(f);
    return got && load >= 0.5;
}

const char *cli_blas_core(void)
{
    const char *core = openblas_get_corename();
    return core ? core : "unknown";
}

void cli_set_load_env(char **argv)
{
    int again = 0;
    const char *want = core_for_cpu();
    if (!getenv("OPENBLAS_CORETYPE") && want && !core_is_current(cli_blas_core()))
        again |= setenv("OPENBLAS_CORETYPE", want, 1) == 0;
    if (!getenv("OMP_WAIT_POLICY") && machine_busy()) again |= setenv("OMP_WAIT_POLICY", "passive", 1) == 0;
    if (again) execv("/proc/self/exe", argv); /* returns only when it fails (no /proc): carry on */
}
