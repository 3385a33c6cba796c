/* onnx_wire.h - a bounds-checked reader of the protobuf wire format (what ONNX files are).
 *
 * A message is a sequence of (field number, wire type, value). pb_next() steps over one field,
 * never reading past `end`: varints longer than 10 bytes, lengths past the buffer, groups
 * (wire types 3, 4) and unknown wire types are errors.
 *
 *   pb_reader r = { data, data + size };
 *   pb_field f;
 *   int rc;
 *   while ((rc = pb_next(&r, &f)) > 0)
 *       if (f.number == 7 && f.wire == PB_LEN) ...f.data, f.len...
 *   if (rc < 0) ...corrupt...
 */
#ifndef PG_ONNX_WIRE_H
#define PG_ONNX_WIRE_H

#include <stddef.h>
#include <stdint.h>

enum { PB_VARINT = 0, PB_I64 = 1, PB_LEN = 2, PB_I32 = 5 };

typedef struct {
    const uint8_t *p, *end;
} pb_reader;

typedef struct {
    uint32_t number;
    int wire;
    uint64_t v;          /* PB_VARINT value, or the raw bits of PB_I64 / PB_I32 */
    const uint8_t *data; /* PB_LEN payload */
    size_t len;
} pb_field;

/* Reads the next field: 1 read, 0 at the end, -1 corrupt. */
int pb_next(pb_reader *r, pb_field *f);
/* Reads one varint from [*p, end): 0 ok (advances *p), -1 truncated or over 10 bytes. */
int pb_varint(const uint8_t **p, const uint8_t *end, uint64_t *v);
/* Number of varints in a packed payload; -1 if it does not end on a varint boundary. */
int64_t pb_count_varints(const uint8_t *data, size_t len);
/* A PB_I32 field's bits as float. */
float pb_float(const pb_field *f);

#endif
