/* camera_path_file.c - reads camera_path.json (see camera_path_file.h). */
#include "render/camera_path_file.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/mathx.h"
#include "io/json.h"

/* Output size from the request, the file and the fallback camera (see the header). */
static pg_status path_size(const char *path, const cJSON *root, const pg_camera *fallback, int *w, int *h)
{
    double fw = io_json_number_or(root, "render_width", 0), fh = io_json_number_or(root, "render_height", 0);
    int has_file = fw >= 1 && fh >= 1;
    if ((cJSON_GetObjectItem(root, "render_width") || cJSON_GetObjectItem(root, "render_height")) &&
        (!has_file || fw > 8192 || fh > 8192 || fw != floor(fw) || fh != floor(fh)))
        return pg_fail(PG_ERR_FORMAT, "%s: render_width/render_height must be whole numbers in 1..8192", path);
    double aw = has_file ? fw : fallback->width, ah = has_file ? fh : fallback->height;
    if (*w > 0 && *h == 0) *h = (int)lround(*w * ah / aw);
    else if (*h > 0 && *w == 0) *w = (int)lround(*h * aw / ah);
    else if (*w <= 0 || *h <= 0) *w = (int)aw, *h = (int)ah;
    if (*w < 1 || *h < 1) return pg_fail(PG_ERR_ARG, "%s: output size %dx%d", path, *w, *h);
    return PG_OK;
}

/* One entry: pose (OpenGL or OpenCV camera axes) and vertical fov -> an OpenCV pg_camera. */
static pg_status entry_camera(const char *path, int i, const cJSON *e, int opengl, int w, int h, pg_camera *cam)
{
    char what[4300];
    snprintf(what, sizeof what, "%s: camera_path[%d]", path, i);
    float m[16], fov;
    const cJSON *c2w = cJSON_GetObjectItem(e, "camera_to_world");
    if (!cJSON_IsArray(c2w) || cJSON_GetArraySize(c2w) != 16)
        return pg_fail(PG_ERR_FORMAT, "%s: camera_to_world must be 16 numbers (a 4x4 matrix, row-major)", what);
    PG_TRY(io_json_get_floats(c2w, NULL, what, m, 16));
    double f;
    PG_TRY(io_json_get_number(e, "fov", what, &f));
    if (!(f > 0.5 && f < 179.5)) return pg_fail(PG_ERR_FORMAT, "%s: fov %g is not in (0.5, 179.5) degrees", what, f);
    fov = (float)f;
    float c2w_rot[9]; /* columns = the camera's axes in the world */
    for (int r = 0; r < 3; r++)
        for (int k = 0; k < 3; k++) c2w_rot[3 * r + k] = m[4 * r + k] * (opengl && k > 0 ? -1.0f : 1.0f);
    float x[3] = { c2w_rot[0], c2w_rot[3], c2w_rot[6] }, y[3] = { c2w_rot[1], c2w_rot[4], c2w_rot[7] }, xy[3];
    float z[3] = { c2w_rot[2], c2w_rot[5], c2w_rot[8] };
    vec3_cross(xy, x, y);
    if (!mat3_is_orthonormal(c2w_rot, 1e-3) || vec3_dot(xy, z) < 0) /* a mirror is no camera */
        return pg_fail(PG_ERR_FORMAT, "%s: the rotation part of camera_to_world is not a rotation", what);
    float eye[3] = { m[3], m[7], m[11] };
    memset(cam, 0, sizeof *cam);
    cam->width = w;
    cam->height = h;
    cam->fy = 0.5f * (float)h / tanf(0.5f * fov * (float)PG_PI / 180.0f);
    cam->fx = cam->fy;
    cam->cx = 0.5f * (float)w;
    cam->cy = 0.5f * (float)h;
    mat3_transpose(cam->R, c2w_rot);
    mat3_mul_vec(cam->t, cam->R, eye);
    vec3_scale(cam->t, cam->t, -1.0f);
    return PG_OK;
}

pg_status render_camera_path_load(const char *path, const pg_camera *fallback, int width, int height,
                                  pg_camera **cams, float **times, int *count)
{
    *cams = NULL;
    *times = NULL;
    *count = 0;
    cJSON *root;
    PG_TRY(io_json_load(path, &root));
    pg_status st = PG_OK;
    const cJSON *list = cJSON_GetObjectItem(root, "camera_path");
    const char *conv = io_json_string_or(root, "convention", "opengl");
    int n = cJSON_IsArray(list) ? cJSON_GetArraySize(list) : 0;
    if (!cJSON_IsObject(root) || !cJSON_IsArray(list) || n < 1)
        st = pg_fail(PG_ERR_FORMAT, "%s: no \"camera_path\" array with at least one camera", path);
    else if (n > RENDER_MAX_PATH_FRAMES)
        st = pg_fail(PG_ERR_SIZE, "%s: %d cameras (at most %d)", path, n, RENDER_MAX_PATH_FRAMES);
    else if (strcmp(conv, "opengl") != 0 && strcmp(conv, "opencv") != 0)
        st = pg_fail(PG_ERR_FORMAT, "%s: convention \"%.32s\" is not opengl or opencv", path, conv);
    int w = width, h = height;
    if (st == PG_OK) st = path_size(path, root, fallback, &w, &h);
    pg_camera *c = NULL;
    float *t = NULL;
    if (st == PG_OK) {
        c = pg_malloc(sizeof *c * (size_t)n, "camera path");
        t = pg_malloc(sizeof *t * (size_t)n, "camera path times");
        if (!c || !t) st = PG_ERR_NOMEM;
    }
    for (int i = 0; st == PG_OK && i < n; i++) {
        const cJSON *e = cJSON_GetArrayItem(list, i);
        st = entry_camera(path, i, e, strcmp(conv, "opengl") == 0, w, h, &c[i]);
        const cJSON *ti = cJSON_GetObjectItem(e, "time");
        t[i] = n > 1 ? (float)i / (float)(n - 1) : 0.0f;
        if (st == PG_OK && ti) {
            if (!cJSON_IsNumber(ti) || !(ti->valuedouble >= 0 && ti->valuedouble <= 1))
                st = pg_fail(PG_ERR_FORMAT, "%s: camera_path[%d]: time must be a number in [0, 1]", path, i);
            else t[i] = (float)ti->valuedouble;
        }
    }
    cJSON_Delete(root);
    if (st != PG_OK) {
        free(c);
        free(t);
        return st;
    }
    *cams = c;
    *times = t;
    *count = n;
    return PG_OK;
}
