/* test_splat_grad.c - finite-difference checks of every rasterizer backward.
 *
 * The float backward is compared with central differences (h = 1e-6) of a double-precision
 * reference forward (tests/splat_ref.h). Error measure: |a - b| / max(|a|, |b|, floor) with
 * floor = 1e-2 x the largest |gradient| of the same parameter kind, so parameters whose
 * gradient is ~0 compared with their siblings are not judged on float round-off alone.
 * Tolerance 1e-3 as required for smooth functions (test data avoids the 0.99 alpha clamp,
 * the early-stop threshold and the 1/255 cut by construction or by being far from them).
 * The rasterizer is checked with a loss on each output (rgb, depth, alpha) separately.
 */
#include "testlib.h"
#include "splat_ref.h"
#include "splat/filter3d.h"
#include "splat/filter3d_kernels.h"
#include "splat/raster_kernels.h"
#include "splat/project.h"
#include "splat/raster.h"
#include "splat/sh.h"
#include "core/rng.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static double rel(double a, double b, double floor)
{
    double m = fmax(fmax(fabs(a), fabs(b)), floor);
    return m > 0 ? fabs(a - b) / m : 0.0; /* both exactly zero (e.g. colour under a depth loss) */
}

static void camera_for_test(pg_camera *cam, int w, int h, int rotated)
{
    pg_camera_from_fov(cam, w, h, 60);
    if (rotated) {
        float eye[3] = { 0.3f, -0.2f, -0.5f }, target[3] = { 0, 0, 4 }, up[3] = { 0, -1, 0 };
        pg_camera_look_at(cam, eye, target, up);
    }
}

/* Projection: loss = sum of random weights * (xy, conic, z). */
static void test_projection(void)
{
    pg_rng rng;
    pg_rng_seed(&rng, 11);
    pg_camera cam;
    camera_for_test(&cam, 64, 48, 1);
    double worst[3] = { 0, 0, 0 };
    for (int trial = 0; trial < 40; trial++) {
        float mean[3], ls[3], q[4];
        /* a few trials put the mean outside the 1.3x frustum so the clamp path is covered */
        float spread = trial % 5 == 4 ? 8.0f : 1.0f;
        mean[0] = (float)pg_rng_range(&rng, -spread, spread);
        mean[1] = (float)pg_rng_range(&rng, -spread, spread);
        mean[2] = (float)pg_rng_range(&rng, 2, 6);
        for (int k = 0; k < 3; k++) ls[k] = (float)pg_rng_range(&rng, -3, -1);
        for (int k = 0; k < 4; k++) q[k] = (float)pg_rng_normal(&rng);
        double wxy[2], wc[3], wz = pg_rng_normal(&rng);
        for (int k = 0; k < 2; k++) wxy[k] = pg_rng_normal(&rng) * 0.1;
        for (int k = 0; k < 3; k++) wc[k] = pg_rng_normal(&rng);
        splat_proj pr;
        if (!splat_project_forward(mean, ls, q, &cam, 0.01f, &pr)) continue;
        /* the conic is tiny for large Gaussians: weight it so every output matters */
        for (int k = 0; k < 3; k++) wc[k] /= fabs(pr.conic[0]) + fabs(pr.conic[2]);
        float dxy[2] = { (float)wxy[0], (float)wxy[1] }, dc[3] = { (float)wc[0], (float)wc[1], (float)wc[2] };
        float gm[3] = { 0 }, gs[3] = { 0 }, gq[4] = { 0 };
        splat_project_backward(mean, ls, q, &cam, dxy, dc, (float)wz, gm, gs, gq);
        double p[REF_NP] = { 0 };
        for (int k = 0; k < 3; k++) { p[REF_MEAN + k] = mean[k]; p[REF_SCALE + k] = ls[k]; }
        for (int k = 0; k < 4; k++) p[REF_QUAT + k] = q[k];
        double fd[10], maxg[3] = { 0, 0, 0 };
        for (int k = 0; k < 10; k++) {
            double h = 1e-6, lp[2];
            for (int sgn = 0; sgn < 2; sgn++) {
                double pp[REF_NP];
                memcpy(pp, p, sizeof(pp));
                pp[k] += sgn ? -h : h;
                double xy[2], con[3], z;
                ref_project(pp, &cam, xy, con, &z, NULL);
                lp[sgn] = wxy[0]*xy[0] + wxy[1]*xy[1] + wc[0]*con[0] + wc[1]*con[1] + wc[2]*con[2] + wz*z;
            }
            fd[k] = (lp[0] - lp[1]) / (2 * h);
            int kind = k < 3 ? 0 : (k < 6 ? 1 : 2);
            maxg[kind] = fmax(maxg[kind], fabs(fd[k]));
        }
        float an[10] = { gm[0], gm[1], gm[2], gs[0], gs[1], gs[2], gq[0], gq[1], gq[2], gq[3] };
        for (int k = 0; k < 10; k++) {
            int kind = k < 3 ? 0 : (k < 6 ? 1 : 2);
            double e = rel(an[k], fd[k], 1e-2 * maxg[kind]);
            if (e > worst[kind]) worst[kind] = e;
            if (e > 1e-3) fprintf(stderr, "projection trial %d param %d: analytic %.8g fd %.8g\n", trial, k, an[k], fd[k]);
        }
    }
    printf("projection FD: worst rel err mean %.2e log_scale %.2e quat %.2e\n", worst[0], worst[1], worst[2]);
    CHECK(worst[0] < 1e-3, "mean gradient rel err %g", worst[0]);
    CHECK(worst[1] < 1e-3, "log_scale gradient rel err %g", worst[1]);
    CHECK(worst[2] < 1e-3, "quaternion gradient rel err %g", worst[2]);
}

