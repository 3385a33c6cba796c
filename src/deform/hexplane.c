/* hexplane.c - HexPlane sampling forward/backward (see hexplane.h). */
#include "deform/hexplane.h"
#include "core/clones.h"

/* With C = 16 a texel is one 512-bit vector; gcc's default 256-bit preference doubles the
 * instructions of these loops (hexplane backward measured -5 ms per 100k points with 512), so
 * CMakeLists.txt compiles this file with -mprefer-vector-width=512. The hot loops are PG_CLONES:
 * AVX-512 / AVX2 / baseline versions chosen at load time. */

#include <math.h>

#define HEX_MAX_C 64

const int hex_plane_axes[HEX_PLANES][2] = { { 0, 1 }, { 0, 2 }, { 1, 2 }, { 0, 3 }, { 1, 3 }, { 2, 3 } };

size_t hex_plane_size(const hex_grid *g, int s, int p)
{
    return (size_t)hex_axis_res(g, s, hex_plane_axes[p][0]) * hex_axis_res(g, s, hex_plane_axes[p][1]) * g->C;
}


static inline __attribute__((always_inline)) void hex_axis_setup(hex_axis *ax, float u, float du_dx, int res)
{
    float dg = du_dx * (float)(res - 1);
    if (!(u > 0.0f)) { u = 0.0f; dg = 0.0f; } /* also catches NaN */
    if (u > 1.0f) { u = 1.0f; dg = 0.0f; }
    float g = u * (float)(res - 1);
    int i0 = (int)g;
    if (i0 > res - 2) i0 = res - 2;
    ax->i0 = i0;
    ax->w = g - (float)i0;
    ax->dgdx = dg;
}

void hex_point_setup(hex_point *hp, const hex_grid *g, const float *pos)
{
    for (int d = 0; d < 3; d++) {
        float inv = 1.0f / (g->aabb[3 + d] - g->aabb[d]);
        float u = (pos[d] - g->aabb[d]) * inv;
        for (int s = 0; s < g->S; s++) hex_axis_setup(&hp->ax[s][d], u, inv, g->R << s);
    }
}

size_t hex_slice_size(const hex_grid *g)
{
    size_t n = 0;
    for (int s = 0; s < g->S; s++) n += (size_t)3 * (g->R << s) * g->C;
    return n;
}

void hex_slice_layout(hex_slice *sl, float *buf, const hex_grid *g, float t)
{
    for (int s = 0; s < g->S; s++) {
        hex_axis ax;
        hex_axis_setup(&ax, t, 1.0f, hex_time_res(g, s));
        sl->row[s] = ax.i0;
        sl->w[s] = ax.w;
        for (int q = 0; q < 3; q++) {
            sl->s[s][q] = buf;
            buf += (size_t)(g->R << s) * g->C;
        }
    }
}

PG_CLONES void hex_slice_forward(hex_slice *sl, const hex_grid *g)
{
    for (int s = 0; s < g->S; s++)
        for (int q = 0; q < 3; q++) {
            const float w = sl->w[s];
            size_t row = (size_t)(g->R << s) * g->C;
            const float *r0 = g->planes[s][3 + q] + (size_t)sl->row[s] * row, *r1 = r0 + row;
            float *o = sl->s[s][q];
            #pragma omp simd
            for (size_t i = 0; i < row; i++) o[i] = (1 - w) * r0[i] + w * r1[i];
        }
}

PG_CLONES void hex_slice_backward(float *const d_planes[HEX_MAX_SCALES][HEX_PLANES], const hex_slice *d_sl, const hex_grid *g)
{
    for (int s = 0; s < g->S; s++)
        for (int q = 0; q < 3; q++) {
            const float w = d_sl->w[s];
            size_t row = (size_t)(g->R << s) * g->C;
            float *r0 = d_planes[s][3 + q] + (size_t)d_sl->row[s] * row, *r1 = r0 + row;
            const float *d = d_sl->s[s][q];
            #pragma omp simd
            for (size_t i = 0; i < row; i++) {
                r0[i] += (1 - w) * d[i];
                r1[i] += w * d[i];
            }
        }
}

