/* metrics.c - masked PSNR and visible-area coverage of proxy views (see metrics.h). */
#include "proxy/metrics.h"

#include <math.h>

pg_status proxy_measure_view(const pg_camera *real, const float *real_depth, const pg_camera *view,
                             const float *view_depth, const float *view_rgb, const float *proxy_rgb,
                             const unsigned char *mask, float vis_tol, proxy_view_metrics *out)
{
    int W = real->width, H = real->height, W2 = view->width, H2 = view->height;
    double se = 0;
    long nm = 0, nvis = 0, nvis_m = 0, nfalse = 0;
    for (int v = 0; v < H2; v++) {
        for (int u = 0; u < W2; u++) {
            size_t i = (size_t)v * W2 + u;
            int visible = 0;
            float d = view_depth[i];
            if (isfinite(d) && d > 0) {
                float X[3], uv[2];
                pg_camera_unproject(view, u + 0.5f, v + 0.5f, d, X);
                float z = pg_camera_project(real, X, uv);
                int x = (int)floorf(uv[0]), y = (int)floorf(uv[1]);
                if (z > 0 && x >= 0 && y >= 0 && x < W && y < H) {
                    float dr = real_depth[(size_t)y * W + x];
                    visible = dr > 0 && fabsf(dr - z) <= vis_tol * z;
                }
            }
            nvis += visible;
            if (mask[i] == PROXY_MASK_REAL) {
                nm++;
                nvis_m += visible;
                nfalse += !visible;
                for (int c = 0; c < 3; c++) {
                    double e = (double)proxy_rgb[i * 3 + c] - view_rgb[i * 3 + c];
                    se += e * e;
                }
            }
        }
    }
    out->visible = nvis;
    out->masked = nm;
    out->coverage = nvis ? (double)nvis_m / nvis : 0;
    out->false_valid = nm ? (double)nfalse / nm : 0;
    out->mask_fraction = (double)nm / ((double)W2 * H2);
    out->psnr_masked = nm ? -10.0 * log10(fmax(se / (3.0 * nm), 1e-12)) : 0;
    return PG_OK;
}
