/* deform.c - deformation network: parameter layout, forward/backward over chunks, regularisers,
 * parameter blobs (see deform.h). */
#include "deform/deform.h"

#include "core/fileutil.h"
#include "core/rng.h"
#include "deform/deform_amx.h"
#include "deform/gemm_amx.h"
#include "deform/mlp.h"
#include "optim/loss_reg.h"

#include <cblas.h>
#include <math.h>
#include <omp.h>
#include <stdlib.h>
#include <string.h>

const int deform_head_offset[DEFORM_HEADS] = { DEFORM_OUT_POS, DEFORM_OUT_SCALE, DEFORM_OUT_ROT, DEFORM_OUT_OPACITY,
                                               DEFORM_OUT_SH };
const int deform_head_dim[DEFORM_HEADS] = { 3, 3, 4, 1, 48 };

#define DEFAULT_CHUNK 256     /* f32 BLAS path */
#define DEFAULT_CHUNK_AMX 128 /* bf16 AMX path: measured ~5% faster than 256, 10% faster than 512 */
#define HEX_PREFETCH_AHEAD 4 /* points */

void deform_config_default(deform_config *c)
{
    memset(c, 0, sizeof(*c));
    c->channels = 16;
    c->res_space = 64;
    c->num_scales = 2;
    c->res_time = 150;
    c->width = 64;
    c->feature_layers = 1;
    c->space_init_lo = 0.1f;
    c->space_init_hi = 0.5f;
    c->head_init_scale = 0.0f;
    c->seed = 1;
    c->bf16 = 1; /* used only where AMX exists; same fit quality in test_deform, ~2x faster */
}

pg_status deform_config_validate(const deform_config *c)
{
    if (c->channels < 1 || c->channels > 64) return pg_fail(PG_ERR_ARG, "deform: channels %d not in [1, 64]", c->channels);
    if (c->num_scales < 1 || c->num_scales > HEX_MAX_SCALES)
        return pg_fail(PG_ERR_ARG, "deform: num_scales %d not in [1, %d]", c->num_scales, HEX_MAX_SCALES);
    if (c->res_space < 2 || (c->res_space << (c->num_scales - 1)) > 4096)
        return pg_fail(PG_ERR_ARG, "deform: res_space %d not in [2, 4096 >> (scales-1)]", c->res_space);
    if (c->res_time < 2 || c->res_time > 100000) return pg_fail(PG_ERR_ARG, "deform: res_time %d not in [2, 100000]", c->res_time);
    if (c->time_coarsen < 0 || c->time_coarsen > HEX_MAX_TIME_COARSEN)
        return pg_fail(PG_ERR_ARG, "deform: time_coarsen %d not in [0, %d]", c->time_coarsen, HEX_MAX_TIME_COARSEN);
    if (c->width < 1 || c->width > 4096) return pg_fail(PG_ERR_ARG, "deform: width %d not in [1, 4096]", c->width);
    if (c->feature_layers < 1 || c->feature_layers > DEFORM_MAX_FEATURE_LAYERS)
        return pg_fail(PG_ERR_ARG, "deform: feature_layers %d not in [1, %d]", c->feature_layers, DEFORM_MAX_FEATURE_LAYERS);
    if (c->head_width < 0 || c->head_width > 4096)
        return pg_fail(PG_ERR_ARG, "deform: head_width %d not in [1, 4096] (0 = width)", c->head_width);
    if (!(c->space_init_lo <= c->space_init_hi)) return pg_fail(PG_ERR_ARG, "deform: space init range is empty");
    return PG_OK;
}

/* ---------------------------------------------------------------------------------------------- */
/* network                                                                                         */

/* 64-byte aligned allocation (freed with free): with C = 16 one texel is exactly one cache line, so
 * aligned planes halve the lines a bilinear gather/scatter touches. */
static float *alloc_floats(size_t n, int zero, const char *what)
{
    size_t bytes = (n * sizeof(float) + 63) & ~(size_t)63;
    float *p = aligned_alloc(64, bytes ? bytes : 64);
    if (!p) {
        pg_fail(PG_ERR_NOMEM, "out of memory allocating %s (%zu bytes)", what, bytes);
        return NULL;
    }
    if (zero) memset(p, 0, bytes);
    return p;
}

/* Plans the parameter layout (planes, then layers, then heads) and returns the total count. */
static size_t plan_layout(deform_network *net)
{
    const deform_config *c = &net->cfg;
    size_t off = 0;
    for (int s = 0; s < c->num_scales; s++)
        for (int p = 0; p < HEX_PLANES; p++) {
            net->plane_off[s][p] = off;
            off += (hex_plane_size(&net->grid, s, p) + 15) & ~(size_t)15; /* keep planes 64-byte aligned */
        }
    net->num_plane_params = off;
    int W = c->width, Wh = deform_head_width(c), in = c->channels * c->num_scales;
    net->num_layers = c->feature_layers + 1;
    for (int l = 0; l < net->num_layers; l++) {
        deform_layer *L = &net->layers[l];
        L->in = l == 0 ? in : W;
        L->out = l == net->num_layers - 1 ? DEFORM_HEADS * Wh : W;
        L->w_off = off;
        off += (size_t)L->in * L->out;
        L->b_off = off;
        off += (size_t)L->out;
    }
    for (int k = 0; k < DEFORM_HEADS; k++) {
        deform_layer *L = &net->heads[k];
        L->in = Wh;
        L->out = deform_head_dim[k];
        L->w_off = off;
        off += (size_t)L->in * L->out;
        L->b_off = off;
        off += (size_t)L->out;
    }
    return (off + 15) & ~(size_t)15; /* so per-thread gradient copies stay 64-byte aligned too */
}

