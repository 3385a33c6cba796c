/* test_nn_hostile.c - hostile ONNX files are refused with one line, never a crash or a huge
 * allocation: every truncation of a valid model, lying sizes, cyclic graphs, huge dims,
 * unsupported ops, random byte flips; plus cycles and bad ids in hand-built graphs (the path
 * the TFLite front end takes). Models are written here with a small protobuf writer. */
#include "testlib.h"
#include "core/rng.h"
#include "nn/nn.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>

/* ---- a growable protobuf writer ---- */
typedef struct { uint8_t *p; size_t n, cap; } pbw;

static void put(pbw *b, const void *d, size_t n)
{
    if (!n) return;
    if (b->n + n > b->cap) {
        b->cap = (b->n + n) * 2 + 64;
        b->p = realloc(b->p, b->cap);
        if (!b->p) abort();
    }
    memcpy(b->p + b->n, d, n);
    b->n += n;
}
static void varint(pbw *b, uint64_t v)
{
    uint8_t t[10];
    int n = 0;
    do { t[n] = (uint8_t)(v & 0x7f); v >>= 7; if (v) t[n] |= 0x80; n++; } while (v);
    put(b, t, (size_t)n);
}
static void f_varint(pbw *b, int field, uint64_t v) { varint(b, (uint64_t)field << 3); varint(b, v); }
static void f_bytes(pbw *b, int field, const void *d, size_t n) { varint(b, (uint64_t)field << 3 | 2); varint(b, n); put(b, d, n); }
static void f_str(pbw *b, int field, const char *s) { f_bytes(b, field, s, strlen(s)); }
static void f_msg(pbw *b, int field, pbw *m) { f_bytes(b, field, m->p, m->n); free(m->p); memset(m, 0, sizeof *m); }
static void f_float(pbw *b, int field, float v) { varint(b, (uint64_t)field << 3 | 5); put(b, &v, 4); }

/* ValueInfoProto name: float tensor of the given dims (-1: a symbolic dim) */
static void value_info(pbw *g, int field, const char *name, int nd, const int64_t *dims)
{
    pbw vi = { 0 }, tp = { 0 }, tt = { 0 }, sh = { 0 };
    for (int i = 0; i < nd; i++) {
        pbw d = { 0 };
        if (dims[i] >= 0) f_varint(&d, 1, (uint64_t)dims[i]);
        else f_str(&d, 2, "batch");
        f_msg(&sh, 1, &d);
    }
    f_varint(&tt, 1, 1);
    f_msg(&tt, 2, &sh);
    f_msg(&tp, 1, &tt);
    f_str(&vi, 1, name);
    f_msg(&vi, 2, &tp);
    f_msg(g, field, &vi);
}

/* TensorProto with float raw data (count floats of value v; raw_bytes overrides the length) */
static void initializer(pbw *g, const char *name, int nd, const int64_t *dims, size_t count, float v, long raw_bytes)
{
    pbw t = { 0 };
    for (int i = 0; i < nd; i++) f_varint(&t, 1, (uint64_t)dims[i]);
    f_varint(&t, 2, 1);
    f_str(&t, 8, name);
    size_t bytes = raw_bytes >= 0 ? (size_t)raw_bytes : count * 4;
    float *d = calloc(bytes / 4 + 1, sizeof(float));
    for (size_t i = 0; i < bytes / 4; i++) d[i] = v;
    f_bytes(&t, 9, d, bytes);
    free(d);
    f_msg(g, 5, &t);
}

static void node(pbw *g, const char *op, const char *name, const char *in0, const char *in1, const char *out, pbw *attrs)
{
    pbw n = { 0 };
    if (in0) f_str(&n, 1, in0);
    if (in1) f_str(&n, 1, in1);
    f_str(&n, 2, out);
    f_str(&n, 3, name);
    f_str(&n, 4, op);
    if (attrs && attrs->n) { put(&n, attrs->p, attrs->n); free(attrs->p); memset(attrs, 0, sizeof *attrs); }
    f_msg(g, 1, &n);
}

static void model(pbw *m, pbw *g, int opset)
{
    pbw os = { 0 };
    f_varint(m, 1, 8);
    f_str(&os, 1, "");
    f_varint(&os, 2, (uint64_t)opset);
    f_msg(m, 8, &os);
    f_msg(m, 7, g);
}

