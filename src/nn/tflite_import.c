/* tflite_import.c - the TFLite front end: a parsed, shape-checked TFLite model (tflite.h) as
 * nodes of the graph IR (nn_graph.h), activations in NHWC.
 *
 * Weights change layout at load: CONV_2D OHWI -> OIHW (group = C / I), DEPTHWISE_CONV_2D
 * 1HWO -> OIHW with I = 1 and group = C, TRANSPOSE_CONV OHWI -> IOHW. Three rewrites keep the
 * runtime from streaming large activations more often than the model needs:
 *   - ADD of a per-channel constant right after a bias-less conv becomes the conv's bias;
 *   - MAXIMUM(x, MUL(a, x)) with a constant scalar 0 <= a <= 1 is LEAKY_RELU(x, a);
 *   - a LEAKY_RELU / RELU / RELU6 whose input is read by nothing else fuses into the conv or ADD
 *     that produced it.
 * Each applies only when the intermediate tensor has that one reader and is not a graph output,
 * so the result is the model's to float rounding (test_nn_tflite checks it against the naive
 * reference of tflite_ref.c, which runs the ops unfused). Fused activations the IR has no fused
 * form of (TANH, RELU_N1_TO_1, and any on CONCATENATION) become separate nodes.
 *
 * Integer models (int8 / uint8 activations) run on the same float kernels with integer values:
 * an integer tensor holds its stored integers minus its zero point (q - zp, exact in a float),
 * integer convs read their weights as (q_w - zp_w) and their int32 biases as they are, so a
 * conv's sums are TFLite's int32 accumulators exactly while partial sums stay below 2^24 (always
 * for up to 518 products of 8-bit values, in practice far beyond), and a REQUANTIZE node then does TFLite's rescale: times the per-channel
 * input_scale * weight_scale / output_scale, rounded half away from zero, plus the zero point,
 * clamped to the type and the fused activation's range. ADD scales each input by its scale over
 * the output's before the sum; QUANTIZE is one REQUANTIZE; DEQUANTIZE and graph outputs multiply
 * by the scale; a graph input is quantised from the real values the caller feeds. Convs and
 * integer QUANTIZE reproduce TFLite's fixed-point rescale bit for bit; ADD (a float sum instead of
 * TFLite's 2^20 fixed-point pre-scaling) and the float input's quantisation can differ only where
 * a value lies within float rounding of a rounding boundary (test_nn_tflite_int compares both
 * with two references on FastDepth). */
#include "nn/nn_graph.h"
#include "nn/tflite.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    int skip;             /* folded into another op */
    int output;           /* tensor written (may be a later op's, after fusion) */
    int bias;             /* conv bias tensor (-1 none) */
    int src;              /* a MAXIMUM rewritten as LEAKY_RELU: its data input (else -1) */
    nn_activation act;
    float alpha;
} plan_op;

typedef struct {
    const nn_tfl_model *m;
    nn_graph *g;
    const char *name;
    int *ir;              /* TFLite tensor -> IR tensor id (-1 not yet) */
    int *readers;         /* ops reading each tensor */
    int *owner;           /* the op whose (planned) output each tensor is, -1 none */
    char *is_output;      /* graph outputs */
} import_ctx;

static void dims64(const nn_tfl_tensor *t, int64_t *d)
{
    for (int i = 0; i < t->ndim; i++) d[i] = t->dims[i];
}

/* The IR id of a TFLite tensor, added on first use (constants as float, activations shaped). */
static pg_status ir_tensor(import_ctx *c, int t, int *id)
{
    if (t < 0) {
        *id = -1;
        return PG_OK;
    }
    if (c->ir[t] >= 0) {
        *id = c->ir[t];
        return PG_OK;
    }
    const nn_tfl_tensor *tt = &c->m->tensors[t];
    int64_t d[NN_TFL_MAX_DIMS];
    dims64(tt, d);
    char name[64];
    const char *nm = tt->name[0] ? tt->name : (snprintf(name, sizeof name, "tensor%d", t), name);
    if (tt->values) PG_TRY(nn_graph_add_const_f32(c->g, nm, tt->ndim, d, tt->values, id));
    else if (tt->ints) return pg_fail(PG_ERR_FORMAT, "%s: tensor '%s': integer data where the runtime needs float", c->name, nm);
    else PG_TRY(nn_graph_add_tensor(c->g, nm, NN_F32, tt->ndim, d, id));
    c->ir[t] = *id;
    return PG_OK;
}

/* A new float constant from a converted weight array (taken over). */
static pg_status add_weight(import_ctx *c, const char *base, const char *suffix, int ndim, const int64_t *dims, float *data, int *id)
{
    char name[256];
    snprintf(name, sizeof name, "%s%s", base, suffix);
    return nn_graph_add_const(c->g, name, NN_F32, ndim, dims, data, id);
}

/* The conv's weights in the IR's layout: real values, or for an integer conv (integer_op) the
 * stored integers minus the zero point. */
