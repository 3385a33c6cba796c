/* output.c - output check and lock shared by every stage (see output.h). */
#include "core/output.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include "core/fileutil.h"

#define OUTPUT_MAX_CLAIMS 32 /* a run holds OUT, five stage folders and its depth file */

typedef struct {
    char path[4096]; /* as claimed, trailing slashes dropped */
    char lock[4200]; /* PATH.lock */
    dev_t lock_dev;
    ino_t lock_ino;
    int fd, count;
} output_claim;

static output_claim claims[OUTPUT_MAX_CLAIMS];

static pg_status normalize(char *out, size_t size, const char *path)
{
    size_t n = path ? strlen(path) : 0;
    while (n > 1 && path[n - 1] == '/') n--; /* "out/" and "out" are one output */
    if (n == 0 || n + 5 >= size) return pg_fail(PG_ERR_ARG, "bad output path '%s'", path ? path : "");
    memcpy(out, path, n);
    out[n] = '\0';
    return PG_OK;
}

/* Locks `lock` for this process, or counts one more claim on the entry that already holds the
 * same file. A holder that releases unlinks its lock file first; a lock taken on a file unlinked
 * meanwhile guards nothing, so it is taken again on the new one. */
static pg_status take_lock(const char *path, const char *lock)
{
    output_claim *c = NULL;
    for (int i = 0; i < OUTPUT_MAX_CLAIMS && !c; i++)
        if (claims[i].count == 0) c = &claims[i];
    for (int tries = 0; tries < 8; tries++) {
        int fd = open(lock, O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
        if (fd < 0) return pg_fail(PG_ERR_ENV, "%s: cannot create the lock file: %s", lock, strerror(errno));
        struct stat st, now;
        if (fstat(fd, &st) != 0) {
            close(fd);
            return pg_fail(PG_ERR_ENV, "%s: %s", lock, strerror(errno));
        }
        for (int i = 0; i < OUTPUT_MAX_CLAIMS; i++)
            if (claims[i].count > 0 && claims[i].lock_dev == st.st_dev && claims[i].lock_ino == st.st_ino) {
                close(fd);
                claims[i].count++;
                return PG_OK;
            }
        if (flock(fd, LOCK_EX | LOCK_NB) != 0) {
            char pid[32] = "";
            ssize_t n = read(fd, pid, sizeof pid - 1);
            pid[n > 0 ? n : 0] = '\0';
            pid[strcspn(pid, "\n")] = '\0';
            close(fd);
            return pg_fail(PG_ERR_ENV, "%s: in use by another prodygs (PID %s); wait for it or choose another --out", path,
                           pid[0] ? pid : "unknown");
        }
        if (stat(lock, &now) != 0 || now.st_ino != st.st_ino || now.st_dev != st.st_dev) {
            close(fd); /* unlinked by a holder that just finished: lock the new file */
            continue;
        }
        if (!c) {
            close(fd);
            return pg_fail(PG_ERR_INTERNAL, "%s: more than %d outputs claimed at once", path, OUTPUT_MAX_CLAIMS);
        }
        char pid[32];
        int len = snprintf(pid, sizeof pid, "%ld\n", (long)getpid());
        if (ftruncate(fd, 0) != 0 || write(fd, pid, (size_t)len) != len) {
            int e = errno;
            unlink(lock);
            close(fd);
            return pg_fail(PG_ERR_ENV, "%s: cannot write the lock file: %s", lock, strerror(e));
        }
        c->fd = fd;
        c->lock_dev = st.st_dev;
        c->lock_ino = st.st_ino;
        c->count = 1;
        snprintf(c->path, sizeof c->path, "%s", path);
        snprintf(c->lock, sizeof c->lock, "%s", lock);
        return PG_OK;
    }
    return pg_fail(PG_ERR_ENV, "%s: the lock file keeps being replaced", lock);
}

/* The shared part of both claims: the kind check, the parent folders, the lock. */
static pg_status claim(const char *out, int want_dir)
{
    char path[4096], lock[4200];
    PG_TRY(normalize(path, sizeof path, out));
    struct stat st;
    if (stat(path, &st) == 0 && (want_dir ? !S_ISDIR(st.st_mode) : !S_ISREG(st.st_mode)))
        return pg_fail(PG_ERR_ARG, "%s: exists and is not a %s", path, want_dir ? "folder" : "regular file");
    const char *slash = strrchr(path, '/');
    if (slash && slash > path) {
        char parent[4096];
        snprintf(parent, sizeof parent, "%.*s", (int)(slash - path), path);
        pg_status s = pg_mkdir_p(parent);
        /* a parent that is a file: the place, not the name, is wrong (exit 3, as a read-only disk) */
        if (s) return pg_fail_context(PG_ERR_ENV, "%s: output is not writable", path);
    }
    snprintf(lock, sizeof lock, "%s.lock", path);
    return take_lock(path, lock);
}

pg_status pg_output_claim_dir(const char *dir) { return claim(dir, 1); }

pg_status pg_output_claim_file(const char *path) { return claim(path, 0); }

void pg_output_release(const char *out)
{
    char path[4096];
    if (normalize(path, sizeof path, out) != PG_OK) return;
    struct stat st;
    int have = 0;
    char lock[4200];
    snprintf(lock, sizeof lock, "%s.lock", path);
    if (stat(lock, &st) == 0) have = 1;
    for (int i = 0; i < OUTPUT_MAX_CLAIMS; i++) {
        output_claim *c = &claims[i];
        if (c->count == 0) continue;
        if (strcmp(c->path, path) != 0 && !(have && c->lock_dev == st.st_dev && c->lock_ino == st.st_ino)) continue;
        if (--c->count > 0) return;
        unlink(c->lock); /* before unlocking: a process that opened it retries on a new file */
        close(c->fd);
        return;
    }
}

int pg_output_is_claimed(const char *path)
{
    struct stat st, cs;
    if (stat(path, &st) != 0) return 0;
    for (int i = 0; i < OUTPUT_MAX_CLAIMS; i++) {
        const output_claim *c = &claims[i];
        if (c->count == 0) continue;
        if (c->lock_dev == st.st_dev && c->lock_ino == st.st_ino) return 1;
        if (stat(c->path, &cs) == 0 && cs.st_dev == st.st_dev && cs.st_ino == st.st_ino) return 1;
    }
    return 0;
}
