/* tflite_ref_int.c - the reference interpreter's integer kernels: ops on int8 / uint8 activations
 * computed the way TFLite's reference kernels define them (integer_ops conv / depthwise / add,
 * quantize, requantize, dequantize, and quantization_util's fixed-point multipliers): int32
 * accumulators of (x - input zero point) * (w - weight zero point) plus the int32 bias, a
 * per-channel real multiplier input_scale * weight_scale / output_scale held as a Q31 mantissa
 * and a power-of-two shift, a rounding doubling high multiply and a rounding right shift, then
 * the output zero point and the fused activation as a clamp in the quantised domain.
 *
 * It is written apart from the runtime's float path (tflite_import.c computes in float and rounds
 * every integer tensor to its grid), so each checks the other. Activations travel through the
 * reference's float buffers as their stored integers (exact in a float). */
#include "nn/tflite.h"

#include <limits.h>
#include <math.h>
#include <stdint.h>

/* The multiplier m > 0 as q * 2^(shift - 31) with q in [2^30, 2^31) (TFLite's QuantizeMultiplier). */
static void quantize_multiplier(double m, int32_t *q, int *shift)
{
    if (!(m > 0 && isfinite(m))) { /* scales at the ends of the float range (a hostile file) */
        *q = 0, *shift = 0;
        return;
    }
    double f = frexp(m, shift); /* m = f * 2^shift, f in [0.5, 1) */
    int64_t fixed = llround(f * 2147483648.0);
    if (fixed == (int64_t)1 << 31) {
        fixed /= 2;
        ++*shift;
    }
    if (*shift < -31) *shift = 0, fixed = 0;
    if (*shift > 30) *shift = 30, fixed = INT32_MAX;
    *q = (int32_t)fixed;
}

/* round(a * b / 2^31), ties away from zero, saturating the one overflowing case. */
static int32_t rounding_doubling_high_mul(int32_t a, int32_t b)
{
    if (a == INT32_MIN && b == INT32_MIN) return INT32_MAX;
    int64_t ab = (int64_t)a * b;
    int64_t nudge = ab >= 0 ? (1 << 30) : 1 - (1 << 30);
    return (int32_t)((ab + nudge) / ((int64_t)1 << 31));
}

/* x / 2^exponent rounded to nearest, ties away from zero. */
static int32_t rounding_divide_by_pot(int32_t x, int exponent)
{
    int32_t mask = (int32_t)(((int64_t)1 << exponent) - 1);
    int32_t remainder = x & mask, threshold = (mask >> 1) + (x < 0);
    return (x >> exponent) + (remainder > threshold);
}

static int32_t multiply_by_quantized_multiplier(int32_t x, int32_t q, int shift)
{
    int left = shift > 0 ? shift : 0, right = shift > 0 ? 0 : -shift;
    int64_t shifted = (int64_t)x * ((int64_t)1 << left);
    if (shifted > INT32_MAX) shifted = INT32_MAX;
    if (shifted < INT32_MIN) shifted = INT32_MIN;
    return rounding_divide_by_pot(rounding_doubling_high_mul((int32_t)shifted, q), right);
}

/* Sums are taken in 64 bits before the clamp: with a hostile file's extreme scales a rescaled
 * value near the int32 limits plus the zero point would overflow (TFLite's int32 would too). */
static int32_t clamp32(int64_t v, int32_t lo, int32_t hi) { return (int32_t)(v < lo ? lo : v > hi ? hi : v); }

/* zero point + round(v / scale) (TFLite's TfLiteRound: half away from zero), kept inside
 * +-2^30 so a hostile tiny scale cannot overflow the conversion. */
static int32_t quantize_bound(float v, const nn_tfl_tensor *y)
{
    double r = round((double)(v / y->scales[0]));
    return y->zero_point + (int32_t)(r < -1073741824.0 ? -1073741824.0 : r > 1073741824.0 ? 1073741824.0 : r);
}

/* TFLite's CalculateActivationRangeQuantized: the fused activation's real bounds quantised to y's
 * grid (round half away from zero), intersected with y's type range. */
static void act_range(int act, const nn_tfl_tensor *y, int32_t *lo, int32_t *hi)
{
    int32_t q0 = quantize_bound(0.0f, y), q6 = quantize_bound(6.0f, y), qm1 = quantize_bound(-1.0f, y), qp1 = quantize_bound(1.0f, y);
    *lo = nn_tfl_qmin(y);
    *hi = nn_tfl_qmax(y);
    if (act == NN_TFL_ACT_RELU || act == NN_TFL_ACT_RELU6) *lo = q0 > *lo ? q0 : *lo;
    if (act == NN_TFL_ACT_RELU6) *hi = q6 < *hi ? q6 : *hi;
    if (act == NN_TFL_ACT_RELU_N1_TO_1) {
        *lo = qm1 > *lo ? qm1 : *lo;
        *hi = qp1 < *hi ? qp1 : *hi;
    }
}

