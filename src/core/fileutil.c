/* fileutil.c - atomic writes and path helpers. */
#include "core/fileutil.h"

#include <dirent.h>
#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

pg_status pg_atomic_open(pg_atomic_file *f, const char *path)
{
    f->fp = NULL;
    if (strlen(path) >= sizeof f->path) return pg_fail(PG_ERR_ARG, "%s: path too long", path);
    strcpy(f->path, path);
    snprintf(f->tmp_path, sizeof f->tmp_path, "%s.tmp.%ld", path, (long)getpid());
    f->fp = fopen(f->tmp_path, "wb");
    if (!f->fp) return pg_fail(PG_ERR_ENV, "%s: cannot write: %s", path, strerror(errno));
    return PG_OK;
}

pg_status pg_atomic_commit(pg_atomic_file *f)
{
    if (!f->fp) return pg_fail(PG_ERR_INTERNAL, "%s: file not open", f->path);
    int bad = ferror(f->fp);
    if (fclose(f->fp) != 0) bad = 1;
    f->fp = NULL;
    if (bad) {
        remove(f->tmp_path);
        return pg_fail(PG_ERR_ENV, "%s: write failed: %s", f->path, strerror(errno));
    }
    if (rename(f->tmp_path, f->path) != 0) {
        int e = errno;
        remove(f->tmp_path);
        return pg_fail(PG_ERR_ENV, "%s: cannot rename into place: %s", f->path, strerror(e));
    }
    return PG_OK;
}

void pg_atomic_abort(pg_atomic_file *f)
{
    if (f->fp) {
        fclose(f->fp);
        f->fp = NULL;
        remove(f->tmp_path);
    }
}

pg_status pg_mkdir_p(const char *path)
{
    char buf[4096];
    size_t n = strlen(path);
    if (n == 0 || n >= sizeof buf) return pg_fail(PG_ERR_ARG, "bad directory path '%s'", path);
    memcpy(buf, path, n + 1);
    for (size_t i = 1; i <= n; i++) {
        if (buf[i] == '/' || buf[i] == '\0') {
            char c = buf[i];
            buf[i] = '\0';
            if (mkdir(buf, 0777) != 0 && errno != EEXIST)
                return pg_fail(PG_ERR_ENV, "%s: cannot create directory: %s", buf, strerror(errno));
            buf[i] = c;
        }
    }
    if (!pg_path_is_dir(path)) return pg_fail(PG_ERR_IO, "%s: exists and is not a directory", path);
    return PG_OK;
}

/* What a path is when it is not what a reader can use. */
static const char *kind_of(mode_t mode)
{
    if (S_ISDIR(mode)) return "a folder";
    if (S_ISFIFO(mode)) return "a FIFO";
    if (S_ISCHR(mode) || S_ISBLK(mode)) return "a device";
    if (S_ISSOCK(mode)) return "a socket";
    return "a special file";
}

pg_status pg_open_read(const char *path, FILE **fp)
{
    *fp = NULL;
    /* O_NONBLOCK: opening a FIFO for reading would otherwise wait for a writer */
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) return pg_fail(PG_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    struct stat st;
    if (fstat(fd, &st) != 0) {
        int e = errno;
        close(fd);
        return pg_fail(PG_ERR_IO, "%s: cannot open: %s", path, strerror(e));
    }
    if (!S_ISREG(st.st_mode)) {
        close(fd);
        return pg_fail(PG_ERR_ARG, "%s: is %s, not a regular file", path, kind_of(st.st_mode));
    }
    int flags = fcntl(fd, F_GETFL);
    if (flags < 0 || fcntl(fd, F_SETFL, flags & ~O_NONBLOCK) != 0 || !(*fp = fdopen(fd, "rb"))) {
        int e = errno;
        close(fd);
        return pg_fail(PG_ERR_IO, "%s: cannot open: %s", path, strerror(e));
    }
    return PG_OK;
}

