/* test_nn_tflite_int.c - integer (int8 / uint8) TFLite models: a small synthetic model using
 * every integer op (written by tests/tflite_writer.h) run by the runtime and by the reference's
 * integer kernels (tflite_ref_int.c, TFLite's fixed-point arithmetic), hostile quantisation
 * parameters, and the real FastDepth when ../shared/models has it (runtime vs reference on
 * tabletop_dev frame 0, Spearman vs the ground truth). Both models are also evaluated by a second,
 * independent oracle in NumPy (tests/nn/tflite_int_ref.py: its own flatbuffer reader) when
 * /usr/bin/python3 has NumPy. The acceptance line: the runtime's output is within one quantisation
 * step of each oracle on >= 99.9 % of the values. */
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
#include "nn/nn.h"
#include "nn/tflite.h"

#define T4(a, b, c, d) (int[]){ a, b, c, d }
#define IN(...) (int[]){ __VA_ARGS__ }, (int)(sizeof((int[]){ __VA_ARGS__ }) / sizeof(int))

static int8_t wa[8 * 3 * 3 * 3], wd[1 * 3 * 3 * 8], wb[4 * 1 * 1 * 8], wc[4 * 1 * 1 * 8];
static int32_t ba[8], bd[8], bb[4], bc[4];
static int32_t pads[8] = { 0, 0, 1, 1, 1, 1, 0, 0 }, rsize[2] = { 12, 14 };
static const float s_in = 1.0f / 255, s_a = 0.02f, s_d = 0.03f, s_b = 0.05f, s_c = 0.04f, s_sum = 0.07f, s_out = 0.08f;

static void set_q(tw_model *m, int t, float scale, int64_t zp)
{
    m->tensors[t].num_scales = 1;
    m->tensors[t].scales[0] = scale;
    m->tensors[t].zero_point = zp;
}

/* per-channel weights of n channels along quant_dim with scales base * (1 + k / 4) */
static void set_channels(tw_model *m, int t, int n, int dim, float base)
{
    m->tensors[t].num_scales = n;
    m->tensors[t].quant_dim = dim;
    for (int k = 0; k < n; k++) m->tensors[t].scales[k] = base * (1 + k / 4.0f);
}

/* the int32 bias of a conv: scale input x weight per channel */
static void set_bias(tw_model *m, int t, int n, float in_scale, int w)
{
    m->tensors[t].num_scales = n;
    for (int k = 0; k < n; k++) m->tensors[t].scales[k] = in_scale * m->tensors[w].scales[m->tensors[w].num_scales > 1 ? k : 0];
}

/* x uint8 (1,12,14,3) -> QUANTIZE int8 -> PAD -> CONV 3x3 s2 per-channel RELU6 (8) -> DEPTHWISE
 * 3x3 RELU -> two 1x1 CONVs (4 each) -> ADD -> RESIZE_NEAREST x2 -> QUANTIZE uint8 (1,12,14,4). */
