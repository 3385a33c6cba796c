/* fuse.c - temporal median of static pixels (see fuse.h). */
#include "depth/fuse.h"

#include "core/parallel.h"

#include <stdlib.h>

long depth_static_reference(const float *depth, const unsigned char *static_masks, int frames, size_t n,
                            int min_frames, float *ref)
{
    if (min_frames < 1) min_frames = 1;
    long found = 0;
    int out_of_memory = 0;
#pragma omp parallel reduction(+ : found)
    {
        float *vals = malloc((size_t)frames * sizeof(float));
        if (!vals) {
#pragma omp atomic write
            out_of_memory = 1;
        }
#pragma omp for schedule(static)
        for (size_t k = 0; k < n; k++) {
            ref[k] = 0.0f;
            if (!vals) continue;
            int m = 0;
            for (int f = 0; f < frames; f++) {
                float d = depth[(size_t)f * n + k];
                if (static_masks[(size_t)f * n + k] && d > 0) vals[m++] = d;
            }
            if (m < min_frames) continue;
            ref[k] = pg_median_float(vals, m);
            found++;
        }
        free(vals);
    }
    return out_of_memory ? -1 : found;
}

long depth_fuse_static(float *depth, const unsigned char *static_masks, int frames, size_t n, int min_frames)
{
    if (frames < 2 || min_frames > frames) return 0;
    if (min_frames < 2) min_frames = 2;
    float *ref = malloc(n * sizeof(float));
    if (!ref) return -1;
    long fused = depth_static_reference(depth, static_masks, frames, n, min_frames, ref);
    if (fused < 0) {
        free(ref);
        return -1;
    }
#pragma omp parallel for schedule(static)
    for (size_t k = 0; k < n; k++) {
        if (!(ref[k] > 0)) continue;
        for (int f = 0; f < frames; f++) {
            float *d = &depth[(size_t)f * n + k];
            if (static_masks[(size_t)f * n + k] && *d > 0) *d = ref[k];
        }
    }
    free(ref);
    return fused;
}
