/* loss_image.c - L1, SSIM and D-SSIM with backward passes (see loss_image.h).
 *
 * SSIM per pixel and channel, with Gaussian-blurred moments m1 = G*x, m2 = G*y, e11 = G*x^2,
 * e22 = G*y^2, e12 = G*xy (s11 = e11 - m1^2, s22 = e22 - m2^2, s12 = e12 - m1 m2):
 *     S = (2 m1 m2 + C1)(2 s12 + C2) / ((m1^2 + m2^2 + C1)(s11 + s22 + C2))
 * Treating S as a function of the blurred moments (m1, e11, e12) that depend on x, the backward is
 *     dL/dx = G*(w dS/dm1) + 2x G*(w dS/de11) + y G*(w dS/de12)
 * because the zero-padded blur G is symmetric (its transpose is itself). The forward computes the
 * three weighted partial maps right away, so the backward is three blurs and one combine.
 */
#include "optim/loss_image.h"

#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

#define R_TAP (OPTIM_SSIM_TAPS / 2)

struct optim_ssim_ws {
    int H, W, C;
    size_t n;        /* H*W*C */
    int cap_H, cap_W; /* the size the buffers were made for (optim_ssim_reshape) */
    float *hblur;    /* (5, H, W, C) horizontal pass of x, y, x^2, y^2, xy */
    float *partial;  /* (3, H, W, C) w * dS/dm1, w * dS/de11, w * dS/de12 of the last forward */
    double *rowsum;  /* (H) per-row SSIM sums, summed in fixed order => thread-count independent */
    float *rows;     /* (nthreads, 5, W*C) per-thread vertical-pass rows */
    int nthreads;
    float win[OPTIM_SSIM_TAPS];
};

void optim_ssim_window(float w[OPTIM_SSIM_TAPS])
{
    double g[OPTIM_SSIM_TAPS], s = 0;
    for (int k = 0; k < OPTIM_SSIM_TAPS; k++) {
        double d = k - R_TAP;
        g[k] = exp(-d * d / (2 * OPTIM_SSIM_SIGMA * OPTIM_SSIM_SIGMA));
        s += g[k];
    }
    for (int k = 0; k < OPTIM_SSIM_TAPS; k++) w[k] = (float)(g[k] / s);
}

/* ---------------------------------------------------------------------------------------------- */
/* L1                                                                                              */

/* Normaliser of the masked mean: C * sum(mask), or H*W*C without a mask. */
static double mask_norm(const float *mask, int H, int W, int C)
{
    size_t np = (size_t)H * W;
    if (!mask) return (double)np * C;
    double s = 0;
    for (size_t p = 0; p < np; p++) s += mask[p];
    return s * C;
}

float optim_l1_forward(const float *pred, const float *target, const float *mask, int H, int W, int C)
{
    double norm = mask_norm(mask, H, W, C);
    if (norm <= 0) return 0.0f;
    /* Serial on purpose (an OpenMP reduction would not be bit-reproducible); one vectorised float
     * sum per row, rows added in double. */
    double total = 0;
    const size_t row = (size_t)W * C;
    for (long r = 0; r < H; r++) {
        const float *x = pred + r * row, *y = target + r * row;
        float s = 0;
        if (mask) {
            const float *m = mask + (size_t)r * W;
            #pragma omp simd reduction(+ : s)
            for (size_t e = 0; e < row; e++) s += fabsf(x[e] - y[e]) * m[e / C];
        } else {
            #pragma omp simd reduction(+ : s)
            for (size_t e = 0; e < row; e++) s += fabsf(x[e] - y[e]);
        }
        total += s;
    }
    return (float)(total / norm);
}

void optim_l1_backward(float *d_pred, float scale, const float *pred, const float *target, const float *mask,
                       int H, int W, int C)
{
    double norm = mask_norm(mask, H, W, C);
    if (norm <= 0) return;
    const float g = (float)(scale / norm);
    const size_t row = (size_t)W * C;
    #pragma omp parallel for schedule(static) if ((long)H * W > 16384)
    for (long r = 0; r < H; r++) {
        const float *x = pred + r * row, *y = target + r * row;
        const float *m = mask ? mask + (size_t)r * W : NULL;
        float *d = d_pred + r * row;
        if (m) {
            for (int p = 0; p < W; p++) {
                float gp = g * m[p];
                for (int c = 0; c < C; c++) {
                    float diff = x[p * C + c] - y[p * C + c];
                    d[p * C + c] += diff > 0 ? gp : (diff < 0 ? -gp : 0.0f);
                }
            }
        } else {
            #pragma omp simd
            for (size_t e = 0; e < row; e++) {
                float diff = x[e] - y[e];
                d[e] += diff > 0 ? g : (diff < 0 ? -g : 0.0f);
            }
        }
    }
}

/* ---------------------------------------------------------------------------------------------- */
/* SSIM                                                                                            */

static int ensure_rows(optim_ssim_ws *ws);

