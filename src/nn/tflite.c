/* tflite.c - the TFLite flatbuffer parser and per-op shape checks (see tflite.h).
 *
 * A flatbuffer is read in place: the root is a uoffset (u32, relative to itself) to a table; a
 * table starts with an soffset (i32) back to its vtable (u16 vtable size, u16 table size, then
 * one u16 offset per field, 0 = absent); a field holding a table, vector or string is a uoffset
 * relative to the field; a vector is a u32 count then the elements. Every read here goes
 * through fb_* helpers that check the bytes lie inside the file (and a field inside its table)
 * in 64-bit arithmetic, so no offset, count or size from the file can reach outside it. The
 * schema (TensorFlow's tensorflow/lite/schema/schema.fbs) fixes the field numbers used below.
 */
#include "nn/tflite.h"

#include "io/npy.h" /* io_half_to_float */

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- flatbuffer reading ---- */

typedef struct {
    const uint8_t *d;
    size_t n;
} fb_file;

typedef struct {
    size_t pos;       /* table start */
    size_t vt;        /* its vtable */
    unsigned vsize;   /* vtable bytes */
    unsigned tsize;   /* table inline bytes */
} fb_table;

static int fb_has(const fb_file *f, uint64_t pos, uint64_t len)
{
    return pos <= f->n && len <= f->n - pos;
}

static uint32_t rd_u32(const uint8_t *p) { return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24; }
static uint16_t rd_u16(const uint8_t *p) { return (uint16_t)(p[0] | p[1] << 8); }
static uint64_t rd_u64(const uint8_t *p) { return (uint64_t)rd_u32(p) | (uint64_t)rd_u32(p + 4) << 32; }
static int32_t rd_i32(const uint8_t *p)
{
    uint32_t u = rd_u32(p);
    int32_t v;
    memcpy(&v, &u, 4);
    return v;
}
static float rd_f32(const uint8_t *p)
{
    uint32_t u = rd_u32(p);
    float v;
    memcpy(&v, &u, 4);
    return v;
}

/* The table at pos, its vtable checked. 0 ok, -1 outside the file or malformed. */
static int fb_table_at(const fb_file *f, uint64_t pos, fb_table *t)
{
    if (!fb_has(f, pos, 4)) return -1;
    int64_t vt = (int64_t)pos - (int64_t)rd_i32(f->d + pos);
    if (vt < 0 || !fb_has(f, (uint64_t)vt, 4)) return -1;
    unsigned vsize = rd_u16(f->d + vt), tsize = rd_u16(f->d + vt + 2);
    if (vsize < 4 || (vsize & 1) || !fb_has(f, (uint64_t)vt, vsize) || tsize < 4 || !fb_has(f, pos, tsize)) return -1;
    t->pos = (size_t)pos;
    t->vt = (size_t)vt;
    t->vsize = vsize;
    t->tsize = tsize;
    return 0;
}

/* Field i of t holding `bytes` inline bytes: 1 present (*pos set), 0 absent, -1 malformed. */
static int fb_field(const fb_table *t, const fb_file *f, int i, unsigned bytes, size_t *pos)
{
    unsigned slot = 4 + 2 * (unsigned)i;
    if (slot + 2 > t->vsize) return 0;
    unsigned off = rd_u16(f->d + t->vt + slot);
    if (off == 0) return 0;
    if (off < 4 || off + bytes > t->tsize) return -1;
    *pos = t->pos + off;
    return 1;
}

static int fb_int(const fb_table *t, const fb_file *f, int i, int def, int *v)
{
    size_t p;
    int r = fb_field(t, f, i, 4, &p);
    if (r < 0) return -1;
    *v = r ? rd_i32(f->d + p) : def;
    return 0;
}

static int fb_byte(const fb_table *t, const fb_file *f, int i, int def, int *v)
{
    size_t p;
    int r = fb_field(t, f, i, 1, &p);
    if (r < 0) return -1;
    *v = r ? f->d[p] : def;
    return 0;
}

static int fb_float(const fb_table *t, const fb_file *f, int i, float def, float *v)
{
    size_t p;
    int r = fb_field(t, f, i, 4, &p);
    if (r < 0) return -1;
    *v = r ? rd_f32(f->d + p) : def;
    return 0;
}

/* Follows the uoffset field i: 1 with *target, 0 absent, -1 malformed or outside. */
static int fb_ref(const fb_table *t, const fb_file *f, int i, uint64_t *target)
{
    size_t p;
    int r = fb_field(t, f, i, 4, &p);
    if (r <= 0) return r;
    uint64_t off = rd_u32(f->d + p);
    if (off == 0 || !fb_has(f, p + off, 4)) return -1;
    *target = p + off;
    return 1;
}

/* Vector field i of elements of `elem` bytes: *count (0 when absent) and *start (first element). */
static int fb_vector(const fb_table *t, const fb_file *f, int i, unsigned elem, uint32_t *count, size_t *start)
{
    uint64_t at;
    *count = 0;
    *start = 0;
    int r = fb_ref(t, f, i, &at);
    if (r <= 0) return r;
    uint32_t c = rd_u32(f->d + at);
    if (!fb_has(f, at + 4, (uint64_t)c * elem)) return -1;
    *count = c;
    *start = (size_t)(at + 4);
    return 0;
}

static int fb_subtable(const fb_table *t, const fb_file *f, int i, fb_table *sub)
{
    uint64_t at;
    int r = fb_ref(t, f, i, &at);
    if (r <= 0) return r;
    return fb_table_at(f, at, sub) ? -1 : 1;
}

/* Element k of a vector of tables starting at start. */
static int fb_vector_table(const fb_file *f, size_t start, uint32_t k, fb_table *sub)
{
    uint64_t p = (uint64_t)start + 4ull * k;
    uint64_t off = rd_u32(f->d + p);
    if (off == 0) return -1;
    return fb_table_at(f, p + off, sub);
}

/* ---- op names ---- */