/* A 16-wide projection forward/backward (AVX-512 or AVX2 CPUs) against the scalar functions,
 * which the test above checks against finite differences. */
static void test_projection16(const char *name, splat_kernel_kind kind, splat_project16_forward_fn forward16,
                              splat_project16_backward_fn backward16)
{
    pg_rng rng;
    pg_rng_seed(&rng, 21);
    pg_camera cam;
    camera_for_test(&cam, 64, 48, 1);
    const int n = 64;
    float means[3 * 64], ls[3 * 64], q[4 * 64];
    for (int i = 0; i < n; i++) {
        float spread = i % 5 == 4 ? 8.0f : 1.0f; /* some outside the 1.3x frustum: clamp path */
        means[3*i] = (float)pg_rng_range(&rng, -spread, spread);
        means[3*i+1] = (float)pg_rng_range(&rng, -spread, spread);
        means[3*i+2] = (float)pg_rng_range(&rng, i % 7 == 6 ? -1 : 2, 6); /* some behind the camera */
        for (int k = 0; k < 3; k++) ls[3*i+k] = (float)pg_rng_range(&rng, -3, -1);
        for (int k = 0; k < 4; k++) q[4*i+k] = (float)pg_rng_normal(&rng);
    }
    float lim[SPLAT_LIM_COUNT];
    splat_project_limits(&cam, SPLAT_LOWPASS, lim);
    float out[9][16], dxy[2][16], dcon[3][16], dz[16];
    unsigned valid;
    if (!splat_kernel_supported(kind) || !forward16(means, ls, q, 0, &cam, lim, 0.01f, out, &valid)) {
        printf("projection16 %s: not on this CPU, skipped\n", name);
        return;
    }
    double ef = 0, eb = 0;
    float gm[3 * 64] = { 0 }, gs[3 * 64] = { 0 }, gq[4 * 64] = { 0 };
    float hm[3 * 64] = { 0 }, hs[3 * 64] = { 0 }, hq[4 * 64] = { 0 };
    int kept = 0;
    for (int b = 0; b < n; b += 16) {
        forward16(means, ls, q, b, &cam, lim, 0.01f, out, &valid);
        for (int l = 0; l < 16; l++) {
            int i = b + l;
            splat_proj p;
            int ok = splat_project_forward_lim(means + 3*i, ls + 3*i, q + 4*i, &cam, lim, 0.01f, &p);
            CHECK(ok == (int)(valid >> l & 1), "Gaussian %d kept by one projection only", i);
            for (int k = 0; k < 2; k++) dxy[k][l] = (float)pg_rng_normal(&rng);
            for (int k = 0; k < 3; k++) dcon[k][l] = (float)pg_rng_normal(&rng);
            dz[l] = (float)pg_rng_normal(&rng);
            if (!ok) continue;
            kept++;
            float v[9] = { p.xy[0], p.xy[1], p.z, p.cov2d[0], p.cov2d[1], p.cov2d[2], p.conic[0], p.conic[1], p.conic[2] };
            for (int k = 0; k < 9; k++) ef = fmax(ef, rel(v[k], out[k][l], 1e-6));
            float d1[2] = { dxy[0][l], dxy[1][l] }, d2[3] = { dcon[0][l], dcon[1][l], dcon[2][l] };
            splat_project_backward_lim(means + 3*i, ls + 3*i, q + 4*i, &cam, lim, d1, d2, dz[l], hm + 3*i, hs + 3*i, hq + 4*i);
        }
        backward16(means, ls, q, b, &cam, lim, dxy, dcon, dz, valid, gm, gs, gq);
    }
    double scale[3] = { 1e-9, 1e-9, 1e-9 };
    for (int i = 0; i < 3 * n; i++) { scale[0] = fmax(scale[0], fabs(hm[i])); scale[1] = fmax(scale[1], fabs(hs[i])); }
    for (int i = 0; i < 4 * n; i++) scale[2] = fmax(scale[2], fabs(hq[i]));
    for (int i = 0; i < 3 * n; i++) { eb = fmax(eb, rel(gm[i], hm[i], 1e-3 * scale[0])); eb = fmax(eb, rel(gs[i], hs[i], 1e-3 * scale[1])); }
    for (int i = 0; i < 4 * n; i++) eb = fmax(eb, rel(gq[i], hq[i], 1e-3 * scale[2]));
    printf("projection16 %s vs scalar (%d of %d kept): forward %.2e, backward %.2e\n", name, kept, n, ef, eb);
    CHECK(kept > 20 && kept < n, "test data should keep some and cull some (%d)", kept);
    CHECK(ef < 1e-4, "16-wide projection differs by %g", ef);
    CHECK(eb < 1e-3, "16-wide projection backward differs by %g", eb);
}