/* CONV_2D (group = C / w's last dim) and DEPTHWISE_CONV_2D on stored integers, per-channel or
 * per-tensor weight scales. */
static void int_conv(const nn_tfl_model *m, const nn_tfl_op *op, const float *x, float *y)
{
    const nn_tfl_tensor *xt = &m->tensors[op->inputs[0]], *wt = &m->tensors[op->inputs[1]], *yt = &m->tensors[op->output];
    const nn_tfl_tensor *bt = op->num_inputs > 2 && op->inputs[2] >= 0 ? &m->tensors[op->inputs[2]] : NULL;
    int depthwise = op->code == NN_TFL_DEPTHWISE_CONV_2D;
    int N = xt->dims[0], H = xt->dims[1], W = xt->dims[2], C = xt->dims[3];
    int KH = wt->dims[1], KW = wt->dims[2], O = yt->dims[3], OH = yt->dims[1], OW = yt->dims[2];
    int CG = depthwise ? 1 : wt->dims[3], OG = depthwise ? O / C : O / (C / CG); /* inputs per group, outputs per group */
    int32_t xzp = xt->zero_point, wzp = wt->zero_point, lo, hi;
    act_range(op->act, yt, &lo, &hi);
    for (int o = 0; o < O; o++) {
        int32_t q;
        int shift;
        float ws = wt->scales[wt->num_scales > 1 ? o : 0];
        quantize_multiplier((double)xt->scales[0] * (double)ws / (double)yt->scales[0], &q, &shift);
        int g = o / OG;
        for (int n = 0; n < N; n++)
            for (int oy = 0; oy < OH; oy++)
                for (int ox = 0; ox < OW; ox++) {
                    int64_t acc = 0; /* int32 in TFLite; wider here so a hostile file cannot overflow it */
                    for (int ky = 0; ky < KH; ky++) {
                        int iy = oy * op->stride_h - op->pad[0] + ky * op->dilation_h;
                        if (iy < 0 || iy >= H) continue;
                        for (int kx = 0; kx < KW; kx++) {
                            int ix = ox * op->stride_w - op->pad[1] + kx * op->dilation_w;
                            if (ix < 0 || ix >= W) continue;
                            const float *xp = x + (((size_t)n * H + iy) * W + ix) * C + (size_t)g * CG;
                            for (int ci = 0; ci < CG; ci++) {
                                size_t wi = depthwise ? ((size_t)ky * KW + kx) * O + o : (((size_t)o * KH + ky) * KW + kx) * CG + ci;
                                acc += (int64_t)((int32_t)xp[ci] - xzp) * (wt->qvalues[wi] - wzp);
                            }
                        }
                    }
                    if (bt) acc += bt->qvalues[o];
                    acc = acc < INT32_MIN ? INT32_MIN : acc > INT32_MAX ? INT32_MAX : acc;
                    int64_t v = (int64_t)multiply_by_quantized_multiplier((int32_t)acc, q, shift) + yt->zero_point;
                    y[(((size_t)n * OH + oy) * OW + ox) * O + o] = (float)clamp32(v, lo, hi);
                }
    }
}

/* ADD with requantisation (TFLite's int8 / uint8 AddElementwise): both inputs rescaled to 2^20
 * times twice the larger input scale, summed, rescaled to the output. Broadcasts like NumPy. */
