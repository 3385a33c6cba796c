/* output.h - the one check and lock every stage takes on its output before any work.
 *
 * A stage claims its output first: a path that exists as the wrong kind (a regular file given
 * as an output folder, a folder given as an output file) is refused before anything runs, and a
 * second process on the same output stops at once, naming the first's PID, instead of racing it.
 * The pipeline claims OUT and every stage folder under it for its whole life, so a standalone
 * stage pointed into a running pipeline's folders is refused too.
 *
 *   PG_TRY(pg_output_claim_dir(dir));
 *   st = do_the_work(dir);
 *   pg_output_release(dir);
 *
 * The lock is an exclusive flock on PATH.lock beside the output (folder or file), the holder's
 * PID inside; the kernel drops it however the process ends, and the last release removes the
 * file. Beside, not inside: a claim creates nothing but the lock (a refused stage leaves no
 * folder), and a stage that moves its folder whole (DIR.partial -> DIR) does not move its lock. Claims are counted per process: a stage
 * inside `run` claims a folder the run already holds and only its count goes up. The table is
 * process-wide and not thread-safe: stages are started from one thread.
 */
#ifndef PG_OUTPUT_H
#define PG_OUTPUT_H

#include "core/status.h"

/* Refuses (PG_ERR_ARG) a path that exists and is not a folder, creates the parent folders
 * (PG_ERR_ENV when it cannot), then locks DIR.lock (PG_ERR_ENV naming the holder's PID when
 * another process has it). DIR itself is left to the stage. */
pg_status pg_output_claim_dir(const char *dir);
/* The same for an output file: refuses a path that exists and is not a regular file. */
pg_status pg_output_claim_file(const char *path);
/* Gives back one claim of pg_output_claim_*; the last one unlocks and removes the lock file. */
void pg_output_release(const char *path);
/* 1 if path is an output this process holds a claim on, or its lock file (content hashes leave
 * them out: an output inside the input folder is not part of the input). */
int pg_output_is_claimed(const char *path);

#endif
