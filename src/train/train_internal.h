/* train_internal.h - the trainer's state, shared by train.c, init.c, densify.c, checkpoint.c. */
#ifndef PG_TRAIN_INTERNAL_H
#define PG_TRAIN_INTERNAL_H

#include "core/image.h"
#include "core/rng.h"
#include "optim/adam.h"
#include "optim/loss_image.h"
#include "splat/raster.h"
#include "train/model.h"
#include "train/motion_regions.h"
#include "train/train.h"

/* The full-size phase's data (detail.c): the real view at the input's size, the still scene's
 * median there and the movers' boxes of every frame. */
typedef struct {
    pg_camera cam;       /* the real view at the input's size (the trainer's units) */
    float *still;        /* (H, W, 3) per-pixel temporal median of sampled frames */
    uint8_t **crop;      /* (frames) frame f's movers' box at full size: its moving tiles' RGB, or NULL */
    int **tiles;         /* (frames) each tile of the box: its index in crop[f], -1 for a still tile */
    int *rect;           /* (frames, 4) x, y, w, h of each box */
    int frames;
    size_t max_px;       /* the largest box's pixels */
    int max_w, max_h;    /* and the largest sides */
    int densify;         /* the steps collect the movers' view-space gradients */
    int score_frames;     /* frames scored before and after the phase, kept from the one pass: */
    uint8_t *score_rgb;   /* (score_frames, H, W, 3) */
    uint8_t *score_moving; /* (score_frames, H, W) their moving pixels */
} train_detail;

struct train_session {
    const train_set *ts;
    train_config cfg;
    char ckpt_path[4096];

    int iter;          /* iterations done */
    pg_rng rng;
    int fine;          /* 1 once the fine stage started (network exists) */
    float extent;      /* scene radius for lr scaling and densification */
    float center[3];
    float max_disp;    /* largest |delta position| seen, culling margin */
    train_net_config net_cfg;

    pg_gaussians g;    /* canonical parameters */
    pg_gaussians gg;   /* their gradients */
    optim_adam *gopt;  /* Adam of g: the OPTIM_G_* groups, g.count rows */
    pg_gaussians d;    /* deformed copy for the current frame */
    pg_gaussians dg;   /* gradients w.r.t. the deformed copy */
    int side_cap;
    uint8_t *is_static;  /* (side_cap) */
    float *grad_accum;   /* (side_cap) summed view-space gradient norms */
    float *grad_denom;   /* (side_cap) times visible */
    float *vs_grad;      /* (side_cap) this iteration's view-space gradient norm */
    int *idx;            /* (side_cap) Gaussians sent through the network */
    int *step_rows;      /* (side_cap) this step's rows the network may move (n_moving_rows of them),
                          * then the fixed rest: only the moving ones are copied, filtered and
                          * back-propagated per rendered time; the fixed ones once per step */
    int n_moving_rows, n_fixed_rows;
    uint8_t *row_flags;  /* (side_cap) scratch: which of the moving rows the network gets */
    float *filter_var;   /* (side_cap) 3D smoothing filter variance (splat/filter3d.h), from the
                          * canonical means every TRAIN_FILTER_EVERY steps and after densification */
    float *filter_saved; /* (side_cap, SPLAT_FILTER3D_SAVED) what the 3D filter's backward needs */
    uint8_t **moving;    /* (num_views) per real view (F, H, W) moving pixels, else NULL; may be NULL */
    int crop_view;       /* the real view whose moving region motion crops render (-1: none) */
    train_motion_regions *regions; /* (num_views) movers' boxes per frame: the crop view's and, with two
                                    * crops or more, each proxy's (empty for the other views); may be NULL */
    int proxy_crop_views;          /* proxies with a moving region */
    train_net *net;
    optim_adam *nopt;    /* Adam of the network parameters: TRAIN_NET_* groups, one row */
    /* the parameters' moving average (average.c; checkpointed with the optimiser state) */
    int avg_on;          /* 1 once the average started */
    pg_gaussians avg_g;  /* of the canonical Gaussians */
    float *avg_net;      /* of the network's parameters */

    splat_raster *raster;
    pg_image target;     /* (H, W, 3) */
    float *mask;         /* (H, W) */
    float *depth_t;      /* (H, W) */
    float *depth_mask;   /* (H, W) valid target depth */
    optim_ssim_ws *ssim;
    optim_ssim_ws *ssim_crop; /* for any smaller image (crops), optim_ssim_reshape'd */
    float *d_rgb;        /* (H, W, 3) */
    float *d_depth;      /* (H, W) */