static void int_model(tw_model *m)
{
    memset(m, 0, sizeof *m);
    int x = tw_tensor(m, "x", 4, T4(1, 12, 14, 3), TW_U8, NULL, 0);
    set_q(m, x, s_in, 0);
    int xq = tw_tensor(m, "x_int8", 4, T4(1, 12, 14, 3), TW_I8, NULL, 0);
    set_q(m, xq, s_in, -128);
    tw_op(m, 114, IN(x), xq, 89, 0, NULL, "");
    int tp = tw_tensor(m, "pads", 2, (int[]){ 4, 2 }, TW_I32, pads, sizeof pads);
    int xp = tw_tensor(m, "padded", 4, T4(1, 14, 16, 3), TW_I8, NULL, 0);
    set_q(m, xp, s_in, -128);
    tw_op(m, 34, IN(xq, tp), xp, 22, 0, NULL, "");
    int twa = tw_tensor(m, "wa", 4, T4(8, 3, 3, 3), TW_I8, wa, sizeof wa);
    set_channels(m, twa, 8, 0, 0.01f);
    int tba = tw_tensor(m, "ba", 1, (int[]){ 8 }, TW_I32, ba, sizeof ba);
    set_bias(m, tba, 8, s_in, twa);
    int ya = tw_tensor(m, "ya", 4, T4(1, 6, 7, 8), TW_I8, NULL, 0);
    set_q(m, ya, s_a, -128);
    tw_op(m, 3, IN(xp, twa, tba), ya, 1, 4, (int32_t[]){ 1, 2, 2, 3 }, "biib");
    int twd = tw_tensor(m, "wd", 4, T4(1, 3, 3, 8), TW_I8, wd, sizeof wd);
    set_channels(m, twd, 8, 3, 0.02f);
    int tbd = tw_tensor(m, "bd", 1, (int[]){ 8 }, TW_I32, bd, sizeof bd);
    set_bias(m, tbd, 8, s_a, twd);
    int yd = tw_tensor(m, "yd", 4, T4(1, 6, 7, 8), TW_I8, NULL, 0);
    set_q(m, yd, s_d, -100);
    tw_op(m, 4, IN(ya, twd, tbd), yd, 2, 5, (int32_t[]){ 0, 1, 1, 1, 1 }, "biiib");
    int twb = tw_tensor(m, "wb", 4, T4(4, 1, 1, 8), TW_I8, wb, sizeof wb);
    set_channels(m, twb, 4, 0, 0.015f);
    int tbb = tw_tensor(m, "bb", 1, (int[]){ 4 }, TW_I32, bb, sizeof bb);
    set_bias(m, tbb, 4, s_d, twb);
    int yb = tw_tensor(m, "yb", 4, T4(1, 6, 7, 4), TW_I8, NULL, 0);
    set_q(m, yb, s_b, 3);
    tw_op(m, 3, IN(yd, twb, tbb), yb, 1, 4, (int32_t[]){ 1, 1, 1, 0 }, "biib");
    int twc = tw_tensor(m, "wc", 4, T4(4, 1, 1, 8), TW_I8, wc, sizeof wc);
    set_q(m, twc, 0.012f, 0); /* per-tensor weights */
    int tbc = tw_tensor(m, "bc", 1, (int[]){ 4 }, TW_I32, bc, sizeof bc);
    set_bias(m, tbc, 1, s_d, twc);
    int yc = tw_tensor(m, "yc", 4, T4(1, 6, 7, 4), TW_I8, NULL, 0);
    set_q(m, yc, s_c, -5);
    tw_op(m, 3, IN(yd, twc, tbc), yc, 1, 4, (int32_t[]){ 1, 1, 1, 0 }, "biib");
    int ys = tw_tensor(m, "sum", 4, T4(1, 6, 7, 4), TW_I8, NULL, 0);
    set_q(m, ys, s_sum, 0);
    tw_op(m, 0, IN(yb, yc), ys, 11, 1, (int32_t[]){ 0 }, "b");
    int trs = tw_tensor(m, "size", 1, (int[]){ 2 }, TW_I32, rsize, sizeof rsize);
    int yr = tw_tensor(m, "up", 4, T4(1, 12, 14, 4), TW_I8, NULL, 0);
    set_q(m, yr, s_sum, 0);
    tw_op(m, 97, IN(ys, trs), yr, 74, 0, NULL, "");
    int y = tw_tensor(m, "y", 4, T4(1, 12, 14, 4), TW_U8, NULL, 0);
    set_q(m, y, s_out, 100);
    tw_op(m, 114, IN(yr), y, 89, 0, NULL, "");
    m->inputs[m->num_inputs++] = x;
    m->outputs[m->num_outputs++] = y;
}

