/* test_depth_align.c - robust scale/shift fit, and the whole preparation stage on the procedural
 * scene: static-mask IoU >= 0.9, scale drift <= 0.5 % after alignment, documented fallbacks. */
#include "testlib.h"
#include "test_depth_scene.h"
#include "core/parallel.h"
#include "core/fileutil.h"
#include "depth/fuse.h"
#include "depth/prepare.h"
#include "depth/static_mask.h"
#include "io/npy.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Exact recovery of (alpha, beta) with 30 % gross outliers. */
static void test_fit(void)
{
    const size_t n = 5000;
    float *a = malloc(sizeof(float) * n), *b = malloc(sizeof(float) * n);
    pg_rng rng;
    pg_rng_seed(&rng, 5);
    for (size_t k = 0; k < n; k++) {
        b[k] = (float)pg_rng_range(&rng, 1.0, 8.0);                       /* reference */
        a[k] = (float)((b[k] - 0.3) / 1.7 * (1 + 0.002 * pg_rng_normal(&rng))); /* D_ref = 1.7 D + 0.3 */
        if (k % 10 < 3) a[k] *= (float)pg_rng_range(&rng, 0.3, 0.7);     /* moving things */
    }
    depth_align_params p;
    depth_align_defaults(&p);
    depth_align_result r;
    CHECK_OK(depth_align_fit(&p, a, b, NULL, n, &r));
    printf("align fit alpha %.4f (1.7) beta %.4f (0.3), inliers %ld/%ld, resid %.4f -> %.4f\n", r.alpha, r.beta,
           r.inliers, r.used, r.resid_before, r.resid_after);
    CHECK(fabs(r.alpha - 1.7) < 0.01 && fabs(r.beta - 0.3) < 0.03, "alpha %.4f beta %.4f", r.alpha, r.beta);
    CHECK(r.resid_after < r.resid_before && r.resid_after < 0.005, "residual %.4f -> %.4f", r.resid_before, r.resid_after);
    /* Narrow depth range: shift not identifiable, scale only. */
    for (size_t k = 0; k < n; k++) {
        b[k] = 5.0f + 0.01f * (float)pg_rng_normal(&rng);
        a[k] = b[k] / 2.0f;
    }
    CHECK_OK(depth_align_fit(&p, a, b, NULL, n, &r));
    CHECK(!r.shift_fitted && fabs(r.alpha - 2.0) < 1e-3, "narrow range: alpha %.4f shift %d", r.alpha, r.shift_fitted);
    /* Too few pixels: a clear error. */
    for (size_t k = 0; k < n; k++) a[k] = NAN;
    CHECK(depth_align_fit(&p, a, b, NULL, n, &r) == PG_ERR_ARG, "all-NaN fit accepted");
    free(a);
    free(b);
}

