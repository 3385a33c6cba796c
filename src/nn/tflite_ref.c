/* tflite_ref.c - the naive NHWC reference interpreter of a parsed TFLite model (tflite.h): one
 * straightforward loop nest per op, double accumulators, no blocking, no threads. It is the
 * oracle the runtime's kernels are checked against, so it follows TFLite's definitions
 * literally (SAME padding split, TRANSPOSE_CONV as the scatter of each input pixel, the legacy
 * RESIZE_BILINEAR coordinates) and shares no code with nn_exec.c. */
#include "nn/tflite.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static float act_apply(int act, float v)
{
    switch (act) {
    case NN_TFL_ACT_RELU: return v > 0 ? v : 0;
    case NN_TFL_ACT_RELU_N1_TO_1: return v < -1 ? -1 : v > 1 ? 1 : v;
    case NN_TFL_ACT_RELU6: return v < 0 ? 0 : v > 6 ? 6 : v;
    case NN_TFL_ACT_TANH: return tanhf(v);
    default: return v;
    }
}

/* y (N,OH,OW,O) = conv(x (N,H,W,C), w (O,KH,KW,C/group)) + b; group = C / w's last dim. */
static void ref_conv(const nn_tfl_op *op, const nn_tfl_tensor *xt, const nn_tfl_tensor *wt, const float *x, const float *w,
                     const float *b, const nn_tfl_tensor *yt, float *y)
{
    int N = xt->dims[0], H = xt->dims[1], W = xt->dims[2], C = xt->dims[3];
    int O = wt->dims[0], KH = wt->dims[1], KW = wt->dims[2], CG = wt->dims[3];
    int OH = yt->dims[1], OW = yt->dims[2], groups = C / CG, OG = O / groups;
    for (int n = 0; n < N; n++)
        for (int oy = 0; oy < OH; oy++)
            for (int ox = 0; ox < OW; ox++)
                for (int o = 0; o < O; o++) {
                    int g = o / OG;
                    double acc = b ? b[o] : 0.0;
                    for (int ky = 0; ky < KH; ky++) {
                        int iy = oy * op->stride_h - op->pad[0] + ky * op->dilation_h;
                        if (iy < 0 || iy >= H) continue;
                        for (int kx = 0; kx < KW; kx++) {
                            int ix = ox * op->stride_w - op->pad[1] + kx * op->dilation_w;
                            if (ix < 0 || ix >= W) continue;
                            const float *xp = x + (((size_t)n * H + iy) * W + ix) * C + (size_t)g * CG;
                            const float *wp = w + (((size_t)o * KH + ky) * KW + kx) * CG;
                            for (int c = 0; c < CG; c++) acc += (double)xp[c] * wp[c];
                        }
                    }
                    y[(((size_t)n * OH + oy) * OW + ox) * O + o] = act_apply(op->act, (float)acc);
                }
}

/* y (N,OH,OW,C*M) = depthwise(x (N,H,W,C), w (1,KH,KW,C*M)) + b. */
static void ref_depthwise(const nn_tfl_op *op, const nn_tfl_tensor *xt, const nn_tfl_tensor *wt, const float *x, const float *w,
                          const float *b, const nn_tfl_tensor *yt, float *y)
{
    int N = xt->dims[0], H = xt->dims[1], W = xt->dims[2], C = xt->dims[3];
    int KH = wt->dims[1], KW = wt->dims[2], O = wt->dims[3], M = O / C;
    int OH = yt->dims[1], OW = yt->dims[2];
    for (int n = 0; n < N; n++)
        for (int oy = 0; oy < OH; oy++)
            for (int ox = 0; ox < OW; ox++)
                for (int o = 0; o < O; o++) {
                    double acc = b ? b[o] : 0.0;
                    for (int ky = 0; ky < KH; ky++) {
                        int iy = oy * op->stride_h - op->pad[0] + ky * op->dilation_h;
                        if (iy < 0 || iy >= H) continue;
                        for (int kx = 0; kx < KW; kx++) {
                            int ix = ox * op->stride_w - op->pad[1] + kx * op->dilation_w;
                            if (ix < 0 || ix >= W) continue;
                            acc += (double)x[(((size_t)n * H + iy) * W + ix) * C + o / M] * w[((size_t)ky * KW + kx) * O + o];
                        }
                    }
                    y[(((size_t)n * OH + oy) * OW + ox) * O + o] = act_apply(op->act, (float)acc);
                }
}