static void fill_weights(void)
{
    pg_rng r;
    pg_rng_seed(&r, 5);
    for (size_t i = 0; i < sizeof wa; i++) wa[i] = (int8_t)(pg_rng_uniform(&r) * 254 - 127);
    for (size_t i = 0; i < sizeof wd; i++) wd[i] = (int8_t)(pg_rng_uniform(&r) * 254 - 127);
    for (size_t i = 0; i < sizeof wb; i++) wb[i] = (int8_t)(pg_rng_uniform(&r) * 254 - 127);
    for (size_t i = 0; i < sizeof wc; i++) wc[i] = (int8_t)(pg_rng_uniform(&r) * 254 - 127);
    for (int i = 0; i < 8; i++) ba[i] = (int32_t)(pg_rng_uniform(&r) * 4000 - 2000), bd[i] = (int32_t)(pg_rng_uniform(&r) * 400 - 100);
    for (int i = 0; i < 4; i++) bb[i] = (int32_t)(pg_rng_uniform(&r) * 400 - 200), bc[i] = (int32_t)(pg_rng_uniform(&r) * 400 - 200);
}

static uint8_t *int_bytes(size_t *n)
{
    tw_model *m = calloc(1, sizeof *m);
    int_model(m);
    uint8_t *b = tw_build(m, n);
    free(m);
    return b;
}

/* Counts values of run equal to ref, and within one step of scale; returns the within-one share. */
static double agreement(const float *run, const float *ref, size_t n, float scale, const char *what)
{
    size_t same = 0, one = 0;
    double worst = 0;
    for (size_t i = 0; i < n; i++) {
        double d = fabs((double)run[i] - ref[i]) / scale;
        same += d < 0.01;
        one += d < 1.01;
        if (!(d <= worst)) worst = d;
    }
    printf("%s: %zu values, %.4f %% identical, %.4f %% within one step (%g), worst %.2f steps\n", what, n, 100.0 * same / n, 100.0 * one / n,
           (double)scale, worst);
    return (double)one / n;
}

static pg_status run_model(const uint8_t *bytes, size_t n, const float *x, float *y, int threads)
{
    nn_model *model;
    PG_TRY(nn_model_load_memory(bytes, n, "int8.tflite", &model));
    pg_status st = nn_model_run(model, x, y, threads);
    nn_model_destroy(model);
    return st;
}

/* The second oracle: tests/nn/tflite_int_ref.py (its own flatbuffer reader and TFLite's integer
 * arithmetic in NumPy) on model_path with input x of `shape`; compares the runtime's output run
 * (count values, step `scale`). Skipped (with a line) when /usr/bin/python3 has no NumPy. */
static void check_numpy(const char *tmp, const char *model_path, const float *x, int ndim, const size_t *shape, const float *run,
                        size_t count, float scale, const char *what)
{
    if (system("/usr/bin/python3 -c 'import numpy' >/dev/null 2>&1") != 0) {
        printf("SKIP %s vs NumPy: /usr/bin/python3 with numpy not available\n", what);
        return;
    }
    char in[4200], out[4200], cmd[16384];
    snprintf(in, sizeof in, "%s/numpy_in.npy", tmp);
    snprintf(out, sizeof out, "%s/numpy_out.npy", tmp);
    remove(out);
    CHECK_OK(io_npy_save(in, x, ndim, shape));
    snprintf(cmd, sizeof cmd, "/usr/bin/python3 '%s/tests/nn/tflite_int_ref.py' '%s' '%s' '%s'", PG_SOURCE_DIR, model_path, in, out);
    CHECK(system(cmd) == 0, "%s: tflite_int_ref.py failed", what);
    pg_array y;
    if (io_npy_load(out, &y) != PG_OK) {
        CHECK(0, "%s: no NumPy output: %s", what, pg_last_error());
        return;
    }
    size_t n = 1;
    for (int d = 0; d < y.ndim; d++) n *= y.shape[d];
    CHECK(n == count, "%s: NumPy output has %zu values, the runtime's %zu", what, n, count);
    if (n == count) {
        char label[256];
        snprintf(label, sizeof label, "%s, runtime vs NumPy", what);
        double share = agreement(run, y.data, n, scale, label);
        CHECK(share >= 0.999, "%s: within one step of NumPy on %.4f %% of the values", what, share * 100);
    }
    pg_array_destroy(&y);
}

