/* raster.c - the rasterizer pipeline: preprocess (project + SH + box), depth sort, tile binning,
 * per-tile forward, per-tile backward into per-(Gaussian, tile) gradient slots, and a fixed-order
 * per-Gaussian reduction chained back through SH and the projection.
 *
 * Determinism: every tile writes only its own pixels and its own gradient slots, and each
 * Gaussian sums its slots in tile order, so results do not depend on the thread count or the
 * OpenMP schedule (no float atomics anywhere).
 */
#include "splat/raster.h"
#include "splat/project.h"
#include "splat/raster_kernels.h"
#include "splat/sh.h"
#include "core/mathx.h"
#include "core/parallel.h"
#include "core/status.h"

#include <limits.h>
#include <omp.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SPLAT_MAX_THREADS 256

struct splat_raster {
    splat_kernel_kind kernel;   /* tile (and projection) kernels */
    /* Per-Gaussian workspace, capacity cap_g. */
    int cap_g;
    splat_rec *rec;             /* (N) */
    int *ntiles;                /* (N) tiles touched, 0 when culled */
    unsigned char *clamp;       /* (N) bit c set: colour channel c clamped at 0 */
    uint16_t *rect;             /* (N, 4) tile box tx0 ty0 tx1 ty1 (compact copy for binning) */
    uint32_t *keys, *keys_tmp;  /* (N) depth sort keys */
    int *order, *order_tmp;     /* (N) visible Gaussians sorted by depth */
    /* Per-tile workspace. */
    int cap_tiles;
    int *tile_start;            /* (tiles + 1) offsets into isect */
    int *tcount;                /* (2, threads, tiles) per-thread tile counts, then write cursors */
    size_t cap_tcount;
    /* Per-intersection workspace, capacity cap_m. */
    size_t cap_m, cap_slots;
    int *isect;                 /* (M) Gaussian ids, grouped by tile, front to back in a tile */
    float *slots;               /* (M, SPLAT_GRAD_STRIDE) gradient slots, Gaussian-major */
    /* Image buffers, capacity cap_px pixels. */
    size_t cap_px;
    float *rgb, *depth, *alpha, *tfinal; /* (H,W,3) (H,W) (H,W) (H,W) */
    int *last;                  /* (H,W) */
    /* State of the latest forward. */
    int valid, n, width, height, tiles_x, tiles_y, sh_degree, visible;
    size_t m;
    float bg[3];
    float lim[SPLAT_LIM_COUNT]; /* frustum clamp limits and screen-space filter of the camera */
    float cam_center[3];
};

pg_render_settings splat_default_settings(void)
{
    pg_render_settings s;
    s.background[0] = s.background[1] = s.background[2] = 0.0f;
    s.near_clip = 0.01f;
    s.sh_degree = -1;
    s.whole = NULL;
    s.train_focal = 0.0f;
    return s;
}

float splat_lowpass_for(const pg_camera *cam, const pg_render_settings *s)
{
    if (!(s->train_focal > 0)) return SPLAT_LOWPASS;
    const float ratio = fmaxf(cam->fx, cam->fy) / s->train_focal;
    return ratio > 1.0f ? SPLAT_LOWPASS * ratio * ratio : SPLAT_LOWPASS;
}

pg_status splat_raster_create(splat_raster **out)
{
    *out = NULL;
    splat_raster *r = pg_calloc(1, sizeof(*r), "rasterizer");
    if (!r) return PG_ERR_NOMEM;
    r->kernel = splat_kernel_default();
    *out = r;
    return PG_OK;
}

void splat_raster_destroy(splat_raster *r)
{
    if (!r) return;
    free(r->rec); free(r->ntiles); free(r->clamp); free(r->rect); free(r->keys); free(r->keys_tmp);
    free(r->order); free(r->order_tmp); free(r->tile_start); free(r->tcount);
    free(r->isect); free(r->slots);
    free(r->rgb); free(r->depth); free(r->alpha); free(r->tfinal); free(r->last);
    free(r);
}

/* Per kernel family: the tile kernels and the 16-wide projection (NULL: the scalar one per Gaussian). */
typedef unsigned (*splat_box16_fn)(const float[9][16], unsigned, const float *, int, int, int, splat_box16 *);
static const struct {
    void (*forward)(const splat_tile_job *), (*backward)(const splat_tile_job *);
    splat_project16_forward_fn project_forward;
    splat_project16_backward_fn project_backward;
    splat_box16_fn box; /* NULL: box_one per lane */
} tile_kernels[SPLAT_KERNELS] = {
    { splat_tile_forward_scalar, splat_tile_backward_scalar, NULL, NULL, NULL },
#if defined(__x86_64__) && defined(__GNUC__)
    { splat_tile_forward_avx2, splat_tile_backward_avx2, splat_project_forward16_avx2, splat_project_backward16_avx2, NULL },
    { splat_tile_forward_avx512, splat_tile_backward_avx512, splat_project_forward16, splat_project_backward16,
      splat_box16_avx512 },
#endif
};