/* Every input pixel (y, x) adds x[c] * w[o, ky, kx, c] at output (y*s + ky - pad, x*s + kx - pad). */
static pg_status ref_transpose_conv(const nn_tfl_op *op, const nn_tfl_tensor *xt, const nn_tfl_tensor *wt, const float *x,
                                    const float *w, const float *b, const nn_tfl_tensor *yt, float *y)
{
    int N = xt->dims[0], H = xt->dims[1], W = xt->dims[2], C = xt->dims[3];
    int O = wt->dims[0], KH = wt->dims[1], KW = wt->dims[2];
    int OH = yt->dims[1], OW = yt->dims[2];
    double *acc = pg_calloc((size_t)yt->count, sizeof(double), "reference transpose conv");
    if (!acc) return PG_ERR_NOMEM;
    for (int n = 0; n < N; n++)
        for (int iy = 0; iy < H; iy++)
            for (int ix = 0; ix < W; ix++)
                for (int ky = 0; ky < KH; ky++) {
                    int oy = iy * op->stride_h + ky - op->pad[0];
                    if (oy < 0 || oy >= OH) continue;
                    for (int kx = 0; kx < KW; kx++) {
                        int ox = ix * op->stride_w + kx - op->pad[1];
                        if (ox < 0 || ox >= OW) continue;
                        const float *xp = x + (((size_t)n * H + iy) * W + ix) * C;
                        double *ap = acc + (((size_t)n * OH + oy) * OW + ox) * O;
                        for (int o = 0; o < O; o++) {
                            const float *wp = w + (((size_t)o * KH + ky) * KW + kx) * C;
                            double s = 0;
                            for (int c = 0; c < C; c++) s += (double)xp[c] * wp[c];
                            ap[o] += s;
                        }
                    }
                }
    for (size_t i = 0; i < (size_t)yt->count; i++) y[i] = act_apply(op->act, (float)(acc[i] + (b ? b[i % (size_t)O] : 0.0)));
    free(acc);
    return PG_OK;
}

/* Element i of a tensor broadcast to (ndim, dims): index by the output coordinates. */
static void ref_binary(const nn_tfl_op *op, const nn_tfl_tensor *at, const float *a, const nn_tfl_tensor *bt, const float *b,
                       const nn_tfl_tensor *yt, float *y)
{
    int nd = yt->ndim;
    size_t sa[NN_TFL_MAX_DIMS], sb[NN_TFL_MAX_DIMS];
    size_t ra = 1, rb = 1;
    for (int d = nd - 1; d >= 0; d--) {
        int ia = d - (nd - at->ndim), ib = d - (nd - bt->ndim);
        int da = ia >= 0 ? at->dims[ia] : 1, db = ib >= 0 ? bt->dims[ib] : 1;
        sa[d] = da == 1 ? 0 : ra;
        sb[d] = db == 1 ? 0 : rb;
        ra *= (size_t)da;
        rb *= (size_t)db;
    }
    int coord[NN_TFL_MAX_DIMS] = { 0 };
    for (size_t i = 0; i < (size_t)yt->count; i++) {
        size_t ia = 0, ib = 0;
        for (int d = 0; d < nd; d++) {
            ia += (size_t)coord[d] * sa[d];
            ib += (size_t)coord[d] * sb[d];
        }
        float u = a[ia], v = b[ib], r;
        switch (op->code) {
        case NN_TFL_ADD: r = u + v; break;
        case NN_TFL_SUB: r = u - v; break;
        case NN_TFL_MUL: r = u * v; break;
        case NN_TFL_MAXIMUM: r = u > v ? u : v; break;
        default: r = u < v ? u : v; break;
        }
        y[i] = act_apply(op->act, r);
        for (int d = nd - 1; d >= 0; d--) {
            if (++coord[d] < yt->dims[d]) break;
            coord[d] = 0;
        }
    }
}

