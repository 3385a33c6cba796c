/* heavy_splat_fit.c - end-to-end optimisation through the rasterizer with Adam.
 *
 * 1. Recover: a known random Gaussian set renders a target; a perturbed copy is optimised
 *    back (L1 loss, gradient sign(diff)/N computed inline): PSNR >= 35 dB within 2000 steps.
 * 2. From scratch: a grid of Gaussians fits a procedural texture to >= 28 dB.
 */
#include "testlib.h"
#include "splat/raster.h"
#include "optim/adam.h"
#include "core/image.h"
#include "core/parallel.h"
#include "core/rng.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static double psnr(const float *a, const float *b, size_t n)
{
    double se = 0;
    for (size_t i = 0; i < n; i++) se += (double)(a[i] - b[i]) * (a[i] - b[i]);
    return se == 0 ? 99.0 : 10 * log10(1.0 / (se / n));
}

/* Runs `iters` Adam steps of L1 between render(g) and target; returns the final PSNR. */
static double fit(pg_gaussians *g, const pg_camera *cam, const float *target, int iters, const float base_lr[6],
                  float means_lr_final, double stop_at)
{
    size_t P = (size_t)cam->width * cam->height;
    pg_gaussians grad;
    splat_gaussians_create(&grad, g->count);
    splat_gaussians_resize(&grad, g->count);
    optim_adam *opt;
    CHECK_OK(optim_adam_create_gaussians(&opt, g->count, g->sh_stride, 1e-15f));
    splat_raster *r;
    CHECK_OK(splat_raster_create(&r));
    pg_render_settings s = splat_default_settings();
    float *d_rgb = malloc(P * 3 * sizeof(float));
    optim_lr_schedule sched = { base_lr[0], means_lr_final, 0, 1.0f, iters };
    pg_render_output out;
    double best = 0;
    for (int it = 0; it <= iters; it++) {
        CHECK_OK(splat_render_forward(r, g, cam, &s, &out));
        double p = psnr(out.rgb, target, 3 * P);
        best = p;
        if (it == iters || p >= stop_at) break;
        for (size_t i = 0; i < 3 * P; i++) {
            float d = out.rgb[i] - target[i];
            d_rgb[i] = (d > 0 ? 1.0f : (d < 0 ? -1.0f : 0.0f)) / (float)(3 * P);
        }
        splat_gaussians_zero(&grad);
        CHECK_OK(splat_render_backward(r, g, cam, &s, d_rgb, NULL, NULL, &grad, NULL));
        float lr[6];
        memcpy(lr, base_lr, sizeof(lr));
        lr[0] = optim_lr_expon(&sched, it);
        CHECK_OK(optim_adam_step_gaussians(opt, g, &grad, lr));
    }
    free(d_rgb);
    splat_raster_destroy(r);
    optim_adam_destroy(opt);
    splat_gaussians_destroy(&grad);
    return best;
}

static void random_gaussians(pg_gaussians *g, int n, pg_rng *rng)
{
    splat_gaussians_create(g, n);
    splat_gaussians_resize(g, n);
    g->sh_degree = 1;
    for (int i = 0; i < n; i++) {
        g->means[3*i] = (float)pg_rng_range(rng, -1.4, 1.4);
        g->means[3*i+1] = (float)pg_rng_range(rng, -1.4, 1.4);
        g->means[3*i+2] = (float)pg_rng_range(rng, 3, 4);
        for (int k = 0; k < 3; k++) g->log_scales[3*i+k] = (float)pg_rng_range(rng, -2.6, -1.6);
        for (int k = 0; k < 4; k++) g->quats[4*i+k] = (float)pg_rng_normal(rng);
        g->opacity[i] = (float)pg_rng_range(rng, -1, 2);
        for (int k = 0; k < 3; k++) g->sh[48*i+k] = (float)pg_rng_range(rng, -1.5, 1.5);
        for (int k = 3; k < 12; k++) g->sh[48*i+k] = (float)(0.1 * pg_rng_normal(rng));
    }
}

