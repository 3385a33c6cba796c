/* model.h - a trained 4D model: canonical Gaussians, static flags and the deformation network.
 *
 *   train_model m;
 *   PG_TRY(train_model_load("out/model.ckpt", &m));       // from a training checkpoint
 *   pg_gaussians at_t = {0};
 *   PG_TRY(train_model_deform(&m, 0.5f, &at_t));           // every Gaussian at t in [0,1]
 *   ... splat_render_forward(r, &at_t, &cam, &settings, &out) ...
 *   splat_gaussians_destroy(&at_t); train_model_destroy(&m);
 *
 * The deformation network is reached through the small train_net adapter (train_net.c) so
 * the trainer, checkpoints and renders share one code path.
 */
#ifndef PG_TRAIN_MODEL_H
#define PG_TRAIN_MODEL_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "splat/gaussians.h"

/* ---- deformation network adapter ---- */
typedef struct train_net train_net;

typedef struct {
    float aabb_min[3], aabb_max[3]; /* position normalisation box */
    int width, res, tres, channels;  /* 0 = defaults */
    int head_width;                  /* 0 = width */
    int time_coarsen;                /* deform_config.time_coarsen (0: every scale at tres) */
    uint64_t seed;
} train_net_config;

pg_status train_net_create(train_net **n, const train_net_config *cfg);
void train_net_destroy(train_net *n);
size_t train_net_num_params(const train_net *n);
/* Parameters a network of cfg would have (0: invalid config), without creating it. */
size_t train_net_config_num_params(const train_net_config *cfg);
float *train_net_params(train_net *n);  /* (P) */
float *train_net_grads(train_net *n);   /* (P) */
/* Parameters [0, grid_end) are HexPlane grids (own lr), [grid_end, P) the MLP. */
size_t train_net_grid_end(const train_net *n);
void train_net_zero_grad(train_net *n);
/* Writes the deformed rows idx[0..n) of out (other rows untouched) from canonical g at t: every
 * attribute and the first sh_floats colour floats of a row (the rest of out's rows untouched: 3
 * when the run trains degree 0, of the 48 the network predicts). */
pg_status train_net_forward(train_net *net, const pg_gaussians *g, const int *idx, int n, float t, int sh_floats,
                            pg_gaussians *out);
/* Backward of the last forward (same idx, t, sh_floats): d_out rows -> net grads (the colour
 * floats past sh_floats count as 0), and into d_canon rows idx (which must hold the identity path
 * d_out already: canon + delta). */
pg_status train_net_backward(train_net *net, const pg_gaussians *g, const int *idx, int n, float t, int sh_floats,
                             const pg_gaussians *d_out, pg_gaussians *d_canon);
/* K-Planes regularisers: adds their gradients, returns the loss value. */
float train_net_regularize(train_net *net, float w_tv, float w_time, float w_l1);
/* A network like `from` but with tres time rows, its parameters resampled in time (the same
 * motion where the rows refine); *to must be destroyed by the caller. */
pg_status train_net_resample_time(const train_net *from, int tres, train_net **to);
/* The same resampling for any parameter-shaped array (an optimiser moment, an average). */
void train_net_resample_array(const train_net *from, const float *src, const train_net *to, float *dst);

/* ---- the model ---- */
typedef struct {
    pg_gaussians g;      /* canonical Gaussians as drawn: the user's units, through the 3D filter */
    pg_gaussians g_net;  /* the same in the trainer's units (train_set_normalize_units), the network's input */
    float unit;          /* the user's length per trainer length */
    uint8_t *is_static;  /* (N) 1 = never deformed */
    float *filter_var;   /* (N) the 3D filter's variance in the user's units (splat/filter3d.h) */
    train_net *net;      /* NULL before the fine stage */
    int frames;
    float bg[3];
} train_model;

pg_status train_model_load(const char *path, train_model *m);
void train_model_destroy(train_model *m);
/* Time in [0,1] of frame f of a video with `frames` frames. */
float train_frame_time(int f, int frames);
/* Every Gaussian at time t in the user's units (static ones copied from the canonical set), scales and
 * opacity through the 3D filter: what a renderer draws; out is resized. */
pg_status train_model_deform(train_model *m, float t, pg_gaussians *out);
/* The same for an out that holds this model's Gaussians at another time (train_model_deform's, not
 * changed since): only the movers are redone (a video's frames skip copying the still scene). */
pg_status train_model_deform_movers(train_model *m, float t, pg_gaussians *out);

#endif
