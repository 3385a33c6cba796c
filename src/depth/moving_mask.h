/* moving_mask.h - which pixels of a static-camera video show something moving.
 *
 * A pixel is moving in frame f when its colour differs from that pixel's temporal median by
 * more than `thresh` in any channel; the mask is then dilated by `dilate` px (a disc). The
 * median is the background for any object that covers a pixel less than half of the time,
 * so this needs no depth and no flow: it is the definition `eval` scores the moving part
 * with, and the trainer uses it (with a lower threshold) to find where to spend capacity.
 *
 *   uint8_t *moving = malloc(F * W * H);
 *   PG_TRY(depth_moving_masks(rgb, F, W, H, 0.12f, 2, moving));   // rgb: (F, H, W, 3) uint8
 */
#ifndef PG_DEPTH_MOVING_MASK_H
#define PG_DEPTH_MOVING_MASK_H

#include <stdint.h>

#include "core/status.h"

/* rgb: (F, H, W, 3) uint8; out: (F, H, W) 1 = moving, 0 = not. thresh in [0, 1] units. */
pg_status depth_moving_masks(const uint8_t *rgb, int F, int W, int H, float thresh, int dilate, uint8_t *out);

#endif