static pg_status conv_weights(import_ctx *c, const nn_tfl_op *op, int integer_op, int *wid)
{
    const nn_tfl_tensor *w = &c->m->tensors[op->inputs[1]];
    int a = w->dims[0], kh = w->dims[1], kw = w->dims[2], b = w->dims[3];
    float *out = pg_malloc((size_t)w->count * sizeof(float), "tflite conv weights");
    float *centred = integer_op ? pg_malloc((size_t)w->count * sizeof(float), "tflite integer weights") : NULL;
    if (!out || (integer_op && !centred)) {
        free(out);
        free(centred);
        return PG_ERR_NOMEM;
    }
    for (int64_t i = 0; integer_op && i < w->count; i++) centred[i] = (float)(w->qvalues[i] - w->zero_point);
    const float *src = integer_op ? centred : w->values;
    int64_t d[4];
    if (op->code == NN_TFL_CONV_2D) { /* OHWI -> OIHW */
        for (int o = 0; o < a; o++)
            for (int i = 0; i < kh; i++)
                for (int j = 0; j < kw; j++)
                    for (int ch = 0; ch < b; ch++)
                        out[(((size_t)o * b + ch) * kh + i) * kw + j] = src[(((size_t)o * kh + i) * kw + j) * b + ch];
        d[0] = a, d[1] = b, d[2] = kh, d[3] = kw;
    } else if (op->code == NN_TFL_DEPTHWISE_CONV_2D) { /* 1HWO -> O1HW */
        for (int i = 0; i < kh; i++)
            for (int j = 0; j < kw; j++)
                for (int o = 0; o < b; o++) out[((size_t)o * kh + i) * kw + j] = src[((size_t)i * kw + j) * b + o];
        d[0] = b, d[1] = 1, d[2] = kh, d[3] = kw;
    } else { /* TRANSPOSE_CONV: OHWI -> IOHW */
        for (int o = 0; o < a; o++)
            for (int i = 0; i < kh; i++)
                for (int j = 0; j < kw; j++)
                    for (int ch = 0; ch < b; ch++)
                        out[(((size_t)ch * a + o) * kh + i) * kw + j] = src[(((size_t)o * kh + i) * kw + j) * b + ch];
        d[0] = b, d[1] = a, d[2] = kh, d[3] = kw;
    }
    free(centred);
    return add_weight(c, w->name, integer_op ? "/ir_int" : "/ir", 4, d, out, wid);
}

static nn_activation fused(int tfl_act, int *extra)
{
    *extra = 0;
    switch (tfl_act) {
    case NN_TFL_ACT_NONE: return NN_ACT_NONE;
    case NN_TFL_ACT_RELU: return NN_ACT_RELU;
    case NN_TFL_ACT_RELU6: return NN_ACT_RELU6;
    default: *extra = tfl_act; return NN_ACT_NONE; /* TANH, RELU_N1_TO_1: separate nodes */
    }
}

static int scalar_const(const nn_tfl_tensor *t, float *v)
{
    if (!t->values || t->count != 1) return 0;
    *v = t->values[0];
    return 1;
}