/* The AVX2 pair does per lane what the AVX-512 pair does, so a model renders alike on either kind of
 * CPU (checked where both run). */
static void test_projection16_families_agree(void)
{
    if (!splat_kernel_supported(SPLAT_KERNEL_AVX512) || !splat_kernel_supported(SPLAT_KERNEL_AVX2)) {
        printf("projection16 avx2 = avx512: needs both on this CPU, skipped\n");
        return;
    }
    pg_rng rng;
    pg_rng_seed(&rng, 23);
    pg_camera cam;
    camera_for_test(&cam, 64, 48, 1);
    float means[48], ls[48], q[64], lim[SPLAT_LIM_COUNT], a[9][16], b[9][16], dxy[2][16], dcon[3][16], dz[16];
    for (int i = 0; i < 16; i++) {
        for (int k = 0; k < 3; k++) means[3*i+k] = (float)pg_rng_range(&rng, k == 2 ? 1 : -2, k == 2 ? 6 : 2);
        for (int k = 0; k < 3; k++) ls[3*i+k] = (float)pg_rng_range(&rng, -3, -1);
        for (int k = 0; k < 4; k++) q[4*i+k] = (float)pg_rng_normal(&rng);
        for (int k = 0; k < 2; k++) dxy[k][i] = (float)pg_rng_normal(&rng);
        for (int k = 0; k < 3; k++) dcon[k][i] = (float)pg_rng_normal(&rng);
        dz[i] = (float)pg_rng_normal(&rng);
    }
    splat_project_limits(&cam, SPLAT_LOWPASS, lim);
    unsigned va, vb;
    splat_project_forward16(means, ls, q, 0, &cam, lim, 0.01f, a, &va);
    splat_project_forward16_avx2(means, ls, q, 0, &cam, lim, 0.01f, b, &vb);
    float ga[10 * 16] = { 0 }, gb[10 * 16] = { 0 };
    splat_project_backward16(means, ls, q, 0, &cam, lim, dxy, dcon, dz, va, ga, ga + 48, ga + 96);
    splat_project_backward16_avx2(means, ls, q, 0, &cam, lim, dxy, dcon, dz, vb, gb, gb + 48, gb + 96);
    double ef = 0, eb = 0;
    for (int k = 0; k < 9; k++)
        for (int l = 0; l < 16; l++)
            if (va >> l & 1) ef = fmax(ef, rel(a[k][l], b[k][l], 1e-6));
    for (int i = 0; i < 160; i++) eb = fmax(eb, rel(ga[i], gb[i], 1e-6));
    /* the same operations in the same order give the same floats; the check allows 1e-6 in case a
     * compiler schedules a fused multiply-add differently in one of the two files */
    CHECK(va == vb, "AVX2 and AVX-512 projections keep other Gaussians (valid %x vs %x)", va, vb);
    CHECK(ef < 1e-6 && eb < 1e-6, "AVX2 and AVX-512 projections differ: forward %g, backward %g", ef, eb);
    printf("projection16 avx2 vs avx512: forward %.2e, backward %.2e (%s)\n", ef, eb,
           memcmp(a, b, sizeof a) == 0 && memcmp(ga, gb, sizeof ga) == 0 ? "same floats" : "not bit-identical");
}

