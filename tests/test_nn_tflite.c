/* test_nn_tflite.c - the TFLite front end: a small model using every supported op (written by
 * tests/tflite_writer.h) run by the runtime and by the naive reference, hostile files (every
 * truncation, random corruption, lying sizes, cycles, unsupported ops), and the real PyDNet++
 * when ../shared/models has it (agreement with the reference, Spearman vs tabletop_dev depth). */
#include "testlib.h"
#include "tflite_writer.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/fileutil.h"
#include "core/parallel.h"
#include "core/rng.h"
#include "io/npy.h"
#include "io/video.h"
#include "nn/nn_ops.h"
#include "nn/nn.h"
#include "nn/tflite.h"

/* ---- the all-ops model ---- */

static int8_t w1[4 * 3 * 3 * 3];
static float b1[4], w2[1 * 3 * 3 * 8], b2[8], s_leak = 0.2f, b3[6];
static uint16_t w3h[6 * 2 * 2 * 8];
static int32_t tshape[4] = { 1, 8, 10, 6 }, sl_begin[4] = { 0, 1, 0, 2 }, sl_end[4] = { 1, 8, 10, 9 }, sl_stride[4] = { 1, 2, 3, 2 };
static int32_t rsize[2] = { 7, 9 }, pads[8] = { 0, 0, 1, 2, 0, 1, 0, 0 };

static uint16_t float_to_half(float f)
{
    /* test weights are small normal numbers: round the mantissa, no subnormals */
    uint32_t u;
    memcpy(&u, &f, 4);
    uint32_t sign = (u >> 16) & 0x8000, exp = (u >> 23) & 0xff, mant = u & 0x7fffff;
    if (exp == 0) return (uint16_t)sign;
    int e = (int)exp - 127 + 15;
    if (e <= 0) return (uint16_t)sign;
    return (uint16_t)(sign | (uint32_t)e << 10 | ((mant + 0x1000) >> 13));
}

static void fill_weights(void)
{
    pg_rng r;
    pg_rng_seed(&r, 7);
    for (size_t i = 0; i < sizeof w1; i++) w1[i] = (int8_t)(pg_rng_uniform(&r) * 254 - 127);
    for (int i = 0; i < 4; i++) b1[i] = pg_rng_uniform(&r) - 0.5f;
    for (int i = 0; i < 72; i++) w2[i] = pg_rng_uniform(&r) - 0.5f;
    for (int i = 0; i < 8; i++) b2[i] = pg_rng_uniform(&r) - 0.5f;
    for (int i = 0; i < 6 * 2 * 2 * 8; i++) w3h[i] = float_to_half(pg_rng_uniform(&r) - 0.5f);
    for (int i = 0; i < 6; i++) b3[i] = pg_rng_uniform(&r) * 2;
}

#define T4(a, b, c, d) (int[]){ a, b, c, d }
#define IN(...) (int[]){ __VA_ARGS__ }, (int)(sizeof((int[]){ __VA_ARGS__ }) / sizeof(int))

/* x (1,8,10,3) -> CONV_2D int8 s2 RELU -> DEPTHWISE x2 -> leaky (MUL+MAXIMUM) -> TRANSPOSE_CONV
 * (fp16 weights via DEQUANTIZE) -> ADD bias RELU6 -> CONCATENATION with x -> STRIDED_SLICE ->
 * RESIZE_BILINEAR -> PAD -> LEAKY_RELU; outputs the last and the resize. */
