/* train.c - the training loop: sampling, deformation, rendering, loss, Adam, density control.
 *
 * One iteration (fine stage) trains several views of ONE time against one deformation, because
 * the network is the expensive part and every view of a time shares its output (times_per_step
 * repeats 1-4 for that many times before the one optimiser step):
 *   1. pick a frame (every frame once per epoch, in a shuffled order), t = frame / (F - 1), and the
 *      batch: the real view and views_per_step - 1 proxies of that frame
 *   2. d = canonical copy; rows of movable Gaussians that may be in any batch view go through the network
 *   3. d's scales and opacity through the 3D filter (splat/filter3d.h); per view: rasterize d,
 *      weighted loss, backward -> dg (summed in batch order), then back through the filter
 *   4. gg = dg (identity path); network backward adds the deformation path into gg and its params
 *   5. K-Planes regularisers, Adam on the Gaussians and the network (train_adam.c), density statistics
 * The coarse stage is the same without step 2/4 (d = g).
 */
#include "train/train_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/fileutil.h"
#include "core/mathx.h"
#include "core/parallel.h"
#include "core/progress.h"
#include "optim/loss_depth.h"
#include "optim/loss_image.h"
#include "depth/moving_mask.h"
#include "splat/filter3d.h"

train_config train_default_config(void)
{
    train_config c;
    memset(&c, 0, sizeof c);
    c.iters = 3000;
    c.coarse_iters = train_default_coarse_iters(c.iters);
    c.seed = 1;
    c.threads = 0;
    c.max_gaussians = 200000;
    c.init_points = 30000;
    c.checkpoint_every = 0;
    c.views_per_step = 2; /* the real view and one proxy: ~35 % less per step, held-out views unchanged (docs/train.md) */
    c.times_per_step = 1;
    c.motion_crops = 2; /* the moving pixels of the real view and of a proxy, rendered alone each step (docs/train.md) */
    c.real_weight = 0.75f; /* +1 dB on the real view's movers, held-out views unchanged (docs/train.md) */
    c.moving_weight = 9.0f;
    c.proxy_moving_weight = 1.0f;
    c.sh_max_degree = 3;
    c.sh_ramp_every = 500;
    c.lambda_dssim = 0.2f;
    c.lambda_depth = 0.05f;
    c.reg_tv = 2e-4f;
    c.reg_time = 1e-3f;
    c.reg_l1 = 1e-4f;
    c.lr_means = 1.6e-4f;
    c.lr_means_final = 1.6e-6f;
    c.lr_scales = 5e-3f;
    c.lr_quats = 1e-3f;
    c.lr_opacity = 0.05f;
    c.lr_sh_dc = 2.5e-3f;
    c.lr_sh_rest = 2.5e-3f / 20;
    c.lr_net = 1.6e-3f;
    c.lr_net_final = 1.6e-4f;
    c.lr_grid = 1.6e-2f;
    c.lr_grid_final = 1.6e-3f;
    c.lr_static_scale = 2.0f;
    c.static_steps = TRAIN_STATIC_STEPS;
    c.average_decay = 0.99f; /* issue 24: the last ~100 steps averaged (docs/train.md) */
    c.densify_from = 200;
    c.densify_until = 0; /* 0: train_default_densify_until(iters) */
    c.densify_every = 100;
    c.opacity_reset_every = 0;
    c.densify_grad = 2e-4f;
    c.densify_movable = 0; /* the trainer's rule: TRAIN_LONG_CLIP_DENSIFY_MOVABLE for a long clip, else 1 */
    c.proxy_downscale = TRAIN_PROXY_DOWNSCALE;
    c.percent_dense = 0.01f;
    c.prune_opacity = 0.005f;
    c.prune_big_scale = 0.2f;
    c.deform_time_coarsen = 2; /* issue 24: +1.4 dB moving on a 300-frame clip (docs/deform.md) */
    c.deform_time_warmup = 0.4f; /* issue 24: +1.2 dB moving on a 300-frame clip (docs/train.md) */
    c.deform_head_width = 32; /* half the width: as good as 64 on tabletop_dev, the network ~28 % cheaper (docs/deform.md) */
    c.use_static_flags = 1;
    c.use_frustum_cull = 1;
    c.static_check_every = 0;
    c.static_eps = 1e-3f;
    return c;
}

int train_session_iteration(const train_session *s) { return s->iter; }
int train_session_gaussians(const train_session *s) { return s->g.count; }
int train_session_static_count(const train_session *s)
{
    int n = 0;
    for (int i = 0; i < s->g.count; i++) n += s->is_static[i] != 0;
    return n;
}
void train_session_motion_regions(const train_session *s, int *frames, double *mean_area, int *proxies)
{
    const train_motion_regions *r = s->crop_view >= 0 ? &s->regions[s->crop_view] : NULL;
    *frames = r ? r->frames_with_motion : 0;
    *proxies = s->proxy_crop_views;
    *mean_area = r ? train_motion_regions_mean_area(r) : 0.0;
}
void train_session_deform_stats(const train_session *s, double *mean_deformed, double *mean_movable)
{
    *mean_deformed = s->fine_steps ? s->sum_deformed / (double)s->fine_steps : 0;
    *mean_movable = s->fine_steps ? s->sum_movable / (double)s->fine_steps : 0;
}

void train_session_timing(const train_session *s, train_timing *t) { *t = s->timing; }
void train_session_timing_total(const train_session *s, train_timing *t) { *t = s->timing_total; }

void train_session_destroy(train_session *s)
{
    if (!s) return;
    splat_gaussians_destroy(&s->g);
    splat_gaussians_destroy(&s->gg);
    splat_gaussians_destroy(&s->d);
    splat_gaussians_destroy(&s->dg);
    free(s->is_static);
    free(s->grad_accum);
    free(s->grad_denom);
    free(s->vs_grad);
    free(s->idx);
    free(s->step_rows);
    free(s->row_flags);
    free(s->filter_var);
    free(s->filter_saved);
    if (s->moving)
        for (int v = 0; v < s->ts->num_views; v++) free(s->moving[v]);
    free(s->moving);
    for (int v = 0; s->regions && v < s->ts->num_views; v++) train_motion_regions_destroy(&s->regions[v]);
    free(s->regions);
    optim_adam_destroy(s->gopt);
    train_net_destroy(s->net);
    optim_adam_destroy(s->nopt);
    train_average_destroy(s);
    splat_raster_destroy(s->raster);
    pg_image_destroy(&s->target);
    free(s->mask);
    free(s->depth_t);
    free(s->depth_mask);
    optim_ssim_destroy(s->ssim);
    train_detail_destroy(s->detail);
    optim_ssim_destroy(s->ssim_crop);
    free(s->d_rgb);
    free(s->d_depth);
    free(s);
}

/* One span of a blend (serial; the callers split the work over the threads). Inline: the per-row
 * blends call it for spans of 1-4 floats. */
static inline void blend_span(float *dst, const float *src, size_t m, train_blend how, float keep)
{
    const float take = 1.0f - keep;
    if (how == TRAIN_BLEND_COPY)
        memcpy(dst, src, m * sizeof(float));
    else if (how == TRAIN_BLEND_ZERO)
        memset(dst, 0, m * sizeof(float));
    else if (how == TRAIN_BLEND_ADD)
        for (size_t k = 0; k < m; k++) dst[k] += src[k];
    else
        for (size_t k = 0; k < m; k++) dst[k] = keep * dst[k] + take * src[k];
}

/* blend_span over a row's used SH floats: 3 (degree 0, a single camera's runs) as a constant, so
 * the copy or zeroing of 12 bytes is inline moves rather than a library call per row. */
static inline void blend_sh_span(float *dst, const float *src, size_t used, train_blend how, float keep)
{
    if (used == 3) blend_span(dst, src, 3, how, keep);
    else blend_span(dst, src, used, how, keep);
}

/* Every parameter pass is 24 MB at 100k Gaussians and runs several times per iteration, so it
 * is split over the threads in blocks. */
void train_blend_floats(float *dst, const float *src, size_t n, train_blend how, float keep)
{
    const size_t block = (size_t)1 << 14;
    const long nb = (long)((n + block - 1) / block);
#pragma omp parallel for schedule(static)
    for (long b = 0; b < nb; b++) {
        size_t lo = (size_t)b * block, m = n - lo < block ? n - lo : block;
        blend_span(dst + lo, src + lo, m, how, keep);
    }
}

/* The first `used` SH floats of each row, where the rows of dst and src differ in stride (a model
 * of every degree into a session's set) or a row holds more floats than the run uses. */
static void blend_sh_rows(pg_gaussians *dst, const pg_gaussians *src, int n, int used, train_blend how, float keep)
{
#pragma omp parallel for schedule(static)
    for (int i = 0; i < n; i++)
        blend_sh_span(splat_gaussians_sh(dst, (size_t)i), splat_gaussians_sh(src, (size_t)i), (size_t)used, how, keep);
}

