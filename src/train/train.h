/* train.h - the 4D trainer: canonical Gaussians + deformation network, coarse then fine stage.
 *
 *   train_set ts;          PG_TRY(train_set_load(dir, &ts));
 *   train_config cfg = train_default_config();
 *   cfg.iters = 3000; cfg.seed = 1; cfg.checkpoint_every = 500;
 *   train_session *s;
 *   PG_TRY(train_session_create(&s, &ts, &cfg, "out/model.ckpt", resume));  // resume: load if present
 *   PG_TRY(train_session_run(s));      // checkpoints every K iterations and at the end
 *   double psnr; train_session_evaluate(s, IO_ROLE_TEST, &psnr);
 *   train_session_destroy(s);
 *
 * The model is rendered later from the checkpoint alone (render/model_render.h). Same seed,
 * same thread count and same training set give byte-identical checkpoints, also across
 * --resume (all state - RNG, Adam moments, densification statistics - is in the file).
 */
#ifndef PG_TRAIN_H
#define PG_TRAIN_H

#include <stdint.h>

#include "core/status.h"
#include "deform/hexplane.h"
#include "splat/gaussians.h"
#include "train/trainset.h"

typedef struct {
    int iters;            /* total iterations, coarse included */
    int coarse_iters;     /* static stage (no deformation) */
    uint64_t seed;
    int threads;          /* informative; the caller sets the thread count */
    int max_gaussians;
    int init_points;      /* target number of Gaussians after voxel downsampling */
    int checkpoint_every; /* 0 = only at the end */
    int stop_at_iter;     /* testing: return PG_OK after saving at this iteration (0 = off) */
    int views_per_step;   /* views trained per deformation: the real view + (this - 1) proxies of one time */
    int times_per_step;   /* times (deformations) per optimiser step, each with its own views (1) */
    int motion_crops;     /* fine stage: extra times per step, each the real view cropped to its moving region */
    float real_weight;    /* share of the step's loss on the real view when proxies are in the batch */
    float moving_weight;  /* extra loss weight on the real view's moving pixels (1 + this) */
    float proxy_moving_weight; /* loss weight of proxy pixels that show the real view's moving pixels */
    int sh_max_degree;
    int sh_ramp_every;
    float bg[3];
    /* loss */
    float lambda_dssim, lambda_depth;
    float reg_tv, reg_time, reg_l1;
    /* learning rates (means scaled by the scene extent) */
    float lr_means, lr_means_final, lr_scales, lr_quats, lr_opacity, lr_sh_dc, lr_sh_rest;
    float lr_net, lr_net_final, lr_grid, lr_grid_final;
    float lr_static_scale; /* factor on the static Gaussians' scale/rotation/opacity/colour rates (2) */
    int static_steps;      /* with one real camera the static Gaussians' scales, rotation, opacity and colour
                            * stop at this iteration and they no longer densify (TRAIN_STATIC_STEPS; 0 = never) */
    float average_decay;   /* the model is this moving average of the parameters after densify_until (0.99; 0 = the last step's) */
    /* density control */
    int densify_from, densify_until, densify_every, opacity_reset_every;
    float densify_grad, percent_dense, prune_opacity, prune_big_scale;
    float densify_movable;   /* the movable Gaussians' densification threshold: this times densify_grad (0: the rule below) */
    int proxy_downscale;     /* proxies train at 1/this of the working size per side: 1 or 2 (TRAIN_PROXY_DOWNSCALE) */
    /* deformation-network speed tricks */
    int use_static_flags, use_frustum_cull;
    int static_check_every;  /* learned static flags: re-check every k fine iterations (0 = off) */
    float static_eps;        /* max |delta position| / extent to call a Gaussian static */
    int deform_width, deform_res, deform_tres, deform_channels; /* 0 = library defaults */
    int deform_head_width;   /* hidden width of each of the network's five heads (32; 0 = deform_width) */
    int deform_time_coarsen; /* the coarse spatial scale's time rows: one per 2^k of the fine scale's (2) */
    float deform_time_warmup; /* share of the fine steps on a quarter of the time rows, refined then (0.4; 0 = off) */
} train_config;

/* Most views trained against one deformation (views_per_step is clamped to it). */
#define TRAIN_MAX_BATCH 16

train_config train_default_config(void);

/* The HexPlane's time texels (unless deform_tres is set): one per frame, since motion that changes
 * between frames needs its own texel, but at most one per TRAIN_STEPS_PER_TIME_TEXEL fine
 * iterations: a time texel is fitted only by the steps whose frame lies next to it, and one
 * visited a handful of times stays near its initial value, so a long clip on a short schedule
 * froze its motion. Between texels the field interpolates linearly in time. */
#define TRAIN_STEPS_PER_TIME_TEXEL 8
int train_time_texels(int frames, int fine_times); /* fine_times: fine iterations x (times_per_step + motion crops) */

