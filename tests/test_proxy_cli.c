/* test_proxy_cli.c - `prodygs proxies` on a tiny synth dataset (dataset and hemisphere poses, the
 * fitted pose scale, resume, --diagnose) and its usage / bad-input errors. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

#include "core/fileutil.h"
#include "io/npy.h"
#include "synth/synth.h"
#include "testlib.h"

static cJSON *load_json(const char *path)
{
    char *text = NULL;
    size_t n = 0;
    if (pg_read_file(path, 1 << 20, &text, &n)) return NULL;
    cJSON *j = cJSON_Parse(text);
    free(text);
    return j;
}

static int count_role(cJSON *root, const char *role)
{
    int n = 0;
    cJSON *c;
    cJSON_ArrayForEach(c, cJSON_GetObjectItem(root, "cameras"))
    {
        const char *r = cJSON_GetStringValue(cJSON_GetObjectItem(c, "role"));
        n += r && !strcmp(r, role);
    }
    return n;
}

/* Runs `prodygs ARGS` (a proxies command writing out_dir), which must succeed, and returns
 * out_dir/trainset.json parsed (NULL after a failed check). */
static cJSON *run_proxies(const char *args, const char *out_dir)
{
    char err[2048], path[1400];
    int rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 0, "prodygs %s failed (%d): %s", args, rc, err);
    snprintf(path, sizeof path, "%s/trainset.json", out_dir);
    cJSON *j = rc == 0 ? load_json(path) : NULL;
    CHECK(rc != 0 || j != NULL, "%s missing or invalid", path);
    return j;
}

static double pose_scale_of(cJSON *trainset)
{
    return cJSON_GetObjectItem(cJSON_GetObjectItem(trainset, "source"), "pose_scale")->valuedouble;
}

