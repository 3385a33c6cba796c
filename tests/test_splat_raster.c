/* test_splat_raster.c - rasterizer properties other than gradients: SIMD vs scalar agreement,
 * determinism across runs and thread counts, edge cases and bad input. */
#include "testlib.h"
#include "splat/random_scene.h"
#include "splat/project.h"
#include "splat/raster.h"
#include "core/parallel.h"
#include "core/rng.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    float *rgb, *depth, *alpha;
    pg_gaussians grad;
    float *vs;
} run_result;

static void run_whole(splat_raster *r, const pg_gaussians *g, const pg_camera *cam, const pg_camera *whole,
                      const float *d_rgb, const float *d_depth, const float *d_alpha, run_result *res)
{
    size_t P = (size_t)cam->width * cam->height;
    pg_render_settings s = splat_default_settings();
    s.whole = whole;
    s.background[0] = 0.1f; s.background[1] = 0.2f; s.background[2] = 0.3f;
    pg_render_output out;
    CHECK_OK(splat_render_forward(r, g, cam, &s, &out));
    res->rgb = malloc(P * 3 * sizeof(float));
    res->depth = malloc(P * sizeof(float));
    res->alpha = malloc(P * sizeof(float));
    memcpy(res->rgb, out.rgb, P * 3 * sizeof(float));
    memcpy(res->depth, out.depth, P * sizeof(float));
    memcpy(res->alpha, out.alpha, P * sizeof(float));
    splat_gaussians_create(&res->grad, g->count);
    splat_gaussians_resize(&res->grad, g->count);
    res->vs = calloc((size_t)g->count + 1, sizeof(float));
    CHECK_OK(splat_render_backward(r, g, cam, &s, d_rgb, d_depth, d_alpha, &res->grad, res->vs));
}

static void run(splat_raster *r, const pg_gaussians *g, const pg_camera *cam, const float *d_rgb,
                const float *d_depth, const float *d_alpha, run_result *res)
{
    run_whole(r, g, cam, NULL, d_rgb, d_depth, d_alpha, res);
}

static void free_result(run_result *res)
{
    free(res->rgb); free(res->depth); free(res->alpha); free(res->vs);
    splat_gaussians_destroy(&res->grad);
}

/* Largest |a - b| / max|a| over an array. */
static double rel_diff(const float *a, const float *b, size_t n)
{
    double m = 1e-30, d = 0;
    for (size_t i = 0; i < n; i++) { m = fmax(m, fabs(a[i])); d = fmax(d, fabs(a[i] - b[i])); }
    return d / m;
}

static int same_bytes(const run_result *a, const run_result *b, int n, size_t P)
{
    return !memcmp(a->rgb, b->rgb, P * 3 * sizeof(float)) && !memcmp(a->depth, b->depth, P * sizeof(float)) &&
           !memcmp(a->alpha, b->alpha, P * sizeof(float)) &&
           !memcmp(a->grad.means, b->grad.means, (size_t)n * 3 * sizeof(float)) &&
           !memcmp(a->grad.log_scales, b->grad.log_scales, (size_t)n * 3 * sizeof(float)) &&
           !memcmp(a->grad.quats, b->grad.quats, (size_t)n * 4 * sizeof(float)) &&
           !memcmp(a->grad.opacity, b->grad.opacity, (size_t)n * sizeof(float)) &&
           !memcmp(a->grad.sh, b->grad.sh, (size_t)n * 48 * sizeof(float)) &&
           !memcmp(a->vs, b->vs, (size_t)n * sizeof(float));
}