static void bind_planes(deform_network *net)
{
    for (int s = 0; s < net->cfg.num_scales; s++)
        for (int p = 0; p < HEX_PLANES; p++) net->grid.planes[s][p] = net->params + net->plane_off[s][p];
}

/* The config and the grid sizes it implies (what plan_layout needs), shared by the allocation and
 * the parameter count so both always agree. */
static void set_config(deform_network *net, const deform_config *cfg)
{
    net->cfg = *cfg;
    net->grid.C = cfg->channels;
    net->grid.S = cfg->num_scales;
    net->grid.R = cfg->res_space;
    net->grid.T = cfg->res_time;
    net->grid.time_coarsen = cfg->time_coarsen;
}

/* Allocates params/grads for cfg (no initialisation). */
static pg_status network_alloc(deform_network **out, const deform_config *cfg, const float aabb[6])
{
    *out = NULL;
    PG_TRY(deform_config_validate(cfg));
    for (int d = 0; d < 3; d++)
        if (!(aabb[3 + d] > aabb[d]) || !isfinite(aabb[d]) || !isfinite(aabb[3 + d]))
            return pg_fail(PG_ERR_ARG, "deform: AABB axis %d is empty or not finite (%g .. %g)", d, aabb[d], aabb[3 + d]);
    deform_network *net = pg_calloc(1, sizeof(*net), "deform network");
    if (!net) return PG_ERR_NOMEM;
    set_config(net, cfg);
    memcpy(net->grid.aabb, aabb, 6 * sizeof(float));
    net->num_params = plan_layout(net);
    net->params = alloc_floats(net->num_params, 1, "deform parameters");
    net->grads = alloc_floats(net->num_params, 1, "deform gradients");
    if (!net->params || !net->grads) {
        deform_network_destroy(net);
        return PG_ERR_NOMEM;
    }
    bind_planes(net);
    *out = net;
    return PG_OK;
}

/* Xavier-uniform weights times gain, zero biases. */
static void init_layer(deform_network *net, const deform_layer *L, pg_rng *rng, double gain)
{
    double a = gain * sqrt(6.0 / (L->in + L->out));
    float *w = net->params + L->w_off;
    for (size_t i = 0; i < (size_t)L->in * L->out; i++) w[i] = gain == 0 ? 0.0f : (float)pg_rng_range(rng, -a, a);
    memset(net->params + L->b_off, 0, (size_t)L->out * sizeof(float));
}

pg_status deform_network_create(deform_network **out, const deform_config *cfg, const float aabb[6])
{
    deform_network *net;
    PG_TRY(network_alloc(&net, cfg, aabb));
    pg_rng rng;
    pg_rng_seed(&rng, cfg->seed);
    for (int s = 0; s < cfg->num_scales; s++)
        for (int p = 0; p < HEX_PLANES; p++) {
            float *pl = net->grid.planes[s][p];
            size_t n = hex_plane_size(&net->grid, s, p);
            int is_time = hex_plane_axes[p][1] == 3;
            for (size_t i = 0; i < n; i++)
                pl[i] = is_time ? 1.0f : (float)pg_rng_range(&rng, cfg->space_init_lo, cfg->space_init_hi);
        }
    for (int l = 0; l < net->num_layers; l++) init_layer(net, &net->layers[l], &rng, 1.0);
    for (int k = 0; k < DEFORM_HEADS; k++) init_layer(net, &net->heads[k], &rng, cfg->head_init_scale);
    *out = net;
    return PG_OK;
}

void deform_network_destroy(deform_network *net)
{
    if (!net) return;
    free(net->params);
    free(net->grads);
    free(net);
}

size_t deform_config_num_params(const deform_config *cfg)
{
    if (deform_config_validate(cfg)) return 0;
    deform_network *net = pg_calloc(1, sizeof(*net), "deform layout");
    if (!net) return 0;
    set_config(net, cfg);
    size_t n = plan_layout(net);
    free(net);
    return n;
}

/* 10 MB with the defaults, every iteration: split over the threads (memory bandwidth per core is
 * the limit). */
void deform_network_zero_grad(deform_network *net)
{
    const size_t block = (size_t)1 << 16;
    const long nblocks = (long)((net->num_params + block - 1) / block);
    #pragma omp parallel for schedule(static)
    for (long b = 0; b < nblocks; b++) {
        size_t lo = (size_t)b * block, n = net->num_params - lo < block ? net->num_params - lo : block;
        memset(net->grads + lo, 0, n * sizeof(float));
    }
}

/* ---------------------------------------------------------------------------------------------- */
/* workspace                                                                                       */

