/* movers_front.c - moving blobs brought in front of the still scene they cover (movers_front.h). */
#include "depth/movers_front.h"

#include "core/mathx.h"
#include "core/parallel.h"
#include "depth/align.h"
#include "depth/fuse.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

void depth_movers_front_defaults(depth_movers_front_params *p, int width, int height)
{
    long area = (long)width * height / 1000;
    p->min_area = area > 16 ? (int)area : 16;
    p->quantile = 0.03f;
    p->tolerance = 0.05f;
    p->window = 3;
}

/* Labels the 4-connected blob of non-still pixels around seed with `label` and lists its pixels.
 * Returns its size. */
static int grow_blob(const unsigned char *still, int16_t *labels, int W, int H, int seed, int16_t label, int *pixels)
{
    int count = 0, head = 0;
    pixels[count++] = seed;
    labels[seed] = label;
    while (head < count) {
        int k = pixels[head++], x = k % W, y = k / W;
        int next[4] = { x > 0 ? k - 1 : -1, x < W - 1 ? k + 1 : -1, y > 0 ? k - W : -1, y < H - 1 ? k + W : -1 };
        for (int e = 0; e < 4; e++) {
            int m = next[e];
            if (m < 0 || labels[m] || still[m]) continue;
            labels[m] = label;
            pixels[count++] = m;
        }
    }
    return count;
}

/* The factor that brings a blob in front of its background: the quantile of background / depth
 * over its pixels with both, or 1 when that is within the tolerance (or too few pixels tell). */
static float blob_factor(const float *d, const float *background, const int *pixels, int count, float *ratios,
                         const depth_movers_front_params *p)
{
    int m = 0;
    for (int i = 0; i < count; i++) {
        int k = pixels[i];
        if (depth_valid(d[k]) && background[k] > 0) ratios[m++] = background[k] / d[k];
    }
    if (m < p->min_area / 2) return 1.0f;
    qsort(ratios, (size_t)m, sizeof(float), pg_cmp_float);
    float q = ratios[(int)(p->quantile * (float)(m - 1))];
    return q < 1.0f - p->tolerance ? q : 1.0f;
}

/* The median still depth behind a blob, over its pixels that have one (0 when none does): the
 * background of its pixels that were never still. */
static float blob_behind(const float *background, const int *pixels, int count, float *vals)
{
    int m = 0;
    for (int i = 0; i < count; i++)
        if (background[pixels[i]] > 0) vals[m++] = background[pixels[i]];
    return m ? pg_median_float(vals, m) : 0.0f;
}

typedef struct {
    int16_t *labels; /* (F, n) blob of each pixel, 1-based within its frame; 0 = none or too small */
    float *factor;  /* (F, max_blobs) each blob's own factor */
    float *behind;  /* (F, max_blobs) the still depth behind each blob (blob_behind) */
    int *count;     /* (F) blobs per frame */
    int max_blobs;
} blob_set;

/* Pass 1: the blobs of frame f and their own factors. While labelling, -1 marks a visited pixel
 * of a blob below min_area (or past max_blobs); such pixels end with label 0. */
static void label_frame(blob_set *b, const float *d, const unsigned char *still, const float *background, int f, int W, int H,
                        int *pixels, float *ratios, const depth_movers_front_params *p)
{
    const size_t n = (size_t)W * H;
    int16_t *lab = b->labels + (size_t)f * n;
    float *fac = b->factor + (size_t)f * b->max_blobs;
    int nb = 0;
    for (size_t k = 0; k < n; k++) {
        if (still[k] || lab[k]) continue;
        int count = grow_blob(still, lab, W, H, (int)k, -1, pixels);
        if (count < p->min_area || nb >= b->max_blobs) continue; /* stays -1: visited, not a blob */
        fac[nb] = blob_factor(d, background, pixels, count, ratios, p);
        b->behind[(size_t)f * b->max_blobs + nb] = blob_behind(background, pixels, count, ratios);
        nb++;
        for (int i = 0; i < count; i++) lab[pixels[i]] = (int16_t)nb;
    }
    for (size_t k = 0; k < n; k++)
        if (lab[k] < 0) lab[k] = 0;
    b->count[f] = nb;
}

/* Pass 2: a blob's factor becomes the median of its own and those of the blobs overlapping it
 * in the frames within the window (the same object one step earlier or later): a per-frame
 * factor flickers with the network's depth, and a mover that jumps in depth blurs the model.
 * One pass over the pixels per frame of the window fills which blobs of f overlap which of that
 * frame. Returns 0, or -1 when out of memory. */
