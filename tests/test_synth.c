/* test_synth.c - the built-in sample scene: determinism, camera conventions through the files it
 * writes (poses_bounds.npy, Panoptic meta), depth / mask / mono-depth ground truth, visibility,
 * CLI errors. */
#include "testlib.h"
#include "core/camera.h"
#include "core/fileutil.h"
#include "core/mathx.h"
#include "io/dataset.h"
#include "io/image_io.h"
#include "io/json.h"
#include "io/npy.h"
#include "io/video.h"
#include "synth/synth.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { W = 96, H = 72, F = 6, NC = 7 };

static float median(float *v, size_t n)
{
    qsort(v, n, sizeof(float), pg_cmp_float);
    return n ? v[n / 2] : 0;
}

/* Same seed -> same pixels and depth; another seed -> different. */
static void test_determinism(void)
{
    synth_scene a, b, c;
    synth_scene_default(&a, 1);
    synth_scene_default(&b, 1);
    synth_scene_default(&c, 2);
    pg_camera cam;
    CHECK_OK(synth_camera(&a, 1, W, H, &cam));
    pg_image ia = { 0 }, ib = { 0 }, ic = { 0 };
    float *da = malloc(W * H * sizeof(float)), *db = malloc(W * H * sizeof(float));
    CHECK_OK(synth_render_frame(&a, &cam, 0.3f, &ia, da, NULL));
    CHECK_OK(synth_render_frame(&b, &cam, 0.3f, &ib, db, NULL));
    CHECK_OK(synth_render_frame(&c, &cam, 0.3f, &ic, NULL, NULL));
    CHECK(memcmp(ia.data, ib.data, sizeof(float) * W * H * 3) == 0, "same seed gave different pixels");
    CHECK(memcmp(da, db, sizeof(float) * W * H) == 0, "same seed gave different depth");
    CHECK(memcmp(ia.data, ic.data, sizeof(float) * W * H * 3) != 0, "seeds 1 and 2 gave the same image");
    /* a textured image: mean absolute horizontal gradient well above zero, no saturation */
    double grad = 0, mean = 0;
    for (int y = 0; y < H; y++)
        for (int x = 0; x + 1 < W; x++)
            for (int k = 0; k < 3; k++) {
                grad += fabsf(pg_image_at(&ia, x + 1, y)[k] - pg_image_at(&ia, x, y)[k]);
                mean += pg_image_at(&ia, x, y)[k];
            }
    grad /= (double)(W - 1) * H * 3;
    mean /= (double)(W - 1) * H * 3;
    CHECK(grad > 0.03, "image has little texture: mean |dI/dx| = %.4f", grad);
    CHECK(mean > 0.2 && mean < 0.8, "image mean %.3f", mean);
    pg_image_destroy(&ia);
    pg_image_destroy(&ib);
    pg_image_destroy(&ic);
    free(da);
    free(db);
}

/* Surface points seen from cam00 (unprojected from traced depth) plus corners of the objects. */
static int sample_points(const synth_scene *sc, float s, float pts[][3], int max)
{
    pg_camera c0;
    synth_camera(sc, 0, W, H, &c0);
    int n = 0;
    for (int j = 0; j < 6 && n < max; j++)
        for (int i = 0; i < 6 && n < max; i++) {
            float u = (i + 0.5f) * W / 6, v = (j + 0.5f) * H / 6;
            float z = synth_trace_depth(sc, &c0, u, v, s, NULL);
            if (z > 0) pg_camera_unproject(&c0, u, v, z, pts[n++]);
        }
    for (int k = 2; k < sc->num_objects && n < max; k++) {
        float R[9], p[3], q[3] = { sc->objects[k].size[0], -sc->objects[k].size[0], 0 }, r[3];
        synth_object_pose(sc, k, s, R, p);
        mat3_mul_vec(r, R, q);
        vec3_add(pts[n++], r, p);
    }
    return n;
}

/* The cameras io's DyNeRF loader reads from what synth wrote reproject like synth's own cameras
 * (<= 0.01 px), and its frames are synth's PNGs. */