struct deform_ws {
    int chunk;            /* points per chunk */
    int F, W, Wh, L;      /* features, width, head width, layers with stored outputs (num_layers) */
    size_t act_pp;        /* activation floats per point: F + (L-1)*W + 5Wh */
    long store_points;    /* activations kept for the first store_points points (a whole chunk multiple) */
    float *store;         /* (store_points, act_pp) chunk-blocked */
    int nthreads;
    size_t scratch_floats;
    float *scratch;       /* (nthreads, scratch_floats): acts + backward buffers of one chunk */
    float *tgrads;        /* (nthreads - 1, num_params): gradient buffers of threads 1.. */
    size_t num_params;
    /* the last forward */
    const float *means;
    const int *idx;
    long n;
    float t;
    long *order;          /* (order_cap) processing order: row j of the chunks is point order[j] */
    long *keys;           /* (order_cap) Morton keys of the points */
    float *pos;           /* (order_cap, 3) positions in processing order (gathered once per forward) */
    hex_slice sl;         /* the time planes at t (built per forward, read by its backward) */
    float *slice_buf;     /* storage of sl */
    size_t slice_off;     /* offset of a thread's slice gradient in its scratch */
    long order_cap;
    long *bins;           /* (SORT_BINS + 1) counting-sort histogram */
    /* bf16 AMX path (deform_amx.h): the MLP there, the HexPlane and ordering here */
    int amx;
    deform_amx *amxp;
};

int deform_ws_uses_amx(const deform_ws *ws) { return ws->amx; }
int deform_ws_chunk(const deform_ws *ws) { return ws->chunk; }

static size_t ws_scratch_floats(const deform_ws *ws)
{
    size_t c = (size_t)ws->chunk;
    size_t n;
    if (ws->amx) { /* features, d_out rows, head outputs; the activations live in the AMX module */
        n = c * ws->F + 2 * c * DEFORM_OUT_DIM;
    } else { /* acts + d_out copy + dA (c, 5Wh) + two ping-pong (c, max(W, F)) */
        size_t big = (size_t)DEFORM_HEADS * ws->Wh;
        size_t mx = (size_t)(ws->W > ws->F ? ws->W : ws->F);
        n = c * ws->act_pp + c * DEFORM_OUT_DIM + c * big + 2 * c * mx;
    }
    return (n + 15) & ~(size_t)15;
}

/* Grows the per-thread buffers to the current OpenMP thread count. */
static pg_status ws_ensure_threads(deform_ws *ws)
{
    int nt = omp_get_max_threads();
    if (nt <= ws->nthreads) return PG_OK;
    float *s = alloc_floats((size_t)nt * ws->scratch_floats, 0, "deform thread scratch");
    float *g = nt > 1 ? alloc_floats((size_t)(nt - 1) * ws->num_params, 0, "deform thread gradients") : NULL;
    if (!s || (nt > 1 && !g) || (ws->amxp && deform_amx_ensure_threads(ws->amxp, nt))) {
        free(s);
        free(g);
        return PG_ERR_NOMEM;
    }
    free(ws->scratch);
    free(ws->tgrads);
    ws->scratch = s;
    ws->tgrads = g;
    ws->nthreads = nt;
    return PG_OK;
}

pg_status deform_ws_create_chunked(deform_ws **out, const deform_network *net, long max_points, int chunk)
{
    *out = NULL;
    if (max_points < 0) return pg_fail(PG_ERR_ARG, "deform_ws_create: max_points %ld < 0", max_points);
    if (chunk <= 0) chunk = net->cfg.bf16 && gemm_bf16_backend() != GEMM_BF16_NONE ? DEFAULT_CHUNK_AMX : DEFAULT_CHUNK;
    deform_ws *ws = pg_calloc(1, sizeof(*ws), "deform workspace");
    if (!ws) return PG_ERR_NOMEM;
    ws->chunk = chunk;
    ws->F = net->cfg.channels * net->cfg.num_scales;
    ws->W = net->cfg.width;
    ws->Wh = deform_head_width(&net->cfg);
    ws->L = net->num_layers;
    ws->act_pp = (size_t)ws->F + (size_t)(ws->L - 1) * ws->W + (size_t)DEFORM_HEADS * ws->Wh;
    ws->num_params = net->num_params;
    ws->amx = net->cfg.bf16 && gemm_bf16_backend() != GEMM_BF16_NONE;
    ws->scratch_floats = ws_scratch_floats(ws);
    ws->slice_off = ws->scratch_floats;
    ws->scratch_floats += (hex_slice_size(&net->grid) + 15) & ~(size_t)15;
    if (!(ws->slice_buf = alloc_floats(hex_slice_size(&net->grid), 0, "deform time slice"))) {
        deform_ws_destroy(ws);
        return PG_ERR_NOMEM;
    }
    ws->store_points = ws->amx ? 0 : (max_points + chunk - 1) / chunk * (long)chunk;
    if (ws->amx) {
        pg_status st = deform_amx_create(&ws->amxp, net, chunk);
        if (st) {
            deform_ws_destroy(ws);
            return st;
        }
    } else {
        size_t store_floats;
        if (pg_size_mul((size_t)ws->store_points, ws->act_pp, &store_floats)) {
            deform_ws_destroy(ws);
            return pg_fail(PG_ERR_SIZE, "deform_ws_create: %ld points overflow", max_points);
        }
        if (store_floats && !(ws->store = alloc_floats(store_floats, 0, "deform stored activations"))) {
            deform_ws_destroy(ws);
            return PG_ERR_NOMEM;
        }
    }
    pg_status st = ws_ensure_threads(ws);
    if (st) {
        deform_ws_destroy(ws);
        return st;
    }
    /* The network parallelises over chunks; nested BLAS threads would only oversubscribe. */
    openblas_set_num_threads(1);
    *out = ws;
    return PG_OK;
}

