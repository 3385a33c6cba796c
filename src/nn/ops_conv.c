/* ops_conv.c - Conv and ConvTranspose, NCHW or NHWC activations, OIHW / IOHW weights, groups
 * (depthwise = group C), dilation, fused bias + activation.
 *
 * Conv is im2col + GEMM on tiles of output pixels: for each (image n, group g, tile of PT output
 * pixels) a thread gathers the patch matrix col (Kg, PT) (Kg = Cg * kH * kW) into its scratch and
 * multiplies: NCHW  y[Og, tile] = w[Og, Kg] * col[Kg, tile];  NHWC  y[tile, Og] = col[tile, Kg] * w^T.
 * A 1x1 stride-1 unpadded NCHW conv skips the gather. ConvTranspose is GEMM then col2im:
 * col[Og*kH*kW, H*W] = w_g^T * x_g, then each output channel sums its own taps (threads split by
 * channel, no atomics). nn_conv_reference is the naive loop the tests compare against.
 */
#include "nn/nn_ops.h"

#include <omp.h>
#include <string.h>

#define CONV_TILE_FLOATS ((size_t)1 << 19) /* col tile budget per thread: 2 MiB (measured best of 128 KiB..8 MiB) */

typedef struct {
    int N, C, H, W, O, OH, OW;
    int kh, kw, sh, sw, dh, dw, pt, pl, pb, pr, G, Cg, Og;
    int nhwc;
} conv_geom;

static void get_geom(const nn_graph *g, const nn_node *n, conv_geom *q, int transpose)
{
    const nn_tensor *x = &g->tensors[n->inputs[0]], *w = &g->tensors[n->inputs[1]], *y = &g->tensors[n->outputs[0]];
    const nn_attrs *a = &n->attr;
    q->nhwc = a->layout == NN_LAYOUT_NHWC;
    q->N = (int)x->dims[0];
    q->C = (int)(q->nhwc ? x->dims[3] : x->dims[1]);
    q->H = (int)(q->nhwc ? x->dims[1] : x->dims[2]);
    q->W = (int)(q->nhwc ? x->dims[2] : x->dims[3]);
    if (y->ndim == 4) {
        q->O = (int)(q->nhwc ? y->dims[3] : y->dims[1]);
        q->OH = (int)(q->nhwc ? y->dims[1] : y->dims[2]);
        q->OW = (int)(q->nhwc ? y->dims[2] : y->dims[3]);
    }
    q->kh = (int)w->dims[2]; q->kw = (int)w->dims[3];
    q->sh = a->stride[0]; q->sw = a->stride[1];
    q->dh = a->dilation[0]; q->dw = a->dilation[1];
    q->pt = a->pads[0]; q->pl = a->pads[1]; q->pb = a->pads[2]; q->pr = a->pads[3];
    q->G = a->group;
    q->Cg = q->C / (q->G ? q->G : 1);
    q->Og = transpose ? (int)w->dims[1] : (int)w->dims[0] / (q->G ? q->G : 1);
}

