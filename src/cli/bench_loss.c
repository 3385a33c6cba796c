/* bench_loss.c - `prodygs bench loss`: time of the per-iteration image losses (L1 + D-SSIM with
 * backward, SSI depth with backward) on random W x H images; one JSON line, medians after a warm-up. */
#include "cli/cli.h"
#include "core/mathx.h"
#include "core/parallel.h"
#include "core/rng.h"
#include "optim/loss_depth.h"
#include "optim/loss_image.h"

#include <stdio.h>
#include <stdlib.h>

int bench_loss(int argc, char **argv)
{
    int W = 320, H = 240, threads = 1, reps = 11;
    const cli_option opts[] = {
        { "--width", CLI_INT, &W, "image width (default 320)" },
        { "--height", CLI_INT, &H, "image height (default 240)" },
        { "--threads", CLI_INT, &threads, "threads (default 1)" },
        { "--reps", CLI_INT, &reps, "timed repetitions (default 11)" },
    };
    cli_spec spec = { "prodygs bench loss", "[options]", "time L1 + D-SSIM + SSI depth forward/backward", opts,
                      (int)(sizeof(opts) / sizeof(opts[0])), 0, 0 };
    int np = 0;
    int rc = cli_parse(&spec, argc, argv, NULL, &np);
    if (rc) return rc < 0 ? 0 : rc;
    if (W < 1 || H < 1 || threads < 1 || reps < 1 || (long)W * H > 100000000L)
        return cli_usage_error("bench loss: bad --width/--height/--threads/--reps");
    pg_set_threads(threads);
    size_t n = (size_t)W * H * 3, np1 = (size_t)W * H;
    float *x = malloc(n * sizeof(float)), *y = malloc(n * sizeof(float)), *g = calloc(n, sizeof(float));
    float *dp = malloc(np1 * sizeof(float)), *dt = malloc(np1 * sizeof(float)), *gd = calloc(np1, sizeof(float));
    double *ts = malloc(reps * sizeof(double)), *td = malloc(reps * sizeof(double));
    optim_ssim_ws *ws = NULL;
    pg_status st = (x && y && g && dp && dt && gd && ts && td) ? optim_ssim_create(&ws, H, W, 3)
                                                              : pg_fail(PG_ERR_NOMEM, "bench loss: out of memory");
    if (!st) {
        pg_rng rng;
        pg_rng_seed(&rng, 1);
        for (size_t i = 0; i < n; i++) { x[i] = (float)pg_rng_uniform(&rng); y[i] = (float)pg_rng_uniform(&rng); }
        for (size_t i = 0; i < np1; i++) { dp[i] = (float)pg_rng_range(&rng, 1, 5); dt[i] = (float)pg_rng_range(&rng, 1, 5); }
        for (int r = -1; r < reps; r++) {
            double t0 = pg_time_seconds();
            optim_l1_forward(x, y, NULL, H, W, 3);
            optim_dssim_forward(ws, x, y, NULL, H, W, 3);
            optim_l1_backward(g, 0.8f, x, y, NULL, H, W, 3);
            optim_ssim_backward(ws, g, -0.2f, x, y, NULL, H, W, 3);
            double t1 = pg_time_seconds();
            optim_ssi_depth fit;
            optim_ssi_depth_forward(&fit, dp, dt, NULL, (long)np1);
            optim_ssi_depth_backward(gd, 0.1f, &fit, dp, dt, NULL, (long)np1);
            double t2 = pg_time_seconds();
            if (r >= 0) { ts[r] = (t1 - t0) * 1e3; td[r] = (t2 - t1) * 1e3; }
        }
        qsort(ts, reps, sizeof(double), pg_cmp_double);
        qsort(td, reps, sizeof(double), pg_cmp_double);
        printf("{\"bench\":\"loss\",\"width\":%d,\"height\":%d,\"threads\":%d,\"l1_dssim_ms\":%.2f,"
               "\"l1_dssim_min_ms\":%.2f,\"ssi_depth_ms\":%.2f}\n", W, H, threads, ts[reps / 2], ts[0], td[reps / 2]);
    }
    optim_ssim_destroy(ws);
    free(x); free(y); free(g); free(dp); free(dt); free(gd); free(ts); free(td);
    return st ? cli_fail(st) : 0;
}