pg_status deform_ws_create(deform_ws **ws, const deform_network *net, long max_points)
{
    return deform_ws_create_chunked(ws, net, max_points, 0);
}

void deform_ws_destroy(deform_ws *ws)
{
    if (!ws) return;
    free(ws->store);
    free(ws->scratch);
    free(ws->tgrads);
    free(ws->order);
    free(ws->keys);
    free(ws->pos);
    free(ws->slice_buf);
    free(ws->bins);
    deform_amx_destroy(ws->amxp);
    free(ws);
}

/* ---------------------------------------------------------------------------------------------- */
/* forward / backward                                                                              */

/* Row of means (and d_means) of the point processed at position j. */
static inline long point_row(const deform_ws *ws, long j)
{
    long i = ws->order[j];
    return ws->idx ? (long)ws->idx[i] : i;
}

#define SORT_BITS 5 /* per axis: 32^3 Morton cells */
#define SORT_BINS (1L << (3 * SORT_BITS))

/* Orders the points along a Morton curve of 32^3 cells over the AABB (stable counting sort).
 * Neighbouring points then touch neighbouring plane texels, which roughly halves the time of the
 * memory-bound HexPlane gather/scatter compared with a random order. O(n + 32768). */
static pg_status ws_sort_points(deform_ws *ws, const hex_grid *g, long n)
{
    if (n > ws->order_cap) {
        long *o = malloc((size_t)n * sizeof(long)), *k = malloc((size_t)n * sizeof(long));
        float *ps = malloc((size_t)n * 3 * sizeof(float));
        if (!o || !k || !ps) {
            free(o);
            free(k);
            free(ps);
            return pg_fail(PG_ERR_NOMEM, "deform: no memory to order %ld points", n);
        }
        free(ws->order);
        free(ws->keys);
        free(ws->pos);
        ws->order = o;
        ws->keys = k;
        ws->pos = ps;
        ws->order_cap = n;
    }
    if (!ws->bins && !(ws->bins = malloc((SORT_BINS + 1) * sizeof(long))))
        return pg_fail(PG_ERR_NOMEM, "deform: no memory for the point sort");
    long *keys = ws->keys;
    float inv[3];
    for (int d = 0; d < 3; d++) inv[d] = (float)(1 << SORT_BITS) / (g->aabb[3 + d] - g->aabb[d]);
    #pragma omp parallel for schedule(static)
    for (long i = 0; i < n; i++) {
        const float *p = ws->means + 3 * (ws->idx ? (long)ws->idx[i] : i);
        long key = 0;
        for (int d = 0; d < 3; d++) {
            float u = (p[d] - g->aabb[d]) * inv[d];
            int c = u > 0.0f ? (int)fminf(u, (float)((1 << SORT_BITS) - 1)) : 0; /* NaN -> 0 */
            for (int b = 0; b < SORT_BITS; b++) key |= (long)((c >> b) & 1) << (3 * b + d);
        }
        keys[i] = key;
    }
    memset(ws->bins, 0, (SORT_BINS + 1) * sizeof(long));
    for (long i = 0; i < n; i++) ws->bins[keys[i] + 1]++;
    for (long b = 0; b < SORT_BINS; b++) ws->bins[b + 1] += ws->bins[b];
    for (long i = 0; i < n; i++) ws->order[ws->bins[keys[i]]++] = i;
    /* one gather pass (independent loads overlap) instead of a dependent random load per point in
     * every HexPlane pass */
    #pragma omp parallel for schedule(static)
    for (long j = 0; j < n; j++) memcpy(ws->pos + 3 * j, ws->means + 3 * point_row(ws, j), 3 * sizeof(float));
    return PG_OK;
}

/* f32 path: activations of chunk k, stored or this thread's scratch. Layout (m rows each): feat
 * (m, F), layer outputs 0..L-2 (m, W), last layer (m, 5Wh). */
static float *chunk_acts(deform_ws *ws, long k, int tid, int *stored)
{
    long start = k * ws->chunk;
    *stored = start < ws->store_points;
    if (*stored) return ws->store + (size_t)start * ws->act_pp;
    return ws->scratch + (size_t)tid * ws->scratch_floats;
}

/* f32 path: pointer to the output of layer l (-1: the features) inside a chunk's activations. */
static float *layer_out(const deform_ws *ws, float *acts, int l, int m)
{
    if (l < 0) return acts;
    return acts + (size_t)m * ws->F + (size_t)l * m * ws->W;
}

