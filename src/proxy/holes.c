/* holes.c - background-side filling of disocclusion holes (see holes.h). */
#include "proxy/holes.h"

#include <math.h>
#include <string.h>

#define SAME_SURFACE 0.04f /* relative depth step below which both ends are one surface */

/* One line of pixels (a row or a column) seen through a stride. valid marks the pixels that may
 * end a run (observed, not filled). */
static long fill_line(int n, long stride, float *rgb, float *depth, unsigned char *mask, const unsigned char *valid,
                      int max_run, unsigned char weight)
{
    long filled = 0;
    int i = 0;
    while (i < n) {
        if (mask[i * stride]) { i++; continue; }
        int a = i;
        while (i < n && !mask[i * stride]) i++;
        int b = i; /* hole run [a, b) */
        if (a == 0 || b == n || b - a > max_run || !valid[(a - 1) * stride] || !valid[b * stride]) continue;
        long l = (long)(a - 1) * stride, r = (long)b * stride;
        float dl = depth[l], dr = depth[r];
        if (!(dl > 0 && dr > 0)) continue;
        int same = fabsf(dl - dr) <= SAME_SURFACE * fminf(dl, dr);
        /* the background end, one pixel further out when that pixel is on the same surface (the
         * end pixel itself may carry the foreground's blended fringe) */
        long src = dl > dr ? l : r;
        long further = dl > dr ? l - stride : r + stride;
        int in_range = dl > dr ? a - 2 >= 0 : b + 1 < n;
        if (!same && in_range && valid[further] && fabsf(depth[further] - depth[src]) <= SAME_SURFACE * depth[src])
            src = further;
        for (int k = a; k < b; k++) {
            long p = (long)k * stride;
            float t = (float)(k - a + 1) / (float)(b - a + 1);
            for (int c = 0; c < 3; c++)
                rgb[3 * p + c] = same ? (1 - t) * rgb[3 * l + c] + t * rgb[3 * r + c] : rgb[3 * src + c];
            depth[p] = same ? (1 - t) * dl + t * dr : depth[src];
            mask[p] = weight;
            filled++;
        }
    }
    return filled;
}

long proxy_fill_holes(int width, int height, float *rgb, float *depth, unsigned char *mask, int max_run,
                      unsigned char weight, unsigned char *scratch)
{
    if (weight == 0) return 0;
    const size_t n = (size_t)width * height;
    for (size_t i = 0; i < n; i++) scratch[i] = mask[i] != 0;
    long filled = 0;
    for (int y = 0; y < height; y++) {
        size_t o = (size_t)y * width;
        filled += fill_line(width, 1, rgb + 3 * o, depth + o, mask + o, scratch + o, max_run, weight);
    }
    /* the column pass may end its runs on the row pass's guesses: a hole under a wide object has
     * no observed pixel above it, only the background the row pass carried in */
    for (size_t i = 0; i < n; i++) scratch[i] = mask[i] != 0;
    for (int x = 0; x < width; x++)
        filled += fill_line(height, width, rgb + 3 * (size_t)x, depth + x, mask + x, scratch + x, max_run, weight);
    return filled;
}
