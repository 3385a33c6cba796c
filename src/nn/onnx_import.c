/* onnx_import.c - placeholder */
#include "nn/nn_graph.h"

pg_status nn_onnx_import(const uint8_t *data, size_t size, const char *name, nn_graph *g)
{
    (void)data; (void)size; (void)g;
    return pg_fail(PG_ERR_FORMAT, "%s: ONNX import not written yet", name);
}