static void all_ops_model(tw_model *m)
{
    memset(m, 0, sizeof *m);
    int x = tw_tensor(m, "x", 4, T4(1, 8, 10, 3), TW_F32, NULL, 0);
    int tw1 = tw_tensor(m, "w1", 4, T4(4, 3, 3, 3), TW_I8, w1, sizeof w1);
    m->tensors[tw1].num_scales = 4;
    for (int i = 0; i < 4; i++) m->tensors[tw1].scales[i] = 0.004f * (i + 1);
    int tb1 = tw_tensor(m, "b1", 1, (int[]){ 4 }, TW_F32, b1, sizeof b1);
    int y1 = tw_tensor(m, "y1", 4, T4(1, 4, 5, 4), TW_F32, NULL, 0);
    tw_op(m, 3, IN(x, tw1, tb1), y1, 1, 4, (int32_t[]){ 0, 2, 2, 1 }, "biib");
    int tw2 = tw_tensor(m, "w2", 4, T4(1, 3, 3, 8), TW_F32, w2, sizeof w2);
    int tb2 = tw_tensor(m, "b2", 1, (int[]){ 8 }, TW_F32, b2, sizeof b2);
    int y2 = tw_tensor(m, "y2", 4, T4(1, 4, 5, 8), TW_F32, NULL, 0);
    tw_op(m, 4, IN(y1, tw2, tb2), y2, 2, 5, (int32_t[]){ 0, 1, 1, 2, 0 }, "biiib");
    int ts = tw_tensor(m, "leak", 0, NULL, TW_F32, &s_leak, 4);
    int y3 = tw_tensor(m, "y3", 4, T4(1, 4, 5, 8), TW_F32, NULL, 0);
    tw_op(m, 18, IN(ts, y2), y3, 21, 0, NULL, "");
    int y4 = tw_tensor(m, "y4", 4, T4(1, 4, 5, 8), TW_F32, NULL, 0);
    tw_op(m, 55, IN(y2, y3), y4, 0, 0, NULL, "");
    int tw3h = tw_tensor(m, "w3h", 4, T4(6, 2, 2, 8), TW_F16, w3h, sizeof w3h);
    int tw3 = tw_tensor(m, "w3", 4, T4(6, 2, 2, 8), TW_F32, NULL, 0);
    tw_op(m, 6, IN(tw3h), tw3, 0, 0, NULL, "");
    int tsh = tw_tensor(m, "shape", 1, (int[]){ 4 }, TW_I32, tshape, sizeof tshape);
    int y5 = tw_tensor(m, "y5", 4, T4(1, 8, 10, 6), TW_F32, NULL, 0);
    tw_op(m, 67, IN(tsh, tw3, y4), y5, 49, 3, (int32_t[]){ 0, 2, 2 }, "bii");
    int tb3 = tw_tensor(m, "b3", 1, (int[]){ 6 }, TW_F32, b3, sizeof b3);
    int y6 = tw_tensor(m, "y6", 4, T4(1, 8, 10, 6), TW_F32, NULL, 0);
    tw_op(m, 0, IN(y5, tb3), y6, 11, 1, (int32_t[]){ 3 }, "b");
    int y7 = tw_tensor(m, "y7", 4, T4(1, 8, 10, 9), TW_F32, NULL, 0);
    tw_op(m, 2, IN(x, y6), y7, 10, 2, (int32_t[]){ -1, 0 }, "ib");
    int tbg = tw_tensor(m, "begin", 1, (int[]){ 4 }, TW_I32, sl_begin, sizeof sl_begin);
    int ten = tw_tensor(m, "end", 1, (int[]){ 4 }, TW_I32, sl_end, sizeof sl_end);
    int tst = tw_tensor(m, "strides", 1, (int[]){ 4 }, TW_I32, sl_stride, sizeof sl_stride);
    int y8 = tw_tensor(m, "y8", 4, T4(1, 4, 4, 4), TW_F32, NULL, 0);
    tw_op(m, 45, IN(y7, tbg, ten, tst), y8, 32, 2, (int32_t[]){ 0, 0 }, "ii");
    int trs = tw_tensor(m, "size", 1, (int[]){ 2 }, TW_I32, rsize, sizeof rsize);
    int y9 = tw_tensor(m, "y9", 4, T4(1, 7, 9, 4), TW_F32, NULL, 0);
    tw_op(m, 23, IN(y8, trs), y9, 15, 0, NULL, "");
    int tpd = tw_tensor(m, "pads", 2, (int[]){ 4, 2 }, TW_I32, pads, sizeof pads);
    int y10 = tw_tensor(m, "y10", 4, T4(1, 10, 10, 4), TW_F32, NULL, 0);
    tw_op(m, 34, IN(y9, tpd), y10, 22, 0, NULL, "");
    int y11 = tw_tensor(m, "y11", 4, T4(1, 10, 10, 4), TW_F32, NULL, 0);
    tw_op(m, 98, IN(y10), y11, 75, 1, (int32_t[]){ tw_float_bits(0.1f) }, "f");
    m->inputs[m->num_inputs++] = x;
    m->outputs[m->num_outputs++] = y11;
    m->outputs[m->num_outputs++] = y9;
}