void train_blend_gaussians(pg_gaussians *dst, const pg_gaussians *src, train_blend how, float keep, int sh_floats)
{
    const size_t n = (size_t)src->count;
    float *d[4] = { dst->means, dst->log_scales, dst->quats, dst->opacity };
    const float *s[4] = { src->means, src->log_scales, src->quats, src->opacity };
    const size_t len[4] = { n * 3, n * 3, n * 4, n };
    for (int a = 0; a < 4; a++) train_blend_floats(d[a], s[a], len[a], how, keep);
    int used = sh_floats < dst->sh_stride ? sh_floats : dst->sh_stride;
    used = used < src->sh_stride ? used : src->sh_stride;
    if (dst->sh_stride == src->sh_stride && used == dst->sh_stride)
        train_blend_floats(dst->sh, src->sh, n * (size_t)used, how, keep);
    else
        blend_sh_rows(dst, src, (int)n, used, how, keep);
    if (how == TRAIN_BLEND_COPY || how == TRAIN_BLEND_AVERAGE) dst->sh_degree = src->sh_degree;
}

/* A blend of the session's rows over the SH floats the run uses (copy, zero with src = dst, add). */
static void blend_used(train_session *s, pg_gaussians *dst, const pg_gaussians *src, train_blend how)
{
    train_blend_gaussians(dst, src, how, 0.0f, splat_sh_floats(s->cfg.sh_max_degree));
}

/* blend_used (copy, zero with src = dst, add) over the listed rows only. */
static void blend_rows(train_session *s, pg_gaussians *dst, const pg_gaussians *src, const int *rows, int n,
                       train_blend how)
{
    const size_t sh_floats = (size_t)splat_sh_floats(s->cfg.sh_max_degree);
    #pragma omp parallel for schedule(static)
    for (int k = 0; k < n; k++) {
        const size_t i = (size_t)rows[k];
        blend_span(dst->means + 3 * i, src->means + 3 * i, 3, how, 0.0f);
        blend_span(dst->log_scales + 3 * i, src->log_scales + 3 * i, 3, how, 0.0f);
        blend_span(dst->quats + 4 * i, src->quats + 4 * i, 4, how, 0.0f);
        blend_span(dst->opacity + i, src->opacity + i, 1, how, 0.0f);
        blend_sh_span(splat_gaussians_sh(dst, i), splat_gaussians_sh(src, i), sh_floats, how, 0.0f);
    }
}

/* The step's rows the network may move (every non-static one in the fine stage, none in the
 * coarse one) and the fixed rest. The fixed rows are the same at every time a step renders (~3/4
 * of a long clip's Gaussians), so the deformed copy and the 3D filter of them are made once per
 * step, and their gradients are summed over the step's times and taken through the (linear)
 * filter backward once at its end. */
static inline int row_may_move(const train_session *s, int i)
{
    return s->fine && !(s->cfg.use_static_flags && s->is_static[i]);
}
static void list_step_rows(train_session *s)
{
    const int n = s->g.count;
    int k = 0;
    for (int i = 0; i < n; i++)
        if (row_may_move(s, i)) s->step_rows[k++] = i;
    s->n_moving_rows = k;
    for (int i = 0; i < n; i++)
        if (!row_may_move(s, i)) s->step_rows[k++] = i;
    s->n_fixed_rows = n - s->n_moving_rows;
}

/* Moving pixels of each real view (colour off the temporal median by > 0.1, dilated 2 px):
 * they get 1 + moving_weight times the loss weight, because they are a few percent of the frame
 * yet all of what the product is for. Derived from the training set, so not checkpointed. */
#define TRAIN_MOVING_THRESH 0.1f
#define TRAIN_MOVING_DILATE 2
static pg_status find_moving_pixels(train_session *s)
{
    const train_set *ts = s->ts;
    if (s->cfg.moving_weight <= 0 || ts->frames < 2) return PG_OK;
    s->moving = pg_calloc((size_t)ts->num_views, sizeof *s->moving, "moving masks");
    if (!s->moving) return PG_ERR_NOMEM;
    size_t n = (size_t)ts->frames * ts->width * ts->height;
    for (int v = 0; v < ts->num_views; v++) {
        if (ts->views[v].role != IO_ROLE_REAL) continue;
        s->moving[v] = pg_malloc(n, "moving masks");
        if (!s->moving[v]) return PG_ERR_NOMEM;
        PG_TRY(depth_moving_masks(ts->views[v].rgb, ts->frames, ts->width, ts->height, TRAIN_MOVING_THRESH,
                                  TRAIN_MOVING_DILATE, s->moving[v]));
    }
    return PG_OK;
}

/* The movers of the (first) real view, boxed per frame, for motion crops; with two crops or more,
 * also each proxy's (found from its own colours, the mask dropped once boxed). */
static pg_status find_moving_regions(train_session *s)
{
    const train_set *ts = s->ts;
    s->crop_view = -1;
    if (!s->moving || s->cfg.motion_crops <= 0) return PG_OK;
    for (int v = 0; v < ts->num_views && s->crop_view < 0; v++)
        if (s->moving[v]) s->crop_view = v;
    if (s->crop_view < 0) return PG_OK;
    s->regions = pg_calloc((size_t)ts->num_views, sizeof *s->regions, "moving regions");
    if (!s->regions) return PG_ERR_NOMEM;
    PG_TRY(train_motion_regions_find(s->moving[s->crop_view], ts->frames, ts->width, ts->height,
                                     &s->regions[s->crop_view]));
    if (s->cfg.motion_crops < 2 || train_set_count_role(ts, IO_ROLE_PROXY) == 0) return PG_OK;
    uint8_t *mask = pg_malloc((size_t)ts->frames * ts->width * ts->height, "proxy moving mask");
    pg_status st = mask ? PG_OK : PG_ERR_NOMEM;
    for (int v = 0; v < ts->num_views && st == PG_OK; v++) {
        if (ts->views[v].role != IO_ROLE_PROXY) continue;
        st = depth_moving_masks(ts->views[v].rgb, ts->frames, ts->width, ts->height, TRAIN_MOVING_THRESH,
                                TRAIN_MOVING_DILATE, mask);
        if (!st) st = train_motion_regions_find(mask, ts->frames, ts->width, ts->height, &s->regions[v]);
        if (!st) s->proxy_crop_views += s->regions[v].frames_with_motion > 0;
    }
    free(mask);
    return st;
}

static int times_per_step(const train_config *c) { return c->times_per_step > 1 ? c->times_per_step : 1; }
/* motion crops each step will make (none without a moving region) */
static int motion_crops(const train_session *s)
{
    return s->crop_view >= 0 && s->regions[s->crop_view].frames_with_motion > 0 ? s->cfg.motion_crops : 0;
}

/* A step that renders one time only takes every row's backward at once, in order (no still rows
 * to hold back for later times). */
static int one_time_per_step(const train_session *s)
{
    return times_per_step(&s->cfg) == 1 && (!s->fine || motion_crops(s) == 0);
}

int train_time_texels(int frames, int fine_iters)
{
    int by_budget = fine_iters / TRAIN_STEPS_PER_TIME_TEXEL;
    int t = frames < by_budget ? frames : by_budget;
    if (t > TRAIN_MAX_TIME_TEXELS) t = TRAIN_MAX_TIME_TEXELS;
    return t > 2 ? t : 2;
}

int train_default_coarse_iters(int iters) { return iters / 6 < TRAIN_MAX_COARSE_ITERS ? iters / 6 : TRAIN_MAX_COARSE_ITERS; }
int train_default_sh_degree(const train_set *ts) { return train_set_count_role(ts, IO_ROLE_REAL) >= 2 ? 3 : 0; }
int train_default_densify_until(int iters) { return (int)(0.7 * iters); }

train_budget train_budget_for_clip(int preset_iters, int frames, int motion_crops, long pixels)
{
    train_budget b = { train_iterations_for_clip(preset_iters, frames, motion_crops, pixels),
                       train_default_coarse_iters(preset_iters), train_default_densify_until(preset_iters) };
    return b;
}
float train_net_lr_scale(int fine_iters)
{
    if (fine_iters <= TRAIN_NET_LR_FULL_STEPS) return 1.0f;
    float k = (float)TRAIN_NET_LR_FULL_STEPS / (float)fine_iters;
    return k > TRAIN_NET_LR_MIN_SCALE ? k : TRAIN_NET_LR_MIN_SCALE;
}
int train_fits_per_step(int motion_crops) { return 1 + (motion_crops > 0 ? motion_crops : 0); }

