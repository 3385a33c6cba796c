/* tflite.h - the TFLite flatbuffer front end: a bounds-checked parser into a plain description
 * (tensors, constants dequantised to float, operators with their options), shape-checked op by
 * op, and a naive NHWC reference interpreter of that description (the test oracle of the
 * runtime, nn_graph.h).
 *
 *   nn_tfl_model m;
 *   PG_TRY(nn_tfl_parse(data, size, "model.tflite", &m));   (data is not kept)
 *   float *out[NN_TFL_MAX_IO];                               (sized by m.tensors[m.outputs[k]].count)
 *   PG_TRY(nn_tfl_ref_run(&m, input, out, m.num_outputs));
 *   nn_tfl_destroy(&m);
 *
 * What is checked before anything is allocated from the file's numbers: every offset, vector
 * and string lies inside the file; tensor indices are in range; dims are positive and under
 * NN_TFL_MAX_DIM with at most NN_TFL_MAX_ELEMENTS elements; a constant's buffer holds exactly its
 * bytes; an operator only reads graph inputs, constants or tensors written by an earlier
 * operator (so a cyclic or out-of-order graph is refused), and each tensor is written once;
 * every op is one of the supported ones (else one line names the first unsupported op and its
 * operator index and output tensor) and the output shape it declares is the one its inputs give.
 *
 * Supported ops (float activations; int8 / uint8 / float16 constant weights are dequantised):
 * CONV_2D, DEPTHWISE_CONV_2D, TRANSPOSE_CONV, ADD, SUB, MUL, MAXIMUM, MINIMUM, CONCATENATION,
 * STRIDED_SLICE, RESIZE_BILINEAR, RESIZE_NEAREST_NEIGHBOR, PAD, LEAKY_RELU, RELU, RELU6,
 * LOGISTIC, TANH, RESHAPE, DEQUANTIZE; fused activations NONE, RELU, RELU_N1_TO_1, RELU6, TANH.
 *
 * Integer models (int8 / uint8 activations, "full integer" quantisation): QUANTIZE (float ->
 * int, int -> int), DEQUANTIZE, CONV_2D and DEPTHWISE_CONV_2D (int8 / uint8 weights, per-tensor
 * or per-channel scales, int32 biases), ADD, PAD, RESIZE_NEAREST_NEIGHBOR and RESHAPE. Every
 * quantisation parameter is checked at parse: scales positive and finite, zero points inside the
 * type's range (0 for int32 biases), one scale per channel of the quantized dimension, a bias
 * scale equal to input scale x weight scale, the same parameters on both sides of the ops that
 * only move values (PAD, RESIZE_NEAREST_NEIGHBOR, RESHAPE).
 *
 * Value convention of the whole front end: a graph input or output tensor that the file stores
 * as integers is exchanged as its REAL value, scale * (q - zero_point) (the reference and the
 * runtime quantise the input themselves), so a caller feeds and reads floats either way.
 */
#ifndef PG_NN_TFLITE_H
#define PG_NN_TFLITE_H

#include <stddef.h>
#include <stdint.h>

#include "core/status.h"

#define NN_TFL_MAX_DIMS 4                  /* the supported ops are at most 4-D (NHWC) */
#define NN_TFL_MAX_DIM (1 << 24)
#define NN_TFL_MAX_ELEMENTS ((int64_t)1 << 30)
#define NN_TFL_MAX_TENSORS (1 << 20)
#define NN_TFL_MAX_OPS (1 << 20)
#define NN_TFL_MAX_IO 8
#define NN_TFL_MAX_OP_INPUTS 64            /* CONCATENATION's inputs */

/* TFLite BuiltinOperator codes of the supported ops (the schema's numbers). */
enum {
    NN_TFL_ADD = 0,
    NN_TFL_CONCATENATION = 2,
    NN_TFL_CONV_2D = 3,
    NN_TFL_DEPTHWISE_CONV_2D = 4,
    NN_TFL_DEQUANTIZE = 6,
    NN_TFL_LOGISTIC = 14,
    NN_TFL_MUL = 18,
    NN_TFL_RELU = 19,
    NN_TFL_RELU6 = 21,
    NN_TFL_RESHAPE = 22,
    NN_TFL_RESIZE_BILINEAR = 23,
    NN_TFL_TANH = 28,
    NN_TFL_PAD = 34,
    NN_TFL_SUB = 41,
    NN_TFL_STRIDED_SLICE = 45,
    NN_TFL_MAXIMUM = 55,
    NN_TFL_MINIMUM = 57,
    NN_TFL_TRANSPOSE_CONV = 67,
    NN_TFL_RESIZE_NEAREST_NEIGHBOR = 97,
    NN_TFL_LEAKY_RELU = 98,
    NN_TFL_QUANTIZE = 114,
};

/* TensorType codes the front end reads. */
enum { NN_TFL_FLOAT32 = 0, NN_TFL_FLOAT16 = 1, NN_TFL_INT32 = 2, NN_TFL_UINT8 = 3, NN_TFL_INT64 = 4, NN_TFL_INT8 = 9 };

/* Fused activations (ActivationFunctionType). */
enum { NN_TFL_ACT_NONE = 0, NN_TFL_ACT_RELU = 1, NN_TFL_ACT_RELU_N1_TO_1 = 2, NN_TFL_ACT_RELU6 = 3, NN_TFL_ACT_TANH = 4 };

