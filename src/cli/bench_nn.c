/* bench_nn.c - `prodygs bench nn --model FILE`: time of one forward pass of an ONNX (or TFLite)
 * model on a seeded random input; one JSON line with the median over --reps after a warm-up.
 * cpu_ms_per_frame is the process CPU time per frame (all threads): on a machine shared with other
 * jobs it shows the work done when the wall clock is stretched (OpenMP spin-waits count in it
 * unless OMP_WAIT_POLICY=passive). */
#include "cli/cli.h"
#include "core/parallel.h"
#include "core/rng.h"
#include "nn/nn.h"
#include "nn/nn_ops.h"

#include <stdio.h>
#include <stdlib.h>
#include <sys/resource.h>
#include <sys/stat.h>

int bench_nn(int argc, char **argv)
{
    const char *model_path = NULL, *shape_text = NULL;
    int threads = 2, reps = 5, profile = 0;
    const cli_option opts[] = {
        { "--model", CLI_STR, &model_path, "model file (.onnx) (required)" },
        { "--threads", CLI_INT, &threads, "threads (default 2)" },
        { "--reps", CLI_INT, &reps, "timed repetitions (default 5)" },
        { "--profile", CLI_FLAG, &profile, "add the time per op kind (ms per frame) to the JSON" },
        { "--shape", CLI_STR, &shape_text, "input shape for a model with dynamic axes, e.g. 1x3x392x518" },
    };
    cli_spec spec = { "prodygs bench nn", "--model FILE [options]", "time one forward pass of a network", opts,
                      (int)(sizeof(opts) / sizeof(opts[0])), 0, 0 };
    int np = 0;
    int rc = cli_parse(&spec, argc, argv, NULL, &np);
    if (rc) return rc < 0 ? 0 : rc;
    if (!model_path) return cli_usage_error("bench nn: --model FILE is required");
    if (threads < 1 || threads > 1024 || reps < 1 || reps > 10000) return cli_usage_error("bench nn: bad --threads/--reps");
    int64_t bind[NN_MAX_DIMS];
    int nbind = 0;
    if (shape_text) {
        const char *p = shape_text;
        while (*p && nbind < NN_MAX_DIMS) {
            char *end;
            long long v = strtoll(p, &end, 10);
            if (end == p || v < 1 || v > (1 << 24)) return cli_usage_error("bench nn: bad --shape '%s' (e.g. 1x3x392x518)", shape_text);
            bind[nbind++] = v;
            p = *end == 'x' ? end + 1 : end;
            if (*end && *end != 'x') return cli_usage_error("bench nn: bad --shape '%s' (e.g. 1x3x392x518)", shape_text);
        }
        if (*p) return cli_usage_error("bench nn: --shape has more than %d dims", NN_MAX_DIMS);
    }
    struct stat sb;
    if (stat(model_path, &sb) != 0) return cli_fail(pg_fail(PG_ERR_IO, "%s: cannot open", model_path));
    double t0 = pg_time_seconds();
    nn_model *m;
    pg_status st = nn_model_load_shaped(model_path, nbind, bind, &m);
    if (st) return cli_fail(st);
    double load_ms = (pg_time_seconds() - t0) * 1e3;
    int64_t di[NN_MAX_DIMS], dout[NN_MAX_DIMS];
    int ni = nn_model_input_shape(m, di), no = nn_model_output_shape(m, dout);
    size_t nx = (size_t)nn_shape_count(ni, di), ny = (size_t)nn_shape_count(no, dout);
    float *x = malloc((nx ? nx : 1) * sizeof(float)), *y = malloc((ny ? ny : 1) * sizeof(float));
    double *ms = malloc((size_t)reps * sizeof(double));
    if (!x || !y || !ms) st = pg_fail(PG_ERR_NOMEM, "bench nn: out of memory");
    double prof[NN_OP_COUNT] = { 0 }, cpu0 = 0, cpu_ms = 0;
    if (!st && profile) nn_model_graph(m)->profile_ms = prof;
    if (!st) {
        pg_rng rng;
        pg_rng_seed(&rng, 1);
        for (size_t i = 0; i < nx; i++) x[i] = (float)pg_rng_normal(&rng);
        for (int r = -1; r < reps && !st; r++) {
            if (r == 0) cpu0 = pg_cpu_seconds();
            double a = pg_time_seconds();
            st = nn_model_run(m, x, y, threads);
            if (r >= 0) ms[r] = (pg_time_seconds() - a) * 1e3;
        }
        cpu_ms = (pg_cpu_seconds() - cpu0) * 1e3 / reps;
    }
    if (!st) {
        double med = pg_median(ms, reps), min = ms[0]; /* pg_median sorted ms */
        struct rusage ru;
        getrusage(RUSAGE_SELF, &ru);
        char shape[128];
        int at = 0;
        for (int i = 0; i < ni && at < (int)sizeof shape - 24; i++) at += snprintf(shape + at, sizeof shape - (size_t)at, "%s%lld", i ? "x" : "", (long long)di[i]);
        if (ni == 0) shape[0] = 0;
        printf("{\"bench\":\"nn\",\"model\":\"%s\",\"model_bytes\":%lld,\"input\":\"%s\",\"threads\":%d,\"omp_wait_policy\":\"%s\",\"blas_core\":\"%s\",\"gemm\":\"%s\",\"reps\":%d,"
               "\"ms_per_frame\":%.1f,\"min_ms\":%.1f,\"cpu_ms_per_frame\":%.1f,\"load_ms\":%.1f,\"runtime_bytes\":%zu,\"peak_memory_bytes\":%lld",
               model_path, (long long)sb.st_size, shape, threads, getenv("OMP_WAIT_POLICY") ? getenv("OMP_WAIT_POLICY") : "default", cli_blas_core(), nn_conv_kernel(), reps, med, min, cpu_ms, load_ms, nn_model_memory_bytes(m),
               (long long)ru.ru_maxrss * 1024);
        if (profile) {
            printf(",\"profile_ms\":{");
            int first = 1;
            for (int k = 0; k < NN_OP_COUNT; k++)
                if (prof[k] > 0) { printf("%s\"%s\":%.1f", first ? "" : ",", nn_op_name((nn_op)k), prof[k] / (reps + 1)); first = 0; }
            printf("}");
        }
        printf("}\n");
    }
    free(x); free(y); free(ms);
    nn_model_destroy(m);
    return st ? cli_fail(st) : 0;
}
