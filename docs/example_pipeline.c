/* example_pipeline.c - the whole ProDyGS pipeline in-process through the public API.
 *
 *   cc example_pipeline.c -lprodygs ... -o example_pipeline
 *   ./example_pipeline DATASET DEPTH.npy OUT_DIR
 *
 * DATASET is a multi-camera recording (DyNeRF or Panoptic layout) whose first camera is the
 * input video; DEPTH.npy its per-frame depth. Cameras cam05 and cam06 are held out and scored.
 * Built and run by tests/test_stage_api.c.
 */
#include <prodygs.h>

#include <stdio.h>

static int fail(const char *stage)
{
    fprintf(stderr, "example: %s failed: %s\n", stage, pg_last_error());
    return 1;
}

int main(int argc, char **argv)
{
    if (argc != 4) {
        fprintf(stderr, "usage: %s DATASET DEPTH.npy OUT_DIR\n", argv[0]);
        return 2;
    }
    char prepare_dir[4096], proxies_dir[4096], model_dir[4096], depth_aligned[4200];
    snprintf(prepare_dir, sizeof prepare_dir, "%s/prepare", argv[3]);
    snprintf(proxies_dir, sizeof proxies_dir, "%s/proxies", argv[3]);
    snprintf(model_dir, sizeof model_dir, "%s/model", argv[3]);
    snprintf(depth_aligned, sizeof depth_aligned, "%s/depth_aligned.npy", prepare_dir);

    /* 1. temporally consistent depth of the training camera */
    pg_prepare_config pc;
    pg_prepare_defaults(&pc);
    pc.input = argv[1];
    pc.depth = argv[2];
    pc.out = prepare_dir;
    pg_prepare_report pr;
    if (pg_prepare_run(&pc, &pr) != PG_OK) return fail("prepare");
    printf("prepare: %d frames of %s, residual %.4f -> %.4f\n", pr.frames, pr.train_camera, pr.residual_before,
           pr.residual_after);

    /* 2. proxy views at the other cameras' poses; the test cameras are never used */
    pg_proxies_config xc;
    pg_proxies_defaults(&xc);
    xc.input = argv[1];
    xc.depth = depth_aligned;
    xc.out = proxies_dir;
    xc.test_cameras = "cam05,cam06";
    xc.poses = "dataset";
    xc.fit_steps = 20;
    pg_proxies_report xr;
    if (pg_proxies_run(&xc, &xr) != PG_OK) return fail("proxies");
    printf("proxies: %d proxy cameras, test cameras %s\n", xr.proxies, xr.test_cameras);

    /* 3. the 4D model */
    pg_train_config tc;
    pg_train_defaults(&tc);
    tc.input = proxies_dir;
    tc.out = model_dir;
    tc.iters = 30;
    pg_train_report tr;
    if (pg_train_run(&tc, &tr) != PG_OK) return fail("train");
    printf("train: %d iterations, %d Gaussians, test PSNR %.2f dB\n", tr.iterations, tr.gaussians, tr.test_psnr);

    /* 4. every frame of the held-out cameras -> OUT/metrics.json, OUT/report.md */
    pg_evaluate_config ec;
    pg_evaluate_defaults(&ec);
    ec.dataset = argv[1];
    ec.model = model_dir;
    ec.out = argv[3];
    pg_evaluate_report er;
    if (pg_evaluate_run(&ec, &er) != PG_OK) return fail("evaluate");
    printf("evaluate: %d frames, PSNR %.2f dB, SSIM %.4f\n", er.frames, er.psnr, er.ssim);
    return 0;
}
