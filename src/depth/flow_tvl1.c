/* flow_tvl1.c - coarse-to-fine TV-L1 optical flow, the built-in depth_flow backend.
 *
 * Energy: E(u) = sum |grad u1| + |grad u2| + lambda |I1(x + u) - I0(x)|, minimised per pyramid
 * level by repeatedly linearising I1 around the current flow ("warps") and solving the convex
 * linearised problem with the alternating scheme of Zach et al.: a point-wise thresholding step
 * for the data term and Chambolle's dual projection for the TV term (coupled through theta).
 * Bicubic warping keeps the sub-pixel accuracy; a 3x3 median on the flow after each warp removes
 * outliers (Sun, Roth & Black, "Secrets of optical flow"). All loops are row-parallel and write
 * disjoint memory, so results do not depend on the thread count.
 */
#include "depth/flow.h"
#include "depth/plane.h"
#include "core/mathx.h"

#define PAR_OK ((size_t)w * h >= PLANE_PAR_MIN_PIXELS)

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define TVL1_MIN_SIDE 16
#define TVL1_MAX_SCALES 10

void depth_flow_tvl1_defaults(depth_flow_tvl1_params *p)
{
    p->lambda = 0.15f;
    p->theta = 0.3f;
    p->tau = 0.25f;
    p->scales = 5;
    p->warps = 4;
    p->iterations = 20;
    p->median = 1;
}

/* Per-level working memory, carved from one allocation. */
typedef struct {
    int w, h;
    float *i0, *i1;       /* (h,w) level images, intensities in [0,255] */
} tvl1_level;

