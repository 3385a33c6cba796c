/* train_net.c - adapter between the trainer and the deformation network (src/deform).
 *
 * The network predicts additive deltas for the five Gaussian attributes; the adapter applies
 * them to the selected rows and maps the rasterizer's gradients back (the identity part of
 * canon + delta is already in the caller's canonical gradient).
 */
#include "train/model.h"

#include <stdlib.h>
#include <string.h>

#include "deform/deform.h"

#define WS_MAX_POINTS 32768

struct train_net {
    train_net_config cfg;
    deform_network *net;
    deform_ws *ws;
    float *out;   /* (n, 59) */
    float *d_out; /* (n, 59) */
    long cap;
    int d_out_sh; /* colour floats of d_out's rows that may be non-zero (the rest are) */
};

/* The deformation network config of a trainer's network config (0 fields: library defaults). */
static void deform_config_of(const train_net_config *cfg, deform_config *dc)
{
    deform_config_default(dc);
    if (cfg->width > 0) dc->width = cfg->width;
    if (cfg->res > 0) dc->res_space = cfg->res;
    if (cfg->tres > 0) dc->res_time = cfg->tres;
    if (cfg->channels > 0) dc->channels = cfg->channels;
    dc->head_width = cfg->head_width;
    dc->time_coarsen = cfg->time_coarsen;
    dc->seed = cfg->seed;
}

size_t train_net_config_num_params(const train_net_config *cfg)
{
    deform_config dc;
    deform_config_of(cfg, &dc);
    return deform_config_num_params(&dc);
}

pg_status train_net_create(train_net **n, const train_net_config *cfg)
{
    train_net *t = pg_calloc(1, sizeof *t, "deformation network");
    if (!t) return PG_ERR_NOMEM;
    t->cfg = *cfg;
    deform_config dc;
    deform_config_of(cfg, &dc);
    float aabb[6] = {cfg->aabb_min[0], cfg->aabb_min[1], cfg->aabb_min[2],
                     cfg->aabb_max[0], cfg->aabb_max[1], cfg->aabb_max[2]};
    pg_status st = deform_network_create(&t->net, &dc, aabb);
    if (!st) st = deform_ws_create(&t->ws, t->net, WS_MAX_POINTS);
    if (st) {
        train_net_destroy(t);
        return st;
    }
    *n = t;
    return PG_OK;
}

void train_net_destroy(train_net *n)
{
    if (!n) return;
    deform_ws_destroy(n->ws);
    deform_network_destroy(n->net);
    free(n->out);
    free(n->d_out);
    free(n);
}

size_t train_net_num_params(const train_net *n) { return n->net->num_params; }
float *train_net_params(train_net *n) { return n->net->params; }
float *train_net_grads(train_net *n) { return n->net->grads; }
size_t train_net_grid_end(const train_net *n) { return n->net->num_plane_params; }
void train_net_zero_grad(train_net *n) { deform_network_zero_grad(n->net); }

static pg_status ensure(train_net *t, long n)
{
    if (n <= t->cap) return PG_OK;
    long c = t->cap ? t->cap : 4096;
    while (c < n) c *= 2;
    float *a = realloc(t->out, (size_t)c * DEFORM_OUT_DIM * sizeof(float));
    if (!a) return pg_fail(PG_ERR_NOMEM, "deformation: out of memory for %ld points", c);
    t->out = a;
    float *b = realloc(t->d_out, (size_t)c * DEFORM_OUT_DIM * sizeof(float));
    if (!b) return pg_fail(PG_ERR_NOMEM, "deformation: out of memory for %ld points", c);
    memset(b + (size_t)t->cap * DEFORM_OUT_DIM, 0, (size_t)(c - t->cap) * DEFORM_OUT_DIM * sizeof(float));
    t->d_out = b;
    t->cap = c;
    return PG_OK;
}

