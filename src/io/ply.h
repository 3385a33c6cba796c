/* ply.h - Gaussian splat PLY files in the standard 3DGS layout.
 *
 * Written: binary little-endian, one `vertex` element with float properties
 *   x y z nx ny nz f_dc_0..2 f_rest_0..44 opacity scale_0..2 rot_0..3
 * (normals are 0; opacity is the logit, scale the log standard deviation, rot = (w, x, y, z)).
 * f_rest is channel-major in the file: f_rest_{c*15 + k} is SH coefficient k+1 of colour c; in
 * pg_gaussians it is sh[(i*16 + k+1)*3 + c]. All 45 f_rest are written whatever sh_degree is
 * (viewers expect them); a "comment sh_degree D" line keeps the active degree exact.
 *
 * Read: little- or big-endian binary PLY, properties in any order and of any scalar type,
 * other elements before/after the vertices skipped. Missing optional properties get defaults:
 * f_dc from red/green/blue (uchar or float) if present else 0 (grey), f_rest 0 (degree from
 * how many f_rest exist), opacity logit 2.0 (about 0.88), scale_* log(0.01), rot (1,0,0,0).
 * x, y, z are required. Counts larger than the file, truncation, list properties in the vertex
 * element and non-finite values fail with a message naming the file.
 */
#ifndef PG_PLY_H
#define PG_PLY_H

#include "splat/gaussians.h"

typedef struct {
    int count;            /* vertices */
    int sh_degree;        /* 0..3 */
    float bbox_min[3], bbox_max[3];
    float mean_opacity;   /* mean sigmoid(opacity) (default opacity when absent) */
    int has_opacity, has_scale, has_rot, num_rest;
} io_ply_info;

/* Parses the header and scans the vertices (bbox, opacity) without allocating Gaussians. */
pg_status io_ply_probe(const char *path, io_ply_info *info);
/* Loads into g (created here; destroy with splat_gaussians_destroy). g is empty on failure. */
pg_status io_ply_load(const char *path, pg_gaussians *g);
/* Saves g (rows 0..count-1) atomically. */
pg_status io_ply_save(const char *path, const pg_gaussians *g);

#endif
