/* trainset.h - a training set held in memory: views (camera + per-frame images) with roles.
 *
 *   train_set ts;
 *   PG_TRY(train_set_load("out/proxies", &ts));            // docs/FORMATS.md directory
 *   // or: the real cameras of a DyNeRF dataset, two held out for testing
 *   train_set_dynerf_options o = train_set_dynerf_defaults();
 *   o.test_cams = (int[]){5, 6}; o.num_test = 2;
 *   PG_TRY(train_set_from_dynerf("data/scene", &o, &ts));
 *   ...
 *   train_set_destroy(&ts);
 *
 * Images are kept as uint8 RGB (4x smaller than float; the trainer converts the sampled
 * frame on the fly), masks as uint8 loss weights 0..TRAIN_MASK_FULL, depth as float16 relative to
 * the view's median (0 = invalid; 11 significant bits, half the memory of float32: a 10-second
 * clip's nine views hold 300 MB less).
 */
#ifndef PG_TRAINSET_H
#define PG_TRAINSET_H

#include <stdint.h>

#include "core/camera.h"
#include "core/image.h"
#include "core/status.h"
#include "io/trainset.h"

#define TRAIN_MASK_FULL 255 /* mask byte of a fully trusted pixel (mask PNG value 1) */


typedef struct {
    char name[64];
    io_view_role role;
    pg_camera cam;
    uint8_t *rgb;   /* (F, H, W, 3) */
    uint8_t *mask;  /* (F, H, W) loss weight x TRAIN_MASK_FULL (0 = invalid), or NULL (all valid) */
    uint16_t *depth; /* (F, H, W) z-depth / depth_scale as float16 bits, 0 = invalid, or NULL */
    float depth_scale; /* the view's median depth: stored values sit near 1, far from float16's limits */
} train_view;

/* Depth of pixel i (frame-major) of a view with depth, in the set's units. */
float train_view_depth(const train_view *v, size_t i);
/* Frame f's depth (px values) into out. */
void train_view_depth_frame(const train_view *v, int f, size_t px, float *out);
/* Stores n float depth values (NaN, inf and <= 0 become 0 = invalid) into a view made with depth;
 * returns how many are valid. d NULL: the view's store already holds the n values as raw halves
 * (io_npy_load_half), which are scaled in place. */
size_t train_view_set_depth(train_view *v, const float *d, size_t n);

typedef struct {
    int frames, width, height;
    float fps;
    int num_views;
    train_view *views; /* (num_views) */
    int has_scene;     /* scene box below is known */
    float center[3], radius, near_z, far_z;
    float unit;        /* the user's length per set length (train_set_normalize_units; 0 or 1: as loaded) */
} train_set;

/* Reads a training-set directory (trainset.json + PNGs + depth.npy). Fails with a message
 * naming the file on missing/garbled parts or sizes that disagree with trainset.json. */
pg_status train_set_load(const char *dir, train_set *ts);

typedef struct {
    int all_real;          /* 1: every camera not in test_cams is a real training view */
    const int *real_cams;  /* used when all_real = 0 */
    int num_real;
    const int *test_cams;  /* held out (role test) */
    int num_test;
    const char *depth_path; /* optional (F,H,W) depth of the first real camera (init/depth loss) */
    int max_frames;         /* 0 = all */
    int width;              /* 0 = native, else resize (height keeps the aspect) */
} train_set_dynerf_options;

train_set_dynerf_options train_set_dynerf_defaults(void);
/* Builds a training set from the real cameras of a DyNeRF-layout dataset (poses_bounds.npy +
 * camXX/images/NNNN.png, or camXX.mp4 when the io video reader is available). Cameras are
 * converted from LLFF (down, right, back) to OpenCV. */
pg_status train_set_from_dynerf(const char *dir, const train_set_dynerf_options *opt, train_set *ts);

void train_set_destroy(train_set *ts);

/* Median scene depth the trainer's length constants are meant for (learning rates, near plane,
 * network bounds): tabletop_dev's and DyNeRF scenes' own scale, where the defaults were tuned. */
#define TRAIN_SET_UNIT_DEPTH 4.0f

/* Makes training independent of the depth's units: divides every length of the set (camera
 * positions, depth, scene box) by unit = (median depth of the real views) / TRAIN_SET_UNIT_DEPTH
 * and records unit in ts->unit, so the model can be brought back to the user's units. Falls
 * back to the scene radius (proxies write the median depth on the optical axis), then to 1. */
void train_set_normalize_units(train_set *ts);
/* The user's length per set length: ts->unit, or 1 for a set never normalised (unit left 0). */
static inline float train_set_unit(const train_set *ts) { return ts->unit > 0 ? ts->unit : 1.0f; }
/* View v's camera in the user's units (translation times ts->unit). */
pg_camera train_set_user_camera(const train_set *ts, int v);

/* Counts views of a role. */
int train_set_count_role(const train_set *ts, io_view_role role);
/* Frame f of view v as a float (H, W, 3) image (img must be created with the set's size). */
void train_set_frame_rgb(const train_set *ts, int v, int f, pg_image *img);

/* Keeps n of the proxy views (evenly spaced in their order; n < 0 keeps all), frees the rest. */
void train_set_limit_proxies(train_set *ts, int n);

/* Appends an empty view with allocated rgb (and mask/depth if asked); returns its index. */
pg_status train_set_add_view(train_set *ts, const char *name, io_view_role role, const pg_camera *cam,
                             int with_mask, int with_depth, int *index);

#endif