static int smooth_frame(const blob_set *b, float *smoothed, int f, int frames, size_t n, int window, float *vals)
{
    const int nb = b->count[f], mb = b->max_blobs;
    const int16_t *lab = b->labels + (size_t)f * n;
    int lo = f - window > 0 ? f - window : 0, hi = f + window < frames - 1 ? f + window : frames - 1;
    size_t cells = 0;
    for (int g = lo; g <= hi; g++) cells += (size_t)nb * b->count[g];
    if (cells == 0) return 0;
    unsigned char *overlap = calloc(cells, 1); /* per frame g: (nb, count[g]) */
    if (!overlap) return -1;
    unsigned char *o = overlap;
    for (int g = lo; g <= hi; g++) {
        const int16_t *other = b->labels + (size_t)g * n;
        const int cg = b->count[g];
        for (size_t k = 0; k < n; k++)
            if (lab[k] && other[k]) o[(size_t)(lab[k] - 1) * cg + other[k] - 1] = 1;
        o += (size_t)nb * cg;
    }
    for (int i = 0; i < nb; i++) {
        int m = 0;
        o = overlap;
        for (int g = lo; g <= hi; g++) {
            const int cg = b->count[g];
            for (int j = 0; j < cg; j++)
                if (o[(size_t)i * cg + j]) vals[m++] = b->factor[(size_t)g * mb + j];
            o += (size_t)nb * cg;
        }
        smoothed[(size_t)f * mb + i] = pg_median_float(vals, m);
    }
    free(overlap);
    return 0;
}

long depth_movers_in_front(float *depth, const unsigned char *still, const float *background, int frames, int width,
                           int height, const depth_movers_front_params *p)
{
    const size_t n = (size_t)width * height;
    blob_set b = { 0 };
    size_t most = n / (size_t)(p->min_area > 0 ? p->min_area : 1) + 1;
    b.max_blobs = most < INT16_MAX ? (int)most : INT16_MAX;
    b.labels = calloc((size_t)frames * n, sizeof(int16_t));
    b.factor = malloc((size_t)frames * b.max_blobs * sizeof(float));
    b.behind = malloc((size_t)frames * b.max_blobs * sizeof(float));
    b.count = calloc((size_t)frames, sizeof(int));
    float *smoothed = malloc((size_t)frames * b.max_blobs * sizeof(float));
    /* (n) the still depth of pixels static in too few frames for `background` (the ring the
     * mask's dilation puts around a mover is still in the frames the mover is elsewhere); a
     * pixel never still compares with its blob's median background */
    float *seen = malloc(n * sizeof(float));
    long moved = 0;
    int out_of_memory = !b.labels || !b.factor || !b.behind || !b.count || !smoothed || !seen;
    if (!out_of_memory) out_of_memory = depth_static_reference(depth, still, frames, n, 1, seen) < 0;
    if (!out_of_memory) {
#pragma omp parallel
        {
            int *pixels = malloc(n * sizeof(int));
            float *ratios = malloc(n * sizeof(float));
            if (!pixels || !ratios) {
#pragma omp atomic write
                out_of_memory = 1;
            }
#pragma omp for schedule(dynamic, 1)
            for (int f = 0; f < frames; f++)
                if (pixels && ratios)
                    label_frame(&b, depth + (size_t)f * n, still + (size_t)f * n, background, f, width, height,
                                pixels, ratios, p);
            free(pixels);
            free(ratios);
        }
    }
    if (!out_of_memory) {
#pragma omp parallel reduction(+ : moved)
        {
            float *vals = malloc((size_t)(2 * p->window + 1) * b.max_blobs * sizeof(float));
            if (!vals) {
#pragma omp atomic write
                out_of_memory = 1;
            }
#pragma omp for schedule(dynamic, 1)
            for (int f = 0; f < frames; f++) {
                if (!vals) continue;
                if (smooth_frame(&b, smoothed, f, frames, n, p->window, vals)) {
#pragma omp atomic write
                    out_of_memory = 1;
                    continue;
                }
                float *d = depth + (size_t)f * n;
                const int16_t *lab = b.labels + (size_t)f * n;
                for (size_t k = 0; k < n; k++) {
                    if (!lab[k] || !depth_valid(d[k])) continue;
                    float s = smoothed[(size_t)f * b.max_blobs + lab[k] - 1];
                    /* the still scene showing through the blob (where the mover was, or the ring
                     * of background the dilation took in) already has its own depth: a pixel
                     * nearer its background's depth than the mover's (less than half the factor's
                     * way, in log) is left alone */
                    if (s >= 1.0f) continue;
                    float behind = background[k] > 0 ? background[k]
                                   : seen[k] > 0     ? seen[k]
                                                     : b.behind[(size_t)f * b.max_blobs + lab[k] - 1];
                    if (behind > 0) {
                        float off = logf(behind / d[k]);
                        if (fabsf(off) < p->tolerance || off > 0.5f * logf(s)) continue;
                    }
                    d[k] *= s;
                }
                for (int i = 0; i < b.count[f]; i++) moved += smoothed[(size_t)f * b.max_blobs + i] < 1.0f;
            }
            free(vals);
        }
    }
    free(b.labels);
    free(b.factor);
    free(b.behind);
    free(b.count);
    free(smoothed);
    free(seen);
    return out_of_memory ? -1 : moved;
}