static const char *const op_names[] = {
    "ADD", "AVERAGE_POOL_2D", "CONCATENATION", "CONV_2D", "DEPTHWISE_CONV_2D", "DEPTH_TO_SPACE", "DEQUANTIZE",
    "EMBEDDING_LOOKUP", "FLOOR", "FULLY_CONNECTED", "HASHTABLE_LOOKUP", "L2_NORMALIZATION", "L2_POOL_2D",
    "LOCAL_RESPONSE_NORMALIZATION", "LOGISTIC", "LSH_PROJECTION", "LSTM", "MAX_POOL_2D", "MUL", "RELU",
    "RELU_N1_TO_1", "RELU6", "RESHAPE", "RESIZE_BILINEAR", "RNN", "SOFTMAX", "SPACE_TO_DEPTH", "SVDF", "TANH",
    "CONCAT_EMBEDDINGS", "SKIP_GRAM", "CALL", "CUSTOM", "EMBEDDING_LOOKUP_SPARSE", "PAD",
    "UNIDIRECTIONAL_SEQUENCE_RNN", "GATHER", "BATCH_TO_SPACE_ND", "SPACE_TO_BATCH_ND", "TRANSPOSE", "MEAN", "SUB",
    "DIV", "SQUEEZE", "UNIDIRECTIONAL_SEQUENCE_LSTM", "STRIDED_SLICE", "BIDIRECTIONAL_SEQUENCE_RNN", "EXP",
    "TOPK_V2", "SPLIT", "LOG_SOFTMAX", "DELEGATE", "BIDIRECTIONAL_SEQUENCE_LSTM", "CAST", "PRELU", "MAXIMUM",
    "ARG_MAX", "MINIMUM", "LESS", "NEG", "PADV2", "GREATER", "GREATER_EQUAL", "LESS_EQUAL", "SELECT", "SLICE",
    "SIN", "TRANSPOSE_CONV", "SPARSE_TO_DENSE", "TILE", "EXPAND_DIMS", "EQUAL", "NOT_EQUAL", "LOG", "SUM", "SQRT",
    "RSQRT", "SHAPE", "POW", "ARG_MIN", "FAKE_QUANT", "REDUCE_PROD", "REDUCE_MAX", "PACK", "LOGICAL_OR",
    "ONE_HOT", "LOGICAL_AND", "LOGICAL_NOT", "UNPACK", "REDUCE_MIN", "FLOOR_DIV", "REDUCE_ANY", "SQUARE",
    "ZEROS_LIKE", "FILL", "FLOOR_MOD", "RANGE", "RESIZE_NEAREST_NEIGHBOR", "LEAKY_RELU", "SQUARED_DIFFERENCE",
    "MIRROR_PAD", "ABS", "SPLIT_V", "UNIQUE", "CEIL", "REVERSE_V2", "ADD_N", "GATHER_ND", "COS", "WHERE", "RANK", "ELU",
    "REVERSE_SEQUENCE", "MATRIX_DIAG", "QUANTIZE",
};

const char *nn_tfl_op_name(int code)
{
    if (code < 0 || code >= (int)(sizeof op_names / sizeof op_names[0])) return NULL;
    return op_names[code];
}

/* ---- the model ---- */

void nn_tfl_destroy(nn_tfl_model *m)
{
    if (!m) return;
    for (int i = 0; i < m->num_tensors; i++) {
        free(m->tensors[i].name);
        free(m->tensors[i].values);
        free(m->tensors[i].ints);
        free(m->tensors[i].scales);
        free(m->tensors[i].qvalues);
    }
    free(m->tensors);
    free(m->ops);
    memset(m, 0, sizeof *m);
}

typedef struct {
    fb_file f;
    const char *name;
    nn_tfl_model *m;
    size_t buffers;          /* vector start of Model.buffers */
    uint32_t num_buffers;
} parse_ctx;

static pg_status bad(const parse_ctx *c, const char *what)
{
    return pg_fail(PG_ERR_FORMAT, "%s: corrupt TFLite file: %s", c->name, what);
}

/* "name: operator k (CONV_2D, output 'x'): " + message. */
static pg_status op_fail(const parse_ctx *c, pg_status code, int k, const nn_tfl_op *op, const char *fmt, ...)
    __attribute__((format(printf, 5, 6)));