int train_iterations_for_clip(int iters, int frames, int motion_crops, long pixels)
{
    long coarse = train_default_coarse_iters(iters), fits_per_step = train_fits_per_step(motion_crops);
    long need = ((long)frames * TRAIN_FITS_PER_FRAME + fits_per_step - 1) / fits_per_step;
    if (need <= iters - coarse) return iters;
    double scale = pixels > 0 && pixels < TRAIN_BUDGET_PIXELS ? (double)TRAIN_BUDGET_PIXELS / (double)pixels : 1.0;
    if (scale > TRAIN_MAX_PIXEL_SCALE) scale = TRAIN_MAX_PIXEL_SCALE;
    long raised = coarse + need, cap = (long)((double)iters * TRAIN_MAX_BUDGET_THIRDS / 3 * scale);
    return (int)(raised < cap ? raised : cap);
}

/* The time rows the network ends with: --deform-time-res, else one per frame within the budget. */
static int final_time_rows(const train_session *s)
{
    if (s->cfg.deform_tres > 0) return s->cfg.deform_tres;
    return train_time_texels(s->ts->frames, (s->cfg.iters - s->cfg.coarse_iters) * (times_per_step(&s->cfg) + motion_crops(s)));
}
/* The time rows of the warm-up: a quarter, each refined into four at the switch (exactly when
 * 4 divides T - 1). */
static int warmup_time_rows(int final_rows)
{
    int r = ((final_rows - 1) >> 2) + 1;
    return r > 2 ? r : 2;
}
/* Whether each final time row is fitted fewer than TRAIN_UNDERFITTED_FITS times in the fine stage:
 * a long clip whose raised budget hit the cap. Such a clip warms its time rows up and trades its
 * movers' density for steps (TRAIN_LONG_CLIP_DENSIFY_MOVABLE). */
static int time_rows_underfitted(const train_session *s)
{
    const long fits = (long)(s->cfg.iters - s->cfg.coarse_iters) * (times_per_step(&s->cfg) + motion_crops(s));
    return fits < (long)final_time_rows(s) * TRAIN_UNDERFITTED_FITS;
}
/* Fine steps on the warm-up's time rows (0: none). Only an underfitted clip warms up: the
 * 300-frame sample clip (~27 fits per row) gained 1.2 dB on its movers, the 30-frame one (~125)
 * lost 3.3 (docs/train.md). */
static int time_warmup_steps(const train_session *s)
{
    int rows = final_time_rows(s);
    if (!(s->cfg.deform_time_warmup > 0) || warmup_time_rows(rows) >= rows || !time_rows_underfitted(s)) return 0;
    return (int)(s->cfg.deform_time_warmup * (float)(s->cfg.iters - s->cfg.coarse_iters));
}

/* Ends the warm-up: the network, its Adam moments and its running average move to the final
 * time rows, each resampled in time, so the motion learnt so far carries over unchanged. */
static pg_status refine_time_rows(train_session *s, int tres)
{
    train_net *old = s->net, *nn = NULL;
    PG_TRY(train_net_resample_time(old, tres, &nn));
    float *avg = s->avg_net ? pg_malloc(train_net_num_params(nn) * sizeof(float), "time refinement") : NULL;
    optim_adam *old_opt = s->nopt;
    s->nopt = NULL;
    s->net = nn;
    pg_status st = !s->avg_net || avg ? train_adam_resample_net(s, old, old_opt) : PG_ERR_NOMEM;
    if (!st && avg) {
        train_net_resample_array(old, s->avg_net, nn, avg);
        free(s->avg_net);
        s->avg_net = avg;
        avg = NULL;
    }
    if (!st) s->net_cfg.tres = tres;
    free(avg);
    if (st) { /* keep the old network */
        optim_adam_destroy(s->nopt);
        s->nopt = old_opt;
        s->net = old;
        train_net_destroy(nn);
        return st;
    }
    optim_adam_destroy(old_opt);
    train_net_destroy(old);
    return PG_OK;
}

/* Creates the network (fine stage) over the box of the canonical means that go through it (the
 * movable ones; all when static flags are off or none is movable): the HexPlane's texels then
 * sit where the motion is instead of spreading over the whole room. Points outside the box
 * (densified later) read the border texels. */
static pg_status start_fine(train_session *s)
{
    train_net_config nc;
    memset(&nc, 0, sizeof nc);
    float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
    int movable = 0;
    for (int i = 0; i < s->g.count && s->cfg.use_static_flags; i++) movable += !s->is_static[i];
    int only_movable = movable > 0 && s->cfg.use_static_flags;
    for (int i = 0; i < s->g.count; i++)
        for (int k = 0; k < 3 && !(only_movable && s->is_static[i]); k++) {
            float x = s->g.means[3 * i + k];
            lo[k] = fminf(lo[k], x);
            hi[k] = fmaxf(hi[k], x);
        }
    for (int k = 0; k < 3; k++) {
        float pad = 0.05f * (hi[k] - lo[k]) + 1e-4f;
        nc.aabb_min[k] = lo[k] - pad;
        nc.aabb_max[k] = hi[k] + pad;
    }
    nc.width = s->cfg.deform_width;
    nc.head_width = s->cfg.deform_head_width;
    nc.time_coarsen = s->cfg.deform_time_coarsen;
    nc.res = s->cfg.deform_res;
    nc.tres = final_time_rows(s);
    if (time_warmup_steps(s) > 0) nc.tres = warmup_time_rows(nc.tres);
    nc.channels = s->cfg.deform_channels;
    nc.seed = s->cfg.seed * 7919u + 17u;
    s->net_cfg = nc;
    PG_TRY(train_net_create(&s->net, &nc));
    PG_TRY(train_adam_create_net(s));
    s->fine = 1;
    return PG_OK;
}

float train_session_densify_movable(const train_session *s) { return s->cfg.densify_movable; }

void train_session_time_rows(const train_session *s, int *rows, int *warmup_rows)
{
    *rows = s->net ? s->net_cfg.tres : final_time_rows(s);
    *warmup_rows = time_warmup_steps(s) > 0 ? warmup_time_rows(final_time_rows(s)) : 0;
}

pg_status train_session_force_fine(train_session *s)
{
    if (s->fine) return PG_OK;
    s->iter = s->cfg.coarse_iters;
    return start_fine(s);
}

pg_status train_session_set_gaussians(train_session *s, const pg_gaussians *g, const uint8_t *is_static)
{
    if (g->count < 1) return pg_fail(PG_ERR_ARG, "train: empty Gaussian set");
    PG_TRY(train_resize_all(s, 0));
    PG_TRY(train_resize_all(s, g->count));
    train_blend_gaussians(&s->g, g, TRAIN_BLEND_COPY, 0.0f, PG_SH_FLOATS);
    for (int i = 0; i < g->count; i++) s->is_static[i] = is_static ? is_static[i] : 0;
    memset(s->grad_accum, 0, (size_t)s->side_cap * sizeof(float));
    memset(s->grad_denom, 0, (size_t)s->side_cap * sizeof(float));
    train_update_filter(s);
    return PG_OK;
}

pg_status train_session_create(train_session **out, const train_set *ts, const train_config *cfg,
                               const char *ckpt_path, int resume)
{
    *out = NULL;
    if (cfg->iters < 1 || cfg->coarse_iters < 0 || cfg->max_gaussians < 1)
        return pg_fail(PG_ERR_ARG, "train: bad iteration counts or Gaussian cap");
    if (train_set_count_role(ts, IO_ROLE_REAL) + train_set_count_role(ts, IO_ROLE_PROXY) == 0)
        return pg_fail(PG_ERR_ARG, "train: the training set has no real or proxy views");
    train_session *s = pg_calloc(1, sizeof *s, "training session");
    if (!s) return PG_ERR_NOMEM;
    s->ts = ts;
    s->cfg = *cfg;
    if (s->cfg.views_per_step < 1) s->cfg.views_per_step = 1;
    if (s->cfg.densify_until <= 0) s->cfg.densify_until = train_default_densify_until(cfg->iters);
    if (ckpt_path) snprintf(s->ckpt_path, sizeof s->ckpt_path, "%s", ckpt_path);
    pg_status st;
    size_t px = (size_t)ts->width * ts->height;
    if ((st = splat_raster_create(&s->raster))) goto fail;
    if ((st = pg_image_create(&s->target, ts->width, ts->height, 3))) goto fail;
    s->mask = pg_malloc(px * sizeof(float), "training mask");
    s->depth_t = pg_malloc(px * sizeof(float), "training depth");
    s->depth_mask = pg_malloc(px * sizeof(float), "training depth mask");
    if ((st = optim_ssim_create(&s->ssim, ts->height, ts->width, 3))) goto fail;
    s->d_rgb = pg_malloc(px * 3 * sizeof(float), "rgb gradient");
    s->d_depth = pg_malloc(px * sizeof(float), "depth gradient");
    if (!s->mask || !s->depth_t || !s->depth_mask || !s->d_rgb || !s->d_depth) {
        st = PG_ERR_NOMEM;
        goto fail;
    }
    if ((st = find_moving_pixels(s))) goto fail;
    if ((st = find_moving_regions(s))) goto fail;
    if (ckpt_path) train_checkpoint_clean_temps(ckpt_path);
    if (resume && ckpt_path && pg_path_exists(ckpt_path)) {
        if ((st = train_checkpoint_read(s, ckpt_path))) goto fail;
        /* options that may legitimately change on resume */
        s->cfg.iters = cfg->iters;
        s->cfg.checkpoint_every = cfg->checkpoint_every;
        s->cfg.stop_at_iter = cfg->stop_at_iter;
    } else {
        if (!(s->cfg.densify_movable > 0)) /* the rule; a resumed run keeps the value it started with */
            s->cfg.densify_movable = time_rows_underfitted(s) ? TRAIN_LONG_CLIP_DENSIFY_MOVABLE : 1.0f;
        pg_rng_seed(&s->rng, cfg->seed);
        if ((st = train_init_gaussians(s))) goto fail;
        train_update_filter(s);
        splat_filter3d_fit_init(s->g.log_scales, s->g.opacity, s->filter_var, s->g.count);
        if (!s->cfg.use_static_flags) memset(s->is_static, 0, (size_t)s->g.count);
        if (s->cfg.coarse_iters == 0 && (st = start_fine(s))) goto fail;
    }
    *out = s;
    return PG_OK;
fail:
    train_session_destroy(s);
    return st;
}

