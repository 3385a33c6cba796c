/* random_scene.h - the benchmark workload: N random Gaussians inside a camera's frustum. */
#ifndef PG_RANDOM_SCENE_H
#define PG_RANDOM_SCENE_H

#include "core/camera.h"
#include "splat/gaussians.h"

/* Fills g (created by the caller, resized here to n) with Gaussians at depths U(2, 10) whose
 * projection centres are uniform over the image, isotropic scales giving a projected standard
 * deviation of sigma_px * U(0.3, 1.7) pixels, opacity U(0.05, 0.95), random colours and (for
 * sh_degree > 0) small random higher SH coefficients. Same seed, same scene. */
pg_status splat_random_scene(pg_gaussians *g, const pg_camera *cam, int n, float sigma_px, int sh_degree,
                             unsigned long long seed);

#endif
