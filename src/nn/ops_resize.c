/* ops_resize.c - Resize of the two spatial dims (NCHW or NHWC): nearest (all ONNX rounding modes),
 * bilinear and bicubic (Keys kernel with coefficient a, taps clamped to the edge or, with
 * exclude_outside, dropped and renormalised), with every ONNX coordinate_transformation_mode
 * except tf_crop_and_resize. Each output coordinate gets up to 4 source indices and weights per
 * axis (a table in scratch); the image loop is the same for all modes. */
#include "nn/nn_ops.h"

#include <math.h>

pg_status nn_infer_resize(nn_graph *g, nn_node *n)
{
    nn_tensor *x = nn_in(g, n, 0);
    const nn_attrs *a = &n->attr;
    if (x->ndim != 4) return nn_node_fail(n, "only 4-D inputs are resized");
    if (a->out_h < 1 || a->out_w < 1 || a->out_h > NN_MAX_DIM || a->out_w > NN_MAX_DIM)
        return nn_node_fail(n, "output size %d x %d", a->out_h, a->out_w);
    if (!(a->scale_h >= 0) || !(a->scale_w >= 0)) return nn_node_fail(n, "bad scales");
    int64_t dims[4] = { x->dims[0], x->dims[1], a->out_h, a->out_w };
    if (a->layout == NN_LAYOUT_NHWC) { dims[1] = a->out_h; dims[2] = a->out_w; dims[3] = x->dims[3]; }
    return nn_set_output(g, n, 0, 4, dims);
}

#define TAPS 4

size_t nn_scratch_resize(const nn_graph *g, const nn_node *n)
{
    (void)g;
    return 2 * TAPS * ((size_t)n->attr.out_h + (size_t)n->attr.out_w);
}

/* Source coordinate of output index o along an axis of in -> out samples. */
static double src_coord(const nn_attrs *a, int o, int in, int out, double scale)
{
    switch (a->coord_mode) {
    case NN_COORD_HALF_PIXEL: return (o + 0.5) / scale - 0.5;
    case NN_COORD_PYTORCH_HALF_PIXEL: return out > 1 ? (o + 0.5) / scale - 0.5 : 0.0;
    case NN_COORD_ALIGN_CORNERS: return out > 1 ? o * (double)(in - 1) / (out - 1) : 0.0;
    case NN_COORD_ASYMMETRIC: return o / scale;
    case NN_COORD_TF_HALF_PIXEL_FOR_NN: return (o + 0.5) / scale;
    }
    return 0.0;
}

static int nearest_index(const nn_attrs *a, double s, int in)
{
    if (!(s > -1)) s = -1; /* also NaN */
    if (s > in) s = in;
    double f = floor(s);
    int64_t i;
    switch (a->nearest_mode) {
    case NN_NEAREST_FLOOR: i = (int64_t)f; break;
    case NN_NEAREST_CEIL: i = (int64_t)ceil(s); break;
    case NN_NEAREST_ROUND_PREFER_CEIL: i = (int64_t)(s - f >= 0.5 ? f + 1 : f); break;
    default: i = (int64_t)(s - f > 0.5 ? f + 1 : f); break;
    }
    return (int)(i < 0 ? 0 : i > in - 1 ? in - 1 : i);
}

/* Keys cubic kernel at distance d (>= 0). */
static double cubic_w(double d, double A)
{
    if (d <= 1) return ((A + 2) * d - (A + 3)) * d * d + 1;
    if (d < 2) return ((A * d - 5 * A) * d + 8 * A) * d - 4 * A;
    return 0;
}

/* Per output index along one axis: TAPS source indices and weights (unused taps weight 0). */
static void axis_table(const nn_attrs *a, int in, int out, double scale, int *idx, float *w)
{
    for (int o = 0; o < out; o++) {
        int *ix = idx + (size_t)o * TAPS;
        float *wt = w + (size_t)o * TAPS;
        for (int k = 0; k < TAPS; k++) { ix[k] = 0; wt[k] = 0.0f; }
        double s = src_coord(a, o, in, out, scale);
        if (!(s == s)) s = 0; /* NaN */
        if (s < -2.0 * in - 4) s = -2.0 * in - 4;
        if (s > 2.0 * in + 4) s = 2.0 * in + 4;
        if (a->resize_mode == NN_RESIZE_NEAREST) {
            ix[0] = nearest_index(a, s, in);
            wt[0] = 1.0f;
        } else if (a->resize_mode == NN_RESIZE_LINEAR) {
            if (s < 0) s = 0;
            if (s > in - 1) s = in - 1;
            int f = (int)floor(s);
            ix[0] = f;
            ix[1] = f + 1 < in ? f + 1 : in - 1;
            wt[1] = (float)(s - f);
            wt[0] = 1.0f - wt[1];
        } else {
            int f = (int)floor(s);
            double t = s - f, sum = 0, ws[TAPS];
            for (int k = 0; k < TAPS; k++) {
                int i = f - 1 + k;
                ws[k] = cubic_w(fabs(t - (k - 1)), a->cubic_a);
                if (a->exclude_outside && (i < 0 || i >= in)) ws[k] = 0;
                sum += ws[k];
                ix[k] = i < 0 ? 0 : i > in - 1 ? in - 1 : i;
            }
            for (int k = 0; k < TAPS; k++) wt[k] = (float)(a->exclude_outside && sum != 0 ? ws[k] / sum : ws[k]);
        }
    }
}

