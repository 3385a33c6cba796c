/* resources.h - what a long run costs and what the machine has: peak memory of a phase, bytes
 * on disk under a folder, free memory and free disk.
 *
 *   pg_peak_window w;
 *   pg_peak_window_begin(&w);       // start of a stage: a thread samples the resident size
 *   ... work ...
 *   long kb = pg_peak_window_end(&w);  // the stage's peak resident memory, KiB
 *   uint64_t bytes = pg_dir_bytes("out/prepare");
 *
 * The window's peak is exact when the stage raised the process's high-water mark (VmHWM), else the
 * largest of the samples taken every 20 ms. Nothing resets the kernel's high-water mark, so
 * /usr/bin/time and getrusage still see the whole process's peak. Linux /proc is read where it
 * exists; elsewhere peaks come from getrusage and the free amounts are 0 (unknown).
 */
#ifndef PG_RESOURCES_H
#define PG_RESOURCES_H

#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>

typedef struct {
    pthread_t thread;
    int running;          /* the sampler thread was started (pg_peak_window_end not yet called) */
    atomic_int stop;
    long hwm_at_begin;    /* VmHWM when the window began */
    atomic_long max_kb;   /* the largest sampled VmRSS */
} pg_peak_window;

void pg_peak_window_begin(pg_peak_window *w);
/* Stops the sampler; the window's peak resident memory in KiB. Safe on a window never begun
 * (zeroed) or already ended. */
long pg_peak_window_end(pg_peak_window *w);
/* The process's peak resident memory in KiB (VmHWM, or getrusage). */
long pg_peak_rss_kb(void);
/* Bytes of disk the files under path take (allocated blocks, as du counts); 0 if absent. */
uint64_t pg_dir_bytes(const char *path);
/* Memory the kernel says a new allocation can get without swapping (MemAvailable); 0 if unknown. */
uint64_t pg_mem_available_bytes(void);
/* Free disk space for an unprivileged writer on the file system holding path; 0 if unknown. */
uint64_t pg_disk_free_bytes(const char *path);

#endif
