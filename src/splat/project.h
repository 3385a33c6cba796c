/* project.h - EWA projection of one 3D Gaussian to a 2D screen-space Gaussian.
 *
 * t = R mean + T (camera space); mean2D = (fx t.x/t.z + cx, fy t.y/t.z + cy);
 * J = [[fx/z, 0, -fx u], [0, fy/z, -fy w]] / with u = clamp(t.x/z) / z etc. (the clamp to 1.3x
 * the frustum keeps J bounded for Gaussians far outside the view; the clamped coordinate passes
 * no gradient); Sigma2D = J R Sigma R^T J^T + lowpass I (the screen-space filter: a tenth of a
 * squared pixel, of a training pixel when the camera draws finer than training did, see
 * splat_lowpass_for; the 3D filter, splat/filter3d.h, bounds what the training views could not
 * resolve); conic = Sigma2D^-1 stored (a, b, c) with
 * sigma(dx, dy) = 0.5 (a dx^2 + c dy^2) + b dx dy.
 */
#ifndef PG_PROJECT_H
#define PG_PROJECT_H

#include "core/camera.h"

#define SPLAT_LOWPASS 0.1f

/* lim of the projection functions: the x/z and y/z clamp bounds, then the screen-space filter's
 * variance in squared pixels of the camera drawn */
#define SPLAT_LIM_COUNT 5

typedef struct {
    float xy[2];    /* pixel coordinates of the projected mean */
    float z;        /* camera-space depth */
    float cov2d[3]; /* Sigma2D (xx, xy, yy) including the low-pass */
    float conic[3]; /* inverse of Sigma2D (a, b, c) */
} splat_proj;

/* Returns 1 and fills p when the Gaussian is in front of near_clip, else 0. */
int splat_project_forward(const float mean[3], const float log_scale[3], const float quat[4],
                          const pg_camera *cam, float near_clip, splat_proj *p);
/* Adds d(loss)/d(mean, log_scale, quat) given d(loss)/d(xy, conic, z). The quaternion gradient
 * has the normalisation projected out. Only valid for Gaussians the forward kept. */
void splat_project_backward(const float mean[3], const float log_scale[3], const float quat[4],
                            const pg_camera *cam, const float d_xy[2], const float d_conic[3], float d_z,
                            float d_mean[3], float d_log_scale[3], float d_quat[4]);

/* The same with the frustum-clamp limits and filter precomputed by splat_project_limits (hot loops). */
void splat_project_limits(const pg_camera *cam, float lowpass, float lim[SPLAT_LIM_COUNT]);
int splat_project_forward_lim(const float mean[3], const float log_scale[3], const float quat[4],
                              const pg_camera *cam, const float lim[SPLAT_LIM_COUNT], float near_clip, splat_proj *p);
void splat_project_backward_lim(const float mean[3], const float log_scale[3], const float quat[4],
                                const pg_camera *cam, const float lim[SPLAT_LIM_COUNT], const float d_xy[2],
                                const float d_conic[3], float d_z, float d_mean[3], float d_log_scale[3],
                                float d_quat[4]);
/* Gaussians i0 .. i0+15 at once (AVX-512 builds; returns 0 and does nothing otherwise).
 * out rows: x, y, z, Sigma2D xx, xy, yy, conic a, b, c (16 lanes each); valid bit l set when
 * Gaussian i0+l was kept. Float results differ from the scalar path by rounding only (exp is
 * a polynomial here). */
int splat_project_forward16(const float *means, const float *log_scales, const float *quats, int i0,
                            const pg_camera *cam, const float lim[SPLAT_LIM_COUNT], float near_clip, float out[9][16],
                            unsigned *valid);
/* Adds the gradients of Gaussians i0 .. i0+15 whose bit is set in mask (AVX-512 builds;
 * returns 0 and does nothing otherwise). Inputs as in splat_project_backward, one row per
 * quantity with 16 lanes. */
int splat_project_backward16(const float *means, const float *log_scales, const float *quats, int i0,
                             const pg_camera *cam, const float lim[SPLAT_LIM_COUNT], const float d_xy[2][16],
                             const float d_conic[3][16], const float d_z[16], unsigned mask,
                             float *d_means, float *d_log_scales, float *d_quats);
/* The signatures of the 16-wide pairs, for tables of kernel families. */
typedef int (*splat_project16_forward_fn)(const float *, const float *, const float *, int, const pg_camera *,
                                          const float *, float, float[9][16], unsigned *);
typedef int (*splat_project16_backward_fn)(const float *, const float *, const float *, int, const pg_camera *,
                                           const float *, const float[2][16], const float[3][16], const float *,
                                           unsigned, float *, float *, float *);
/* The same two on AVX2 + FMA (two 8-lane halves; per lane the AVX-512 pair's operations). They
 * return 0 and do nothing in builds without AVX2 kernels. */
int splat_project_forward16_avx2(const float *means, const float *log_scales, const float *quats, int i0,
                                 const pg_camera *cam, const float lim[SPLAT_LIM_COUNT], float near_clip, float out[9][16],
                                 unsigned *valid);
int splat_project_backward16_avx2(const float *means, const float *log_scales, const float *quats, int i0,
                                  const pg_camera *cam, const float lim[SPLAT_LIM_COUNT], const float d_xy[2][16],
                                  const float d_conic[3][16], const float d_z[16], unsigned mask,
                                  float *d_means, float *d_log_scales, float *d_quats);

#endif