/* The rewrites of the file comment, on plan[] (ops untouched). */
static void plan_fusions(import_ctx *c, plan_op *plan)
{
    const nn_tfl_model *m = c->m;
    const nn_tfl_tensor *T = m->tensors;
    for (int k = 0; k < m->num_ops; k++) {
        plan[k].output = m->ops[k].output;
        plan[k].bias = -1;
        plan[k].src = -1;
        int extra;
        plan[k].act = fused(m->ops[k].act, &extra);
        if (m->ops[k].code == NN_TFL_CONV_2D || m->ops[k].code == NN_TFL_DEPTHWISE_CONV_2D)
            plan[k].bias = m->ops[k].num_inputs > 2 ? m->ops[k].inputs[2] : -1;
        if (m->ops[k].code == NN_TFL_TRANSPOSE_CONV) plan[k].bias = m->ops[k].num_inputs > 3 ? m->ops[k].inputs[3] : -1;
    }
    /* only readers: the single-reader test below holds after the folds too, since a fold moves
     * the one read of the intermediate into the producer */
    /* an integer intermediate is rounded to its grid, so nothing folds across it */
#define SOLE(t) ((t) >= 0 && c->readers[t] == 1 && !c->is_output[t] && T[t].producer >= 0 && !nn_tfl_is_quantized(&T[t]))
    for (int k = 0; k < m->num_ops; k++) {
        const nn_tfl_op *op = &m->ops[k];
        if (op->code == NN_TFL_ADD && op->act == NN_TFL_ACT_NONE) {
            /* conv (no bias) -> ADD per-channel constant */
            for (int side = 0; side < 2; side++) {
                int y = op->inputs[side], b = op->inputs[1 - side];
                if (!SOLE(y) || !T[b].values || T[b].ndim != 1) continue;
                int p = T[y].producer;
                const nn_tfl_op *pop = &m->ops[p];
                int conv = pop->code == NN_TFL_CONV_2D || pop->code == NN_TFL_DEPTHWISE_CONV_2D || pop->code == NN_TFL_TRANSPOSE_CONV;
                if (!conv || plan[p].skip || plan[p].bias >= 0 || pop->act != NN_TFL_ACT_NONE || plan[p].output != y) continue;
                if (T[y].ndim != 4 || T[b].count != T[y].dims[3]) continue;
                plan[p].bias = b;
                plan[p].output = op->output;
                c->owner[op->output] = p;
                c->owner[y] = -1;
                plan[k].skip = 1;
                break;
            }
        }
    }
    for (int k = 0; k < m->num_ops; k++) {
        const nn_tfl_op *op = &m->ops[k];
        if (plan[k].skip || op->code != NN_TFL_MAXIMUM || op->act != NN_TFL_ACT_NONE) continue;
        /* MAXIMUM(x, MUL(a, x)) -> LEAKY_RELU(x, a) */
        for (int side = 0; side < 2; side++) {
            int x = op->inputs[side], t = op->inputs[1 - side];
            if (!SOLE(t)) continue;
            int j = T[t].producer;
            const nn_tfl_op *mul = &m->ops[j];
            float a;
            if (plan[j].skip || mul->code != NN_TFL_MUL || mul->act != NN_TFL_ACT_NONE) continue;
            int sx = mul->inputs[0] == x ? 1 : mul->inputs[1] == x ? 0 : -1;
            if (sx < 0 || !scalar_const(&T[mul->inputs[sx]], &a) || !(a >= 0 && a <= 1)) continue;
            if (T[x].count != T[op->output].count) continue;
            plan[j].skip = 1;
            plan[k].act = NN_ACT_LEAKY_RELU;
            plan[k].alpha = a;
            plan[k].src = x;
            c->readers[x]--; /* the MUL no longer reads it */
            break;
        }
    }
    for (int k = 0; k < m->num_ops; k++) {
        const nn_tfl_op *op = &m->ops[k];
        if (plan[k].skip) continue;
        nn_activation act = NN_ACT_NONE;
        float alpha = 0;
        int x = op->inputs[0];
        if (plan[k].src >= 0) {
            act = NN_ACT_LEAKY_RELU;
            alpha = plan[k].alpha;
            x = plan[k].src;
        } else if (op->code == NN_TFL_LEAKY_RELU) act = NN_ACT_LEAKY_RELU, alpha = op->alpha;
        else if (op->code == NN_TFL_RELU) act = NN_ACT_RELU;
        else if (op->code == NN_TFL_RELU6) act = NN_ACT_RELU6;
        else continue;
        if (!SOLE(x)) continue;
        int p = c->owner[x]; /* the producer, after the folds */
        if (p < 0 || plan[p].skip) continue;
        int code = m->ops[p].code;
        int ok = code == NN_TFL_CONV_2D || code == NN_TFL_DEPTHWISE_CONV_2D || code == NN_TFL_TRANSPOSE_CONV || code == NN_TFL_ADD ||
                 code == NN_TFL_SUB || code == NN_TFL_MUL;
        if (!ok || plan[p].act != NN_ACT_NONE || m->ops[p].act != NN_TFL_ACT_NONE) continue;
        plan[p].act = act;
        plan[p].alpha = alpha;
        c->owner[x] = -1;
        plan[p].output = plan[k].output;
        c->owner[plan[k].output] = p;
        plan[k].skip = 1;
    }
#undef SOLE
}

/* Appends the activation nodes TFLite fuses but the IR does not: y = act(x). */
static pg_status extra_act(import_ctx *c, const char *base, int act, int x, int y)
{
    nn_attrs a;
    nn_attrs_default(&a);
    if (act == NN_TFL_ACT_TANH) return nn_graph_add_node(c->g, NN_OP_TANH, base, &x, 1, &y, 1, &a, NULL);
    if (act == NN_TFL_ACT_RELU_N1_TO_1) {
        float lo = -1, hi = 1;
        int tlo, thi, mid;
        char name[256];
        snprintf(name, sizeof name, "%s/n1", base);
        PG_TRY(nn_graph_add_const_f32(c->g, name, 0, NULL, &lo, &tlo));
        snprintf(name, sizeof name, "%s/p1", base);
        PG_TRY(nn_graph_add_const_f32(c->g, name, 0, NULL, &hi, &thi));
        snprintf(name, sizeof name, "%s/clip", base);
        PG_TRY(nn_graph_add_tensor(c->g, name, NN_F32, -1, NULL, &mid));
        PG_TRY(nn_graph_add_node(c->g, NN_OP_MAXIMUM, name, (int[]){ x, tlo }, 2, &mid, 1, &a, NULL));
        return nn_graph_add_node(c->g, NN_OP_MINIMUM, base, (int[]){ mid, thi }, 2, &y, 1, &a, NULL);
    }
    if (act == NN_TFL_ACT_RELU || act == NN_TFL_ACT_RELU6) {
        if (act == NN_TFL_ACT_RELU) return nn_graph_add_node(c->g, NN_OP_RELU, base, &x, 1, &y, 1, &a, NULL);
        float six = 6;
        int t6, mid;
        char name[256];
        snprintf(name, sizeof name, "%s/six", base);
        PG_TRY(nn_graph_add_const_f32(c->g, name, 0, NULL, &six, &t6));
        snprintf(name, sizeof name, "%s/relu", base);
        PG_TRY(nn_graph_add_tensor(c->g, name, NN_F32, -1, NULL, &mid));
        PG_TRY(nn_graph_add_node(c->g, NN_OP_RELU, name, &x, 1, &mid, 1, &a, NULL));
        return nn_graph_add_node(c->g, NN_OP_MINIMUM, base, (int[]){ mid, t6 }, 2, &y, 1, &a, NULL);
    }
    return nn_graph_add_node(c->g, NN_OP_IDENTITY, base, &x, 1, &y, 1, &a, NULL);
}

