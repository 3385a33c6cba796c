/* test_nn_kernels.c - the runtime's kernels through hand-built graphs (no torch needed): Conv
 * (NCHW and NHWC, groups, depthwise, dilation, stride, pads, fused ReLU) against the scalar
 * reference nn_conv_reference; ConvTranspose and Resize in NHWC against NCHW; MatMul with the
 * fused bias / trans_b / Relu against a naive loop; the AVX-512 GEMM of convolutions against
 * OpenBLAS. Prints the largest difference of each. */
#include "testlib.h"
#include "core/rng.h"
#include "nn/nn.h"
#include "nn/nn_ops.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static pg_rng rng;

static float *randv(size_t n)
{
    float *v = malloc(n * sizeof(float));
    for (size_t i = 0; i < n; i++) v[i] = (float)pg_rng_normal(&rng);
    return v;
}

static double max_diff(const float *a, const float *b, size_t n)
{
    double m = 0;
    for (size_t i = 0; i < n; i++) m = fmax(m, fabs((double)a[i] - b[i]));
    return m;
}

/* (N,C,H,W) <-> (N,H,W,C) */
static void to_nhwc(float *dst, const float *src, int N, int C, int H, int W)
{
    for (int n = 0; n < N; n++) for (int c = 0; c < C; c++) for (int y = 0; y < H; y++) for (int x = 0; x < W; x++)
        dst[(((size_t)n * H + y) * W + x) * C + c] = src[(((size_t)n * C + c) * H + y) * W + x];
}

/* Runs a one-node graph: input x (dims), constants w (wdims) and b (bdims, optional). */
static pg_status run_node(nn_op op, const nn_attrs *a, const float *x, int xnd, const int64_t *xd, const float *w, int wnd,
                          const int64_t *wd, const float *b, int bnd, const int64_t *bd, float **y, size_t *ny)
{
    nn_graph g;
    nn_graph_init(&g);
    int ix, iw = -1, ib = -1, iy;
    PG_TRY(nn_graph_add_tensor(&g, "x", NN_F32, xnd, xd, &ix));
    if (w) PG_TRY(nn_graph_add_const_f32(&g, "w", wnd, wd, w, &iw));
    if (b) PG_TRY(nn_graph_add_const_f32(&g, "b", bnd, bd, b, &ib));
    PG_TRY(nn_graph_add_tensor(&g, "y", NN_F32, -1, NULL, &iy));
    int in[3] = { ix, iw, ib };
    PG_TRY(nn_graph_add_node(&g, op, "node", in, w ? (b || op == NN_OP_CONV || op == NN_OP_CONV_TRANSPOSE ? 3 : 2) : 1, &iy, 1, a, NULL));
    PG_TRY(nn_graph_set_io(&g, &ix, 1, &iy, 1));
    pg_status st = nn_graph_prepare(&g);
    if (!st) {
        memcpy(nn_graph_data(&g, ix), x, (size_t)nn_shape_count(xnd, xd) * sizeof(float));
        st = nn_graph_run(&g, 2);
    }
    if (!st) {
        const nn_tensor *t = &g.tensors[iy];
        *ny = (size_t)nn_shape_count(t->ndim, t->dims);
        *y = malloc(*ny * sizeof(float));
        memcpy(*y, nn_graph_data(&g, iy), *ny * sizeof(float));
    }
    nn_graph_destroy(&g);
    return st;
}

