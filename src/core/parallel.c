/* parallel.c - OpenMP thread settings and a monotonic clock. */
#include "core/parallel.h"

#include <omp.h>
#include <time.h>

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
