/* prodygs.h - the public C API: the ProDyGS pipeline's stages as library calls.
 *
 * Each stage takes a typed config (start from its _defaults function; strings are borrowed and
 * NULL means "the default"), validates it, does its work and fills a report. On failure it
 * returns a pg_status and pg_last_error() holds one line naming the file or value at fault.
 *
 *   pg_prepare_config pc;  pg_prepare_defaults(&pc);
 *   pc.input = "clip.mp4"; pc.depth = "depth.npy"; pc.out = "out/prepare";
 *   pg_prepare_report pr;
 *   if (pg_prepare_run(&pc, &pr) != PG_OK) fprintf(stderr, "%s\n", pg_last_error());
 *
 * prepare -> proxies -> train -> evaluate / render / export, or all of them with resumable
 * stage markers through pg_pipeline_run (what `prodygs run` and `prodygs eval` call).
 * docs/example_pipeline.c runs the whole pipeline in-process.
 *
 * Cameras (train_camera, test_cameras, real_cameras, camera): a token equal to a camera name
 * means that camera; otherwise a plain integer is an index; anything else is an error that
 * lists the names. Reports give cameras as "name (index i)".
 */
#ifndef PRODYGS_H
#define PRODYGS_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

#define PRODYGS_VERSION "0.4.0"

typedef enum {
    PG_OK = 0,
    PG_ERR_ARG,      /* bad argument or option value (user error) */
    PG_ERR_IO,       /* file missing or unreadable */
    PG_ERR_FORMAT,   /* file content corrupt, truncated or unsupported */
    PG_ERR_SIZE,     /* dimensions disagree or exceed limits */
    PG_ERR_NOMEM,    /* allocation failed */
    PG_ERR_INTERNAL, /* a bug or an unexpected library failure */
    PG_ERR_ENV,      /* the machine, not the input: a write failed (disk full, read-only, permissions),
                        the output folder is in use, a port is taken */
    PG_STATUS_COUNT
} pg_status;

/* The message of the last failure on this thread. */
const char *pg_last_error(void);
/* Warnings (input that works but is probably not what the user meant: depth that looks like
 * disparity, a --size that stretches the frames, a variable frame rate) go to this handler;
 * by default they print "prodygs: warning: <message>" on stderr. NULL restores the default. */
typedef void (*pg_warning_handler)(const char *message, void *ctx);
void pg_set_warning_handler(pg_warning_handler handler, void *ctx);
const char *pg_status_name(pg_status code);
/* The library's PRODYGS_VERSION (a program built against another header can tell). */
const char *pg_version(void);
/* sizeof the public struct named NAME ("pg_train_config", ...), 0 for an unknown name: bindings
 * that mirror the structs (python/prodygs) check their copies against it. */
size_t pg_struct_size(const char *name);

#define PG_CAMERA_LABEL 160  /* "name (index i)" */
#define PG_CAMERA_LABELS 2048 /* a comma-separated list of labels */

/* ---- depth: per-frame depth from a monocular depth network (TFLite or ONNX) ----
 * Writes OUT (an (F,H,W) .npy, float16 when every value fits it, else float32; DEPTH: larger = farther, the model's relative units; a
 * disparity model's output is inverted) and beside it OUT minus ".npy" plus ".json" (model, kind,
 * hashes). Frames are decoded straight to the smallest size that covers the network's input (a
 * 1080p clip is never held at 1080p) and the output is written at out_width x out_height, by
 * default the network's own resolution fitted to the video's aspect: a larger map would only
 * interpolate what the network saw. Finished frames are kept in OUT.cache/ until OUT is written, so
 * an interrupted run resumes; a rerun with the same model, input and settings does nothing. */
typedef struct {
    const char *input, *model, *out; /* video, frame folder or dataset; .tflite / .onnx; .npy (required) */
    const char *train_camera; /* dataset camera (NULL: the first) */
    const char *kind;         /* the model's raw output: "depth" or "disparity" (NULL: MODEL.json or the default) */
    int size;                 /* inference size, longer side (0: the model's; a fixed-size model must match) */
    int out_width, out_height; /* output size (0, 0: the network's resolution at the video's aspect;
                                  one side 0 keeps the aspect) */
    int frames;               /* first N frames (0: all) */
    int threads;              /* 0: all cores */
    int stop_after;           /* tests: stop after computing N frames as if killed (0: off) */
} pg_depth_config;