static void test_prepare_scene(void)
{
    test_scene sc;
    const int W = 160, H = 120, F = 8;
    CHECK(test_scene_make(&sc, W, H, F, 9) == 0, "scene");
    const size_t n = (size_t)W * H;
    depth_prepare_options opt;
    depth_prepare_defaults(&opt);
    opt.keep_flow = 1;
    depth_prepare_result res;
    double t0 = pg_time_seconds();
    CHECK_OK(depth_prepare_run(&opt, sc.rgb, F, sc.depth_mono, &res));
    printf("prepare %d frames %dx%d: %.2f s (refine %.2f, flow %.2f, align %.2f)\n", F, W, H,
           pg_time_seconds() - t0, res.seconds_refine, res.seconds_flow, res.seconds_align);
    if (!res.depth) { test_scene_destroy(&sc); return; }

    /* Static-mask IoU against the GT static region of frame i (complement of the moving ball). */
    unsigned char *gts = malloc(n), *gtb = malloc(n);
    double iou_min = 1, iou_mean = 0, iou2_min = 1;
    for (int i = 1; i < F; i++) {
        for (size_t k = 0; k < n; k++) {
            gts[k] = !sc.dynamic[i * n + k];
            gtb[k] = !sc.dynamic[i * n + k] && !sc.dynamic[k]; /* static in frame i and frame 0 */
        }
        double iou = depth_mask_iou(res.static_masks + i * n, gts, n);
        double iou2 = depth_mask_iou(res.static_masks + i * n, gtb, n);
        iou_mean += iou / (F - 1);
        if (iou < iou_min) iou_min = iou;
        if (iou2 < iou2_min) iou2_min = iou2;
    }
    printf("static mask IoU vs GT static: mean %.3f min %.3f; vs static-in-both-frames: min %.3f\n", iou_mean,
           iou_min, iou2_min);
    CHECK(iou_min >= 0.9, "static mask IoU %.3f < 0.9", iou_min);

    /* Scale drift: std over frames of median(D / D_gt) on GT static pixels. */
    unsigned char *st = malloc(n * F);
    for (size_t k = 0; k < n * F; k++) st[k] = !sc.dynamic[k];
    double med[64];
    double before = scene_scale_drift(sc.depth_mono, sc.depth_gt, st, F, n, med);
    double after = scene_scale_drift(res.depth, sc.depth_gt, st, F, n, med);
    printf("scale drift (std/mean of median ratio over frames): input %.2f %% -> aligned %.3f %%\n", 100 * before,
           100 * after);
    CHECK(before > 0.02, "input drift %.3f too small for a meaningful test", before);
    CHECK(after <= 0.005, "drift after alignment %.3f %% > 0.5 %%", 100 * after);
    CHECK(res.info[0].alpha == 1.0 && res.info[0].beta == 0.0 && res.reference == 0, "frame 0 not the identity");
    for (int i = 1; i < F; i++)
        CHECK(res.info[i].resid_after <= res.info[i].resid_before, "frame %d residual %.4f -> %.4f", i,
              res.info[i].resid_before, res.info[i].resid_after);

    /* Outputs on disk, then read back. */
    char dir[512], path[600];
    test_tmpdir("depth_align_prepare", dir, sizeof dir);
    CHECK_OK(depth_prepare_write(dir, &opt, &res, sc.rgb, sc.depth_mono, "{\"input\": \"procedural\"}"));
    snprintf(path, sizeof path, "%s/depth_aligned.npy", dir);
    pg_array arr;
    CHECK_OK(io_npy_load(path, &arr));
    CHECK(arr.ndim == 3 && arr.shape[0] == (size_t)F && arr.shape[1] == (size_t)H && arr.shape[2] == (size_t)W,
          "depth_aligned.npy shape");
    if (arr.data) { /* stored as float16: each value within half a float16 step */
        double worst = 0;
        for (size_t i = 0; i < n * F; i++)
            worst = fmax(worst, res.depth[i] > 0 ? fabs(arr.data[i] / res.depth[i] - 1.0) : fabs(arr.data[i]));
        CHECK(worst <= 1.0 / 2048, "depth_aligned.npy content: relative error %.3g", worst);
    }
    pg_array_destroy(&arr);
    snprintf(path, sizeof path, "%s/vis/flow_0005.png", dir);
    CHECK(pg_path_exists(path), "missing %s", path);
    snprintf(path, sizeof path, "%s/prepare.json", dir);
    CHECK(pg_path_exists(path), "missing %s", path);

    free(gts);
    free(gtb);
    free(st);
    depth_prepare_result_destroy(&res);
    test_scene_destroy(&sc);
}

