/* checkpoint.c - the training checkpoint: everything needed to continue bit-exactly, and to
 * render the model.
 *
 * Layout (little-endian, written in one go to a temporary file then renamed):
 *   "PGDYCKP1"                              magic
 *   u32 version (8), u32 flags (bit 0: optimiser state present; bit 1: the parameters' average), u32
 *   config text length, config text ("key=value\n" lines)
 *   i32 iter, fine, frames, width, height, num_views; u64 rng[4]
 *   f32 extent, unit, center[3], max_disp, bg[3]    (unit: the user's length per trainer length)
 *   i32 N, sh_degree; Gaussians (means, log_scales, quats, opacity, sh for N rows; of each row's 48
 *       SH floats only the (sh_max_degree + 1)^2 x 3 up to the config's largest degree: the others are
 *       never rendered nor stepped, and read back as zero)
 *   with optimiser state: Adam of the Gaussians: i32 step[6], then per group f32 m[N x cols],
 *       v[N x cols] (groups means, log_scales, quats, opacity, sh_dc, sh_rest of 3, 3, 4, 1, 3 cols
 *       and the SH floats stored above less 3)
 *   u8 is_static[N]; f32 filter_var[N] (the 3D filter, splat/filter3d.h); with optimiser state:
 *       f32 grad_accum[N], grad_denom[N]
 *   if fine: network config (f32 aabb[6], i32 width, res, tres, channels, head_width, time_coarsen, u64 seed),
 *       u64 P, f32 params[P], with optimiser state: Adam of the network: i32 step[2], then per
 *       group m, v (groups HexPlane grids [0, grid_end) and MLP [grid_end, P))
 *   with the average flag (bit 1, only with optimiser state): the parameters' moving average
 *       (average.c): Gaussians as above for N rows, then if fine f32 params[P]
 *   "PGEND\0\0\0", u32 CRC-32 (zlib) of every byte before it
 * The CRC is checked before anything is parsed, and every field is range-checked before it sizes
 * an allocation, so a damaged or crafted file fails with one message. Adam sections are the optimiser's groups in order (src/optim/adam). Nothing time- or
 * machine-dependent is stored, so equal training gives equal bytes. Only the current version is
 * read (1: one step count for all Gaussian groups, moments stored like Gaussians; 3: no head
 * width in the network config; 4: no unit, trained in the depth's own units; 5: no flags, always
 * optimiser state; 6: no 3D filter; 7: no time_coarsen in the network config; 8: all 48 SH floats
 * per Gaussian whatever the degree; 9: the Adam moments of all 45 higher SH floats whatever the degree). The checkpoint written when training ends leaves the optimiser state out (it
 * is two thirds of the bytes and only a continuation needs it): continuing a finished model
 * starts Adam afresh, while an interrupted run resumes bit-exactly from a periodic checkpoint.
 */
#include "train/train_internal.h"

#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "core/fileutil.h"
#include "splat/filter3d.h"

#define CKPT_MAGIC "PGDYCKP1"
#define CKPT_END "PGEND\0\0\0"
#define CKPT_VERSION 10u
#define CKPT_HAS_OPTIMIZER 1u
#define CKPT_HAS_AVERAGE 2u /* only with the optimiser state */
#define CKPT_MAX_STEP 100000000 /* iterations and Adam steps beyond this are corruption */
#define GAUSS_NON_SH (3 + 3 + 4 + 1) /* per Gaussian besides the SH floats, also Adam's columns */

/* The checkpoint streams into its temporary file with the CRC kept as the bytes go: a copy of
 * the model and its optimiser state in memory (growing by doubling) was up to twice the file. */
typedef struct {
    FILE *fp;
    uLong crc;
    int failed; /* the errno of the first failed write, else 0 */
} buf;

static void put(buf *b, const void *p, size_t n)
{
    if (b->failed || n == 0) return;
    b->crc = crc32_z(b->crc, p, n);
    if (fwrite(p, 1, n, b->fp) != n) b->failed = errno ? errno : EIO;
}
static void put_i32(buf *b, int32_t x) { put(b, &x, 4); }
static void put_u64(buf *b, uint64_t x) { put(b, &x, 8); }
static void put_f32(buf *b, float x) { put(b, &x, 4); }

static void put_gaussians(buf *b, const pg_gaussians *g, int n, int sh_cols)
{
    put(b, g->means, (size_t)n * 3 * 4);
    put(b, g->log_scales, (size_t)n * 3 * 4);
    put(b, g->quats, (size_t)n * 4 * 4);
    put(b, g->opacity, (size_t)n * 4);
    if (sh_cols == g->sh_stride) {
        put(b, g->sh, (size_t)n * sh_cols * 4);
        return;
    }
    enum { ROWS = 256 }; /* gathered in blocks: one write (and CRC update) per row would be slow */
    float block[ROWS * PG_SH_FLOATS];
    for (int i0 = 0; i0 < n; i0 += ROWS) {
        int m = n - i0 < ROWS ? n - i0 : ROWS;
        for (int k = 0; k < m; k++)
            memcpy(block + (size_t)k * sh_cols, splat_gaussians_sh(g, (size_t)(i0 + k)), (size_t)sh_cols * 4);
        put(b, block, (size_t)m * sh_cols * 4);
    }
}

