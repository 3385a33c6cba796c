/* ground.c - the floor and the wall behind it from the vertical vanishing point (see ground.h). */
#include "depth/ground.h"

#include "core/mathx.h"
#include "core/parallel.h"
#include "core/rng.h"
#include "depth/plane.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define STILL_FRAMES 15
#define VP_SAMPLES 2000
#define VP_INLIER_DEG 1.5
#define WALL_SAMPLES 500
/* the floor lies at least this far below the horizon (up . ray, about 1 degree) */
#define BELOW_HORIZON 0.02
/* the floor's colour: the bottom rows' pixels within this of their dominant colour (per channel) */
#define SEED_RADIUS 0.15
/* pixels a floor column's top may climb on the sharper image */
#define EDGE_CLIMB 4

void depth_ground_defaults(depth_ground_params *p)
{
    p->focal = 0;
    p->up_known = 0;
    p->up[0] = p->up[1] = p->up[2] = 0;
    p->min_vp_share = 0.15f;
    p->max_tilt_deg = 60;
    p->colour_sigma = 3;
    p->min_floor_share = 0.1f;
    p->wall_tolerance = 0.02f;
    p->wall_min_span = 0.4f;
    p->wall_band = 0.35f;
    p->min_disagreement = 0.05f;
    p->floor_colour = 0.08f;
    p->object_join = 0.04f;
    p->min_contact = 3;
    p->seed = 1;
}

typedef struct {
    float x, y;   /* normalised camera coordinates ((u - cx) / f, (v - cy) / f) */
    float a, b;   /* unit normal of the edge (the gradient direction) */
    float w;      /* gradient magnitude */
} edgel;

/* The per-pixel median colour of up to STILL_FRAMES evenly spaced frames: the still scene. */
static void still_image(const pg_image *frames, int F, size_t n, float *rgb)
{
    int k = F < STILL_FRAMES ? F : STILL_FRAMES;
    float v[STILL_FRAMES];
    for (size_t i = 0; i < n; i++)
        for (int c = 0; c < 3; c++) {
            for (int j = 0; j < k; j++) v[j] = frames[k > 1 ? (long)j * (F - 1) / (k - 1) : 0].data[i * 3 + c];
            rgb[i * 3 + c] = pg_median_float(v, k);
        }
}

/* Each channel of an interleaved RGB image blurred by a Gaussian of sigma (in may be out). */
static void blur_rgb(const float *in, int W, int H, float sigma, float *grey, float *tmp, float *out)
{
    const size_t n = (size_t)W * H;
    for (int c = 0; c < 3; c++) {
        for (size_t i = 0; i < n; i++) grey[i] = in[i * 3 + c];
        depth_plane_gaussian_blur(grey, W, H, sigma, tmp, grey);
        for (size_t i = 0; i < n; i++) out[i * 3 + c] = grey[i];
    }
}

/* The ray through pixel (x, y)'s centre in camera coordinates, z = 1 (principal point at the
 * image centre, focal f). */
static void pixel_ray(int x, int y, int W, int H, double f, double r[3])
{
    r[0] = (x + 0.5 - 0.5 * W) / f;
    r[1] = (y + 0.5 - 0.5 * H) / f;
    r[2] = 1;
}

/* Is the edge through e pointing at the homogeneous point v (within VP_INLIER_DEG)? */
static int points_at(const edgel *e, const double v[3], double cos_tol)
{
    double dx = v[0] - e->x * v[2], dy = v[1] - e->y * v[2];
    double len = sqrt(dx * dx + dy * dy);
    return len > 0 && fabs(-e->b * dx + e->a * dy) > cos_tol * len;
}

