/* test_proxy_colmap.c - the evaluation's depth alignment: the robust scale-and-shift fit on
 * synthetic points (always), then COLMAP end to end on the sample scene, where a depth whose
 * inverse is off by a known scale and shift must come back to the ground truth (skipped, exit 77,
 * when COLMAP is not installed). */
#include "testlib.h"
#include "core/fileutil.h"
#include "core/rng.h"
#include "io/json.h"
#include "io/npy.h"
#include "proxy/colmap_align.h"
#include "prodygs.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Points z = s d / (1 + a d) with 1 % noise on 1/z and 15 % gross mismatches: the fit returns
 * s and a; least squares on the same points would not (the mismatches pull it). */
static void test_fit(void)
{
    enum { N = 400 };
    double d[N], z[N];
    const double s = 2.4, a = 0.35;
    pg_rng rng;
    pg_rng_seed(&rng, 7);
    for (int i = 0; i < N; i++) {
        d[i] = 0.5 + 3.0 * pg_rng_uniform(&rng);
        double inv = (1 + a * d[i]) / (s * d[i]);
        inv *= 1 + 0.01 * pg_rng_normal(&rng);
        if (i % 7 == 0) inv *= 0.4 + 1.2 * pg_rng_uniform(&rng); /* a wrong match */
        z[i] = 1 / inv;
    }
    proxy_colmap_report rep;
    CHECK_OK(proxy_fit_scale_shift(d, z, N, &rep));
    CHECK(fabs(rep.scale / s - 1) < 0.02 && fabs(rep.shift / a - 1) < 0.05, "fit %g / %g, true %g / %g", rep.scale,
          rep.shift, s, a);
    CHECK(rep.abs_rel < 0.02 && rep.abs_rel < rep.abs_rel_scale_only, "median error %g (scale alone %g)", rep.abs_rel,
          rep.abs_rel_scale_only);
    CHECK(proxy_fit_scale_shift(d, z, 5, &rep) == PG_ERR_FORMAT, "five points are not enough");
}

/* The sample scene's ground-truth depth of cam00 distorted as a monocular network's would be
 * (1/d = s/Z - a), through the proxies stage at the dataset's poses: the fitted scale and shift
 * undo it and the training set's depth is the ground truth again. */
static void test_colmap_end_to_end(void)
{
    char dir[1024], args[2048], err[4096], path[1300], scene[1100];
    test_tmpdir("proxy_colmap", dir, sizeof dir);
    snprintf(scene, sizeof scene, "%s/scene", dir);
    snprintf(args, sizeof args, "synth '%s' --cams 7 --frames 2 --size 320x240 --threads 2", scene);
    int rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 0, "synth exit %d: %s", rc, err);
    pg_array gt = { 0 };
    snprintf(path, sizeof path, "%s/depth_gt/cam00.npy", scene);
    CHECK_OK(io_npy_load(path, &gt));
    if (!gt.data) return;
    const float s = 1.6f, a = 0.3f;
    for (size_t i = 0; i < gt.count; i++) gt.data[i] = 1.0f / (s / gt.data[i] - a);
    snprintf(path, sizeof path, "%s/distorted.npy", dir);
    CHECK_OK(io_npy_save(path, gt.data, gt.ndim, gt.shape));
    pg_array_destroy(&gt);

    pg_proxies_config c;
    pg_proxies_defaults(&c);
    char out[1200];
    snprintf(out, sizeof out, "%s/proxies", dir);
    c.input = scene, c.depth = path, c.out = out, c.test_cameras = "cam05,cam06", c.threads = 2;
    pg_proxies_report r;
    CHECK_OK(pg_proxies_run(&c, &r));
    printf("COLMAP alignment: scale %.4f shift %.4f (true %.4f / %.4f): %s\n", r.pose_scale, r.pose_shift, s, a, r.pose_fit);
    CHECK(strstr(r.pose_fit, "COLMAP scale and shift") != NULL, "fitted by %s", r.pose_fit);
    CHECK(fabs(r.pose_scale / s - 1) < 0.03 && fabs(r.pose_shift / a - 1) < 0.08, "fit %g / %g, true %g / %g",
          r.pose_scale, r.pose_shift, s, a);
    snprintf(args, sizeof args, "%s.colmap", out);
    CHECK(!pg_path_exists(args), "COLMAP's work folder %s is left behind", args);

    /* without the shift (the ablation) the stage falls back to the photometric scale */
    snprintf(out, sizeof out, "%s/proxies_scale", dir);
    c.out = out, c.pose_shift = 0;
    CHECK_OK(pg_proxies_run(&c, &r));
    CHECK(strcmp(r.pose_fit, "photometric scale") == 0 && r.pose_shift == 0, "ablation fitted by %s, shift %g",
          r.pose_fit, r.pose_shift);
}

int main(void)
{
    test_fit();
    if (!proxy_colmap_available()) {
        printf("test_proxy_colmap: COLMAP is not installed (apt-get install colmap): end-to-end part skipped\n");
        test_summary("test_proxy_colmap");
        return test_failed ? 1 : 77;
    }
    test_colmap_end_to_end();
    return test_summary("test_proxy_colmap");
}