/* SH: every degree, loss = w . rgb, gradient to the coefficients and the view direction. */
static void test_sh(void)
{
    pg_rng rng;
    pg_rng_seed(&rng, 5);
    for (int deg = 0; deg <= 3; deg++) {
        double worst_sh = 0, worst_dir = 0;
        for (int trial = 0; trial < 20; trial++) {
            float sh[48], dir[3];
            for (int k = 0; k < 48; k++) sh[k] = (float)(pg_rng_normal(&rng) * (k < 3 ? 0.5 : 0.2));
            for (int k = 0; k < 3; k++) dir[k] = (float)pg_rng_normal(&rng);
            double w[3];
            for (int k = 0; k < 3; k++) w[k] = pg_rng_normal(&rng);
            float rgb[3], dw[3] = { (float)w[0], (float)w[1], (float)w[2] }, dsh[48] = { 0 }, ddir[3] = { 0 };
            int cl[3];
            splat_sh_forward(deg, sh, dir, rgb, cl);
            splat_sh_backward(deg, sh, dir, cl, dw, dsh, ddir);
            double shd[48], dird[3];
            for (int k = 0; k < 48; k++) shd[k] = sh[k];
            for (int k = 0; k < 3; k++) dird[k] = dir[k];
            double fd[51], maxsh = 0, maxdir = 0;
            for (int k = 0; k < 51; k++) {
                double h = 1e-6, lp[2];
                for (int sgn = 0; sgn < 2; sgn++) {
                    double s2[48], d2[3], out[3];
                    memcpy(s2, shd, sizeof(s2));
                    memcpy(d2, dird, sizeof(d2));
                    if (k < 48) s2[k] += sgn ? -h : h;
                    else d2[k - 48] += sgn ? -h : h;
                    ref_sh(deg, s2, d2, out);
                    lp[sgn] = w[0]*out[0] + w[1]*out[1] + w[2]*out[2];
                }
                fd[k] = (lp[0] - lp[1]) / (2 * h);
                if (k < 48) maxsh = fmax(maxsh, fabs(fd[k])); else maxdir = fmax(maxdir, fabs(fd[k]));
            }
            for (int k = 0; k < 48; k++) worst_sh = fmax(worst_sh, rel(dsh[k], fd[k], 1e-2 * maxsh));
            /* the direction gradient is exactly 0 at degree 0: compare absolutely there */
            for (int k = 0; k < 3; k++)
                worst_dir = fmax(worst_dir, rel(ddir[k], fd[48 + k], fmax(1e-2 * maxdir, 1e-6)));
        }
        printf("SH degree %d FD: worst rel err coeffs %.2e view dir %.2e\n", deg, worst_sh, worst_dir);
        CHECK(worst_sh < 1e-3, "SH degree %d coefficient gradient rel err %g", deg, worst_sh);
        CHECK(worst_dir < 1e-3, "SH degree %d direction gradient rel err %g", deg, worst_dir);
    }
}

/* A few overlapping Gaussians in front of a rotated camera, SH degree 3. */
static void make_scene(pg_gaussians *g, int n, pg_rng *rng)
{
    splat_gaussians_create(g, n);
    splat_gaussians_resize(g, n);
    for (int i = 0; i < n; i++) {
        g->means[3*i] = (float)pg_rng_range(rng, -1.2, 1.2);
        g->means[3*i+1] = (float)pg_rng_range(rng, -1.0, 1.0);
        g->means[3*i+2] = (float)pg_rng_range(rng, 3.5, 4.5);
        for (int k = 0; k < 3; k++) g->log_scales[3*i+k] = (float)pg_rng_range(rng, -1.0, -0.4);
        for (int k = 0; k < 4; k++) g->quats[4*i+k] = (float)pg_rng_normal(rng);
        g->opacity[i] = (float)pg_rng_range(rng, -1.0, 1.2); /* o in (0.27, 0.77) */
        for (int k = 0; k < 48; k++) g->sh[48*i+k] = (float)(pg_rng_normal(rng) * (k < 3 ? 0.6 : 0.15));
    }
    g->sh_degree = 3;
}

/* output: 0 = rgb, 1 = depth, 2 = alpha; the loss is a random weighting of that output only,
 * and the float backward gets NULL for the other two (as a caller would pass). */
