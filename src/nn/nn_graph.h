/* nn_graph.h - the graph IR of the inference runtime, shared by the ONNX and TFLite front ends.
 *
 * A graph is a list of tensors and a list of nodes. A tensor is either a constant (weights,
 * folded shape values: `data` set at import) or an activation computed by one node (`producer`)
 * and placed in the arena by the planner. A node is one op (nn_op) reading input tensor ids and
 * writing output tensor ids, with its parameters in one nn_attrs struct.
 *
 * Conventions every front end follows, so one kernel family serves both:
 *   - compute is float32; int8 / fp16 weights are dequantised to float32 at import; int64
 *     tensors exist only as constants (Gather indices, shape values folded at import, REQUANTIZE's
 *     fixed-point multipliers). Integer TFLite models keep integer values in float tensors
 *     (q - zero_point, exact) and round with REQUANTIZE (tflite_import.c).
 *   - shapes are static: every dim is known after import (front ends fold Shape/Gather/Concat
 *     chains and turn constant "shape-like" inputs into attributes: Reshape's target shape,
 *     Slice's starts/ends/axes/steps, Resize's output size, Pad's pads, Expand's shape, the axes
 *     of Unsqueeze/Squeeze/ReduceMean). After import a node's inputs are only its data inputs.
 *   - conv weights are OIHW (O = output channels, I = input channels / group); ConvTranspose
 *     weights are IOHW (I = input channels, O = output channels / group) as in ONNX. The TFLite
 *     importer converts OHWI / 1HWO(depthwise) / OHWI(transpose) at load. `layout` says whether
 *     the activations of conv-like ops (CONV, CONV_TRANSPOSE, RESIZE, PAD's spatial meaning) are
 *     NCHW or NHWC; weights are OIHW either way.
 *   - tensor names are owned copies; an omitted optional input is -1.
 *
 * Building a graph by hand (tests do this; the front ends do the same):
 *
 *   nn_graph g;  nn_graph_init(&g);
 *   int x, w, y;
 *   nn_graph_add_tensor(&g, "x", NN_F32, 4, (int64_t[]){1, 3, 8, 8}, &x);
 *   nn_graph_add_const_f32(&g, "w", 4, (int64_t[]){4, 3, 3, 3}, weights, &w);
 *   nn_graph_add_tensor(&g, "y", NN_F32, 0, NULL, &y);           (shape inferred later)
 *   nn_attrs a;  nn_attrs_default(&a);  a.kernel[0] = a.kernel[1] = 3;
 *   nn_graph_add_node(&g, NN_OP_CONV, "conv0", (int[]){x, w, -1}, 3, &y, 1, &a);
 *   nn_graph_set_io(&g, &x, 1, &y, 1);
 *   nn_graph_prepare(&g);     validates, sorts, infers shapes, plans memory (nn_exec.c)
 *   ...copy the input into nn_graph_data(&g, x); nn_graph_run(&g, threads); read nn_graph_data(&g, y)
 *   nn_graph_destroy(&g);
 */
#ifndef PG_NN_GRAPH_H
#define PG_NN_GRAPH_H

#include <stddef.h>
#include <stdint.h>

#include "core/status.h"

#define NN_MAX_DIMS 6
#define NN_MAX_OUTPUTS 4
#define NN_MAX_IO 8                         /* graph inputs / outputs */
#define NN_MAX_DIM ((int64_t)1 << 24)        /* largest single dim a model may declare */
#define NN_MAX_ELEMENTS ((int64_t)1 << 28)   /* largest tensor (elements, 1 GiB of float) */
#define NN_MAX_WORK_BYTES ((size_t)2 << 30)  /* activations + scratch of one graph */
#define NN_MAX_FOLD_BYTES ((size_t)512 << 20) /* constants computed at load (a tiny file can ask for big ones) */
#define NN_MAX_TENSORS (1 << 20)
#define NN_MAX_NODES (1 << 20)

typedef enum { NN_F32, NN_I64 } nn_dtype;

typedef enum { NN_LAYOUT_NCHW, NN_LAYOUT_NHWC } nn_layout;

/* Activation fused into the output of CONV / CONV_TRANSPOSE / GEMM / MATMUL / ADD ... */
typedef enum { NN_ACT_NONE, NN_ACT_RELU, NN_ACT_LEAKY_RELU, NN_ACT_RELU6 } nn_activation;

