/* test_proxy_holes.c - disocclusion holes of a proxy view take the background side's colour and
 * depth at the margin weight; holes at the border, long runs and invalid ends stay holes. */
#include "testlib.h"
#include "proxy/holes.h"

#include <math.h>
#include <string.h>

enum { W = 24, H = 12 };
static float rgb[H * W * 3], depth[H * W];
static unsigned char mask[H * W], scratch[H * W];

static void paint(int x, int y, float r, float g, float b, float d, unsigned char m)
{
    float *p = rgb + 3 * (y * W + x);
    p[0] = r, p[1] = g, p[2] = b;
    depth[y * W + x] = d;
    mask[y * W + x] = m;
}

int main(void)
{
    /* background wall (red, depth 5) with a near box (blue, depth 2) from x = 14; the proxy lost
     * the wall strip x = 10..13 of rows 2..5 behind the box */
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            paint(x, y, x < 14 ? 1.0f : 0.0f, 0.0f, x < 14 ? 0.0f : 1.0f, x < 14 ? 5.0f : 2.0f, 255);
    for (int y = 2; y <= 5; y++)
        for (int x = 10; x < 14; x++) paint(x, y, 0, 0, 0, 0, 0);
    /* a hole inside the wall between two wall pixels of different shade: blended */
    paint(3, 8, 0.2f, 0.0f, 0.0f, 5.0f, 255);
    paint(4, 8, 0, 0, 0, 0, 0);
    paint(5, 8, 0, 0, 0, 0, 0);
    paint(6, 8, 0.8f, 0.0f, 0.0f, 5.0f, 255);
    /* a hole touching the left border in row 10 only: the column pass fills it from rows 9 and 11 */
    paint(0, 10, 0, 0, 0, 0, 0);
    paint(1, 10, 0, 0, 0, 0, 0);
    /* a whole row 0 hole from x = 0 .. 23 touching the border, with row 1 invalid below: stays */
    for (int x = 0; x < W; x++) paint(x, 0, 0, 0, 0, 0, 0), paint(x, 1, 0, 0, 0, 0, 0);

    long filled = proxy_fill_holes(W, H, rgb, depth, mask, 6, 128, scratch);
    int wall_ok = 1;
    for (int y = 2; y <= 5; y++)
        for (int x = 10; x < 14; x++) {
            const float *p = rgb + 3 * (y * W + x);
            wall_ok &= mask[y * W + x] == 128 && p[0] == 1.0f && p[2] == 0.0f && depth[y * W + x] == 5.0f;
        }
    CHECK(wall_ok, "the strip behind the box must take the wall (red, depth 5) at weight 128");
    float r4 = rgb[3 * (8 * W + 4)], r5 = rgb[3 * (8 * W + 5)];
    CHECK(mask[8 * W + 4] == 128 && fabsf(r4 - 0.4f) < 1e-6f && fabsf(r5 - 0.6f) < 1e-6f,
          "one surface on both ends: blended, got %g %g", r4, r5);
    CHECK(mask[10 * W + 0] == 128 && mask[10 * W + 1] == 128 && depth[10 * W + 1] == 5.0f, "column pass at the border");
    int top_kept = 1;
    for (int x = 0; x < W; x++) top_kept &= mask[x] == 0 && mask[W + x] == 0;
    CHECK(top_kept, "holes without a valid end on both sides must stay holes");
    CHECK(filled == 16 + 2 + 2, "filled %ld pixels, want 20", filled);

    /* a run longer than max_run stays a hole */
    memset(mask, 255, sizeof mask);
    for (int x = 3; x < 20; x++) mask[6 * W + x] = 0;
    for (int y = 0; y < H; y++) /* no vertical help: the column pass sees holes at the border */
        for (int x = 3; x < 20; x++)
            if (y != 6) mask[y * W + x] = y < 6 ? 255 : 0;
    for (int i = 0; i < W * H; i++) depth[i] = 3.0f;
    filled = proxy_fill_holes(W, H, rgb, depth, mask, 6, 128, scratch);
    CHECK(filled == 0, "a 17-pixel run with max_run 6 was filled (%ld pixels)", filled);
    return test_summary("test_proxy_holes");
}
