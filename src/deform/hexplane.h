/* hexplane.h - multi-scale HexPlane feature field: sampling forward and backward.
 *
 * Six planes per scale over the 4D coordinates (x, y, z, t):
 *     plane 0 (x,y)  1 (x,z)  2 (y,z)  3 (x,t)  4 (y,t)  5 (z,t)
 * Plane (a,b) is stored (res_b, res_a, C): rows along its second axis b (time for planes 3-5),
 * columns along a, C channels contiguous per texel. Scale s has spatial resolution R << s; the time
 * resolution T is the same at every scale. Positions are normalised by the AABB to u in [0,1]^3 and
 * clamped (border clamp, zero position gradient outside); t in [0,1] covers the whole time axis.
 * Grid coordinates use the align-corners convention: g = u * (res - 1).
 *
 * The feature of a point is, per scale, the channel-wise product of the six bilinear samples,
 * concatenated over scales: feat (S*C) with feat[s*C + c] = prod_P sample_{s,P}(u, t)[c].
 *
 * The planes are views into one flat parameter array (see deform_network); this module only does
 * the per-point maths, so it is shared by the network and the tests.
 */
#ifndef PG_DEFORM_HEXPLANE_H
#define PG_DEFORM_HEXPLANE_H

#include <stddef.h>

#define HEX_PLANES 6
#define HEX_MAX_SCALES 4
#define HEX_MAX_TIME_COARSEN 8 /* largest hex_grid.time_coarsen any config, blob or checkpoint may hold */

/* Which of the 4 coordinates (0 x, 1 y, 2 z, 3 t) each plane uses: {a (columns), b (rows)}. */
extern const int hex_plane_axes[HEX_PLANES][2];

typedef struct {
    int C;                  /* channels per plane */
    int S;                  /* number of scales */
    int R;                  /* spatial resolution of scale 0 (scale s: R << s) */
    int T;                  /* time resolution of the finest scale */
    int time_coarsen;       /* k: scale s has ((T - 1) >> (k * (S - 1 - s))) + 1 time rows, at least 2 (0: T at
                             * every scale), so the coarse scale's time rows are shared by 2^k times as many frames */
    float aabb[6];          /* min xyz, max xyz */
    float *planes[HEX_MAX_SCALES][HEX_PLANES];  /* (res_b, res_a, C) views into the parameters */
} hex_grid;

/* Cell index, fractional weight and d(grid coord)/d(input) of one axis of one point. */
typedef struct {
    int i0;
    float w;
    float dgdx; /* 0 where the coordinate was clamped */
} hex_axis;

/* The per-scale spatial axis setup of one point (shared by prefetch, forward and backward). */
typedef struct {
    hex_axis ax[HEX_MAX_SCALES][3];
} hex_point;

/* The time planes at one t, each collapsed to one row: slice(a) = (1-w) plane(row, a) + w plane(row+1, a).
 * All points of a call share t, so a time-plane sample becomes a linear interpolation along its
 * spatial axis (2 texels instead of 4); the backward accumulates into a slice-shaped gradient that
 * hex_slice_backward spreads onto the two rows once per call. */
typedef struct {
    int row[HEX_MAX_SCALES];            /* first of the two time rows (of the scale's time resolution) */
    float w[HEX_MAX_SCALES];            /* weight of row + 1 */
    float *s[HEX_MAX_SCALES][3];        /* (res_a, C) for time planes 3, 4, 5 (a = x, y, z) */
} hex_slice;

/* Time rows of scale s: coarser scales may have coarser time, so their rows are shared by many
 * frames and train from all of them. */
static inline int hex_time_res(const hex_grid *g, int s)
{
    int r = ((g->T - 1) >> (g->time_coarsen * (g->S - 1 - s))) + 1;
    return r > 2 ? r : 2;
}
/* Resolution of coordinate axis d (0..3) at scale s. */
static inline int hex_axis_res(const hex_grid *g, int s, int d) { return d == 3 ? hex_time_res(g, s) : g->R << s; }
/* Number of floats of plane p at scale s. */
size_t hex_plane_size(const hex_grid *g, int s, int p);

/* Floats of one slice; hex_slice_layout points sl into buf (hex_slice_size floats) for time t,
 * hex_slice_forward fills it from the planes, hex_slice_backward adds a slice gradient d_sl (laid
 * out for the same t) into the two time rows of d_planes. */
size_t hex_slice_size(const hex_grid *g);
void hex_slice_layout(hex_slice *sl, float *buf, const hex_grid *g, float t);
void hex_slice_forward(hex_slice *sl, const hex_grid *g);
void hex_slice_backward(float *const d_planes[HEX_MAX_SCALES][HEX_PLANES], const hex_slice *d_sl, const hex_grid *g);

/* Sampling on a prepared point (hex_point_setup), so a caller that prefetches ahead computes the
 * axes once per point. hex_prefetch_point prefetches the spatial planes' texels (and, if
 * d_planes != NULL, their gradient lines) the point will touch (time planes are read through the
 * slice, which stays cached); called a few points ahead it hides the cache misses of the random
 * plane accesses. feat (S*C); pos (3) in world units. The backward adds dL/dplanes into d_planes
 * (spatial planes, same layout as the planes) and d_sl (time planes), and dL/dpos into d_pos (3;
 * may be NULL). */
void hex_point_setup(hex_point *hp, const hex_grid *g, const float *pos);
void hex_prefetch_point(const hex_grid *g, float *const d_planes[HEX_MAX_SCALES][HEX_PLANES], const hex_point *hp);
void hex_sample_forward_point(float *feat, const hex_grid *g, const hex_slice *sl, const hex_point *hp);
void hex_sample_backward_point(float *const d_planes[HEX_MAX_SCALES][HEX_PLANES], const hex_slice *d_sl, float *d_pos,
                               const float *d_feat, const hex_grid *g, const hex_slice *sl, const hex_point *hp);

#endif