/* HexPlane features feat (m, F) of the chunk's points (prefetching texels a few points ahead). */
static void chunk_features(const deform_network *net, const deform_ws *ws, float *feat, long start, int m)
{
    const int F = ws->F;
    hex_point ring[HEX_PREFETCH_AHEAD + 1]; /* axes of points i .. i+AHEAD */
    for (int i = 0; i < m && i < HEX_PREFETCH_AHEAD; i++)
        hex_point_setup(&ring[i], &net->grid, ws->pos + 3 * (start + i));
    for (int i = 0; i < m; i++) {
        int ahead = i + HEX_PREFETCH_AHEAD;
        if (ahead < m) {
            hex_point *hp = &ring[ahead % (HEX_PREFETCH_AHEAD + 1)];
            hex_point_setup(hp, &net->grid, ws->pos + 3 * (start + ahead));
            hex_prefetch_point(&net->grid, NULL, hp);
        }
        hex_sample_forward_point(feat + (size_t)i * F, &net->grid, &ws->sl, &ring[i % (HEX_PREFETCH_AHEAD + 1)]);
    }
}

/* Forward of chunk k up to the heads' hidden layer (AMX: also the heads when y != NULL). */
static void chunk_forward(const deform_network *net, deform_ws *ws, long k, int m, int tid, float *y)
{
    long start = k * ws->chunk;
    float *scr = ws->scratch + (size_t)tid * ws->scratch_floats;
    if (ws->amx) {
        chunk_features(net, ws, scr, start, m);
        deform_amx_chunk_forward(ws->amxp, tid, k, scr, m, y);
        return;
    }
    int stored;
    float *acts = chunk_acts(ws, k, tid, &stored);
    chunk_features(net, ws, acts, start, m);
    for (int l = 0; l < net->num_layers; l++) {
        const deform_layer *L = &net->layers[l];
        mlp_linear_forward(layer_out(ws, acts, l, m), L->out, layer_out(ws, acts, l - 1, m), L->in,
                           net->params + L->w_off, net->params + L->b_off, m, L->in, L->out, 1);
    }
    if (!y) return;
    const float *a = layer_out(ws, acts, net->num_layers - 1, m);
    for (int h = 0; h < DEFORM_HEADS; h++) {
        const deform_layer *L = &net->heads[h];
        mlp_linear_forward(y + deform_head_offset[h], DEFORM_OUT_DIM, a + (size_t)h * ws->Wh, DEFORM_HEADS * ws->Wh,
                           net->params + L->w_off, net->params + L->b_off, m, L->in, L->out, 0);
    }
}

pg_status deform_network_forward(deform_network *net, deform_ws *ws, const float *means, const int *idx, long n,
                                 float t, float *out)
{
    if (n < 0 || !(t >= 0.0f && t <= 1.0f)) return pg_fail(PG_ERR_ARG, "deform_network_forward: n=%ld t=%g", n, t);
    PG_TRY(ws_ensure_threads(ws));
    ws->means = means;
    ws->idx = idx;
    ws->n = n;
    ws->t = t;
    PG_TRY(ws_sort_points(ws, &net->grid, n));
    hex_slice_layout(&ws->sl, ws->slice_buf, &net->grid, t);
    hex_slice_forward(&ws->sl, &net->grid);
    long nchunks = (n + ws->chunk - 1) / ws->chunk;
    if (ws->amx) {
        PG_TRY(deform_amx_prepare(ws->amxp, nchunks));
        deform_amx_pack_forward(ws->amxp, net); /* weights change every optimiser step */
    }
    #pragma omp parallel for schedule(static)
    for (long k = 0; k < nchunks; k++) {
        int tid = omp_get_thread_num();
        long start = k * ws->chunk;
        int m = (int)(n - start < ws->chunk ? n - start : ws->chunk);
        float *scr = ws->scratch + (size_t)tid * ws->scratch_floats;
        float *y = ws->amx ? scr + (size_t)ws->chunk * (ws->F + DEFORM_OUT_DIM) : scr + (size_t)ws->chunk * ws->act_pp;
        chunk_forward(net, ws, k, m, tid, y);
        for (int i = 0; i < m; i++)
            memcpy(out + (size_t)ws->order[start + i] * DEFORM_OUT_DIM, y + (size_t)i * DEFORM_OUT_DIM, DEFORM_OUT_DIM * sizeof(float));
    }
    return PG_OK;
}

