/* adam.c - Adam over strided parameter groups with row remapping. */
#include "optim/adam.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    optim_group_desc d;
    float *m, *v;  /* (rows, cols) */
    int step;
} adam_group;

struct optim_adam {
    int ngroups, rows, cap_rows;
    float beta1, beta2, eps;
    adam_group *g;
};

float optim_lr_expon(const optim_lr_schedule *s, int step)
{
    if (step < 0 || (s->lr_init == 0 && s->lr_final == 0)) return 0.0f;
    double delay = 1.0;
    if (s->delay_steps > 0) {
        double u = (double)step / s->delay_steps;
        u = u < 0 ? 0 : (u > 1 ? 1 : u);
        delay = s->delay_mult + (1.0 - s->delay_mult) * sin(0.5 * 3.14159265358979323846 * u);
    }
    double t = s->max_steps > 0 ? (double)step / s->max_steps : 1.0;
    t = t < 0 ? 0 : (t > 1 ? 1 : t);
    /* log-linear needs two positive ends; otherwise (e.g. decay to 0) interpolate linearly */
    double lr = s->lr_init > 0 && s->lr_final > 0 ? exp(log(s->lr_init) * (1 - t) + log(s->lr_final) * t)
                                                  : s->lr_init * (1 - t) + (double)s->lr_final * t;
    return (float)(delay * lr);
}

void optim_adam_destroy(optim_adam *opt)
{
    if (!opt) return;
    for (int i = 0; i < opt->ngroups; i++) { free(opt->g[i].m); free(opt->g[i].v); }
    free(opt->g);
    free(opt);
}

/* (Re)allocates every group's moments for cap rows, zeroed. */
static pg_status alloc_moments(optim_adam *opt, int cap)
{
    for (int i = 0; i < opt->ngroups; i++) {
        size_t n;
        if (pg_size_mul((size_t)(cap > 0 ? cap : 1), (size_t)opt->g[i].d.cols * sizeof(float), &n))
            return pg_fail(PG_ERR_SIZE, "adam: %d rows overflow", cap);
        float *m = calloc(1, n ? n : 1), *v = calloc(1, n ? n : 1); /* a 0-column group: no moments */
        if (!m || !v) { free(m); free(v); return pg_fail(PG_ERR_NOMEM, "adam: out of memory for %d rows", cap); }
        free(opt->g[i].m); free(opt->g[i].v);
        opt->g[i].m = m; opt->g[i].v = v;
    }
    opt->cap_rows = cap;
    return PG_OK;
}

pg_status optim_adam_create(optim_adam **out, const optim_group_desc *groups, int ngroups, int rows, float eps)
{
    *out = NULL;
    if (ngroups <= 0 || rows < 0) return pg_fail(PG_ERR_ARG, "adam: %d groups, %d rows", ngroups, rows);
    for (int i = 0; i < ngroups; i++)
        if (groups[i].cols < 0 || groups[i].col0 < 0 || groups[i].col0 + groups[i].cols > groups[i].row_stride)
            return pg_fail(PG_ERR_ARG, "adam: group %s has columns [%d, %d) outside its row of %d",
                           groups[i].name ? groups[i].name : "?", groups[i].col0, groups[i].col0 + groups[i].cols,
                           groups[i].row_stride);
    optim_adam *opt = pg_calloc(1, sizeof(*opt), "adam");
    if (!opt) return PG_ERR_NOMEM;
    opt->g = pg_calloc((size_t)ngroups, sizeof(adam_group), "adam groups");
    if (!opt->g) { free(opt); return PG_ERR_NOMEM; }
    opt->ngroups = ngroups;
    opt->rows = rows;
    opt->beta1 = 0.9f; opt->beta2 = 0.999f; opt->eps = eps;
    for (int i = 0; i < ngroups; i++) opt->g[i].d = groups[i];
    pg_status st = alloc_moments(opt, rows);
    if (st) { optim_adam_destroy(opt); return st; }
    *out = opt;
    return PG_OK;
}

pg_status optim_adam_create_gaussians(optim_adam **opt, int rows, int sh_stride, float eps)
{
    if (sh_stride < 3 || sh_stride > PG_SH_FLOATS) return pg_fail(PG_ERR_ARG, "adam: SH rows of %d floats", sh_stride);
    const optim_group_desc groups[OPTIM_GAUSS_GROUPS] = {
        { "means", 3, 0, 3 }, { "log_scales", 3, 0, 3 }, { "quats", 4, 0, 4 },
        { "opacity", 1, 0, 1 }, { "sh_dc", sh_stride, 0, 3 }, { "sh_rest", sh_stride, 3, sh_stride - 3 },
    };
    return optim_adam_create(opt, groups, OPTIM_GAUSS_GROUPS, rows, eps);
}

