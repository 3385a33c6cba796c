/* test_proxy_model.c - per-frame RGB-D Gaussians on the analytic scene: the fit improves the source
 * view, proxies match the ray-cast ground truth where the mask says valid, and the mask keeps the
 * truly visible area while rejecting disocclusions. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/camera.h"
#include "core/parallel.h"
#include "proxy/frame_model.h"
#include "proxy/metrics.h"
#include "proxy/outpaint.h"
#include "proxy/poses.h"
#include "proxy/procedural.h"
#include "testlib.h"

enum { W = 128, H = 96, M = 4 };

/* Renders M views 5-10 degrees off the real camera of the analytic scene and checks them against
 * the scene rendered exactly there; returns the mean masked PSNR. */
static double run(proxy_render_kind render, int block, int steps, double min_psnr, double min_cov)
{
    pg_camera real;
    pg_camera_from_fov(&real, W, H, 60);
    float *rgb = malloc(sizeof(float) * W * H * 3), *depth = malloc(sizeof(float) * W * H);
    float *vrgb = malloc(sizeof(float) * W * H * 3), *vdepth = malloc(sizeof(float) * W * H);
    float *prgb = malloc(sizeof(float) * W * H * 3), *pdepth = malloc(sizeof(float) * W * H);
    unsigned char *mask = malloc(W * H);
    proxy_procedural_render(&real, 0, 3, rgb, depth);
    float c[3], r;
    CHECK_OK(proxy_scene_center(&real, depth, 1.0f, c, &r));
    pg_camera cams[M];
    CHECK_OK(proxy_poses_hemisphere(&real, c, M, 10.0f, cams));

    proxy_fit_options o = proxy_default_fit_options();
    o.render = render;
    o.block = block;
    o.steps = steps;
    proxy_frame_model *m = NULL;
    CHECK_OK(proxy_model_create(&m, W, H, &o));
    if (!m) return 0;
    CHECK_OK(proxy_model_init(m, &real, rgb, depth));
    CHECK_OK(proxy_model_fit(m));
    const proxy_model_stats *st = proxy_model_get_stats(m);
    printf("%s block %d steps %d: %d Gaussians, loss %.4f -> %.4f, source PSNR %.2f dB\n",
           render == PROXY_RENDER_MESH ? "mesh" : "splat", block, steps, st->gaussians, st->first_loss, st->last_loss,
           st->source_psnr);
    if (render == PROXY_RENDER_SPLAT && steps > 0) CHECK(st->last_loss < st->first_loss, "fit did not reduce the loss (%g -> %g)", st->first_loss,
                         st->last_loss);
    double worst_psnr = 1e9, worst_cov = 1e9, worst_false = 0, mean_psnr = 0;
    for (int k = 0; k < M; k++) {
        float frac;
        CHECK_OK(proxy_model_render(m, &cams[k], prgb, pdepth, mask, &frac));
        proxy_procedural_render(&cams[k], 0, 3, vrgb, vdepth);
        proxy_view_metrics mt;
        CHECK_OK(proxy_measure_view(&real, depth, &cams[k], vdepth, vrgb, prgb, mask, 0.01f, &mt));
        /* masked proxy depth must agree with the true depth */
        double derr = 0;
        long nd = 0;
        for (int i = 0; i < W * H; i++)
            if (mask[i] == PROXY_MASK_REAL) { derr += fabs(pdepth[i] - vdepth[i]) / vdepth[i]; nd++; }
        printf("  view %d (%.1f deg): psnr %.2f coverage %.3f false %.4f mask %.3f depth err %.4f\n", k,
               proxy_camera_angle_deg(&real, &cams[k]), mt.psnr_masked, mt.coverage, mt.false_valid,
               mt.mask_fraction, nd ? derr / nd : 0);
        mean_psnr += mt.psnr_masked / M;
        if (mt.psnr_masked < worst_psnr) worst_psnr = mt.psnr_masked;
        if (mt.coverage < worst_cov) worst_cov = mt.coverage;
        if (mt.false_valid > worst_false) worst_false = mt.false_valid;
        CHECK(nd && derr / nd < 0.01, "view %d: masked depth error %g", k, nd ? derr / nd : -1);
    }
    CHECK(worst_psnr >= min_psnr, "block %d: worst masked PSNR %.2f < %.2f", block, worst_psnr, min_psnr);
    CHECK(worst_cov >= min_cov, "block %d: worst visible coverage %.3f < %.3f", block, worst_cov, min_cov);
    CHECK(worst_false <= 0.02, "block %d: %.4f of the mask is not visible from the real camera", block, worst_false);
    /* Bad input: all-invalid depth. */
    memset(depth, 0, sizeof(float) * W * H);
    CHECK(proxy_model_init(m, &real, rgb, depth) == PG_ERR_ARG, "all-invalid depth accepted");
    proxy_model_destroy(m);
    free(rgb); free(depth); free(vrgb); free(vdepth); free(prgb); free(pdepth); free(mask);
    return mean_psnr;
}

