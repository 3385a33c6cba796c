/* deform.h - the 4D deformation network: HexPlane features + MLP + five heads (4DGaussians style).
 *
 * For a canonical Gaussian centre x and a time t in [0,1] the network predicts
 *     out (59) = [ dpos(3) | dlogscale(3) | dquat(4) | dopacity(1) | dSH(48) ]
 * Pipeline per point (F = S*C features, W = width, Wh = head width, default W):
 *     feat (F)  = HexPlane(x, t)                       (hexplane.h)
 *     h    (W)  = [Linear + ReLU] x feature_layers      (first layer F -> W, then W -> W)
 *     a   (5Wh) = ReLU(Linear_W->5Wh(h))                (the five heads' first layers, fused;
 *                                                        h is already ReLU'd = the heads' first ReLU)
 *     out_k     = Linear_Wh->d_k(a[kWh:(k+1)Wh])        (head k's last layer, init 0 => identity)
 *
 * Parameters live in ONE flat array (net->params, net->num_params floats) with a matching gradient
 * array (net->grads), so Adam runs over flat arrays. The planes come first:
 *     params[0, num_plane_params)            HexPlane planes (use the grid learning rate)
 *     params[num_plane_params, num_params)   MLP weights and biases (use the network learning rate)
 * (planes and the total are padded to 16 floats for alignment; padding stays 0 with 0 gradient.)
 *
 *   deform_config cfg;
 *   deform_config_default(&cfg);
 *   cfg.res_time = num_frames / 2;
 *   deform_network *net;  deform_ws *ws;
 *   PG_TRY(deform_network_create(&net, &cfg, aabb));        // aabb: min xyz, max xyz
 *   PG_TRY(deform_ws_create(&ws, net, max_points));          // activations kept for max_points
 *   deform_network_zero_grad(net);
 *   deform_network_forward(net, ws, means, idx, n, t, out);   // out (n, 59); idx may be NULL
 *   ... d_out (n, 59) from the rasterizer backward ...
 *   deform_network_backward(net, ws, d_out, d_means);         // += into net->grads and d_means
 *   float reg = deform_network_regularize(net, 2e-4f, 1e-3f, 1e-4f);   // += into net->grads
 *   deform_ws_destroy(ws);  deform_network_destroy(net);
 *
 * Threads: points are split into chunks; each OpenMP thread runs whole chunks (hexplane -> MLP ->
 * heads) with single-threaded BLAS calls (deform_ws_create sets OpenBLAS to 1 thread). Parameter
 * gradients go to per-thread buffers summed in thread order: results are identical for the same
 * inputs and thread count. Points are processed internally in Morton order (plane locality);
 * outputs and gradients come back in the caller's order. By default the Linear layers run in bf16
 * where the CPU can (cfg.bf16): on AMX tiles, else AVX512-BF16 (gemm_amx.h, chosen at run time);
 * the first layer and the heads' forward stay f32 there (outputs within 0.3% of the f32 path).
 */
#ifndef PG_DEFORM_DEFORM_H
#define PG_DEFORM_DEFORM_H

#include <stddef.h>
#include <stdint.h>

#include "core/status.h"
#include "deform/hexplane.h"

#define DEFORM_OUT_POS 0
#define DEFORM_OUT_SCALE 3
#define DEFORM_OUT_ROT 6
#define DEFORM_OUT_OPACITY 10
#define DEFORM_OUT_SH 11
#define DEFORM_OUT_DIM 59
#define DEFORM_HEADS 5
#define DEFORM_MAX_FEATURE_LAYERS 8

/* Output offsets and sizes of the five heads, in the order above. */
extern const int deform_head_offset[DEFORM_HEADS];
extern const int deform_head_dim[DEFORM_HEADS];

typedef struct {
    int channels;          /* C, channels per plane (default 16, at most 64) */
    int res_space;         /* R, spatial resolution of the coarsest scale (default 64) */
    int num_scales;        /* S, spatial scales R, 2R, ... (default 2, at most 4) */
    int res_time;          /* T, time resolution of the finest scale (default 150; >= 2) */
    int time_coarsen;      /* k (default 0, at most HEX_MAX_TIME_COARSEN): scale s has ((T-1) >> (k (S-1-s))) + 1 time rows: a long
                            * clip's coarse rows are each fitted by many frames (issue 24, docs/deform.md) */
    int width;             /* W, MLP width (default 64: measured as good as 128, docs/deform.md) */
    int feature_layers;    /* Linear+ReLU layers before the heads (default 1) */
    int head_width;        /* Wh, hidden width of each head (0, the default: = width). Any value in
                            * [1, 4096]: the bf16 path pads 5*Wh to a multiple of 32 itself (as it
                            * does 5W), so multiples of 32 waste no padding there. */
    float space_init_lo;   /* spatial planes ~ U(lo, hi) (default 0.1, 0.5); time planes = 1 */
    float space_init_hi;
    float head_init_scale; /* heads' last layers = scale * Xavier-uniform (default 0: identity) */
    uint64_t seed;         /* initialisation seed (default 1) */
    int bf16;              /* 1 (default): Linear layers as bf16 GEMMs on AMX or AVX512-BF16 when
                            * the CPU has one (~0.4% relative rounding in products, f32 sums;
                            * the first layer, the heads' forward and everything else f32);
                            * 0: f32 OpenBLAS everywhere (what the FD tests check). Not stored in
                            * blobs (a runtime choice). */
} deform_config;