    /* reporting (not part of the checkpoint) */
    double last_loss, last_psnr, t_start;
    int it_start;
    train_timing timing;
    train_timing timing_total; /* summed over this process's steps, in train.json */
    double sum_deformed, sum_movable; /* per fine iteration, for the speed report */
    long fine_steps;
    train_detail *detail; /* the full-size phase's, NULL before it */
};

/* Adam groups of the network's flat parameter array (train_net_grid_end splits it). */
enum { TRAIN_NET_GRID, TRAIN_NET_MLP, TRAIN_NET_GROUPS };

/* the 3D filter follows the means this often (Mip-Splatting's interval) */
#define TRAIN_FILTER_EVERY 100

/* train.c */
void train_update_filter(train_session *s);
/* dst = src, dst += src, dst = keep * dst + (1 - keep) * src (the parameters' average) or dst = 0 */
typedef enum { TRAIN_BLEND_COPY, TRAIN_BLEND_ADD, TRAIN_BLEND_AVERAGE, TRAIN_BLEND_ZERO } train_blend;
void train_blend_floats(float *dst, const float *src, size_t n, train_blend how, float keep);
/* Over every parameter array of src's rows, the SH rows up to their first sh_floats (copy and
 * average also take src's SH degree). */
void train_blend_gaussians(pg_gaussians *dst, const pg_gaussians *src, train_blend how, float keep, int sh_floats);
/* Proxies at half size (TRAIN_PROXY_DOWNSCALE): the (w, h) c-channel image buf becomes, in place,
 * its (w / 2, h / 2) 2x2 box average (with skip_zero, zeros - invalid depth - are left out), and
 * the camera of that image (pixel centres at (x + 0.5) x 2 of the full one). */
void train_halve_in_place(float *buf, int w, int h, int c, int skip_zero);
pg_camera train_half_camera(const pg_camera *cam);
/* The whole model at frame f's time rendered with cam (the deformed copy d is redone). */
pg_status train_render_frame(train_session *s, int f, const pg_camera *cam, pg_render_output *out);
/* detail.c: rect (inside frame f's full-size box) into rgb (w x h x 3) and its loss weights into
 * mask (1 + moving_weight on pixels off the still scene). */
void train_detail_target(const train_session *s, int f, const int *rect, float *rgb, float *mask);
/* the full-size steps' windows of a box are at most this many pixels a side */
#define TRAIN_DETAIL_WINDOW 640
void train_detail_destroy(train_detail *d);
/* train_adam.c */
pg_status train_adam_resize_gaussians(train_session *s, int n);
pg_status train_adam_create_net(train_session *s);
/* The network's optimiser for s->net, moments resampled from old_opt of `from` (same network but
 * its time rows, train_net_resample_array), step counts kept; old_opt is left to the caller. */
pg_status train_adam_resample_net(train_session *s, const train_net *from, optim_adam *old_opt);
pg_status train_adam_step(train_session *s);
/* 1 once the static Gaussians stopped (train_config.static_steps): no optimiser steps, no
 * densification. Only with one real camera: with two or more the still scene is seen from
 * several true viewpoints, and sharpening it is what those steps are for. */
static inline int train_still_frozen(const train_session *s)
{
    return s->cfg.static_steps > 0 && s->iter >= s->cfg.static_steps && train_set_count_role(s->ts, IO_ROLE_REAL) == 1;
}
/* init.c */
pg_status train_init_gaussians(train_session *s);
/* train.c: the movable rows that never cover the real view's moving pixels made still (their
 * count into frozen) */
pg_status train_freeze_off_motion(train_session *s, int *frozen);
/* densify.c */
pg_status train_ensure_side(train_session *s, int n);
pg_status train_resize_all(train_session *s, int n);
pg_status train_densify_and_prune(train_session *s, int densify);
void train_reset_opacity(train_session *s);
/* average.c: after each optimiser step (from densify_until on); after the parameters changed
 * outside the optimiser; at the end of the run (the model becomes the average) */
pg_status train_average_update(train_session *s);
void train_average_restart(train_session *s);
pg_status train_average_apply(train_session *s);
void train_average_destroy(train_session *s);
/* checkpoint.c */
/* with_optimizer 0 (the end of training): the model alone, a third of the bytes. */
pg_status train_checkpoint_write(train_session *s, const char *path, int with_optimizer);
pg_status train_checkpoint_read(train_session *s, const char *path);
/* NULL if every field of a (stored) config is in range, else the first bad field's name. */
const char *train_config_invalid(const train_config *c);
/* PG_OK if a checkpoint's config equals the one asked for, except the settings a resume may change
 * (iterations, checkpoint interval, threads); else an error naming the first difference. */
pg_status train_checkpoint_check_config(const train_config *stored, const train_config *given, const char *path);
/* Removes PATH.tmp.* left by a checkpoint write that was killed. */
void train_checkpoint_clean_temps(const char *path);

#endif