void hex_prefetch_point(const hex_grid *g, float *const d_planes[HEX_MAX_SCALES][HEX_PLANES], const hex_point *hp)
{
    const int C = g->C;
    for (int s = 0; s < g->S; s++) {
        const hex_axis *ax = hp->ax[s];
        for (int p = 0; p < 3; p++) {
            const hex_axis *A = &ax[hex_plane_axes[p][0]], *B = &ax[hex_plane_axes[p][1]];
            size_t Wp = (size_t)(g->R << s);
            size_t off = ((size_t)B->i0 * Wp + A->i0) * C, row = Wp * C;
            const float *t00 = g->planes[s][p] + off;
            __builtin_prefetch(t00, 0, 3);
            __builtin_prefetch(t00 + C, 0, 3);
            __builtin_prefetch(t00 + row, 0, 3);
            __builtin_prefetch(t00 + row + C, 0, 3);
            if (d_planes) {
                float *d00 = d_planes[s][p] + off;
                __builtin_prefetch(d00, 1, 3);
                __builtin_prefetch(d00 + C, 1, 3);
                __builtin_prefetch(d00 + row, 1, 3);
                __builtin_prefetch(d00 + row + C, 1, 3);
            }
        }
    }
}

/* Sample of each plane of scale s: bilinear for the spatial planes 0-2, linear in the slice for
 * the time planes 3-5 (plane 3 + q reads the slice along axis q). */
static inline __attribute__((always_inline)) void hex_scale_samples(float v[HEX_PLANES][HEX_MAX_C], const hex_grid *g,
                                                                     const hex_slice *sl, const hex_axis *ax, int s)
{
    const int C = g->C;
    const size_t row = (size_t)(g->R << s) * C;
    for (int p = 0; p < 3; p++) {
        const hex_axis *A = &ax[hex_plane_axes[p][0]], *B = &ax[hex_plane_axes[p][1]];
        const float *t00 = g->planes[s][p] + (size_t)B->i0 * row + (size_t)A->i0 * C;
        const float *t01 = t00 + C, *t10 = t00 + row, *t11 = t10 + C;
        float wa = A->w, wb = B->w;
        float w00 = (1 - wa) * (1 - wb), w01 = wa * (1 - wb), w10 = (1 - wa) * wb, w11 = wa * wb;
        #pragma omp simd
        for (int c = 0; c < C; c++) v[p][c] = w00 * t00[c] + w01 * t01[c] + w10 * t10[c] + w11 * t11[c];
    }
    for (int q = 0; q < 3; q++) {
        const float *l0 = sl->s[s][q] + (size_t)ax[q].i0 * C, *l1 = l0 + C;
        float wa = ax[q].w;
        #pragma omp simd
        for (int c = 0; c < C; c++) v[3 + q][c] = (1 - wa) * l0[c] + wa * l1[c];
    }
}

PG_CLONES void hex_sample_forward_point(float *feat, const hex_grid *g, const hex_slice *sl, const hex_point *hp)
{
    const int C = g->C;
    float v[HEX_PLANES][HEX_MAX_C];
    for (int s = 0; s < g->S; s++) {
        hex_scale_samples(v, g, sl, hp->ax[s], s);
        float *f = feat + s * C;
        #pragma omp simd
        for (int c = 0; c < C; c++) f[c] = ((v[0][c] * v[1][c]) * v[2][c]) * ((v[3][c] * v[4][c]) * v[5][c]);
    }
}

/* Position gradients: per channel, accumulated per axis over all planes and scales (dgdx folded
 * in), then summed over channels once per axis; a horizontal sum per plane would be a serial add
 * chain 2 x 12 times per point. */