static void cross3(const double a[3], const double b[3], double out[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

/* inv = A^-1 for a 3x3 matrix (row-major) by cofactors; returns 0 when A is singular. */
static int invert3(const double A[9], double inv[9])
{
    double c0 = A[4] * A[8] - A[5] * A[7], c1 = A[5] * A[6] - A[3] * A[8], c2 = A[3] * A[7] - A[4] * A[6];
    double det = A[0] * c0 + A[1] * c1 + A[2] * c2;
    if (!(fabs(det) > 1e-300)) return 0;
    const double adj[9] = { c0, A[2] * A[7] - A[1] * A[8], A[1] * A[5] - A[2] * A[4],
                            c1, A[0] * A[8] - A[2] * A[6], A[2] * A[3] - A[0] * A[5],
                            c2, A[1] * A[6] - A[0] * A[7], A[0] * A[4] - A[1] * A[3] };
    for (int k = 0; k < 9; k++) inv[k] = adj[k] / det;
    return 1;
}

/* The eigenvector of the symmetric 3x3 M with the smallest eigenvalue, by inverse iteration
 * from v (the RANSAC estimate, close to it). */
static void smallest_eigenvector(const double M[9], double v[3])
{
    double tr = M[0] + M[4] + M[8], A[9];
    memcpy(A, M, sizeof A);
    for (int k = 0; k < 3; k++) A[k * 4] += 1e-9 * tr + 1e-300;
    double inv[9];
    if (!invert3(A, inv)) return;
    for (int it = 0; it < 30; it++) {
        double w[3];
        for (int r = 0; r < 3; r++) w[r] = inv[r * 3] * v[0] + inv[r * 3 + 1] * v[1] + inv[r * 3 + 2] * v[2];
        double nrm = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
        if (!(nrm > 0)) return;
        for (int r = 0; r < 3; r++) v[r] = w[r] / nrm;
    }
}

/* The vertical vanishing point as a unit direction in camera coordinates, from the
 * near-vertical edges of the grey still image. Returns the inliers' share of the edge weight. */
static double vertical_vanishing_point(const float *grey, int W, int H, double f, pg_rng *rng, double dir[3])
{
    size_t n = (size_t)W * H, m = 0;
    float *mag = malloc(n * sizeof *mag);
    edgel *e = malloc(n * sizeof *e);
    double share = 0;
    if (!mag || !e) goto done;
    for (int y = 1; y < H - 1; y++)
        for (int x = 1; x < W - 1; x++) {
            const float *g = grey + (size_t)y * W + x;
            float gx = (g[1 - W] + 2 * g[1] + g[1 + W] - g[-1 - W] - 2 * g[-1] - g[-1 + W]) / 8;
            float gy = (g[W - 1] + 2 * g[W] + g[W + 1] - g[-W - 1] - 2 * g[-W] - g[-W + 1]) / 8;
            double r[3];
            pixel_ray(x, y, W, H, f, r);
            mag[m] = hypotf(gx, gy);
            e[m] = (edgel){ (float)r[0], (float)r[1], gx, gy, mag[m] };
            m++;
        }
    /* strong edges (the top fifth, at least 0.01 per pixel) whose direction is within 35 degrees
     * of the image's vertical */
    float *sorted = malloc(m * sizeof *sorted);
    if (!sorted) goto done;
    memcpy(sorted, mag, m * sizeof *sorted);
    qsort(sorted, m, sizeof *sorted, pg_cmp_float);
    float thr = sorted[m * 4 / 5] > 0.01f ? sorted[m * 4 / 5] : 0.01f;
    free(sorted);
    size_t k = 0;
    double total = 0;
    const double sin35 = sin(35 * 3.14159265358979 / 180);
    for (size_t i = 0; i < m; i++) {
        if (!(e[i].w > thr)) continue;
        float a = e[i].a / e[i].w, b = e[i].b / e[i].w;
        if (fabs(b) >= sin35) continue; /* the edge runs along (-b, a): near vertical when |b| is small */
        e[k] = e[i];
        e[k].a = a, e[k].b = b;
        total += e[k].w;
        k++;
    }
    if (k < 50) goto done;
    const double cos_tol = cos(VP_INLIER_DEG * 3.14159265358979 / 180), min_dx = 0.125 * W / f;
    double best = 0, v[3] = { 0, 1, 0 };
    for (int s = 0; s < VP_SAMPLES; s++) {
        const edgel *p = &e[pg_rng_below(rng, (uint32_t)k)], *q = &e[pg_rng_below(rng, (uint32_t)k)];
        if (fabs(p->x - q->x) < min_dx) continue;
        double l1[3] = { p->a, p->b, -(p->a * p->x + p->b * p->y) }, l2[3] = { q->a, q->b, -(q->a * q->x + q->b * q->y) }, c[3];
        cross3(l1, l2, c);
        double score = 0;
        for (size_t i = 0; i < k; i++)
            if (points_at(&e[i], c, cos_tol)) score += e[i].w;
        if (score > best) best = score, memcpy(v, c, sizeof v);
    }
    /* least squares on the inliers: the point closest to all their lines */
    for (int round = 0; round < 3 && best > 0; round++) {
        double nv = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]), M[9] = { 0 };
        for (int r = 0; r < 3; r++) v[r] /= nv;
        best = 0;
        for (size_t i = 0; i < k; i++) {
            if (!points_at(&e[i], v, cos_tol)) continue;
            double l[3] = { e[i].a, e[i].b, -(e[i].a * e[i].x + e[i].b * e[i].y) };
            for (int r = 0; r < 3; r++)
                for (int c = 0; c < 3; c++) M[r * 3 + c] += e[i].w * l[r] * l[c];
            best += e[i].w;
        }
        smallest_eigenvector(M, v);
    }
    share = total > 0 ? best / total : 0;
    memcpy(dir, v, sizeof v);
done:
    free(mag);
    free(e);
    return share;
}

