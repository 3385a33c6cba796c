/* view_scene.c - quantises Gaussians over time into the viewer's scene file (view_scene.h). */
#include "view/view_scene.h"
#include "splat/sh.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/fileutil.h"
#include "core/mathx.h"

#define LOGIT_VISIBLE (-5.537334f) /* logit(1/255): below it a Gaussian adds < 1/255 anywhere */
/* Log-scales are quantised around their median: an axis below e^-6 of the typical size is flat
 * to the eye (the renderer's low-pass filter dominates); one above e^8 of it covers the scene.
 * Trained models have both (log-scales from -200 to +9 occur). */
#define LOG_SCALE_BELOW 6.0f
#define LOG_SCALE_ABOVE 8.0f

static size_t pad4(size_t n) { return (n + 3) & ~(size_t)3; }

/* Bytes of one block of n Gaussians: pos u16[3n], log-scale u8[3n], rot u8[4n], rgba u8[4n]. */
static size_t block_bytes(size_t n) { return pad4(6 * n) + pad4(3 * n) + 8 * n; }

/* Quantisation ranges shared by every record (header fields). */
typedef struct {
    float box_min[3], box_max[3];
    float ls_lo, ls_hi;  /* log-scale */
    float col_lo, col_hi; /* 0.5 + C0 * SH DC */
    float sh_max;        /* |higher SH| */
} quant_ranges;

/* Per-Gaussian extremes over all time samples (for moving ones) or its canonical values. */
typedef struct {
    float lo[3], hi[3];          /* position */
    float ls_lo[3], ls_hi[3];    /* log-scale per axis */
    float col_lo[3], col_hi[3];  /* 0.5 + C0 * SH DC */
    float q_lo[4], q_hi[4];      /* unit quaternion with w >= 0 */
    float opacity_lo, opacity_hi; /* logit */
} gauss_range;

static void range_init(gauss_range *r)
{
    for (int k = 0; k < 4; k++) {
        if (k < 3) r->lo[k] = r->ls_lo[k] = r->col_lo[k] = INFINITY, r->hi[k] = r->ls_hi[k] = r->col_hi[k] = -INFINITY;
        r->q_lo[k] = INFINITY, r->q_hi[k] = -INFINITY;
    }
    r->opacity_lo = INFINITY;
    r->opacity_hi = -INFINITY;
}

