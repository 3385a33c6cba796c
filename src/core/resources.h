/* resources.h - what a long run costs and what the machine has: peak memory per phase, bytes on
 * disk under a folder, free memory and free disk.
 *
 *   pg_peak_rss_reset();            // start of a stage
 *   ... work ...
 *   long kb = pg_peak_rss_kb();     // the stage's peak resident memory
 *   uint64_t bytes = pg_dir_bytes("out/prepare");
 *
 * Linux /proc is read where it exists; elsewhere the peak falls back to getrusage (the process's
 * peak, never reset) and the free amounts to 0 (unknown).
 */
#ifndef PG_RESOURCES_H
#define PG_RESOURCES_H

#include <stdint.h>

/* Starts a new peak-memory window (Linux: /proc/self/clear_refs 5; a no-op elsewhere). */
void pg_peak_rss_reset(void);
/* Peak resident memory in KiB since the last reset (or since the process started). */
long pg_peak_rss_kb(void);
/* Bytes of disk the files under path take (allocated blocks, as du counts); 0 if absent. */
uint64_t pg_dir_bytes(const char *path);
/* Memory the kernel says a new allocation can get without swapping (MemAvailable); 0 if unknown. */
uint64_t pg_mem_available_bytes(void);
/* Free disk space for an unprivileged writer on the file system holding path; 0 if unknown. */
uint64_t pg_disk_free_bytes(const char *path);

#endif