/* An optimiser's state: every group's step count, then every group's m and v. */
static void put_adam(buf *b, optim_adam *opt)
{
    int ng = optim_adam_num_groups(opt);
    for (int gi = 0; gi < ng; gi++) put_i32(b, optim_adam_group_step(opt, gi));
    for (int gi = 0; gi < ng; gi++)
        for (int which = 0; which < 2; which++)
            put(b, optim_adam_moment(opt, gi, which), optim_adam_moment_size(opt, gi) * 4);
}

/* The config as text lines; read back by name so fields can be added later. */
static void config_text(const train_config *c, char *out, size_t size)
{
    snprintf(out, size,
             "iters=%d\ncoarse_iters=%d\nseed=%llu\nmax_gaussians=%d\ninit_points=%d\nviews_per_step=%d\n"
             "sh_max_degree=%d\nsh_ramp_every=%d\nbg=%.9g,%.9g,%.9g\nlambda_dssim=%.9g\nlambda_depth=%.9g\n"
             "reg_tv=%.9g\nreg_time=%.9g\nreg_l1=%.9g\nlr_means=%.9g\nlr_means_final=%.9g\nlr_scales=%.9g\n"
             "lr_quats=%.9g\nlr_opacity=%.9g\nlr_sh_dc=%.9g\nlr_sh_rest=%.9g\nlr_net=%.9g\nlr_net_final=%.9g\n"
             "lr_grid=%.9g\nlr_grid_final=%.9g\ndensify_from=%d\ndensify_until=%d\ndensify_every=%d\n"
             "opacity_reset_every=%d\ndensify_grad=%.9g\npercent_dense=%.9g\nprune_opacity=%.9g\n"
             "prune_big_scale=%.9g\nuse_static_flags=%d\nuse_frustum_cull=%d\nstatic_check_every=%d\n"
             "static_eps=%.9g\ndeform_width=%d\ndeform_res=%d\ndeform_tres=%d\ndeform_channels=%d\n"
             "deform_head_width=%d\ndeform_time_coarsen=%d\nreal_weight=%.9g\nmoving_weight=%.9g\nproxy_moving_weight=%.9g\ntimes_per_step=%d\nmotion_crops=%d\nlr_static_scale=%.9g\naverage_decay=%.9g\ndeform_time_warmup=%.9g\ndensify_movable=%.9g\nproxy_downscale=%d\nstatic_steps=%d\n",
             c->iters, c->coarse_iters, (unsigned long long)c->seed, c->max_gaussians, c->init_points, c->views_per_step,
             c->sh_max_degree, c->sh_ramp_every, c->bg[0], c->bg[1], c->bg[2], c->lambda_dssim, c->lambda_depth,
             c->reg_tv, c->reg_time, c->reg_l1, c->lr_means, c->lr_means_final, c->lr_scales, c->lr_quats,
             c->lr_opacity, c->lr_sh_dc, c->lr_sh_rest, c->lr_net, c->lr_net_final, c->lr_grid, c->lr_grid_final,
             c->densify_from, c->densify_until, c->densify_every, c->opacity_reset_every, c->densify_grad,
             c->percent_dense, c->prune_opacity, c->prune_big_scale, c->use_static_flags, c->use_frustum_cull,
             c->static_check_every, c->static_eps, c->deform_width, c->deform_res, c->deform_tres,
             c->deform_channels, c->deform_head_width, c->deform_time_coarsen, c->real_weight, c->moving_weight, c->proxy_moving_weight, c->times_per_step, c->motion_crops, c->lr_static_scale, c->average_decay, c->deform_time_warmup, c->densify_movable, c->proxy_downscale, c->static_steps);
}

static int cfg_get(const char *text, const char *key, char *val, size_t size)
{
    size_t kl = strlen(key);
    for (const char *p = text; p && *p;) {
        if (strncmp(p, key, kl) == 0 && p[kl] == '=') {
            const char *e = strchr(p + kl + 1, '\n');
            size_t n = e ? (size_t)(e - (p + kl + 1)) : strlen(p + kl + 1);
            if (n >= size) n = size - 1;
            memcpy(val, p + kl + 1, n);
            val[n] = 0;
            return 1;
        }
        p = strchr(p, '\n');
        if (p) p++;
    }
    return 0;
}

