/* heavy_depth_units.c - depth in other units trains to the same result: the sample scene with its
 * monocular depth as given, x1000 (millimetres) and x0.001, through the whole pipeline with the
 * same settings; the held-out PSNR must agree within 0.3 dB, since every stage works in units
 * fitted to the depth (pose scale, scene extent). (Measured: 19.079 / 19.085 / 19.080 dB. The
 * training camera's moving part, a few hundred pixels here, varied 36.8-38.5 dB: printed, not
 * checked.) */
#include "testlib.h"
#include "io/npy.h"
#include "synth/synth.h"

#include <prodygs.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

static pg_evaluate_report run(const char *data, const char *depth, const char *out)
{
    pg_pipeline_config c;
    pg_pipeline_defaults(&c);
    c.input = data;
    c.depth = depth;
    c.out = out;
    c.test_cameras = "cam05,cam06";
    c.iters = 300;
    c.threads = 2;
    c.evaluate = 1;
    pg_pipeline_report r;
    pg_status st = pg_pipeline_run(&c, &r);
    CHECK(st == PG_OK, "pipeline in %s: %s", out, pg_last_error());
    return r.evaluation;
}

int main(void)
{
    char dir[1024], data[1100], path[1200], depth[1200], out[1200];
    test_tmpdir("depth_units", dir, sizeof dir);
    snprintf(data, sizeof data, "%s/data", dir);
    synth_options so;
    synth_options_default(&so);
    so.cams = 7;
    so.frames = 4;
    so.width = 64;
    so.height = 48;
    CHECK_OK(synth_write_dataset(data, &so));
    snprintf(path, sizeof path, "%s/depth_mono/cam00.npy", data);
    pg_array d = { 0 };
    CHECK_OK(io_npy_load(path, &d));
    const size_t n = d.count;
    float *scaled = malloc(n * sizeof(float));
    static const double factors[3] = { 1.0, 1000.0, 0.001 };
    pg_evaluate_report e[3];
    for (int f = 0; f < 3; f++) {
        for (size_t i = 0; i < n; i++) scaled[i] = (float)(d.data[i] * factors[f]);
        snprintf(depth, sizeof depth, "%s/depth_x%g.npy", dir, factors[f]);
        CHECK_OK(io_npy_save(depth, scaled, d.ndim, d.shape));
        snprintf(out, sizeof out, "%s/out_x%g", dir, factors[f]);
        e[f] = run(data, depth, out);
        printf("depth x%g: held-out PSNR %.3f (moving %.3f), training camera moving %.3f\n", factors[f], e[f].psnr,
               e[f].psnr_moving, e[f].train_psnr_moving);
    }
    CHECK(e[0].psnr > 15, "the reference run did not learn the scene (held-out PSNR %.2f)", e[0].psnr);
    for (int f = 1; f < 3; f++) {
        CHECK(fabs(e[f].psnr - e[0].psnr) <= 0.3, "depth x%g: held-out PSNR %.3f vs %.3f", factors[f], e[f].psnr, e[0].psnr);
    }
    free(scaled);
    pg_array_destroy(&d);
    return test_summary("heavy_depth_units");
}
