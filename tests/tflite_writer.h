/* tflite_writer.h - a tiny TFLite flatbuffer writer for tests: builds small models from a plain
 * description so the front end can be tested without the real model or TensorFlow.
 *
 *   tw_model d = { 0 };
 *   int x = tw_tensor(&d, "x", 4, (int[]){1, 8, 8, 3}, TW_F32, NULL, 0);
 *   int w = tw_tensor(&d, "w", 4, (int[]){4, 3, 3, 3}, TW_F32, weights, 0);
 *   int y = tw_tensor(&d, "y", 4, (int[]){1, 8, 8, 4}, TW_F32, NULL, 0);
 *   tw_op(&d, 3, (int[]){x, w, -1}, 3, y, 1, 4, (int[]){0, 1, 1, 0}, (int[]){'b', 'i', 'i', 'b'});
 *   d.inputs[d.num_inputs++] = x;  d.outputs[d.num_outputs++] = y;
 *   size_t n;  uint8_t *bytes = tw_build(&d, &n);   (malloc'd)
 *
 * Layout written: the root offset and "TFL3", then every table's vtable just before the table,
 * children after their parents (uoffsets point forward, as flatbuffers require). Every scalar
 * field takes 4 bytes (bytes are stored in the first); quantised tensors get a per-tensor or
 * per-channel scale and one zero point. */
#ifndef PG_TFLITE_WRITER_H
#define PG_TFLITE_WRITER_H

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

enum { TW_F32 = 0, TW_F16 = 1, TW_I32 = 2, TW_U8 = 3, TW_I8 = 9 };

#define TW_MAX 256

typedef struct {
    const char *name;
    int ndim, dims[6];
    int type;
    const void *data;   /* constant bytes (count * element size) or NULL */
    size_t bytes;
    int num_scales;     /* quantised tensors: 1 (per tensor) or dims[quant_dim] scales */
    float scales[512];
    int64_t zero_point; /* written for every channel */
    int quant_dim;
    int shape_absent;   /* leave the shape vector out */
    int buffer_override; /* >= 0: write this buffer index instead (for lying files) */
} tw_tensor_desc;

typedef struct {
    int code;
    int inputs[16], num_inputs;
    int output;
    int options_type;            /* BuiltinOptions union index, 0 none */
    int num_fields;
    int32_t field_value[8];
    char field_kind[8];          /* 'i' int32, 'b' byte, 'f' float (value holds the bits), 0 absent */
} tw_op_desc;

typedef struct {
    tw_tensor_desc tensors[TW_MAX];
    int num_tensors;
    tw_op_desc ops[TW_MAX];
    int num_ops;
    int inputs[8], num_inputs, outputs[8], num_outputs;
    int version;                 /* 0: 3 */
} tw_model;

static inline int tw_tensor(tw_model *m, const char *name, int ndim, const int *dims, int type, const void *data, size_t bytes)
{
    tw_tensor_desc *t = &m->tensors[m->num_tensors];
    memset(t, 0, sizeof *t);
    t->name = name;
    t->ndim = ndim;
    for (int i = 0; i < ndim; i++) t->dims[i] = dims[i];
    t->type = type;
    t->data = data;
    t->bytes = bytes;
    t->buffer_override = -1;
    return m->num_tensors++;
}

static inline int tw_op(tw_model *m, int code, const int *inputs, int num_inputs, int output, int options_type, int num_fields,
                        const int32_t *values, const char *kinds)
{
    tw_op_desc *o = &m->ops[m->num_ops];
    memset(o, 0, sizeof *o);
    o->code = code;
    for (int i = 0; i < num_inputs; i++) o->inputs[i] = inputs[i];
    o->num_inputs = num_inputs;
    o->output = output;
    o->options_type = options_type;
    o->num_fields = num_fields;
    for (int i = 0; i < num_fields; i++) {
        o->field_value[i] = values[i];
        o->field_kind[i] = kinds[i];
    }
    return m->num_ops++;
}

static inline int32_t tw_float_bits(float f)
{
    int32_t v;
    memcpy(&v, &f, 4);
    return v;
}

typedef struct {
    uint8_t *d;
    size_t n, cap;
} tw_buf;

static inline size_t tw_put(tw_buf *b, const void *p, size_t len)
{
    if (b->n + len + 8 > b->cap) {
        size_t cap = (b->n + len + 8) * 2;
        uint8_t *nd = realloc(b->d, cap);
        if (!nd) abort();
        memset(nd + b->cap, 0, cap - b->cap);
        b->d = nd;
        b->cap = cap;
    }
    size_t at = b->n;
    if (p) memcpy(b->d + at, p, len);
    else memset(b->d + at, 0, len);
    b->n += len;
    return at;
}

