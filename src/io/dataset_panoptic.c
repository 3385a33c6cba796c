/* dataset_panoptic.c - Dynamic3DGaussians / CMU Panoptic layout.
 *
 * DIR/train_meta.json and/or DIR/test_meta.json hold w, h and per frame t and camera c:
 * k[t][c] (3x3 intrinsics), w2c[t][c] (4x4 world-to-camera, OpenCV axes), fn[t][c] (image
 * path relative to DIR/ims/) and cam_id[t][c]. Cameras of train_meta come first (role "train"),
 * then those of test_meta (role "test"); the camera name is its cam_id. K is used as given
 * (its principal point is taken in our continuous-pixel convention; sub-pixel offset at most).
 */
#include "io/dataset_internal.h"
#include "core/fileutil.h"
#include "core/mathx.h"
#include "io/json.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { META_K, META_W2C, META_FN, META_CAM_ID, META_ARRAYS };
static const char *const meta_keys[META_ARRAYS] = { "k", "w2c", "fn", "cam_id" };

/* cJSON arrays are linked lists: each per-frame list is found once (rows) and walked in order, so
 * reading a meta file is linear in its size (indexing item t costs t steps). */
typedef struct {
    cJSON *root;
    char path[4200];
    const char *role;
    int T, C, w, h;
    const cJSON **rows[META_ARRAYS]; /* (T) the per-frame camera lists of k, w2c, fn, cam_id */
} meta_file;

static pg_status check_meta(meta_file *m)
{
    PG_TRY(io_json_get_int(m->root, "w", m->path, 1, PG_MAX_IMAGE_SIDE, &m->w));
    PG_TRY(io_json_get_int(m->root, "h", m->path, 1, PG_MAX_IMAGE_SIDE, &m->h));
    const cJSON *arrs[META_ARRAYS];
    for (int i = 0; i < META_ARRAYS; i++) {
        arrs[i] = cJSON_GetObjectItemCaseSensitive(m->root, meta_keys[i]);
        if (!cJSON_IsArray(arrs[i])) return pg_fail(PG_ERR_FORMAT, "%s: missing array '%s'", m->path, meta_keys[i]);
    }
    m->T = cJSON_GetArraySize(arrs[META_FN]);
    if (m->T <= 0) return pg_fail(PG_ERR_FORMAT, "%s: 'fn' has no frames", m->path);
    for (int i = 0; i < META_ARRAYS; i++) {
        if (cJSON_GetArraySize(arrs[i]) != m->T)
            return pg_fail(PG_ERR_FORMAT, "%s: '%s' has %d frames, 'fn' has %d", m->path, meta_keys[i],
                           cJSON_GetArraySize(arrs[i]), m->T);
        m->rows[i] = pg_malloc((size_t)m->T * sizeof *m->rows[i], m->path);
        if (!m->rows[i]) return PG_ERR_NOMEM;
        int t = 0;
        for (const cJSON *l = arrs[i]->child; l; l = l->next) m->rows[i][t++] = l;
    }
    m->C = cJSON_GetArraySize(m->rows[META_FN][0]);
    if (m->C <= 0 || m->C > 1000) return pg_fail(PG_ERR_FORMAT, "%s: frame 0 lists %d cameras", m->path, m->C);
    for (int t = 0; t < m->T; t++)
        for (int i = 0; i < META_ARRAYS; i++) {
            const cJSON *l = m->rows[i][t];
            if (!cJSON_IsArray(l) || cJSON_GetArraySize(l) != m->C)
                return pg_fail(PG_ERR_FORMAT, "%s: %s[%d] must list %d cameras", m->path, meta_keys[i], t, m->C);
        }
    return PG_OK;
}

/* Camera c of frame t from its k and w2c items. */
static pg_status camera_from_meta(const meta_file *m, int t, int c, const cJSON *k, const cJSON *w2c, pg_camera *cam)
{
    char what[4300];
    snprintf(what, sizeof what, "%s: frame %d camera %d", m->path, t, c);
    float K[9], M[16];
    PG_TRY(io_json_get_floats(k, NULL, what, K, 9));
    PG_TRY(io_json_get_floats(w2c, NULL, what, M, 16));
    memset(cam, 0, sizeof *cam);
    cam->width = m->w;
    cam->height = m->h;
    cam->fx = K[0];
    cam->fy = K[4];
    cam->cx = K[2];
    cam->cy = K[5];
    if (!(cam->fx > 0 && cam->fy > 0)) return pg_fail(PG_ERR_FORMAT, "%s: focal lengths must be positive", what);
    for (int r = 0; r < 3; r++) {
        for (int k = 0; k < 3; k++) cam->R[r * 3 + k] = M[r * 4 + k];
        cam->t[r] = M[r * 4 + 3];
    }
    if (!mat3_is_orthonormal(cam->R, 1e-2)) return pg_fail(PG_ERR_FORMAT, "%s: w2c rotation is not orthonormal", what);
    return PG_OK;
}

