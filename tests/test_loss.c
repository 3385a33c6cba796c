/* test_loss.c - L1, SSIM (with and without mask), SSI depth and K-Planes regularisers:
 * float forward vs a double-precision reference, float analytic gradients vs central finite
 * differences of the double reference.
 *
 * Tolerance: relative error |g - fd| / max(|g|, |fd|, floor) < 1e-3 where floor = 1e-2 * max|fd| over
 * the checked entries (entries a hundred times smaller than the largest gradient are compared
 * against that scale, since float rounding of the summed partials is absolute, not relative).
 */
#include "testlib.h"
#include "core/parallel.h"
#include "core/rng.h"
#include "core/status.h"
#include "optim/loss_depth.h"
#include "optim/loss_image.h"
#include "optim/loss_reg.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---------------------------------------------------------------------------------------------- */
/* double references                                                                               */

static double ref_l1(const double *x, const double *y, const float *mask, int H, int W, int C)
{
    double s = 0, norm = 0;
    for (int p = 0; p < H * W; p++) {
        double m = mask ? mask[p] : 1.0;
        norm += m * C;
        for (int c = 0; c < C; c++) s += m * fabs(x[p * C + c] - y[p * C + c]);
    }
    return norm > 0 ? s / norm : 0;
}

static double ref_ssim(const double *x, const double *y, const float *mask, int H, int W, int C)
{
    double win[11], ws = 0;
    for (int k = 0; k < 11; k++) { win[k] = exp(-(k - 5.0) * (k - 5.0) / (2 * 1.5 * 1.5)); ws += win[k]; }
    for (int k = 0; k < 11; k++) win[k] /= ws;
    double total = 0, norm = 0;
    for (int i = 0; i < H; i++)
        for (int j = 0; j < W; j++) {
            double m = mask ? mask[i * W + j] : 1.0;
            norm += m * C;
            for (int c = 0; c < C; c++) {
                double m1 = 0, m2 = 0, e11 = 0, e22 = 0, e12 = 0;
                for (int a = 0; a < 11; a++)
                    for (int b = 0; b < 11; b++) {
                        int r = i + a - 5, q = j + b - 5;
                        if (r < 0 || r >= H || q < 0 || q >= W) continue;
                        double w = win[a] * win[b], u = x[(r * W + q) * C + c], v = y[(r * W + q) * C + c];
                        m1 += w * u; m2 += w * v; e11 += w * u * u; e22 += w * v * v; e12 += w * u * v;
                    }
                double C1 = 1e-4, C2 = 9e-4;
                double s11 = e11 - m1 * m1, s22 = e22 - m2 * m2, s12 = e12 - m1 * m2;
                double S = (2 * m1 * m2 + C1) * (2 * s12 + C2) / ((m1 * m1 + m2 * m2 + C1) * (s11 + s22 + C2));
                total += m * S;
            }
        }
    return norm > 0 ? total / norm : 0;
}

/* ---------------------------------------------------------------------------------------------- */

static void random_pair(pg_rng *rng, float *x, float *y, double *xd, double *yd, int n)
{
    for (int i = 0; i < n; i++) {
        /* correlated images, like a render vs its target */
        y[i] = (float)pg_rng_uniform(rng);
        x[i] = (float)(0.5 * y[i] + 0.5 * pg_rng_uniform(rng));
        if (fabsf(x[i] - y[i]) < 1e-3f) x[i] = y[i] + 2e-3f; /* keep L1 away from its kink */
        xd[i] = x[i];
        yd[i] = y[i];
    }
}