int splat_kernel_supported(splat_kernel_kind k)
{
#if defined(__x86_64__) && defined(__GNUC__)
    switch (k) {
    case SPLAT_KERNEL_SCALAR: return 1;
    case SPLAT_KERNEL_AVX2: return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
    case SPLAT_KERNEL_AVX512:
        return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq") &&
               __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512vl") && __builtin_cpu_supports("fma");
    default: return 0;
    }
#else
    return k == SPLAT_KERNEL_SCALAR;
#endif
}

const char *splat_kernel_name(splat_kernel_kind k)
{
    static const char *names[SPLAT_KERNELS] = { "scalar", "avx2", "avx512" };
    return (unsigned)k < SPLAT_KERNELS ? names[k] : "?";
}

splat_kernel_kind splat_kernel_default(void)
{
    static int chosen = -1;
    if (chosen >= 0) return (splat_kernel_kind)chosen;
    splat_kernel_kind best = SPLAT_KERNEL_AVX512;
    while (!splat_kernel_supported(best)) best--;
    chosen = best;
    const char *env = getenv("PG_RASTER");
    if (env && *env) {
        int k = 0;
        while (k < SPLAT_KERNELS && strcmp(env, splat_kernel_name((splat_kernel_kind)k)) != 0) k++;
        if (k < SPLAT_KERNELS && splat_kernel_supported((splat_kernel_kind)k)) chosen = k;
        else
            pg_warn("PG_RASTER=%s is not %s; using %s", env,
                    k < SPLAT_KERNELS ? "supported by this CPU" : "one of scalar, avx2, avx512", splat_kernel_name(best));
    }
    return (splat_kernel_kind)chosen;
}

int splat_raster_set_kernel(splat_raster *r, splat_kernel_kind k)
{
    if (!splat_kernel_supported(k)) return -1;
    r->kernel = k;
    return 0;
}

splat_kernel_kind splat_raster_kernel(const splat_raster *r) { return r->kernel; }

/* Grows *p to hold need elements of elem bytes (contents not kept); 64-byte aligned. */
static pg_status grow(void **p, size_t *cap, size_t need, size_t elem, const char *what)
{
    if (need <= *cap && *p) return PG_OK;
    size_t n = need + need / 4 + 64, bytes;
    if (pg_size_mul(n, elem, &bytes)) return pg_fail(PG_ERR_SIZE, "rasterizer: %s size overflows", what);
    bytes = (bytes + 63) & ~(size_t)63;
    void *q = aligned_alloc(64, bytes);
    if (!q) return pg_fail(PG_ERR_NOMEM, "rasterizer: out of memory for %s (%zu bytes)", what, bytes);
    free(*p);
    *p = q;
    *cap = n;
    return PG_OK;
}

static pg_status ensure_gaussians(splat_raster *r, int n)
{
    if (n <= r->cap_g && r->rec) return PG_OK;
    size_t cap = 0, c2;
    PG_TRY(grow((void **)&r->rec, &cap, (size_t)n, sizeof(splat_rec), "Gaussian records"));
    c2 = 0; PG_TRY(grow((void **)&r->ntiles, &c2, (size_t)n, sizeof(int), "tile counts"));
    c2 = 0; PG_TRY(grow((void **)&r->clamp, &c2, (size_t)n, 1, "clamp flags"));
    c2 = 0; PG_TRY(grow((void **)&r->rect, &c2, (size_t)n, 4 * sizeof(uint16_t), "tile boxes"));
    c2 = 0; PG_TRY(grow((void **)&r->keys, &c2, (size_t)n, sizeof(uint32_t), "sort keys"));
    c2 = 0; PG_TRY(grow((void **)&r->keys_tmp, &c2, (size_t)n, sizeof(uint32_t), "sort keys"));
    c2 = 0; PG_TRY(grow((void **)&r->order, &c2, (size_t)n, sizeof(int), "sort order"));
    c2 = 0; PG_TRY(grow((void **)&r->order_tmp, &c2, (size_t)n, sizeof(int), "sort order"));
    r->cap_g = cap > INT_MAX ? INT_MAX : (int)cap;
    return PG_OK;
}