static void test_raster(int output)
{
    static const char *outname[3] = { "rgb", "depth", "alpha" };
    pg_rng rng;
    pg_rng_seed(&rng, 3);
    const int n = 6, W = 40, H = 24; /* 3 x 2 tiles, partial edge tiles */
    pg_gaussians g, grads[SPLAT_KERNELS];
    make_scene(&g, n, &rng);
    pg_camera cam;
    camera_for_test(&cam, W, H, 1);
    pg_render_settings s = splat_default_settings();
    s.background[0] = 0.2f; s.background[1] = 0.5f; s.background[2] = 0.9f;
    size_t P = (size_t)W * H;
    float *wr = malloc(P * 3 * sizeof(float)), *wd = malloc(P * sizeof(float)), *wa = malloc(P * sizeof(float));
    for (size_t i = 0; i < 3 * P; i++) wr[i] = output == 0 ? (float)pg_rng_normal(&rng) : 0.0f;
    for (size_t i = 0; i < P; i++) {
        wd[i] = output == 1 ? (float)pg_rng_normal(&rng) : 0.0f;
        wa[i] = output == 2 ? (float)pg_rng_normal(&rng) : 0.0f;
    }

    splat_raster *r;
    CHECK_OK(splat_raster_create(&r));
    pg_render_output out;
    float *vs = calloc(n, sizeof(float));
    int kinds = 0; /* the kernel families this CPU has: 0 .. kinds-1 */
    while (kinds < SPLAT_KERNELS && splat_kernel_supported((splat_kernel_kind)kinds)) kinds++;
    for (int simd = 0; simd < kinds; simd++) {
        splat_gaussians_create(&grads[simd], n);
        splat_gaussians_resize(&grads[simd], n);
        splat_raster_set_kernel(r, (splat_kernel_kind)simd);
        CHECK_OK(splat_render_forward(r, &g, &cam, &s, &out));
        CHECK_OK(splat_render_backward(r, &g, &cam, &s, output == 0 ? wr : NULL, output == 1 ? wd : NULL,
                                       output == 2 ? wa : NULL, &grads[simd], vs));
    }

    double *params = malloc(sizeof(double) * REF_NP * n);
    for (int i = 0; i < n; i++) ref_pack(&g, i, params + REF_NP * i);
    double *rgb = malloc(sizeof(double) * 3 * P), *dep = malloc(sizeof(double) * P), *alp = malloc(sizeof(double) * P);
    double bg[3] = { s.background[0], s.background[1], s.background[2] };
    /* forward agreement */
    ref_render(params, n, 3, &cam, bg, rgb, dep, alp);
    double fwd_err = 0;
    for (size_t i = 0; i < P; i++) {
        for (int c = 0; c < 3; c++) fwd_err = fmax(fwd_err, fabs(rgb[3*i+c] - out.rgb[3*i+c]));
        fwd_err = fmax(fwd_err, fabs(dep[i] - out.depth[i]) / 5);
        fwd_err = fmax(fwd_err, fabs(alp[i] - out.alpha[i]));
    }
    double cover = 0;
    for (size_t i = 0; i < P; i++) cover += out.alpha[i];
    if (output == 0)
        printf("raster forward (%s) vs double reference: max abs err %.2e, mean alpha %.3f\n",
               splat_kernel_name(splat_raster_kernel(r)), fwd_err, cover / P);
    CHECK(fwd_err < 1e-4, "forward differs from the double reference by %g", fwd_err);
    CHECK(cover / P > 0.15, "test scene covers too little (mean alpha %g)", cover / P);

    /* kinds: 0 mean, 1 log_scale, 2 quat, 3 opacity, 4 SH */
    static const char *names[5] = { "mean", "log_scale", "quat", "opacity", "sh" };
    double *fd = malloc(sizeof(double) * REF_NP * n), maxg[5] = { 0 }, worst[5] = { 0 };
    for (int i = 0; i < n; i++)
        for (int k = 0; k < REF_NP; k++) {
            double h = 1e-6, lp[2];
            for (int sgn = 0; sgn < 2; sgn++) {
                double keep = params[REF_NP * i + k];
                params[REF_NP * i + k] = keep + (sgn ? -h : h);
                ref_render(params, n, 3, &cam, bg, rgb, dep, alp);
                params[REF_NP * i + k] = keep;
                double L = 0;
                for (size_t q = 0; q < P; q++) {
                    L += (double)wr[3*q]*rgb[3*q] + (double)wr[3*q+1]*rgb[3*q+1] + (double)wr[3*q+2]*rgb[3*q+2];
                    L += (double)wd[q]*dep[q] + (double)wa[q]*alp[q];
                }
                lp[sgn] = L;
            }
            fd[REF_NP * i + k] = (lp[0] - lp[1]) / (2 * h);
            int kind = k < 3 ? 0 : k < 6 ? 1 : k < 10 ? 2 : k < 11 ? 3 : 4;
            maxg[kind] = fmax(maxg[kind], fabs(fd[REF_NP * i + k]));
        }
    for (int simd = 0; simd < kinds; simd++) {
        for (int k = 0; k < 5; k++) worst[k] = 0;
        for (int i = 0; i < n; i++)
            for (int k = 0; k < REF_NP; k++) {
                int kind = k < 3 ? 0 : k < 6 ? 1 : k < 10 ? 2 : k < 11 ? 3 : 4;
                double a = ref_grad_of(&grads[simd], i, k), b = fd[REF_NP * i + k];
                double e = rel(a, b, 1e-2 * maxg[kind]);
                if (e > 1e-3) fprintf(stderr, "raster gaussian %d param %d (%s): analytic %.8g fd %.8g\n", i, k, names[kind], a, b);
                worst[kind] = fmax(worst[kind], e);
            }
        printf("raster FD, loss on %s (%s kernels): worst rel err mean %.2e log_scale %.2e quat %.2e opacity %.2e sh %.2e\n",
               outname[output], splat_kernel_name((splat_kernel_kind)simd), worst[0], worst[1], worst[2], worst[3], worst[4]);
        for (int k = 0; k < 5; k++)
            CHECK(worst[k] < 1e-3, "raster %s gradient rel err %g (loss on %s, %s kernels)", names[k], worst[k],
                  outname[output], splat_kernel_name((splat_kernel_kind)simd));
    }
    double vs_sum = 0;
    for (int i = 0; i < n; i++) vs_sum += vs[i];
    CHECK(vs_sum > 0, "view-space gradient norm not accumulated");

    free(fd); free(params); free(rgb); free(dep); free(alp); free(vs); free(wr); free(wd); free(wa);
    splat_raster_destroy(r);
    splat_gaussians_destroy(&g);
    for (int simd = 0; simd < kinds; simd++) splat_gaussians_destroy(&grads[simd]);
}

