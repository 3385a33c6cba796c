/* refine.h - edge-aware depth refinement guided by the RGB frame, behind a backend interface.
 *
 * Monocular depth is blurred across object boundaries: a band of pixels gets depths between the
 * foreground and the background, which later become "flying" Gaussians. Backends:
 *   DEPTH_REFINE_EDGE_SNAP (default): finds the blurred bands (large curvature of log-depth),
 *     then re-assigns each band pixel the colour-weighted median depth of nearby confident pixels
 *     (outside the band). The median picks one side of the edge - the side whose colour matches -
 *     instead of averaging across it, so discontinuities land on colour edges and flat or smoothly
 *     sloped regions are left untouched.
 *   DEPTH_REFINE_BILATERAL: classic joint bilateral filter (smooths noise; reference/baseline).
 *   DEPTH_REFINE_NONE: copy.
 * A neural refiner plugs in by filling a depth_refine_backend with its own function.
 *
 *   depth_refine_backend be = depth_refine_backend_get(DEPTH_REFINE_EDGE_SNAP);
 *   PG_TRY(depth_refine_run(&be, &rgb, depth_in, depth_out));   // (H,W) each, 0 = invalid
 */
#ifndef PG_DEPTH_REFINE_H
#define PG_DEPTH_REFINE_H

#include "core/image.h"

typedef enum {
    DEPTH_REFINE_NONE,
    DEPTH_REFINE_EDGE_SNAP,
    DEPTH_REFINE_BILATERAL,
    DEPTH_REFINE_COUNT
} depth_refine_kind;

/* depth_in, depth_out: (H,W) matching rgb; invalid pixels (<= 0, NaN) stay 0 in the output.
 * The depth stage calls it for one frame at a time (it may use threads inside). */
typedef pg_status (*depth_refine_fn)(void *ctx, const pg_image *rgb, const float *depth_in, float *depth_out);

typedef struct {
    const char *name;
    depth_refine_fn refine;
    void *ctx;           /* owned by the caller */
} depth_refine_backend;

typedef struct {
    int radius;          /* search window radius in px (default 9) */
    float sigma_color;   /* RGB distance scale (default 0.08) */
    float sigma_space;   /* px (default 4) */
    float edge_thresh;   /* log-depth second difference marking a blurred edge (default 0.03) */
    int band_radius;     /* dilation of the detected edge pixels into the band (default 1) */
    float guide_blur;    /* Gaussian sigma (px) on the RGB guide before colour weights (default 0) */
    float depth_weight;  /* width of the depth likelihood as a fraction of the local step (0.15; 0 = off) */
} depth_refine_params;

void depth_refine_defaults(depth_refine_params *p);
/* Backend of a built-in kind with the given params (NULL = defaults; must outlive the backend). */
depth_refine_backend depth_refine_backend_get(depth_refine_kind kind, const depth_refine_params *params);
/* Parses "edge-snap", "bilateral", "none"; returns DEPTH_REFINE_COUNT when unknown. */
depth_refine_kind depth_refine_kind_parse(const char *name);
const char *depth_refine_kind_name(depth_refine_kind kind);

pg_status depth_refine_run(const depth_refine_backend *be, const pg_image *rgb, const float *depth_in,
                           float *depth_out);

/* Uncertain band of the edge-snap backend (1 = blurred edge pixel), for visualisation/tests. */
pg_status depth_refine_band(const depth_refine_params *p, const float *depth, int width, int height,
                            unsigned char *band);

#endif