static pg_status ensure_pixels(splat_raster *r, size_t px)
{
    if (px <= r->cap_px && r->rgb) return PG_OK;
    size_t cap = 0, c2;
    PG_TRY(grow((void **)&r->rgb, &cap, px, 3 * sizeof(float), "rgb image"));
    c2 = 0; PG_TRY(grow((void **)&r->depth, &c2, px, sizeof(float), "depth image"));
    c2 = 0; PG_TRY(grow((void **)&r->alpha, &c2, px, sizeof(float), "alpha image"));
    c2 = 0; PG_TRY(grow((void **)&r->tfinal, &c2, px, sizeof(float), "transmittance image"));
    c2 = 0; PG_TRY(grow((void **)&r->last, &c2, px, sizeof(int), "last-contributor image"));
    r->cap_px = cap;
    return PG_OK;
}

static pg_status ensure_tiles(splat_raster *r, int tiles)
{
    if (tiles <= r->cap_tiles && r->tile_start) return PG_OK;
    size_t cap = 0;
    PG_TRY(grow((void **)&r->tile_start, &cap, (size_t)tiles + 1, sizeof(int), "tile ranges"));
    r->cap_tiles = (int)(cap - 1);
    return PG_OK;
}

/* The opacity-aware pixel box of Gaussian i's projection p: activated opacity o, threshold ln(255 o)
 * and clamped bounds (xmin, xmax, ymin, ymax); 0 when it covers no pixel. splat_box16_avx512 does
 * the same operations on 16 lanes (the opacity's exp and log are the shared polynomials), so both
 * paths give the same bits. */
static int box_one(const splat_proj *p, float logit, int width, int height, float *o_out, float *thr, int box[4])
{
    /* The box at the largest reach (3.33 sigma) contains the opacity-aware one below: a Gaussian
     * outside the image even so is culled before its opacity's exp and log (most of a motion
     * crop's Gaussians are). */
    const float sx = sqrtf(p->cov2d[0]), sy = sqrtf(p->cov2d[2]);
    {
        float rx = ceilf(3.33f * sx), ry = ceilf(3.33f * sy);
        if (!(floorf(p->xy[0] + rx - 0.5f) >= 0 && floorf(p->xy[1] + ry - 0.5f) >= 0 &&
              ceilf(p->xy[0] - rx - 0.5f) <= width - 1 && ceilf(p->xy[1] - ry - 0.5f) <= height - 1))
            return 0;
    }
    float o = splat_sigmoid_poly(logit);
    if (!(o >= SPLAT_ALPHA_MIN)) return 0;
    /* alpha = o exp(-sigma) >= 1/255 inside sigma <= ln(255 o); along x that reaches
     * sqrt(2 ln(255 o) Sigma_xx). Ternaries, not fminf / fmaxf: without -ffast-math those are
     * library calls (NaN rules); lim is a number here. */
    float lim = splat_log_poly(255.0f * o), reach = sqrtf(2.0f * (lim > 0.0f ? lim : 0.0f));
    float e = reach < 3.33f ? reach : 3.33f;
    float rx = ceilf(e * sx), ry = ceilf(e * sy);
    /* Pixel i is covered when |i + 0.5 - x| <= rx. Compare in float before any int cast. */
    float fxmin = ceilf(p->xy[0] - rx - 0.5f), fxmax = floorf(p->xy[0] + rx - 0.5f);
    float fymin = ceilf(p->xy[1] - ry - 0.5f), fymax = floorf(p->xy[1] + ry - 0.5f);
    if (!(fxmax >= 0 && fymax >= 0 && fxmin <= width - 1 && fymin <= height - 1)) return 0;
    box[0] = fxmin < 0 ? 0 : (int)fxmin, box[1] = fxmax > width - 1 ? width - 1 : (int)fxmax;
    box[2] = fymin < 0 ? 0 : (int)fymin, box[3] = fymax > height - 1 ? height - 1 : (int)fymax;
    if (box[0] > box[1] || box[2] > box[3]) return 0;
    *o_out = o;
    *thr = lim; /* sigma <= ln(255 o) is exactly o exp(-sigma) >= 1/255, without rounding doubts */
    return 1;
}

/* Fills r->rec[i], r->rect[i], r->clamp[i] and r->ntiles[i] of a Gaussian whose box (xmin, xmax,
 * ymin, ymax) covers pixels: its record for the tile kernels and its colour. */