/* The frame of iteration it: every frame once per epoch of F iterations, in an order shuffled by
 * (seed, epoch). Derived from the iteration alone, so resuming needs no extra state. */
static int pick_frame(const train_session *s, int it)
{
    int F = s->ts->frames, epoch = it / F, pos = it % F;
    pg_rng r;
    pg_rng_seed(&r, s->cfg.seed * 0x9E3779B97F4A7C15ULL + (uint64_t)epoch * 0xBF58476D1CE4E5B9ULL + 1);
    int perm[F];
    for (int i = 0; i < F; i++) perm[i] = i;
    for (int i = F - 1; i > 0; i--) {
        int j = (int)pg_rng_below(&r, (uint32_t)(i + 1)), tmp = perm[i];
        perm[i] = perm[j];
        perm[j] = tmp;
    }
    return perm[pos];
}

/* Draws k distinct views of a role into out (k <= the role's count); returns k. */
static int pick_views(train_session *s, io_view_role role, int k, int *out)
{
    const train_set *ts = s->ts;
    int n = train_set_count_role(ts, role);
    if (k > n) k = n;
    for (int got = 0; got < k;) {
        int pick = (int)pg_rng_below(&s->rng, (uint32_t)n), vi = -1;
        for (int i = 0; i < ts->num_views; i++)
            if (ts->views[i].role == role && pick-- == 0) {
                vi = i;
                break;
            }
        int dup = 0;
        for (int j = 0; j < got; j++) dup |= out[j] == vi;
        if (!dup) out[got++] = vi;
    }
    return k;
}

/* The batch of one step: one real view and views_per_step - 1 proxies (real views only when
 * there are no proxies, proxies only when there is no real view), with their loss weights
 * (real_weight on the real view when proxies share the batch, the rest split evenly). */
static int pick_batch(train_session *s, int *views, float *weights)
{
    const train_set *ts = s->ts;
    int nreal = train_set_count_role(ts, IO_ROLE_REAL), nproxy = train_set_count_role(ts, IO_ROLE_PROXY);
    int k = s->cfg.views_per_step, n;
    if (nproxy == 0) {
        n = pick_views(s, IO_ROLE_REAL, k, views);
        for (int i = 0; i < n; i++) weights[i] = 1.0f / n;
        return n;
    }
    n = nreal > 0 ? pick_views(s, IO_ROLE_REAL, 1, views) : 0;
    int np = pick_views(s, IO_ROLE_PROXY, k - n > 0 ? k - n : 1, views + n);
    float wr = n ? s->cfg.real_weight : 0.0f;
    if (n) weights[0] = np ? wr : 1.0f;
    for (int i = 0; i < np; i++) weights[n + i] = (1.0f - wr) / np;
    return n + np;
}

float train_frame_time(int f, int frames) { return frames > 1 ? (float)f / (float)(frames - 1) : 0.0f; }

/* Whether a Gaussian at camera-space (xc, yc, zc) with margin m may land in the camera's frame. */
static int may_be_visible(const pg_camera *cam, const float *x, float m)
{
    float zc = cam->R[6] * x[0] + cam->R[7] * x[1] + cam->R[8] * x[2] + cam->t[2];
    float xc = cam->R[0] * x[0] + cam->R[1] * x[1] + cam->R[2] * x[2] + cam->t[0];
    float yc = cam->R[3] * x[0] + cam->R[4] * x[1] + cam->R[5] * x[2] + cam->t[1];
    if (zc + m < 0.01f) return 0;
    if (zc <= m) return 1;
    float mx = cam->fx * m / zc + 0.15f * cam->width, my = cam->fy * m / zc + 0.15f * cam->height;
    float u = cam->fx * xc / zc + cam->cx, v = cam->fy * yc / zc + cam->cy;
    return !(u < -mx || u > cam->width + mx || v < -my || v > cam->height + my);
}

/* Selects the Gaussians to send through the network: the step's moving rows (list_step_rows)
 * that are, if culling, within the frustum of one of the ncam cameras, enlarged by the largest
 * displacement seen plus the Gaussian's own size. */
static int build_subset(train_session *s, const pg_camera *const *cams, int ncam)
{
    const pg_gaussians *g = &s->g;
    const int nm = s->n_moving_rows;
    if (ncam == 0) {
        memcpy(s->idx, s->step_rows, (size_t)nm * sizeof(int));
        return nm;
    }
    /* the test in parallel (an exponential and a projection per row), the list in row order */
    uint8_t *vis = s->row_flags;
    #pragma omp parallel for schedule(static)
    for (int k = 0; k < nm; k++) {
        const int i = s->step_rows[k];
        const float *ls = g->log_scales + 3 * (size_t)i;
        float m = s->max_disp + 3.0f * expf(fmaxf(ls[0], fmaxf(ls[1], ls[2])));
        int v = 0;
        for (int c = 0; c < ncam && !v; c++) v = may_be_visible(cams[c], g->means + 3 * (size_t)i, m);
        vis[k] = (uint8_t)v;
    }
    int n = 0;
    for (int k = 0; k < nm; k++)
        if (vis[k]) s->idx[n++] = s->step_rows[k];
    return n;
}

/* Scales the loss weight of proxy view vi's pixels at frame f that show something moving in the
 * real view (the pixel's depth, already in s->depth_t, carried into the real camera lands on a
 * moving pixel) by
 * proxy_moving_weight: a moving object's monocular depth is the least reliable part of a proxy
 * (smeared edges, a body stretched to the floor behind it), and at full weight those pixels
 * out-voted the real view, which alone sees the motion as it was. */
static void weigh_proxy_moving(train_session *s, const train_view *v, int f)
{
    const train_set *ts = s->ts;
    int real = -1;
    for (int k = 0; k < ts->num_views && real < 0; k++)
        if (ts->views[k].role == IO_ROLE_REAL && s->moving && s->moving[k]) real = k;
    if (real < 0 || !v->depth || s->cfg.proxy_moving_weight >= 1.0f) return;
    const int W = ts->width, H = ts->height;
    const size_t px = (size_t)W * H;
    const uint8_t *mv = s->moving[real] + (size_t)f * px;
    const pg_camera *rc = &ts->views[real].cam;
    const float *d = s->depth_t;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            size_t i = (size_t)y * W + x;
            if (!(d[i] > 0) || s->mask[i] <= 0) continue;
            float X[3], uv[2];
            pg_camera_unproject(&v->cam, x + 0.5f, y + 0.5f, d[i], X);
            if (!(pg_camera_project(rc, X, uv) > 0)) continue;
            int qx = (int)floorf(uv[0]), qy = (int)floorf(uv[1]);
            if (qx >= 0 && qx < W && qy >= 0 && qy < H && mv[(size_t)qy * W + qx]) s->mask[i] *= s->cfg.proxy_moving_weight;
        }
}

/* Loads the target image, loss weights and depth of (view, frame) into the session buffers;
 * returns whether the view has depth. Weights: the view's mask, times 1 + moving_weight on
 * moving pixels when moving (training) is set; proxies' moving pixels at proxy_moving_weight. */
