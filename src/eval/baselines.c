/* baselines.c - the 2.5D warp yardstick (the flat and as-is ones need no code of their own). */
#include "eval/baselines.h"

#include <stdlib.h>
#include <string.h>

#include "proxy/poses.h"

const char *const eval_baseline_names[EVAL_BASELINES] = { "flat", "as_is", "warp" };

/* One pass of crack filling: each empty pixel with at least 4 filled 8-neighbours (the cracks of a
 * magnifying nearest-pixel warp) takes the colour and depth of the farthest one. Wider holes are
 * left to fill_rows: dilating them would grow an occluder's edge into what it uncovered. Returns
 * the pixels filled. */
static size_t dilate_far(float *rgb, float *z, float *z_next, int W, int H)
{
    size_t filled = 0;
    memcpy(z_next, z, (size_t)W * H * sizeof(float));
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            size_t o = (size_t)y * W + x;
            if (z[o] > 0) continue;
            long best = -1;
            float bz = 0;
            int around = 0;
            for (int dy = -1; dy <= 1; dy++)
                for (int dx = -1; dx <= 1; dx++) {
                    int xx = x + dx, yy = y + dy;
                    if (xx < 0 || yy < 0 || xx >= W || yy >= H) continue;
                    size_t q = (size_t)yy * W + xx;
                    around += z[q] > 0;
                    if (z[q] > bz) bz = z[q], best = (long)q;
                }
            if (best < 0 || around < 4) continue;
            memcpy(rgb + 3 * o, rgb + 3 * (size_t)best, 3 * sizeof(float));
            z_next[o] = bz;
            filled++;
        }
    memcpy(z, z_next, (size_t)W * H * sizeof(float));
    return filled;
}

/* What crack filling left (disocclusions, the parts past the real frame's border): the farther of
 * the nearest filled pixels to the left and right on the row, i.e. the background beside the hole.
 * left: W longs of scratch. */
static void fill_rows(float *rgb, const float *z, int W, int H, const float fill[3], long *left)
{
    for (int y = 0; y < H; y++) {
        const float *zr = z + (size_t)y * W;
        float *row = rgb + (size_t)y * W * 3;
        long last = -1;
        for (int x = 0; x < W; x++) {
            if (zr[x] > 0) last = x;
            left[x] = last;
        }
        long right = -1;
        for (int x = W - 1; x >= 0; x--) {
            if (zr[x] > 0) {
                right = x;
                continue;
            }
            long l = left[x], src = l < 0 ? right : right < 0 ? l : (zr[l] >= zr[right] ? l : right);
            memcpy(row + 3 * x, src < 0 ? fill : row + 3 * src, 3 * sizeof(float));
        }
    }
}

pg_status eval_warp_baseline(const pg_camera *real, const float *rgb, const float *depth, const pg_camera *dst,
                             const float fill[3], float *out)
{
    int W = dst->width, H = dst->height;
    size_t n = (size_t)W * H;
    float *z = pg_malloc(2 * n * sizeof(float), "warp baseline depth");
    long *left = pg_malloc((size_t)W * sizeof(long), "warp baseline rows");
    if (!z || !left) {
        free(z);
        free(left);
        return PG_ERR_NOMEM;
    }
    pg_status st = proxy_forward_warp(real, rgb, depth, 1.0f, dst, out, z);
    for (int pass = 0; st == PG_OK && pass < 2 && dilate_far(out, z, z + n, W, H) > 0; pass++) {}
    if (st == PG_OK) fill_rows(out, z, W, H, fill, left);
    free(z);
    free(left);
    return st;
}
