/* nn_graph.c - building the graph IR (see nn_graph.h): tensors, constants, nodes, io. */
#include "nn/nn_graph.h"

#include <stdlib.h>
#include <string.h>

int64_t nn_shape_count(int ndim, const int64_t *dims)
{
    int64_t n = 1;
    for (int i = 0; i < ndim; i++) n *= dims[i];
    return n;
}

void nn_graph_init(nn_graph *g) { memset(g, 0, sizeof *g); }

void nn_graph_destroy(nn_graph *g)
{
    if (!g) return;
    for (int i = 0; i < g->num_tensors; i++) { free(g->tensors[i].name); free(g->tensors[i].data); }
    for (int i = 0; i < g->num_nodes; i++) { free(g->nodes[i].name); free(g->nodes[i].inputs); }
    free(g->tensors);
    free(g->nodes);
    free(g->arena_block);
    free(g->scratch);
    memset(g, 0, sizeof *g);
}

void nn_attrs_default(nn_attrs *a)
{
    memset(a, 0, sizeof *a);
    a->stride[0] = a->stride[1] = 1;
    a->dilation[0] = a->dilation[1] = 1;
    a->group = 1;
    a->keepdims = 1;
    for (int i = 0; i < NN_MAX_DIMS; i++) a->steps[i] = 1;
    a->alpha = 1.0f;
    a->beta = 1.0f;
    a->epsilon = 1e-5f;
    a->act_alpha = 0.01f;
    a->resize_mode = NN_RESIZE_NEAREST;
    a->coord_mode = NN_COORD_HALF_PIXEL;
    a->nearest_mode = NN_NEAREST_ROUND_PREFER_FLOOR;
    a->cubic_a = -0.75f;
}

static char *dup_name(const char *name)
{
    size_t n = strlen(name ? name : "");
    char *s = pg_malloc(n + 1, "nn tensor name");
    if (s) memcpy(s, name ? name : "", n + 1);
    return s;
}

/* Checks dims are positive, under NN_MAX_DIM, and their product under NN_MAX_ELEMENTS. */
static pg_status check_dims(const char *name, int ndim, const int64_t *dims)
{
    if (ndim < 0 || ndim > NN_MAX_DIMS) return pg_fail(PG_ERR_SIZE, "tensor '%s': %d dims (at most %d)", name, ndim, NN_MAX_DIMS);
    int64_t n = 1;
    for (int i = 0; i < ndim; i++) {
        if (dims[i] < 0 || dims[i] > NN_MAX_DIM)
            return pg_fail(PG_ERR_SIZE, "tensor '%s': dim %d is %lld (limit %lld)", name, i, (long long)dims[i], (long long)NN_MAX_DIM);
        n *= dims[i];
        if (n > NN_MAX_ELEMENTS) return pg_fail(PG_ERR_SIZE, "tensor '%s': more than %lld elements", name, (long long)NN_MAX_ELEMENTS);
    }
    return PG_OK;
}

static pg_status push_tensor(nn_graph *g, const char *name, nn_dtype dtype, int ndim, const int64_t *dims, int *id)
{
    if (dims && ndim >= 0) PG_TRY(check_dims(name ? name : "", ndim, dims));
    if (g->num_tensors >= NN_MAX_TENSORS) return pg_fail(PG_ERR_SIZE, "more than %d tensors", NN_MAX_TENSORS);
    if (g->num_tensors == g->cap_tensors) {
        int cap = g->cap_tensors ? g->cap_tensors * 2 : 64;
        nn_tensor *t = realloc(g->tensors, (size_t)cap * sizeof *t);
        if (!t) return pg_fail(PG_ERR_NOMEM, "out of memory for %d tensors", cap);
        g->tensors = t;
        g->cap_tensors = cap;
    }
    nn_tensor *t = &g->tensors[g->num_tensors];
    memset(t, 0, sizeof *t);
    t->name = dup_name(name);
    if (!t->name) return PG_ERR_NOMEM;
    t->dtype = dtype;
    t->ndim = dims ? ndim : -1;
    if (dims) for (int i = 0; i < ndim; i++) t->dims[i] = dims[i];
    t->producer = -1;
    t->last_use = -1;
    *id = g->num_tensors++;
    return PG_OK;
}

pg_status nn_graph_add_tensor(nn_graph *g, const char *name, nn_dtype dtype, int ndim, const int64_t *dims, int *id)
{
    return push_tensor(g, name, dtype, ndim, dims, id);
}

pg_status nn_graph_add_const(nn_graph *g, const char *name, nn_dtype dtype, int ndim, const int64_t *dims, void *data, int *id)
{
    pg_status st = push_tensor(g, name, dtype, ndim, dims, id);
    if (st) { free(data); return st; }
    g->tensors[*id].data = data;
    return PG_OK;
}