static void test_conv(int N, int C, int H, int W, int O, int k, int stride, int pad, int dil, int group, int relu)
{
    nn_attrs a;
    nn_attrs_default(&a);
    a.kernel[0] = a.kernel[1] = k;
    a.stride[0] = a.stride[1] = stride;
    a.dilation[0] = a.dilation[1] = dil;
    a.pads[0] = a.pads[1] = a.pads[2] = a.pads[3] = pad;
    a.group = group;
    if (relu) a.act = NN_ACT_RELU;
    int OH = (H + 2 * pad - dil * (k - 1) - 1) / stride + 1, OW = (W + 2 * pad - dil * (k - 1) - 1) / stride + 1;
    size_t nx = (size_t)N * C * H * W, nw = (size_t)O * (C / group) * k * k, ny = (size_t)N * O * OH * OW;
    float *x = randv(nx), *w = randv(nw), *b = randv((size_t)O), *ref = malloc(ny * sizeof(float));
    nn_conv_reference(ref, x, w, b, N, C, H, W, O, OH, OW, &a);
    if (relu) for (size_t i = 0; i < ny; i++) ref[i] = ref[i] > 0 ? ref[i] : 0;
    float *y = NULL, *y2 = NULL, *xh = malloc(nx * sizeof(float)), *refh = malloc(ny * sizeof(float));
    size_t n1 = 0, n2 = 0;
    CHECK_OK(run_node(NN_OP_CONV, &a, x, 4, (int64_t[]){ N, C, H, W }, w, 4, (int64_t[]){ O, C / group, k, k }, b, 1,
                      (int64_t[]){ O }, &y, &n1));
    to_nhwc(xh, x, N, C, H, W);
    to_nhwc(refh, ref, N, O, OH, OW);
    a.layout = NN_LAYOUT_NHWC;
    nn_conv_force_f32(1);
    CHECK_OK(run_node(NN_OP_CONV, &a, xh, 4, (int64_t[]){ N, H, W, C }, w, 4, (int64_t[]){ O, C / group, k, k }, b, 1,
                      (int64_t[]){ O }, &y2, &n2));
    nn_conv_force_f32(0);
    double d1 = y && n1 == ny ? max_diff(y, ref, ny) : 1e9, d2 = y2 && n2 == ny ? max_diff(y2, refh, ny) : 1e9;
    printf("  conv N%d C%d %dx%d O%d k%d s%d p%d d%d g%d%s: NCHW %.2g, NHWC %.2g", N, C, H, W, O, k, stride, pad, dil,
           group, relu ? " relu" : "", d1, d2);
    double big = 1;
    for (size_t i = 0; i < ny; i++) big = fmax(big, fabs(ref[i]));
    CHECK(d1 < 1e-5 * big && d2 < 1e-5 * big, "conv vs reference: %g %g (max |y| %g)", d1, d2, big);
    /* the bf16 product (8 mantissa bits per operand, f32 sums): a fraction of a percent of the
     * largest output; a wrong layout or padding would be off by the output's own size */
    float *y3 = NULL;
    size_t n3 = 0;
    if (group == 1 && nn_conv_bf16()) {
        CHECK_OK(run_node(NN_OP_CONV, &a, xh, 4, (int64_t[]){ N, H, W, C }, w, 4, (int64_t[]){ O, C / group, k, k }, b, 1,
                          (int64_t[]){ O }, &y3, &n3));
        double d3 = y3 && n3 == ny ? max_diff(y3, refh, ny) : 1e9;
        printf(", NHWC %s %.2g", nn_conv_kernel(), d3);
        CHECK(d3 < 1e-2 * big && d3 > 0, "bf16 conv vs reference: %g (max |y| %g)", d3, big);
    }
    printf("\n");
    free(x); free(w); free(b); free(ref); free(y); free(y2); free(y3); free(xh); free(refh);
}