static void write_record(splat_raster *r, const pg_gaussians *g, int deg, int i, const splat_proj *p, float o,
                         float thr, int xmin, int xmax, int ymin, int ymax)
{
    splat_rec *rc = &r->rec[i];
    rc->x = p->xy[0]; rc->y = p->xy[1];
    rc->ha = 0.5f * p->conic[0]; rc->cb = p->conic[1]; rc->hc = 0.5f * p->conic[2];
    rc->o = o; rc->z = p->z;
    rc->thr = thr;
    rc->ymin = ymin; rc->ymax = ymax;
    rc->tx0 = xmin / SPLAT_TILE;
    rc->tw = xmax / SPLAT_TILE - rc->tx0 + 1;
    float dir[3];
    vec3_sub(dir, g->means + 3*i, r->cam_center);
    int cl[3];
    splat_sh_forward(deg, splat_gaussians_sh(g, (size_t)i), dir, rc->col, cl);
    r->clamp[i] = (unsigned char)(cl[0] | cl[1] << 1 | cl[2] << 2);
    r->ntiles[i] = rc->tw * (ymax / SPLAT_TILE - ymin / SPLAT_TILE + 1);
    uint16_t *bx = r->rect + 4 * (size_t)i;
    bx[0] = (uint16_t)rc->tx0; bx[1] = (uint16_t)(ymin / SPLAT_TILE);
    bx[2] = (uint16_t)(xmax / SPLAT_TILE); bx[3] = (uint16_t)(ymax / SPLAT_TILE);
}

/* box_one then write_record (ntiles 0 when culled). */
static void finish_one(splat_raster *r, const pg_gaussians *g, const pg_camera *cam, int deg, int i,
                       const splat_proj *p)
{
    float o, thr;
    int b[4];
    r->ntiles[i] = 0;
    if (box_one(p, g->opacity[i], cam->width, cam->height, &o, &thr, b)) write_record(r, g, deg, i, p, o, thr, b[0], b[1], b[2], b[3]);
}

/* Starts loading the colour rows of Gaussians i .. i+15 (for writing when write is set). A row
 * of the 48 floats of degree 3 of which degree 0 reads 3 is a stride the hardware prefetcher does
 * not follow: without this, the colour load of every Gaussian was a cache miss (~7 % of a
 * classroom training step in perf when its rows were 48 floats; ~2 % with the prefetch). Rows of
 * up to 16 floats are a few cache lines for the 16, which the prefetcher streams itself. */
static inline void prefetch_sh_rows(const pg_gaussians *g, int i, int end, int write)
{
    if (g->sh_stride < 16) return;
    int n = end - i < 16 ? end - i : 16;
    for (int l = 0; l < n; l++) {
        const float *row = splat_gaussians_sh(g, (size_t)(i + l));
        if (write) __builtin_prefetch(row, 1, 3);
        else __builtin_prefetch(row, 0, 3);
    }
}

/* Preprocesses Gaussians i0 .. i1-1: projection 16 at a time with the kernel family's vector code. */
static void preprocess_range(splat_raster *r, const pg_gaussians *g, const pg_camera *cam,
                             const pg_render_settings *s, int deg, int i0, int i1)
{
    int i = i0;
    float pr[9][16];
    unsigned valid;
    splat_project16_forward_fn project16 = tile_kernels[r->kernel].project_forward;
    splat_box16_fn box16 = tile_kernels[r->kernel].box;
    for (; project16 && i + 16 <= i1; i += 16) {
        if (!project16(g->means, g->log_scales, g->quats, i, cam, r->lim, s->near_clip, pr, &valid))
            break;
        prefetch_sh_rows(g, i + 16, i1, 0);
        splat_box16 bx;
        unsigned keep = box16 ? box16(pr, valid, g->opacity, i, cam->width, cam->height, &bx) : 0;
        for (int l = 0; l < 16; l++) {
            r->ntiles[i + l] = 0;
            if (!((box16 ? keep : valid) >> l & 1)) continue;
            splat_proj p = { { pr[0][l], pr[1][l] }, pr[2][l], { pr[3][l], pr[4][l], pr[5][l] },
                             { pr[6][l], pr[7][l], pr[8][l] } };
            if (box16) write_record(r, g, deg, i + l, &p, bx.o[l], bx.thr[l], bx.xmin[l], bx.xmax[l], bx.ymin[l], bx.ymax[l]);
            else finish_one(r, g, cam, deg, i + l, &p);
        }
    }
    for (; i < i1; i++) {
        splat_proj p;
        if (splat_project_forward_lim(g->means + 3*i, g->log_scales + 3*i, g->quats + 4*i, cam, r->lim, s->near_clip, &p))
            finish_one(r, g, cam, deg, i, &p);
        else
            r->ntiles[i] = 0;
    }
}

/* Stable LSD radix sort of (key, value) pairs by 32-bit key, 8 bits per pass. Each thread
 * counts and scatters a contiguous part; a digit's entries from earlier parts go first, so the
 * result is the serial one for any thread count (the depth order of ~100k Gaussians per view
 * was a serial pass the other threads waited on). */