/* x (1,2,4,4) -> Conv(w 3x2x3x3 of 0.5, pads 1) -> Relu -> Mul(s) -> y */
static void valid_model(pbw *m)
{
    pbw g = { 0 }, a = { 0 }, at = { 0 };
    initializer(&g, "w", 4, (int64_t[]){ 3, 2, 3, 3 }, 54, 0.5f, -1);
    initializer(&g, "s", 1, (int64_t[]){ 1 }, 1, 2.0f, -1);
    f_str(&at, 1, "pads");
    for (int i = 0; i < 4; i++) f_varint(&at, 8, 1);
    f_varint(&at, 20, 7);
    f_msg(&a, 5, &at);
    node(&g, "Conv", "conv0", "x", "w", "c", &a);
    node(&g, "Relu", "relu0", "c", NULL, "r", NULL);
    node(&g, "Mul", "mul0", "r", "s", "y", NULL);
    value_info(&g, 11, "x", 4, (int64_t[]){ 1, 2, 4, 4 });
    value_info(&g, 12, "y", 0, NULL);
    model(m, &g, 17);
}

/* Loads bytes; checks it fails with a one-line message (containing want, if set). */
static void expect_refused(const pbw *m, const char *what, const char *want)
{
    nn_model *nm = NULL;
    pg_status st = nn_model_load_memory(m->p, m->n, "hostile.onnx", &nm);
    CHECK(st != PG_OK, "%s: accepted", what);
    if (st == PG_OK) { nn_model_destroy(nm); return; }
    const char *msg = pg_last_error();
    CHECK(msg[0] && !strchr(msg, '\n'), "%s: message '%s' is not one line", what, msg);
    CHECK(strstr(msg, "hostile.onnx") != NULL, "%s: message '%s' does not name the file", what, msg);
    if (want) CHECK(strstr(msg, want) != NULL, "%s: message '%s' lacks '%s'", what, msg, want);
    printf("  %-28s -> %s\n", what, msg);
}

static void test_valid(void)
{
    pbw m = { 0 };
    valid_model(&m);
    nn_model *nm;
    CHECK_OK(nn_model_load_memory(m.p, m.n, "valid.onnx", &nm));
    if (!nm) { free(m.p); return; }
    float x[32], y[48];
    for (int i = 0; i < 32; i++) x[i] = 1.0f;
    CHECK_OK(nn_model_run(nm, x, y, 2));
    /* centre pixel of a 4x4 all-ones input: 2 channels * 9 taps * 0.5, times 2; corner: 2 * 4 * 0.5 * 2 */
    CHECK(y[5] == 18.0f && y[0] == 8.0f, "valid model: y[5] = %g (18), y[0] = %g (8)", y[5], y[0]);
    nn_model_destroy(nm);
    /* every truncation is refused */
    int refused = 0;
    for (size_t n = 0; n < m.n; n++) {
        nm = NULL;
        pg_status st = nn_model_load_memory(m.p, n, "hostile.onnx", &nm);
        refused += st != PG_OK;
        if (!st) nn_model_destroy(nm);
        else CHECK(!strchr(pg_last_error(), '\n'), "truncation %zu: multi-line message", n);
    }
    CHECK(refused == (int)m.n, "%d of %zu truncations refused", refused, m.n);
    printf("  %zu truncations of a %zu-byte model: %d refused\n", m.n, m.n, refused);
    /* random byte flips: anything may happen except a crash */
    pg_rng rng;
    pg_rng_seed(&rng, 11);
    int ok = 0;
    for (int k = 0; k < 3000; k++) {
        uint8_t *c = malloc(m.n);
        memcpy(c, m.p, m.n);
        int flips = 1 + (int)(pg_rng_uniform(&rng) * 4);
        for (int f = 0; f < flips; f++) c[(size_t)(pg_rng_uniform(&rng) * m.n) % m.n] ^= (uint8_t)(1 + pg_rng_uniform(&rng) * 255);
        nm = NULL;
        if (nn_model_load_memory(c, m.n, "flip.onnx", &nm) == PG_OK) {
            ok++;
            int64_t d[NN_MAX_DIMS];
            size_t ni = (size_t)nn_shape_count(nn_model_input_shape(nm, d), d);
            size_t no = (size_t)nn_shape_count(nn_model_output_shape(nm, d), d);
            float *xi = calloc(ni + 1, sizeof(float)), *yo = calloc(no + 1, sizeof(float));
            CHECK_OK(nn_model_run(nm, xi, yo, 1));
            free(xi); free(yo);
            nn_model_destroy(nm);
        }
        free(c);
    }
    printf("  3000 random byte flips: %d still load and run\n", ok);
    free(m.p);
}

