/* test_depth_sample.c - the depth stage on the built-in sample scene (src/synth, DyNeRF layout in
 * a temp dir), through the `prodygs prepare` CLI: static-mask IoU, scale drift after alignment,
 * refinement band error, and bad inputs (shape mismatch, all-NaN frame, single frame). */
#include "testlib.h"
#include "test_depth_scene.h"
#include "core/fileutil.h"
#include "core/parallel.h"
#include "depth/prepare.h"
#include "io/dataset.h"
#include "io/npy.h"
#include "synth/synth.h"

#include <stdio.h>

#define W 160
#define H 120
#define F 12

static int load(const char *dir, const char *name, pg_array *a)
{
    char path[1200];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    pg_status st = io_npy_load(path, a);
    CHECK(st == PG_OK, "%s: %s", path, st ? pg_last_error() : "");
    return st == PG_OK;
}

int main(void)
{
    pg_set_threads(2);
    char dir[1024], data[1100], out[1100], args[4096], err[2048], path[1200];
    test_tmpdir("depth_sample", dir, sizeof dir);
    snprintf(data, sizeof data, "%s/scene", dir);
    snprintf(out, sizeof out, "%s/prep", dir);
    synth_options so;
    synth_options_default(&so);
    so.cams = 1;
    so.frames = F;
    so.width = W;
    so.height = H;
    so.all_depth = 0;
    CHECK_OK(synth_write_dataset(data, &so));

    /* The CLI end to end. */
    snprintf(args, sizeof args, "prepare '%s' --depth '%s/depth_mono/cam00.npy' --out '%s'", data, data, out);
    double t0 = pg_time_seconds();
    int rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 0, "prepare exit %d: %s", rc, err);
    printf("sample scene %d frames %dx%d: prepare %.1f s\n", F, W, H, pg_time_seconds() - t0);

    pg_array gt = { 0 }, mono = { 0 }, dyn = { 0 }, al = { 0 }, sm = { 0 };
    int ok = load(data, "depth_gt/cam00.npy", &gt) & load(data, "depth_mono/cam00.npy", &mono) &
             load(data, "masks_dynamic/cam00.npy", &dyn) & load(out, "depth_aligned.npy", &al) &
             load(out, "static_masks.npy", &sm);
    const size_t n = (size_t)W * H;
    if (ok) CHECK(al.count == n * F && sm.count == n * F, "output sizes %zu %zu", al.count, sm.count);
    if (ok && al.count == n * F && sm.count == n * F) {
        unsigned char *gts = malloc(n * F), *mask = malloc(n * F);
        for (size_t k = 0; k < n * F; k++) {
            gts[k] = dyn.data[k] < 0.5f;
            mask[k] = sm.data[k] > 0.5f;
        }
        double iou_min = 1, iou_mean = 0, both_min = 1;
        unsigned char *both = malloc(n);
        for (int i = 1; i < F; i++) {
            double iou = depth_mask_iou(mask + i * n, gts + i * n, n);
            for (size_t k = 0; k < n; k++) both[k] = gts[i * n + k] && gts[k];
            double iou2 = depth_mask_iou(mask + i * n, both, n);
            iou_mean += iou / (F - 1);
            if (iou < iou_min) iou_min = iou;
            if (iou2 < both_min) both_min = iou2;
        }
        printf("sample static-mask IoU vs GT static (1 - masks_dynamic): mean %.3f min %.3f; vs static in frame i "
               "and 0: min %.3f\n", iou_mean, iou_min, both_min);
        CHECK(iou_min >= 0.9, "static-mask IoU %.3f < 0.9", iou_min);

        double med[F];
        double before = scene_scale_drift(mono.data, gt.data, gts, F, n, med);
        double after = scene_scale_drift(al.data, gt.data, gts, F, n, med);
        printf("sample scale drift (std/mean over frames of median D/D_gt, GT-static pixels): %.2f %% -> %.3f %%\n",
               100 * before, 100 * after);
        CHECK(before > 0.01, "input drift only %.3f %%", 100 * before);
        CHECK(after <= 0.005, "drift after alignment %.3f %% > 0.5 %%", 100 * after);
        free(gts);
        free(mask);
        free(both);

        /* Refinement alone, in-process, against the GT (same per-frame GT mapping for both). */
        pg_dataset *ds = NULL;
        io_dataset_options dopt = io_dataset_defaults();
        CHECK_OK(io_dataset_open(data, &dopt, &ds));
        float *ref = malloc(sizeof(float) * n * F);
        depth_refine_backend be = depth_refine_backend_get(DEPTH_REFINE_EDGE_SNAP, NULL);
        for (int i = 0; i < F && ds; i++) {
            pg_image img;
            CHECK_OK(io_dataset_frame(ds, 0, i, &img));
            CHECK_OK(depth_refine_run(&be, &img, mono.data + i * n, ref + i * n));
            pg_image_destroy(&img);
        }
        double ba, bb, ea, eb;
        scene_band_errors(mono.data, ref, gt.data, W, H, F, &ba, &bb, &ea, &eb);
        printf("sample refine band MAE %.4f -> %.4f (%+.1f %%), elsewhere %.4f -> %.4f (%+.2f %%)\n", ba, bb,
               100 * (bb / ba - 1), ea, eb, 100 * (eb / ea - 1));
        CHECK(bb <= 0.8 * ba, "band error %.4f -> %.4f: not 20 %% lower", ba, bb);
        CHECK(eb <= 1.02 * ea, "error elsewhere grew %.4f -> %.4f", ea, eb);
        free(ref);
        io_dataset_close(ds);
    }
    snprintf(path, sizeof path, "%s/vis/depth_0003.png", out);
    CHECK(pg_path_exists(path), "missing %s", path);
    snprintf(path, sizeof path, "%s/prepare.json", out);
    CHECK(pg_path_exists(path), "missing %s", path);
    snprintf(path, sizeof path, "%s/dynamic_prob.npy", out);
    CHECK(pg_path_exists(path), "missing %s", path);

    /* Bad input through the CLI. */
    if (mono.data) {
        size_t shape[3] = { F - 2, H, W };
        snprintf(path, sizeof path, "%s/short.npy", dir);
        CHECK_OK(io_npy_save(path, mono.data, 3, shape));
        snprintf(args, sizeof args, "prepare '%s' --depth '%s' --out '%s/bad'", data, path, dir);
        rc = test_run_cli(args, err, sizeof err);
        CHECK(rc == 2 && strstr(err, "short.npy"), "frame-count mismatch: exit %d, '%s'", rc, err);
        /* --frames 4 takes the first 4 of each: fine. */
        snprintf(args, sizeof args, "prepare '%s' --depth '%s' --out '%s/four' --frames 4 --no-refine", data, path, dir);
        rc = test_run_cli(args, err, sizeof err);
        CHECK(rc == 0, "--frames 4: exit %d, '%s'", rc, err);
        /* An all-NaN frame: documented fallback (copy of the previous frame), exit 0 with a warning. */
        for (size_t k = 0; k < n; k++) mono.data[2 * n + k] = NAN;
        size_t shape4[3] = { 4, H, W };
        snprintf(path, sizeof path, "%s/nan.npy", dir);
        CHECK_OK(io_npy_save(path, mono.data, 3, shape4));
        snprintf(args, sizeof args, "prepare '%s' --depth '%s' --out '%s/nan' --frames 4", data, path, dir);
        rc = test_run_cli(args, err, sizeof err);
        CHECK(rc == 0 && strstr(err, "frame 2"), "all-NaN frame: exit %d, '%s'", rc, err);
        /* A single frame: alignment is the identity. */
        snprintf(args, sizeof args, "prepare '%s' --depth '%s' --out '%s/one' --frames 1", data, path, dir);
        rc = test_run_cli(args, err, sizeof err);
        CHECK(rc == 0, "single frame: exit %d, '%s'", rc, err);
        /* All frames invalid: a clear error. */
        for (size_t k = 0; k < n * 4; k++) mono.data[k] = NAN;
        CHECK_OK(io_npy_save(path, mono.data, 3, shape4));
        snprintf(args, sizeof args, "prepare '%s' --depth '%s' --out '%s/nan2' --frames 4", data, path, dir);
        rc = test_run_cli(args, err, sizeof err);
        CHECK(rc == 2 && strstr(err, "valid depth"), "all-NaN input: exit %d, '%s'", rc, err);
        /* Usage errors. */
        snprintf(args, sizeof args, "prepare '%s' --depth '%s'", data, path);
        CHECK(test_run_cli(args, err, sizeof err) == 2 && strstr(err, "--out"), "missing --out accepted: '%s'", err);
        snprintf(args, sizeof args, "prepare '%s' --depth '%s' --out '%s/x' --size 12by3", data, path, dir);
        CHECK(test_run_cli(args, err, sizeof err) == 2, "bad --size accepted");
        snprintf(args, sizeof args, "prepare '%s/missing' --depth '%s' --out '%s/x'", dir, path, dir);
        CHECK(test_run_cli(args, err, sizeof err) == 2, "missing input accepted");
    }
    pg_array_destroy(&gt);
    pg_array_destroy(&mono);
    pg_array_destroy(&dyn);
    pg_array_destroy(&al);
    pg_array_destroy(&sm);
    return test_summary("test_depth_sample");
}