static void test_dynerf_files(const char *dir)
{
    synth_scene sc;
    synth_scene_default(&sc, 3);
    char path[4096];
    io_dataset_options dopt = io_dataset_defaults();
    pg_dataset *ds = NULL;
    CHECK_OK(io_dataset_open(dir, &dopt, &ds));
    if (!ds) return;
    CHECK(io_dataset_get_kind(ds) == IO_DATASET_DYNERF, "kind %s", io_dataset_kind_name(io_dataset_get_kind(ds)));
    CHECK(io_dataset_num_cameras(ds) == NC && io_dataset_num_frames(ds) == F, "%d cameras, %d frames",
          io_dataset_num_cameras(ds), io_dataset_num_frames(ds));
    float pts[64][3];
    int np = sample_points(&sc, 0.5f, pts, 64);
    CHECK(np > 30, "only %d sample points", np);
    double worst = 0;
    int in_view = 0;
    for (int c = 0; c < NC && c < io_dataset_num_cameras(ds); c++) {
        pg_camera a, b;
        CHECK_OK(synth_camera(&sc, c, W, H, &a));
        io_dataset_camera(ds, c, &b);
        char name[16];
        snprintf(name, sizeof name, "cam%02d", c);
        CHECK(strcmp(io_dataset_camera_name(ds, c), name) == 0, "camera %d is named %s", c, io_dataset_camera_name(ds, c));
        CHECK(b.width == W && b.height == H, "cam%02d hwf gives %d x %d", c, b.width, b.height);
        float nearv, farv;
        io_dataset_near_far(ds, c, &nearv, &farv);
        CHECK(nearv > 0.5f && farv > nearv && farv < 20, "cam%02d near/far %g %g", c, nearv, farv);
        for (int k = 0; k < np; k++) {
            float ua[2], ub[2];
            float za = pg_camera_project(&a, pts[k], ua), zb = pg_camera_project(&b, pts[k], ub);
            CHECK(za > 0 && zb > 0, "point behind camera %d", c);
            double e = hypot(ua[0] - ub[0], ua[1] - ub[1]);
            if (e > worst) worst = e;
            in_view += ua[0] >= 0 && ua[0] < W && ua[1] >= 0 && ua[1] < H;
        }
        float C[3];
        pg_camera_center(&b, C);
        if (c == 0) CHECK(vec3_norm(C) < 1e-6f, "cam00 centre %g %g %g", C[0], C[1], C[2]);
    }
    printf("DyNeRF loader vs synth cameras: worst reprojection %.2e px over %d points x %d cams (%d in view)\n", worst, np,
           NC, in_view);
    CHECK(worst <= 0.01, "loaded camera reprojects %.4f px away", worst);
    CHECK(in_view > np * NC * 8 / 10, "only %d of %d projections in view", in_view, np * NC);
    /* frame (cam 2, frame 3) through the loader = the rendered frame to 8-bit precision */
    pg_image img = { 0 }, ref = { 0 };
    pg_camera c2;
    synth_camera(&sc, 2, W, H, &c2);
    sc.spp = 1; /* the CLI run used --spp 1 */
    CHECK_OK(io_dataset_frame(ds, 2, 3, &img));
    CHECK_OK(synth_render_frame(&sc, &c2, synth_frame_time(3, F), &ref, NULL, NULL));
    double psnr = img.data ? pg_image_psnr(&img, &ref, NULL) : 0;
    CHECK(psnr > 45, "loaded frame vs render PSNR %.1f dB", psnr);
    pg_image_destroy(&img);
    pg_image_destroy(&ref);
    io_dataset_close(ds);

    /* depth_gt: unprojected pixels land on the analytic surfaces (z-depth, not ray length) */
    pg_array dg = { 0 }, mk = { 0 }, dm = { 0 };
    snprintf(path, sizeof path, "%s/depth_gt/cam00.npy", dir);
    CHECK_OK(io_npy_load(path, &dg));
    snprintf(path, sizeof path, "%s/masks_dynamic/cam00.npy", dir);
    CHECK_OK(io_npy_load(path, &mk));
    snprintf(path, sizeof path, "%s/depth_mono/cam00.npy", dir);
    CHECK_OK(io_npy_load(path, &dm));
    int shapes_ok = dg.ndim == 3 && dg.shape[0] == F && dg.shape[1] == H && dg.shape[2] == W && mk.count == dg.count &&
                    dm.count == dg.count;
    CHECK(shapes_ok, "depth/mask/mono shapes");
    if (shapes_ok) {
        pg_camera c0;
        synth_camera(&sc, 0, W, H, &c0);
        double worst_table = 0, worst_ball = 0, worst_trace = 0;
        int n_table = 0, n_ball = 0, dyn_agree = 0, dyn_total = 0;
        for (int f = 0; f < F; f++) {
            float s = synth_frame_time(f, F);
            float Rb[9], pbl[3];
            synth_object_pose(&sc, 8, s, Rb, pbl); /* the ball */
            for (int y = 0; y < H; y += 3)
                for (int x = 0; x < W; x += 3) {
                    size_t i = ((size_t)f * H + y) * W + x;
                    float z = dg.data[i], X[3], Xs[3];
                    int obj;
                    float zt = synth_trace_depth(&sc, &c0, x + 0.5f, y + 0.5f, s, &obj);
                    worst_trace = fmax(worst_trace, fabs(zt - z));
                    if (!(z > 0)) continue;
                    pg_camera_unproject(&c0, x + 0.5f, y + 0.5f, z, X);
                    synth_world_to_scene(&sc, X, Xs);
                    if (obj == 0) {
                        worst_table = fmax(worst_table, fabs(Xs[2]));
                        n_table++;
                    }
                    if (obj == 8) {
                        float d[3];
                        vec3_sub(d, X, pbl);
                        worst_ball = fmax(worst_ball, fabs(vec3_norm(d) - sc.objects[8].size[0]));
                        n_ball++;
                    }
                    int dyn = synth_point_is_dynamic(&sc, X, s, 1e-3f);
                    dyn_total++;
                    dyn_agree += dyn == (mk.data[i] > 0.5f);
                }
        }
        printf("depth_gt: table |z| worst %.2e (%d px), ball radius error worst %.2e (%d px), trace diff %.2e\n",
               worst_table, n_table, worst_ball, n_ball, worst_trace);
        CHECK(n_table > 100 && worst_table < 1e-4, "table points off the plane by %.2e", worst_table);
        CHECK(n_ball > 5 && worst_ball < 1e-4, "ball points off the sphere by %.2e", worst_ball);
        CHECK(worst_trace == 0, "depth_gt differs from the traced depth by %.2e", worst_trace);
        /* (a static surface within 1 mm of a moving object may count as dynamic for the point test) */
        CHECK(dyn_total - dyn_agree <= dyn_total / 500, "mask vs point-is-dynamic disagree at %d of %d px",
              dyn_total - dyn_agree, dyn_total);

        /* masks: non-empty every frame, and they move */
        double cx0 = 0, cy0 = 0, cx1 = 0, cy1 = 0;
        for (int f = 0; f < F; f++) {
            size_t cnt = 0;
            double sx = 0, sy = 0;
            for (int y = 0; y < H; y++)
                for (int x = 0; x < W; x++)
                    if (mk.data[((size_t)f * H + y) * W + x] > 0.5f) { cnt++; sx += x; sy += y; }
            CHECK(cnt > 30 && cnt < (size_t)W * H / 3, "frame %d mask has %zu px", f, cnt);
            if (f == 0) { cx0 = sx / cnt; cy0 = sy / cnt; }
            if (f == F - 1) { cx1 = sx / cnt; cy1 = sy / cnt; }
        }
        size_t diff = 0, plane = (size_t)H * W;
        for (size_t i = 0; i < plane; i++) diff += (mk.data[i] > 0.5f) != (mk.data[(F - 1) * plane + i] > 0.5f);
        CHECK(diff > 100, "masks barely change: %zu px differ between first and last frame", diff);
        printf("masks: centroid (%.1f, %.1f) -> (%.1f, %.1f), %zu px change\n", cx0, cy0, cx1, cy1, diff);

        /* depth_mono: per-frame median ratio to depth_gt drifts by a few percent around ~1.25 */
        float *ratio = malloc(plane * sizeof(float));
        float rmin = 1e9f, rmax = 0;
        for (int f = 0; f < F; f++) {
            size_t n = 0;
            for (size_t i = 0; i < plane; i++) {
                float g = dg.data[f * plane + i], m = dm.data[f * plane + i];
                if (g > 0) ratio[n++] = m / g;
            }
            float r = median(ratio, n);
            rmin = fminf(rmin, r);
            rmax = fmaxf(rmax, r);
        }
        free(ratio);
        printf("depth_mono: per-frame median ratio in [%.3f, %.3f], drift %.1f%%\n", rmin, rmax, 100 * (rmax / rmin - 1));
        CHECK(rmin > 1.1f && rmax < 1.45f, "mono/gt ratio range [%g, %g]", rmin, rmax);
        CHECK(rmax / rmin - 1 > 0.03f && rmax / rmin - 1 < 0.3f, "mono drift %.3f", rmax / rmin - 1);
    }
    /* covis_cam00/cam03.npy agrees with reprojecting cam03's depth_gt into cam00's depth_gt */
    pg_array d3 = { 0 }, cv = { 0 };
    snprintf(path, sizeof path, "%s/depth_gt/cam03.npy", dir);
    CHECK_OK(io_npy_load(path, &d3));
    snprintf(path, sizeof path, "%s/covis_cam00/cam03.npy", dir);
    CHECK_OK(io_npy_load(path, &cv));
    if (shapes_ok && d3.count == dg.count && cv.count == dg.count) {
        pg_camera c0, c3;
        synth_camera(&sc, 0, W, H, &c0);
        synth_camera(&sc, 3, W, H, &c3);
        int n1 = 0, ok1 = 0, n0 = 0, ok0 = 0;
        for (int f = 0; f < F; f++)
            for (int y = 0; y < H; y++)
                for (int x = 0; x < W; x++) {
                    size_t i = ((size_t)f * H + y) * W + x;
                    if (!(d3.data[i] > 0)) continue;
                    float X[3], uv[2];
                    pg_camera_unproject(&c3, x + 0.5f, y + 0.5f, d3.data[i], X);
                    float z0 = pg_camera_project(&c0, X, uv);
                    int inside = z0 > 0 && uv[0] >= 0 && uv[1] >= 0 && uv[0] < W && uv[1] < H;
                    float g0 = inside ? dg.data[((size_t)f * H + (int)uv[1]) * W + (int)uv[0]] : 0;
                    if (cv.data[i] > 0.5f) {
                        n1++;
                        ok1 += inside && fabsf(g0 - z0) < 0.02f * z0;
                    } else if (inside) {
                        n0++;
                        ok0 += g0 < z0 * 0.98f;
                    }
                }
        printf("covis cam03: %d covisible px (%d agree with depth_gt), %d occluded px (%d agree)\n", n1, ok1, n0, ok0);
        CHECK(n1 > 1000 && ok1 > n1 * 0.95, "covisible pixels: %d of %d agree", ok1, n1);
        CHECK(n0 > 20 && ok0 > n0 * 0.8, "occluded pixels: %d of %d agree", ok0, n0);
    }
    pg_array_destroy(&d3);
    pg_array_destroy(&cv);
    pg_array_destroy(&dg);
    pg_array_destroy(&mk);
    pg_array_destroy(&dm);

    /* scene.json parses and names the cameras */
    cJSON *root = NULL;
    snprintf(path, sizeof path, "%s/scene.json", dir);
    CHECK_OK(io_json_load(path, &root));
    if (root) {
        cJSON *cams = cJSON_GetObjectItem(root, "cameras"), *dmj = cJSON_GetObjectItem(root, "depth_mono");
        CHECK(cJSON_GetArraySize(cams) == NC, "scene.json has %d cameras", cJSON_GetArraySize(cams));
        cJSON *fs = dmj ? cJSON_GetObjectItem(dmj, "frame_scale") : NULL;
        CHECK(cJSON_GetArraySize(fs) == F, "depth_mono.frame_scale has %d entries", cJSON_GetArraySize(fs));
        cJSON_Delete(root);
    }
}

