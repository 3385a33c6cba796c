/* flow.h - dense optical flow between two frames behind a swappable backend.
 *
 * The flow maps frame 0 pixels into frame 1: for a pixel centre x in img0,
 * img0(x) ~ img1(x + flow(x)). Flow buffers are (H, W, 2) float, (dx, dy) in pixels.
 *
 *   float *f01 = ..., *f10 = ..., *conf = ...;            // (H,W,2), (H,W,2), (H,W)
 *   depth_flow_backend be = depth_flow_backend_default();
 *   PG_TRY(depth_flow_compute(&be, &frame0, &frame1, f01));
 *   PG_TRY(depth_flow_compute(&be, &frame1, &frame0, f10));
 *   depth_flow_consistency(f01, f10, W, H, conf);         // 1 = consistent, 0 = occluded
 *
 * The built-in backend is a coarse-to-fine TV-L1 flow (Zach, Pock & Bischof 2007, in the
 * formulation of Sanchez, Meinhardt-Llopis & Facciolo, IPOL 2013) with bicubic warping and a
 * median filter between warps. A learned flow network plugs in by filling a depth_flow_backend
 * with its own compute function.
 */
#ifndef PG_DEPTH_FLOW_H
#define PG_DEPTH_FLOW_H

#include "core/image.h"

/* Computes flow (H,W,2) from img0 to img1 (same size, 1 or 3 channels, values in [0,1]).
 * Must be safe to call concurrently from several threads (the depth stage computes the flows of
 * different frames in parallel); on failure it records a message with pg_fail. */
typedef pg_status (*depth_flow_fn)(void *ctx, const pg_image *img0, const pg_image *img1, float *flow);

typedef struct {
    const char *name;   /* "tvl1", or the name of a plugged-in network */
    depth_flow_fn compute;
    void *ctx;          /* owned by the caller; passed to compute */
} depth_flow_backend;

/* TV-L1 settings; depth_flow_tvl1_defaults() fills the tested values. */
typedef struct {
    float lambda;    /* data attachment weight (intensities scaled to [0,255]) */
    float theta;     /* coupling between the TV and data sub-problems */
    float tau;       /* dual step (<= 0.25 for convergence) */
    int scales;      /* pyramid levels (coarsest side is kept >= 16 px) */
    int warps;       /* re-linearisations per level */
    int iterations;  /* inner primal-dual iterations per warp */
    int median;      /* 1: 3x3 median filter on the flow after each warp */
} depth_flow_tvl1_params;

void depth_flow_tvl1_defaults(depth_flow_tvl1_params *p);
/* A backend using params (NULL ctx = defaults); params must outlive the backend. */
depth_flow_backend depth_flow_backend_tvl1(const depth_flow_tvl1_params *params);
/* The default backend (TV-L1 with default settings). */
depth_flow_backend depth_flow_backend_default(void);

/* Runs the backend after checking that both images have the same size. */
pg_status depth_flow_compute(const depth_flow_backend *be, const pg_image *img0, const pg_image *img1,
                             float *flow);

/* Forward-backward check: conf (H,W) in [0,1] is exp(-e^2 / (2 s^2)) with e the length of
 * f01(x) + f10(x + f01(x)) and s = 0.5 + 0.05 * (|f01| + |f10|); 0 where x + f01 leaves the image. */
void depth_flow_consistency(const float *f01, const float *f10, int width, int height, float *conf);

/* Mean end-point error between two flows over pixels with mask > 0.5 (all if mask is NULL). */
double depth_flow_epe(const float *flow, const float *truth, int width, int height, const float *mask);

/* Colour-wheel visualisation (Middlebury style): hue = direction, saturation = |flow| / max_mag
 * (max_mag <= 0: the 99th percentile magnitude). out must be an RGB image of the flow's size. */
void depth_flow_to_color(const float *flow, int width, int height, float max_mag, pg_image *out);

#endif
