/* test_cameras.c - every option that names cameras picks the same cameras in every stage:
 * a token equal to a camera name means that camera, otherwise a plain integer is an index.
 * On a Panoptic layout with numeric camera ids out of index order (the trap: "0" is the name of
 * the camera at index 1), `eval --train-cam/--test-cams` must train on and score the cameras
 * with those NAMES, and an index spelling of the same cameras must give the same metrics. */
#include "testlib.h"
#include "core/fileutil.h"
#include "io/dataset.h"
#include "io/json.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* New names of the synth cameras 0..4: numeric and shuffled. */
static const char *const kNames[5] = { "12", "0", "27", "3", "10" };

/* Renames the Panoptic sample's cameras (train_meta.json cam_id/fn and the ims/ folders). */
static void rename_cameras(const char *dir)
{
    char path[1200], from[1200], to[1200];
    snprintf(path, sizeof path, "%s/train_meta.json", dir);
    cJSON *m = NULL;
    CHECK_OK(io_json_load(path, &m));
    if (!m) return;
    cJSON *ids = cJSON_GetObjectItem(m, "cam_id"), *fn = cJSON_GetObjectItem(m, "fn");
    for (int t = 0; t < cJSON_GetArraySize(ids); t++)
        for (int c = 0; c < 5; c++) {
            cJSON_ReplaceItemInArray(cJSON_GetArrayItem(ids, t), c, cJSON_CreateNumber(atoi(kNames[c])));
            const char *old = cJSON_GetArrayItem(cJSON_GetArrayItem(fn, t), c)->valuestring;
            char name[256];
            snprintf(name, sizeof name, "%s%s", kNames[c], strchr(old, '/'));
            cJSON_ReplaceItemInArray(cJSON_GetArrayItem(fn, t), c, cJSON_CreateString(name));
        }
    CHECK_OK(io_json_write_atomic(path, m));
    cJSON_Delete(m);
    for (int c = 0; c < 5; c++) { /* via temporary names: "0" is both an old and a new name */
        snprintf(from, sizeof from, "%s/ims/%d", dir, c);
        snprintf(to, sizeof to, "%s/ims/tmp%d", dir, c);
        CHECK(rename(from, to) == 0, "rename %s", from);
    }
    for (int c = 0; c < 5; c++) {
        snprintf(from, sizeof from, "%s/ims/tmp%d", dir, c);
        snprintf(to, sizeof to, "%s/ims/%s", dir, kNames[c]);
        CHECK(rename(from, to) == 0, "rename %s", from);
    }
}

/* Runs eval and returns its metrics.json (caller deletes). */
static cJSON *run_eval(const char *data, const char *depth, const char *out, const char *cams)
{
    char args[8192], err[8192], path[1200];
    snprintf(args, sizeof args, "eval '%s' --depth '%s' --out '%s' %s --iters 12 --threads 1", data, depth, out, cams);
    int rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 0, "eval %s: exit %d: %s", cams, rc, err);
    snprintf(path, sizeof path, "%s/metrics.json", out);
    cJSON *m = NULL;
    if (rc == 0) CHECK_OK(io_json_load(path, &m));
    return m;
}

/* The role of each camera in the training set DIR/trainset.json, as "name:role," for the real
 * and test ones. */
static void trainset_roles(const char *dir, char *roles, size_t size)
{
    char path[1300];
    snprintf(path, sizeof path, "%s/trainset.json", dir);
    roles[0] = '\0';
    cJSON *t = NULL;
    CHECK_OK(io_json_load(path, &t));
    const cJSON *c;
    cJSON_ArrayForEach(c, cJSON_GetObjectItem(t, "cameras"))
    {
        const char *role = io_json_string_or(c, "role", "");
        if (strcmp(role, "proxy") == 0) continue;
        snprintf(roles + strlen(roles), size - strlen(roles), "%s:%s,", io_json_string_or(c, "name", ""), role);
    }
    cJSON_Delete(t);
}

/* Two spellings of the same cameras: run b trained and scored `want` and both give the same
 * metrics. Deletes both. */
static void check_same_cameras(const char *what, cJSON *ma, cJSON *mb, const char *out_b, const char *want)
{
    char dir[1300], roles[512];
    snprintf(dir, sizeof dir, "%s/proxies", out_b);
    trainset_roles(dir, roles, sizeof roles);
    CHECK(strcmp(roles, want) == 0, "%s: cameras and roles %s, want %s", what, roles, want);
    CHECK(ma && mb && io_json_number_or(ma, "psnr", -1) == io_json_number_or(mb, "psnr", -2),
          "%s: the spellings give different metrics: %f vs %f", what, io_json_number_or(ma, "psnr", -1),
          io_json_number_or(mb, "psnr", -2));
    cJSON_Delete(ma);
    cJSON_Delete(mb);
}