pg_status optim_ssim_create(optim_ssim_ws **out, int H, int W, int C)
{
    *out = NULL;
    if (H <= 0 || W <= 0 || C <= 0) return pg_fail(PG_ERR_ARG, "optim_ssim_create: bad size %dx%dx%d", H, W, C);
    size_t n;
    if (pg_size_mul((size_t)H * W, (size_t)C, &n) || n > ((size_t)1 << 40))
        return pg_fail(PG_ERR_SIZE, "optim_ssim_create: image too large");
    optim_ssim_ws *ws = pg_calloc(1, sizeof(*ws), "ssim workspace");
    if (!ws) return PG_ERR_NOMEM;
    ws->H = H; ws->W = W; ws->C = C; ws->n = n;
    ws->cap_H = H; ws->cap_W = W;
    ws->hblur = pg_malloc(5 * n * sizeof(float), "ssim blur buffers");
    ws->partial = pg_calloc(3 * n, sizeof(float), "ssim partials");
    ws->rowsum = pg_calloc((size_t)H, sizeof(double), "ssim row sums");
    if (!ws->hblur || !ws->partial || !ws->rowsum || ensure_rows(ws)) {
        optim_ssim_destroy(ws);
        return PG_ERR_NOMEM;
    }
    optim_ssim_window(ws->win);
    *out = ws;
    return PG_OK;
}

pg_status optim_ssim_reshape(optim_ssim_ws *ws, int H, int W)
{
    if (H <= 0 || W <= 0 || H > ws->cap_H || W > ws->cap_W)
        return pg_fail(PG_ERR_ARG, "optim_ssim_reshape: %dx%d does not fit the %dx%d workspace", H, W, ws->cap_H, ws->cap_W);
    ws->H = H; ws->W = W;
    ws->n = (size_t)H * W * ws->C;
    return PG_OK;
}

void optim_ssim_destroy(optim_ssim_ws *ws)
{
    if (!ws) return;
    free(ws->hblur);
    free(ws->partial);
    free(ws->rowsum);
    free(ws->rows);
    free(ws);
}

/* Horizontal zero-padded blur of one row of W*C interleaved values: out[e] = sum_k w[k] in[e+(k-5)C].
 * The tap loop is outermost so the inner loop is a contiguous, vectorisable axpy. */
static void hblur_row(float *restrict out, const float *restrict in, const float *w, int W, int C)
{
    int n = W * C;
    memset(out, 0, (size_t)n * sizeof(float));
    for (int k = 0; k < OPTIM_SSIM_TAPS; k++) {
        int off = (k - R_TAP) * C;
        int lo = off < 0 ? -off : 0, hi = off > 0 ? n - off : n;
        float wk = w[k];
        #pragma omp simd
        for (int e = lo; e < hi; e++) out[e] += wk * in[e + off];
    }
}

/* Same, for the four moment rows derived from x and y (x^2, y^2, xy) without materialising them. */
static void hblur_row_moments(float *restrict ox, float *restrict oy, float *restrict oxx, float *restrict oyy,
                              float *restrict oxy, const float *restrict x, const float *restrict y,
                              const float *w, int W, int C)
{
    int n = W * C;
    memset(ox, 0, (size_t)n * sizeof(float));
    memset(oy, 0, (size_t)n * sizeof(float));
    memset(oxx, 0, (size_t)n * sizeof(float));
    memset(oyy, 0, (size_t)n * sizeof(float));
    memset(oxy, 0, (size_t)n * sizeof(float));
    for (int k = 0; k < OPTIM_SSIM_TAPS; k++) {
        int off = (k - R_TAP) * C;
        int lo = off < 0 ? -off : 0, hi = off > 0 ? n - off : n;
        float wk = w[k];
        #pragma omp simd
        for (int e = lo; e < hi; e++) {
            float a = x[e + off], b = y[e + off];
            ox[e] += wk * a;
            oy[e] += wk * b;
            oxx[e] += wk * a * a;
            oyy[e] += wk * b * b;
            oxy[e] += wk * a * b;
        }
    }
}

/* Vertical zero-padded blur producing output row i from the horizontally blurred map src (H, W*C). */
static void vblur_row(float *restrict out, const float *restrict src, const float *w, int i, int H, int n)
{
    memset(out, 0, (size_t)n * sizeof(float));
    for (int k = 0; k < OPTIM_SSIM_TAPS; k++) {
        int r = i + k - R_TAP;
        if (r < 0 || r >= H) continue;
        const float *s = src + (size_t)r * n;
        float wk = w[k];
        #pragma omp simd
        for (int e = 0; e < n; e++) out[e] += wk * s[e];
    }
}

/* Grows the per-thread row buffers to the current OpenMP thread count; 0 on success. */
static int ensure_rows(optim_ssim_ws *ws)
{
    int nt = omp_get_max_threads();
    if (nt <= ws->nthreads) return 0;
    float *r = malloc((size_t)nt * 5 * ws->cap_W * ws->C * sizeof(float));
    if (!r) return -1;
    free(ws->rows);
    ws->rows = r;
    ws->nthreads = nt;
    return 0;
}