/* Double reference of the 3D filter for one Gaussian: filtered log-scales and opacity logit. */
static void filter3d_ref(const double ls[3], double o, double var, double out[4])
{
    double log_rho = 0;
    for (int k = 0; k < 3; k++) {
        out[k] = 0.5 * log(exp(2 * ls[k]) + var);
        log_rho += ls[k] - out[k];
    }
    double a = 1 / (1 + exp(-o)) * exp(log_rho);
    out[3] = log(a / (1 - a));
}

/* The 3D filter with kernel family k: its backward against central differences of the double
 * reference (scales far below, near and far above the filter; opacity logits from -100 to 12), and
 * the variance it takes from the cameras (the nearest camera that sees a point; none in front: 0). */
static void test_filter3d(splat_kernel_kind kind)
{
    if (!splat_kernel_supported(kind)) {
        printf("3D filter %s: not supported by this CPU, skipped\n", splat_kernel_name(kind));
        return;
    }
    splat_filter3d_set_kernel(kind);
    enum { N = 60 };
    pg_rng rng;
    pg_rng_seed(&rng, 11);
    float ls[N * 3], op[N], var[N], saved[N * SPLAT_FILTER3D_SAVED], g_ls[N * 3], g_op[N];
    double w[N][4];
    for (int i = 0; i < N; i++) {
        var[i] = i % 10 == 9 ? 0.0f : (float)exp(-6 + 4 * pg_rng_uniform(&rng));
        for (int k = 0; k < 3; k++) ls[3 * i + k] = (float)(-7 + 7 * pg_rng_uniform(&rng));
        op[i] = (float)(-4 + 10 * pg_rng_uniform(&rng));
        if (i % 10 == 3) op[i] = i % 20 == 3 ? 12.0f : -100.0f; /* near-opaque; below float's sigmoid */
        if (i % 10 == 5) { /* what the deformation produced on tabletop_dev: a needle squeezed to
                              * rho under float (was opacity -inf), or stretched past s^2's float
                              * range (was log-scale inf, NaN next) */
            ls[3 * i] = -36.0f, ls[3 * i + 1] = i % 20 == 5 ? 10.5f : 46.0f, ls[3 * i + 2] = -26.4f, op[i] = -43.5f;
            var[i] = 4.4e-5f;
        }
        for (int k = 0; k < 4; k++) w[i][k] = pg_rng_normal(&rng);
    }
    float fl[N * 3], fo[N];
    memcpy(fl, ls, sizeof ls);
    memcpy(fo, op, sizeof op);
    splat_filter3d_forward(fl, fo, var, N, saved);
    for (int i = 0; i < N; i++) {
        for (int k = 0; k < 3; k++) g_ls[3 * i + k] = (float)w[i][k];
        g_op[i] = (float)w[i][3];
    }
    splat_filter3d_backward(saved, var, N, g_ls, g_op);
    double worst = 0, worst_fwd = 0;
    const double h = 1e-6;
    for (int i = 0; i < N; i++) {
        double base[4] = { ls[3 * i], ls[3 * i + 1], ls[3 * i + 2], op[i] }, ref[4];
        filter3d_ref(base, base[3], var[i], ref);
        for (int k = 0; k < 3; k++) worst_fwd = fmax(worst_fwd, fabs(ref[k] - fl[3 * i + k]));
        worst_fwd = fmax(worst_fwd, fabs(ref[3] - fo[i]) / fmax(1, fabs(ref[3])));
        for (int p = 0; p < 4; p++) {
            double hi[4], lo[4], x[4];
            memcpy(x, base, sizeof x);
            x[p] += h;
            filter3d_ref(x, x[3], var[i], hi);
            x[p] -= 2 * h;
            filter3d_ref(x, x[3], var[i], lo);
            double fd = 0;
            for (int k = 0; k < 4; k++) fd += w[i][k] * (hi[k] - lo[k]) / (2 * h);
            double an = p < 3 ? g_ls[3 * i + p] : g_op[i];
            worst = fmax(worst, rel(an, fd, 1e-3));
        }
    }
    printf("3D filter %s: forward off the double reference by %.2e, backward off finite differences by %.2e\n",
           splat_kernel_name(kind), worst_fwd, worst);
    CHECK(worst_fwd < 1e-5, "3D filter %s forward off the double reference by %.3g", splat_kernel_name(kind), worst_fwd);
    CHECK(worst < 1e-3, "3D filter %s backward vs finite differences: worst relative error %.3g", splat_kernel_name(kind), worst);
    /* the rows variant filters exactly the listed rows, as the whole-array one does */
    {
        int rows[N / 2];
        float rl[N * 3], ro[N], rs[N * SPLAT_FILTER3D_SAVED];
        memcpy(rl, ls, sizeof ls);
        memcpy(ro, op, sizeof op);
        for (int k = 0; k < N / 2; k++) rows[k] = 2 * k + 1;
        splat_filter3d_forward_rows(rl, ro, var, rows, N / 2, rs);
        int wrong = 0;
        for (int i = 0; i < N; i++) {
            const int listed = i % 2 == 1;
            for (int k = 0; k < 3; k++) wrong += rl[3 * i + k] != (listed ? fl[3 * i + k] : ls[3 * i + k]);
            wrong += ro[i] != (listed ? fo[i] : op[i]);
            for (int k = 0; listed && var[i] > 0 && k < SPLAT_FILTER3D_SAVED; k++)
                wrong += rs[SPLAT_FILTER3D_SAVED * i + k] != saved[SPLAT_FILTER3D_SAVED * i + k];
        }
        CHECK(wrong == 0, "3D filter %s: the rows variant differs from the whole-array one in %d values",
              splat_kernel_name(kind), wrong);
    }

    pg_camera cams[2];
    pg_camera_from_fov(&cams[0], 100, 80, 60);
    pg_camera_from_fov(&cams[1], 100, 80, 60);
    cams[1].t[2] = 2; /* 2 units further back: camera z = world z + 2 */
    const float means[3 * 3] = { 0, 0, 4, 3.5f, 0, 4, 0, 0, -5 }; /* both see; only the far one sees; behind */
    float v[3];
    splat_filter3d_compute(means, 3, cams, 2, v);
    const double foot0 = 4.0 / cams[0].fx, foot1 = 6.0 / cams[1].fx;
    CHECK(fabs(v[0] - SPLAT_FILTER3D_VAR * foot0 * foot0) < 1e-6 * v[0], "filter of a point both cameras see: %g", (double)v[0]);
    CHECK(fabs(v[1] - SPLAT_FILTER3D_VAR * foot1 * foot1) < 1e-6 * v[1], "filter of a point only the far camera sees: %g", (double)v[1]);
    CHECK(v[2] == 0, "filter of a point behind every camera: %g", (double)v[2]);

    /* fresh Gaussians: after fit_init, filtered, they draw at their initial opacity (below the
     * cap) and no scale is under the filter's std */
    float il[N * 3], io[N], jl[N * 3], jo[N];
    memcpy(il, ls, sizeof ls);
    for (int i = 0; i < N; i++) io[i] = logf(0.3f / 0.7f);
    memcpy(jl, il, sizeof il);
    memcpy(jo, io, sizeof io);
    splat_filter3d_fit_init(jl, jo, var, N);
    int thin = 0;
    double worst_op = 0;
    for (int i = 0; i < N; i++)
        for (int k = 0; k < 3; k++) thin += var[i] > 0 && expf(2 * jl[3 * i + k]) < 0.999f * var[i];
    memcpy(fl, jl, sizeof jl);
    memcpy(fo, jo, sizeof jo);
    splat_filter3d_forward(fl, fo, var, N, NULL);
    for (int i = 0; i < N; i++) {
        const double raised = 1 / (1 + exp(-(double)jo[i]));
        if (raised < 0.98) worst_op = fmax(worst_op, fabs(1 / (1 + exp(-(double)fo[i])) - 0.3));
    }
    CHECK(thin == 0, "%d scales under the filter's std after fit_init", thin);
    CHECK(worst_op < 1e-5, "filtered opacity after fit_init off the initial 0.3 by %.3g", worst_op);
    splat_filter3d_set_kernel(SPLAT_KERNELS); /* back to the default */
}


