/* gaussians.h - a set of 3D Gaussians as structure of arrays.
 *
 * The same struct holds parameters and their gradients, so an optimiser can walk matching
 * arrays. A set stores the SH coefficients up to a largest degree fixed at creation (its row
 * of sh_stride = 3 (d + 1)^2 floats; degree 3, all 48, unless asked otherwise); `sh_degree` says
 * how many are in use. A run that never goes past degree 0 keeps 3 floats a row: every pass over
 * the rows then reads a sixteenth of the SH bytes.
 */
#ifndef PG_GAUSSIANS_H
#define PG_GAUSSIANS_H

#include "core/status.h"

#define PG_SH_COEFFS 16 /* (degree 3 + 1)^2 */
#define PG_SH_FLOATS (PG_SH_COEFFS * 3)

/* Floats of a row holding the SH coefficients up to degree d (0..3). */
static inline int splat_sh_floats(int d) { return 3 * (d + 1) * (d + 1); }

typedef struct {
    int count;        /* N in use */
    int capacity;     /* allocated rows */
    int sh_degree;    /* active SH degree, 0..3, at most the stride's */
    int sh_stride;    /* floats per row of sh: splat_sh_floats of the largest degree it can hold */
    float *means;      /* (N, 3) world position */
    float *log_scales; /* (N, 3) log of the standard deviations along the local axes */
    float *quats;      /* (N, 4) rotation (w, x, y, z), normalised in use */
    float *opacity;    /* (N) logit of opacity */
    float *sh;         /* (N, sh_stride) SH coefficients, coefficient-major then RGB */
} pg_gaussians;

/* The largest SH degree a set's rows hold. */
static inline int splat_gaussians_sh_max(const pg_gaussians *g)
{
    int d = 0;
    while (d < 3 && splat_sh_floats(d) < g->sh_stride) d++;
    return d;
}

/* Row i of the SH coefficients. */
static inline float *splat_gaussians_sh(const pg_gaussians *g, size_t i) { return g->sh + (size_t)g->sh_stride * i; }

/* Allocates zeroed storage for `capacity` Gaussians with count = 0 and every SH degree. */
pg_status splat_gaussians_create(pg_gaussians *g, int capacity);
/* The same for SH up to degree sh_max (0..3) only: rows of splat_sh_floats(sh_max). */
pg_status splat_gaussians_create_sh(pg_gaussians *g, int capacity, int sh_max);
void splat_gaussians_destroy(pg_gaussians *g);
/* Sets count, growing capacity (content preserved, new rows zeroed). */
pg_status splat_gaussians_resize(pg_gaussians *g, int count);
/* Zeroes every array (rows 0..count-1), e.g. gradients before a backward pass. */
void splat_gaussians_zero(pg_gaussians *g);
/* Copies every row and the SH degree of src into dst (resized, grown as needed; dst takes src's
 * SH stride). */
pg_status splat_gaussians_copy(const pg_gaussians *src, pg_gaussians *dst);

#endif
