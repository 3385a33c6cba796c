/* moving_mask.c - moving pixels from the colour distance to the temporal median (moving_mask.h). */
#include "depth/moving_mask.h"

#include <stdlib.h>
#include <string.h>

#include "core/fileutil.h"
#include "depth/plane.h"

/* Median of n bytes by counting: the values are 8-bit, so a 256-bin histogram is exact and
 * costs O(n) without sorting. */
static int median_u8(const uint8_t *v, int n, int stride)
{
    int hist[256] = {0};
    for (int i = 0; i < n; i++) hist[v[(size_t)i * stride]]++;
    int half = (n - 1) / 2, acc = 0;
    for (int b = 0; b < 256; b++) {
        acc += hist[b];
        if (acc > half) return b;
    }
    return 255;
}

pg_status depth_moving_masks(const uint8_t *rgb, int F, int W, int H, float thresh, int dilate, uint8_t *out)
{
    if (F < 1 || W < 1 || H < 1) return pg_fail(PG_ERR_ARG, "moving mask: empty video (%d frames of %dx%d)", F, W, H);
    const size_t px = (size_t)W * H;
    const float t = thresh * 255.0f; /* byte units: |difference| / 255 > thresh */
    uint8_t *tmp = pg_malloc(px, "moving mask");
    if (!tmp) return PG_ERR_NOMEM;
#pragma omp parallel for schedule(static)
    for (long p = 0; p < (long)px; p++) {
        int med[3];
        for (int c = 0; c < 3; c++) med[c] = median_u8(rgb + (size_t)p * 3 + c, F, (int)(px * 3));
        for (int f = 0; f < F; f++) {
            const uint8_t *v = rgb + ((size_t)f * px + (size_t)p) * 3;
            int moving = 0;
            for (int c = 0; c < 3; c++) moving |= (float)abs(v[c] - med[c]) > t;
            out[(size_t)f * px + (size_t)p] = (uint8_t)moving;
        }
    }
    if (dilate > 0)
        for (int f = 0; f < F; f++) {
            depth_mask_dilate(out + (size_t)f * px, W, H, dilate, tmp);
            memcpy(out + (size_t)f * px, tmp, px);
        }
    free(tmp);
    return PG_OK;
}