typedef enum { NN_RESIZE_NEAREST, NN_RESIZE_LINEAR, NN_RESIZE_CUBIC } nn_resize_mode;

/* ONNX coordinate_transformation_mode (TFLite's align_corners / half_pixel_centers map onto these). */
typedef enum {
    NN_COORD_HALF_PIXEL,          /* x_in = (x_out + 0.5) / scale - 0.5 */
    NN_COORD_PYTORCH_HALF_PIXEL,  /* same, but 0 when the output length is 1 */
    NN_COORD_ALIGN_CORNERS,       /* x_in = x_out * (in - 1) / (out - 1) */
    NN_COORD_ASYMMETRIC,          /* x_in = x_out / scale */
    NN_COORD_TF_HALF_PIXEL_FOR_NN /* x_in = (x_out + 0.5) / scale */
} nn_coord_mode;

/* Nearest rounding for NN_RESIZE_NEAREST (ONNX nearest_mode). */
typedef enum { NN_NEAREST_ROUND_PREFER_FLOOR, NN_NEAREST_ROUND_PREFER_CEIL, NN_NEAREST_FLOOR, NN_NEAREST_CEIL } nn_nearest_mode;

typedef enum { NN_PAD_CONSTANT, NN_PAD_REFLECT, NN_PAD_EDGE } nn_pad_mode;

/* The ops. Inputs listed as (data inputs) after import; "attr" names the nn_attrs fields used.
 * Keep nn_ops[] in nn_exec.c in the same order (a static_assert checks the count). */
typedef enum {
    NN_OP_CONV,           /* (x, w[OIHW], bias|-1) attr: layout kernel stride dilation pads group act */
    NN_OP_CONV_TRANSPOSE, /* (x, w[IOHW], bias|-1) attr: layout kernel stride dilation pads group output_padding act */
    NN_OP_MATMUL,         /* (a, b, bias|-1) numpy matmul with batch broadcast, + bias[N]; attr: trans_b act */
    NN_OP_GEMM,           /* (a, b, c|-1) alpha*op(a)*op(b) + beta*c; attr: alpha beta trans_a trans_b act */
    NN_OP_ADD,            /* (a, b) numpy broadcast; attr: act */
    NN_OP_SUB,
    NN_OP_MUL,
    NN_OP_DIV,
    NN_OP_POW,
    NN_OP_MAXIMUM,
    NN_OP_MINIMUM,
    NN_OP_SQRT,           /* (x) unary */
    NN_OP_ERF,
    NN_OP_EXP,
    NN_OP_TANH,
    NN_OP_NEG,
    NN_OP_RELU,
    NN_OP_LEAKY_RELU,     /* attr: alpha */
    NN_OP_SIGMOID,
    NN_OP_GELU,           /* attr: gelu_tanh (0: erf form) */
    NN_OP_LAYER_NORM,     /* (x, scale|-1, bias|-1) over axes [axis, ndim); attr: axis epsilon */
    NN_OP_SOFTMAX,        /* (x) attr: axis */
    NN_OP_REDUCE_MEAN,    /* (x) attr: axes num_axes keepdims */
    NN_OP_RESHAPE,        /* (x) attr: shape num_shape (already resolved: no 0 / -1 left after prepare) */
    NN_OP_TRANSPOSE,      /* (x) attr: perm */
    NN_OP_SLICE,          /* (x) attr: axes num_axes starts ends steps (ONNX clamping rules) */
    NN_OP_CONCAT,         /* (x0, x1, ...) attr: axis */
    NN_OP_GATHER,         /* (x, indices[i64 const]) attr: axis */
    NN_OP_EXPAND,         /* (x) attr: shape num_shape (numpy broadcast to it) */
    NN_OP_PAD,            /* (x) attr: pad_amounts[2*ndim] (begins then ends, as ONNX) pad_mode pad_value */
    NN_OP_RESIZE,         /* (x) attr: layout out_h out_w scale_h scale_w resize_mode coord_mode nearest_mode
                           * cubic_a exclude_outside */
    NN_OP_IDENTITY,       /* (x) copy */
    NN_OP_ABS,            /* (x) unary */
    NN_OP_ATTENTION,      /* (q[..., M, D], k[..., N, D], v[..., N, E]) softmax(q k^T) v per batch, in row blocks
                           * (made by the fusion pass from MatMul(q, k^T) -> Softmax -> MatMul(., v)) */
    NN_OP_REQUANTIZE,     /* (x, fixed[C,2] i64|-1) attr: q_multiplier q_zero_point q_min q_max:
                           * y = clamp(r + zp, q_min, q_max) - zp where r = x * m rounded: with
                           * `fixed` (per channel of the last axis: Q31 mantissa, power-of-two shift) x is an
                           * int32 value and r is TFLite's fixed-point product with its two roundings; without
                           * it r = round(x * q_multiplier) half away from zero (see tflite_import.c) */
    NN_OP_COUNT
} nn_op;