pg_status pg_check_input(const char *path)
{
    struct stat st;
    if (stat(path, &st) != 0) return pg_fail(PG_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    if (!S_ISREG(st.st_mode) && !S_ISDIR(st.st_mode))
        return pg_fail(PG_ERR_ARG, "%s: is %s, not a regular file or folder", path, kind_of(st.st_mode));
    return PG_OK;
}

pg_status pg_private_dir(const char *dir)
{
    char parent[4096];
    const char *slash = strrchr(dir, '/');
    if (slash && slash > dir) {
        snprintf(parent, sizeof parent, "%.*s", (int)(slash - dir), dir);
        PG_TRY(pg_mkdir_p(parent));
    }
    if (mkdir(dir, 0700) != 0 && errno != EEXIST)
        return pg_fail(PG_ERR_ENV, "%s: cannot create the cache folder: %s", dir, strerror(errno));
    struct stat st;
    if (lstat(dir, &st) != 0) return pg_fail(PG_ERR_ENV, "%s: cannot use the cache folder: %s", dir, strerror(errno));
    if (S_ISLNK(st.st_mode))
        return pg_fail(PG_ERR_ENV, "%s: the cache folder is a symbolic link; remove it or set XDG_CACHE_HOME", dir);
    if (!S_ISDIR(st.st_mode)) return pg_fail(PG_ERR_ENV, "%s: the cache folder is not a folder; remove it or set XDG_CACHE_HOME", dir);
    if (st.st_uid != geteuid())
        return pg_fail(PG_ERR_ENV, "%s: the cache folder belongs to uid %ld, not to you (uid %ld); remove it or set XDG_CACHE_HOME",
                       dir, (long)st.st_uid, (long)geteuid());
    /* ours, so nobody else could have created entries unless it was open to them: close it; the
     * files in it are checked byte for byte by their users */
    if ((st.st_mode & 077) && chmod(dir, 0700) != 0)
        return pg_fail(PG_ERR_ENV, "%s: cannot make the cache folder private: %s", dir, strerror(errno));
    return PG_OK;
}

int pg_path_exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

int pg_path_is_dir(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0 && S_ISDIR(st.st_mode);
}

pg_status pg_path_join(char *out, size_t size, const char *dir, const char *name)
{
    size_t dl = strlen(dir);
    int slash = dl > 0 && dir[dl - 1] != '/';
    int n = snprintf(out, size, "%s%s%s", dir, slash ? "/" : "", name);
    if (n < 0 || (size_t)n >= size) return pg_fail(PG_ERR_ARG, "%s/%s: path too long", dir, name);
    return PG_OK;
}

pg_status pg_path_join_beside(char *out, size_t size, const char *path, const char *name)
{
    if (pg_path_is_dir(path)) return pg_path_join(out, size, path, name);
    const char *slash = strrchr(path, '/');
    if (!slash) return pg_path_join(out, size, ".", name);
    int n = snprintf(out, size, "%.*s/%s", (int)(slash - path), path, name);
    if (n < 0 || (size_t)n >= size) return pg_fail(PG_ERR_ARG, "%s: path too long", path);
    return PG_OK;
}

pg_status pg_read_file(const char *path, size_t limit, char **data, size_t *size)
{
    *data = NULL;
    *size = 0;
    FILE *fp;
    PG_TRY(pg_open_read(path, &fp));
    if (fseek(fp, 0, SEEK_END) != 0) { fclose(fp); return pg_fail(PG_ERR_IO, "%s: cannot seek", path); }
    long len = ftell(fp);
    if (len < 0) { fclose(fp); return pg_fail(PG_ERR_IO, "%s: cannot tell size", path); }
    if ((size_t)len > limit) {
        fclose(fp);
        return pg_fail(PG_ERR_SIZE, "%s: file is %ld bytes, more than the %zu allowed", path, len, limit);
    }
    rewind(fp);
    char *buf = pg_malloc((size_t)len + 1, path);
    if (!buf) { fclose(fp); return PG_ERR_NOMEM; }
    size_t got = fread(buf, 1, (size_t)len, fp);
    fclose(fp);
    if (got != (size_t)len) { free(buf); return pg_fail(PG_ERR_IO, "%s: short read", path); }
    buf[len] = '\0';
    *data = buf;
    *size = (size_t)len;
    return PG_OK;
}

pg_status pg_write_file_atomic(const char *path, const void *data, size_t size)
{
    pg_atomic_file f;
    PG_TRY(pg_atomic_open(&f, path));
    if (size && fwrite(data, 1, size, f.fp) != size) {
        pg_atomic_abort(&f);
        return pg_fail(PG_ERR_ENV, "%s: write failed: %s", path, strerror(errno));
    }
    return pg_atomic_commit(&f);
}

/* Removes every entry of a folder, keeping the folder. */
static pg_status empty_dir(const char *path)
{
    DIR *dir = opendir(path);
    if (!dir) return pg_fail(PG_ERR_IO, "%s: cannot list: %s", path, strerror(errno));
    pg_status rc = PG_OK;
    struct dirent *e;
    char child[4096];
    while (rc == PG_OK && (e = readdir(dir)) != NULL) {
        if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0) continue;
        rc = pg_path_join(child, sizeof child, path, e->d_name);
        if (rc == PG_OK) rc = pg_remove_tree(child);
    }
    closedir(dir);
    return rc;
}

