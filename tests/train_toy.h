/* train_toy.h - a tiny dynamic scene rendered by the rasterizer, written as a training-set
 * directory (docs/FORMATS.md), for the trainer tests. Header-only (static functions). */
#ifndef PG_TRAIN_TOY_H
#define PG_TRAIN_TOY_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/camera.h"
#include "core/fileutil.h"
#include "core/image.h"
#include "core/rng.h"
#include "io/image_io.h"
#include "io/npy.h"
#include "splat/gaussians.h"
#include "splat/raster.h"

#include <prodygs.h>

#define TOY_SH_C0 0.28209479177387814f

/* Ground truth: n Gaussians on a textured back plane and a few boxes; the last n_dyn move
 * along x with time (t in [0,1]). */
static pg_status toy_scene(pg_gaussians *g, int n, int n_dyn, uint64_t seed)
{
    PG_TRY(splat_gaussians_create(g, n));
    PG_TRY(splat_gaussians_resize(g, n));
    pg_rng rng;
    pg_rng_seed(&rng, seed);
    for (int i = 0; i < n; i++) {
        float *m = g->means + 3 * i;
        if (i < n - n_dyn) {
            if (i % 3) { /* back plane at z = 5 */
                m[0] = (float)pg_rng_range(&rng, -2.2, 2.2);
                m[1] = (float)pg_rng_range(&rng, -1.7, 1.7);
                m[2] = 5.0f + (float)pg_rng_range(&rng, -0.05, 0.05);
            } else { /* a box in the middle */
                m[0] = (float)pg_rng_range(&rng, -1.5, -0.5);
                m[1] = (float)pg_rng_range(&rng, 0.0, 1.0);
                m[2] = (float)pg_rng_range(&rng, 3.5, 4.0);
            }
        } else { /* moving blob */
            m[0] = (float)pg_rng_range(&rng, 0.3, 0.8);
            m[1] = (float)pg_rng_range(&rng, -0.8, -0.3);
            m[2] = (float)pg_rng_range(&rng, 3.0, 3.5);
        }
        for (int k = 0; k < 3; k++) g->log_scales[3 * i + k] = logf((float)pg_rng_range(&rng, 0.08, 0.16));
        g->quats[4 * i] = 1.0f;
        g->opacity[i] = 2.0f;
        float col[3];
        if (i >= n - n_dyn) { col[0] = 0.9f; col[1] = 0.2f; col[2] = 0.1f; }
        else if (i % 3 == 0) { col[0] = 0.2f; col[1] = 0.4f + 0.3f * (float)pg_rng_uniform(&rng); col[2] = 0.8f; }
        else {
            float u = g->means[3 * i], v = g->means[3 * i + 1];
            float c = ((int)floorf(u * 2) + (int)floorf(v * 2)) & 1 ? 0.8f : 0.35f;
            col[0] = c; col[1] = c * 0.9f; col[2] = c * 0.6f;
        }
        for (int k = 0; k < 3; k++) g->sh[i * PG_SH_COEFFS * 3 + k] = (col[k] - 0.5f) / TOY_SH_C0;
    }
    g->sh_degree = 0;
    return PG_OK;
}

static void toy_at_time(const pg_gaussians *g, int n_dyn, float t, pg_gaussians *out)
{
    int n = g->count;
    memcpy(out->means, g->means, (size_t)n * 3 * 4);
    memcpy(out->log_scales, g->log_scales, (size_t)n * 3 * 4);
    memcpy(out->quats, g->quats, (size_t)n * 4 * 4);
    memcpy(out->opacity, g->opacity, (size_t)n * 4);
    memcpy(out->sh, g->sh, (size_t)n * PG_SH_COEFFS * 3 * 4);
    out->sh_degree = g->sh_degree;
    for (int i = n - n_dyn; i < n; i++) out->means[3 * i] += 0.8f * t;
}

static void toy_camera(pg_camera *cam, int w, int h, float x_offset, float y_offset)
{
    pg_camera_from_fov(cam, w, h, 60.0f);
    float eye[3] = {x_offset, y_offset, 0}, target[3] = {0, 0, 4.5f}, up[3] = {0, -1, 0};
    pg_camera_look_at(cam, eye, target, up);
}

/* Writes DIR/trainset.json etc.: cam00 real (with depth), proxies (with masks + depth) and
 * test cameras, F frames of w x h. */