/* The iterations a preset's budget becomes for a clip of `frames` frames: a long clip's frames each
 * need their motion fitted some number of times, and the budget that fits 60 frames fits each of
 * 300 a fifth as often (the 300-frame sample scene lost 6 dB of moving PSNR against 30 frames at
 * 1,500 iterations; 3,000 won back 3.1). So the fine stage (5/6 of the budget) gets at least
 * TRAIN_FITS_PER_FRAME times per frame, each step fitting 1 + motion_crops times, up to
 * TRAIN_MAX_BUDGET_THIRDS / 3 times the preset's budget (the first doubling buys the most; docs/train.md).
 * Short clips keep `iters` (up to 58 frames at the fast preset). 64 rather than the 40 of before:
 * a 120-frame clip got 1,850 iterations and its movers 34.05 dB against the 30-frame clip's 38.59;
 * at 3,000 iterations 38.21. */
#define TRAIN_FITS_PER_FRAME 64
#define TRAIN_MAX_BUDGET_THIRDS 8 /* the cap: 8/3 of the preset's budget (4,000 for the fast preset's 1,500) */
/* The cap is one of compute: a step costs about what its pixels cost, so a clip trained smaller than
 * TRAIN_BUDGET_PIXELS (the fast preset's 320 x 180 of 16:9 footage) has its cap raised by the ratio,
 * up to TRAIN_MAX_PIXEL_SCALE times. The 300-frame 160 x 120 sample clip then gets its 64 fits per
 * frame (6,650 steps) in less train time than the classroom's 4,000 steps at 320 x 180 (docs/train.md). */
#define TRAIN_BUDGET_PIXELS (320L * 180)
#define TRAIN_MAX_PIXEL_SCALE 3
/* The HexPlane's time rows stay at most this many whatever the budget: about what the cap gives at
 * 320 x 180 (1,406), so a raised budget does not grow the model (an 8 x 8 clip of 10,000 frames:
 * 1,406 rows, 43 MB, 384 MB peak at 4,000 steps; 1,500 rows at 12,000 steps took 402 MB). */
#define TRAIN_MAX_TIME_TEXELS 1400
/* A clip whose time rows are each fitted fewer than TRAIN_UNDERFITTED_FITS times (a clip the cap
 * leaves that short: over 281 frames at the fast preset) warms its time rows up (docs/train.md) and
 * densifies its movers less (below). 40, below the budget's 64, because that is where both were
 * measured: the 300-frame clip's ~37 fits per row gained from them, the 30-frame clip's ~125 lost. */
#define TRAIN_UNDERFITTED_FITS 40
/* Such a clip is short of steps, not of Gaussians: its movable Gaussians densify at this multiple
 * of the still ones' threshold unless densify_movable says otherwise. The moving pixels' 10x loss
 * weight inflates their view-space gradients; at a third of them a step costs ~30 % less and the
 * cap's extra steps give the movers back what the density took (docs/train.md). A short clip,
 * fitted ~125 times per frame, keeps its density: it lost 1.9 dB on its movers at 3. */
#define TRAIN_LONG_CLIP_DENSIFY_MOVABLE 3.0f
int train_iterations_for_clip(int iters, int frames, int motion_crops, long pixels); /* pixels: the working size (<= 0: TRAIN_BUDGET_PIXELS) */
/* Proxies train at half the working size per side. A proxy is the real frame carried to another
 * viewpoint through a blurred monocular depth: its pixel-level detail is the real view's, resampled,
 * and what it adds is where things are, which half the pixels show as well. The real view keeps
 * every pixel. A proxy render then costs about a third (classroom_cam3: training 11 % faster,
 * moving pixels within the run-to-run floor; docs/train.md). */
#define TRAIN_PROXY_DOWNSCALE 2
/* With one real camera the still scene is fitted for this many iterations, whatever the budget:
 * past it each step only sharpens still texture where the monocular depth placed it a pixel off
 * in the other views, and the held-out views lose (tabletop_dev, 3,000 steps: 27.82 dB held out,
 * frozen at 1,000: 28.02; docs/train.md "The still scene stops at 1,500 steps"). The fast
 * preset's length, so it is unchanged. */
#define TRAIN_STATIC_STEPS 1500
/* The longest coarse stage a default gives: the fast preset's 250 steps place the still scene
 * before the motion starts. A sixth of a long budget fits the movers as still blobs for longer
 * (8,000 steps: 1,333) and the held-out views' movers lose for it (tabletop_dev at 8,000 steps:
 * 22.02 dB, coarse 250: 22.74; docs/train.md "The coarse stage stays short"). */
#define TRAIN_MAX_COARSE_ITERS 250
/* The largest SH degree when none is asked for: 3 with two or more real cameras, 0 with one. With
 * one camera every proxy carries that camera's colours to its viewpoint, so a colour that changes
 * with the direction has nothing true to learn, only where the proxies disagree (tabletop_dev
 * held out: degree 0 as good as 3, a step ~8 % cheaper; docs/train.md). */
