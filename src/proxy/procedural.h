/* procedural.h - an analytic RGB-D test scene for the proxy stage (tests and `bench proxy`).
 *
 * World = the frame of a camera at the origin looking down +z. A textured back wall at z = 4 and
 * a textured card (|x| <= 0.6, |y| <= 0.45) at z = 2.5 - 0.3 x (slanted), plus a small card at
 * z = 2 that moves with `time`. Every view is ray-cast exactly (no splatting), so it gives ground
 * truth images, depths and visibility for any camera.
 */
#ifndef PG_PROXY_PROCEDURAL_H
#define PG_PROXY_PROCEDURAL_H

#include "core/camera.h"

/* rgb (H,W,3) and depth (H,W) z-depth, either may be NULL; `ss` x `ss` supersampling of the
 * colour (depth at the pixel centre). */
void proxy_procedural_render(const pg_camera *cam, float time, int ss, float *rgb, float *depth);

#endif