static void radix_sort(uint32_t *keys, int *vals, uint32_t *ktmp, int *vtmp, int n, int nth)
{
    int count[nth][256]; /* nth <= SPLAT_MAX_THREADS */
    int skip = 0;
    #pragma omp parallel num_threads(nth)
    {
        const int t = omp_get_thread_num(), T = omp_get_num_threads();
        const int i0 = (int)((long)n * t / T), i1 = (int)((long)n * (t + 1) / T);
        uint32_t *src_k = keys, *dst_k = ktmp;
        int *src_v = vals, *dst_v = vtmp;
        for (int shift = 0; shift < 32; shift += 8) {
            int *c = count[t];
            memset(c, 0, sizeof count[t]);
            for (int i = i0; i < i1; i++) c[(src_k[i] >> shift) & 255]++;
            #pragma omp barrier
            #pragma omp single
            {
                /* every digit's start, thread parts in order; a byte all keys share changes nothing */
                skip = 0;
                for (int d = 0, total = 0; d < 256; d++) {
                    int digit_total = 0;
                    for (int q = 0; q < T; q++) digit_total += count[q][d];
                    if (digit_total == n) skip = 1;
                    for (int q = 0; q < T; q++) {
                        int cq = count[q][d];
                        count[q][d] = total;
                        total += cq;
                    }
                }
            } /* implicit barrier */
            if (skip) continue;
            for (int i = i0; i < i1; i++) {
                const int d = c[(src_k[i] >> shift) & 255]++;
                dst_k[d] = src_k[i];
                dst_v[d] = src_v[i];
            }
            uint32_t *tk = src_k; src_k = dst_k; dst_k = tk;
            int *tv = src_v; src_v = dst_v; dst_v = tv;
            #pragma omp barrier
        }
        /* an odd number of scatters left the result in the scratch arrays */
        if (src_k != keys) {
            memcpy(keys + i0, src_k + i0, (size_t)(i1 - i0) * sizeof(uint32_t));
            memcpy(vals + i0, src_v + i0, (size_t)(i1 - i0) * sizeof(int));
        }
    }
}

static void make_job(const splat_raster *r, int tile, splat_tile_job *j)
{
    j->tx = tile % r->tiles_x;
    j->ty = tile / r->tiles_x;
    j->x0 = j->tx * SPLAT_TILE;
    j->y0 = j->ty * SPLAT_TILE;
    j->w = r->width - j->x0 < SPLAT_TILE ? r->width - j->x0 : SPLAT_TILE;
    j->h = r->height - j->y0 < SPLAT_TILE ? r->height - j->y0 : SPLAT_TILE;
    j->width = r->width;
    j->list = r->isect + r->tile_start[tile];
    j->n = r->tile_start[tile + 1] - r->tile_start[tile];
    j->rec = r->rec;
    for (int c = 0; c < 3; c++) j->bg[c] = r->bg[c];
    j->rgb = r->rgb; j->depth = r->depth; j->alpha = r->alpha; j->tfinal = r->tfinal; j->last = r->last;
    j->d_rgb = j->d_depth = j->d_alpha = NULL;
    j->grad_slots = r->slots;
}

/* The SH degree a render uses: the settings' (-1: the set's own), within 0..3. */
static int render_degree(const pg_gaussians *g, const pg_render_settings *s)
{
    int deg = s->sh_degree >= 0 ? s->sh_degree : g->sh_degree;
    return deg < 0 ? 0 : (deg > 3 ? 3 : deg);
}

static pg_status check_inputs(const pg_gaussians *g, const pg_camera *cam, const pg_render_settings *s)
{
    if (!g || !cam || !s) return pg_fail(PG_ERR_ARG, "rasterizer: NULL argument");
    if (cam->width <= 0 || cam->height <= 0 || cam->width > 16384 || cam->height > 16384)
        return pg_fail(PG_ERR_SIZE, "rasterizer: bad image size %d x %d", cam->width, cam->height);
    if (!(cam->fx > 0) || !(cam->fy > 0))
        return pg_fail(PG_ERR_ARG, "rasterizer: bad focal length %g %g", cam->fx, cam->fy);
    if (g->count < 0 || (g->count > 0 && !g->means))
        return pg_fail(PG_ERR_ARG, "rasterizer: Gaussian set has %d rows but no storage", g->count);
    if (s->sh_degree > 3) return pg_fail(PG_ERR_ARG, "rasterizer: SH degree %d > 3", s->sh_degree);
    int deg = render_degree(g, s);
    if (g->count > 0 && splat_sh_floats(deg) > g->sh_stride)
        return pg_fail(PG_ERR_ARG, "rasterizer: SH degree %d but the set stores %d SH floats a row", deg, g->sh_stride);
    return PG_OK;
}

