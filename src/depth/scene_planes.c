/* scene_planes.c - dominant planes of the static depth and snapping onto them (see scene_planes.h). */
#include "depth/scene_planes.h"

#include "core/mathx.h"
#include "core/rng.h"
#include "depth/fuse.h"
#include "depth/plane.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Scoring a RANSAC sample looks at about this many pixels (a regular subsample). */
#define SCORE_PIXELS 20000
/* Snapping reaches this many pixels past a plane's inliers (the blend zone lives there). */
#define NEAR_RADIUS 3

void depth_scene_planes_defaults(depth_scene_planes_params *p)
{
    p->tolerance = 0.03f;
    p->min_support = 0.05f;
    p->max_planes = 6;
    p->iterations = 400;
    p->max_median_residual = 0.3f;
    p->min_frames = 3;
    p->seed = 1;
}

static inline double norm_x(int u, int W) { return (u + 0.5) / W - 0.5; }
static inline double norm_y(int v, int H) { return (v + 0.5) / H - 0.5; }

static inline double plane_inverse(const depth_scene_plane *pl, int u, int v, int W, int H)
{
    return pl->a * norm_x(u, W) + pl->b * norm_y(v, H) + pl->c;
}

float depth_scene_plane_depth(const depth_scene_plane *pl, int u, int v, int W, int H)
{
    double q = plane_inverse(pl, u, v, W, H);
    return q > 0 ? (float)(1.0 / q) : 0.0f;
}

/* |log(d / d_plane)| of depth d at (u, v); HUGE_VAL behind the camera. */
static inline double plane_residual(const depth_scene_plane *pl, float d, int u, int v, int W, int H)
{
    double r = d * plane_inverse(pl, u, v, W, H);
    return r > 0 ? fabs(log(r)) : HUGE_VAL;
}

static double det3(const double m[3][3])
{
    return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
}

/* Solves the 3x3 system m x = y by Cramer's rule into the plane's (a, b, c); 0 when (nearly)
 * singular (the plane is left as it was). */
static int solve_plane(const double m[3][3], const double y[3], depth_scene_plane *pl)
{
    double det = det3(m), scale = fabs(m[0][0]) + fabs(m[1][1]) + fabs(m[2][2]), x[3];
    if (!(fabs(det) > 1e-12 * scale * scale * scale)) return 0;
    for (int c = 0; c < 3; c++) {
        double t[3][3];
        memcpy(t, m, sizeof t);
        for (int r = 0; r < 3; r++) t[r][c] = y[r];
        x[c] = det3(t) / det;
    }
    pl->a = x[0];
    pl->b = x[1];
    pl->c = x[2];
    return 1;
}

/* Least squares of the relative residual, sum over inliers of (d q(x, y) - 1)^2: linear in (a, b, c),
 * and it weighs near and far pixels alike, as the multiplicative error of the depth asks. */
static int plane_refit(depth_scene_plane *pl, const float *ref, const unsigned char *inlier, int W, int H)
{
    double m[3][3] = { { 0 } }, y[3] = { 0 };
    for (int v = 0; v < H; v++)
        for (int u = 0; u < W; u++) {
            size_t k = (size_t)v * W + u;
            if (!inlier[k]) continue;
            double row[3] = { ref[k] * norm_x(u, W), ref[k] * norm_y(v, H), ref[k] };
            for (int i = 0; i < 3; i++) {
                y[i] += row[i];
                for (int j = 0; j < 3; j++) m[i][j] += row[i] * row[j];
            }
        }
    return solve_plane(m, y, pl);
}

/* The plane through three pixels of the static depth; 0 when they are (nearly) collinear. */
static int plane_through(depth_scene_plane *pl, const float *ref, const int *px, int W, int H)
{
    double m[3][3], y[3];
    for (int i = 0; i < 3; i++) {
        int u = px[i] % W, v = px[i] / W;
        m[i][0] = norm_x(u, W);
        m[i][1] = norm_y(v, H);
        m[i][2] = 1.0;
        y[i] = 1.0 / ref[px[i]];
    }
    double area = fabs((m[1][0] - m[0][0]) * (m[2][1] - m[0][1]) - (m[2][0] - m[0][0]) * (m[1][1] - m[0][1]));
    return area >= 4.0 / ((double)W * H) && solve_plane(m, y, pl); /* not under ~2 square pixels */
}