static void config_parse(const char *text, train_config *c)
{
    char v[256];
#define GI(name) if (cfg_get(text, #name, v, sizeof v)) c->name = atoi(v)
#define GF(name) if (cfg_get(text, #name, v, sizeof v)) c->name = strtof(v, NULL)
    GI(iters); GI(coarse_iters); GI(max_gaussians); GI(init_points); GI(views_per_step); GI(sh_max_degree);
    GI(sh_ramp_every); GF(lambda_dssim); GF(lambda_depth); GF(reg_tv); GF(reg_time); GF(reg_l1);
    GF(lr_means); GF(lr_means_final); GF(lr_scales); GF(lr_quats); GF(lr_opacity); GF(lr_sh_dc);
    GF(lr_sh_rest); GF(lr_net); GF(lr_net_final); GF(lr_grid); GF(lr_grid_final); GI(densify_from);
    GI(densify_until); GI(densify_every); GI(opacity_reset_every); GF(densify_grad); GF(percent_dense);
    GF(prune_opacity); GF(prune_big_scale); GI(use_static_flags); GI(use_frustum_cull);
    GI(static_check_every); GF(static_eps); GI(deform_width); GI(deform_res); GI(deform_tres);
    GI(deform_channels); GI(deform_head_width); GI(deform_time_coarsen); GF(real_weight); GF(moving_weight); GF(proxy_moving_weight); GI(times_per_step); GI(motion_crops); GF(lr_static_scale); GF(average_decay); GF(deform_time_warmup); GF(densify_movable); GI(proxy_downscale); GI(static_steps);
#undef GI
#undef GF
    if (!cfg_get(text, "deform_time_warmup", v, sizeof v)) c->deform_time_warmup = 0; /* written before it existed */
    if (!cfg_get(text, "densify_movable", v, sizeof v)) c->densify_movable = 1;
    if (!cfg_get(text, "static_steps", v, sizeof v)) c->static_steps = 0;
    if (!cfg_get(text, "proxy_downscale", v, sizeof v)) c->proxy_downscale = 1; /* proxies at full size before it */
    if (cfg_get(text, "seed", v, sizeof v)) c->seed = strtoull(v, NULL, 10);
    if (cfg_get(text, "bg", v, sizeof v)) sscanf(v, "%f,%f,%f", &c->bg[0], &c->bg[1], &c->bg[2]);
}

pg_status train_checkpoint_write(train_session *s, const char *path, int with_optimizer)
{
    pg_atomic_file f;
    PG_TRY(pg_atomic_open(&f, path));
    buf b = { f.fp, crc32(0L, Z_NULL, 0), 0 };
    char text[8192];
    config_text(&s->cfg, text, sizeof text);
    put(&b, CKPT_MAGIC, 8);
    put_i32(&b, (int32_t)CKPT_VERSION);
    const int with_average = with_optimizer && s->avg_on;
    put_i32(&b, (int32_t)((with_optimizer ? CKPT_HAS_OPTIMIZER : 0) | (with_average ? CKPT_HAS_AVERAGE : 0)));
    put_i32(&b, (int32_t)strlen(text));
    put(&b, text, strlen(text));
    put_i32(&b, s->iter);
    put_i32(&b, s->fine);
    put_i32(&b, s->ts->frames);
    put_i32(&b, s->ts->width);
    put_i32(&b, s->ts->height);
    put_i32(&b, s->ts->num_views);
    for (int k = 0; k < 4; k++) put_u64(&b, s->rng.s[k]);
    put_f32(&b, s->extent);
    put_f32(&b, train_set_unit(s->ts));
    for (int k = 0; k < 3; k++) put_f32(&b, s->center[k]);
    put_f32(&b, s->max_disp);
    for (int k = 0; k < 3; k++) put_f32(&b, s->cfg.bg[k]);
    int n = s->g.count;
    put_i32(&b, n);
    put_i32(&b, s->g.sh_degree);
    const int sh_cols = splat_sh_floats(s->cfg.sh_max_degree);
    put_gaussians(&b, &s->g, n, sh_cols);
    if (with_optimizer) put_adam(&b, s->gopt);
    put(&b, s->is_static, (size_t)n);
    put(&b, s->filter_var, (size_t)n * 4);
    if (with_optimizer) {
        put(&b, s->grad_accum, (size_t)n * 4);
        put(&b, s->grad_denom, (size_t)n * 4);
    }
    if (s->fine) {
        const train_net_config *nc = &s->net_cfg;
        for (int k = 0; k < 3; k++) put_f32(&b, nc->aabb_min[k]);
        for (int k = 0; k < 3; k++) put_f32(&b, nc->aabb_max[k]);
        put_i32(&b, nc->width);
        put_i32(&b, nc->res);
        put_i32(&b, nc->tres);
        put_i32(&b, nc->channels);
        put_i32(&b, nc->head_width);
        put_i32(&b, nc->time_coarsen);
        put_u64(&b, nc->seed);
        uint64_t P = train_net_num_params(s->net);
        put_u64(&b, P);
        put(&b, train_net_params(s->net), (size_t)P * 4);
        if (with_optimizer) put_adam(&b, s->nopt);
    }
    if (with_average) {
        put_gaussians(&b, &s->avg_g, n, sh_cols);
        if (s->fine) put(&b, s->avg_net, train_net_num_params(s->net) * 4);
    }
    put(&b, CKPT_END, 8);
    int32_t crc = (int32_t)b.crc;
    put(&b, &crc, 4);
    if (b.failed) {
        pg_atomic_abort(&f);
        return pg_fail(PG_ERR_ENV, "%s: write failed: %s", path, strerror(b.failed));
    }
    return pg_atomic_commit(&f);
}

/* ---------- reading ---------- */

typedef struct {
    const unsigned char *p;
    size_t size, off;
    int bad;
} rd;

/* off never passes size: skip() refuses to, so size - off cannot wrap around. */
static int has(const rd *r, size_t n) { return !r->bad && r->off <= r->size && r->size - r->off >= n; }

