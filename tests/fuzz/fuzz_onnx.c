/* fuzz_onnx.c - libFuzzer harness: nn_model_load_memory on any bytes, and a run of what loads
 * (small models only, so one input stays fast). */
#include "fuzz_common.h"
#include "nn/nn.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    nn_model *m;
    if (nn_model_load_memory(data, size, "fuzz.onnx", &m) != PG_OK) return 0;
    int64_t d[NN_MAX_DIMS];
    size_t ni = (size_t)nn_shape_count(nn_model_input_shape(m, d), d);
    size_t no = (size_t)nn_shape_count(nn_model_output_shape(m, d), d);
    if (nn_model_memory_bytes(m) < ((size_t)16 << 20)) {
        float *x = calloc(ni + 1, sizeof(float)), *y = calloc(no + 1, sizeof(float));
        if (x && y) nn_model_run(m, x, y, 1);
        free(x);
        free(y);
    }
    nn_model_destroy(m);
    return 0;
}
