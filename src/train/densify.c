/* densify.c - adaptive density control (3DGS): clone small / split large Gaussians whose mean
 * view-space gradient is high, prune transparent and oversized ones, keep N under the cap.
 *
 * Every per-Gaussian array of the session (parameters, static flags, density statistics) moves
 * together; the Adam moments follow through one optim_adam_remap_rows per pass (rows record
 * where they came from), and new rows get zero moments, as in the reference.
 */
#include "train/train_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/mathx.h"
#include "splat/filter3d.h"

pg_status train_ensure_side(train_session *s, int n)
{
    if (n <= s->side_cap) return PG_OK;
    int nc = s->side_cap ? s->side_cap : 1024;
    while (nc < n) nc *= 2;
    uint8_t *a = realloc(s->is_static, (size_t)nc);
    if (!a) return pg_fail(PG_ERR_NOMEM, "train: out of memory for %d Gaussians", nc);
    s->is_static = a;
    float *b = realloc(s->grad_accum, (size_t)nc * sizeof(float));
    if (!b) return pg_fail(PG_ERR_NOMEM, "train: out of memory for %d Gaussians", nc);
    s->grad_accum = b;
    float *c = realloc(s->grad_denom, (size_t)nc * sizeof(float));
    if (!c) return pg_fail(PG_ERR_NOMEM, "train: out of memory for %d Gaussians", nc);
    s->grad_denom = c;
    float *d = realloc(s->vs_grad, (size_t)nc * sizeof(float));
    if (!d) return pg_fail(PG_ERR_NOMEM, "train: out of memory for %d Gaussians", nc);
    s->vs_grad = d;
    int *e = realloc(s->idx, (size_t)nc * sizeof(int));
    if (!e) return pg_fail(PG_ERR_NOMEM, "train: out of memory for %d Gaussians", nc);
    s->idx = e;
    int *r = realloc(s->step_rows, (size_t)nc * sizeof(int));
    if (!r) return pg_fail(PG_ERR_NOMEM, "train: out of memory for %d Gaussians", nc);
    s->step_rows = r;
    uint8_t *rf = realloc(s->row_flags, (size_t)nc);
    if (!rf) return pg_fail(PG_ERR_NOMEM, "train: out of memory for %d Gaussians", nc);
    s->row_flags = rf;
    float *f = realloc(s->filter_var, (size_t)nc * sizeof(float));
    if (!f) return pg_fail(PG_ERR_NOMEM, "train: out of memory for %d Gaussians", nc);
    s->filter_var = f;
    float *h = realloc(s->filter_saved, (size_t)nc * SPLAT_FILTER3D_SAVED * sizeof(float));
    if (!h) return pg_fail(PG_ERR_NOMEM, "train: out of memory for %d Gaussians", nc);
    s->filter_saved = h;
    size_t old = (size_t)s->side_cap, add = (size_t)(nc - s->side_cap);
    memset(s->is_static + old, 0, add);
    memset(s->grad_accum + old, 0, add * sizeof(float));
    memset(s->grad_denom + old, 0, add * sizeof(float));
    memset(s->vs_grad + old, 0, add * sizeof(float));
    memset(s->filter_var + old, 0, add * sizeof(float));
    s->side_cap = nc;
    return PG_OK;
}

static void zero_rows(pg_gaussians *g, int from, int to)
{
    if (to <= from) return;
    size_t n = (size_t)(to - from);
    memset(g->means + 3 * (size_t)from, 0, n * 3 * sizeof(float));
    memset(g->log_scales + 3 * (size_t)from, 0, n * 3 * sizeof(float));
    memset(g->quats + 4 * (size_t)from, 0, n * 4 * sizeof(float));
    memset(g->opacity + from, 0, n * sizeof(float));
    memset(splat_gaussians_sh(g, (size_t)from), 0, n * (size_t)g->sh_stride * sizeof(float));
}