/* One RANSAC search on the free pixels: the first pixel anywhere, the other two within a window
 * around it (planes are compact regions, so local triples hit one plane far more often than
 * triples drawn from the whole image). Scored on a regular subsample. */
static long ransac_plane(const depth_scene_planes_params *p, const float *ref, const unsigned char *free_px,
                         const int *sample, long nsample, int W, int H, pg_rng *rng, depth_scene_plane *best)
{
    const double lo = exp(-p->tolerance), hi = exp(p->tolerance);
    const int R = (W > H ? W : H) / 10 > 8 ? (W > H ? W : H) / 10 : 8;
    long best_score = 0;
    for (int it = 0; it < p->iterations; it++) {
        int px[3], found = 0;
        for (int tries = 0; tries < 32 && !found; tries++) {
            int k = sample[pg_rng_below(rng, (uint32_t)nsample)];
            if (free_px[k]) px[0] = k, found = 1;
        }
        if (!found) continue;
        int u0 = px[0] % W, v0 = px[0] / W;
        for (int j = 1; j < 3 && found; j++) {
            found = 0;
            for (int tries = 0; tries < 32 && !found; tries++) {
                int u = u0 + (int)pg_rng_below(rng, 2 * R + 1) - R, v = v0 + (int)pg_rng_below(rng, 2 * R + 1) - R;
                if (u < 0 || v < 0 || u >= W || v >= H) continue;
                int k = v * W + u;
                if (free_px[k]) px[j] = k, found = 1;
            }
        }
        depth_scene_plane pl = { 0 };
        if (!found || !plane_through(&pl, ref, px, W, H)) continue;
        long score = 0;
        for (long s = 0; s < nsample; s++) {
            int k = sample[s];
            if (!free_px[k]) continue;
            double r = ref[k] * plane_inverse(&pl, k % W, k / W, W, H);
            score += r > lo && r < hi;
        }
        if (score > best_score) best_score = score, *best = pl;
    }
    return best_score;
}

/* Marks the free pixels within tolerance of pl in inlier[]; returns their count. */
static long plane_inliers(const depth_scene_plane *pl, const float *ref, const unsigned char *free_px, float tol, int W,
                          int H, unsigned char *inlier, float *resid)
{
    long count = 0;
    for (int v = 0; v < H; v++)
        for (int u = 0; u < W; u++) {
            size_t k = (size_t)v * W + u;
            double r = free_px[k] ? plane_residual(pl, ref[k], u, v, W, H) : HUGE_VAL;
            inlier[k] = r < tol;
            if (inlier[k] && resid) resid[count] = (float)r;
            count += inlier[k];
        }
    return count;
}

/* Greedy detection: best plane by RANSAC, refined on its inliers, removed; repeat. */
static void find_planes(const depth_scene_planes_params *p, const float *ref, int W, int H, unsigned char *free_px,
                        unsigned char *inlier, float *resid, int *sample, signed char *label,
                        depth_scene_planes_result *res)
{
    const size_t n = (size_t)W * H;
    const int stride = n > SCORE_PIXELS ? (int)ceil(sqrt((double)n / SCORE_PIXELS)) : 1;
    long nsample = 0, ngrid = 0;
    for (int v = stride / 2; v < H; v += stride)
        for (int u = stride / 2; u < W; u += stride, ngrid++)
            if (free_px[(size_t)v * W + u]) sample[nsample++] = v * W + u;
    pg_rng rng;
    pg_rng_seed(&rng, p->seed);
    int max_planes = p->max_planes < DEPTH_SCENE_PLANES_MAX ? p->max_planes : DEPTH_SCENE_PLANES_MAX;
    while (res->count < max_planes && nsample >= 3) {
        depth_scene_plane pl = { 0 };
        long score = ransac_plane(p, ref, free_px, sample, nsample, W, H, &rng, &pl);
        if (score < p->min_support * ngrid) break;
        for (int rep = 0; rep < 3; rep++) {
            plane_inliers(&pl, ref, free_px, p->tolerance, W, H, inlier, NULL);
            if (!plane_refit(&pl, ref, inlier, W, H)) break;
        }
        pl.inliers = plane_inliers(&pl, ref, free_px, p->tolerance, W, H, inlier, resid);
        if (pl.inliers < p->min_support * (double)n) break;
        qsort(resid, (size_t)pl.inliers, sizeof(float), pg_cmp_float);
        pl.median_residual = resid[pl.inliers / 2];
        /* A curved surface crossing the plane fills the band evenly (median near tolerance / 2); a
         * plane seen through smooth depth error piles its residuals up near 0. */
        if (pl.median_residual > p->max_median_residual * p->tolerance) break;
        for (size_t k = 0; k < n; k++)
            if (inlier[k]) label[k] = (signed char)res->count, free_px[k] = 0;
        res->planes[res->count++] = pl;
    }
}

