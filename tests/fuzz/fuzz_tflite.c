/* fuzz_tflite.c - libFuzzer harness: the TFLite front end on any bytes - the parser and its
 * reference interpreter, then the importer, the runtime's prepare and (for small graphs) a run.
 * Seeds: tests/fuzz/corpus/tflite (small synthetic models written by tests/test_nn_tflite.c,
 * tests/test_nn_tflite_int.c (int8_ops.tflite: the integer ops) and tests/test_depth_model.c,
 * tests/test_reliability.c (input_8x8.tflite; empty.tflite and bad_magic.tflite: issue 70), never the
 * real model). */
#include "fuzz_common.h"
#include "nn/nn.h"
#include "nn/tflite.h"

#define FUZZ_MAX_ELEMENTS ((int64_t)1 << 20) /* run only graphs this small */

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    nn_tfl_model m;
    if (nn_tfl_parse(data, size, "fuzz.tflite", &m) == PG_OK) {
        int64_t total = 0;
        for (int i = 0; i < m.num_tensors; i++) total += m.tensors[i].count;
        if (total <= FUZZ_MAX_ELEMENTS && m.num_inputs == 1) {
            float *x = calloc((size_t)m.tensors[m.inputs[0]].count, sizeof(float));
            float *y = calloc((size_t)m.tensors[m.outputs[0]].count, sizeof(float));
            if (x && y) nn_tfl_ref_run(&m, x, &y, 1);
            free(x);
            free(y);
        }
        nn_tfl_destroy(&m);
    }
    nn_model *model;
    if (nn_model_load_memory(data, size, "fuzz.tflite", &model) == PG_OK) {
        if (nn_model_memory_bytes(model) <= (size_t)FUZZ_MAX_ELEMENTS * 16) {
            int64_t din[NN_MAX_DIMS], dout[NN_MAX_DIMS];
            int ni = nn_model_input_shape(model, din), no = nn_model_output_shape(model, dout);
            float *x = calloc((size_t)nn_shape_count(ni, din), sizeof(float));
            float *y = calloc((size_t)nn_shape_count(no, dout) + 1, sizeof(float));
            if (x && y) nn_model_run(model, x, y, 1);
            free(x);
            free(y);
        }
        nn_model_destroy(model);
    }
    return 0;
}
