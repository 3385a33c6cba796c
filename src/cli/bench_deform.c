/* bench_deform.c - `prodygs bench deform`: forward/backward time of the deformation network.
 *
 * N random points inside a unit AABB, one time value, random (non-zero) head weights; prints one
 * JSON line with the medians over --reps repetitions after one warm-up.
 */
#include "cli/cli.h"
#include "deform/gemm_amx.h"
#include "core/mathx.h"
#include "core/parallel.h"
#include "core/rng.h"
#include "deform/deform.h"
#include "train/train.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

int bench_deform(int argc, char **argv)
{
    int points = 100000, threads = 1, reps = 5, chunk = 0, store = 1, sorted = 0;
    deform_config cfg;
    deform_config_default(&cfg);
    cfg.head_width = train_default_config().deform_head_width; /* the trainer's network */
    cfg.time_coarsen = train_default_config().deform_time_coarsen;
    const cli_option opts[] = {
        { "--points", CLI_INT, &points, "number of points (default 100000)" },
        { "--threads", CLI_INT, &threads, "threads (default 1)" },
        { "--reps", CLI_INT, &reps, "timed repetitions (default 5)" },
        { "--chunk", CLI_INT, &chunk, "points per chunk (default 128 with AMX, else 256)" },
        { "--store", CLI_INT, &store, "1: keep activations for the backward, 0: recompute (default 1)" },
        { "--sorted", CLI_INT, &sorted, "1: points ordered along x (spatially coherent), 0: random (default)" },
        { "--bf16", CLI_INT, &cfg.bf16, "1: Linear layers in bf16 where the CPU has AMX or AVX512-BF16 (default), 0: f32" },
        { "--channels", CLI_INT, &cfg.channels, "plane channels C (default 16)" },
        { "--res", CLI_INT, &cfg.res_space, "spatial resolution R (default 64)" },
        { "--res-time", CLI_INT, &cfg.res_time, "time resolution T (default 150)" },
        { "--width", CLI_INT, &cfg.width, "MLP width (default 64)" },
        { "--feature-layers", CLI_INT, &cfg.feature_layers, "Linear+ReLU layers before the heads (default 1)" },
        { "--head-width", CLI_INT, &cfg.head_width, "hidden width of each head (default 32, the trainer's; 0 = --width)" },
    };
    cli_spec spec = { "prodygs bench deform", "[options]", "time the deformation network forward/backward", opts,
                      (int)(sizeof(opts) / sizeof(opts[0])), 0, 0 };
    int np = 0;
    int rc = cli_parse(&spec, argc, argv, NULL, &np);
    if (rc) return rc < 0 ? 0 : rc;
    if (points < 1 || threads < 1 || reps < 1) return cli_usage_error("bench deform: --points, --threads, --reps must be >= 1");
    if (points > 20000000) return cli_usage_error("bench deform: --points must be at most 20000000 (got %d)", points);
    pg_set_threads(threads);
    cfg.head_init_scale = 1.0f;
    const float aabb[6] = { -1, -1, -1, 1, 1, 1 };
    deform_network *net = NULL;
    deform_ws *ws = NULL;
    pg_status st = deform_network_create(&net, &cfg, aabb);
    if (!st) st = deform_ws_create_chunked(&ws, net, store ? points : 0, chunk);
    float *means = malloc((size_t)points * 3 * sizeof(float));
    float *out = malloc((size_t)points * DEFORM_OUT_DIM * sizeof(float));
    float *dout = malloc((size_t)points * DEFORM_OUT_DIM * sizeof(float));
    float *dmeans = calloc((size_t)points * 3, sizeof(float));
    double *tf = malloc(reps * sizeof(double)), *tb = malloc(reps * sizeof(double));
    double cpu_f = 0, cpu_b = 0, reg_ms = 0;
    if (!st && (!means || !out || !dout || !dmeans || !tf || !tb)) st = pg_fail(PG_ERR_NOMEM, "bench deform: out of memory");
    if (!st) {
        pg_rng rng;
        pg_rng_seed(&rng, 1);
        for (long i = 0; i < (long)points * 3; i++) means[i] = (float)pg_rng_range(&rng, -1, 1);
        if (sorted) /* a coherent order: rows of a 64^3 grid, like points unprojected scanline by scanline */
            for (long i = 0; i < points; i++) {
                long cell = i * 262144L / points;
                means[3 * i + 0] = -1 + 2 * ((cell % 64) + 0.5f) / 64;
                means[3 * i + 1] = -1 + 2 * ((cell / 64 % 64) + 0.5f) / 64;
                means[3 * i + 2] = -1 + 2 * ((cell / 4096) + 0.5f) / 64;
            }
        for (long i = 0; i < (long)points * DEFORM_OUT_DIM; i++) dout[i] = (float)pg_rng_range(&rng, -1, 1);
        for (int r = -1; r < reps && !st; r++) {
            float t = (float)pg_rng_uniform(&rng);
            double c0 = pg_cpu_seconds(), t0 = pg_time_seconds();
            st = deform_network_forward(net, ws, means, NULL, points, t, out);
            double c1 = pg_cpu_seconds(), t1 = pg_time_seconds();
            if (!st) st = deform_network_backward(net, ws, dout, dmeans);
            double c2 = pg_cpu_seconds(), t2 = pg_time_seconds();
            double t3 = pg_time_seconds();
            if (!st) deform_network_regularize(net, 2e-4f, 1e-3f, 1e-4f);
            if (r >= 0) reg_ms += (pg_time_seconds() - t3) * 1e3 / reps;
            if (r >= 0) {
                cpu_f += (c1 - c0) * 1e3 / reps;
                cpu_b += (c2 - c1) * 1e3 / reps;
                tf[r] = (t1 - t0) * 1e3;
                tb[r] = (t2 - t1) * 1e3;
            }
        }
    }
    if (!st) {
        qsort(tf, reps, sizeof(double), pg_cmp_double);
        qsort(tb, reps, sizeof(double), pg_cmp_double);
        printf("{\"bench\":\"deform\",\"points\":%d,\"threads\":%d,\"forward_ms\":%.2f,\"backward_ms\":%.2f,\"forward_min_ms\":%.2f,\"backward_min_ms\":%.2f,"
               "\"forward_cpu_ms\":%.2f,\"backward_cpu_ms\":%.2f,\"regularize_ms\":%.2f,"
               "\"params\":%zu,\"channels\":%d,\"res\":%d,\"res_time\":%d,\"width\":%d,\"head_width\":%d,\"chunk\":%d,\"store\":%d,\"sorted\":%d,\"deform_kernel\":\"%s\"}\n",
               points, threads, tf[reps / 2], tb[reps / 2], tf[0], tb[0], cpu_f, cpu_b, reg_ms, net->num_params, cfg.channels, cfg.res_space,
               cfg.res_time, cfg.width, deform_head_width(&cfg), deform_ws_chunk(ws), store, sorted,
               deform_ws_uses_amx(ws) ? gemm_bf16_name(gemm_bf16_backend()) : "f32");
    }
    free(means); free(out); free(dout); free(dmeans); free(tf); free(tb);
    deform_ws_destroy(ws);
    deform_network_destroy(net);
    return st ? cli_fail(st) : 0;
}
