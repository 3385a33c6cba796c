/* trainset.c - writes the training-set directory layout and trainset.json (docs/FORMATS.md). */
#include "io/trainset.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

#include "core/fileutil.h"
#include "io/json.h"

const char *io_view_role_name(io_view_role role)
{
    switch (role) {
    case IO_ROLE_REAL: return "real";
    case IO_ROLE_PROXY: return "proxy";
    case IO_ROLE_TEST: return "test";
    }
    return "proxy";
}

int io_view_role_parse(const char *name)
{
    for (int r = IO_ROLE_REAL; r <= IO_ROLE_TEST; r++)
        if (name && strcmp(name, io_view_role_name((io_view_role)r)) == 0) return r;
    return -1;
}

pg_status io_trainset_frame_path(char *out, size_t size, const char *dir, const char *camera, const char *kind,
                           int frame)
{
    return io_trainset_frame_path_ext(out, size, dir, camera, kind, frame, "png");
}

pg_status io_trainset_frame_path_ext(char *out, size_t size, const char *dir, const char *camera, const char *kind,
                                     int frame, const char *ext)
{
    int n = snprintf(out, size, "%s/%s/%s/%04d.%s", dir, camera, kind, frame, ext);
    if (n < 0 || (size_t)n >= size) return pg_fail(PG_ERR_ARG, "%s: path too long", dir);
    return PG_OK;
}

pg_status io_trainset_make_dirs(const char *dir, const char *camera, int with_mask)
{
    char path[4096];
    int n = snprintf(path, sizeof path, "%s/%s/rgb", dir, camera);
    if (n < 0 || (size_t)n >= sizeof path) return pg_fail(PG_ERR_ARG, "%s: path too long", dir);
    PG_TRY(pg_mkdir_p(path));
    if (with_mask) {
        snprintf(path, sizeof path, "%s/%s/mask", dir, camera);
        PG_TRY(pg_mkdir_p(path));
    }
    return PG_OK;
}

static cJSON *camera_json(const io_trainset_camera *c)
{
    char path[160];
    cJSON *o = io_json_from_camera(&c->cam, c->name);
    if (!o) return NULL;
    cJSON_AddStringToObject(o, "role", io_view_role_name(c->role));
    if (c->has_rgb) {
        snprintf(path, sizeof path, "%s/rgb", c->name);
        cJSON_AddStringToObject(o, "rgb", path);
    } else {
        cJSON_AddNullToObject(o, "rgb");
    }
    if (c->has_mask) {
        snprintf(path, sizeof path, "%s/mask", c->name);
        cJSON_AddStringToObject(o, "mask", path);
    } else {
        cJSON_AddNullToObject(o, "mask");
    }
    if (c->has_depth) {
        snprintf(path, sizeof path, "%s/depth.npy", c->name);
        cJSON_AddStringToObject(o, "depth", path);
    } else {
        cJSON_AddNullToObject(o, "depth");
    }
    return o;
}

pg_status io_trainset_write_json(const char *dir, const io_trainset_info *info, const io_trainset_camera *cams, int n)
{
    return io_trainset_write_json_named(dir, "trainset.json", info, cams, n);
}

pg_status io_trainset_write_json_named(const char *dir, const char *file, const io_trainset_info *info,
                                       const io_trainset_camera *cams, int n)
{
    char path[4096];
    PG_TRY(pg_path_join(path, sizeof path, dir, file));
    cJSON *root = cJSON_CreateObject();
    if (!root) return pg_fail(PG_ERR_NOMEM, "%s: out of memory building JSON", path);
    cJSON_AddNumberToObject(root, "version", 1);
    cJSON_AddNumberToObject(root, "frames", info->frames);
    cJSON_AddNumberToObject(root, "width", info->width);
    cJSON_AddNumberToObject(root, "height", info->height);
    cJSON_AddNumberToObject(root, "fps", info->fps);
    cJSON *arr = cJSON_AddArrayToObject(root, "cameras");
    for (int i = 0; i < n; i++) cJSON_AddItemToArray(arr, camera_json(&cams[i]));
    cJSON *scene = cJSON_AddObjectToObject(root, "scene");
    cJSON_AddItemToObject(scene, "center", io_json_float_array(info->center, 3));
    cJSON_AddNumberToObject(scene, "radius", info->radius);
    cJSON_AddNumberToObject(scene, "near", info->near);
    cJSON_AddNumberToObject(scene, "far", info->far);
    cJSON *src = cJSON_AddObjectToObject(root, "source");
    if (info->input) cJSON_AddStringToObject(src, "input", info->input);
    else cJSON_AddNullToObject(src, "input");
    if (info->depth) cJSON_AddStringToObject(src, "depth", info->depth);
    else cJSON_AddNullToObject(src, "depth");
    cJSON_AddNumberToObject(src, "pose_scale", info->pose_scale);
    cJSON_AddNumberToObject(src, "pose_shift", info->pose_shift);
    if (info->pose_fit) cJSON_AddStringToObject(src, "pose_fit", info->pose_fit);
    cJSON_AddNumberToObject(src, "unit", info->unit > 0 ? info->unit : 1);
    char *text = cJSON_Print(root);
    cJSON_Delete(root);
    if (!text) return pg_fail(PG_ERR_NOMEM, "%s: out of memory printing JSON", path);
    size_t len = strlen(text);
    text[len] = '\n'; /* cJSON_Print leaves the terminator; replace it and write len+1 bytes */
    pg_status st = pg_write_file_atomic(path, text, len + 1);
    free(text);
    return st;
}
