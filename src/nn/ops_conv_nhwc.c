/* ops_conv_nhwc.c - the NHWC convolution of the TFLite front end's graphs (group 1, any kernel,
 * stride, dilation, padding): im2col + GEMM whose patch rows copy contiguous runs.
 *
 * In NHWC the C channels of one input pixel are contiguous, and for stride 1 so are the kW
 * pixels a kernel row covers. Ordering a patch row as (ky, kx, c) - the weights permuted to
 * OHWI to match - turns the gather into one memcpy per kernel row (kW * C floats) instead of
 * one strided store per value. Each thread permutes the weights into its scratch once per run,
 * then takes tiles of PT output pixels: col (PT, K) with K = kH*kW*C, y[tile, O] = col * w^T on
 * one thread's OpenBLAS call, bias and fused activation on the tile while it is in cache.
 * Threads write separate output rows (no atomics); nn_conv_reference (ops_conv.c) is the oracle
 * test_nn_tflite checks it against through the TFLite reference. */
#include "nn/nn_ops.h"

#include <omp.h>
#include <string.h>

#define NHWC_TILE_FLOATS ((size_t)1 << 18) /* col tile per thread: 1 MiB, about one core's L2 */

typedef struct {
    int N, C, H, W, O, OH, OW, kh, kw, sh, sw, dh, dw, pt, pl;
    size_t K;
} nhwc_geom;

static void geom(const nn_graph *g, const nn_node *n, nhwc_geom *q)
{
    const nn_tensor *x = &g->tensors[n->inputs[0]], *w = &g->tensors[n->inputs[1]], *y = &g->tensors[n->outputs[0]];
    const nn_attrs *a = &n->attr;
    q->N = (int)x->dims[0], q->H = (int)x->dims[1], q->W = (int)x->dims[2], q->C = (int)x->dims[3];
    q->O = (int)w->dims[0], q->kh = (int)w->dims[2], q->kw = (int)w->dims[3];
    q->OH = y->ndim == 4 ? (int)y->dims[1] : 0, q->OW = y->ndim == 4 ? (int)y->dims[2] : 0;
    q->sh = a->stride[0], q->sw = a->stride[1], q->dh = a->dilation[0], q->dw = a->dilation[1];
    q->pt = a->pads[0], q->pl = a->pads[1];
    q->K = (size_t)q->kh * q->kw * q->C;
}

static int tile_pixels(const nhwc_geom *q)
{
    size_t pt = NHWC_TILE_FLOATS / (q->K ? q->K : 1);
    if (pt < 32) pt = 32;
    size_t P = (size_t)q->OH * q->OW;
    return (int)(pt < P ? pt : P);
}

int nn_conv_nhwc_applies(const nn_graph *g, const nn_node *n)
{
    return n->attr.layout == NN_LAYOUT_NHWC && n->attr.group == 1 && g->tensors[n->inputs[0]].ndim == 4;
}

size_t nn_scratch_conv_nhwc(const nn_graph *g, const nn_node *n)
{
    nhwc_geom q;
    geom(g, n, &q);
    return q.K * (size_t)tile_pixels(&q) + q.K * (size_t)q.O;
}

/* col (len, K): output pixels [p0, p0 + len) of image ni, rows ordered (ky, kx, c). */
static void im2col_rows(float *col, const float *x, const nhwc_geom *q, int ni, int p0, int len)
{
    size_t C = (size_t)q->C, run = (size_t)q->kw * C;
    for (int p = 0; p < len; p++) {
        int oy = (p0 + p) / q->OW, ox = (p0 + p) % q->OW;
        float *dst = col + (size_t)p * q->K;
        int ix0 = ox * q->sw - q->pl;
        int row_inside = ix0 >= 0 && ix0 + (q->kw - 1) * q->dw < q->W && q->dw == 1;
        for (int i = 0; i < q->kh; i++, dst += run) {
            int iy = oy * q->sh - q->pt + i * q->dh;
            if (iy < 0 || iy >= q->H) {
                memset(dst, 0, run * sizeof(float));
                continue;
            }
            const float *xr = x + ((size_t)ni * q->H + iy) * q->W * C;
            if (row_inside) {
                memcpy(dst, xr + (size_t)ix0 * C, run * sizeof(float));
                continue;
            }
            for (int j = 0; j < q->kw; j++) {
                int ix = ix0 + j * q->dw;
                if (ix < 0 || ix >= q->W) memset(dst + j * C, 0, C * sizeof(float));
                else memcpy(dst + j * C, xr + (size_t)ix * C, C * sizeof(float));
            }
        }
    }
}

void nn_run_conv_nhwc(const nn_ctx *c, const nn_node *n)
{
    nhwc_geom q;
    geom(c->g, n, &q);
    const float *x = nn_in_data(c, n, 0), *w = nn_in_data(c, n, 1), *b = nn_in_data(c, n, 2);
    float *y = nn_out_data(c, n, 0);
    int P = q.OH * q.OW, pt = tile_pixels(&q);
    int T = omp_get_max_threads();
    /* at least two tiles per thread on small images, so both threads have work */
    int64_t want_tiles = 2 * (int64_t)T;
    if ((int64_t)q.N * ((P + pt - 1) / pt) < want_tiles) {
        int64_t per = (P * (int64_t)q.N + want_tiles - 1) / want_tiles;
        if (per >= 16 && per < pt) pt = (int)per;
    }
    int tiles = (P + pt - 1) / pt;
    int64_t jobs = (int64_t)q.N * tiles;
    const nn_attrs *a = &n->attr;
    int kk = q.kh * q.kw;
    #pragma omp parallel
    {
        float *col = c->scratch + (size_t)omp_get_thread_num() * c->scratch_floats;
        float *wp = col + q.K * (size_t)tile_pixels(&q); /* (O, kh, kw, C) */
        for (int o = 0; o < q.O; o++)
            for (int ch = 0; ch < q.C; ch++)
                for (int r = 0; r < kk; r++) wp[((size_t)o * kk + r) * q.C + ch] = w[((size_t)o * q.C + ch) * kk + r];
        #pragma omp for schedule(dynamic, 1)
        for (int64_t job = 0; job < jobs; job++) {
            int t = (int)(job % tiles), ni = (int)(job / tiles);
            int p0 = t * pt, len = P - p0 < pt ? P - p0 : pt;
            float *yt = y + ((size_t)ni * P + p0) * q.O;
            im2col_rows(col, x, &q, ni, p0, len);
            nn_sgemm1(0, 1, len, q.O, (int)q.K, col, (int)q.K, wp, (int)q.K, 0.0f, yt, q.O);
            for (int p = 0; p < len; p++) {
                float *row = yt + (size_t)p * q.O;
                if (b)
                    for (int o = 0; o < q.O; o++) row[o] += b[o];
                nn_apply_act(row, (size_t)q.O, a->act, a->act_alpha);
            }
        }
    }
}
