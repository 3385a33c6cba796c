/* metrics.h - how good is a proxy view? (acceptance measurements of the proxy stage)
 *
 * Given ground truth for a proxy camera (its real image and depth) and the real camera's ground-
 * truth depth, measures the masked PSNR of the proxy and how much of the truly visible area the
 * validity mask keeps. A view pixel is "truly visible from the real camera" when the surface point
 * it sees (from its ground-truth depth) projects inside the real image with a depth that agrees
 * with the real camera's ground-truth depth there (relative tolerance vis_tol).
 */
#ifndef PG_PROXY_METRICS_H
#define PG_PROXY_METRICS_H

#include "core/camera.h"
#include "core/status.h"
#include "proxy/mask.h"

typedef struct {
    double psnr_masked;     /* PSNR over mask pixels (RGB) */
    double coverage;        /* |mask AND visible| / |visible| */
    double false_valid;     /* |mask AND NOT visible| / |mask| */
    double mask_fraction;   /* |mask| / all pixels */
    long visible, masked;
} proxy_view_metrics;

/* real_depth (H,W) and view_depth (H',W') ground-truth z-depth in pose units; view_rgb, proxy_rgb
 * (H',W',3); mask (H',W') from proxy_mask_combine: only PROXY_MASK_REAL pixels count (the
 * outpainted margin is a guess, not a reprojection). */
pg_status proxy_measure_view(const pg_camera *real, const float *real_depth, const pg_camera *view,
                             const float *view_depth, const float *view_rgb, const float *proxy_rgb,
                             const unsigned char *mask, float vis_tol, proxy_view_metrics *out);

#endif
