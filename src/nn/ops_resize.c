/* ops_resize.c - Resize of the two spatial dims (NCHW or NHWC): nearest (all ONNX rounding modes)
 * and bilinear, with every ONNX coordinate_transformation_mode except tf_crop_and_resize. */
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

size_t nn_scratch_resize(const nn_graph *g, const nn_node *n)
{
    (void)g;
    return 3 * ((size_t)n->attr.out_h + (size_t)n->attr.out_w);
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

/* Per output index along one axis: the two source indices and the weight of the second. */
static void axis_table(const nn_attrs *a, int in, int out, double scale, int *i0, int *i1, float *t)
{
    for (int o = 0; o < out; o++) {
        double s = src_coord(a, o, in, out, scale);
        if (a->resize_mode == NN_RESIZE_NEAREST) {
            i0[o] = i1[o] = nearest_index(a, s, in);
            t[o] = 0.0f;
            continue;
        }
        if (!(s > 0)) s = 0; /* also NaN */
        if (s > in - 1) s = in - 1;
        int f = (int)floor(s);
        i0[o] = f;
        i1[o] = f + 1 < in ? f + 1 : in - 1;
        t[o] = (float)(s - f);
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
    float *ty = c->scratch, *tw = ty + OH;
    int *iy0 = (int *)(tw + OW), *iy1 = iy0 + OH, *ix0 = iy1 + OH, *ix1 = ix0 + OW;
    axis_table(a, H, OH, sh, iy0, iy1, ty);
    axis_table(a, W, OW, sw, ix0, ix1, tw);
    if (!nhwc) {
        #pragma omp parallel for schedule(static)
        for (int64_t r = 0; r < (int64_t)N * C * OH; r++) {
            int oy = (int)(r % OH);
            int64_t plane = r / OH;
            const float *r0 = x + (plane * H + iy0[oy]) * W, *r1 = x + (plane * H + iy1[oy]) * W;
            float *yr = y + r * OW, wy = ty[oy];
            for (int ox = 0; ox < OW; ox++) {
                float top = r0[ix0[ox]] + (r0[ix1[ox]] - r0[ix0[ox]]) * tw[ox];
                float bot = r1[ix0[ox]] + (r1[ix1[ox]] - r1[ix0[ox]]) * tw[ox];
                yr[ox] = top + (bot - top) * wy;
            }
        }
    } else {
        #pragma omp parallel for schedule(static)
        for (int64_t r = 0; r < (int64_t)N * OH; r++) {
            int oy = (int)(r % OH), ni = (int)(r / OH);
            const float *r0 = x + ((size_t)ni * H + iy0[oy]) * W * C, *r1 = x + ((size_t)ni * H + iy1[oy]) * W * C;
            float wy = ty[oy];
            for (int ox = 0; ox < OW; ox++) {
                float *yp = y + ((size_t)r * OW + ox) * C;
                const float *a0 = r0 + (size_t)ix0[ox] * C, *a1 = r0 + (size_t)ix1[ox] * C;
                const float *b0 = r1 + (size_t)ix0[ox] * C, *b1 = r1 + (size_t)ix1[ox] * C;
                for (int ch = 0; ch < C; ch++) {
                    float top = a0[ch] + (a1[ch] - a0[ch]) * tw[ox], bot = b0[ch] + (b1[ch] - b0[ch]) * tw[ox];
                    yp[ch] = top + (bot - top) * wy;
                }
            }
        }
    }
}
