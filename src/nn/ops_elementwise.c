/* ops_elementwise.c - binary ops with numpy broadcasting (Add Sub Mul Div Pow Max Min), unary ops
 * and activations (Sqrt Erf Exp Tanh Neg Relu LeakyRelu Sigmoid Gelu), fused activations. */
#include "nn/nn_ops.h"

#include <stdint.h>

#include <math.h>
#include <string.h>

void nn_apply_act(float *x, size_t n, nn_activation act, float alpha)
{
    switch (act) {
    case NN_ACT_NONE: break;
    case NN_ACT_RELU: for (size_t i = 0; i < n; i++) x[i] = x[i] > 0 ? x[i] : 0; break;
    case NN_ACT_RELU6: for (size_t i = 0; i < n; i++) x[i] = x[i] > 0 ? (x[i] < 6 ? x[i] : 6) : 0; break;
    case NN_ACT_LEAKY_RELU: for (size_t i = 0; i < n; i++) x[i] = x[i] >= 0 ? x[i] : alpha * x[i]; break;
    }
}

pg_status nn_infer_binary(nn_graph *g, nn_node *n)
{
    nn_tensor *a = nn_in(g, n, 0), *b = nn_in(g, n, 1);
    if (!b) return nn_node_fail(n, "second input missing");
    int nd = a->ndim > b->ndim ? a->ndim : b->ndim;
    int64_t dims[NN_MAX_DIMS];
    for (int i = 0; i < nd; i++) {
        int ia = i - (nd - a->ndim), ib = i - (nd - b->ndim);
        int64_t da = ia >= 0 ? a->dims[ia] : 1, db = ib >= 0 ? b->dims[ib] : 1;
        if (da != db && da != 1 && db != 1)
            return nn_node_fail(n, "shapes of '%s' and '%s' do not broadcast (dim %d: %lld vs %lld)", a->name, b->name, i,
                                (long long)da, (long long)db);
        dims[i] = da == 1 ? db : da;
    }
    return nn_set_output(g, n, 0, nd, dims);
}

static inline float binary_one(nn_op op, float x, float y)
{
    switch (op) {
    case NN_OP_ADD: return x + y;
    case NN_OP_SUB: return x - y;
    case NN_OP_MUL: return x * y;
    case NN_OP_DIV: return x / y;
    case NN_OP_POW: return y == 2.0f ? x * x : y == 0.5f ? sqrtf(x) : powf(x, y);
    case NN_OP_MAXIMUM: return x > y ? x : y;
    case NN_OP_MINIMUM: return x < y ? x : y;
    default: return 0;
    }
}

/* y[i] = x[i * sx] op z[i * sz] for i < len; the switch sits outside the loops so they vectorise. */
static void binary_row(nn_op op, float *y, const float *x, int64_t sx, const float *z, int64_t sz, int64_t len)
{
#define ROW(expr) for (int64_t i = 0; i < len; i++) { float a = x[i * sx], b = z[i * sz]; y[i] = (expr); } break
    switch (op) {
    case NN_OP_ADD: ROW(a + b);
    case NN_OP_SUB: ROW(a - b);
    case NN_OP_MUL: ROW(a * b);
    case NN_OP_DIV: ROW(a / b);
    case NN_OP_MAXIMUM: ROW(a > b ? a : b);
    case NN_OP_MINIMUM: ROW(a < b ? a : b);
    default: ROW(binary_one(op, a, b));
    }
#undef ROW
}

