/* scene_cameras.c - reads cameras and the scene centre from a trainset.json-layout file. */
#include "render/scene_cameras.h"
#include "core/fileutil.h"
#include "core/mathx.h"
#include "io/json.h"

#include <stdio.h>
#include <string.h>

pg_status scene_cameras_load(const char *path, scene_cameras *sc)
{
    char file[4096];
    if (pg_path_is_dir(path)) PG_TRY(pg_path_join(file, sizeof file, path, "trainset.json"));
    else snprintf(file, sizeof file, "%s", path);
    memset(sc, 0, sizeof *sc);
    sc->real = -1;
    cJSON *root;
    PG_TRY(io_json_load(file, &root));
    pg_status st = PG_OK;
    const cJSON *cams = cJSON_GetObjectItem(root, "cameras");
    if (!cJSON_IsArray(cams) || cJSON_GetArraySize(cams) == 0) {
        st = pg_fail(PG_ERR_FORMAT, "%s: no \"cameras\" array", file);
        goto done;
    }
    const cJSON *c;
    cJSON_ArrayForEach(c, cams) {
        if (sc->count >= RENDER_MAX_CAMERAS) {
            st = pg_fail(PG_ERR_SIZE, "%s: more than %d cameras", file, RENDER_MAX_CAMERAS);
            goto done;
        }
        int k = sc->count;
        char what[4200];
        snprintf(what, sizeof what, "%s: camera %d", file, k);
        st = io_json_to_camera(c, what, &sc->cams[k], sc->names[k], sizeof sc->names[k]);
        if (st != PG_OK) goto done;
        const char *role_text = io_json_string_or(c, "role", "proxy");
        int role = io_view_role_parse(role_text);
        if (role < 0) {
            st = pg_fail(PG_ERR_FORMAT, "%s: camera %s has unknown role \"%.32s\"", file, sc->names[k], role_text);
            goto done;
        }
        sc->roles[k] = (io_view_role)role;
        if (sc->roles[k] == IO_ROLE_REAL && sc->real < 0) sc->real = k;
        sc->count++;
    }
    if (sc->real < 0) {
        st = pg_fail(PG_ERR_FORMAT, "%s: no camera has role \"real\"", file);
        goto done;
    }
    sc->frames = 0; /* optional; a huge or fractional count is refused, not cast */
    if (cJSON_GetObjectItem(root, "frames") && (st = io_json_get_int(root, "frames", file, 0, 1000000, &sc->frames)))
        goto done;
    sc->fps = io_json_number_or(root, "fps", 30);
    const cJSON *scene = cJSON_GetObjectItem(root, "scene");
    if (!scene || io_json_get_floats(scene, "center", "scene", sc->center, 3) != PG_OK) {
        /* no centre recorded: the near/far midpoint on the real camera's axis (else 1 unit ahead) */
        const pg_camera *r = &sc->cams[sc->real];
        float d = scene ? (float)(0.5 * (io_json_number_or(scene, "near", 0.5) + io_json_number_or(scene, "far", 1.5))) : 1.0f;
        float Xc[3] = { 0, 0, d };
        pg_camera_cam_to_world(r, Xc, sc->center);
    }
    /* a training set's lengths times source.unit are the user's (the model's) */
    double unit;
    if ((st = io_json_get_source_unit(root, "unit", file, &unit))) goto done;
    for (int k = 0; k < sc->count; k++)
        for (int i = 0; i < 3; i++) sc->cams[k].t[i] = (float)(sc->cams[k].t[i] * unit);
    for (int i = 0; i < 3; i++) sc->center[i] = (float)(sc->center[i] * unit);
done:
    cJSON_Delete(root);
    return st;
}

pg_status scene_cameras_for_model(const char *model, const char *explicit_path, scene_cameras *sc)
{
    if (explicit_path) return scene_cameras_load(explicit_path, sc);
    char path[4200];
    /* cameras.json is what training writes; trainset.json beside older models */
    static const char *names[] = { "cameras.json", "trainset.json" };
    for (int k = 0; k < 2; k++) {
        PG_TRY(pg_path_join_beside(path, sizeof path, model, names[k]));
        if (pg_path_exists(path)) return scene_cameras_load(path, sc);
    }
    return pg_fail(PG_ERR_IO, "%s: no cameras.json beside the model (train writes it there: copy it back or retrain)", model);
}

int scene_cameras_find(const scene_cameras *sc, const char *name)
{
    for (int k = 0; k < sc->count; k++)
        if (strcmp(sc->names[k], name) == 0) return k;
    return -1;
}
