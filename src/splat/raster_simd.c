/* raster_simd.c - SIMD tile kernels (AVX-512: one 16-pixel tile row per vector). */
#include "splat/raster_kernels.h"

int splat_simd_available(void) { return 0; }
const char *splat_simd_name(void) { return "scalar"; }
void splat_tile_forward_simd(const splat_tile_job *job) { splat_tile_forward_scalar(job); }
void splat_tile_backward_simd(const splat_tile_job *job) { splat_tile_backward_scalar(job); }