typedef struct {
    nn_layout layout;         /* activations of conv-like ops and RESIZE */
    int kernel[2];            /* kH, kW (0: take from the weight) */
    int stride[2];            /* sH, sW (default 1) */
    int dilation[2];          /* default 1 */
    int pads[4];              /* top, left, bottom, right (conv-like) */
    int output_padding[2];    /* CONV_TRANSPOSE */
    int group;                /* default 1; group == C_in == C_out is depthwise */
    nn_activation act;        /* fused activation on the output */
    float act_alpha;          /* leaky relu slope of the fused activation */

    int axis;                 /* SOFTMAX, CONCAT, GATHER, LAYER_NORM (may be negative until prepare) */
    int num_axes;             /* REDUCE_MEAN, SLICE */
    int64_t axes[NN_MAX_DIMS];
    int keepdims;             /* REDUCE_MEAN (default 1) */
    int perm[NN_MAX_DIMS];    /* TRANSPOSE (num_perm == 0: reverse) */
    int num_perm;
    int64_t starts[NN_MAX_DIMS], ends[NN_MAX_DIMS], steps[NN_MAX_DIMS]; /* SLICE, per axes[i] */
    int64_t shape[NN_MAX_DIMS]; /* RESHAPE / EXPAND target */
    int num_shape;
    int64_t pad_amounts[2 * NN_MAX_DIMS]; /* PAD: begins of every axis, then ends */
    nn_pad_mode pad_mode;
    float pad_value;

    float alpha, beta;        /* GEMM (1, 1); LEAKY_RELU alpha (0.01) */
    float epsilon;            /* LAYER_NORM (1e-5) */
    int trans_a, trans_b;     /* GEMM; MATMUL trans_b */
    int gelu_tanh;            /* GELU approximation */

    nn_resize_mode resize_mode;
    nn_coord_mode coord_mode;
    nn_nearest_mode nearest_mode;
    int out_h, out_w;         /* RESIZE output spatial size */
    float scale_h, scale_w;   /* RESIZE scales used by the coordinate transform (0: out / in) */
    float cubic_a;            /* RESIZE cubic coefficient (-0.75, as ONNX and torch) */
    int exclude_outside;      /* RESIZE cubic: taps outside the input get weight 0, the rest renormalised */

    float q_multiplier;       /* REQUANTIZE: float multiplier, zero point and integer range of the result */
    int q_zero_point, q_min, q_max;
} nn_attrs;

typedef struct {
    char *name;
    nn_dtype dtype;
    int ndim;                 /* -1: unknown until shape inference */
    int64_t dims[NN_MAX_DIMS];
    void *data;               /* constants: owned float / int64_t array; NULL for activations */
    int producer;             /* node id, -1 for constants and graph inputs */
    /* filled by nn_graph_prepare */
    int last_use;             /* last node (in run order) reading it; -1 if none */
    size_t offset;            /* arena offset in floats, for activations */
} nn_tensor;

typedef struct {
    nn_op op;
    char *name;
    int num_inputs;
    int *inputs;              /* tensor ids (owned); -1 for an omitted optional input */
    int num_outputs;
    int outputs[NN_MAX_OUTPUTS];
    nn_attrs attr;
} nn_node;

