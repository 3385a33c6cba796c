/* scene_planes.h - dominant planes of the static scene, and static depth snapped onto them.
 *
 * A monocular network bends flat surfaces: its error is a smooth multiplicative field (a few
 * percent) that a per-frame scale/shift cannot remove and a static camera gives no parallax to
 * correct. The scenes people film from a fixed camera are dominated by planes (floor, walls,
 * table tops, courts), and a plane is exactly what the error field is not: fitting one through
 * the bent surface averages the field out. Novel views need this - at a 20-degree test camera a
 * 1 % depth error on the wall shifts its texture by about a pixel, which costs structure (SSIM)
 * more than colour (PSNR). tabletop_dev depth_mono: median |log error| 0.64 % -> 0.19 %.
 *
 * Model: a plane seen by a pinhole camera has inverse depth affine in pixel coordinates,
 * 1/d = a x + b y + c (x, y the pixel centre over the image width/height, minus 0.5), whatever the
 * focal length - so no intrinsics are needed. Planes are found greedily by RANSAC on the per-pixel
 * static depth (median over the frames where the pixel is static): minimal samples of 3 nearby
 * pixels, inliers where d (a x + b y + c) lies within exp(+-tolerance), refits minimising the
 * relative residual sum (d q - 1)^2, then the next plane on the pixels left. A plane needs
 * min_support of the image and residuals piled up near zero (a curved surface that merely crosses
 * the plane spreads them evenly over the band). Each static pixel of every frame within tolerance of its best plane
 * (near that plane's inliers) takes the plane's depth; between tolerance and 2x tolerance it is
 * blended in log-depth, so snapping leaves no step at the rim. Moving pixels are never touched.
 *
 * Limits: an error field that is linear over a surface only tilts its plane (no single view can
 * tell); a bend stronger than about +-1.5 % spreads the residuals like a curved surface and is left
 * alone (test_depth_planes: +-1.2 % bends drop to a quarter; a dome gets no plane). */
#ifndef PG_DEPTH_SCENE_PLANES_H
#define PG_DEPTH_SCENE_PLANES_H

#include <stddef.h>
#include <stdint.h>

#include "core/status.h"

#define DEPTH_SCENE_PLANES_MAX 8

typedef struct {
    float tolerance;    /* inlier band, |log(d / d_plane)| (default 0.03) */
    float min_support;  /* smallest plane, fraction of the image's pixels (default 0.05) */
    float max_median_residual; /* a plane's inliers must have a median residual below this times
                                * the tolerance (0.3; evenly spread residuals give 0.5) */
    int max_planes;     /* <= DEPTH_SCENE_PLANES_MAX (default 6) */
    int iterations;     /* RANSAC samples per plane (default 400) */
    int min_frames;     /* a pixel needs this many static valid frames to have a static depth */
    uint64_t seed;
} depth_scene_planes_params;

typedef struct {
    double a, b, c;     /* 1/d = a x + b y + c, x = (u + 0.5)/W - 0.5, y = (v + 0.5)/H - 0.5 */
    long inliers;       /* pixels of the static depth within tolerance */
    double median_residual; /* median |log(d / d_plane)| over them */
} depth_scene_plane;

typedef struct {
    int count;
    depth_scene_plane planes[DEPTH_SCENE_PLANES_MAX];
    long snapped;       /* (frame, pixel) values changed, over all frames */
} depth_scene_planes_result;

void depth_scene_planes_defaults(depth_scene_planes_params *p);

/* depth (F, H*W) aligned depth, 0 = invalid, updated in place; static_masks (F, H*W). label
 * (H*W, may be NULL) receives each pixel's plane index or -1. Fails only for memory. */
pg_status depth_scene_planes_snap(const depth_scene_planes_params *p, float *depth, const unsigned char *static_masks, int frames,
                      int width, int height, depth_scene_planes_result *res, signed char *label);

/* Plane depth at pixel (u, v) of a W x H image; 0 where the plane is behind the camera. */
float depth_scene_plane_depth(const depth_scene_plane *pl, int u, int v, int width, int height);

#endif