typedef struct {
    char train_camera[PG_CAMERA_LABEL], model_name[128], kind[16];
    int frames, computed, reused, width, height, model_width, model_height, threads;
    int decode_width, decode_height; /* the size frames were decoded at for the network */
    int finished;             /* 0 after stop_after */
    int skipped;              /* 1: OUT was already current */
    double seconds, ms_per_frame;
} pg_depth_report;

void pg_depth_defaults(pg_depth_config *c);
pg_status pg_depth_run(const pg_depth_config *c, pg_depth_report *r);
/* The built-in depth network (FastDepth, MIT): written once into the user's cache folder
 * ($XDG_CACHE_HOME/prodygs, else ~/.cache/prodygs) and its path given in PATH, for a config's
 * model / depth_model when the caller names none (what the CLI does). */
pg_status pg_depth_default_model(char *path, size_t size);

/* ---- prepare: refine and temporally align per-frame depth (paper 3.1) ---- */
typedef struct {
    const char *input;        /* video, frame folder or dataset (required) */
    const char *depth;        /* per-frame depth: (F,H,W) .npy or a folder (this or depth_model) */
    const char *depth_model;  /* or: a depth network run first into OUT/depth.npy (pg_depth_run; its
                                 output is depth, so depth_kind and depth_scale do not apply) */
    const char *out;          /* output directory (required) */
    const char *train_camera; /* dataset camera (NULL: the first) */
    const char *depth_kind;   /* "depth" (default) or "disparity" */
    float depth_scale;        /* multiply raw depth by this (1) */
    const char *refine;       /* "edge-snap" (default), "bilateral" or "none" */
    int align;                /* per-frame scale/shift alignment (1) */
    int fuse;                 /* static pixels take their temporal median depth (1) */
    int planes;               /* static depth snapped onto the scene's dominant planes (1) */
    int ground;               /* the floor and the wall placed by the vertical vanishing point (1) */
    float fov;                /* single video: horizontal field of view in degrees (0: 60); datasets use their own */
    int movers_front;         /* moving blobs behind the still scene they cover brought in front (1) */
    int frames;               /* first N frames (0: all) */
    int width, height;        /* resize (0, 0: keep; one side 0 keeps the aspect) */
    int threads;              /* worker threads (0: all cores) */
    int keep_flow_vis;        /* keep flow fields for vis/flow_*.png (1; off above 1 GiB) */
} pg_prepare_config;

typedef struct {
    char train_camera[PG_CAMERA_LABEL];
    int frames, width, height, reference, fallback_frames, threads;
    double residual_before, residual_after, seconds;
} pg_prepare_report;

void pg_prepare_defaults(pg_prepare_config *c);
pg_status pg_prepare_run(const pg_prepare_config *c, pg_prepare_report *r);

/* ---- proxies: virtual views rendered from each RGB-D frame (paper 3.2) ---- */
typedef struct {
    const char *input, *depth, *out; /* depth: prepare's depth_aligned.npy (required) */
    const char *train_camera;        /* NULL: the first */
    const char *test_cameras;        /* held out, never used (NULL: cam05,cam06 on a >= 7-camera dataset) */
    const char *poses;               /* "hemisphere" or "dataset" (NULL: dataset for a multi-camera input) */
    int proxies;                     /* proxy cameras (-1: 18 on the hemisphere, every other camera for dataset) */
    float max_angle;                 /* hemisphere cap angle in degrees (20) */
    float fov;                       /* single video: horizontal field of view in degrees (60) */
    float pad;                       /* outpainted margin, fraction of the larger side (< 0: default 0.3) */
    float pose_scale;                /* pose units per user depth unit (0: fitted on a dataset, 1 otherwise) */
    double depth_unit;               /* the user's length per value of the depth file (0: prepare.json's
                                        source.depth_unit beside it, else 1) */
    const char *render;              /* proxy renderer: "mesh" (NULL: default) or "splat" (the paper's
                                        per-frame Gaussians, fitted with fit_steps / fit_block) */
    int fit_steps, fit_block;        /* splat: per-frame fit Adam steps (50), pixel block (1) */
    int frames, width, height, threads, force; /* force: recompute cached frames */
    int diagnose;                    /* dataset poses: score each proxy against its camera's real
                                        frames (OUT/diagnose.json, OUT/vis/) */
    int pose_shift;                  /* dataset poses, evaluation only: the paper's global scale-and-shift
                                        alignment to COLMAP's points at the known poses when COLMAP is
                                        installed (1); 0 or no COLMAP: a photometric scale alone */
} pg_proxies_config;