static void ref_concat(const nn_tfl_op *op, const nn_tfl_model *m, float *const *buf, const nn_tfl_tensor *yt, float *y)
{
    size_t outer = 1, inner = 1;
    for (int d = 0; d < op->axis; d++) outer *= (size_t)yt->dims[d];
    for (int d = op->axis + 1; d < yt->ndim; d++) inner *= (size_t)yt->dims[d];
    size_t row = (size_t)yt->dims[op->axis] * inner, at = 0;
    for (int j = 0; j < op->num_inputs; j++) {
        const nn_tfl_tensor *t = &m->tensors[op->inputs[j]];
        size_t len = (size_t)t->dims[op->axis] * inner;
        for (size_t o = 0; o < outer; o++)
            for (size_t i = 0; i < len; i++) y[o * row + at + i] = act_apply(op->act, buf[op->inputs[j]][o * len + i]);
        at += len;
    }
}

static void ref_slice(const nn_tfl_op *op, const nn_tfl_tensor *xt, const float *x, float *y)
{
    int nd = xt->ndim, coord[NN_TFL_MAX_DIMS] = { 0 };
    size_t total = 1, n = 0;
    for (int d = 0; d < nd; d++) total *= (size_t)op->slice_len[d];
    for (size_t i = 0; i < total; i++) {
        size_t src = 0;
        for (int d = 0; d < nd; d++) src = src * (size_t)xt->dims[d] + (size_t)(op->slice_begin[d] + coord[d] * op->slice_stride[d]);
        y[n++] = x[src];
        for (int d = nd - 1; d >= 0; d--) {
            if (++coord[d] < op->slice_len[d]) break;
            coord[d] = 0;
        }
    }
}

/* TFLite's RESIZE_BILINEAR: source coordinate = dst * in/out (align_corners: dst * (in-1)/(out-1);
 * half_pixel_centers: (dst + 0.5) * in/out - 0.5), neighbours clamped to the image. */
/* The two source taps (clamped to [0, size)) of output index o along one axis with scale s, and the
 * weight d of the second. */
static void resize_taps(const nn_tfl_op *op, int o, double s, int size, int *i0, int *i1, double *d)
{
    double f = op->half_pixel_centers ? (o + 0.5) * s - 0.5 : o * s;
    double f0 = floor(f);
    int a = (int)f0, b = a + 1;
    *d = f - f0;
    if (a < 0) a = 0;
    if (b > size - 1) b = size - 1;
    if (a > size - 1) a = size - 1;
    *i0 = a;
    *i1 = b;
}

static void ref_resize(const nn_tfl_op *op, const nn_tfl_tensor *xt, const float *x, const nn_tfl_tensor *yt, float *y)
{
    int N = xt->dims[0], H = xt->dims[1], W = xt->dims[2], C = xt->dims[3], OH = yt->dims[1], OW = yt->dims[2];
    double sy = op->align_corners && OH > 1 ? (double)(H - 1) / (OH - 1) : (double)H / OH;
    double sx = op->align_corners && OW > 1 ? (double)(W - 1) / (OW - 1) : (double)W / OW;
    for (int n = 0; n < N; n++)
        for (int oy = 0; oy < OH; oy++) {
            int y0, y1;
            double dy;
            resize_taps(op, oy, sy, H, &y0, &y1, &dy);
            for (int ox = 0; ox < OW; ox++) {
                int x0, x1;
                double dx;
                resize_taps(op, ox, sx, W, &x0, &x1, &dx);
                for (int c = 0; c < C; c++) {
#define PX(yy, xx) (double)x[(((size_t)n * H + (yy)) * W + (xx)) * C + c]
                    double v = PX(y0, x0) * (1 - dy) * (1 - dx) + PX(y0, x1) * (1 - dy) * dx + PX(y1, x0) * dy * (1 - dx) +
                               PX(y1, x1) * dy * dx;
#undef PX
                    y[(((size_t)n * OH + oy) * OW + ox) * C + c] = (float)v;
                }
            }
        }
}

