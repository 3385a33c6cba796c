/* onnx_import.c - ONNX ModelProto -> graph IR (nn_graph.h).
 *
 * The file is walked with the bounds-checked wire reader (onnx_wire.h); nothing is allocated
 * from a size before the bytes backing it are known to be there. Initializers become constants
 * (float32 from raw_data / float_data / double_data / float16; integer types as int64; external
 * data is refused). Nodes are taken in file order, which ONNX requires to be topological: an
 * input not defined earlier is an error, so cyclic graphs are refused here. Each node is either
 *   - an alias (Identity, Dropout, Cast float->float): its output names the input tensor;
 *   - folded at import by the small constant evaluator below (Shape, Gather, Concat, Cast,
 *     ConstantOfShape, Equal, Where, Range, ... on int64 or small constants), or
 *   - a runtime node, its constant shape-like inputs turned into attributes (Reshape's shape,
 *     Slice's starts/ends, Resize's sizes/scales, Pad's pads, Unsqueeze's axes...). Its shapes are
 *     inferred at once (nn_node_infer) so later Shape / Flatten / Squeeze see them.
 * The first op that fits none of these is reported with its node name and index.
 */
#include "nn/nn_graph.h"
#include "nn/onnx_wire.h"
#include "io/npy.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define ONNX_MAX_ATTRS 64
#define ONNX_MAX_LIST 64              /* ints / floats in one attribute */
#define ONNX_MAX_NODE_IO 4096
#define ONNX_EVAL_MAX ((int64_t)1 << 24) /* elements the constant evaluator produces */

enum { T_FLOAT = 1, T_UINT8 = 2, T_INT8 = 3, T_UINT16 = 4, T_INT16 = 5, T_INT32 = 6, T_INT64 = 7, T_STRING = 8,
       T_BOOL = 9, T_FLOAT16 = 10, T_DOUBLE = 11, T_UINT32 = 12, T_UINT64 = 13, T_BFLOAT16 = 16 };

typedef struct { const uint8_t *p; size_t n; } span;

typedef struct {
    span name;
    int type;
    float f;
    int64_t i;
    span s, t;
    int num_ints, num_floats;
    int64_t ints[ONNX_MAX_LIST];
    float floats[ONNX_MAX_LIST];
} onnx_attr;

typedef struct { const uint8_t *key; size_t len; int id; } name_slot;

typedef struct {
    const char *path;
    nn_graph *g;
    name_slot *map;
    size_t cap, count;
    int opset;
    size_t fold_left;   /* bytes the constant evaluator may still produce (64 MiB + 8 x the file) */
    /* the node being converted, for messages */
    char node[160];
    char op[64];
    int index;
} onnx_ctx;

/* double -> int64 without undefined behaviour: NaN -> 0, out of range -> saturated. */
static int64_t d2i(double v)
{
    if (v != v) return 0;
    if (v >= 9.2e18) return INT64_MAX;
    if (v <= -9.2e18) return INT64_MIN;
    return (int64_t)v;
}

static int span_eq(span a, const char *s) { return a.n == strlen(s) && (a.n == 0 || memcmp(a.p, s, a.n) == 0); }

static void span_str(span a, char *out, size_t size)
{
    size_t n = a.n < size - 1 ? a.n : size - 1;
    for (size_t i = 0; i < n; i++) out[i] = a.p[i] >= 32 && a.p[i] < 127 ? (char)a.p[i] : '?';
    out[n] = 0;
}

static pg_status bad(onnx_ctx *c, const char *what)
{
    return pg_fail(PG_ERR_FORMAT, "%s: %s", c->path, what);
}