/* Visibility: cam00's own surface points are visible from cam00; points pushed further along
 * the ray (behind the first surface) are not. */
static void test_visibility(void)
{
    synth_scene sc;
    synth_scene_default(&sc, 1);
    pg_camera c0, c5;
    synth_camera(&sc, 0, W, H, &c0);
    synth_camera(&sc, 5, W, H, &c5);
    int vis = 0, hidden = 0, n = 0, vis5 = 0;
    for (int y = 2; y < H; y += 5)
        for (int x = 2; x < W; x += 5) {
            float z = synth_trace_depth(&sc, &c0, x + 0.5f, y + 0.5f, 0.25f, NULL);
            if (!(z > 0)) continue;
            float X[3], Xb[3];
            pg_camera_unproject(&c0, x + 0.5f, y + 0.5f, z, X);
            pg_camera_unproject(&c0, x + 0.5f, y + 0.5f, z * 1.2f, Xb);
            n++;
            vis += synth_point_visible(&sc, &c0, X, 0.25f, 1e-3f);
            hidden += !synth_point_visible(&sc, &c0, Xb, 0.25f, 1e-3f);
            vis5 += synth_point_visible(&sc, &c5, X, 0.25f, 1e-3f);
        }
    printf("visibility: %d/%d visible from cam00, %d/%d hidden behind, %d/%d visible from cam05\n", vis, n, hidden, n,
           vis5, n);
    CHECK(n > 100 && vis == n, "surface points visible from their own camera: %d of %d", vis, n);
    CHECK(hidden == n, "points behind the surface reported visible: %d of %d hidden", hidden, n);
    CHECK(vis5 > n / 2 && vis5 < n, "cam05 should see most but not all of cam00's points (%d of %d)", vis5, n);
}