static void test_simd_and_determinism(void)
{
    const int W = 150, H = 90, N = 3000;
    size_t P = (size_t)W * H;
    pg_camera cam;
    pg_camera_from_fov(&cam, W, H, 60);
    pg_gaussians g;
    CHECK_OK(splat_gaussians_create(&g, N));
    CHECK_OK(splat_random_scene(&g, &cam, N, 3.0f, 3, 17));
    /* some nearly opaque Gaussians: exercises the 0.99 alpha clamp and early termination */
    for (int i = 0; i < N; i += 7) g.opacity[i] = 6.0f;
    /* some anisotropic, rotated ones */
    for (int i = 3; i < N; i += 5) {
        g.log_scales[3*i] += 0.7f;
        g.log_scales[3*i+2] -= 0.5f;
        g.quats[4*i+1] = 0.4f; g.quats[4*i+3] = -0.3f;
    }
    pg_rng rng;
    pg_rng_seed(&rng, 4);
    float *d_rgb = malloc(P * 3 * sizeof(float)), *d_depth = malloc(P * sizeof(float)), *d_alpha = malloc(P * sizeof(float));
    for (size_t i = 0; i < 3 * P; i++) d_rgb[i] = (float)pg_rng_normal(&rng);
    for (size_t i = 0; i < P; i++) { d_depth[i] = (float)(0.1 * pg_rng_normal(&rng)); d_alpha[i] = (float)pg_rng_normal(&rng); }

    splat_raster *r;
    CHECK_OK(splat_raster_create(&r));
    run_result sc;
    CHECK_OK(splat_raster_set_kernel(r, SPLAT_KERNEL_SCALAR));
    pg_set_threads(2);
    run(r, &g, &cam, d_rgb, d_depth, d_alpha, &sc);
    /* every SIMD kernel family the CPU has, against the scalar reference */
    for (int k = SPLAT_KERNEL_AVX2; k < SPLAT_KERNELS; k++) {
        const char *name = splat_kernel_name((splat_kernel_kind)k);
        if (splat_raster_set_kernel(r, (splat_kernel_kind)k) != 0) {
            printf("raster kernels %s: not supported by this CPU, skipped\n", name);
            continue;
        }
        run_result si, si2, t1;
        pg_set_threads(2);
        run(r, &g, &cam, d_rgb, d_depth, d_alpha, &si);
        run(r, &g, &cam, d_rgb, d_depth, d_alpha, &si2);
        pg_set_threads(1);
        run(r, &g, &cam, d_rgb, d_depth, d_alpha, &t1);
        pg_set_threads(2);
        double e_img = fmax(rel_diff(sc.rgb, si.rgb, 3 * P), fmax(rel_diff(sc.depth, si.depth, P), rel_diff(sc.alpha, si.alpha, P)));
        double e_grad[6] = { rel_diff(sc.grad.means, si.grad.means, 3 * (size_t)N),
                             rel_diff(sc.grad.log_scales, si.grad.log_scales, 3 * (size_t)N),
                             rel_diff(sc.grad.quats, si.grad.quats, 4 * (size_t)N),
                             rel_diff(sc.grad.opacity, si.grad.opacity, (size_t)N),
                             rel_diff(sc.grad.sh, si.grad.sh, 48 * (size_t)N),
                             rel_diff(sc.vs, si.vs, (size_t)N) };
        double e_max = 0;
        for (int q = 0; q < 6; q++) e_max = fmax(e_max, e_grad[q]);
        printf("scalar vs %s: images %.2e, gradients mean %.2e scale %.2e quat %.2e opacity %.2e sh %.2e vs-norm %.2e\n",
               name, e_img, e_grad[0], e_grad[1], e_grad[2], e_grad[3], e_grad[4], e_grad[5]);
        CHECK(e_img <= 1e-5, "scalar and %s images differ by %g", name, e_img);
        CHECK(e_max <= 1e-5, "scalar and %s gradients differ by %g (relative to the largest)", name, e_max);
        CHECK(same_bytes(&si, &si2, N, P), "%s: two identical runs gave different bytes", name);
        CHECK(same_bytes(&si, &t1, N, P), "%s: 1 and 2 threads gave different bytes", name);
        free_result(&si); free_result(&si2); free_result(&t1);
    }
    double cover = 0;
    for (size_t i = 0; i < P; i++) cover += sc.alpha[i];
    CHECK(cover / P > 0.3, "workload covers too little: mean alpha %g", cover / P);
    free_result(&sc);
    free(d_rgb); free(d_depth); free(d_alpha);
    splat_raster_destroy(r);
    splat_gaussians_destroy(&g);
}