pg_status train_net_forward(train_net *t, const pg_gaussians *g, const int *idx, int n, float tm, int sh_floats,
                            pg_gaussians *out)
{
    if (sh_floats < 0 || sh_floats > PG_SH_FLOATS) sh_floats = PG_SH_FLOATS;
    if (sh_floats > g->sh_stride) sh_floats = g->sh_stride;
    if (sh_floats > out->sh_stride) sh_floats = out->sh_stride;
    PG_TRY(ensure(t, n));
    PG_TRY(deform_network_forward(t->net, t->ws, g->means, idx, n, tm, t->out));
#pragma omp parallel for schedule(static)
    for (int k = 0; k < n; k++) {
        int i = idx[k];
        const float *o = t->out + (size_t)k * DEFORM_OUT_DIM;
        for (int a = 0; a < 3; a++) out->means[3 * i + a] = g->means[3 * i + a] + o[DEFORM_OUT_POS + a];
        for (int a = 0; a < 3; a++)
            out->log_scales[3 * i + a] = g->log_scales[3 * i + a] + o[DEFORM_OUT_SCALE + a];
        for (int a = 0; a < 4; a++) out->quats[4 * i + a] = g->quats[4 * i + a] + o[DEFORM_OUT_ROT + a];
        out->opacity[i] = g->opacity[i] + o[DEFORM_OUT_OPACITY];
        const float *sh = splat_gaussians_sh(g, (size_t)i);
        float *out_sh = splat_gaussians_sh(out, (size_t)i);
        for (int a = 0; a < sh_floats; a++) out_sh[a] = sh[a] + o[DEFORM_OUT_SH + a];
    }
    return PG_OK;
}

pg_status train_net_backward(train_net *t, const pg_gaussians *g, const int *idx, int n, float tm, int sh_floats,
                             const pg_gaussians *d_out, pg_gaussians *d_canon)
{
    (void)g;
    (void)tm;
    if (sh_floats < 0 || sh_floats > PG_SH_FLOATS) sh_floats = PG_SH_FLOATS;
    if (sh_floats > d_out->sh_stride) sh_floats = d_out->sh_stride;
    PG_TRY(ensure(t, n));
    if (t->d_out_sh > sh_floats) { /* an earlier call wrote colour floats this one leaves out */
        for (long k = 0; k < t->cap; k++)
            memset(t->d_out + (size_t)k * DEFORM_OUT_DIM + DEFORM_OUT_SH + sh_floats, 0,
                   (size_t)(t->d_out_sh - sh_floats) * sizeof(float));
    }
    t->d_out_sh = sh_floats;
#pragma omp parallel for schedule(static)
    for (int k = 0; k < n; k++) {
        int i = idx[k];
        float *o = t->d_out + (size_t)k * DEFORM_OUT_DIM;
        memcpy(o + DEFORM_OUT_POS, d_out->means + 3 * (size_t)i, 3 * sizeof(float));
        memcpy(o + DEFORM_OUT_SCALE, d_out->log_scales + 3 * (size_t)i, 3 * sizeof(float));
        memcpy(o + DEFORM_OUT_ROT, d_out->quats + 4 * (size_t)i, 4 * sizeof(float));
        o[DEFORM_OUT_OPACITY] = d_out->opacity[i];
        const float *sh = splat_gaussians_sh(d_out, (size_t)i);
        if (sh_floats == 3) memcpy(o + DEFORM_OUT_SH, sh, 3 * sizeof(float)); /* inline */
        else memcpy(o + DEFORM_OUT_SH, sh, (size_t)sh_floats * sizeof(float));
    }
    return deform_network_backward(t->net, t->ws, t->d_out, d_canon->means);
}

float train_net_regularize(train_net *t, float w_tv, float w_time, float w_l1)
{
    return deform_network_regularize(t->net, w_tv, w_time, w_l1);
}

pg_status train_net_resample_time(const train_net *from, int tres, train_net **to)
{
    train_net_config c = from->cfg;
    c.tres = tres;
    PG_TRY(train_net_create(to, &c));
    train_net_resample_array(from, from->net->params, *to, (*to)->net->params);
    return PG_OK;
}

void train_net_resample_array(const train_net *from, const float *src, const train_net *to, float *dst)
{
    deform_params_resample_time(from->net, src, to->net, dst);
}