/* A new activation tensor named base + suffix (shape inferred). */
static pg_status new_tensor(import_ctx *c, const char *base, const char *suffix, int *id)
{
    char name[300];
    snprintf(name, sizeof name, "%s%s", base, suffix);
    return nn_graph_add_tensor(c->g, name, NN_F32, -1, NULL, id);
}

/* y = x * v (v a scalar constant). */
static pg_status scale_by(import_ctx *c, const char *base, const char *suffix, int x, float v, int y)
{
    char name[300];
    snprintf(name, sizeof name, "%s%s", base, suffix);
    int k;
    PG_TRY(nn_graph_add_const_f32(c->g, name, 1, (int64_t[]){ 1 }, &v, &k));
    nn_attrs a;
    nn_attrs_default(&a);
    return nn_graph_add_node(c->g, NN_OP_MUL, name, (int[]){ x, k }, 2, &y, 1, &a, NULL);
}

/* zero point + round(v / scale), bounded so a tiny scale cannot overflow the int. */
static int quantize_bound(float v, const nn_tfl_tensor *t)
{
    float r = roundf(v / t->scales[0]);
    r = r < -1e6f ? -1e6f : r > 1e6f ? 1e6f : r;
    return t->zero_point + (int)r;
}

/* The multiplier m > 0 as q * 2^(shift - 31), q in [2^30, 2^31) (TFLite's QuantizeMultiplier). */
static void fixed_multiplier(double m, int64_t *q, int64_t *shift)
{
    if (!(m > 0 && isfinite(m))) { /* only from scales at the ends of the float range: the product is 0 */
        *q = *shift = 0;
        return;
    }
    int e;
    double f = frexp(m, &e);
    int64_t fixed = llround(f * 2147483648.0);
    if (fixed == (int64_t)1 << 31) fixed /= 2, e++;
    if (e < -31) e = 0, fixed = 0;
    if (e > 30) e = 30, fixed = INT32_MAX;
    *q = fixed;
    *shift = e;
}

/* A (C, 2) int64 constant of per-channel fixed-point multipliers input_scale * weight_scale[c] /
 * output_scale (wt NULL: input_scale / output_scale for every channel), the form REQUANTIZE takes. */
static pg_status fixed_multipliers(import_ctx *c, const char *base, int C, const nn_tfl_tensor *xt, const nn_tfl_tensor *wt,
                                   const nn_tfl_tensor *yt, int *id)
{
    int64_t *fixed = pg_malloc((size_t)C * 2 * sizeof(int64_t), "tflite requantize multipliers");
    if (!fixed) return PG_ERR_NOMEM;
    for (int ch = 0; ch < C; ch++) {
        double w = wt ? wt->scales[wt->num_scales > 1 ? ch : 0] : 1.0;
        fixed_multiplier((double)xt->scales[0] * w / yt->scales[0], &fixed[2 * ch], &fixed[2 * ch + 1]);
    }
    int64_t d[2] = { C, 2 };
    char name[300];
    snprintf(name, sizeof name, "%s/multipliers", base);
    return nn_graph_add_const(c->g, name, NN_I64, 2, d, fixed, id); /* takes fixed over */
}

/* y = the integer tensor t's centred value (q - zero point) from x times a multiplier (mult: an
 * int64 constant of per-channel fixed-point multipliers, or -1 for the float m0), clamped to t's
 * range narrowed by the fused activation act (TFLite's CalculateActivationRangeQuantized: the
 * activation's bounds quantised with round-half-away). */
