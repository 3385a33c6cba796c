/* resources.c - peak memory, disk use and free space (see resources.h). */
#define _DEFAULT_SOURCE
#include "core/resources.h"

#include <dirent.h>
#include <stdio.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <time.h>

/* The value in KiB of a "Key:   123 kB" line of a /proc file; -1 if absent. */
static long proc_kb(const char *file, const char *key)
{
    FILE *f = fopen(file, "r");
    if (!f) return -1;
    char line[256];
    long v = -1;
    size_t n = strlen(key);
    while (fgets(line, sizeof line, f))
        if (strncmp(line, key, n) == 0 && line[n] == ':') {
            if (sscanf(line + n + 1, "%ld", &v) != 1) v = -1;
            break;
        }
    fclose(f);
    return v;
}

long pg_peak_rss_kb(void)
{
    long kb = proc_kb("/proc/self/status", "VmHWM");
    if (kb >= 0) return kb;
    struct rusage u;
    return getrusage(RUSAGE_SELF, &u) == 0 ? u.ru_maxrss : 0;
}

static void *sample_rss(void *arg)
{
    pg_peak_window *w = arg;
    while (!atomic_load(&w->stop)) {
        long kb = proc_kb("/proc/self/status", "VmRSS");
        if (kb > atomic_load(&w->max_kb)) atomic_store(&w->max_kb, kb);
        struct timespec ts = { 0, 20 * 1000 * 1000 };
        nanosleep(&ts, NULL);
    }
    return NULL;
}

void pg_peak_window_begin(pg_peak_window *w)
{
    atomic_store(&w->stop, 0);
    w->hwm_at_begin = pg_peak_rss_kb();
    atomic_store(&w->max_kb, proc_kb("/proc/self/status", "VmRSS"));
    w->running = atomic_load(&w->max_kb) >= 0 && pthread_create(&w->thread, NULL, sample_rss, w) == 0;
}

long pg_peak_window_end(pg_peak_window *w)
{
    if (w->running) {
        atomic_store(&w->stop, 1);
        pthread_join(w->thread, NULL);
        w->running = 0;
    }
    long hwm = pg_peak_rss_kb(), sampled = atomic_load(&w->max_kb);
    if (hwm > w->hwm_at_begin && hwm > sampled) return hwm; /* the stage set the process's peak */
    return sampled > 0 ? sampled : hwm;
}

uint64_t pg_dir_bytes(const char *path)
{
    struct stat sb;
    if (lstat(path, &sb) != 0) return 0;
    uint64_t total = (uint64_t)sb.st_blocks * 512u;
    if (!S_ISDIR(sb.st_mode)) return total;
    DIR *d = opendir(path);
    if (!d) return total;
    struct dirent *e;
    char child[4400];
    while ((e = readdir(d)))
        if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..") &&
            snprintf(child, sizeof child, "%s/%s", path, e->d_name) < (int)sizeof child)
            total += pg_dir_bytes(child);
    closedir(d);
    return total;
}

uint64_t pg_mem_available_bytes(void)
{
    long kb = proc_kb("/proc/meminfo", "MemAvailable");
    return kb > 0 ? (uint64_t)kb * 1024u : 0;
}

uint64_t pg_disk_free_bytes(const char *path)
{
    struct statvfs v;
    return statvfs(path, &v) == 0 ? (uint64_t)v.f_bavail * v.f_frsize : 0;
}
