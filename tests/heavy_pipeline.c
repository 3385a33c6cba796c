/* heavy_pipeline.c - the whole pipeline through the CLI on a small sample scene: demo (synth ->
 * prepare -> proxies -> train -> eval -> videos), the outputs a user looks for, a rerun that
 * skips finished stages, render/export from the model alone, and clear errors on bad input. */
#include "testlib.h"
#include "core/fileutil.h"
#include "core/image.h"
#include "io/image_io.h"
#include "io/json.h"
#include "io/ply.h"

#include <stdio.h>
#include <string.h>

/* Mean PSNR over frames of the PNGs in render_dir against truth_dir (NNNN.png each); up_w > 0:
 * the renders are first resized (bilinear) to up_w x up_h. */
static double psnr_frames(const char *truth_dir, const char *render_dir, int frames, int up_w, int up_h)
{
    double sum = 0;
    for (int f = 0; f < frames; f++) {
        char path[1300];
        pg_image truth = { 0 }, render = { 0 }, big = { 0 };
        snprintf(path, sizeof path, "%s/%04d.png", truth_dir, f);
        CHECK_OK(io_image_load(path, &truth));
        snprintf(path, sizeof path, "%s/%04d.png", render_dir, f);
        CHECK_OK(io_image_load(path, &render));
        const pg_image *r = &render;
        if (up_w > 0 && pg_image_resize(&big, &render, up_w, up_h) == PG_OK) r = &big;
        sum += truth.data && r->data && r->width == truth.width ? pg_image_psnr(r, &truth, NULL) : 0;
        pg_image_destroy(&truth);
        pg_image_destroy(&render);
        pg_image_destroy(&big);
    }
    return sum / frames;
}

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

    /* issue 29: rendered at twice its training size, the model is at least as close to the scene
     * ray-traced at that size as its training-size render blown up (before the 3D filter, thin
     * Gaussians turned into needles and holes there: 4 dB worse at 2x after full training) */
    snprintf(args, sizeof args, "synth '%s/big' --cams 10 --frames 6 --size 320x240", dir);
    rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 0, "synth at 320x240: exit %d: %s", rc, err);
    for (int k = 0; k < 2; k++) {
        snprintf(args, sizeof args, "render '%s/demo/model' --out '%s/r%d' --path dataset-cam --camera cam05 --size %s --png --no-depth",
                 dir, dir, k, k ? "320x240" : "160x120");
        rc = test_run_cli(args, err, sizeof err);
        CHECK(rc == 0, "render at %s: exit %d: %s", k ? "320x240" : "160x120", rc, err);
    }
    char truth_dir[1100], r0[1100], r1[1100];
    snprintf(truth_dir, sizeof truth_dir, "%s/big/cam05/images", dir);
    snprintf(r0, sizeof r0, "%s/r0/cam05", dir);
    snprintf(r1, sizeof r1, "%s/r1/cam05", dir);
    double native = psnr_frames(truth_dir, r1, 6, 0, 0), upscaled = psnr_frames(truth_dir, r0, 6, 320, 240);
    printf("cam05 at 320x240 (trained at 160x120): native render %.2f dB, the 160x120 render upscaled %.2f dB\n", native,
           upscaled);
    CHECK(native >= upscaled, "native 2x render %.2f dB below the upscaled 1x render's %.2f dB", native, upscaled);

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
