/* moving_mask.c - moving pixels from the colour distance to the temporal median (moving_mask.h). */
#include "depth/moving_mask.h"

#include <omp.h>
#include <stdlib.h>
#include <string.h>

#include "core/fileutil.h"
#include "depth/plane.h"

/* Pixels per block of the median pass: 16 RGB pixels are 48 bytes of one frame row, so a frame's
 * bytes of a block come in one or two cache lines instead of 48 strided reads. */
#define MOVING_BLOCK 16

/* The median of each of n byte channels over F frames by counting (the values are 8-bit, so a
 * 256-bin histogram is exact, O(F) without sorting); channel i of frame f is row(f)[i]. */
static void median_u8_block(const uint8_t *first, size_t frame_stride, int F, int n, int hist[][256], int *med)
{
    memset(hist, 0, (size_t)n * sizeof hist[0]);
    for (int f = 0; f < F; f++) {
        const uint8_t *row = first + (size_t)f * frame_stride;
        for (int i = 0; i < n; i++) hist[i][row[i]]++;
    }
    const int half = (F - 1) / 2;
    for (int i = 0; i < n; i++) {
        int acc = 0, b = 0;
        for (; b < 255; b++) {
            acc += hist[i][b];
            if (acc > half) break;
        }
        med[i] = b;
    }
}

pg_status depth_moving_masks(const uint8_t *rgb, int F, int W, int H, float thresh, int dilate, uint8_t *out)
{
    if (F < 1 || W < 1 || H < 1) return pg_fail(PG_ERR_ARG, "moving mask: empty video (%d frames of %dx%d)", F, W, H);
    const size_t px = (size_t)W * H;
    const float t = thresh * 255.0f; /* byte units: |difference| / 255 > thresh */
    const int nth = omp_get_max_threads();
    uint8_t *tmp = pg_malloc(px * (size_t)nth, "moving mask");
    if (!tmp) return PG_ERR_NOMEM;
#pragma omp parallel for schedule(static)
    for (long p0 = 0; p0 < (long)px; p0 += MOVING_BLOCK) {
        const int nb = (long)px - p0 < MOVING_BLOCK ? (int)((long)px - p0) : MOVING_BLOCK;
        int hist[MOVING_BLOCK * 3][256], med[MOVING_BLOCK * 3];
        median_u8_block(rgb + (size_t)p0 * 3, px * 3, F, nb * 3, hist, med);
        for (int f = 0; f < F; f++) {
            const uint8_t *v = rgb + ((size_t)f * px + (size_t)p0) * 3;
            for (int q = 0; q < nb; q++) {
                int moving = 0;
                for (int c = 0; c < 3; c++) moving |= (float)abs(v[3 * q + c] - med[3 * q + c]) > t;
                out[(size_t)f * px + (size_t)p0 + q] = (uint8_t)moving;
            }
        }
    }
    /* a frame per thread: a frame's own parallel rows were too short to pay for their forks (the
     * dilation was a quarter of loading a long clip's training set) */
    if (dilate > 0)
#pragma omp parallel for schedule(dynamic, 8) num_threads(nth)
        for (int f = 0; f < F; f++) {
            uint8_t *mine = tmp + px * (size_t)omp_get_thread_num();
            depth_mask_dilate(out + (size_t)f * px, W, H, dilate, mine);
            memcpy(out + (size_t)f * px, mine, px);
        }
    free(tmp);
    return PG_OK;
}