/* Max (grow = 1) or min (grow = 0) of a mask over a (2r+1)^2 square, separably. */
static void square_morph(unsigned char *m, unsigned char *tmp, int W, int H, int r, int grow)
{
    for (int pass = 0; pass < 2; pass++) {
        const unsigned char *src = pass ? tmp : m;
        unsigned char *dst = pass ? m : tmp;
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++) {
                int v = grow ? 0 : 1;
                for (int d = -r; d <= r; d++) {
                    int xx = pass ? x : x + d, yy = pass ? y + d : y;
                    if (xx < 0 || yy < 0 || xx >= W || yy >= H) continue;
                    int s = src[(size_t)yy * W + xx];
                    v = grow ? (v | s) : (v & s);
                }
                dst[(size_t)y * W + x] = (unsigned char)v;
            }
    }
}

/* Is colour v within SEED_RADIUS of mean in every channel? */
static int near_colour(const float *v, const double mean[3])
{
    return fabs(v[0] - mean[0]) <= SEED_RADIUS && fabs(v[1] - mean[1]) <= SEED_RADIUS && fabs(v[2] - mean[2]) <= SEED_RADIUS;
}

/* Mahalanobis distance squared of colour v from mean under the inverse covariance inv. */
static double colour_distance(const float *v, const double mean[3], const double inv[9])
{
    double d[3] = { v[0] - mean[0], v[1] - mean[1], v[2] - mean[2] }, q = 0;
    for (int r = 0; r < 3; r++) q += d[r] * (inv[r * 3] * d[0] + inv[r * 3 + 1] * d[1] + inv[r * 3 + 2] * d[2]);
    return q;
}

/* The floor: grown from the bottom rows through pixels of their colour (Mahalanobis distance in
 * the still image blurred by sigma 2, which the texture does not break), below the horizon;
 * closed over 5x5 so the texture leaves no holes. The blur stops the region a few pixels short
 * of a wall's foot, where a pixel's depth changes fastest: each column's top then climbs up to
 * EDGE_CLIMB pixels while the less blurred image (rgb1) is still the floor's colour. */