void nn_run_resize(const nn_ctx *c, const nn_node *n)
{
    const nn_tensor *tx = nn_in(c->g, n, 0);
    const nn_attrs *a = &n->attr;
    const float *x = nn_in_data(c, n, 0);
    float *y = nn_out_data(c, n, 0);
    int nhwc = a->layout == NN_LAYOUT_NHWC;
    int N = (int)tx->dims[0], C = (int)(nhwc ? tx->dims[3] : tx->dims[1]);
    int H = (int)(nhwc ? tx->dims[1] : tx->dims[2]), W = (int)(nhwc ? tx->dims[2] : tx->dims[3]);
    int OH = a->out_h, OW = a->out_w;
    double sh = a->scale_h > 0 ? a->scale_h : (double)OH / H, sw = a->scale_w > 0 ? a->scale_w : (double)OW / W;
    /* the index and weight tables (nn_scratch_resize floats) sit in thread 0's scratch */
    float *wy = c->scratch, *wx = wy + (size_t)OH * TAPS;
    int *iy = (int *)(wx + (size_t)OW * TAPS), *ix = iy + (size_t)OH * TAPS;
    axis_table(a, H, OH, sh, iy, wy);
    axis_table(a, W, OW, sw, ix, wx);
    int taps = a->resize_mode == NN_RESIZE_NEAREST ? 1 : a->resize_mode == NN_RESIZE_LINEAR ? 2 : 4;
    int par = (int64_t)N * C * OH * OW * taps * taps >= NN_PAR_COMPUTE;
    if (!nhwc) {
        #pragma omp parallel for schedule(static) if (par)
        for (int64_t r = 0; r < (int64_t)N * C * OH; r++) {
            int oy = (int)(r % OH);
            int64_t plane = r / OH;
            const float *xp = x + plane * H * W;
            float *yr = y + r * OW;
            if (taps == 2) {
                /* bilinear: two rows, two taps each */
                const float *r0 = xp + (size_t)iy[oy * TAPS] * W, *r1 = xp + (size_t)iy[oy * TAPS + 1] * W;
                float w0 = wy[oy * TAPS], w1 = wy[oy * TAPS + 1];
                for (int ox = 0; ox < OW; ox++) {
                    int a0 = ix[ox * TAPS], a1 = ix[ox * TAPS + 1];
                    float u0 = wx[ox * TAPS], u1 = wx[ox * TAPS + 1];
                    yr[ox] = (r0[a0] * u0 + r0[a1] * u1) * w0 + (r1[a0] * u0 + r1[a1] * u1) * w1;
                }
                continue;
            }
            for (int ox = 0; ox < OW; ox++) {
                float v = 0;
                for (int ky = 0; ky < taps; ky++) {
                    const float *row = xp + (size_t)iy[oy * TAPS + ky] * W;
                    float h = 0;
                    for (int kx = 0; kx < taps; kx++) h += row[ix[ox * TAPS + kx]] * wx[ox * TAPS + kx];
                    v += h * wy[oy * TAPS + ky];
                }
                yr[ox] = v;
            }
        }
    } else {
        #pragma omp parallel for schedule(static) if (par)
        for (int64_t r = 0; r < (int64_t)N * OH; r++) {
            int oy = (int)(r % OH), ni = (int)(r / OH);
            for (int ox = 0; ox < OW; ox++) {
                float *yp = y + ((size_t)r * OW + ox) * C;
                for (int ch = 0; ch < C; ch++) yp[ch] = 0;
                for (int ky = 0; ky < taps; ky++)
                    for (int kx = 0; kx < taps; kx++) {
                        float w = wy[oy * TAPS + ky] * wx[ox * TAPS + kx];
                        const float *xp = x + (((size_t)ni * H + iy[oy * TAPS + ky]) * W + ix[ox * TAPS + kx]) * C;
                        for (int ch = 0; ch < C; ch++) yp[ch] += w * xp[ch];
                    }
            }
        }
    }
}
