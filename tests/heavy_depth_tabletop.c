/* heavy_depth_tabletop.c - the depth-stage figures on ../shared/data/tabletop_dev (skipped when
 * absent): static-mask IoU, scale drift before/after alignment, refinement band error.
 * tabletop_dev has no dynamic masks, so its GT static region for frame i is where depth_gt
 * changed by less than 1 % against frame 0 (static in both frames). */
#include "testlib.h"
#include "test_depth_scene.h"
#include "core/parallel.h"
#include "depth/prepare.h"
#include "io/dataset.h"
#include "io/depth_io.h"

#include <stdio.h>
#include <stdlib.h>

int main(void)
{
    char dir[1024], path[1200];
    if (!test_shared_data("tabletop_dev", dir, sizeof dir)) {
        printf("heavy_depth_tabletop: tabletop_dev absent, skipped\n");
        return test_summary("heavy_depth_tabletop");
    }
    pg_set_threads(2);
    pg_dataset *ds = NULL;
    io_dataset_options dopt = io_dataset_defaults();
    /* The first 20 of 40 frames keep this under a minute on a shared machine; set
     * PG_TABLETOP_FRAMES=40 for the full figures in docs/depth.md. */
    const char *env = getenv("PG_TABLETOP_FRAMES");
    dopt.count = env && atoi(env) > 0 ? atoi(env) : 20;
    CHECK_OK(io_dataset_open(dir, &dopt, &ds));
    if (!ds) return test_summary("heavy_depth_tabletop");
    const int F = io_dataset_num_frames(ds), W = io_dataset_width(ds), H = io_dataset_height(ds);
    const size_t n = (size_t)W * H;
    pg_image *frames = calloc(F, sizeof(pg_image));
    for (int t = 0; t < F; t++) CHECK_OK(io_dataset_frame(ds, 0, t, &frames[t]));
    io_depth mono, gt;
    io_depth_options o = io_depth_defaults();
    o.width = W;
    o.height = H;
    o.count = F;
    o.expect_frames = F;
    snprintf(path, sizeof path, "%s/depth_mono/cam00.npy", dir);
    CHECK_OK(io_depth_load(path, &o, &mono));
    snprintf(path, sizeof path, "%s/depth_gt/cam00.npy", dir);
    CHECK_OK(io_depth_load(path, &o, &gt));

    depth_prepare_options opt;
    depth_prepare_defaults(&opt);
    depth_prepare_result res;
    double t0 = pg_time_seconds();
    CHECK_OK(depth_prepare_run(&opt, frames, F, mono.data, &res));
    printf("tabletop prepare %d frames %dx%d: %.1f s (refine %.1f, flow %.1f, align %.1f)\n", F, W, H,
           pg_time_seconds() - t0, res.seconds_refine, res.seconds_flow, res.seconds_align);

    if (res.depth) {
        /* Static-mask IoU against the GT-derived static region. */
        unsigned char *gts = malloc(n * F);
        double iou_min = 1, iou_mean = 0;
        for (int i = 0; i < F; i++)
            for (size_t k = 0; k < n; k++) {
                float a = gt.data[i * n + k], b = gt.data[k];
                gts[i * n + k] = a > 0 && b > 0 && fabsf(logf(a / b)) < 0.01f;
            }
        for (int i = 1; i < F; i++) {
            double iou = depth_mask_iou(res.static_masks + i * n, gts + i * n, n);
            iou_mean += iou / (F - 1);
            if (iou < iou_min) iou_min = iou;
        }
        printf("tabletop static mask IoU vs GT (depth change < 1 %% vs frame 0): mean %.3f min %.3f\n", iou_mean, iou_min);
        CHECK(iou_min >= 0.9, "IoU %.3f", iou_min);

        double med[64];
        double before = scene_scale_drift(mono.data, gt.data, gts, F, n, med);
        double after = scene_scale_drift(res.depth, gt.data, gts, F, n, med);
        printf("tabletop scale drift (std/mean over frames of median D/D_gt on GT-static pixels): %.2f %% -> %.3f %%\n",
               100 * before, 100 * after);
        CHECK(after <= 0.005, "drift %.3f %%", 100 * after);
        free(gts);

        /* Refinement alone (no alignment), compared fairly in GT units. */
        float *ref = malloc(sizeof(float) * n * F);
        depth_refine_backend be = depth_refine_backend_get(DEPTH_REFINE_EDGE_SNAP, NULL);
        for (int i = 0; i < F; i++) CHECK_OK(depth_refine_run(&be, &frames[i], mono.data + i * n, ref + i * n));
        double ba, bb, ea, eb;
        scene_band_errors(mono.data, ref, gt.data, W, H, F, &ba, &bb, &ea, &eb);
        printf("tabletop refine band MAE %.4f -> %.4f (%+.1f %%), elsewhere %.4f -> %.4f (%+.2f %%)\n", ba, bb,
               100 * (bb / ba - 1), ea, eb, 100 * (eb / ea - 1));
        /* The issue asks 20 % on the sample scene; tabletop_dev is harder (white and yellow objects
         * on a white/yellow striped table, curved silhouettes): we reach about 20-22 % there. */
        CHECK(bb <= 0.85 * ba, "band error %.4f -> %.4f", ba, bb);
        CHECK(eb <= 1.02 * ea, "elsewhere %.4f -> %.4f", ea, eb);
        free(ref);
    }
    depth_prepare_result_destroy(&res);
    io_depth_destroy(&mono);
    io_depth_destroy(&gt);
    for (int t = 0; t < F; t++) pg_image_destroy(&frames[t]);
    free(frames);
    io_dataset_close(ds);
    return test_summary("heavy_depth_tabletop");
}