static void test_edge_cases(void)
{
    pg_camera cam;
    pg_camera_from_fov(&cam, 33, 17, 50);
    splat_raster *r;
    CHECK_OK(splat_raster_create(&r));
    pg_render_settings s = splat_default_settings();
    s.background[0] = 0.25f; s.background[1] = 0.5f; s.background[2] = 1.0f;
    pg_gaussians g, grad;
    CHECK_OK(splat_gaussians_create(&g, 4));
    CHECK_OK(splat_gaussians_create(&grad, 4));
    pg_render_output out;
    /* backward before any forward */
    CHECK(splat_render_backward(r, &g, &cam, &s, NULL, NULL, NULL, &grad, NULL) != PG_OK, "backward without forward accepted");
    /* empty set: background everywhere */
    CHECK_OK(splat_render_forward(r, &g, &cam, &s, &out));
    CHECK(out.rgb[0] == 0.25f && out.rgb[3 * 33 * 17 - 1] == 1.0f && out.alpha[5] == 0 && out.depth[7] == 0,
          "empty scene is not the background");
    CHECK_OK(splat_render_backward(r, &g, &cam, &s, NULL, NULL, NULL, &grad, NULL));
    /* behind the camera, NaN, huge and off-screen Gaussians are culled without trouble */
    CHECK_OK(splat_gaussians_resize(&g, 4));
    CHECK_OK(splat_gaussians_resize(&grad, 4));
    float means[12] = { 0, 0, -3, NAN, 0, 3, 1e30f, 0, 3, 0, 0, 3 };
    memcpy(g.means, means, sizeof(means));
    for (int i = 0; i < 4; i++) { g.quats[4*i] = 1; g.opacity[i] = 3; for (int k = 0; k < 3; k++) g.log_scales[3*i+k] = -2; }
    g.log_scales[9] = 40; /* enormous */
    CHECK_OK(splat_render_forward(r, &g, &cam, &s, &out));
    int finite = 1;
    for (int i = 0; i < 33 * 17 * 3; i++) finite &= isfinite(out.rgb[i]);
    CHECK(finite, "non-finite pixels");
    float *d = calloc(33 * 17 * 3, sizeof(float));
    for (int i = 0; i < 33 * 17 * 3; i++) d[i] = 1;
    CHECK_OK(splat_render_backward(r, &g, &cam, &s, d, NULL, NULL, &grad, NULL));
    CHECK(grad.means[0] == 0 && grad.opacity[0] == 0 && grad.opacity[1] == 0, "culled Gaussians got gradients");
    /* mismatched gradient set */
    pg_gaussians small;
    CHECK_OK(splat_gaussians_create(&small, 1));
    CHECK(splat_render_backward(r, &g, &cam, &s, d, NULL, NULL, &small, NULL) == PG_ERR_ARG, "wrong gradient size accepted");
    /* bad camera */
    pg_camera bad = cam;
    bad.width = 0;
    CHECK(splat_render_forward(r, &g, &bad, &s, &out) != PG_OK, "zero-width camera accepted");
    CHECK(splat_render_backward(r, &g, &bad, &s, d, NULL, NULL, &grad, NULL) != PG_OK, "backward after failed forward accepted");
    free(d);
    splat_gaussians_destroy(&small);
    splat_gaussians_destroy(&g);
    splat_gaussians_destroy(&grad);
    splat_raster_destroy(r);
}

/* A crop is a camera with the crop's size and its principal point shifted by the crop's corner
 * (the trainer's motion crops rely on it): the crop renders the full image's pixels there, and
 * a loss gradient that is zero outside the crop gives the same Gaussian gradients both ways. */
static void test_crop_camera(void)
{
    const int W = 96, H = 64, N = 1500, x0 = 32, y0 = 16, cw = 48, ch = 32;
    size_t P = (size_t)W * H, Pc = (size_t)cw * ch;
    pg_camera cam, crop;
    pg_camera_from_fov(&cam, W, H, 60);
    pg_gaussians g;
    CHECK_OK(splat_gaussians_create(&g, N));
    CHECK_OK(splat_random_scene(&g, &cam, N, 3.0f, 3, 5));
    crop = cam;
    crop.width = cw, crop.height = ch;
    crop.cx -= (float)x0, crop.cy -= (float)y0;
    float *d_full = calloc(P * 3, sizeof(float)), *d_crop = malloc(Pc * 3 * sizeof(float));
    pg_rng rng;
    pg_rng_seed(&rng, 9);
    for (int y = 0; y < ch; y++)
        for (int x = 0; x < cw * 3; x++)
            d_crop[(size_t)y * cw * 3 + x] = d_full[((size_t)(y0 + y) * W + x0) * 3 + x] = (float)pg_rng_normal(&rng);
    splat_raster *r;
    CHECK_OK(splat_raster_create(&r));
    pg_set_threads(2);
    run_result full, part;
    run(r, &g, &cam, d_full, NULL, NULL, &full);
    run_whole(r, &g, &crop, &cam, d_crop, NULL, NULL, &part);
    double worst = 0;
    for (int y = 0; y < ch; y++)
        for (int x = 0; x < cw * 3; x++)
            worst = fmax(worst, fabs(part.rgb[(size_t)y * cw * 3 + x] - full.rgb[((size_t)(y0 + y) * W + x0) * 3 + x]));
    CHECK(worst < 1e-5, "crop render differs from the full render by %g", worst);
    double gm = rel_diff(full.grad.means, part.grad.means, (size_t)N * 3);
    double go = rel_diff(full.grad.opacity, part.grad.opacity, (size_t)N);
    double gs = rel_diff(full.grad.sh, part.grad.sh, (size_t)N * 48);
    double gv = rel_diff(full.vs, part.vs, (size_t)N);
    CHECK(gm < 1e-4 && go < 1e-4 && gs < 1e-4 && gv < 1e-4, "crop gradients differ: means %g opacity %g sh %g view-space %g",
          gm, go, gs, gv);
    free_result(&full);
    free_result(&part);
    free(d_full);
    free(d_crop);
    splat_gaussians_destroy(&g);
    splat_raster_destroy(r);
}