static void int_add(const nn_tfl_model *m, const nn_tfl_op *op, const float *a, const float *b, float *y)
{
    const nn_tfl_tensor *at = &m->tensors[op->inputs[0]], *bt = &m->tensors[op->inputs[1]], *yt = &m->tensors[op->output];
    const int left_shift = 20;
    double twice_max = 2.0 * fmax(at->scales[0], bt->scales[0]);
    int32_t qa, qb, qy, lo, hi;
    int sa, sb, sy;
    quantize_multiplier(at->scales[0] / twice_max, &qa, &sa);
    quantize_multiplier(bt->scales[0] / twice_max, &qb, &sb);
    quantize_multiplier(twice_max / ((double)(1 << left_shift) * yt->scales[0]), &qy, &sy);
    act_range(op->act, yt, &lo, &hi);
    int nd = yt->ndim, coord[NN_TFL_MAX_DIMS] = { 0 };
    size_t stride_a[NN_TFL_MAX_DIMS], stride_b[NN_TFL_MAX_DIMS], ra = 1, rb = 1;
    for (int d = nd - 1; d >= 0; d--) {
        int ia = d - (nd - at->ndim), ib = d - (nd - bt->ndim);
        int da = ia >= 0 ? at->dims[ia] : 1, db = ib >= 0 ? bt->dims[ib] : 1;
        stride_a[d] = da == 1 ? 0 : ra;
        stride_b[d] = db == 1 ? 0 : rb;
        ra *= (size_t)da;
        rb *= (size_t)db;
    }
    for (size_t i = 0; i < (size_t)yt->count; i++) {
        size_t ia = 0, ib = 0;
        for (int d = 0; d < nd; d++) ia += (size_t)coord[d] * stride_a[d], ib += (size_t)coord[d] * stride_b[d];
        int32_t va = ((int32_t)a[ia] - at->zero_point) * (1 << left_shift);
        int32_t vb = ((int32_t)b[ib] - bt->zero_point) * (1 << left_shift);
        int64_t sum = (int64_t)multiply_by_quantized_multiplier(va, qa, sa) + multiply_by_quantized_multiplier(vb, qb, sb);
        sum = sum < INT32_MIN ? INT32_MIN : sum > INT32_MAX ? INT32_MAX : sum;
        int64_t out = (int64_t)multiply_by_quantized_multiplier((int32_t)sum, qy, sy) + yt->zero_point;
        y[i] = (float)clamp32(out, lo, hi);
        for (int d = nd - 1; d >= 0; d--) {
            if (++coord[d] < yt->dims[d]) break;
            coord[d] = 0;
        }
    }
}

/* QUANTIZE: float -> integer (round(x / scale) + zero point), or integer -> integer (requantise
 * by input_scale / output_scale); both clamp to the output type. */
static void int_quantize(const nn_tfl_model *m, const nn_tfl_op *op, const float *x, float *y)
{
    const nn_tfl_tensor *xt = &m->tensors[op->inputs[0]], *yt = &m->tensors[op->output];
    int32_t lo = nn_tfl_qmin(yt), hi = nn_tfl_qmax(yt);
    if (xt->type == NN_TFL_FLOAT32) {
        for (size_t i = 0; i < (size_t)yt->count; i++) {
            float r = roundf(x[i] / yt->scales[0]);
            r = r < -1e9f ? -1e9f : r > 1e9f ? 1e9f : r; /* NaN stays NaN below: clamp by comparisons */
            int64_t v = r == r ? (int64_t)r + yt->zero_point : yt->zero_point;
            y[i] = (float)clamp32(v, lo, hi);
        }
        return;
    }
    int32_t q;
    int shift;
    quantize_multiplier((double)xt->scales[0] / (double)yt->scales[0], &q, &shift);
    for (size_t i = 0; i < (size_t)yt->count; i++) {
        int64_t v = (int64_t)multiply_by_quantized_multiplier((int32_t)x[i] - xt->zero_point, q, shift) + yt->zero_point;
        y[i] = (float)clamp32(v, lo, hi);
    }
}

int nn_tfl_op_is_integer(const nn_tfl_model *m, const nn_tfl_op *op)
{
    if (op->code == NN_TFL_QUANTIZE || op->code == NN_TFL_DEQUANTIZE) return 1;
    int data_op = op->code == NN_TFL_CONV_2D || op->code == NN_TFL_DEPTHWISE_CONV_2D || op->code == NN_TFL_ADD;
    return data_op && nn_tfl_is_quantized(&m->tensors[op->output]);
}

pg_status nn_tfl_ref_int_op(const nn_tfl_model *m, const nn_tfl_op *op, float *const *buf, float *y)
{
    const nn_tfl_tensor *xt = &m->tensors[op->inputs[0]], *yt = &m->tensors[op->output];
    const float *x = buf[op->inputs[0]];
    switch (op->code) {
    case NN_TFL_CONV_2D: case NN_TFL_DEPTHWISE_CONV_2D:
        int_conv(m, op, x, y);
        return PG_OK;
    case NN_TFL_ADD:
        int_add(m, op, x, buf[op->inputs[1]], y);
        return PG_OK;
    case NN_TFL_QUANTIZE:
        int_quantize(m, op, x, y);
        return PG_OK;
    case NN_TFL_DEQUANTIZE:
        for (size_t i = 0; i < (size_t)yt->count; i++) y[i] = (float)((double)xt->scales[0] * ((int32_t)x[i] - xt->zero_point));
        return PG_OK;
    default:
        return pg_fail(PG_ERR_FORMAT, "reference run: no integer kernel for %s", nn_tfl_op_name(op->code));
    }
}