static void test_l1(int use_mask)
{
    const int H = 9, W = 7, C = 3, n = H * W * C;
    pg_rng rng;
    pg_rng_seed(&rng, 11 + use_mask);
    float x[9 * 7 * 3], y[9 * 7 * 3], mask[9 * 7], g[9 * 7 * 3] = { 0 };
    double xd[9 * 7 * 3], yd[9 * 7 * 3], fd[9 * 7 * 3];
    random_pair(&rng, x, y, xd, yd, n);
    for (int p = 0; p < H * W; p++) mask[p] = (float)pg_rng_uniform(&rng);
    const float *m = use_mask ? mask : NULL;
    float l = optim_l1_forward(x, y, m, H, W, C);
    double lr = ref_l1(xd, yd, m, H, W, C);
    CHECK(fabs(l - lr) < 1e-6, "l1 forward %g vs ref %g (mask %d)", l, lr, use_mask);
    optim_l1_backward(g, 1.5f, x, y, m, H, W, C);
    const double h = 1e-5;
    for (int i = 0; i < n; i++) {
        double s = xd[i];
        xd[i] = s + h; double lp = ref_l1(xd, yd, m, H, W, C);
        xd[i] = s - h; double lm = ref_l1(xd, yd, m, H, W, C);
        xd[i] = s;
        fd[i] = 1.5 * (lp - lm) / (2 * h);
    }
    double e = test_grad_err(g, fd, n);
    CHECK(e < 1e-3, "l1 gradient rel err %g (mask %d)", e, use_mask);
    printf("l1 (mask %d): loss %.6f ref %.6f, grad rel err %.2e\n", use_mask, l, lr, e);
}

static void test_ssim(int use_mask, int H, int W)
{
    const int C = 3, n = H * W * C;
    pg_rng rng;
    pg_rng_seed(&rng, 21 + use_mask);
    float *x = malloc(n * sizeof(float)), *y = malloc(n * sizeof(float)), *g = calloc(n, sizeof(float));
    float *mask = malloc(H * W * sizeof(float));
    double *xd = malloc(n * sizeof(double)), *yd = malloc(n * sizeof(double)), *fd = malloc(n * sizeof(double));
    random_pair(&rng, x, y, xd, yd, n);
    for (int p = 0; p < H * W; p++) mask[p] = (float)pg_rng_uniform(&rng);
    const float *m = use_mask ? mask : NULL;
    optim_ssim_ws *ws = NULL;
    CHECK_OK(optim_ssim_create(&ws, H, W, C));
    if (!ws) return;
    float s = optim_ssim_forward(ws, x, y, m, H, W, C);
    double sr = ref_ssim(xd, yd, m, H, W, C);
    CHECK(fabs(s - sr) < 2e-6, "ssim forward %.8f vs ref %.8f (mask %d)", s, sr, use_mask);
    CHECK(sr < 0.9 && sr > 0.05, "test images should be dissimilar, ssim %g", sr);
    float same = optim_ssim_forward(ws, y, y, m, H, W, C);
    CHECK(fabs(same - 1.0f) < 1e-5, "ssim(y, y) = %.8f", same);
    float ds = optim_dssim_forward(ws, x, y, m, H, W, C);
    CHECK(fabs(ds - (1 - sr)) < 2e-6, "dssim %.8f vs %.8f", ds, 1 - sr);
    /* last forward was on (x, y): backward of D-SSIM with weight 0.2 */
    optim_ssim_backward(ws, g, -0.2f, x, y, m, H, W, C);
    const double h = 1e-6;
    for (int i = 0; i < n; i++) {
        double v = xd[i];
        xd[i] = v + h; double lp = ref_ssim(xd, yd, m, H, W, C);
        xd[i] = v - h; double lm = ref_ssim(xd, yd, m, H, W, C);
        xd[i] = v;
        fd[i] = -0.2 * (lp - lm) / (2 * h);
    }
    double e = test_grad_err(g, fd, n);
    CHECK(e < 1e-3, "ssim gradient rel err %g (mask %d, %dx%d)", e, use_mask, H, W);
    printf("ssim (mask %d, %dx%d): %.6f ref %.6f, grad rel err %.2e\n", use_mask, H, W, s, sr, e);
    optim_ssim_destroy(ws);
    free(x); free(y); free(g); free(mask); free(xd); free(yd); free(fd);
}