static uint8_t *all_ops_bytes(size_t *n)
{
    tw_model *m = calloc(1, sizeof *m);
    all_ops_model(m);
    uint8_t *b = tw_build(m, n);
    free(m);
    return b;
}

static void test_parse_and_reference(void)
{
    size_t n;
    uint8_t *bytes = all_ops_bytes(&n);
    nn_tfl_model m;
    CHECK_OK(nn_tfl_parse(bytes, n, "all_ops.tflite", &m));
    CHECK(m.num_ops == 11, "ops %d (DEQUANTIZE of a constant is folded)", m.num_ops);
    CHECK(m.num_outputs == 2 && m.tensors[m.outputs[0]].count == 400, "outputs");
    /* per-channel int8: w1[o,...] = scale[o] * q */
    const nn_tfl_tensor *tw1 = &m.tensors[1];
    CHECK(tw1->values && fabsf(tw1->values[27] - 0.008f * w1[27]) < 1e-7f, "per-channel dequantisation %g vs %g",
          tw1->values ? tw1->values[27] : 0, 0.008f * w1[27]);
    float x[240], y0[400], y1[252];
    for (int i = 0; i < 240; i++) x[i] = (float)((i * 37) % 101) / 100.0f;
    float *outs[2] = { y0, y1 };
    CHECK_OK(nn_tfl_ref_run(&m, x, outs, 2));
    int finite = 1;
    double mx = 0;
    for (int i = 0; i < 400; i++) {
        finite &= isfinite(y0[i]);
        mx = fmax(mx, fabs(y0[i]));
    }
    CHECK(finite && mx > 0.05, "reference output finite and not all zero (max %g)", mx);
    nn_tfl_destroy(&m);
    free(bytes);
}

/* Largest |a - b| / max(|b|max, floor) over n values: relative to the output's scale. */
static double rel_diff(const float *a, const float *b, size_t n)
{
    double scale = 0, worst = 0;
    for (size_t i = 0; i < n; i++) scale = fmax(scale, fabs(b[i]));
    if (scale < 1e-6) scale = 1e-6;
    for (size_t i = 0; i < n; i++) {
        double d = fabs((double)a[i] - b[i]) / scale;
        if (!(d <= worst)) worst = d; /* NaN counts as worst */
    }
    return worst;
}

/* Runs bytes with the runtime on threads threads; out[k] gets graph output k. */
static pg_status run_runtime(const uint8_t *bytes, size_t n, const float *x, float **out, int num_out, int threads)
{
    nn_model *model;
    PG_TRY(nn_model_load_memory(bytes, n, "model.tflite", &model));
    nn_graph *g = nn_model_graph(model);
    const nn_tensor *ti = &g->tensors[g->inputs[0]];
    memcpy(nn_graph_data(g, g->inputs[0]), x, (size_t)nn_shape_count(ti->ndim, ti->dims) * sizeof(float));
    pg_status st = nn_graph_run(g, threads);
    for (int k = 0; !st && k < num_out; k++) {
        const nn_tensor *to = &g->tensors[g->outputs[k]];
        memcpy(out[k], nn_graph_data(g, g->outputs[k]), (size_t)nn_shape_count(to->ndim, to->dims) * sizeof(float));
    }
    nn_model_destroy(model);
    return st;
}

