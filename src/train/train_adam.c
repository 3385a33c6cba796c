/* train_adam.c - the trainer's use of the shared Adam (src/optim/adam): learning rates and
 * schedules of the Gaussian groups and of the deformation network, and the network's groups.
 *
 * Betas 0.9 / 0.999, eps 1e-15 (3DGS). Every group counts its own steps for the bias
 * correction; with positive learning rates all of them step every iteration (of their stage),
 * so the Gaussian groups count the iterations since the start and the network groups those
 * since the fine stage began. Checkpoints store each group's count (checkpoint.c).
 */
#include "train/train_internal.h"

#include <limits.h>
#include <stdlib.h>
#include <string.h>

#define TRAIN_ADAM_EPS 1e-15f

/* Gives the Gaussians' optimiser n rows (creating it on first use): rows below the old count
 * keep their moments, new rows start at zero, the step counts are kept. */
pg_status train_adam_resize_gaussians(train_session *s, int n)
{
    if (!s->gopt) return optim_adam_create_gaussians(&s->gopt, n, s->g.sh_stride, TRAIN_ADAM_EPS);
    int old = optim_adam_rows(s->gopt);
    int *src = pg_malloc((size_t)(n > 0 ? n : 1) * sizeof(int), "Adam row map");
    if (!src) return PG_ERR_NOMEM;
    for (int i = 0; i < n; i++) src[i] = i < old ? i : -1;
    pg_status st = optim_adam_remap_rows(s->gopt, src, n);
    free(src);
    return st;
}

/* The network's flat parameter array is one row of P floats: the HexPlane grids are columns
 * [0, grid_end) and the MLP [grid_end, P), each a group with its own learning rate. */
pg_status train_adam_create_net(train_session *s)
{
    size_t P = train_net_num_params(s->net), ge = train_net_grid_end(s->net);
    if (ge == 0 || ge >= P || P > INT_MAX)
        return pg_fail(PG_ERR_INTERNAL, "train: network of %zu parameters (%zu in grids) has no Adam layout", P, ge);
    optim_group_desc groups[TRAIN_NET_GROUPS] = {
        {"grid", (int)P, 0, (int)ge},
        {"mlp", (int)P, (int)ge, (int)(P - ge)},
    };
    optim_adam_destroy(s->nopt);
    s->nopt = NULL;
    return optim_adam_create(&s->nopt, groups, TRAIN_NET_GROUPS, 1, TRAIN_ADAM_EPS);
}

pg_status train_adam_resample_net(train_session *s, const train_net *from, optim_adam *old_opt)
{
    const size_t P0 = train_net_num_params(from), P1 = train_net_num_params(s->net);
    const size_t ge0 = train_net_grid_end(from), ge1 = train_net_grid_end(s->net);
    float *a = pg_malloc(P0 * sizeof(float), "Adam time refinement"), *b = pg_malloc(P1 * sizeof(float), "Adam time refinement");
    pg_status st = a && b ? train_adam_create_net(s) : PG_ERR_NOMEM;
    for (int which = 0; which < 2 && !st; which++) { /* each moment as one parameter-shaped row */
        memcpy(a, optim_adam_moment(old_opt, TRAIN_NET_GRID, which), ge0 * sizeof(float));
        memcpy(a + ge0, optim_adam_moment(old_opt, TRAIN_NET_MLP, which), (P0 - ge0) * sizeof(float));
        train_net_resample_array(from, a, s->net, b);
        memcpy(optim_adam_moment(s->nopt, TRAIN_NET_GRID, which), b, ge1 * sizeof(float));
        memcpy(optim_adam_moment(s->nopt, TRAIN_NET_MLP, which), b + ge1, (P1 - ge1) * sizeof(float));
    }
    for (int gi = 0; gi < TRAIN_NET_GROUPS && !st; gi++) optim_adam_set_group_step(s->nopt, gi, optim_adam_group_step(old_opt, gi));
    free(a);
    free(b);
    return st;
}

/* Learning rate decaying exponentially from lr0 to lr1 over the current stage (coarse:
 * iterations [0, coarse_iters), fine: [coarse_iters, iters)), as 3DGS schedules the means. */
static float stage_lr(const train_session *s, float lr0, float lr1)
{
    const train_config *c = &s->cfg;
    optim_lr_schedule sched = {lr0, lr1, 0, 1.0f, s->fine ? c->iters - c->coarse_iters : c->coarse_iters};
    return optim_lr_expon(&sched, s->fine ? s->iter - c->coarse_iters : s->iter);
}

/* The Gaussian groups; a group with lr <= 0 is frozen. The SH degree only grows and
 * coefficients above it get no gradient, so their moments are still zero and an Adam step would
 * not move them: only the columns up to the current degree are stepped. Scales, rotation,
 * opacity and colour go in one pass over the rows, at lr_static_scale times the rate on the static
 * Gaussians (0 once they stopped, train_still_frozen): 3DGS's rates are set for 30,000 iterations
 * and the still scene converges faster at twice them in our 1,500-3,000, while the movable ones
 * keep theirs, which the deformation network follows (docs/train.md). */
static pg_status step_gaussians(train_session *s)
{
    const train_config *c = &s->cfg;
    pg_gaussians *g = &s->g;
    const pg_gaussians *gr = &s->gg;
    float lr_means = stage_lr(s, c->lr_means, c->lr_means_final) * s->extent;
    if (lr_means > 0) PG_TRY(optim_adam_step_group(s->gopt, OPTIM_G_MEANS, g->means, gr->means, lr_means));
    const uint8_t *st = s->is_static;
    const float k = train_still_frozen(s) ? 0.0f : c->lr_static_scale;
    int deg = g->sh_degree, sh_rest_cols = (deg + 1) * (deg + 1) * 3 - 3;
    const optim_group_step all[] = {
        {OPTIM_G_LOG_SCALES, g->log_scales, gr->log_scales, c->lr_scales, 3, st, k},
        {OPTIM_G_QUATS, g->quats, gr->quats, c->lr_quats, 4, st, k},
        {OPTIM_G_OPACITY, g->opacity, gr->opacity, c->lr_opacity, 1, st, k},
        {OPTIM_G_SH_DC, g->sh, gr->sh, c->lr_sh_dc, 3, st, k},
        {OPTIM_G_SH_REST, g->sh, gr->sh, c->lr_sh_rest, sh_rest_cols, st, k},
    };
    enum { NGROUPS = sizeof all / sizeof all[0] };
    optim_group_step run[NGROUPS];
    int n = 0;
    for (int i = 0; i < NGROUPS; i++)
        if (all[i].lr > 0) run[n++] = all[i];
    return optim_adam_step_groups(s->gopt, run, n);
}

/* The network's rates follow the fine stage's length (train_net_lr_scale). */
static pg_status step_network(train_session *s)
{
    const train_config *c = &s->cfg;
    float k = train_net_lr_scale(c->iters - c->coarse_iters) * s->extent;
    float lr[TRAIN_NET_GROUPS] = {stage_lr(s, c->lr_grid, c->lr_grid_final) * k,
                                  stage_lr(s, c->lr_net, c->lr_net_final) * k};
    float *p = train_net_params(s->net);
    const float *g = train_net_grads(s->net);
    for (int i = 0; i < TRAIN_NET_GROUPS; i++)
        if (lr[i] > 0) PG_TRY(optim_adam_step_group(s->nopt, i, p, g, lr[i]));
    return PG_OK;
}

pg_status train_adam_step(train_session *s)
{
    PG_TRY(step_gaussians(s));
    if (s->fine) PG_TRY(step_network(s));
    return PG_OK;
}