pg_status optim_adam_create_flat(optim_adam **opt, int n, float eps)
{
    optim_group_desc d = { "flat", 1, 0, 1 };
    return optim_adam_create(opt, &d, 1, n, eps);
}

int optim_adam_rows(const optim_adam *opt) { return opt->rows; }

/* A group's step prepared for the loops: its Adam state, where its columns start in param and
 * grad, and the bias-corrected step size. */
typedef struct {
    adam_group *g;
    float *p;
    const float *gr;
    int ncols;
    float step_size, inv_sqrt_c2;
    const uint8_t *boost_rows;
    float boost;
} adam_run;

/* Advances the group's step count and folds the bias corrections into the step size and
 * eps, in double for long runs. */
static adam_run prepare_run(optim_adam *opt, const optim_group_step *st)
{
    adam_group *g = &opt->g[st->group];
    g->step++;
    double c1 = 1.0 - pow(opt->beta1, g->step), c2 = 1.0 - pow(opt->beta2, g->step);
    adam_run r = { g, st->param + g->d.col0, st->grad + g->d.col0, st->cols,
                   (float)(st->lr / c1), (float)(1.0 / sqrt(c2)), st->boost_rows, st->boost };
    return r;
}

/* The Adam update of n contiguous values with step size step(i): the one place its arithmetic is
 * written, shared by the flat and the per-row (grouped) steps so both give the same bits. */
#define ADAM_SPAN_BODY(step_of_i)                                                                   \
    for (long i = 0; i < n; i++) {                                                                  \
        float gv = gr[i];                                                                           \
        m[i] = b1 * m[i] + (1.0f - b1) * gv;                                                        \
        v[i] = b2 * v[i] + (1.0f - b2) * gv * gv;                                                   \
        p[i] -= (step_of_i) * m[i] / (sqrtf(v[i]) * inv_sqrt_c2 + eps);                             \
    }

static inline void adam_span(float *restrict p, const float *restrict gr, float *restrict m, float *restrict v,
                             long n, float b1, float b2, float eps, float step_size, float inv_sqrt_c2)
{
    #pragma omp simd
    ADAM_SPAN_BODY(step_size)
}

static inline void adam_span_steps(float *restrict p, const float *restrict gr, float *restrict m, float *restrict v,
                                   long n, float b1, float b2, float eps, const float *restrict step, float inv_sqrt_c2)
{
    #pragma omp simd
    ADAM_SPAN_BODY(step[i])
}

pg_status optim_adam_step_group(optim_adam *opt, int gi, float *param, const float *grad, float lr)
{
    if (gi < 0 || gi >= opt->ngroups) return pg_fail(PG_ERR_ARG, "adam: no group %d", gi);
    adam_group *g = &opt->g[gi];
    optim_group_step st = { gi, param, grad, lr, g->d.cols, NULL, 1.0f };
    if (g->d.row_stride != g->d.cols && opt->rows != 1) return optim_adam_step_groups(opt, &st, 1);
    /* Contiguous run (full rows, or one row): adam_span over blocks split across the threads. */
    adam_run r = prepare_run(opt, &st);
    float b1 = opt->beta1, b2 = opt->beta2, eps = opt->eps, step_size = r.step_size, inv_sqrt_c2 = r.inv_sqrt_c2;
    long n = (long)opt->rows * g->d.cols;
    const long block = 16384, nb = (n + block - 1) / block;
    #pragma omp parallel for schedule(static) if (n > 65536)
    for (long b = 0; b < nb; b++) {
        long o = b * block, len = n - o < block ? n - o : block;
        adam_span(r.p + o, r.gr + o, g->m + o, g->v + o, len, b1, b2, eps, step_size, inv_sqrt_c2);
    }
    return PG_OK;
}

/* Rows a grouped step takes at a time: their columns are made contiguous (parameters, gradients,
 * moments, per-value step sizes) so the update runs as one vector loop. Row by row, a group's few
 * columns (1 to 4) left the loop scalar: a division and a square root per value, ~3 % of a
 * classroom training step. */
#define ADAM_BLOCK_ROWS 64
#define ADAM_MAX_COLS 48

/* nr rows of nc floats between a strided array and a packed one. A row of 3 (the colour's DC) has
 * its own loop: with nc unknown the compiler made a library memcpy per row of 12 bytes. */