void nn_run_binary(const nn_ctx *c, const nn_node *n)
{
    nn_graph *g = c->g;
    const nn_tensor *ta = nn_in(g, n, 0), *tb = nn_in(g, n, 1), *ty = nn_out(g, n, 0);
    const float *a = nn_in_data(c, n, 0), *b = nn_in_data(c, n, 1);
    float *y = nn_out_data(c, n, 0);
    int nd = ty->ndim;
    /* per output dim: size and the strides of a and b (0 where broadcast), then coalesce dims */
    int64_t size[NN_MAX_DIMS], sa[NN_MAX_DIMS], sb[NN_MAX_DIMS];
    int64_t acc_a = 1, acc_b = 1;
    for (int i = nd - 1; i >= 0; i--) {
        int ia = i - (nd - ta->ndim), ib = i - (nd - tb->ndim);
        int64_t da = ia >= 0 ? ta->dims[ia] : 1, db = ib >= 0 ? tb->dims[ib] : 1;
        size[i] = ty->dims[i];
        sa[i] = da == 1 ? 0 : acc_a;
        sb[i] = db == 1 ? 0 : acc_b;
        acc_a *= da;
        acc_b *= db;
    }
    int m = 0;
    int64_t cs[NN_MAX_DIMS], ca[NN_MAX_DIMS], cb[NN_MAX_DIMS];
    for (int i = 0; i < nd; i++) {
        if (size[i] == 1) continue;
        if (m > 0 && ca[m - 1] == sa[i] * size[i] && cb[m - 1] == sb[i] * size[i]) {
            cs[m - 1] *= size[i]; ca[m - 1] = sa[i]; cb[m - 1] = sb[i];
        } else { cs[m] = size[i]; ca[m] = sa[i]; cb[m] = sb[i]; m++; }
    }
    if (m == 0) { cs[0] = 1; ca[0] = cb[0] = 0; m = 1; }
    int64_t len = cs[m - 1], outer = 1;
    for (int i = 0; i < m - 1; i++) outer *= cs[i];
    nn_op op = n->op;
    if (outer == 1 && len >= NN_PAR_MEMORY) {
        /* one long row: split it */
        #pragma omp parallel for schedule(static)
        for (int64_t s = 0; s < len; s += 16384) {
            int64_t l = len - s < 16384 ? len - s : 16384;
            binary_row(op, y + s, a + s * ca[m - 1], ca[m - 1], b + s * cb[m - 1], cb[m - 1], l);
        }
    } else {
        #pragma omp parallel for schedule(static) if (outer * len >= NN_PAR_MEMORY)
        for (int64_t o = 0; o < outer; o++) {
            int64_t rem = o, oa = 0, ob = 0;
            for (int i = m - 2; i >= 0; i--) {
                int64_t idx = rem % cs[i];
                rem /= cs[i];
                oa += idx * ca[i];
                ob += idx * cb[i];
            }
            binary_row(op, y + o * len, a + oa, ca[m - 1], b + ob, cb[m - 1], len);
        }
    }
    nn_apply_act(y, (size_t)nn_shape_count(ty->ndim, ty->dims), n->attr.act, n->attr.act_alpha);
}

pg_status nn_infer_unary(nn_graph *g, nn_node *n)
{
    nn_tensor *x = nn_in(g, n, 0);
    return nn_set_output(g, n, 0, x->ndim, x->dims);
}

/* One chunk of a unary op; separate from the parallel loop so the pointers are plain locals and
 * the loops vectorise (nn_exp / nn_erf are arithmetic only). */
static void unary_chunk(nn_op op, float *restrict y, const float *restrict x, int64_t n, const nn_attrs *a)
{
    float alpha = a->alpha;
    switch (op) {
    case NN_OP_SQRT: for (int64_t i = 0; i < n; i++) y[i] = sqrtf(x[i]); break;
    case NN_OP_ERF: for (int64_t i = 0; i < n; i++) y[i] = nn_erf(x[i]); break;
    case NN_OP_EXP: for (int64_t i = 0; i < n; i++) y[i] = expf(x[i]); break;
    case NN_OP_TANH: for (int64_t i = 0; i < n; i++) y[i] = tanhf(x[i]); break;
    case NN_OP_NEG: for (int64_t i = 0; i < n; i++) y[i] = -x[i]; break;
    case NN_OP_ABS: for (int64_t i = 0; i < n; i++) y[i] = fabsf(x[i]); break;
    case NN_OP_RELU: for (int64_t i = 0; i < n; i++) y[i] = x[i] > 0 ? x[i] : 0; break;
    case NN_OP_LEAKY_RELU: for (int64_t i = 0; i < n; i++) y[i] = x[i] >= 0 ? x[i] : alpha * x[i]; break;
    case NN_OP_SIGMOID: for (int64_t i = 0; i < n; i++) y[i] = 1.0f / (1.0f + nn_exp(-x[i])); break;
    case NN_OP_GELU:
        if (a->gelu_tanh)
            for (int64_t i = 0; i < n; i++)
                y[i] = 0.5f * x[i] * (1.0f + tanhf(0.7978845608f * (x[i] + 0.044715f * x[i] * x[i] * x[i])));
        else
            for (int64_t i = 0; i < n; i++) y[i] = 0.5f * x[i] * (1.0f + nn_erf(x[i] * 0.70710678118654752f));
        break;
    default: break;
    }
}

