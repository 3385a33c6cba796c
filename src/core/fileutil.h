/* fileutil.h - atomic file output and small path helpers.
 *
 * Results are written to "<path>.tmp.<pid>" and renamed over <path> only after a
 * successful fclose, so an interrupted run never leaves a complete-looking file.
 *
 *   pg_atomic_file f;
 *   PG_TRY(pg_atomic_open(&f, path));
 *   fwrite(..., f.fp);
 *   PG_TRY(pg_atomic_commit(&f));   // or pg_atomic_abort(&f) on error
 */
#ifndef PG_FILEUTIL_H
#define PG_FILEUTIL_H

#include <stdio.h>
#include "core/status.h"

typedef struct {
    FILE *fp;
    char path[4096];
    char tmp_path[4200];
} pg_atomic_file;

pg_status pg_atomic_open(pg_atomic_file *f, const char *path);
/* Flushes, closes (checked) and renames into place. Removes the temporary on failure. */
pg_status pg_atomic_commit(pg_atomic_file *f);
/* Closes and removes the temporary; safe to call twice. */
void pg_atomic_abort(pg_atomic_file *f);

/* Creates a directory and its parents (like mkdir -p). */
pg_status pg_mkdir_p(const char *path);
int pg_path_exists(const char *path);
int pg_path_is_dir(const char *path);
/* Joins dir and name with one slash into out (size bytes); fails if it does not fit. */
pg_status pg_path_join(char *out, size_t size, const char *dir, const char *name);
/* Joins name to path when path is a directory, else to the directory holding the file path ("."
 * for a bare file name): what lies beside a model given as its directory or its checkpoint. */
pg_status pg_path_join_beside(char *out, size_t size, const char *path, const char *name);
/* Reads a whole file into a malloc'd buffer (NUL-terminated); limit guards huge files. */
pg_status pg_read_file(const char *path, size_t limit, char **data, size_t *size);
/* Writes a whole buffer atomically. */
pg_status pg_write_file_atomic(const char *path, const void *data, size_t size);

#endif