static int id_of(const cJSON *v, int *id)
{
    if (!cJSON_IsNumber(v)) return -1;
    *id = v->valueint;
    return 0;
}

/* Fills frame k (meta frame t) of the m->C cameras starting at cams, walking the four per-frame
 * lists side by side. */
static pg_status read_frame(const meta_file *m, const char *dir, ds_camera *cams, int k, int t)
{
    const cJSON *it[META_ARRAYS];
    for (int i = 0; i < META_ARRAYS; i++) it[i] = m->rows[i][t]->child;
    for (int c = 0; c < m->C; c++) {
        ds_camera *cam = &cams[c];
        int id;
        if (id_of(it[META_CAM_ID], &id) || id != atoi(cam->name))
            return pg_fail(PG_ERR_FORMAT, "%s: cam_id[%d][%d] differs from cam_id[0][%d] (cameras must keep their order)",
                           m->path, t, c, c);
        PG_TRY(camera_from_meta(m, t, c, it[META_K], it[META_W2C], &cam->cams[k]));
        const cJSON *f = it[META_FN];
        if (!cJSON_IsString(f) || !f->valuestring[0] || strlen(f->valuestring) > 1000)
            return pg_fail(PG_ERR_FORMAT, "%s: fn[%d][%d] is not a file name", m->path, t, c);
        size_t len = strlen(dir) + strlen(f->valuestring) + 8;
        cam->frame_paths[k] = pg_malloc(len, "frame path");
        if (!cam->frame_paths[k]) return PG_ERR_NOMEM;
        snprintf(cam->frame_paths[k], len, "%s/ims/%s", dir, f->valuestring);
        for (int i = 0; i < META_ARRAYS; i++) it[i] = it[i]->next;
    }
    return PG_OK;
}

pg_status ds_open_panoptic(pg_dataset *ds)
{
    meta_file meta[2];
    memset(meta, 0, sizeof meta);
    const char *files[2] = { "train_meta.json", "test_meta.json" }, *roles[2] = { "train", "test" };
    pg_status st = PG_OK;
    int nmeta = 0, total_cams = 0, T = 0, w = 0, h = 0;
    for (int i = 0; i < 2 && st == PG_OK; i++) {
        meta_file *m = &meta[nmeta];
        if (pg_path_join(m->path, sizeof m->path, ds->path, files[i]) || !pg_path_exists(m->path)) continue;
        m->role = roles[i];
        st = io_json_load(m->path, &m->root);
        if (st == PG_OK) st = check_meta(m);
        if (st == PG_OK && nmeta > 0 && (m->w != w || m->h != h))
            st = pg_fail(PG_ERR_FORMAT, "%s: size %d x %d differs from %s (%d x %d)", m->path, m->w, m->h, meta[0].path, w, h);
        if (st == PG_OK) {
            if (nmeta == 0 || m->T < T) T = m->T;
            w = m->w;
            h = m->h;
            total_cams += m->C;
        }
        nmeta++;
    }
    if (st == PG_OK) st = ds_select_frames(ds, ds->path, T);
    if (st == PG_OK) st = ds_alloc_cameras(ds, total_cams);
    ds->fps = ds->opt.fps;
    int ci = 0;
    for (int i = 0; i < nmeta && st == PG_OK; i++) {
        meta_file *m = &meta[i];
        ds_camera *first = &ds->cams[ci];
        const cJSON *idv = m->rows[META_CAM_ID][0]->child;
        for (int c = 0; c < m->C && st == PG_OK; c++, ci++, idv = idv->next) {
            ds_camera *cam = &ds->cams[ci];
            int id0;
            if (id_of(idv, &id0)) { st = pg_fail(PG_ERR_FORMAT, "%s: cam_id[0][%d] is not a number", m->path, c); break; }
            snprintf(cam->name, sizeof cam->name, "%d", id0);
            snprintf(cam->role, sizeof cam->role, "%s", m->role);
            pg_path_join(cam->source, sizeof cam->source, ds->path, "ims");
            cam->cams = pg_calloc((size_t)ds->frames, sizeof *cam->cams, "cameras");
            cam->frame_paths = pg_calloc((size_t)ds->frames, sizeof *cam->frame_paths, "frame paths");
            if (!cam->cams || !cam->frame_paths) { st = PG_ERR_NOMEM; break; }
            cam->num_cams = ds->frames;
        }
        for (int k = 0; k < ds->frames && st == PG_OK; k++) st = read_frame(m, ds->path, first, k, ds->first + k * ds->stride);
    }
    /* Check the first image of the first camera exists now, so a broken layout fails at open. */
    if (st == PG_OK && !pg_path_exists(ds->cams[0].frame_paths[0]))
        st = pg_fail(PG_ERR_IO, "%s: missing (listed in the meta file)", ds->cams[0].frame_paths[0]);
    for (int i = 0; i < 2; i++) {
        cJSON_Delete(meta[i].root);
        for (int a = 0; a < META_ARRAYS; a++) free(meta[i].rows[a]);
    }
    if (st) return st;
    ds_set_sizes(ds, w, h);
    return PG_OK;
}