typedef struct nn_graph {
    nn_tensor *tensors;
    int num_tensors, cap_tensors;
    nn_node *nodes;           /* in run order after nn_graph_prepare */
    int num_nodes, cap_nodes;
    int inputs[NN_MAX_IO], num_inputs;
    int outputs[NN_MAX_IO], num_outputs;
    /* filled by nn_graph_prepare */
    float *arena;             /* 64-byte aligned inside arena_block */
    void *arena_block;        /* calloc'd: a large arena costs no page until a run touches it */
    size_t arena_floats;      /* planned size */
    size_t const_bytes;       /* bytes of constant data */
    float *scratch;           /* per-run temporaries (im2col etc.), scratch_floats per thread */
    size_t scratch_floats;
    int scratch_threads;      /* threads the scratch is allocated for */
    double *profile_ms;       /* if set (NN_OP_COUNT entries, caller-owned), nn_graph_run adds each op's wall time */
    /* set before import: the shape of the first graph input, binding the dims a model declares
     * symbolic (exported with dynamic axes); its fixed dims must agree. bind_ndim 0: none. */
    int bind_ndim;
    int64_t bind_dims[NN_MAX_DIMS];
    int prepared;
} nn_graph;

/* Number of elements of a shape (1 for a scalar). */
int64_t nn_shape_count(int ndim, const int64_t *dims);

void nn_graph_init(nn_graph *g);
/* Frees everything the graph owns; accepts a zeroed or already destroyed graph. */
void nn_graph_destroy(nn_graph *g);
void nn_attrs_default(nn_attrs *a);

/* Adds an activation tensor (ndim -1 / dims NULL: inferred by prepare). Checks dims against
 * NN_MAX_DIM / NN_MAX_ELEMENTS. */
pg_status nn_graph_add_tensor(nn_graph *g, const char *name, nn_dtype dtype, int ndim, const int64_t *dims, int *id);
/* Adds a constant, taking ownership of data (malloc'ed; freed by the graph even on failure). */
pg_status nn_graph_add_const(nn_graph *g, const char *name, nn_dtype dtype, int ndim, const int64_t *dims, void *data, int *id);
/* Adds a float constant, copying data. */
pg_status nn_graph_add_const_f32(nn_graph *g, const char *name, int ndim, const int64_t *dims, const float *data, int *id);
/* Adds a node; inputs/outputs must be valid tensor ids (or -1 for an omitted input). */
pg_status nn_graph_add_node(nn_graph *g, nn_op op, const char *name, const int *inputs, int num_inputs,
                            const int *outputs, int num_outputs, const nn_attrs *attr, int *id);
/* Declares graph inputs (activations with a static shape) and outputs. */
pg_status nn_graph_set_io(nn_graph *g, const int *inputs, int num_inputs, const int *outputs, int num_outputs);
/* Tensor id by name, -1 if none. Linear search (importers keep their own map). */
int nn_graph_find_tensor(const nn_graph *g, const char *name);

/* nn_exec.c: validates (ids, cycles, shapes against limits), puts nodes in topological order,
 * infers every shape, drops nodes no output depends on, evaluates once the nodes whose inputs are
 * all constants (their outputs become constants), and plans the arena (tensors share memory once
 * their last reader ran). Fails with one line naming the node at fault. */
pg_status nn_graph_prepare(nn_graph *g);
/* Checks node id's inputs (count, presence, known shapes, float32) and infers its outputs' shapes;
 * importers call it as they add nodes so later shape-dependent ops (Shape, Flatten) see shapes. */
pg_status nn_node_infer(nn_graph *g, int id);
/* Runs all nodes with the given number of threads (<= 0: all cores). Inputs must be written first. */
pg_status nn_graph_run(nn_graph *g, int threads);
/* Float data of a tensor (constant or arena) after prepare; NULL for int64 tensors. */
float *nn_graph_data(const nn_graph *g, int id);
/* Bytes the prepared graph holds: constants + arena + scratch. */
size_t nn_graph_memory_bytes(const nn_graph *g);

/* Name of an op ("Conv", "MatMul", ...). */
const char *nn_op_name(nn_op op);

/* Front ends: append the model in data[0..size) to an empty graph (not yet prepared). `name` is
 * the path used in messages. */
pg_status nn_onnx_import(const uint8_t *data, size_t size, const char *name, nn_graph *g);
/* The TFLite front end (src/nn/tflite_import.c; a stub returning "not supported yet" until the
 * nn-tflite branch lands). */
pg_status nn_tflite_import(const uint8_t *data, size_t size, const char *name, nn_graph *g);

#endif
