/* bench_iteration.c - `prodygs bench iteration`: time one fine-stage training iteration.
 *
 * Workload: one real view of W x H with 8 frames (a smooth colour pattern, a depth plane),
 * N random Gaussians inside the view frustum at depths U(2, 10), isotropic scales giving a
 * projected standard deviation of 2 U(0.3, 1.7) pixels, opacity U(0.05, 0.95), random colour,
 * seed fixed. A fraction of them can be flagged static (--static-fraction). Densification is
 * off so N stays fixed. Prints one JSON line with per-phase medians in milliseconds.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "cli/cli.h"
#include "splat/sh.h"
#include "deform/deform.h"
#include "deform/gemm_amx.h"
#include "splat/raster.h"
#include "core/parallel.h"
#include "core/rng.h"
#include "train/train.h"
#include "train/trainset.h"


/* Process CPU time in ms: on a shared machine wall time includes waiting for a core; with one
 * thread CPU time is what an idle machine would take. */
static double cpu_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

int bench_iteration(int argc, char **argv)
{
    int width = 320, height = 240, n = 100000, threads = 2, reps = 7, no_cull = 0, head_width = train_default_config().deform_head_width;
    float static_fraction = 0;
    cli_option opts[] = {
        {"--width", CLI_INT, &width, "image width (320)"},
        {"--height", CLI_INT, &height, "image height (240)"},
        {"--gaussians", CLI_INT, &n, "number of Gaussians (100000)"},
        {"--threads", CLI_INT, &threads, "worker threads (2)"},
        {"--reps", CLI_INT, &reps, "timed iterations after 2 warm-up ones (7)"},
        {"--static-fraction", CLI_FLOAT, &static_fraction, "fraction of Gaussians flagged static (0)"},
        {"--no-cull", CLI_FLAG, &no_cull, "no frustum culling before the network"},
        {"--head-width", CLI_INT, &head_width, "hidden width of each deformation head (the trainer's 32; 0 = the network width)"},
    };
    cli_spec spec = {"prodygs bench iteration", "[options]",
                     "Time one fine-stage training iteration (deformation, rasterizer, loss, optimiser).", opts,
                     (int)(sizeof opts / sizeof opts[0]), 0, 0};
    int rc = cli_parse(&spec, argc, argv, NULL, NULL);
    if (rc == -1) return 0;
    if (rc) return rc;
    if (width < 16 || height < 16 || width > 4096 || height > 4096) return cli_usage_error("bench iteration: bad size");
    if (n < 16 || n > 5000000) return cli_usage_error("bench iteration: --gaussians must be in 16..5000000");
    if (threads < 1 || threads > 256 || reps < 1 || reps > 1000) return cli_usage_error("bench iteration: bad threads/reps");
    if (!(static_fraction >= 0 && static_fraction <= 1)) return cli_usage_error("bench iteration: bad --static-fraction");
    if (head_width < 0 || head_width > 4096) return cli_usage_error("bench iteration: --head-width must be in 0..4096");
    pg_set_threads(threads);

    train_set ts;
    memset(&ts, 0, sizeof ts);
    ts.frames = 8;
    ts.width = width;
    ts.height = height;
    ts.fps = 30;
    pg_camera cam;
    pg_camera_from_fov(&cam, width, height, 60.0f);
    pg_status st = train_set_add_view(&ts, "cam00", IO_ROLE_REAL, &cam, 0, 1, NULL);
    pg_gaussians g = {0};
    uint8_t *flags = NULL;
    train_session *s = NULL;
    double *t[10] = {0};
    if (st) goto done;
    size_t px = (size_t)width * height;
    for (int f = 0; f < ts.frames; f++)
        for (size_t i = 0; i < px; i++) {
            int x = (int)(i % width), y = (int)(i / width);
            uint8_t *p = ts.views[0].rgb + ((size_t)f * px + i) * 3;
            p[0] = (uint8_t)(128 + 100 * sinf(0.05f * x + 0.3f * f));
            p[1] = (uint8_t)(128 + 100 * cosf(0.07f * y));
            p[2] = (uint8_t)((x + y + 8 * f) & 255);
            ts.views[0].depth[(size_t)f * px + i] = 5.0f;
        }
    train_config cfg = train_default_config();
    cfg.iters = 1000000;
    cfg.coarse_iters = 0;
    cfg.init_points = 1000;
    cfg.densify_from = 1 << 30;
    cfg.sh_ramp_every = 0;
    cfg.sh_max_degree = 3;
    cfg.use_frustum_cull = !no_cull;
    cfg.deform_head_width = head_width;
    cfg.coarse_iters = 1;
    if ((st = train_session_create(&s, &ts, &cfg, NULL, 0))) goto done;

    /* N random Gaussians in the frustum */
    if ((st = splat_gaussians_create(&g, n)) || (st = splat_gaussians_resize(&g, n))) goto done;
    flags = calloc((size_t)n, 1);
    if (!flags) {
        st = pg_fail(PG_ERR_NOMEM, "bench: out of memory");
        goto done;
    }
    pg_rng rng;
    pg_rng_seed(&rng, 12345);
    for (int i = 0; i < n; i++) {
        float z = (float)pg_rng_range(&rng, 2, 10);
        float u = (float)pg_rng_range(&rng, 0, width), v = (float)pg_rng_range(&rng, 0, height);
        pg_camera_unproject(&cam, u, v, z, g.means + 3 * i);
        float sigma_px = 2.0f * (float)pg_rng_range(&rng, 0.3, 1.7);
        float ls = logf(sigma_px * z / cam.fx);
        for (int k = 0; k < 3; k++) g.log_scales[3 * i + k] = ls;
        g.quats[4 * i] = 1;
        float o = (float)pg_rng_range(&rng, 0.05, 0.95);
        g.opacity[i] = logf(o / (1 - o));
        for (int k = 0; k < 3; k++) splat_gaussians_sh(&g, (size_t)i)[k] = ((float)pg_rng_uniform(&rng) - 0.5f) / SPLAT_SH_C0;
        flags[i] = pg_rng_uniform(&rng) < static_fraction;
    }
    g.sh_degree = 3;
    if ((st = train_session_set_gaussians(s, &g, flags))) goto done;
    if ((st = train_session_force_fine(s))) goto done;
    for (int k = 0; k < 10; k++) {
        t[k] = calloc((size_t)reps, sizeof(double));
        if (!t[k]) {
            st = pg_fail(PG_ERR_NOMEM, "bench: out of memory");
            goto done;
        }
    }
    int deformed = 0;
    deform_config net_cfg; /* the trainer's network: library defaults but the head width */
    deform_config_default(&net_cfg);
    net_cfg.head_width = head_width;
    for (int r = -2; r < reps; r++) {
        double t0 = pg_time_seconds(), c0 = cpu_ms();
        if ((st = train_session_step(s))) goto done;
        double total = (pg_time_seconds() - t0) * 1e3, cpu = cpu_ms() - c0;
        if (r < 0) continue;
        train_timing tm;
        train_session_timing(s, &tm);
        t[0][r] = total;
        t[1][r] = tm.deform_forward;
        t[2][r] = tm.deform_backward;
        t[3][r] = tm.raster_forward;
        t[4][r] = tm.raster_backward;
        t[5][r] = tm.loss;
        t[6][r] = tm.optimizer;
        t[7][r] = tm.other;
        t[8][r] = tm.regularize;
        t[9][r] = cpu;
        deformed = tm.deformed;
    }
    printf("{\"ms_per_iteration\": %.2f, \"cpu_ms_per_iteration\": %.2f, \"deform_forward\": %.2f, \"deform_backward\": %.2f, "
           "\"regularize\": %.2f, \"raster_forward\": %.2f, \"raster_backward\": %.2f, \"loss\": %.2f, \"optimizer\": %.2f, "
           "\"other\": %.2f, \"deformed\": %d, \"gaussians\": %d, \"width\": %d, \"height\": %d, \"threads\": %d, "
           "\"static_fraction\": %.2f, \"cull\": %s, \"deform_width\": %d, \"head_width\": %d, \"deform_kernel\": \"%s\", "
           "\"raster_kernel\": \"%s\"}\n",
           pg_median(t[0], reps), pg_median(t[9], reps), pg_median(t[1], reps), pg_median(t[2], reps), pg_median(t[8], reps), pg_median(t[3], reps), pg_median(t[4], reps),
           pg_median(t[5], reps), pg_median(t[6], reps), pg_median(t[7], reps), deformed, n, width, height, threads,
           static_fraction, no_cull ? "false" : "true", net_cfg.width, deform_head_width(&net_cfg),
           gemm_bf16_name(gemm_bf16_backend()),
           splat_kernel_name(splat_kernel_default()));
done:
    for (int k = 0; k < 10; k++) free(t[k]);
    free(flags);
    splat_gaussians_destroy(&g);
    train_session_destroy(s);
    train_set_destroy(&ts);
    return st ? cli_fail(st) : 0;
}