/* Bad input: single frame, all-NaN frames (incl. frame 0), nothing valid, size mismatch. */
static void test_fallbacks(void)
{
    test_scene sc;
    const int W = 64, H = 48, F = 4;
    CHECK(test_scene_make(&sc, W, H, F, 2) == 0, "scene");
    const size_t n = (size_t)W * H;
    depth_prepare_options opt;
    depth_prepare_defaults(&opt);
    depth_prepare_result res;
    CHECK_OK(depth_prepare_run(&opt, sc.rgb, 1, sc.depth_mono, &res));
    CHECK(res.frames == 1 && res.info[0].alpha == 1.0 && res.static_masks[0] == 1, "single frame");
    depth_prepare_result_destroy(&res);

    float *d = malloc(sizeof(float) * n * F);
    memcpy(d, sc.depth_mono, sizeof(float) * n * F);
    for (size_t k = 0; k < n; k++) d[2 * n + k] = NAN;
    CHECK_OK(depth_prepare_run(&opt, sc.rgb, F, d, &res));
    if (res.info) {
        CHECK(res.info[2].fallback == DEPTH_FALLBACK_COPIED && res.info[2].source_frame == 1, "all-NaN frame 2: %d from %d",
              res.info[2].fallback, res.info[2].source_frame);
        CHECK(memcmp(res.depth + 2 * n, res.depth + n, n * sizeof(float)) == 0, "frame 2 not a copy of frame 1");
    }
    depth_prepare_result_destroy(&res);
    for (size_t k = 0; k < n; k++) d[k] = NAN;
    CHECK_OK(depth_prepare_run(&opt, sc.rgb, F, d, &res));
    if (res.info) {
        CHECK(res.reference == 1 && res.info[0].fallback == DEPTH_FALLBACK_COPIED && res.info[0].source_frame == 1,
              "all-NaN frame 0: reference %d", res.reference);
    }
    depth_prepare_result_destroy(&res);
    for (size_t k = 0; k < n * F; k++) d[k] = NAN;
    CHECK(depth_prepare_run(&opt, sc.rgb, F, d, &res) == PG_ERR_ARG, "all-NaN input accepted");
    CHECK(strstr(pg_last_error(), "valid depth") != NULL, "message: %s", pg_last_error());
    CHECK(res.depth == NULL, "result not cleared on failure");
    pg_image small;
    CHECK_OK(pg_image_create(&small, 32, 24, 3));
    pg_image two[2] = { sc.rgb[0], small };
    CHECK(depth_prepare_run(&opt, two, 2, sc.depth_mono, &res) == PG_ERR_SIZE, "frame size mismatch accepted");
    pg_image_destroy(&small);
    free(d);
    test_scene_destroy(&sc);

    /* A tiny image (below the pyramid's minimum side, fewer pixels than the fit needs). */
    CHECK(test_scene_make(&sc, 6, 5, 3, 1) == 0, "tiny scene");
    CHECK_OK(depth_prepare_run(&opt, sc.rgb, 3, sc.depth_mono, &res));
    if (res.info) CHECK(res.info[1].fallback == DEPTH_FALLBACK_IDENTITY && res.info[1].alpha == 1.0, "tiny: fallback %d",
                        res.info[1].fallback);
    depth_prepare_result_destroy(&res);
    test_scene_destroy(&sc);
}

/* Same bytes for 1 and 2 threads (frames run in parallel, each single-threaded inside). */
static void test_determinism(void)
{
    test_scene sc;
    const int W = 96, H = 72, F = 4;
    CHECK(test_scene_make(&sc, W, H, F, 4) == 0, "scene");
    const size_t n = (size_t)W * H;
    depth_prepare_options opt;
    depth_prepare_defaults(&opt);
    depth_prepare_result a, b;
    pg_set_threads(1);
    CHECK_OK(depth_prepare_run(&opt, sc.rgb, F, sc.depth_mono, &a));
    pg_set_threads(2);
    CHECK_OK(depth_prepare_run(&opt, sc.rgb, F, sc.depth_mono, &b));
    if (a.depth && b.depth) {
        CHECK(memcmp(a.depth, b.depth, sizeof(float) * n * F) == 0, "depth differs between 1 and 2 threads");
        CHECK(memcmp(a.static_masks, b.static_masks, n * F) == 0, "masks differ between 1 and 2 threads");
    }
    depth_prepare_result_destroy(&a);
    depth_prepare_result_destroy(&b);
    test_scene_destroy(&sc);
}

/* Static pixels take their temporal median: a surface whose depth wobbles by a different smooth
 * factor each frame comes out at (almost) its true depth in every static frame, while the frames
 * where a pixel moves, pixels static too rarely, and invalid depth are left alone. */
static void test_fuse_static(void)
{
    enum { F = 9, N = 400 };
    float depth[F * N], truth[N];
    unsigned char mask[F * N];
    pg_rng rng;
    pg_rng_seed(&rng, 5);
    for (int k = 0; k < N; k++) truth[k] = 2.0f + 0.01f * (float)k;
    double err_before = 0, err_after = 0;
    for (int f = 0; f < F; f++)
        for (int k = 0; k < N; k++) {
            float wobble = 1.0f + 0.03f * sinf(0.02f * (float)k + 1.7f * (float)f); /* smooth, per frame */
            depth[f * N + k] = truth[k] * wobble;
            mask[f * N + k] = !(k < 40 && f == 4) && !(k >= 390); /* a mover at frame 4; pixels never static */
            err_before += fabs(depth[f * N + k] / truth[k] - 1);
        }
    depth[2 * N + 100] = 0; /* invalid: stays invalid, not counted */
    float moving = depth[4 * N + 10], never = depth[3 * N + 395];
    long fused = depth_fuse_static(depth, mask, F, N, 3);
    for (int f = 0; f < F; f++)
        for (int k = 0; k < 390; k++)
            if (mask[f * N + k] && depth[f * N + k] > 0) err_after += fabs(depth[f * N + k] / truth[k] - 1);
    CHECK(fused == 390, "fused %ld pixels, want 390", fused);
    CHECK(depth[4 * N + 10] == moving && depth[3 * N + 395] == never && depth[2 * N + 100] == 0,
          "moving, never-static and invalid pixels must keep their depth");
    CHECK(depth[0 * N + 50] == depth[8 * N + 50], "one depth per static pixel across frames");
    CHECK(err_after < 0.35 * err_before, "mean relative error %.4f -> %.4f", err_before / (F * N), err_after / (F * N));
    printf("fuse static: mean relative error %.4f -> %.4f\n", err_before / (F * N), err_after / (F * 390));
}

