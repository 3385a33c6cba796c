/* test_depth_ground.c - the floor and the wall placed by the vertical vanishing point (ground.h):
 * a camera pitched down 20 degrees sees a striped wall standing on a textured floor; the given
 * depth has the floor nearly flat and the wall turned (as FastDepth draws tabletop_dev). The stage
 * must find the pitch, put both surfaces within 2 % of the truth and stand a moving box on the
 * floor where it meets it; with no vertical edges, a floor of no single colour or no focal length it must
 * change nothing. */
#include "testlib.h"
#include "core/parallel.h"
#include "depth/ground.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { W = 160, H = 120, F = 3 };
#define FOCAL 140.0
#define PITCH_DEG 20.0
#define CAMERA_HEIGHT 1.5
#define WALL_DISTANCE 6.0

enum { SCENE_ROOM, SCENE_NO_VERTICALS, SCENE_MOTLEY_FLOOR };

/* The true depth and colour of every pixel: the floor up . X = -height and the wall
 * forward . X = distance, up and forward horizontal as seen by the pitched camera. */
static void render_room(int scene, float *truth, unsigned char *is_floor, pg_image *img)
{
    const double p = PITCH_DEG * 3.14159265358979 / 180;
    const double up[3] = { 0, -cos(p), -sin(p) }, fwd[3] = { 0, -sin(p), cos(p) };
    for (int v = 0; v < H; v++)
        for (int u = 0; u < W; u++) {
            double r[3] = { (u + 0.5 - W / 2.0) / FOCAL, (v + 0.5 - H / 2.0) / FOCAL, 1 };
            double du = up[0] * r[0] + up[1] * r[1] + up[2] * r[2], df = fwd[0] * r[0] + fwd[1] * r[1] + fwd[2] * r[2];
            double zf = du < 0 ? CAMERA_HEIGHT / -du : 1e9, zw = df > 0 ? WALL_DISTANCE / df : 1e9;
            size_t k = (size_t)v * W + u;
            float *c = img->data + k * 3;
            if (zf < zw) {
                /* the floor: yellow with waves across the view (no vertical lines) */
                double along = zf * df, across = zf * r[0];
                double wave = 0.5 + 0.5 * sin(along * 9 + 0.8 * sin(across * 3));
                c[0] = 0.9f, c[1] = (float)(0.7 + 0.15 * wave), c[2] = (float)(0.2 + 0.1 * wave);
                static const float motley[4][3] = { { 0.9f, 0.8f, 0.25f }, { 0.1f, 0.3f, 0.9f }, { 0.2f, 0.8f, 0.3f }, { 0.6f, 0.1f, 0.5f } };
                int cell = ((int)floor(across * 2) + 2 * (int)floor(along * 2)) & 3;
                if (scene == SCENE_MOTLEY_FLOOR) memcpy(c, motley[cell], sizeof motley[cell]);
                truth[k] = (float)zf, is_floor[k] = 1;
            } else {
                /* the wall: vertical pink and white stripes (or horizontal bands) */
                double x = zw * r[0], height = -zw * du;
                double s = scene == SCENE_NO_VERTICALS ? sin(height * 12) : sin(x * 14 + 0.5 * sin(x * 2));
                float t = (float)(0.5 + 0.5 * tanh(2 * s)); /* soft edges, as a camera draws them */
                c[0] = 0.95f, c[1] = 0.55f + 0.4f * t, c[2] = 0.55f + 0.4f * t;
                truth[k] = (float)zw, is_floor[k] = 0;
            }
        }
}

/* A monocular network's idea of it: the floor almost one depth, the wall turned. */
static void network_depth(const float *truth, const unsigned char *is_floor, float *d)
{
    for (int v = 0; v < H; v++)
        for (int u = 0; u < W; u++) {
            size_t k = (size_t)v * W + u;
            double x = (u + 0.5) / W - 0.5;
            d[k] = is_floor[k] ? (float)(2.0 * pow(truth[k], 0.3)) : (float)(0.6 * truth[k] * exp(0.4 * x));
        }
}

/* Median |log(d / truth)| over the pixels of one surface, the global scale removed. */
static double surface_error(const float *d, const float *truth, const unsigned char *is_floor, int which, double log_scale)
{
    size_t n = (size_t)W * H;
    int m = 0;
    double *e = malloc(n * sizeof *e);
    for (size_t i = 0; i < n; i++)
        if (is_floor[i] == which) e[m++] = fabs(log(d[i] / truth[i]) - log_scale);
    double med = m ? pg_median(e, m) : 1e9;
    free(e);
    return med;
}