static void test_synthetic(const char *tmp)
{
    size_t n;
    uint8_t *bytes = int_bytes(&n);
    nn_tfl_model m;
    CHECK_OK(nn_tfl_parse(bytes, n, "int8.tflite", &m));
    float x[12 * 14 * 3], ref[12 * 14 * 4], run[12 * 14 * 4];
    for (int i = 0; i < 12 * 14 * 3; i++) x[i] = (float)((i * 53) % 256) / 255.0f;
    float *pr = ref;
    CHECK_OK(nn_tfl_ref_run(&m, x, &pr, 1));
    /* the output is real: (q - 100) * 0.08 on the uint8 grid; it must not be constant */
    int on_grid = 1, distinct = 0;
    for (int i = 0; i < 12 * 14 * 4; i++) {
        double q = ref[i] / s_out + 100;
        on_grid &= fabs(q - floor(q + 0.5)) < 1e-3 && q > -0.5 && q < 255.5;
        distinct += i > 0 && ref[i] != ref[0];
    }
    CHECK(on_grid && distinct > 100, "reference output on the uint8 grid and not constant (%d values differ from the first)", distinct);
    for (int threads = 1; threads <= 2; threads++) {
        CHECK_OK(run_model(bytes, n, x, run, threads));
        double share = agreement(run, ref, 12 * 14 * 4, s_out, threads == 1 ? "synthetic int8 model, 1 thread" : "synthetic int8 model, 2 threads");
        CHECK(share >= 0.999, "within one step on %.4f %% of the values", share * 100);
    }
    char path[4200];
    snprintf(path, sizeof path, "%s/int8_model.tflite", tmp);
    CHECK_OK(pg_write_file_atomic(path, bytes, n));
    check_numpy(tmp, path, x, 4, (size_t[]){ 1, 12, 14, 3 }, run, 12 * 14 * 4, s_out, "synthetic int8 model");
    nn_tfl_destroy(&m);
    free(bytes);
}

/* Hand-checked integer arithmetic of the reference: a 1x1 conv of one pixel. */
static void test_reference_by_hand(void)
{
    /* x uint8 real 1.0 (q 255, scale 1/255) -> QUANTIZE int8 (q 127, zp -128) -> CONV 1x1, weight
     * q 64 scale 0.5, bias 10 (scale 0.5/255) -> y int8 scale 0.25 zp 1:
     * acc = (127 + 128) * 64 + 10 = 16330; real = 16330 * 0.5/255 = 32.0196; / 0.25 = 128.08 -> 128 + 1
     * clamps to 127. With the RELU6 fused: 6 / 0.25 = 24 -> 1 + 24 = 25, real (25 - 1) * 0.25 = 6. */
    static int8_t w[1] = { 64 };
    static int32_t b[1] = { 10 };
    for (int relu6 = 0; relu6 < 2; relu6++) {
        tw_model *m = calloc(1, sizeof *m);
        int x = tw_tensor(m, "x", 4, T4(1, 1, 1, 1), TW_U8, NULL, 0);
        set_q(m, x, 1.0f / 255, 0);
        int xq = tw_tensor(m, "xq", 4, T4(1, 1, 1, 1), TW_I8, NULL, 0);
        set_q(m, xq, 1.0f / 255, -128);
        tw_op(m, 114, IN(x), xq, 89, 0, NULL, "");
        int tw = tw_tensor(m, "w", 4, T4(1, 1, 1, 1), TW_I8, w, sizeof w);
        set_q(m, tw, 0.5f, 0);
        int tb = tw_tensor(m, "b", 1, (int[]){ 1 }, TW_I32, b, sizeof b);
        set_bias(m, tb, 1, 1.0f / 255, tw);
        int y = tw_tensor(m, "y", 4, T4(1, 1, 1, 1), TW_I8, NULL, 0);
        set_q(m, y, 0.25f, 1);
        tw_op(m, 3, IN(xq, tw, tb), y, 1, 4, (int32_t[]){ 1, 1, 1, relu6 ? 3 : 0 }, "biib");
        m->inputs[m->num_inputs++] = x;
        m->outputs[m->num_outputs++] = y;
        size_t n;
        uint8_t *bytes = tw_build(m, &n);
        free(m);
        nn_tfl_model t;
        CHECK_OK(nn_tfl_parse(bytes, n, "by_hand.tflite", &t));
        float in = 1.0f, out = 0, *po = &out, run = 0;
        CHECK_OK(nn_tfl_ref_run(&t, &in, &po, 1));
        float want = relu6 ? 6.0f : (127 - 1) * 0.25f;
        CHECK(out == want, "1x1 conv by hand (relu6 %d): %g, want %g", relu6, out, want);
        CHECK_OK(run_model(bytes, n, &in, &run, 1));
        CHECK(run == want, "runtime 1x1 conv by hand (relu6 %d): %g, want %g", relu6, run, want);
        nn_tfl_destroy(&t);
        free(bytes);
    }
}