/* Sets the count of every per-Gaussian array to n; rows past the old count are zeroed. */
pg_status train_resize_all(train_session *s, int n)
{
    pg_gaussians *all[4] = {&s->g, &s->gg, &s->d, &s->dg};
    for (int k = 0; k < 4; k++) {
        int old = all[k]->count;
        if (all[k]->capacity == 0) PG_TRY(splat_gaussians_create_sh(all[k], n > 16 ? n : 16, s->cfg.sh_max_degree));
        PG_TRY(splat_gaussians_resize(all[k], n));
        zero_rows(all[k], old, n);
    }
    PG_TRY(train_adam_resize_gaussians(s, n));
    PG_TRY(train_ensure_side(s, n));
    return PG_OK;
}

static void copy_row(pg_gaussians *dst, int di, const pg_gaussians *src, int si)
{
    memmove(dst->means + 3 * (size_t)di, src->means + 3 * (size_t)si, 3 * sizeof(float));
    memmove(dst->log_scales + 3 * (size_t)di, src->log_scales + 3 * (size_t)si, 3 * sizeof(float));
    memmove(dst->quats + 4 * (size_t)di, src->quats + 4 * (size_t)si, 4 * sizeof(float));
    dst->opacity[di] = src->opacity[si];
    memmove(splat_gaussians_sh(dst, (size_t)di), splat_gaussians_sh(src, (size_t)si), (size_t)dst->sh_stride * sizeof(float));
}

static float max_scale(const pg_gaussians *g, int i)
{
    const float *l = g->log_scales + 3 * (size_t)i;
    return expf(fmaxf(l[0], fmaxf(l[1], l[2])));
}

typedef struct {
    float grad;
    int index;
} cand;

static int cand_cmp(const void *a, const void *b)
{
    const cand *x = a, *y = b;
    if (x->grad != y->grad) return x->grad > y->grad ? -1 : 1;
    return x->index - y->index;
}

/* Appends a copy of row i (Adam moments zero: src -1, flags inherited); returns the new index. */
static int append_copy(train_session *s, int i, int *src)
{
    int j = s->g.count;
    /* capacity was ensured by the caller */
    s->g.count = s->gg.count = s->d.count = s->dg.count = j + 1;
    copy_row(&s->g, j, &s->g, i);
    src[j] = -1;
    s->is_static[j] = s->is_static[i];
    s->grad_accum[j] = 0;
    s->grad_denom[j] = 0;
    return j;
}

