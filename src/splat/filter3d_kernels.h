/* filter3d_kernels.h - the 3D filter's vector kernels (filter3d.c chooses them at run time). */
#ifndef PG_FILTER3D_KERNELS_H
#define PG_FILTER3D_KERNELS_H

#include "splat/filter3d.h"
#include "splat/raster.h"

/* Makes the forward use kernel family k (scalar or avx512; tests compare them); an unsupported k
 * restores the default, the rasterizer's (PG_RASTER). */
void splat_filter3d_set_kernel(splat_kernel_kind k);

/* The forward of n <= 16 Gaussians: rows[0 .. n-1] when rows is set, else i0 .. i0 + n - 1 (the
 * scalar forward's arguments otherwise). */
void splat_filter3d_forward16_avx512(float *log_scales, float *opacity, const float *var, const int *rows, int i0,
                                     int n, float *saved);

#endif