/* f32 path: backward of chunk k's MLP; dy (m, 59) is overwritten; returns d features (m, F). */
static const float *chunk_backward_f32(const deform_network *net, deform_ws *ws, long k, int m, int tid, float *dy,
                                       float *grads)
{
    const int W = ws->W, Wh = ws->Wh, W5 = DEFORM_HEADS * Wh, F = ws->F;
    const size_t c = (size_t)ws->chunk, mx = (size_t)(W > F ? W : F);
    int stored;
    float *acts = chunk_acts(ws, k, tid, &stored);
    if (!stored) chunk_forward(net, ws, k, m, tid, NULL);
    float *dA = dy + c * DEFORM_OUT_DIM; /* (c, 5W) */
    float *dB = dA + c * W5, *dC = dB + c * mx;
    const float *a = layer_out(ws, acts, net->num_layers - 1, m);
    for (int h = 0; h < DEFORM_HEADS; h++) {
        const deform_layer *L = &net->heads[h];
        mlp_linear_backward(dA + (size_t)h * Wh, W5, grads + L->w_off, grads + L->b_off, dy + deform_head_offset[h],
                            DEFORM_OUT_DIM, NULL, 0, a + (size_t)h * Wh, W5, net->params + L->w_off, m, L->in, L->out, 0);
    }
    float *dcur = dA, *dnext = dB;
    for (int l = net->num_layers - 1; l >= 0; l--) {
        const deform_layer *L = &net->layers[l];
        mlp_linear_backward(dnext, L->in, grads + L->w_off, grads + L->b_off, dcur, L->out, layer_out(ws, acts, l, m),
                            L->out, layer_out(ws, acts, l - 1, m), L->in, net->params + L->w_off, m, L->in, L->out, 1);
        dcur = dnext;
        dnext = dnext == dB ? dC : dB;
    }
    return dcur;
}

#define REDUCE_BLOCK 1024 /* floats of the thread-gradient reduction per loop trip */

pg_status deform_network_backward(deform_network *net, deform_ws *ws, const float *d_out, float *d_means)
{
    const long n = ws->n;
    long nchunks = (n + ws->chunk - 1) / ws->chunk;
    int nt = omp_get_max_threads();
    if (nt > ws->nthreads) return pg_fail(PG_ERR_ARG, "deform_network_backward: more threads than the workspace was sized for at the forward");
    int used_threads = 1;
    /* Parameter ranges a backward can write: spatial planes, the two time rows at t of each time
     * plane (60% of the parameters are time planes; this skips zeroing/reducing the rest of them
     * in the per-thread buffers), and the MLP. */
    size_t ranges[HEX_MAX_SCALES * HEX_PLANES + 1][2];
    int nranges = 0;
    for (int s = 0; s < net->cfg.num_scales; s++)
        for (int p = 0; p < HEX_PLANES; p++) {
            size_t off = net->plane_off[s][p], len = hex_plane_size(&net->grid, s, p);
            if (hex_plane_axes[p][1] == 3) {
                size_t row = len / (size_t)hex_time_res(&net->grid, s);
                off += (size_t)ws->sl.row[s] * row; /* the forward's slice: the rows it read at t */
                len = 2 * row;
            }
            ranges[nranges][0] = off;
            ranges[nranges][1] = len;
            nranges++;
        }
    ranges[nranges][0] = net->num_plane_params;
    ranges[nranges][1] = net->num_params - net->num_plane_params;
    nranges++;
    if (ws->amx) deform_amx_pack_backward(ws->amxp, net);
    #pragma omp parallel
    {
        int tid = omp_get_thread_num();
        #pragma omp single
        used_threads = omp_get_num_threads();
        float *grads = tid == 0 ? net->grads : ws->tgrads + (size_t)(tid - 1) * ws->num_params;
        if (tid > 0)
            for (int r = 0; r < nranges; r++) memset(grads + ranges[r][0], 0, ranges[r][1] * sizeof(float));
        float *dplanes[HEX_MAX_SCALES][HEX_PLANES];
        for (int s = 0; s < net->cfg.num_scales; s++)
            for (int p = 0; p < HEX_PLANES; p++) dplanes[s][p] = grads + net->plane_off[s][p];
        float *scr = ws->scratch + (size_t)tid * ws->scratch_floats;
        /* d_out rows of the chunk: after the activations (f32) or the features (AMX) */
        float *dy = ws->amx ? scr + (size_t)ws->chunk * ws->F : scr + (size_t)ws->chunk * ws->act_pp;
        if (ws->amx) deform_amx_backward_begin(ws->amxp, tid);
        hex_slice dsl; /* this thread's time-plane gradient, spread onto the two time rows at the end */
        hex_slice_layout(&dsl, scr + ws->slice_off, &net->grid, ws->t);
        memset(scr + ws->slice_off, 0, hex_slice_size(&net->grid) * sizeof(float));
        #pragma omp for schedule(static)
        for (long k = 0; k < nchunks; k++) {
            long start = k * ws->chunk;
            int m = (int)(n - start < ws->chunk ? n - start : ws->chunk);
            for (int i = 0; i < m; i++)
                memcpy(dy + (size_t)i * DEFORM_OUT_DIM, d_out + (size_t)ws->order[start + i] * DEFORM_OUT_DIM,
                       DEFORM_OUT_DIM * sizeof(float));
            const float *dfeat;
            int ldf = ws->F;
            if (ws->amx) {
                deform_amx_chunk_forward(ws->amxp, tid, k, NULL, m, NULL);
                dfeat = deform_amx_chunk_backward(ws->amxp, tid, k, dy, m, &ldf);
            } else {
                dfeat = chunk_backward_f32(net, ws, k, m, tid, dy, grads);
            }
            hex_point ring[HEX_PREFETCH_AHEAD + 1];
            for (int i = 0; i < m && i < HEX_PREFETCH_AHEAD; i++)
                hex_point_setup(&ring[i], &net->grid, ws->pos + 3 * (start + i));
            for (int i = 0; i < m; i++) {
                int ahead = i + HEX_PREFETCH_AHEAD;
                if (ahead < m) {
                    long gn = point_row(ws, start + ahead);
                    hex_point *hp = &ring[ahead % (HEX_PREFETCH_AHEAD + 1)];
                    hex_point_setup(hp, &net->grid, ws->pos + 3 * (start + ahead));
                    hex_prefetch_point(&net->grid, dplanes, hp);
                    if (d_means) __builtin_prefetch(d_means + 3 * gn, 1, 3);
                }
                long gi = point_row(ws, start + i);
                hex_sample_backward_point(dplanes, &dsl, d_means ? d_means + 3 * gi : NULL, dfeat + (size_t)i * ldf,
                                          &net->grid, &ws->sl, &ring[i % (HEX_PREFETCH_AHEAD + 1)]);
            }
        }
        if (ws->amx) deform_amx_backward_end(ws->amxp, net, tid, grads);
        hex_slice_backward(dplanes, &dsl, &net->grid);
        /* Fixed-order reduction of the other threads' buffers over the written ranges, inside the
         * same parallel region (a fork/join per range is slow when the cores are busy). */
        if (used_threads > 1) {
            #pragma omp barrier
            const size_t P = ws->num_params;
            for (int r = 0; r < nranges; r++) {
                size_t lo = ranges[r][0], hi = lo + ranges[r][1];
                /* threads outermost: the same sums in the same order, and an inner loop that vectorises */
                #pragma omp for schedule(static) nowait
                for (size_t b = lo; b < hi; b += REDUCE_BLOCK) {
                    const size_t e = hi - b < REDUCE_BLOCK ? hi : b + REDUCE_BLOCK;
                    for (int th = 1; th < used_threads; th++) {
                        const float *src = ws->tgrads + (size_t)(th - 1) * P;
                        #pragma omp simd
                        for (size_t i = b; i < e; i++) net->grads[i] += src[i];
                    }
                }
            }
        }
    }
    return PG_OK;
}

