/* ops_shape.c - data movement: Reshape/Identity (copy), Transpose, Slice, Expand (one strided
 * gather each), Concat, Gather (constant indices), Pad. */
#include "nn/nn_ops.h"

#include <string.h>

/* y (out dims) [o] = x[base + sum idx_d * stride[d]] with one row per outer index; strides may be
 * 0 (broadcast) or negative (reverse slice). */
static void strided_copy(float *y, int nd, const int64_t *dims, const float *x, int64_t base, const int64_t *stride)
{
    if (nd == 0) { y[0] = x[base]; return; }
    int64_t len = dims[nd - 1], outer = nn_shape_count(nd - 1, dims), s_last = stride[nd - 1];
    #pragma omp parallel for schedule(static) if (outer * len >= NN_PAR_MEMORY)
    for (int64_t o = 0; o < outer; o++) {
        int64_t rem = o, off = base;
        for (int d = nd - 2; d >= 0; d--) { off += (rem % dims[d]) * stride[d]; rem /= dims[d]; }
        float *yr = y + o * len;
        const float *xr = x + off;
        if (s_last == 1) memcpy(yr, xr, (size_t)len * sizeof(float));
        else for (int64_t i = 0; i < len; i++) yr[i] = xr[i * s_last];
    }
}

static void contiguous_strides(int nd, const int64_t *dims, int64_t *stride)
{
    int64_t acc = 1;
    for (int i = nd - 1; i >= 0; i--) { stride[i] = acc; acc *= dims[i]; }
}

pg_status nn_infer_reshape(nn_graph *g, nn_node *n)
{
    nn_tensor *x = nn_in(g, n, 0);
    nn_attrs *a = &n->attr;
    if (a->num_shape < 0 || a->num_shape > NN_MAX_DIMS) return nn_node_fail(n, "target has %d dims", a->num_shape);
    int64_t dims[NN_MAX_DIMS], known = 1;
    int minus = -1;
    for (int i = 0; i < a->num_shape; i++) {
        int64_t d = a->shape[i];
        if (d == 0) {
            if (i >= x->ndim) return nn_node_fail(n, "0 in the target copies dim %d the input lacks", i);
            d = x->dims[i];
        }
        if (d == -1) {
            if (minus >= 0) return nn_node_fail(n, "more than one -1 in the target shape");
            minus = i;
            dims[i] = 1;
            continue;
        }
        if (d < 0 || d > NN_MAX_DIM) return nn_node_fail(n, "target dim %d is %lld", i, (long long)d);
        dims[i] = d;
        known *= d;
        if (known > NN_MAX_ELEMENTS) return nn_node_fail(n, "target shape too large");
    }
    int64_t count = nn_shape_count(x->ndim, x->dims);
    if (minus >= 0) {
        if (known == 0 || count % known) return nn_node_fail(n, "cannot infer -1: %lld elements into %lld", (long long)count, (long long)known);
        dims[minus] = count / known;
    }
    if (nn_shape_count(a->num_shape, dims) != count)
        return nn_node_fail(n, "%lld elements cannot take the target shape", (long long)count);
    for (int i = 0; i < a->num_shape; i++) a->shape[i] = dims[i];
    return nn_set_output(g, n, 0, a->num_shape, dims);
}

void nn_run_reshape(const nn_ctx *c, const nn_node *n)
{
    const nn_tensor *tx = nn_in(c->g, n, 0);
    const float *x = nn_in_data(c, n, 0);
    float *y = nn_out_data(c, n, 0);
    if (x != y) memcpy(y, x, (size_t)nn_shape_count(tx->ndim, tx->dims) * sizeof(float));
}

pg_status nn_infer_transpose(nn_graph *g, nn_node *n)
{
    nn_tensor *x = nn_in(g, n, 0);
    nn_attrs *a = &n->attr;
    if (a->num_perm == 0) {
        a->num_perm = x->ndim;
        for (int i = 0; i < x->ndim; i++) a->perm[i] = x->ndim - 1 - i;
    }
    if (a->num_perm != x->ndim) return nn_node_fail(n, "perm has %d entries for %d dims", a->num_perm, x->ndim);
    int seen[NN_MAX_DIMS] = { 0 };
    int64_t dims[NN_MAX_DIMS];
    for (int i = 0; i < x->ndim; i++) {
        if (a->perm[i] < 0 || a->perm[i] >= x->ndim || seen[a->perm[i]]) return nn_node_fail(n, "perm is not a permutation");
        seen[a->perm[i]] = 1;
        dims[i] = x->dims[a->perm[i]];
    }
    return nn_set_output(g, n, 0, x->ndim, dims);
}