static void get(rd *r, void *dst, size_t n)
{
    if (!has(r, n)) {
        r->bad = 1;
        memset(dst, 0, n);
        return;
    }
    memcpy(dst, r->p + r->off, n);
    r->off += n;
}
static void skip(rd *r, size_t n)
{
    if (has(r, n)) r->off += n;
    else r->bad = 1;
}
static int32_t get_i32(rd *r) { int32_t x; get(r, &x, 4); return x; }
static uint64_t get_u64(rd *r) { uint64_t x; get(r, &x, 8); return x; }
static float get_f32(rd *r) { float x; get(r, &x, 4); return x; }

/* A NaN or infinite Gaussian parameter would render as garbage and export PLYs that readers reject. */
static pg_status check_finite(const pg_gaussians *g, int n, const char *path)
{
    const float *arrays[5] = { g->means, g->log_scales, g->quats, g->opacity, g->sh };
    const size_t cols[5] = { 3, 3, 4, 1, (size_t)g->sh_stride };
    for (int a = 0; a < 5; a++)
        for (size_t i = 0; i < (size_t)n * cols[a]; i++)
            if (!isfinite(arrays[a][i]))
                return pg_fail(PG_ERR_FORMAT, "%s: Gaussian %zu has a non-finite parameter (corrupt checkpoint)", path,
                               i / cols[a]);
    return PG_OK;
}

/* The 3D filter's variances: finite and >= 0 (a crafted value would blow up every render). */
static pg_status check_filter(const float *var, int n, const char *path)
{
    for (int i = 0; i < n; i++)
        if (!(var[i] >= 0 && var[i] < INFINITY))
            return pg_fail(PG_ERR_FORMAT, "%s: 3D filter of Gaussian %d is %g", path, i, (double)var[i]);
    return PG_OK;
}

/* Into g's rows (which hold at least sh_cols SH floats: created for the file's largest degree). */
static void get_gaussians(rd *r, pg_gaussians *g, int n, int sh_cols)
{
    if (g->sh_stride < sh_cols) {
        r->bad = 1;
        return;
    }
    get(r, g->means, (size_t)n * 3 * 4);
    get(r, g->log_scales, (size_t)n * 3 * 4);
    get(r, g->quats, (size_t)n * 4 * 4);
    get(r, g->opacity, (size_t)n * 4);
    if (sh_cols == g->sh_stride) {
        get(r, g->sh, (size_t)n * sh_cols * 4);
        return;
    }
    for (size_t i = 0; i < (size_t)n; i++) {
        get(r, splat_gaussians_sh(g, i), (size_t)sh_cols * 4);
        memset(splat_gaussians_sh(g, i) + sh_cols, 0, (size_t)(g->sh_stride - sh_cols) * 4);
    }
}

/* Reads an optimiser's state written by put_adam into opt (created with the right groups and
 * rows); a negative step count is corruption. */
static void get_adam(rd *r, optim_adam *opt)
{
    int ng = optim_adam_num_groups(opt);
    for (int gi = 0; gi < ng; gi++) {
        int32_t step = get_i32(r);
        if (step < 0 || step > CKPT_MAX_STEP) r->bad = 1;
        optim_adam_set_group_step(opt, gi, step);
    }
    for (int gi = 0; gi < ng; gi++)
        for (int which = 0; which < 2; which++)
            get(r, optim_adam_moment(opt, gi, which), optim_adam_moment_size(opt, gi) * 4);
}

typedef struct {
    train_config cfg;
    int iter, fine, frames, width, height, num_views;
    int optimizer; /* the file holds the optimiser state */
    int average;   /* and the parameters' moving average */
    uint64_t rng[4];
    float extent, unit, center[3], max_disp, bg[3];
    int n, sh_degree;
} ckpt_header;

#define CKPT_MAX_GAUSSIANS 50000000

/* The trailing CRC-32 against the bytes before it: any flipped bit anywhere is caught here. */
static pg_status check_crc(const unsigned char *data, size_t size, const char *path)
{
    if (size < 16 || memcmp(data, CKPT_MAGIC, 8) != 0)
        return pg_fail(PG_ERR_FORMAT, "%s: not a prodygs training checkpoint", path);
    uint32_t ver, want;
    memcpy(&ver, data + 8, 4);
    if (ver != CKPT_VERSION)
        return pg_fail(PG_ERR_FORMAT, "%s: checkpoint format version %u, this build reads only version %u (train again)",
                       path, ver, CKPT_VERSION);
    memcpy(&want, data + size - 4, 4);
    if ((uint32_t)crc32_z(crc32(0L, Z_NULL, 0), data, size - 4) != want)
        return pg_fail(PG_ERR_FORMAT, "%s: checkpoint is damaged (CRC mismatch): truncated or changed since it was written",
                       path);
    return PG_OK;
}