static void test_runtime_vs_reference(void)
{
    size_t n;
    uint8_t *bytes = all_ops_bytes(&n);
    nn_tfl_model m;
    CHECK_OK(nn_tfl_parse(bytes, n, "all_ops.tflite", &m));
    float x[240], r0[400], r1[252], y0[400], y1[252];
    for (int i = 0; i < 240; i++) x[i] = (float)((i * 37) % 101) / 100.0f;
    float *ref[2] = { r0, r1 }, *run[2] = { y0, y1 };
    CHECK_OK(nn_tfl_ref_run(&m, x, ref, 2));
    for (int threads = 1; threads <= 2; threads++) {
        memset(y0, 0, sizeof y0);
        memset(y1, 0, sizeof y1);
        CHECK_OK(run_runtime(bytes, n, x, run, 2, threads));
        double d0 = rel_diff(y0, r0, 400), d1 = rel_diff(y1, r1, 252);
        printf("all-ops model, %d thread(s): runtime vs reference %.2e, %.2e (relative to the output's largest value)\n", threads, d0, d1);
        CHECK(d0 < 1e-5 && d1 < 1e-5, "runtime vs reference %g %g", d0, d1);
    }
    /* the IR the importer built: weights converted, the leaky pattern and bias fused */
    nn_model *model;
    CHECK_OK(nn_model_load_memory(bytes, n, "all_ops.tflite", &model));
    if (model) {
        const nn_graph *g = nn_model_graph(model);
        int leaky_fused = 0, muls = 0;
        for (int i = 0; i < g->num_nodes; i++) {
            if (g->nodes[i].attr.act == NN_ACT_LEAKY_RELU && g->nodes[i].op == NN_OP_CONV) leaky_fused++;
            muls += g->nodes[i].op == NN_OP_MUL || g->nodes[i].op == NN_OP_MAXIMUM;
        }
        CHECK(leaky_fused == 1 && muls == 0, "MUL + MAXIMUM fused into the depthwise conv (%d fused, %d left)", leaky_fused, muls);
    }
    nn_model_destroy(model);
    nn_tfl_destroy(&m);
    free(bytes);
}

/* Two 3x3 stride-1 NHWC convs (ops_conv_nhwc.c): odd sizes, SAME and VALID padding, bias, fused
 * RELU6, no bias, against the reference. */
static void test_conv3x3(void)
{
    static float w[20 * 3 * 3 * 16], b[20], w2[24 * 3 * 3 * 20];
    pg_rng r;
    pg_rng_seed(&r, 11);
    for (size_t i = 0; i < sizeof w / sizeof w[0]; i++) w[i] = (float)pg_rng_uniform(&r) - 0.5f;
    for (size_t i = 0; i < sizeof w2 / sizeof w2[0]; i++) w2[i] = (float)pg_rng_uniform(&r) - 0.5f;
    for (int i = 0; i < 20; i++) b[i] = (float)pg_rng_uniform(&r);
    tw_model *m = calloc(1, sizeof *m);
    int x = tw_tensor(m, "x", 4, T4(1, 7, 9, 16), TW_F32, NULL, 0);
    int tw = tw_tensor(m, "w", 4, T4(20, 3, 3, 16), TW_F32, w, sizeof w);
    int tb = tw_tensor(m, "b", 1, (int[]){ 20 }, TW_F32, b, sizeof b);
    int y = tw_tensor(m, "y", 4, T4(1, 7, 9, 20), TW_F32, NULL, 0);
    tw_op(m, 3, IN(x, tw, tb), y, 1, 4, (int32_t[]){ 0, 1, 1, 3 }, "biib");
    int tw2 = tw_tensor(m, "w2", 4, T4(24, 3, 3, 20), TW_F32, w2, sizeof w2);
    int z = tw_tensor(m, "z", 4, T4(1, 5, 7, 24), TW_F32, NULL, 0);
    tw_op(m, 3, IN(y, tw2, -1), z, 1, 4, (int32_t[]){ 1, 1, 1, 0 }, "biib");
    m->inputs[m->num_inputs++] = x;
    m->outputs[m->num_outputs++] = z;
    size_t n;
    uint8_t *bytes = tw_build(m, &n);
    free(m);
    nn_tfl_model t;
    CHECK_OK(nn_tfl_parse(bytes, n, "conv3x3.tflite", &t));
    float in[7 * 9 * 16], ref[5 * 7 * 24], run[5 * 7 * 24];
    for (int i = 0; i < 7 * 9 * 16; i++) in[i] = (float)pg_rng_uniform(&r) * 2 - 1;
    float *pr = ref, *pu = run;
    CHECK_OK(nn_tfl_ref_run(&t, in, &pr, 1));
    for (int threads = 1; threads <= 2; threads++) {
        CHECK_OK(run_runtime(bytes, n, in, &pu, 1, threads));
        double d = rel_diff(run, ref, 5 * 7 * 24);
        printf("3x3 convs (7x9x16 -> 20 SAME RELU6 -> 24 VALID), %d thread(s): %.2e vs reference\n", threads, d);
        CHECK(d < 1e-5, "3x3 convs vs reference %g", d);
    }
    if (nn_conv_force_f32(0), nn_conv_bf16()) { /* the bf16 products: well inside a percent */
        CHECK_OK(run_runtime(bytes, n, in, &pu, 1, 2));
        double d = rel_diff(run, ref, 5 * 7 * 24);
        printf("3x3 convs on %s: %.2e vs reference\n", nn_conv_kernel(), d);
        CHECK(d < 1e-2 && d > 0, "bf16 3x3 convs vs reference %g", d);
        nn_conv_force_f32(1);
    }
    nn_tfl_destroy(&t);
    free(bytes);
}

