/* colmap_align.h - evaluation-only alignment of the monocular depth to the dataset's multi-view
 * reconstruction, as the paper does it (section 4, "Pose Alignment"): COLMAP triangulates SIFT
 * matches between frame 0 of the real camera and of the other (never the test) cameras at their
 * known poses, and the real camera's depth is fitted to the points it sees with one global scale
 * and one disparity shift:
 *
 *   pose depth = scale * d / (1 + shift * d)      (1 / depth is affine in 1 / d)
 *
 * A monocular network's disparity is known up to such an affine map, and the shift keeps planes
 * planar. A photometric fit of both (the warp into the other cameras) is degenerate on a wide
 * dome: on Panoptic it flattened the whole scene onto a card (shift 2.9 x 1/median depth against
 * COLMAP's -0.14); COLMAP's points pin the geometry instead.
 *
 *   proxy_colmap_report rep;
 *   if (proxy_colmap_available() && proxy_colmap_align(dir, &real, rgb0, depth0, W, H, n, cams, rgbs, 2, &rep) == PG_OK)
 *       use rep.scale, rep.shift;
 *
 * The single-video path never calls it: it needs cameras with known poses.
 */
#ifndef PG_PROXY_COLMAP_ALIGN_H
#define PG_PROXY_COLMAP_ALIGN_H

#include "core/camera.h"
#include "core/status.h"

typedef struct {
    float scale, shift;        /* the fit (shift in 1 / depth units) */
    int points;                /* triangulated points the real camera sees that the fit used */
    double abs_rel;            /* median |fitted depth - point depth| / point depth over them */
    double abs_rel_scale_only; /* the same with the best scale alone (median ratio) */
} proxy_colmap_report;

/* 1 when a `colmap` executable is on PATH and PG_COLMAP is not "0". */
int proxy_colmap_available(void);

/* Runs COLMAP in workdir (created; the caller removes it) on the real camera (real, real_rgb (H,W,3)
 * in [0,1]) and the n other cameras (cams, rgb, each image at its camera's size), all at their known
 * poses, then fits scale and shift to depth0 (dw x dh, the real camera's frame-0 depth at any size,
 * <= 0 invalid). Fails (a message naming the COLMAP step and its log) when a step fails or fewer
 * than 12 points are usable. */
pg_status proxy_colmap_align(const char *workdir, const pg_camera *real, const float *real_rgb, const float *depth0,
                             int dw, int dh, int n, const pg_camera *cams, const float *const *rgb, int threads,
                             proxy_colmap_report *rep);

/* The fit alone, from n pairs (d[i] the depth map's value, z[i] the point's depth): iteratively
 * reweighted least squares of 1 / z = a / d + b relative to 1 / z (scale = 1 / a, shift = b / a).
 * Fails when n < 12 or the fit is not a positive scale. Exposed for the tests. */
pg_status proxy_fit_scale_shift(const double *d, const double *z, int n, proxy_colmap_report *rep);

#endif
