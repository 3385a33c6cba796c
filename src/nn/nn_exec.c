/* nn_exec.c - validation, topological order, shape inference, memory plan and the run loop.
 *
 * nn_graph_prepare does all checks before any compute memory exists: every id valid, each tensor
 * produced once, no cycles (Kahn's algorithm: nodes left over sit on a cycle), every shape
 * inferred and under NN_MAX_DIM / NN_MAX_ELEMENTS, and the arena size computed. The arena plan is
 * greedy best-fit: walking the nodes in run order, outputs take the smallest free block that fits
 * (or grow the arena), and a tensor's block returns to the free list after its last reader.
 */
#include "nn/nn_ops.h"

#include <assert.h>
#include <limits.h>
#include <math.h>
#include <omp.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cblas.h>

#define NN_ALIGN 16 /* floats: 64-byte blocks */

const nn_op_info nn_ops[NN_OP_COUNT] = {
    [NN_OP_CONV] = { "Conv", 2, 3, nn_infer_conv, nn_run_conv, nn_scratch_conv },
    [NN_OP_CONV_TRANSPOSE] = { "ConvTranspose", 2, 3, nn_infer_conv_transpose, nn_run_conv_transpose, nn_scratch_conv_transpose },
    [NN_OP_MATMUL] = { "MatMul", 2, 3, nn_infer_matmul, nn_run_matmul, nn_scratch_matmul },
    [NN_OP_GEMM] = { "Gemm", 2, 3, nn_infer_gemm, nn_run_gemm, NULL },
    [NN_OP_ADD] = { "Add", 2, 2, nn_infer_binary, nn_run_binary, NULL },
    [NN_OP_SUB] = { "Sub", 2, 2, nn_infer_binary, nn_run_binary, NULL },
    [NN_OP_MUL] = { "Mul", 2, 2, nn_infer_binary, nn_run_binary, NULL },
    [NN_OP_DIV] = { "Div", 2, 2, nn_infer_binary, nn_run_binary, NULL },
    [NN_OP_POW] = { "Pow", 2, 2, nn_infer_binary, nn_run_binary, NULL },
    [NN_OP_MAXIMUM] = { "Max", 2, 2, nn_infer_binary, nn_run_binary, NULL },
    [NN_OP_MINIMUM] = { "Min", 2, 2, nn_infer_binary, nn_run_binary, NULL },
    [NN_OP_SQRT] = { "Sqrt", 1, 1, nn_infer_unary, nn_run_unary, NULL },
    [NN_OP_ERF] = { "Erf", 1, 1, nn_infer_unary, nn_run_unary, NULL },
    [NN_OP_EXP] = { "Exp", 1, 1, nn_infer_unary, nn_run_unary, NULL },
    [NN_OP_TANH] = { "Tanh", 1, 1, nn_infer_unary, nn_run_unary, NULL },
    [NN_OP_NEG] = { "Neg", 1, 1, nn_infer_unary, nn_run_unary, NULL },
    [NN_OP_RELU] = { "Relu", 1, 1, nn_infer_unary, nn_run_unary, NULL },
    [NN_OP_LEAKY_RELU] = { "LeakyRelu", 1, 1, nn_infer_unary, nn_run_unary, NULL },
    [NN_OP_SIGMOID] = { "Sigmoid", 1, 1, nn_infer_unary, nn_run_unary, NULL },
    [NN_OP_GELU] = { "Gelu", 1, 1, nn_infer_unary, nn_run_unary, NULL },
    [NN_OP_LAYER_NORM] = { "LayerNormalization", 1, 3, nn_infer_layer_norm, nn_run_layer_norm, NULL },
    [NN_OP_SOFTMAX] = { "Softmax", 1, 1, nn_infer_softmax, nn_run_softmax, NULL },
    [NN_OP_REDUCE_MEAN] = { "ReduceMean", 1, 1, nn_infer_reduce_mean, nn_run_reduce_mean, NULL },
    [NN_OP_RESHAPE] = { "Reshape", 1, 1, nn_infer_reshape, nn_run_reshape, NULL },
    [NN_OP_TRANSPOSE] = { "Transpose", 1, 1, nn_infer_transpose, nn_run_transpose, NULL },
    [NN_OP_SLICE] = { "Slice", 1, 1, nn_infer_slice, nn_run_slice, NULL },
    [NN_OP_CONCAT] = { "Concat", 1, 4096, nn_infer_concat, nn_run_concat, NULL },
    [NN_OP_GATHER] = { "Gather", 2, 2, nn_infer_gather, nn_run_gather, NULL },
    [NN_OP_EXPAND] = { "Expand", 1, 1, nn_infer_expand, nn_run_expand, NULL },
    [NN_OP_PAD] = { "Pad", 1, 1, nn_infer_pad, nn_run_pad, NULL },
    [NN_OP_RESIZE] = { "Resize", 1, 1, nn_infer_resize, nn_run_resize, nn_scratch_resize },
    [NN_OP_IDENTITY] = { "Identity", 1, 1, nn_infer_unary, nn_run_reshape, NULL },
    [NN_OP_ABS] = { "Abs", 1, 1, nn_infer_unary, nn_run_unary, NULL },
    [NN_OP_ATTENTION] = { "Attention", 3, 3, nn_infer_attention, nn_run_attention, nn_scratch_attention },
    [NN_OP_REQUANTIZE] = { "Requantize", 1, 2, nn_infer_requantize, nn_run_requantize, nn_scratch_requantize },
};
static_assert(sizeof nn_ops / sizeof nn_ops[0] == NN_OP_COUNT, "one nn_ops entry per nn_op");

