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

static int average_due(const train_session *s)
{
    /* not in the full-size phase, which adds still rows the average never saw */
    return s->cfg.average_decay > 0 && s->fine && s->iter >= s->cfg.densify_until && !s->detail;
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
    train_blend_gaussians(&s->avg_g, &s->g, TRAIN_BLEND_AVERAGE, s->cfg.average_decay, splat_sh_floats(s->cfg.sh_max_degree));
    train_blend_floats(s->avg_net, net, P, TRAIN_BLEND_AVERAGE, s->cfg.average_decay);
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