static double grow_floor(const float *rgb, const float *rgb1, const float *below, int W, int H, float sigma, unsigned char *is_floor)
{
    memset(is_floor, 0, (size_t)W * H);
    size_t n = (size_t)W * H, seeds = 0, kept = 0;
    int y0 = H - (H + 15) / 16;
    float *seed = malloc((size_t)W * (H - y0) * 3 * sizeof *seed), *chan = malloc((size_t)W * (H - y0) * sizeof *chan);
    if (!seed || !chan) {
        free(seed);
        free(chan);
        return -1;
    }
    for (int y = y0; y < H; y++)
        for (int x = 0; x < W; x++) {
            size_t i = (size_t)y * W + x;
            if (below[i] > -BELOW_HORIZON) continue;
            memcpy(seed + seeds * 3, rgb + i * 3, 3 * sizeof *seed);
            seeds++;
        }
    /* the bottom rows' dominant colour: from the median, three rounds of the mean of the seeds
     * within SEED_RADIUS of it (a table or a person there is not the floor) */
    double mean[3] = { 0 }, cov[9] = { 0 };
    for (int c = 0; c < 3; c++) {
        for (size_t s = 0; s < seeds; s++) chan[s] = seed[s * 3 + c];
        mean[c] = pg_median_float(chan, (int)seeds);
    }
    for (int round = 0; round < 3 && seeds; round++) {
        double sum[3] = { 0 };
        kept = 0;
        for (size_t s = 0; s < seeds; s++) {
            const float *v = seed + s * 3;
            if (!near_colour(v, mean)) continue;
            for (int c = 0; c < 3; c++) sum[c] += v[c];
            kept++;
        }
        for (int c = 0; c < 3 && kept; c++) mean[c] = sum[c] / (double)kept;
    }
    for (size_t s = 0; s < seeds && kept; s++) {
        const float *v = seed + s * 3;
        if (!near_colour(v, mean)) continue;
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++) cov[r * 3 + c] += (v[r] - mean[r]) * (v[c] - mean[c]) / (double)kept;
    }
    free(seed);
    free(chan);
    if (seeds < (size_t)W || kept < seeds / 2) return 0; /* no floor colour holds most of the bottom rows */
    for (int c = 0; c < 3; c++) cov[c * 4] += 1e-4;
    double inv[9];
    if (!invert3(cov, inv)) return 0; /* cannot happen: the diagonal is raised by 1e-4 */
    size_t *queue = malloc(n * sizeof *queue);
    unsigned char *tmp = malloc(n);
    if (!queue || !tmp) {
        free(queue);
        free(tmp);
        return -1;
    }
    /* candidates: 1; reached from a seed: 2 */
    for (size_t i = 0; i < n; i++) is_floor[i] = colour_distance(rgb + i * 3, mean, inv) < (double)sigma * sigma && below[i] <= -BELOW_HORIZON;
    size_t head = 0, tail = 0;
    for (int y = y0; y < H; y++)
        for (int x = 0; x < W; x++) {
            size_t i = (size_t)y * W + x;
            if (is_floor[i] == 1) is_floor[i] = 2, queue[tail++] = i;
        }
    while (head < tail) {
        size_t i = queue[head++];
        int x = (int)(i % W), y = (int)(i / W);
        size_t nb[4] = { i - 1, i + 1, i - W, i + W };
        int ok[4] = { x > 0, x < W - 1, y > 0, y < H - 1 };
        for (int k = 0; k < 4; k++)
            if (ok[k] && is_floor[nb[k]] == 1) is_floor[nb[k]] = 2, queue[tail++] = nb[k];
    }
    for (size_t i = 0; i < n; i++) is_floor[i] = is_floor[i] == 2;
    square_morph(is_floor, tmp, W, H, 2, 1);
    square_morph(is_floor, tmp, W, H, 2, 0);
    for (size_t i = 0; i < n; i++) is_floor[i] = is_floor[i] && below[i] <= -BELOW_HORIZON;
    for (int x = 0; x < W; x++)
        for (int y = 1; y < H; y++) {
            size_t i = (size_t)y * W + x;
            if (!is_floor[i] || is_floor[i - W]) continue;
            for (int k = 1; k <= EDGE_CLIMB && y - k >= 0; k++) {
                size_t j = (size_t)(y - k) * W + x;
                if (is_floor[j] || below[j] > -BELOW_HORIZON || colour_distance(rgb1 + j * 3, mean, inv) >= 4.0 * sigma * sigma) break;
                is_floor[j] = 3; /* climbed: not a start for this column's next climb */
            }
        }
    size_t count = 0;
    for (size_t i = 0; i < n; i++) {
        is_floor[i] = is_floor[i] != 0;
        count += is_floor[i];
    }
    free(queue);
    free(tmp);
    return (double)count / (double)n;
}

/* Does contact point k (3D point X, floor-plane coordinates q) lie on the line through q0 with
 * unit normal n, within tol of its range? */
static int on_line(const double X[3], const double q[2], const double q0[2], const double n[2], double tol)
{
    double dist = fabs((q[0] - q0[0]) * n[0] + (q[1] - q0[1]) * n[1]);
    return dist < tol * sqrt(X[0] * X[0] + X[1] * X[1] + X[2] * X[2]);
}

/* The vertical plane standing on the floor's top edge, when that edge is a straight line in 3D:
 * RANSAC over the contact points in the floor plane's coordinates, then a total least squares
 * refit. Writes its depth per pixel (0 where it is behind the camera); returns the inliers' span
 * as a share of the width, 0 if there is no such line. */
