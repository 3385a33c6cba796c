/* ops_norm.c - LayerNormalization, Softmax and ReduceMean. Sums run in double so results do not
 * depend on the thread split and stay within 1e-6 of torch on rows of a few thousand. */
#include "nn/nn_ops.h"

#include <math.h>

pg_status nn_infer_layer_norm(nn_graph *g, nn_node *n)
{
    nn_tensor *x = nn_in(g, n, 0);
    int axis = nn_axis(n->attr.axis, x->ndim);
    if (axis < 0) return nn_node_fail(n, "axis %d out of range for %d dims", n->attr.axis, x->ndim);
    n->attr.axis = axis;
    int64_t inner = nn_shape_count(x->ndim - axis, x->dims + axis);
    for (int i = 1; i <= 2; i++) {
        nn_tensor *p = nn_in(g, n, i);
        if (p && nn_shape_count(p->ndim, p->dims) != inner && nn_shape_count(p->ndim, p->dims) != 1)
            return nn_node_fail(n, "'%s' has %lld values for a normalised size of %lld", p->name,
                                (long long)nn_shape_count(p->ndim, p->dims), (long long)inner);
    }
    return nn_set_output(g, n, 0, x->ndim, x->dims);
}

void nn_run_layer_norm(const nn_ctx *c, const nn_node *n)
{
    const nn_tensor *tx = nn_in(c->g, n, 0), *ts = nn_in(c->g, n, 1), *tb = nn_in(c->g, n, 2);
    const float *x = nn_in_data(c, n, 0), *scale = nn_in_data(c, n, 1), *bias = nn_in_data(c, n, 2);
    float *y = nn_out_data(c, n, 0);
    int64_t inner = nn_shape_count(tx->ndim - n->attr.axis, tx->dims + n->attr.axis);
    int64_t rows = nn_shape_count(n->attr.axis, tx->dims);
    int s1 = ts && nn_shape_count(ts->ndim, ts->dims) == 1, b1 = tb && nn_shape_count(tb->ndim, tb->dims) == 1;
    float eps = n->attr.epsilon;
    #pragma omp parallel for schedule(static) if (rows * inner >= NN_PAR_MEMORY / 4)
    for (int64_t r = 0; r < rows; r++) {
        const float *xr = x + r * inner;
        float *yr = y + r * inner;
        double sum = 0, sq = 0;
        for (int64_t i = 0; i < inner; i++) sum += xr[i];
        double mean = sum / (double)inner;
        for (int64_t i = 0; i < inner; i++) { double d = xr[i] - mean; sq += d * d; }
        float rstd = (float)(1.0 / sqrt(sq / (double)inner + eps)), m = (float)mean;
        for (int64_t i = 0; i < inner; i++) {
            float v = (xr[i] - m) * rstd;
            if (scale) v *= scale[s1 ? 0 : i];
            if (bias) v += bias[b1 ? 0 : i];
            yr[i] = v;
        }
    }
}

pg_status nn_infer_softmax(nn_graph *g, nn_node *n)
{
    nn_tensor *x = nn_in(g, n, 0);
    int axis = nn_axis(n->attr.axis, x->ndim);
    if (axis < 0) return nn_node_fail(n, "axis %d out of range for %d dims", n->attr.axis, x->ndim);
    n->attr.axis = axis;
    return nn_set_output(g, n, 0, x->ndim, x->dims);
}

void nn_run_softmax(const nn_ctx *c, const nn_node *n)
{
    const nn_tensor *tx = nn_in(c->g, n, 0);
    const float *x = nn_in_data(c, n, 0);
    float *y = nn_out_data(c, n, 0);
    int axis = n->attr.axis;
    int64_t outer = nn_shape_count(axis, tx->dims), len = tx->dims[axis];
    int64_t inner = nn_shape_count(tx->ndim - axis - 1, tx->dims + axis + 1);
    if (inner == 1) {
        /* rows contiguous: vectorised max, exp and scale */
        #pragma omp parallel for schedule(static) if (outer * len >= NN_PAR_COMPUTE)
        for (int64_t o = 0; o < outer; o++) {
            const float *xr = x + o * len;
            float *yr = y + o * len;
            float mx = -INFINITY;
            for (int64_t i = 0; i < len; i++) mx = xr[i] > mx ? xr[i] : mx;
            for (int64_t i = 0; i < len; i++) yr[i] = nn_exp(xr[i] - mx);
            float inv = 1.0f / nn_sum(yr, len);
            for (int64_t i = 0; i < len; i++) yr[i] *= inv;
        }
        return;
    }
    #pragma omp parallel for schedule(static) if (outer * len * inner >= NN_PAR_COMPUTE)
    for (int64_t r = 0; r < outer * inner; r++) {
        int64_t o = r / inner, in = r % inner;
        const float *xr = x + o * len * inner + in;
        float *yr = y + o * len * inner + in;
        float mx = -INFINITY;
        for (int64_t i = 0; i < len; i++) mx = xr[i * inner] > mx ? xr[i * inner] : mx;
        double sum = 0;
        for (int64_t i = 0; i < len; i++) { float e = nn_exp(xr[i * inner] - mx); yr[i * inner] = e; sum += e; }
        float inv = (float)(1.0 / sum);
        for (int64_t i = 0; i < len; i++) yr[i * inner] *= inv;
    }
}