/* Hand-computed values of the reference's trickier ops. */
static void test_reference_by_hand(void)
{
    /* RESIZE_BILINEAR 2 -> 4 (legacy coordinates x * in/out): [1, 3] -> [1, 2, 3, 3] */
    tw_model *m = calloc(1, sizeof *m);
    int32_t size[2] = { 1, 4 };
    int x = tw_tensor(m, "x", 4, T4(1, 1, 2, 1), TW_F32, NULL, 0);
    int s = tw_tensor(m, "s", 1, (int[]){ 2 }, TW_I32, size, sizeof size);
    int y = tw_tensor(m, "y", 4, T4(1, 1, 4, 1), TW_F32, NULL, 0);
    tw_op(m, 23, IN(x, s), y, 15, 0, NULL, "");
    m->inputs[m->num_inputs++] = x;
    m->outputs[m->num_outputs++] = y;
    size_t n;
    uint8_t *b = tw_build(m, &n);
    nn_tfl_model t;
    CHECK_OK(nn_tfl_parse(b, n, "resize", &t));
    float in[2] = { 1, 3 }, out[4] = { 0 }, *o[1] = { out };
    CHECK_OK(nn_tfl_ref_run(&t, in, o, 1));
    CHECK(out[0] == 1 && out[1] == 2 && out[2] == 3 && out[3] == 3, "resize %g %g %g %g", out[0], out[1], out[2], out[3]);
    nn_tfl_destroy(&t);
    free(b);

    /* TRANSPOSE_CONV 2x2 stride 2, one channel: each input pixel stamps v * w */
    memset(m, 0, sizeof *m);
    int32_t shape[4] = { 1, 2, 4, 1 };
    float w[4] = { 1, 2, 3, 4 };
    x = tw_tensor(m, "x", 4, T4(1, 1, 2, 1), TW_F32, NULL, 0);
    s = tw_tensor(m, "shape", 1, (int[]){ 4 }, TW_I32, shape, sizeof shape);
    int tw = tw_tensor(m, "w", 4, T4(1, 2, 2, 1), TW_F32, w, sizeof w);
    y = tw_tensor(m, "y", 4, T4(1, 2, 4, 1), TW_F32, NULL, 0);
    tw_op(m, 67, IN(s, tw, x), y, 49, 3, (int32_t[]){ 0, 2, 2 }, "bii");
    m->inputs[m->num_inputs++] = x;
    m->outputs[m->num_outputs++] = y;
    b = tw_build(m, &n);
    CHECK_OK(nn_tfl_parse(b, n, "tconv", &t));
    float in2[2] = { 1, 10 }, out2[8] = { 0 }, *o2[1] = { out2 };
    CHECK_OK(nn_tfl_ref_run(&t, in2, o2, 1));
    const float want[8] = { 1, 2, 10, 20, 3, 4, 30, 40 };
    CHECK(memcmp(out2, want, sizeof want) == 0, "transpose conv %g %g %g %g / %g %g %g %g", out2[0], out2[1], out2[2], out2[3],
          out2[4], out2[5], out2[6], out2[7]);
    nn_tfl_destroy(&t);
    free(b);
    free(m);
}

/* ---- hostile files ---- */

static pg_status parse_bytes(const uint8_t *b, size_t n, char *msg, size_t size)
{
    nn_tfl_model m;
    pg_status st = nn_tfl_parse(b, n, "bad.tflite", &m);
    if (msg) snprintf(msg, size, "%s", st ? pg_last_error() : "");
    nn_tfl_destroy(&m);
    return st;
}

static pg_status parse_model_desc(tw_model *m, char *msg, size_t size)
{
    size_t n;
    uint8_t *b = tw_build(m, &n);
    pg_status st = parse_bytes(b, n, msg, size);
    free(b);
    return st;
}