static void test_hostile(void)
{
    pbw m = { 0 }, g = { 0 }, a = { 0 }, at = { 0 };
    /* raw data shorter than the dims say */
    initializer(&g, "w", 4, (int64_t[]){ 3, 2, 3, 3 }, 54, 0.5f, 8);
    node(&g, "Conv", "conv0", "x", "w", "y", NULL);
    value_info(&g, 11, "x", 4, (int64_t[]){ 1, 2, 4, 4 });
    value_info(&g, 12, "y", 0, NULL);
    model(&m, &g, 17);
    expect_refused(&m, "short raw data", "raw data");
    free(m.p); memset(&m, 0, sizeof m);
    /* dims whose product is 10^12 with 4 bytes of data: refused before allocating */
    initializer(&g, "w", 2, (int64_t[]){ 1000000, 1000000 }, 0, 0, 4);
    node(&g, "Relu", "r", "x", NULL, "y", NULL);
    value_info(&g, 11, "x", 1, (int64_t[]){ 4 });
    value_info(&g, 12, "y", 0, NULL);
    model(&m, &g, 17);
    expect_refused(&m, "huge initializer dims", "elements");
    free(m.p); memset(&m, 0, sizeof m);
    /* a length prefix claiming far more bytes than the file holds */
    f_varint(&m, 1, 8);
    varint(&m, 7 << 3 | 2);
    varint(&m, (uint64_t)1 << 40);
    put(&m, "\x0a\x02", 2);
    expect_refused(&m, "lying length prefix", "corrupt");
    free(m.p); memset(&m, 0, sizeof m);
    /* a cycle: a = Relu(b), b = Relu(a) */
    node(&g, "Relu", "first", "b", NULL, "a", NULL);
    node(&g, "Relu", "second", "a", NULL, "b", NULL);
    value_info(&g, 11, "x", 1, (int64_t[]){ 4 });
    value_info(&g, 12, "b", 0, NULL);
    model(&m, &g, 17);
    expect_refused(&m, "cyclic graph", "first");
    free(m.p); memset(&m, 0, sizeof m);
    /* huge graph input */
    node(&g, "Relu", "r", "x", NULL, "y", NULL);
    value_info(&g, 11, "x", 4, (int64_t[]){ 1, 3, 100000000, 100000000 });
    value_info(&g, 12, "y", 0, NULL);
    model(&m, &g, 17);
    expect_refused(&m, "huge input dims", NULL);
    free(m.p); memset(&m, 0, sizeof m);
    /* input fine, output of an Expand huge: refused at shape inference */
    {
        pbw t = { 0 };
        f_varint(&t, 1, 4);
        f_varint(&t, 2, 7);
        f_str(&t, 8, "shape");
        int64_t sh[4] = { 1 << 20, 1 << 20, 1 << 10, 1 };
        f_bytes(&t, 9, sh, sizeof sh);
        f_msg(&g, 5, &t);
    }
    node(&g, "Expand", "expand0", "x", "shape", "y", NULL);
    value_info(&g, 11, "x", 1, (int64_t[]){ 1 });
    value_info(&g, 12, "y", 0, NULL);
    model(&m, &g, 17);
    expect_refused(&m, "huge Expand", "expand0");
    free(m.p); memset(&m, 0, sizeof m);
    /* ConstantOfShape of 2^40 elements */
    {
        pbw t = { 0 };
        f_varint(&t, 1, 2);
        f_varint(&t, 2, 7);
        f_str(&t, 8, "shape");
        int64_t sh[2] = { 1 << 20, 1 << 20 };
        f_bytes(&t, 9, sh, sizeof sh);
        f_msg(&g, 5, &t);
    }
    node(&g, "ConstantOfShape", "cos0", "shape", NULL, "z", NULL);
    node(&g, "Add", "add0", "x", "z", "y", NULL);
    value_info(&g, 11, "x", 1, (int64_t[]){ 1 });
    value_info(&g, 12, "y", 0, NULL);
    model(&m, &g, 17);
    expect_refused(&m, "huge ConstantOfShape", "cos0");
    free(m.p); memset(&m, 0, sizeof m);
    /* 40 ConstantOfShape of 4M elements each: each is under the per-tensor limit, together far over
     * what a 300-byte file may make the loader compute */
    {
        pbw t = { 0 };
        f_varint(&t, 1, 2);
        f_varint(&t, 2, 7);
        f_str(&t, 8, "shape");
        int64_t sh[2] = { 2048, 2048 };
        f_bytes(&t, 9, sh, sizeof sh);
        f_msg(&g, 5, &t);
        for (int i = 0; i < 40; i++) {
            char out[16];
            snprintf(out, sizeof out, "z%d", i);
            node(&g, "ConstantOfShape", out, "shape", NULL, out, NULL);
        }
    }
    node(&g, "Relu", "r", "x", NULL, "y", NULL);
    value_info(&g, 11, "x", 1, (int64_t[]){ 1 });
    value_info(&g, 12, "y", 0, NULL);
    model(&m, &g, 17);
    expect_refused(&m, "many big folded constants", "budget");
    free(m.p); memset(&m, 0, sizeof m);
    /* unsupported op: named with its node */
    node(&g, "Relu", "ok0", "x", NULL, "r", NULL);
    node(&g, "NonMaxSuppression", "nms7", "r", NULL, "y", NULL);
    value_info(&g, 11, "x", 1, (int64_t[]){ 4 });
    value_info(&g, 12, "y", 0, NULL);
    model(&m, &g, 17);
    expect_refused(&m, "unsupported op", "op 'NonMaxSuppression' is not supported");
    CHECK(strstr(pg_last_error(), "nms7") != NULL, "unsupported op message lacks the node name: %s", pg_last_error());
    free(m.p); memset(&m, 0, sizeof m);
    /* symbolic batch dim */
    node(&g, "Relu", "r", "x", NULL, "y", NULL);
    value_info(&g, 11, "x", 2, (int64_t[]){ -1, 4 });
    value_info(&g, 12, "y", 0, NULL);
    model(&m, &g, 17);
    expect_refused(&m, "symbolic dim", "symbolic");
    free(m.p); memset(&m, 0, sizeof m);
    /* external data */
    {
        pbw t = { 0 };
        f_varint(&t, 1, 4);
        f_varint(&t, 2, 1);
        f_str(&t, 8, "w");
        f_varint(&t, 14, 1);
        f_msg(&g, 5, &t);
    }
    node(&g, "Mul", "mul0", "x", "w", "y", NULL);
    value_info(&g, 11, "x", 1, (int64_t[]){ 4 });
    value_info(&g, 12, "y", 0, NULL);
    model(&m, &g, 17);
    expect_refused(&m, "external data", "external data");
    free(m.p); memset(&m, 0, sizeof m);
    /* conv weight that does not fit the input channels */
    initializer(&g, "w", 4, (int64_t[]){ 3, 5, 3, 3 }, 135, 0.5f, -1);
    node(&g, "Conv", "conv_bad", "x", "w", "y", NULL);
    value_info(&g, 11, "x", 4, (int64_t[]){ 1, 2, 4, 4 });
    value_info(&g, 12, "y", 0, NULL);
    model(&m, &g, 17);
    expect_refused(&m, "conv channel mismatch", "conv_bad");
    free(m.p); memset(&m, 0, sizeof m);
    /* old opset */
    node(&g, "Relu", "r", "x", NULL, "y", NULL);
    value_info(&g, 11, "x", 1, (int64_t[]){ 4 });
    value_info(&g, 12, "y", 0, NULL);
    model(&m, &g, 7);
    expect_refused(&m, "opset 7", "opset");
    free(m.p); memset(&m, 0, sizeof m);
    /* a float attribute list claiming more values than allowed */
    f_str(&at, 1, "scales");
    for (int i = 0; i < 100; i++) f_float(&at, 7, 1.0f);
    f_msg(&a, 5, &at);
    node(&g, "Relu", "many_attrs", "x", NULL, "y", &a);
    value_info(&g, 11, "x", 1, (int64_t[]){ 4 });
    value_info(&g, 12, "y", 0, NULL);
    model(&m, &g, 17);
    expect_refused(&m, "attribute list too long", "many_attrs");
    free(m.p); memset(&m, 0, sizeof m);
    /* empty file and garbage */
    expect_refused(&m, "empty file", NULL);
    put(&m, "\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff\xff", 12);
    expect_refused(&m, "garbage", NULL);
    free(m.p);
}

