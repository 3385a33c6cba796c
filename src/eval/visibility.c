/* visibility.c - seen / disoccluded / outside labels of a test view (visibility.h). */
#include "eval/visibility.h"

#include <math.h>

#include "eval/metrics.h"

/* Relative depth margin before a point counts as hidden: rendered depth is a blend of the
 * Gaussians along the ray, a few percent off at edges and on soft surfaces. */
#define OCCLUSION_MARGIN 0.05f

void eval_visibility_labels(const pg_camera *test, const float *test_depth, const float *test_alpha,
                            const pg_camera *real, const float *real_zdepth, uint8_t *labels)
{
    const int W = test->width, H = test->height, RW = real->width, RH = real->height;
#pragma omp parallel for schedule(static)
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            size_t i = (size_t)y * W + x;
            float a = test_alpha[i];
            uint8_t label = EVAL_OUTSIDE;
            if (a > 0.5f) {
                float X[3], uv[2];
                pg_camera_unproject(test, x + 0.5f, y + 0.5f, test_depth[i] / a, X);
                float z = pg_camera_project(real, X, uv);
                int u = (int)floorf(uv[0]), v = (int)floorf(uv[1]);
                if (z > 0 && u >= 0 && u < RW && v >= 0 && v < RH) {
                    /* the farthest surface around the landing pixel: a point on a depth edge
                     * is seen if either side of the edge is at its depth */
                    float zmax = 0;
                    for (int dy = -1; dy <= 1; dy++)
                        for (int dx = -1; dx <= 1; dx++) {
                            int uu = u + dx, vv = v + dy;
                            if (uu < 0 || uu >= RW || vv < 0 || vv >= RH) continue;
                            zmax = fmaxf(zmax, real_zdepth[(size_t)vv * RW + uu]);
                        }
                    label = (zmax > 0 && z > zmax * (1.0f + OCCLUSION_MARGIN)) ? EVAL_DISOCCLUDED : EVAL_SEEN;
                }
            }
            labels[i] = label;
        }
}