typedef struct {
    char train_camera[PG_CAMERA_LABEL], test_cameras[PG_CAMERA_LABELS], poses[16];
    int frames, computed, reused, proxies, threads, pose_scale_fitted;
    double pose_scale, pose_scale_cost, mean_valid_fraction, seconds;
    double mean_source_psnr;         /* splat: fitted model vs the real frame; NaN for mesh */
    int diagnosed_views;             /* diagnose: proxies scored against their camera's real frames */
    double diagnose_psnr_reprojected, diagnose_psnr_guessed, diagnose_psnr_moving; /* pooled; NaN: none */
    double pose_shift;               /* fitted disparity shift per user depth unit (0: none):
                                        pose depth = pose_scale * d / (1 + pose_shift * d) */
    char pose_fit[160];              /* how: "COLMAP scale and shift (N points, ...)", "photometric scale", "given", "none" */
} pg_proxies_report;

void pg_proxies_defaults(pg_proxies_config *c);
pg_status pg_proxies_run(const pg_proxies_config *c, pg_proxies_report *r);

/* ---- train: canonical Gaussians + HexPlane deformation (paper 3.3) ---- */
typedef struct {
    const char *input;      /* training set (proxies' output) or a DyNeRF dataset (required) */
    const char *out;        /* model directory (required) */
    int iters;              /* total iterations, coarse included (3000) */
    int coarse_iters;       /* static iterations first (-1: iters / 6) */
    int densify_until;      /* no densification from this iteration on (0: 70 % of iters) */
    int resume;             /* continue from OUT/model.ckpt when it exists */
    int threads;            /* 0: all cores */
    int seed;               /* (1) */
    int max_gaussians, init_points, checkpoint_every;
    int sh_degree;          /* largest SH degree of the colours (-1: 3 with several real cameras, 0 with one) */
    int proxies;            /* training set: use N of the proxy views, evenly spaced (-1: all) */
    const char *real_cameras, *test_cameras, *depth; /* DyNeRF input only */
    int frames, width;      /* DyNeRF input: first N frames, resize to this width (0: all / keep) */
    int views_per_step;     /* real view + proxies of one time per deformation (2) */
    int times_per_step;     /* times (deformations) per optimiser step (0: the trainer's default) */
    int motion_crops;       /* motion crops per fine step (-1: the trainer's default) */
    float real_weight, moving_weight, lambda_depth, lambda_dssim; /* < 0: defaults */
    float proxy_moving_weight; /* loss weight of proxy pixels showing the real view's movers (< 0: default) */
    int deform_res, deform_width, static_check_every; /* 0: defaults / off */
    int deform_head_width;  /* hidden width of each deformation head (0: the trainer's default, 32) */
    int deform_tres;        /* HexPlane time texels (0: the trainer's rule, train_time_texels) */
    int deform_time_coarsen; /* coarse scale's time rows: 1 per 2^k of the fine scale's (-1: the trainer's, 2) */
    float deform_time_warmup; /* share of the fine stage on a quarter of the time rows (< 0: the trainer's, 0.4) */
    float densify_movable;  /* movable Gaussians' densification threshold / the still ones' (< 0: the trainer's) */
    int proxy_downscale;    /* proxies train at 1/this of the working size per side, 1 or 2 (0: the trainer's, 2) */
    int use_static, use_cull; /* static Gaussians skip the network; frustum culling (1, 1) */
    int eval_train;         /* also score the real views, moving and static pixels apart */
    int stop_at_iter;       /* tests: stop after this iteration as if killed (0: off) */
    /* the full-size phase (one real view): after the iterations, the still scene and the movers at
     * the size of this source's frames (the video or dataset the training set was made from), the
     * model's cameras at that size; NULL: off */
    const char *full_size_input;
    const char *full_size_camera; /* its camera (NULL: the first) */
    int full_size_steps;    /* the movers' steps at full size (0: 4 per frame, 100 to 1200) */
} pg_train_config;

typedef struct {
    int iterations, gaussians, static_gaussians, threads, seed, finished;
    double test_psnr;       /* NaN without test cameras */
    double train_psnr, train_psnr_moving, train_psnr_static; /* NaN unless eval_train (or empty) */
    double seconds;
    /* the full-size phase: the input's size and the model scored there (NaN without the phase) */
    int full_width, full_height, full_still_added, full_movers_frozen;
    double full_psnr, full_psnr_moving, full_psnr_static, full_seconds;
    double full_psnr_before, full_psnr_moving_before; /* the working-size model drawn at that size */
} pg_train_report;

