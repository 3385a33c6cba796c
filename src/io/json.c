/* json.c - cJSON helpers: checked getters with messages, atomic writes, camera objects. */
#include "io/json.h"
#include "core/fileutil.h"
#include "core/image.h"
#include "core/mathx.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

pg_status io_json_load(const char *path, cJSON **root)
{
    *root = NULL;
    char *text;
    size_t size;
    PG_TRY(pg_read_file(path, (size_t)512 << 20, &text, &size));
    const char *end = NULL;
    cJSON *j = cJSON_ParseWithLengthOpts(text, size, &end, 0);
    if (!j) {
        long off = end ? (long)(end - text) : -1;
        const char *e = cJSON_GetErrorPtr();
        if (e && e >= text && e <= text + size) off = (long)(e - text);
        free(text);
        return pg_fail(PG_ERR_FORMAT, "%s: invalid JSON near byte %ld", path, off);
    }
    const char *p = end ? end : text + size;
    while (p < text + size && (*p == ' ' || *p == '\t' || *p == '\n' || *p == '\r' || *p == '\0')) p++;
    if (p < text + size) {
        long off = (long)(p - text);
        free(text);
        cJSON_Delete(j);
        return pg_fail(PG_ERR_FORMAT, "%s: trailing data after the JSON value at byte %ld", path, off);
    }
    free(text);
    *root = j;
    return PG_OK;
}

pg_status io_json_write_atomic(const char *path, const cJSON *root)
{
    char *s = cJSON_Print(root);
    if (!s) return pg_fail(PG_ERR_NOMEM, "%s: cannot format JSON", path);
    size_t n = strlen(s);
    pg_status st;
    char *t = malloc(n + 2);
    if (!t) st = pg_fail(PG_ERR_NOMEM, "%s: cannot format JSON", path);
    else {
        memcpy(t, s, n);
        t[n] = '\n';
        st = pg_write_file_atomic(path, t, n + 1);
        free(t);
    }
    cJSON_free(s);
    return st;
}

pg_status io_json_get_number(const cJSON *obj, const char *key, const char *what, double *out)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(obj, key);
    if (!v) return pg_fail(PG_ERR_FORMAT, "%s: missing key '%s'", what, key);
    if (!cJSON_IsNumber(v) || !isfinite(v->valuedouble))
        return pg_fail(PG_ERR_FORMAT, "%s: '%s' must be a finite number", what, key);
    *out = v->valuedouble;
    return PG_OK;
}

pg_status io_json_get_source_unit(const cJSON *root, const char *key, const char *what, double *out)
{
    const cJSON *src = cJSON_GetObjectItemCaseSensitive(root, "source");
    const cJSON *u = cJSON_IsObject(src) ? cJSON_GetObjectItemCaseSensitive(src, key) : NULL;
    *out = 1;
    if (!u) return PG_OK;
    if (!cJSON_IsNumber(u) || !(u->valuedouble >= 1e-30 && u->valuedouble <= 1e30))
        return pg_fail(PG_ERR_FORMAT, "%s: source.%s must be a positive number", what, key);
    *out = u->valuedouble;
    return PG_OK;
}

pg_status io_json_get_int(const cJSON *obj, const char *key, const char *what, int lo, int hi, int *out)
{
    double d;
    PG_TRY(io_json_get_number(obj, key, what, &d));
    if (d != floor(d) || d < lo || d > hi)
        return pg_fail(PG_ERR_FORMAT, "%s: '%s' = %g must be an integer in [%d, %d]", what, key, d, lo, hi);
    *out = (int)d;
    return PG_OK;
}

pg_status io_json_get_floats(const cJSON *obj, const char *key, const char *what, float *out, int n)
{
    const cJSON *a = key ? cJSON_GetObjectItemCaseSensitive(obj, key) : obj;
    const char *k = key ? key : "array";
    if (!a) return pg_fail(PG_ERR_FORMAT, "%s: missing key '%s'", what, k);
    /* Nested arrays (e.g. a 3x3 matrix as [[..],[..],[..]]) are flattened row by row. */
    int count = 0;
    const cJSON *stack[4];
    int depth = 0;
    if (!cJSON_IsArray(a)) return pg_fail(PG_ERR_FORMAT, "%s: '%s' must be an array of %d numbers", what, k, n);
    stack[depth++] = a->child;
    while (depth > 0) {
        const cJSON *it = stack[depth - 1];
        if (!it) { depth--; if (depth > 0) stack[depth - 1] = stack[depth - 1]->next; continue; }
        if (cJSON_IsArray(it)) {
            if (depth >= 4) return pg_fail(PG_ERR_FORMAT, "%s: '%s' is nested too deeply", what, k);
            stack[depth++] = it->child;
            continue;
        }
        if (!cJSON_IsNumber(it) || !isfinite(it->valuedouble) || fabs(it->valuedouble) > FLT_MAX)
            return pg_fail(PG_ERR_FORMAT, "%s: '%s' must hold finite numbers within float range", what, k);
        if (count >= n) return pg_fail(PG_ERR_FORMAT, "%s: '%s' has more than %d numbers", what, k, n);
        out[count++] = (float)it->valuedouble;
        stack[depth - 1] = it->next;
    }
    if (count != n) return pg_fail(PG_ERR_FORMAT, "%s: '%s' has %d numbers, expected %d", what, k, count, n);
    return PG_OK;
}