static inline void tw_align(tw_buf *b, size_t a)
{
    while (b->n % a) tw_put(b, NULL, 1);
}

static inline void tw_u32_at(tw_buf *b, size_t at, uint32_t v) { memcpy(b->d + at, &v, 4); }
static inline void tw_patch(tw_buf *b, size_t field, size_t target) { tw_u32_at(b, field, (uint32_t)(target - field)); }

/* A table of nf fields; kind[i]: 0 absent, 'i'/'b'/'f' scalar (value[i]), 'r' reference (patched
 * later through fpos[i]). Returns the table's position. */
static inline size_t tw_table(tw_buf *b, int nf, const char *kind, const int32_t *value, size_t *fpos)
{
    tw_align(b, 4);
    int present = 0;
    for (int i = 0; i < nf; i++) present += kind[i] != 0;
    uint16_t vt[2 + 16];
    vt[0] = (uint16_t)(4 + 2 * nf);
    vt[1] = (uint16_t)(4 + 4 * present);
    int at = 4;
    for (int i = 0; i < nf; i++) {
        vt[2 + i] = kind[i] ? (uint16_t)at : 0;
        if (kind[i]) at += 4;
    }
    size_t vpos = tw_put(b, vt, (size_t)(4 + 2 * nf));
    tw_align(b, 4);
    size_t t = tw_put(b, NULL, 4);
    int32_t so = (int32_t)(t - vpos);
    memcpy(b->d + t, &so, 4);
    for (int i = 0; i < nf; i++) {
        if (!kind[i]) continue;
        size_t p = tw_put(b, NULL, 4);
        if (kind[i] == 'b') b->d[p] = (uint8_t)value[i];
        else if (kind[i] != 'r') memcpy(b->d + p, &value[i], 4);
        if (fpos) fpos[i] = p;
    }
    return t;
}

static inline size_t tw_vec(tw_buf *b, uint32_t count, const void *items, size_t elem)
{
    tw_align(b, elem > 4 ? 8 : 4);
    if (elem > 4 && (b->n + 4) % 8) tw_put(b, NULL, 4);
    size_t at = tw_put(b, &count, 4);
    tw_put(b, items, (size_t)count * elem);
    return at;
}

static inline size_t tw_string(tw_buf *b, const char *s)
{
    uint32_t n = (uint32_t)strlen(s);
    size_t at = tw_vec(b, n, s, 1);
    tw_put(b, NULL, 1);
    return at;
}

/* A vector of n table references; the references are patched by the caller: slot k at at+4+4k. */
static inline size_t tw_refs(tw_buf *b, uint32_t n)
{
    tw_align(b, 4);
    size_t at = tw_put(b, &n, 4);
    tw_put(b, NULL, 4 * (size_t)n);
    return at;
}