pg_status splat_render_forward(splat_raster *r, const pg_gaussians *g, const pg_camera *cam,
                               const pg_render_settings *s, pg_render_output *out)
{
    PG_TRY(check_inputs(g, cam, s));
    double t0 = pg_time_seconds();
    r->valid = 0;
    int n = g->count, W = cam->width, H = cam->height;
    int deg = render_degree(g, s);
    int tx = (W + SPLAT_TILE - 1) / SPLAT_TILE, ty = (H + SPLAT_TILE - 1) / SPLAT_TILE;
    PG_TRY(ensure_gaussians(r, n > 0 ? n : 1));
    PG_TRY(ensure_pixels(r, (size_t)W * H));
    PG_TRY(ensure_tiles(r, tx * ty));
    r->n = n; r->width = W; r->height = H; r->tiles_x = tx; r->tiles_y = ty; r->sh_degree = deg;
    for (int c = 0; c < 3; c++) r->bg[c] = s->background[c];
    splat_project_limits(s->whole ? s->whole : cam, splat_lowpass_for(cam, s), r->lim);
    pg_camera_center(cam, r->cam_center);

    /* Preprocess, then gradient slot offsets (Gaussian-major) and the visible list in index
     * order: each thread takes a contiguous chunk, chunk sums are prefixed, then each chunk
     * fills its part (same result for any thread count; one parallel region, one barrier). */
    int nth = pg_get_threads();
    if (nth < 1) nth = 1;
    if (nth > SPLAT_MAX_THREADS) nth = SPLAT_MAX_THREADS;
    size_t part_m[SPLAT_MAX_THREADS + 1] = { 0 };
    int part_v[SPLAT_MAX_THREADS + 1] = { 0 };
    #pragma omp parallel num_threads(nth)
    {
        int t = omp_get_thread_num(), T = omp_get_num_threads();
        /* chunk edges on multiples of 16, so every Gaussian takes the same (vector or scalar
         * tail) projection path whatever the thread count */
        int i0 = (int)((long)n * t / T) & ~15, i1 = t == T - 1 ? n : (int)((long)n * (t + 1) / T) & ~15;
        size_t mm = 0;
        int vv = 0;
        preprocess_range(r, g, cam, s, deg, i0, i1);
        for (int i = i0; i < i1; i++) {
            mm += (size_t)r->ntiles[i];
            vv += r->ntiles[i] > 0;
        }
        part_m[t + 1] = mm;
        part_v[t + 1] = vv;
        #pragma omp barrier
        /* every thread prefixes the chunk sums itself: no second barrier */
        mm = 0;
        vv = 0;
        for (int q = 0; q < t; q++) { mm += part_m[q + 1]; vv += part_v[q + 1]; }
        size_t total = 0;
        int total_v = 0;
        for (int q = 0; q < T; q++) { total += part_m[q + 1]; total_v += part_v[q + 1]; }
        if (total <= INT_MAX)
            for (int i = i0; i < i1; i++) {
                r->rec[i].slot_base = (int)mm;
                if (r->ntiles[i] > 0) {
                    mm += (size_t)r->ntiles[i];
                    union { float f; uint32_t u; } z = { r->rec[i].z };
                    r->keys[vv] = z.u; /* positive floats order like their bit patterns */
                    r->order[vv++] = i;
                }
            }
        if (t == T - 1) { part_m[0] = total; part_v[0] = total_v; } /* slot 0 is read by nobody else */
    }
    size_t m = part_m[0];
    int vis = part_v[0];
    if (m > INT_MAX) return pg_fail(PG_ERR_SIZE, "rasterizer: %zu tile intersections (limit %d)", m, INT_MAX);
    r->m = m;
    r->visible = vis;
    if (vis > 0) radix_sort(r->keys, r->order, r->keys_tmp, r->order_tmp, vis, vis >= 4096 ? nth : 1);

    /* Bin: counting sort by tile of the depth-sorted list keeps depth order inside each tile.
     * Each thread counts a contiguous part of the list; a thread's entries of a tile go after
     * those of earlier parts, so the lists equal the serial ones. */
    size_t capm = r->cap_m;
    PG_TRY(grow((void **)&r->isect, &capm, m > 0 ? m : 1, sizeof(int), "tile lists"));
    r->cap_m = capm;
    int ntile = tx * ty;
    size_t capc = r->cap_tcount;
    PG_TRY(grow((void **)&r->tcount, &capc, (size_t)2 * nth * ntile, sizeof(int), "tile counts"));
    r->cap_tcount = capc;
    #pragma omp parallel num_threads(nth)
    {
        int t = omp_get_thread_num(), T = omp_get_num_threads();
        int v0 = (int)((long)vis * t / T), v1 = (int)((long)vis * (t + 1) / T);
        int *cnt = r->tcount + (size_t)t * ntile;
        memset(cnt, 0, (size_t)ntile * sizeof(int));
        /* the boxes are read in depth order, a random walk over r->rect: fetched ahead, each was a
         * cache miss (~a quarter of the binning's time) */
        for (int v = v0; v < v1; v++) {
            if (v + 16 < v1) __builtin_prefetch(r->rect + 4 * (size_t)r->order[v + 16]);
            const uint16_t *bx = r->rect + 4 * (size_t)r->order[v];
            for (int yy = bx[1]; yy <= bx[3]; yy++)
                for (int xx = bx[0]; xx <= bx[2]; xx++) cnt[yy * tx + xx]++;
        }
        #pragma omp barrier
        /* each thread derives its own write cursors from all counts (thread 0 also publishes
         * the tile ranges): no second barrier */
        int *cur = r->tcount + (size_t)(T + t) * ntile;
        int run = 0;
        for (int tile = 0; tile < ntile; tile++) {
            if (t == 0) r->tile_start[tile] = run;
            for (int q = 0; q < T; q++) {
                if (q == t) cur[tile] = run;
                run += r->tcount[(size_t)q * ntile + tile];
            }
        }
        if (t == 0) r->tile_start[ntile] = run;
        for (int v = v0; v < v1; v++) {
            if (v + 16 < v1) __builtin_prefetch(r->rect + 4 * (size_t)r->order[v + 16]);
            int id = r->order[v];
            const uint16_t *bx = r->rect + 4 * (size_t)id;
            for (int yy = bx[1]; yy <= bx[3]; yy++)
                for (int xx = bx[0]; xx <= bx[2]; xx++) r->isect[cur[yy * tx + xx]++] = id;
        }
    }
    double t1 = pg_time_seconds();

    void (*tile_forward)(const splat_tile_job *) = tile_kernels[r->kernel].forward;
    #pragma omp parallel for schedule(dynamic, 1)
    for (int t = 0; t < ntile; t++) {
        splat_tile_job j;
        make_job(r, t, &j);
        tile_forward(&j);
    }
    double t2 = pg_time_seconds();

    r->valid = 1;
    out->width = W; out->height = H;
    out->rgb = r->rgb; out->depth = r->depth; out->alpha = r->alpha;
    out->intersections = (long)m;
    out->preprocess_ms = (t1 - t0) * 1e3;
    out->forward_ms = (t2 - t0) * 1e3;
    return PG_OK;
}