static double median_log_ratio(const float *d, const float *truth)
{
    size_t n = (size_t)W * H;
    double *e = malloc(n * sizeof *e);
    for (size_t i = 0; i < n; i++) e[i] = log(d[i] / truth[i]);
    double med = pg_median(e, (int)n);
    free(e);
    return med;
}

typedef struct {
    pg_image frames[F];
    float truth[W * H], still[W * H], depth[F * W * H];
    unsigned char is_floor[W * H], static_masks[F * W * H];
} room;

static room *make_room(int scene)
{
    room *r = calloc(1, sizeof *r);
    for (int t = 0; t < F; t++) pg_image_create(&r->frames[t], W, H, 3);
    render_room(scene, r->truth, r->is_floor, &r->frames[0]);
    for (int t = 1; t < F; t++) memcpy(r->frames[t].data, r->frames[0].data, sizeof(float) * 3 * W * H);
    network_depth(r->truth, r->is_floor, r->still);
    for (int t = 0; t < F; t++) memcpy(r->depth + (size_t)t * W * H, r->still, sizeof r->still);
    memset(r->static_masks, 1, sizeof r->static_masks);
    return r;
}

static void free_room(room *r)
{
    for (int t = 0; t < F; t++) pg_image_destroy(&r->frames[t]);
    free(r);
}

static void test_room(void)
{
    room *r = make_room(SCENE_ROOM);
    /* frame 2 has a mover: a blue box standing on the floor (its front a vertical face) that the
     * network draws at the floor's depth behind it, inside a mask dilated by two pixels of floor */
    const int bx0 = 70, bx1 = 80, by0 = 84, by1 = 100;
    /* the box's front: the vertical plane through the floor point seen at (bx0 + 5, by1), facing
     * the camera; the truth at the pixel checked, (bx0 + 5, by0 + 4) */
    const double pitch = PITCH_DEG * 3.14159265358979 / 180, fwd[3] = { 0, -sin(pitch), cos(pitch) };
    const double foot[3] = { (bx0 + 5.5 - W / 2.0) / FOCAL, (by1 + 0.5 - H / 2.0) / FOCAL, 1 };
    const double ray[3] = { foot[0], (by0 + 4.5 - H / 2.0) / FOCAL, 1 };
    const double sheet = r->truth[(size_t)by1 * W + bx0 + 5] * (fwd[1] * foot[1] + fwd[2] * foot[2]);
    const float box_truth = (float)(sheet / (fwd[1] * ray[1] + fwd[2] * ray[2]));
    for (int v = by0 - 2; v < by1 + 2; v++)
        for (int u = bx0 - 2; u < bx1 + 2; u++) {
            size_t k = (size_t)v * W + u;
            r->static_masks[2 * W * H + k] = 0;
            if (v < by0 || v >= by1 || u < bx0 || u >= bx1) continue;
            float *c = r->frames[2].data + k * 3;
            c[0] = 0.1f, c[1] = 0.2f, c[2] = 0.8f;
        }
    double s0 = median_log_ratio(r->depth, r->truth);
    double floor_before = surface_error(r->depth, r->truth, r->is_floor, 1, s0);
    double wall_before = surface_error(r->depth, r->truth, r->is_floor, 0, s0);
    depth_ground_params p;
    depth_ground_defaults(&p);
    p.focal = (float)FOCAL;
    depth_ground_result res;
    CHECK_OK(depth_ground_snap(&p, r->frames, F, r->depth, r->static_masks, r->still, W, H, &res));
    CHECK(res.found, "res.found");
    CHECK(fabs(res.tilt_deg - PITCH_DEG) < 1.0, "tilt %.2f deg, true %.0f", res.tilt_deg, PITCH_DEG);
    CHECK(res.wall, "res.wall");
    CHECK(res.floor_share > 0.4 && res.floor_share < 0.8, "res.floor_share > 0.4 && res.floor_share < 0.8");
    double s1 = median_log_ratio(r->depth, r->truth);
    double floor_after = surface_error(r->depth, r->truth, r->is_floor, 1, s1);
    double wall_after = surface_error(r->depth, r->truth, r->is_floor, 0, s1);
    printf("ground: tilt %.2f deg (true %.0f), vp share %.2f, floor %.2f of the image, rest x%.3f, wall span %.2f\n", res.tilt_deg,
           PITCH_DEG, res.vp_share, res.floor_share, res.rest_scale, res.wall_span);
    printf("ground: median |log error| floor %.4f -> %.4f, wall %.4f -> %.4f\n", floor_before, floor_after, wall_before, wall_after);
    CHECK(floor_before > 0.1 && wall_before > 0.05, "floor_before > 0.1 && wall_before > 0.05");
    CHECK(floor_after < 0.02, "floor_after < 0.02");
    CHECK(wall_after < 0.02, "wall_after < 0.02");
    /* the box stands where it meets the floor; the ring of floor in its mask is floor */
    double box_error = fabs(log(r->depth[2 * W * H + (size_t)(by0 + 4) * W + bx0 + 5] / box_truth) - s1);
    double ring_error = fabs(log(r->depth[2 * W * H + (size_t)(by1 + 1) * W + bx0 + 5] / r->truth[(size_t)(by1 + 1) * W + bx0 + 5]) - s1);
    printf("ground: box |log error| %.4f (rest factor alone %.4f), ring %.4f; %ld objects, %ld on the floor\n", box_error,
           fabs(log(r->still[(size_t)(by0 + 4) * W + bx0 + 5] * res.rest_scale / box_truth) - s1), ring_error, res.blobs, res.anchored);
    CHECK(box_error < 0.02, "box |log error| %.4f", box_error);
    CHECK(ring_error < 0.02, "ring |log error| %.4f", ring_error);
    CHECK(res.anchored >= 1, "%ld objects on the floor", res.anchored);
    free_room(r);
}