static double wall_plane(const int *top, const float *floor_depth, int W, int H, double f, const double up[3], const depth_ground_params *p,
                         pg_rng *rng, float *wall_depth)
{
    double e1[3] = { up[1], -up[0], 0 }, e2[3];
    double l1 = sqrt(e1[0] * e1[0] + e1[1] * e1[1]);
    if (!(l1 > 1e-6)) return 0;
    e1[0] /= l1, e1[1] /= l1;
    cross3(up, e1, e2);
    double *P = malloc((size_t)W * 3 * sizeof *P), *Q = malloc((size_t)W * 2 * sizeof *Q);
    int *col = malloc((size_t)W * sizeof *col), m = 0;
    double span = 0;
    if (!P || !Q || !col) goto done;
    for (int x = 0; x < W; x++) {
        if (top[x] < 0) continue;
        double z = floor_depth[(size_t)top[x] * W + x], *X = P + (size_t)m * 3;
        pixel_ray(x, top[x], W, H, f, X);
        for (int c = 0; c < 3; c++) X[c] *= z;
        Q[m * 2] = X[0] * e1[0] + X[1] * e1[1] + X[2] * e1[2];
        Q[m * 2 + 1] = X[0] * e2[0] + X[1] * e2[1] + X[2] * e2[2];
        col[m++] = x;
    }
    if (m < W / 4) goto done;
    int best = 0;
    double bn[2] = { 0, 0 }, bq[2] = { 0, 0 };
    for (int s = 0; s < WALL_SAMPLES; s++) {
        int i = (int)pg_rng_below(rng, (uint32_t)m), j = (int)pg_rng_below(rng, (uint32_t)m);
        if (abs(col[i] - col[j]) < W / 6) continue;
        double dx = Q[j * 2] - Q[i * 2], dy = Q[j * 2 + 1] - Q[i * 2 + 1], len = sqrt(dx * dx + dy * dy);
        if (!(len > 0)) continue;
        const double nrm[2] = { -dy / len, dx / len };
        int count = 0;
        for (int k = 0; k < m; k++) count += on_line(P + (size_t)k * 3, Q + k * 2, Q + i * 2, nrm, p->wall_tolerance);
        if (count > best) best = count, bn[0] = nrm[0], bn[1] = nrm[1], bq[0] = Q[i * 2], bq[1] = Q[i * 2 + 1];
    }
    if (best < W / 4) goto done;
    /* total least squares over the inliers: the line through their mean along their main axis */
    double mq[2] = { 0, 0 }, sxx = 0, sxy = 0, syy = 0;
    int lo = W, hi = -1, cnt = 0;
    for (int k = 0; k < m; k++) {
        if (!on_line(P + (size_t)k * 3, Q + k * 2, bq, bn, p->wall_tolerance)) continue;
        mq[0] += Q[k * 2], mq[1] += Q[k * 2 + 1], cnt++;
        lo = col[k] < lo ? col[k] : lo, hi = col[k] > hi ? col[k] : hi;
    }
    mq[0] /= cnt, mq[1] /= cnt;
    for (int k = 0; k < m; k++) {
        if (!on_line(P + (size_t)k * 3, Q + k * 2, bq, bn, p->wall_tolerance)) continue;
        double a = Q[k * 2] - mq[0], b = Q[k * 2 + 1] - mq[1];
        sxx += a * a, sxy += a * b, syy += b * b;
    }
    double angle = 0.5 * atan2(2 * sxy, sxx - syy); /* the main axis */
    double nx = -sin(angle), ny = cos(angle);
    span = (double)(hi - lo) / W;
    if (span < p->wall_min_span) {
        span = 0;
        goto done;
    }
    double wn[3], wd;
    for (int r = 0; r < 3; r++) wn[r] = nx * e1[r] + ny * e2[r];
    wd = mq[0] * nx + mq[1] * ny; /* wn . X for X on the wall (e1, e2 orthonormal) */
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            double den = wn[0] * (x + 0.5 - 0.5 * W) / f + wn[1] * (y + 0.5 - 0.5 * H) / f + wn[2];
            double z = fabs(den) > 1e-9 ? wd / den : 0;
            wall_depth[(size_t)y * W + x] = z > 0 ? (float)z : 0.0f;
        }
done:
    free(P);
    free(Q);
    free(col);
    return span;
}

/* Scratch for stand_on_floor, one frame's worth. */
typedef struct {
    unsigned char *floor; /* the floor as this frame shows it */
    float *rgb, *grey, *tmp; /* the frame, blurred like the still image */
    int *label, *stack, *first, *count, *contact;
    unsigned char *moving; /* per blob */
    float *ratio, *factor;
    float *sheet;          /* per blob: unit normal and distance of a mover's sheet (distance 0: none) */
} anchor_scratch;

/* Every object stands where it meets the floor. A monocular network's error is smooth across the
 * image, so a still object's depth is off by what the floor's is off by where it touches it: the
 * still pixels that are not floor are grouped into depth-continuous blobs (|log| step under
 * p->object_join), and a blob with floor directly below some of its pixels is scaled by the
 * median plane / depth over them. Movers are grouped by connection alone and, standing on the
 * floor, become vertical sheets through their contacts. A blob that touches no floor takes rest
 * (the wall's factor). Moving pixels over the floor whose colour is the still image's there are
 * floor (the ring a dilated mask puts around a mover). Writes the frame's floor mask, each pixel's
 * blob and each blob's factor and sheet into a; returns the number of blobs. */