/* Hostile quantisation parameters: each refused with one line naming the file and the problem. */
static void test_hostile_quantization(void)
{
    tw_model *m = calloc(1, sizeof *m);
    char msg[1024];
    struct { const char *what, *expect; } cases[] = {
        { "zero scale", "positive finite" }, { "negative scale", "positive finite" }, { "NaN scale", "positive finite" },
        { "zero point 300 in int8", "outside" }, { "per-channel count", "scales" }, { "bias scale", "bias scale" },
        { "PAD changes the quantisation", "differs" }, { "uint8 zero point -1", "outside" }, { "int32 bias zero point", "outside" },
        { "per-channel weights of a 1x1 conv along the wrong axis", "scales" },
    };
    int nc = (int)(sizeof cases / sizeof cases[0]);
    for (int k = 0; k < nc; k++) {
        int_model(m);
        switch (k) {
        case 0: m->tensors[4].scales[2] = 0; break;                  /* wa */
        case 1: m->tensors[6].scales[0] = -0.02f; break;             /* ya */
        case 2: m->tensors[6].scales[0] = NAN; break;
        case 3: m->tensors[6].zero_point = 300; break;
        case 4: m->tensors[4].num_scales = 3; break;
        case 5: m->tensors[5].scales[1] *= 1.5f; break;              /* ba */
        case 6: m->tensors[3].zero_point = -127; break;              /* padded */
        case 7: m->tensors[0].zero_point = -1; break;                /* uint8 input */
        case 8: m->tensors[5].zero_point = 2; break;
        case 9: set_channels(m, 10, 8, 3, 0.015f); break;            /* wb (4,1,1,8): scales along its inputs */
        }
        size_t n;
        uint8_t *b = tw_build(m, &n);
        nn_tfl_model t;
        pg_status st = nn_tfl_parse(b, n, "hostile_int8.tflite", &t);
        snprintf(msg, sizeof msg, "%s", st ? pg_last_error() : "(accepted)");
        nn_tfl_destroy(&t);
        CHECK(st == PG_ERR_FORMAT && strstr(msg, "hostile_int8.tflite") && strstr(msg, cases[k].expect) && !strchr(msg, '\n'),
              "%s: %s", cases[k].what, msg);
        printf("%s -> %s\n", cases[k].what, msg);
        /* the runtime's loader refuses it the same way */
        nn_model *model = NULL;
        CHECK(nn_model_load_memory(b, n, "hostile_int8.tflite", &model) == PG_ERR_FORMAT, "%s: loader accepted", cases[k].what);
        nn_model_destroy(model);
        free(b);
    }
    /* extreme but valid scales (1e-30, 1e30, the biases made consistent): accepted, and both
     * interpreters run without an overflow (UBSan) and give finite values */
    int_model(m);
    m->tensors[0].scales[0] = 1e-30f; /* x */
    m->tensors[6].scales[0] = 1e-30f; /* ya */
    m->tensors[9].scales[0] = 1e30f;  /* yd */
    set_bias(m, 8, 8, 1e-30f, 7);
    set_bias(m, 11, 4, 1e30f, 10);
    set_bias(m, 14, 1, 1e30f, 13);
    size_t n;
    uint8_t *b = tw_build(m, &n);
    nn_tfl_model t;
    CHECK_OK(nn_tfl_parse(b, n, "extreme_scales.tflite", &t));
    float x[12 * 14 * 3], ref[12 * 14 * 4] = { 0 }, run[12 * 14 * 4] = { 0 }, *pr = ref;
    if (!t.num_outputs) {
        free(b);
        free(m);
        return;
    }
    for (int i = 0; i < 12 * 14 * 3; i++) x[i] = (float)i / 500.0f;
    CHECK_OK(nn_tfl_ref_run(&t, x, &pr, 1));
    CHECK_OK(run_model(b, n, x, run, 1));
    int finite = 1;
    for (int i = 0; i < 12 * 14 * 4; i++) finite &= isfinite(ref[i]) && isfinite(run[i]);
    CHECK(finite, "extreme scales: finite outputs");
    nn_tfl_destroy(&t);
    free(b);
    free(m);
}