/* ConvTranspose and Resize: NHWC result = NCHW result transposed. */
static void test_nhwc_twins(void)
{
    int N = 2, C = 4, H = 5, W = 6, O = 6, k = 3, G = 2;
    nn_attrs a;
    nn_attrs_default(&a);
    a.stride[0] = a.stride[1] = 2;
    a.pads[0] = a.pads[1] = a.pads[2] = a.pads[3] = 1;
    a.output_padding[0] = a.output_padding[1] = 1;
    a.group = G;
    size_t nx = (size_t)N * C * H * W;
    float *x = randv(nx), *w = randv((size_t)C * (O / G) * k * k), *b = randv((size_t)O), *xh = malloc(nx * sizeof(float));
    to_nhwc(xh, x, N, C, H, W);
    float *y = NULL, *yh = NULL;
    size_t ny = 0, nyh = 0;
    CHECK_OK(run_node(NN_OP_CONV_TRANSPOSE, &a, x, 4, (int64_t[]){ N, C, H, W }, w, 4, (int64_t[]){ C, O / G, k, k }, b, 1,
                      (int64_t[]){ O }, &y, &ny));
    a.layout = NN_LAYOUT_NHWC;
    CHECK_OK(run_node(NN_OP_CONV_TRANSPOSE, &a, xh, 4, (int64_t[]){ N, H, W, C }, w, 4, (int64_t[]){ C, O / G, k, k }, b, 1,
                      (int64_t[]){ O }, &yh, &nyh));
    int OH = (H - 1) * 2 - 2 + k + 1, OW = (W - 1) * 2 - 2 + k + 1;
    CHECK(ny == (size_t)N * O * OH * OW && nyh == ny, "conv transpose sizes %zu %zu", ny, nyh);
    if (y && yh && ny == nyh && ny == (size_t)N * O * OH * OW) {
        float *t = malloc(ny * sizeof(float));
        to_nhwc(t, y, N, O, OH, OW);
        double d = max_diff(t, yh, ny);
        printf("  conv transpose NHWC vs NCHW: %.2g\n", d);
        CHECK(d < 1e-5, "conv transpose NHWC differs by %g", d);
        free(t);
    }
    free(y); free(yh);
    for (int mode = 0; mode < 2; mode++) {
        nn_attrs r;
        nn_attrs_default(&r);
        r.resize_mode = mode ? NN_RESIZE_LINEAR : NN_RESIZE_NEAREST;
        r.coord_mode = mode ? NN_COORD_ALIGN_CORNERS : NN_COORD_ASYMMETRIC;
        r.out_h = 11;
        r.out_w = 8;
        y = yh = NULL;
        CHECK_OK(run_node(NN_OP_RESIZE, &r, x, 4, (int64_t[]){ N, C, H, W }, NULL, 0, NULL, NULL, 0, NULL, &y, &ny));
        r.layout = NN_LAYOUT_NHWC;
        CHECK_OK(run_node(NN_OP_RESIZE, &r, xh, 4, (int64_t[]){ N, H, W, C }, NULL, 0, NULL, NULL, 0, NULL, &yh, &nyh));
        if (y && yh && ny == nyh) {
            float *t = malloc(ny * sizeof(float));
            to_nhwc(t, y, N, C, 11, 8);
            double d = max_diff(t, yh, ny);
            printf("  resize %s NHWC vs NCHW: %.2g\n", mode ? "bilinear" : "nearest", d);
            CHECK(d < 1e-6, "resize NHWC differs by %g", d);
            free(t);
        }
        free(y); free(yh);
    }
    free(x); free(w); free(b); free(xh);
}

/* MatMul + bias + Relu fused from separate nodes, b read transposed, against a naive loop. */
static void test_matmul_fused(void)
{
    int B = 3, M = 37, K = 29, N = 23;
    float *a = randv((size_t)B * M * K), *bt = randv((size_t)N * K), *bias = randv((size_t)N);
    nn_graph g;
    nn_graph_init(&g);
    int ia, ib, ibias, it, im, iadd, iy;
    CHECK_OK(nn_graph_add_tensor(&g, "a", NN_F32, 3, (int64_t[]){ B, M, K }, &ia));
    CHECK_OK(nn_graph_add_const_f32(&g, "bt", 2, (int64_t[]){ N, K }, bt, &ib));
    CHECK_OK(nn_graph_add_const_f32(&g, "bias", 1, (int64_t[]){ N }, bias, &ibias));
    CHECK_OK(nn_graph_add_tensor(&g, "t", NN_F32, -1, NULL, &it));
    CHECK_OK(nn_graph_add_tensor(&g, "m", NN_F32, -1, NULL, &im));
    CHECK_OK(nn_graph_add_tensor(&g, "add", NN_F32, -1, NULL, &iadd));
    CHECK_OK(nn_graph_add_tensor(&g, "y", NN_F32, -1, NULL, &iy));
    /* the transpose of a constant folds; feed it through an input-dependent transpose instead */
    nn_attrs tr;
    nn_attrs_default(&tr);
    CHECK_OK(nn_graph_add_node(&g, NN_OP_TRANSPOSE, "tr", &ib, 1, &it, 1, &tr, NULL));
    CHECK_OK(nn_graph_add_node(&g, NN_OP_MATMUL, "mm", (int[]){ ia, it }, 2, &im, 1, NULL, NULL));
    CHECK_OK(nn_graph_add_node(&g, NN_OP_ADD, "add", (int[]){ ibias, im }, 2, &iadd, 1, NULL, NULL));
    CHECK_OK(nn_graph_add_node(&g, NN_OP_RELU, "relu", &iadd, 1, &iy, 1, NULL, NULL));
    CHECK_OK(nn_graph_set_io(&g, &ia, 1, &iy, 1));
    CHECK_OK(nn_graph_prepare(&g));
    if (g.prepared) {
        memcpy(nn_graph_data(&g, ia), a, (size_t)B * M * K * sizeof(float));
        CHECK_OK(nn_graph_run(&g, 2));
        const float *y = nn_graph_data(&g, iy);
        double d = 0;
        for (int p = 0; p < B; p++)
            for (int i = 0; i < M; i++)
                for (int j = 0; j < N; j++) {
                    double s = bias[j];
                    for (int k = 0; k < K; k++) s += (double)a[((size_t)p * M + i) * K + k] * bt[(size_t)j * K + k];
                    d = fmax(d, fabs((s > 0 ? s : 0) - y[((size_t)p * M + i) * N + j]));
                }
        printf("  matmul (folded transpose) + bias + relu, %d nodes after fusion: %.2g\n", g.num_nodes, d);
        CHECK(d < 1e-4, "fused matmul differs by %g", d);
        CHECK(g.num_nodes == 1, "%d nodes left after folding and fusion (1 expected)", g.num_nodes);
    }
    nn_graph_destroy(&g);
    free(a); free(bt); free(bias);
}