/* The IR directly: a cycle and a missing producer are refused by nn_graph_prepare. */
static void test_graph_cycle(void)
{
    nn_graph g;
    nn_graph_init(&g);
    int x, a, b;
    CHECK_OK(nn_graph_add_tensor(&g, "x", NN_F32, 1, (int64_t[]){ 4 }, &x));
    CHECK_OK(nn_graph_add_tensor(&g, "a", NN_F32, -1, NULL, &a));
    CHECK_OK(nn_graph_add_tensor(&g, "b", NN_F32, -1, NULL, &b));
    CHECK_OK(nn_graph_add_node(&g, NN_OP_ADD, "n0", (int[]){ x, b }, 2, &a, 1, NULL, NULL));
    CHECK_OK(nn_graph_add_node(&g, NN_OP_RELU, "n1", (int[]){ a }, 1, &b, 1, NULL, NULL));
    CHECK_OK(nn_graph_set_io(&g, &x, 1, &b, 1));
    pg_status st = nn_graph_prepare(&g);
    CHECK(st != PG_OK && strstr(pg_last_error(), "cycle"), "IR cycle: %s", st ? pg_last_error() : "accepted");
    nn_graph_destroy(&g);
    nn_graph_init(&g);
    CHECK_OK(nn_graph_add_tensor(&g, "x", NN_F32, 1, (int64_t[]){ 4 }, &x));
    CHECK_OK(nn_graph_add_tensor(&g, "a", NN_F32, -1, NULL, &a));
    CHECK_OK(nn_graph_add_tensor(&g, "b", NN_F32, -1, NULL, &b));
    CHECK_OK(nn_graph_add_node(&g, NN_OP_ADD, "n0", (int[]){ x, a }, 2, &b, 1, NULL, NULL));
    CHECK_OK(nn_graph_set_io(&g, &x, 1, &b, 1));
    st = nn_graph_prepare(&g);
    CHECK(st != PG_OK && strstr(pg_last_error(), "never computed"), "IR missing producer: %s", st ? pg_last_error() : "accepted");
    nn_graph_destroy(&g);
    CHECK(nn_graph_add_tensor(&g, "big", NN_F32, 2, (int64_t[]){ 1 << 20, 1 << 20 }, &x) == PG_ERR_SIZE, "huge IR tensor accepted");
    nn_graph_destroy(&g);
}

