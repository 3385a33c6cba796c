/* view_scene.h - the viewer's 4D scene file (docs/FORMATS.md, "Viewer scene file").
 *
 * Static Gaussians are stored once; Gaussians that move get one record per time sample.
 * Everything is quantised: positions 16-bit in a bounding box, log-scales, rotations, colour,
 * opacity and higher SH 8-bit. Gaussians invisible at every time (opacity < 1/255) are dropped.
 *
 *   view_scene_source src = { .canonical = &g, .is_static = flags, .at_time = deform,
 *                             .ctx = model, .frames = 20, .fps = 30 };
 *   view_scene_stats st;
 *   PG_TRY(view_scene_write("viewer/scene.pgvs", &src, "{\"cameras\": []}", &st));
 */
#ifndef PG_VIEW_SCENE_H
#define PG_VIEW_SCENE_H

#include <stddef.h>
#include <stdint.h>

#include "splat/gaussians.h"

#define VIEW_SCENE_VERSION 1
#define VIEW_SCENE_HEADER_BYTES 128
#define VIEW_SCENE_MAX_FRAMES 10000

typedef struct {
    const pg_gaussians *canonical; /* every Gaussian; static rows are taken from here */
    const uint8_t *is_static;      /* (N) 1 = never moves; NULL: every Gaussian is static */
    /* Every Gaussian at time t into out (only the moving rows are read); NULL: all static. */
    pg_status (*at_time)(void *ctx, float t, pg_gaussians *out);
    void *ctx;
    int frames;          /* time samples K >= 1 at t_k = k / (K - 1) */
    int max_gaussians;   /* keep the N most visible (0: every visible one) */
    float fps;           /* playback rate of the samples */
    float background[3]; /* colour behind everything */
} view_scene_source;

typedef struct {
    int static_count, moving_count, frames, sh_degree;
    int dropped;  /* invisible at every time, or beyond max_gaussians */
    size_t bytes; /* file size */
} view_scene_stats;

/* Writes the scene file atomically; meta_json (cameras etc., see docs/FORMATS.md) is stored as
 * is. Fails with PG_ERR_ARG on a bad source, PG_ERR_IO on a write failure. */
pg_status view_scene_write(const char *path, const view_scene_source *src, const char *meta_json,
                           view_scene_stats *stats);

#endif