int main(void)
{
    char dir[1024], data[1100], depth[1200], args[4096], err[8192], a[1200], b[1200], roles[512], path[1300];
    test_tmpdir("cameras", dir, sizeof dir);

    /* Panoptic layout, numeric ids out of order */
    snprintf(data, sizeof data, "%s/pano", dir);
    snprintf(args, sizeof args, "synth '%s' --layout panoptic --cams 5 --frames 3 --size 32x24 --spp 1 --threads 1", data);
    CHECK(test_run_cli(args, err, sizeof err) == 0, "synth: %s", err);
    rename_cameras(data);
    snprintf(depth, sizeof depth, "%s/depth_mono/cam00.npy", data); /* synth camera 0, now named "12" */

    snprintf(a, sizeof a, "%s/by_name", dir);
    cJSON *ma = run_eval(data, depth, a, "--train-cam 12 --test-cams 27,0");
    snprintf(path, sizeof path, "%s/proxies", a);
    trainset_roles(path, roles, sizeof roles);
    CHECK(strcmp(roles, "12:real,27:test,0:test,") == 0, "by name: cameras and roles %s", roles);
    const cJSON *cfg = cJSON_GetObjectItem(ma, "config");
    CHECK(strcmp(io_json_string_or(cfg, "train_camera", ""), "12 (index 0)") == 0 &&
          strcmp(io_json_string_or(cfg, "test_cameras", ""), "27 (index 2), 0 (index 1)") == 0,
          "recorded cameras '%s' / '%s'", io_json_string_or(cfg, "train_camera", ""), io_json_string_or(cfg, "test_cameras", ""));
    const cJSON *pc = cJSON_GetObjectItem(ma, "per_camera");
    CHECK(cJSON_GetObjectItem(pc, "27") && cJSON_GetObjectItem(pc, "0") && !cJSON_GetObjectItem(pc, "3"),
          "scored cameras are 27 and 0");

    /* the same test cameras by index ("2" and "1" are no camera's name) */
    snprintf(b, sizeof b, "%s/by_index", dir);
    cJSON *mb = run_eval(data, depth, b, "--train-cam 12 --test-cams 2,1");
    check_same_cameras("Panoptic, test cameras by index", ma, mb, b, "12:real,27:test,0:test,");

    /* "0" is a name: it means the camera at index 1, not index 0 */
    snprintf(a, sizeof a, "%s/zero", dir);
    snprintf(args, sizeof args, "proxies '%s' --depth '%s' --out '%s' --train-cam 0 --test-cams 27 --fit-steps 2", data,
             depth, a);
    CHECK(test_run_cli(args, err, sizeof err) == 0, "proxies --train-cam 0: %s", err);
    trainset_roles(a, roles, sizeof roles);
    CHECK(strcmp(roles, "0:real,27:test,") == 0, "--train-cam 0 must be the camera named 0: %s", roles);
    /* a token that is neither a name nor an index: usage error listing the names */
    snprintf(args, sizeof args, "eval '%s' --depth '%s' --out '%s/bad' --train-cam cam99", data, depth, dir);
    CHECK(test_run_cli(args, err, sizeof err) == 2 && strstr(err, "cam99") && strstr(err, "12, 0, 27, 3, 10"),
          "unknown camera: %s", err);
    snprintf(args, sizeof args, "eval '%s' --depth '%s' --out '%s/bad' --train-cam 12 --test-cams 27,7", data, depth, dir);
    CHECK(test_run_cli(args, err, sizeof err) == 2 && strstr(err, "'7'") && strstr(err, "out of range"),
          "index out of range: %s", err);

    /* DyNeRF: cam00 / 0 and cam05,cam06 / 5,6 are the same cameras */
    snprintf(data, sizeof data, "%s/dyn", dir);
    snprintf(args, sizeof args, "synth '%s' --cams 7 --frames 3 --size 32x24 --spp 1 --threads 1", data);
    CHECK(test_run_cli(args, err, sizeof err) == 0, "synth: %s", err);
    snprintf(depth, sizeof depth, "%s/depth_mono/cam00.npy", data);
    snprintf(a, sizeof a, "%s/dyn_names", dir);
    snprintf(b, sizeof b, "%s/dyn_index", dir);
    ma = run_eval(data, depth, a, "--train-cam cam00 --test-cams cam05,cam06");
    mb = run_eval(data, depth, b, "--train-cam 0 --test-cams 5,6");
    check_same_cameras("DyNeRF, by index", ma, mb, b, "cam00:real,cam05:test,cam06:test,");
    return test_summary("test_cameras");
}
