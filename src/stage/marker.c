/* marker.c - stage markers and content hashes (see marker.h). */
#include "stage/marker.h"

#include <dirent.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "core/fileutil.h"
#include "core/output.h"
#include "io/json.h"

typedef struct {
    uLong crc;
    unsigned long long bytes;
} content_hash;

static void hash_bytes(content_hash *h, const void *data, size_t n)
{
    h->crc = crc32_z(h->crc, data, n);
    h->bytes += n;
}

static int compare_names(const void *a, const void *b)
{
    return strcmp(*(char *const *)a, *(char *const *)b);
}

static pg_status hash_path(content_hash *h, const char *path, int depth);

/* Every entry of a directory in name order, so the hash does not depend on readdir's order. */
static pg_status hash_dir(content_hash *h, const char *path, int depth)
{
    if (depth > 16) return pg_fail(PG_ERR_ARG, "%s: directories nested too deep to hash", path);
    DIR *d = opendir(path);
    if (!d) return pg_fail(PG_ERR_IO, "%s: cannot list the directory", path);
    char **names = NULL;
    size_t n = 0, cap = 0;
    pg_status st = PG_OK;
    struct dirent *e;
    while (st == PG_OK && (e = readdir(d)) != NULL) {
        if (e->d_name[0] == '.') continue; /* ".", "..", and hidden files (editor swap files) */
        if (n == cap) {
            cap = cap ? 2 * cap : 64;
            char **grown = realloc(names, cap * sizeof *names);
            if (!grown) {
                st = pg_fail(PG_ERR_NOMEM, "%s: out of memory listing the directory", path);
                break;
            }
            names = grown;
        }
        names[n] = strdup(e->d_name);
        if (!names[n]) st = pg_fail(PG_ERR_NOMEM, "%s: out of memory listing the directory", path);
        else n++;
    }
    closedir(d);
    if (st == PG_OK && n > 0) qsort(names, n, sizeof *names, compare_names); /* an empty folder has no list */
    for (size_t i = 0; i < n && st == PG_OK; i++) {
        char child[4096];
        st = pg_path_join(child, sizeof child, path, names[i]);
        if (st == PG_OK && pg_output_is_claimed(child)) continue; /* a run's --out inside its input folder */
        hash_bytes(h, names[i], strlen(names[i]) + 1);
        if (st == PG_OK) st = hash_path(h, child, depth + 1);
    }
    for (size_t i = 0; i < n; i++) free(names[i]);
    free(names);
    return st;
}

static pg_status hash_path(content_hash *h, const char *path, int depth)
{
    if (pg_path_is_dir(path)) return hash_dir(h, path, depth);
    FILE *f;
    PG_TRY(pg_open_read(path, &f));
    static _Thread_local unsigned char buf[1 << 16];
    size_t got;
    while ((got = fread(buf, 1, sizeof buf, f)) > 0) hash_bytes(h, buf, got);
    int bad = ferror(f);
    fclose(f);
    return bad ? pg_fail(PG_ERR_IO, "%s: read error", path) : PG_OK;
}

pg_status stage_hash_input(cJSON *inputs, const char *name, const char *path)
{
    content_hash h = { crc32(0L, Z_NULL, 0), 0 };
    PG_TRY(hash_path(&h, path, 0));
    char text[64];
    snprintf(text, sizeof text, "%08lx-%llu", (unsigned long)h.crc, h.bytes);
    cJSON_AddStringToObject(inputs, name, text);
    return PG_OK;
}

static void marker_path(char *path, size_t size, const char *out, const char *stage, const char *kind)
{
    snprintf(path, size, "%s/%s.%s", out, stage, kind);
}

/* Names the first field of `want` that `have` lacks or holds differently: an input's hashes are
 * not worth printing, a setting's values are. */
static int first_difference(const cJSON *want, const cJSON *have, int inputs, char *why, size_t size)
{
    const char *what = inputs ? "input" : "setting";
    const cJSON *it;
    cJSON_ArrayForEach(it, want)
    {
        const cJSON *old = cJSON_GetObjectItemCaseSensitive(have, it->string);
        if (old && cJSON_Compare(it, old, 1)) continue;
        if (inputs) {
            snprintf(why, size, "input %s has new content", it->string);
            return 1;
        }
        char *a = old ? cJSON_PrintUnformatted(old) : NULL, *b = cJSON_PrintUnformatted(it);
        snprintf(why, size, "setting %s changed (%.60s -> %.60s)", it->string, a ? a : "unset", b ? b : "?");
        free(a);
        free(b);
        return 1;
    }
    if (cJSON_GetArraySize(have) != cJSON_GetArraySize(want)) {
        snprintf(why, size, "the %ss changed", what);
        return 1;
    }
    return 0;
}

int stage_marker_matches(const char *out, const char *stage, const char *kind, const cJSON *config,
                         const cJSON *inputs, char *why, size_t size)
{
    char path[4200];
    marker_path(path, sizeof path, out, stage, kind);
    cJSON *root = NULL;
    if (!pg_path_exists(path) || io_json_load(path, &root) != PG_OK) {
        snprintf(why, size, "not %s before", strcmp(kind, "done") == 0 ? "finished" : "started");
        return 0;
    }
    int differs = first_difference(inputs, cJSON_GetObjectItem(root, "inputs"), 1, why, size) ||
                  first_difference(config, cJSON_GetObjectItem(root, "config"), 0, why, size);
    cJSON_Delete(root);
    return !differs;
}

pg_status stage_marker_write(const char *out, const char *stage, const char *kind, const cJSON *config,
                             const cJSON *inputs, const cJSON *extra)
{
    char path[4200];
    marker_path(path, sizeof path, out, stage, kind);
    cJSON *root = cJSON_CreateObject();
    cJSON_AddItemToObject(root, "config", cJSON_Duplicate(config, 1));
    cJSON_AddItemToObject(root, "inputs", cJSON_Duplicate(inputs, 1));
    const cJSON *it;
    if (extra) cJSON_ArrayForEach(it, extra) cJSON_AddItemToObject(root, it->string, cJSON_Duplicate(it, 1));
    pg_status st = io_json_write_atomic(path, root);
    cJSON_Delete(root);
    return st;
}

double stage_marker_number(const char *out, const char *stage, const char *field)
{
    char path[4200];
    marker_path(path, sizeof path, out, stage, "done");
    cJSON *root = NULL;
    if (io_json_load(path, &root) != PG_OK) return 0;
    double v = io_json_number_or(root, field, 0);
    cJSON_Delete(root);
    return v;
}

void stage_marker_remove(const char *out, const char *stage, const char *kind)
{
    char path[4200];
    marker_path(path, sizeof path, out, stage, kind);
    remove(path);
}