static pg_status read_header(rd *r, const char *path, ckpt_header *h)
{
    r->off = 12; /* magic and version: checked with the CRC */
    uint32_t flags = (uint32_t)get_i32(r);
    if ((flags & ~(CKPT_HAS_OPTIMIZER | CKPT_HAS_AVERAGE)) || ((flags & CKPT_HAS_AVERAGE) && !(flags & CKPT_HAS_OPTIMIZER)))
        return pg_fail(PG_ERR_FORMAT, "%s: unknown checkpoint flags %#x", path, flags);
    h->optimizer = (int)(flags & CKPT_HAS_OPTIMIZER);
    h->average = (int)((flags & CKPT_HAS_AVERAGE) != 0);
    int32_t tl = get_i32(r);
    if (tl < 0 || (size_t)tl > r->size - r->off) return pg_fail(PG_ERR_FORMAT, "%s: truncated checkpoint", path);
    char *text = pg_malloc((size_t)tl + 1, "checkpoint config");
    if (!text) return PG_ERR_NOMEM;
    get(r, text, (size_t)tl);
    text[tl] = 0;
    h->cfg = train_default_config();
    config_parse(text, &h->cfg);
    free(text);
    h->iter = get_i32(r);
    h->fine = get_i32(r);
    h->frames = get_i32(r);
    h->width = get_i32(r);
    h->height = get_i32(r);
    h->num_views = get_i32(r);
    for (int k = 0; k < 4; k++) h->rng[k] = get_u64(r);
    h->extent = get_f32(r);
    h->unit = get_f32(r);
    for (int k = 0; k < 3; k++) h->center[k] = get_f32(r);
    h->max_disp = get_f32(r);
    for (int k = 0; k < 3; k++) h->bg[k] = get_f32(r);
    h->n = get_i32(r);
    h->sh_degree = get_i32(r);
    if (r->bad) return pg_fail(PG_ERR_FORMAT, "%s: truncated checkpoint header", path);
    if (h->n < 1 || h->n > CKPT_MAX_GAUSSIANS || h->sh_degree < 0 || h->sh_degree > 3 || h->frames < 1 ||
        h->frames > 1000000 || h->width < 1 || h->width > PG_MAX_IMAGE_SIDE || h->height < 1 ||
        h->height > PG_MAX_IMAGE_SIDE || h->num_views < 1 || h->num_views > 100000 || (h->fine != 0 && h->fine != 1) ||
        h->iter < 0 || h->iter > CKPT_MAX_STEP || !isfinite(h->extent) || !(h->extent > 0) || !isfinite(h->max_disp) ||
        !isfinite(h->unit) || !(h->unit > 0))
        return pg_fail(PG_ERR_FORMAT, "%s: corrupt checkpoint header (N=%d, sh=%d, iteration %d)", path, h->n,
                       h->sh_degree, h->iter);
    const char *bad = train_config_invalid(&h->cfg);
    if (bad) return pg_fail(PG_ERR_FORMAT, "%s: corrupt checkpoint config (%s)", path, bad);
    if (h->sh_degree > h->cfg.sh_max_degree)
        return pg_fail(PG_ERR_FORMAT, "%s: corrupt checkpoint header (SH degree %d above the run's largest, %d)", path,
                       h->sh_degree, h->cfg.sh_max_degree);
    /* the rest must fit: the Gaussians, their Adam state, flags and statistics */
    const size_t row = (size_t)(GAUSS_NON_SH + splat_sh_floats(h->cfg.sh_max_degree)) * 4;
    size_t need = h->optimizer ? (size_t)h->n * (row + row * 2 + 1 + 8) + OPTIM_GAUSS_GROUPS * 4
                               : (size_t)h->n * (row + 1);
    if (r->size - r->off < need) return pg_fail(PG_ERR_FORMAT, "%s: truncated checkpoint (Gaussians)", path);
    return PG_OK;
}

/* The network section; with s, the network and its optimiser go into the session (a fresh
 * optimiser when the file has none), without (model loading) the network into *net and any Adam
 * state is skipped. */
static pg_status read_net(rd *r, const char *path, train_net_config *nc, train_net **net, train_session *s, int optimizer)
{
    memset(nc, 0, sizeof *nc);
    for (int k = 0; k < 3; k++) nc->aabb_min[k] = get_f32(r);
    for (int k = 0; k < 3; k++) nc->aabb_max[k] = get_f32(r);
    nc->width = get_i32(r);
    nc->res = get_i32(r);
    nc->tres = get_i32(r);
    nc->channels = get_i32(r);
    nc->head_width = get_i32(r);
    nc->time_coarsen = get_i32(r);
    nc->seed = get_u64(r);
    uint64_t P = get_u64(r);
    if (r->bad) return pg_fail(PG_ERR_FORMAT, "%s: truncated checkpoint (network)", path);
    if (nc->width < 0 || nc->width > 4096 || nc->res < 0 || nc->res > 4096 || nc->tres < 0 || nc->tres > 100000 ||
        nc->channels < 0 || nc->channels > 1024 || nc->head_width < 0 || nc->head_width > 4096 ||
        nc->time_coarsen < 0 || nc->time_coarsen > HEX_MAX_TIME_COARSEN)
        return pg_fail(PG_ERR_FORMAT, "%s: corrupt network config in the checkpoint", path);
    /* sizes first: the parameters (and their Adam moments) must be in the file before the network
     * they describe is allocated */
    size_t expect = train_net_config_num_params(nc);
    if (expect == 0 || expect != P)
        return pg_fail(PG_ERR_FORMAT, "%s: network config (width %d, head width %d, res %d x %d, %d channels) does not "
                       "match its %llu parameters", path, nc->width, nc->head_width, nc->res, nc->tres, nc->channels,
                       (unsigned long long)P);
    size_t adam_bytes = optimizer ? TRAIN_NET_GROUPS * 4 + (size_t)P * 8 : 0;
    if ((r->size - r->off) / (optimizer ? 12 : 4) < P) return pg_fail(PG_ERR_FORMAT, "%s: truncated checkpoint (network)", path);
    PG_TRY(train_net_create(net, nc));
    get(r, train_net_params(*net), (size_t)P * 4);
    if (s) PG_TRY(train_adam_create_net(s)); /* zero moments, step 0 */
    if (s && optimizer) {
        get_adam(r, s->nopt);
        if (r->bad) return pg_fail(PG_ERR_FORMAT, "%s: corrupt network Adam state in the checkpoint", path);
    } else {
        skip(r, adam_bytes);
    }
    return PG_OK;
}