static pg_status check_conv(nn_graph *g, nn_node *n, int transpose, conv_geom *q)
{
    nn_tensor *x = nn_in(g, n, 0), *w = nn_in(g, n, 1), *b = nn_in(g, n, 2);
    const nn_attrs *a = &n->attr;
    if (x->ndim != 4 || w->ndim != 4) return nn_node_fail(n, "only 2-D convolutions (4-D input and weight)");
    if (a->group < 1 || a->stride[0] < 1 || a->stride[1] < 1 || a->dilation[0] < 1 || a->dilation[1] < 1)
        return nn_node_fail(n, "group, strides and dilations must be >= 1");
    for (int i = 0; i < 4; i++) if (a->pads[i] < 0 || a->pads[i] > 65536) return nn_node_fail(n, "bad pads");
    if (a->kernel[0] && (a->kernel[0] != w->dims[2] || a->kernel[1] != w->dims[3]))
        return nn_node_fail(n, "kernel_shape disagrees with the weight");
    get_geom(g, n, q, transpose);
    if (q->C % a->group) return nn_node_fail(n, "%d channels not divisible by group %d", q->C, a->group);
    if (!transpose) {
        if (w->dims[1] != q->Cg || w->dims[0] % a->group)
            return nn_node_fail(n, "weight (%lld, %lld, ...) does not fit %d input channels in %d groups",
                                (long long)w->dims[0], (long long)w->dims[1], q->C, a->group);
        q->O = (int)w->dims[0];
    } else {
        if (w->dims[0] != q->C) return nn_node_fail(n, "weight has %lld input channels, input %d", (long long)w->dims[0], q->C);
        q->O = q->Og * a->group;
    }
    if (b && nn_shape_count(b->ndim, b->dims) != q->O) return nn_node_fail(n, "bias has %lld values for %d channels",
                                                                         (long long)nn_shape_count(b->ndim, b->dims), q->O);
    if ((int64_t)q->Cg * q->kh * q->kw > NN_MAX_ELEMENTS / 64) return nn_node_fail(n, "kernel too large");
    return PG_OK;
}

static pg_status set_conv_output(nn_graph *g, nn_node *n, const conv_geom *q, int64_t oh, int64_t ow)
{
    if (oh < 1 || ow < 1) return nn_node_fail(n, "output would be %lld x %lld", (long long)oh, (long long)ow);
    int64_t dims[4] = { q->N, q->O, oh, ow };
    if (q->nhwc) { dims[1] = oh; dims[2] = ow; dims[3] = q->O; }
    return nn_set_output(g, n, 0, 4, dims);
}

pg_status nn_infer_conv(nn_graph *g, nn_node *n)
{
    conv_geom q;
    PG_TRY(check_conv(g, n, 0, &q));
    int64_t eh = (int64_t)q.dh * (q.kh - 1) + 1, ew = (int64_t)q.dw * (q.kw - 1) + 1;
    int64_t oh = ((int64_t)q.H + q.pt + q.pb - eh) / q.sh + 1, ow = ((int64_t)q.W + q.pl + q.pr - ew) / q.sw + 1;
    if ((int64_t)q.H + q.pt + q.pb < eh || (int64_t)q.W + q.pl + q.pr < ew) oh = ow = 0;
    return set_conv_output(g, n, &q, oh, ow);
}

pg_status nn_infer_conv_transpose(nn_graph *g, nn_node *n)
{
    conv_geom q;
    PG_TRY(check_conv(g, n, 1, &q));
    const nn_attrs *a = &n->attr;
    if (a->output_padding[0] < 0 || a->output_padding[1] < 0 || a->output_padding[0] >= a->stride[0] || a->output_padding[1] >= a->stride[1])
        return nn_node_fail(n, "output_padding must be in [0, stride)");
    int64_t oh = (int64_t)(q.H - 1) * q.sh - q.pt - q.pb + (int64_t)q.dh * (q.kh - 1) + a->output_padding[0] + 1;
    int64_t ow = (int64_t)(q.W - 1) * q.sw - q.pl - q.pr + (int64_t)q.dw * (q.kw - 1) + a->output_padding[1] + 1;
    return set_conv_output(g, n, &q, oh, ow);
}

/* Output pixels per tile so a (Kg, PT) col fits the budget. */
static int conv_tile(const conv_geom *q)
{
    size_t K = (size_t)q->Cg * q->kh * q->kw;
    size_t pt = CONV_TILE_FLOATS / (K ? K : 1);
    pt = pt / 16 * 16;
    if (pt < 16) pt = 16;
    size_t P = (size_t)q->OH * q->OW;
    return (int)(pt < P ? pt : P);
}