pg_status nn_graph_add_const_f32(nn_graph *g, const char *name, int ndim, const int64_t *dims, const float *data, int *id)
{
    PG_TRY(check_dims(name, ndim, dims));
    size_t n = (size_t)nn_shape_count(ndim, dims);
    float *copy = pg_malloc((n ? n : 1) * sizeof(float), name);
    if (!copy) return PG_ERR_NOMEM;
    if (n) memcpy(copy, data, n * sizeof(float));
    return nn_graph_add_const(g, name, NN_F32, ndim, dims, copy, id);
}

pg_status nn_graph_add_node(nn_graph *g, nn_op op, const char *name, const int *inputs, int num_inputs,
                            const int *outputs, int num_outputs, const nn_attrs *attr, int *id)
{
    if ((unsigned)op >= NN_OP_COUNT) return pg_fail(PG_ERR_INTERNAL, "node '%s': bad op %d", name, (int)op);
    if (num_inputs < 0 || num_inputs > 4096 || num_outputs < 1 || num_outputs > NN_MAX_OUTPUTS)
        return pg_fail(PG_ERR_FORMAT, "node '%s' (%s): %d inputs, %d outputs", name, nn_op_name(op), num_inputs, num_outputs);
    for (int i = 0; i < num_inputs; i++)
        if (inputs[i] < -1 || inputs[i] >= g->num_tensors) return pg_fail(PG_ERR_FORMAT, "node '%s': bad input id", name);
    for (int i = 0; i < num_outputs; i++)
        if (outputs[i] < 0 || outputs[i] >= g->num_tensors) return pg_fail(PG_ERR_FORMAT, "node '%s': bad output id", name);
    if (g->num_nodes >= NN_MAX_NODES) return pg_fail(PG_ERR_SIZE, "more than %d nodes", NN_MAX_NODES);
    if (g->num_nodes == g->cap_nodes) {
        int cap = g->cap_nodes ? g->cap_nodes * 2 : 64;
        nn_node *n = realloc(g->nodes, (size_t)cap * sizeof *n);
        if (!n) return pg_fail(PG_ERR_NOMEM, "out of memory for %d nodes", cap);
        g->nodes = n;
        g->cap_nodes = cap;
    }
    nn_node *n = &g->nodes[g->num_nodes];
    memset(n, 0, sizeof *n);
    n->op = op;
    n->name = dup_name(name);
    n->inputs = pg_malloc((size_t)(num_inputs ? num_inputs : 1) * sizeof(int), "nn node inputs");
    if (!n->name || !n->inputs) { free(n->name); free(n->inputs); return PG_ERR_NOMEM; }
    if (num_inputs) memcpy(n->inputs, inputs, (size_t)num_inputs * sizeof(int));
    n->num_inputs = num_inputs;
    memcpy(n->outputs, outputs, (size_t)num_outputs * sizeof(int));
    n->num_outputs = num_outputs;
    if (attr) n->attr = *attr;
    else nn_attrs_default(&n->attr);
    if (id) *id = g->num_nodes;
    g->num_nodes++;
    return PG_OK;
}

pg_status nn_graph_set_io(nn_graph *g, const int *inputs, int num_inputs, const int *outputs, int num_outputs)
{
    if (num_inputs < 0 || num_inputs > NN_MAX_IO || num_outputs < 1 || num_outputs > NN_MAX_IO)
        return pg_fail(PG_ERR_FORMAT, "graph has %d inputs and %d outputs (at most %d each, at least one output)",
                       num_inputs, num_outputs, NN_MAX_IO);
    for (int i = 0; i < num_inputs; i++)
        if (inputs[i] < 0 || inputs[i] >= g->num_tensors) return pg_fail(PG_ERR_FORMAT, "graph input %d: bad tensor id", i);
    for (int i = 0; i < num_outputs; i++)
        if (outputs[i] < 0 || outputs[i] >= g->num_tensors) return pg_fail(PG_ERR_FORMAT, "graph output %d: bad tensor id", i);
    if (num_inputs) memcpy(g->inputs, inputs, (size_t)num_inputs * sizeof(int));
    memcpy(g->outputs, outputs, (size_t)num_outputs * sizeof(int));
    g->num_inputs = num_inputs;
    g->num_outputs = num_outputs;
    return PG_OK;
}

int nn_graph_find_tensor(const nn_graph *g, const char *name)
{
    for (int i = 0; i < g->num_tensors; i++)
        if (strcmp(g->tensors[i].name, name) == 0) return i;
    return -1;
}
