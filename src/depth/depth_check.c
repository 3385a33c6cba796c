/* depth_check.c - plausibility checks on a user's depth (see depth_check.h). */
#include "depth/depth_check.h"

#include <math.h>
#include <stdlib.h>

typedef struct {
    float value;
    int index;
} ranked;

static int by_value(const void *a, const void *b)
{
    const ranked *p = a, *q = b;
    if (p->value != q->value) return (p->value > q->value) - (p->value < q->value);
    return (p->index > q->index) - (p->index < q->index); /* deterministic whatever qsort does with ties */
}

/* Spearman rank correlation between the row order and the rows' mean depth. Rows of equal depth
 * share their average rank, so a flat map (every row the same) has no trend at all: with ties
 * broken by row it read as depth growing down the frame, a perfect "disparity". */
static double row_trend(const float *plane, int width, int height, ranked *rows)
{
    int n = 0;
    for (int y = 0; y < height; y++) {
        double sum = 0;
        int valid = 0;
        for (int x = 0; x < width; x++) {
            float d = plane[(size_t)y * width + x];
            if (d > 0 && isfinite(d)) { sum += d; valid++; }
        }
        if (valid * 10 >= width) {
            rows[n].value = (float)(sum / valid);
            rows[n].index = n;
            n++;
        }
    }
    if (n < 8) return 0;
    qsort(rows, (size_t)n, sizeof *rows, by_value);
    /* Pearson correlation of the row's own rank (its index) and its value's average rank */
    double mean = (n - 1) / 2.0, sxy = 0, sxx = 0, syy = 0;
    for (int r = 0; r < n;) {
        int end = r;
        while (end + 1 < n && rows[end + 1].value == rows[r].value) end++;
        double b = (r + end) / 2.0 - mean;
        for (int k = r; k <= end; k++) {
            double a = rows[k].index - mean;
            sxy += a * b;
            sxx += a * a;
            syy += b * b;
        }
        r = end + 1;
    }
    return sxx > 0 && syy > 0 ? sxy / sqrt(sxx * syy) : 0;
}

double depth_share_inverted_frames(const float *depth, int frames, int width, int height)
{
    if (frames <= 0 || width <= 0 || height <= 0) return 0;
    ranked *rows = malloc((size_t)height * sizeof *rows);
    if (!rows) return 0;
    int step = frames > 32 ? (frames + 31) / 32 : 1, sampled = 0, inverted = 0;
    for (int f = 0; f < frames; f += step) {
        sampled++;
        inverted += row_trend(depth + (size_t)f * width * height, width, height, rows) > 0.3;
    }
    free(rows);
    return (double)inverted / sampled;
}
