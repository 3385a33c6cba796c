/* bench_flow.c - `prodygs bench flow`: time of one TV-L1 optical flow between two frames.
 *
 * A smooth colour texture and the same texture shifted by (3.4, -2.3) px; one warm-up, then
 * --reps timed runs on one thread (the depth stage runs frames in parallel, one thread each).
 * Prints one JSON line: median wall and process-CPU seconds per flow, and the end-point error.
 */
#include "cli/cli.h"
#include "core/mathx.h"
#include "core/parallel.h"
#include "depth/flow.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static void bench_texture(float x, float y, float *rgb)
{
    float a = sinf(0.21f * x + 0.13f * y) + 0.6f * sinf(0.05f * x - 0.31f * y + 1.0f) + 0.4f * sinf(0.47f * x + 0.29f * y);
    float b = sinf(0.17f * x - 0.23f * y + 2.0f) + 0.5f * sinf(0.41f * x + 0.07f * y);
    rgb[0] = 0.5f + 0.2f * a;
    rgb[1] = 0.5f + 0.2f * b;
    rgb[2] = 0.5f + 0.1f * (a - b);
}

int bench_flow(int argc, char **argv)
{
    const char *size = "320x240";
    int reps = 5;
    const cli_option opts[] = {
        { "--size", CLI_STR, &size, "frame size WxH (default 320x240)" },
        { "--reps", CLI_INT, &reps, "timed repetitions (default 5)" },
    };
    cli_spec spec = { "prodygs bench flow", "[options]", "time one TV-L1 optical flow between two frames", opts,
                      (int)(sizeof(opts) / sizeof(opts[0])), 0, 0 };
    int np = 0;
    int rc = cli_parse(&spec, argc, argv, NULL, &np);
    if (rc) return rc < 0 ? 0 : rc;
    int W = 0, H = 0;
    if ((rc = cli_parse_size("--size", size, &W, &H))) return rc;
    if (W < 16 || H < 16) return cli_usage_error("bench flow: --size '%s' needs both sides >= 16", size);
    if (reps < 1 || reps > 1000) return cli_usage_error("bench flow: --reps must be in 1..1000");
    pg_set_threads(1);
    pg_image i0, i1;
    pg_status st = pg_image_create(&i0, W, H, 3);
    if (!st) st = pg_image_create(&i1, W, H, 3);
    float *flow = malloc(sizeof(float) * 2 * W * H);
    double *wall = malloc(sizeof(double) * reps), *cpu = malloc(sizeof(double) * reps);
    if (!st && (!flow || !wall || !cpu)) st = pg_fail(PG_ERR_NOMEM, "bench flow: out of memory");
    if (st) {
        pg_image_destroy(&i0);
        pg_image_destroy(&i1);
        free(flow);
        free(wall);
        free(cpu);
        return cli_fail(st);
    }
    const float dx = 3.4f, dy = -2.3f;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            bench_texture((float)x, (float)y, pg_image_at(&i0, x, y));
            bench_texture(x - dx, y - dy, pg_image_at(&i1, x, y));
        }
    depth_flow_backend be = depth_flow_backend_default();
    st = depth_flow_compute(&be, &i0, &i1, flow); /* warm-up */
    for (int r = 0; r < reps && !st; r++) {
        double t0 = pg_time_seconds(), c0 = pg_cpu_seconds();
        st = depth_flow_compute(&be, &i0, &i1, flow);
        wall[r] = pg_time_seconds() - t0;
        cpu[r] = pg_cpu_seconds() - c0;
    }
    if (!st) {
        double epe = 0;
        long cnt = 0;
        for (int y = 8; y < H - 8; y++)
            for (int x = 8; x < W - 8; x++) {
                size_t k = (size_t)y * W + x;
                epe += hypot(flow[2 * k] - dx, flow[2 * k + 1] - dy);
                cnt++;
            }
        qsort(wall, reps, sizeof(double), pg_cmp_double);
        qsort(cpu, reps, sizeof(double), pg_cmp_double);
        printf("{\"bench\": \"flow\", \"backend\": \"%s\", \"width\": %d, \"height\": %d, \"threads\": 1, "
               "\"wall_s\": %.4f, \"cpu_s\": %.4f, \"epe_px\": %.4f}\n",
               be.name, W, H, wall[reps / 2], cpu[reps / 2], cnt ? epe / cnt : 0.0);
    }
    pg_image_destroy(&i0);
    pg_image_destroy(&i1);
    free(flow);
    free(wall);
    free(cpu);
    return st ? cli_fail(st) : 0;
}
