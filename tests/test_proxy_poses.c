/* test_proxy_poses.c - hemisphere poses, forward warp, mesh coverage masks and the pose-scale fit. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/camera.h"
#include "core/mathx.h"
#include "proxy/mask.h"
#include "proxy/poses.h"
#include "proxy/procedural.h"
#include "testlib.h"

static void test_hemisphere(void)
{
    pg_camera real;
    pg_camera_from_fov(&real, 160, 120, 60);
    /* A non-trivial real pose: look from (0.3, -0.2, -1) at (0, 0, 3). */
    float eye0[3] = { 0.3f, -0.2f, -1.0f }, tgt[3] = { 0, 0, 3 }, up0[3] = { 0, -1, 0 };
    pg_camera_look_at(&real, eye0, tgt, up0);
    float depth[160 * 120];
    for (int i = 0; i < 160 * 120; i++) depth[i] = (i % 7 == 0) ? 0.0f : 2.0f + 0.001f * (i % 5);
    depth[5] = NAN;
    float c[3], r;
    CHECK_OK(proxy_scene_center(&real, depth, 1.5f, c, &r));
    float C0[3], d[3];
    pg_camera_center(&real, C0);
    vec3_sub(d, c, C0);
    CHECK(fabsf(vec3_norm(d) - r) < 1e-4f && fabsf(r - 1.5f * 2.002f) < 0.01f, "radius %g", r);

    enum { M = 18 };
    pg_camera cams[M];
    CHECK_OK(proxy_poses_hemisphere(&real, c, M, 20.0f, cams));
    float up[3] = { -real.R[3], -real.R[4], -real.R[5] };
    float max_angle = 0, min_angle = 180, min_pair = 180;
    for (int j = 0; j < M; j++) {
        float e[3], uv[2];
        pg_camera_center(&cams[j], e);
        vec3_sub(d, e, c);
        CHECK(fabsf(vec3_norm(d) - r) < 1e-3f * r, "camera %d at distance %g, not %g", j, vec3_norm(d), r);
        float z = pg_camera_project(&cams[j], c, uv);
        CHECK(z > 0 && fabsf(uv[0] - real.cx) < 1e-2f && fabsf(uv[1] - real.cy) < 1e-2f,
              "camera %d does not look at the centre (%g %g)", j, uv[0], uv[1]);
        CHECK(cams[j].fx == real.fx && cams[j].cy == real.cy, "intrinsics changed");
        float xdotup = cams[j].R[0] * up[0] + cams[j].R[1] * up[1] + cams[j].R[2] * up[2];
        CHECK(fabsf(xdotup) < 1e-4f, "camera %d rolled: x.up = %g", j, xdotup);
        float a = proxy_camera_angle_deg(&real, &cams[j]);
        if (a > max_angle) max_angle = a;
        if (a < min_angle) min_angle = a;
        for (int k = 0; k < j; k++) {
            float b = proxy_camera_angle_deg(&cams[k], &cams[j]);
            if (b < min_pair) min_pair = b;
        }
    }
    CHECK(max_angle <= 20.01f && max_angle > 19.0f, "max angle %g", max_angle);
    CHECK(min_angle > 2.0f, "a proxy camera repeats the real one (%g deg)", min_angle);
    /* Even spread: 18 points on a 20 deg cap are ~8 deg apart; clumping would show here. */
    CHECK(min_pair > 4.0f, "closest pair of proxy cameras only %g deg apart", min_pair);
    CHECK(proxy_poses_hemisphere(&real, c, 0, 20.0f, cams) == PG_ERR_ARG, "m = 0 accepted");
    CHECK(proxy_poses_hemisphere(&real, c, 4, 95.0f, cams) == PG_ERR_ARG, "95 deg accepted");
    for (int i = 0; i < 160 * 120; i++) depth[i] = 0;
    CHECK(proxy_scene_center(&real, depth, 1.0f, c, &r) == PG_ERR_ARG, "all-invalid depth accepted");
}

/* Warping a view into itself is the identity; mesh coverage of a plane seen from the side is full
 * where the plane is visible and the disocclusion behind the card is uncovered. */