/* nn_sgemm1's A * B^T products on the AVX-512 kernel against OpenBLAS (forced), on shapes with
 * ragged edges (M not a multiple of 8, N not of 16, leading dimensions wider than the operands):
 * the same sums in another order, so agreement to float rounding. Skips on a CPU without AVX-512. */
static void test_gemm_kernels(void)
{
    if (strcmp(nn_gemm_kernel(), "avx512") != 0) {
        printf("  gemm: this CPU runs OpenBLAS only (no AVX-512F): skipped\n");
        return;
    }
    const int shapes[][3] = { { 1, 1, 1 }, { 7, 5, 3 }, { 37, 23, 29 }, { 64, 48, 27 }, { 129, 50, 1152 }, { 9, 113, 64 } };
    for (size_t s = 0; s < sizeof shapes / sizeof shapes[0]; s++) {
        const int M = shapes[s][0], N = shapes[s][1], K = shapes[s][2], lda = K + 3, ldb = K + 1, ldc = N + 5;
        float *a = randv((size_t)M * lda), *b = randv((size_t)N * ldb);
        float *c_own = malloc((size_t)M * ldc * sizeof(float)), *c_blas = malloc((size_t)M * ldc * sizeof(float));
        for (size_t i = 0; i < (size_t)M * ldc; i++) c_own[i] = c_blas[i] = 7.0f; /* the gaps must stay */
        nn_sgemm1(0, 1, M, N, K, a, lda, b, ldb, 0.0f, c_own, ldc);
        nn_gemm_force_openblas(1);
        nn_sgemm1(0, 1, M, N, K, a, lda, b, ldb, 0.0f, c_blas, ldc);
        nn_gemm_force_openblas(0);
        double d = max_diff(c_own, c_blas, (size_t)M * ldc), scale = sqrt((double)K);
        int gaps = 1;
        for (int i = 0; i < M; i++)
            for (int j = N; j < ldc; j++) gaps &= c_own[(size_t)i * ldc + j] == 7.0f;
        printf("  gemm %dx%dx%d avx512 vs openblas: %.2g\n", M, N, K, d);
        CHECK(d < 1e-5 * scale * 4, "gemm %dx%dx%d: avx512 and openblas differ by %g", M, N, K, d);
        CHECK(gaps, "gemm %dx%dx%d wrote outside its %d columns", M, N, K, N);
        free(a); free(b); free(c_own); free(c_blas);
    }
}