/* Ground-truth flow: zero on static surfaces, nonzero on moving objects, and warping frame s1's
 * image by the flow reproduces frame s0 on valid pixels. */
static void test_flow(void)
{
    synth_scene sc;
    synth_scene_default(&sc, 1);
    pg_camera cam;
    synth_camera(&sc, 0, W, H, &cam);
    float *flow = malloc(sizeof(float) * W * H * 2);
    unsigned char *valid = malloc(W * H), *mask = malloc(W * H);
    pg_image a = { 0 }, b = { 0 };
    const float s0 = 0.4f, s1 = 0.5f;
    CHECK_OK(synth_render_flow(&sc, &cam, s0, s1, flow, valid));
    CHECK_OK(synth_render_frame(&sc, &cam, s0, &a, NULL, mask));
    CHECK_OK(synth_render_frame(&sc, &cam, s1, &b, NULL, NULL));
    int moving = 0, static_nonzero = 0, nvalid = 0;
    double err = 0, err_zero = 0;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            size_t i = (size_t)y * W + x;
            float fx = flow[2 * i], fy = flow[2 * i + 1], m = hypotf(fx, fy);
            if (mask[i]) moving += m > 0.3f;
            else static_nonzero += m > 1e-4f;
            if (!mask[i] || !valid[i]) continue;
            /* nearest-neighbour warp of frame s1 back to s0 vs. no warp */
            int u = clampi((int)floorf(x + 0.5f + fx), 0, W - 1), v = clampi((int)floorf(y + 0.5f + fy), 0, H - 1);
            for (int k = 0; k < 3; k++) {
                err += fabsf(pg_image_at(&b, u, v)[k] - pg_image_at(&a, x, y)[k]);
                err_zero += fabsf(pg_image_at(&b, x, y)[k] - pg_image_at(&a, x, y)[k]);
            }
            nvalid++;
        }
    printf("flow: %d moving px with |flow| > 0.3, warp error %.4f vs %.4f unwarped (%d px)\n", moving,
           err / (3.0 * nvalid), err_zero / (3.0 * nvalid), nvalid);
    CHECK(static_nonzero == 0, "%d static pixels have flow", static_nonzero);
    CHECK(moving > 50, "only %d moving pixels with flow", moving);
    CHECK(nvalid > 50 && err < 0.6 * err_zero, "flow warp does not explain the motion: %g vs %g", err, err_zero);
    pg_image_destroy(&a);
    pg_image_destroy(&b);
    free(flow);
    free(valid);
    free(mask);
}