static int load_target(train_session *s, int vi, int f, int moving)
{
    const train_set *ts = s->ts;
    const train_view *v = &ts->views[vi];
    size_t px = (size_t)ts->width * ts->height;
    train_set_frame_rgb(ts, vi, f, &s->target);
    const uint8_t *mv = moving && s->moving && s->moving[vi] ? s->moving[vi] + (size_t)f * px : NULL;
    const uint8_t *vm = v->mask ? v->mask + (size_t)f * px : NULL;
    #pragma omp parallel for schedule(static)
    for (size_t i = 0; i < px; i++) {
        float m = vm ? vm[i] * (1.0f / TRAIN_MASK_FULL) : 1.0f;
        s->mask[i] = mv ? m * (1.0f + s->cfg.moving_weight * mv[i]) : m;
    }
    if (v->depth) train_view_depth_frame(v, f, px, s->depth_t);
    if (moving && v->role == IO_ROLE_PROXY) weigh_proxy_moving(s, v, f);
    return v->depth != NULL;
}

void train_update_filter(train_session *s)
{
    const train_set *ts = s->ts;
    pg_camera cams[ts->num_views + 1];
    int ncam = 0;
    for (int v = 0; v < ts->num_views; v++)
        if (ts->views[v].role != IO_ROLE_TEST) cams[ncam++] = ts->views[v].cam;
    if (s->detail) cams[ncam++] = s->detail->cam; /* the full-size phase draws finer */
    splat_filter3d_compute(s->g.means, s->g.count, cams, ncam, s->filter_var);
}

/* Deformed copy d of the canonical set at time t for the ncam cameras (culling to their frusta
 * when enabled; ncam 0: no culling), with the 3D filter applied (the unfiltered values kept in
 * filter_saved for the backward). whole 0: only the step's moving rows are redone (the fixed
 * ones are as the step's first time left them, list_step_rows). */
static pg_status deform_all(train_session *s, const pg_camera *const *cams, int ncam, float t, int whole, int *n_deformed)
{
    if (whole) blend_used(s, &s->d, &s->g, TRAIN_BLEND_COPY);
    else blend_rows(s, &s->d, &s->g, s->step_rows, s->n_moving_rows, TRAIN_BLEND_COPY);
    *n_deformed = 0;
    if (s->fine) {
        int n = build_subset(s, cams, s->cfg.use_frustum_cull ? ncam : 0);
        *n_deformed = n;
        if (n > 0) PG_TRY(train_net_forward(s->net, &s->g, s->idx, n, t, splat_sh_floats(s->cfg.sh_max_degree), &s->d));
    }
    if (whole) splat_filter3d_forward(s->d.log_scales, s->d.opacity, s->filter_var, s->d.count, s->filter_saved);
    else splat_filter3d_forward_rows(s->d.log_scales, s->d.opacity, s->filter_var, s->step_rows, s->n_moving_rows,
                                     s->filter_saved);
    return PG_OK;
}

/* The fixed rows' gradients, summed over the step's times in dg, through the 3D filter into gg
 * (list_step_rows). */
static void finish_fixed_rows(train_session *s)
{
    const int *fixed = s->step_rows + s->n_moving_rows;
    splat_filter3d_backward_rows(s->filter_saved, s->filter_var, fixed, s->n_fixed_rows, s->dg.log_scales, s->dg.opacity);
    blend_rows(s, &s->gg, &s->dg, fixed, s->n_fixed_rows, TRAIN_BLEND_COPY);
}

/* lambda_d * scale-and-shift-invariant L2 of the rendered depth against the target, divided by
 * the target's variance on valid pixels so the weight does not depend on the depth units. */
static double depth_loss(train_session *s, const float *depth, int W, int H, float weight)
{
    size_t px = (size_t)W * H;
    double n = 0, sum = 0, sum2 = 0;
    for (size_t i = 0; i < px; i++) {
        /* invalid target pixels are excluded through the mask; the real view's movers weigh what
         * they weigh in the image loss (1 + moving_weight), or their depth would hold them ten times
         * less than their colours pull them (docs/train.md, "The movers' depth") */
        s->depth_mask[i] = (s->depth_t[i] > 0 && s->mask[i] > 0.5f) ? fmaxf(1.0f, s->mask[i]) : 0.0f;
        if (s->depth_mask[i] > 0) {
            n += 1;
            sum += s->depth_t[i];
            sum2 += (double)s->depth_t[i] * s->depth_t[i];
        }
    }
    if (n < 16) return 0;
    double var = sum2 / n - (sum / n) * (sum / n);
    if (!(var > 1e-12)) return 0;
    optim_ssi_depth fit;
    double l = optim_ssi_depth_forward(&fit, depth, s->depth_t, s->depth_mask, (long)px);
    float w = (float)(weight * s->cfg.lambda_depth / var);
    optim_ssi_depth_backward(s->d_depth, w, &fit, depth, s->depth_t, s->depth_mask, (long)px);
    return w * l;
}

/* Row i's deformed attributes (s->d) minus its canonical ones (s->g): position, log-scales,
 * rotation, opacity, then the SH floats (0 past the set's stride: no change). */
#define TRAIN_ROW_DELTAS 59
static void row_deltas(const train_session *s, int i, float *dl)
{
    memset(dl, 0, TRAIN_ROW_DELTAS * sizeof(float));
    for (int a = 0; a < 3; a++) dl[a] = s->d.means[3 * i + a] - s->g.means[3 * i + a];
    for (int a = 0; a < 3; a++) dl[3 + a] = s->d.log_scales[3 * i + a] - s->g.log_scales[3 * i + a];
    for (int a = 0; a < 4; a++) dl[6 + a] = s->d.quats[4 * i + a] - s->g.quats[4 * i + a];
    dl[10] = s->d.opacity[i] - s->g.opacity[i];
    for (int a = 0; a < s->g.sh_stride; a++) dl[11 + a] = splat_gaussians_sh(&s->d, i)[a] - splat_gaussians_sh(&s->g, i)[a];
}

/* Row i made still with its mean deltas dl baked into its canonical parameters. */
static void bake_still(train_session *s, int i, const float *dl)
{
    for (int a = 0; a < 3; a++) s->g.means[3 * i + a] += dl[a];
    for (int a = 0; a < 3; a++) s->g.log_scales[3 * i + a] += dl[3 + a];
    for (int a = 0; a < 4; a++) s->g.quats[4 * i + a] += dl[6 + a];
    s->g.opacity[i] += dl[10];
    for (int a = 0; a < s->g.sh_stride; a++) splat_gaussians_sh(&s->g, i)[a] += dl[11 + a];
    s->is_static[i] = 1;
}

/* Learned static flags: evaluates the network for every movable Gaussian at 5 times; those
 * whose predicted deltas hardly change over time (position by < static_eps * extent, the other
 * attributes by < 0.02) get the mean delta baked into their canonical parameters and are
 * flagged static, so they skip the network from now on. */
static pg_status check_static(train_session *s)
{
    int n = 0;
    for (int i = 0; i < s->g.count; i++)
        if (!s->is_static[i]) s->idx[n++] = i;
    if (n == 0) return PG_OK;
    size_t N = (size_t)s->g.count;
    const int S = s->g.sh_stride;
    enum { K = 5 };
    float *lo = pg_malloc((size_t)n * TRAIN_ROW_DELTAS * sizeof(float), "static check");
    float *hi = pg_malloc((size_t)n * TRAIN_ROW_DELTAS * sizeof(float), "static check");
    float *mean = pg_calloc((size_t)n * TRAIN_ROW_DELTAS, sizeof(float), "static check");
    pg_status st = (lo && hi && mean) ? PG_OK : PG_ERR_NOMEM;
    for (int k = 0; k < K && !st; k++) {
        blend_used(s, &s->d, &s->g, TRAIN_BLEND_COPY);
        if ((st = train_net_forward(s->net, &s->g, s->idx, n, (float)k / (K - 1), S, &s->d))) break;
        for (int j = 0; j < n; j++) {
            int i = s->idx[j];
            float dl[TRAIN_ROW_DELTAS];
            row_deltas(s, i, dl);
            for (int a = 0; a < TRAIN_ROW_DELTAS; a++) {
                size_t o = (size_t)j * TRAIN_ROW_DELTAS + a;
                lo[o] = k ? fminf(lo[o], dl[a]) : dl[a];
                hi[o] = k ? fmaxf(hi[o], dl[a]) : dl[a];
                mean[o] += dl[a] / K;
            }
        }
    }
    float pos_tol = s->cfg.static_eps * s->extent;
    for (int j = 0; j < n && !st; j++) {
        size_t o = (size_t)j * TRAIN_ROW_DELTAS;
        int ok = 1;
        for (int a = 0; a < TRAIN_ROW_DELTAS && ok; a++) ok = hi[o + a] - lo[o + a] < (a < 3 ? pos_tol : 0.02f);
        if (!ok) continue;
        bake_still(s, s->idx[j], mean + o);
        train_average_restart(s);
    }
    (void)N;
    free(lo);
    free(hi);
    free(mean);
    return st;
}