pg_status train_densify_and_prune(train_session *s, int densify)
{
    const train_config *c = &s->cfg;
    int n0 = s->g.count;
    float thr_scale = c->percent_dense * s->extent;
    int nc = 0;
    cand *cs = pg_malloc(sizeof(cand) * (size_t)(n0 ? n0 : 1), "densify candidates");
    if (!cs) return PG_ERR_NOMEM;
    if (densify) {
        const int still_frozen = train_still_frozen(s);
        for (int i = 0; i < n0; i++) {
            if (still_frozen && s->is_static[i]) continue; /* a copy could not move away from its original */
            float g = s->grad_denom[i] > 0 ? s->grad_accum[i] / s->grad_denom[i] : 0;
            if (g >= (s->is_static[i] ? c->densify_grad : c->densify_grad * c->densify_movable)) cs[nc++] = (cand){g, i};
        }
        int budget = c->max_gaussians - n0;
        if (budget < 0) budget = 0;
        if (nc > budget) {
            qsort(cs, (size_t)nc, sizeof(cand), cand_cmp);
            nc = budget;
        }
    }
    /* room for the clones and the second half of each split */
    int grow = n0 + nc;
    pg_gaussians *all[4] = {&s->g, &s->gg, &s->d, &s->dg};
    pg_status st = PG_OK;
    for (int k = 0; k < 4 && !st; k++) {
        st = splat_gaussians_resize(all[k], grow);
        all[k]->count = n0;
    }
    if (!st) st = train_ensure_side(s, grow);
    /* src[i]: the old row whose Adam moments row i gets (-1: zero), for optim_adam_remap_rows;
     * chosen: candidates in index order so the result does not depend on the sort above */
    int *src = st ? NULL : pg_malloc(sizeof(int) * (size_t)(grow + 1), "densify row map");
    uint8_t *chosen = src ? pg_calloc((size_t)n0 + 1, 1, "densify chosen") : NULL;
    if (!chosen) {
        free(cs);
        free(src);
        return st ? st : PG_ERR_NOMEM;
    }
    for (int i = 0; i < n0; i++) src[i] = i;
    if (densify) {
        for (int k = 0; k < nc; k++) chosen[cs[k].index] = 1;
        for (int i = 0; i < n0; i++) {
            if (!chosen[i]) continue;
            if (max_scale(&s->g, i) <= thr_scale) {
                append_copy(s, i, src); /* clone: same Gaussian twice, the gradient pulls them apart */
            } else {
                /* split: two samples from the Gaussian, scales / 1.6; the original row becomes
                 * the first sample and an appended row the second */
                float R[9], q[4];
                memcpy(q, s->g.quats + 4 * (size_t)i, sizeof q);
                float qn = sqrtf(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
                if (qn > 0)
                    for (int k = 0; k < 4; k++) q[k] /= qn;
                else
                    q[0] = 1;
                quat_to_mat3(R, q);
                float sc[3];
                for (int k = 0; k < 3; k++) sc[k] = expf(s->g.log_scales[3 * (size_t)i + k]);
                int j = append_copy(s, i, src);
                int rows[2] = {i, j};
                float mean[3];
                memcpy(mean, s->g.means + 3 * (size_t)i, sizeof mean);
                for (int r = 0; r < 2; r++) {
                    float z[3], w[3];
                    for (int k = 0; k < 3; k++) z[k] = (float)pg_rng_normal(&s->rng) * sc[k];
                    mat3_mul_vec(w, R, z);
                    for (int k = 0; k < 3; k++) {
                        s->g.means[3 * (size_t)rows[r] + k] = mean[k] + w[k];
                        s->g.log_scales[3 * (size_t)rows[r] + k] -= logf(1.6f);
                    }
                }
                src[i] = -1; /* both halves start with zero moments */
            }
        }
    }
    free(chosen);
    free(cs);
    /* prune: transparent or too large (in place, order kept) */
    int n = s->g.count, w = 0;
    float big = c->prune_big_scale * s->extent;
    for (int i = 0; i < n; i++) {
        float op = 1.0f / (1.0f + expf(-s->g.opacity[i]));
        int keep = op >= c->prune_opacity && max_scale(&s->g, i) <= big;
        if (!keep && n - (i + 1) + w == 0 && w == 0) keep = 1; /* never prune to nothing */
        if (!keep) continue;
        if (w != i) {
            copy_row(&s->g, w, &s->g, i);
            src[w] = src[i];
            s->is_static[w] = s->is_static[i];
        }
        w++;
    }
    for (int k = 0; k < 4; k++) all[k]->count = w;
    memset(s->grad_accum, 0, (size_t)s->side_cap * sizeof(float));
    memset(s->grad_denom, 0, (size_t)s->side_cap * sizeof(float));
    st = optim_adam_remap_rows(s->gopt, src, w);
    free(src);
    return st;
}

void train_reset_opacity(train_session *s)
{
    float lim = logf(0.01f / 0.99f);
    float *m = optim_adam_moment(s->gopt, OPTIM_G_OPACITY, 0), *v = optim_adam_moment(s->gopt, OPTIM_G_OPACITY, 1);
    for (int i = 0; i < s->g.count; i++) {
        if (s->g.opacity[i] > lim) {
            s->g.opacity[i] = lim;
            m[i] = 0;
            v[i] = 0;
        }
    }
}
