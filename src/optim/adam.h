/* adam.h - Adam with per-group learning rates, 3DGS-style exponential decay, and row remapping
 * so the moments follow Gaussians through clone / split / prune.
 *
 *   // Gaussians: six groups over a pg_gaussians (means, log_scales, quats, opacity, sh dc, sh rest)
 *   optim_adam *opt;
 *   optim_adam_create_gaussians(&opt, g.count, g.sh_stride, 1e-15f);
 *   optim_lr_schedule means_lr = { 1.6e-4f, 1.6e-6f, 0, 1.0f, 30000 };
 *   float lr[OPTIM_GAUSS_GROUPS] = { optim_lr_expon(&means_lr, step), 5e-3f, 1e-3f, 5e-2f, 2.5e-3f, 1.25e-4f };
 *   optim_adam_step_gaussians(opt, &g, &grad, lr);
 *   // densification: row i of the new set comes from old row src[i] (-1: new, zero moments)
 *   optim_adam_remap_rows(opt, src, new_count);
 *
 *   // any flat float array (e.g. network weights): one group of n values
 *   optim_adam_create_flat(&opt, n, 1e-15f);
 *   optim_adam_step_group(opt, 0, weights, grads, lr);
 *   // or one row of n floats in column ranges with their own rates (grids [0, k), MLP [k, n))
 *   optim_group_desc ranges[2] = { { "grid", n, 0, k }, { "mlp", n, k, n - k } };
 *   optim_adam_create(&opt, ranges, 2, 1, 1e-15f);
 *
 * Moments live in the optimiser; parameter and gradient pointers are passed at every step, so
 * the caller may reallocate its arrays freely. Each group counts its own steps for the bias
 * correction. Deterministic and thread-count independent (element-wise updates).
 */
#ifndef PG_ADAM_H
#define PG_ADAM_H

#include <stdint.h>

#include "core/status.h"
#include "splat/gaussians.h"

/* 3DGS get_expon_lr_func: log-linear from lr_init to lr_final over max_steps (linear when
 * either end is <= 0, e.g. a decay to 0), optionally scaled by a sine ramp from delay_mult to 1
 * over the first delay_steps. 0 for step < 0; steps past max_steps give lr_final. */
typedef struct {
    float lr_init, lr_final;
    int delay_steps;   /* 0: no delay ramp */
    float delay_mult;  /* multiplier at step 0 of the ramp (3DGS default 1.0 = no effect) */
    int max_steps;
} optim_lr_schedule;

float optim_lr_expon(const optim_lr_schedule *s, int step);

/* One parameter group: `rows` rows of `row_stride` floats, of which columns [col0, col0+cols)
 * belong to this group (e.g. the SH DC is col0 = 0, cols = 3 of each 48-float row). A group of
 * 0 columns (the higher SH degrees of a set that stores degree 0 only) steps nothing. */
typedef struct {
    const char *name;
    int row_stride, col0, cols;
} optim_group_desc;

typedef struct optim_adam optim_adam;

/* Group indices of optim_adam_create_gaussians. */
enum { OPTIM_G_MEANS, OPTIM_G_LOG_SCALES, OPTIM_G_QUATS, OPTIM_G_OPACITY, OPTIM_G_SH_DC, OPTIM_G_SH_REST,
       OPTIM_GAUSS_GROUPS };

/* Creates an optimiser of ngroups groups of `rows` rows each (betas 0.9 / 0.999). */
pg_status optim_adam_create(optim_adam **opt, const optim_group_desc *groups, int ngroups, int rows, float eps);
/* The six pg_gaussians groups listed in the enum above, for SH rows of sh_stride floats. */
pg_status optim_adam_create_gaussians(optim_adam **opt, int rows, int sh_stride, float eps);
/* One group of n scalars (row_stride = cols = 1, rows = n). */
pg_status optim_adam_create_flat(optim_adam **opt, int n, float eps);
void optim_adam_destroy(optim_adam *opt);

/* One Adam step of group gi: param -= lr * mhat / (sqrt(vhat) + eps) over its rows x cols.
 * param and grad are the full (rows, row_stride) arrays. */
pg_status optim_adam_step_group(optim_adam *opt, int gi, float *param, const float *grad, float lr);
/* One group's part of optim_adam_step_groups: param and grad are the full (rows, row_stride)
 * arrays; only the first `cols` (0..the group's cols) columns of each row are updated.
 * Rows r with boost_rows[r] != 0 (boost_rows (rows) may be NULL) step at lr * boost. */
typedef struct {
    int group;
    float *param;
    const float *grad;
    float lr;
    int cols;
    const uint8_t *boost_rows;
    float boost;
} optim_group_step;

enum { OPTIM_MAX_GROUP_STEPS = 8 };

/* Steps up to OPTIM_MAX_GROUP_STEPS distinct groups in one pass over the rows, so groups sharing
 * the rows of one array (SH DC and rest) load each row once; same arithmetic as stepping them
 * one by one, and every listed group's step count advances. Columns past `cols` keep their
 * parameters and moments, which is exact when their gradients have always been zero (e.g. SH
 * coefficients above the current degree). Fails without change on a bad group, column count
 * or a group listed twice. */
pg_status optim_adam_step_groups(optim_adam *opt, const optim_group_step *steps, int n);
/* Steps all six Gaussian groups with per-group learning rates lr[OPTIM_GAUSS_GROUPS];
 * a group with lr <= 0 is left untouched (frozen) and does not advance its step count. */
pg_status optim_adam_step_gaussians(optim_adam *opt, pg_gaussians *g, const pg_gaussians *grad,
                                    const float lr[OPTIM_GAUSS_GROUPS]);
/* Reorders / duplicates / drops moment rows in every group: new row i takes old row src[i], or
 * zero moments when src[i] < 0. Covers prune (src = kept rows), clone/split (src repeats a
 * row) and append (src = -1). Fails without change if an index is out of range. */
pg_status optim_adam_remap_rows(optim_adam *opt, const int *src, int new_rows);
int optim_adam_rows(const optim_adam *opt);
/* Zeroes the moments of one group (e.g. after resetting opacities, as 3DGS does). */
void optim_adam_reset_group(optim_adam *opt, int gi);
/* Raw moment access (rows, cols) for checkpoints; NULL if gi is out of range. */
float *optim_adam_moment(optim_adam *opt, int gi, int which /* 0: m, 1: v */);
int optim_adam_num_groups(const optim_adam *opt);
/* Floats in each moment array of group gi (rows x cols; 0 if gi is out of range). */
size_t optim_adam_moment_size(const optim_adam *opt, int gi);
int optim_adam_group_step(const optim_adam *opt, int gi);
void optim_adam_set_group_step(optim_adam *opt, int gi, int step);

#endif
