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

#include "deform/gemm_amx.h"

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

/* The bf16 product's operands per thread, in floats: the tile's patches as bf16 rows (Mp, Kp), its
 * f32 product (Mp, Np), and the weights as bf16 VNNI pairs (Kp/2, Np, 2), packed once per run by
 * one thread and read by all from thread 0's scratch. */
static size_t bf16_floats(const nhwc_geom *q, size_t *a_off, size_t *c_off, size_t *w_off)
{
    size_t Mp = (size_t)gemm_amx_round(tile_pixels(q)), Kp = (size_t)gemm_amx_round((int)q->K);
    size_t Np = (size_t)gemm_amx_round(q->O);
    size_t base = q->K * (size_t)tile_pixels(q) + q->K * (size_t)q->O;
    *a_off = base;
    *c_off = *a_off + Mp * Kp / 2;
    *w_off = *c_off + Mp * Np;
    return *w_off + Kp * Np / 2 - base;
}

size_t nn_scratch_conv_nhwc(const nn_graph *g, const nn_node *n)
{
    nhwc_geom q;
    geom(g, n, &q);
    size_t a, c, w;
    return q.K * (size_t)tile_pixels(&q) + q.K * (size_t)q.O + bf16_floats(&q, &a, &c, &w);
}

static inline void to_bf16(uint16_t *dst, const float *src, size_t n)
{
    #pragma omp simd
    for (size_t i = 0; i < n; i++) dst[i] = gemm_amx_bf16(src[i]);
}

/* n values at element k of a patch row, f32 (colf) or bf16 (colh); src NULL: zeros. */
static inline void put_run(float *colf, uint16_t *colh, size_t k, const float *src, size_t n)
{
    if (colh) {
        if (src) to_bf16(colh + k, src, n);
        else memset(colh + k, 0, n * sizeof(uint16_t));
    } else {
        if (src) memcpy(colf + k, src, n * sizeof(float));
        else memset(colf + k, 0, n * sizeof(float));
    }
}

/* Patch rows of output pixels [p0, p0 + len) of image ni, ordered (ky, kx, c), ld elements apart:
 * f32 into colf (ld = K, rows = len), or bf16 into colh (the A operand of gemm_bf16: ld and rows
 * padded to 32, zero past K and past len). */
static void im2col_rows(float *colf, uint16_t *colh, int ld, int rows, const float *x, const nhwc_geom *q, int ni,
                        int p0, int len)
{
    size_t C = (size_t)q->C, run = (size_t)q->kw * C;
    for (int p = 0; p < rows; p++) {
        size_t at = (size_t)p * ld;
        if (p >= len) {
            put_run(colf, colh, at, NULL, (size_t)ld);
            continue;
        }
        int oy = (p0 + p) / q->OW, ox = (p0 + p) % q->OW;
        int ix0 = ox * q->sw - q->pl;
        int row_inside = ix0 >= 0 && ix0 + (q->kw - 1) * q->dw < q->W && q->dw == 1;
        for (int i = 0; i < q->kh; i++) {
            size_t k = at + (size_t)i * run;
            int iy = oy * q->sh - q->pt + i * q->dh;
            if (iy < 0 || iy >= q->H) {
                put_run(colf, colh, k, NULL, run);
                continue;
            }
            const float *xr = x + ((size_t)ni * q->H + iy) * q->W * C;
            if (row_inside) {
                put_run(colf, colh, k, xr + (size_t)ix0 * C, run);
                continue;
            }
            for (int j = 0; j < q->kw; j++) {
                int ix = ix0 + j * q->dw;
                put_run(colf, colh, k + j * C, ix < 0 || ix >= q->W ? NULL : xr + (size_t)ix * C, C);
            }
        }
        if ((size_t)ld > q->K) put_run(colf, colh, at + q->K, NULL, (size_t)ld - q->K);
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
    const int bf16 = nn_conv_bf16();
    size_t a_off, c_off, w_off;
    bf16_floats(&q, &a_off, &c_off, &w_off);
    const int Kp = gemm_amx_round((int)q.K), Np = gemm_amx_round(q.O);
    const uint16_t *wv = (const uint16_t *)(c->scratch + w_off); /* thread 0's packed weights */
    #pragma omp parallel
    {
        float *col = c->scratch + (size_t)omp_get_thread_num() * c->scratch_floats;
        float *wp = col + q.K * (size_t)tile_pixels(&q); /* (O, kh, kw, C) */
        for (int o = 0; o < q.O; o++)
            for (int ch = 0; ch < q.C; ch++)
                for (int r = 0; r < kk; r++) wp[((size_t)o * kk + r) * q.C + ch] = w[((size_t)o * q.C + ch) * kk + r];
        if (bf16) {
            #pragma omp single
            gemm_amx_pack_b((uint16_t *)wv, wp, 1, (long)q.K, (int)q.K, q.O); /* b(k, o) = wp[o][k] */
        }
        uint16_t *abf = (uint16_t *)(col + a_off);
        float *cbuf = col + c_off;
        #pragma omp for schedule(dynamic, 1)
        for (int64_t job = 0; job < jobs; job++) {
            int t = (int)(job % tiles), ni = (int)(job / tiles);
            int p0 = t * pt, len = P - p0 < pt ? P - p0 : pt;
            float *yt = y + ((size_t)ni * P + p0) * q.O;
            if (bf16) {
                /* bf16 patches times bf16 weights, summed in f32, into the padded product, then
                 * its O columns into the output */
                const int Mp = gemm_amx_round(len);
                im2col_rows(NULL, abf, Kp, Mp, x, &q, ni, p0, len);
                gemm_amx_epilogue e;
                memset(&e, 0, sizeof e);
                e.c = cbuf;
                e.ldc = Np;
                gemm_bf16(abf, Kp, wv, 2 * Np, Mp, Np, Kp, &e);
                for (int p = 0; p < len; p++) memcpy(yt + (size_t)p * q.O, cbuf + (size_t)p * Np, (size_t)q.O * sizeof(float));
            } else {
                im2col_rows(col, NULL, (int)q.K, len, x, &q, ni, p0, len);
                nn_sgemm1(0, 1, len, q.O, (int)q.K, col, (int)q.K, wp, (int)q.K, 0.0f, yt, q.O);
            }
            for (int p = 0; p < len; p++) {
                float *row = yt + (size_t)p * q.O;
                if (b)
                    for (int o = 0; o < q.O; o++) row[o] += b[o];
                nn_apply_act(row, (size_t)q.O, a->act, a->act_alpha);
            }
        }
    }
}