/* The parameters' moving average of a periodic checkpoint into the session (none: it restarts). */
static pg_status read_average(rd *r, const char *path, train_session *s, const ckpt_header *h)
{
    s->avg_on = 0;
    if (!h->average) return PG_OK;
    size_t P = h->fine ? train_net_num_params(s->net) : 0;
    const int sh_cols = splat_sh_floats(h->cfg.sh_max_degree);
    if ((r->size - r->off) / 4 < (size_t)h->n * (GAUSS_NON_SH + sh_cols) + P)
        return pg_fail(PG_ERR_FORMAT, "%s: truncated checkpoint (parameter average)", path);
    PG_TRY(splat_gaussians_copy(&s->g, &s->avg_g)); /* sized like the Gaussians, then overwritten */
    get_gaussians(r, &s->avg_g, h->n, sh_cols);
    PG_TRY(check_finite(&s->avg_g, h->n, path));
    if (P) {
        free(s->avg_net);
        if (!(s->avg_net = pg_malloc(P * sizeof(float), "parameter average"))) return PG_ERR_NOMEM;
        get(r, s->avg_net, P * 4);
    }
    s->avg_on = 1;
    return PG_OK;
}

static pg_status check_end(rd *r, const char *path)
{
    char end[8];
    get(r, end, 8);
    if (r->bad || memcmp(end, CKPT_END, 8) != 0 || r->off != r->size)
        return pg_fail(PG_ERR_FORMAT, "%s: checkpoint is truncated or has trailing bytes", path);
    return PG_OK;
}

pg_status train_checkpoint_read(train_session *s, const char *path)
{
    char *data = NULL;
    size_t size = 0;
    PG_TRY(pg_read_file(path, (size_t)1 << 34, &data, &size));
    rd r = {(const unsigned char *)data, size - 4, 0, 0};
    ckpt_header h;
    pg_status st = check_crc((const unsigned char *)data, size, path);
    if (!st) st = read_header(&r, path, &h);
    if (st) goto done;
    const train_set *ts = s->ts;
    if (h.frames != ts->frames || h.width != ts->width || h.height != ts->height || h.num_views != ts->num_views) {
        st = pg_fail(PG_ERR_ARG, "%s: checkpoint was made for %d views of %d frames %dx%d, not this training set",
                     path, h.num_views, h.frames, h.width, h.height);
        goto done;
    }
    float unit = train_set_unit(ts);
    if (fabsf(h.unit - unit) > 1e-6f * unit) {
        st = pg_fail(PG_ERR_ARG, "%s: checkpoint was made with the scene scaled by %g, this training set needs %g",
                     path, (double)h.unit, (double)unit);
        goto done;
    }
    if ((st = train_checkpoint_check_config(&h.cfg, &s->cfg, path))) goto done;
    s->cfg = h.cfg;
    s->iter = h.iter;
    memcpy(s->rng.s, h.rng, sizeof h.rng);
    s->extent = h.extent;
    memcpy(s->center, h.center, sizeof h.center);
    s->max_disp = h.max_disp;
    memcpy(s->cfg.bg, h.bg, sizeof h.bg);
    if ((st = train_resize_all(s, h.n))) goto done;
    get_gaussians(&r, &s->g, h.n, splat_sh_floats(h.cfg.sh_max_degree));
    if ((st = check_finite(&s->g, h.n, path))) goto done;
    if (h.optimizer) get_adam(&r, s->gopt);
    else /* a finished model continued: Adam starts afresh */
        for (int gi = 0; gi < optim_adam_num_groups(s->gopt); gi++) {
            optim_adam_reset_group(s->gopt, gi);
            optim_adam_set_group_step(s->gopt, gi, 0);
        }
    if (r.bad) {
        st = pg_fail(PG_ERR_FORMAT, "%s: corrupt Adam state of the Gaussians in the checkpoint", path);
        goto done;
    }
    s->g.sh_degree = h.sh_degree;
    get(&r, s->is_static, (size_t)h.n);
    get(&r, s->filter_var, (size_t)h.n * 4);
    if ((st = check_filter(s->filter_var, h.n, path))) goto done;
    if (h.optimizer) {
        get(&r, s->grad_accum, (size_t)h.n * 4);
        get(&r, s->grad_denom, (size_t)h.n * 4);
    } else {
        memset(s->grad_accum, 0, (size_t)h.n * 4);
        memset(s->grad_denom, 0, (size_t)h.n * 4);
    }
    if (h.fine) {
        if ((st = read_net(&r, path, &s->net_cfg, &s->net, s, h.optimizer))) goto done;
        s->fine = 1;
    }
    if ((st = read_average(&r, path, s, &h))) goto done;
    st = check_end(&r, path);
done:
    free(data);
    return st;
}

