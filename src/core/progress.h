/* progress.h - progress reporting without printing from the library.
 *
 * Long-running stages call pg_progress_report(); the CLI installs a sink that prints
 * a live line on a terminal or one structured line per update otherwise.
 */
#ifndef PG_PROGRESS_H
#define PG_PROGRESS_H

/* stage: "proxies", "train", ...; step in [0, total]; detail: "loss=0.031 psnr=27.1" or "". */
typedef void (*pg_progress_fn)(void *ctx, const char *stage, long step, long total, const char *detail);

void pg_progress_set_sink(pg_progress_fn fn, void *ctx);
/* Reports progress (no-op without a sink). Call from one thread only. */
void pg_progress_report(const char *stage, long step, long total, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));

#endif
