/* splat_file.h - Gaussians as a ".splat" file, the layout of antimatter15's web viewer that
 * many web splat viewers read: no header, 32 bytes per Gaussian, little-endian:
 *
 *   float32 x, y, z          position
 *   float32 sx, sy, sz       scales (standard deviations, exp of the log-scales)
 *   uint8   r, g, b, a       colour 0.5 + C0 * SH DC clamped to [0, 1], a = sigmoid(opacity), x 255
 *   uint8   qw, qx, qy, qz   unit quaternion, each round(q * 128 + 128) clamped to 0..255
 *
 * Higher SH bands are dropped (the format has none).
 */
#ifndef PG_SPLAT_FILE_H
#define PG_SPLAT_FILE_H

#include "splat/gaussians.h"

#define IO_SPLAT_ROW_BYTES 32

/* Writes every Gaussian of g atomically. */
pg_status io_splat_save(const char *path, const pg_gaussians *g);

#endif
