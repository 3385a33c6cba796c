/* status.h - error codes with a context message.
 *
 * Every library function that can fail returns a pg_status. On failure it also
 * records one human-readable line (naming the file, frame or value at fault) that
 * the caller can fetch with pg_last_error(). The message is per thread.
 *
 *   if (bad) return pg_fail(PG_ERR_FORMAT, "%s: header says %d x %d", path, w, h);
 *   ...
 *   pg_status st = io_npy_load(path, &arr);
 *   if (st) fprintf(stderr, "prodygs: %s\n", pg_last_error());
 */
#ifndef PG_STATUS_H
#define PG_STATUS_H

#include <stddef.h>

#include "prodygs.h" /* pg_status, pg_last_error: part of the public API */

/* Records the message and returns code, so callers can `return pg_fail(...)`. */
pg_status pg_fail(pg_status code, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
/* Prefixes the current message with more context ("frame 3: " + old message). */
pg_status pg_fail_context(pg_status code, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
/* Reports a warning through the handler of pg_set_warning_handler (one line, controls escaped). */
void pg_warn(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
/* Process exit code for a status: 0 ok, 2 user/input error, 1 internal failure. */
int pg_status_exit_code(pg_status code);

/* Overflow-checked size arithmetic for buffers whose sizes come from files. */
int pg_size_mul(size_t a, size_t b, size_t *out); /* 0 on success, -1 on overflow */
/* malloc/calloc that record PG_ERR_NOMEM with what was being allocated. */
void *pg_malloc(size_t bytes, const char *what);
void *pg_calloc(size_t count, size_t size, const char *what);

#define PG_TRY(expr) do { pg_status pg__st = (expr); if (pg__st != PG_OK) return pg__st; } while (0)

#endif