/* The vectorisable exp and erf against libm (their scalar references). */
static void test_exp_erf(void)
{
    double worst_exp = 0, worst_erf = 0, worst_erf_rel = 0;
    for (int i = 0; i <= 2000000; i++) {
        float x = -87.0f + 175.0f * (float)i / 2000000.0f;
        double e = exp((double)x);
        worst_exp = fmax(worst_exp, fabs(nn_exp(x) - e) / e);
        float z = -6.0f + 12.0f * (float)i / 2000000.0f;
        worst_erf = fmax(worst_erf, fabs(nn_erf(z) - erf((double)z)));
        float w = 0.5f * (float)i / 2000000.0f + 1e-6f;
        worst_erf_rel = fmax(worst_erf_rel, fabs(nn_erf(w) - erf((double)w)) / erf((double)w));
    }
    printf("  nn_exp on [-87, 88]: max rel error %.3g; nn_erf on [-6, 6]: max abs error %.3g, on (0, 0.5]: max rel error %.3g\n",
           worst_exp, worst_erf, worst_erf_rel);
    CHECK(worst_erf_rel < 1e-6, "nn_erf relative error near 0: %g", worst_erf_rel);
    CHECK(worst_exp < 5e-7, "nn_exp relative error %g", worst_exp);
    CHECK(worst_erf < 4e-7, "nn_erf absolute error %g", worst_erf);
    CHECK(isnan(nn_exp(NAN)) && nn_exp(-1000.0f) >= 0 && nn_exp(-1000.0f) < 1e-37f, "nn_exp edge cases");
}

/* The CLI runs OpenBLAS's kernels for this CPU: Debian 12's OpenBLAS took a CPU newer than itself
 * for an SSE3 "Prescott" (3.6x slower depth network); with AVX2 + FMA the version line must name
 * a current core, and a user's OPENBLAS_CORETYPE is kept (no re-run loop either way). */
static void blas_core_of_cli(const char *env, char *core, size_t size)
{
    char cmd[4200], line[1024] = "";
    snprintf(cmd, sizeof cmd, "%s '%s' --version", env, PG_CLI_PATH);
    FILE *p = popen(cmd, "r");
    if (p && !fgets(line, sizeof line, p)) line[0] = '\0';
    if (p) pclose(p);
    const char *at = strstr(line, "OpenBLAS ");
    snprintf(core, size, "%s", at ? at + 9 : "?");
    core[strcspn(core, ";,) \n")] = '\0';
}

static void test_blas_core(void)
{
    char core[64];
    blas_core_of_cli("env -u OPENBLAS_CORETYPE", core, sizeof core);
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma"))
        CHECK(strcmp(core, "Haswell") == 0 || strcmp(core, "SkylakeX") == 0 || strcmp(core, "Cooperlake") == 0 ||
                  strcmp(core, "SapphireRapids") == 0 || strcmp(core, "Zen") == 0,
              "CLI runs OpenBLAS core '%s' on a CPU with AVX2 + FMA", core);
    blas_core_of_cli("OPENBLAS_CORETYPE=Prescott", core, sizeof core);
    CHECK(strcmp(core, "Prescott") == 0, "the user's OPENBLAS_CORETYPE=Prescott gave core '%s'", core);
    printf("OpenBLAS core of the CLI: ok\n");
}

int main(void)
{
    pg_rng_seed(&rng, 5);
    test_blas_core();
    test_exp_erf();
    test_gemm_kernels();
    test_conv(1, 3, 17, 13, 8, 3, 1, 1, 1, 1, 0);
    test_conv(2, 8, 15, 18, 12, 3, 2, 2, 2, 4, 1);
    test_conv(1, 3, 56, 42, 16, 14, 14, 0, 1, 1, 0);
    test_conv(1, 6, 9, 11, 6, 5, 1, 2, 1, 6, 0);
    test_conv(2, 24, 13, 11, 24, 3, 2, 1, 2, 24, 1); /* depthwise, strided, dilated, relu (ops_conv_depthwise.c in NHWC) */
    test_conv(1, 16, 7, 9, 8, 1, 1, 0, 1, 1, 1);
    test_conv(1, 64, 40, 36, 32, 3, 1, 1, 1, 1, 1);
    test_nhwc_twins();
    test_matmul_fused();
    return test_summary("test_nn_kernels");
}