static pg_status node_fail(onnx_ctx *c, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static pg_status node_fail(onnx_ctx *c, const char *fmt, ...)
{
    char msg[400];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return pg_fail(PG_ERR_FORMAT, "%s: node %d '%s' (%s): %s", c->path, c->index, c->node, c->op, msg);
}

/* ---- name -> tensor id map (open addressing, FNV-1a) ---- */

static uint64_t hash_span(const uint8_t *p, size_t n)
{
    uint64_t h = 1469598103934665603ull;
    for (size_t i = 0; i < n; i++) h = (h ^ p[i]) * 1099511628211ull;
    return h;
}

static int map_get(const onnx_ctx *c, span name)
{
    if (!c->cap) return -1;
    for (size_t i = hash_span(name.p, name.n) & (c->cap - 1);; i = (i + 1) & (c->cap - 1)) {
        const name_slot *s = &c->map[i];
        if (!s->key) return -1;
        if (s->len == name.n && (name.n == 0 || memcmp(s->key, name.p, name.n) == 0)) return s->id;
    }
}

static pg_status map_put(onnx_ctx *c, span name, int id)
{
    if ((c->count + 1) * 2 > c->cap) {
        size_t cap = c->cap ? c->cap * 2 : 1024;
        name_slot *m = calloc(cap, sizeof *m);
        if (!m) return pg_fail(PG_ERR_NOMEM, "%s: out of memory for the name table", c->path);
        for (size_t i = 0; i < c->cap; i++) {
            if (!c->map[i].key) continue;
            size_t j = hash_span(c->map[i].key, c->map[i].len) & (cap - 1);
            while (m[j].key) j = (j + 1) & (cap - 1);
            m[j] = c->map[i];
        }
        free(c->map);
        c->map = m;
        c->cap = cap;
    }
    size_t i = hash_span(name.p, name.n) & (c->cap - 1);
    while (c->map[i].key && !(c->map[i].len == name.n && (name.n == 0 || memcmp(c->map[i].key, name.p, name.n) == 0)))
        i = (i + 1) & (c->cap - 1);
    if (!c->map[i].key) c->count++;
    c->map[i] = (name_slot){ name.p ? name.p : (const uint8_t *)"", name.n, id };
    return PG_OK;
}

/* ---- TensorProto ---- */

static int elem_bytes(int type)
{
    switch (type) {
    case T_FLOAT: case T_INT32: case T_UINT32: return 4;
    case T_DOUBLE: case T_INT64: case T_UINT64: return 8;
    case T_FLOAT16: case T_BFLOAT16: case T_INT16: case T_UINT16: return 2;
    case T_INT8: case T_UINT8: case T_BOOL: return 1;
    default: return 0;
    }
}

static float bf16_to_float(uint16_t h)
{
    uint32_t bits = (uint32_t)h << 16;
    float f;
    memcpy(&f, &bits, 4);
    return f;
}

/* Value i of little-endian raw data of the given type, as double. */
static double raw_value(const uint8_t *p, int type)
{
    uint64_t u = 0;
    int nb = elem_bytes(type);
    for (int i = nb - 1; i >= 0; i--) u = (u << 8) | p[i];
    switch (type) {
    case T_FLOAT: { uint32_t b = (uint32_t)u; float f; memcpy(&f, &b, 4); return f; }
    case T_DOUBLE: { double d; memcpy(&d, &u, 8); return d; }
    case T_FLOAT16: return io_half_to_float((uint16_t)u);
    case T_BFLOAT16: return bf16_to_float((uint16_t)u);
    case T_INT8: return (int8_t)u;
    case T_INT16: return (int16_t)u;
    case T_INT32: return (int32_t)u;
    case T_INT64: return (double)(int64_t)u;
    case T_UINT64: return (double)u;
    default: return (double)u; /* uint8/16/32, bool */
    }
}

static int is_float_type(int type) { return type == T_FLOAT || type == T_DOUBLE || type == T_FLOAT16 || type == T_BFLOAT16; }

/* Parses a TensorProto into a new graph constant (float types -> NN_F32, integer -> NN_I64).
 * name_override (if set) replaces the tensor's own name. */
static pg_status parse_tensor(onnx_ctx *c, span bytes, span name_override, int *id)
{
    pb_reader r = { bytes.p, bytes.p + bytes.n };
    pb_field f;
    int rc, type = 0, ndim = 0, external = 0;
    int64_t dims[NN_MAX_DIMS];
    span name = { (const uint8_t *)"", 0 }, raw = { NULL, 0 };
    span packed = { NULL, 0 };
    int packed_field = 0;
    int64_t unpacked = 0; /* count of unpacked repeated values */
    int unpacked_field = 0;
    while ((rc = pb_next(&r, &f)) > 0) {
        switch (f.number) {
        case 1: /* dims: varint or packed */
            if (f.wire == PB_VARINT) {
                if (ndim >= NN_MAX_DIMS) return bad(c, "initializer with more than 6 dims");
                dims[ndim++] = (int64_t)f.v;
            } else if (f.wire == PB_LEN) {
                const uint8_t *p = f.data, *e = f.data + f.len;
                while (p < e) {
                    uint64_t v;
                    if (pb_varint(&p, e, &v)) return bad(c, "corrupt tensor dims");
                    if (ndim >= NN_MAX_DIMS) return bad(c, "initializer with more than 6 dims");
                    dims[ndim++] = (int64_t)v;
                }
            }
            break;
        case 2: if (f.wire == PB_VARINT) type = (int)f.v; break;
        case 8: if (f.wire == PB_LEN) name = (span){ f.data, f.len }; break;
        case 9: if (f.wire == PB_LEN) raw = (span){ f.data, f.len }; break;
        case 14: if (f.wire == PB_VARINT && f.v == 1) external = 1; break;
        case 13: external = 1; break;
        case 4: case 5: case 7: case 10: case 11:
            if (f.wire == PB_LEN) { packed = (span){ f.data, f.len }; packed_field = (int)f.number; }
            else { unpacked++; unpacked_field = (int)f.number; }
            break;
        default: break;
        }
    }
    if (rc < 0) return bad(c, "corrupt TensorProto");
    if (name_override.p) name = name_override;
    char nm[128];
    span_str(name, nm, sizeof nm);
    if (external) return pg_fail(PG_ERR_FORMAT, "%s: tensor '%s' uses external data (save the model with all weights inside the .onnx file)", c->path, nm);
    int64_t count = 1;
    for (int i = 0; i < ndim; i++) {
        if (dims[i] < 0 || dims[i] > NN_MAX_DIM) return pg_fail(PG_ERR_SIZE, "%s: tensor '%s' dim %d is %lld", c->path, nm, i, (long long)dims[i]);
        count *= dims[i];
        if (count > NN_MAX_ELEMENTS) return pg_fail(PG_ERR_SIZE, "%s: tensor '%s' has more than %lld elements", c->path, nm, (long long)NN_MAX_ELEMENTS);
    }
    int eb = elem_bytes(type);
    if (!eb) return pg_fail(PG_ERR_FORMAT, "%s: tensor '%s' has unsupported data type %d", c->path, nm, type);
    /* check the data is there before allocating */
    int src_kind; /* 0 raw, 1 packed, 2 unpacked */
    if (raw.p) {
        if ((uint64_t)raw.n != (uint64_t)count * (uint64_t)eb)
            return pg_fail(PG_ERR_FORMAT, "%s: tensor '%s' has %zu bytes of raw data for %lld values", c->path, nm, raw.n, (long long)count);
        src_kind = 0;
    } else if (packed.p) {
        int64_t have;
        if (packed_field == 4 || packed_field == 10) {
            int w = packed_field == 4 ? 4 : 8;
            if (packed.n % (size_t)w) return pg_fail(PG_ERR_FORMAT, "%s: tensor '%s': truncated packed data", c->path, nm);
            have = (int64_t)(packed.n / (size_t)w);
        } else have = pb_count_varints(packed.p, packed.n);
        if (have != count) return pg_fail(PG_ERR_FORMAT, "%s: tensor '%s' has %lld values for %lld elements", c->path, nm, (long long)have, (long long)count);
        src_kind = 1;
    } else {
        if (unpacked != count) return pg_fail(PG_ERR_FORMAT, "%s: tensor '%s' has %lld values for %lld elements", c->path, nm, (long long)unpacked, (long long)count);
        src_kind = 2;
        (void)unpacked_field;
    }
    int fl = is_float_type(type);
    void *data = pg_malloc((size_t)(count ? count : 1) * (fl ? sizeof(float) : sizeof(int64_t)), nm);
    if (!data) return PG_ERR_NOMEM;
    float *df = data;
    int64_t *di = data;
    const uint16_t endian_probe = 1;
    int little = *(const uint8_t *)&endian_probe == 1;
    if (src_kind == 0 && type == T_FLOAT && little) {
        memcpy(df, raw.p, (size_t)count * 4); /* the common case: float32 weights as stored */
    } else if (src_kind == 0) {
        for (int64_t i = 0; i < count; i++) {
            double v = raw_value(raw.p + i * eb, type);
            if (fl) df[i] = (float)v;
            else if (type == T_INT64) { uint64_t u = 0; for (int b = 7; b >= 0; b--) u = (u << 8) | raw.p[i * 8 + b]; di[i] = (int64_t)u; }
            else di[i] = d2i(v);
        }
    } else {
        /* float_data (4) holds float / float16 bits? no: float16 uses int32_data (5); double_data (10) */
        pb_reader pr = { bytes.p, bytes.p + bytes.n };
        int64_t i = 0;
        while (pb_next(&pr, &f) > 0 && i < count) {
            if (!(f.number == 4 || f.number == 5 || f.number == 7 || f.number == 10 || f.number == 11)) continue;
            if (f.wire == PB_LEN) {
                const uint8_t *p = f.data, *e = f.data + f.len;
                while (p < e && i < count) {
                    double v;
                    if (f.number == 4) { uint32_t b = (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24; float x; memcpy(&x, &b, 4); v = x; p += 4; }
                    else if (f.number == 10) { uint64_t u = 0; for (int b = 7; b >= 0; b--) u = (u << 8) | p[b]; memcpy(&v, &u, 8); p += 8; }
                    else {
                        uint64_t u;
                        if (pb_varint(&p, e, &u)) { free(data); return bad(c, "corrupt packed tensor data"); }
                        if (f.number == 7) { if (!fl) { di[i++] = (int64_t)u; continue; } v = (double)(int64_t)u; }
                        else if (type == T_FLOAT16) v = io_half_to_float((uint16_t)u);
                        else if (type == T_BFLOAT16) v = bf16_to_float((uint16_t)u);
                        else if (f.number == 5) v = (double)(int32_t)(uint32_t)u;
                        else v = (double)u;
                    }
                    if (fl) df[i++] = (float)v; else di[i++] = d2i(v);
                }
            } else {
                double v;
                if (f.wire == PB_I32) v = pb_float(&f);
                else if (f.wire == PB_I64) { uint64_t u = f.v; memcpy(&v, &u, 8); }
                else if (f.number == 7) { if (!fl) { di[i++] = (int64_t)f.v; continue; } v = (double)(int64_t)f.v; }
                else if (type == T_FLOAT16) v = io_half_to_float((uint16_t)f.v);
                else if (f.number == 5) v = (double)(int32_t)(uint32_t)f.v;
                else v = (double)f.v;
                if (fl) df[i++] = (float)v; else di[i++] = d2i(v);
            }
        }
        if (i != count) { free(data); return pg_fail(PG_ERR_FORMAT, "%s: tensor '%s': data does not match its type", c->path, nm); }
    }
    return nn_graph_add_const(c->g, nm, fl ? NN_F32 : NN_I64, ndim, dims, data, id);
}

/* ---- AttributeProto ---- */

static pg_status parse_attr(onnx_ctx *c, span bytes, onnx_attr *a)
{
    memset(a, 0, sizeof *a);
    pb_reader r = { bytes.p, bytes.p + bytes.n };
    pb_field f;
    int rc;
    while ((rc = pb_next(&r, &f)) > 0) {
        switch (f.number) {
        case 1: if (f.wire == PB_LEN) a->name = (span){ f.data, f.len }; break;
        case 20: if (f.wire == PB_VARINT) a->type = (int)f.v; break;
        case 2: if (f.wire == PB_I32) a->f = pb_float(&f); break;
        case 3: if (f.wire == PB_VARINT) a->i = (int64_t)f.v; break;
        case 4: if (f.wire == PB_LEN) a->s = (span){ f.data, f.len }; break;
        case 5: if (f.wire == PB_LEN) a->t = (span){ f.data, f.len }; break;
        case 7:
            if (f.wire == PB_I32) {
                if (a->num_floats >= ONNX_MAX_LIST) return node_fail(c, "attribute list too long");
                a->floats[a->num_floats++] = pb_float(&f);
            } else if (f.wire == PB_LEN) {
                if (f.len % 4 || f.len / 4 + (size_t)a->num_floats > ONNX_MAX_LIST) return node_fail(c, "bad float list attribute");
                for (size_t k = 0; k < f.len; k += 4) {
                    pb_field t = { .v = (uint64_t)f.data[k] | (uint64_t)f.data[k + 1] << 8 | (uint64_t)f.data[k + 2] << 16 | (uint64_t)f.data[k + 3] << 24 };
                    a->floats[a->num_floats++] = pb_float(&t);
                }
            }
            break;
        case 8:
            if (f.wire == PB_VARINT) {
                if (a->num_ints >= ONNX_MAX_LIST) return node_fail(c, "attribute list too long");
                a->ints[a->num_ints++] = (int64_t)f.v;
            } else if (f.wire == PB_LEN) {
                const uint8_t *p = f.data, *e = f.data + f.len;
                while (p < e) {
                    uint64_t v;
                    if (pb_varint(&p, e, &v) || a->num_ints >= ONNX_MAX_LIST) return node_fail(c, "bad int list attribute");
                    a->ints[a->num_ints++] = (int64_t)v;
                }
            }
            break;
        case 6: case 10: case 11: return node_fail(c, "graph / tensor-list attributes (control flow) are not supported");
        default: break;
        }
    }
    if (rc < 0) return node_fail(c, "corrupt attribute");
    return PG_OK;
}

static const onnx_attr *find_attr(const onnx_attr *a, int n, const char *name)
{
    for (int i = 0; i < n; i++) if (span_eq(a[i].name, name)) return &a[i];
    return NULL;
}

static int64_t attr_i(const onnx_attr *a, int n, const char *name, int64_t def)
{
    const onnx_attr *x = find_attr(a, n, name);
    return x ? x->i : def;
}

static float attr_f(const onnx_attr *a, int n, const char *name, float def)
{
    const onnx_attr *x = find_attr(a, n, name);
    return x ? x->f : def;
}

/* ---- constants as double arrays (the evaluator's working form) ---- */

typedef struct {
    int is_int;
    int ndim;
    int64_t dims[NN_MAX_DIMS];
    int64_t n;
    double *v;
} cval;

static void cval_free(cval *x) { free(x->v); x->v = NULL; }

static int is_const(const onnx_ctx *c, int id) { return id >= 0 && c->g->tensors[id].data != NULL; }

static pg_status cval_get(onnx_ctx *c, int id, cval *x)
{
    const nn_tensor *t = &c->g->tensors[id];
    memset(x, 0, sizeof *x);
    x->is_int = t->dtype == NN_I64;
    x->ndim = t->ndim;
    memcpy(x->dims, t->dims, sizeof x->dims);
    x->n = nn_shape_count(t->ndim, t->dims);
    if (x->n > ONNX_EVAL_MAX) return node_fail(c, "constant '%s' too large to fold", t->name);
    x->v = pg_malloc((size_t)(x->n ? x->n : 1) * sizeof(double), "constant");
    if (!x->v) return PG_ERR_NOMEM;
    for (int64_t i = 0; i < x->n; i++)
        x->v[i] = x->is_int ? (double)((int64_t *)t->data)[i] : (double)((float *)t->data)[i];
    return PG_OK;
}

static pg_status cval_alloc(onnx_ctx *c, cval *x, int is_int, int ndim, const int64_t *dims)
{
    memset(x, 0, sizeof *x);
    if (ndim < 0 || ndim > NN_MAX_DIMS) return node_fail(c, "folded value has %d dims", ndim);
    x->is_int = is_int;
    x->ndim = ndim;
    x->n = 1;
    for (int i = 0; i < ndim; i++) {
        if (dims[i] < 0 || dims[i] > NN_MAX_DIM) return node_fail(c, "folded value dim %lld", (long long)dims[i]);
        x->dims[i] = dims[i];
        x->n *= dims[i];
        if (x->n > ONNX_EVAL_MAX) return node_fail(c, "folded value too large");
    }
    x->v = pg_calloc((size_t)(x->n ? x->n : 1), sizeof(double), "folded constant");
    return x->v ? PG_OK : PG_ERR_NOMEM;
}

/* Adds x as a graph constant named by output span out and maps the name. Frees x. */
static pg_status cval_put(onnx_ctx *c, span out, cval *x)
{
    char nm[128];
    span_str(out, nm, sizeof nm);
    size_t bytes = (size_t)(x->n ? x->n : 1) * (x->is_int ? sizeof(int64_t) : sizeof(float));
    if (bytes > c->fold_left) { cval_free(x); return node_fail(c, "constants folded at load exceed the budget (64 MiB + 8 x the file size)"); }
    c->fold_left -= bytes;
    void *data = pg_malloc(bytes, nm);
    if (!data) { cval_free(x); return PG_ERR_NOMEM; }
    for (int64_t i = 0; i < x->n; i++) {
        if (x->is_int) {
            double v = x->v[i];
            ((int64_t *)data)[i] = d2i(v);
        } else ((float *)data)[i] = (float)x->v[i];
    }
    int id;
    pg_status st = nn_graph_add_const(c->g, nm, x->is_int ? NN_I64 : NN_F32, x->ndim, x->dims, data, &id);
    cval_free(x);
    if (st) return st;
    return map_put(c, out, id);
}

/* int64 values of a constant tensor (at most max); returns count or -1. */
static int const_ints(const onnx_ctx *c, int id, int64_t *out, int max)
{
    if (!is_const(c, id)) return -1;
    const nn_tensor *t = &c->g->tensors[id];
    int64_t n = nn_shape_count(t->ndim, t->dims);
    if (n > max) return -1;
    for (int64_t i = 0; i < n; i++)
        out[i] = t->dtype == NN_I64 ? ((int64_t *)t->data)[i] : d2i(((float *)t->data)[i]);
    return (int)n;
}

static int const_floats(const onnx_ctx *c, int id, float *out, int max)
{
    if (!is_const(c, id)) return -1;
    const nn_tensor *t = &c->g->tensors[id];
    int64_t n = nn_shape_count(t->ndim, t->dims);
    if (n > max) return -1;
    for (int64_t i = 0; i < n; i++)
        out[i] = t->dtype == NN_I64 ? (float)((int64_t *)t->data)[i] : ((float *)t->data)[i];
    return (int)n;
}

/* Broadcast output shape of k values; -1 if they do not broadcast. */
static int broadcast_shape(const cval *in, int k, int *ndim, int64_t *dims)
{
    int nd = 0;
    for (int i = 0; i < k; i++) nd = in[i].ndim > nd ? in[i].ndim : nd;
    for (int d = 0; d < nd; d++) {
        int64_t v = 1;
        for (int i = 0; i < k; i++) {
            int j = d - (nd - in[i].ndim);
            int64_t x = j >= 0 ? in[i].dims[j] : 1;
            if (x != 1 && v != 1 && x != v) return -1;
            if (x != 1) v = x;
        }
        dims[d] = v;
    }
    *ndim = nd;
    return 0;
}

/* Offset in x of output flat index o for output shape (nd, dims) under broadcasting. */
static int64_t bcast_index(const cval *x, int nd, const int64_t *dims, int64_t o)
{
    int64_t off = 0, stride = 1;
    for (int d = nd - 1; d >= 0; d--) {
        int64_t idx = o % dims[d];
        o /= dims[d];
        int j = d - (nd - x->ndim);
        if (j >= 0) {
            if (x->dims[j] != 1) off += idx * stride;
            stride *= x->dims[j];
        }
    }
    return off;
}

static double binary_eval(span op, double a, double b, int is_int)
{
    if (span_eq(op, "Add")) return a + b;
    if (span_eq(op, "Sub")) return a - b;
    if (span_eq(op, "Mul")) return a * b;
    if (span_eq(op, "Div")) return is_int ? (b != 0 ? trunc(a / b) : 0) : a / b;
    if (span_eq(op, "Pow")) return pow(a, b);
    if (span_eq(op, "Max")) return a > b ? a : b;
    if (span_eq(op, "Min")) return a < b ? a : b;
    if (span_eq(op, "Mod")) return b != 0 ? a - b * floor(a / b) : 0;
    if (span_eq(op, "Equal")) return a == b;
    if (span_eq(op, "Less")) return a < b;
    if (span_eq(op, "Greater")) return a > b;
    if (span_eq(op, "LessOrEqual")) return a <= b;
    if (span_eq(op, "GreaterOrEqual")) return a >= b;
    if (span_eq(op, "And")) return a != 0 && b != 0;
    if (span_eq(op, "Or")) return a != 0 || b != 0;
    return 0;
}

static int is_compare(span op)
{
    return span_eq(op, "Equal") || span_eq(op, "Less") || span_eq(op, "Greater") || span_eq(op, "LessOrEqual") ||
           span_eq(op, "GreaterOrEqual") || span_eq(op, "And") || span_eq(op, "Or");
}

static const char *const EVAL_OPS[] = { "Shape", "Size", "Constant", "ConstantOfShape", "Cast", "Floor", "Ceil", "Neg", "Abs",
    "Sqrt", "Not", "Add", "Sub", "Mul", "Div", "Pow", "Max", "Min", "Mod", "Equal", "Less", "Greater", "LessOrEqual",
    "GreaterOrEqual", "And", "Or", "Where", "Gather", "Concat", "Unsqueeze", "Squeeze", "Reshape", "Flatten", "Slice",
    "Transpose", "Expand", "Range", "DequantizeLinear", "ReduceProd", "Identity", NULL };

static int is_eval_op(span op)
{
    for (int i = 0; EVAL_OPS[i]; i++) if (span_eq(op, EVAL_OPS[i])) return 1;
    return 0;
}

/* Folds one node whose inputs (ids in in[], -1 omitted) are all constants (or, for Shape/Size,
 * have a known shape) into constants named outs[0]. */
static pg_status eval_node(onnx_ctx *c, span op, const int *in, int nin, const span *outs, const onnx_attr *at, int na)
{
    nn_graph *g = c->g;
    cval x[3] = { 0 }, y = { 0 };
    pg_status st = PG_OK;
    if (span_eq(op, "Shape") || span_eq(op, "Size")) {
        const nn_tensor *t = &g->tensors[in[0]];
        if (t->ndim < 0) return node_fail(c, "input shape unknown");
        if (span_eq(op, "Size")) {
            PG_TRY(cval_alloc(c, &y, 1, 0, NULL));
            y.v[0] = (double)nn_shape_count(t->ndim, t->dims);
        } else {
            int64_t s = attr_i(at, na, "start", 0), e = attr_i(at, na, "end", t->ndim);
            if (s < 0) s += t->ndim;
            if (e < 0) e += t->ndim;
            s = s < 0 ? 0 : s > t->ndim ? t->ndim : s;
            e = e < s ? s : e > t->ndim ? t->ndim : e;
            int64_t n = e - s;
            PG_TRY(cval_alloc(c, &y, 1, 1, &n));
            for (int64_t i = 0; i < n; i++) y.v[i] = (double)t->dims[s + i];
        }
        return cval_put(c, outs[0], &y);
    }
    if (span_eq(op, "Constant")) {
        const onnx_attr *a;
        if ((a = find_attr(at, na, "value")) && a->t.p) {
            int id;
            PG_TRY(parse_tensor(c, a->t, outs[0], &id));
            return map_put(c, outs[0], id);
        }
        if ((a = find_attr(at, na, "value_float"))) { PG_TRY(cval_alloc(c, &y, 0, 0, NULL)); y.v[0] = a->f; }
        else if ((a = find_attr(at, na, "value_int"))) { PG_TRY(cval_alloc(c, &y, 1, 0, NULL)); y.v[0] = (double)a->i; }
        else if ((a = find_attr(at, na, "value_floats"))) {
            int64_t n = a->num_floats;
            PG_TRY(cval_alloc(c, &y, 0, 1, &n));
            for (int i = 0; i < a->num_floats; i++) y.v[i] = a->floats[i];
        } else if ((a = find_attr(at, na, "value_ints"))) {
            int64_t n = a->num_ints;
            PG_TRY(cval_alloc(c, &y, 1, 1, &n));
            for (int i = 0; i < a->num_ints; i++) y.v[i] = (double)a->ints[i];
        } else return node_fail(c, "Constant without a supported value attribute");
        return cval_put(c, outs[0], &y);
    }
    if (nin < 1 || in[0] < 0) return node_fail(c, "first input missing");
    for (int i = 0; i < nin && i < 3; i++)
        if (in[i] >= 0 && (st = cval_get(c, in[i], &x[i]))) goto done;
    if (span_eq(op, "ConstantOfShape")) {
        int64_t dims[NN_MAX_DIMS];
        if (x[0].n > NN_MAX_DIMS) { st = node_fail(c, "shape of %lld dims", (long long)x[0].n); goto done; }
        for (int i = 0; i < x[0].n; i++) dims[i] = d2i(x[0].v[i]);
        const onnx_attr *a = find_attr(at, na, "value");
        int is_int = 0;
        double v = 0;
        if (a && a->t.p) {
            int id;
            if ((st = parse_tensor(c, a->t, (span){ (const uint8_t *)"value", 5 }, &id))) goto done;
            const nn_tensor *t = &g->tensors[id];
            if (nn_shape_count(t->ndim, t->dims) < 1) { st = node_fail(c, "empty value"); goto done; }
            is_int = t->dtype == NN_I64;
            v = is_int ? (double)((int64_t *)t->data)[0] : ((float *)t->data)[0];
        }
        if ((st = cval_alloc(c, &y, is_int, (int)x[0].n, dims))) goto done;
        for (int64_t i = 0; i < y.n; i++) y.v[i] = v;
    } else if (span_eq(op, "Cast")) {
        int64_t to = attr_i(at, na, "to", T_FLOAT);
        if ((st = cval_alloc(c, &y, !is_float_type((int)to), x[0].ndim, x[0].dims))) goto done;
        for (int64_t i = 0; i < y.n; i++) {
            double v = x[0].v[i];
            y.v[i] = to == T_BOOL ? (v != 0) : is_float_type((int)to) ? (double)(float)v : trunc(v);
        }
    } else if (span_eq(op, "Identity")) {
        y = x[0];
        x[0].v = NULL;
    } else if (span_eq(op, "Floor") || span_eq(op, "Ceil") || span_eq(op, "Neg") || span_eq(op, "Abs") ||
               span_eq(op, "Sqrt") || span_eq(op, "Not")) {
        if ((st = cval_alloc(c, &y, x[0].is_int, x[0].ndim, x[0].dims))) goto done;
        for (int64_t i = 0; i < y.n; i++) {
            double v = x[0].v[i];
            y.v[i] = span_eq(op, "Floor") ? floor(v) : span_eq(op, "Ceil") ? ceil(v) : span_eq(op, "Neg") ? -v
                   : span_eq(op, "Abs") ? fabs(v) : span_eq(op, "Not") ? (v == 0) : sqrt(v);
            if (!x[0].is_int) y.v[i] = (float)y.v[i];
        }
    } else if (span_eq(op, "Where")) {
        int nd;
        int64_t dims[NN_MAX_DIMS];
        if (nin < 3 || in[1] < 0 || in[2] < 0 || broadcast_shape(x, 3, &nd, dims)) { st = node_fail(c, "inputs do not broadcast"); goto done; }
        if ((st = cval_alloc(c, &y, x[1].is_int, nd, dims))) goto done;
        for (int64_t o = 0; o < y.n; o++)
            y.v[o] = x[0].v[bcast_index(&x[0], nd, dims, o)] != 0 ? x[1].v[bcast_index(&x[1], nd, dims, o)] : x[2].v[bcast_index(&x[2], nd, dims, o)];
    } else if (span_eq(op, "Expand")) {
        int64_t shape[NN_MAX_DIMS];
        if (nin < 2 || in[1] < 0 || x[1].n > NN_MAX_DIMS) { st = node_fail(c, "bad shape input"); goto done; }
        cval s = { .ndim = (int)x[1].n };
        for (int i = 0; i < s.ndim; i++) s.dims[i] = d2i(x[1].v[i]);
        cval pair[2] = { x[0], s };
        int nd;
        if (broadcast_shape(pair, 2, &nd, shape)) { st = node_fail(c, "shape does not broadcast"); goto done; }
        if ((st = cval_alloc(c, &y, x[0].is_int, nd, shape))) goto done;
        for (int64_t o = 0; o < y.n; o++) y.v[o] = x[0].v[bcast_index(&x[0], nd, shape, o)];
    } else if (nin == 2 && in[0] >= 0 && in[1] >= 0 && !span_eq(op, "Gather") && !span_eq(op, "Concat") &&
               !span_eq(op, "Reshape") && !span_eq(op, "Unsqueeze") && !span_eq(op, "Squeeze") && !span_eq(op, "Range") &&
               !span_eq(op, "ReduceProd") && !span_eq(op, "DequantizeLinear") && !span_eq(op, "Slice")) {
        int nd;
        int64_t dims[NN_MAX_DIMS];
        if (broadcast_shape(x, 2, &nd, dims)) { st = node_fail(c, "inputs do not broadcast"); goto done; }
        int is_int = x[0].is_int && x[1].is_int;
        if ((st = cval_alloc(c, &y, is_int || is_compare(op), nd, dims))) goto done;
        for (int64_t o = 0; o < y.n; o++) {
            double v = binary_eval(op, x[0].v[bcast_index(&x[0], nd, dims, o)], x[1].v[bcast_index(&x[1], nd, dims, o)], is_int);
            y.v[o] = is_int || is_compare(op) ? v : (double)(float)v;
        }
    } else if (span_eq(op, "Gather")) {
        if (nin < 2 || in[1] < 0) { st = node_fail(c, "indices missing"); goto done; }
        int axis = (int)attr_i(at, na, "axis", 0);
        if (axis < 0) axis += x[0].ndim;
        if (axis < 0 || axis >= x[0].ndim || x[0].ndim - 1 + x[1].ndim > NN_MAX_DIMS) { st = node_fail(c, "bad axis"); goto done; }
        int64_t dims[NN_MAX_DIMS];
        int nd = 0;
        for (int i = 0; i < axis; i++) dims[nd++] = x[0].dims[i];
        for (int i = 0; i < x[1].ndim; i++) dims[nd++] = x[1].dims[i];
        for (int i = axis + 1; i < x[0].ndim; i++) dims[nd++] = x[0].dims[i];
        if ((st = cval_alloc(c, &y, x[0].is_int, nd, dims))) goto done;
        int64_t outer = nn_shape_count(axis, x[0].dims), d = x[0].dims[axis], inner = nn_shape_count(x[0].ndim - axis - 1, x[0].dims + axis + 1);
        for (int64_t o = 0; o < outer; o++)
            for (int64_t k = 0; k < x[1].n; k++) {
                int64_t v = d2i(x[1].v[k]);
                if (v < 0) v += d;
                if (v < 0 || v >= d) { st = node_fail(c, "index %g out of range", x[1].v[k]); goto done; }
                memcpy(y.v + (o * x[1].n + k) * inner, x[0].v + (o * d + v) * inner, (size_t)inner * sizeof(double));
            }
    } else if (span_eq(op, "Concat")) {
        int axis = (int)attr_i(at, na, "axis", 0);
        cval all[ONNX_MAX_LIST];
        if (nin > ONNX_MAX_LIST) { st = node_fail(c, "too many inputs to fold"); goto done; }
        int k = 0;
        for (int i = 0; i < nin; i++) {
            if (in[i] < 0) continue;
            if (i < 3) { all[k] = x[i]; x[i].v = NULL; }
            else if ((st = cval_get(c, in[i], &all[k]))) { for (int j = 0; j < k; j++) cval_free(&all[j]); goto done; }
            k++;
        }
        if (k == 0) { st = node_fail(c, "no inputs"); goto done; }
        if (axis < 0) axis += all[0].ndim;
        int64_t dims[NN_MAX_DIMS];
        memcpy(dims, all[0].dims, sizeof dims);
        int ok = axis >= 0 && axis < all[0].ndim;
        if (ok) dims[axis] = 0;
        for (int i = 0; ok && i < k; i++) {
            ok = all[i].ndim == all[0].ndim;
            for (int d = 0; ok && d < all[0].ndim; d++) ok = d == axis || all[i].dims[d] == all[0].dims[d];
            if (ok) dims[axis] += all[i].dims[axis];
        }
        if (!ok) st = node_fail(c, "inputs do not concatenate");
        else st = cval_alloc(c, &y, all[0].is_int, all[0].ndim, dims);
        if (!st) {
            int64_t outer = nn_shape_count(axis, dims), inner = nn_shape_count(all[0].ndim - axis - 1, dims + axis + 1), at0 = 0;
            for (int i = 0; i < k; i++) {
                int64_t chunk = all[i].dims[axis] * inner;
                for (int64_t o = 0; o < outer; o++)
                    memcpy(y.v + o * dims[axis] * inner + at0, all[i].v + o * chunk, (size_t)chunk * sizeof(double));
                at0 += chunk;
            }
        }
        for (int j = 0; j < k; j++) cval_free(&all[j]);
    } else if (span_eq(op, "Unsqueeze") || span_eq(op, "Squeeze") || span_eq(op, "Reshape") || span_eq(op, "Flatten")) {
        /* shape-only changes: compute the new dims, keep the values */
        int64_t dims[NN_MAX_DIMS];
        int nd = 0;
        int64_t axes[NN_MAX_DIMS + 1];
        int nax = 0;
        const onnx_attr *a = find_attr(at, na, "axes");
        if (a) { nax = a->num_ints <= NN_MAX_DIMS ? a->num_ints : -1; if (nax > 0) memcpy(axes, a->ints, (size_t)nax * sizeof(int64_t)); }
        else if (nin > 1 && in[1] >= 0 && !span_eq(op, "Reshape")) {
            nax = x[1].n <= NN_MAX_DIMS ? (int)x[1].n : -1;
            for (int i = 0; i < nax; i++) axes[i] = d2i(x[1].v[i]);
        }
        if (nax < 0) { st = node_fail(c, "too many axes"); goto done; }
        if (span_eq(op, "Unsqueeze")) {
            nd = x[0].ndim + nax;
            if (nd > NN_MAX_DIMS) { st = node_fail(c, "too many dims"); goto done; }
            int mark[NN_MAX_DIMS] = { 0 };
            for (int i = 0; i < nax; i++) {
                int64_t ax = axes[i] < 0 ? axes[i] + nd : axes[i];
                if (ax < 0 || ax >= nd || mark[ax]) { st = node_fail(c, "bad axes"); goto done; }
                mark[ax] = 1;
            }
            for (int i = 0, j = 0; i < nd; i++) dims[i] = mark[i] ? 1 : x[0].dims[j++];
        } else if (span_eq(op, "Squeeze")) {
            int mark[NN_MAX_DIMS] = { 0 };
            for (int i = 0; i < nax; i++) {
                int64_t ax = axes[i] < 0 ? axes[i] + x[0].ndim : axes[i];
                if (ax < 0 || ax >= x[0].ndim || x[0].dims[ax] != 1) { st = node_fail(c, "bad axes"); goto done; }
                mark[ax] = 1;
            }
            for (int i = 0; i < x[0].ndim; i++) if (!(nax ? mark[i] : x[0].dims[i] == 1)) dims[nd++] = x[0].dims[i];
        } else if (span_eq(op, "Flatten")) {
            int axis = (int)attr_i(at, na, "axis", 1);
            if (axis < 0) axis += x[0].ndim;
            if (axis < 0 || axis > x[0].ndim) { st = node_fail(c, "bad axis"); goto done; }
            dims[0] = nn_shape_count(axis, x[0].dims);
            dims[1] = nn_shape_count(x[0].ndim - axis, x[0].dims + axis);
            nd = 2;
        } else {
            if (nin < 2 || in[1] < 0 || x[1].n > NN_MAX_DIMS) { st = node_fail(c, "bad shape input"); goto done; }
            nd = (int)x[1].n;
            int64_t known = 1;
            int minus = -1;
            for (int i = 0; i < nd; i++) {
                int64_t d = d2i(x[1].v[i]);
                if (d == 0 && i < x[0].ndim) d = x[0].dims[i];
                if (d == -1 && minus < 0) { minus = i; d = 1; }
                if (d < 0 || d > NN_MAX_DIM) { st = node_fail(c, "bad target shape"); goto done; }
                dims[i] = d;
                known *= d;
            }
            if (minus >= 0 && known > 0) dims[minus] = x[0].n / known;
        }
        if (nn_shape_count(nd, dims) != x[0].n) { st = node_fail(c, "element count changes"); goto done; }
        y = x[0];
        x[0].v = NULL;
        y.ndim = nd;
        memcpy(y.dims, dims, sizeof dims);
    } else if (span_eq(op, "Slice") || span_eq(op, "Transpose")) {
        /* both: an output index maps to an input offset through per-dim start + step * stride */
        int nd = x[0].ndim;
        int64_t start[NN_MAX_DIMS], step[NN_MAX_DIMS], dims[NN_MAX_DIMS], stride[NN_MAX_DIMS], acc = 1;
        for (int i = nd - 1; i >= 0; i--) { stride[i] = acc; acc *= x[0].dims[i]; }
        for (int i = 0; i < nd; i++) { start[i] = 0; step[i] = stride[i]; dims[i] = x[0].dims[i]; }
        if (span_eq(op, "Transpose")) {
            const onnx_attr *a = find_attr(at, na, "perm");
            int seen[NN_MAX_DIMS] = { 0 };
            for (int i = 0; i < nd; i++) {
                int p = a ? (i < a->num_ints ? (int)a->ints[i] : -1) : nd - 1 - i;
                if ((a && a->num_ints != nd) || p < 0 || p >= nd || seen[p]) { st = node_fail(c, "bad perm"); goto done; }
                seen[p] = 1;
                dims[i] = x[0].dims[p];
                step[i] = stride[p];
            }
        } else {
            int64_t n = nin > 1 && in[1] >= 0 ? x[1].n : 0;
            if (n > NN_MAX_DIMS || nin < 3 || in[2] < 0 || x[2].n != n) { st = node_fail(c, "bad starts/ends"); goto done; }
            cval ax = { 0 }, sp = { 0 };
            if (nin > 3 && in[3] >= 0 && (st = cval_get(c, in[3], &ax))) goto done;
            if (nin > 4 && in[4] >= 0 && (st = cval_get(c, in[4], &sp))) { cval_free(&ax); goto done; }
            int okk = (!ax.v || ax.n == n) && (!sp.v || sp.n == n);
            for (int64_t k = 0; okk && k < n; k++) {
                int64_t a = ax.v ? d2i(ax.v[k]) : k;
                if (a < 0) a += nd;
                if (a < 0 || a >= nd) { okk = 0; break; }
                double s = x[1].v[k], e = x[2].v[k], p = sp.v ? sp.v[k] : 1, d = (double)x[0].dims[a];
                if (p == 0 || p != p || s != s || e != e) { okk = 0; break; }
                p = p > d + 1 ? d + 1 : p < -d - 1 ? -d - 1 : p; /* a step past the end takes one element */
                if (s < 0) s += d;
                if (e < 0) e += d;
                if (p > 0) { s = s < 0 ? 0 : s > d ? d : s; e = e < 0 ? 0 : e > d ? d : e; }
                else { s = s < 0 ? 0 : s > d - 1 ? d - 1 : s; e = e < -1 ? -1 : e > d - 1 ? d - 1 : e; }
                double len = p > 0 ? ceil((e - s) / p) : ceil((s - e) / -p);
                dims[a] = len > 0 ? d2i(len) : 0;
                start[a] = d2i(s);
                step[a] = stride[a] * d2i(p);
            }
            cval_free(&ax);
            cval_free(&sp);
            if (!okk) { st = node_fail(c, "bad slice parameters"); goto done; }
        }
        if ((st = cval_alloc(c, &y, x[0].is_int, nd, dims))) goto done;
        int64_t base = 0;
        for (int i = 0; i < nd; i++) base += start[i] * stride[i];
        for (int64_t o = 0; o < y.n; o++) {
            int64_t rem = o, off = base;
            for (int d = nd - 1; d >= 0; d--) { off += (rem % dims[d]) * step[d]; rem /= dims[d]; }
            y.v[o] = x[0].v[off];
        }
    } else if (span_eq(op, "Range")) {
        if (nin < 3 || x[0].n != 1 || x[1].n != 1 || x[2].n != 1 || x[2].v[0] == 0) { st = node_fail(c, "bad range"); goto done; }
        double n = ceil((x[1].v[0] - x[0].v[0]) / x[2].v[0]);
        int64_t len = n > 0 ? (int64_t)fmin(n, (double)ONNX_EVAL_MAX + 1) : 0;
        if ((st = cval_alloc(c, &y, x[0].is_int, 1, &len))) goto done;
        for (int64_t i = 0; i < len; i++) y.v[i] = x[0].v[0] + (double)i * x[2].v[0];
    } else if (span_eq(op, "ReduceProd")) {
        if (x[0].ndim > 1 || find_attr(at, na, "axes")) { st = node_fail(c, "only 1-D ReduceProd is folded"); goto done; }
        int keep = (int)attr_i(at, na, "keepdims", 1);
        int64_t one = 1;
        if ((st = cval_alloc(c, &y, x[0].is_int, keep ? 1 : 0, &one))) goto done;
        y.v[0] = 1;
        for (int64_t i = 0; i < x[0].n; i++) y.v[0] *= x[0].v[i];
    } else if (span_eq(op, "DequantizeLinear")) {
        if (nin < 2 || in[1] < 0) { st = node_fail(c, "scale missing"); goto done; }
        int axis = (int)attr_i(at, na, "axis", 1);
        if (axis < 0) axis += x[0].ndim;
        int per_axis = x[1].n > 1;
        if (per_axis && (axis < 0 || axis >= x[0].ndim || x[1].n != x[0].dims[axis])) { st = node_fail(c, "scale does not fit the axis"); goto done; }
        if (nin > 2 && in[2] >= 0 && x[2].n != x[1].n) { st = node_fail(c, "zero point does not fit the scale"); goto done; }
        if ((st = cval_alloc(c, &y, 0, x[0].ndim, x[0].dims))) goto done;
        int64_t inner = per_axis ? nn_shape_count(x[0].ndim - axis - 1, x[0].dims + axis + 1) : 1;
        for (int64_t i = 0; i < y.n; i++) {
            int64_t k = per_axis ? (i / inner) % x[1].n : 0;
            double zp = nin > 2 && in[2] >= 0 ? x[2].v[k] : 0;
            y.v[i] = (float)((x[0].v[i] - zp) * x[1].v[k]);
        }
    } else {
        st = node_fail(c, "cannot fold this op");
    }
    if (!st) st = cval_put(c, outs[0], &y);
done:
    for (int i = 0; i < 3; i++) cval_free(&x[i]);
    cval_free(&y);
    return st;
}

/* ---- runtime nodes ---- */

typedef struct { const char *onnx; nn_op op; } op_map;
static const op_map RUNTIME_OPS[] = {
    { "Conv", NN_OP_CONV }, { "ConvTranspose", NN_OP_CONV_TRANSPOSE }, { "MatMul", NN_OP_MATMUL }, { "Gemm", NN_OP_GEMM },
    { "Add", NN_OP_ADD }, { "Sub", NN_OP_SUB }, { "Mul", NN_OP_MUL }, { "Div", NN_OP_DIV }, { "Pow", NN_OP_POW },
    { "Max", NN_OP_MAXIMUM }, { "Min", NN_OP_MINIMUM }, { "Sqrt", NN_OP_SQRT }, { "Erf", NN_OP_ERF }, { "Exp", NN_OP_EXP },
    { "Tanh", NN_OP_TANH }, { "Neg", NN_OP_NEG }, { "Abs", NN_OP_ABS }, { "Relu", NN_OP_RELU }, { "LeakyRelu", NN_OP_LEAKY_RELU },
    { "Sigmoid", NN_OP_SIGMOID }, { "Gelu", NN_OP_GELU }, { "LayerNormalization", NN_OP_LAYER_NORM },
    { "Softmax", NN_OP_SOFTMAX }, { "ReduceMean", NN_OP_REDUCE_MEAN }, { "Reshape", NN_OP_RESHAPE },
    { "Flatten", NN_OP_RESHAPE }, { "Squeeze", NN_OP_RESHAPE }, { "Unsqueeze", NN_OP_RESHAPE },
    { "Transpose", NN_OP_TRANSPOSE }, { "Slice", NN_OP_SLICE }, { "Concat", NN_OP_CONCAT }, { "Gather", NN_OP_GATHER },
    { "Expand", NN_OP_EXPAND }, { "Pad", NN_OP_PAD }, { "Resize", NN_OP_RESIZE }, { "Upsample", NN_OP_RESIZE },
    { NULL, NN_OP_COUNT } };

static nn_op runtime_op(span op)
{
    for (int i = 0; RUNTIME_OPS[i].onnx; i++) if (span_eq(op, RUNTIME_OPS[i].onnx)) return RUNTIME_OPS[i].op;
    return NN_OP_COUNT;
}

/* Reads a list attribute of exactly n ints (or leaves out alone when absent). */
static pg_status ints_attr(onnx_ctx *c, const onnx_attr *at, int na, const char *name, int n, int *out)
{
    const onnx_attr *a = find_attr(at, na, name);
    if (!a) return PG_OK;
    if (a->num_ints != n) return node_fail(c, "attribute %s has %d values (expected %d)", name, a->num_ints, n);
    for (int i = 0; i < n; i++) {
        if (a->ints[i] < -65536 || a->ints[i] > 65536) return node_fail(c, "attribute %s value %lld out of range", name, (long long)a->ints[i]);
        out[i] = (int)a->ints[i];
    }
    return PG_OK;
}

static pg_status resize_modes(onnx_ctx *c, const onnx_attr *at, int na, nn_attrs *a)
{
    const onnx_attr *m = find_attr(at, na, "mode"), *ct = find_attr(at, na, "coordinate_transformation_mode"),
                    *nm = find_attr(at, na, "nearest_mode");
    if (!m || span_eq(m->s, "nearest")) a->resize_mode = NN_RESIZE_NEAREST;
    else if (span_eq(m->s, "linear") || span_eq(m->s, "bilinear")) a->resize_mode = NN_RESIZE_LINEAR;
    else if (span_eq(m->s, "cubic")) a->resize_mode = NN_RESIZE_CUBIC;
    else { char s[32]; span_str(m->s, s, sizeof s); return node_fail(c, "Resize mode '%s' is not supported (nearest, linear, cubic)", s); }
    a->cubic_a = attr_f(at, na, "cubic_coeff_a", -0.75f);
    a->exclude_outside = attr_i(at, na, "exclude_outside", 0) != 0;
    if (!ct || span_eq(ct->s, "half_pixel")) a->coord_mode = NN_COORD_HALF_PIXEL;
    else if (span_eq(ct->s, "pytorch_half_pixel")) a->coord_mode = NN_COORD_PYTORCH_HALF_PIXEL;
    else if (span_eq(ct->s, "align_corners")) a->coord_mode = NN_COORD_ALIGN_CORNERS;
    else if (span_eq(ct->s, "asymmetric")) a->coord_mode = NN_COORD_ASYMMETRIC;
    else if (span_eq(ct->s, "tf_half_pixel_for_nn")) a->coord_mode = NN_COORD_TF_HALF_PIXEL_FOR_NN;
    else { char s[32]; span_str(ct->s, s, sizeof s); return node_fail(c, "coordinate_transformation_mode '%s' is not supported", s); }
    if (!nm || span_eq(nm->s, "round_prefer_floor")) a->nearest_mode = NN_NEAREST_ROUND_PREFER_FLOOR;
    else if (span_eq(nm->s, "round_prefer_ceil")) a->nearest_mode = NN_NEAREST_ROUND_PREFER_CEIL;
    else if (span_eq(nm->s, "floor")) a->nearest_mode = NN_NEAREST_FLOOR;
    else if (span_eq(nm->s, "ceil")) a->nearest_mode = NN_NEAREST_CEIL;
    else return node_fail(c, "nearest_mode not supported");
    if (attr_i(at, na, "antialias", 0)) return node_fail(c, "antialiased Resize is not supported");
    if (find_attr(at, na, "axes")) return node_fail(c, "Resize with axes is not supported");
    return PG_OK;
}

/* Fills attributes from the ONNX node and the constant shape-like inputs; returns how many of the
 * inputs stay data inputs. */
static pg_status convert_attrs(onnx_ctx *c, nn_op op, span opname, const onnx_attr *at, int na, const int *in, int nin,
                               nn_attrs *a, int *keep)
{
    nn_graph *g = c->g;
    nn_attrs_default(a);
    *keep = nin;
    switch (op) {
    case NN_OP_CONV: case NN_OP_CONV_TRANSPOSE: {
        const onnx_attr *ap = find_attr(at, na, "auto_pad");
        if (ap && !span_eq(ap->s, "NOTSET") && !span_eq(ap->s, "VALID")) return node_fail(c, "auto_pad SAME_* is not supported (export with explicit pads)");
        if (in[0] >= 0 && g->tensors[in[0]].ndim != 4) return node_fail(c, "only 2-D convolutions are supported");
        PG_TRY(ints_attr(c, at, na, "kernel_shape", 2, a->kernel));
        PG_TRY(ints_attr(c, at, na, "strides", 2, a->stride));
        PG_TRY(ints_attr(c, at, na, "dilations", 2, a->dilation));
        PG_TRY(ints_attr(c, at, na, "pads", 4, a->pads));
        PG_TRY(ints_attr(c, at, na, "output_padding", 2, a->output_padding));
        if (find_attr(at, na, "output_shape")) return node_fail(c, "ConvTranspose output_shape is not supported (export with pads)");
        int64_t gr = attr_i(at, na, "group", 1);
        if (gr < 1 || gr > 1 << 20) return node_fail(c, "group %lld", (long long)gr);
        a->group = (int)gr;
        break;
    }
    case NN_OP_GEMM:
        a->alpha = attr_f(at, na, "alpha", 1.0f);
        a->beta = attr_f(at, na, "beta", 1.0f);
        a->trans_a = attr_i(at, na, "transA", 0) != 0;
        a->trans_b = attr_i(at, na, "transB", 0) != 0;
        break;
    case NN_OP_LEAKY_RELU: a->alpha = attr_f(at, na, "alpha", 0.01f); break;
    case NN_OP_GELU: {
        const onnx_attr *ap = find_attr(at, na, "approximate");
        a->gelu_tanh = ap && span_eq(ap->s, "tanh");
        break;
    }
    case NN_OP_LAYER_NORM:
        a->axis = (int)attr_i(at, na, "axis", -1);
        a->epsilon = attr_f(at, na, "epsilon", 1e-5f);
        if (attr_i(at, na, "stash_type", 1) != 1) return node_fail(c, "stash_type other than float");
        break;
    case NN_OP_SOFTMAX:
        a->axis = (int)attr_i(at, na, "axis", c->opset >= 13 ? -1 : 1);
        if (c->opset < 13) return node_fail(c, "Softmax before opset 13 (2-D coercion) is not supported");
        break;
    case NN_OP_CONCAT: case NN_OP_GATHER: a->axis = (int)attr_i(at, na, "axis", 0); break;
    case NN_OP_TRANSPOSE: {
        const onnx_attr *p = find_attr(at, na, "perm");
        if (p) {
            if (p->num_ints > NN_MAX_DIMS) return node_fail(c, "perm too long");
            a->num_perm = p->num_ints;
            for (int i = 0; i < p->num_ints; i++) a->perm[i] = p->ints[i] < 0 || p->ints[i] > NN_MAX_DIMS ? -1 : (int)p->ints[i];
        }
        break;
    }
    case NN_OP_REDUCE_MEAN: {
        a->keepdims = attr_i(at, na, "keepdims", 1) != 0;
        const onnx_attr *ax = find_attr(at, na, "axes");
        int64_t v[NN_MAX_DIMS];
        int n = 0;
        if (ax) {
            if (ax->num_ints > NN_MAX_DIMS) return node_fail(c, "too many axes");
            n = ax->num_ints;
            memcpy(v, ax->ints, (size_t)n * sizeof(int64_t));
        } else if (nin > 1 && in[1] >= 0) {
            if ((n = const_ints(c, in[1], v, NN_MAX_DIMS)) < 0) return node_fail(c, "axes must be a constant");
        }
        if (n == 0 && attr_i(at, na, "noop_with_empty_axes", 0)) return node_fail(c, "noop_with_empty_axes is not supported");
        a->num_axes = n;
        memcpy(a->axes, v, (size_t)n * sizeof(int64_t));
        *keep = 1;
        break;
    }
    case NN_OP_RESHAPE: {
        const nn_tensor *x = &g->tensors[in[0]];
        int64_t dims[NN_MAX_DIMS];
        int nd = 0;
        if (span_eq(opname, "Reshape")) {
            if (nin < 2 || in[1] < 0 || (nd = const_ints(c, in[1], dims, NN_MAX_DIMS)) < 0) return node_fail(c, "shape must be a constant of at most 6 values");
            if (attr_i(at, na, "allowzero", 0)) for (int i = 0; i < nd; i++) if (dims[i] == 0) return node_fail(c, "allowzero with a 0 dim is not supported");
        } else if (span_eq(opname, "Flatten")) {
            int axis = (int)attr_i(at, na, "axis", 1);
            if (axis < 0) axis += x->ndim;
            if (axis < 0 || axis > x->ndim) return node_fail(c, "axis out of range");
            dims[0] = nn_shape_count(axis, x->dims);
            dims[1] = nn_shape_count(x->ndim - axis, x->dims + axis);
            nd = 2;
        } else {
            int64_t axes[NN_MAX_DIMS];
            int nax = 0;
            const onnx_attr *ax = find_attr(at, na, "axes");
            if (ax) { if (ax->num_ints > NN_MAX_DIMS) return node_fail(c, "too many axes"); nax = ax->num_ints; memcpy(axes, ax->ints, (size_t)nax * sizeof(int64_t)); }
            else if (nin > 1 && in[1] >= 0 && (nax = const_ints(c, in[1], axes, NN_MAX_DIMS)) < 0) return node_fail(c, "axes must be a constant");
            int mark[NN_MAX_DIMS] = { 0 };
            if (span_eq(opname, "Unsqueeze")) {
                nd = x->ndim + nax;
                if (nd > NN_MAX_DIMS) return node_fail(c, "more than 6 dims");
                for (int i = 0; i < nax; i++) {
                    int64_t v = axes[i] < 0 ? axes[i] + nd : axes[i];
                    if (v < 0 || v >= nd || mark[v]) return node_fail(c, "bad axes");
                    mark[v] = 1;
                }
                for (int i = 0, j = 0; i < nd; i++) dims[i] = mark[i] ? 1 : x->dims[j++];
            } else {
                for (int i = 0; i < nax; i++) {
                    int64_t v = axes[i] < 0 ? axes[i] + x->ndim : axes[i];
                    if (v < 0 || v >= x->ndim || x->dims[v] != 1) return node_fail(c, "squeezed axis is not of size 1");
                    mark[v] = 1;
                }
                for (int i = 0; i < x->ndim; i++) if (!(nax ? mark[i] : x->dims[i] == 1)) dims[nd++] = x->dims[i];
            }
        }
        a->num_shape = nd;
        memcpy(a->shape, dims, (size_t)nd * sizeof(int64_t));
        *keep = 1;
        break;
    }
    case NN_OP_SLICE: {
        int64_t s[NN_MAX_DIMS], e[NN_MAX_DIMS], ax[NN_MAX_DIMS], st[NN_MAX_DIMS];
        int n = nin > 1 && in[1] >= 0 ? const_ints(c, in[1], s, NN_MAX_DIMS) : -1;
        if (n < 0 || nin < 3 || in[2] < 0 || const_ints(c, in[2], e, NN_MAX_DIMS) != n) return node_fail(c, "starts/ends must be constants");
        if (nin > 3 && in[3] >= 0) { if (const_ints(c, in[3], ax, NN_MAX_DIMS) != n) return node_fail(c, "axes must be a constant"); }
        else for (int i = 0; i < n; i++) ax[i] = i;
        if (nin > 4 && in[4] >= 0) { if (const_ints(c, in[4], st, NN_MAX_DIMS) != n) return node_fail(c, "steps must be a constant"); }
        else for (int i = 0; i < n; i++) st[i] = 1;
        a->num_axes = n;
        for (int i = 0; i < n; i++) { a->axes[i] = ax[i]; a->starts[i] = s[i]; a->ends[i] = e[i]; a->steps[i] = st[i]; }
        *keep = 1;
        break;
    }
    case NN_OP_EXPAND: {
        int n = nin > 1 && in[1] >= 0 ? const_ints(c, in[1], a->shape, NN_MAX_DIMS) : -1;
        if (n < 0) return node_fail(c, "shape must be a constant");
        a->num_shape = n;
        *keep = 1;
        break;
    }
    case NN_OP_PAD: {
        const onnx_attr *m = find_attr(at, na, "mode");
        if (!m || span_eq(m->s, "constant")) a->pad_mode = NN_PAD_CONSTANT;
        else if (span_eq(m->s, "reflect")) a->pad_mode = NN_PAD_REFLECT;
        else if (span_eq(m->s, "edge")) a->pad_mode = NN_PAD_EDGE;
        else return node_fail(c, "pad mode not supported");
        int nd = g->tensors[in[0]].ndim;
        int n = nin > 1 && in[1] >= 0 ? const_ints(c, in[1], a->pad_amounts, 2 * NN_MAX_DIMS) : -1;
        if (n != 2 * nd) return node_fail(c, "pads must be a constant of 2 x rank values");
        if (nin > 2 && in[2] >= 0) {
            float v;
            if (const_floats(c, in[2], &v, 1) != 1) return node_fail(c, "constant_value must be a scalar constant");
            a->pad_value = v;
        }
        if (nin > 3 && in[3] >= 0) return node_fail(c, "Pad with axes is not supported");
        *keep = 1;
        break;
    }
    case NN_OP_RESIZE: {
        PG_TRY(resize_modes(c, at, na, a));
        const nn_tensor *x = &g->tensors[in[0]];
        if (x->ndim != 4) return node_fail(c, "only 4-D Resize is supported");
        float sc[NN_MAX_DIMS];
        int64_t sz[NN_MAX_DIMS];
        int ns = -1, nz = -1;
        int si = span_eq(opname, "Upsample") ? 1 : 2, zi = 3;
        if (nin > si && in[si] >= 0) ns = const_floats(c, in[si], sc, NN_MAX_DIMS);
        if (nin > zi && in[zi] >= 0) nz = const_ints(c, in[zi], sz, NN_MAX_DIMS);
        if (nz == 4) {
            if (sz[0] != x->dims[0] || sz[1] != x->dims[1]) return node_fail(c, "only the two spatial dims may be resized");
            if (sz[2] < 1 || sz[3] < 1 || sz[2] > NN_MAX_DIM || sz[3] > NN_MAX_DIM) return node_fail(c, "bad sizes");
            a->out_h = (int)sz[2];
            a->out_w = (int)sz[3];
        } else if (ns == 4) {
            if (sc[0] != 1.0f || sc[1] != 1.0f) return node_fail(c, "only the two spatial dims may be resized");
            if (!(sc[2] > 0 && sc[3] > 0) || x->dims[2] * (double)sc[2] > NN_MAX_DIM || x->dims[3] * (double)sc[3] > NN_MAX_DIM)
                return node_fail(c, "bad scales");
            a->out_h = (int)floor(x->dims[2] * (double)sc[2]);
            a->out_w = (int)floor(x->dims[3] * (double)sc[3]);
            a->scale_h = sc[2];
            a->scale_w = sc[3];
        } else return node_fail(c, "scales or sizes must be constants for a 4-D input");
        *keep = 1;
        break;
    }
    default:
        break;
    }
    if (op == NN_OP_CONV || op == NN_OP_CONV_TRANSPOSE || op == NN_OP_GEMM || op == NN_OP_LAYER_NORM) *keep = nin < 3 ? nin : 3;
    else if (op == NN_OP_GATHER || op == NN_OP_MATMUL || (op >= NN_OP_ADD && op <= NN_OP_MINIMUM)) *keep = 2;
    else if (op != NN_OP_CONCAT) *keep = 1;
    (void)opname;
    return PG_OK;
}

/* ---- NodeProto ---- */

static int find_or_fail(onnx_ctx *c, span name, int *id)
{
    if (name.n == 0) { *id = -1; return 0; }
    *id = map_get(c, name);
    return *id < 0 ? -1 : 0;
}

static pg_status convert_node(onnx_ctx *c, span bytes, onnx_attr *at)
{
    nn_graph *g = c->g;
    span op = { NULL, 0 }, name = { (const uint8_t *)"", 0 }, domain = { (const uint8_t *)"", 0 };
    int nin = 0, nout = 0, na = 0;
    pb_reader r = { bytes.p, bytes.p + bytes.n };
    pb_field f;
    int rc;
    /* first pass: op, name, counts */
    while ((rc = pb_next(&r, &f)) > 0) {
        if (f.wire != PB_LEN) continue;
        if (f.number == 1) nin++;
        else if (f.number == 2) nout++;
        else if (f.number == 3) name = (span){ f.data, f.len };
        else if (f.number == 4) op = (span){ f.data, f.len };
        else if (f.number == 7) domain = (span){ f.data, f.len };
    }
    if (rc < 0) return bad(c, "corrupt NodeProto");
    span_str(name, c->node, sizeof c->node);
    span_str(op, c->op, sizeof c->op);
    if (!op.p) return node_fail(c, "no op_type");
    if (domain.n && !span_eq(domain, "ai.onnx")) {
        char d[64];
        span_str(domain, d, sizeof d);
        return node_fail(c, "op domain '%s' is not supported", d);
    }
    if (nin > ONNX_MAX_NODE_IO || nout < 1 || nout > NN_MAX_OUTPUTS) return node_fail(c, "%d inputs, %d outputs", nin, nout);
    int *in = malloc(sizeof(int) * (size_t)(nin + 1));
    span outs[NN_MAX_OUTPUTS];
    if (!in) return pg_fail(PG_ERR_NOMEM, "%s: out of memory", c->path);
    pg_status st = PG_OK;
    int k = 0, o = 0;
    r = (pb_reader){ bytes.p, bytes.p + bytes.n };
    while (!st && pb_next(&r, &f) > 0) {
        if (f.wire != PB_LEN) continue;
        if (f.number == 1) {
            span s = { f.data, f.len };
            if (find_or_fail(c, s, &in[k])) {
                char nm[128];
                span_str(s, nm, sizeof nm);
                st = node_fail(c, "input '%s' is not produced by an earlier node (cyclic or unsorted graph)", nm);
            }
            k++;
        } else if (f.number == 2) outs[o++] = (span){ f.data, f.len };
        else if (f.number == 5) {
            if (na >= ONNX_MAX_ATTRS) st = node_fail(c, "more than %d attributes", ONNX_MAX_ATTRS);
            else st = parse_attr(c, (span){ f.data, f.len }, &at[na++]);
        }
    }
    if (st) goto done;
    if (outs[0].n == 0) { st = node_fail(c, "empty output name"); goto done; }
    /* aliases */
    if (span_eq(op, "Identity") || span_eq(op, "Dropout") ||
        (span_eq(op, "Cast") && in[0] >= 0 && g->tensors[in[0]].dtype == NN_F32 && is_float_type((int)attr_i(at, na, "to", 0)))) {
        if (nin < 1 || in[0] < 0) { st = node_fail(c, "input missing"); goto done; }
        st = map_put(c, outs[0], in[0]);
        goto done;
    }
    int all_const = 1, any_int = 0;
    int64_t elems = 0;
    for (int i = 0; i < nin; i++) {
        if (in[i] < 0) continue;
        all_const &= is_const(c, in[i]);
        any_int |= g->tensors[in[i]].dtype == NN_I64;
        elems += nn_shape_count(g->tensors[in[i]].ndim, g->tensors[in[i]].dims);
    }
    nn_op rop = runtime_op(op);
    int shape_only = span_eq(op, "Shape") || span_eq(op, "Size");
    if (is_eval_op(op) && (shape_only || span_eq(op, "Constant") ||
                           (all_const && (any_int || rop == NN_OP_COUNT || elems <= 4096)))) {
        if (shape_only && (nin < 1 || in[0] < 0)) { st = node_fail(c, "input missing"); goto done; }
        st = eval_node(c, op, in, nin, outs, at, na);
        goto done;
    }
    if (rop == NN_OP_COUNT) { st = node_fail(c, "op '%s' is not supported", c->op); goto done; }
    if (nin < 1 || in[0] < 0) { st = node_fail(c, "first input missing"); goto done; }
    nn_attrs a;
    int keep;
    if ((st = convert_attrs(c, rop, op, at, na, in, nin, &a, &keep))) goto done;
    if ((rop >= NN_OP_ADD && rop <= NN_OP_MINIMUM && nin != 2) || (rop == NN_OP_MATMUL && nin != 2) ||
        (rop >= NN_OP_SQRT && rop <= NN_OP_GELU && nin != 1) || (rop == NN_OP_ABS && nin != 1)) {
        st = node_fail(c, "%d inputs", nin);
        goto done;
    }
    if (nout > 1 && rop != NN_OP_LAYER_NORM && !span_eq(op, "Dropout")) { st = node_fail(c, "%d outputs (one expected)", nout); goto done; }
    char on[128];
    span_str(outs[0], on, sizeof on);
    int out_id, node_id;
    if ((st = nn_graph_add_tensor(g, on, NN_F32, -1, NULL, &out_id))) goto done;
    if ((st = nn_graph_add_node(g, rop, c->node[0] ? c->node : on, in, keep, &out_id, 1, &a, &node_id))) goto done;
    if ((st = nn_node_infer(g, node_id))) { pg_fail_context(st, "%s: node %d", c->path, c->index); goto done; }
    st = map_put(c, outs[0], out_id);
done:
    free(in);
    return st;
}

/* ---- ValueInfoProto: name and static shape of a graph input ---- */

static pg_status parse_value_info(onnx_ctx *c, span bytes, span *name, int *elem, int *ndim, int64_t *dims)
{
    pb_reader r = { bytes.p, bytes.p + bytes.n };
    pb_field f, f2, f3, f4, f5;
    int rc;
    *ndim = -1;
    *elem = 0;
    name->p = (const uint8_t *)""; /* never NULL: names are compared with memcmp */
    name->n = 0;
    while ((rc = pb_next(&r, &f)) > 0) {
        if (f.number == 1 && f.wire == PB_LEN) *name = (span){ f.data, f.len };
        if (f.number != 2 || f.wire != PB_LEN) continue;
        pb_reader tr = { f.data, f.data + f.len }; /* TypeProto */
        while ((rc = pb_next(&tr, &f2)) > 0) {
            if (f2.number != 1 || f2.wire != PB_LEN) continue;
            pb_reader tt = { f2.data, f2.data + f2.len }; /* TypeProto.Tensor */
            while ((rc = pb_next(&tt, &f3)) > 0) {
                if (f3.number == 1 && f3.wire == PB_VARINT) *elem = (int)f3.v;
                if (f3.number != 2 || f3.wire != PB_LEN) continue;
                *ndim = 0;
                pb_reader sr = { f3.data, f3.data + f3.len }; /* TensorShapeProto */
                while ((rc = pb_next(&sr, &f4)) > 0) {
                    if (f4.number != 1 || f4.wire != PB_LEN) continue;
                    if (*ndim >= NN_MAX_DIMS) return bad(c, "graph input with more than 6 dims");
                    pb_reader dr = { f4.data, f4.data + f4.len };
                    int64_t v = -1;
                    while ((rc = pb_next(&dr, &f5)) > 0) if (f5.number == 1 && f5.wire == PB_VARINT) v = (int64_t)f5.v;
                    if (rc < 0) return bad(c, "corrupt dimension");
                    dims[(*ndim)++] = v;
                }
                if (rc < 0) return bad(c, "corrupt shape");
            }
            if (rc < 0) return bad(c, "corrupt tensor type");
        }
        if (rc < 0) return bad(c, "corrupt type");
    }
    if (rc < 0) return bad(c, "corrupt ValueInfoProto");
    return PG_OK;
}

/* ---- GraphProto / ModelProto ---- */

static pg_status import_graph(onnx_ctx *c, span bytes)
{
    nn_graph *g = c->g;
    pb_reader r = { bytes.p, bytes.p + bytes.n };
    pb_field f;
    int rc;
    /* initializers first: they may be listed after the nodes in the file */
    while ((rc = pb_next(&r, &f)) > 0) {
        if (f.number == 5 && f.wire == PB_LEN) {
            int id;
            PG_TRY(parse_tensor(c, (span){ f.data, f.len }, (span){ NULL, 0 }, &id));
            /* map the name as written in the file */
            pb_reader tr = { f.data, f.data + f.len };
            pb_field tf;
            span nm = { (const uint8_t *)"", 0 };
            while (pb_next(&tr, &tf) > 0) if (tf.number == 8 && tf.wire == PB_LEN) nm = (span){ tf.data, tf.len };
            PG_TRY(map_put(c, nm, id));
        } else if (f.number == 15) return bad(c, "sparse initializers are not supported");
    }
    if (rc < 0) return bad(c, "corrupt GraphProto");
    int ins[NN_MAX_IO], nins = 0;
    r = (pb_reader){ bytes.p, bytes.p + bytes.n };
    while (pb_next(&r, &f) > 0) {
        if (f.number != 11 || f.wire != PB_LEN) continue;
        span name;
        int elem, ndim;
        int64_t dims[NN_MAX_DIMS];
        PG_TRY(parse_value_info(c, (span){ f.data, f.len }, &name, &elem, &ndim, dims));
        if (map_get(c, name) >= 0) continue; /* an initializer also listed as input (IR < 4) */
        char nm[128];
        span_str(name, nm, sizeof nm);
        if (elem != T_FLOAT) return pg_fail(PG_ERR_FORMAT, "%s: graph input '%s' is not float32 (type %d)", c->path, nm, elem);
        if (ndim < 0) return pg_fail(PG_ERR_FORMAT, "%s: graph input '%s' has no shape", c->path, nm);
        if (nins == 0 && g->bind_ndim > 0) {
            /* the caller's shape binds symbolic dims */
            if (ndim != g->bind_ndim)
                return pg_fail(PG_ERR_ARG, "%s: graph input '%s' has %d dims, %d were given", c->path, nm, ndim, g->bind_ndim);
            for (int i = 0; i < ndim; i++) {
                if (g->bind_dims[i] < 1 || g->bind_dims[i] > NN_MAX_DIM)
                    return pg_fail(PG_ERR_ARG, "%s: input dim %d given as %lld", c->path, i, (long long)g->bind_dims[i]);
                if (dims[i] >= 1 && dims[i] != g->bind_dims[i])
                    return pg_fail(PG_ERR_ARG, "%s: graph input '%s' dim %d is fixed at %lld, %lld was given", c->path, nm, i,
                                   (long long)dims[i], (long long)g->bind_dims[i]);
                dims[i] = g->bind_dims[i];
            }
        }
        for (int i = 0; i < ndim; i++)
            if (dims[i] < 1)
                return pg_fail(PG_ERR_FORMAT, "%s: graph input '%s' has a symbolic or empty dim %d (export with static shapes, or load with nn_model_load_shaped)", c->path, nm, i);
        if (nins >= NN_MAX_IO) return pg_fail(PG_ERR_FORMAT, "%s: more than %d graph inputs", c->path, NN_MAX_IO);
        int id;
        pg_status st = nn_graph_add_tensor(g, nm, NN_F32, ndim, dims, &id);
        if (st) return pg_fail_context(st, "%s: graph input", c->path);
        PG_TRY(map_put(c, name, id));
        ins[nins++] = id;
    }
    /* nodes in file order */
    onnx_attr *at = malloc(sizeof(onnx_attr) * ONNX_MAX_ATTRS);
    if (!at) return pg_fail(PG_ERR_NOMEM, "%s: out of memory", c->path);
    r = (pb_reader){ bytes.p, bytes.p + bytes.n };
    c->index = 0;
    pg_status st = PG_OK;
    while (!st && pb_next(&r, &f) > 0) {
        if (f.number != 1 || f.wire != PB_LEN) continue;
        st = convert_node(c, (span){ f.data, f.len }, at);
        c->index++;
    }
    free(at);
    if (st) return st;
    int outs[NN_MAX_IO], nouts = 0;
    r = (pb_reader){ bytes.p, bytes.p + bytes.n };
    while (pb_next(&r, &f) > 0) {
        if (f.number != 12 || f.wire != PB_LEN) continue;
        span name;
        int elem, ndim;
        int64_t dims[NN_MAX_DIMS];
        PG_TRY(parse_value_info(c, (span){ f.data, f.len }, &name, &elem, &ndim, dims));
        char nm[128];
        span_str(name, nm, sizeof nm);
        int id = map_get(c, name);
        if (id < 0) return pg_fail(PG_ERR_FORMAT, "%s: graph output '%s' is not produced by any node", c->path, nm);
        if (nouts >= NN_MAX_IO) return pg_fail(PG_ERR_FORMAT, "%s: more than %d graph outputs", c->path, NN_MAX_IO);
        if (g->tensors[id].dtype != NN_F32) return pg_fail(PG_ERR_FORMAT, "%s: graph output '%s' is not float32", c->path, nm);
        /* an output that is a graph input or another output gets its own copy */
        int taken = 0;
        for (int i = 0; i < nins; i++) taken |= ins[i] == id;
        for (int i = 0; i < nouts; i++) taken |= outs[i] == id;
        if (taken) {
            int cp, node;
            PG_TRY(nn_graph_add_tensor(g, nm, NN_F32, -1, NULL, &cp));
            PG_TRY(nn_graph_add_node(g, NN_OP_IDENTITY, nm, &id, 1, &cp, 1, NULL, &node));
            PG_TRY(nn_node_infer(g, node));
            id = cp;
        }
        outs[nouts++] = id;
    }
    if (nouts == 0) return pg_fail(PG_ERR_FORMAT, "%s: the graph has no outputs", c->path);
    return nn_graph_set_io(g, ins, nins, outs, nouts);
}

pg_status nn_onnx_import(const uint8_t *data, size_t size, const char *name, nn_graph *g)
{
    onnx_ctx c = { .path = name, .g = g, .opset = -1 };
    c.fold_left = ((size_t)64 << 20) + (size < ((size_t)1 << 40) ? 8 * size : ((size_t)1 << 43));
    pb_reader r = { data, data + size };
    pb_field f;
    int rc;
    span graph = { NULL, 0 };
    int64_t ir = -1;
    while ((rc = pb_next(&r, &f)) > 0) {
        if (f.number == 1 && f.wire == PB_VARINT) ir = (int64_t)f.v;
        else if (f.number == 7 && f.wire == PB_LEN) graph = (span){ f.data, f.len };
        else if (f.number == 8 && f.wire == PB_LEN) {
            pb_reader o = { f.data, f.data + f.len };
            pb_field of;
            span domain = { (const uint8_t *)"", 0 };
            int64_t version = -1;
            while ((rc = pb_next(&o, &of)) > 0) {
                if (of.number == 1 && of.wire == PB_LEN) domain = (span){ of.data, of.len };
                if (of.number == 2 && of.wire == PB_VARINT) version = (int64_t)of.v;
            }
            if (rc < 0) break;
            if (domain.n == 0 || span_eq(domain, "ai.onnx")) c.opset = (int)(version > 1000 ? 1000 : version);
        }
    }
    if (rc < 0) return pg_fail(PG_ERR_FORMAT, "%s: not an ONNX model (corrupt or truncated protobuf)", name);
    if (!graph.p || ir < 3) return pg_fail(PG_ERR_FORMAT, "%s: not an ONNX model (no graph or IR version)", name);
    if (c.opset < 11 || c.opset > 18)
        return pg_fail(PG_ERR_FORMAT, "%s: opset %d is not supported (11 to 18; tested with 17)", name, c.opset);
    pg_status st = import_graph(&c, graph);
    free(c.map);
    return st;
}