double io_json_number_or(const cJSON *obj, const char *key, double def)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(obj, key);
    return cJSON_IsNumber(v) ? v->valuedouble : def;
}

const char *io_json_string_or(const cJSON *obj, const char *key, const char *def)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(obj, key);
    return cJSON_IsString(v) && v->valuestring ? v->valuestring : def;
}

cJSON *io_json_float_array(const float *v, int n)
{
    cJSON *a = cJSON_CreateArray();
    for (int i = 0; a && i < n; i++) {
        cJSON *x = cJSON_CreateNumber((double)v[i]);
        if (!x || !cJSON_AddItemToArray(a, x)) { cJSON_Delete(x); cJSON_Delete(a); return NULL; }
    }
    return a;
}

cJSON *io_json_from_camera(const pg_camera *cam, const char *name)
{
    cJSON *o = cJSON_CreateObject();
    if (!o) return NULL;
    int ok = 1;
    if (name) ok &= cJSON_AddStringToObject(o, "name", name) != NULL;
    ok &= cJSON_AddNumberToObject(o, "width", cam->width) != NULL;
    ok &= cJSON_AddNumberToObject(o, "height", cam->height) != NULL;
    ok &= cJSON_AddNumberToObject(o, "fx", cam->fx) != NULL;
    ok &= cJSON_AddNumberToObject(o, "fy", cam->fy) != NULL;
    ok &= cJSON_AddNumberToObject(o, "cx", cam->cx) != NULL;
    ok &= cJSON_AddNumberToObject(o, "cy", cam->cy) != NULL;
    cJSON *R = io_json_float_array(cam->R, 9), *t = io_json_float_array(cam->t, 3);
    if (R) ok &= cJSON_AddItemToObject(o, "R", R); else ok = 0;
    if (t) ok &= cJSON_AddItemToObject(o, "t", t); else ok = 0;
    if (!ok) { cJSON_Delete(o); return NULL; }
    return o;
}

pg_status io_json_to_camera(const cJSON *obj, const char *what, pg_camera *cam, char *name, size_t name_size)
{
    memset(cam, 0, sizeof *cam);
    if (!cJSON_IsObject(obj)) return pg_fail(PG_ERR_FORMAT, "%s: camera must be a JSON object", what);
    if (name && name_size) {
        const char *n = io_json_string_or(obj, "name", "");
        if (strlen(n) >= name_size) return pg_fail(PG_ERR_FORMAT, "%s: camera name too long", what);
        strcpy(name, n);
    }
    double fx, fy, cx, cy;
    PG_TRY(io_json_get_int(obj, "width", what, 1, PG_MAX_IMAGE_SIDE, &cam->width));
    PG_TRY(io_json_get_int(obj, "height", what, 1, PG_MAX_IMAGE_SIDE, &cam->height));
    PG_TRY(io_json_get_number(obj, "fx", what, &fx));
    PG_TRY(io_json_get_number(obj, "fy", what, &fy));
    PG_TRY(io_json_get_number(obj, "cx", what, &cx));
    PG_TRY(io_json_get_number(obj, "cy", what, &cy));
    if (fx <= 0 || fy <= 0) return pg_fail(PG_ERR_FORMAT, "%s: focal lengths must be positive (fx %g, fy %g)", what, fx, fy);
    cam->fx = (float)fx;
    cam->fy = (float)fy;
    cam->cx = (float)cx;
    cam->cy = (float)cy;
    PG_TRY(io_json_get_floats(obj, "R", what, cam->R, 9));
    PG_TRY(io_json_get_floats(obj, "t", what, cam->t, 3));
    if (!mat3_is_orthonormal(cam->R, 1e-3)) return pg_fail(PG_ERR_FORMAT, "%s: camera R is not a rotation", what);
    return PG_OK;
}