/* A render at 3x the training size, given the training focal, samples the image the training size
 * drew: its pixel (3i+1, 3j+1) sits on the 1x pixel (i, j)'s centre and must show the same colour.
 * With each camera's own pixel filter the sub-pixel splats of the 3x render are thinner and fainter,
 * and the two renders part. Checked on every kernel the CPU has. */
static void test_training_pixel_filter(void)
{
    const int W = 40, H = 30, N = 400, S = 3;
    pg_camera cam1, cam3;
    pg_camera_from_fov(&cam1, W, H, 60);
    pg_camera_from_fov(&cam3, S * W, S * H, 60);
    pg_render_settings s = splat_default_settings();
    CHECK(fabsf(splat_lowpass_for(&cam3, &s) - SPLAT_LOWPASS) < 1e-9f, "no training focal: plain filter");
    s.train_focal = cam1.fx;
    CHECK(fabsf(splat_lowpass_for(&cam1, &s) - SPLAT_LOWPASS) < 1e-9f, "training size: plain filter");
    CHECK(fabsf(splat_lowpass_for(&cam3, &s) - 9 * SPLAT_LOWPASS) < 1e-5f, "3x: %g (0.9 wanted)", splat_lowpass_for(&cam3, &s));
    pg_camera half;
    pg_camera_from_fov(&half, W / 2, H / 2, 60);
    CHECK(fabsf(splat_lowpass_for(&half, &s) - SPLAT_LOWPASS) < 1e-9f, "coarser than training: the pixel's own filter");

    pg_gaussians g;
    CHECK_OK(splat_gaussians_create(&g, N));
    CHECK_OK(splat_random_scene(&g, &cam1, N, 0.4f, 0, 11)); /* mostly thinner than a training pixel */
    splat_raster *r;
    CHECK_OK(splat_raster_create(&r));
    pg_set_threads(2);
    for (int k = 0; k < SPLAT_KERNELS; k++) {
        if (!splat_kernel_supported((splat_kernel_kind)k)) continue;
        splat_raster_set_kernel(r, (splat_kernel_kind)k);
        float *ref = malloc((size_t)W * H * 3 * sizeof(float));
        pg_render_output out;
        s.train_focal = cam1.fx;
        CHECK_OK(splat_render_forward(r, &g, &cam1, &s, &out));
        memcpy(ref, out.rgb, (size_t)W * H * 3 * sizeof(float));
        double worst[2] = { 0, 0 };
        for (int consistent = 0; consistent < 2; consistent++) {
            s.train_focal = consistent ? cam1.fx : 0.0f;
            CHECK_OK(splat_render_forward(r, &g, &cam3, &s, &out));
            for (int y = 0; y < H; y++)
                for (int x = 0; x < W; x++)
                    for (int c = 0; c < 3; c++)
                        worst[consistent] = fmax(worst[consistent], fabs(ref[((size_t)y * W + x) * 3 + c] -
                                                                           out.rgb[(((size_t)(S * y + 1) * S * W) + S * x + 1) * 3 + c]));
        }
        printf("training-pixel filter, %s: 3x vs 1x at shared centres %.2e (own-pixel filter: %.3f)\n", splat_kernel_name((splat_kernel_kind)k), worst[1], worst[0]);
        CHECK(worst[1] < 1e-4, "%s: 3x render off the 1x one by %g at shared pixel centres", splat_kernel_name((splat_kernel_kind)k), worst[1]);
        CHECK(worst[0] > 0.1, "%s: without the training focal the 3x render should part from the 1x one (%g)",
              splat_kernel_name((splat_kernel_kind)k), worst[0]);
        free(ref);
    }
    splat_gaussians_destroy(&g);
    splat_raster_destroy(r);
}

static void test_bench_cli(void)
{
    char err[512];
    int rc = test_run_cli("bench raster --width 64 --height 48 --gaussians 500 --sigma-px 2 --threads 1 --reps 5", err, sizeof(err));
    CHECK(rc == 0, "bench raster failed (%d): %s", rc, err);
    rc = test_run_cli("bench raster --gaussians -5", err, sizeof(err));
    CHECK(rc == 2 && strstr(err, "--gaussians"), "bad --gaussians gives %d: %s", rc, err);
}