/* The unit quaternion of row i with w >= 0 (q and -q are one rotation); identity for a zero one. */
static void unit_quat(const pg_gaussians *g, size_t i, float u[4])
{
    const float *q = g->quats + 4 * i;
    float len = sqrtf(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    float sgn = q[0] < 0 ? -1.0f : 1.0f;
    for (int k = 0; k < 4; k++) u[k] = len > 0 ? sgn * q[k] / len : (float)(k == 0);
}

static void range_add(gauss_range *r, const pg_gaussians *g, int i)
{
    size_t a = (size_t)i;
    for (int k = 0; k < 3; k++) {
        float p = g->means[3 * a + k], s = g->log_scales[3 * a + k];
        float c = 0.5f + SPLAT_SH_C0 * splat_gaussians_sh(g, a)[k];
        r->lo[k] = fminf(r->lo[k], p), r->hi[k] = fmaxf(r->hi[k], p);
        r->ls_lo[k] = fminf(r->ls_lo[k], s), r->ls_hi[k] = fmaxf(r->ls_hi[k], s);
        r->col_lo[k] = fminf(r->col_lo[k], c), r->col_hi[k] = fmaxf(r->col_hi[k], c);
    }
    float u[4];
    unit_quat(g, a, u);
    for (int k = 0; k < 4; k++) r->q_lo[k] = fminf(r->q_lo[k], u[k]), r->q_hi[k] = fmaxf(r->q_hi[k], u[k]);
    r->opacity_lo = fminf(r->opacity_lo, g->opacity[a]);
    r->opacity_hi = fmaxf(r->opacity_hi, g->opacity[a]);
}

static float sigmoidf(float x) { return 1.0f / (1.0f + expf(-x)); }

/* 1 if a moving Gaussian changes too little over time to be seen changing: it moves less than
 * 5 % of its size and its scales (5 %), rotation (0.01), colour and opacity (1.5/255) hold. */
static int range_still(const gauss_range *r)
{
    float size = expf(fmaxf(r->ls_hi[0], fmaxf(r->ls_hi[1], r->ls_hi[2])));
    for (int k = 0; k < 3; k++)
        if (r->hi[k] - r->lo[k] > 0.05f * size || r->ls_hi[k] - r->ls_lo[k] > 0.05f ||
            r->col_hi[k] - r->col_lo[k] > 1.5f / 255.0f)
            return 0;
    for (int k = 0; k < 4; k++)
        if (r->q_hi[k] - r->q_lo[k] > 0.01f) return 0;
    return sigmoidf(r->opacity_hi) - sigmoidf(r->opacity_lo) <= 1.5f / 255.0f;
}

/* Visible footprint for --max-gaussians: opacity times the area of the two largest axes. */
static float importance(const pg_gaussians *g, int i, const gauss_range *r)
{
    float s[3];
    for (int k = 0; k < 3; k++) s[k] = g->log_scales[3 * (size_t)i + k];
    float lo = fminf(s[0], fminf(s[1], s[2]));
    return sigmoidf(r->opacity_hi) * expf(s[0] + s[1] + s[2] - lo);
}

typedef struct {
    float key;
    int index;
} ranked;

static int cmp_ranked(const void *a, const void *b)
{
    const ranked *x = a, *y = b;
    if (x->key != y->key) return x->key > y->key ? -1 : 1;
    return (x->index > y->index) - (x->index < y->index);
}

static uint16_t q16(float v, float lo, float hi)
{
    float u = hi > lo ? (v - lo) / (hi - lo) : 0.0f;
    return (uint16_t)lroundf(clampf(u, 0.0f, 1.0f) * 65535.0f);
}

static uint8_t q8(float v, float lo, float hi)
{
    float u = hi > lo ? (v - lo) / (hi - lo) : 0.0f;
    return (uint8_t)lroundf(clampf(u, 0.0f, 1.0f) * 255.0f);
}

/* Quantises rows idx[0..n) of g into one block (layout in docs/FORMATS.md). */
static void encode_block(const pg_gaussians *g, const int *idx, int n, const quant_ranges *q, uint8_t *out)
{
    uint16_t *pos = (uint16_t *)out;                  /* (n, 3) */
    uint8_t *ls = out + pad4(6 * (size_t)n);          /* (n, 3) */
    uint8_t *rot = ls + pad4(3 * (size_t)n);          /* (n, 4) w x y z */
    uint8_t *rgba = rot + 4 * (size_t)n;              /* (n, 4) */
    for (int j = 0; j < n; j++) {
        size_t i = (size_t)idx[j];
        for (int k = 0; k < 3; k++) {
            pos[3 * j + k] = q16(g->means[3 * i + k], q->box_min[k], q->box_max[k]);
            ls[3 * j + k] = q8(g->log_scales[3 * i + k], q->ls_lo, q->ls_hi);
            rgba[4 * j + k] = q8(0.5f + SPLAT_SH_C0 * splat_gaussians_sh(g, i)[k], q->col_lo, q->col_hi);
        }
        float u[4];
        unit_quat(g, i, u);
        for (int k = 0; k < 4; k++) rot[4 * j + k] = (uint8_t)lroundf(clampf(u[k] * 127.5f + 127.5f, 0.0f, 255.0f));
        rgba[4 * j + 3] = (uint8_t)lroundf(clampf(sigmoidf(g->opacity[i]), 0.0f, 1.0f) * 255.0f);
    }
}

static void put_u32(uint8_t *p, uint32_t v) { memcpy(p, &v, 4); } /* little-endian hosts only (x86-64) */
static void put_f32(uint8_t *p, float v) { memcpy(p, &v, 4); }

static pg_status write_bytes(pg_atomic_file *f, const void *data, size_t n)
{
    if (n && fwrite(data, 1, n, f->fp) != n)
        return pg_fail(PG_ERR_ENV, "%s: write failed: %s", f->path, strerror(errno));
    return PG_OK;
}

/* The scan over time: per-Gaussian ranges (moving ones over every sample), the Gaussians at the
 * first sample (what the file stores once), and movers that hold still demoted to static. */
static pg_status scan_ranges(const view_scene_source *src, uint8_t *moving, pg_gaussians *tmp, pg_gaussians *first,
                             gauss_range *gr)
{
    const pg_gaussians *g = src->canonical;
    int any_moving = 0;
    for (int i = 0; i < g->count; i++) {
        range_init(&gr[i]);
        if (moving[i]) any_moving = 1;
        else range_add(&gr[i], g, i);
    }
    if (!any_moving) PG_TRY(splat_gaussians_copy(g, first));
    for (int k = 0; any_moving && k < src->frames; k++) {
        float t = src->frames > 1 ? (float)k / (float)(src->frames - 1) : 0.0f;
        PG_TRY(src->at_time(src->ctx, t, tmp));
        if (tmp->count != g->count)
            return pg_fail(PG_ERR_ARG, "scene: %d Gaussians at t = %g, %d canonical", tmp->count, t, g->count);
        if (k == 0) PG_TRY(splat_gaussians_copy(tmp, first));
        for (int i = 0; i < g->count; i++)
            if (moving[i]) range_add(&gr[i], tmp, i);
    }
    for (int i = 0; i < g->count; i++) {
        const gauss_range *r = &gr[i];
        int finite = isfinite(r->opacity_lo) && isfinite(r->opacity_hi);
        for (int k = 0; k < 3; k++)
            finite &= isfinite(r->lo[k]) && isfinite(r->hi[k]) && isfinite(r->ls_lo[k]) && isfinite(r->ls_hi[k]) &&
                      isfinite(r->col_lo[k]) && isfinite(r->col_hi[k]);
        if (!finite) return pg_fail(PG_ERR_ARG, "scene: Gaussian %d has a non-finite value", i);
        if (moving[i] && range_still(r)) moving[i] = 0;
    }
    return PG_OK;
}

/* Chooses the kept Gaussians: static ones first, then moving, each in index order. */
static pg_status choose(const view_scene_source *src, const uint8_t *moving, const gauss_range *gr, int *order,
                        int *n_static, int *n_moving)
{
    const pg_gaussians *g = src->canonical;
    int n = 0;
    ranked *rk = pg_malloc(sizeof(ranked) * (size_t)g->count + 1, "scene ranking");
    if (!rk) return PG_ERR_NOMEM;
    for (int i = 0; i < g->count; i++)
        if (gr[i].opacity_hi >= LOGIT_VISIBLE) rk[n++] = (ranked){ importance(g, i, &gr[i]), i };
    if (src->max_gaussians > 0 && n > src->max_gaussians) {
        qsort(rk, (size_t)n, sizeof *rk, cmp_ranked);
        n = src->max_gaussians;
    }
    uint8_t *keep = pg_calloc((size_t)g->count + 1, 1, "scene keep flags");
    if (!keep) {
        free(rk);
        return PG_ERR_NOMEM;
    }
    for (int j = 0; j < n; j++) keep[rk[j].index] = 1;
    int s = 0, m = 0;
    for (int i = 0; i < g->count; i++)
        if (keep[i] && !moving[i]) order[s++] = i;
    for (int i = 0; i < g->count; i++)
        if (keep[i] && moving[i]) order[s + m++] = i;
    *n_static = s;
    *n_moving = m;
    free(keep);
    free(rk);
    return PG_OK;
}

/* Median canonical log-scale of the kept Gaussians (all three axes). */
static pg_status median_log_scale_of(const pg_gaussians *g, const int *order, int n, float *out)
{
    *out = 0.0f;
    if (n == 0) return PG_OK;
    float *v = pg_malloc(sizeof(float) * 3 * (size_t)n, "log-scale median");
    if (!v) return PG_ERR_NOMEM;
    for (int j = 0; j < n; j++) memcpy(v + 3 * (size_t)j, g->log_scales + 3 * (size_t)order[j], 3 * sizeof(float));
    qsort(v, 3 * (size_t)n, sizeof(float), pg_cmp_float);
    *out = v[3 * (size_t)n / 2];
    free(v);
    return PG_OK;
}

/* The range of the higher SH coefficients: their 99.9th percentile of |value|. A few deformed
 * Gaussians reach 40 where the rest stay below 0.3; those few saturate instead of coarsening the
 * step for everyone. */
static float sh_range(const pg_gaussians *g, const int *order, int n, int rest)
{
    enum { BINS = 4096 };
    float top = 0.0f;
    for (int j = 0; j < n; j++)
        for (int k = 3; k < 3 * (rest + 1); k++) top = fmaxf(top, fabsf(splat_gaussians_sh(g, (size_t)order[j])[k]));
    if (!(top > 0.0f)) return 0.0f;
    static size_t hist[BINS];
    memset(hist, 0, sizeof hist);
    for (int j = 0; j < n; j++)
        for (int k = 3; k < 3 * (rest + 1); k++) {
            int b = (int)(fabsf(splat_gaussians_sh(g, (size_t)order[j])[k]) / top * (BINS - 1));
            hist[b < 0 ? 0 : b > BINS - 1 ? BINS - 1 : b]++;
        }
    size_t total = (size_t)n * 3 * (size_t)rest, below = 0;
    for (int b = 0; b < BINS; b++) {
        below += hist[b];
        if ((double)below >= 0.999 * (double)total) return top * (float)(b + 1) / (BINS - 1);
    }
    return top;
}

/* Ranges over the kept Gaussians; higher SH from the canonical set (what the file stores). */
static void compute_ranges(const pg_gaussians *canonical, const gauss_range *gr, const int *order, int n,
                           float median_log_scale, quant_ranges *q)
{
    float ls_lo = INFINITY, ls_hi = -INFINITY, col_lo = INFINITY, col_hi = -INFINITY;
    for (int k = 0; k < 3; k++) q->box_min[k] = INFINITY, q->box_max[k] = -INFINITY;
    int rest = (canonical->sh_degree + 1) * (canonical->sh_degree + 1) - 1;
    for (int j = 0; j < n; j++) {
        const gauss_range *r = &gr[order[j]];
        for (int k = 0; k < 3; k++) {
            q->box_min[k] = fminf(q->box_min[k], r->lo[k]);
            q->box_max[k] = fmaxf(q->box_max[k], r->hi[k]);
            ls_lo = fminf(ls_lo, r->ls_lo[k]);
            ls_hi = fmaxf(ls_hi, r->ls_hi[k]);
            col_lo = fminf(col_lo, r->col_lo[k]);
            col_hi = fmaxf(col_hi, r->col_hi[k]);
        }
    }
    q->sh_max = sh_range(canonical, order, n, rest);
    if (n == 0) {
        for (int k = 0; k < 3; k++) q->box_min[k] = 0.0f, q->box_max[k] = 1.0f;
        ls_lo = ls_hi = col_lo = col_hi = 0.0f;
    }
    q->ls_lo = fmaxf(ls_lo, median_log_scale - LOG_SCALE_BELOW);
    q->ls_hi = fmaxf(q->ls_lo, fminf(ls_hi, median_log_scale + LOG_SCALE_ABOVE));
    /* colours beyond [-1, 2] saturate either way after the SH terms */
    q->col_lo = fmaxf(fminf(col_lo, 0.0f), -1.0f);
    q->col_hi = fminf(fmaxf(col_hi, 1.0f), 2.0f);
}

static void header_bytes(uint8_t *h, const view_scene_source *src, const quant_ranges *q, size_t meta, int s, int m,
                         int sh_degree)
{
    memset(h, 0, VIEW_SCENE_HEADER_BYTES);
    memcpy(h, "PGVS", 4);
    put_u32(h + 4, VIEW_SCENE_VERSION);
    put_u32(h + 8, VIEW_SCENE_HEADER_BYTES);
    put_u32(h + 12, (uint32_t)meta);
    put_u32(h + 16, (uint32_t)s);
    put_u32(h + 20, (uint32_t)m);
    put_u32(h + 24, (uint32_t)src->frames);
    put_u32(h + 28, (uint32_t)sh_degree);
    for (int k = 0; k < 3; k++) {
        put_f32(h + 32 + 4 * k, q->box_min[k]);
        put_f32(h + 44 + 4 * k, q->box_max[k]);
        put_f32(h + 80 + 4 * k, src->background[k]);
    }
    put_f32(h + 56, q->ls_lo);
    put_f32(h + 60, q->ls_hi);
    put_f32(h + 64, q->col_lo);
    put_f32(h + 68, q->col_hi);
    put_f32(h + 72, q->sh_max);
    put_f32(h + 76, src->fps);
}

pg_status view_scene_write(const char *path, const view_scene_source *src, const char *meta_json,
                           view_scene_stats *stats)
{
    memset(stats, 0, sizeof *stats);
    const pg_gaussians *g = src->canonical;
    if (!g || g->count < 1) return pg_fail(PG_ERR_ARG, "%s: no Gaussians to write", path);
    if (src->frames < 1 || src->frames > VIEW_SCENE_MAX_FRAMES)
        return pg_fail(PG_ERR_ARG, "%s: %d time samples (1..%d)", path, src->frames, VIEW_SCENE_MAX_FRAMES);
    if (src->max_gaussians < 0) return pg_fail(PG_ERR_ARG, "%s: max_gaussians %d < 0", path, src->max_gaussians);
    if (g->sh_degree < 0 || g->sh_degree > 3) return pg_fail(PG_ERR_ARG, "%s: SH degree %d", path, g->sh_degree);
    size_t N = (size_t)g->count;
    int rest = (g->sh_degree + 1) * (g->sh_degree + 1) - 1;
    uint8_t *moving = pg_calloc(N, 1, "moving flags");
    gauss_range *gr = pg_malloc(N * sizeof *gr, "scene ranges");
    int *order = pg_malloc(N * sizeof(int), "scene order");
    pg_gaussians tmp = { 0 }, first = { 0 }; /* at a sample time; at the first one */
    uint8_t *block = NULL;
    pg_atomic_file f = { 0 };
    int opened = 0;
    pg_status st = moving && gr && order ? PG_OK : PG_ERR_NOMEM;
    for (size_t i = 0; st == PG_OK && i < N; i++) moving[i] = src->at_time && src->is_static && !src->is_static[i];
    int s = 0, m = 0;
    if (st == PG_OK) st = scan_ranges(src, moving, &tmp, &first, gr);
    if (st == PG_OK) st = choose(src, moving, gr, order, &s, &m);
    quant_ranges q;
    size_t meta = strlen(meta_json);
    size_t frame_bytes = block_bytes((size_t)m), sh_bytes = pad4((size_t)(s + m) * 3 * (size_t)rest);
    float median_ls = 0.0f;
    if (st == PG_OK) st = median_log_scale_of(&first, order, s + m, &median_ls);
    if (st == PG_OK) {
        compute_ranges(g, gr, order, s + m, median_ls, &q);
        size_t biggest = block_bytes((size_t)s) > frame_bytes ? block_bytes((size_t)s) : frame_bytes;
        if (sh_bytes > biggest) biggest = sh_bytes;
        block = pg_calloc(biggest + VIEW_SCENE_HEADER_BYTES, 1, "scene block");
        if (!block) st = PG_ERR_NOMEM;
    }
    if (st == PG_OK && (st = pg_atomic_open(&f, path)) == PG_OK) opened = 1;
    if (st == PG_OK) {
        header_bytes(block, src, &q, meta, s, m, g->sh_degree);
        st = write_bytes(&f, block, VIEW_SCENE_HEADER_BYTES);
    }
    if (st == PG_OK) st = write_bytes(&f, meta_json, meta);
    if (st == PG_OK) st = write_bytes(&f, "\0\0\0", pad4(meta) - meta);
    if (st == PG_OK) { /* static block */
        memset(block, 0, block_bytes((size_t)s));
        encode_block(&first, order, s, &q, block);
        st = write_bytes(&f, block, block_bytes((size_t)s));
    }
    /* Higher SH of every kept Gaussian, canonical (q8 around 0): the network's SH deltas swing
     * widely over time (up to 40) where their Gaussians are faint; the canonical bands render
     * every sample better than any one deformed sample does. */
    if (st == PG_OK) {
        memset(block, 0, sh_bytes);
        for (int j = 0; j < s + m; j++) {
            const float *sh = splat_gaussians_sh(g, (size_t)order[j]) + 3;
            for (int k = 0; k < 3 * rest; k++) block[(size_t)j * 3 * rest + k] = q8(sh[k], -q.sh_max, q.sh_max);
        }
        st = write_bytes(&f, block, sh_bytes);
    }
    for (int k = 0; st == PG_OK && m > 0 && k < src->frames; k++) {
        float t = src->frames > 1 ? (float)k / (float)(src->frames - 1) : 0.0f;
        st = src->at_time(src->ctx, t, &tmp);
        if (st == PG_OK) {
            memset(block, 0, frame_bytes);
            encode_block(&tmp, order + s, m, &q, block);
            st = write_bytes(&f, block, frame_bytes);
        }
    }
    if (opened) {
        if (st == PG_OK) st = pg_atomic_commit(&f);
        else pg_atomic_abort(&f);
    }
    if (st == PG_OK) {
        stats->static_count = s;
        stats->moving_count = m;
        stats->frames = src->frames;
        stats->sh_degree = g->sh_degree;
        stats->dropped = g->count - s - m;
        stats->bytes = VIEW_SCENE_HEADER_BYTES + pad4(meta) + block_bytes((size_t)s) + sh_bytes +
                       (m > 0 ? (size_t)src->frames * frame_bytes : 0);
    }
    splat_gaussians_destroy(&tmp);
    splat_gaussians_destroy(&first);
    free(block);
    free(order);
    free(gr);
    free(moving);
    return st;
}