size_t nn_scratch_conv(const nn_graph *g, const nn_node *n)
{
    if (nn_conv_nhwc_applies(g, n)) return nn_scratch_conv_nhwc(g, n); /* ops_conv_nhwc.c (nn-tflite) */
    if (nn_conv_depthwise_applies(g, n)) return nn_scratch_conv_depthwise(g, n);
    conv_geom q;
    get_geom(g, n, &q, 0);
    return (size_t)q.Cg * q.kh * q.kw * (size_t)conv_tile(&q);
}

size_t nn_scratch_conv_transpose(const nn_graph *g, const nn_node *n)
{
    conv_geom q;
    get_geom(g, n, &q, 1);
    return (size_t)q.Og * q.kh * q.kw * (size_t)q.H * q.W;
}

/* col (Kg, len) for output pixels [p0, p0 + len) of image n, group g (NCHW input): row k = (c, i, j)
 * of the kernel, walked one output row at a time; with stride 1 the inside of a row is one memcpy. */
static void im2col_nchw(float *col, const float *x, const conv_geom *q, int n, int g, int p0, int len)
{
    int K = q->Cg * q->kh * q->kw;
    for (int k = 0; k < K; k++) {
        int c = k / (q->kh * q->kw), r = k % (q->kh * q->kw), i = r / q->kw, j = r % q->kw;
        const float *xc = x + ((size_t)n * q->C + (size_t)g * q->Cg + c) * q->H * q->W;
        float *dst = col + (size_t)k * len;
        int oy = p0 / q->OW, ox0 = p0 % q->OW;
        for (int p = 0; p < len; oy++, ox0 = 0) {
            int run = q->OW - ox0 < len - p ? q->OW - ox0 : len - p;
            int iy = oy * q->sh - q->pt + i * q->dh;
            float *d = dst + p;
            p += run;
            if (iy < 0 || iy >= q->H) { memset(d, 0, (size_t)run * sizeof(float)); continue; }
            const float *xr = xc + (size_t)iy * q->W;
            int ixb = ox0 * q->sw - q->pl + j * q->dw;
            if (q->sw == 1) {
                int lo = ixb < 0 ? -ixb : 0, hi = q->W - ixb < run ? q->W - ixb : run;
                if (lo > run) lo = run;
                if (hi < lo) hi = lo;
                if (lo) memset(d, 0, (size_t)lo * sizeof(float));
                if (hi > lo) memcpy(d + lo, xr + ixb + lo, (size_t)(hi - lo) * sizeof(float));
                if (run > hi) memset(d + hi, 0, (size_t)(run - hi) * sizeof(float));
            } else {
                for (int t = 0; t < run; t++) {
                    int ix = ixb + t * q->sw;
                    d[t] = ix >= 0 && ix < q->W ? xr[ix] : 0.0f;
                }
            }
        }
    }
}

/* col (len, Kg) row-major for NHWC input; column order (c, i, j) matches OIHW weights. */
static void im2col_nhwc(float *col, const float *x, const conv_geom *q, int n, int g, int p0, int len)
{
    int K = q->Cg * q->kh * q->kw, kk = q->kh * q->kw;
    for (int p = 0; p < len; p++) {
        int oy = (p0 + p) / q->OW, ox = (p0 + p) % q->OW;
        float *dst = col + (size_t)p * K;
        for (int i = 0; i < q->kh; i++)
            for (int j = 0; j < q->kw; j++) {
                int iy = oy * q->sh - q->pt + i * q->dh, ix = ox * q->sw - q->pl + j * q->dw;
                int inside = iy >= 0 && iy < q->H && ix >= 0 && ix < q->W;
                const float *xp = x + (((size_t)n * q->H + (inside ? iy : 0)) * q->W + (inside ? ix : 0)) * q->C + (size_t)g * q->Cg;
                for (int c = 0; c < q->Cg; c++) dst[c * kk + i * q->kw + j] = inside ? xp[c] : 0.0f;
            }
    }
}