float optim_ssim_forward(optim_ssim_ws *ws, const float *pred, const float *target, const float *mask,
                         int H, int W, int C)
{
    if (!ws || H != ws->H || W != ws->W || C != ws->C || ensure_rows(ws)) return NAN;
    const int n = W * C; /* floats per row */
    const size_t N = ws->n;
    const float *w = ws->win;
    float *hb = ws->hblur;
    double norm = mask_norm(mask, H, W, C);
    if (norm <= 0) {
        memset(ws->partial, 0, 3 * N * sizeof(float));
        return 0.0f;
    }
    const float inv_norm = (float)(1.0 / norm);
    const float C1 = (float)OPTIM_SSIM_C1, C2 = (float)OPTIM_SSIM_C2;

    #pragma omp parallel
    {
        #pragma omp for schedule(static)
        for (int i = 0; i < H; i++) {
            size_t o = (size_t)i * n;
            hblur_row_moments(hb + o, hb + N + o, hb + 2 * N + o, hb + 3 * N + o, hb + 4 * N + o, pred + o,
                              target + o, w, W, C);
        }
        /* Per-thread row buffers for the vertical pass: (5, n). */
        float *vb = ws->rows + (size_t)omp_get_thread_num() * 5 * n;
        #pragma omp for schedule(static)
        for (int i = 0; i < H; i++) {
            for (int q = 0; q < 5; q++) vblur_row(vb + (size_t)q * n, hb + q * N, w, i, H, n);
            const float *m1 = vb, *m2 = vb + n, *e11 = vb + 2 * n, *e22 = vb + 3 * n, *e12 = vb + 4 * n;
            size_t o = (size_t)i * n;
            float *gm = ws->partial + o, *g11 = ws->partial + N + o, *g12 = ws->partial + 2 * N + o;
            float rs = 0; /* one row (<= a few thousand terms) in float; rows are summed in double */
            #pragma omp simd reduction(+ : rs)
            for (int e = 0; e < n; e++) {
                float mu1 = m1[e], mu2 = m2[e];
                float s11 = e11[e] - mu1 * mu1, s22 = e22[e] - mu2 * mu2, s12 = e12[e] - mu1 * mu2;
                float A1 = 2 * mu1 * mu2 + C1, A2 = 2 * s12 + C2;
                float B1 = mu1 * mu1 + mu2 * mu2 + C1, B2 = s11 + s22 + C2;
                float inv = 1.0f / (B1 * B2);
                float S = A1 * A2 * inv;
                float wt = (mask ? mask[(size_t)i * W + e / C] : 1.0f) * inv_norm;
                rs += S * (mask ? mask[(size_t)i * W + e / C] : 1.0f);
                /* partials with s held fixed, then through s11 = e11 - m1^2, s12 = e12 - m1 m2 */
                float dS_dmu = 2 * mu2 * A2 * inv - 2 * mu1 * S / B1;
                float dS_ds11 = -S / B2;
                float dS_ds12 = 2 * A1 * inv;
                gm[e] = wt * (dS_dmu - 2 * mu1 * dS_ds11 - mu2 * dS_ds12);
                g11[e] = wt * dS_ds11;
                g12[e] = wt * dS_ds12;
            }
            ws->rowsum[i] = rs;
        }
    }
    double total = 0;
    for (int i = 0; i < H; i++) total += ws->rowsum[i];
    return (float)(total / norm);
}

void optim_ssim_backward(optim_ssim_ws *ws, float *d_pred, float scale, const float *pred, const float *target,
                         const float *mask, int H, int W, int C)
{
    (void)mask; /* already folded into the partials by the forward */
    if (!ws || H != ws->H || W != ws->W || C != ws->C || ensure_rows(ws)) return;
    const int n = W * C;
    const size_t N = ws->n;
    const float *w = ws->win;
    float *hb = ws->hblur; /* reuse: (3, H, W, C) horizontal blur of the partials */
    #pragma omp parallel
    {
        #pragma omp for schedule(static)
        for (int i = 0; i < H; i++) {
            size_t o = (size_t)i * n;
            for (int q = 0; q < 3; q++) hblur_row(hb + q * N + o, ws->partial + q * N + o, w, W, C);
        }
        float *vb = ws->rows + (size_t)omp_get_thread_num() * 5 * n;
        #pragma omp for schedule(static)
        for (int i = 0; i < H; i++) {
            for (int q = 0; q < 3; q++) vblur_row(vb + (size_t)q * n, hb + q * N, w, i, H, n);
            size_t o = (size_t)i * n;
            const float *x = pred + o, *y = target + o;
            float *d = d_pred + o;
            #pragma omp simd
            for (int e = 0; e < n; e++) d[e] += scale * (vb[e] + 2 * x[e] * vb[n + e] + y[e] * vb[2 * n + e]);
        }
    }
}

float optim_dssim_forward(optim_ssim_ws *ws, const float *pred, const float *target, const float *mask,
                          int H, int W, int C)
{
    return 1.0f - optim_ssim_forward(ws, pred, target, mask, H, W, C);
}
