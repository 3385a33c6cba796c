/* colormap.c - a perceptually ordered blue-to-yellow ramp for depth maps. */
#include "render/colormap.h"
#include "core/mathx.h"

#include <math.h>
#include <stdlib.h>

/* Piecewise-linear ramp through dark blue, purple, orange and yellow (viridis/inferno-like). */
static const float STOPS[5][3] = {
    { 0.05f, 0.03f, 0.35f }, { 0.45f, 0.10f, 0.55f }, { 0.85f, 0.30f, 0.35f }, { 0.98f, 0.65f, 0.15f }, { 0.99f, 0.98f, 0.60f },
};

pg_status render_depth_colormap(const float *depth, int width, int height, float lo, float hi, pg_image *rgb)
{
    const size_t n = (size_t)width * height;
    if (lo <= 0 || hi <= lo) {
        /* the 2nd and 98th percentiles by quickselect (a full sort of every frame was a tenth of a
         * render); in double, exact for floats */
        double *valid = pg_malloc(n * sizeof(double), "depth colour map");
        if (!valid) return PG_ERR_NOMEM;
        size_t m = 0;
        for (size_t i = 0; i < n; i++)
            if (depth[i] > 0 && isfinite(depth[i])) valid[m++] = depth[i];
        if (m > 0) {
            lo = (float)pg_select_kth(valid, m, m / 50);
            hi = (float)pg_select_kth(valid, m, m - 1 - m / 50);
        }
        free(valid);
        if (m == 0 || hi <= lo) { lo = 0.0f; hi = lo + 1.0f; }
    }
    PG_TRY(pg_image_create(rgb, width, height, 3));
    for (size_t i = 0; i < n; i++) {
        float d = depth[i];
        float *out = rgb->data + 3 * i;
        if (!(d > 0) || !isfinite(d)) { out[0] = out[1] = out[2] = 0; continue; }
        pg_color_ramp(STOPS, 5, 1.0f - (d - lo) / (hi - lo), out); /* near is bright */
    }
    return PG_OK;
}