/* Weight of the plane's depth for a pixel at relative residual r: 1 inside the tolerance, falling
 * linearly to 0 at twice it (no step where the snapped region ends). */
static inline double snap_weight(double r, double tol) { return r <= tol ? 1.0 : r >= 2 * tol ? 0.0 : (2 * tol - r) / tol; }

/* Moves each static pixel of every frame towards the plane it fits best among those whose
 * inliers lie within NEAR_RADIUS pixels. */
static long snap_frames(const depth_scene_planes_params *p, const depth_scene_planes_result *res, float *depth,
                        const unsigned char *static_masks, int F, int W, int H, const unsigned char *near)
{
    const size_t n = (size_t)W * H;
    long snapped = 0;
#pragma omp parallel for schedule(static) reduction(+ : snapped)
    for (int v = 0; v < H; v++)
        for (int u = 0; u < W; u++) {
            size_t k = (size_t)v * W + u;
            for (int f = 0; f < F; f++) {
                float *d = &depth[(size_t)f * n + k];
                if (!static_masks[(size_t)f * n + k] || !(*d > 0)) continue;
                double best_r = HUGE_VAL;
                int best = -1;
                for (int i = 0; i < res->count; i++) {
                    if (!near[(size_t)i * n + k]) continue;
                    double r = plane_residual(&res->planes[i], *d, u, v, W, H);
                    if (r < best_r) best_r = r, best = i;
                }
                double w = best >= 0 ? snap_weight(best_r, p->tolerance) : 0.0;
                if (w <= 0) continue;
                double dp = depth_scene_plane_depth(&res->planes[best], u, v, W, H);
                float out = (float)exp((1 - w) * log(*d) + w * log(dp));
                snapped += out != *d;
                *d = out;
            }
        }
    return snapped;
}

pg_status depth_scene_planes_snap(const depth_scene_planes_params *p, float *depth, const unsigned char *static_masks,
                                  int F, int W, int H, depth_scene_planes_result *res, signed char *label)
{
    memset(res, 0, sizeof *res);
    const size_t n = (size_t)W * H;
    if (label) memset(label, -1, n);
    if (F < 1 || n < 3) return PG_OK;
    int min_frames = p->min_frames < F ? p->min_frames : F;
    float *ref = pg_malloc(n * sizeof(float), "static depth for plane detection");
    float *resid = pg_malloc(n * sizeof(float), "plane residuals");
    unsigned char *free_px = pg_malloc(n, "plane detection mask");
    unsigned char *inlier = pg_malloc(n, "plane inliers");
    signed char *own_label = label ? NULL : pg_malloc(n, "plane labels");
    unsigned char *near = NULL;
    int *sample = pg_malloc(n * sizeof(int), "plane detection sample");
    pg_status st = PG_OK;
    if (!ref || !resid || !free_px || !inlier || (!label && !own_label) || !sample ||
        depth_static_reference(depth, static_masks, F, n, min_frames, ref) < 0)
        st = pg_fail(PG_ERR_NOMEM, "plane detection: out of memory for %d x %d", W, H);
    if (!st) {
        signed char *lab = label ? label : own_label; /* label was cleared on entry */
        if (own_label) memset(own_label, -1, n);
        for (size_t k = 0; k < n; k++) free_px[k] = ref[k] > 0 && isfinite(ref[k]);
        find_planes(p, ref, W, H, free_px, inlier, resid, sample, lab, res);
        if (res->count > 0) near = pg_malloc(n * (size_t)res->count, "plane neighbourhoods");
        if (res->count > 0 && !near) st = PG_ERR_NOMEM;
        for (int i = 0; i < res->count && near; i++) {
            for (size_t k = 0; k < n; k++) inlier[k] = lab[k] == i;
            depth_mask_dilate(inlier, W, H, NEAR_RADIUS, near + (size_t)i * n);
        }
        if (near) res->snapped = snap_frames(p, res, depth, static_masks, F, W, H, near);
    }
    free(ref);
    free(resid);
    free(free_px);
    free(inlier);
    free(own_label);
    free(near);
    free(sample);
    return st;
}