static pg_status requantize(import_ctx *c, const char *base, int x, int mult, float m0, const nn_tfl_tensor *t, int act, int y)
{
    nn_attrs a;
    nn_attrs_default(&a);
    a.q_multiplier = m0;
    a.q_zero_point = t->zero_point;
    a.q_min = nn_tfl_qmin(t);
    a.q_max = nn_tfl_qmax(t);
    int zero = quantize_bound(0.0f, t), six = quantize_bound(6.0f, t), m1 = quantize_bound(-1.0f, t), p1 = quantize_bound(1.0f, t);
    if (act == NN_TFL_ACT_RELU || act == NN_TFL_ACT_RELU6) a.q_min = zero > a.q_min ? zero : a.q_min;
    if (act == NN_TFL_ACT_RELU6) a.q_max = six < a.q_max ? six : a.q_max;
    if (act == NN_TFL_ACT_RELU_N1_TO_1) {
        a.q_min = m1 > a.q_min ? m1 : a.q_min;
        a.q_max = p1 < a.q_max ? p1 : a.q_max;
    }
    if (a.q_max < a.q_min) a.q_max = a.q_min; /* an activation range outside the type: everything clamps to one value */
    char name[300];
    snprintf(name, sizeof name, "%s/requantize", base);
    int in[2] = { x, mult };
    return nn_graph_add_node(c->g, NN_OP_REQUANTIZE, name, in, mult >= 0 ? 2 : 1, &y, 1, &a, NULL);
}

/* The ops that compute integer tensors (see the file comment): QUANTIZE, DEQUANTIZE of an
 * activation, and CONV_2D / DEPTHWISE_CONV_2D / ADD writing int8 / uint8. */
static int is_integer_compute(const nn_tfl_model *m, const nn_tfl_op *op)
{
    if (op->code == NN_TFL_QUANTIZE || op->code == NN_TFL_DEQUANTIZE) return 1;
    int computes = op->code == NN_TFL_CONV_2D || op->code == NN_TFL_DEPTHWISE_CONV_2D || op->code == NN_TFL_ADD;
    return computes && nn_tfl_is_quantized(&m->tensors[op->output]);
}

static pg_status emit_integer_op(import_ctx *c, const nn_tfl_op *op, const char *base, int y)
{
    const nn_tfl_model *m = c->m;
    const nn_tfl_tensor *xt = &m->tensors[op->inputs[0]], *yt = &m->tensors[op->output];
    int x, acc;
    PG_TRY(ir_tensor(c, op->inputs[0], &x));
    if (op->code == NN_TFL_QUANTIZE && !nn_tfl_is_quantized(xt)) /* real -> integer: round(x / s) */
        return requantize(c, base, x, -1, 1.0f / yt->scales[0], yt, NN_TFL_ACT_NONE, y);
    if (op->code == NN_TFL_QUANTIZE) { /* integer -> integer: TFLite's fixed-point input_scale / output_scale */
        int mult, channels = yt->ndim ? yt->dims[yt->ndim - 1] : 1; /* REQUANTIZE refuses a 0-d tensor */
        PG_TRY(fixed_multipliers(c, base, channels, xt, NULL, yt, &mult));
        return requantize(c, base, x, mult, 0.0f, yt, NN_TFL_ACT_NONE, y);
    }
    if (op->code == NN_TFL_DEQUANTIZE) return scale_by(c, base, "/scale", x, xt->scales[0], y);
    PG_TRY(new_tensor(c, base, "/acc", &acc));
    nn_attrs a;
    nn_attrs_default(&a);
    if (op->code == NN_TFL_ADD) {
        /* a * (sa / sy) + b * (sb / sy): the sum in units of the output's step */
        const nn_tfl_tensor *bt = &m->tensors[op->inputs[1]];
        int b, sa, sb;
        PG_TRY(ir_tensor(c, op->inputs[1], &b));
        PG_TRY(new_tensor(c, base, "/a", &sa));
        PG_TRY(new_tensor(c, base, "/b", &sb));
        PG_TRY(scale_by(c, base, "/a_scale", x, (float)((double)xt->scales[0] / yt->scales[0]), sa));
        PG_TRY(scale_by(c, base, "/b_scale", b, (float)((double)bt->scales[0] / yt->scales[0]), sb));
        PG_TRY(nn_graph_add_node(c->g, NN_OP_ADD, base, (int[]){ sa, sb }, 2, &acc, 1, &a, NULL));
        return requantize(c, base, acc, -1, 1.0f, yt, op->act, y);
    }
    /* CONV_2D / DEPTHWISE_CONV_2D: integer weights and bias, exact sums in float (see the file
     * comment), then the per-channel rescale */
    const nn_tfl_tensor *wt = &m->tensors[op->inputs[1]];
    const nn_tfl_tensor *bt = op->num_inputs > 2 && op->inputs[2] >= 0 ? &m->tensors[op->inputs[2]] : NULL;
    int cout = yt->dims[3], in[3], mult;
    in[0] = x;
    PG_TRY(conv_weights(c, op, 1, &in[1]));
    in[2] = -1;
    if (bt) {
        float *bias = pg_malloc((size_t)cout * sizeof(float), "tflite integer bias");
        if (!bias) return PG_ERR_NOMEM;
        for (int o = 0; o < cout; o++) bias[o] = (float)bt->qvalues[o];
        int64_t d = cout;
        char name[300];
        snprintf(name, sizeof name, "%s/bias_int", base);
        PG_TRY(nn_graph_add_const(c->g, name, NN_F32, 1, &d, bias, &in[2]));
    }
    PG_TRY(fixed_multipliers(c, base, cout, xt, wt, yt, &mult));
    a.layout = NN_LAYOUT_NHWC;
    a.kernel[0] = wt->dims[1], a.kernel[1] = wt->dims[2];
    a.stride[0] = op->stride_h, a.stride[1] = op->stride_w;
    a.dilation[0] = op->dilation_h, a.dilation[1] = op->dilation_w;
    for (int i = 0; i < 4; i++) a.pads[i] = op->pad[i];
    a.group = op->code == NN_TFL_DEPTHWISE_CONV_2D ? xt->dims[3] : xt->dims[3] / wt->dims[3];
    PG_TRY(nn_graph_add_node(c->g, NN_OP_CONV, base, in, 3, &acc, 1, &a, NULL));
    return requantize(c, base, acc, mult, 0.0f, yt, op->act, y);
}