/* Every truncation of the integer model is refused; 2,000 random byte flips are refused or run
 * (parser, integer reference, loader, runtime) without a crash (the ASan + UBSan build checks
 * the rest), every refusal in one line. */
static void test_corruption(void)
{
    size_t n;
    uint8_t *good = int_bytes(&n), *mut = malloc(n);
    int truncations_ok = 1;
    for (size_t len = 0; len < n; len++) {
        nn_tfl_model t;
        pg_status st = nn_tfl_parse(good, len, "cut.tflite", &t);
        truncations_ok &= st == PG_ERR_FORMAT || st == PG_ERR_SIZE;
        nn_tfl_destroy(&t);
    }
    CHECK(truncations_ok, "every truncation of the %zu-byte integer model is refused", n);
    pg_rng r;
    pg_rng_seed(&r, 9);
    int refused = 0, ran = 0, one_line = 1;
    for (int trial = 0; trial < 2000; trial++) {
        memcpy(mut, good, n);
        for (int f = 0; f <= trial % 3; f++) mut[(size_t)(pg_rng_uniform(&r) * n) % n] ^= (uint8_t)(1 + pg_rng_uniform(&r) * 255);
        nn_tfl_model t;
        pg_status st = nn_tfl_parse(mut, n, "flipped.tflite", &t);
        if (st) {
            refused++;
            one_line &= strchr(pg_last_error(), '\n') == NULL;
            continue;
        }
        int64_t total = 0;
        for (int i = 0; i < t.num_tensors; i++) total += t.tensors[i].count;
        if (total <= ((int64_t)1 << 18) && t.num_inputs == 1) {
            float *x = calloc((size_t)t.tensors[t.inputs[0]].count, sizeof(float));
            float *y = calloc((size_t)t.tensors[t.outputs[0]].count, sizeof(float));
            for (int64_t i = 0; i < t.tensors[t.inputs[0]].count; i++) x[i] = (float)((i * 29) % 256) / 255.0f;
            nn_tfl_ref_run(&t, x, &y, 1);
            nn_model *model;
            if (nn_model_load_memory(mut, n, "flipped.tflite", &model) == PG_OK) {
                int64_t din[NN_MAX_DIMS], dout[NN_MAX_DIMS];
                int ni = nn_model_input_shape(model, din), no = nn_model_output_shape(model, dout);
                float *xi = calloc((size_t)nn_shape_count(ni, din), sizeof(float)), *yo = calloc((size_t)nn_shape_count(no, dout) + 1, sizeof(float));
                nn_model_run(model, xi, yo, 1);
                ran++;
                free(xi);
                free(yo);
                nn_model_destroy(model);
            }
            free(x);
            free(y);
        }
        nn_tfl_destroy(&t);
    }
    printf("integer model, random corruption: %d of 2000 refused by the parser, %d run by the runtime\n", refused, ran);
    CHECK(one_line && refused > 0 && ran > 0, "corruption: every refusal one line (%d), some refused (%d) and some run (%d)", one_line, refused, ran);
    free(mut);
    free(good);
}


