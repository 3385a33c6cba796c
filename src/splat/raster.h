/* raster.h - differentiable tile-based Gaussian rasterizer (3DGS forward and backward).
 *
 *   splat_raster *r;
 *   splat_raster_create(&r);
 *   pg_render_settings s = splat_default_settings();
 *   splat_render_forward(r, &gaussians, &camera, &s, &out);     // out.rgb/depth/alpha
 *   ... loss gradients d_rgb (H,W,3), d_depth (H,W), d_alpha (H,W), any may be NULL ...
 *   splat_render_backward(r, &gaussians, &camera, &s, d_rgb, d_depth, d_alpha, &grads, grad2d);
 *   splat_raster_destroy(r);
 *
 * The rasterizer keeps what the backward needs (projected Gaussians, sorted tile lists,
 * per-pixel final transmittance and last contributor) from the latest forward call, so a
 * backward must follow the forward of the same Gaussians and camera.
 */
#ifndef PG_RASTER_H
#define PG_RASTER_H

#include "core/camera.h"
#include "splat/gaussians.h"

typedef struct {
    float background[3]; /* colour behind everything */
    float near_clip;     /* cull Gaussians with camera z below this (0.01) */
    int sh_degree;       /* -1: use the Gaussians' own sh_degree */
    /* NULL, or the whole camera when cam is a crop of it (its size, the principal point shifted
     * by the crop's corner): projection clamps and view-space gradient units follow the whole
     * image, so a crop renders exactly the whole image's pixels */
    const pg_camera *whole;
    /* focal length in pixels of the views the Gaussians were trained on (0: unknown). A camera
     * drawing finer than that (a render larger than the training size) gets a training pixel's
     * screen-space filter instead of its own pixel's (splat_lowpass_for) */
    float train_focal;
} pg_render_settings;

typedef struct {
    int width, height;
    float *rgb;   /* (H, W, 3) composited colour incl. background, owned by the rasterizer */
    float *depth; /* (H, W) expected depth sum_i z_i alpha_i T_i (not normalised by alpha) */
    float *alpha; /* (H, W) 1 - T_final */
    long intersections; /* tile-Gaussian pairs rendered (for benchmarks) */
    double preprocess_ms, forward_ms; /* timing of the last forward */
} pg_render_output;

typedef struct splat_raster splat_raster;

pg_render_settings splat_default_settings(void);
/* The screen-space filter's variance in squared pixels of cam: SPLAT_LOWPASS, times the square of
 * how many of cam's pixels one training pixel spans when that is above 1. Trained at one size,
 * each splat's footprint includes the filter of a training pixel; a larger render that shrank
 * the filter to its own pixel drew every small splat thinner and fainter than training fitted
 * it (the demo at 2x: 24.43 dB against 24.77 with the training pixel's filter; docs/viewer.md). */
float splat_lowpass_for(const pg_camera *cam, const pg_render_settings *s);
pg_status splat_raster_create(splat_raster **r);
void splat_raster_destroy(splat_raster *r);
/* Renders; out's buffers stay valid until the next forward or destroy. */
pg_status splat_render_forward(splat_raster *r, const pg_gaussians *g, const pg_camera *cam,
                               const pg_render_settings *s, pg_render_output *out);
/* Accumulates (+=) gradients w.r.t. every Gaussian parameter into grad (same count as g).
 * viewspace_grad_norm (N), if not NULL, gets += |dL/d(mean2D)| per Gaussian (densification),
 * measured in NDC units (pixel gradient * (W/2, H/2)) like 3DGS, so its 2e-4 threshold applies;
 * Gaussians culled in the forward get nothing. Deterministic: the same bytes for any thread
 * count. Fails (PG_ERR_ARG) if the latest forward was not of the same Gaussian count and size. */
pg_status splat_render_backward(splat_raster *r, const pg_gaussians *g, const pg_camera *cam,
                                const pg_render_settings *s, const float *d_rgb, const float *d_depth,
                                const float *d_alpha, pg_gaussians *grad, float *viewspace_grad_norm);

/* Tile and projection kernels, chosen at run time from the CPU (one binary for every x86-64 CPU):
 * AVX-512 (16 lanes, also the 16-wide projection), AVX2+FMA (8 lanes), or the scalar reference. A
 * new rasterizer takes the best the CPU has, or PG_RASTER=scalar|avx2|avx512 from the environment. */
typedef enum { SPLAT_KERNEL_SCALAR = 0, SPLAT_KERNEL_AVX2, SPLAT_KERNEL_AVX512, SPLAT_KERNELS } splat_kernel_kind;
int splat_kernel_supported(splat_kernel_kind k);
const char *splat_kernel_name(splat_kernel_kind k);
/* The default kernels (the best supported, or PG_RASTER's choice when the CPU has it). */
splat_kernel_kind splat_kernel_default(void);
/* Tests and benchmarks: use kernels k in r from now on (-1, nothing changed, if the CPU lacks them). */
int splat_raster_set_kernel(splat_raster *r, splat_kernel_kind k);
splat_kernel_kind splat_raster_kernel(const splat_raster *r);

#endif