/* The movable rows that never cover a moving pixel of the real view (its trainer mask, at every
 * FREEZE_EVERY-th frame, the deformed centre's pixel and its 8 neighbours) made still, their mean
 * deltas over those frames baked in: at the working size they are blurred still scene (the
 * seated people, a mover's halo), and drawn over the full-size still scene they hide it. */
#define FREEZE_EVERY 4
pg_status train_freeze_off_motion(train_session *s, int *frozen)
{
    const train_set *ts = s->ts;
    int real = 0;
    while (real < ts->num_views && ts->views[real].role != IO_ROLE_REAL) real++;
    *frozen = 0;
    if (!s->fine || real == ts->num_views || !s->moving || !s->moving[real]) return PG_OK;
    const pg_camera *cam = &ts->views[real].cam;
    const int W = ts->width, H = ts->height, D = TRAIN_ROW_DELTAS;
    int n = 0;
    for (int i = 0; i < s->g.count; i++)
        if (!s->is_static[i]) s->idx[n++] = i;
    if (n == 0) return PG_OK;
    float *mean = pg_calloc((size_t)n * D, sizeof(float), "freeze");
    uint8_t *hit = pg_calloc((size_t)n, 1, "freeze");
    pg_status st = mean && hit ? PG_OK : PG_ERR_NOMEM;
    int samples = 0;
    for (int f = 0; f < ts->frames && !st; f += FREEZE_EVERY, samples++) {
        blend_used(s, &s->d, &s->g, TRAIN_BLEND_COPY);
        if ((st = train_net_forward(s->net, &s->g, s->idx, n, train_frame_time(f, ts->frames), s->g.sh_stride, &s->d))) break;
        const uint8_t *mv = s->moving[real] + (size_t)f * W * H;
        #pragma omp parallel for schedule(static)
        for (int j = 0; j < n; j++) {
            const int i = s->idx[j];
            float dl[TRAIN_ROW_DELTAS], uv[2];
            row_deltas(s, i, dl);
            for (int a = 0; a < D; a++) mean[(size_t)j * D + a] += dl[a];
            if (pg_camera_project(cam, s->d.means + 3 * (size_t)i, uv) <= 0.01f) continue;
            const int x = (int)floorf(uv[0]), y = (int)floorf(uv[1]);
            for (int dy = -1; dy <= 1 && !hit[j]; dy++)
                for (int dx = -1; dx <= 1 && !hit[j]; dx++) {
                    const int xx = x + dx, yy = y + dy;
                    if (xx >= 0 && xx < W && yy >= 0 && yy < H && mv[(size_t)yy * W + xx]) hit[j] = 1;
                }
        }
    }
    for (int j = 0; !st && j < n; j++) {
        if (hit[j]) continue;
        for (int a = 0; a < D; a++) mean[(size_t)j * D + a] /= samples;
        bake_still(s, s->idx[j], mean + (size_t)j * D);
        (*frozen)++;
    }
    free(mean);
    free(hit);
    return st;
}

/* Keeps the rect (x0, y0, w, h) of the (W, c)-channel image in buf, packed at its start: rows
 * move to lower addresses only, so in place is safe. */
static void crop_in_place(float *buf, int W, int c, const int *rect)
{
    for (int y = 0; y < rect[3]; y++)
        memmove(buf + (size_t)y * rect[2] * c, buf + ((size_t)(rect[1] + y) * W + rect[0]) * c,
                (size_t)rect[2] * c * sizeof *buf);
}

/* The camera of rect (x0, y0, w, h) of cam's image: its size, the principal point shifted. */
static pg_camera crop_camera(const pg_camera *cam, const int *rect)
{
    pg_camera c = *cam;
    c.width = rect[2], c.height = rect[3];
    c.cx -= (float)rect[0], c.cy -= (float)rect[1];
    return c;
}

/* Output pixels only read input rows at or after their own index, so in place is safe. */
void train_halve_in_place(float *buf, int w, int h, int c, int skip_zero)
{
    const int w2 = w / 2, h2 = h / 2;
    for (int y = 0; y < h2; y++)
        for (int x = 0; x < w2; x++)
            for (int k = 0; k < c; k++) {
                const float *p = buf + ((size_t)(2 * y) * w + 2 * x) * c + k;
                const float v[4] = { p[0], p[c], p[(size_t)w * c], p[(size_t)w * c + c] };
                float sum = 0, n = 0;
                for (int q = 0; q < 4; q++)
                    if (!skip_zero || v[q] > 0) sum += v[q], n += 1;
                buf[((size_t)y * w2 + x) * c + k] = n > 0 ? sum / n : 0.0f;
            }
}

pg_camera train_half_camera(const pg_camera *cam)
{
    pg_camera c = *cam;
    c.width = cam->width / 2, c.height = cam->height / 2;
    c.fx *= 0.5f, c.fy *= 0.5f, c.cx *= 0.5f, c.cy *= 0.5f;
    return c;
}

/* The SSIM workspace for a w x h image: the full-size one, or the one every smaller image (crops)
 * shares, reshaped to it. */
static pg_status ssim_workspace(train_session *s, int w, int h, optim_ssim_ws **ws)
{
    if (w == s->ts->width && h == s->ts->height) {
        *ws = s->ssim;
        return PG_OK;
    }
    if (!s->ssim_crop) PG_TRY(optim_ssim_create(&s->ssim_crop, s->ts->height, s->ts->width, 3));
    PG_TRY(optim_ssim_reshape(s->ssim_crop, h, w));
    *ws = s->ssim_crop;
    return PG_OK;
}

/* Renders view vi at frame f from the deformed set d (only the pixels of rect - x0, y0, w, h -
 * when rect is set), adds its weighted loss gradient into dg and its view-space gradients into
 * the density statistics (measured at unit weight, so the 3DGS threshold keeps its meaning);
 * returns the weighted loss. */
static pg_status step_view(train_session *s, int vi, int f, float weight, const int *rect, double *loss_out)
{
    const train_set *ts = s->ts;
    const train_config *c = &s->cfg;
    pg_camera cam = ts->views[vi].cam, whole = cam;
    int real = ts->views[vi].role == IO_ROLE_REAL;
    double t0 = pg_time_seconds(), t1;
    const int full = rect && real && s->detail; /* a full-size crop of the full-size phase */
    int has_depth = 0;
    if (full) {
        train_detail_target(s, f, rect, s->target.data, s->mask);
        whole = s->detail->cam;
        cam = crop_camera(&whole, rect);
    } else {
        has_depth = load_target(s, vi, f, 1);
        if (rect) {
            crop_in_place(s->target.data, ts->width, 3, rect);
            crop_in_place(s->mask, ts->width, 1, rect);
            if (has_depth) crop_in_place(s->depth_t, ts->width, 1, rect);
            cam = crop_camera(&cam, rect);
        }
    }
    if (c->proxy_downscale == 2 && ts->views[vi].role == IO_ROLE_PROXY && cam.width >= 32 && cam.height >= 32) {
        train_halve_in_place(s->target.data, cam.width, cam.height, 3, 0);
        train_halve_in_place(s->mask, cam.width, cam.height, 1, 0);
        if (has_depth) train_halve_in_place(s->depth_t, cam.width, cam.height, 1, 1);
        cam = train_half_camera(&cam);
        whole = train_half_camera(&whole);
    }
    const int W = cam.width, H = cam.height;
    const size_t px = (size_t)W * H;
    optim_ssim_ws *ssim;
    PG_TRY(ssim_workspace(s, W, H, &ssim));
    t1 = pg_time_seconds();
    s->timing.targets += (t1 - t0) * 1e3;
    t0 = t1;
    pg_render_settings rs = splat_default_settings();
    memcpy(rs.background, c->bg, sizeof rs.background);
    if (rect) rs.whole = &whole;
    pg_render_output out;
    PG_TRY(splat_render_forward(s->raster, &s->d, &cam, &rs, &out));
    t1 = pg_time_seconds();
    s->timing.raster_forward += (t1 - t0) * 1e3;
    t0 = t1;

    memset(s->d_rgb, 0, px * 3 * sizeof(float));
    memset(s->d_depth, 0, px * sizeof(float));
    int weighted = ts->views[vi].mask != NULL || (real && s->moving && s->moving[vi]) ||
                   (ts->views[vi].role == IO_ROLE_PROXY && s->cfg.proxy_moving_weight < 1.0f);
    const float *mk = weighted ? s->mask : NULL;
    double loss = optim_l1_forward(out.rgb, s->target.data, mk, H, W, 3);
    optim_l1_backward(s->d_rgb, weight, out.rgb, s->target.data, mk, H, W, 3);
    if (c->lambda_dssim > 0) {
        float ssim_v = optim_ssim_forward(ssim, out.rgb, s->target.data, mk, H, W, 3);
        optim_ssim_backward(ssim, s->d_rgb, -c->lambda_dssim * weight, out.rgb, s->target.data, mk, H, W, 3);
        loss += c->lambda_dssim * (1.0 - ssim_v);
    }
    loss *= weight;
    if (has_depth && c->lambda_depth > 0) loss += depth_loss(s, out.depth, W, H, weight); /* weighted inside */
    if (real && !rect) {
        pg_image rendered = {W, H, 3, out.rgb};
        s->last_psnr = pg_image_psnr(&rendered, &s->target, ts->views[vi].mask ? s->mask : NULL);
    }
    t1 = pg_time_seconds();
    s->timing.loss += (t1 - t0) * 1e3;
    t0 = t1;

    /* the densification's statistics, while a densification is still to come (a long clip's
     * budget trains ~3/4 of its steps after the last one) */
    const int densifying = s->detail ? s->detail->densify : s->iter + 1 < c->densify_until;
    if (densifying) memset(s->vs_grad, 0, (size_t)s->g.count * sizeof(float));
    PG_TRY(splat_render_backward(s->raster, &s->d, &cam, &rs, s->d_rgb, has_depth ? s->d_depth : NULL, NULL, &s->dg,
                                 densifying ? s->vs_grad : NULL));
    t1 = pg_time_seconds();
    s->timing.raster_backward += (t1 - t0) * 1e3;

    if (densifying) {
        const float unit = weight > 0 ? 1.0f / weight : 0.0f;
        #pragma omp parallel for schedule(static)
        for (int i = 0; i < s->d.count; i++) {
            float uv[2];
            float z = pg_camera_project(&cam, s->d.means + 3 * i, uv);
            if (z > 0.01f && uv[0] >= 0 && uv[0] < W && uv[1] >= 0 && uv[1] < H) {
                s->grad_accum[i] += s->vs_grad[i] * unit;
                s->grad_denom[i] += 1;
            }
        }
    }
    *loss_out = loss;
    return PG_OK;
}