/* Panoptic layout: meta files hold k / w2c equal to synth's cameras. */
static void test_panoptic(const char *dir)
{
    synth_scene sc;
    synth_scene_default(&sc, 1);
    char path[4096];
    cJSON *root = NULL;
    snprintf(path, sizeof path, "%s/train_meta.json", dir);
    CHECK_OK(io_json_load(path, &root));
    if (root) {
        cJSON *k = cJSON_GetObjectItem(root, "k"), *w2c = cJSON_GetObjectItem(root, "w2c");
        cJSON *fn = cJSON_GetObjectItem(root, "fn"), *cid = cJSON_GetObjectItem(root, "cam_id");
        CHECK(cJSON_GetArraySize(k) == 2 && cJSON_GetArraySize(w2c) == 2 && cJSON_GetArraySize(fn) == 2 &&
                  cJSON_GetArraySize(cid) == 2,
              "meta arrays have the wrong frame count");
        CHECK(cJSON_GetObjectItem(root, "w")->valueint == W, "w");
        cJSON *ids = cJSON_GetArrayItem(cid, 1);
        int ncam = cJSON_GetArraySize(ids);
        CHECK(ncam == NC - 2, "train split has %d cameras", ncam);
        double worst = 0;
        for (int i = 0; i < ncam; i++) {
            int c = cJSON_GetArrayItem(ids, i)->valueint;
            pg_camera cam;
            synth_camera(&sc, c, W, H, &cam);
            cJSON *M = cJSON_GetArrayItem(cJSON_GetArrayItem(w2c, 1), i);
            cJSON *K = cJSON_GetArrayItem(cJSON_GetArrayItem(k, 1), i);
            for (int r = 0; r < 3; r++) {
                for (int j = 0; j < 3; j++)
                    worst = fmax(worst, fabs(cJSON_GetArrayItem(cJSON_GetArrayItem(M, r), j)->valuedouble - cam.R[3 * r + j]));
                worst = fmax(worst, fabs(cJSON_GetArrayItem(cJSON_GetArrayItem(M, r), 3)->valuedouble - cam.t[r]));
            }
            worst = fmax(worst, fabs(cJSON_GetArrayItem(cJSON_GetArrayItem(K, 0), 0)->valuedouble - cam.fx) / cam.fx);
            const char *name = cJSON_GetArrayItem(cJSON_GetArrayItem(fn, 1), i)->valuestring;
            snprintf(path, sizeof path, "%s/ims/%s", dir, name);
            CHECK(pg_path_exists(path), "%s missing", path);
        }
        CHECK(worst < 1e-5, "meta camera differs from synth camera by %g", worst);
        cJSON_Delete(root);
    }
    snprintf(path, sizeof path, "%s/test_meta.json", dir);
    CHECK(pg_path_exists(path), "test_meta.json missing");

    /* io's Panoptic loader: every camera reprojects like synth's (<= 0.01 px), roles from the split */
    io_dataset_options dopt = io_dataset_defaults();
    pg_dataset *ds = NULL;
    CHECK_OK(io_dataset_open(dir, &dopt, &ds));
    if (!ds) return;
    CHECK(io_dataset_get_kind(ds) == IO_DATASET_PANOPTIC, "kind %s", io_dataset_kind_name(io_dataset_get_kind(ds)));
    CHECK(io_dataset_num_cameras(ds) == NC && io_dataset_num_frames(ds) == 2, "%d cameras, %d frames",
          io_dataset_num_cameras(ds), io_dataset_num_frames(ds));
    float pts[64][3];
    int np = sample_points(&sc, 1.0f, pts, 64);
    double worst = 0;
    int ntest = 0;
    for (int i = 0; i < io_dataset_num_cameras(ds); i++) {
        int c = atoi(io_dataset_camera_name(ds, i));
        pg_camera a, b;
        synth_camera(&sc, c, W, H, &a);
        io_dataset_camera_at(ds, i, 1, &b);
        for (int k = 0; k < np; k++) {
            float ua[2], ub[2];
            pg_camera_project(&a, pts[k], ua);
            pg_camera_project(&b, pts[k], ub);
            worst = fmax(worst, hypot(ua[0] - ub[0], ua[1] - ub[1]));
        }
        int is_test = strcmp(io_dataset_camera_role(ds, i), "test") == 0;
        ntest += is_test;
        CHECK(is_test == (c == 5 || c == 6), "camera %d has role %s", c, io_dataset_camera_role(ds, i));
    }
    printf("Panoptic loader vs synth cameras: worst reprojection %.2e px\n", worst);
    CHECK(worst <= 0.01, "Panoptic camera reprojects %.4f px away", worst);
    CHECK(ntest == 2, "%d test cameras", ntest);
    pg_image img = { 0 };
    CHECK_OK(io_dataset_frame(ds, 0, 1, &img));
    CHECK(img.width == W && img.height == H, "Panoptic frame %d x %d", img.width, img.height);
    pg_image_destroy(&img);
    io_dataset_close(ds);
}