void pg_train_defaults(pg_train_config *c);
pg_status pg_train_run(const pg_train_config *c, pg_train_report *r);

/* ---- evaluate: the DyNeRF protocol on held-out cameras ---- */
typedef struct {
    const char *dataset, *model, *out; /* writes OUT/metrics.json, OUT/report.md, OUT/side_by_side */
    const char *config_json;           /* optional JSON object recorded as "config" */
    const char *stages_json;           /* optional JSON object of per-stage {seconds, threads} */
    int threads;
    const char *trainset;              /* the training set the model learnt from: its real camera's depth
                                          gives the report's 2.5D-warp baseline (NULL: no warp row) */
} pg_evaluate_config;

typedef struct {
    int frames;                 /* scored test frames */
    double psnr, ssim;          /* test cameras (NaN without) */
    double psnr_moving;         /* test cameras' moving pixels */
    double train_psnr_moving, train_psnr_static; /* the training camera */
    double seconds;
    /* the yardsticks at the same test frames (NaN: not scored): a flat image of the training
       camera's mean colour, its frame as is, its 2.5D warp with the trained-on depth */
    double flat_psnr, as_is_psnr, warp_psnr, warp_psnr_moving;
} pg_evaluate_report;

void pg_evaluate_defaults(pg_evaluate_config *c);
pg_status pg_evaluate_run(const pg_evaluate_config *c, pg_evaluate_report *r);

/* ---- render: videos of a trained model along a camera path ---- */
typedef struct {
    const char *model, *out;
    const char *path;       /* "fixed" (default), "orbit", "spiral" or "dataset-cam" */
    const char *camera;     /* dataset-cam: the camera (name or index) */
    const char *name;       /* output file stem (NULL: the path's name or the camera's) */
    const char *reference_frames; /* fixed path: folder of NNNN.png shown beside it (NULL: none) */
    int steps;              /* path frames (0: the video's frame count) */
    float angle, yaw, pitch, time, fps; /* fps 0: the input's */
    int write_depth, write_frames, threads;
    const char *camera_path; /* a camera_path.json (docs/FORMATS.md): one frame per entry; overrides path */
    int width, height;       /* output size (0, 0: the camera's; one side 0 keeps the aspect) */
} pg_render_config;

typedef struct {
    int frames, fallback_png;
    double seconds;
} pg_render_report;

void pg_render_defaults(pg_render_config *c);
pg_status pg_render_run(const pg_render_config *c, pg_render_report *r);

/* ---- export: deformed Gaussians as standard 3DGS PLY or .splat ---- */
typedef struct {
    const char *model, *out;
    const float *times; int num_times;   /* times in [0, 1] */
    const int *frames; int num_frames;   /* frames of the training video */
    int all_frames;                      /* one PLY per frame (with none of the above: time 0) */
    const char *format;                  /* "ply" (3DGS, default) or "splat" (antimatter15's 32-byte rows) */
} pg_export_config;

/* Every file holds the Gaussians visible at its time (opacity >= 1/255) with unit quaternions;
 * OUT/cameras.json is a copy of the model's cameras. */
typedef struct {
    int files, gaussians; /* gaussians: of the last file */
    int dropped;          /* invisible Gaussians left out of the last file */
    int cameras;          /* 1: cameras.json written beside the files */
} pg_export_report;

void pg_export_defaults(pg_export_config *c);
pg_status pg_export_run(const pg_export_config *c, pg_export_report *r);

/* ---- view: a self-contained web viewer (index.html + scene.pgvs) served on localhost ----
 * pg_view_run writes OUT/index.html (the WebGL2 viewer, nothing fetched from the network) and
 * OUT/scene.pgvs (docs/FORMATS.md): static Gaussians once, moving ones per time sample,
 * quantised. pg_view_serve answers http://127.0.0.1:PORT/ with those two files only. */
typedef struct {
    const char *model, *out;
    int frames;         /* time samples (0: the model's video frames) */
    int max_gaussians;  /* keep the N most visible (0: all visible) */
} pg_view_config;

typedef struct {
    int static_gaussians, moving_gaussians, dropped, frames, sh_degree;
    double scene_bytes;       /* size of scene.pgvs */
    double bytes_per_second;  /* scene bytes per second of the video (at its fps) */
    double seconds;
} pg_view_report;