/* A surface without texture cannot show motion, so a flow over it (the solver's smoothness
 * dragging a passer-by's motion across a gym floor) must not mark it dynamic when its colour has
 * not changed; the same flow over a textured surface must. Two identical frames, the left half
 * flat grey, the right half stripes, and a 2 px flow everywhere. */
static void test_static_mask_flat(void)
{
    const int W = 64, H = 32;
    pg_image a, b;
    CHECK_OK(pg_image_create(&a, W, H, 3));
    CHECK_OK(pg_image_create(&b, W, H, 3));
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            for (int c = 0; c < 3; c++)
                a.data[((size_t)y * W + x) * 3 + c] = x < W / 2 ? 0.4f : 0.4f + 0.3f * (float)sin(x * 1.3 + y * 0.4);
    memcpy(b.data, a.data, sizeof(float) * (size_t)W * H * 3);
    float *flow = malloc(sizeof(float) * W * H * 2), *prob = malloc(sizeof(float) * W * H);
    unsigned char *mask = malloc((size_t)W * H);
    for (int k = 0; k < W * H; k++) flow[2 * k] = 2.0f, flow[2 * k + 1] = 0.0f;
    depth_static_params p;
    depth_static_defaults(&p);
    for (int gated = 1; gated >= 0; gated--) {
        if (!gated) p.texture_thresh = 0.0f;
        depth_mask_reference ref;
        CHECK_OK(depth_mask_reference_create(&p, &b, &ref));
        CHECK_OK(depth_static_mask(&p, &a, &ref, flow, NULL, prob, mask));
        depth_mask_reference_free(&ref);
        int flat_static = 0, tex_static = 0; /* away from the seam, where the blurs mix the halves */
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++) {
                if (x < W / 2 - 6) flat_static += mask[y * W + x];
                if (x >= W / 2 + 6) tex_static += mask[y * W + x];
            }
        const int half = H * (W / 2 - 6);
        printf("static mask, %s: flat half %d/%d static, striped half %d/%d\n", gated ? "texture gate" : "no gate",
               flat_static, half, tex_static, half);
        CHECK(tex_static == 0, "a 2 px flow over stripes must be dynamic (%d static)", tex_static);
        if (gated) CHECK(flat_static == half, "flat unchanged surface called dynamic (%d of %d static)", flat_static, half);
        else CHECK(flat_static == 0, "without the gate the flow must count everywhere (%d static)", flat_static);
    }
    /* a reference made without the gate cannot serve a gated mask, nor one of another size */
    depth_mask_reference ref;
    CHECK_OK(depth_mask_reference_create(&p, &b, &ref));
    depth_static_defaults(&p);
    CHECK(depth_static_mask(&p, &a, &ref, flow, NULL, prob, mask) == PG_ERR_ARG, "gate missing from the reference");
    depth_mask_reference_free(&ref);
    pg_image small;
    CHECK_OK(pg_image_create(&small, W / 2, H, 3));
    CHECK_OK(depth_mask_reference_create(&p, &small, &ref));
    CHECK(depth_static_mask(&p, &a, &ref, flow, NULL, prob, mask) == PG_ERR_SIZE, "reference of another size");
    depth_mask_reference_free(&ref);
    pg_image_destroy(&small);
    free(flow);
    free(prob);
    free(mask);
    pg_image_destroy(&a);
    pg_image_destroy(&b);
}

int main(void)
{
    pg_set_threads(2);
    test_fit();
    test_prepare_scene();
    test_fallbacks();
    test_determinism();
    test_fuse_static();
    test_static_mask_flat();
    return test_summary("test_depth_align");
}