/* value: what the border holds (0, or an integer tensor's zero point: its stored 0). */
/* TFLite's RESIZE_NEAREST_NEIGHBOR source index: floor((o + offset) * in/out), or with
 * align_corners round(o * (in-1)/(out-1)); offset 0.5 with half_pixel_centers; clamped. */
static int nearest_index(const nn_tfl_op *op, int o, int in, int out)
{
    float scale = op->align_corners && out > 1 ? (float)(in - 1) / (float)(out - 1) : (float)in / (float)out;
    float f = ((float)o + (op->half_pixel_centers ? 0.5f : 0.0f)) * scale;
    int i = op->align_corners ? (int)roundf(f) : (int)floorf(f);
    if (i > in - 1) i = in - 1;
    return i < 0 ? 0 : i;
}

/* Copies values, so it serves float and integer tensors alike. */
static void ref_resize_nearest(const nn_tfl_op *op, const nn_tfl_tensor *xt, const float *x, const nn_tfl_tensor *yt, float *y)
{
    int N = xt->dims[0], H = xt->dims[1], W = xt->dims[2], C = xt->dims[3], OH = yt->dims[1], OW = yt->dims[2];
    for (int n = 0; n < N; n++)
        for (int oy = 0; oy < OH; oy++)
            for (int ox = 0; ox < OW; ox++) {
                const float *src = x + (((size_t)n * H + nearest_index(op, oy, H, OH)) * W + nearest_index(op, ox, W, OW)) * C;
                memcpy(y + (((size_t)n * OH + oy) * OW + ox) * C, src, (size_t)C * sizeof(float));
            }
}

static void ref_pad(const nn_tfl_op *op, const nn_tfl_tensor *xt, const float *x, const nn_tfl_tensor *yt, float value, float *y)
{
    int nd = yt->ndim, coord[NN_TFL_MAX_DIMS] = { 0 };
    for (size_t i = 0; i < (size_t)yt->count; i++) {
        size_t src = 0;
        int inside = 1;
        for (int d = 0; d < nd; d++) {
            int c = coord[d] - op->pads[d];
            if (c < 0 || c >= xt->dims[d]) inside = 0;
            src = src * (size_t)xt->dims[d] + (size_t)(c < 0 ? 0 : c);
        }
        y[i] = inside ? x[src] : value;
        for (int d = nd - 1; d >= 0; d--) {
            if (++coord[d] < yt->dims[d]) break;
            coord[d] = 0;
        }
    }
}

static void ref_unary(const nn_tfl_op *op, const float *x, size_t n, float *y)
{
    for (size_t i = 0; i < n; i++) {
        float v = x[i];
        switch (op->code) {
        case NN_TFL_LEAKY_RELU: y[i] = v >= 0 ? v : v * op->alpha; break;
        case NN_TFL_RELU: y[i] = v > 0 ? v : 0; break;
        case NN_TFL_RELU6: y[i] = v < 0 ? 0 : v > 6 ? 6 : v; break;
        case NN_TFL_LOGISTIC: y[i] = (float)(1.0 / (1.0 + exp(-(double)v))); break;
        case NN_TFL_TANH: y[i] = (float)tanh((double)v); break;
        default: y[i] = v; break; /* RESHAPE */
        }
    }
}