static void test_hostile(void)
{
    size_t n;
    uint8_t *good = all_ops_bytes(&n);
    char msg[1024];
    /* every truncation fails cleanly */
    int bad_ok = 1;
    for (size_t len = 0; len < n; len++) {
        pg_status st = parse_bytes(good, len, NULL, 0);
        if (st != PG_ERR_FORMAT && st != PG_ERR_SIZE) bad_ok = 0;
    }
    CHECK(bad_ok, "every truncation of a %zu-byte file is refused", n);
    /* random corruption: refused or parsed, never a crash (ASan/UBSan builds check the rest) */
    pg_rng r;
    pg_rng_seed(&r, 3);
    uint8_t *mut = malloc(n);
    int refused = 0;
    for (int trial = 0; trial < 3000; trial++) {
        memcpy(mut, good, n);
        int flips = 1 + trial % 4;
        for (int f = 0; f < flips; f++) mut[(size_t)(pg_rng_uniform(&r) * n) % n] ^= (uint8_t)(1 + pg_rng_uniform(&r) * 255);
        pg_status st = parse_bytes(mut, n, msg, sizeof msg);
        refused += st != PG_OK;
        if (st && strchr(msg, '\n')) {
            CHECK(0, "message is one line: %s", msg);
            break;
        }
    }
    printf("random corruption: %d of 3000 refused\n", refused);
    free(mut);
    free(good);

    tw_model *m = calloc(1, sizeof *m);
    /* huge dims */
    all_ops_model(m);
    m->tensors[0].dims[1] = 1 << 30;
    CHECK(parse_model_desc(m, msg, sizeof msg) == PG_ERR_SIZE && strstr(msg, "dimension"), "huge dim: %s", msg);
    all_ops_model(m);
    m->tensors[0].dims[1] = 1 << 20;
    m->tensors[0].dims[2] = 1 << 20;
    CHECK(parse_model_desc(m, msg, sizeof msg) == PG_ERR_SIZE, "huge tensor: %s", msg);
    /* a lying shape: the weights' buffer is smaller than their shape */
    all_ops_model(m);
    m->tensors[1].dims[1] = 5; /* not the quantized dimension, whose scale count is checked first */
    CHECK(parse_model_desc(m, msg, sizeof msg) == PG_ERR_FORMAT && strstr(msg, "buffer holds"), "lying weights: %s", msg);
    /* a lying output shape */
    all_ops_model(m);
    m->tensors[3].dims[1] = 5;
    CHECK(parse_model_desc(m, msg, sizeof msg) == PG_ERR_FORMAT && strstr(msg, "declared"), "lying output: %s", msg);
    /* buffer index out of range */
    all_ops_model(m);
    m->tensors[1].buffer_override = 1000;
    CHECK(parse_model_desc(m, msg, sizeof msg) == PG_ERR_FORMAT, "buffer index: %s", msg);
    /* a cycle: op 1 reads op 2's output, op 2 reads op 1's */
    all_ops_model(m);
    m->ops[1].inputs[0] = m->ops[2].output;
    CHECK(parse_model_desc(m, msg, sizeof msg) == PG_ERR_FORMAT && strstr(msg, "not computed before"), "cycle: %s", msg);
    /* a tensor written twice */
    all_ops_model(m);
    m->ops[3].output = m->ops[2].output;
    CHECK(parse_model_desc(m, msg, sizeof msg) == PG_ERR_FORMAT, "written twice: %s", msg);
    /* an unsupported op names the op and the operator */
    all_ops_model(m);
    m->ops[4].code = 25; /* SOFTMAX */
    m->ops[4].options_type = 0;
    CHECK(parse_model_desc(m, msg, sizeof msg) == PG_ERR_FORMAT && strstr(msg, "SOFTMAX") && strstr(msg, "operator 4") &&
              strstr(msg, "unsupported"),
          "unsupported: %s", msg);
    /* options of the wrong type */
    all_ops_model(m);
    m->ops[0].options_type = 2;
    CHECK(parse_model_desc(m, msg, sizeof msg) == PG_ERR_FORMAT && strstr(msg, "options"), "options type: %s", msg);
    /* an index out of range */
    all_ops_model(m);
    m->ops[0].inputs[0] = 999;
    CHECK(parse_model_desc(m, msg, sizeof msg) == PG_ERR_FORMAT && strstr(msg, "out of range"), "index: %s", msg);
    /* int8 weights without a scale */
    all_ops_model(m);
    m->tensors[1].num_scales = 0;
    CHECK(parse_model_desc(m, msg, sizeof msg) == PG_ERR_FORMAT && strstr(msg, "scale"), "no scale: %s", msg);
    /* not TFLite */
    CHECK(parse_bytes((const uint8_t *)"\x10\0\0\0ABCDxxxxxxxxxxxxxxxx", 24, msg, sizeof msg) == PG_ERR_FORMAT && strstr(msg, "TFL3"),
          "identifier: %s", msg);
    free(m);
}


