/* plane.h - small helpers on single-channel float planes (H, W) shared by the depth stage.
 * Internal to src/depth. Pixel centres sit at (x + 0.5, y + 0.5); samplers clamp at borders. */
#ifndef PG_DEPTH_PLANE_H
#define PG_DEPTH_PLANE_H

#include <stddef.h>
#include "core/image.h"

/* Loops on planes smaller than this run on one thread: at 320x240 the per-iteration fork/join
 * barriers of an iterative solver cost more than they save on a shared 2-core machine, and the
 * depth stage parallelises across frames instead. */
#define PLANE_PAR_MIN_PIXELS 200000

/* Luma (Rec. 601) of an RGB or 1-channel image into gray (H,W), scaled by `scale`. */
void depth_plane_from_image(const pg_image *img, float scale, float *gray);
/* Separable Gaussian blur (sigma in pixels, radius ceil(3 sigma)); tmp is (H,W) scratch. */
void depth_plane_gaussian_blur(const float *src, int w, int h, float sigma, float *tmp, float *dst);
/* Bilinear resample of a (h,w) plane to (h2,w2) (centre-aligned). */
void depth_plane_resize(const float *src, int w, int h, float *dst, int w2, int h2);
/* Bilinear sample at continuous coordinates in pixel-index units (centre of pixel i is i). */
float depth_plane_sample_bilinear(const float *p, int w, int h, float x, float y);
/* Bicubic (Keys, a = -0.5) samples of n planes at one point (same coordinates as above) into
 * out[0..n): the weights once for all (the flow warps an image and its two gradients together). */
void depth_plane_sample_bicubic(const float *const *planes, int n, int w, int h, float x, float y, float *out);
/* Central-difference gradient of a (h,w) plane into gx, gy (one-sided at the borders). */
void depth_plane_gradient(const float *src, int w, int h, float *gx, float *gy);
/* 3x3 median filter (borders replicate): a sorting network; _ref sorts (test oracle). */
void depth_plane_median3(const float *src, int w, int h, float *dst);
void depth_plane_median3_ref(const float *src, int w, int h, float *dst);
/* Binary morphology on a (h,w) uint8 mask with a disc of radius r: erode or dilate. */
void depth_mask_erode(const unsigned char *src, int w, int h, int r, unsigned char *dst);
void depth_mask_dilate(const unsigned char *src, int w, int h, int r, unsigned char *dst);

#endif