static int stand_on_floor(const pg_image *frame, const float *d, const unsigned char *s, const unsigned char *is_floor,
                          const float *floor_depth, const float *still_rgb, int W, int H, double focal, const double up[3],
                          double rest, const depth_ground_params *p, anchor_scratch *a)
{
    const size_t n = (size_t)W * H;
    blur_rgb(frame->data, W, H, 1.0f, a->grey, a->tmp, a->rgb);
    for (size_t i = 0; i < n; i++) {
        float off = 0;
        for (int c = 0; c < 3; c++) off = fmaxf(off, fabsf(a->rgb[i * 3 + c] - still_rgb[i * 3 + c]));
        a->floor[i] = is_floor[i] && (s[i] || off < p->floor_colour);
    }
    for (size_t i = 0; i < n; i++) a->label[i] = -1;
    const float join = p->object_join;
    int blobs = 0;
    for (size_t seed = 0; seed < n; seed++) {
        if (a->floor[seed] || a->label[seed] >= 0 || !(d[seed] > 0)) continue;
        const int moving = !s[seed];
        int top = 0;
        a->stack[top++] = (int)seed;
        a->label[seed] = blobs;
        while (top > 0) {
            int i = a->stack[--top], x = i % W, y = i / W;
            int nb[4] = { x > 0 ? i - 1 : -1, x < W - 1 ? i + 1 : -1, y > 0 ? i - W : -1, y < H - 1 ? i + W : -1 };
            for (int k = 0; k < 4; k++) {
                int j = nb[k];
                if (j < 0 || a->floor[j] || a->label[j] >= 0 || !(d[j] > 0) || (s[j] == 0) != moving) continue;
                if (!moving && fabsf(logf(d[j] / d[i])) >= join) continue;
                a->label[j] = blobs;
                a->stack[top++] = j;
            }
        }
        a->moving[blobs++] = (unsigned char)moving;
    }
    /* the contact ratios, grouped by blob */
    for (int b = 0; b < blobs; b++) a->count[b] = 0;
    for (size_t i = 0; i + W < n; i++)
        if (a->label[i] >= 0 && a->floor[i + W]) a->count[a->label[i]]++;
    int total = 0;
    for (int b = 0; b < blobs; b++) a->first[b] = total, total += a->count[b], a->count[b] = 0;
    for (size_t i = 0; i + W < n; i++)
        if (a->label[i] >= 0 && a->floor[i + W]) {
            int b = a->label[i];
            a->contact[a->first[b] + a->count[b]] = (int)(i + W);
            a->ratio[a->first[b] + a->count[b]++] = logf(floor_depth[i + W] / d[i + W]);
        }
    /* the contact bounds an object from behind: what stands on the floor is not behind the floor
     * seen just below it (a ball's silhouette ends in front of its contact, a lifted block's far in
     * front), so a network that puts it nearer than that keeps its depth, times rest */
    for (int b = 0; b < blobs; b++)
        a->factor[b] = a->count[b] >= p->min_contact ? fminf(expf(pg_median_float(a->ratio + a->first[b], a->count[b])), (float)rest)
                                                     : (float)rest;
    /* a mover standing on the floor is a vertical sheet through its contact, facing the camera:
     * FastDepth draws classroom_cam3's walking person at the wall's depth above the waist, and a
     * sheet at his feet keeps him whole. Its normal: the horizontal part of the mean contact
     * point's direction; its distance: the median over the contacts. */
    for (int b = 0; b < blobs; b++) {
        float *sheet = a->sheet + b * 4;
        sheet[3] = 0;
        if (!a->moving[b] || a->count[b] < p->min_contact) continue;
        double mean[3] = { 0, 0, 0 };
        for (int k = 0; k < a->count[b]; k++) {
            int j = a->contact[a->first[b] + k];
            double r[3];
            pixel_ray(j % W, j / W, W, H, focal, r);
            for (int c = 0; c < 3; c++) mean[c] += floor_depth[j] * r[c];
        }
        double along = mean[0] * up[0] + mean[1] * up[1] + mean[2] * up[2], nrm[3], len = 0;
        for (int c = 0; c < 3; c++) nrm[c] = mean[c] - along * up[c], len += nrm[c] * nrm[c];
        if (!(len > 0)) continue;
        len = sqrt(len);
        for (int k = 0; k < a->count[b]; k++) {
            int j = a->contact[a->first[b] + k];
            double r[3];
            pixel_ray(j % W, j / W, W, H, focal, r);
            a->ratio[a->first[b] + k] = (float)(floor_depth[j] * (nrm[0] * r[0] + nrm[1] * r[1] + nrm[2] * r[2]) / len);
        }
        for (int c = 0; c < 3; c++) sheet[c] = (float)(nrm[c] / len);
        sheet[3] = pg_median_float(a->ratio + a->first[b], a->count[b]);
    }
    return blobs;
}

/* A rig of cameras standing around the scene (a dome, a ring; not a forward-facing row) knows the
 * vertical: the camera centres spread least along it, and cameras are mounted roughly upright, so
 * the sign is the one against their mean image-down direction. Accepted when the cameras' optical
 * axes average to under half a unit (they look in from around) and the centres' least variance is
 * under 0.36 of the mean of the other two. */