/* The real PyDNet++ (skipped when ../shared/models does not have it): the runtime agrees with
 * the reference to 1e-4 on tabletop_dev frame 0 and the depth ranks like the ground truth. */
static void test_real_model(void)
{
    char path[4096], data_dir[4096], video[4200], gt_path[4300];
#ifdef PG_SANITIZED
    printf("SKIP real PyDNet++ under the sanitizers (checked in the Release pass)\n");
    return;
#endif
    snprintf(path, sizeof path, "%s/models/pydnet++_matterport.tflite", PG_SHARED_DIR);
    if (!pg_path_exists(path) || !test_shared_data("tabletop_dev", data_dir, sizeof data_dir)) {
        printf("SKIP real PyDNet++: %s or tabletop_dev not found\n", path);
        return;
    }
    char *bytes = NULL;
    size_t n = 0;
    CHECK_OK(pg_read_file(path, (size_t)64 << 20, &bytes, &n));
    nn_tfl_model m;
    pg_status st = nn_tfl_parse((const uint8_t *)bytes, n, path, &m);
    CHECK(st == PG_OK && m.num_ops == 136 && m.num_outputs == 3, "PyDNet++ parses: %s", st ? pg_last_error() : "");
    if (st) {
        free(bytes);
        return;
    }
    snprintf(video, sizeof video, "%s/cam00.mp4", data_dir);
    snprintf(gt_path, sizeof gt_path, "%s/depth_gt/cam00.npy", data_dir);
    io_video_options o = io_video_defaults();
    o.count = 1;
    io_frames fr;
    pg_image img = { 0 }, in = { 0 };
    CHECK_OK(io_frames_read(video, &o, &fr));
    CHECK_OK(io_frames_image(&fr, 0, &img));
    CHECK_OK(pg_image_resize(&in, &img, 640, 448));
    size_t P = 448 * 640;
    float *ref = malloc(P * sizeof(float)), *run = malloc(P * sizeof(float));
    double t0 = pg_time_seconds();
    CHECK_OK(nn_tfl_ref_run(&m, in.data, &ref, 1));
    double t_ref = pg_time_seconds() - t0;
    nn_model *model = NULL;
    CHECK_OK(nn_model_load_memory(bytes, n, path, &model));
    double best = 1e9;
    for (int rep = 0; model && rep < 3; rep++) {
        t0 = pg_time_seconds();
        CHECK_OK(nn_model_run(model, in.data, run, 2));
        double t = pg_time_seconds() - t0;
        best = t < best ? t : best;
    }
    int finite = 1;
    double pix = 0; /* worst per-pixel |a - b| / |b| (the output is positive depth) */
    for (size_t i = 0; i < P; i++) {
        finite &= isfinite(run[i]);
        if (fabs(ref[i]) > 0) pix = fmax(pix, fabs((double)run[i] - ref[i]) / fabs(ref[i]));
    }
    double d = rel_diff(run, ref, P);
    printf("PyDNet++ 640x448: runtime vs reference %.2e of the largest value, %.2e worst per pixel; reference %.1f s, runtime %.0f ms "
           "on 2 threads (best of 3)\n", d, pix, t_ref, best * 1e3);
    CHECK(pix < 1e-4, "per-pixel relative difference %g", pix);
    CHECK(finite, "output finite");
    CHECK(d < 1e-4, "runtime vs reference %g", d);
    if (model && (nn_conv_force_f32(0), nn_conv_bf16())) {
        /* the convolutions as bf16 products (AMX): within a percent of the reference over the
         * image, a few percent at the worst pixel (measured 3.3e-3 and 2.9e-2) */
        float *run16 = malloc(P * sizeof(float));
        t0 = pg_time_seconds();
        CHECK_OK(nn_model_run(model, in.data, run16, 2));
        double t16 = pg_time_seconds() - t0, pix16 = 0, d16 = rel_diff(run16, ref, P);
        for (size_t i = 0; i < P; i++)
            if (fabs(ref[i]) > 0) pix16 = fmax(pix16, fabs((double)run16[i] - ref[i]) / fabs(ref[i]));
        printf("PyDNet++ 640x448 on %s convolutions: %.2e of the largest value, %.2e worst per pixel, %.0f ms\n",
               nn_conv_kernel(), d16, pix16, t16 * 1e3);
        CHECK(d16 < 1e-2 && pix16 < 0.1 && d16 > 0, "bf16 PyDNet++ vs reference %g, worst pixel %g", d16, pix16);
        free(run16);
        nn_conv_force_f32(1);
    }
    /* Spearman against the ground truth at the video's size */
    pg_image depth = { 640, 448, 1, run }, small = { 0 };
    CHECK_OK(pg_image_resize(&small, &depth, img.width, img.height));
    pg_array gt;
    CHECK_OK(io_npy_load(gt_path, &gt));
    if (gt.data && small.data) {
        double rho = test_spearman(small.data, gt.data, img.width * img.height);
        printf("PyDNet++ on tabletop_dev cam00 frame 0: Spearman %.4f vs depth_gt\n", rho);
        CHECK(rho >= 0.4, "Spearman %.4f", rho);
    }
    pg_array_destroy(&gt);
    pg_image_destroy(&small);
    nn_model_destroy(model);
    free(ref);
    free(run);
    pg_image_destroy(&img);
    pg_image_destroy(&in);
    io_frames_destroy(&fr);
    nn_tfl_destroy(&m);
    free(bytes);
}

