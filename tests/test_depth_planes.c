/* test_depth_planes.c - dominant planes of the static depth (scene_planes.h): a wall and a floor
 * under a smooth multiplicative error field are found and straightened, a ball on the floor and
 * moving pixels are left alone, a curved scene has no plane, degenerate inputs do nothing. */
#include "testlib.h"
#include "core/rng.h"
#include "depth/plane.h"
#include "depth/scene_planes.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { W = 160, H = 120, F = 6 };
#define FOCAL 140.0

/* Ray of pixel (u, v) in camera coordinates (z forward, y down). */
static void pixel_ray(int u, int v, double r[3])
{
    r[0] = (u + 0.5 - W / 2.0) / FOCAL;
    r[1] = (v + 0.5 - H / 2.0) / FOCAL;
    r[2] = 1.0;
}

/* Depth of the ray hitting the plane n.X = c (0 when it does not, in front). */
static double plane_hit(const double r[3], const double n[3], double c)
{
    double den = n[0] * r[0] + n[1] * r[1] + n[2] * r[2];
    double t = den != 0 ? c / den : -1;
    return t > 0 ? t : 0;
}

/* Depth of the ray hitting the sphere (centre s, radius rad); 0 when it misses. */
static double sphere_hit(const double r[3], const double s[3], double rad)
{
    double a = r[0] * r[0] + r[1] * r[1] + r[2] * r[2], b = -2 * (r[0] * s[0] + r[1] * s[1] + r[2] * s[2]);
    double c = s[0] * s[0] + s[1] * s[1] + s[2] * s[2] - rad * rad, disc = b * b - 4 * a * c;
    if (disc < 0) return 0;
    return (-b - sqrt(disc)) / (2 * a);
}

enum { WALL, FLOOR, BALL };

/* A room corner: the wall z = 5 (upper part), a floor y = 1 (seen below the horizon), a ball on the
 * floor; true z-depth into truth (H*W), the surface of each pixel into surface. */
static void room_truth(float *truth, unsigned char *surface)
{
    const double wall_n[3] = { 0, 0, 1 }, floor_n[3] = { 0, 1, 0 }, ball[3] = { 0.6, 0.7, 3.2 };
    for (int v = 0; v < H; v++)
        for (int u = 0; u < W; u++) {
            double r[3];
            pixel_ray(u, v, r);
            double dw = plane_hit(r, wall_n, 5.0), df = plane_hit(r, floor_n, 1.0);
            double d = dw > 0 && (df <= 0 || dw < df) ? dw : df;
            double db = sphere_hit(r, ball, 0.3);
            size_t k = (size_t)v * W + u;
            surface[k] = dw > 0 && (df <= 0 || dw < df) ? WALL : FLOOR;
            if (db > 0 && db < d) surface[k] = BALL, d = db;
            truth[k] = (float)(d * r[2]);
        }
}

/* What a monocular network gives: the truth times a smooth field (+-1.2 %, one and a half periods
 * across the frame, like tabletop_dev's depth_mono) and 0.3 % noise, the same field in every frame
 * (a fused static depth). A field that is linear over a surface only tilts its plane: no single
 * view can tell; the curved part is what snapping removes. */
static void bend(const float *truth, float *depth, pg_rng *rng)
{
    for (int f = 0; f < F; f++)
        for (int v = 0; v < H; v++)
            for (int u = 0; u < W; u++) {
                size_t k = (size_t)v * W + u;
                double field = 0.012 * sin(2 * M_PI * (1.2 * u / W + 0.9 * v / H) + 0.4);
                depth[(size_t)f * W * H + k] = (float)(truth[k] * exp(field + 0.003 * pg_rng_normal(rng)));
            }
}