static void test_recover(void)
{
    pg_rng rng;
    pg_rng_seed(&rng, 2024);
    pg_camera cam;
    pg_camera_from_fov(&cam, 64, 64, 60);
    pg_gaussians truth, g;
    random_gaussians(&truth, 60, &rng);
    splat_raster *r;
    CHECK_OK(splat_raster_create(&r));
    pg_render_settings s = splat_default_settings();
    pg_render_output out;
    CHECK_OK(splat_render_forward(r, &truth, &cam, &s, &out));
    size_t P = 64 * 64;
    float *target = malloc(P * 3 * sizeof(float));
    memcpy(target, out.rgb, P * 3 * sizeof(float));
    splat_raster_destroy(r);

    random_gaussians(&g, 60, &rng); /* allocate, then overwrite with a perturbed copy */
    for (int i = 0; i < 60; i++) {
        for (int k = 0; k < 3; k++) g.means[3*i+k] = truth.means[3*i+k] + (float)(0.03 * pg_rng_normal(&rng));
        for (int k = 0; k < 3; k++) g.log_scales[3*i+k] = truth.log_scales[3*i+k] + (float)(0.15 * pg_rng_normal(&rng));
        for (int k = 0; k < 4; k++) g.quats[4*i+k] = truth.quats[4*i+k] + (float)(0.1 * pg_rng_normal(&rng));
        g.opacity[i] = truth.opacity[i] + (float)(0.3 * pg_rng_normal(&rng));
        for (int k = 0; k < 48; k++) g.sh[48*i+k] = truth.sh[48*i+k] + (k < 3 ? (float)(0.1 * pg_rng_normal(&rng)) : 0);
    }
    float lr[6] = { 2e-3f, 5e-3f, 1e-3f, 5e-2f, 2.5e-3f, 1.25e-4f };
    double p = fit(&g, &cam, target, 2000, lr, 2e-5f, 40.0);
    printf("recover perturbed Gaussians: PSNR %.2f dB\n", p);
    CHECK(p >= 35.0, "fit of perturbed Gaussians reached only %.2f dB", p);
    free(target);
    splat_gaussians_destroy(&truth);
    splat_gaussians_destroy(&g);
}

/* Stripes, a checker patch, a disc and a smooth gradient. */
static void texture(float *img, int W, int H)
{
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            float u = (x + 0.5f) / W, v = (y + 0.5f) / H, *p = img + 3 * ((size_t)y * W + x);
            p[0] = 0.5f + 0.4f * sinf(9.0f * u + 3.0f * v);
            p[1] = 0.3f + 0.5f * v;
            p[2] = 0.5f + 0.3f * cosf(7.0f * v - 4.0f * u);
            if ((u - 0.3f) * (u - 0.3f) + (v - 0.65f) * (v - 0.65f) < 0.03f) { p[0] = 0.95f; p[1] = 0.9f; p[2] = 0.2f; }
            if (u > 0.6f && v < 0.4f && (((int)(u * 10) + (int)(v * 10)) & 1)) { p[0] *= 0.3f; p[1] *= 0.3f; p[2] *= 0.3f; }
        }
}

static void test_from_scratch(void)
{
    const int W = 64, H = 64, G = 40;
    pg_camera cam;
    pg_camera_from_fov(&cam, W, H, 60);
    float *target = malloc((size_t)W * H * 3 * sizeof(float));
    texture(target, W, H);
    pg_gaussians g;
    splat_gaussians_create(&g, G * G);
    splat_gaussians_resize(&g, G * G);
    g.sh_degree = 0;
    pg_rng rng;
    pg_rng_seed(&rng, 9);
    float z = 3, half = z * tanf(30.0f * 3.14159265f / 180);
    for (int j = 0; j < G; j++)
        for (int i = 0; i < G; i++) {
            int k = j * G + i;
            g.means[3*k] = -half + (2 * half) * (i + 0.5f) / G;
            g.means[3*k+1] = -half + (2 * half) * (j + 0.5f) / G;
            g.means[3*k+2] = z + (float)(0.01 * pg_rng_normal(&rng));
            for (int c = 0; c < 3; c++) g.log_scales[3*k+c] = logf(2 * half / G * 0.7f);
            g.quats[4*k] = 1;
            g.opacity[k] = 1.0f;
            for (int c = 0; c < 3; c++) g.sh[48*k+c] = (float)(0.2 * pg_rng_normal(&rng));
        }
    float lr[6] = { 5e-4f, 5e-3f, 1e-3f, 5e-2f, 1e-2f, 0 };
    double p = fit(&g, &cam, target, 2000, lr, 5e-6f, 99.0);
    printf("fit procedural texture from scratch: PSNR %.2f dB\n", p);
    CHECK(p >= 28.0, "texture fit reached only %.2f dB", p);
    free(target);
    splat_gaussians_destroy(&g);
}

int main(void)
{
    pg_set_threads(1); /* 64x64 images: threads only add overhead on a shared machine */
    test_recover();
    test_from_scratch();
    return test_summary("heavy_splat_fit");
}