PG_CLONES void hex_sample_backward_point(float *const d_planes[HEX_MAX_SCALES][HEX_PLANES], const hex_slice *d_sl, float *d_pos,
                               const float *d_feat, const hex_grid *g, const hex_slice *sl, const hex_point *hp)
{
    const int C = g->C;
    float v[HEX_PLANES][HEX_MAX_C]; /* per-plane samples */
    float pre[HEX_MAX_C], suf[HEX_PLANES][HEX_MAX_C];
    float acc[3][HEX_MAX_C];        /* d_pos per axis and channel */
    for (int d = 0; d < 3; d++)
        for (int c = 0; c < C; c++) acc[d][c] = 0.0f;
    for (int s = 0; s < g->S; s++) {
        const hex_axis *ax = hp->ax[s];
        const float *df = d_feat + s * C;
        const size_t row = (size_t)(g->R << s) * C;
        hex_scale_samples(v, g, sl, ax, s);
        /* product of the other five planes without division (samples can be 0): prefix * suffix */
        for (int c = 0; c < C; c++) suf[HEX_PLANES - 1][c] = 1.0f;
        for (int p = HEX_PLANES - 2; p >= 0; p--)
            #pragma omp simd
            for (int c = 0; c < C; c++) suf[p][c] = suf[p + 1][c] * v[p + 1][c];
        for (int c = 0; c < C; c++) pre[c] = 1.0f;
        for (int p = 0; p < 3; p++) {
            int a = hex_plane_axes[p][0], b = hex_plane_axes[p][1];
            const hex_axis *A = &ax[a], *B = &ax[b];
            float wa = A->w, wb = B->w;
            float w00 = (1 - wa) * (1 - wb), w01 = wa * (1 - wb), w10 = (1 - wa) * wb, w11 = wa * wb;
            size_t off = (size_t)B->i0 * row + (size_t)A->i0 * C;
            float *restrict d00 = d_planes[s][p] + off, *restrict d01 = d00 + C, *restrict d10 = d00 + row,
                  *restrict d11 = d10 + C;
            const float *t00 = g->planes[s][p] + off, *t01 = t00 + C, *t10 = t00 + row, *t11 = t10 + C;
            float *restrict ga = acc[a], *restrict gb = acc[b];
            const float sa = A->dgdx, sb = B->dgdx;
            #pragma omp simd
            for (int c = 0; c < C; c++) {
                float gp = df[c] * pre[c] * suf[p][c];
                d00[c] += w00 * gp;
                d01[c] += w01 * gp;
                d10[c] += w10 * gp;
                d11[c] += w11 * gp;
                ga[c] += sa * gp * ((1 - wb) * (t01[c] - t00[c]) + wb * (t11[c] - t10[c]));
                gb[c] += sb * gp * ((1 - wa) * (t10[c] - t00[c]) + wa * (t11[c] - t01[c]));
                pre[c] *= v[p][c];
            }
        }
        for (int q = 0; q < 3; q++) { /* time planes: the slice along axis q */
            const hex_axis *A = &ax[q];
            const float wa = A->w, sa = A->dgdx;
            const float *l0 = sl->s[s][q] + (size_t)A->i0 * C, *l1 = l0 + C;
            float *restrict d0 = d_sl->s[s][q] + (size_t)A->i0 * C, *restrict d1 = d0 + C;
            float *restrict ga = acc[q];
            #pragma omp simd
            for (int c = 0; c < C; c++) {
                float gp = df[c] * pre[c] * suf[3 + q][c];
                d0[c] += (1 - wa) * gp;
                d1[c] += wa * gp;
                ga[c] += sa * gp * (l1[c] - l0[c]);
                pre[c] *= v[3 + q][c];
            }
        }
    }
    if (d_pos) {
        float sx = 0, sy = 0, sz = 0;
        for (int c = 0; c < C; c++) {
            sx += acc[0][c];
            sy += acc[1][c];
            sz += acc[2][c];
        }
        d_pos[0] += sx;
        d_pos[1] += sy;
        d_pos[2] += sz;
    }
}