/* Deforms once to frame f's time, renders and back-propagates each of the nb views (view b cropped
 * to rects[4 b ...] when rects is set), then sends the gradient through the network; the canonical
 * gradient is summed into gg (first = 1: gg starts from it). Returns the loss. */
static pg_status step_views(train_session *s, int f, const int *views, const float *weights, int nb,
                            const int *rects, int first, double *loss_out)
{
    const train_set *ts = s->ts;
    double t0 = pg_time_seconds(), t1;
    pg_camera crop_cams[TRAIN_MAX_BATCH];
    const pg_camera *cams[TRAIN_MAX_BATCH];
    for (int b = 0; b < nb; b++) {
        cams[b] = &ts->views[views[b]].cam;
        if (rects && s->detail && ts->views[views[b]].role == IO_ROLE_REAL) cams[b] = &s->detail->cam;
        if (rects) { /* cull to the crops' frusta */
            crop_cams[b] = crop_camera(cams[b], rects + 4 * b);
            cams[b] = &crop_cams[b];
        }
    }
    float t = train_frame_time(f, ts->frames);

    int nd = 0;
    PG_TRY(deform_all(s, cams, nb, t, first, &nd));
    s->timing.deformed += nd;
    if (s->fine) {
        s->sum_deformed += nd;
        s->sum_movable += s->n_moving_rows;
        s->fine_steps++;
    }
    if (s->fine && nd > 0) {
        float md = s->max_disp;
#pragma omp parallel for schedule(static) reduction(max : md)
        for (int k = 0; k < nd; k++) {
            int i = s->idx[k];
            float dx[3];
            vec3_sub(dx, s->d.means + 3 * i, s->g.means + 3 * i);
            md = fmaxf(md, vec3_norm(dx));
        }
        s->max_disp = fminf(md, s->extent);
    }
    t1 = pg_time_seconds();
    s->timing.deform_forward += (t1 - t0) * 1e3;

    /* every view's gradient sums into dg in batch order (deterministic); the fixed rows' sum over
     * the step's times */
    if (first) blend_used(s, &s->dg, &s->dg, TRAIN_BLEND_ZERO);
    else blend_rows(s, &s->dg, &s->dg, s->step_rows, s->n_moving_rows, TRAIN_BLEND_ZERO);
    double loss = 0;
    for (int b = 0; b < nb; b++) {
        double lv;
        PG_TRY(step_view(s, views[b], f, weights[b], rects ? rects + 4 * b : NULL, &lv));
        loss += lv;
    }
    t0 = pg_time_seconds();

    /* the moving rows through the 3D filter, then the identity path and the deformation path for
     * the deformed rows (the fixed rows at the step's end, finish_fixed_rows); a step of one time
     * does every row at once, in order */
    if (one_time_per_step(s)) {
        splat_filter3d_backward(s->filter_saved, s->filter_var, s->dg.count, s->dg.log_scales, s->dg.opacity);
        blend_used(s, &s->gg, &s->dg, TRAIN_BLEND_COPY);
    } else {
        splat_filter3d_backward_rows(s->filter_saved, s->filter_var, s->step_rows, s->n_moving_rows, s->dg.log_scales,
                                     s->dg.opacity);
        blend_rows(s, &s->gg, &s->dg, s->step_rows, s->n_moving_rows, first ? TRAIN_BLEND_COPY : TRAIN_BLEND_ADD);
    }
    if (s->fine && nd > 0)
        PG_TRY(train_net_backward(s->net, &s->g, s->idx, nd, t, splat_sh_floats(s->cfg.sh_max_degree), &s->dg, &s->gg));
    s->timing.deform_backward += (pg_time_seconds() - t0) * 1e3;
    *loss_out = loss;
    return PG_OK;
}

/* One time of a step: frame `slot` of the epoch order with its batch of views. */
static pg_status step_time(train_session *s, int slot, int first, double *loss_out)
{
    int f = pick_frame(s, slot);
    int views[TRAIN_MAX_BATCH];
    float weights[TRAIN_MAX_BATCH];
    int nb = pick_batch(s, views, weights);
    return step_views(s, f, views, weights, nb, NULL, first, loss_out);
}

/* View v's movers at frame f when v is a proxy (NULL for the real views). */
static const train_region *proxy_box_at(const train_session *s, int v, int f)
{
    return s->ts->views[v].role == IO_ROLE_PROXY ? train_motion_regions_at(&s->regions[v], f) : NULL;
}

/* A random window of frame f's full-size box, at most TRAIN_DETAIL_WINDOW a side: a box holds
 * every mover of the frame (half of a classroom's frame), and a window of it costs a fraction. */
static void full_size_window(train_session *s, int f, int *rect)
{
    memcpy(rect, s->detail->rect + 4 * (size_t)f, 4 * sizeof(int));
    for (int k = 0; k < 2; k++)
        if (rect[2 + k] > TRAIN_DETAIL_WINDOW) {
            rect[k] += (int)pg_rng_below(&s->rng, (uint32_t)(rect[2 + k] - TRAIN_DETAIL_WINDOW + 1));
            rect[2 + k] = TRAIN_DETAIL_WINDOW;
        }
}

/* Motion crops k and k + 1 of a step: the real view and a proxy at one random frame with motion,
 * each rendered over the box around its movers alone. The moving part is a few percent of the
 * frame and changes with every frame, while the still scene is learnt from any frame; a crop costs
 * a fraction of a full time (fewer pixels, fewer Gaussians through the network), so a long clip's
 * frames get their motion fitted more often for the same CPU time. The real view's crop is at its
 * weight, the proxy's at the proxies' share: real-view crops alone fit the motion to the one camera
 * and blur it from every other (tabletop_dev held-out moving -1.1 dB, docs/train.md). The two share
 * one deformation (the network's forward and backward once for both); the proxy is drawn among
 * those whose own colours move at that frame. An odd last crop is the real view's alone. */