void nn_run_conv(const nn_ctx *c, const nn_node *n)
{
    if (nn_conv_nhwc_applies(c->g, n)) { nn_run_conv_nhwc(c, n); return; } /* ops_conv_nhwc.c (nn-tflite) */
    if (nn_conv_depthwise_applies(c->g, n)) { nn_run_conv_depthwise(c, n); return; }
    conv_geom q;
    get_geom(c->g, n, &q, 0);
    const float *x = nn_in_data(c, n, 0), *w = nn_in_data(c, n, 1), *b = nn_in_data(c, n, 2);
    float *y = nn_out_data(c, n, 0);
    int P = q.OH * q.OW, K = q.Cg * q.kh * q.kw;
    int T = omp_get_max_threads();
    int pt = conv_tile(&q);
    /* equal tiles, their count a multiple of the threads when (image, group) jobs are few */
    int64_t jobs_ng = (int64_t)q.N * q.G;
    int tiles = (P + pt - 1) / pt;
    if (jobs_ng < 4 * T) {
        int per = (tiles + T - 1) / T * T;
        int want = ((P + per - 1) / per + 15) / 16 * 16;
        if (want >= 64 && want <= pt) pt = want;
        tiles = (P + pt - 1) / pt;
    }
    int direct = !q.nhwc && q.kh == 1 && q.kw == 1 && q.sh == 1 && q.sw == 1 && !q.pt && !q.pl && !q.pb && !q.pr;
    int64_t jobs = jobs_ng * tiles;
    const nn_attrs *a = &n->attr;
    #pragma omp parallel for schedule(dynamic, 1) if (2.0 * q.N * q.O * (double)P * K >= NN_PAR_FLOPS)
    for (int64_t job = 0; job < jobs; job++) {
        int t = (int)(job % tiles), gi = (int)(job / tiles % q.G), ni = (int)(job / tiles / q.G);
        int p0 = t * pt, len = P - p0 < pt ? P - p0 : pt;
        float *col = c->scratch + (size_t)omp_get_thread_num() * c->scratch_floats;
        const float *wg = w + (size_t)gi * q.Og * K;
        if (!q.nhwc) {
            float *yt = y + ((size_t)ni * q.O + (size_t)gi * q.Og) * P + p0;
            if (direct)
                nn_sgemm1(0, 0, q.Og, len, K, wg, K, x + ((size_t)ni * q.C + (size_t)gi * q.Cg) * P + p0, P, 0.0f, yt, P);
            else {
                im2col_nchw(col, x, &q, ni, gi, p0, len);
                nn_sgemm1(0, 0, q.Og, len, K, wg, K, col, len, 0.0f, yt, P);
            }
            for (int o = 0; o < q.Og; o++) {
                float *row = yt + (size_t)o * P;
                if (b) { float bv = b[gi * q.Og + o]; for (int p = 0; p < len; p++) row[p] += bv; }
                nn_apply_act(row, (size_t)len, a->act, a->act_alpha);
            }
        } else {
            float *yt = y + ((size_t)ni * P + p0) * q.O + (size_t)gi * q.Og;
            im2col_nhwc(col, x, &q, ni, gi, p0, len);
            nn_sgemm1(0, 1, len, q.Og, K, col, K, wg, K, 0.0f, yt, q.O);
            for (int p = 0; p < len; p++) {
                float *row = yt + (size_t)p * q.O;
                if (b) for (int o = 0; o < q.Og; o++) row[o] += b[gi * q.Og + o];
                nn_apply_act(row, (size_t)q.Og, a->act, a->act_alpha);
            }
        }
    }
}