void nn_run_transpose(const nn_ctx *c, const nn_node *n)
{
    const nn_tensor *tx = nn_in(c->g, n, 0), *ty = nn_out(c->g, n, 0);
    int64_t sx[NN_MAX_DIMS], st[NN_MAX_DIMS];
    contiguous_strides(tx->ndim, tx->dims, sx);
    for (int i = 0; i < tx->ndim; i++) st[i] = sx[n->attr.perm[i]];
    strided_copy(nn_out_data(c, n, 0), ty->ndim, ty->dims, nn_in_data(c, n, 0), 0, st);
}

/* Normalises slice parameters to one entry per dim: axes[i] = i, starts clamped, steps. */
pg_status nn_infer_slice(nn_graph *g, nn_node *n)
{
    nn_tensor *x = nn_in(g, n, 0);
    nn_attrs *a = &n->attr;
    int64_t start[NN_MAX_DIMS], end[NN_MAX_DIMS], step[NN_MAX_DIMS], dims[NN_MAX_DIMS];
    int set[NN_MAX_DIMS] = { 0 };
    for (int i = 0; i < x->ndim; i++) { start[i] = 0; end[i] = x->dims[i]; step[i] = 1; }
    if (a->num_axes < 0 || a->num_axes > NN_MAX_DIMS) return nn_node_fail(n, "%d axes", a->num_axes);
    for (int k = 0; k < a->num_axes; k++) {
        int ax = nn_axis(a->axes[k], x->ndim);
        if (ax < 0 || set[ax]) return nn_node_fail(n, "axis %lld out of range or repeated", (long long)a->axes[k]);
        set[ax] = 1;
        int64_t d = x->dims[ax], s = a->starts[k], e = a->ends[k], p = a->steps[k];
        if (p == 0) return nn_node_fail(n, "step 0");
        p = p > d + 1 ? d + 1 : p < -d - 1 ? -d - 1 : p; /* a longer step takes one element; keeps the sums in range */
        if (s < 0) s += d;
        if (e < 0) e += d;
        if (p > 0) {
            s = s < 0 ? 0 : s > d ? d : s;
            e = e < 0 ? 0 : e > d ? d : e;
        } else {
            s = s < 0 ? 0 : s > d - 1 ? d - 1 : s;  /* negative steps: start in [0, d-1], end in [-1, d-1] */
            e = e < -1 ? -1 : e > d - 1 ? d - 1 : e;
        }
        start[ax] = s; end[ax] = e; step[ax] = p;
    }
    for (int i = 0; i < x->ndim; i++) {
        int64_t len = step[i] > 0 ? (end[i] - start[i] + step[i] - 1) / step[i] : (start[i] - end[i] - step[i] - 1) / -step[i];
        dims[i] = len > 0 ? len : 0;
        a->axes[i] = i; a->starts[i] = start[i]; a->ends[i] = end[i]; a->steps[i] = step[i];
    }
    a->num_axes = x->ndim;
    return nn_set_output(g, n, 0, x->ndim, dims);
}

void nn_run_slice(const nn_ctx *c, const nn_node *n)
{
    const nn_tensor *tx = nn_in(c->g, n, 0), *ty = nn_out(c->g, n, 0);
    if (nn_shape_count(ty->ndim, ty->dims) == 0) return;
    int64_t sx[NN_MAX_DIMS], st[NN_MAX_DIMS], base = 0;
    contiguous_strides(tx->ndim, tx->dims, sx);
    for (int i = 0; i < tx->ndim; i++) { st[i] = sx[i] * n->attr.steps[i]; base += n->attr.starts[i] * sx[i]; }
    strided_copy(nn_out_data(c, n, 0), ty->ndim, ty->dims, nn_in_data(c, n, 0), base, st);
}

pg_status nn_infer_concat(nn_graph *g, nn_node *n)
{
    nn_tensor *x = nn_in(g, n, 0);
    int axis = nn_axis(n->attr.axis, x->ndim);
    if (axis < 0) return nn_node_fail(n, "axis %d out of range", n->attr.axis);
    n->attr.axis = axis;
    int64_t dims[NN_MAX_DIMS];
    memcpy(dims, x->dims, sizeof dims);
    dims[axis] = 0;
    for (int i = 0; i < n->num_inputs; i++) {
        nn_tensor *t = nn_in(g, n, i);
        if (!t) return nn_node_fail(n, "input %d missing", i);
        if (t->ndim != x->ndim) return nn_node_fail(n, "inputs differ in rank");
        for (int d = 0; d < x->ndim; d++)
            if (d != axis && t->dims[d] != x->dims[d]) return nn_node_fail(n, "'%s' differs in dim %d", t->name, d);
        dims[axis] += t->dims[axis];
        if (dims[axis] > NN_MAX_DIM) return nn_node_fail(n, "concatenated dim too large");
    }
    return nn_set_output(g, n, 0, x->ndim, dims);
}