/* ---------------------------------------------------------------------------------------------- */
/* time refinement                                                                                 */

void deform_params_resample_time(const deform_network *from, const float *src, const deform_network *to, float *dst)
{
    const int C = from->cfg.channels;
    for (int s = 0; s < from->cfg.num_scales; s++)
        for (int p = 0; p < HEX_PLANES; p++) {
            const float *a = src + from->plane_off[s][p];
            float *b = dst + to->plane_off[s][p];
            if (hex_plane_axes[p][1] != 3) { /* spatial: same size */
                memcpy(b, a, hex_plane_size(&from->grid, s, p) * sizeof(float));
                continue;
            }
            const int cols = hex_axis_res(&from->grid, s, hex_plane_axes[p][0]);
            const int tf = hex_time_res(&from->grid, s), tt = hex_time_res(&to->grid, s);
            const size_t row = (size_t)cols * C;
            for (int r = 0; r < tt; r++) {
                double g = (double)r * (tf - 1) / (tt - 1);
                int i0 = (int)g < tf - 1 ? (int)g : tf - 2;
                float w = (float)(g - i0);
                const float *r0 = a + (size_t)i0 * row, *r1 = r0 + row;
                for (size_t k = 0; k < row; k++) b[(size_t)r * row + k] = (1.0f - w) * r0[k] + w * r1[k];
            }
        }
    memcpy(dst + to->num_plane_params, src + from->num_plane_params,
           (from->num_params - from->num_plane_params) * sizeof(float));
}

/* ---------------------------------------------------------------------------------------------- */
/* regularisers                                                                                    */

/* One parallel region over the planes (each plane's regularisers then run serially inside it):
 * the per-function row parallelism would fork/join ~50 times per call, which is slow on busy
 * cores. Per-plane totals are summed in plane order, so the result is thread-count independent. */
float deform_network_regularize(deform_network *net, float w_tv, float w_time, float w_l1)
{
    const int np = net->cfg.num_scales * HEX_PLANES;
    double part[HEX_MAX_SCALES * HEX_PLANES];
    #pragma omp parallel for schedule(dynamic, 1)
    for (int q = np - 1; q >= 0; q--) { /* finest scale first: the biggest planes start early */
        int s = q / HEX_PLANES, p = q % HEX_PLANES;
        int Wp = hex_axis_res(&net->grid, s, hex_plane_axes[p][0]);
        int Hp = hex_axis_res(&net->grid, s, hex_plane_axes[p][1]);
        int C = net->cfg.channels;
        const float *pl = net->grid.planes[s][p];
        float *g = net->grads + net->plane_off[s][p];
        double t = 0;
        if (hex_plane_axes[p][1] != 3) {
            if (w_tv != 0) {
                t += (double)w_tv * optim_plane_tv_forward(pl, Hp, Wp, C);
                optim_plane_tv_backward(g, w_tv, pl, Hp, Wp, C);
            }
        } else {
            if (w_time != 0) {
                t += (double)w_time * optim_plane_time_smooth_forward(pl, Hp, Wp, C);
                optim_plane_time_smooth_backward(g, w_time, pl, Hp, Wp, C);
            }
            if (w_l1 != 0) {
                t += (double)w_l1 * optim_plane_l1_one_forward(pl, Hp, Wp, C);
                optim_plane_l1_one_backward(g, w_l1, pl, Hp, Wp, C);
            }
        }
        part[q] = t;
    }
    double total = 0;
    for (int q = 0; q < np; q++) total += part[q];
    return (float)total;
}