/* Trainer lengths -> the user's: positions times unit, log-scales plus log(unit), for rows
 * rows[0..nrows) (rows NULL: all). */
static void to_user_units(pg_gaussians *g, float unit, const int *rows, int nrows)
{
    if (unit == 1.0f) return;
    const float log_unit = logf(unit);
    const int n = rows ? nrows : g->count;
    for (int k = 0; k < n; k++) {
        const size_t i = rows ? (size_t)rows[k] : (size_t)k;
        for (int a = 0; a < 3; a++) {
            g->means[3 * i + a] *= unit;
            g->log_scales[3 * i + a] += log_unit;
        }
    }
}

pg_status train_model_load(const char *path, train_model *m)
{
    memset(m, 0, sizeof *m);
    char *data = NULL;
    size_t size = 0;
    PG_TRY(pg_read_file(path, (size_t)1 << 34, &data, &size));
    rd r = {(const unsigned char *)data, size - 4, 0, 0};
    ckpt_header h;
    pg_status st = check_crc((const unsigned char *)data, size, path);
    if (!st) st = read_header(&r, path, &h);
    if (st) goto done;
    const int sh_cols = splat_sh_floats(h.cfg.sh_max_degree);
    if ((st = splat_gaussians_create_sh(&m->g_net, h.n, h.cfg.sh_max_degree)) ||
        (st = splat_gaussians_resize(&m->g_net, h.n)))
        goto done;
    get_gaussians(&r, &m->g_net, h.n, sh_cols);
    if ((st = check_finite(&m->g_net, h.n, path))) goto done;
    m->g_net.sh_degree = h.sh_degree;
    m->unit = h.unit;
    if ((st = splat_gaussians_copy(&m->g_net, &m->g))) goto done;
    to_user_units(&m->g, m->unit, NULL, 0);
    if (h.optimizer) skip(&r, OPTIM_GAUSS_GROUPS * 4 + (size_t)h.n * (GAUSS_NON_SH + sh_cols) * 4 * 2); /* Adam state */
    m->is_static = pg_malloc((size_t)h.n, "model static flags");
    m->filter_var = pg_malloc((size_t)h.n * sizeof(float) + 1, "model 3D filter");
    if (!m->is_static || !m->filter_var) {
        st = PG_ERR_NOMEM;
        goto done;
    }
    get(&r, m->is_static, (size_t)h.n);
    get(&r, m->filter_var, (size_t)h.n * 4);
    if (r.bad) {
        st = pg_fail(PG_ERR_FORMAT, "%s: truncated checkpoint", path);
        goto done;
    }
    if ((st = check_filter(m->filter_var, h.n, path))) goto done;
    for (int i = 0; i < h.n; i++) m->filter_var[i] *= h.unit * h.unit; /* the user's units */
    splat_filter3d_forward(m->g.log_scales, m->g.opacity, m->filter_var, h.n, NULL);
    if (h.optimizer) skip(&r, (size_t)h.n * 8);
    if (h.fine) {
        train_net_config nc;
        if ((st = read_net(&r, path, &nc, &m->net, NULL, h.optimizer))) goto done;
    }
    if (h.average) skip(&r, ((size_t)h.n * (GAUSS_NON_SH + sh_cols) + (h.fine ? train_net_num_params(m->net) : 0)) * 4);
    st = check_end(&r, path);
    m->frames = h.frames;
    memcpy(m->bg, h.bg, sizeof h.bg);
done:
    free(data);
    if (st) train_model_destroy(m);
    return st;
}

void train_model_destroy(train_model *m)
{
    if (!m) return;
    splat_gaussians_destroy(&m->g);
    splat_gaussians_destroy(&m->g_net);
    free(m->is_static);
    free(m->filter_var);
    train_net_destroy(m->net);
    memset(m, 0, sizeof *m);
}

/* The still rows at any time are the loaded set's (m->g: the user's units, filtered), so a time
 * copies them and redoes only the movers (a render's 3D filter over every row was a tenth of it). */
pg_status train_model_deform(train_model *m, float t, pg_gaussians *out)
{
    PG_TRY(splat_gaussians_copy(&m->g, out));
    return train_model_deform_movers(m, t, out);
}

pg_status train_model_deform_movers(train_model *m, float t, pg_gaussians *out)
{
    if (!m->net) return PG_OK;
    const int n = m->g_net.count;
    if (out->count != n) return pg_fail(PG_ERR_ARG, "deform: %d Gaussians to update, the model has %d", out->count, n);
    int *idx = pg_malloc((size_t)n * sizeof(int) + 1, "deform indices");
    if (!idx) return PG_ERR_NOMEM;
    int k = 0;
    for (int i = 0; i < n; i++)
        if (!m->is_static[i]) idx[k++] = i;
    pg_status st = k ? train_net_forward(m->net, &m->g_net, idx, k, t, PG_SH_FLOATS, out) : PG_OK;
    if (!st) {
        to_user_units(out, m->unit, idx, k);
        splat_filter3d_forward_rows(out->log_scales, out->opacity, m->filter_var, idx, k, NULL);
    }
    free(idx);
    return st;
}