pg_status nn_infer_reduce_mean(nn_graph *g, nn_node *n)
{
    nn_tensor *x = nn_in(g, n, 0);
    int reduce[NN_MAX_DIMS] = { 0 };
    if (n->attr.num_axes == 0) for (int i = 0; i < x->ndim; i++) reduce[i] = 1; /* ONNX: no axes = all */
    for (int i = 0; i < n->attr.num_axes; i++) {
        int a = nn_axis(n->attr.axes[i], x->ndim);
        if (a < 0) return nn_node_fail(n, "axis %lld out of range", (long long)n->attr.axes[i]);
        reduce[a] = 1;
    }
    n->attr.num_axes = 0;
    for (int i = 0; i < x->ndim; i++) if (reduce[i]) n->attr.axes[n->attr.num_axes++] = i;
    int64_t dims[NN_MAX_DIMS];
    int nd = 0;
    for (int i = 0; i < x->ndim; i++) {
        if (!reduce[i]) dims[nd++] = x->dims[i];
        else if (n->attr.keepdims) dims[nd++] = 1;
    }
    return nn_set_output(g, n, 0, nd, dims);
}

void nn_run_reduce_mean(const nn_ctx *c, const nn_node *n)
{
    const nn_tensor *tx = nn_in(c->g, n, 0), *ty = nn_out(c->g, n, 0);
    const float *x = nn_in_data(c, n, 0);
    float *y = nn_out_data(c, n, 0);
    int reduce[NN_MAX_DIMS] = { 0 };
    for (int i = 0; i < n->attr.num_axes; i++) reduce[n->attr.axes[i]] = 1;
    int64_t out_count = nn_shape_count(ty->ndim, ty->dims), red = 1;
    for (int i = 0; i < tx->ndim; i++) if (reduce[i]) red *= tx->dims[i];
    /* reduced axes the trailing ones (LayerNorm decomposed): contiguous rows */
    int trailing = n->attr.num_axes > 0;
    for (int i = 0; i < n->attr.num_axes; i++) trailing &= n->attr.axes[i] == tx->ndim - n->attr.num_axes + i;
    if (trailing) {
        #pragma omp parallel for schedule(static) if (out_count * red >= NN_PAR_MEMORY)
        for (int64_t o = 0; o < out_count; o++) {
            const float *xr = x + o * red;
            double sum = 0;
            for (int64_t r = 0; r < red; r++) sum += xr[r];
            y[o] = red ? (float)(sum / (double)red) : 0.0f;
        }
        return;
    }
    /* strides of x */
    int64_t stride[NN_MAX_DIMS], acc = 1;
    for (int i = tx->ndim - 1; i >= 0; i--) { stride[i] = acc; acc *= tx->dims[i]; }
    #pragma omp parallel for schedule(static) if (out_count * red >= NN_PAR_COMPUTE)
    for (int64_t o = 0; o < out_count; o++) {
        /* base offset from the kept dims of o */
        int64_t rem = o, base = 0;
        for (int i = tx->ndim - 1; i >= 0; i--) {
            if (reduce[i]) continue;
            base += (rem % tx->dims[i]) * stride[i];
            rem /= tx->dims[i];
        }
        double sum = 0;
        for (int64_t r = 0; r < red; r++) {
            int64_t rr = r, off = base;
            for (int i = tx->ndim - 1; i >= 0; i--) {
                if (!reduce[i]) continue;
                off += (rr % tx->dims[i]) * stride[i];
                rr /= tx->dims[i];
            }
            sum += x[off];
        }
        y[o] = red ? (float)(sum / (double)red) : 0.0f;
    }
}