/* A set storing degree 0 only (3 SH floats a row, what the trainer keeps for one camera) renders
 * and back-propagates to the same bytes as the same Gaussians in rows of 48; a degree above what
 * the rows hold is refused. */
static void test_sh_stride(void)
{
    const int W = 96, H = 64, N = 800;
    const size_t P = (size_t)W * H;
    pg_camera cam;
    pg_camera_from_fov(&cam, W, H, 60);
    pg_gaussians wide, narrow, gw, gn;
    CHECK_OK(splat_gaussians_create(&wide, N));
    CHECK_OK(splat_random_scene(&wide, &cam, N, 2.5f, 0, 5));
    CHECK_OK(splat_gaussians_create_sh(&narrow, N, 0));
    CHECK_OK(splat_gaussians_resize(&narrow, N));
    CHECK(narrow.sh_stride == 3 && wide.sh_stride == 48, "strides %d and %d", narrow.sh_stride, wide.sh_stride);
    memcpy(narrow.means, wide.means, (size_t)N * 3 * sizeof(float));
    memcpy(narrow.log_scales, wide.log_scales, (size_t)N * 3 * sizeof(float));
    memcpy(narrow.quats, wide.quats, (size_t)N * 4 * sizeof(float));
    memcpy(narrow.opacity, wide.opacity, (size_t)N * sizeof(float));
    for (int i = 0; i < N; i++) memcpy(splat_gaussians_sh(&narrow, (size_t)i), splat_gaussians_sh(&wide, (size_t)i), 3 * sizeof(float));
    narrow.sh_degree = wide.sh_degree = 0;
    float *d_rgb = malloc(P * 3 * sizeof(float)), *img = malloc(P * 3 * sizeof(float));
    pg_rng rng;
    pg_rng_seed(&rng, 9);
    for (size_t i = 0; i < 3 * P; i++) d_rgb[i] = (float)pg_rng_normal(&rng);
    splat_raster *r;
    CHECK_OK(splat_raster_create(&r));
    pg_render_settings s = splat_default_settings();
    pg_render_output out;
    CHECK_OK(splat_gaussians_create(&gw, N));
    CHECK_OK(splat_gaussians_resize(&gw, N));
    CHECK_OK(splat_gaussians_create_sh(&gn, N, 0));
    CHECK_OK(splat_gaussians_resize(&gn, N));
    CHECK_OK(splat_render_forward(r, &wide, &cam, &s, &out));
    memcpy(img, out.rgb, P * 3 * sizeof(float));
    CHECK_OK(splat_render_backward(r, &wide, &cam, &s, d_rgb, NULL, NULL, &gw, NULL));
    CHECK_OK(splat_render_forward(r, &narrow, &cam, &s, &out));
    CHECK(!memcmp(img, out.rgb, P * 3 * sizeof(float)), "3-float SH rows render other colours than 48-float ones");
    CHECK_OK(splat_render_backward(r, &narrow, &cam, &s, d_rgb, NULL, NULL, &gn, NULL));
    int same = !memcmp(gw.means, gn.means, (size_t)N * 3 * sizeof(float)) &&
               !memcmp(gw.log_scales, gn.log_scales, (size_t)N * 3 * sizeof(float)) &&
               !memcmp(gw.opacity, gn.opacity, (size_t)N * sizeof(float));
    for (int i = 0; i < N; i++)
        same &= !memcmp(splat_gaussians_sh(&gw, (size_t)i), splat_gaussians_sh(&gn, (size_t)i), 3 * sizeof(float));
    CHECK(same, "3-float SH rows give other gradients than 48-float ones");
    s.sh_degree = 1;
    CHECK(splat_render_forward(r, &narrow, &cam, &s, &out) == PG_ERR_ARG && strstr(pg_last_error(), "SH floats"),
          "degree 1 on rows of 3 SH floats: %s", pg_last_error());
    splat_raster_destroy(r);
    free(d_rgb);
    free(img);
    splat_gaussians_destroy(&wide);
    splat_gaussians_destroy(&narrow);
    splat_gaussians_destroy(&gw);
    splat_gaussians_destroy(&gn);
}

int main(void)
{
    test_simd_and_determinism();
    test_sh_stride();
    test_edge_cases();
    test_crop_camera();
    test_training_pixel_filter();
    test_bench_cli();
    return test_summary("test_splat_raster");
}