void pg_view_defaults(pg_view_config *c);
pg_status pg_view_run(const pg_view_config *c, pg_view_report *r);
/* Serves DIR on 127.0.0.1:port (0: a free port) until max_requests responses were sent (0: until
 * the process ends); on_listen (may be NULL) gets the URL once the socket listens. */
pg_status pg_view_serve(const char *dir, int port, long max_requests, void (*on_listen)(const char *url, void *user),
                        void *user);

/* ---- pipeline: prepare -> proxies -> train (-> evaluate, -> render) with stage markers ----
 * Each finished stage writes OUT/<stage>.done holding its config and the content hashes of its
 * inputs; a rerun skips a stage only when both match, else reruns it and every later stage and
 * says why on stderr. Training resumes from its last checkpoint. */
typedef struct pg_pipeline_report {
    char train_camera[PG_CAMERA_LABEL], test_cameras[PG_CAMERA_LABELS];
    int width, height, iters, proxies, threads;
    int ran[6];                       /* prepare, proxies, train, evaluate, render, depth: 1 ran, 0 skipped/off */
    double seconds[6];
    pg_train_report train;
    pg_evaluate_report evaluation;
    double seconds_total;
    long peak_rss_kb;
    double disk_mib;                  /* everything under OUT after the run */
    int started;                      /* the stages began (OUT created and locked) */
} pg_pipeline_report;

typedef struct {
    const char *input, *depth, *out;  /* required (depth, or depth_model instead) */
    const char *depth_model;          /* a depth network run first into OUT/depth/depth.npy (stage
                                         "depth", rerun when the model or input changes) */
    const char *preset;               /* "fast" (default) or "quality" */
    const char *train_camera, *test_cameras;
    const char *poses;                /* NULL: dataset with test cameras, else hemisphere */
    int proxies;                      /* -1: the preset's */
    float max_angle, fov, pad, pose_scale; /* 0 (pad < 0): defaults */
    const char *proxy_render;         /* "mesh" (NULL: default) or "splat" */
    const char *depth_kind;
    float depth_scale;                /* 0: 1 */
    int refine, align, fuse, planes, ground, movers_front; /* (1, 1, 1, 1, 1, 1) */
    int pose_shift;                   /* dataset poses: scale and disparity shift to COLMAP's points (1; see pg_proxies_config) */
    int frames, width, height, iters; /* 0: all / the preset's */
    int deform_width;                 /* 0: the trainer's default */
    int deform_head_width;            /* 0: the trainer's default (32) */
    int deform_time_coarsen;          /* -1: the trainer's default (2) */
    float deform_time_warmup;         /* -1: the trainer's default (0.4) */
    float densify_movable;            /* movable Gaussians' densification threshold / the still ones' (-1: the trainer's) */
    int densify_until;                /* no densification from this step on (0: 70 % of the steps; of the preset's when a long clip raises them) */
    int proxy_downscale;              /* proxies train at 1/this of the working size per side, 1 or 2 (0: the trainer's, 2) */
    int motion_crops;                 /* motion crops per fine step (-1: the trainer's default) */
    int views_per_step;               /* views trained per deformation (the trainer's default, 2) */
    float proxy_moving_weight;        /* loss weight of proxy pixels showing the movers (-1: the trainer's, 1) */
    float real_weight;                /* share of a step's loss on the real view (-1: the trainer's, 0.75) */
    int sh_degree;                    /* largest SH degree of the colours (-1: the trainer's: 0 with one real camera) */
    int threads;                      /* 0: all cores; every stage uses this count */
    int seed;                         /* (1) */
    int evaluate;                     /* score the test cameras into OUT/metrics.json, report.md */
    int render_videos;                /* fixed/orbit/spiral videos into OUT/renders */
    int render_width, render_height;  /* their size (0, 0: the working size; one side 0 keeps the aspect) */
    const char *command;              /* recorded in report.md and metrics.json (may be NULL) */
    /* called once the cameras, size and thread count are settled, before the first stage (a
     * caller prints them; may be NULL) */
    void (*on_plan)(const struct pg_pipeline_report *plan, void *user);
    void *user;
} pg_pipeline_config;

void pg_pipeline_defaults(pg_pipeline_config *c);
pg_status pg_pipeline_run(const pg_pipeline_config *c, pg_pipeline_report *r);

#ifdef __cplusplus
}
#endif
#endif
