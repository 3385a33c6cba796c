/* test_depth_refine.c - edge-aware refinement on the procedural scene: band error near
 * ground-truth discontinuities must drop >= 20 %, error elsewhere must not grow > 2 %. */
#include "testlib.h"
#include "test_depth_scene.h"
#include "core/parallel.h"
#include "depth/refine.h"

#include <stdio.h>

int main(void)
{
    pg_set_threads(2);
    test_scene sc;
    const int W = 160, H = 120, F = 6;
    CHECK(test_scene_make(&sc, W, H, F, 3) == 0, "scene");
    size_t n = (size_t)W * H;
    float *ref = malloc(sizeof(float) * n * F);
    const depth_refine_kind kinds[2] = { DEPTH_REFINE_EDGE_SNAP, DEPTH_REFINE_BILATERAL };
    for (int q = 0; q < 2; q++) {
        depth_refine_backend be = depth_refine_backend_get(kinds[q], NULL);
        double t0 = pg_time_seconds();
        for (int i = 0; i < F; i++) CHECK_OK(depth_refine_run(&be, &sc.rgb[i], sc.depth_mono + i * n, ref + i * n));
        double dt = (pg_time_seconds() - t0) / F;
        double ba, bb, ea, eb;
        scene_band_errors(sc.depth_mono, ref, sc.depth_gt, W, H, F, &ba, &bb, &ea, &eb);
        printf("refine %-9s band MAE %.4f -> %.4f (%+.1f %%), elsewhere %.4f -> %.4f (%+.2f %%), %.3f s/frame\n",
               be.name, ba, bb, 100 * (bb / ba - 1), ea, eb, 100 * (eb / ea - 1), dt);
        if (kinds[q] == DEPTH_REFINE_EDGE_SNAP) {
            CHECK(bb <= 0.8 * ba, "band error %.4f -> %.4f: less than 20 %% lower", ba, bb);
            CHECK(eb <= 1.02 * ea, "error elsewhere grew %.4f -> %.4f", ea, eb);
        }
    }
    /* Invalid pixels stay invalid; NaN input does not spread. */
    float *d = malloc(sizeof(float) * n), *o = malloc(sizeof(float) * n);
    memcpy(d, sc.depth_mono, sizeof(float) * n);
    for (int y = 40; y < 60; y++)
        for (int x = 40; x < 60; x++) d[y * W + x] = NAN;
    d[5] = -1.0f;
    depth_refine_backend be = depth_refine_backend_get(DEPTH_REFINE_EDGE_SNAP, NULL);
    CHECK_OK(depth_refine_run(&be, &sc.rgb[0], d, o));
    int bad = 0;
    for (size_t k = 0; k < n; k++) {
        int inv = !(d[k] > 0);
        if (inv && o[k] != 0.0f) bad++;
        if (!inv && !(o[k] > 0)) bad++;
    }
    CHECK(bad == 0, "%d pixels with wrong validity after refinement", bad);
    /* All-NaN frame: all zeros, no crash. */
    for (size_t k = 0; k < n; k++) d[k] = NAN;
    CHECK_OK(depth_refine_run(&be, &sc.rgb[0], d, o));
    CHECK(o[n / 2] == 0.0f, "all-NaN frame gave %g", o[n / 2]);
    CHECK(depth_refine_kind_parse("edge-snap") == DEPTH_REFINE_EDGE_SNAP, "parse");
    CHECK(depth_refine_kind_parse("nope") == DEPTH_REFINE_COUNT, "parse unknown");
    free(d);
    free(o);
    free(ref);
    test_scene_destroy(&sc);
    return test_summary("test_depth_refine");
}
