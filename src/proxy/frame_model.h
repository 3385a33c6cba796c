/* frame_model.h - the per-frame model of one RGB-D frame that renders proxy views (paper §3.2).
 *
 * Two renderers (proxy_fit_options.render):
 *  - PROXY_RENDER_MESH (default): the frame's depth map as a triangle mesh over the pixel centres
 *    (triangles across depth edges dropped, mask.h), colours interpolated perspective-correctly,
 *    z-buffered. Exact on planar surfaces and at the source view, no fitting.
 *  - PROXY_RENDER_SPLAT (the paper's): one Gaussian per pixel, briefly fitted to the source view,
 *    splatted. Measured on tabletop_dev (GT depth, dataset cameras 7-21 degrees away): its texture
 *    lands 0.25-0.4 px off at every proxy camera, the direction following the camera's side - overlapping
 *    Gaussians of one surface composite front to back, so whichever neighbour sorts first wins the
 *    shared pixels - which costs 1.4-2.4 dB and 0.035-0.065 SSIM against the mesh (docs/proxy.md).
 *
 *   proxy_frame_model *m;
 *   proxy_fit_options o = proxy_default_fit_options();
 *   proxy_model_create(&m, W, H, &o);                       // one per worker, reused across frames
 *   for each frame:
 *       proxy_model_init(m, &real_cam, rgb, depth);         // margin; SPLAT: one Gaussian per pixel
 *       proxy_model_fit(m);                                 // SPLAT: ~50 Adam steps on the source view
 *       for each proxy camera:
 *           proxy_model_render(m, &cam, rgb, depth, mask);  // RGB, depth/alpha, validity mask
 *   proxy_model_destroy(m);
 *
 * depth is in the pose units of the cameras (already multiplied by any pose scale), 0 = invalid.
 * With opt.pad > 0 the model also covers an outpainted margin around the frame (SPLAT: one Gaussian
 * per 4k x 4k block there, not fitted), so proxies turned away from the real view have no empty borders.
 */
#ifndef PG_PROXY_FRAME_MODEL_H
#define PG_PROXY_FRAME_MODEL_H

#include "core/camera.h"
#include "core/status.h"
#include "proxy/mask.h"

typedef enum { PROXY_RENDER_MESH, PROXY_RENDER_SPLAT } proxy_render_kind;

typedef struct {
    proxy_render_kind render; /* MESH (default) or SPLAT; block .. lr_color apply to SPLAT only */
    int block;            /* k: one Gaussian per k x k pixel block (1) */
    int steps;            /* Adam steps on the source view (50) */
    float ssim_weight;    /* weight of D-SSIM against L1 (0.2) */
    int ssim_every;       /* D-SSIM (forward + backward) only every k-th step and the last; L1 alone between (8) */
    float depth_weight;   /* weight of the relative depth L1 term (0.1) */
    float init_opacity;   /* initial opacity (0.8; higher gave lower proxy PSNR) */
    float scale_mult;     /* initial std = scale_mult * k * depth / f (0.6) */
    int surfels;          /* 1: flat Gaussians in the depth map's tangent plane (1); 0: isotropic */
    float surfel_thickness; /* surfel std along the normal, relative to the in-plane std (0.2) */
    float lr_means;       /* mean learning rate relative to the median depth (2e-5) */
    float lr_scales, lr_opacity, lr_color; /* Adam learning rates (0.005, 0.02, 0.005) */
    float pad;            /* margin added on each side by outpainting (outpaint.h), as a fraction of
                           * the larger frame side (0.3); 0 = proxies end at the real frame's border */
    proxy_mask_options mask;
} proxy_fit_options;

typedef struct {
    double init_s, fit_s, render_s; /* accumulated wall time of each phase */
    float first_loss, last_loss;    /* loss of the first and last fit step of the latest frame */
    float source_psnr;              /* PSNR of the fitted model at the source view (latest frame; SPLAT) */
    int gaussians;                  /* Gaussians of the latest frame */
} proxy_model_stats;

typedef struct proxy_frame_model proxy_frame_model;

proxy_fit_options proxy_default_fit_options(void);

/* Allocates a model for frames of width x height (the worst case: every pixel valid). */
pg_status proxy_model_create(proxy_frame_model **m, int width, int height, const proxy_fit_options *o);
void proxy_model_destroy(proxy_frame_model *m);

/* Takes one RGB-D frame: rgb (H,W,3), depth (H,W); outpaints the margin and (SPLAT) seeds the
 * Gaussians. Fails (PG_ERR_ARG) when no pixel has valid depth. */
pg_status proxy_model_init(proxy_frame_model *m, const pg_camera *cam, const float *rgb, const float *depth);

/* SPLAT: runs the Adam steps on the source view (L1 + D-SSIM + depth). MESH: nothing to fit. */
pg_status proxy_model_fit(proxy_frame_model *m);

/* Renders a view: rgb (H',W',3), depth (H',W') (SPLAT: normalised by alpha; 0 where invalid), mask
 * (H',W') (mask.h values); any output may be NULL. The view may differ in size from the source.
 * valid_fraction (may be NULL) receives the masked fraction. */
pg_status proxy_model_render(proxy_frame_model *m, const pg_camera *view, float *rgb, float *depth,
                             unsigned char *mask, float *valid_fraction);

const proxy_model_stats *proxy_model_get_stats(const proxy_frame_model *m);

#endif