/* The rasterizer's polynomial log and sigmoid: within 2 ulp of the double ones over the range
 * they see, and (with AVX-512) the 16-lane twins equal to the scalar ones bit for bit. */
static void test_poly_log_sigmoid(void)
{
    double worst_log = 0, worst_sig = 0;
    int lanes_differ = 0;
    for (int k = 0; k < 20000; k++) {
        float x = (float)exp(-80.0 + 160.0 * k / 20000.0), t = (float)(-90.0 + 180.0 * k / 20000.0);
        double ulp_log = fabs(log((double)x)) * 1.2e-7 + 1e-45;
        worst_log = fmax(worst_log, fabs(splat_log_poly(x) - log((double)x)) / fmax(ulp_log, 1.2e-7 * 1e-1));
        double sig = 1.0 / (1.0 + exp(-(double)t));
        if (sig > 1e-37) worst_sig = fmax(worst_sig, fabs(splat_sigmoid_poly(t) - sig) / (sig * 1.2e-7));
#if defined(__AVX512F__)
        if (splat_kernel_supported(SPLAT_KERNEL_AVX512) && k % 16 == 0) {
            float xs[16], ts[16], lv[16], sv[16];
            for (int l = 0; l < 16; l++) {
                xs[l] = (float)exp(-80.0 + 160.0 * (k + l) / 20000.0);
                ts[l] = (float)(-90.0 + 180.0 * (k + l) / 20000.0);
            }
            _mm512_storeu_ps(lv, splat_log_poly16(_mm512_loadu_ps(xs)));
            _mm512_storeu_ps(sv, splat_sigmoid_poly16(_mm512_loadu_ps(ts)));
            for (int l = 0; l < 16; l++)
                lanes_differ += memcmp(&lv[l], &(float){ splat_log_poly(xs[l]) }, 4) != 0 ||
                                memcmp(&sv[l], &(float){ splat_sigmoid_poly(ts[l]) }, 4) != 0;
        }
#endif
    }
    printf("polynomial log: worst %.2f ulp; sigmoid: worst %.2f ulp; 16-lane twins differ in %d lanes\n", worst_log,
           worst_sig, lanes_differ);
    CHECK(worst_log < 2.0, "splat_log_poly off log by %.2f ulp", worst_log);
    CHECK(worst_sig < 4.0, "splat_sigmoid_poly off the sigmoid by %.2f ulp", worst_sig);
    CHECK(lanes_differ == 0, "%d lanes of the 16-lane log / sigmoid differ from the scalar ones", lanes_differ);
    CHECK(splat_sigmoid_poly(NAN) != splat_sigmoid_poly(NAN), "sigmoid of NaN is not NaN");
}

int main(void)
{
    test_projection();
    test_projection16("avx512", SPLAT_KERNEL_AVX512, splat_project_forward16, splat_project_backward16);
    test_projection16("avx2", SPLAT_KERNEL_AVX2, splat_project_forward16_avx2, splat_project_backward16_avx2);
    test_projection16_families_agree();
    test_sh();
    test_poly_log_sigmoid();
    test_filter3d(SPLAT_KERNEL_SCALAR);
    test_filter3d(SPLAT_KERNEL_AVX512);
    for (int output = 0; output < 3; output++) test_raster(output);
    return test_summary("test_splat_grad");
}