/* Solves one pyramid level in place on u1, u2, p (all (h,w)). scratch holds 10 planes. */
static void tvl1_solve_level(const depth_flow_tvl1_params *prm, const float *i0, const float *i1, int w, int h,
                             float *u1, float *u2, float *p11, float *p12, float *p21, float *p22, float *scratch)
{
    const size_t n = (size_t)w * h;
    float *i1x = scratch, *i1y = scratch + n, *i1w = scratch + 2 * n, *i1wx = scratch + 3 * n;
    float *i1wy = scratch + 4 * n, *grad = scratch + 5 * n, *rhoc = scratch + 6 * n;
    float *div1 = scratch + 7 * n, *div2 = scratch + 8 * n, *tmp = scratch + 9 * n;
    const float lt = prm->lambda * prm->theta, taut = prm->tau / prm->theta, theta = prm->theta;

    /* Central-difference gradient of I1, warped together with I1 below. */
    depth_plane_gradient(i1, w, h, i1x, i1y);

    for (int warp = 0; warp < prm->warps; warp++) {
        #pragma omp parallel for schedule(static) if (PAR_OK)
        for (int y = 0; y < h; y++) {
            for (int x = 0; x < w; x++) {
                size_t k = (size_t)y * w + x;
                float xs = x + u1[k], ys = y + u2[k];
                if (xs < 0.0f || ys < 0.0f || xs > w - 1 || ys > h - 1) {
                    /* Leaves the image: no data term here, the TV term fills it in. */
                    i1wx[k] = i1wy[k] = grad[k] = rhoc[k] = 0.0f;
                    continue;
                }
                const float *warped[3] = { i1, i1x, i1y };
                float sample[3];
                depth_plane_sample_bicubic(warped, 3, w, h, xs, ys, sample);
                float v = sample[0], gx = sample[1], gy = sample[2];
                i1w[k] = v;
                i1wx[k] = gx;
                i1wy[k] = gy;
                grad[k] = gx * gx + gy * gy;
                rhoc[k] = v - gx * u1[k] - gy * u2[k] - i0[k];
            }
        }
        /* Border handling without per-pixel branches (so the loops vectorise): the row above
         * row 0 is a zero row, the row below the last row is the row itself (zero difference),
         * and the last column is done separately; `omp simd` because GCC's -O2 left even these
         * loops scalar, and vectorised they take half the time (bench flow). */
        float *zero_row = tmp;
        memset(zero_row, 0, sizeof(float) * w);
        for (int it = 0; it < prm->iterations; it++) {
            /* Divergence of the dual fields (adjoint of the forward-difference gradient). */
            #pragma omp parallel for schedule(static) if (PAR_OK)
            for (int y = 0; y < h; y++) {
                const size_t r = (size_t)y * w;
                const float ylast = y < h - 1 ? 1.0f : 0.0f;
                const float *q11 = p11 + r, *q12 = p12 + r, *q21 = p21 + r, *q22 = p22 + r;
                const float *u12 = y > 0 ? p12 + r - w : zero_row, *u22 = y > 0 ? p22 + r - w : zero_row;
                float *o1 = div1 + r, *o2 = div2 + r;
                o1[0] = (w > 1 ? q11[0] : 0.0f) + ylast * q12[0] - u12[0];
                o2[0] = (w > 1 ? q21[0] : 0.0f) + ylast * q22[0] - u22[0];
                #pragma omp simd
                for (int x = 1; x < w - 1; x++) {
                    o1[x] = q11[x] - q11[x - 1] + ylast * q12[x] - u12[x];
                    o2[x] = q21[x] - q21[x - 1] + ylast * q22[x] - u22[x];
                }
                if (w > 1) {
                    o1[w - 1] = -q11[w - 2] + ylast * q12[w - 1] - u12[w - 1];
                    o2[w - 1] = -q21[w - 2] + ylast * q22[w - 1] - u22[w - 1];
                }
            }
            /* Data step (point-wise thresholding, written as selects) then the primal update. */
            #pragma omp parallel for schedule(static) if (PAR_OK)
            for (int y = 0; y < h; y++) {
                const size_t r = (size_t)y * w;
                #pragma omp simd
                for (int x = 0; x < w; x++) {
                    const size_t k = r + x;
                    float rho = rhoc[k] + i1wx[k] * u1[k] + i1wy[k] * u2[k];
                    float g = grad[k], t = lt * g;
                    float gs = g > 1e-10f ? g : 1.0f;
                    float f = g > 1e-10f ? -rho / gs : 0.0f;
                    f = rho < -t ? lt : (rho > t ? -lt : f);
                    u1[k] = u1[k] + f * i1wx[k] + theta * div1[k];
                    u2[k] = u2[k] + f * i1wy[k] + theta * div2[k];
                }
            }
            /* Dual update: Chambolle's projection with forward differences. */
            #pragma omp parallel for schedule(static) if (PAR_OK)
            for (int y = 0; y < h; y++) {
                const size_t r = (size_t)y * w;
                const size_t rn = y < h - 1 ? r + w : r;
                const float *a1 = u1 + r, *a2 = u2 + r, *b1 = u1 + rn, *b2 = u2 + rn;
                float *q11 = p11 + r, *q12 = p12 + r, *q21 = p21 + r, *q22 = p22 + r;
                #pragma omp simd
                for (int x = 0; x < w - 1; x++) {
                    float u1x = a1[x + 1] - a1[x], u1y = b1[x] - a1[x];
                    float u2x = a2[x + 1] - a2[x], u2y = b2[x] - a2[x];
                    float i1 = 1.0f / (1.0f + taut * sqrtf(u1x * u1x + u1y * u1y));
                    float i2 = 1.0f / (1.0f + taut * sqrtf(u2x * u2x + u2y * u2y));
                    q11[x] = (q11[x] + taut * u1x) * i1;
                    q12[x] = (q12[x] + taut * u1y) * i1;
                    q21[x] = (q21[x] + taut * u2x) * i2;
                    q22[x] = (q22[x] + taut * u2y) * i2;
                }
                {
                    const int x = w - 1; /* no forward difference along x in the last column */
                    float u1y = b1[x] - a1[x], u2y = b2[x] - a2[x];
                    float n1 = 1.0f + taut * fabsf(u1y), n2 = 1.0f + taut * fabsf(u2y);
                    q11[x] = q11[x] / n1;
                    q12[x] = (q12[x] + taut * u1y) / n1;
                    q21[x] = q21[x] / n2;
                    q22[x] = (q22[x] + taut * u2y) / n2;
                }
            }
        }
        if (prm->median) {
            depth_plane_median3(u1, w, h, tmp);
            memcpy(u1, tmp, sizeof(float) * n);
            depth_plane_median3(u2, w, h, tmp);
            memcpy(u2, tmp, sizeof(float) * n);
        }
    }
}

