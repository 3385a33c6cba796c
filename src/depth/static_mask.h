/* static_mask.h - which pixels of frame i show the same static surface as the reference frame.
 *
 * The camera does not move, so a pixel is static when the flow between frame i and the
 * reference is small, the colours agree, and the flow passes the forward-backward check.
 * Each cue gives a soft "dynamic" probability; they combine as independent evidence
 * p = 1 - (1 - o p_motion)(1 - p_colour), p_motion = 1 - (1 - p_flow)(1 - p_occlusion), where o
 * says how observable motion is at the pixel (its local image gradient in either frame): on a
 * flat surface the flow is the solver's smoothness filling in a passer-by's motion, not a
 * measurement, and only the colour can tell. The binary mask (1 = static) is p < 0.5 cleaned
 * with a morphological opening and closing of the dynamic region.
 */
#ifndef PG_DEPTH_STATIC_MASK_H
#define PG_DEPTH_STATIC_MASK_H

#include "core/image.h"

typedef struct {
    float flow_thresh;   /* px: |flow| at which p_flow = 0.5 (default 0.6) */
    float color_thresh;  /* mean absolute RGB difference at which p_colour = 0.5 (default 0.05) */
    float color_blur;    /* Gaussian sigma applied to both frames before differencing (default 1) */
    float texture_thresh; /* local mean |gradient| of the blurred grey frame (per px, intensities
                           * in [0,1]) at which the flow and occlusion cues count half (default
                           * 0.004; <= 0: they count everywhere) */
    int open_radius;     /* removes dynamic specks smaller than this (default 1) */
    int close_radius;    /* fills holes in dynamic regions (default 2) */
    int dilate_radius;   /* extra safety margin around dynamic regions (default 0) */
} depth_static_params;

void depth_static_defaults(depth_static_params *p);

/* What every frame's mask needs of the reference frame, made once per clip: its blurred colour
 * planes and, with the texture gate on, its texture map. */
typedef struct {
    int width, height, channels; /* channels: 3 (RGB) or 1 (grey) */
    float *blurred;              /* channels planes of (H,W) */
    float *texture;              /* (H,W); NULL when p->texture_thresh <= 0 */
} depth_mask_reference;

/* img_ref: the reference frame (RGB or grey in [0,1]); p: the parameters the masks will use. */
pg_status depth_mask_reference_create(const depth_static_params *p, const pg_image *img_ref,
                                        depth_mask_reference *ref);
void depth_mask_reference_free(depth_mask_reference *ref);

/* img_i: frame i (the reference's size and channels); flow_i: (H,W,2) from frame i to the
 * reference; conf_i: (H,W) forward-backward confidence of flow_i (NULL: not used).
 * Outputs prob (H,W) dynamic probability (may be NULL) and mask (H,W) 1 = static, 0 = dynamic. */
pg_status depth_static_mask(const depth_static_params *p, const pg_image *img_i, const depth_mask_reference *ref,
                            const float *flow_i, const float *conf_i, float *prob, unsigned char *mask);

/* Intersection over union of the 1-pixels of two (n) masks (1 when both are empty). */
double depth_mask_iou(const unsigned char *a, const unsigned char *b, size_t n);

#endif
