/* prepare.h - the depth preparation stage (paper 3.1): refine, static masks, temporal alignment.
 *
 * For each frame i: edge-aware refinement of D_i guided by RGB_i; optical flow between frame i
 * and the reference frame (frame 0) in both directions; static mask B_i from flow, colour and the
 * forward-backward check; robust (alpha_i, beta_i) with alpha_i R_i + beta_i ~ R_ref on B_i;
 * output D'_i = alpha_i R_i + beta_i (0 = invalid); then every pixel static in enough frames takes
 * its temporal median in those frames (fuse.h: one depth per static surface), and static depth
 * near one of the scene's dominant planes takes the plane's (scene_planes.h).
 *
 *   depth_prepare_options opt;
 *   depth_prepare_defaults(&opt);
 *   depth_prepare_result res;
 *   PG_TRY(depth_prepare_run(&opt, frames, F, depth, &res));  // frames: F RGB images, depth (F,H,W)
 *   PG_TRY(depth_prepare_write("out", &opt, &res, frames, "{\"input\": ...}"));
 *   depth_prepare_result_destroy(&res);
 *
 * Documented fallbacks (never a crash):
 *  - a single frame: no flow, mask all static, alpha = 1, beta = 0 (refinement still runs);
 *  - a frame with (almost) no valid depth (all NaN/0, fewer than min_valid_fraction): its output
 *    is a copy of the nearest earlier valid frame's aligned depth (later one if none earlier),
 *    `fallback: "copied"` and `source_frame` in the report; if frame 0 is such a frame the first
 *    valid frame becomes the reference; if no frame is valid the stage fails (PG_ERR_ARG);
 *  - too few static pixels to fit (everything moves): fit on all valid pixels (the robust fit
 *    treats moving parts as outliers), `fallback: "all_pixels"`; if that fails too: identity.
 */
#ifndef PG_DEPTH_PREPARE_H
#define PG_DEPTH_PREPARE_H

#include "core/image.h"
#include "depth/align.h"
#include "depth/flow.h"
#include "depth/ground.h"
#include "depth/movers_front.h"
#include "depth/refine.h"
#include "depth/scene_planes.h"
#include "depth/static_mask.h"

typedef struct {
    depth_refine_kind refine;        /* built-in refiner (default EDGE_SNAP; NONE for --no-refine) */
    const depth_refine_backend *refiner; /* if set, replaces the built-in kind (neural refiner) */
    const depth_flow_backend *flow;  /* NULL = built-in TV-L1 */
    int align;                       /* 0: alpha = 1, beta = 0 for every frame (--no-align) */
    int fuse_static;                 /* 1: static pixels take their temporal median (fuse.h; --no-fuse) */
    int ground;                      /* 1: the floor and the wall placed by the vertical vanishing point
                                        (ground.h; needs ground_params.focal; --no-ground) */
    int snap_planes;                 /* 1: static depth snapped onto dominant planes (scene_planes.h; --no-planes) */
    int movers_front;                /* 1: moving blobs behind the still scene brought in front (movers_front.h;
                                        --no-movers-front) */
    int keep_flow;                   /* 1: result.flow holds the flow of every frame (for vis) */
    float min_valid_fraction;        /* below this a frame counts as invalid (default 0.01) */
    depth_refine_params refine_params;
    depth_static_params static_params;
    depth_align_params align_params;
    depth_ground_params ground_params;
    depth_scene_planes_params planes_params;
    depth_movers_front_params movers_params; /* min_area 0: the image size's default */
} depth_prepare_options;

typedef enum { DEPTH_FALLBACK_NONE, DEPTH_FALLBACK_COPIED, DEPTH_FALLBACK_ALL_PIXELS, DEPTH_FALLBACK_IDENTITY } depth_fallback;

typedef struct {
    double alpha, beta;
    double resid_before, resid_after;  /* median relative residual vs the reference on the mask */
    long invalid_in;                   /* invalid input depth pixels (NaN, inf, <= 0) */
    long invalid_out;                  /* zeros in the output frame */
    long static_pixels;                /* pixels in the static mask */
    long fit_pixels, fit_inliers;
    int shift_fitted;
    depth_fallback fallback;
    int source_frame;                  /* frame whose depth was copied (fallback COPIED), else i */
} depth_prepare_frame;

typedef struct {
    int frames, width, height, reference;
    float *depth;                 /* (F,H,W) aligned, refined depth, 0 = invalid */
    unsigned char *static_masks;  /* (F,H,W) 1 = static against the reference */
    float *dynamic_prob;          /* (F,H,W) */
    float *flow;                  /* (F,H,W,2) frame i -> reference, only with keep_flow */
    depth_prepare_frame *info;    /* (F) */
    long fused_pixels;            /* pixels given their temporal median (fuse_static) */
    long movers_moved;            /* moving blobs brought in front of the still scene, over all frames */
    depth_ground_result ground;   /* the floor and wall placed (ground) */
    depth_scene_planes_result planes; /* dominant planes found (snap_planes) */
    signed char *plane_label;     /* (H,W) plane index of each pixel, -1 none (snap_planes) */
    double seconds_refine, seconds_flow, seconds_align, seconds_total;
} depth_prepare_result;

void depth_prepare_defaults(depth_prepare_options *opt);

/* frames: num_frames RGB images of one size; depth: (num_frames, H, W) matching them.
 * Reports progress as stage "prepare". res is zeroed on failure. */
pg_status depth_prepare_run(const depth_prepare_options *opt, const pg_image *frames, int num_frames,
                            const float *depth, depth_prepare_result *res);
void depth_prepare_result_destroy(depth_prepare_result *res);

/* Writes dir/depth_aligned.npy, dir/static_masks.npy, dir/dynamic_prob.npy, dir/prepare.json and dir/vis/ PNGs
 * (depth_NNNN, mask_NNNN, flow_NNNN when flow was kept, input_depth_NNNN when input is given; at
 * most 60 evenly spaced frames of each). Depth and probability maps are float16 when they fit.
 * source_json: a JSON object text merged into prepare.json as "source" (may be NULL).
 * input_depth: the raw (F,H,W) input for the before/after pictures (may be NULL). */
pg_status depth_prepare_write(const char *dir, const depth_prepare_options *opt, const depth_prepare_result *res,
                              const pg_image *frames, const float *input_depth, const char *source_json);

/* Colour-maps depth (H,W) into an RGB image (near = bright yellow, far = dark purple, invalid =
 * black) over [lo, hi] in inverse depth. */
void depth_to_color(const float *depth, int width, int height, float lo, float hi, pg_image *out);

#endif
