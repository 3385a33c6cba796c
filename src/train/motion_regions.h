/* motion_regions.h - where the real view moves, frame by frame, as boxes for the trainer's
 * motion crops (a crop renders the real view over one box only).
 *
 *   train_motion_regions r;
 *   PG_TRY(train_motion_regions_find(moving, frames, W, H, &r));   // moving: (F, H, W) 0/1
 *   int f;
 *   const train_region *b = train_motion_regions_draw(&r, &rng, &f); // NULL: nothing moves
 *   train_motion_regions_destroy(&r);
 */
#ifndef PG_TRAIN_MOTION_REGIONS_H
#define PG_TRAIN_MOTION_REGIONS_H

#include <stdint.h>

#include "core/rng.h"
#include "core/status.h"

/* Tiles of this many pixels a side are counted; a tile with at least TRAIN_REGION_TILE_MIN
 * moving pixels is part of a mover (a lone flickering pixel, dilated to 5 x 5, stays below it). */
#define TRAIN_REGION_TILE 16
#define TRAIN_REGION_TILE_MIN 26

typedef struct {
    int x, y, w, h; /* pixels */
    int moving;     /* moving pixels inside: the box's share of the draws */
} train_region;

typedef struct {
    int frames, width, height;
    int *start;            /* (frames + 1): frame f's boxes are boxes[start[f] .. start[f + 1]) */
    train_region *boxes;
    int frames_with_motion;
} train_motion_regions;

pg_status train_motion_regions_find(const uint8_t *moving, int frames, int width, int height, train_motion_regions *r);
void train_motion_regions_destroy(train_motion_regions *r);
/* A frame with motion (uniformly) and one of its boxes (in proportion to its moving pixels;
 * today one box per frame holds all its movers). */
const train_region *train_motion_regions_draw(const train_motion_regions *r, pg_rng *rng, int *frame);
/* Frame f's largest box (by moving pixels), NULL if nothing moves there. */
const train_region *train_motion_regions_at(const train_motion_regions *r, int f);
/* Mean share of a frame with motion that its boxes cover. */
double train_motion_regions_mean_area(const train_motion_regions *r);

#endif