static pg_status emit_op(import_ctx *c, int k, const plan_op *p)
{
    const nn_tfl_model *m = c->m;
    const nn_tfl_op *op = &m->ops[k];
    const nn_tfl_tensor *yt = &m->tensors[p->output];
    char base[256];
    snprintf(base, sizeof base, "%s", yt->name[0] ? yt->name : "op");
    nn_attrs a;
    nn_attrs_default(&a);
    a.layout = NN_LAYOUT_NHWC;
    a.act = p->act;
    a.act_alpha = p->alpha;
    int extra = 0;
    if (op->act != NN_TFL_ACT_NONE && p->act == NN_ACT_NONE) fused(op->act, &extra);
    if (op->code == NN_TFL_CONCATENATION && op->act != NN_TFL_ACT_NONE) extra = op->act;
    int y, target;
    PG_TRY(ir_tensor(c, p->output, &target));
    if (is_integer_compute(m, op)) return emit_integer_op(c, op, base, target);
    y = target;
    if (extra) {
        char name[300];
        snprintf(name, sizeof name, "%s/pre_act", base);
        PG_TRY(nn_graph_add_tensor(c->g, name, NN_F32, -1, NULL, &y));
    }
    int in[NN_TFL_MAX_OP_INPUTS], nin = 0;
    nn_op ir_op;
    switch (op->code) {
    case NN_TFL_CONV_2D:
    case NN_TFL_DEPTHWISE_CONV_2D:
    case NN_TFL_TRANSPOSE_CONV: {
        int tc = op->code == NN_TFL_TRANSPOSE_CONV;
        const nn_tfl_tensor *w = &m->tensors[op->inputs[1]], *x = &m->tensors[op->inputs[tc ? 2 : 0]];
        PG_TRY(ir_tensor(c, op->inputs[tc ? 2 : 0], &in[0]));
        PG_TRY(conv_weights(c, op, 0, &in[1]));
        PG_TRY(ir_tensor(c, p->bias, &in[2]));
        nin = 3;
        ir_op = tc ? NN_OP_CONV_TRANSPOSE : NN_OP_CONV;
        a.kernel[0] = w->dims[1], a.kernel[1] = w->dims[2];
        a.stride[0] = op->stride_h, a.stride[1] = op->stride_w;
        a.dilation[0] = op->dilation_h, a.dilation[1] = op->dilation_w;
        for (int i = 0; i < 4; i++) a.pads[i] = op->pad[i];
        a.group = op->code == NN_TFL_DEPTHWISE_CONV_2D ? x->dims[3] : op->code == NN_TFL_CONV_2D ? x->dims[3] / w->dims[3] : 1;
        if (tc) {
            /* the IR's output length is (H-1)*s - pads + k + output_padding */
            int64_t oh = (int64_t)(x->dims[1] - 1) * op->stride_h - op->pad[0] - op->pad[2] + w->dims[1];
            int64_t ow = (int64_t)(x->dims[2] - 1) * op->stride_w - op->pad[1] - op->pad[3] + w->dims[2];
            a.output_padding[0] = (int)(yt->dims[1] - oh);
            a.output_padding[1] = (int)(yt->dims[2] - ow);
            if (a.output_padding[0] < 0 || a.output_padding[1] < 0 || a.output_padding[0] >= op->stride_h ||
                a.output_padding[1] >= op->stride_w)
                return pg_fail(PG_ERR_FORMAT, "%s: operator %d (TRANSPOSE_CONV, output '%s'): output size %dx%d not reachable", c->name,
                               k, yt->name, yt->dims[1], yt->dims[2]);
        }
        break;
    }
    case NN_TFL_ADD: case NN_TFL_SUB: case NN_TFL_MUL: case NN_TFL_MAXIMUM: case NN_TFL_MINIMUM:
        if (p->src >= 0) { /* the rewritten MAXIMUM(x, MUL(a, x)) */
            PG_TRY(ir_tensor(c, p->src, &in[0]));
            nin = 1;
            ir_op = NN_OP_LEAKY_RELU;
            a.alpha = p->alpha;
            a.act = NN_ACT_NONE;
            break;
        }
        PG_TRY(ir_tensor(c, op->inputs[0], &in[0]));
        PG_TRY(ir_tensor(c, op->inputs[1], &in[1]));
        nin = 2;
        ir_op = op->code == NN_TFL_ADD ? NN_OP_ADD : op->code == NN_TFL_SUB ? NN_OP_SUB : op->code == NN_TFL_MUL ? NN_OP_MUL
              : op->code == NN_TFL_MAXIMUM ? NN_OP_MAXIMUM : NN_OP_MINIMUM;
        break;
    case NN_TFL_CONCATENATION:
        for (int j = 0; j < op->num_inputs; j++) PG_TRY(ir_tensor(c, op->inputs[j], &in[j]));
        nin = op->num_inputs;
        ir_op = NN_OP_CONCAT;
        a.axis = op->axis;
        a.act = NN_ACT_NONE;
        break;
    case NN_TFL_STRIDED_SLICE: {
        const nn_tfl_tensor *x = &m->tensors[op->inputs[0]];
        PG_TRY(ir_tensor(c, op->inputs[0], &in[0]));
        nin = 1;
        ir_op = NN_OP_SLICE;
        a.num_axes = x->ndim;
        for (int d = 0; d < x->ndim; d++) {
            int64_t b = op->slice_begin[d], s = op->slice_stride[d], e = b + (int64_t)op->slice_len[d] * s;
            if (s < 0 && e < 0) e = -(int64_t)x->dims[d] - 1; /* past the front: ONNX's "before index 0" */
            a.axes[d] = d, a.starts[d] = b, a.ends[d] = e, a.steps[d] = s;
        }
        if (op->shrink_axis_mask) {
            /* slice, then reshape away the shrunk axes */
            char name[300];
            int mid;
            snprintf(name, sizeof name, "%s/slice", base);
            PG_TRY(nn_graph_add_tensor(c->g, name, NN_F32, -1, NULL, &mid));
            PG_TRY(nn_graph_add_node(c->g, NN_OP_SLICE, name, in, 1, &mid, 1, &a, NULL));
            nn_attrs r;
            nn_attrs_default(&r);
            r.num_shape = yt->ndim;
            for (int d = 0; d < yt->ndim; d++) r.shape[d] = yt->dims[d];
            return nn_graph_add_node(c->g, NN_OP_RESHAPE, base, &mid, 1, &y, 1, &r, NULL);
        }
        break;
    }
    case NN_TFL_RESIZE_NEAREST_NEIGHBOR:
        PG_TRY(ir_tensor(c, op->inputs[0], &in[0]));
        nin = 1;
        ir_op = NN_OP_RESIZE;
        a.resize_mode = NN_RESIZE_NEAREST;
        /* TFLite: floor((o + offset) * in/out), or round(o * (in-1)/(out-1)) with align_corners */
        a.coord_mode = op->align_corners ? NN_COORD_ALIGN_CORNERS : op->half_pixel_centers ? NN_COORD_TF_HALF_PIXEL_FOR_NN : NN_COORD_ASYMMETRIC;
        a.nearest_mode = op->align_corners ? NN_NEAREST_ROUND_PREFER_CEIL : NN_NEAREST_FLOOR;
        a.out_h = yt->dims[1], a.out_w = yt->dims[2];
        a.act = NN_ACT_NONE;
        break;
    case NN_TFL_RESIZE_BILINEAR:
        PG_TRY(ir_tensor(c, op->inputs[0], &in[0]));
        nin = 1;
        ir_op = NN_OP_RESIZE;
        a.resize_mode = NN_RESIZE_LINEAR;
        a.coord_mode = op->align_corners ? NN_COORD_ALIGN_CORNERS : op->half_pixel_centers ? NN_COORD_HALF_PIXEL : NN_COORD_ASYMMETRIC;
        a.out_h = yt->dims[1], a.out_w = yt->dims[2];
        a.act = NN_ACT_NONE;
        break;
    case NN_TFL_PAD: {
        const nn_tfl_tensor *x = &m->tensors[op->inputs[0]];
        PG_TRY(ir_tensor(c, op->inputs[0], &in[0]));
        nin = 1;
        ir_op = NN_OP_PAD;
        for (int d = 0; d < x->ndim; d++) {
            a.pad_amounts[d] = op->pads[d];
            a.pad_amounts[x->ndim + d] = op->pads[NN_TFL_MAX_DIMS + d];
        }
        a.pad_mode = NN_PAD_CONSTANT;
        a.pad_value = 0;
        a.act = NN_ACT_NONE;
        break;
    }
    case NN_TFL_RESHAPE:
        PG_TRY(ir_tensor(c, op->inputs[0], &in[0]));
        nin = 1;
        ir_op = NN_OP_RESHAPE;
        a.num_shape = yt->ndim;
        for (int d = 0; d < yt->ndim; d++) a.shape[d] = yt->dims[d];
        break;
    case NN_TFL_LEAKY_RELU: case NN_TFL_RELU: case NN_TFL_RELU6: case NN_TFL_LOGISTIC: case NN_TFL_TANH:
        PG_TRY(ir_tensor(c, op->inputs[0], &in[0]));
        nin = 1;
        a.act = NN_ACT_NONE;
        if (op->code == NN_TFL_RELU6) return extra_act(c, base, NN_TFL_ACT_RELU6, in[0], y);
        ir_op = op->code == NN_TFL_LEAKY_RELU ? NN_OP_LEAKY_RELU : op->code == NN_TFL_RELU ? NN_OP_RELU
              : op->code == NN_TFL_LOGISTIC ? NN_OP_SIGMOID : NN_OP_TANH;
        a.alpha = op->alpha;
        break;
    default:
        return pg_fail(PG_ERR_FORMAT, "%s: operator %d: unsupported op %d", c->name, k, op->code);
    }
    PG_TRY(nn_graph_add_node(c->g, ir_op, base, in, nin, &y, 1, &a, NULL));
    if (extra) return extra_act(c, base, extra, y, target);
    return PG_OK;
}

