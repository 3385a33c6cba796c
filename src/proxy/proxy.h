/* proxy.h - the proxy-view stage: frames + aligned depth -> training-set directory.
 *
 * For every frame: build its model (frame_model.h: the depth mesh, or per-pixel Gaussians fitted
 * briefly on the real view), render every proxy camera (RGB, depth, validity mask), write them to DIR (docs/FORMATS.md) and free the model.
 * Frames run in parallel (one model per worker, so memory is bounded by the worker count). Each
 * finished frame leaves a marker holding the settings hash; a rerun with the same settings skips
 * those frames (resumable), a change of settings recomputes everything.
 *
 *   proxy_job job = {...};                       // frames callback, depth, cameras
 *   proxy_options o = proxy_default_options();
 *   proxy_result r;
 *   proxy_generate(&o, &job, "out/trainset", &r);
 *
 * Units: job.depth is in depth units; everything written (proxy depth, real depth.npy) and every
 * camera is in pose units: depth_pose = job.pose_scale * depth. Poses are never rescaled.
 */
#ifndef PG_PROXY_PROXY_H
#define PG_PROXY_PROXY_H

#include "core/camera.h"
#include "core/image.h"
#include "proxy/frame_model.h"

typedef struct {
    proxy_fit_options fit;
    int threads; /* frame workers (2) */
    int force;   /* recompute every frame even if cached */
    int fill_holes; /* 1: disocclusion holes take the background's colour at the margin weight (holes.h) */
} proxy_options;

/* Fills *out (an empty pg_image the callee creates, (H,W,3) at the job's size) with frame `frame`
 * of camera `camera`: 0 = the real camera, 1 + j = test camera j. Called from one thread at a time. */
typedef pg_status (*proxy_frame_fn)(void *ctx, int camera, int frame, pg_image *out);

typedef struct {
    int frames, width, height;
    double fps;
    proxy_frame_fn get_frame;
    void *frame_ctx;
    const float *depth; /* (F, H, W) aligned depth in depth units, 0 = invalid */
    float pose_scale;   /* pose units per depth unit (1 for hemisphere poses) */
    float pose_shift;   /* the disparity shift already applied to depth (trainset.json "source"; 0: none) */
    const char *pose_fit; /* how pose_scale and pose_shift were found (trainset.json "source"; may be NULL) */
    double unit;        /* the user's length per pose unit (hemisphere: the depth's unit; 1 for dataset poses) */
    const char *real_name;
    pg_camera real;
    int num_proxies; /* may be 0: only the real (and test) cameras are written */
    const char *const *proxy_names;
    const pg_camera *proxies;
    int num_tests; /* test cameras: their frames are written with role "test", never used here */
    const char *const *test_names;
    const pg_camera *tests;
    float center[3], radius; /* scene centre and radius in pose units (trainset.json "scene") */
    const char *input_path, *depth_path; /* for trainset.json "source" (may be NULL) */
} proxy_job;

typedef struct {
    int frames_done, frames_skipped;
    double init_s, fit_s, render_s, write_s; /* summed over workers */
    double wall_s;
    double mean_valid_fraction; /* over computed proxy views */
    double mean_source_psnr;    /* fitted model vs the real frame, over computed frames (NaN: none fitted) */
    unsigned long long settings_hash;
} proxy_result;

proxy_options proxy_default_options(void);

/* Runs the stage into out_dir (created if needed). On failure the message names the frame and
 * file; completed frames stay on disk and are reused by the next run. */
pg_status proxy_generate(const proxy_options *opt, const proxy_job *job, const char *out_dir, proxy_result *res);

#endif