static inline uint8_t *tw_build(const tw_model *m, size_t *size)
{
    tw_buf b = { 0 };
    tw_put(&b, NULL, 4);
    tw_put(&b, "TFL3", 4);
    /* Model: version, operator_codes, subgraphs, description, buffers */
    size_t mf[5];
    int32_t mv[5] = { m->version ? m->version : 3, 0, 0, 0, 0 };
    size_t root = tw_table(&b, 5, "irr\0r", mv, mf);
    tw_u32_at(&b, 0, (uint32_t)root);

    /* operator codes: one per op (simple, duplicates are allowed) */
    size_t codes = tw_refs(&b, (uint32_t)m->num_ops);
    tw_patch(&b, mf[1], codes);
    for (int k = 0; k < m->num_ops; k++) {
        int dep = m->ops[k].code < 127 ? m->ops[k].code : 127;
        int32_t v[4] = { dep, 0, 1, m->ops[k].code };
        size_t t = tw_table(&b, 4, "b\0ii", v, NULL);
        tw_patch(&b, codes + 4 + 4 * (size_t)k, t);
    }
    /* subgraph: tensors, inputs, outputs, operators, name */
    size_t subs = tw_refs(&b, 1);
    tw_patch(&b, mf[2], subs);
    size_t gf[5];
    int32_t gv[5] = { 0 };
    size_t g = tw_table(&b, 5, "rrrr", gv, gf);
    tw_patch(&b, subs + 4, g);
    size_t tens = tw_refs(&b, (uint32_t)m->num_tensors);
    tw_patch(&b, gf[0], tens);
    int next_buffer = 1;
    for (int i = 0; i < m->num_tensors; i++) {
        const tw_tensor_desc *t = &m->tensors[i];
        int buffer = t->data ? next_buffer++ : 0;
        if (t->buffer_override >= 0) buffer = t->buffer_override;
        size_t tf[5];
        int32_t tv[5] = { 0, t->type, buffer, 0, 0 };
        char kind[6] = { t->shape_absent ? 0 : 'r', 'b', 'i', 'r', (char)(t->num_scales ? 'r' : 0), 0 };
        size_t tt = tw_table(&b, 5, kind, tv, tf);
        tw_patch(&b, tens + 4 + 4 * (size_t)i, tt);
        if (!t->shape_absent) tw_patch(&b, tf[0], tw_vec(&b, (uint32_t)t->ndim, t->dims, 4));
        tw_patch(&b, tf[3], tw_string(&b, t->name ? t->name : ""));
        if (t->num_scales) {
            /* QuantizationParameters: min, max, scale, zero_point, details_type, details, quantized_dimension */
            size_t qf[7];
            int32_t qv[7] = { 0, 0, 0, 0, 0, 0, t->quant_dim };
            size_t q = tw_table(&b, 7, "\0\0rr\0\0i", qv, qf);
            tw_patch(&b, tf[4], q);
            tw_patch(&b, qf[2], tw_vec(&b, (uint32_t)t->num_scales, t->scales, 4));
            int64_t zp[512];
            for (int k = 0; k < t->num_scales; k++) zp[k] = t->zero_point;
            tw_patch(&b, qf[3], tw_vec(&b, (uint32_t)t->num_scales, zp, 8));
        }
    }
    int32_t ins[8], outs[8];
    for (int j = 0; j < m->num_inputs; j++) ins[j] = m->inputs[j];
    for (int j = 0; j < m->num_outputs; j++) outs[j] = m->outputs[j];
    tw_patch(&b, gf[1], tw_vec(&b, (uint32_t)m->num_inputs, ins, 4));
    tw_patch(&b, gf[2], tw_vec(&b, (uint32_t)m->num_outputs, outs, 4));
    size_t opv = tw_refs(&b, (uint32_t)m->num_ops);
    tw_patch(&b, gf[3], opv);
    for (int k = 0; k < m->num_ops; k++) {
        const tw_op_desc *o = &m->ops[k];
        size_t of[5];
        int32_t ov[5] = { k, 0, 0, o->options_type, 0 };
        char kind[6] = { 'i', 'r', 'r', 'b', (char)(o->options_type ? 'r' : 0), 0 };
        size_t ot = tw_table(&b, 5, kind, ov, of);
        tw_patch(&b, opv + 4 + 4 * (size_t)k, ot);
        int32_t oi[16];
        for (int j = 0; j < o->num_inputs; j++) oi[j] = o->inputs[j];
        tw_patch(&b, of[1], tw_vec(&b, (uint32_t)o->num_inputs, oi, 4));
        int32_t oo = o->output;
        tw_patch(&b, of[2], tw_vec(&b, 1, &oo, 4));
        if (o->options_type) {
            char fk[9] = { 0 };
            for (int i = 0; i < o->num_fields; i++) fk[i] = o->field_kind[i] == 'f' ? 'i' : o->field_kind[i];
            tw_patch(&b, of[4], tw_table(&b, o->num_fields, fk, o->field_value, NULL));
        }
    }
    /* buffers: 0 is the empty one, then one per constant in tensor order */
    size_t bufs = tw_refs(&b, (uint32_t)next_buffer);
    tw_patch(&b, mf[4], bufs);
    int32_t none[1] = { 0 };
    tw_patch(&b, bufs + 4, tw_table(&b, 1, "\0", none, NULL));
    int k = 1;
    for (int i = 0; i < m->num_tensors; i++) {
        const tw_tensor_desc *t = &m->tensors[i];
        if (!t->data) continue;
        size_t bf[1];
        size_t bt = tw_table(&b, 1, "r", none, bf);
        tw_patch(&b, bufs + 4 + 4 * (size_t)k++, bt);
        tw_patch(&b, bf[0], tw_vec(&b, (uint32_t)t->bytes, t->data, 1));
    }
    *size = b.n;
    return b.d;
}

#endif
