/* parallel.h - thread count control on top of OpenMP. */
#ifndef PG_PARALLEL_H
#define PG_PARALLEL_H

/* Sets the number of worker threads (<= 0: all cores). */
void pg_set_threads(int n);
int pg_get_threads(void);
/* Index of the calling thread inside a parallel region (0 outside). */
int pg_thread_index(void);
/* Monotonic wall clock in seconds. */
double pg_time_seconds(void);
/* CPU time of the whole process in seconds (all threads): on a shared machine this shows what
 * a run cost even when other jobs stretch the wall clock. */
double pg_cpu_seconds(void);
/* Median of v[0..n) (sorts v in place). */
double pg_median(double *v, int n);
/* The same for floats (v sorted in place; 0 when n <= 0). */
float pg_median_float(float *v, int n);

#endif