/* The IR graph input for TFLite input t. An integer input is fed its real values (tflite.h) and
 * quantised by a first node, as a TFLite caller does before feeding. */
static pg_status import_input(import_ctx *c, int t, int *id)
{
    const nn_tfl_tensor *tt = &c->m->tensors[t];
    if (!nn_tfl_is_quantized(tt)) return ir_tensor(c, t, id);
    int q;
    PG_TRY(ir_tensor(c, t, &q));
    int64_t d[NN_TFL_MAX_DIMS];
    dims64(tt, d);
    char name[300];
    snprintf(name, sizeof name, "%s/real", tt->name);
    PG_TRY(nn_graph_add_tensor(c->g, name, NN_F32, tt->ndim, d, id));
    return requantize(c, tt->name, *id, -1, 1.0f / tt->scales[0], tt, NN_TFL_ACT_NONE, q);
}

/* The IR graph output for TFLite output t: an integer output is given as its real value. */
static pg_status import_output(import_ctx *c, int t, int *id)
{
    const nn_tfl_tensor *tt = &c->m->tensors[t];
    if (!nn_tfl_is_quantized(tt)) return ir_tensor(c, t, id);
    int q;
    PG_TRY(ir_tensor(c, t, &q));
    PG_TRY(new_tensor(c, tt->name, "/real", id));
    return scale_by(c, tt->name, "/output_scale", q, tt->scales[0], *id);
}

