/* gaussians.h - a set of 3D Gaussians as structure of arrays.
 *
 * The same struct holds parameters, their gradients and Adam moments, so an optimiser
 * can walk matching arrays. SH storage is always degree 3 (16 coefficients per colour
 * channel); `sh_degree` says how many are in use.
 */
#ifndef PG_GAUSSIANS_H
#define PG_GAUSSIANS_H

#include "core/status.h"

#define PG_SH_COEFFS 16 /* (degree 3 + 1)^2 */

typedef struct {
    int count;        /* N in use */
    int capacity;     /* allocated rows */
    int sh_degree;    /* active SH degree, 0..3 */
    float *means;      /* (N, 3) world position */
    float *log_scales; /* (N, 3) log of the standard deviations along the local axes */
    float *quats;      /* (N, 4) rotation (w, x, y, z), normalised in use */
    float *opacity;    /* (N) logit of opacity */
    float *sh;         /* (N, 16, 3) SH coefficients, coefficient-major then RGB */
} pg_gaussians;

/* Allocates zeroed storage for `capacity` Gaussians with count = 0. */
pg_status splat_gaussians_create(pg_gaussians *g, int capacity);
void splat_gaussians_destroy(pg_gaussians *g);
/* Sets count, growing capacity (content preserved, new rows zeroed). */
pg_status splat_gaussians_resize(pg_gaussians *g, int count);
/* Zeroes every array (rows 0..count-1), e.g. gradients before a backward pass. */
void splat_gaussians_zero(pg_gaussians *g);
/* Copies every row and the SH degree of src into dst (resized, grown as needed). */
pg_status splat_gaussians_copy(const pg_gaussians *src, pg_gaussians *dst);

#endif