/* The fuzz seeds (tests/fuzz/corpus/onnx, made by tests/nn/make_fuzz_seeds.py) all load and run. */
static void test_seeds(void)
{
    const char *seeds[] = { "conv_relu", "convtranspose_gelu", "layernorm", "matmul_softmax", "resize", "shape_chain", "slice_pad" };
    for (size_t i = 0; i < sizeof seeds / sizeof seeds[0]; i++) {
        char path[1024];
        snprintf(path, sizeof path, "%s/tests/fuzz/corpus/onnx/%s.onnx", PG_SOURCE_DIR, seeds[i]);
        nn_model *m;
        pg_status st = nn_model_load(path, &m);
        CHECK(st == PG_OK, "seed %s: %s", seeds[i], st ? pg_last_error() : "");
        if (st) continue;
        int64_t d[NN_MAX_DIMS];
        size_t ni = (size_t)nn_shape_count(nn_model_input_shape(m, d), d);
        size_t no = (size_t)nn_shape_count(nn_model_output_shape(m, d), d);
        float *x = calloc(ni, sizeof(float)), *y = calloc(no, sizeof(float));
        for (size_t k = 0; k < ni; k++) x[k] = (float)k / (float)ni - 0.5f;
        CHECK_OK(nn_model_run(m, x, y, 2));
        free(x);
        free(y);
        nn_model_destroy(m);
        /* 300 random byte flips of each seed: refused or run, never a crash (ASan build) */
        FILE *f = fopen(path, "rb");
        uint8_t buf[4096];
        size_t n = f ? fread(buf, 1, sizeof buf, f) : 0;
        if (f) fclose(f);
        pg_rng rng;
        pg_rng_seed(&rng, 100 + i);
        int loaded = 0;
        for (int k = 0; k < 300 && n; k++) {
            uint8_t c[4096];
            memcpy(c, buf, n);
            int flips = 1 + (int)(pg_rng_uniform(&rng) * 3);
            for (int t = 0; t < flips; t++) c[(size_t)(pg_rng_uniform(&rng) * n) % n] ^= (uint8_t)(1 + pg_rng_uniform(&rng) * 255);
            nn_model *fm = NULL;
            if (nn_model_load_memory(c, n, "flip.onnx", &fm) != PG_OK) continue;
            loaded++;
            int64_t dd[NN_MAX_DIMS];
            size_t fi = (size_t)nn_shape_count(nn_model_input_shape(fm, dd), dd);
            size_t fo = (size_t)nn_shape_count(nn_model_output_shape(fm, dd), dd);
            if (nn_model_memory_bytes(fm) < ((size_t)64 << 20)) {
                float *xi = calloc(fi + 1, sizeof(float)), *yo = calloc(fo + 1, sizeof(float));
                CHECK_OK(nn_model_run(fm, xi, yo, 2));
                free(xi);
                free(yo);
            }
            nn_model_destroy(fm);
        }
        printf("  seed %-20s loads and runs; 300 byte flips: %d still load\n", seeds[i], loaded);
    }
}