void nn_run_conv_transpose(const nn_ctx *c, const nn_node *n)
{
    conv_geom q;
    get_geom(c->g, n, &q, 1);
    const float *x = nn_in_data(c, n, 0), *w = nn_in_data(c, n, 1), *b = nn_in_data(c, n, 2);
    float *y = nn_out_data(c, n, 0);
    int HW = q.H * q.W, kk = q.kh * q.kw, R = q.Og * kk, OP = q.OH * q.OW;
    float *col = c->scratch; /* (R, HW) for NCHW, (HW, R) for NHWC */
    const nn_attrs *a = &n->attr;
    for (int ni = 0; ni < q.N; ni++)
        for (int gi = 0; gi < q.G; gi++) {
            const float *wg = w + (size_t)gi * q.Cg * R; /* (Cg, Og*kh*kw) */
            if (!q.nhwc)
                nn_sgemm(1, 0, R, HW, q.Cg, wg, R, x + ((size_t)ni * q.C + (size_t)gi * q.Cg) * HW, HW, 0.0f, col, HW);
            else
                nn_sgemm(0, 0, HW, R, q.Cg, x + (size_t)ni * HW * q.C + (size_t)gi * q.Cg, q.C, wg, R, 0.0f, col, R);
            #pragma omp parallel for schedule(static) if ((int64_t)q.Og * (OP + (int64_t)kk * HW) >= NN_PAR_COMPUTE)
            for (int o = 0; o < q.Og; o++) {
                int oc = gi * q.Og + o;
                float bv = b ? b[oc] : 0.0f;
                /* the output plane of channel oc, strided for NHWC */
                size_t ystride = q.nhwc ? (size_t)q.O : 1;
                float *yp = q.nhwc ? y + (size_t)ni * OP * q.O + oc : y + ((size_t)ni * q.O + oc) * OP;
                for (int p = 0; p < OP; p++) yp[p * ystride] = bv;
                for (int i = 0; i < q.kh; i++)
                    for (int j = 0; j < q.kw; j++) {
                        int r = o * kk + i * q.kw + j;
                        for (int iy = 0; iy < q.H; iy++) {
                            int oy = iy * q.sh - q.pt + i * q.dh;
                            if (oy < 0 || oy >= q.OH) continue;
                            for (int ix = 0; ix < q.W; ix++) {
                                int ox = ix * q.sw - q.pl + j * q.dw;
                                if (ox < 0 || ox >= q.OW) continue;
                                float v = q.nhwc ? col[((size_t)iy * q.W + ix) * R + r] : col[(size_t)r * HW + (size_t)iy * q.W + ix];
                                yp[((size_t)oy * q.OW + ox) * ystride] += v;
                            }
                        }
                    }
                if (a->act != NN_ACT_NONE)
                    for (int p = 0; p < OP; p++) nn_apply_act(yp + p * ystride, 1, a->act, a->act_alpha);
            }
        }
}

void nn_conv_reference(float *y, const float *x, const float *w, const float *b, int N, int C, int H, int W,
                       int O, int OH, int OW, const nn_attrs *a)
{
    int G = a->group, Cg = C / G, Og = O / G, kh = a->kernel[0], kw = a->kernel[1];
    for (int n = 0; n < N; n++)
        for (int o = 0; o < O; o++)
            for (int oy = 0; oy < OH; oy++)
                for (int ox = 0; ox < OW; ox++) {
                    double s = b ? b[o] : 0.0;
                    int g = o / Og;
                    for (int c = 0; c < Cg; c++)
                        for (int i = 0; i < kh; i++)
                            for (int j = 0; j < kw; j++) {
                                int iy = oy * a->stride[0] - a->pads[0] + i * a->dilation[0];
                                int ix = ox * a->stride[1] - a->pads[1] + j * a->dilation[1];
                                if (iy < 0 || iy >= H || ix < 0 || ix >= W) continue;
                                s += (double)w[(((size_t)o * Cg + c) * kh + i) * kw + j] *
                                     x[(((size_t)n * C + g * Cg + c) * H + iy) * W + ix];
                            }
                    y[(((size_t)n * O + o) * OH + oy) * OW + ox] = (float)s;
                }
}