void nn_run_unary(const nn_ctx *c, const nn_node *n)
{
    const nn_tensor *tx = nn_in(c->g, n, 0);
    const float *x = nn_in_data(c, n, 0);
    float *y = nn_out_data(c, n, 0);
    int64_t count = nn_shape_count(tx->ndim, tx->dims);
    nn_op op = n->op;
    int heavy = op == NN_OP_ERF || op == NN_OP_EXP || op == NN_OP_TANH || op == NN_OP_SIGMOID || op == NN_OP_GELU || op == NN_OP_SQRT;
    #pragma omp parallel for schedule(static) if (count >= (heavy ? NN_PAR_COMPUTE : NN_PAR_MEMORY))
    for (int64_t s = 0; s < count; s += 4096)
        unary_chunk(op, y + s, x + s, count - s < 4096 ? count - s : 4096, &n->attr);
}

pg_status nn_infer_requantize(nn_graph *g, nn_node *n)
{
    nn_tensor *x = nn_in(g, n, 0), *m = nn_in(g, n, 1);
    if (m && (!m->data || m->dtype != NN_I64 || x->ndim < 1 || nn_shape_count(m->ndim, m->dims) != 2 * x->dims[x->ndim - 1]))
        return nn_node_fail(n, "the multipliers must be an int64 constant of (mantissa, shift) per channel of the last axis");
    if (!(n->attr.q_min <= n->attr.q_zero_point && n->attr.q_zero_point <= n->attr.q_max))
        return nn_node_fail(n, "zero point %d outside %d..%d", n->attr.q_zero_point, n->attr.q_min, n->attr.q_max);
    return nn_set_output(g, n, 0, x->ndim, x->dims);
}

/* TFLite's MultiplyByQuantizedMultiplier: x * q / 2^31 rounded half away from zero (a
 * saturating rounding doubling high multiply), then a rounding right shift by -shift (ties
 * away from zero) or a left shift first. The two roundings are what make it differ from one
 * rounding of x * m, so it is reproduced exactly. */
static int32_t fixed_point_multiply(int32_t x, int32_t q, int shift)
{
    int left = shift > 0 ? shift : 0, right = shift > 0 ? 0 : -shift;
    int64_t xs = (int64_t)x * ((int64_t)1 << left);
    xs = xs > INT32_MAX ? INT32_MAX : xs < INT32_MIN ? INT32_MIN : xs;
    int64_t ab = xs * q;
    int32_t high = xs == INT32_MIN && q == INT32_MIN ? INT32_MAX : (int32_t)((ab + (ab >= 0 ? (1 << 30) : 1 - (1 << 30))) / ((int64_t)1 << 31));
    int32_t mask = (int32_t)(((int64_t)1 << right) - 1), rem = high & mask, threshold = (mask >> 1) + (high < 0);
    return (high >> right) + (rem > threshold);
}

/* The fixed-point rescale of one row of C channels in doubles, exactly TFLite's: high = x * q /
 * 2^31 rounded half up (floor(v + 0.5): the rounding of its doubling high multiply, ties toward
 * +inf for both signs), then high / 2^right rounded half away from zero. Every step is exact
 * while |x| stays below exact_below; a row with a larger value takes fixed_point_multiply. */
