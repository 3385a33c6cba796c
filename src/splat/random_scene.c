/* random_scene.c - benchmark / test workload generator. */
#include "splat/random_scene.h"
#include "splat/sh.h"
#include "core/rng.h"

#include <math.h>

pg_status splat_random_scene(pg_gaussians *g, const pg_camera *cam, int n, float sigma_px, int sh_degree,
                             unsigned long long seed)
{
    if (n < 0 || !(sigma_px > 0) || sh_degree < 0 || sh_degree > 3)
        return pg_fail(PG_ERR_ARG, "random scene: bad arguments (n %d, sigma %g px, SH degree %d)", n, sigma_px, sh_degree);
    PG_TRY(splat_gaussians_resize(g, n));
    g->sh_degree = sh_degree;
    pg_rng rng;
    pg_rng_seed(&rng, seed);
    for (int i = 0; i < n; i++) {
        float z = (float)pg_rng_range(&rng, 2, 10);
        float u = (float)pg_rng_range(&rng, 0, cam->width), v = (float)pg_rng_range(&rng, 0, cam->height);
        pg_camera_unproject(cam, u, v, z, g->means + 3*i);
        float s = sigma_px * (float)pg_rng_range(&rng, 0.3, 1.7) * z / cam->fx;
        for (int k = 0; k < 3; k++) g->log_scales[3*i+k] = logf(s);
        g->quats[4*i] = 1; g->quats[4*i+1] = g->quats[4*i+2] = g->quats[4*i+3] = 0;
        float o = (float)pg_rng_range(&rng, 0.05, 0.95);
        g->opacity[i] = logf(o / (1 - o));
        float *sh = splat_gaussians_sh(g, (size_t)i);
        for (int k = 0; k < g->sh_stride; k++) sh[k] = 0;
        for (int c = 0; c < 3; c++) sh[c] = ((float)pg_rng_uniform(&rng) - 0.5f) / SPLAT_SH_C0;
        int nb = (sh_degree + 1) * (sh_degree + 1);
        for (int k = 3; k < 3 * nb; k++) sh[k] = (float)(0.1 * pg_rng_normal(&rng));
    }
    return PG_OK;
}
