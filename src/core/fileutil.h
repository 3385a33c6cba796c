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

/* A stage's output folder filled out of sight. The stage writes into `work` (DIR.partial, beside
 * DIR); pg_staged_dir_commit moves every entry into DIR once the stage completes. A crash or a
 * full disk leaves DIR.partial, never a half-filled DIR that looks complete; creating
 * DIR.partial first is also the check, before any work, that the output is writable.
 *
 *   pg_staged_dir out;
 *   PG_TRY(pg_staged_dir_begin(&out, dir, 0));
 *   st = write_everything(out.work);
 *   st = st ? (pg_staged_dir_abort(&out), st) : pg_staged_dir_commit(&out);
 */
typedef struct {
    char final[4096];
    char work[4200];
    int replace; /* set after begin: commit empties DIR first, so DIR holds exactly this result */
} pg_staged_dir;

/* Creates DIR's parent and DIR.partial. resume = 0 clears what a crashed run left in
 * DIR.partial; resume = 1 keeps it (stages that skip finished frames). */
pg_status pg_staged_dir_begin(pg_staged_dir *d, const char *dir, int resume);
/* Moves every entry of DIR.partial into DIR (replacing same-named ones) and removes DIR.partial. */
pg_status pg_staged_dir_commit(pg_staged_dir *d);
/* Removes DIR.partial and what is in it (a failed stage). */
void pg_staged_dir_abort(pg_staged_dir *d);
/* Removes a file or a directory tree (like rm -rf); a missing path is not an error. */
pg_status pg_remove_tree(const char *path);

/* Creates a directory and its parents (like mkdir -p). */
pg_status pg_mkdir_p(const char *path);
/* The one policy for a cache folder shared between runs (the built-in model's): created mode
 * 0700 if missing; used only if it is a real folder (not a symbolic link) owned by this user, and
 * made 0700 if it was open to others. PG_ERR_ENV naming the folder otherwise: another user's
 * folder in /tmp could swap the files the next run loads. */
pg_status pg_private_dir(const char *dir);
int pg_path_exists(const char *path);
int pg_path_is_dir(const char *path);
/* Joins dir and name with one slash into out (size bytes); fails if it does not fit. */
pg_status pg_path_join(char *out, size_t size, const char *dir, const char *name);
/* Joins name to path when path is a directory, else to the directory holding the file path ("."
 * for a bare file name): what lies beside a model given as its directory or its checkpoint. */
pg_status pg_path_join_beside(char *out, size_t size, const char *path, const char *name);
/* Opens a file for reading if it is a regular file: a folder, FIFO or device where a file is read
 * would hang or give nonsense sizes. PG_ERR_ARG names what the path is instead; PG_ERR_IO when it
 * cannot be opened. */
pg_status pg_open_read(const char *path, FILE **fp);
/* The same for a path a library opens itself (ffmpeg, a dataset): a regular file or a folder. */
pg_status pg_check_input(const char *path);
/* Reads a whole file into a malloc'd buffer (NUL-terminated); limit guards huge files. */
pg_status pg_read_file(const char *path, size_t limit, char **data, size_t *size);
/* Writes a whole buffer atomically. */
pg_status pg_write_file_atomic(const char *path, const void *data, size_t size);

#endif
