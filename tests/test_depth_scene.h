/* test_depth_scene.h - a small procedural RGB-D sequence for the depth-stage tests.
 *
 * A static camera looks at a textured wall that creases into a floor, a static box and a
 * moving textured ball. Gives per frame: RGB (2x2 supersampled, light noise), ground-truth
 * z-depth, the ball's mask (dynamic), and a simulated monocular estimate with the same kinds
 * of error as the shared sample data: per-frame scale drift (+-6 % sinusoid + 2 % noise),
 * a small shift, sigma = 1.2 px blur, +-3 % low-frequency multiplicative error, 0.5 % noise.
 */
#ifndef TEST_DEPTH_SCENE_H
#define TEST_DEPTH_SCENE_H

#include "core/image.h"
#include "core/rng.h"
#include "depth/align.h"
#include "depth/plane.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    int frames, width, height;
    pg_image *rgb;          /* (F) */
    float *depth_gt;        /* (F,H,W) */
    float *depth_mono;      /* (F,H,W) */
    unsigned char *dynamic; /* (F,H,W) 1 = moving object */
    float scale[64];        /* per-frame mono scale (first 64 frames) */
} test_scene;

static inline float scene_tex(float u, float v, int seed)
{
    float s = 0;
    s += sinf(0.9f * u + 0.4f * v + seed) * 0.5f;
    s += sinf(0.31f * u - 0.77f * v + 2.0f * seed) * 0.35f;
    s += sinf(-0.53f * u + 0.23f * v + 3.0f * seed) * 0.3f;
    s += sinf(1.7f * u + 1.3f * v + 0.5f * seed) * 0.15f;
    return s;
}

/* Colour and depth of the scene at continuous pixel (x, y) in frame t. */
static inline void scene_sample(const test_scene *sc, int t, float x, float y, float *rgb, float *z, int *dyn)
{
    const float W = (float)sc->width, H = (float)sc->height, F = (float)(sc->frames > 1 ? sc->frames - 1 : 1);
    const float s = W / 160.0f; /* features scale with the image */
    /* Ball: moves along a diagonal. */
    float bx = (95.0f + 35.0f * t / F) * s, by = (42.0f + 26.0f * t / F) * s, br = 15.0f * s;
    float dx = x - bx, dy = y - by, r2 = dx * dx + dy * dy;
    if (r2 < br * br) {
        float h = sqrtf(1.0f - r2 / (br * br));
        *z = 2.2f - 0.35f * h;
        float tx = scene_tex(dx / s * 1.3f, dy / s * 1.3f, 3);
        rgb[0] = 0.75f + 0.2f * tx;
        rgb[1] = 0.30f + 0.15f * tx;
        rgb[2] = 0.15f + 0.1f * tx;
        *dyn = 1;
        return;
    }
    *dyn = 0;
    /* Static box. */
    if (x >= 20 * s && x < 62 * s && y >= 48 * s && y < 96 * s) {
        *z = 3.2f + 0.01f * (x / s - 20.0f);
        float tx = scene_tex(x / s, y / s, 5);
        rgb[0] = 0.2f + 0.1f * tx;
        rgb[1] = 0.55f + 0.2f * tx;
        rgb[2] = 0.3f + 0.1f * tx;
        return;
    }
    float yh = 0.55f * H;
    if (y < yh) {
        *z = 6.0f + 0.004f * (x / s - 80.0f);
        float tx = scene_tex(x / s * 0.8f, y / s * 0.8f, 1);
        rgb[0] = 0.35f + 0.12f * tx;
        rgb[1] = 0.4f + 0.12f * tx;
        rgb[2] = 0.6f + 0.15f * tx;
    } else {
        *z = 6.0f + 0.004f * (x / s - 80.0f) - 3.2f * (y - yh) / (H - yh);
        float tx = scene_tex(x / s * 0.9f, y / s * 1.6f, 2);
        rgb[0] = 0.55f + 0.15f * tx;
        rgb[1] = 0.45f + 0.12f * tx;
        rgb[2] = 0.3f + 0.1f * tx;
    }
}

static inline void test_scene_destroy(test_scene *sc)
{
    if (sc->rgb)
        for (int i = 0; i < sc->frames; i++) pg_image_destroy(&sc->rgb[i]);
    free(sc->rgb);
    free(sc->depth_gt);
    free(sc->depth_mono);
    free(sc->dynamic);
    memset(sc, 0, sizeof *sc);
}