static pg_status step_motion_crops(train_session *s, int k, double *loss_out)
{
    *loss_out = 0;
    int f, views[2] = { s->crop_view, -1 }, rects[8];
    float weights[2] = { s->cfg.real_weight, 1.0f - s->cfg.real_weight };
    const train_region *b = train_motion_regions_draw(&s->regions[s->crop_view], &s->rng, &f);
    if (!b) return PG_OK;
    rects[0] = b->x, rects[1] = b->y, rects[2] = b->w, rects[3] = b->h;
    if (s->detail) { /* the full-size phase: a window of the real view's box at the input's size */
        if (!s->detail->crop[f]) return PG_OK;
        full_size_window(s, f, rects);
    }
    int nb = 1;
    if (k + 1 < motion_crops(s) && s->proxy_crop_views > 0) {
        int moving = 0;
        for (int v = 0; v < s->ts->num_views; v++) moving += proxy_box_at(s, v, f) != NULL;
        int pick = moving > 0 ? (int)pg_rng_below(&s->rng, (uint32_t)moving) : -1;
        for (int v = 0; v < s->ts->num_views && pick >= 0; v++) {
            const train_region *pb = proxy_box_at(s, v, f);
            if (pb && pick-- == 0) {
                views[1] = v;
                rects[4] = pb->x, rects[5] = pb->y, rects[6] = pb->w, rects[7] = pb->h;
                nb = 2;
            }
        }
    }
    return step_views(s, f, views, weights, nb, rects, 0, loss_out);
}

pg_status train_session_step(train_session *s)
{
    const train_config *c = &s->cfg;
    if (!s->fine && s->iter >= c->coarse_iters) PG_TRY(start_fine(s));
    if (s->fine) {
        const int rows = final_time_rows(s), warm_steps = time_warmup_steps(s);
        if (s->net_cfg.tres != rows && warm_steps > 0 && s->iter - c->coarse_iters >= warm_steps)
            PG_TRY(refine_time_rows(s, rows));
    }
    if (s->cfg.views_per_step > TRAIN_MAX_BATCH) s->cfg.views_per_step = TRAIN_MAX_BATCH;
    memset(&s->timing, 0, sizeof s->timing);
    list_step_rows(s);
    const int times = times_per_step(c);
    if (s->fine) train_net_zero_grad(s->net);
    double loss = 0;
    for (int k = 0; k < times; k++) {
        double lk;
        PG_TRY(step_time(s, s->iter * times + k, k == 0, &lk));
        loss += lk / times;
    }
    for (int k = 0; s->fine && k < motion_crops(s); k += 2) {
        double lk;
        PG_TRY(step_motion_crops(s, k, &lk));
    }
    double tf = pg_time_seconds();
    if (!one_time_per_step(s)) finish_fixed_rows(s);
    if (s->detail) /* the still scene was fitted at full size already: its means stay where they are */
        for (int k = 0; k < s->n_fixed_rows; k++) memset(s->gg.means + 3 * (size_t)s->step_rows[s->n_moving_rows + k], 0, 3 * sizeof(float));
    s->timing.deform_backward += (pg_time_seconds() - tf) * 1e3;
    if (s->fine) {
        double tr = pg_time_seconds();
        loss += train_net_regularize(s->net, c->reg_tv, c->reg_time, c->reg_l1);
        s->timing.regularize = (pg_time_seconds() - tr) * 1e3;
    }
    double t0 = pg_time_seconds(), t1;
    PG_TRY(train_adam_step(s));
    t1 = pg_time_seconds();
    s->timing.optimizer = (t1 - t0) * 1e3;
    t0 = t1;
    s->last_loss = loss;
    s->iter++;
    PG_TRY(train_average_update(s));

    int it = s->iter;
    if (c->sh_ramp_every > 0 && it % c->sh_ramp_every == 0 && s->g.sh_degree < c->sh_max_degree) s->g.sh_degree++;
    int densified = it < c->densify_until && it >= c->densify_from && c->densify_every > 0 && it % c->densify_every == 0;
    if (densified) PG_TRY(train_densify_and_prune(s, 1));
    if (densified || it % TRAIN_FILTER_EVERY == 0) train_update_filter(s);
    int fine_it = it - c->coarse_iters;
    if (s->fine && c->static_check_every > 0 && fine_it >= 2 * c->static_check_every &&
        fine_it % c->static_check_every == 0 && c->use_static_flags)
        PG_TRY(check_static(s));
    if (c->opacity_reset_every > 0 && it < c->densify_until && it % c->opacity_reset_every == 0) train_reset_opacity(s);
    s->timing.other = (pg_time_seconds() - t0) * 1e3;
    train_timing *a = &s->timing_total, *b = &s->timing;
    a->deform_forward += b->deform_forward;
    a->deform_backward += b->deform_backward;
    a->regularize += b->regularize;
    a->raster_forward += b->raster_forward;
    a->raster_backward += b->raster_backward;
    a->loss += b->loss;
    a->optimizer += b->optimizer;
    a->other += b->other;
    a->targets += b->targets;
    a->deformed += b->deformed;
    return PG_OK;
}


pg_status train_render_frame(train_session *s, int f, const pg_camera *cam, pg_render_output *out)
{
    list_step_rows(s);
    const pg_camera *cams[1] = { cam };
    int nd;
    PG_TRY(deform_all(s, cams, 1, train_frame_time(f, s->ts->frames), 1, &nd));
    pg_render_settings rs = splat_default_settings();
    memcpy(rs.background, s->cfg.bg, sizeof rs.background);
    return splat_render_forward(s->raster, &s->d, cam, &rs, out);
}

pg_status train_session_run(train_session *s)
{
    const train_config *c = &s->cfg;
    s->t_start = pg_time_seconds();
    s->it_start = s->iter;
    while (s->iter < c->iters) {
        if (c->stop_at_iter > 0 && s->iter == c->stop_at_iter) return PG_OK; /* simulated kill */
        PG_TRY(train_session_step(s));
        int it = s->iter;
        if (s->ckpt_path[0] && c->checkpoint_every > 0 && it % c->checkpoint_every == 0 && it < c->iters)
            PG_TRY(train_checkpoint_write(s, s->ckpt_path, 1));
        if (it % 10 == 0 || it == c->iters) {
            double el = pg_time_seconds() - s->t_start;
            double ips = el > 0 ? (it - s->it_start) / el : 0;
            double eta = ips > 0 ? (c->iters - it) / ips : 0;
            pg_progress_report("train", it, c->iters, "loss=%.4f psnr=%.2f gaussians=%d it/s=%.2f eta=%.0fs%s",
                               s->last_loss, s->last_psnr, s->g.count, ips, eta, s->fine ? "" : " (coarse)");
        }
    }
    PG_TRY(train_average_apply(s));
    if (s->ckpt_path[0]) PG_TRY(train_checkpoint_write(s, s->ckpt_path, 0));
    return PG_OK;
}

pg_status train_session_evaluate(train_session *s, io_view_role role, double *psnr)
{
    train_eval_scores e;
    PG_TRY(train_session_evaluate_parts(s, role, &e));
    *psnr = e.psnr;
    return PG_OK;
}

static double psnr_of(double sse, double n) { return n > 0 ? (sse > 0 ? -10.0 * log10(sse / n) : 200.0) : NAN; }

pg_status train_session_evaluate_parts(train_session *s, io_view_role role, train_eval_scores *e)
{
    const train_set *ts = s->ts;
    const size_t px = (size_t)ts->width * ts->height;
    double sum = 0, sse[2] = {0, 0}, cnt[2] = {0, 0};
    int n = 0;
    uint8_t *moving = pg_malloc((size_t)ts->frames * px, "evaluation moving masks");
    if (!moving) return PG_ERR_NOMEM;
    pg_status st = PG_OK;
    for (int vi = 0; vi < ts->num_views && !st; vi++) {
        if (ts->views[vi].role != role) continue;
        st = depth_moving_masks(ts->views[vi].rgb, ts->frames, ts->width, ts->height, 0.12f, 2, moving);
        for (int f = 0; f < ts->frames && !st; f++) {
            load_target(s, vi, f, 0);
            pg_render_output out;
            if ((st = train_render_frame(s, f, &ts->views[vi].cam, &out))) break;
            pg_image rendered = {ts->width, ts->height, 3, out.rgb};
            const float *mask = ts->views[vi].mask ? s->mask : NULL;
            sum += pg_image_psnr(&rendered, &s->target, mask);
            n++;
            for (size_t i = 0; i < px; i++) {
                if (mask && mask[i] <= 0) continue;
                int k = moving[(size_t)f * px + i] != 0;
                for (int c = 0; c < 3; c++) {
                    double d = (double)out.rgb[3 * i + c] - s->target.data[3 * i + c];
                    sse[k] += d * d;
                }
                cnt[k] += 3;
            }
        }
    }
    free(moving);
    if (st) return st;
    if (n == 0) return pg_fail(PG_ERR_ARG, "evaluate: no views with that role in the training set");
    e->psnr = sum / n;
    e->psnr_moving = psnr_of(sse[1], cnt[1]);
    e->psnr_static = psnr_of(sse[0], cnt[0]);
    e->moving_fraction = cnt[0] + cnt[1] > 0 ? cnt[1] / (cnt[0] + cnt[1]) : 0;
    return PG_OK;
}