int main(void)
{
    test_determinism();
    test_visibility();
    test_flow();

    char dir[2048], dir2[2048], pan[2048], args[8192], err[1024];
    test_tmpdir("synth_a", dir, sizeof dir);
    test_tmpdir("synth_b", dir2, sizeof dir2);
    test_tmpdir("synth_pan", pan, sizeof pan);
    snprintf(args, sizeof args, "synth '%s' --cams %d --frames %d --size %dx%d --seed 3 --spp 1", dir, NC, F, W, H);
    CHECK(test_run_cli(args, err, sizeof err) == 0, "synth failed: %s", err);
    snprintf(args, sizeof args, "synth '%s' --cams %d --frames %d --size %dx%d --seed 3 --spp 1 --threads 1", dir2, NC, F, W, H);
    CHECK(test_run_cli(args, err, sizeof err) == 0, "synth failed: %s", err);
    const char *files[] = { "poses_bounds.npy", "depth_gt/cam00.npy", "depth_gt/cam03.npy", "masks_dynamic/cam00.npy",
                            "depth_mono/cam00.npy", "cam02/images/0003.png", "scene.json" };
    for (size_t i = 0; i < sizeof files / sizeof files[0]; i++) {
        char a[4096], b[4096];
        snprintf(a, sizeof a, "%s/%s", dir, files[i]);
        snprintf(b, sizeof b, "%s/%s", dir2, files[i]);
        CHECK(test_files_equal(a, b), "%s differs between two runs (2 threads vs 1)", files[i]);
    }
    test_dynerf_files(dir);

    snprintf(args, sizeof args, "synth '%s' --cams %d --frames 2 --size %dx%d --layout panoptic", pan, NC, W, H);
    CHECK(test_run_cli(args, err, sizeof err) == 0, "synth panoptic failed: %s", err);
    test_panoptic(pan);

    /* --video: camXX.mp4 decodes to the PNG frames (H.264 yuv420p crf 10: ~27 dB on this tiny,
     * saturated, high-frequency content because of chroma subsampling; PNGs stay the reference) */
    char vid[2048];
    test_tmpdir("synth_vid", vid, sizeof vid);
    snprintf(args, sizeof args, "synth '%s' --cams 2 --frames 4 --size %dx%d --spp 1 --video", vid, W, H);
    CHECK(test_run_cli(args, err, sizeof err) == 0, "synth --video failed: %s", err);
    {
        char mp4[4096], png[4096];
        snprintf(mp4, sizeof mp4, "%s/cam01.mp4", vid);
        snprintf(png, sizeof png, "%s/cam01/images/0002.png", vid);
        io_video_options vo = io_video_defaults();
        io_frames fr = { 0 };
        pg_image a = { 0 }, b = { 0 };
        CHECK_OK(io_frames_read(mp4, &vo, &fr));
        CHECK(fr.count == 4, "video has %d frames", fr.count);
        if (fr.count == 4) {
            CHECK_OK(io_frames_image(&fr, 2, &a));
            CHECK_OK(io_image_load(png, &b));
            double psnr = a.data && b.data ? pg_image_psnr(&a, &b, NULL) : 0;
            printf("video frame vs PNG: %.1f dB\n", psnr);
            CHECK(psnr > 24, "video frame vs PNG %.1f dB", psnr);
        }
        pg_image_destroy(&a);
        pg_image_destroy(&b);
        io_frames_destroy(&fr);
    }

    /* bad input: exit code 2 with one clear line */
    CHECK(test_run_cli("synth /tmp/x --cams 0", err, sizeof err) == 2 && strstr(err, "--cams"), "cams 0: %s", err);
    CHECK(test_run_cli("synth /tmp/x --size 10by10", err, sizeof err) == 2 && strstr(err, "--size"), "size: %s", err);
    CHECK(test_run_cli("synth /tmp/x --layout llff", err, sizeof err) == 2 && strstr(err, "layout"), "layout: %s", err);
    CHECK(test_run_cli("synth", err, sizeof err) == 2, "no OUT: %s", err);
    CHECK(test_run_cli("synth /proc/nope/x --frames 1 --cams 1", err, sizeof err) == 3 && strstr(err, "/proc/nope"),
          "unwritable dir: %s", err);
    return test_summary("test_synth");
}