/* The SSIM result must not depend on the thread count (row sums in fixed order). */
static void test_ssim_determinism(void)
{
    const int H = 240, W = 320, C = 3, n = H * W * C;
    pg_rng rng;
    pg_rng_seed(&rng, 5);
    float *x = malloc(n * sizeof(float)), *y = malloc(n * sizeof(float));
    float *g1 = calloc(n, sizeof(float)), *g2 = calloc(n, sizeof(float));
    for (int i = 0; i < n; i++) { x[i] = (float)pg_rng_uniform(&rng); y[i] = (float)pg_rng_uniform(&rng); }
    optim_ssim_ws *ws = NULL;
    CHECK_OK(optim_ssim_create(&ws, H, W, C));
    if (!ws) return;
    pg_set_threads(1);
    float a = optim_ssim_forward(ws, x, y, NULL, H, W, C);
    optim_ssim_backward(ws, g1, 1.0f, x, y, NULL, H, W, C);
    pg_set_threads(2);
    float b = optim_ssim_forward(ws, x, y, NULL, H, W, C);
    optim_ssim_backward(ws, g2, 1.0f, x, y, NULL, H, W, C);
    CHECK(a == b && memcmp(g1, g2, n * sizeof(float)) == 0, "ssim differs across thread counts: %.9g %.9g", a, b);
    CHECK(optim_ssim_forward(ws, x, y, NULL, H, W + 1, C) != optim_ssim_forward(ws, x, y, NULL, H, W + 1, C),
          "size mismatch must give NaN");
    optim_ssim_destroy(ws);
    free(x); free(y); free(g1); free(g2);
}

/* Weighted: w_i = mask[i] where mask[i] > 0.5 (1 without a mask), out below. */
static double ref_ssi(const double *p, const float *t, const float *mask, int n)
{
    double sp = 0, st = 0, spp = 0, spt = 0, W = 0;
    for (int i = 0; i < n; i++) {
        if (mask && mask[i] <= 0.5f) continue;
        double w = mask ? mask[i] : 1.0;
        sp += w * p[i]; st += w * t[i]; spp += w * p[i] * p[i]; spt += w * p[i] * t[i]; W += w;
    }
    double s = (W * spt - sp * st) / (W * spp - sp * sp), b = (st - s * sp) / W, l = 0;
    for (int i = 0; i < n; i++) {
        if (mask && mask[i] <= 0.5f) continue;
        double r = s * p[i] + b - t[i];
        l += (mask ? mask[i] : 1.0) * r * r;
    }
    return l / (2.0 * W);
}

static void test_ssi_depth(void)
{
    enum { n = 200 };
    pg_rng rng;
    pg_rng_seed(&rng, 3);
    float p[n], t[n], mask[n], g[n] = { 0 };
    double pd[n], fd[n];
    for (int i = 0; i < n; i++) {
        p[i] = (float)pg_rng_range(&rng, 1, 5);
        t[i] = 0.7f * p[i] + 0.4f + (float)(0.3 * pg_rng_normal(&rng));
        double u = pg_rng_uniform(&rng); /* out, weight 1, or a mover's weight */
        mask[i] = u < 0.2 ? 0.0f : u < 0.9 ? 1.0f : 10.0f;
        pd[i] = p[i];
    }
    t[7] = NAN; mask[7] = 0; /* invalid target is skipped when masked out */
    optim_ssi_depth fit;
    float l = optim_ssi_depth_forward(&fit, p, t, mask, n);
    double lr = ref_ssi(pd, t, mask, n);
    CHECK(fabs(l - lr) < 1e-5 * fmax(1, lr), "ssi depth loss %g vs ref %g", l, lr);
    CHECK(fabs(fit.scale - 0.7) < 0.15 && fabs(fit.shift - 0.4) < 0.5, "fit s=%g b=%g", fit.scale, fit.shift);
    optim_ssi_depth_backward(g, 2.0f, &fit, p, t, mask, n);
    const double h = 1e-5;
    for (int i = 0; i < n; i++) {
        double v = pd[i];
        pd[i] = v + h; double lp = ref_ssi(pd, t, mask, n);
        pd[i] = v - h; double lm = ref_ssi(pd, t, mask, n);
        pd[i] = v;
        fd[i] = 2.0 * (lp - lm) / (2 * h);
    }
    double e = test_grad_err(g, fd, n);
    CHECK(e < 1e-3, "ssi depth gradient rel err %g", e);
    printf("ssi depth: loss %.6f ref %.6f s=%.4f b=%.4f M=%ld, grad rel err %.2e\n", l, lr, fit.scale, fit.shift,
           fit.valid, e);
    /* exact affine relation => zero loss, recovered s and b; NaN target without mask is skipped */
    for (int i = 0; i < n; i++) t[i] = 2.0f * p[i] + 3.0f;
    t[9] = INFINITY;
    l = optim_ssi_depth_forward(&fit, p, t, NULL, n);
    CHECK(l < 1e-8 && fabs(fit.scale - 2) < 1e-5 && fabs(fit.shift - 3) < 1e-4 && fit.valid == n - 1,
          "affine target: loss %g s %g b %g M %ld", l, fit.scale, fit.shift, fit.valid);
    /* constant prediction: finite loss, fallback s = 1 */
    for (int i = 0; i < n; i++) p[i] = 2.0f;
    l = optim_ssi_depth_forward(&fit, p, t, NULL, n);
    CHECK(isfinite(l) && fit.scale == 1.0, "constant pred: loss %g s %g", l, fit.scale);
}