const char *train_config_invalid(const train_config *c)
{
    if (c->iters < 1 || c->iters > CKPT_MAX_STEP) return "iters";
    if (c->coarse_iters < 0 || c->coarse_iters > c->iters) return "coarse_iters";
    if (c->views_per_step < 1 || c->views_per_step > TRAIN_MAX_BATCH) return "views_per_step";
    if (c->times_per_step < 1 || c->times_per_step > TRAIN_MAX_BATCH) return "times_per_step";
    if (c->motion_crops < 0 || c->motion_crops > TRAIN_MAX_BATCH) return "motion_crops";
    if (c->max_gaussians < 16 || c->max_gaussians > CKPT_MAX_GAUSSIANS) return "max_gaussians";
    if (c->init_points < 1 || c->init_points > CKPT_MAX_GAUSSIANS) return "init_points";
    if (c->sh_max_degree < 0 || c->sh_max_degree > 3) return "sh_max_degree";
    if (!(c->average_decay >= 0 && c->average_decay < 1)) return "average_decay";
    if (!(c->densify_movable > 0)) return "densify_movable"; /* written resolved: 0 (the rule) would densify every mover */
    if (c->proxy_downscale != 1 && c->proxy_downscale != 2) return "proxy_downscale";
    if (c->static_steps < 0) return "static_steps";
    if (c->sh_ramp_every < 0 || c->densify_every < 0 || c->opacity_reset_every < 0 || c->static_check_every < 0)
        return "an interval";
    if (c->deform_width < 0 || c->deform_width > 4096 || c->deform_res < 0 || c->deform_res > 4096 ||
        c->deform_tres < 0 || c->deform_tres > 100000 || c->deform_channels < 0 || c->deform_channels > 1024 ||
        c->deform_head_width < 0 || c->deform_head_width > 4096 || c->deform_time_coarsen < 0 ||
        c->deform_time_coarsen > HEX_MAX_TIME_COARSEN)
        return "deformation network size";
    const float f[] = { c->lambda_dssim, c->lambda_depth, c->reg_tv, c->reg_time, c->reg_l1, c->lr_means,
                        c->lr_means_final, c->lr_scales, c->lr_quats, c->lr_opacity, c->lr_sh_dc, c->lr_sh_rest,
                        c->lr_net, c->lr_net_final, c->lr_grid, c->lr_grid_final, c->densify_grad, c->percent_dense,
                        c->prune_opacity, c->prune_big_scale, c->static_eps, c->real_weight, c->moving_weight,
                        c->proxy_moving_weight, c->lr_static_scale, c->densify_movable, c->bg[0], c->bg[1], c->bg[2] };
    for (size_t k = 0; k < sizeof f / sizeof f[0]; k++)
        if (!isfinite(f[k]) || f[k] < 0) return "a weight or learning rate";
    return NULL;
}

pg_status train_checkpoint_check_config(const train_config *stored, const train_config *given, const char *path)
{
    /* what may change on --resume: the length of the run (the coarse stage keeps the stored length,
     * its default follows --iters) and when it saves */
    train_config a = *stored, b = *given;
    a.iters = b.iters = 0;
    a.coarse_iters = b.coarse_iters = 0;
    a.checkpoint_every = b.checkpoint_every = 0;
    a.stop_at_iter = b.stop_at_iter = 0;
    a.threads = b.threads = 0;
    if (!(b.densify_movable > 0)) a.densify_movable = b.densify_movable = 0; /* the rule: what the run started with */
    char ta[8192], tb[8192];
    config_text(&a, ta, sizeof ta);
    config_text(&b, tb, sizeof tb);
    if (strcmp(ta, tb) == 0) return PG_OK;
    const char *pa = ta, *pb = tb;
    while (*pa && *pa == *pb) { /* to the first differing line */
        pa++;
        pb++;
    }
    while (pa > ta && pa[-1] != '\n') {
        pa--;
        pb--;
    }
    int la = (int)strcspn(pa, "\n"), lb = (int)strcspn(pb, "\n");
    return pg_fail(PG_ERR_ARG, "%s: the checkpoint was trained with %.*s, this run asks for %.*s (use the same "
                   "settings to resume, or train into a new directory)", path, la, pa, lb, pb);
}

void train_checkpoint_clean_temps(const char *path)
{
    char dir[4096];
    snprintf(dir, sizeof dir, "%s", path);
    char *slash = strrchr(dir, '/');
    const char *base = slash ? slash + 1 : path;
    if (slash) *slash = '\0';
    else snprintf(dir, sizeof dir, ".");
    char prefix[512];
    snprintf(prefix, sizeof prefix, "%s.tmp.", base);
    DIR *d = opendir(dir);
    if (!d) return;
    struct dirent *e;
    while ((e = readdir(d)) != NULL)
        if (strncmp(e->d_name, prefix, strlen(prefix)) == 0) {
            char p[4600];
            snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
            remove(p);
        }
    closedir(d);
}
