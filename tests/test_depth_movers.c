/* test_depth_movers.c - moving blobs brought in front of the still scene (movers_front.h): a
 * blob the depth puts behind the wall it covers comes to the wall, whole, while the wall showing
 * through its ring keeps its depth; blobs in front, within the tolerance, too small or over an
 * unknown background stay; a one-frame flicker of the blob's depth takes its neighbours' factor. */
#include "testlib.h"
#include "depth/movers_front.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { W = 80, H = 60, F = 9, RING = 2 };
#define WALL 10.0f

typedef struct {
    float depth[F * W * H], before[F * W * H], background[W * H];
    unsigned char still[F * W * H]; /* 1 = still: everything but the mover and its ring */
    unsigned char inside[F * W * H]; /* 1 = the mover itself, 0 = ring or still scene */
} scene;

/* A wall at WALL everywhere; in frame f a 12 x 20 mover at x = 10 + 4f drawn at mover_depth(f),
 * its blob (not still) the mover plus a RING px ring where the wall shows. */
static void make_scene(scene *s, float (*mover_depth)(int f), int width, int height)
{
    for (int k = 0; k < W * H; k++) s->background[k] = WALL;
    for (int f = 0; f < F; f++) {
        int x0 = 10 + 4 * f, y0 = 20;
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++) {
                size_t k = (size_t)f * W * H + (size_t)y * W + x;
                int in = x >= x0 && x < x0 + width && y >= y0 && y < y0 + height;
                int near = x >= x0 - RING && x < x0 + width + RING && y >= y0 - RING && y < y0 + height + RING;
                s->inside[k] = (unsigned char)in;
                s->still[k] = (unsigned char)!near;
                s->depth[k] = in ? mover_depth(f) : WALL;
            }
    }
    memcpy(s->before, s->depth, sizeof s->depth);
}

static float behind(int f) { (void)f; return 15.0f; }
static float in_front(int f) { (void)f; return 5.0f; }
static float slightly_behind(int f) { (void)f; return 10.3f; }
static float flicker(int f) { return f == 4 ? 30.0f : 15.0f; }

static void check_unchanged(const scene *s, const char *what)
{
    CHECK(memcmp(s->depth, s->before, sizeof s->depth) == 0, "%s: the depth changed", what);
}

static void test_behind(const depth_movers_front_params *p)
{
    scene *s = malloc(sizeof *s);
    make_scene(s, behind, 12, 20);
    long moved = depth_movers_in_front(s->depth, s->still, s->background, F, W, H, p);
    CHECK(moved == F, "moved %ld blobs, want %d", moved, F);
    double worst_mover = 0, worst_wall = 0;
    for (size_t k = 0; k < (size_t)F * W * H; k++) {
        double err = fabs(s->depth[k] - (s->inside[k] ? WALL : s->before[k]));
        if (s->inside[k]) worst_mover = fmax(worst_mover, err);
        else worst_wall = fmax(worst_wall, err);
    }
    CHECK(worst_mover < 1e-4, "the mover is %.4g off the wall it stands against", worst_mover);
    CHECK(worst_wall == 0, "the wall around the mover moved by %.4g", worst_wall);
    free(s);
}

static void test_left_alone(const depth_movers_front_params *p)
{
    scene *s = malloc(sizeof *s);
    make_scene(s, in_front, 12, 20);
    CHECK(depth_movers_in_front(s->depth, s->still, s->background, F, W, H, p) == 0, "a blob in front moved");
    check_unchanged(s, "in front");

    make_scene(s, slightly_behind, 12, 20);
    CHECK(depth_movers_in_front(s->depth, s->still, s->background, F, W, H, p) == 0, "3 %% behind moved");
    check_unchanged(s, "within the tolerance");

    make_scene(s, behind, 2, 1); /* 6 x 5 px with its ring: under min_area */
    CHECK(depth_movers_in_front(s->depth, s->still, s->background, F, W, H, p) == 0, "a small blob moved");
    check_unchanged(s, "too small");

    make_scene(s, behind, 12, 20);
    memset(s->background, 0, sizeof s->background);
    CHECK(depth_movers_in_front(s->depth, s->still, s->background, F, W, H, p) == 0, "moved without a background");
    check_unchanged(s, "unknown background");
    free(s);
}

static void test_flicker(const depth_movers_front_params *p)
{
    scene *s = malloc(sizeof *s);
    make_scene(s, flicker, 12, 20);
    CHECK(depth_movers_in_front(s->depth, s->still, s->background, F, W, H, p) == F, "not every frame moved");
    size_t k4 = (size_t)4 * W * H + (size_t)25 * W + 28, k3 = (size_t)3 * W * H + (size_t)25 * W + 28;
    CHECK(s->inside[k4] && s->inside[k3], "test pixels off the mover");
    /* frame 4's own factor would be 1/3; its neighbours' 2/3 win the median */
    CHECK(fabsf(s->depth[k4] - 20.0f) < 1e-4f, "the flickered frame is at %.4g, want 30 x 2/3 = 20", s->depth[k4]);
    CHECK(fabsf(s->depth[k3] - WALL) < 1e-4f, "frame 3 is at %.4g, want the wall", s->depth[k3]);
    free(s);
}

int main(void)
{
    depth_movers_front_params p;
    depth_movers_front_defaults(&p, W, H);
    CHECK(p.min_area == 16 && p.window == 3, "defaults: min_area %d window %d", p.min_area, p.window);
    p.min_area = 40;
    test_behind(&p);
    test_left_alone(&p);
    test_flicker(&p);
    return test_summary("test_depth_movers");
}