static inline void gather_rows(float *restrict dst, const float *restrict src, int stride, int nr, int nc)
{
    if (nc == 3)
        for (int r = 0; r < nr; r++)
            for (int j = 0; j < 3; j++) dst[r * 3 + j] = src[(size_t)r * stride + j];
    else
        for (int r = 0; r < nr; r++) memcpy(dst + r * nc, src + (size_t)r * stride, nc * sizeof(float));
}

static inline void scatter_rows(float *restrict dst, int stride, const float *restrict src, int nr, int nc)
{
    if (nc == 3)
        for (int r = 0; r < nr; r++)
            for (int j = 0; j < 3; j++) dst[(size_t)r * stride + j] = src[r * 3 + j];
    else
        for (int r = 0; r < nr; r++) memcpy(dst + (size_t)r * stride, src + r * nc, nc * sizeof(float));
}

/* The step size of row r of a group's step: boosted on the rows the step marks. */
static inline float row_step_size(const adam_run *u, int r)
{
    return u->boost_rows && u->boost_rows[r] ? u->step_size * u->boost : u->step_size;
}

/* Rows r0 .. r0 + ADAM_BLOCK_ROWS - 1 (those below rows) of one group's step. */
static void step_rows_block(const adam_run *u, int r0, int rows, float b1, float b2, float eps)
{
    const int stride = u->g->d.row_stride, cols = u->g->d.cols, nc = u->ncols;
    const int nr = rows - r0 < ADAM_BLOCK_ROWS ? rows - r0 : ADAM_BLOCK_ROWS;
    const long len = (long)nr * nc;
    float *p = u->p + (size_t)r0 * stride, *m = u->g->m + (size_t)r0 * cols, *v = u->g->v + (size_t)r0 * cols;
    const float *gr = u->gr + (size_t)r0 * stride;
    if (nc > ADAM_MAX_COLS) { /* long rows vectorise on their own */
        for (int r = 0; r < nr; r++)
            adam_span(p + (size_t)r * stride, gr + (size_t)r * stride, m + (size_t)r * cols, v + (size_t)r * cols, nc,
                      b1, b2, eps, row_step_size(u, r0 + r), u->inv_sqrt_c2);
        return;
    }
    float step[ADAM_BLOCK_ROWS * ADAM_MAX_COLS];
    for (int r = 0; r < nr; r++) {
        const float s = row_step_size(u, r0 + r);
        for (int j = 0; j < nc; j++) step[r * nc + j] = s;
    }
    if (stride == nc && cols == nc) { /* already contiguous */
        adam_span_steps(p, gr, m, v, len, b1, b2, eps, step, u->inv_sqrt_c2);
        return;
    }
    float tp[ADAM_BLOCK_ROWS * ADAM_MAX_COLS], tg[ADAM_BLOCK_ROWS * ADAM_MAX_COLS];
    float tm[ADAM_BLOCK_ROWS * ADAM_MAX_COLS], tv[ADAM_BLOCK_ROWS * ADAM_MAX_COLS];
    gather_rows(tp, p, stride, nr, nc);
    gather_rows(tg, gr, stride, nr, nc);
    gather_rows(tm, m, cols, nr, nc);
    gather_rows(tv, v, cols, nr, nc);
    adam_span_steps(tp, tg, tm, tv, len, b1, b2, eps, step, u->inv_sqrt_c2);
    scatter_rows(p, stride, tp, nr, nc);
    scatter_rows(m, cols, tm, nr, nc);
    scatter_rows(v, cols, tv, nr, nc);
}

pg_status optim_adam_step_groups(optim_adam *opt, const optim_group_step *steps, int n)
{
    if (n < 0 || n > OPTIM_MAX_GROUP_STEPS) return pg_fail(PG_ERR_ARG, "adam: %d groups in one step", n);
    long work = 0;
    for (int k = 0; k < n; k++) {
        int gi = steps[k].group;
        if (gi < 0 || gi >= opt->ngroups) return pg_fail(PG_ERR_ARG, "adam: no group %d", gi);
        const optim_group_desc *d = &opt->g[gi].d;
        if (steps[k].cols < 0 || steps[k].cols > d->cols)
            return pg_fail(PG_ERR_ARG, "adam: %d of the %d columns of group %s", steps[k].cols, d->cols,
                           d->name ? d->name : "?");
        for (int j = 0; j < k; j++)
            if (steps[j].group == gi) return pg_fail(PG_ERR_ARG, "adam: group %d listed twice in one step", gi);
        work += steps[k].cols;
    }
    adam_run run[OPTIM_MAX_GROUP_STEPS];
    for (int k = 0; k < n; k++) run[k] = prepare_run(opt, &steps[k]);
    float b1 = opt->beta1, b2 = opt->beta2, eps = opt->eps;
    int rows = opt->rows, nblocks = (rows + ADAM_BLOCK_ROWS - 1) / ADAM_BLOCK_ROWS;
    #pragma omp parallel for schedule(static) if ((long)rows * work > 65536)
    for (int b = 0; b < nblocks; b++)
        for (int k = 0; k < n; k++) step_rows_block(&run[k], b * ADAM_BLOCK_ROWS, rows, b1, b2, eps);
    return PG_OK;
}