int train_default_sh_degree(const train_set *ts);
/* The coarse (still) stage's iterations when none are asked for: a sixth of the budget, at most
 * TRAIN_MAX_COARSE_ITERS. */
int train_default_coarse_iters(int iters);
/* The iteration densification stops at when none is asked for: 70 % of the budget. A long clip's
 * raised budget keeps its preset's point (the extra steps fit, they do not add Gaussians): the
 * classroom clip densified to 147k Gaussians over 3,000 steps, 1.6 GiB and a 48 MB checkpoint. */
int train_default_densify_until(int iters);
/* A preset's budget for a clip of `frames` frames: its iterations raised for a long clip, the
 * coarse stage and the end of densification at the preset's own. */
typedef struct {
    int iters, coarse_iters, densify_until;
} train_budget;
train_budget train_budget_for_clip(int preset_iters, int frames, int motion_crops, long pixels);
/* The factor on the deformation network's learning rates (HexPlane and MLP) for a fine stage of
 * `fine_iters` steps: 1 up to TRAIN_NET_LR_FULL_STEPS steps, falling as FULL / fine_iters to
 * TRAIN_NET_LR_MIN_SCALE. A full budget at the full rates learns the motion through the rates'
 * noise (half of them: +0.9 dB on the movers of the classroom clip, the sample scene at 30 and 300
 * frames, tabletop_dev held out), while a short schedule at half of them never reaches the motion
 * (heavy_train's 110 fine steps: 31 -> 16 dB on the movers); docs/train.md. */
#define TRAIN_NET_LR_FULL_STEPS 500
#define TRAIN_NET_LR_MIN_SCALE 0.5f
float train_net_lr_scale(int fine_iters);
/* Times one fine step fits: the step's own time and each motion crop (negative crops: none). */
int train_fits_per_step(int motion_crops);

typedef struct train_session train_session;

/* Creates a session; if resume and ckpt_path exists, continues from it (the training set and
 * the config must match the ones it was made with, except iters may grow). */
pg_status train_session_create(train_session **s, const train_set *ts, const train_config *cfg,
                               const char *ckpt_path, int resume);
void train_session_destroy(train_session *s);
/* Runs to cfg.iters (or stop_at_iter), writing checkpoints; reports progress as "train". */
pg_status train_session_run(train_session *s);
/* One iteration (exposed for benchmarks and tests). */
pg_status train_session_step(train_session *s);
/* Mean PSNR over every frame of every view with the role (only frames where ts has them). */
pg_status train_session_evaluate(train_session *s, io_view_role role, double *psnr);
/* The same, plus PSNR over the moving and the static pixels of those views (eval's definition:
 * colour off the pixel's temporal median by > 0.12, dilated 2 px; squared error pooled over
 * all frames; NaN for an empty part). */
typedef struct {
    double psnr, psnr_moving, psnr_static, moving_fraction;
} train_eval_scores;
pg_status train_session_evaluate_parts(train_session *s, io_view_role role, train_eval_scores *out);
int train_session_iteration(const train_session *s);
int train_session_gaussians(const train_session *s);
/* Mean number of Gaussians sent through the network per fine iteration (after static flags and
 * culling) and mean number of movable ones (this process only, not across --resume). */
void train_session_deform_stats(const train_session *s, double *mean_deformed, double *mean_movable);
/* Frames of the real view with a moving region for motion crops (0 when crops are off), the
 * regions' mean share of the frame, and the proxies with a moving region (crops alternate the real
 * view with them). */
void train_session_motion_regions(const train_session *s, int *frames, double *mean_area, int *proxies);
/* The network's time rows now (before the fine stage: those it ends with) and during its warm-up
 * (0: no warm-up). */
void train_session_time_rows(const train_session *s, int *rows, int *warmup_rows);
/* The movable Gaussians' densification threshold over the still ones' (densify_movable resolved). */
float train_session_densify_movable(const train_session *s);
/* Gaussians flagged static (never sent through the network). */
int train_session_static_count(const train_session *s);

/* Per-phase timings of the last step in milliseconds (bench iteration). */
typedef struct {
    double deform_forward, deform_backward, regularize, raster_forward, raster_backward, loss, optimizer, other;
    double targets; /* each view's target frame, mask and depth made ready (cropped, halved) */
    int deformed;   /* Gaussians sent through the network */
} train_timing;
void train_session_timing(const train_session *s, train_timing *t);
/* The same summed over every step of this process (train.json's phase_seconds). */
void train_session_timing_total(const train_session *s, train_timing *t);
/* Benchmarks: start the fine stage now (creates the network). */
pg_status train_session_force_fine(train_session *s);
/* Replaces the canonical Gaussians (moments and density statistics zeroed); is_static (N) may
 * be NULL (all movable). Call before the fine stage starts (the network box follows them). */
pg_status train_session_set_gaussians(train_session *s, const pg_gaussians *g, const uint8_t *is_static);

#endif
