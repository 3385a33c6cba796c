/* test_nn_onnx.c - the ONNX front end + runtime against torch: every op in isolation and a
 * Depth-Anything-V2-small-shaped network (ViT-S/14 + DPT head, seeded random weights) on three
 * images. tests/nn/make_onnx_models.py exports the models with torch.onnx (opset 17) and saves
 * torch's outputs; this test runs /usr/bin/python3 on it and skips (exit 77) without torch.
 *
 * Relative error = max |ours - torch| / max |torch| over the whole output tensor; limit 1e-4.
 * The error against the output's range (max - min) is printed too.
 */
#include "testlib.h"
#include "io/npy.h"
#include "nn/nn.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#define SKIP 77
#define REL_LIMIT 1e-4

static double rel_error(const float *a, const float *b, size_t n)
{
    double num = 0, den = 0;
    for (size_t i = 0; i < n; i++) {
        double d = fabs((double)a[i] - b[i]);
        if (d > num || isnan(d)) num = d;
        if (fabs(b[i]) > den) den = fabs(b[i]);
    }
    return den > 0 ? num / den : num;
}

/* Loads dir/model, runs it on in.npy, returns the relative error against out.npy (or -1). */
static double run_case(const char *dir, const char *model, const char *in, const char *out, nn_model **cache)
{
    char path[1024];
    nn_model *m = cache ? *cache : NULL;
    if (!m) {
        snprintf(path, sizeof path, "%s/%s", dir, model);
        pg_status st;
        if (strncmp(model, "dyn_", 4) == 0) {
            /* exported with dynamic axes: bind the input shape to the saved input's */
            char in_path[1024];
            pg_array xi;
            snprintf(in_path, sizeof in_path, "%s/%s", dir, in);
            CHECK_OK(io_npy_load(in_path, &xi));
            int64_t d[NN_MAX_DIMS];
            for (int i = 0; i < xi.ndim; i++) d[i] = (int64_t)xi.shape[i];
            st = nn_model_load_shaped(path, xi.ndim, d, &m);
            pg_array_destroy(&xi);
        } else st = nn_model_load(path, &m);
        CHECK(st == PG_OK, "%s: %s", model, st ? pg_last_error() : "");
        if (st) return -1;
        if (cache) *cache = m;
    }
    pg_array x, y;
    snprintf(path, sizeof path, "%s/%s", dir, in);
    CHECK_OK(io_npy_load(path, &x));
    snprintf(path, sizeof path, "%s/%s", dir, out);
    CHECK_OK(io_npy_load(path, &y));
    int64_t di[NN_MAX_DIMS], dout[NN_MAX_DIMS];
    int ni = nn_model_input_shape(m, di), no = nn_model_output_shape(m, dout);
    double err = -1;
    if ((size_t)nn_shape_count(ni, di) == x.count && (size_t)nn_shape_count(no, dout) == y.count) {
        float *res = malloc(y.count * sizeof(float));
        pg_status st = nn_model_run(m, x.data, res, 2);
        CHECK(st == PG_OK, "%s: run: %s", model, st ? pg_last_error() : "");
        if (!st) {
            err = rel_error(res, y.data, y.count);
            /* also against the output's range, stricter when the output is mostly an offset */
            float lo = INFINITY, hi = -INFINITY;
            double num = 0;
            for (size_t i = 0; i < y.count; i++) {
                lo = fminf(lo, y.data[i]);
                hi = fmaxf(hi, y.data[i]);
                num = fmax(num, fabs((double)res[i] - y.data[i]));
            }
            if (hi > lo) printf("    %s: max abs error %.3g, %.3g of the output range\n", model, num, num / (hi - lo));
            /* a test against an all-zero or constant output would prove nothing */
            CHECK(hi > lo, "%s: torch's output is constant (%g)", model, hi);
        }
        free(res);
    } else {
        CHECK(0, "%s: input/output sizes %zu/%zu do not match the model's %lld/%lld", model, x.count, y.count,
              (long long)nn_shape_count(ni, di), (long long)nn_shape_count(no, dout));
    }
    pg_array_destroy(&x);
    pg_array_destroy(&y);
    if (!cache) nn_model_destroy(m);
    return err;
}

int main(void)
{
    char dir[512], cmd[2048];
    test_tmpdir("nn_onnx", dir, sizeof dir);
    snprintf(cmd, sizeof cmd, "/usr/bin/python3 '%s/tests/nn/make_onnx_models.py' '%s' >'%s/export.log' 2>&1",
             PG_SOURCE_DIR, dir, dir);
    int rc = system(cmd);
    if (rc == -1 || !WIFEXITED(rc) || WEXITSTATUS(rc) == SKIP || access("/usr/bin/python3", X_OK) != 0) {
        printf("test_nn_onnx: SKIPPED: /usr/bin/python3 with torch and onnx is needed to export the test models (see %s/export.log)\n", dir);
        return SKIP;
    }
    CHECK(WEXITSTATUS(rc) == 0, "make_onnx_models.py failed (exit %d), see %s/export.log", WEXITSTATUS(rc), dir);
    char list[1024];
    snprintf(list, sizeof list, "%s/cases.txt", dir);
    FILE *f = fopen(list, "r");
    CHECK(f != NULL, "no %s", list);
    char name[256];
    double worst = 0;
    while (f && fscanf(f, "%255s", name) == 1) {
        char model[300], in[300], out[300];
        snprintf(model, sizeof model, "%s.onnx", name);
        snprintf(in, sizeof in, "%s_in.npy", name);
        snprintf(out, sizeof out, "%s_out.npy", name);
        double err = run_case(dir, model, in, out, NULL);
        printf("  op %-26s rel error %.3g\n", name, err);
        CHECK(err >= 0 && err <= REL_LIMIT, "%s: relative error %g > %g", name, err, REL_LIMIT);
        if (err > worst) worst = err;
    }
    if (f) fclose(f);
    printf("  ops: worst rel error %.3g\n", worst);
    nn_model *net = NULL;
    for (int i = 0; i < 3; i++) {
        char in[64], out[64];
        snprintf(in, sizeof in, "net_in%d.npy", i);
        snprintf(out, sizeof out, "net_out%d.npy", i);
        double err = run_case(dir, "net.onnx", in, out, &net);
        printf("  ViT-S/14 + DPT net (266x196) image %d: rel error %.3g\n", i, err);
        CHECK(err >= 0 && err <= REL_LIMIT, "net image %d: relative error %g > %g", i, err, REL_LIMIT);
    }
    nn_model_destroy(net);
    return test_summary("test_nn_onnx");
}