/* The CLI: a hostile model is exit 2 with one line on stderr; a valid one prints one JSON line. */
static void test_cli(void)
{
    char dir[512], path[600], args[1400], err[2048];
    test_tmpdir("nn_hostile", dir, sizeof dir);
    pbw m = { 0 }, g = { 0 };
    node(&g, "Relu", "ok0", "x", NULL, "r", NULL);
    node(&g, "NonMaxSuppression", "nms7", "r", NULL, "y", NULL);
    value_info(&g, 11, "x", 1, (int64_t[]){ 4 });
    value_info(&g, 12, "y", 0, NULL);
    model(&m, &g, 17);
    snprintf(path, sizeof path, "%s/unsupported.onnx", dir);
    FILE *f = fopen(path, "wb");
    if (f) { fwrite(m.p, 1, m.n, f); fclose(f); }
    free(m.p);
    snprintf(args, sizeof args, "bench nn --model '%s'", path);
    int rc = test_run_cli(args, err, sizeof err);
    size_t len = strlen(err);
    CHECK(rc == 2, "bench nn on an unsupported model: exit %d (2 expected)", rc);
    CHECK(strncmp(err, "prodygs: ", 9) == 0 && strstr(err, "NonMaxSuppression") && strstr(err, "nms7") &&
          len > 0 && strchr(err, '\n') == err + len - 1, "stderr is not one line naming the op and node: '%s'", err);
    printf("  CLI: exit %d, %s", rc, err);
    memset(&m, 0, sizeof m);
    valid_model(&m);
    snprintf(path, sizeof path, "%s/valid.onnx", dir);
    f = fopen(path, "wb");
    if (f) { fwrite(m.p, 1, m.n, f); fclose(f); }
    free(m.p);
    snprintf(args, sizeof args, "bench nn --model '%s' --threads 2 --reps 2", path);
    rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 0, "bench nn on a valid model: exit %d: %s", rc, err);
}

/* 256 MiB activations declared by a 100-byte file: loading plans the arena but must not touch it
 * (fuzz_onnx spent seconds zeroing such arenas; only a run may fault the pages in). Runs first, so
 * the peak RSS it compares against is not an earlier test's. */
static void test_untouched_arena(void)
{
    pbw g = { 0 }, m = { 0 };
    node(&g, "Relu", "r", "x", NULL, "y", NULL);
    value_info(&g, 11, "x", 2, (int64_t[]){ 4, (int64_t)1 << 24 });
    value_info(&g, 12, "y", 0, NULL);
    model(&m, &g, 17);
    {
        struct rusage ru0, ru1;
        getrusage(RUSAGE_SELF, &ru0);
        nn_model *nm = NULL;
        CHECK_OK(nn_model_load_memory(m.p, m.n, "big_arena.onnx", &nm));
        getrusage(RUSAGE_SELF, &ru1);
        CHECK(nm && nn_model_memory_bytes(nm) >= ((size_t)256 << 20), "planned arena %zu bytes",
              nm ? nn_model_memory_bytes(nm) : 0);
        /* ASan's shadow of the allocation (an eighth of it, 64 MiB) is allowed */
        CHECK(ru1.ru_maxrss - ru0.ru_maxrss < 128 * 1024, "loading touched %ld KiB of a 512 MiB arena",
              ru1.ru_maxrss - ru0.ru_maxrss);
        nn_model_destroy(nm);
    }
    free(m.p);
}

int main(void)
{
    test_untouched_arena();
    test_seeds();
    test_cli();
    test_valid();
    test_hostile();
    test_graph_cycle();
    return test_summary("test_nn_hostile");
}