void nn_run_concat(const nn_ctx *c, const nn_node *n)
{
    const nn_tensor *ty = nn_out(c->g, n, 0);
    float *y = nn_out_data(c, n, 0);
    int axis = n->attr.axis;
    int64_t outer = nn_shape_count(axis, ty->dims), inner = nn_shape_count(ty->ndim - axis - 1, ty->dims + axis + 1);
    int64_t row = ty->dims[axis] * inner, at = 0;
    for (int i = 0; i < n->num_inputs; i++) {
        const nn_tensor *t = nn_in(c->g, n, i);
        const float *x = nn_in_data(c, n, i);
        int64_t chunk = t->dims[axis] * inner;
        #pragma omp parallel for schedule(static) if (outer * chunk >= NN_PAR_MEMORY)
        for (int64_t o = 0; o < outer; o++) memcpy(y + o * row + at, x + o * chunk, (size_t)chunk * sizeof(float));
        at += chunk;
    }
}

/* A float index as int64 without undefined behaviour (NaN and huge values fall out of range). */
static int64_t index_of(float v) { return v == v && v > -1e18f && v < 1e18f ? (int64_t)v : INT64_MAX; }

pg_status nn_infer_gather(nn_graph *g, nn_node *n)
{
    nn_tensor *x = nn_in(g, n, 0), *idx = nn_in(g, n, 1);
    if (!idx || !idx->data) return nn_node_fail(n, "indices must be a constant");
    int axis = nn_axis(n->attr.axis, x->ndim);
    if (axis < 0) return nn_node_fail(n, "axis %d out of range", n->attr.axis);
    n->attr.axis = axis;
    if (x->ndim - 1 + idx->ndim > NN_MAX_DIMS) return nn_node_fail(n, "output has too many dims");
    int64_t count = nn_shape_count(idx->ndim, idx->dims);
    for (int64_t i = 0; i < count; i++) {
        int64_t v = idx->dtype == NN_I64 ? ((int64_t *)idx->data)[i] : index_of(((float *)idx->data)[i]);
        if (v < -x->dims[axis] || v >= x->dims[axis]) return nn_node_fail(n, "index %lld out of range", (long long)v);
    }
    int64_t dims[NN_MAX_DIMS];
    int nd = 0;
    for (int i = 0; i < axis; i++) dims[nd++] = x->dims[i];
    for (int i = 0; i < idx->ndim; i++) dims[nd++] = idx->dims[i];
    for (int i = axis + 1; i < x->ndim; i++) dims[nd++] = x->dims[i];
    return nn_set_output(g, n, 0, nd, dims);
}

void nn_run_gather(const nn_ctx *c, const nn_node *n)
{
    const nn_tensor *tx = nn_in(c->g, n, 0), *ti = nn_in(c->g, n, 1);
    const float *x = nn_in_data(c, n, 0);
    float *y = nn_out_data(c, n, 0);
    int axis = n->attr.axis;
    int64_t outer = nn_shape_count(axis, tx->dims), inner = nn_shape_count(tx->ndim - axis - 1, tx->dims + axis + 1);
    int64_t d = tx->dims[axis], count = nn_shape_count(ti->ndim, ti->dims);
    for (int64_t o = 0; o < outer; o++)
        for (int64_t k = 0; k < count; k++) {
            int64_t v = ti->dtype == NN_I64 ? ((int64_t *)ti->data)[k] : index_of(((float *)ti->data)[k]);
            if (v < 0) v += d;
            memcpy(y + (o * count + k) * inner, x + (o * d + v) * inner, (size_t)inner * sizeof(float));
        }
}

pg_status nn_infer_expand(nn_graph *g, nn_node *n)
{
    nn_tensor *x = nn_in(g, n, 0);
    nn_attrs *a = &n->attr;
    if (a->num_shape < 0 || a->num_shape > NN_MAX_DIMS) return nn_node_fail(n, "target has %d dims", a->num_shape);
    int nd = a->num_shape > x->ndim ? a->num_shape : x->ndim;
    int64_t dims[NN_MAX_DIMS];
    for (int i = 0; i < nd; i++) {
        int ix = i - (nd - x->ndim), is = i - (nd - a->num_shape);
        int64_t dx = ix >= 0 ? x->dims[ix] : 1, ds = is >= 0 ? a->shape[is] : 1;
        if (dx != ds && dx != 1 && ds != 1) return nn_node_fail(n, "shape does not broadcast at dim %d", i);
        dims[i] = dx == 1 ? ds : dx;
    }
    return nn_set_output(g, n, 0, nd, dims);
}

