/* parallel.c - OpenMP thread settings and a monotonic clock. */
#include "core/parallel.h"

#include <omp.h>
#include <stdlib.h>
#include <time.h>

#include "core/mathx.h"

void pg_set_threads(int n)
{
    if (n <= 0) n = omp_get_num_procs();
    omp_set_num_threads(n);
}

int pg_get_threads(void) { return omp_get_max_threads(); }

int pg_thread_index(void) { return omp_get_thread_num(); }

double pg_time_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

double pg_cpu_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

double pg_median(double *v, int n)
{
    if (n <= 0) return 0.0;
    qsort(v, (size_t)n, sizeof(double), pg_cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

float pg_median_float(float *v, int n)
{
    if (n <= 0) return 0.0f;
    qsort(v, (size_t)n, sizeof(float), pg_cmp_float);
    return n % 2 ? v[n / 2] : 0.5f * (v[n / 2 - 1] + v[n / 2]);
}