static void test_warp_and_mesh(void)
{
    enum { W = 160, H = 120 };
    pg_camera cam, side;
    pg_camera_from_fov(&cam, W, H, 60);
    float *rgb = malloc(sizeof(float) * W * H * 3), *depth = malloc(sizeof(float) * W * H);
    float *wrgb = malloc(sizeof(float) * W * H * 3), *wdepth = malloc(sizeof(float) * W * H);
    float *zmesh = malloc(sizeof(float) * W * H), *zside = malloc(sizeof(float) * W * H);
    proxy_procedural_render(&cam, 0, 1, rgb, depth);
    CHECK_OK(proxy_forward_warp(&cam, rgb, depth, 1.0f, &cam, wrgb, wdepth));
    double err = 0;
    for (int i = 0; i < W * H * 3; i++) err = fmax(err, fabs(wrgb[i] - rgb[i]));
    CHECK(err < 1e-6, "identity warp changed colours by %g", err);
    proxy_mask_options mo = proxy_default_mask_options();
    CHECK_OK(proxy_mesh_depth(&cam, depth, 0, &cam, &mo, zmesh, NULL, NULL, NULL));
    int inner_bad = 0;
    for (int v = 1; v < H - 1; v++)
        for (int u = 1; u < W - 1; u++)
            if (zmesh[v * W + u] > 0 && fabsf(zmesh[v * W + u] - depth[v * W + u]) > 1e-3f) inner_bad++;
    CHECK(inner_bad == 0, "%d pixels where the mesh depth differs from the input depth", inner_bad);

    /* Side view: rotate 12 deg about the scene centre. */
    float c[3] = { 0, 0, 3 }, up[3] = { 0, -1, 0 }, eye[3] = { 3 * sinf(0.21f), 0, 3 - 3 * cosf(0.21f) };
    side = cam;
    pg_camera_look_at(&side, eye, c, up);
    float *tdepth = malloc(sizeof(float) * W * H);
    proxy_procedural_render(&side, 0, 1, NULL, tdepth);
    CHECK_OK(proxy_mesh_depth(&cam, depth, 0, &side, &mo, zside, NULL, NULL, NULL));
    /* Ground-truth visibility from cam of what side sees: reproject and compare with cam's depth. */
    long vis = 0, vis_cov = 0, hidden = 0, hidden_cov = 0;
    for (int v = 0; v < H; v++) {
        for (int u = 0; u < W; u++) {
            float X[3], uv[2];
            pg_camera_unproject(&side, u + 0.5f, v + 0.5f, tdepth[v * W + u], X);
            float z = pg_camera_project(&cam, X, uv);
            int x = (int)floorf(uv[0]), y = (int)floorf(uv[1]);
            if (x < 2 || y < 2 || x >= W - 2 || y >= H - 2) continue;
            int visible = fabsf(depth[y * W + x] - z) < 0.01f * z;
            int covered = zside[v * W + u] > 0;
            if (visible) { vis++; vis_cov += covered; }
            else { hidden++; hidden_cov += covered; }
        }
    }
    CHECK(hidden > 100, "the side view sees no disocclusion (%ld)", hidden);
    CHECK(vis_cov > 0.97 * vis, "mesh covers %ld of %ld visible pixels", vis_cov, vis);
    CHECK(hidden_cov < 0.1 * hidden, "mesh covers %ld of %ld disoccluded pixels", hidden_cov, hidden);
    free(rgb); free(depth); free(wrgb); free(wdepth); free(zmesh); free(zside); free(tdepth);
}

/* Depth in units 1/s of the pose units: the photometric fit must find s, with training cameras
 * near the real one (a DyNeRF rig) and spread wide around the scene (a Panoptic dome, where most
 * of each target sees what the real camera does not). */
static void check_pose_scale(const char *rig, const float (*ang)[2], int n)
{
    enum { W = 160, H = 120 };
    pg_camera cam, t[8];
    pg_camera_from_fov(&cam, W, H, 60);
    float *rgb = malloc(sizeof(float) * W * H * 3), *depth = malloc(sizeof(float) * W * H);
    float *trgb[8];
    proxy_procedural_render(&cam, 0, 2, rgb, depth);
    const float s_true = 1.7f;
    for (int i = 0; i < W * H; i++) depth[i] /= s_true;
    for (int k = 0; k < n; k++) {
        float c[3] = { 0, 0, 3 }, up[3] = { 0, -1, 0 };
        float eye[3] = { 3 * sinf(ang[k][0]), 3 * sinf(ang[k][1]), 3 - 3 * cosf(ang[k][0]) * cosf(ang[k][1]) };
        t[k] = cam;
        pg_camera_look_at(&t[k], eye, c, up);
        trgb[k] = malloc(sizeof(float) * W * H * 3);
        proxy_procedural_render(&t[k], 0, 2, trgb[k], NULL);
    }
    proxy_scale_report rep;
    proxy_scale_options so = proxy_default_scale_options();
    so.scale_min = 1.0f / 16, so.scale_max = 16; /* the range when bounds are unknown */
    CHECK_OK(proxy_fit_pose_scale(&cam, rgb, depth, n, t, (const float *const *)trgb, &so, &rep));
    CHECK(fabsf(rep.scale / s_true - 1) < 0.02f, "%s: fitted scale %g, true %g (cost %g, coverage %g)", rig,
          rep.scale, s_true, rep.cost, rep.coverage);
    printf("pose scale, %s: fitted %.4f true %.4f cost %.4f coverage %.3f evals %d\n", rig, rep.scale, s_true,
           rep.cost, rep.coverage, rep.evaluations);
    for (int k = 0; k < n; k++) free(trgb[k]);
    free(rgb); free(depth);
}

static void test_pose_scale(void)
{
    const float near[3][2] = { { 0.12f, 0 }, { -0.1f, 0.05f }, { 0.05f, -0.12f } };
    const float wide[4][2] = { { 0.5f, 0 }, { -0.6f, 0.1f }, { 0.8f, -0.15f }, { -0.9f, 0.2f } };
    check_pose_scale("near cameras", near, 3);
    check_pose_scale("cameras 29-53 degrees away", wide, 4);
}

int main(void)
{
    test_hemisphere();
    test_warp_and_mesh();
    test_pose_scale();
    return test_summary("test_proxy_poses");
}