/* Writes the seed corpus of tests/fuzz/fuzz_tflite.c into dir (small synthetic files). */
static void write_corpus(const char *dir)
{
    size_t n;
    uint8_t *b = all_ops_bytes(&n);
    char path[4200];
    snprintf(path, sizeof path, "%s/all_ops.tflite", dir);
    CHECK_OK(pg_write_file_atomic(path, b, n));
    free(b);
}

/* fuzz_tflite: graphs whose output no op writes, or whose ADD reads an integer tensor, made the
 * reference interpreter read through NULL; they are refused in one line now. */
static void test_reference_refuses_broken_graph(const char *file)
{
    char *data = NULL, path[4096];
    size_t size = 0;
    snprintf(path, sizeof path, "%s/tests/fuzz/corpus/tflite/%s", PG_SOURCE_DIR, file);
    CHECK_OK(pg_read_file(path, 1 << 20, &data, &size));
    nn_tfl_model m;
    if (data && nn_tfl_parse((const uint8_t *)data, size, "unwritten.tflite", &m) == PG_OK) {
        float *x = calloc((size_t)m.tensors[m.inputs[0]].count + 1, sizeof(float));
        float *y = calloc((size_t)m.tensors[m.outputs[0]].count + 1, sizeof(float));
        pg_status st = nn_tfl_ref_run(&m, x, &y, 1);
        CHECK(st == PG_ERR_FORMAT && strstr(pg_last_error(), "reference run") && !strchr(pg_last_error(), '\n'),
              "%s: status %d, %s", file, st, pg_last_error());
        free(x);
        free(y);
        nn_tfl_destroy(&m);
    }
    free(data);
}

int main(void)
{
    char tmp[4096];
    test_reference_refuses_broken_graph("crash-output-never-written.tflite");
    test_reference_refuses_broken_graph("crash-int-tensor-as-floats.tflite");
    test_tmpdir("nn_tflite", tmp, sizeof tmp);
    nn_conv_force_f32(1); /* the f32 runtime against the f32 reference; bf16 checked on its own */
    fill_weights();
    test_parse_and_reference();
    test_reference_by_hand();
    test_runtime_vs_reference();
    test_conv3x3();
    test_hostile();
    test_real_model();
    write_corpus(tmp);
    return test_summary("test_nn_tflite");
}