pg_status pg_remove_tree(const char *path)
{
    struct stat st;
    if (lstat(path, &st) != 0)
        return errno == ENOENT || errno == ENOTDIR ? PG_OK : pg_fail(PG_ERR_IO, "%s: %s", path, strerror(errno));
    if (S_ISDIR(st.st_mode)) {
        PG_TRY(empty_dir(path));
        if (rmdir(path) != 0) return pg_fail(PG_ERR_ENV, "%s: cannot remove: %s", path, strerror(errno));
        return PG_OK;
    }
    if (unlink(path) != 0) return pg_fail(PG_ERR_ENV, "%s: cannot remove: %s", path, strerror(errno));
    return PG_OK;
}

pg_status pg_staged_dir_begin(pg_staged_dir *d, const char *dir, int resume)
{
    size_t n = strlen(dir);
    while (n > 1 && dir[n - 1] == '/') n--; /* "out/" -> "out" so the sibling is out.partial */
    if (n == 0 || n >= sizeof d->final) return pg_fail(PG_ERR_ARG, "bad output directory '%s'", dir);
    memcpy(d->final, dir, n);
    d->final[n] = '\0';
    snprintf(d->work, sizeof d->work, "%s.partial", d->final);
    d->replace = 0;
    if (!resume) PG_TRY(pg_remove_tree(d->work));
    pg_status st = pg_mkdir_p(d->work);
    if (st) return pg_fail_context(st, "%s: output is not writable", d->final);
    return PG_OK;
}

pg_status pg_staged_dir_commit(pg_staged_dir *d)
{
    PG_TRY(pg_mkdir_p(d->final));
    if (d->replace) PG_TRY(empty_dir(d->final));
    DIR *dir = opendir(d->work);
    if (!dir) return pg_fail(PG_ERR_IO, "%s: cannot list: %s", d->work, strerror(errno));
    pg_status rc = PG_OK;
    struct dirent *e;
    char from[4096], to[4096];
    while (rc == PG_OK && (e = readdir(dir)) != NULL) {
        if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0) continue;
        rc = pg_path_join(from, sizeof from, d->work, e->d_name);
        if (rc == PG_OK) rc = pg_path_join(to, sizeof to, d->final, e->d_name);
        /* a folder of an earlier result (vis/, frames/) is replaced whole, not merged */
        if (rc == PG_OK && pg_path_is_dir(to)) rc = pg_remove_tree(to);
        if (rc == PG_OK && rename(from, to) != 0)
            rc = pg_fail(PG_ERR_ENV, "%s: cannot move into place: %s", to, strerror(errno));
    }
    closedir(dir);
    if (rc) return rc;
    if (rmdir(d->work) != 0) return pg_fail(PG_ERR_ENV, "%s: cannot remove: %s", d->work, strerror(errno));
    return PG_OK;
}

void pg_staged_dir_abort(pg_staged_dir *d)
{
    char saved[512];
    snprintf(saved, sizeof saved, "%s", pg_last_error()); /* keep the stage's own error message */
    pg_remove_tree(d->work);
    pg_fail(PG_ERR_IO, "%s", saved);
}