static void requantize_fixed_row(float *restrict y, const float *restrict x, const double *restrict mult, const double *restrict post,
                                 const float *restrict exact_below, const int64_t *fixed, int64_t C, float lo, float hi)
{
    int exact = 1;
    for (int64_t c = 0; c < C; c++) exact &= fabsf(x[c]) < exact_below[c];
    if (!exact) {
        for (int64_t c = 0; c < C; c++) {
            float v = x[c] < -2147483520.0f ? -2147483520.0f : x[c] > 2147483520.0f ? 2147483520.0f : x[c];
            float r = (float)fixed_point_multiply(v == v ? (int32_t)v : 0, (int32_t)fixed[2 * c], (int)fixed[2 * c + 1]);
            r = r < lo ? lo : r;
            y[c] = r > hi ? hi : r;
        }
        return;
    }
    double dlo = lo, dhi = hi;
    for (int64_t c = 0; c < C; c++) {
        double v = floor((double)x[c] * mult[c] + 0.5) * post[c];
        double r = trunc(v + (v < 0 ? -0.5 : 0.5));
        r = r < dlo ? dlo : r;
        y[c] = (float)(r > dhi ? dhi : r);
    }
}

/* The float-multiplier form: round(x * m0) half away from zero (truncf keeps it vectorisable). */
static void requantize_float_row(float *restrict y, const float *restrict x, float m0, int64_t C, float lo, float hi)
{
    for (int64_t c = 0; c < C; c++) {
        float v = x[c] * m0, t = truncf(v);
        float r = t + (fabsf(v - t) >= 0.5f ? (v < 0 ? -1.0f : 1.0f) : 0.0f);
        r = r < lo ? lo : r;
        y[c] = r > hi ? hi : r;
    }
}

size_t nn_scratch_requantize(const nn_graph *g, const nn_node *n)
{
    const nn_tensor *x = nn_in((nn_graph *)g, n, 0);
    return n->num_inputs > 1 && n->inputs[1] >= 0 && x->ndim >= 1 ? (size_t)x->dims[x->ndim - 1] * 5 : 0; /* 2 doubles + 1 float */
}

void nn_run_requantize(const nn_ctx *c, const nn_node *n)
{
    const nn_tensor *tx = nn_in(c->g, n, 0), *tm = nn_in(c->g, n, 1);
    const float *x = nn_in_data(c, n, 0);
    const int64_t *fixed = tm ? tm->data : NULL;
    float *y = nn_out_data(c, n, 0);
    int64_t count = nn_shape_count(tx->ndim, tx->dims), C = fixed ? tx->dims[tx->ndim - 1] : (count < 4096 ? count : 4096);
    if (C < 1) return;
    const nn_attrs *a = &n->attr;
    float lo = (float)(a->q_min - a->q_zero_point), hi = (float)(a->q_max - a->q_zero_point);
    /* per-channel doubles, once, in the first thread's scratch (64-byte aligned): mult = q *
     * 2^(left - 31) (exact: q has 31 bits), post = 2^-right, exact_below = 2^21 / 2^left (below
     * it x * mult, 21 integer + 31 fraction bits, and x * mult + 0.5 fit a double's 53 bits) */
    double *mult = NULL, *post = NULL;
    float *exact_below = NULL;
    if (fixed) { /* the float path has no scratch (its size is 0: c->scratch may be NULL) */
        mult = (double *)c->scratch;
        post = mult + C;
        exact_below = (float *)(post + C);
    }
    for (int64_t ch = 0; fixed && ch < C; ch++) {
        int shift = (int)fixed[2 * ch + 1], left = shift > 0 ? shift : 0;
        mult[ch] = ldexp((double)fixed[2 * ch], left - 31);
        post[ch] = ldexp(1.0, shift > 0 ? 0 : shift);
        exact_below[ch] = (float)ldexp(1.0, 21 - left);
    }
    #pragma omp parallel for schedule(static) if (count >= NN_PAR_COMPUTE)
    for (int64_t s = 0; s < count; s += C) {
        int64_t len = count - s < C ? count - s : C;
        if (fixed) requantize_fixed_row(y + s, x + s, mult, post, exact_below, fixed, len, lo, hi);
        else requantize_float_row(y + s, x + s, a->q_multiplier, len, lo, hi);
    }
}