typedef struct {
    char *name;              /* owned copy ("" when the file has none) */
    int ndim;
    int dims[NN_TFL_MAX_DIMS];
    int64_t count;           /* elements */
    int type;                /* TFLite TensorType of the file (0 FLOAT32, 2 INT32, 9 INT8 ...) */
    float *values;           /* constants: (dims) as float, dequantised (owned); NULL for activations */
    int32_t *ints;           /* INT32 / INT64 constants (shape-like inputs) as int32 (owned), else NULL */
    int producer;            /* operator index writing it, -1 for inputs and constants */
    /* quantisation (checked at parse); num_scales 0: none */
    int num_scales;          /* 1 (per tensor) or dims[quant_dim] (per channel) */
    int quant_dim;
    float *scales;           /* (num_scales) owned */
    int zero_point;          /* the same for every channel */
    int32_t *qvalues;        /* quantised constants (int8 / uint8 / int32 with scales): the stored integers (owned) */
} nn_tfl_tensor;

typedef struct {
    int code;                /* builtin operator (NN_TFL_*) */
    int num_inputs, num_outputs;
    int inputs[NN_TFL_MAX_OP_INPUTS]; /* tensor indices; -1 for an omitted optional input */
    int output;              /* the supported ops have one output */
    /* options (the fields the op's table has; defaults as the schema's) */
    int padding_valid;       /* Padding: 0 SAME, 1 VALID */
    int stride_w, stride_h, dilation_w, dilation_h, depth_multiplier;
    int act;                 /* NN_TFL_ACT_* */
    int axis;                /* CONCATENATION, resolved to 0..ndim-1 */
    int begin_mask, end_mask, shrink_axis_mask;
    int align_corners, half_pixel_centers; /* RESIZE_* */
    float alpha;             /* LEAKY_RELU */
    /* resolved by the shape check */
    int pad[4];              /* conv-like: top, left, bottom, right */
    int slice_begin[NN_TFL_MAX_DIMS], slice_stride[NN_TFL_MAX_DIMS]; /* STRIDED_SLICE per input axis */
    int slice_len[NN_TFL_MAX_DIMS];
    int pads[2 * NN_TFL_MAX_DIMS]; /* PAD: before/after per axis */
} nn_tfl_op;

typedef struct {
    nn_tfl_tensor *tensors;
    int num_tensors;
    nn_tfl_op *ops;
    int num_ops;
    int inputs[NN_TFL_MAX_IO], num_inputs;
    int outputs[NN_TFL_MAX_IO], num_outputs;
} nn_tfl_model;

/* Parses and checks a TFLite file held in data[0..size) (first subgraph only); name is used in
 * messages ("name: operator 12 (SOFTMAX, output 'probs'): unsupported op"). Fails with
 * PG_ERR_FORMAT (corrupt, truncated, unsupported) or PG_ERR_SIZE (dims over the limits); m is
 * empty on failure. */
pg_status nn_tfl_parse(const uint8_t *data, size_t size, const char *name, nn_tfl_model *m);
void nn_tfl_destroy(nn_tfl_model *m); /* accepts a zeroed or destroyed model */

/* TFLite's name of a builtin op ("CONV_2D"), or NULL when this table has none. */
const char *nn_tfl_op_name(int code);
/* 1 if t holds constant data (weights, shape-like inputs). */
static inline int nn_tfl_is_const(const nn_tfl_tensor *t) { return t->values != NULL || t->ints != NULL; }
/* 1 if t is an activation stored as int8 / uint8 (its values are scale * (q - zero_point)). */
static inline int nn_tfl_is_quantized(const nn_tfl_tensor *t)
{
    return !nn_tfl_is_const(t) && (t->type == NN_TFL_INT8 || t->type == NN_TFL_UINT8);
}
/* The integer range of an int8 / uint8 tensor. */
static inline int nn_tfl_qmin(const nn_tfl_tensor *t) { return t->type == NN_TFL_UINT8 ? 0 : -128; }
static inline int nn_tfl_qmax(const nn_tfl_tensor *t) { return t->type == NN_TFL_UINT8 ? 255 : 127; }

/* The naive reference: runs every op with straightforward scalar loops (double accumulators)
 * on the first graph input (float, dims of m->inputs[0]) and writes the first num_outputs graph
 * outputs into out[k] (m->tensors[m->outputs[k]].count floats each, caller-allocated). Slow, and
 * meant to be: it is the oracle the runtime is tested against. Ops on int8 / uint8 activations
 * run in integer arithmetic as TFLite's reference kernels define it (tflite_ref_int.c). */
pg_status nn_tfl_ref_run(const nn_tfl_model *m, const float *input, float **out, int num_outputs);

/* tflite_ref_int.c: one op on integer activations. buf[t] holds tensor t's STORED integers as
 * floats (exact for 8-bit values) for quantised activations, real values for float ones;
 * constants are read from the tensors. Writes op's output into y. */
pg_status nn_tfl_ref_int_op(const nn_tfl_model *m, const nn_tfl_op *op, float *const *buf, float *y);
/* Whether the reference runs op with nn_tfl_ref_int_op (it reads or writes integer activations). */
int nn_tfl_op_is_integer(const nn_tfl_model *m, const nn_tfl_op *op);

#endif