static inline int test_scene_make(test_scene *sc, int W, int H, int F, unsigned seed)
{
    memset(sc, 0, sizeof *sc);
    sc->frames = F;
    sc->width = W;
    sc->height = H;
    size_t n = (size_t)W * H;
    sc->rgb = calloc(F, sizeof(pg_image));
    sc->depth_gt = malloc(sizeof(float) * n * F);
    sc->depth_mono = malloc(sizeof(float) * n * F);
    sc->dynamic = malloc(n * F);
    float *tmp = malloc(sizeof(float) * n * 2);
    if (!sc->rgb || !sc->depth_gt || !sc->depth_mono || !sc->dynamic || !tmp) {
        free(tmp);
        test_scene_destroy(sc);
        return -1;
    }
    pg_rng rng;
    pg_rng_seed(&rng, seed);
    for (int t = 0; t < F; t++) {
        if (pg_image_create(&sc->rgb[t], W, H, 3)) {
            free(tmp);
            test_scene_destroy(sc);
            return -1;
        }
        for (int y = 0; y < H; y++) {
            for (int x = 0; x < W; x++) {
                size_t k = (size_t)y * W + x;
                float acc[3] = { 0, 0, 0 }, c[3], z;
                int dyn;
                for (int sy = 0; sy < 2; sy++)
                    for (int sx = 0; sx < 2; sx++) {
                        scene_sample(sc, t, x + 0.25f + 0.5f * sx, y + 0.25f + 0.5f * sy, c, &z, &dyn);
                        for (int ch = 0; ch < 3; ch++) acc[ch] += 0.25f * c[ch];
                    }
                scene_sample(sc, t, x + 0.5f, y + 0.5f, c, &z, &dyn);
                for (int ch = 0; ch < 3; ch++) sc->rgb[t].data[3 * k + ch] = acc[ch] + 0.01f * (float)pg_rng_normal(&rng);
                sc->depth_gt[t * n + k] = z;
                sc->dynamic[t * n + k] = (unsigned char)dyn;
            }
        }
        float s = 1.3f * (1.0f + 0.06f * sinf(2.0f * (float)M_PI * 1.5f * t / F + 0.3f) + 0.02f * (float)pg_rng_normal(&rng));
        if (t < 64) sc->scale[t] = s;
        depth_plane_gaussian_blur(sc->depth_gt + t * n, W, H, 1.2f, tmp, tmp + n);
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++) {
                size_t k = (size_t)y * W + x;
                float lf = 1.0f + 0.03f * sinf(2.0f * (float)M_PI * x / W) * cosf(2.0f * (float)M_PI * y / H);
                sc->depth_mono[t * n + k] = (s * tmp[n + k] * lf + 0.05f) * (1.0f + 0.005f * (float)pg_rng_normal(&rng));
            }
    }
    free(tmp);
    return 0;
}

/* Median of v[0..m) (reorders v). */
static inline int scene_cmp(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}
static inline double scene_median(double *v, size_t m)
{
    if (!m) return 0.0;
    qsort(v, m, sizeof(double), scene_cmp);
    return m % 2 ? v[m / 2] : 0.5 * (v[m / 2 - 1] + v[m / 2]);
}

/* Relative std over frames of median(D_i / D_gt,i) on pixels with static[i] set (static may be
 * NULL = all). This is the temporal drift of the depth's scale. Writes the medians to med. */
static inline double scene_scale_drift(const float *d, const float *gt, const unsigned char *stat, int F, size_t n, double *med)
{
    double *v = malloc(sizeof(double) * n), mean = 0, var = 0;
    if (!v) return -1;
    for (int i = 0; i < F; i++) {
        size_t m = 0;
        for (size_t k = 0; k < n; k++) {
            size_t q = (size_t)i * n + k;
            if ((!stat || stat[q]) && d[q] > 0 && gt[q] > 0) v[m++] = d[q] / gt[q];
        }
        med[i] = scene_median(v, m);
        mean += med[i];
    }
    mean /= F;
    for (int i = 0; i < F; i++) var += (med[i] - mean) * (med[i] - mean);
    free(v);
    return sqrt(var / F) / mean;
}

/* Band-error metric for refinement. GT discontinuities: 4-neighbours whose log-depths differ by
 * more than 0.05; band = pixels within 3 px of one. Both depths are mapped into GT units with
 * the SAME robust per-frame scale/shift (fitted from `unrefined` to GT on all pixels), so the
 * comparison is fair. Outputs the mean absolute error in the band and elsewhere over all frames
 * for the unrefined (a) and refined (b) depth. */
static inline void scene_band_errors(const float *unrefined, const float *refined, const float *gt, int W, int H, int F,
                              double *band_a, double *band_b, double *else_a, double *else_b)
{
    size_t n = (size_t)W * H, nb = 0, ne = 0;
    unsigned char *edge = calloc(n, 1), *band = calloc(n, 1);
    double sba = 0, sbb = 0, sea = 0, seb = 0;
    depth_align_params ap;
    depth_align_defaults(&ap);
    for (int i = 0; i < F && edge && band; i++) {
        const float *g = gt + (size_t)i * n, *u = unrefined + (size_t)i * n, *r = refined + (size_t)i * n;
        depth_align_result ar;
        if (depth_align_fit(&ap, u, g, NULL, n, &ar)) continue;
        memset(edge, 0, n);
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++) {
                size_t k = (size_t)y * W + x;
                if (x + 1 < W && fabsf(logf(g[k]) - logf(g[k + 1])) > 0.05f) edge[k] = edge[k + 1] = 1;
                if (y + 1 < H && fabsf(logf(g[k]) - logf(g[k + W])) > 0.05f) edge[k] = edge[k + W] = 1;
            }
        depth_mask_dilate(edge, W, H, 3, band);
        for (size_t k = 0; k < n; k++) {
            if (!(u[k] > 0) || !(r[k] > 0) || !(g[k] > 0)) continue;
            double ea = fabs(ar.alpha * u[k] + ar.beta - g[k]), eb = fabs(ar.alpha * r[k] + ar.beta - g[k]);
            if (band[k]) { sba += ea; sbb += eb; nb++; }
            else { sea += ea; seb += eb; ne++; }
        }
    }
    free(edge);
    free(band);
    *band_a = nb ? sba / nb : 0;
    *band_b = nb ? sbb / nb : 0;
    *else_a = ne ? sea / ne : 0;
    *else_b = ne ? seb / ne : 0;
}

#endif
