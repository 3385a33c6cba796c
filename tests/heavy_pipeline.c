/* heavy_pipeline.c - the whole pipeline through the CLI on a small sample scene: demo (synth ->
 * prepare -> proxies -> train -> eval -> videos), the outputs a user looks for, a rerun that
 * skips finished stages, render/export from the model alone, and clear errors on bad input. */
#include "testlib.h"
#include "core/fileutil.h"
#include "io/json.h"
#include "io/ply.h"

#include <stdio.h>
#include <string.h>

int main(void)
{
    char dir[1024], args[4096], err[8192], path[1200];
    test_tmpdir("pipeline", dir, sizeof dir);

    snprintf(args, sizeof args, "demo --out '%s/demo' --frames 6 --iters 300", dir);
    int rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 0, "demo exit %d: %s", rc, err);

    snprintf(path, sizeof path, "%s/demo/metrics.json", dir);
    cJSON *m = NULL;
    CHECK_OK(io_json_load(path, &m));
    if (m) {
        double psnr = io_json_number_or(m, "psnr", 0), masked = io_json_number_or(m, "psnr_masked", 0);
        printf("demo (6 frames, 300 iterations): held-out PSNR %.2f dB, masked %.2f dB\n", psnr, masked);
        /* a blank or misplaced render scores ~10 dB here; a working pipeline far more */
        CHECK(psnr > 16.0 && masked > 18.0, "held-out PSNR %.2f / masked %.2f too low", psnr, masked);
        const cJSON *cams = cJSON_GetObjectItem(m, "per_camera");
        CHECK(cJSON_GetObjectItem(cams, "cam05") && cJSON_GetObjectItem(cams, "cam06"), "test cameras missing");
        CHECK(cJSON_GetArraySize(cJSON_GetObjectItem(m, "per_frame")) == 18,
              "expected 2 test cameras + the training camera x 6 frames");
        const cJSON *tc = cJSON_GetObjectItem(m, "train_camera");
        const cJSON *mv = cJSON_GetObjectItem(cJSON_GetObjectItem(tc, "regions"), "moving");
        double mp = io_json_number_or(mv, "psnr", 0);
        printf("demo: training camera moving-pixel PSNR %.2f dB\n", mp);
        CHECK(mp > 20.0, "training camera moving-pixel PSNR %.2f too low (or missing)", mp);
        cJSON_Delete(m);
    }
    const char *outputs[] = { "report.md", "renders/fixed.mp4", "renders/fixed_compare.mp4", "renders/orbit.mp4",
                              "renders/spiral_depth.mp4", "side_by_side/cam05_0000.png", "model/cameras.json" };
    for (size_t i = 0; i < sizeof outputs / sizeof outputs[0]; i++) {
        snprintf(path, sizeof path, "%s/demo/%s", dir, outputs[i]);
        CHECK(pg_path_exists(path), "missing %s", path);
    }

    /* the same command again skips every finished stage */
    rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 0 && strstr(err, "prepare: already done") && strstr(err, "train: already done"),
          "rerun did not skip finished stages (exit %d): %s", rc, err);

    /* the model alone renders and exports */
    snprintf(args, sizeof args, "render '%s/demo/model' --out '%s/r' --path dataset-cam --camera cam05", dir, dir);
    rc = test_run_cli(args, err, sizeof err);
    snprintf(path, sizeof path, "%s/r/cam05.mp4", dir);
    CHECK(rc == 0 && pg_path_exists(path), "render dataset-cam exit %d: %s", rc, err);
    snprintf(args, sizeof args, "export '%s/demo/model' --out '%s/ply' --frame-list 0,5", dir, dir);
    rc = test_run_cli(args, err, sizeof err);
    snprintf(path, sizeof path, "%s/ply/frame_0005.ply", dir);
    io_ply_info info;
    CHECK(rc == 0 && io_ply_probe(path, &info) == PG_OK && info.count > 1000, "export exit %d: %s", rc, err);

    /* bad input: one line naming the problem, exit 2 */
    snprintf(args, sizeof args, "eval '%s/demo/scene' --depth '%s/nope.npy' --out '%s/bad'", dir, dir, dir);
    rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 2 && strstr(err, "nope.npy"), "missing depth: exit %d: %s", rc, err);
    snprintf(args, sizeof args, "render '%s/demo/model' --out '%s/r2' --path zigzag", dir, dir);
    rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 2 && strstr(err, "zigzag"), "bad path: exit %d: %s", rc, err);
    snprintf(args, sizeof args, "export '%s/demo/model' --out '%s/p2' --times 2.5", dir, dir);
    rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 2 && strstr(err, "--times"), "bad time: exit %d: %s", rc, err);
    return test_summary("heavy_pipeline");
}
