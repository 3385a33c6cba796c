/* poses.h - where the proxy (virtual) cameras go.
 *
 *   float c[3], r;
 *   proxy_scene_center(&real, depth0, 1.0f, c, &r);          // median depth on the optical axis
 *   pg_camera cams[18];
 *   proxy_poses_hemisphere(&real, c, 18, 20.0f, cams);       // frontal cap, <= 20 deg from real
 *
 * "given" poses need no helper: they are plain pg_camera values (e.g. a dataset's other cameras).
 * For those, the depth has to be brought into the dataset's pose units first:
 *
 *   float s;
 *   proxy_fit_pose_scale(&real, rgb0, depth0, n, train_cams, train_rgb0, &opt, &s, &report);
 *   // then use s * depth everywhere (poses are never rescaled)
 */
#ifndef PG_PROXY_POSES_H
#define PG_PROXY_POSES_H

#include "core/camera.h"
#include "core/status.h"

/* Scene centre c = camera centre + median(valid depth) * optical axis, radius = |c - centre|.
 * depth (H,W) is in the real camera's size; depth_scale multiplies it (pose units).
 * Fails with PG_ERR_ARG when no pixel has valid (finite, > 0) depth. */
pg_status proxy_scene_center(const pg_camera *real, const float *depth, float depth_scale, float center[3],
                             float *radius);

/* Places m cameras on the spherical cap of radius |center - real centre| around center, all within
 * max_angle_deg of the real camera's direction, evenly spread (sunflower spiral, polar angle
 * max_angle * sqrt((j+1)/m), so the real camera itself is never repeated and the outermost camera
 * sits on the cap's rim). Each looks at center with the real camera's intrinsics and up direction. */
pg_status proxy_poses_hemisphere(const pg_camera *real, const float center[3], int m, float max_angle_deg,
                                 pg_camera *out);

/* Angle in degrees between the viewing directions of two cameras (optical axes). */
float proxy_camera_angle_deg(const pg_camera *a, const pg_camera *b);

typedef struct {
    float scale_min, scale_max; /* search range for s (0,0: derived from the data) */
    int coarse_steps;           /* least log-spaced samples of the coarse grid (the grid is 3 % apart, more when the range is wide) */
    int refine_steps;           /* golden-section refinements at full resolution (24) */
} proxy_scale_options;

typedef struct {
    float scale;         /* the best s */
    float cost;          /* mean |warp - target| per target pixel at s, chance error where nothing landed */
    float coverage;      /* fraction of the target pixels some real pixel lands on at s */
    int evaluations;     /* cost evaluations made */
} proxy_scale_report;

proxy_scale_options proxy_default_scale_options(void);

/* Evaluation-only alignment of depth units to pose units. Fits one global scale s such that
 * forward-warping the real frame 0 (rgb (H,W,3), depth (H,W)) with depth s*D into each of the
 * n target cameras reproduces their frame 0 (targets[k] (H,W,3), same size as the real frame).
 * Every target pixel counts (the chance error where no real pixel lands). A log grid 3 % apart at
 * quarter size, then golden-section search around its three deepest minima at half and full size.
 * The caller must not pass test cameras. */
pg_status proxy_fit_pose_scale(const pg_camera *real, const float *rgb, const float *depth, int n,
                               const pg_camera *targets, const float *const *target_rgb,
                               const proxy_scale_options *opt, proxy_scale_report *report);

/* depth[i] -> depth[i] / (1 + shift * depth[i]) for valid entries (0 where the denominator is <= 0). */
void proxy_shift_disparity(float *depth, size_t n, float shift);

/* Forward warp (nearest splat with a z-buffer, no hole filling) of a source RGB-D image into dst.
 * out_rgb (H2,W2,3), out_depth (H2,W2) z in dst (0 where nothing landed); either may be NULL.
 * depth is multiplied by depth_scale. Used by the pose-scale fit and as a test reference. */
pg_status proxy_forward_warp(const pg_camera *src, const float *rgb, const float *depth, float depth_scale,
                             const pg_camera *dst, float *out_rgb, float *out_depth);

#endif