typedef double (*reg_ref_fn)(const double *, int, int, int);

static double ref_tv(const double *p, int H, int W, int C)
{
    double th = 0, tw = 0;
    for (int i = 0; i < H; i++)
        for (int j = 0; j < W; j++)
            for (int c = 0; c < C; c++) {
                double v = p[(i * W + j) * C + c];
                if (i + 1 < H) th += pow(p[((i + 1) * W + j) * C + c] - v, 2);
                if (j + 1 < W) tw += pow(p[(i * W + j + 1) * C + c] - v, 2);
            }
    return 2 * (th / (C * (H - 1.0) * W) + tw / (C * H * (W - 1.0)));
}

static double ref_ts(const double *p, int H, int W, int C)
{
    double t = 0;
    for (int i = 1; i + 1 < H; i++)
        for (int j = 0; j < W * C; j++) t += pow(p[(i + 1) * W * C + j] - 2 * p[i * W * C + j] + p[(i - 1) * W * C + j], 2);
    return t / (C * (H - 2.0) * W);
}

static double ref_l1one(const double *p, int H, int W, int C)
{
    double t = 0;
    for (int i = 0; i < H * W * C; i++) t += fabs(1 - p[i]);
    return t / (H * W * C);
}

static void test_reg(const char *name, reg_ref_fn ref, float (*fwd)(const float *, int, int, int),
                     void (*bwd)(float *, float, const float *, int, int, int))
{
    enum { H = 6, W = 5, C = 4, n = H * W * C };
    pg_rng rng;
    pg_rng_seed(&rng, 99);
    float p[n], g[n] = { 0 };
    double pd[n], fd[n];
    for (int i = 0; i < n; i++) {
        p[i] = (float)pg_rng_range(&rng, 0.1, 1.9);
        if (fabsf(p[i] - 1) < 1e-3f) p[i] = 1.01f;
        pd[i] = p[i];
    }
    float l = fwd(p, H, W, C);
    double lr = ref(pd, H, W, C);
    CHECK(fabs(l - lr) < 1e-6 * fmax(1, lr), "%s forward %g vs %g", name, l, lr);
    bwd(g, 0.5f, p, H, W, C);
    const double h = 1e-5;
    for (int i = 0; i < n; i++) {
        double v = pd[i];
        pd[i] = v + h; double lp = ref(pd, H, W, C);
        pd[i] = v - h; double lm = ref(pd, H, W, C);
        pd[i] = v;
        fd[i] = 0.5 * (lp - lm) / (2 * h);
    }
    double e = test_grad_err(g, fd, n);
    CHECK(e < 1e-3, "%s gradient rel err %g", name, e);
    printf("%s: %.6f ref %.6f, grad rel err %.2e\n", name, l, lr, e);
}

int main(void)
{
    test_l1(0);
    test_l1(1);
    test_ssim(0, 16, 13);
    test_ssim(1, 16, 13);
    test_ssim(0, 5, 4); /* smaller than the window */
    test_ssim_determinism();
    test_ssi_depth();
    test_reg("plane tv", ref_tv, optim_plane_tv_forward, optim_plane_tv_backward);
    test_reg("plane time smooth", ref_ts, optim_plane_time_smooth_forward, optim_plane_time_smooth_backward);
    test_reg("plane l1-to-one", ref_l1one, optim_plane_l1_one_forward, optim_plane_l1_one_backward);
    return test_summary("test_loss");
}