int depth_ground_rig_up(const pg_camera *cams, int count, int ref, float up[3])
{
    if (count < 4 || ref < 0 || ref >= count) return 0;
    double mean[3] = { 0 }, axis[3] = { 0 }, down[3] = { 0 }, M[9] = { 0 };
    float C[32][3];
    if (count > 32) count = 32;
    for (int k = 0; k < count; k++) {
        pg_camera_center(&cams[k], C[k]);
        for (int r = 0; r < 3; r++) {
            mean[r] += C[k][r] / count;
            axis[r] += cams[k].R[6 + r] / count;
            down[r] += cams[k].R[3 + r] / count;
        }
    }
    if (sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]) >= 0.5) return 0;
    for (int k = 0; k < count; k++)
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++) M[r * 3 + c] += (C[k][r] - mean[r]) * (C[k][c] - mean[c]);
    double v[3] = { -down[0], -down[1], -down[2] };
    smallest_eigenvector(M, v);
    double Mv[3], least = 0, trace = M[0] + M[4] + M[8];
    for (int r = 0; r < 3; r++) Mv[r] = M[r * 3] * v[0] + M[r * 3 + 1] * v[1] + M[r * 3 + 2] * v[2];
    least = v[0] * Mv[0] + v[1] * Mv[1] + v[2] * Mv[2];
    if (!(least < 0.36 * 0.5 * (trace - least))) return 0;
    if (v[0] * down[0] + v[1] * down[1] + v[2] * down[2] > 0) v[0] = -v[0], v[1] = -v[1], v[2] = -v[2];
    const float *R = cams[ref].R;
    for (int r = 0; r < 3; r++) up[r] = (float)(R[r * 3] * v[0] + R[r * 3 + 1] * v[1] + R[r * 3 + 2] * v[2]);
    return 1;
}

