/* average.c - the model a run ends with is an exponential moving average of its parameters over
 * the steps after densification ends (Polyak averaging), not the last iterate.
 *
 * Each step fits one or a few frames and a handful of views, so the last iterate carries the
 * noise of its last few steps: the moving parts of the frames trained last fit better than the
 * rest, and two runs whose inputs differ by a rounding part by up to a dB on the movers. The
 * average of the last ~1 / (1 - decay) steps keeps what they agree on. It starts when the
 * Gaussian set stops changing (densify_until) and restarts if the set's flags change. */
#include "train/train_internal.h"

#include <stdlib.h>
#include <string.h>

/* avg = keep * avg + (1 - keep) * x over n floats, in blocks over the threads. */
static void blend_into_average(float *avg, const float *x, size_t n, float keep)
{
    const size_t block = (size_t)1 << 14;
    const long nb = (long)((n + block - 1) / block);
    const float take = 1.0f - keep;
#pragma omp parallel for schedule(static)
    for (long b = 0; b < nb; b++) {
        size_t lo = (size_t)b * block, hi = n - lo < block ? n : lo + block;
        for (size_t k = lo; k < hi; k++) avg[k] = keep * avg[k] + take * x[k];
    }
}

static int average_due(const train_session *s)
{
    return s->cfg.average_decay > 0 && s->fine && s->iter >= s->cfg.densify_until;
}

pg_status train_average_update(train_session *s)
{
    if (!average_due(s)) return PG_OK;
    const size_t P = train_net_num_params(s->net);
    const float *net = train_net_params(s->net);
    if (!s->avg_on || s->avg_g.count != s->g.count) { /* the first step of the average */
        PG_TRY(splat_gaussians_copy(&s->g, &s->avg_g));
        if (!s->avg_net && !(s->avg_net = pg_malloc(P * sizeof(float), "parameter average"))) return PG_ERR_NOMEM;
        memcpy(s->avg_net, net, P * sizeof(float));
        s->avg_on = 1;
        return PG_OK;
    }
    const size_t n = (size_t)s->g.count;
    float *avg[5] = { s->avg_g.means, s->avg_g.log_scales, s->avg_g.quats, s->avg_g.opacity, s->avg_g.sh };
    const float *cur[5] = { s->g.means, s->g.log_scales, s->g.quats, s->g.opacity, s->g.sh };
    const size_t len[5] = { n * 3, n * 3, n * 4, n, n * PG_SH_COEFFS * 3 };
    for (int a = 0; a < 5; a++) blend_into_average(avg[a], cur[a], len[a], s->cfg.average_decay);
    blend_into_average(s->avg_net, net, P, s->cfg.average_decay);
    s->avg_g.sh_degree = s->g.sh_degree;
    return PG_OK;
}

void train_average_restart(train_session *s) { s->avg_on = 0; }

pg_status train_average_apply(train_session *s)
{
    if (!s->avg_on) return PG_OK;
    PG_TRY(splat_gaussians_copy(&s->avg_g, &s->g));
    memcpy(train_net_params(s->net), s->avg_net, train_net_num_params(s->net) * sizeof(float));
    train_update_filter(s);
    s->avg_on = 0; /* training on from here (a continued model) starts a new average */
    return PG_OK;
}

void train_average_destroy(train_session *s)
{
    splat_gaussians_destroy(&s->avg_g);
    free(s->avg_net);
    s->avg_net = NULL;
    s->avg_on = 0;
}