/* Builds the pyramids, runs the levels coarse to fine and writes interleaved flow. */
static pg_status tvl1_compute(void *ctx, const pg_image *img0, const pg_image *img1, float *flow)
{
    depth_flow_tvl1_params prm;
    if (ctx) prm = *(const depth_flow_tvl1_params *)ctx;
    else depth_flow_tvl1_defaults(&prm);
    if (prm.scales < 1) prm.scales = 1;
    if (prm.scales > TVL1_MAX_SCALES) prm.scales = TVL1_MAX_SCALES;
    if (prm.warps < 1) prm.warps = 1;
    if (prm.iterations < 1) prm.iterations = 1;
    const int W = img0->width, H = img0->height;

    int ws[TVL1_MAX_SCALES], hs[TVL1_MAX_SCALES], L = 0;
    size_t offs[TVL1_MAX_SCALES + 1];
    offs[0] = 0;
    for (int s = 0; s < prm.scales; s++) {
        int w = (int)lroundf(W * ldexpf(1.0f, -s)), h = (int)lroundf(H * ldexpf(1.0f, -s));
        if (s > 0 && (w < TVL1_MIN_SIDE || h < TVL1_MIN_SIDE)) break;
        ws[s] = w;
        hs[s] = h;
        offs[s + 1] = offs[s] + (size_t)w * h;
        L = s + 1;
    }
    const size_t n0 = (size_t)W * H, total = offs[L];
    /* Two image pyramids + flow (2) + duals (4) + scratch (10) + a resample buffer, at full size. */
    size_t count = 2 * total + 17 * n0;
    float *mem = pg_malloc(count * sizeof(float), "TV-L1 flow buffers");
    if (!mem) return PG_ERR_NOMEM;
    float *pyr0 = mem, *pyr1 = mem + total, *work = mem + 2 * total;
    float *u1 = work, *u2 = work + n0, *p11 = work + 2 * n0, *p12 = work + 3 * n0, *p21 = work + 4 * n0,
          *p22 = work + 5 * n0, *scratch = work + 6 * n0, *rs = work + 16 * n0;

    /* Level 0: light pre-smoothing against noise; coarser levels: anti-alias blur then resample. */
    depth_plane_from_image(img0, 255.0f, scratch);
    depth_plane_gaussian_blur(scratch, W, H, 0.5f, scratch + n0, pyr0);
    depth_plane_from_image(img1, 255.0f, scratch);
    depth_plane_gaussian_blur(scratch, W, H, 0.5f, scratch + n0, pyr1);
    const float sigma_down = 0.6f * sqrtf(3.0f); /* 0.6 sqrt(1/eta^2 - 1) for eta = 0.5 */
    for (int s = 1; s < L; s++) {
        for (int k = 0; k < 2; k++) {
            float *pyr = k ? pyr1 : pyr0;
            depth_plane_gaussian_blur(pyr + offs[s - 1], ws[s - 1], hs[s - 1], sigma_down, scratch, scratch + n0);
            depth_plane_resize(scratch + n0, ws[s - 1], hs[s - 1], pyr + offs[s], ws[s], hs[s]);
        }
    }

    memset(work, 0, 6 * n0 * sizeof(float));
    for (int s = L - 1; s >= 0; s--) {
        const int w = ws[s], h = hs[s];
        tvl1_solve_level(&prm, pyr0 + offs[s], pyr1 + offs[s], w, h, u1, u2, p11, p12, p21, p22, scratch);
        if (s == 0) break;
        /* Upsample flow (scaled by the size ratio) and duals to the next finer level. */
        const int w2 = ws[s - 1], h2 = hs[s - 1];
        float *planes[6] = { u1, u2, p11, p12, p21, p22 };
        for (int q = 0; q < 6; q++) {
            depth_plane_resize(planes[q], w, h, rs, w2, h2);
            float f = q == 0 ? (float)w2 / w : (q == 1 ? (float)h2 / h : 1.0f);
            size_t n2 = (size_t)w2 * h2;
            for (size_t k = 0; k < n2; k++) planes[q][k] = rs[k] * f;
        }
    }
    for (size_t k = 0; k < n0; k++) {
        flow[2 * k] = u1[k];
        flow[2 * k + 1] = u2[k];
    }
    free(mem);
    return PG_OK;
}

depth_flow_backend depth_flow_backend_tvl1(const depth_flow_tvl1_params *params)
{
    depth_flow_backend be = { "tvl1", tvl1_compute, (void *)params };
    return be;
}

depth_flow_backend depth_flow_backend_default(void) { return depth_flow_backend_tvl1(NULL); }

pg_status depth_flow_compute(const depth_flow_backend *be, const pg_image *img0, const pg_image *img1, float *flow)
{
    if (!be || !be->compute) return pg_fail(PG_ERR_ARG, "optical flow: no backend");
    if (!img0->data || !img1->data || img0->width != img1->width || img0->height != img1->height)
        return pg_fail(PG_ERR_SIZE, "optical flow: frames differ in size (%d x %d vs %d x %d)", img0->width,
                       img0->height, img1->width, img1->height);
    return be->compute(be->ctx, img0, img1, flow);
}

