/* test_motion_regions.c - the boxes motion crops render: one per frame around all its movers,
 * a flickering speck neither a mover nor stretching the box, every mover inside, frames drawn
 * evenly, nothing to draw when nothing moves. */
#include <stdlib.h>
#include <string.h>

#include "testlib.h"
#include "train/motion_regions.h"

enum { W = 320, H = 192, F = 3 };

static void fill(uint8_t *m, int x0, int y0, int w, int h)
{
    for (int y = y0; y < y0 + h; y++)
        for (int x = x0; x < x0 + w; x++) m[y * W + x] = 1;
}

/* Whether pixel (x, y) lies in one of frame f's boxes. */
static int covered(const train_motion_regions *r, int f, int x, int y)
{
    for (int i = r->start[f]; i < r->start[f + 1]; i++) {
        const train_region *b = &r->boxes[i];
        if (x >= b->x && x < b->x + b->w && y >= b->y && y < b->y + b->h) return 1;
    }
    return 0;
}

int main(void)
{
    uint8_t *m = calloc((size_t)F * W * H, 1);
    /* frame 0: a person (20 x 40) on the left, a ball (12 x 12) on the right, one 5 x 5 speck */
    fill(m, 20, 30, 20, 40);
    fill(m, 120, 50, 12, 12);
    fill(m, 90, 5, 5, 5);
    /* frame 1: two movers a tile apart */
    fill(m + W * H, 20, 20, 16, 16);
    fill(m + W * H, 52, 20, 16, 16);
    /* frame 2: still */
    train_motion_regions r;
    CHECK_OK(train_motion_regions_find(m, F, W, H, &r));
    CHECK(r.frames_with_motion == 2, "%d frames with motion, want 2", r.frames_with_motion);
    CHECK(r.start[1] - r.start[0] == 1 && r.start[2] - r.start[1] == 1, "frames 0, 1: %d, %d boxes, want 1 each",
          r.start[1] - r.start[0], r.start[2] - r.start[1]);
    CHECK(r.start[3] == r.start[2], "frame 2 has boxes");
    int inside = 1;
    for (int y = 30; y < 70; y++)
        for (int x = 20; x < 40; x++) inside &= covered(&r, 0, x, y);
    for (int y = 50; y < 62; y++)
        for (int x = 120; x < 132; x++) inside &= covered(&r, 0, x, y);
    CHECK(inside, "a mover's pixel outside every box");
    CHECK(!covered(&r, 0, 92, 7) && !covered(&r, 0, 80, 150) && !covered(&r, 0, 250, 60),
          "frame 0's box reaches the speck, the floor below or the wall right of the movers");
    const train_region *b1 = &r.boxes[r.start[1]];
    CHECK(b1->x == 0 && b1->y == 0 && b1->w == 96 && b1->h == 64, "frame 1's box %d %d %d %d, want 0 0 96 64", b1->x,
          b1->y, b1->w, b1->h);
    for (int i = 0; i < r.start[F]; i++) {
        const train_region *b = &r.boxes[i];
        CHECK(b->x >= 0 && b->y >= 0 && b->x + b->w <= W && b->y + b->h <= H && b->w > 0 && b->h > 0,
              "box %d (%d %d %d %d) outside the frame", i, b->x, b->y, b->w, b->h);
    }
    double area = train_motion_regions_mean_area(&r);
    CHECK(area > 0.05 && area < 0.3, "mean area %.3f", area);

    /* draws: frames 0 and 1 evenly, never the still frame 2 */
    pg_rng rng;
    pg_rng_seed(&rng, 5);
    int per_frame[F] = {0};
    for (int k = 0; k < 4000; k++) {
        int f = -1;
        const train_region *b = train_motion_regions_draw(&r, &rng, &f);
        if (b && f >= 0 && f < F && b == &r.boxes[r.start[f]]) per_frame[f]++;
    }
    CHECK(per_frame[2] == 0 && per_frame[0] > 1850 && per_frame[1] > 1850, "frame draws %d %d %d", per_frame[0],
          per_frame[1], per_frame[2]);
    train_motion_regions_destroy(&r);

    /* nothing moves: nothing to draw */
    memset(m, 0, (size_t)F * W * H);
    CHECK_OK(train_motion_regions_find(m, F, W, H, &r));
    int f = -1;
    CHECK(r.frames_with_motion == 0 && train_motion_regions_draw(&r, &rng, &f) == NULL, "a still clip has crops");
    train_motion_regions_destroy(&r);
    free(m);
    return test_summary("test_motion_regions");
}