pg_status optim_adam_step_gaussians(optim_adam *opt, pg_gaussians *g, const pg_gaussians *grad,
                                    const float lr[OPTIM_GAUSS_GROUPS])
{
    if (opt->ngroups != OPTIM_GAUSS_GROUPS || g->count != opt->rows || grad->count != opt->rows)
        return pg_fail(PG_ERR_ARG, "adam: Gaussian step with %d rows (params) / %d (grads), optimiser has %d",
                       g->count, grad->count, opt->rows);
    float *P[OPTIM_GAUSS_GROUPS] = { g->means, g->log_scales, g->quats, g->opacity, g->sh, g->sh };
    const float *G[OPTIM_GAUSS_GROUPS] = { grad->means, grad->log_scales, grad->quats, grad->opacity, grad->sh, grad->sh };
    for (int i = 0; i < OPTIM_G_SH_DC; i++)
        if (lr[i] > 0) PG_TRY(optim_adam_step_group(opt, i, P[i], G[i], lr[i]));
    /* the two SH groups share the rows of g->sh: one pass */
    optim_group_step sh[2];
    int n = 0;
    for (int i = OPTIM_G_SH_DC; i <= OPTIM_G_SH_REST; i++)
        if (lr[i] > 0) sh[n++] = (optim_group_step){ i, P[i], G[i], lr[i], opt->g[i].d.cols, NULL, 1.0f };
    return optim_adam_step_groups(opt, sh, n);
}

pg_status optim_adam_remap_rows(optim_adam *opt, const int *src, int new_rows)
{
    if (new_rows < 0) return pg_fail(PG_ERR_ARG, "adam: remap to %d rows", new_rows);
    for (int i = 0; i < new_rows; i++)
        if (src[i] >= opt->rows) return pg_fail(PG_ERR_ARG, "adam: remap row %d from %d, only %d rows", i, src[i], opt->rows);
    for (int gi = 0; gi < opt->ngroups; gi++) {
        adam_group *g = &opt->g[gi];
        int cols = g->d.cols;
        size_t n = (size_t)(new_rows > 0 ? new_rows : 1) * cols;
        float *m = calloc(n ? n : 1, sizeof(float)), *v = calloc(n ? n : 1, sizeof(float));
        if (!m || !v) { free(m); free(v); return pg_fail(PG_ERR_NOMEM, "adam: out of memory remapping %d rows", new_rows); }
        for (int i = 0; i < new_rows; i++)
            if (src[i] >= 0) {
                memcpy(m + (size_t)i * cols, g->m + (size_t)src[i] * cols, cols * sizeof(float));
                memcpy(v + (size_t)i * cols, g->v + (size_t)src[i] * cols, cols * sizeof(float));
            }
        free(g->m); free(g->v);
        g->m = m; g->v = v;
    }
    opt->rows = new_rows;
    opt->cap_rows = new_rows;
    return PG_OK;
}

void optim_adam_reset_group(optim_adam *opt, int gi)
{
    if (gi < 0 || gi >= opt->ngroups) return;
    size_t n = (size_t)opt->rows * opt->g[gi].d.cols;
    memset(opt->g[gi].m, 0, n * sizeof(float));
    memset(opt->g[gi].v, 0, n * sizeof(float));
}

float *optim_adam_moment(optim_adam *opt, int gi, int which)
{
    if (gi < 0 || gi >= opt->ngroups) return NULL;
    return which ? opt->g[gi].v : opt->g[gi].m;
}

int optim_adam_num_groups(const optim_adam *opt) { return opt->ngroups; }

size_t optim_adam_moment_size(const optim_adam *opt, int gi)
{
    return gi >= 0 && gi < opt->ngroups ? (size_t)opt->rows * opt->g[gi].d.cols : 0;
}

int optim_adam_group_step(const optim_adam *opt, int gi) { return gi >= 0 && gi < opt->ngroups ? opt->g[gi].step : 0; }
void optim_adam_set_group_step(optim_adam *opt, int gi, int step) { if (gi >= 0 && gi < opt->ngroups) opt->g[gi].step = step; }