int main(void)
{
    char dir[1024], data[1200], out[1200], out2[1200], args[4096], err[2048], path[1400];
    test_tmpdir("test_proxy_cli", dir, sizeof dir);
    snprintf(data, sizeof data, "%s/data", dir);
    snprintf(out, sizeof out, "%s/out", dir);
    snprintf(out2, sizeof out2, "%s/hemi", dir);
    synth_options so;
    synth_options_default(&so);
    so.cams = 8;
    so.frames = 2;
    so.width = 80;
    so.height = 60;
    so.spp = 1;
    CHECK_OK(synth_write_dataset(data, &so));

    /* Dataset poses: cam00 real, cam05/06 test, the 5 others proxies; scale fitted on depth_gt = 1. */
    snprintf(args, sizeof args, "proxies '%s' --depth '%s/depth_gt/cam00.npy' --out '%s' --fit-steps 3", data, data, out);
    cJSON *j = run_proxies(args, out);
    if (j) {
        CHECK(count_role(j, "real") == 1 && count_role(j, "proxy") == 5 && count_role(j, "test") == 2,
              "roles real %d proxy %d test %d", count_role(j, "real"), count_role(j, "proxy"), count_role(j, "test"));
        CHECK(fabs(pose_scale_of(j) - 1.0) < 0.02, "fitted pose scale %g on ground-truth depth", pose_scale_of(j));
        cJSON_Delete(j);
    }
    snprintf(path, sizeof path, "%s/cam03/mask/0001.png", out);
    CHECK(pg_path_exists(path), "%s missing", path);
    snprintf(path, sizeof path, "%s/cam05/rgb/0001.png", out);
    CHECK(pg_path_exists(path), "test camera frames missing (%s)", path);
    snprintf(path, sizeof path, "%s/cam05/mask", out);
    CHECK(!pg_path_exists(path), "a test camera got proxy masks");

    /* Hemisphere poses on the single camera's frame folder, with a given scale. */
    snprintf(args, sizeof args,
             "proxies '%s/cam00/images' --depth '%s/depth_gt/cam00.npy' --out '%s' --poses hemisphere --proxies 3 "
             "--max-angle 12 --fit-steps 2 --fit-block 2 --frames 1 --pose-scale 2",
             data, data, out2);
    j = run_proxies(args, out2);
    if (j) {
        CHECK(count_role(j, "proxy") == 3 && count_role(j, "test") == 0, "hemisphere roles");
        CHECK(cJSON_GetObjectItem(j, "frames")->valueint == 1, "--frames ignored");
        cJSON_Delete(j);
    }
    pg_array a = { 0 };
    snprintf(path, sizeof path, "%s/proxy02/depth.npy", out2);
    CHECK_OK(io_npy_load(path, &a));
    CHECK(a.ndim == 3 && a.shape[0] == 1 && a.shape[1] == 60 && a.shape[2] == 80, "proxy depth shape");
    pg_array_destroy(&a);

    /* Hemisphere poses on the dataset, scored at its test cameras: the depth (here twice the truth)
     * must still be brought into pose units, or every test camera sees the scene at the wrong scale. */
    snprintf(path, sizeof path, "%s/depth_gt/cam00.npy", data);
    CHECK_OK(io_npy_load(path, &a));
    if (a.data) {
        float *v = a.data;
        for (size_t k = 0; k < a.shape[0] * a.shape[1] * a.shape[2]; k++) v[k] *= 2.0f;
        snprintf(path, sizeof path, "%s/depth_x2.npy", dir);
        CHECK_OK(io_npy_save(path, v, 3, a.shape));
    }
    pg_array_destroy(&a);
    snprintf(path, sizeof path, "%s/hemi_eval", dir);
    snprintf(args, sizeof args, "proxies '%s' --depth '%s/depth_x2.npy' --out '%s' --poses hemisphere --proxies 2 "
             "--frames 1", data, dir, path);
    j = run_proxies(args, path);
    if (j) {
        CHECK(count_role(j, "proxy") == 2 && count_role(j, "test") == 2, "hemisphere + test roles");
        CHECK(fabs(pose_scale_of(j) - 0.5) < 0.01, "hemisphere poses with test cameras: pose scale %g, want 0.5 (depth x2)",
              pose_scale_of(j));
        cJSON_Delete(j);
    }

    /* Dataset poses limited to the 2 cameras closest to the real one, real camera given by name. */
    snprintf(path, sizeof path, "%s/two", dir);
    snprintf(args, sizeof args, "proxies '%s' --depth '%s/depth_gt/cam00.npy' --out '%s' --fit-steps 1 --proxies 2 "
             "--train-cam cam00 --pose-scale 1", data, data, path);
    j = run_proxies(args, path);
    if (j) {
        CHECK(count_role(j, "proxy") == 2 && count_role(j, "test") == 2, "--proxies 2: %d proxies", count_role(j, "proxy"));
        cJSON_Delete(j);
    }

    /* --diagnose scores each proxy against its camera's real frames (measured 19.62 dB at 80x60 with
     * ground-truth depth, 15.41 with it doubled): ground-truth depth gives
     * proxies close to what those cameras recorded, the same depth doubled (wrong geometry at a
     * given pose scale) clearly worse. */
    double diag_psnr[2] = { 0, 0 };
    for (int k = 0; k < 2; k++) {
        char ddir[1300], depth[1300];
        snprintf(ddir, sizeof ddir, "%s/diag%d", dir, k);
        if (k == 0) snprintf(depth, sizeof depth, "%s/depth_gt/cam00.npy", data);
        else snprintf(depth, sizeof depth, "%s/depth_x2.npy", dir);
        snprintf(args, sizeof args, "proxies '%s' --depth '%s' --out '%s' --pose-scale 1 --diagnose", data, depth, ddir);
        j = run_proxies(args, ddir);
        cJSON_Delete(j);
        snprintf(path, sizeof path, "%s/diagnose.json", ddir);
        cJSON *d = load_json(path);
        CHECK(d != NULL, "%s missing or invalid", path);
        if (!d) continue;
        CHECK(cJSON_GetArraySize(cJSON_GetObjectItem(d, "cameras")) == 5, "diagnose: %d views, want the 5 proxies",
              cJSON_GetArraySize(cJSON_GetObjectItem(d, "cameras")));
        cJSON *all = cJSON_GetObjectItem(cJSON_GetObjectItem(d, "all"), "reprojected");
        cJSON *p = cJSON_GetObjectItem(all, "psnr"), *fr = cJSON_GetObjectItem(all, "fraction");
        diag_psnr[k] = cJSON_IsNumber(p) ? p->valuedouble : 0;
        CHECK(cJSON_IsNumber(fr) && fr->valuedouble > 0.2, "diagnose: reprojected share %g",
              cJSON_IsNumber(fr) ? fr->valuedouble : -1);
        cJSON_Delete(d);
        snprintf(path, sizeof path, "%s/vis/diagnose_cam01_0001.png", ddir);
        CHECK(pg_path_exists(path), "%s missing", path);
    }
    printf("diagnose: proxies vs their cameras' frames %.2f dB with ground-truth depth, %.2f dB with it doubled\n",
           diag_psnr[0], diag_psnr[1]);
    CHECK(diag_psnr[0] > 17, "diagnose: ground-truth depth proxies at %.2f dB", diag_psnr[0]);
    CHECK(diag_psnr[0] > diag_psnr[1] + 2.5, "diagnose: doubled depth %.2f dB not below ground truth %.2f dB",
          diag_psnr[1], diag_psnr[0]);
    snprintf(args, sizeof args, "proxies '%s' --depth '%s/depth_gt/cam00.npy' --out '%s/diag_h' --poses hemisphere --diagnose",
             data, data, dir);
    int rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 2 && strstr(err, "--diagnose"), "--diagnose with hemisphere poses: rc %d, %s", rc, err);

    /* Errors: exit 2 with one line naming the problem. */
    snprintf(args, sizeof args, "proxies '%s' --depth '%s/nope.npy' --out '%s'", data, data, out);
    rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 2 && strstr(err, "nope.npy"), "missing depth: rc %d, %s", rc, err);
    snprintf(args, sizeof args, "proxies '%s' --depth '%s/depth_gt/cam00.npy' --out '%s' --poses sideways", data,
             data, out);
    rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 2 && strstr(err, "sideways"), "bad --poses: rc %d, %s", rc, err);
    snprintf(args, sizeof args, "proxies '%s' --out '%s'", data, out);
    rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 2 && strstr(err, "--depth"), "missing --depth: rc %d, %s", rc, err);
    snprintf(args, sizeof args, "proxies '%s' --depth '%s/depth_gt/cam00.npy' --out '%s' --test-cams 0", data, data,
             out);
    rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 2, "real camera as test camera accepted: rc %d", rc);
    /* depth of another size/shape: a (2, 60, 80) array where 3 frames are asked for */
    snprintf(args, sizeof args, "proxies '%s' --depth '%s/depth_gt/cam00.npy' --out '%s' --frames 3", data, data, out);
    rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 2, "3 frames of a 2-frame input accepted: rc %d %s", rc, err);
    snprintf(args, sizeof args, "bench proxy --width 48 --height 32 --num 2 --frames 2 --steps 2 --out '%s/bench'", dir);
    rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 0, "bench proxy failed: %s", err);
    return test_summary("test_proxy_cli");
}