typedef struct {
    int in, out;
    size_t w_off, b_off;   /* offsets of w (out, in) and b (out) in params / grads */
} deform_layer;

typedef struct {
    deform_config cfg;
    hex_grid grid;                     /* planes point into params */
    size_t num_params;
    size_t num_plane_params;           /* planes = params[0, num_plane_params) */
    float *params;                     /* (num_params) */
    float *grads;                      /* (num_params), += by backward / regularize */
    int num_layers;                    /* feature_layers + 1 (the fused head first layers, W -> 5Wh) */
    deform_layer layers[DEFORM_MAX_FEATURE_LAYERS + 1];
    deform_layer heads[DEFORM_HEADS];  /* last layers Wh -> d_k */
    size_t plane_off[HEX_MAX_SCALES][HEX_PLANES];
} deform_network;

typedef struct deform_ws deform_ws;

void deform_config_default(deform_config *cfg);
/* Wh: cfg->head_width, or the width when it is 0. */
static inline int deform_head_width(const deform_config *cfg) { return cfg->head_width > 0 ? cfg->head_width : cfg->width; }
/* Checks sizes; PG_ERR_ARG with the offending field otherwise. */
pg_status deform_config_validate(const deform_config *cfg);

/* Allocates and initialises a network for positions inside aabb (min xyz, max xyz; max > min).
 * Gradients start at zero. */
pg_status deform_network_create(deform_network **net, const deform_config *cfg, const float aabb[6]);
void deform_network_destroy(deform_network *net);
/* Parameters a network of this config has, without allocating it (0 for an invalid config): files
 * that claim a network are checked against it before anything big is allocated. */
size_t deform_config_num_params(const deform_config *cfg);
void deform_network_zero_grad(deform_network *net);

/* Workspace: per-thread chunk scratch, per-thread gradient buffers, and (f32 path only) stored
 * activations for up to max_points points (forward calls with more points still work: the backward
 * then recomputes the activations of the chunks that were not kept). The AMX path ignores
 * max_points and always recomputes (as fast as reading them back, see deform_amx.h).
 * chunk = points per chunk (0: default, 128 on the AMX path, else 256). */
pg_status deform_ws_create(deform_ws **ws, const deform_network *net, long max_points);
pg_status deform_ws_create_chunked(deform_ws **ws, const deform_network *net, long max_points, int chunk);
void deform_ws_destroy(deform_ws *ws);
/* 1 if this workspace runs the hidden layers in bf16 on AMX (cfg.bf16 and the CPU supports it). */
int deform_ws_uses_amx(const deform_ws *ws);
/* Points per chunk of this workspace. */
int deform_ws_chunk(const deform_ws *ws);

/* Evaluates the network for n points at time t: point i is means[idx[i]] (idx != NULL, e.g. only the
 * Gaussians that can move) or means[i] (idx == NULL). out (n, DEFORM_OUT_DIM), row i for point i.
 * means (3 per row) and idx must stay unchanged until the matching backward. Can fail only with
 * PG_ERR_ARG (bad n/t) or PG_ERR_NOMEM (thread count grew beyond the workspace). */
pg_status deform_network_forward(deform_network *net, deform_ws *ws, const float *means, const int *idx, long n,
                                 float t, float *out);
/* Backward of the last forward: d_out (n, DEFORM_OUT_DIM). Adds parameter gradients into net->grads
 * and position gradients into d_means[idx[i]] (or d_means[i]); d_means may be NULL. idx entries
 * must be distinct. */
pg_status deform_network_backward(deform_network *net, deform_ws *ws, const float *d_out, float *d_means);

/* K-Planes regularisers over all scales: w_tv * TV(spatial planes) + w_time * smoothness(time planes)
 * + w_l1 * |1 - time planes|, each a per-plane mean summed over planes. Adds gradients into
 * net->grads and returns the weighted total. */
float deform_network_regularize(deform_network *net, float w_tv, float w_time, float w_l1);

/* Copies a parameter-shaped array (the parameters, or an optimiser moment laid out like them) of
 * `from` into the layout of `to`, a network that differs only in its time resolution: the MLP and
 * the spatial planes verbatim, each time plane's rows resampled linearly in t (align-corners).
 * With (T_to - 1) a multiple of (T_from - 1) the field is the same at every t (a refinement).
 * Used to start a long clip's motion on few, often-visited time rows and refine them later. */
void deform_params_resample_time(const deform_network *from, const float *src, const deform_network *to, float *dst);

/* Parameter blobs for checkpoints: a small header (magic, config, aabb, count) + params (float32). */
size_t deform_network_blob_size(const deform_network *net);
pg_status deform_network_write_blob(const deform_network *net, void *buf, size_t size);
/* Creates a network from a blob (what = name for error messages, e.g. the checkpoint path). */
pg_status deform_network_read_blob(deform_network **net, const void *buf, size_t size, const char *what);
pg_status deform_network_save(const deform_network *net, const char *path);
pg_status deform_network_load(deform_network **net, const char *path);

#endif