pg_status nn_tflite_import(const uint8_t *data, size_t size, const char *name, nn_graph *g)
{
    nn_tfl_model m;
    PG_TRY(nn_tfl_parse(data, size, name, &m));
    import_ctx c = { &m, g, name, NULL, NULL, NULL, NULL };
    plan_op *plan = pg_calloc((size_t)m.num_ops, sizeof *plan, "tflite import plan");
    c.ir = pg_malloc((size_t)m.num_tensors * sizeof(int), "tflite import map");
    c.readers = pg_calloc((size_t)m.num_tensors, sizeof(int), "tflite import readers");
    c.is_output = pg_calloc((size_t)m.num_tensors, 1, "tflite import outputs");
    c.owner = pg_malloc((size_t)m.num_tensors * sizeof(int), "tflite import owners");
    pg_status st = plan && c.ir && c.readers && c.is_output && c.owner ? PG_OK : PG_ERR_NOMEM;
    if (!st) {
        for (int i = 0; i < m.num_tensors; i++) c.ir[i] = -1, c.owner[i] = m.tensors[i].producer;
        for (int k = 0; k < m.num_ops; k++)
            for (int j = 0; j < m.ops[k].num_inputs; j++)
                if (m.ops[k].inputs[j] >= 0) c.readers[m.ops[k].inputs[j]]++;
        for (int j = 0; j < m.num_outputs; j++) c.is_output[m.outputs[j]] = 1;
        plan_fusions(&c, plan);
    }
    int ins[NN_TFL_MAX_IO], outs[NN_TFL_MAX_IO];
    for (int j = 0; !st && j < m.num_inputs; j++) st = import_input(&c, m.inputs[j], &ins[j]);
    for (int k = 0; !st && k < m.num_ops; k++)
        if (!plan[k].skip) st = emit_op(&c, k, &plan[k]);
    for (int j = 0; !st && j < m.num_outputs; j++) st = import_output(&c, m.outputs[j], &outs[j]);
    if (!st) st = nn_graph_set_io(g, ins, m.num_inputs, outs, m.num_outputs);
    free(plan);
    free(c.ir);
    free(c.readers);
    free(c.is_output);
    free(c.owner);
    nn_tfl_destroy(&m);
    return st;
}