static int by_value(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

static double median(float *v, int m)
{
    qsort(v, (size_t)m, sizeof(float), by_value);
    return m ? v[m / 2] : 0;
}

/* How far one surface's depth bends: the median of |log(d / truth) - its median| over the surface
 * (a global scale is not observable from one camera; a bend shifts textures in novel views). */
static double bend_of(const float *d, const float *truth, const unsigned char *surface, int want)
{
    float *e = malloc(sizeof(float) * W * H);
    int m = 0;
    for (int k = 0; k < W * H; k++)
        if (surface[k] == want) e[m++] = logf(d[k] / truth[k]);
    float *tmp = malloc(sizeof(float) * (m ? m : 1));
    memcpy(tmp, e, sizeof(float) * m);
    double mid = median(tmp, m);
    for (int i = 0; i < m; i++) e[i] = fabsf(e[i] - (float)mid);
    double out = median(e, m);
    free(e);
    free(tmp);
    return out;
}

static void test_room(void)
{
    float *truth = malloc(sizeof(float) * W * H), *depth = malloc(sizeof(float) * F * W * H);
    float *before = malloc(sizeof(float) * F * W * H);
    unsigned char *surface = malloc(W * H), *masks = malloc((size_t)F * W * H);
    signed char *label = malloc(W * H);
    pg_rng rng;
    pg_rng_seed(&rng, 3);
    room_truth(truth, surface);
    bend(truth, depth, &rng);
    memset(masks, 1, (size_t)F * W * H);
    /* a moving object crosses the left half of the wall in frames 1-2 */
    for (int f = 1; f <= 2; f++)
        for (int v = 10; v < 40; v++)
            for (int u = 20 + 30 * f; u < 50 + 30 * f; u++) {
                size_t k = (size_t)f * W * H + (size_t)v * W + u;
                masks[k] = 0;
                depth[k] = 2.5f; /* its own depth: must stay */
            }
    memcpy(before, depth, sizeof(float) * F * W * H);

    depth_scene_planes_params p;
    depth_scene_planes_defaults(&p);
    depth_scene_planes_result res;
    CHECK_OK(depth_scene_planes_snap(&p, depth, masks, F, W, H, &res, label));
    printf("room: %d planes (", res.count);
    for (int i = 0; i < res.count; i++)
        printf("%s%.1f %% support, median residual %.4f", i ? "; " : "", 100.0 * res.planes[i].inliers / (W * H),
               res.planes[i].median_residual);
    printf("), %ld values snapped\n", res.snapped);
    CHECK(res.count == 2, "found %d planes, want the wall and the floor", res.count);

    /* Frame 3 (all static): plane pixels straightened, the ball kept. */
    const float *d3 = depth + (size_t)3 * W * H, *b3 = before + (size_t)3 * W * H;
    for (int s = WALL; s <= FLOOR; s++) {
        double e_before = bend_of(b3, truth, surface, s), e_after = bend_of(d3, truth, surface, s);
        printf("room: %s bend (median |log error - its median|) %.4f -> %.4f\n", s == WALL ? "wall" : "floor",
               e_before, e_after);
        CHECK(e_after < e_before / 3, "%s bend %.4f -> %.4f, want a third or less", s == WALL ? "wall" : "floor",
              e_before, e_after);
    }
    long ball_moved = 0, ball_px = 0, ball_labelled = 0;
    for (int k = 0; k < W * H; k++) {
        if (surface[k] != BALL) continue;
        ball_px++;
        ball_labelled += label[k] >= 0;
        /* the ball's rim touches the floor: only pixels more than twice the tolerance from every plane
         * must keep their depth exactly */
        int far_from_planes = 1;
        for (int i = 0; i < res.count; i++) {
            double dp = depth_scene_plane_depth(&res.planes[i], k % W, k / W, W, H);
            if (dp > 0 && fabs(log(b3[k] / dp)) < 2 * p.tolerance) far_from_planes = 0;
        }
        if (far_from_planes) ball_moved += d3[k] != b3[k];
    }
    printf("room: ball %ld px, %ld labelled, %ld far from the planes moved\n", ball_px, ball_labelled, ball_moved);
    CHECK(ball_px > 200 && ball_moved == 0, "%ld ball pixels away from the planes changed depth", ball_moved);
    CHECK(ball_labelled < ball_px / 10, "%ld of %ld ball pixels labelled as a plane", ball_labelled, ball_px);

    /* Moving pixels keep their depth. */
    long moved = 0;
    for (size_t k = 0; k < (size_t)F * W * H; k++)
        if (!masks[k]) moved += depth[k] != before[k];
    CHECK(moved == 0, "%ld moving pixels changed depth", moved);

    /* Same seed, same result (the RANSAC draws are seeded). */
    memcpy(depth, before, sizeof(float) * F * W * H);
    depth_scene_planes_result again;
    CHECK_OK(depth_scene_planes_snap(&p, depth, masks, F, W, H, &again, NULL));
    CHECK(again.count == res.count && again.snapped == res.snapped && again.planes[0].a == res.planes[0].a,
          "second run differs");
    free(truth); free(depth); free(before); free(surface); free(masks); free(label);
}

/* A scene that is one big sphere seen from inside (a dome): bands of it lie within the tolerance of
 * many planes, but no plane explains it; nothing may be snapped. */
static void test_curved(void)
{
    float *depth = malloc(sizeof(float) * F * W * H);
    unsigned char *masks = malloc((size_t)F * W * H);
    memset(masks, 1, (size_t)F * W * H);
    const double c[3] = { 0.5, -0.3, 1.5 };
    for (int v = 0; v < H; v++)
        for (int u = 0; u < W; u++) {
            double r[3];
            pixel_ray(u, v, r);
            /* far intersection with a sphere of radius 5 around c (the camera is inside) */
            double a = r[0] * r[0] + r[1] * r[1] + r[2] * r[2], b = -2 * (r[0] * c[0] + r[1] * c[1] + r[2] * c[2]);
            double cc = c[0] * c[0] + c[1] * c[1] + c[2] * c[2] - 25.0;
            double t = (-b + sqrt(b * b - 4 * a * cc)) / (2 * a);
            for (int f = 0; f < F; f++) depth[(size_t)f * W * H + (size_t)v * W + u] = (float)t;
        }
    depth_scene_planes_params p;
    depth_scene_planes_defaults(&p);
    depth_scene_planes_result res;
    CHECK_OK(depth_scene_planes_snap(&p, depth, masks, F, W, H, &res, NULL));
    printf("dome: %d planes, %ld values snapped\n", res.count, res.snapped);
    CHECK(res.count == 0 && res.snapped == 0, "dome: %d planes, %ld values snapped", res.count, res.snapped);
    free(depth);
    free(masks);
}

/* Nothing static, no valid depth, a single frame: no plane, no change, no failure. */
static void test_degenerate(void)
{
    float *depth = calloc((size_t)F * W * H, sizeof(float));
    unsigned char *masks = calloc((size_t)F * W * H, 1);
    depth_scene_planes_params p;
    depth_scene_planes_defaults(&p);
    depth_scene_planes_result res;
    CHECK_OK(depth_scene_planes_snap(&p, depth, masks, F, W, H, &res, NULL));
    CHECK(res.count == 0 && res.snapped == 0, "empty input: %d planes", res.count);
    for (size_t k = 0; k < (size_t)W * H; k++) depth[k] = 4.0f;
    memset(masks, 1, (size_t)W * H);
    CHECK_OK(depth_scene_planes_snap(&p, depth, masks, 1, W, H, &res, NULL));
    CHECK(res.count == 1 && res.snapped == 0, "a flat single frame: %d planes, %ld snapped (already on it)", res.count,
          res.snapped);
    free(depth);
    free(masks);
}

/* Disc erosion and dilation against a direct scan of the disc |d|^2 <= r^2 + r (out-of-image
 * pixels ignored), on random masks of several densities and radii. */
static void test_morphology(void)
{
    enum { W = 37, H = 23 };
    unsigned char src[W * H], got[W * H];
    pg_rng rng;
    pg_rng_seed(&rng, 7);
    int wrong = 0;
    for (int trial = 0; trial < 24; trial++) {
        float density = 0.05f + 0.04f * trial;
        int r = trial % 6;
        for (int i = 0; i < W * H; i++) src[i] = pg_rng_uniform(&rng) < density ? (unsigned char)(1 + trial) : 0;
        for (int dilate = 0; dilate < 2; dilate++) {
            if (dilate) depth_mask_dilate(src, W, H, r, got);
            else depth_mask_erode(src, W, H, r, got);
            for (int y = 0; y < H; y++)
                for (int x = 0; x < W; x++) {
                    int v = !dilate;
                    for (int dy = -r; dy <= r; dy++)
                        for (int dx = -r; dx <= r; dx++) {
                            int xx = x + dx, yy = y + dy;
                            if (xx < 0 || xx >= W || yy < 0 || yy >= H || dx * dx + dy * dy > r * r + r) continue;
                            int on = src[yy * W + xx] != 0;
                            v = dilate ? (v | on) : (v & on);
                        }
                    wrong += got[y * W + x] != v;
                }
        }
    }
    CHECK(wrong == 0, "%d pixels differ from the direct disc scan", wrong);
}

int main(void)
{
    test_morphology();
    test_room();
    test_curved();
    test_degenerate();
    return test_summary("test_depth_planes");
}