static pg_status toy_write_trainset(const char *dir, int w, int h, int frames, int n_proxy, int n_test)
{
    pg_gaussians g = {0}, gt = {0};
    splat_raster *r = NULL;
    PG_TRY(toy_scene(&g, 600, 60, 7));
    PG_TRY(splat_gaussians_create(&gt, g.count));
    PG_TRY(splat_gaussians_resize(&gt, g.count));
    PG_TRY(splat_raster_create(&r));
    PG_TRY(pg_mkdir_p(dir));
    char json[65536];
    int len = snprintf(json, sizeof json,
                       "{\"version\": 1, \"frames\": %d, \"width\": %d, \"height\": %d, \"fps\": 30,\n"
                       " \"cameras\": [\n", frames, w, h);
    int ncam = 1 + n_proxy + n_test;
    pg_image img = {0}, mask = {0};
    PG_TRY(pg_image_create(&img, w, h, 3));
    PG_TRY(pg_image_create(&mask, w, h, 1));
    float *depth = malloc(sizeof(float) * (size_t)frames * w * h);
    for (int c = 0; c < ncam; c++) {
        const char *role = c == 0 ? "real" : (c <= n_proxy ? "proxy" : "test");
        char name[32];
        snprintf(name, sizeof name, c == 0 ? "cam00" : (c <= n_proxy ? "proxy%02d" : "test%02d"), c);
        float ang = (c == 0) ? 0 : 0.35f * (float)((c % 2) ? (c + 1) / 2 : -(c + 1) / 2);
        pg_camera cam;
        toy_camera(&cam, w, h, ang, 0.15f * (float)(c % 3 - 1) * (c > 0));
        char sub[1024], path[2048];
        if (strlen(dir) > 900) return pg_fail(PG_ERR_ARG, "toy: path too long");
        snprintf(sub, sizeof sub, "%.900s/%s/rgb", dir, name);
        PG_TRY(pg_mkdir_p(sub));
        if (c > 0 && c <= n_proxy) {
            snprintf(sub, sizeof sub, "%.900s/%s/mask", dir, name);
            PG_TRY(pg_mkdir_p(sub));
        }
        for (int f = 0; f < frames; f++) {
            toy_at_time(&g, 60, frames > 1 ? (float)f / (frames - 1) : 0, &gt);
            pg_render_settings s = splat_default_settings();
            pg_render_output out;
            PG_TRY(splat_render_forward(r, &gt, &cam, &s, &out));
            memcpy(img.data, out.rgb, sizeof(float) * 3 * w * h);
            snprintf(path, sizeof path, "%.900s/%s/rgb/%04d.png", dir, name, f % 10000);
            PG_TRY(io_image_save_png(path, &img));
            for (int i = 0; i < w * h; i++) {
                depth[(size_t)f * w * h + i] = out.alpha[i] > 0.5f ? out.depth[i] / out.alpha[i] : 0.0f;
                /* proxies: pretend the left 10% is a disocclusion hole */
                mask.data[i] = (i % w) < w / 10 ? 0.0f : 1.0f;
            }
            if (c > 0 && c <= n_proxy) {
                snprintf(path, sizeof path, "%.900s/%s/mask/%04d.png", dir, name, f % 10000);
                PG_TRY(io_image_save_png(path, &mask));
            }
        }
        if (c <= n_proxy) {
            size_t shape[3] = {(size_t)frames, (size_t)h, (size_t)w};
            snprintf(path, sizeof path, "%.900s/%s/depth.npy", dir, name);
            PG_TRY(io_npy_save(path, depth, 3, shape));
        }
        len += snprintf(json + len, sizeof json - len,
                        "  {\"name\": \"%s\", \"width\": %d, \"height\": %d, \"fx\": %.9g, \"fy\": %.9g, \"cx\": %.9g, "
                        "\"cy\": %.9g, \"R\": [%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g], \"t\": [%.9g,%.9g,%.9g], "
                        "\"role\": \"%s\", \"rgb\": \"%s/rgb\", \"mask\": %s%s%s, \"depth\": %s%s%s}%s\n",
                        name, w, h, cam.fx, cam.fy, cam.cx, cam.cy, cam.R[0], cam.R[1], cam.R[2], cam.R[3], cam.R[4],
                        cam.R[5], cam.R[6], cam.R[7], cam.R[8], cam.t[0], cam.t[1], cam.t[2], role, name,
                        (c > 0 && c <= n_proxy) ? "\"" : "null", (c > 0 && c <= n_proxy) ? name : "",
                        (c > 0 && c <= n_proxy) ? "/mask\"" : "", c <= n_proxy ? "\"" : "null", c <= n_proxy ? name : "",
                        c <= n_proxy ? "/depth.npy\"" : "", c + 1 < ncam ? "," : "");
    }
    len += snprintf(json + len, sizeof json - len, " ]}\n");
    char jpath[2048];
    snprintf(jpath, sizeof jpath, "%.900s/trainset.json", dir);
    PG_TRY(pg_write_file_atomic(jpath, json, (size_t)len));
    free(depth);
    pg_image_destroy(&img);
    pg_image_destroy(&mask);
    splat_gaussians_destroy(&g);
    splat_gaussians_destroy(&gt);
    splat_raster_destroy(r);
    return PG_OK;
}

/* A small 4D model of the toy scene (w x h, frames frames, n_proxy proxies) trained in dir/toyset ->
 * dir/toymodel for iters steps (max_gaussians 0: the default cap): what the tests of the model's
 * consumers need, in seconds. */
static inline pg_status toy_train_model(const char *dir, int w, int h, int frames, int n_proxy, int iters,
                                        int init_points, int max_gaussians, int seed, char *model, size_t size)
{
    char data[1200];
    snprintf(data, sizeof data, "%s/toyset", dir);
    snprintf(model, size, "%s/toymodel", dir);
    PG_TRY(toy_write_trainset(data, w, h, frames, n_proxy, 0));
    pg_train_config c;
    pg_train_defaults(&c);
    c.input = data;
    c.out = model;
    c.iters = iters;
    c.coarse_iters = iters / 3;
    c.init_points = init_points;
    if (max_gaussians > 0) c.max_gaussians = max_gaussians;
    c.deform_res = 8;
    c.deform_width = 32;
    c.threads = 2;
    c.seed = seed;
    pg_train_report r;
    return pg_train_run(&c, &r);
}

#endif
