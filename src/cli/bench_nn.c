/* bench_nn.c - `prodygs bench nn --model FILE`: time of one forward pass of a TFLite or ONNX
 * model on the nn runtime.
 *
 * The input is a smooth pattern in [0, 1] of the model's first input shape; one warm-up run, then
 * --reps timed runs on --threads threads. Prints one JSON line: median wall and process-CPU
 * seconds per run, the load, the memory the model holds and the input shape. (Added on nn-tflite
 * for the PyDNet++ speed check; the ONNX branch may extend it.)
 */
#include "cli/cli.h"
#include "core/parallel.h"
#include "nn/nn.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int bench_nn(int argc, char **argv)
{
    const char *model_path = NULL;
    int reps = 10, threads = 2;
    const cli_option opts[] = {
        { "--model", CLI_STR, &model_path, "model file: .tflite or .onnx (required)" },
        { "--threads", CLI_INT, &threads, "threads (default 2)" },
        { "--reps", CLI_INT, &reps, "timed repetitions (default 10)" },
    };
    cli_spec spec = { "prodygs bench nn", "--model FILE [options]", "time one forward pass of a model on the nn runtime", opts,
                      (int)(sizeof(opts) / sizeof(opts[0])), 0, 0 };
    int np = 0;
    int rc = cli_parse(&spec, argc, argv, NULL, &np);
    if (rc) return rc < 0 ? 0 : rc;
    if (!model_path) return cli_usage_error("bench nn: --model FILE is required");
    if (reps < 1 || reps > 1000) return cli_usage_error("bench nn: --reps must be in 1..1000");
    if (threads < 1 || threads > 256) return cli_usage_error("bench nn: --threads must be in 1..256");
    double tl0 = pg_time_seconds();
    nn_model *m;
    pg_status st = nn_model_load(model_path, &m);
    if (st) return cli_fail(st);
    double load_s = pg_time_seconds() - tl0;
    int64_t din[NN_MAX_DIMS], dout[NN_MAX_DIMS];
    int ni = nn_model_input_shape(m, din), no = nn_model_output_shape(m, dout);
    size_t nin = (size_t)nn_shape_count(ni, din), nout = (size_t)nn_shape_count(no, dout);
    float *x = malloc(nin * sizeof(float)), *y = malloc((nout ? nout : 1) * sizeof(float));
    double *wall = malloc(sizeof(double) * reps), *cpu = malloc(sizeof(double) * reps);
    if (!x || !y || !wall || !cpu) st = pg_fail(PG_ERR_NOMEM, "bench nn: out of memory");
    for (size_t i = 0; !st && i < nin; i++) x[i] = 0.5f + 0.4f * sinf(0.013f * (float)i) * cosf(0.0007f * (float)i);
    if (!st) st = nn_model_run(m, x, y, threads); /* warm-up: scratch allocation, page faults */
    for (int r = 0; r < reps && !st; r++) {
        double t0 = pg_time_seconds(), c0 = pg_cpu_seconds();
        st = nn_model_run(m, x, y, threads);
        wall[r] = pg_time_seconds() - t0;
        cpu[r] = pg_cpu_seconds() - c0;
    }
    if (!st) {
        char shape[128] = "";
        for (int i = 0; i < ni; i++) {
            size_t n = strlen(shape);
            snprintf(shape + n, sizeof shape - n, "%s%lld", i ? "x" : "", (long long)din[i]);
        }
        double best = wall[0];
        for (int r = 1; r < reps; r++) best = wall[r] < best ? wall[r] : best;
        double loadavg = 0;
        FILE *f = fopen("/proc/loadavg", "r");
        if (f) {
            if (fscanf(f, "%lf", &loadavg) != 1) loadavg = 0;
            fclose(f);
        }
        printf("{\"bench\": \"nn\", \"model\": \"%s\", \"input\": \"%s\", \"threads\": %d, \"reps\": %d, \"load_s\": %.3f, "
               "\"median_ms\": %.1f, \"best_ms\": %.1f, \"median_cpu_ms\": %.1f, \"memory_mib\": %.1f, \"loadavg\": %.2f}\n",
               model_path, shape, threads, reps, load_s, 1e3 * pg_median(wall, reps), 1e3 * best, 1e3 * pg_median(cpu, reps),
               nn_model_memory_bytes(m) / 1048576.0, loadavg);
    }
    free(x);
    free(y);
    free(wall);
    free(cpu);
    nn_model_destroy(m);
    return st ? cli_fail(st) : 0;
}