/* The sums over a Gaussian's ntiles gradient slots, in double. Ten named sums stay in registers:
 * an array summed in place went through the stack at every add (store-forwarding stalls made the
 * reduction ~half of the backward's per-Gaussian pass). */
_Static_assert(SPLAT_GRAD_STRIDE == 10, "sum_slots names the ten slot sums");
static inline void sum_slots(const float *sl, int ntiles, double acc[SPLAT_GRAD_STRIDE])
{
    double a0 = 0, a1 = 0, a2 = 0, a3 = 0, a4 = 0, a5 = 0, a6 = 0, a7 = 0, a8 = 0, a9 = 0;
    for (int k = 0; k < ntiles; k++, sl += SPLAT_GRAD_STRIDE) {
        a0 += sl[0]; a1 += sl[1]; a2 += sl[2]; a3 += sl[3]; a4 += sl[4];
        a5 += sl[5]; a6 += sl[6]; a7 += sl[7]; a8 += sl[8]; a9 += sl[9];
    }
    acc[0] = a0; acc[1] = a1; acc[2] = a2; acc[3] = a3; acc[4] = a4;
    acc[5] = a5; acc[6] = a6; acc[7] = a7; acc[8] = a8; acc[9] = a9;
}

pg_status splat_render_backward(splat_raster *r, const pg_gaussians *g, const pg_camera *cam,
                                const pg_render_settings *s, const float *d_rgb, const float *d_depth,
                                const float *d_alpha, pg_gaussians *grad, float *viewspace_grad_norm)
{
    PG_TRY(check_inputs(g, cam, s));
    if (!r->valid || r->n != g->count || r->width != cam->width || r->height != cam->height)
        return pg_fail(PG_ERR_ARG, "rasterizer: backward without a matching forward (%d Gaussians, %d x %d)",
                       g->count, cam->width, cam->height);
    if (!grad || grad->count != g->count || (g->count > 0 && !grad->means))
        return pg_fail(PG_ERR_ARG, "rasterizer: gradient set has %d rows, expected %d",
                       grad ? grad->count : -1, g->count);
    if (g->count > 0 && splat_sh_floats(r->sh_degree) > grad->sh_stride)
        return pg_fail(PG_ERR_ARG, "rasterizer: SH degree %d but the gradient set stores %d SH floats a row",
                       r->sh_degree, grad->sh_stride);
    size_t caps = r->cap_slots;
    PG_TRY(grow((void **)&r->slots, &caps, (r->m > 0 ? r->m : 1) * SPLAT_GRAD_STRIDE, sizeof(float), "gradient slots"));
    r->cap_slots = caps;
    int ntile = r->tiles_x * r->tiles_y;
    void (*tile_backward)(const splat_tile_job *) = tile_kernels[r->kernel].backward;
    #pragma omp parallel for schedule(dynamic, 1)
    for (int t = 0; t < ntile; t++) {
        splat_tile_job j;
        make_job(r, t, &j);
        j.d_rgb = d_rgb; j.d_depth = d_depth; j.d_alpha = d_alpha;
        tile_backward(&j);
    }

    /* Per-Gaussian fixed-order reduction of the slots, then the chain through SH and projection. */
    float C[3], lim[SPLAT_LIM_COUNT];
    pg_camera_center(cam, C);
    splat_project_limits(s->whole ? s->whole : cam, splat_lowpass_for(cam, s), lim);
    int deg = r->sh_degree, n = g->count;
    const pg_camera *frame = s->whole ? s->whole : cam;
    float half_w = 0.5f * frame->width, half_h = 0.5f * frame->height;
    /* Blocks of 16 Gaussians: slot sums, opacity and SH per Gaussian, then the projection
     * backward 16 at a time (same blocks for any thread count, so results stay identical). */
    int nblk = (n + 15) / 16;
    splat_project16_backward_fn project16 = tile_kernels[r->kernel].project_backward;
    #pragma omp parallel for schedule(static, 16)
    for (int b = 0; b < nblk; b++) {
        int i0 = 16 * b, cnt = n - i0 < 16 ? n - i0 : 16;
        float d_xy[2][16], d_conic[3][16], d_z[16];
        prefetch_sh_rows(grad, i0 + 16, n, 1);
        if (deg > 0) prefetch_sh_rows(g, i0 + 16, n, 0);
        unsigned mask = 0;
        for (int l = 0; l < cnt; l++) {
            int i = i0 + l;
            d_xy[0][l] = d_xy[1][l] = d_conic[0][l] = d_conic[1][l] = d_conic[2][l] = d_z[l] = 0;
            if (r->ntiles[i] == 0) continue;
            mask |= 1u << l;
            const splat_rec *rc = &r->rec[i];
            double acc[SPLAT_GRAD_STRIDE];
            sum_slots(r->slots + (size_t)SPLAT_GRAD_STRIDE * rc->slot_base, r->ntiles[i], acc);
            d_xy[0][l] = (float)acc[0]; d_xy[1][l] = (float)acc[1];
            d_conic[0][l] = (float)acc[2]; d_conic[1][l] = (float)acc[3]; d_conic[2][l] = (float)acc[4];
            d_z[l] = (float)acc[9];
            float d_rgb3[3] = { (float)acc[6], (float)acc[7], (float)acc[8] };
            /* opacity = sigmoid(logit) */
            grad->opacity[i] += (float)acc[5] * rc->o * (1.0f - rc->o);
            float dir[3], d_dir[3] = { 0, 0, 0 };
            vec3_sub(dir, g->means + 3*i, C);
            int cl[3] = { r->clamp[i] & 1, (r->clamp[i] >> 1) & 1, (r->clamp[i] >> 2) & 1 };
            splat_sh_backward(deg, splat_gaussians_sh(g, (size_t)i), dir, cl, d_rgb3, splat_gaussians_sh(grad, (size_t)i), d_dir);
            vec3_add(grad->means + 3*i, grad->means + 3*i, d_dir);
            if (viewspace_grad_norm) {
                /* In NDC units (x pixels * 2/W) like 3DGS, so its 2e-4 densification threshold applies. */
                float gx = d_xy[0][l] * half_w, gy = d_xy[1][l] * half_h;
                viewspace_grad_norm[i] += sqrtf(gx * gx + gy * gy);
            }
        }
        if (!mask) continue;
        if (cnt == 16 && project16 && project16(g->means, g->log_scales, g->quats, i0, cam, lim, d_xy, d_conic, d_z,
                                                  mask, grad->means, grad->log_scales, grad->quats))
            continue;
        for (int l = 0; l < cnt; l++) {
            if (!(mask >> l & 1)) continue;
            int i = i0 + l;
            float dxy[2] = { d_xy[0][l], d_xy[1][l] }, dcon[3] = { d_conic[0][l], d_conic[1][l], d_conic[2][l] };
            splat_project_backward_lim(g->means + 3*i, g->log_scales + 3*i, g->quats + 4*i, cam, lim, dxy, dcon, d_z[l],
                                       grad->means + 3*i, grad->log_scales + 3*i, grad->quats + 4*i);
        }
    }
    return PG_OK;
}