/* Each case must leave the depth exactly as it was. */
static void test_left_alone(int scene, float focal, const char *what)
{
    room *r = make_room(scene);
    depth_ground_params p;
    depth_ground_defaults(&p);
    p.focal = focal;
    depth_ground_result res;
    CHECK_OK(depth_ground_snap(&p, r->frames, F, r->depth, r->static_masks, r->still, W, H, &res));
    int same = 1;
    for (int t = 0; t < F; t++) same &= memcmp(r->depth + (size_t)t * W * H, r->still, sizeof r->still) == 0;
    printf("ground, %s: found %d, vp share %.2f, floor %.2f\n", what, res.found, res.vp_share, res.floor_share);
    CHECK(!res.found, "!res.found");
    CHECK(res.changed == 0, "res.changed == 0");
    CHECK(same, "same");
    free_room(r);
}

/* A ring of cameras around the scene knows the vertical; a forward-facing row does not. */
static void test_rig_up(void)
{
    pg_camera ring[8], row[8];
    const float world_up[3] = { 0, -1, 0 }, target[3] = { 0, 0, 0 }; /* y points down, as in Panoptic */
    for (int k = 0; k < 8; k++) {
        double a = k * 2 * 3.14159265358979 / 8;
        float eye[3] = { (float)(4 * cos(a)), (float)(-1.5 - 0.3 * (k % 2)), (float)(4 * sin(a)) };
        pg_camera_from_fov(&ring[k], W, H, 60);
        pg_camera_look_at(&ring[k], eye, target, world_up);
        float eye2[3] = { (float)(k - 3.5) * 0.2f, -1.5f, -4 };
        pg_camera_from_fov(&row[k], W, H, 60);
        pg_camera_look_at(&row[k], eye2, target, world_up);
    }
    float up[3], expected[3];
    int found = depth_ground_rig_up(ring, 8, 3, up);
    for (int r = 0; r < 3; r++) expected[r] = ring[3].R[r * 3] * world_up[0] + ring[3].R[r * 3 + 1] * world_up[1] + ring[3].R[r * 3 + 2] * world_up[2];
    double dot = up[0] * expected[0] + up[1] * expected[1] + up[2] * expected[2];
    printf("ground, ring of 8 cameras: up found %d, %.2f deg from the truth\n", found, acos(dot < 1 ? dot : 1) * 180 / 3.14159265358979);
    CHECK(found, "the ring's up found");
    CHECK(dot > cos(1.0 * 3.14159265358979 / 180), "up within 1 deg of the truth (cos %.6f)", dot);
    CHECK(!depth_ground_rig_up(row, 8, 3, up), "a forward-facing row gives no up");
}

int main(void)
{
    test_rig_up();
    test_room();
    test_left_alone(SCENE_NO_VERTICALS, (float)FOCAL, "no vertical edges");
    test_left_alone(SCENE_MOTLEY_FLOOR, (float)FOCAL, "a floor of four colours");
    test_left_alone(SCENE_ROOM, 0, "no focal length");
    return test_summary("test_depth_ground");
}