static pg_status op_fail(const parse_ctx *c, pg_status code, int k, const nn_tfl_op *op, const char *fmt, ...)
{
    char msg[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    const char *opname = nn_tfl_op_name(op->code);
    char codebuf[32];
    if (!opname) {
        snprintf(codebuf, sizeof codebuf, "builtin op %d", op->code);
        opname = codebuf;
    }
    const char *out = op->output >= 0 && op->output < c->m->num_tensors ? c->m->tensors[op->output].name : "?";
    return pg_fail(code, "%s: operator %d (%s, output '%s'): %s", c->name, k, opname, out ? out : "?", msg);
}

static size_t type_bytes(int type)
{
    switch (type) {
    case 0: return 4;  /* FLOAT32 */
    case 1: return 2;  /* FLOAT16 */
    case 2: return 4;  /* INT32 */
    case 3: return 1;  /* UINT8 */
    case 4: return 8;  /* INT64 */
    case 9: return 1;  /* INT8 */
    default: return 0;
    }
}

/* The bytes of buffer b: Buffer.data (field 0), or for files over 2 GiB Buffer.offset/size
 * (fields 1, 2: relative to the file start). *len 0 when the buffer is empty. */
static pg_status buffer_bytes(const parse_ctx *c, uint32_t b, const uint8_t **ptr, size_t *len)
{
    *ptr = NULL;
    *len = 0;
    if (b >= c->num_buffers) return bad(c, "tensor buffer index out of range");
    fb_table bt;
    if (fb_vector_table(&c->f, c->buffers, b, &bt)) return bad(c, "buffer table outside the file");
    uint32_t n;
    size_t start;
    if (fb_vector(&bt, &c->f, 0, 1, &n, &start)) return bad(c, "buffer data outside the file");
    if (n) {
        *ptr = c->f.d + start;
        *len = n;
        return PG_OK;
    }
    size_t p;
    int ro = fb_field(&bt, &c->f, 1, 8, &p);
    if (ro < 0) return bad(c, "buffer offset field");
    if (ro == 0) return PG_OK;
    uint64_t off = rd_u64(c->f.d + p), sz = 0;
    int rs = fb_field(&bt, &c->f, 2, 8, &p);
    if (rs < 0) return bad(c, "buffer size field");
    if (rs) sz = rd_u64(c->f.d + p);
    if (off <= 1 || !fb_has(&c->f, off, sz)) return bad(c, "buffer offset/size outside the file");
    *ptr = c->f.d + off;
    *len = (size_t)sz;
    return PG_OK;
}

/* Reads Tensor.quantization of an int8 / uint8 / int32 tensor into t and checks it: scales
 * positive and finite, one per channel of quant_dim (or one), as many zero points as scales (or
 * none), all equal and inside the type's range (0 for int32). Other types' parameters
 * (calibration ranges some converters leave on float tensors) are ignored. An int8 / uint8
 * tensor without scales fails. */
static pg_status parse_quantization(parse_ctx *c, const fb_table *tt, int i)
{
    nn_tfl_tensor *t = &c->m->tensors[i];
    const fb_file *f = &c->f;
    int is_int8 = t->type == NN_TFL_INT8 || t->type == NN_TFL_UINT8;
    if (!is_int8 && t->type != NN_TFL_INT32) return PG_OK;
    fb_table qt;
    int rq = fb_subtable(tt, f, 4, &qt);
    if (rq < 0) return bad(c, "quantization table");
    uint32_t ns = 0, nz = 0;
    size_t ss = 0, sz = 0;
    int qdim = 0;
    if (rq && (fb_vector(&qt, f, 2, 4, &ns, &ss) || fb_vector(&qt, f, 3, 8, &nz, &sz) || fb_int(&qt, f, 6, 0, &qdim)))
        return bad(c, "quantization parameters outside the file");
    if (ns == 0) {
        if (is_int8)
            return pg_fail(PG_ERR_FORMAT, "%s: tensor %d '%s': %s tensor without a quantization scale", c->name, i, t->name,
                           t->type == NN_TFL_INT8 ? "int8" : "uint8");
        return PG_OK;
    }
    if (ns > 1 && (qdim < 0 || qdim >= t->ndim || (uint32_t)t->dims[qdim] != ns))
        return pg_fail(PG_ERR_FORMAT, "%s: tensor %d '%s': %u scales do not match quantized dimension %d", c->name, i, t->name,
                       ns, qdim);
    if (nz != 0 && nz != ns)
        return pg_fail(PG_ERR_FORMAT, "%s: tensor %d '%s': %u zero points for %u scales", c->name, i, t->name, nz, ns);
    t->scales = pg_malloc((size_t)ns * sizeof(float), "tflite quantization scales");
    if (!t->scales) return PG_ERR_NOMEM;
    t->num_scales = (int)ns;
    t->quant_dim = ns > 1 ? qdim : 0;
    int64_t lo = t->type == NN_TFL_INT8 ? -128 : 0, hi = t->type == NN_TFL_INT8 ? 127 : t->type == NN_TFL_UINT8 ? 255 : 0;
    for (uint32_t k = 0; k < ns; k++) {
        float s = rd_f32(f->d + ss + 4 * k);
        int64_t zp = nz ? (int64_t)rd_u64(f->d + sz + 8 * k) : 0;
        if (!(isfinite(s) && s > 0))
            return pg_fail(PG_ERR_FORMAT, "%s: tensor %d '%s': quantization scale %g (channel %u) is not a positive finite number",
                           c->name, i, t->name, (double)s, k);
        if (zp < lo || zp > hi)
            return pg_fail(PG_ERR_FORMAT, "%s: tensor %d '%s': zero point %lld (channel %u) outside %lld..%lld", c->name, i,
                           t->name, (long long)zp, k, (long long)lo, (long long)hi);
        if (k > 0 && zp != t->zero_point)
            return pg_fail(PG_ERR_FORMAT, "%s: tensor %d '%s': per-channel zero points differ (%d, %lld)", c->name, i, t->name,
                           t->zero_point, (long long)zp);
        t->scales[k] = s;
        t->zero_point = (int)zp;
    }
    return PG_OK;
}

/* Reads tensor i: shape, type, name, and (constants) its data as float or int32. */
static pg_status parse_tensor(parse_ctx *c, const fb_table *tt, int i)
{
    nn_tfl_tensor *t = &c->m->tensors[i];
    const fb_file *f = &c->f;
    t->producer = -1;
    uint32_t nname;
    size_t sname;
    if (fb_vector(tt, f, 3, 1, &nname, &sname)) return bad(c, "tensor name outside the file");
    if (nname > 4096) nname = 4096;
    t->name = pg_malloc((size_t)nname + 1, "tflite tensor name");
    if (!t->name) return PG_ERR_NOMEM;
    if (nname) memcpy(t->name, f->d + sname, nname);
    t->name[nname] = '\0';
    for (uint32_t k = 0; k < nname; k++)
        if ((unsigned char)t->name[k] < 32) t->name[k] = '?'; /* names go into one-line messages */

    uint32_t nd;
    size_t sd;
    if (fb_vector(tt, f, 0, 4, &nd, &sd)) return bad(c, "tensor shape outside the file");
    if (nd > NN_TFL_MAX_DIMS)
        return pg_fail(PG_ERR_FORMAT, "%s: tensor %d '%s' has %u dimensions (at most %d supported)", c->name, i, t->name,
                       nd, NN_TFL_MAX_DIMS);
    t->ndim = (int)nd;
    t->count = 1;
    for (uint32_t k = 0; k < nd; k++) {
        int32_t v = rd_i32(f->d + sd + 4 * k);
        if (v < 1 || v > NN_TFL_MAX_DIM)
            return pg_fail(PG_ERR_SIZE, "%s: tensor %d '%s': dimension %u is %d (must be 1..%d)", c->name, i, t->name, k,
                           (int)v, NN_TFL_MAX_DIM);
        t->dims[k] = v;
        t->count *= v;
        if (t->count > NN_TFL_MAX_ELEMENTS)
            return pg_fail(PG_ERR_SIZE, "%s: tensor %d '%s' has more than %lld elements", c->name, i, t->name,
                           (long long)NN_TFL_MAX_ELEMENTS);
    }
    int type, buffer;
    if (fb_byte(tt, f, 1, 0, &type) || fb_int(tt, f, 2, 0, &buffer)) return bad(c, "tensor fields");
    t->type = type;
    PG_TRY(parse_quantization(c, tt, i));
    const uint8_t *data;
    size_t len;
    PG_TRY(buffer_bytes(c, (uint32_t)buffer, &data, &len));
    if (!len) return PG_OK; /* an activation (its type is checked where an op uses it) */

    size_t eb = type_bytes(type);
    if (!eb) return pg_fail(PG_ERR_FORMAT, "%s: tensor %d '%s': constant of unsupported type %d", c->name, i, t->name, type);
    if ((uint64_t)t->count * eb != len)
        return pg_fail(PG_ERR_FORMAT, "%s: tensor %d '%s': buffer holds %zu bytes, its shape needs %llu", c->name, i,
                       t->name, len, (unsigned long long)t->count * eb);
    size_t n = (size_t)t->count;
    if (type == NN_TFL_INT32 || type == NN_TFL_INT64) {
        t->ints = pg_malloc(n * sizeof(int32_t), "tflite int constant");
        if (!t->ints) return PG_ERR_NOMEM;
        for (size_t k = 0; k < n; k++) {
            int64_t v = type == NN_TFL_INT32 ? rd_i32(data + 4 * k) : (int64_t)rd_u64(data + 8 * k);
            if (v < INT32_MIN || v > INT32_MAX)
                return pg_fail(PG_ERR_FORMAT, "%s: tensor %d '%s': int64 value out of range", c->name, i, t->name);
            t->ints[k] = (int32_t)v;
        }
        if (type == NN_TFL_INT64 || !t->num_scales) return PG_OK;
        /* a quantised int32 constant (a bias): also its real values and stored integers */
    } else if (type == NN_TFL_INT8 || type == NN_TFL_UINT8) {
        if (!t->num_scales)
            return pg_fail(PG_ERR_FORMAT, "%s: tensor %d '%s': %s constant without a quantization scale", c->name, i,
                           t->name, type == NN_TFL_INT8 ? "int8" : "uint8");
    }
    t->values = pg_malloc(n * sizeof(float), "tflite constant");
    if (!t->values) return PG_ERR_NOMEM;
    if (type == NN_TFL_FLOAT32) {
        for (size_t k = 0; k < n; k++) t->values[k] = rd_f32(data + 4 * k);
    } else if (type == NN_TFL_FLOAT16) {
        for (size_t k = 0; k < n; k++) t->values[k] = io_half_to_float(rd_u16(data + 2 * k));
    } else {
        /* value = scale[ch] * (q - zero_point) along quant_dim */
        t->qvalues = pg_malloc(n * sizeof(int32_t), "tflite quantised constant");
        if (!t->qvalues) return PG_ERR_NOMEM;
        size_t inner = 1, chans = (size_t)t->num_scales;
        for (int k = t->quant_dim + 1; chans > 1 && k < t->ndim; k++) inner *= (size_t)t->dims[k];
        for (size_t k = 0; k < n; k++) {
            int32_t q = type == NN_TFL_INT8 ? (int8_t)data[k] : type == NN_TFL_UINT8 ? data[k] : t->ints[k];
            t->qvalues[k] = q;
            t->values[k] = (float)((double)t->scales[(k / inner) % chans] * ((double)q - t->zero_point));
        }
    }
    for (size_t k = 0; k < n; k++)
        if (!isfinite(t->values[k]))
            return pg_fail(PG_ERR_FORMAT, "%s: tensor %d '%s': constant holds NaN or infinity", c->name, i, t->name);
    return PG_OK;
}

/* Options table type each op expects (BuiltinOptions union index), -1 for none. */
static int options_type(int code)
{
    switch (code) {
    case NN_TFL_CONV_2D: return 1;
    case NN_TFL_DEPTHWISE_CONV_2D: return 2;
    case NN_TFL_CONCATENATION: return 10;
    case NN_TFL_ADD: return 11;
    case NN_TFL_RESIZE_BILINEAR: return 15;
    case NN_TFL_RESHAPE: return 17;
    case NN_TFL_MUL: return 21;
    case NN_TFL_PAD: return 22;
    case NN_TFL_SUB: return 28;
    case NN_TFL_STRIDED_SLICE: return 32;
    case NN_TFL_DEQUANTIZE: return 38;
    case NN_TFL_MAXIMUM: case NN_TFL_MINIMUM: return 39;
    case NN_TFL_TRANSPOSE_CONV: return 49;
    case NN_TFL_LEAKY_RELU: return 75;
    case NN_TFL_RESIZE_NEAREST_NEIGHBOR: return 74;
    case NN_TFL_QUANTIZE: return 89;
    case NN_TFL_RELU: case NN_TFL_RELU6: case NN_TFL_LOGISTIC: case NN_TFL_TANH: return 0;
    default: return -1;
    }
}

/* Reads an operator's options into op (fields absent from the file keep the schema's defaults). */
static pg_status parse_options(parse_ctx *c, const fb_table *ot, int k, nn_tfl_op *op, int reshape_new_shape[NN_TFL_MAX_DIMS + 1])
{
    const fb_file *f = &c->f;
    int ok = 0;
    switch (op->code) {
    case NN_TFL_CONV_2D:
        ok = fb_byte(ot, f, 0, 0, &op->padding_valid) | fb_int(ot, f, 1, 0, &op->stride_w) | fb_int(ot, f, 2, 0, &op->stride_h) |
             fb_byte(ot, f, 3, 0, &op->act) | fb_int(ot, f, 4, 1, &op->dilation_w) | fb_int(ot, f, 5, 1, &op->dilation_h);
        break;
    case NN_TFL_DEPTHWISE_CONV_2D:
        ok = fb_byte(ot, f, 0, 0, &op->padding_valid) | fb_int(ot, f, 1, 0, &op->stride_w) | fb_int(ot, f, 2, 0, &op->stride_h) |
             fb_int(ot, f, 3, 0, &op->depth_multiplier) | fb_byte(ot, f, 4, 0, &op->act) |
             fb_int(ot, f, 5, 1, &op->dilation_w) | fb_int(ot, f, 6, 1, &op->dilation_h);
        break;
    case NN_TFL_TRANSPOSE_CONV:
        ok = fb_byte(ot, f, 0, 0, &op->padding_valid) | fb_int(ot, f, 1, 0, &op->stride_w) | fb_int(ot, f, 2, 0, &op->stride_h) |
             fb_byte(ot, f, 3, 0, &op->act);
        break;
    case NN_TFL_CONCATENATION:
        ok = fb_int(ot, f, 0, 0, &op->axis) | fb_byte(ot, f, 1, 0, &op->act);
        break;
    case NN_TFL_ADD: case NN_TFL_MUL: case NN_TFL_SUB:
        ok = fb_byte(ot, f, 0, 0, &op->act);
        break;
    case NN_TFL_RESIZE_BILINEAR:
        ok = fb_byte(ot, f, 2, 0, &op->align_corners) | fb_byte(ot, f, 3, 0, &op->half_pixel_centers);
        break;
    case NN_TFL_RESIZE_NEAREST_NEIGHBOR:
        ok = fb_byte(ot, f, 0, 0, &op->align_corners) | fb_byte(ot, f, 1, 0, &op->half_pixel_centers);
        break;
    case NN_TFL_STRIDED_SLICE: {
        int ellipsis = 0, new_axis = 0, offset = 0;
        ok = fb_int(ot, f, 0, 0, &op->begin_mask) | fb_int(ot, f, 1, 0, &op->end_mask) | fb_int(ot, f, 2, 0, &ellipsis) |
             fb_int(ot, f, 3, 0, &new_axis) | fb_int(ot, f, 4, 0, &op->shrink_axis_mask) | fb_byte(ot, f, 5, 0, &offset);
        if (!ok && (ellipsis || new_axis || offset))
            return op_fail(c, PG_ERR_FORMAT, k, op, "ellipsis, new-axis and offset masks are not supported");
        break;
    }
    case NN_TFL_LEAKY_RELU:
        ok = fb_float(ot, f, 0, 0.0f, &op->alpha);
        break;
    case NN_TFL_RESHAPE: {
        uint32_t n;
        size_t s;
        ok = fb_vector(ot, f, 0, 4, &n, &s);
        if (!ok && n > NN_TFL_MAX_DIMS) return op_fail(c, PG_ERR_FORMAT, k, op, "new shape has %u dimensions", n);
        if (!ok && s) {
            reshape_new_shape[0] = (int)n;
            for (uint32_t j = 0; j < n; j++) reshape_new_shape[1 + j] = rd_i32(f->d + s + 4 * j);
        }
        break;
    }
    default:
        break;
    }
    return ok ? bad(c, "operator options outside their table") : PG_OK;
}

static int dims_equal(const nn_tfl_tensor *t, int ndim, const int *dims)
{
    if (t->ndim != ndim) return 0;
    for (int i = 0; i < ndim; i++)
        if (t->dims[i] != dims[i]) return 0;
    return 1;
}

static void dims_text(char *buf, size_t size, int ndim, const int *dims)
{
    size_t n = (size_t)snprintf(buf, size, "[");
    for (int i = 0; i < ndim && n < size; i++) n += (size_t)snprintf(buf + n, size - n, "%s%d", i ? "," : "", dims[i]);
    if (n < size) snprintf(buf + n, size - n, "]");
}

/* SAME / VALID output length and leading pad of one spatial axis of a conv. */
static int conv_out(int in, int k, int stride, int dil, int valid, int *pad_before, int *pad_after)
{
    int64_t dk = (int64_t)(k - 1) * dil + 1;
    int64_t out = valid ? (in - dk) / stride + 1 : ((int64_t)in + stride - 1) / stride;
    if (valid && in < dk) return 0;
    int64_t total = (out - 1) * stride + dk - in;
    if (total < 0) total = 0;
    *pad_before = (int)(total / 2);
    *pad_after = (int)(total - total / 2);
    return (int)out;
}

/* The op's output shape from its inputs (and the constants it reads); checks inputs. */
static pg_status infer_shape(parse_ctx *c, int k, nn_tfl_op *op, const int *reshape_new_shape, int *ndim, int *dims)
{
    nn_tfl_tensor *T = c->m->tensors;
    nn_tfl_tensor *x = &T[op->inputs[0]];
    int ni = op->num_inputs;
#define NEED(cond, ...) do { if (!(cond)) return op_fail(c, PG_ERR_FORMAT, k, op, __VA_ARGS__); } while (0)
    switch (op->code) {
    case NN_TFL_CONV_2D:
    case NN_TFL_DEPTHWISE_CONV_2D: {
        NEED(ni == 2 || ni == 3, "needs 2 or 3 inputs, has %d", ni);
        const nn_tfl_tensor *w = op->inputs[1] >= 0 ? &T[op->inputs[1]] : NULL;
        NEED(x->ndim == 4, "input must be 4-D NHWC");
        NEED(w && w->values && w->ndim == 4, "weights must be a 4-D constant");
        NEED(op->stride_w >= 1 && op->stride_h >= 1 && op->stride_w <= 64 && op->stride_h <= 64, "stride %dx%d", op->stride_w, op->stride_h);
        NEED(op->dilation_w >= 1 && op->dilation_h >= 1 && op->dilation_w <= 64 && op->dilation_h <= 64, "dilation %dx%d",
             op->dilation_w, op->dilation_h);
        int cin = x->dims[3], cout;
        if (op->code == NN_TFL_CONV_2D) {
            cout = w->dims[0];
            NEED(w->dims[3] >= 1 && cin % w->dims[3] == 0 && cout % (cin / w->dims[3]) == 0,
                 "weights [%d,%d,%d,%d] do not fit %d input channels", w->dims[0], w->dims[1], w->dims[2], w->dims[3], cin);
        } else {
            cout = w->dims[3];
            NEED(w->dims[0] == 1 && cout % cin == 0, "depthwise weights [%d,%d,%d,%d] do not fit %d input channels",
                 w->dims[0], w->dims[1], w->dims[2], w->dims[3], cin);
            NEED(op->depth_multiplier == 0 || op->depth_multiplier == cout / cin, "depth multiplier %d, weights say %d",
                 op->depth_multiplier, cout / cin);
            op->depth_multiplier = cout / cin;
        }
        if (ni == 3 && op->inputs[2] >= 0) {
            const nn_tfl_tensor *b = &T[op->inputs[2]];
            NEED(b->values && b->count == cout, "bias must be a constant of %d values", cout);
        }
        int oh = conv_out(x->dims[1], w->dims[1], op->stride_h, op->dilation_h, op->padding_valid, &op->pad[0], &op->pad[2]);
        int ow = conv_out(x->dims[2], w->dims[2], op->stride_w, op->dilation_w, op->padding_valid, &op->pad[1], &op->pad[3]);
        NEED(oh >= 1 && ow >= 1, "kernel larger than the input");
        *ndim = 4;
        dims[0] = x->dims[0], dims[1] = oh, dims[2] = ow, dims[3] = cout;
        return PG_OK;
    }
    case NN_TFL_TRANSPOSE_CONV: {
        NEED(ni == 3 || ni == 4, "needs 3 or 4 inputs, has %d", ni);
        const nn_tfl_tensor *s = &T[op->inputs[0]];
        const nn_tfl_tensor *w = op->inputs[1] >= 0 ? &T[op->inputs[1]] : NULL;
        x = op->inputs[2] >= 0 ? &T[op->inputs[2]] : NULL;
        NEED(s->ints && s->count == 4, "output shape must be a constant of 4 ints");
        NEED(x && x->ndim == 4, "input must be 4-D NHWC");
        NEED(w && w->values && w->ndim == 4 && w->dims[3] == x->dims[3], "weights must be a 4-D constant [O,kh,kw,%d]", x->dims[3]);
        NEED(op->stride_w >= 1 && op->stride_h >= 1 && op->stride_w <= 64 && op->stride_h <= 64, "stride %dx%d", op->stride_w, op->stride_h);
        for (int j = 0; j < 4; j++) NEED(s->ints[j] >= 1 && s->ints[j] <= NN_TFL_MAX_DIM, "output shape entry %d is %d", j, s->ints[j]);
        NEED(s->ints[0] == x->dims[0] && s->ints[3] == w->dims[0], "output shape does not match the input batch / weights");
        int oh = s->ints[1], ow = s->ints[2];
        /* the output must be what a forward conv of it would map back onto the input */
        int pt, pb, pl, pr;
        NEED(conv_out(oh, w->dims[1], op->stride_h, 1, op->padding_valid, &pt, &pb) == x->dims[1] &&
                 conv_out(ow, w->dims[2], op->stride_w, 1, op->padding_valid, &pl, &pr) == x->dims[2],
             "output %dx%d does not fit input %dx%d with stride %dx%d", oh, ow, x->dims[1], x->dims[2], op->stride_h, op->stride_w);
        op->pad[0] = pt, op->pad[1] = pl, op->pad[2] = pb, op->pad[3] = pr;
        if (ni == 4 && op->inputs[3] >= 0) {
            const nn_tfl_tensor *b = &T[op->inputs[3]];
            NEED(b->values && b->count == w->dims[0], "bias must be a constant of %d values", w->dims[0]);
        }
        *ndim = 4;
        for (int j = 0; j < 4; j++) dims[j] = s->ints[j];
        return PG_OK;
    }
    case NN_TFL_ADD: case NN_TFL_SUB: case NN_TFL_MUL: case NN_TFL_MAXIMUM: case NN_TFL_MINIMUM: {
        NEED(ni == 2 && op->inputs[1] >= 0, "needs 2 inputs, has %d", ni);
        const nn_tfl_tensor *b = &T[op->inputs[1]];
        *ndim = x->ndim > b->ndim ? x->ndim : b->ndim;
        for (int j = 0; j < *ndim; j++) {
            int da = j - (*ndim - x->ndim) >= 0 ? x->dims[j - (*ndim - x->ndim)] : 1;
            int db = j - (*ndim - b->ndim) >= 0 ? b->dims[j - (*ndim - b->ndim)] : 1;
            NEED(da == db || da == 1 || db == 1, "shapes do not broadcast (axis %d: %d vs %d)", j, da, db);
            dims[j] = da > db ? da : db;
        }
        return PG_OK;
    }
    case NN_TFL_CONCATENATION: {
        NEED(ni >= 1, "no inputs");
        int axis = op->axis < 0 ? op->axis + x->ndim : op->axis;
        NEED(axis >= 0 && axis < x->ndim, "axis %d out of range for %d dimensions", op->axis, x->ndim);
        op->axis = axis;
        *ndim = x->ndim;
        memcpy(dims, x->dims, sizeof(int) * (size_t)x->ndim);
        int64_t sum = 0;
        for (int j = 0; j < ni; j++) {
            NEED(op->inputs[j] >= 0, "input %d omitted", j);
            const nn_tfl_tensor *t = &T[op->inputs[j]];
            NEED(t->ndim == x->ndim, "input %d has %d dimensions, input 0 has %d", j, t->ndim, x->ndim);
            for (int d = 0; d < x->ndim; d++) NEED(d == axis || t->dims[d] == x->dims[d], "input %d: dimension %d differs", j, d);
            sum += t->dims[axis];
        }
        NEED(sum <= NN_TFL_MAX_DIM, "concatenated axis too long");
        dims[axis] = (int)sum;
        return PG_OK;
    }
    case NN_TFL_STRIDED_SLICE: {
        NEED(ni == 4, "needs 4 inputs, has %d", ni);
        const nn_tfl_tensor *b = op->inputs[1] >= 0 ? &T[op->inputs[1]] : NULL, *e = op->inputs[2] >= 0 ? &T[op->inputs[2]] : NULL,
                            *s = op->inputs[3] >= 0 ? &T[op->inputs[3]] : NULL;
        NEED(b && e && s && b->ints && e->ints && s->ints && b->count == x->ndim && e->count == x->ndim && s->count == x->ndim,
             "begin, end and strides must be constants of %d ints", x->ndim);
        *ndim = 0;
        for (int d = 0; d < x->ndim; d++) {
            int64_t n = x->dims[d], st = s->ints[d], lo, hi;
            NEED(st != 0 && st > -NN_TFL_MAX_DIM && st < NN_TFL_MAX_DIM, "stride %d of axis %d", (int)st, d);
            int64_t bb = b->ints[d], ee = e->ints[d];
            if (op->begin_mask >> d & 1) lo = st > 0 ? 0 : n - 1;
            else {
                if (bb < 0) bb += n;
                lo = st > 0 ? (bb < 0 ? 0 : bb > n ? n : bb) : (bb < -1 ? -1 : bb > n - 1 ? n - 1 : bb);
            }
            if (op->shrink_axis_mask >> d & 1) {
                NEED(lo >= 0 && lo < n, "shrunk axis %d index out of range", d);
                op->slice_begin[d] = (int)lo, op->slice_stride[d] = 1, op->slice_len[d] = 1;
                continue;
            }
            if (op->end_mask >> d & 1) hi = st > 0 ? n : -1;
            else {
                if (ee < 0) ee += n;
                hi = st > 0 ? (ee < 0 ? 0 : ee > n ? n : ee) : (ee < -1 ? -1 : ee > n - 1 ? n - 1 : ee);
            }
            int64_t len = st > 0 ? (hi - lo + st - 1) / st : (lo - hi + (-st) - 1) / (-st);
            NEED(len >= 1, "axis %d slices to nothing", d);
            op->slice_begin[d] = (int)lo, op->slice_stride[d] = (int)st, op->slice_len[d] = (int)len;
            dims[(*ndim)++] = (int)len;
        }
        return PG_OK;
    }
    case NN_TFL_RESIZE_BILINEAR: case NN_TFL_RESIZE_NEAREST_NEIGHBOR: {
        NEED(ni == 2 && op->inputs[1] >= 0, "needs 2 inputs, has %d", ni);
        const nn_tfl_tensor *s = &T[op->inputs[1]];
        NEED(x->ndim == 4, "input must be 4-D NHWC");
        NEED(s->ints && s->count == 2, "size must be a constant of 2 ints");
        NEED(s->ints[0] >= 1 && s->ints[1] >= 1 && s->ints[0] <= NN_TFL_MAX_DIM && s->ints[1] <= NN_TFL_MAX_DIM, "size %dx%d",
             s->ints[0], s->ints[1]);
        NEED(!(op->align_corners && op->half_pixel_centers), "align_corners with half_pixel_centers");
        *ndim = 4;
        dims[0] = x->dims[0], dims[1] = s->ints[0], dims[2] = s->ints[1], dims[3] = x->dims[3];
        return PG_OK;
    }
    case NN_TFL_PAD: {
        NEED(ni == 2 && op->inputs[1] >= 0, "needs 2 inputs, has %d", ni);
        const nn_tfl_tensor *p = &T[op->inputs[1]];
        NEED(p->ints && p->count == 2 * x->ndim, "paddings must be a constant of %dx2 ints", x->ndim);
        *ndim = x->ndim;
        for (int d = 0; d < x->ndim; d++) {
            int a = p->ints[2 * d], z = p->ints[2 * d + 1];
            NEED(a >= 0 && z >= 0 && a <= NN_TFL_MAX_DIM && z <= NN_TFL_MAX_DIM, "padding of axis %d is %d, %d", d, a, z);
            NEED((int64_t)x->dims[d] + a + z <= NN_TFL_MAX_DIM, "padded axis %d too long", d);
            op->pads[d] = a;
            op->pads[NN_TFL_MAX_DIMS + d] = z;
            dims[d] = x->dims[d] + a + z;
        }
        return PG_OK;
    }
    case NN_TFL_RESHAPE: {
        NEED(ni == 1 || ni == 2, "needs 1 or 2 inputs, has %d", ni);
        const int *want = NULL;
        int nw = 0;
        if (ni == 2 && op->inputs[1] >= 0) {
            const nn_tfl_tensor *s = &T[op->inputs[1]];
            NEED(s->ints && s->ndim <= 1 && s->count <= NN_TFL_MAX_DIMS, "shape must be a constant of at most %d ints", NN_TFL_MAX_DIMS);
            want = s->ints;
            nw = (int)s->count;
        } else if (reshape_new_shape[0] >= 0) {
            want = reshape_new_shape + 1;
            nw = reshape_new_shape[0];
        } else
            return op_fail(c, PG_ERR_FORMAT, k, op, "no target shape");
        int64_t known = 1;
        int infer = -1;
        for (int d = 0; d < nw; d++) {
            if (want[d] == -1) {
                NEED(infer < 0, "more than one -1 in the shape");
                infer = d;
            } else {
                NEED(want[d] >= 1 && want[d] <= NN_TFL_MAX_DIM, "shape entry %d is %d", d, want[d]);
                known *= want[d];
                NEED(known <= NN_TFL_MAX_ELEMENTS, "shape too large");
            }
            dims[d] = want[d];
        }
        if (infer >= 0) {
            NEED(x->count % known == 0, "cannot infer the -1 of the shape");
            dims[infer] = (int)(x->count / known);
            known = x->count;
        }
        NEED(known == x->count, "%lld elements reshaped to %lld", (long long)x->count, (long long)known);
        *ndim = nw;
        return PG_OK;
    }
    case NN_TFL_LEAKY_RELU: case NN_TFL_RELU: case NN_TFL_RELU6: case NN_TFL_LOGISTIC: case NN_TFL_TANH:
    case NN_TFL_QUANTIZE: case NN_TFL_DEQUANTIZE:
        NEED(ni == 1, "needs 1 input, has %d", ni);
        NEED(isfinite(op->alpha), "alpha is not finite");
        *ndim = x->ndim;
        memcpy(dims, x->dims, sizeof(int) * (size_t)x->ndim);
        return PG_OK;
    default:
        return op_fail(c, PG_ERR_FORMAT, k, op, "unsupported op");
    }
#undef NEED
}

/* Whether two per-tensor quantisations are the same. */
static int same_quantization(const nn_tfl_tensor *a, const nn_tfl_tensor *b)
{
    return a->type == b->type && a->scales[0] == b->scales[0] && a->zero_point == b->zero_point;
}

/* The activation types an op may read and write, and on integer activations the quantisation
 * rules TFLite's kernels assume (see tflite.h): float ops read and write float32; integer ops
 * read and write one integer type with per-tensor parameters; QUANTIZE / DEQUANTIZE convert. */
static pg_status check_types(parse_ctx *c, int k, const nn_tfl_op *op)
{
    const nn_tfl_tensor *T = c->m->tensors, *y = &T[op->output], *x = &T[op->inputs[0]];
#define NEED(cond, ...) do { if (!(cond)) return op_fail(c, PG_ERR_FORMAT, k, op, __VA_ARGS__); } while (0)
    int y_int = y->type == NN_TFL_INT8 || y->type == NN_TFL_UINT8;
    NEED(y_int || y->type == NN_TFL_FLOAT32, "output is of type %d (float32, int8 or uint8 supported)", y->type);
    NEED(!y_int || y->num_scales == 1, "output has %d quantization scales (one per tensor supported for activations)", y->num_scales);
    for (int j = 0; j < op->num_inputs; j++) {
        const nn_tfl_tensor *t = op->inputs[j] >= 0 ? &T[op->inputs[j]] : NULL;
        if (!t || nn_tfl_is_const(t)) continue;
        int t_int = nn_tfl_is_quantized(t);
        NEED(t_int || t->type == NN_TFL_FLOAT32, "input %d (tensor '%s') is of type %d (float32, int8 or uint8 supported)", j, t->name,
             t->type);
        NEED(!t_int || t->num_scales == 1, "input %d (tensor '%s') has %d quantization scales (one per tensor supported)", j, t->name,
             t->num_scales);
        if (op->code == NN_TFL_QUANTIZE || op->code == NN_TFL_DEQUANTIZE) continue;
        NEED(t->type == y->type, "input %d (tensor '%s') is of type %d but the output of type %d", j, t->name, t->type, y->type);
    }
    if (op->code == NN_TFL_QUANTIZE) {
        NEED(!nn_tfl_is_const(x), "QUANTIZE of a constant is not supported");
        NEED(y_int, "QUANTIZE must write an int8 or uint8 tensor");
        return PG_OK;
    }
    if (op->code == NN_TFL_DEQUANTIZE) {
        NEED(nn_tfl_is_quantized(x) && y->type == NN_TFL_FLOAT32, "DEQUANTIZE must read int8 / uint8 and write float32");
        return PG_OK;
    }
    if (!y_int) return PG_OK;
    NEED(nn_tfl_is_quantized(x), "input 0 must be an int8 / uint8 activation");
    switch (op->code) {
    case NN_TFL_CONV_2D: case NN_TFL_DEPTHWISE_CONV_2D: {
        const nn_tfl_tensor *w = &T[op->inputs[1]];
        int depthwise = op->code == NN_TFL_DEPTHWISE_CONV_2D, cout = depthwise ? w->dims[3] : w->dims[0];
        NEED(w->qvalues && (w->type == NN_TFL_INT8 || w->type == NN_TFL_UINT8), "weights of an integer conv must be int8 or uint8");
        NEED(w->num_scales == 1 || (w->num_scales == cout && w->quant_dim == (depthwise ? 3 : 0)),
             "weights have %d scales along dimension %d (1, or %d along the output channels)", w->num_scales, w->quant_dim, cout);
        if (op->num_inputs > 2 && op->inputs[2] >= 0) {
            const nn_tfl_tensor *b = &T[op->inputs[2]];
            NEED(b->type == NN_TFL_INT32 && b->qvalues && b->num_scales == w->num_scales,
                 "bias must be int32 with as many scales as the weights (%d)", w->num_scales);
            for (int o = 0; o < b->num_scales; o++) {
                double want = (double)x->scales[0] * w->scales[o], have = b->scales[o];
                NEED(fabs(have - want) <= 1e-5 * want, "bias scale %g of channel %d is not input scale x weight scale (%g)", have, o, want);
            }
        }
        return PG_OK;
    }
    case NN_TFL_ADD:
        NEED(nn_tfl_is_quantized(&T[op->inputs[1]]), "input 1 must be an int8 / uint8 activation");
        return PG_OK;
    case NN_TFL_PAD: case NN_TFL_RESIZE_NEAREST_NEIGHBOR: case NN_TFL_RESHAPE:
        NEED(same_quantization(x, y), "output quantization (scale %g, zero point %d) differs from the input's (%g, %d)", (double)y->scales[0],
             y->zero_point, (double)x->scales[0], x->zero_point);
        return PG_OK;
    default:
        return op_fail(c, PG_ERR_FORMAT, k, op, "not supported on int8 / uint8 activations");
    }
#undef NEED
}

static pg_status parse_operator(parse_ctx *c, const fb_table *ot, int k, const int *codes, uint32_t num_codes, char *written)
{
    const fb_file *f = &c->f;
    nn_tfl_model *m = c->m;
    nn_tfl_op *op = &m->ops[m->num_ops];
    memset(op, 0, sizeof *op);
    op->output = -1;
    op->dilation_w = op->dilation_h = 1;
    int opcode;
    if (fb_int(ot, f, 0, 0, &opcode)) return bad(c, "operator opcode index");
    if (opcode < 0 || (uint32_t)opcode >= num_codes)
        return pg_fail(PG_ERR_FORMAT, "%s: operator %d: opcode index %d out of range", c->name, k, opcode);
    op->code = codes[opcode];
    uint32_t ni, no;
    size_t si, so;
    if (fb_vector(ot, f, 1, 4, &ni, &si) || fb_vector(ot, f, 2, 4, &no, &so)) return bad(c, "operator inputs/outputs outside the file");
    if (no >= 1) {
        int o = rd_i32(f->d + so);
        if (o >= 0 && o < m->num_tensors) op->output = o;
    }
    if (options_type(op->code) < 0) return op_fail(c, PG_ERR_FORMAT, k, op, "unsupported op");
    if (no != 1) return op_fail(c, PG_ERR_FORMAT, k, op, "has %u outputs (1 supported)", no);
    if (op->output < 0) return pg_fail(PG_ERR_FORMAT, "%s: operator %d: output tensor index out of range", c->name, k);
    if (ni < 1 || ni > NN_TFL_MAX_OP_INPUTS) return op_fail(c, PG_ERR_FORMAT, k, op, "has %u inputs", ni);
    op->num_inputs = (int)ni;
    for (uint32_t j = 0; j < ni; j++) {
        int t = rd_i32(f->d + si + 4 * j);
        if (t < -1 || t >= m->num_tensors) return op_fail(c, PG_ERR_FORMAT, k, op, "input %u: tensor index %d out of range", j, t);
        if (t >= 0 && !written[t] && !nn_tfl_is_const(&m->tensors[t]))
            return op_fail(c, PG_ERR_FORMAT, k, op, "input %u (tensor %d '%s') is not computed before this operator (cyclic or unordered graph)",
                           j, t, m->tensors[t].name);
        if (j == 0 && t < 0) return op_fail(c, PG_ERR_FORMAT, k, op, "input 0 omitted");
        op->inputs[j] = t;
    }
    int otype = 0, reshape_new_shape[NN_TFL_MAX_DIMS + 1] = { -1 };
    if (fb_byte(ot, f, 3, 0, &otype)) return bad(c, "operator options type");
    fb_table opt;
    int ro = fb_subtable(ot, f, 4, &opt);
    if (ro < 0) return bad(c, "operator options outside the file");
    if (ro) {
        if (otype != options_type(op->code)) return op_fail(c, PG_ERR_FORMAT, k, op, "options of type %d (expected %d)", otype, options_type(op->code));
        PG_TRY(parse_options(c, &opt, k, op, reshape_new_shape));
    }
    if (op->act < 0 || op->act > NN_TFL_ACT_TANH) return op_fail(c, PG_ERR_FORMAT, k, op, "unsupported fused activation %d", op->act);

    nn_tfl_tensor *out = &m->tensors[op->output];
    if (written[op->output] || nn_tfl_is_const(out))
        return op_fail(c, PG_ERR_FORMAT, k, op, "output tensor %d is written twice or is a constant", op->output);

    if (op->code == NN_TFL_DEQUANTIZE && nn_tfl_is_const(&m->tensors[op->inputs[0]])) {
        /* constant folding: the output is the input's dequantised values */
        const nn_tfl_tensor *in = &m->tensors[op->inputs[0]];
        if (ni != 1 || !in->values) return op_fail(c, PG_ERR_FORMAT, k, op, "DEQUANTIZE of a constant that holds no numbers");
        if (!dims_equal(out, in->ndim, in->dims)) return op_fail(c, PG_ERR_FORMAT, k, op, "output shape differs from the input's");
        out->values = pg_malloc((size_t)in->count * sizeof(float), "tflite dequantized constant");
        if (!out->values) return PG_ERR_NOMEM;
        memcpy(out->values, in->values, (size_t)in->count * sizeof(float));
        return PG_OK; /* no op added */
    }
    int ndim = 0, dims[NN_TFL_MAX_DIMS];
    PG_TRY(infer_shape(c, k, op, reshape_new_shape, &ndim, dims));
    PG_TRY(check_types(c, k, op));
    if (!dims_equal(out, ndim, dims)) {
        char want[96], have[96];
        dims_text(want, sizeof want, ndim, dims);
        dims_text(have, sizeof have, out->ndim, out->dims);
        return op_fail(c, PG_ERR_FORMAT, k, op, "output declared %s but its inputs give %s", have, want);
    }
    out->producer = m->num_ops;
    written[op->output] = 1;
    m->num_ops++;
    return PG_OK;
}

static pg_status parse_io(parse_ctx *c, const fb_table *g, int field, int *list, int *count, const char *what)
{
    uint32_t n;
    size_t s;
    if (fb_vector(g, &c->f, field, 4, &n, &s)) return bad(c, "subgraph inputs/outputs outside the file");
    if (n < 1 || n > NN_TFL_MAX_IO) return pg_fail(PG_ERR_FORMAT, "%s: %u graph %s (1..%d supported)", c->name, n, what, NN_TFL_MAX_IO);
    for (uint32_t j = 0; j < n; j++) {
        int t = rd_i32(c->f.d + s + 4 * j);
        if (t < 0 || t >= c->m->num_tensors) return pg_fail(PG_ERR_FORMAT, "%s: graph %s tensor index %d out of range", c->name, what, t);
        list[j] = t;
    }
    *count = (int)n;
    return PG_OK;
}

static pg_status parse_model(parse_ctx *c)
{
    const fb_file *f = &c->f;
    nn_tfl_model *m = c->m;
    if (f->n < 8) return bad(c, "shorter than a flatbuffer header");
    if (memcmp(f->d + 4, "TFL3", 4) != 0) return pg_fail(PG_ERR_FORMAT, "%s: not a TFLite file (no TFL3 identifier)", c->name);
    fb_table root, g;
    if (fb_table_at(f, rd_u32(f->d), &root)) return bad(c, "root table outside the file");
    int version;
    if (fb_int(&root, f, 0, 0, &version)) return bad(c, "version");
    if (version != 3) return pg_fail(PG_ERR_FORMAT, "%s: TFLite schema version %d (3 supported)", c->name, version);

    uint32_t ncodes, nsub;
    size_t scodes, ssub;
    if (fb_vector(&root, f, 1, 4, &ncodes, &scodes) || fb_vector(&root, f, 4, 4, &c->num_buffers, &c->buffers) ||
        fb_vector(&root, f, 2, 4, &nsub, &ssub))
        return bad(c, "model tables outside the file");
    if (nsub < 1) return bad(c, "no subgraph");
    if (fb_vector_table(f, ssub, 0, &g)) return bad(c, "subgraph outside the file");

    int *codes = pg_malloc(((size_t)ncodes + 1) * sizeof(int), "tflite opcodes");
    if (!codes) return PG_ERR_NOMEM;
    for (uint32_t k = 0; k < ncodes; k++) {
        fb_table ct;
        int dep, code;
        uint32_t ncustom;
        size_t scustom;
        if (fb_vector_table(f, scodes, k, &ct) || fb_byte(&ct, f, 0, 0, &dep) || fb_int(&ct, f, 3, 0, &code) ||
            fb_vector(&ct, f, 1, 1, &ncustom, &scustom)) {
            free(codes);
            return bad(c, "operator code table");
        }
        /* deprecated_builtin_code (an int8) holds codes < 127; newer files set builtin_code */
        int d8 = (int)(int8_t)dep;
        codes[k] = code > d8 ? code : d8;
        if (ncustom) codes[k] = 32; /* CUSTOM */
    }

    uint32_t nt, nops;
    size_t st, sops;
    pg_status s = PG_OK;
    char *written = NULL;
    if (fb_vector(&g, f, 0, 4, &nt, &st) || fb_vector(&g, f, 3, 4, &nops, &sops)) s = bad(c, "subgraph tensors/operators outside the file");
    else if (nt > NN_TFL_MAX_TENSORS || nops > NN_TFL_MAX_OPS) s = pg_fail(PG_ERR_SIZE, "%s: %u tensors, %u operators (too many)", c->name, nt, nops);
    else if (nops == 0) s = pg_fail(PG_ERR_FORMAT, "%s: the graph has no operators", c->name);
    if (!s) {
        m->tensors = pg_calloc(nt ? nt : 1, sizeof *m->tensors, "tflite tensors");
        m->ops = pg_calloc(nops, sizeof *m->ops, "tflite operators");
        written = pg_calloc(nt ? nt : 1, 1, "tflite tensor flags");
        if (!m->tensors || !m->ops || !written) s = PG_ERR_NOMEM;
    }
    for (uint32_t i = 0; !s && i < nt; i++) {
        fb_table tt;
        m->num_tensors = (int)i + 1;
        m->tensors[i].producer = -1;
        if (fb_vector_table(f, st, i, &tt)) s = bad(c, "tensor table outside the file");
        else s = parse_tensor(c, &tt, (int)i);
    }
    if (!s) s = parse_io(c, &g, 1, m->inputs, &m->num_inputs, "inputs");
    if (!s) s = parse_io(c, &g, 2, m->outputs, &m->num_outputs, "outputs");
    for (int j = 0; !s && j < m->num_inputs; j++) {
        const nn_tfl_tensor *t = &m->tensors[m->inputs[j]];
        if (nn_tfl_is_const(t) || !(t->type == NN_TFL_FLOAT32 || (nn_tfl_is_quantized(t) && t->num_scales == 1)) || t->ndim < 1)
            s = pg_fail(PG_ERR_FORMAT, "%s: graph input '%s' must be a float32, int8 or uint8 (one scale) tensor with a shape", c->name,
                        t->name);
        else written[m->inputs[j]] = 1;
    }
    for (uint32_t k = 0; !s && k < nops; k++) {
        fb_table ot;
        if (fb_vector_table(f, sops, k, &ot)) s = bad(c, "operator table outside the file");
        else s = parse_operator(c, &ot, (int)k, codes, ncodes, written);
    }
    for (int j = 0; !s && j < m->num_outputs; j++)
        if (!written[m->outputs[j]] && !nn_tfl_is_const(&m->tensors[m->outputs[j]]))
            s = pg_fail(PG_ERR_FORMAT, "%s: graph output '%s' is never computed", c->name, m->tensors[m->outputs[j]].name);
    free(codes);
    free(written);
    return s;
}

pg_status nn_tfl_parse(const uint8_t *data, size_t size, const char *name, nn_tfl_model *m)
{
    memset(m, 0, sizeof *m);
    parse_ctx c = { { data, size }, name ? name : "model", m, 0, 0 };
    pg_status s = parse_model(&c);
    if (s) nn_tfl_destroy(m);
    return s;
}
