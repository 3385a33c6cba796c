/* mask.h - which pixels of a proxy view can be trusted.
 *
 * A splatted proxy fills disocclusions (surfaces hidden from the real camera) by stretching the
 * Gaussians of the foreground and background edges across the gap. To detect that, the source depth
 * map is treated as a triangle mesh over the pixel centres; triangles that straddle a depth edge
 * (relative depth jump > edge_rel) or that stretch to more than stretch_max target pixels per
 * source pixel are dropped, the rest are rasterised into the proxy view with a z-buffer. A proxy
 * pixel is valid when
 *   - the splat alpha > alpha_min,
 *   - a kept triangle covers it (it sees a surface the real camera saw), and
 *   - the splat depth (normalised by alpha) agrees with the mesh depth within depth_tol (relative),
 *     which also rejects the blended fringe where foreground splats spill over a background.
 */
#ifndef PG_PROXY_MASK_H
#define PG_PROXY_MASK_H

#include "core/camera.h"
#include "core/status.h"

typedef struct {
    float alpha_min;   /* 0.5 */
    float edge_rel;    /* 0.04: |d1 - d2| / min(d1, d2) above this is a depth edge */
    float stretch_max; /* 2.5: max projected edge length in target pixels per source pixel */
    float depth_tol;   /* 0.02: relative splat-vs-mesh depth disagreement allowed */
    float margin_weight; /* 0.5: mask value (training weight) of valid pixels that show the
                          * outpainted margin rather than something the real camera saw */
} proxy_mask_options;

/* Mask values: 0 invalid, PROXY_MASK_REAL seen by the real camera, in between the margin weight. */
#define PROXY_MASK_REAL 255

proxy_mask_options proxy_default_mask_options(void);

/* Rasterises the depth mesh of src (depth (H,W) in pose units, 0 = invalid) into dst.
 * zmesh (H2,W2) receives the nearest kept-triangle depth, 0 where no kept triangle lands. With rgb
 * (H,W,3) given, rgb_out (H2,W2,3) receives the nearest triangle's colour, interpolated
 * perspective-correctly between its corner pixels (0 where none lands); both may be NULL.
 * The outer `pad` pixels of src are an outpainted margin: margin (H2,W2, may be NULL) gets 1
 * where the nearest triangle touches it. */
pg_status proxy_mesh_depth(const pg_camera *src, const float *depth, int pad, const pg_camera *dst,
                           const proxy_mask_options *opt, float *zmesh, unsigned char *margin, const float *rgb,
                           float *rgb_out);

/* The mask of a mesh-rendered view (H2,W2): covered by a kept triangle = valid (the margin's weight
 * where it shows the margin). mask may be NULL. Returns the valid fraction. */
float proxy_mask_mesh(int width, int height, const float *zmesh, const unsigned char *margin,
                      const proxy_mask_options *opt, unsigned char *mask);

/* Combines splat alpha (H2,W2), splat depth normalised by alpha (H2,W2), zmesh and margin (may be
 * NULL) into mask (H2,W2): 0, the margin weight x 255, or PROXY_MASK_REAL. Returns the valid
 * fraction (margin included). */
float proxy_mask_combine(int width, int height, const float *alpha, const float *depth_norm, const float *zmesh,
                         const unsigned char *margin, const proxy_mask_options *opt, unsigned char *mask);

#endif
