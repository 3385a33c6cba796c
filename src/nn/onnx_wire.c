/* onnx_wire.c - the protobuf wire format reader (see onnx_wire.h). */
#include "nn/onnx_wire.h"

#include <string.h>

int pb_varint(const uint8_t **p, const uint8_t *end, uint64_t *v)
{
    uint64_t x = 0;
    const uint8_t *q = *p;
    for (int shift = 0; shift < 70; shift += 7) {
        if (q >= end) return -1;
        uint8_t b = *q++;
        x |= (uint64_t)(b & 0x7f) << (shift < 64 ? shift : 63);
        if (!(b & 0x80)) { *v = x; *p = q; return 0; }
        if (shift == 63) return -1;
    }
    return -1;
}

int pb_next(pb_reader *r, pb_field *f)
{
    if (r->p >= r->end) return 0;
    uint64_t key;
    if (pb_varint(&r->p, r->end, &key)) return -1;
    if ((key >> 3) == 0 || (key >> 3) > 0x1fffffff) return -1;
    memset(f, 0, sizeof *f);
    f->number = (uint32_t)(key >> 3);
    f->wire = (int)(key & 7);
    switch (f->wire) {
    case PB_VARINT:
        return pb_varint(&r->p, r->end, &f->v) ? -1 : 1;
    case PB_I64:
        if (r->end - r->p < 8) return -1;
        for (int i = 7; i >= 0; i--) f->v = (f->v << 8) | r->p[i];
        r->p += 8;
        return 1;
    case PB_I32:
        if (r->end - r->p < 4) return -1;
        for (int i = 3; i >= 0; i--) f->v = (f->v << 8) | r->p[i];
        r->p += 4;
        return 1;
    case PB_LEN: {
        uint64_t len;
        if (pb_varint(&r->p, r->end, &len)) return -1;
        if (len > (uint64_t)(r->end - r->p)) return -1;
        f->data = r->p;
        f->len = (size_t)len;
        r->p += len;
        return 1;
    }
    default:
        return -1;
    }
}

int64_t pb_count_varints(const uint8_t *data, size_t len)
{
    int64_t n = 0;
    for (size_t i = 0; i < len; i++) n += !(data[i] & 0x80);
    if (len && (data[len - 1] & 0x80)) return -1;
    return n;
}

float pb_float(const pb_field *f)
{
    uint32_t bits = (uint32_t)f->v;
    float x;
    memcpy(&x, &bits, 4);
    return x;
}