/* Whether op input j is read as float data (the others are int shapes, sizes or paddings). */
static int reads_floats(const nn_tfl_op *op, int j)
{
    switch (op->code) {
    case NN_TFL_TRANSPOSE_CONV: return j >= 1;
    case NN_TFL_CONV_2D: case NN_TFL_DEPTHWISE_CONV_2D: return j <= 2;
    case NN_TFL_ADD: case NN_TFL_SUB: case NN_TFL_MUL: case NN_TFL_MAXIMUM: case NN_TFL_MINIMUM: return j <= 1;
    case NN_TFL_CONCATENATION: return 1;
    default: return j == 0;
    }
}

/* An integer graph input gets real values (tflite.h): stored as round(x / scale) + zero point,
 * clamped to the type (what a TFLite caller does before feeding the model). */
static void quantize_input(const nn_tfl_tensor *t, const float *x, float *q)
{
    for (size_t i = 0; i < (size_t)t->count; i++) {
        float r = roundf(x[i] / t->scales[0]);
        r = r == r ? r : 0;
        float v = r + (float)t->zero_point;
        q[i] = v < nn_tfl_qmin(t) ? (float)nn_tfl_qmin(t) : v > nn_tfl_qmax(t) ? (float)nn_tfl_qmax(t) : v;
    }
}