/* ---------------------------------------------------------------------------------------------- */
/* blobs                                                                                           */

/* magic, i32 channels, res_space, num_scales, res_time, width, feature_layers, head_width, time_coarsen,
 * f32 aabb[6], u64 parameter count. Older versions (1: no head_width, 2: no time_coarsen) are refused. */
#define BLOB_MAGIC "PGDEFRM3"
#define BLOB_MAGIC_OLD "PGDEFRM"
#define BLOB_INTS 8
#define BLOB_AABB (8 + 4 * BLOB_INTS)
#define BLOB_COUNT (BLOB_AABB + 4 * 6)
#define BLOB_HEADER (BLOB_COUNT + 8)

size_t deform_network_blob_size(const deform_network *net) { return BLOB_HEADER + net->num_params * sizeof(float); }

pg_status deform_network_write_blob(const deform_network *net, void *buf, size_t size)
{
    if (size < deform_network_blob_size(net))
        return pg_fail(PG_ERR_SIZE, "deform_network_write_blob: buffer of %zu bytes is too small", size);
    unsigned char *p = buf;
    const deform_config *c = &net->cfg;
    int32_t h[BLOB_INTS] = { c->channels, c->res_space, c->num_scales, c->res_time, c->width, c->feature_layers,
                             c->head_width, c->time_coarsen };
    uint64_t np = net->num_params;
    memcpy(p, BLOB_MAGIC, 8);
    memcpy(p + 8, h, sizeof(h));
    memcpy(p + BLOB_AABB, net->grid.aabb, 6 * sizeof(float));
    memcpy(p + BLOB_COUNT, &np, 8);
    memcpy(p + BLOB_HEADER, net->params, net->num_params * sizeof(float));
    return PG_OK;
}

pg_status deform_network_read_blob(deform_network **out, const void *buf, size_t size, const char *what)
{
    *out = NULL;
    const unsigned char *p = buf;
    if (size >= 8 && memcmp(p, BLOB_MAGIC_OLD, 7) == 0 && memcmp(p, BLOB_MAGIC, 8) != 0)
        return pg_fail(PG_ERR_FORMAT, "%s: deformation network blob format %.8s, this build reads only %s", what,
                       (const char *)p, BLOB_MAGIC);
    if (size < BLOB_HEADER || memcmp(p, BLOB_MAGIC, 8) != 0)
        return pg_fail(PG_ERR_FORMAT, "%s: not a deformation network blob", what);
    int32_t h[BLOB_INTS];
    float aabb[6];
    uint64_t np;
    memcpy(h, p + 8, sizeof(h));
    memcpy(aabb, p + BLOB_AABB, sizeof(aabb));
    memcpy(&np, p + BLOB_COUNT, 8);
    deform_config c;
    deform_config_default(&c);
    c.channels = h[0];
    c.res_space = h[1];
    c.num_scales = h[2];
    c.res_time = h[3];
    c.width = h[4];
    c.feature_layers = h[5];
    c.head_width = h[6];
    c.time_coarsen = h[7];
    pg_status st = deform_config_validate(&c);
    if (st) return pg_fail_context(PG_ERR_FORMAT, "%s: ", what);
    deform_network *net;
    st = network_alloc(&net, &c, aabb);
    if (st) return st == PG_ERR_NOMEM ? st : pg_fail_context(PG_ERR_FORMAT, "%s: ", what);
    size_t need = deform_network_blob_size(net);
    if (np != net->num_params || size != need) {
        deform_network_destroy(net);
        return pg_fail(PG_ERR_FORMAT, "%s: blob holds %llu parameters in %zu bytes, config needs %zu", what,
                       (unsigned long long)np, size, need);
    }
    memcpy(net->params, p + BLOB_HEADER, net->num_params * sizeof(float));
    for (size_t i = 0; i < net->num_params; i++)
        if (!isfinite(net->params[i])) {
            deform_network_destroy(net);
            return pg_fail(PG_ERR_FORMAT, "%s: parameter %zu is not finite", what, i);
        }
    *out = net;
    return PG_OK;
}

pg_status deform_network_save(const deform_network *net, const char *path)
{
    size_t n = deform_network_blob_size(net);
    void *buf = pg_malloc(n, "deform blob");
    if (!buf) return PG_ERR_NOMEM;
    pg_status st = deform_network_write_blob(net, buf, n);
    if (!st) st = pg_write_file_atomic(path, buf, n);
    free(buf);
    return st;
}

pg_status deform_network_load(deform_network **net, const char *path)
{
    char *data;
    size_t size;
    PG_TRY(pg_read_file(path, (size_t)1 << 32, &data, &size));
    pg_status st = deform_network_read_blob(net, data, size, path);
    free(data);
    return st;
}
