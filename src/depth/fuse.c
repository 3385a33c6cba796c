/* fuse.c - temporal median of static pixels (see fuse.h). */
#include "depth/fuse.h"

#include <stdlib.h>

static int by_value(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

long depth_fuse_static(float *depth, const unsigned char *static_masks, int frames, size_t n, int min_frames)
{
    if (frames < 2 || min_frames > frames) return 0;
    if (min_frames < 2) min_frames = 2;
    long fused = 0;
#pragma omp parallel reduction(+ : fused)
    {
        float *vals = malloc((size_t)frames * sizeof(float));
#pragma omp for schedule(static)
        for (size_t k = 0; k < n; k++) {
            if (!vals) continue;
            int m = 0;
            for (int f = 0; f < frames; f++) {
                float d = depth[(size_t)f * n + k];
                if (static_masks[(size_t)f * n + k] && d > 0) vals[m++] = d;
            }
            if (m < min_frames) continue;
            qsort(vals, (size_t)m, sizeof(float), by_value);
            float med = m % 2 ? vals[m / 2] : 0.5f * (vals[m / 2 - 1] + vals[m / 2]);
            for (int f = 0; f < frames; f++) {
                float *d = &depth[(size_t)f * n + k];
                if (static_masks[(size_t)f * n + k] && *d > 0) *d = med;
            }
            fused++;
        }
        free(vals);
    }
    return fused;
}