/* The real FastDepth (skipped when ../shared/models does not have it). */
static void test_fastdepth(const char *tmp)
{
    char path[4096], data_dir[4096], video[4200], gt_path[4300];
    snprintf(path, sizeof path, "%s/models/fastdepth_224_int8.tflite", PG_SHARED_DIR);
    if (!pg_path_exists(path) || !test_shared_data("tabletop_dev", data_dir, sizeof data_dir)) {
        printf("SKIP real FastDepth: %s or tabletop_dev not found\n", path);
        return;
    }
    char *bytes = NULL;
    size_t n = 0;
    CHECK_OK(pg_read_file(path, (size_t)64 << 20, &bytes, &n));
    nn_tfl_model m;
    pg_status st = nn_tfl_parse((const uint8_t *)bytes, n, path, &m);
    CHECK(st == PG_OK && m.num_ops == 67, "FastDepth parses (%d ops): %s", m.num_ops, st ? pg_last_error() : "");
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
    CHECK_OK(pg_image_resize(&in, &img, 224, 224));
    size_t P = 224 * 224;
    for (size_t p = 0; p < P; p++) { /* the network reads BGR (models/README.md) */
        float r = in.data[3 * p];
        in.data[3 * p] = in.data[3 * p + 2];
        in.data[3 * p + 2] = r;
    }
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
    float step = m.tensors[m.outputs[0]].scales[0];
    double share = agreement(run, ref, P, step, "FastDepth 224x224, tabletop_dev frame 0");
    printf("FastDepth: reference %.2f s, runtime %.0f ms on 2 threads (best of 3)\n", t_ref, best * 1e3);
    CHECK(share >= 0.999, "FastDepth within one step on %.4f %% of the pixels", share * 100);
    check_numpy(tmp, path, in.data, 4, (size_t[]){ 1, 224, 224, 3 }, run, P, step, "FastDepth 224x224, tabletop_dev frame 0");
    pg_image depth = { 224, 224, 1, run }, full = { 0 };
    CHECK_OK(pg_image_resize(&full, &depth, img.width, img.height));
    pg_array gt;
    CHECK_OK(io_npy_load(gt_path, &gt));
    if (gt.data && full.data) {
        double rho = test_spearman(full.data, gt.data, img.width * img.height);
        printf("FastDepth on tabletop_dev cam00 frame 0: Spearman %.4f vs depth_gt\n", rho);
        CHECK(rho >= 0.6, "Spearman %.4f", rho);
    }
    pg_array_destroy(&gt);
    pg_image_destroy(&full);
    nn_model_destroy(model);
    free(ref);
    free(run);
    pg_image_destroy(&img);
    pg_image_destroy(&in);
    io_frames_destroy(&fr);
    nn_tfl_destroy(&m);
    free(bytes);
}

/* Writes the integer model into the fuzz seed corpus directory dir. */
static void write_corpus(const char *dir)
{
    size_t n;
    uint8_t *b = int_bytes(&n);
    char path[4200];
    snprintf(path, sizeof path, "%s/int8_ops.tflite", dir);
    CHECK_OK(pg_write_file_atomic(path, b, n));
    free(b);
}

int main(void)
{
    char tmp[4096];
    test_tmpdir("nn_tflite_int", tmp, sizeof tmp);
    fill_weights();
    test_reference_by_hand();
    test_synthetic(tmp);
    test_hostile_quantization();
    test_corruption();
    test_fastdepth(tmp);
    write_corpus(tmp);
    return test_summary("test_nn_tflite_int");
}
