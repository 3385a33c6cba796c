/* nn_model.c - the nn.h API: read a model file, pick the front end, prepare, run. */
#include "nn/nn.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "core/fileutil.h"

#define NN_MAX_FILE ((size_t)4 << 30) /* 4 GiB: larger models are refused before reading */

struct nn_model {
    nn_graph g;
};

pg_status nn_model_load_memory_shaped(const void *data, size_t size, const char *name, int ndim, const int64_t *dims,
                                      nn_model **model)
{
    *model = NULL;
    if (ndim < 0 || ndim > NN_MAX_DIMS || (ndim && !dims)) return pg_fail(PG_ERR_ARG, "%s: bad input shape (%d dims)", name, ndim);
    nn_model *m = pg_calloc(1, sizeof *m, "nn model");
    if (!m) return PG_ERR_NOMEM;
    nn_graph_init(&m->g);
    m->g.bind_ndim = ndim;
    for (int i = 0; i < ndim; i++) m->g.bind_dims[i] = dims[i];
    const uint8_t *d = data;
    size_t nl = strlen(name);
    int tflite_name = nl >= 7 && strcasecmp(name + nl - 7, ".tflite") == 0;
    pg_status st;
    /* the format is the identifier's; a .tflite file without it is a broken TFLite file, not an ONNX one */
    if (size == 0) st = pg_fail(PG_ERR_FORMAT, "%s: empty file, not a model", name);
    else if (size >= 8 && memcmp(d + 4, "TFL3", 4) == 0) st = nn_tflite_import(d, size, name, &m->g);
    else if (tflite_name) st = pg_fail(PG_ERR_FORMAT, "%s: not a TFLite model (no TFL3 identifier at byte 4)", name);
    else st = nn_onnx_import(d, size, name, &m->g);
    if (!st) st = nn_graph_prepare(&m->g);
    if (!st && (m->g.num_inputs < 1 || m->g.tensors[m->g.inputs[0]].dtype != NN_F32))
        st = pg_fail(PG_ERR_FORMAT, "%s: the model has no float32 input", name);
    if (st) {
        /* every message names the file, once */
        if (strncmp(pg_last_error(), name, strlen(name)) != 0) pg_fail_context(st, "%s", name);
        nn_model_destroy(m);
        return st;
    }
    *model = m;
    return PG_OK;
}

pg_status nn_model_load_memory(const void *data, size_t size, const char *name, nn_model **model)
{
    return nn_model_load_memory_shaped(data, size, name, 0, NULL, model);
}

pg_status nn_model_load_shaped(const char *path, int ndim, const int64_t *dims, nn_model **model)
{
    *model = NULL;
    FILE *f;
    PG_TRY(pg_open_read(path, &f));
    long len = -1;
    if (fseek(f, 0, SEEK_END) == 0) len = ftell(f);
    if (len < 0 || fseek(f, 0, SEEK_SET) != 0) { fclose(f); return pg_fail(PG_ERR_IO, "%s: cannot read", path); }
    if ((size_t)len > NN_MAX_FILE) { fclose(f); return pg_fail(PG_ERR_SIZE, "%s: %ld bytes is larger than the 4 GiB limit", path, len); }
    uint8_t *buf = pg_malloc((size_t)len + 1, path);
    if (!buf) { fclose(f); return PG_ERR_NOMEM; }
    size_t got = fread(buf, 1, (size_t)len, f);
    fclose(f);
    if (got != (size_t)len) { free(buf); return pg_fail(PG_ERR_IO, "%s: short read", path); }
    pg_status st = nn_model_load_memory_shaped(buf, (size_t)len, path, ndim, dims, model);
    free(buf);
    return st;
}

pg_status nn_model_load(const char *path, nn_model **model) { return nn_model_load_shaped(path, 0, NULL, model); }

void nn_model_destroy(nn_model *model)
{
    if (!model) return;
    nn_graph_destroy(&model->g);
    free(model);
}

static int copy_shape(const nn_tensor *t, int64_t dims[NN_MAX_DIMS])
{
    for (int i = 0; i < t->ndim; i++) dims[i] = t->dims[i];
    return t->ndim;
}

int nn_model_input_shape(const nn_model *model, int64_t dims[NN_MAX_DIMS])
{
    return copy_shape(&model->g.tensors[model->g.inputs[0]], dims);
}

int nn_model_output_shape(const nn_model *model, int64_t dims[NN_MAX_DIMS])
{
    return copy_shape(&model->g.tensors[model->g.outputs[0]], dims);
}

pg_status nn_model_run(nn_model *model, const float *input, float *output, int threads)
{
    nn_graph *g = &model->g;
    const nn_tensor *ti = &g->tensors[g->inputs[0]], *to = &g->tensors[g->outputs[0]];
    size_t nin = (size_t)nn_shape_count(ti->ndim, ti->dims), nout = (size_t)nn_shape_count(to->ndim, to->dims);
    if (nin) memcpy(nn_graph_data(g, g->inputs[0]), input, nin * sizeof(float));
    PG_TRY(nn_graph_run(g, threads));
    const float *y = nn_graph_data(g, g->outputs[0]);
    if (!y) return pg_fail(PG_ERR_FORMAT, "output '%s' is not float32", to->name);
    if (nout) memcpy(output, y, nout * sizeof(float));
    return PG_OK;
}

size_t nn_model_memory_bytes(const nn_model *model) { return nn_graph_memory_bytes(&model->g); }

nn_graph *nn_model_graph(nn_model *model) { return &model->g; }