/* Outpainting continues a tilted plane exactly (inverse depth is affine in the pixel coordinates),
 * keeps a constant colour, copies the interior and leaves the margin empty without valid depth. */
static void outpaint_plane(void)
{
    enum { w = 40, h = 30, p = 12, w2 = w + 2 * p, h2 = h + 2 * p };
    float rgb[h][w][3], depth[h][w], rgb2[h2][w2][3], depth2[h2][w2];
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            depth[y][x] = 1.0f / (0.5f + 0.004f * x - 0.003f * y);
            rgb[y][x][0] = 0.2f; rgb[y][x][1] = 0.4f; rgb[y][x][2] = 0.6f;
        }
    CHECK_OK(proxy_outpaint(w, h, &rgb[0][0][0], &depth[0][0], p, &rgb2[0][0][0], &depth2[0][0]));
    double worst = 0, worst_rgb = 0;
    for (int y = 0; y < h2; y++)
        for (int x = 0; x < w2; x++) {
            double want = 1.0 / (0.5 + 0.004 * (x - p) - 0.003 * (y - p));
            worst = fmax(worst, fabs(depth2[y][x] - want) / want);
            for (int c = 0; c < 3; c++) worst_rgb = fmax(worst_rgb, fabs(rgb2[y][x][c] - (0.2 + 0.2 * c)));
        }
    printf("outpaint: plane depth worst relative error %.2e, colour %.2e\n", worst, worst_rgb);
    CHECK(worst < 1e-3, "plane continued with relative depth error %g", worst);
    CHECK(worst_rgb < 1e-5, "constant colour changed by %g", worst_rgb);
    CHECK(depth2[p + 3][p + 5] == depth[3][5], "interior depth not copied");
    memset(depth, 0, sizeof depth);
    CHECK_OK(proxy_outpaint(w, h, &rgb[0][0][0], &depth[0][0], p, &rgb2[0][0][0], &depth2[0][0]));
    CHECK(depth2[0][0] == 0 && depth2[h2 / 2][1] == 0, "margin got depth without any valid border depth");
}

int main(void)
{
    outpaint_plane();
    pg_set_threads(2);
    {
        proxy_fit_options o = proxy_default_fit_options();
        proxy_frame_model *m = NULL;
        o.ssim_every = 0;
        CHECK(proxy_model_create(&m, W, H, &o) == PG_ERR_ARG && !m, "ssim_every 0 accepted");
    }
    {
        /* the largest block: margin blocks are MARGIN_BLOCK x 64 pixels wide (seeding scratch) */
        pg_camera real;
        pg_camera_from_fov(&real, W, H, 60);
        float *rgb = malloc(sizeof(float) * W * H * 3), *depth = malloc(sizeof(float) * W * H);
        proxy_procedural_render(&real, 0, 3, rgb, depth);
        proxy_fit_options o = proxy_default_fit_options();
        o.render = PROXY_RENDER_SPLAT;
        o.block = 64;
        o.steps = 2;
        proxy_frame_model *m = NULL;
        CHECK_OK(proxy_model_create(&m, W, H, &o));
        if (m) {
            CHECK_OK(proxy_model_init(m, &real, rgb, depth));
            CHECK_OK(proxy_model_fit(m));
            CHECK(proxy_model_get_stats(m)->gaussians >= 4, "block 64: %d Gaussians", proxy_model_get_stats(m)->gaussians);
        }
        proxy_model_destroy(m);
        free(rgb);
        free(depth);
    }
    double splat = run(PROXY_RENDER_SPLAT, 1, 40, 25.0, 0.85);
    run(PROXY_RENDER_SPLAT, 2, 10, 20.0, 0.80);
    double mesh = run(PROXY_RENDER_MESH, 1, 0, 28.0, 0.85);
    printf("mean masked PSNR: mesh %.2f dB, splat %.2f dB\n", mesh, splat);
    /* The mesh interpolates the frame exactly on each surface; overlapping splats shift the texture
     * by a fraction of a pixel wherever their depth order flips (frame_model.h). Measured 30.25 vs
     * 28.41 dB with the screen-space filter at 0.1 px^2 (it was 0.3, and the gap over 2 dB). */
    CHECK(mesh > splat + 1.5, "mesh proxies %.2f dB not 1.5 dB above the fitted splats' %.2f dB", mesh, splat);
    return test_summary("test_proxy_model");
}
