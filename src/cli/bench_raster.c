/* bench_raster.c - `prodygs bench raster`: times the rasterizer forward and backward on the
 * random-Gaussian workload and prints one JSON line. */
#include "cli/cli.h"
#include "core/camera.h"
#include "core/parallel.h"
#include "core/rng.h"
#include "splat/random_scene.h"
#include "splat/raster.h"

#include <stdio.h>
#include <stdlib.h>
#include <time.h>

int bench_raster(int argc, char **argv)
{
    int width = 800, height = 800, n = 100000, threads = 1, sh_degree = 0, seed = 1, reps = 7, scalar = 0;
    float sigma = 2.0f;
    cli_option opts[] = {
        { "--width", CLI_INT, &width, "image width (800)" },
        { "--height", CLI_INT, &height, "image height (800)" },
        { "--gaussians", CLI_INT, &n, "number of Gaussians (100000)" },
        { "--sigma-px", CLI_FLOAT, &sigma, "mean projected standard deviation in pixels (2)" },
        { "--threads", CLI_INT, &threads, "worker threads (1)" },
        { "--sh-degree", CLI_INT, &sh_degree, "SH degree 0..3 (0)" },
        { "--seed", CLI_INT, &seed, "workload seed (1)" },
        { "--reps", CLI_INT, &reps, "timed repetitions after one warm-up, >= 5 (7)" },
        { "--scalar", CLI_FLAG, &scalar, "use the scalar reference kernels (PG_RASTER=scalar|avx2|avx512 picks any)" },
    };
    cli_spec spec = { "prodygs bench raster", "[options]",
                      "time the rasterizer forward/backward on N random Gaussians; prints one JSON line",
                      opts, (int)(sizeof(opts) / sizeof(opts[0])), 0, 0 };
    int rc = cli_parse(&spec, argc, argv, NULL, NULL);
    if (rc) return rc < 0 ? 0 : rc;
    if (width < 1 || height < 1 || width > 16384 || height > 16384)
        return cli_usage_error("bench raster: --width/--height must be in 1..16384");
    if (n < 1 || n > 50000000) return cli_usage_error("bench raster: --gaussians must be in 1..50000000");
    if (!(sigma > 0 && sigma < 1000)) return cli_usage_error("bench raster: --sigma-px must be in (0, 1000)");
    if (threads < 1 || threads > 256) return cli_usage_error("bench raster: --threads must be in 1..256");
    if (sh_degree < 0 || sh_degree > 3) return cli_usage_error("bench raster: --sh-degree must be 0..3");
    if (reps < 5 || reps > 1000) return cli_usage_error("bench raster: --reps must be in 5..1000");
    pg_set_threads(threads);

    pg_camera cam;
    pg_camera_from_fov(&cam, width, height, 60);
    pg_gaussians g = { 0 }, grad = { 0 };
    splat_raster *r = NULL;
    float *d_rgb = NULL, *d_depth = NULL;
    double *tf = calloc((size_t)reps, sizeof(double)), *tb = calloc((size_t)reps, sizeof(double));
    double *tp = calloc((size_t)reps, sizeof(double)), *cf = calloc((size_t)reps, sizeof(double));
    double *cb = calloc((size_t)reps, sizeof(double));
    pg_status st = PG_OK;
    size_t P = (size_t)width * height;
    d_rgb = malloc(P * 3 * sizeof(float));
    d_depth = malloc(P * sizeof(float));
    if (!tf || !tb || !tp || !cf || !cb || !d_rgb || !d_depth) { st = pg_fail(PG_ERR_NOMEM, "bench raster: out of memory"); goto done; }
    if ((st = splat_gaussians_create(&g, n)) || (st = splat_random_scene(&g, &cam, n, sigma, sh_degree, (unsigned)seed)))
        goto done;
    if ((st = splat_gaussians_create(&grad, n)) || (st = splat_gaussians_resize(&grad, n))) goto done;
    if ((st = splat_raster_create(&r))) goto done;
    if (scalar) splat_raster_set_kernel(r, SPLAT_KERNEL_SCALAR);
    pg_rng rng;
    pg_rng_seed(&rng, 99);
    for (size_t i = 0; i < 3 * P; i++) d_rgb[i] = (float)(pg_rng_uniform(&rng) - 0.5) / (float)P;
    for (size_t i = 0; i < P; i++) d_depth[i] = (float)(pg_rng_uniform(&rng) - 0.5) / (float)P;
    pg_render_settings s = splat_default_settings();
    s.sh_degree = sh_degree;
    pg_render_output out = { 0 };
    for (int k = -1; k < reps; k++) { /* k = -1 is the warm-up */
        double c0 = pg_cpu_seconds(), t0 = pg_time_seconds();
        if ((st = splat_render_forward(r, &g, &cam, &s, &out))) goto done;
        double t1 = pg_time_seconds(), c1 = pg_cpu_seconds();
        splat_gaussians_zero(&grad);
        double c2 = pg_cpu_seconds(), t2 = pg_time_seconds();
        if ((st = splat_render_backward(r, &g, &cam, &s, d_rgb, d_depth, NULL, &grad, NULL))) goto done;
        double t3 = pg_time_seconds(), c3 = pg_cpu_seconds();
        if (k >= 0) {
            tf[k] = (t1 - t0) * 1e3; tb[k] = (t3 - t2) * 1e3; tp[k] = out.preprocess_ms;
            cf[k] = (c1 - c0) * 1e3; cb[k] = (c3 - c2) * 1e3;
        }
    }
    printf("{\"bench\":\"raster\",\"width\":%d,\"height\":%d,\"gaussians\":%d,\"sigma_px\":%g,\"sh_degree\":%d,"
           "\"threads\":%d,\"simd\":\"%s\",\"reps\":%d,\"forward_ms\":%.3f,\"backward_ms\":%.3f,"
           "\"preprocess_ms\":%.3f,\"intersections\":%ld,\"cpu_forward_ms\":%.3f,\"cpu_backward_ms\":%.3f}\n",
           width, height, n, sigma, sh_degree, threads, splat_kernel_name(splat_raster_kernel(r)), reps, pg_median(tf, reps),
           pg_median(tb, reps), pg_median(tp, reps), out.intersections, pg_median(cf, reps), pg_median(cb, reps));
done:
    free(tf); free(tb); free(tp); free(cf); free(cb); free(d_rgb); free(d_depth);
    splat_raster_destroy(r);
    splat_gaussians_destroy(&g);
    splat_gaussians_destroy(&grad);
    return st ? cli_fail(st) : 0;
}
