/* nn.h - a small neural-network inference runtime: load an ONNX (or, later, TFLite) model, run it
 * on float32 input, get float32 output.
 *
 * The model file is read whole, parsed by a bounds-checked front end into the graph IR
 * (nn_graph.h), validated (ops supported, no cycles, every shape static and under the limits)
 * and planned (one arena, tensors share memory after their last use) before any compute memory
 * is allocated. A model the runtime cannot run is refused at load with one line naming the first
 * unsupported op and its node. Compute is float32 on OpenMP threads + single-threaded OpenBLAS
 * calls per thread.
 *
 *   nn_model *m;
 *   if (nn_model_load("depth_anything_v2_vits.onnx", &m)) { fprintf(stderr, "%s\n", pg_last_error()); ... }
 *   int64_t in[NN_MAX_DIMS], out[NN_MAX_DIMS];
 *   int in_ndim = nn_model_input_shape(m, in);    e.g. 4: (1, 3, 392, 518)
 *   int out_ndim = nn_model_output_shape(m, out); e.g. 3: (1, 392, 518)
 *   float *x = ..., *y = ...;                     sized by nn_shape_count(in_ndim, in) ...
 *   pg_status st = nn_model_run(m, x, y, 2);
 *   nn_model_destroy(m);
 */
#ifndef PG_NN_H
#define PG_NN_H

#include <stddef.h>
#include <stdint.h>

#include "core/status.h"
#include "nn/nn_graph.h"

typedef struct nn_model nn_model;

/* Loads an ONNX or TFLite file (told apart by content: a TFLite flatbuffer carries "TFL3" at
 * byte 4). Fails with PG_ERR_IO (unreadable), PG_ERR_FORMAT (corrupt, unsupported op, external
 * data) or PG_ERR_SIZE (dims over the limits), one line naming the file. */
pg_status nn_model_load(const char *path, nn_model **model);
/* The same from memory (data is not kept); name is used in messages. */
pg_status nn_model_load_memory(const void *data, size_t size, const char *name, nn_model **model);
/* The same for a model whose input has symbolic dims (exported with dynamic axes): dims (ndim
 * values) is the input shape to use; dims the file fixes must agree with it. */
pg_status nn_model_load_shaped(const char *path, int ndim, const int64_t *dims, nn_model **model);
pg_status nn_model_load_memory_shaped(const void *data, size_t size, const char *name, int ndim, const int64_t *dims,
                                      nn_model **model);
void nn_model_destroy(nn_model *model); /* accepts NULL */

/* Shape of the first graph input / output; returns ndim. */
int nn_model_input_shape(const nn_model *model, int64_t dims[NN_MAX_DIMS]);
int nn_model_output_shape(const nn_model *model, int64_t dims[NN_MAX_DIMS]);

/* Runs the model on input (the first graph input, its shape's element count) into output (the
 * first graph output; an integer TFLite model's input and output are their real values, see
 * tflite.h) with threads threads (<= 0: all cores). One run at a time per model (the
 * activations live in the model); load the model once per concurrent user. */
pg_status nn_model_run(nn_model *model, const float *input, float *output, int threads);

/* Bytes the loaded model holds: weights + activation arena + scratch. */
size_t nn_model_memory_bytes(const nn_model *model);
/* The graph, for tests and tools that need more than one input / output. */
nn_graph *nn_model_graph(nn_model *model);

#endif
