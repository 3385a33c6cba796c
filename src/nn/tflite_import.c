/* tflite_import.c - the TFLite front end. A stub until the nn-tflite branch replaces this file
 * with the flatbuffer importer (same signature, declared in nn_graph.h). */
#include "nn/nn_graph.h"

pg_status nn_tflite_import(const uint8_t *data, size_t size, const char *name, nn_graph *g)
{
    (void)data; (void)size; (void)g;
    return pg_fail(PG_ERR_FORMAT, "%s: TFLite models are not supported yet", name);
}