void depth_flow_consistency(const float *f01, const float *f10, int width, int height, float *conf)
{
    #pragma omp parallel for schedule(static) if ((size_t)width * height >= PLANE_PAR_MIN_PIXELS)
    for (int y = 0; y < height; y++) {
        for (int x = 0; x < width; x++) {
            size_t k = (size_t)y * width + x;
            float fx = f01[2 * k], fy = f01[2 * k + 1];
            float xs = x + fx, ys = y + fy;
            if (xs < -0.5f || ys < -0.5f || xs > width - 0.5f || ys > height - 0.5f) {
                conf[k] = 0.0f;
                continue;
            }
            /* Sample the backward flow bilinearly (the two components are interleaved). */
            if (xs < 0) xs = 0;
            if (ys < 0) ys = 0;
            if (xs > width - 1) xs = (float)(width - 1);
            if (ys > height - 1) ys = (float)(height - 1);
            int ix = (int)xs, iy = (int)ys;
            int ix1 = ix + 1 < width ? ix + 1 : ix, iy1 = iy + 1 < height ? iy + 1 : iy;
            float ax = xs - ix, ay = ys - iy, b[2];
            for (int c = 0; c < 2; c++) {
                float a00 = f10[2 * ((size_t)iy * width + ix) + c], a01 = f10[2 * ((size_t)iy * width + ix1) + c];
                float a10 = f10[2 * ((size_t)iy1 * width + ix) + c], a11 = f10[2 * ((size_t)iy1 * width + ix1) + c];
                b[c] = (a00 * (1 - ax) + a01 * ax) * (1 - ay) + (a10 * (1 - ax) + a11 * ax) * ay;
            }
            float ex = fx + b[0], ey = fy + b[1];
            float s = 0.5f + 0.05f * (sqrtf(fx * fx + fy * fy) + sqrtf(b[0] * b[0] + b[1] * b[1]));
            conf[k] = expf(-(ex * ex + ey * ey) / (2.0f * s * s));
        }
    }
}

double depth_flow_epe(const float *flow, const float *truth, int width, int height, const float *mask)
{
    double sum = 0.0;
    size_t cnt = 0, n = (size_t)width * height;
    for (size_t k = 0; k < n; k++) {
        if (mask && mask[k] <= 0.5f) continue;
        double dx = flow[2 * k] - truth[2 * k], dy = flow[2 * k + 1] - truth[2 * k + 1];
        sum += sqrt(dx * dx + dy * dy);
        cnt++;
    }
    return cnt ? sum / cnt : 0.0;
}

void depth_flow_to_color(const float *flow, int width, int height, float max_mag, pg_image *out)
{
    const size_t n = (size_t)width * height;
    if (max_mag <= 0.0f) {
        float *mags = malloc(n * sizeof(float));
        if (mags) {
            for (size_t k = 0; k < n; k++) mags[k] = hypotf(flow[2 * k], flow[2 * k + 1]);
            qsort(mags, n, sizeof(float), pg_cmp_float);
            max_mag = mags[(size_t)(0.99 * (n - 1))];
            free(mags);
        }
        if (max_mag < 1.0f) max_mag = 1.0f; /* sub-pixel noise stays near white */
    }
    for (size_t k = 0; k < n; k++) {
        float fx = flow[2 * k], fy = flow[2 * k + 1];
        float mag = hypotf(fx, fy) / max_mag;
        if (mag > 1.0f) mag = 1.0f;
        float hue = (atan2f(-fy, -fx) / (float)M_PI + 1.0f) * 3.0f; /* [0, 6) */
        int sector = (int)hue % 6;
        float f = hue - floorf(hue), rgb[3];
        float q = 1.0f - f, t = f;
        switch (sector) {
        case 0: rgb[0] = 1; rgb[1] = t; rgb[2] = 0; break;
        case 1: rgb[0] = q; rgb[1] = 1; rgb[2] = 0; break;
        case 2: rgb[0] = 0; rgb[1] = 1; rgb[2] = t; break;
        case 3: rgb[0] = 0; rgb[1] = q; rgb[2] = 1; break;
        case 4: rgb[0] = t; rgb[1] = 0; rgb[2] = 1; break;
        default: rgb[0] = 1; rgb[1] = 0; rgb[2] = q; break;
        }
        for (int c = 0; c < 3; c++) out->data[3 * k + c] = 1.0f - mag * (1.0f - rgb[c]);
    }
}