const char *nn_op_name(nn_op op) { return (unsigned)op < NN_OP_COUNT && nn_ops[op].name ? nn_ops[op].name : "?"; }

pg_status nn_node_fail(const nn_node *n, const char *fmt, ...)
{
    char msg[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return pg_fail(PG_ERR_FORMAT, "node '%s' (%s): %s", n->name, nn_op_name(n->op), msg);
}

int nn_axis(int64_t axis, int ndim)
{
    if (axis < -ndim || axis >= ndim) return -1;
    return (int)(axis < 0 ? axis + ndim : axis);
}

pg_status nn_set_output(nn_graph *g, const nn_node *n, int i, int ndim, const int64_t *dims)
{
    if (ndim < 0 || ndim > NN_MAX_DIMS) return nn_node_fail(n, "output has %d dims (at most %d)", ndim, NN_MAX_DIMS);
    int64_t count = 1;
    for (int d = 0; d < ndim; d++) {
        if (dims[d] < 0 || dims[d] > NN_MAX_DIM) return nn_node_fail(n, "output dim %d is %lld", d, (long long)dims[d]);
        count *= dims[d];
        if (count > NN_MAX_ELEMENTS)
            return pg_fail(PG_ERR_SIZE, "node '%s' (%s): output over %lld elements", n->name, nn_op_name(n->op), (long long)NN_MAX_ELEMENTS);
    }
    nn_tensor *t = nn_out(g, n, i);
    if (t->ndim >= 0 && t->producer >= 0) {
        /* a shape declared by the model must agree with the inferred one */
        int same = t->ndim == ndim;
        for (int d = 0; same && d < ndim; d++) same = t->dims[d] == dims[d];
        if (!same) return nn_node_fail(n, "inferred output shape disagrees with the shape declared for '%s'", t->name);
    }
    t->ndim = ndim;
    for (int d = 0; d < ndim; d++) t->dims[d] = dims[d];
    t->dtype = NN_F32;
    return PG_OK;
}

float *nn_graph_data(const nn_graph *g, int id)
{
    const nn_tensor *t = &g->tensors[id];
    if (t->dtype != NN_F32) return NULL;
    if (t->data) return t->data;
    return g->arena ? g->arena + t->offset : NULL;
}

size_t nn_graph_memory_bytes(const nn_graph *g)
{
    return g->const_bytes + g->arena_floats * sizeof(float) + g->scratch_floats * sizeof(float) * (size_t)(g->scratch_threads > 0 ? g->scratch_threads : 1);
}

/* ---- ordering ---- */

/* Sets producers, checks every input is a constant, a graph input or produced by some node. */
static pg_status link_tensors(nn_graph *g)
{
    for (int i = 0; i < g->num_tensors; i++) g->tensors[i].producer = -1;
    for (int i = 0; i < g->num_inputs; i++) {
        nn_tensor *t = &g->tensors[g->inputs[i]];
        if (t->data) return pg_fail(PG_ERR_FORMAT, "graph input '%s' is also a constant", t->name);
        if (t->ndim < 0) return pg_fail(PG_ERR_FORMAT, "graph input '%s' has no static shape", t->name);
        if (t->dtype != NN_F32) return pg_fail(PG_ERR_FORMAT, "graph input '%s' is not float32", t->name);
    }
    for (int k = 0; k < g->num_nodes; k++) {
        nn_node *n = &g->nodes[k];
        const nn_op_info *info = &nn_ops[n->op];
        if (n->num_inputs < info->min_inputs || n->num_inputs > info->max_inputs)
            return nn_node_fail(n, "%d inputs (expected %d to %d)", n->num_inputs, info->min_inputs, info->max_inputs);
        if (n->inputs[0] < 0) return nn_node_fail(n, "first input missing");
        for (int o = 0; o < n->num_outputs; o++) {
            nn_tensor *t = &g->tensors[n->outputs[o]];
            if (t->data) return nn_node_fail(n, "writes constant '%s'", t->name);
            for (int i = 0; i < g->num_inputs; i++)
                if (g->inputs[i] == n->outputs[o]) return nn_node_fail(n, "writes graph input '%s'", t->name);
            if (t->producer >= 0) return nn_node_fail(n, "'%s' is already produced by node '%s'", t->name, g->nodes[t->producer].name);
            t->producer = k;
        }
    }
    for (int k = 0; k < g->num_nodes; k++) {
        nn_node *n = &g->nodes[k];
        for (int i = 0; i < n->num_inputs; i++) {
            if (n->inputs[i] < 0) continue;
            nn_tensor *t = &g->tensors[n->inputs[i]];
            int is_input = 0;
            for (int j = 0; j < g->num_inputs; j++) is_input |= g->inputs[j] == n->inputs[i];
            if (!t->data && !is_input && t->producer < 0) return nn_node_fail(n, "input '%s' is never computed", t->name);
        }
    }
    for (int i = 0; i < g->num_outputs; i++) {
        nn_tensor *t = &g->tensors[g->outputs[i]];
        int is_input = 0;
        for (int j = 0; j < g->num_inputs; j++) is_input |= g->inputs[j] == g->outputs[i];
        if (!t->data && !is_input && t->producer < 0) return pg_fail(PG_ERR_FORMAT, "graph output '%s' is never computed", t->name);
    }
    return PG_OK;
}

/* Keeps the nodes some graph output depends on, in topological order (Kahn). */
static pg_status sort_nodes(nn_graph *g)
{
    int N = g->num_nodes, T = g->num_tensors;
    pg_status st = PG_OK;
    char *live = calloc((size_t)N + 1, 1);
    int *stack = malloc(((size_t)N + (size_t)T + 1) * sizeof(int));
    int *pending = calloc((size_t)N + 1, sizeof(int));
    int *order = malloc(((size_t)N + 1) * sizeof(int));
    /* readers of each tensor, CSR */
    int *start = calloc((size_t)T + 1, sizeof(int)), *readers = NULL;
    if (!live || !stack || !pending || !order || !start) { st = pg_fail(PG_ERR_NOMEM, "out of memory sorting %d nodes", N); goto done; }
    /* liveness: walk back from the outputs */
    int sp = 0;
    for (int i = 0; i < g->num_outputs; i++) {
        int p = g->tensors[g->outputs[i]].producer;
        if (p >= 0 && !live[p]) { live[p] = 1; stack[sp++] = p; }
    }
    while (sp) {
        nn_node *n = &g->nodes[stack[--sp]];
        for (int i = 0; i < n->num_inputs; i++) {
            if (n->inputs[i] < 0) continue;
            int p = g->tensors[n->inputs[i]].producer;
            if (p >= 0 && !live[p]) { live[p] = 1; stack[sp++] = p; }
        }
    }
    size_t edges = 0;
    for (int k = 0; k < N; k++) {
        if (!live[k]) continue;
        nn_node *n = &g->nodes[k];
        for (int i = 0; i < n->num_inputs; i++) {
            if (n->inputs[i] < 0 || g->tensors[n->inputs[i]].producer < 0) continue;
            start[n->inputs[i] + 1]++;
            pending[k]++;
            edges++;
        }
    }
    for (int t = 0; t < T; t++) start[t + 1] += start[t];
    readers = malloc((edges + 1) * sizeof(int));
    int *fill = calloc((size_t)T + 1, sizeof(int));
    if (!readers || !fill) { free(fill); st = pg_fail(PG_ERR_NOMEM, "out of memory sorting %d nodes", N); goto done; }
    for (int k = 0; k < N; k++) {
        if (!live[k]) continue;
        nn_node *n = &g->nodes[k];
        for (int i = 0; i < n->num_inputs; i++) {
            int t = n->inputs[i];
            if (t < 0 || g->tensors[t].producer < 0) continue;
            readers[start[t] + fill[t]++] = k;
        }
    }
    free(fill);
    int count = 0, live_count = 0;
    sp = 0;
    for (int k = N - 1; k >= 0; k--) {
        if (!live[k]) continue;
        live_count++;
        if (pending[k] == 0) stack[sp++] = k;
    }
    while (sp) {
        int k = stack[--sp];
        order[count++] = k;
        nn_node *n = &g->nodes[k];
        for (int o = 0; o < n->num_outputs; o++) {
            int t = n->outputs[o];
            for (int r = start[t]; r < start[t + 1]; r++)
                if (--pending[readers[r]] == 0) stack[sp++] = readers[r];
        }
    }
    if (count < live_count) {
        int bad = 0;
        for (int k = 0; k < N; k++) if (live[k] && pending[k] > 0) { bad = k; break; }
        st = pg_fail(PG_ERR_FORMAT, "node '%s' (%s) is on a cycle", g->nodes[bad].name, nn_op_name(g->nodes[bad].op));
        goto done;
    }
    /* permute: keep live nodes in order, free the dead ones, renumber producers */
    nn_node *sorted = malloc(((size_t)count + 1) * sizeof *sorted);
    if (!sorted) { st = pg_fail(PG_ERR_NOMEM, "out of memory sorting %d nodes", N); goto done; }
    for (int i = 0; i < count; i++) sorted[i] = g->nodes[order[i]];
    for (int k = 0; k < N; k++) if (!live[k]) { free(g->nodes[k].name); free(g->nodes[k].inputs); }
    free(g->nodes);
    g->nodes = sorted;
    g->num_nodes = g->cap_nodes = count;
    for (int t = 0; t < T; t++) g->tensors[t].producer = -1;
    for (int k = 0; k < count; k++)
        for (int o = 0; o < sorted[k].num_outputs; o++) g->tensors[sorted[k].outputs[o]].producer = k;
done:
    free(live); free(stack); free(pending); free(order); free(start); free(readers);
    return st;
}

/* ---- memory plan ---- */

typedef struct { size_t off, size; } nn_block;

typedef struct {
    nn_block *free_list;
    int count, cap;
    size_t end;
} nn_planner;

static size_t plan_take(nn_planner *p, size_t size)
{
    int best = -1;
    for (int i = 0; i < p->count; i++)
        if (p->free_list[i].size >= size && (best < 0 || p->free_list[i].size < p->free_list[best].size)) best = i;
    if (best < 0) {
        /* grow: a free block ending at the arena's end is extended */
        for (int i = 0; i < p->count; i++)
            if (p->free_list[i].off + p->free_list[i].size == p->end) {
                size_t off = p->free_list[i].off;
                p->end = off + size;
                p->free_list[i] = p->free_list[--p->count];
                return off;
            }
        size_t off = p->end;
        p->end += size;
        return off;
    }
    size_t off = p->free_list[best].off;
    p->free_list[best].off += size;
    p->free_list[best].size -= size;
    if (p->free_list[best].size == 0) p->free_list[best] = p->free_list[--p->count];
    return off;
}

static int plan_give(nn_planner *p, size_t off, size_t size)
{
    /* merge with neighbours */
    for (int i = 0; i < p->count; i++) {
        if (p->free_list[i].off + p->free_list[i].size == off) {
            off = p->free_list[i].off; size += p->free_list[i].size;
            p->free_list[i--] = p->free_list[--p->count];
        } else if (off + size == p->free_list[i].off) {
            size += p->free_list[i].size;
            p->free_list[i--] = p->free_list[--p->count];
        }
    }
    if (p->count == p->cap) {
        int cap = p->cap ? p->cap * 2 : 64;
        nn_block *b = realloc(p->free_list, (size_t)cap * sizeof *b);
        if (!b) return -1;
        p->free_list = b;
        p->cap = cap;
    }
    p->free_list[p->count++] = (nn_block){ off, size };
    return 0;
}

static size_t tensor_floats(const nn_tensor *t)
{
    size_t n = (size_t)nn_shape_count(t->ndim, t->dims);
    return (n + NN_ALIGN - 1) / NN_ALIGN * NN_ALIGN + (n == 0 ? NN_ALIGN : 0);
}

static pg_status plan_memory(nn_graph *g)
{
    for (int t = 0; t < g->num_tensors; t++) g->tensors[t].last_use = -1;
    for (int k = 0; k < g->num_nodes; k++)
        for (int i = 0; i < g->nodes[k].num_inputs; i++)
            if (g->nodes[k].inputs[i] >= 0) g->tensors[g->nodes[k].inputs[i]].last_use = k;
    for (int i = 0; i < g->num_outputs; i++) g->tensors[g->outputs[i]].last_use = INT_MAX;
    nn_planner p = { 0 };
    int ok = 1;
    for (int i = 0; i < g->num_inputs; i++) {
        nn_tensor *t = &g->tensors[g->inputs[i]];
        t->offset = plan_take(&p, tensor_floats(t));
        t->last_use = INT_MAX; /* the caller writes inputs before each run */
    }
    for (int k = 0; k < g->num_nodes && ok; k++) {
        nn_node *n = &g->nodes[k];
        for (int o = 0; o < n->num_outputs; o++) {
            nn_tensor *t = &g->tensors[n->outputs[o]];
            t->offset = plan_take(&p, tensor_floats(t));
        }
        for (int o = 0; o < n->num_outputs && ok; o++) {
            nn_tensor *t = &g->tensors[n->outputs[o]];
            if (t->last_use < 0) ok = !plan_give(&p, t->offset, tensor_floats(t));
        }
        for (int i = 0; i < n->num_inputs && ok; i++) {
            int id = n->inputs[i];
            if (id < 0) continue;
            nn_tensor *t = &g->tensors[id];
            int dup = 0;
            for (int j = 0; j < i; j++) dup |= n->inputs[j] == id;
            if (!t->data && t->last_use == k && !dup) ok = !plan_give(&p, t->offset, tensor_floats(t));
        }
    }
    free(p.free_list);
    if (!ok) return pg_fail(PG_ERR_NOMEM, "out of memory planning the arena");
    g->arena_floats = p.end;
    return PG_OK;
}

pg_status nn_node_infer(nn_graph *g, int id)
{
    nn_node *n = &g->nodes[id];
    const nn_op_info *info = &nn_ops[n->op];
    if (n->num_inputs < info->min_inputs || n->num_inputs > info->max_inputs)
        return nn_node_fail(n, "%d inputs (expected %d to %d)", n->num_inputs, info->min_inputs, info->max_inputs);
    for (int i = 0; i < n->num_inputs; i++) {
        nn_tensor *t = nn_in(g, n, i);
        if (!t && (i < info->min_inputs || n->op == NN_OP_CONCAT)) return nn_node_fail(n, "input %d missing", i);
        if (t && t->ndim < 0) return nn_node_fail(n, "input '%s' has no shape", t->name);
        if (t && t->dtype != NN_F32 && !((n->op == NN_OP_GATHER || n->op == NN_OP_REQUANTIZE) && i == 1))
            return nn_node_fail(n, "input '%s' is int64 (only float32 is computed)", t->name);
    }
    return info->infer(g, n);
}

/* Runs once every node whose inputs are all constants, in order, and turns its outputs into
 * constants; the node is dropped. Later nodes may then fold too. */
static pg_status fold_constants(nn_graph *g)
{
    int kept = 0;
    size_t folded = 0, budget = NN_MAX_FOLD_BYTES;
    /* a tiny file must not buy seconds of work and hundreds of MiB at load: 64 MiB plus twice
     * the constants it carries */
    size_t given = 0;
    for (int t = 0; t < g->num_tensors; t++)
        if (g->tensors[t].data) given += (size_t)nn_shape_count(g->tensors[t].ndim, g->tensors[t].dims) * sizeof(float);
    if (budget > ((size_t)64 << 20) + 2 * given) budget = ((size_t)64 << 20) + 2 * given;
    for (int k = 0; k < g->num_nodes; k++) {
        nn_node *n = &g->nodes[k];
        int all_const = 1;
        for (int i = 0; i < n->num_inputs; i++) all_const &= n->inputs[i] < 0 || g->tensors[n->inputs[i]].data != NULL;
        if (!all_const) { g->nodes[kept++] = *n; continue; }
        for (int o = 0; o < n->num_outputs; o++) {
            nn_tensor *t = nn_out(g, n, o);
            size_t count = (size_t)nn_shape_count(t->ndim, t->dims);
            folded += count * sizeof(float);
            if (folded > budget)
                return pg_fail(PG_ERR_SIZE, "node '%s' (%s): constants computed at load exceed %zu MiB", n->name,
                               nn_op_name(n->op), budget >> 20);
            t->data = pg_malloc((count ? count : 1) * sizeof(float), "folded constant");
            if (!t->data) return PG_ERR_NOMEM;
            t->producer = -1;
        }
        size_t sc = nn_ops[n->op].scratch ? nn_ops[n->op].scratch(g, n) : 0;
        float *scratch = sc ? pg_malloc(sc * sizeof(float), "folding scratch") : NULL;
        if (sc && !scratch) return PG_ERR_NOMEM;
        nn_ctx c = { g, scratch, sc };
        int saved = omp_get_max_threads();
        omp_set_num_threads(1);
        nn_ops[n->op].run(&c, n);
        omp_set_num_threads(saved);
        free(scratch);
        free(n->name);
        free(n->inputs);
    }
    g->num_nodes = kept;
    for (int t = 0; t < g->num_tensors; t++) g->tensors[t].producer = -1;
    for (int k = 0; k < kept; k++)
        for (int o = 0; o < g->nodes[k].num_outputs; o++) g->tensors[g->nodes[k].outputs[o]].producer = k;
    return PG_OK;
}

/* ---- fusion: fewer passes over memory, same arithmetic ----
 *   Conv / ConvTranspose / MatMul / Gemm + Relu          -> fused activation
 *   MatMul + Add(constant bias of N values)              -> MatMul with a bias input
 *   Transpose(swap of the last two axes) -> MatMul's b   -> MatMul trans_b
 *   x / sqrt(2) -> Erf -> + 1 -> * x -> * 0.5            -> Gelu (torch's export of nn.GELU)
 *   MatMul(q, k, trans_b) -> Softmax(last) -> MatMul(., v) -> Attention (scores never leave cache)
 *   LayerNorm as exported before opset 17: d = x - mean(x); d / sqrt(mean(d^2) + eps) (* g) (+ b)
 *                                                         -> LayerNormalization
 * An intermediate tensor is fused away only if its one reader is the next node of the pattern and
 * it is not a graph output. */

static int const_scalar(const nn_graph *g, int id, float *v)
{
    if (id < 0) return 0;
    const nn_tensor *t = &g->tensors[id];
    if (!t->data || t->dtype != NN_F32 || nn_shape_count(t->ndim, t->dims) != 1) return 0;
    *v = ((float *)t->data)[0];
    return 1;
}

static int is_last_axis_mean(const nn_graph *g, const nn_node *n)
{
    const nn_tensor *x = &g->tensors[n->inputs[0]];
    return n->op == NN_OP_REDUCE_MEAN && n->attr.keepdims && n->attr.num_axes == 1 && n->attr.axes[0] == x->ndim - 1;
}

/* The constant input of binary node n other than t, if it is a float constant of `count` values. */
static int const_other(const nn_graph *g, const nn_node *n, int t, int64_t count)
{
    if (n->num_inputs != 2 || (n->inputs[0] == t) == (n->inputs[1] == t)) return -1;
    int o = n->inputs[0] == t ? n->inputs[1] : n->inputs[0];
    const nn_tensor *c = &g->tensors[o];
    return c->data && c->dtype == NN_F32 && nn_shape_count(c->ndim, c->dims) == count ? o : -1;
}

static pg_status fuse_nodes(nn_graph *g)
{
    int N = g->num_nodes, T = g->num_tensors;
    /* per tensor: number of reading nodes, the first and the last of them */
    int *readers = calloc((size_t)T + 1, sizeof(int)), *reader = malloc(((size_t)T + 1) * sizeof(int));
    int *first = malloc(((size_t)T + 1) * sizeof(int));
    char *dead = calloc((size_t)N + 1, 1);
    if (!readers || !reader || !first || !dead) {
        free(readers); free(reader); free(first); free(dead);
        return pg_fail(PG_ERR_NOMEM, "out of memory fusing");
    }
    for (int k = 0; k < N; k++)
        for (int i = 0; i < g->nodes[k].num_inputs; i++) {
            int t = g->nodes[k].inputs[i];
            if (t >= 0) { if (!readers[t]) first[t] = k; readers[t]++; reader[t] = k; }
        }
    for (int i = 0; i < g->num_outputs; i++) readers[g->outputs[i]] += 2;
    /* the only reader of node k's output, or -1 */
    #define NEXT(k) (readers[g->nodes[k].outputs[0]] == 1 && g->nodes[k].num_outputs == 1 ? reader[g->nodes[k].outputs[0]] : -1)
    for (int k = 0; k < N; k++) {
        nn_node *n = &g->nodes[k];
        if (dead[k]) continue;
        /* Transpose (last two axes) feeding MatMul's b */
        if (n->op == NN_OP_TRANSPOSE && NEXT(k) >= 0) {
            int m = NEXT(k);
            nn_node *mm = &g->nodes[m];
            const nn_attrs *a = &n->attr;
            int nd = a->num_perm, swap = nd >= 2 && a->perm[nd - 1] == nd - 2 && a->perm[nd - 2] == nd - 1;
            for (int i = 0; i < nd - 2 && swap; i++) swap = a->perm[i] == i;
            if (swap && mm->op == NN_OP_MATMUL && mm->inputs[1] == n->outputs[0] && mm->inputs[0] != n->outputs[0] && !mm->attr.trans_b) {
                mm->inputs[1] = n->inputs[0];
                mm->attr.trans_b = 1;
                dead[k] = 1;
                continue;
            }
        }
        /* Gelu */
        if (n->op == NN_OP_DIV && NEXT(k) >= 0) {
            float v;
            int x = n->inputs[0], e = NEXT(k);
            if (!const_scalar(g, n->inputs[1], &v) || fabsf(v - 1.41421356f) > 1e-5f || g->nodes[e].op != NN_OP_ERF) goto not_gelu;
            int ad = NEXT(e);
            if (ad < 0 || g->nodes[ad].op != NN_OP_ADD) goto not_gelu;
            int other = g->nodes[ad].inputs[0] == g->nodes[e].outputs[0] ? g->nodes[ad].inputs[1] : g->nodes[ad].inputs[0];
            if (!const_scalar(g, other, &v) || v != 1.0f) goto not_gelu;
            int m1 = NEXT(ad);
            if (m1 < 0 || g->nodes[m1].op != NN_OP_MUL) goto not_gelu;
            other = g->nodes[m1].inputs[0] == g->nodes[ad].outputs[0] ? g->nodes[m1].inputs[1] : g->nodes[m1].inputs[0];
            if (other != x) goto not_gelu;
            int m2 = NEXT(m1);
            if (m2 < 0 || g->nodes[m2].op != NN_OP_MUL) goto not_gelu;
            other = g->nodes[m2].inputs[0] == g->nodes[m1].outputs[0] ? g->nodes[m2].inputs[1] : g->nodes[m2].inputs[0];
            if (!const_scalar(g, other, &v) || v != 0.5f) goto not_gelu;
            nn_node *gn = &g->nodes[m2];
            gn->op = NN_OP_GELU;
            gn->inputs[0] = x;
            gn->num_inputs = 1;
            gn->attr.gelu_tanh = 0;
            dead[k] = dead[e] = dead[ad] = dead[m1] = 1;
            continue;
        }
    not_gelu:
        /* decomposed LayerNorm, matched from its first ReduceMean */
        if (is_last_axis_mean(g, n) && NEXT(k) >= 0) {
            int x = n->inputs[0], sub = NEXT(k);
            const nn_tensor *tx = &g->tensors[x];
            int64_t C = tx->ndim ? tx->dims[tx->ndim - 1] : 1;
            nn_node *sn = &g->nodes[sub];
            if (sn->op != NN_OP_SUB || sn->inputs[0] != x || sn->inputs[1] != n->outputs[0]) goto not_ln;
            int d = sn->outputs[0];
            if (readers[d] != 2) goto not_ln;
            int pw = -1, dv = -1, two[2] = { first[d], reader[d] };
            for (int i = 0; i < 2; i++) {
                const nn_node *r = &g->nodes[two[i]];
                if (dead[two[i]] || r->inputs[0] != d) continue;
                if (r->op == NN_OP_POW) pw = two[i];
                if (r->op == NN_OP_DIV) dv = two[i];
            }
            float v;
            if (pw < 0 || dv < 0 || !const_scalar(g, g->nodes[pw].inputs[1], &v) || v != 2.0f) goto not_ln;
            int m2 = NEXT(pw);
            if (m2 < 0 || !is_last_axis_mean(g, &g->nodes[m2])) goto not_ln;
            int ad = NEXT(m2);
            if (ad < 0 || g->nodes[ad].op != NN_OP_ADD) goto not_ln;
            int eps_id = const_other(g, &g->nodes[ad], g->nodes[m2].outputs[0], 1);
            if (eps_id < 0) goto not_ln;
            float eps = ((float *)g->tensors[eps_id].data)[0];
            int sq = NEXT(ad);
            if (sq < 0 || g->nodes[sq].op != NN_OP_SQRT || NEXT(sq) != dv || g->nodes[dv].inputs[1] != g->nodes[sq].outputs[0])
                goto not_ln;
            /* optional scale and shift */
            int last = dv, gamma = -1, beta = -1;
            int mu = NEXT(dv);
            if (mu >= 0 && g->nodes[mu].op == NN_OP_MUL && (gamma = const_other(g, &g->nodes[mu], g->nodes[dv].outputs[0], C)) >= 0) {
                last = mu;
                int ab = NEXT(mu);
                if (ab >= 0 && g->nodes[ab].op == NN_OP_ADD && (beta = const_other(g, &g->nodes[ab], g->nodes[mu].outputs[0], C)) >= 0)
                    last = ab;
            }
            nn_node *ln = &g->nodes[last];
            int *in = realloc(ln->inputs, 3 * sizeof(int));
            if (!in) { free(readers); free(reader); free(first); free(dead); return pg_fail(PG_ERR_NOMEM, "out of memory fusing"); }
            ln->inputs = in;
            ln->inputs[0] = x;
            ln->inputs[1] = gamma;
            ln->inputs[2] = beta;
            ln->num_inputs = 3;
            ln->op = NN_OP_LAYER_NORM;
            ln->attr.axis = tx->ndim - 1;
            ln->attr.epsilon = eps;
            ln->attr.act = NN_ACT_NONE;
            int chain[] = { k, sub, pw, m2, ad, sq, dv, last == dv ? -1 : mu };
            for (size_t i = 0; i < sizeof chain / sizeof chain[0]; i++)
                if (chain[i] >= 0 && chain[i] != last) dead[chain[i]] = 1;
            continue;
        }
    not_ln:
        /* attention: the transpose of k is already folded into trans_b (it comes earlier) */
        if (n->op == NN_OP_MATMUL && n->attr.trans_b && n->num_inputs == 2 && n->attr.act == NN_ACT_NONE && NEXT(k) >= 0) {
            int sm = NEXT(k), m2 = -1;
            const nn_tensor *q = &g->tensors[n->inputs[0]], *kk = &g->tensors[n->inputs[1]];
            if (g->nodes[sm].op == NN_OP_SOFTMAX && g->nodes[sm].attr.axis == g->tensors[n->outputs[0]].ndim - 1) m2 = NEXT(sm);
            if (m2 >= 0 && g->nodes[m2].op == NN_OP_MATMUL && g->nodes[m2].num_inputs == 2 && !g->nodes[m2].attr.trans_b &&
                g->nodes[m2].attr.act == NN_ACT_NONE && g->nodes[m2].inputs[0] == g->nodes[sm].outputs[0]) {
                const nn_tensor *v = &g->tensors[g->nodes[m2].inputs[1]];
                int same = q->ndim >= 2 && q->ndim == kk->ndim && q->ndim == v->ndim;
                for (int i = 0; same && i < q->ndim - 2; i++) same = q->dims[i] == kk->dims[i] && q->dims[i] == v->dims[i];
                if (same) {
                    nn_node *at = &g->nodes[m2];
                    int *in = realloc(at->inputs, 3 * sizeof(int));
                    if (!in) { free(readers); free(reader); free(first); free(dead); return pg_fail(PG_ERR_NOMEM, "out of memory fusing"); }
                    at->inputs = in;
                    at->inputs[2] = at->inputs[1];
                    at->inputs[0] = n->inputs[0];
                    at->inputs[1] = n->inputs[1];
                    at->num_inputs = 3;
                    at->op = NN_OP_ATTENTION;
                    dead[k] = dead[sm] = 1;
                    continue;
                }
            }
        }
        if (n->op != NN_OP_CONV && n->op != NN_OP_CONV_TRANSPOSE && n->op != NN_OP_MATMUL && n->op != NN_OP_GEMM) continue;
        /* MatMul + bias */
        if (n->op == NN_OP_MATMUL && n->num_inputs == 2 && NEXT(k) >= 0 && n->attr.act == NN_ACT_NONE) {
            int m = NEXT(k);
            nn_node *ad = &g->nodes[m];
            const nn_tensor *y = &g->tensors[n->outputs[0]];
            if (ad->op == NN_OP_ADD && ad->attr.act == NN_ACT_NONE && y->ndim >= 2) {
                int bias = ad->inputs[0] == n->outputs[0] ? ad->inputs[1] : ad->inputs[0];
                const nn_tensor *b = &g->tensors[bias];
                int64_t cols = y->dims[y->ndim - 1];
                int fits = b->data && b->dtype == NN_F32 && nn_shape_count(b->ndim, b->dims) == cols && b->ndim <= y->ndim &&
                           ad->inputs[0] != ad->inputs[1];
                if (fits) {
                    int *in = realloc(n->inputs, 3 * sizeof(int));
                    if (!in) { free(readers); free(reader); free(first); free(dead); return pg_fail(PG_ERR_NOMEM, "out of memory fusing"); }
                    n->inputs = in;
                    n->inputs[2] = bias;
                    n->num_inputs = 3;
                    n->outputs[0] = ad->outputs[0];
                    dead[m] = 1;
                }
            }
        }
        /* + Relu */
        if (NEXT(k) >= 0 && n->attr.act == NN_ACT_NONE && g->nodes[NEXT(k)].op == NN_OP_RELU) {
            int m = NEXT(k);
            n->attr.act = NN_ACT_RELU;
            n->outputs[0] = g->nodes[m].outputs[0];
            dead[m] = 1;
        }
    }
    #undef NEXT
    int kept = 0;
    for (int k = 0; k < N; k++) {
        if (dead[k]) { free(g->nodes[k].name); free(g->nodes[k].inputs); continue; }
        g->nodes[kept++] = g->nodes[k];
    }
    g->num_nodes = kept;
    for (int t = 0; t < T; t++) g->tensors[t].producer = -1;
    for (int k = 0; k < kept; k++)
        for (int o = 0; o < g->nodes[k].num_outputs; o++) g->tensors[g->nodes[k].outputs[o]].producer = k;
    free(readers); free(reader); free(first); free(dead);
    return PG_OK;
}

pg_status nn_graph_prepare(nn_graph *g)
{
    if (g->prepared) return PG_OK;
    if (g->num_outputs < 1) return pg_fail(PG_ERR_FORMAT, "graph has no outputs");
    PG_TRY(link_tensors(g));
    PG_TRY(sort_nodes(g));
    for (int k = 0; k < g->num_nodes; k++) PG_TRY(nn_node_infer(g, k));
    PG_TRY(fold_constants(g));
    PG_TRY(fuse_nodes(g));
    g->const_bytes = 0;
    for (int t = 0; t < g->num_tensors; t++) {
        nn_tensor *x = &g->tensors[t];
        if (x->data) g->const_bytes += (size_t)nn_shape_count(x->ndim, x->dims) * (x->dtype == NN_F32 ? 4 : 8);
    }
    PG_TRY(plan_memory(g));
    g->scratch_floats = 0;
    for (int k = 0; k < g->num_nodes; k++) {
        const nn_op_info *info = &nn_ops[g->nodes[k].op];
        if (info->scratch) {
            size_t s = info->scratch(g, &g->nodes[k]);
            if (s > g->scratch_floats) g->scratch_floats = s;
        }
    }
    /* working memory for as many threads as there are cores (nn_graph_run checks again for more) */
    size_t procs = (size_t)omp_get_num_procs();
    if (g->scratch_floats > NN_MAX_WORK_BYTES / 4 / procs || g->arena_floats > NN_MAX_WORK_BYTES / 4 ||
        (g->arena_floats + g->scratch_floats * procs) * 4 > NN_MAX_WORK_BYTES)
        return pg_fail(PG_ERR_SIZE, "the model needs more than %zu MiB of working memory (activations %zu MiB, scratch %zu MiB per thread)",
                       NN_MAX_WORK_BYTES >> 20, g->arena_floats >> 18, g->scratch_floats >> 18);
    g->arena_block = calloc(g->arena_floats + NN_ALIGN + 16, sizeof(float));
    if (!g->arena_block)
        return pg_fail(PG_ERR_NOMEM, "out of memory for a %zu MiB activation arena", g->arena_floats * 4 >> 20);
    g->arena = (float *)(((uintptr_t)g->arena_block + 63) & ~(uintptr_t)63);
    g->prepared = 1;
    return PG_OK;
}

pg_status nn_graph_run(nn_graph *g, int threads)
{
    if (!g->prepared) return pg_fail(PG_ERR_INTERNAL, "nn_graph_run before nn_graph_prepare");
    if (threads <= 0) threads = omp_get_num_procs();
    if (g->scratch_floats && g->scratch_threads < threads) {
        free(g->scratch);
        g->scratch_threads = 0;
        size_t bytes;
        if (pg_size_mul(g->scratch_floats * sizeof(float), (size_t)threads, &bytes) || bytes > NN_MAX_WORK_BYTES)
            return pg_fail(PG_ERR_SIZE, "%d threads need more than %zu MiB of scratch", threads, NN_MAX_WORK_BYTES >> 20);
        g->scratch = aligned_alloc(64, (bytes + 63) / 64 * 64);
        if (!g->scratch) return pg_fail(PG_ERR_NOMEM, "out of memory for %zu MiB of scratch", bytes >> 20);
        g->scratch_threads = threads;
    }
    /* OpenMP threads split the work; OpenBLAS runs single-threaded inside them (both restored).
     * OpenBLAS's thread count is process-wide: graphs run side by side in a parallel region would
     * race saving and restoring it (one net's later products ran on 2 BLAS threads, its output
     * off by a float16 step), so there the caller sets it once around the region. */
    int nested = omp_in_parallel();
    int saved = omp_get_max_threads(), saved_blas = nested ? 1 : openblas_get_num_threads();
    omp_set_num_threads(threads);
    if (!nested) openblas_set_num_threads(1);
    nn_ctx c = { g, g->scratch, g->scratch_floats };
    for (int k = 0; k < g->num_nodes; k++) {
        double t0 = g->profile_ms ? omp_get_wtime() : 0;
        nn_ops[g->nodes[k].op].run(&c, &g->nodes[k]);
        if (g->profile_ms) g->profile_ms[g->nodes[k].op] += (omp_get_wtime() - t0) * 1e3;
    }
    omp_set_num_threads(saved);
    if (!nested) openblas_set_num_threads(saved_blas);
    return PG_OK;
}