void nn_run_expand(const nn_ctx *c, const nn_node *n)
{
    const nn_tensor *tx = nn_in(c->g, n, 0), *ty = nn_out(c->g, n, 0);
    int64_t sx[NN_MAX_DIMS], st[NN_MAX_DIMS];
    contiguous_strides(tx->ndim, tx->dims, sx);
    for (int i = 0; i < ty->ndim; i++) {
        int ix = i - (ty->ndim - tx->ndim);
        st[i] = ix >= 0 && tx->dims[ix] != 1 ? sx[ix] : 0;
    }
    if (nn_shape_count(ty->ndim, ty->dims) == 0) return;
    strided_copy(nn_out_data(c, n, 0), ty->ndim, ty->dims, nn_in_data(c, n, 0), 0, st);
}

pg_status nn_infer_pad(nn_graph *g, nn_node *n)
{
    nn_tensor *x = nn_in(g, n, 0);
    int64_t dims[NN_MAX_DIMS];
    for (int i = 0; i < x->ndim; i++) {
        int64_t b = n->attr.pad_amounts[i], e = n->attr.pad_amounts[x->ndim + i];
        if (b < 0 || e < 0 || b > NN_MAX_DIM || e > NN_MAX_DIM) return nn_node_fail(n, "pads of dim %d are %lld, %lld", i, (long long)b, (long long)e);
        if (n->attr.pad_mode == NN_PAD_REFLECT && (b >= x->dims[i] || e >= x->dims[i]))
            return nn_node_fail(n, "reflect pad wider than dim %d", i);
        if (n->attr.pad_mode == NN_PAD_EDGE && x->dims[i] == 0 && (b || e)) return nn_node_fail(n, "edge pad of an empty dim");
        dims[i] = x->dims[i] + b + e;
    }
    return nn_set_output(g, n, 0, x->ndim, dims);
}

/* Source index along one axis for output index o (pads b in front), or -1 for the constant. */
static int64_t pad_source(int64_t o, int64_t b, int64_t len, nn_pad_mode mode)
{
    int64_t i = o - b;
    if (i >= 0 && i < len) return i;
    if (mode == NN_PAD_CONSTANT) return -1;
    if (mode == NN_PAD_EDGE) return i < 0 ? 0 : len - 1;
    return i < 0 ? -i : 2 * (len - 1) - i; /* reflect: prepare checked the pads are < len */
}

/* One output row (the last axis) at a time: the source row of the outer indices (or the constant),
 * then the row itself with its ends padded. */
void nn_run_pad(const nn_ctx *c, const nn_node *n)
{
    const nn_tensor *tx = nn_in(c->g, n, 0), *ty = nn_out(c->g, n, 0);
    const float *x = nn_in_data(c, n, 0);
    float *y = nn_out_data(c, n, 0);
    const nn_attrs *a = &n->attr;
    int nd = tx->ndim;
    if (nd == 0) { y[0] = x[0]; return; }
    int64_t sx[NN_MAX_DIMS];
    contiguous_strides(nd, tx->dims, sx);
    int64_t len = ty->dims[nd - 1], in_len = tx->dims[nd - 1], b = a->pad_amounts[nd - 1];
    int64_t rows = nn_shape_count(nd - 1, ty->dims);
    if (len == 0) return;
    #pragma omp parallel for schedule(static) if (rows * len >= NN_PAR_MEMORY)
    for (int64_t r = 0; r < rows; r++) {
        float *yr = y + r * len;
        int64_t rem = r, off = 0;
        int inside = 1;
        for (int d = nd - 2; d >= 0; d--) {
            int64_t i = pad_source(rem % ty->dims[d], a->pad_amounts[d], tx->dims[d], a->pad_mode);
            rem /= ty->dims[d];
            if (i < 0) { inside = 0; break; }
            off += i * sx[d];
        }
        if (!inside || in_len == 0) {
            for (int64_t i = 0; i < len; i++) yr[i] = a->pad_value;
            continue;
        }
        const float *xr = x + off;
        for (int64_t i = 0; i < b && i < len; i++) {
            int64_t j = pad_source(i, b, in_len, a->pad_mode);
            yr[i] = j < 0 ? a->pad_value : xr[j];
        }
        int64_t copy = in_len < len - b ? in_len : len - b;
        if (copy > 0) memcpy(yr + b, xr, (size_t)copy * sizeof(float));
        for (int64_t i = b + in_len; i < len; i++) {
            int64_t j = pad_source(i, b, in_len, a->pad_mode);
            yr[i] = j < 0 ? a->pad_value : xr[j];
        }
    }
}