pg_status nn_tfl_ref_run(const nn_tfl_model *m, const float *input, float **out, int num_outputs)
{
    if (num_outputs < 0 || num_outputs > m->num_outputs) return pg_fail(PG_ERR_ARG, "reference run: %d outputs asked, the model has %d", num_outputs, m->num_outputs);
    if (m->num_inputs != 1) return pg_fail(PG_ERR_ARG, "reference run: the model has %d inputs (1 supported)", m->num_inputs);
    float **buf = pg_calloc((size_t)m->num_tensors, sizeof(float *), "reference buffers");
    int *last = pg_malloc((size_t)m->num_tensors * sizeof(int), "reference last use");
    pg_status st = PG_OK;
    if (!buf || !last) st = PG_ERR_NOMEM;
    /* constants are read in place; an activation is freed after its last reader */
    for (int i = 0; !st && i < m->num_tensors; i++) {
        last[i] = -1;
        buf[i] = m->tensors[i].values;
    }
    for (int k = 0; !st && k < m->num_ops; k++)
        for (int j = 0; j < m->ops[k].num_inputs; j++)
            if (m->ops[k].inputs[j] >= 0) last[m->ops[k].inputs[j]] = k;
    for (int j = 0; !st && j < m->num_outputs; j++) last[m->outputs[j]] = m->num_ops;
    if (!st) {
        const nn_tfl_tensor *it = &m->tensors[m->inputs[0]];
        buf[m->inputs[0]] = pg_malloc((size_t)it->count * sizeof(float), "reference input");
        if (!buf[m->inputs[0]]) st = PG_ERR_NOMEM;
        else if (!nn_tfl_is_quantized(it)) memcpy(buf[m->inputs[0]], input, (size_t)it->count * sizeof(float));
        else quantize_input(it, input, buf[m->inputs[0]]);
    }
    for (int k = 0; !st && k < m->num_ops; k++) {
        const nn_tfl_op *op = &m->ops[k];
        /* a file may order its ops so that one reads what nothing wrote yet, or write a constant */
        for (int j = 0; j < op->num_inputs && !st; j++) {
            int t = op->inputs[j];
            if (t < 0) continue;
            if (t == op->output)
                st = pg_fail(PG_ERR_FORMAT, "reference run: op %d reads tensor %d that it also writes", k, t);
            else if (!buf[t] && !nn_tfl_is_const(&m->tensors[t]))
                st = pg_fail(PG_ERR_FORMAT, "reference run: op %d reads tensor %d before anything writes it", k, t);
            else if (!buf[t] && reads_floats(op, j))
                st = pg_fail(PG_ERR_FORMAT, "reference run: op %d reads the integer tensor %d as floats", k, t);
        }
        if (!st && nn_tfl_is_const(&m->tensors[op->output]))
            st = pg_fail(PG_ERR_FORMAT, "reference run: op %d writes the constant tensor %d", k, op->output);
        if (st) break;
        const nn_tfl_tensor *yt = &m->tensors[op->output], *t0 = &m->tensors[op->inputs[0]];
        free(buf[op->output]); /* written twice: the earlier value is dead */
        float *y = pg_malloc((size_t)yt->count * sizeof(float), "reference activation");
        if (!y) {
            st = PG_ERR_NOMEM;
            break;
        }
        buf[op->output] = y;
        const float *b2 = op->num_inputs > 2 && op->inputs[2] >= 0 ? buf[op->inputs[2]] : NULL;
        if (nn_tfl_op_is_integer(m, op)) st = nn_tfl_ref_int_op(m, op, buf, y);
        else switch (op->code) {
        case NN_TFL_CONV_2D:
            ref_conv(op, t0, &m->tensors[op->inputs[1]], buf[op->inputs[0]], buf[op->inputs[1]], b2, yt, y);
            break;
        case NN_TFL_DEPTHWISE_CONV_2D:
            ref_depthwise(op, t0, &m->tensors[op->inputs[1]], buf[op->inputs[0]], buf[op->inputs[1]], b2, yt, y);
            break;
        case NN_TFL_TRANSPOSE_CONV:
            st = ref_transpose_conv(op, &m->tensors[op->inputs[2]], &m->tensors[op->inputs[1]], buf[op->inputs[2]],
                                    buf[op->inputs[1]], op->num_inputs > 3 && op->inputs[3] >= 0 ? buf[op->inputs[3]] : NULL, yt, y);
            break;
        case NN_TFL_ADD: case NN_TFL_SUB: case NN_TFL_MUL: case NN_TFL_MAXIMUM: case NN_TFL_MINIMUM:
            ref_binary(op, t0, buf[op->inputs[0]], &m->tensors[op->inputs[1]], buf[op->inputs[1]], yt, y);
            break;
        case NN_TFL_CONCATENATION:
            ref_concat(op, m, buf, yt, y);
            break;
        case NN_TFL_STRIDED_SLICE:
            ref_slice(op, t0, buf[op->inputs[0]], y);
            break;
        case NN_TFL_RESIZE_BILINEAR:
            ref_resize(op, t0, buf[op->inputs[0]], yt, y);
            break;
        case NN_TFL_RESIZE_NEAREST_NEIGHBOR:
            ref_resize_nearest(op, t0, buf[op->inputs[0]], yt, y);
            break;
        case NN_TFL_PAD:
            ref_pad(op, t0, buf[op->inputs[0]], yt, nn_tfl_is_quantized(yt) ? (float)yt->zero_point : 0.0f, y);
            break;
        default:
            ref_unary(op, buf[op->inputs[0]], (size_t)yt->count, y);
            break;
        }
        for (int j = 0; j < op->num_inputs; j++) {
            int t = op->inputs[j];
            if (t >= 0 && last[t] == k && !nn_tfl_is_const(&m->tensors[t]) && buf[t]) {
                free(buf[t]);
                buf[t] = NULL;
                last[t] = -2; /* freed (a tensor read twice by one op is freed once) */
            }
        }
    }
    for (int j = 0; !st && j < num_outputs; j++) {
        if (!buf[m->outputs[j]]) {
            st = pg_fail(PG_ERR_FORMAT, "reference run: output tensor %d is never computed", m->outputs[j]);
            break;
        }
        const nn_tfl_tensor *ot = &m->tensors[m->outputs[j]];
        for (size_t i = 0; i < (size_t)ot->count; i++)
            out[j][i] = nn_tfl_is_quantized(ot) ? (float)((double)ot->scales[0] * (buf[m->outputs[j]][i] - ot->zero_point))
                                                : buf[m->outputs[j]][i];
    }
    for (int i = 0; buf && i < m->num_tensors; i++)
        if (!nn_tfl_is_const(&m->tensors[i])) free(buf[i]);
    free(buf);
    free(last);
    return st;
}