pg_status depth_ground_snap(const depth_ground_params *p, const pg_image *frames, int F, float *depth,
                            const unsigned char *static_masks, const float *still, int W, int H, depth_ground_result *res)
{
    memset(res, 0, sizeof *res);
    if (!(p->focal > 0) || F < 1 || W < 16 || H < 16) return PG_OK;
    const size_t n = (size_t)W * H;
    const double f = p->focal;
    pg_status st = PG_OK;
    float *rgb = malloc(n * 3 * sizeof *rgb), *rgb2 = malloc(n * 3 * sizeof *rgb2), *grey = malloc(n * sizeof *grey), *tmp = malloc(n * sizeof *tmp);
    float *below = malloc(n * sizeof *below), *floor_depth = malloc(n * sizeof *floor_depth);
    float *wall_depth = calloc(n, sizeof *wall_depth), *ratios = malloc(n * sizeof *ratios);
    unsigned char *is_floor = malloc(n);
    int *top = malloc((size_t)W * sizeof *top);
    anchor_scratch a = { .floor = malloc(n), .rgb = malloc(n * 3 * sizeof(float)), .grey = malloc(n * sizeof(float)),
                         .tmp = malloc(n * sizeof(float)), .label = malloc(n * sizeof(int)), .stack = malloc(n * sizeof(int)),
                         .first = malloc(n * sizeof(int)), .count = malloc(n * sizeof(int)), .contact = malloc(n * sizeof(int)),
                         .moving = malloc(n), .ratio = malloc(n * sizeof(float)), .factor = malloc(n * sizeof(float)),
                         .sheet = malloc(n * 4 * sizeof(float)) };
    if (!rgb || !rgb2 || !grey || !tmp || !below || !floor_depth || !wall_depth || !ratios || !is_floor || !top || !a.floor ||
        !a.rgb || !a.grey || !a.tmp || !a.label || !a.stack || !a.first || !a.count || !a.ratio || !a.factor || !a.contact || !a.moving ||
        !a.sheet) {
        st = PG_ERR_NOMEM;
        goto done;
    }
    pg_rng rng;
    pg_rng_seed(&rng, p->seed);
    still_image(frames, F, n, rgb);
    for (size_t i = 0; i < n; i++) grey[i] = (rgb[i * 3] + rgb[i * 3 + 1] + rgb[i * 3 + 2]) / 3;
    depth_plane_gaussian_blur(grey, W, H, 1.0f, tmp, grey);
    double dir[3] = { p->up[0], p->up[1], p->up[2] };
    if (!p->up_known) res->vp_share = vertical_vanishing_point(grey, W, H, f, &rng, dir);
    double len = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
    if (!(p->up_known || res->vp_share >= p->min_vp_share) || !(len > 0)) goto done;
    double sgn = dir[1] < 0 ? 1 / len : -1 / len; /* up points to the image's top (-y) */
    for (int r = 0; r < 3; r++) res->up[r] = dir[r] * sgn;
    res->tilt_deg = acos(-res->up[1] < 1 ? -res->up[1] : 1) * 180 / 3.14159265358979;
    if (!(res->tilt_deg <= p->max_tilt_deg)) goto done;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            below[(size_t)y * W + x] = (float)(res->up[0] * (x + 0.5 - 0.5 * W) / f + res->up[1] * (y + 0.5 - 0.5 * H) / f + res->up[2]);
    blur_rgb(rgb, W, H, 1.0f, grey, tmp, rgb);
    blur_rgb(rgb, W, H, 1.7f, grey, tmp, rgb2); /* sigma 2 in all */
    res->floor_share = grow_floor(rgb2, rgb, below, W, H, p->colour_sigma, is_floor);
    if (res->floor_share < 0) {
        st = PG_ERR_NOMEM;
        goto done;
    }
    if (res->floor_share < p->min_floor_share) goto done;
    /* the height that the still depth implies over the floor: z = h / (-up . ray) */
    size_t m = 0;
    for (size_t i = 0; i < n; i++)
        if (is_floor[i] && still[i] > 0) ratios[m++] = logf(still[i] * -below[i]);
    if (m < n / 20) goto done;
    res->height = exp(pg_median_float(ratios, (int)m));
    /* a depth that already draws this floor (within the vanishing point's own uncertainty) is
     * left as it is: the plane would only trade its error for the tilt's */
    for (size_t k = 0; k < m; k++) ratios[k] = fabsf(ratios[k] - (float)log(res->height));
    res->floor_disagreement = pg_median_float(ratios, (int)m);
    if (res->floor_disagreement < p->min_disagreement) goto done;
    for (size_t i = 0; i < n; i++) floor_depth[i] = below[i] < 0 ? (float)(res->height / -below[i]) : 0.0f;
    /* the floor's top edge in each column (the floor run that starts in the bottom rows), and the
     * factor that makes what stands there meet it */
    m = 0;
    for (int x = 0; x < W; x++) {
        int y = H - 1;
        while (y > H - 8 && !is_floor[(size_t)y * W + x]) y--;
        top[x] = -1;
        if (!is_floor[(size_t)y * W + x]) continue;
        while (y > 0 && is_floor[(size_t)(y - 1) * W + x]) y--;
        top[x] = y;
        size_t above = (size_t)(y - 1) * W + x;
        if (y > 0 && still[above] > 0) ratios[m++] = logf(floor_depth[(size_t)y * W + x] / still[above]);
    }
    res->rest_scale = m >= (size_t)W / 8 ? exp(pg_median_float(ratios, (int)m)) : 1.0;
    res->wall_span = wall_plane(top, floor_depth, W, H, f, res->up, p, &rng, wall_depth);
    res->wall = res->wall_span > 0;
    res->found = 1;
    const float band = p->wall_band;
    for (int t = 0; t < F; t++) {
        float *d = depth + (size_t)t * n;
        const unsigned char *s = static_masks + (size_t)t * n;
        int blobs = stand_on_floor(&frames[t], d, s, is_floor, floor_depth, rgb, W, H, f, res->up, res->rest_scale, p, &a);
        for (int b = 0; b < blobs; b++) res->anchored += a.count[b] >= p->min_contact;
        res->blobs += blobs;
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++) {
                size_t i = (size_t)y * W + x;
                float v = d[i], o = v;
                if (!(v > 0)) continue;
                if (a.floor[i]) {
                    v = floor_depth[i];
                } else {
                    const float *sheet = a.sheet + a.label[i] * 4;
                    double facing = sheet[3] > 0 ? sheet[0] * (x + 0.5 - 0.5 * W) / f + sheet[1] * (y + 0.5 - 0.5 * H) / f + sheet[2] : 0;
                    v = facing > 0.05 ? (float)(sheet[3] / facing) : v * a.factor[a.label[i]];
                    float w = wall_depth[i];
                    if (res->wall && s[i] && !is_floor[i] && top[x] > y && w > 0 && (fabsf(logf(v / w)) < band || v > w)) v = w;
                }
                if (v != o) d[i] = v, res->changed++;
            }
    }
done:
    free(rgb);
    free(rgb2);
    free(grey);
    free(tmp);
    free(below);
    free(floor_depth);
    free(wall_depth);
    free(ratios);
    free(is_floor);
    free(top);
    free(a.floor);
    free(a.rgb);
    free(a.grey);
    free(a.tmp);
    free(a.label);
    free(a.stack);
    free(a.first);
    free(a.count);
    free(a.ratio);
    free(a.factor);
    free(a.contact);
    free(a.moving);
    free(a.sheet);
    return st;
}
