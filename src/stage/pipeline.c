/* pipeline.c - prepare -> proxies -> train (-> evaluate, -> render) as typed stage calls with
 * markers (marker.h): a stage reruns when its settings or the content of its inputs changed,
 * and then so does every stage after it. */
#include "stage/stage_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/fileutil.h"
#include "core/output.h"
#include "core/parallel.h"
#include "core/status.h"
#include "core/resources.h"
#include "io/dataset.h"
#include "train/detail.h"
#include "train/train.h"
#include "io/json.h"
#include "io/video.h"
#include "stage/marker.h"

/* warn_if_too_big's model of a run (fitted to measured runs: docs/run.md) */
#define RUN_MEM_BASE_MIB 300.0
#define RUN_MEM_PER_PIXEL 8.0   /* bytes per frame-pixel of each view */
#define RUN_DISK_PER_PIXEL 4.0
#define RUN_DISK_PER_FRAME 8192.0 /* per frame of each view: an image and a mask file, a block each at least */

/* depth is last in the report's arrays (it was added later) but runs first */
enum { ST_PREPARE, ST_PROXIES, ST_TRAIN, ST_EVALUATE, ST_RENDER, ST_DEPTH, ST_COUNT };
static const char *stage_names[ST_COUNT] = { "prepare", "proxies", "train", "evaluate", "render", "depth" };
/* each stage's output folder under OUT, for its disk use */
static const char *stage_dirs[ST_COUNT] = { "prepare", "proxies", "model", "metrics.json", "renders", "depth" };

typedef struct {
    const char *name;
    int iters;
    int proxies;  /* hemisphere proxy cameras (-1: all dataset cameras) */
    int max_side; /* shrink larger inputs so the longer side is at most this */
    int fit_steps; /* Adam steps of the proxies' per-frame fit (--proxy-render splat only) */
    int full_size; /* then the full-size phase: the still scene and the movers at the input's size */
} preset;

/* fast: minutes on 2 cores for a short clip at up to 320 px. quality: twice the steps and 18
 * proxies (all of a dataset's cameras) at the same size, ~3x the time: the real view's movers
 * gain ~4 dB and the novel views stay within 0.15 dB. More steps or 640 px did not buy novel
 * views: held out they peak at 1,000-1,500 steps on tabletop_dev and stay flat on Panoptic while
 * only the real view keeps improving (8,000 steps at 640 px: -0.24 dB held out at ~10x the
 * time; docs/train.md "Held-out views against the budget").
 * 50 fit steps give the same proxies as 100 with monocular depth (docs/proxy.md) in half the time. */
static const preset presets[] = {
    { "fast", 1500, 8, 320, 50, 0 },
    { "quality", 3000, -1, 320, 100, 0 },
    { "full", 1000, 8, 320, 50, 1 },
};

void pg_pipeline_defaults(pg_pipeline_config *c)
{
    memset(c, 0, sizeof *c);
    c->preset = "fast";
    c->proxies = -1;
    c->pad = -1;
    c->refine = c->align = c->fuse = c->planes = c->ground = c->movers_front = c->pose_shift = 1;
    c->seed = 1;
    c->motion_crops = -1;
    c->views_per_step = train_default_config().views_per_step;
    c->deform_time_coarsen = -1;
    c->deform_time_warmup = -1;
    c->densify_movable = -1;
    c->proxy_moving_weight = -1;
    c->real_weight = -1;
    c->sh_degree = -1;
}

/* What a pipeline run settles before its first stage: the cameras by name, the size and the
 * preset's numbers, so every stage gets the same values. */
typedef struct {
    char train_camera[128], test_cameras[1024];
    int width, height, iters, coarse_iters, densify_until, proxies, threads, fit_steps, full_size;
    float densify_movable; /* -1: the config's (or the trainer's rule) */
    const char *poses;
    char depth[4200];         /* the depth file prepare reads: c->depth or the depth stage's output */
} pipeline_plan;

static pg_status check_config(const pg_pipeline_config *c, const preset **p)
{
    if (!c->input || !c->out || (!c->depth && !c->depth_model)) return pg_fail(PG_ERR_ARG, "input, depth (or a depth model) and out are required");
    if (c->depth && c->depth_model) return pg_fail(PG_ERR_ARG, "give --depth or --depth-model, not both");
    if (c->iters < 0) return pg_fail(PG_ERR_ARG, "--iters must be >= 1 (got %d)", c->iters);
    if (c->densify_until < 0) return pg_fail(PG_ERR_ARG, "--densify-until must be >= 1 (got %d)", c->densify_until);
    if (c->frames < 0) return pg_fail(PG_ERR_ARG, "--frames must be >= 1 (got %d)", c->frames);
    PG_TRY(stage_check_threads("pipeline", c->threads));
    if (c->seed < 0) return pg_fail(PG_ERR_ARG, "--seed must be >= 0 (got %d)", c->seed);
    PG_TRY(stage_check_trainer_options("pipeline", c->deform_width, c->deform_head_width, c->deform_time_coarsen, c->deform_time_warmup,
                                       c->densify_movable, c->proxy_downscale,
                                       c->motion_crops, c->views_per_step, c->proxy_moving_weight, c->real_weight,
                                       c->sh_degree));
    if (c->depth_scale < 0) return pg_fail(PG_ERR_ARG, "--depth-scale must be > 0 (got %g)", c->depth_scale);
    if (c->pose_scale < 0) return pg_fail(PG_ERR_ARG, "--pose-scale must be > 0 (got %g)", c->pose_scale);
    if (c->proxy_render && strcmp(c->proxy_render, "mesh") != 0 && strcmp(c->proxy_render, "splat") != 0)
        return pg_fail(PG_ERR_ARG, "--proxy-render must be mesh or splat, not '%s'", c->proxy_render);
    if (c->max_angle < 0 || c->max_angle >= 90)
        return pg_fail(PG_ERR_ARG, "--max-angle must be in (0, 90) degrees (got %g)", c->max_angle);
    if (c->fov < 0 || c->fov >= 179) return pg_fail(PG_ERR_ARG, "--fov must be in (0, 179) degrees (got %g)", c->fov);
    if (c->pad > 1 || (c->pad < 0 && c->pad != -1)) return pg_fail(PG_ERR_ARG, "--pad must be in [0, 1] (got %g)", c->pad);
    if (c->proxies < -1 || c->proxies > 256) return pg_fail(PG_ERR_ARG, "--proxies must be in 0..256 or all (got %d)", c->proxies);
    if (c->poses && strcmp(c->poses, "hemisphere") != 0 && strcmp(c->poses, "dataset") != 0)
        return pg_fail(PG_ERR_ARG, "--poses must be hemisphere or dataset (got '%s')", c->poses);
    if (c->depth_kind && strcmp(c->depth_kind, "depth") != 0 && strcmp(c->depth_kind, "disparity") != 0)
        return pg_fail(PG_ERR_ARG, "--depth-kind must be depth or disparity (got '%s')", c->depth_kind);
    PG_TRY(stage_check_size("pipeline", "--size", c->width, c->height, 0));
    PG_TRY(stage_check_size("pipeline", "--render-size", c->render_width, c->render_height, 1));
    const char *name = c->preset ? c->preset : "fast";
    for (size_t i = 0; i < sizeof presets / sizeof presets[0]; i++)
        if (strcmp(name, presets[i].name) == 0) {
            *p = &presets[i];
            return PG_OK;
        }
    return pg_fail(PG_ERR_ARG, "unknown preset '%s' (fast, quality, full)", name);
}

/* Warns, before anything runs, when the run's estimated peak memory or disk exceeds what the
 * machine has free. The estimate is linear in frames x pixels x views, fitted to measured runs
 * (docs/run.md): the training set holds every view's frames, masks and depth in memory, and each
 * stage writes about as much again. */
static void warn_if_too_big(const char *out, int frames, int w, int h, int views)
{
    double pixels = (double)frames * w * h * views;
    double mem = RUN_MEM_BASE_MIB * 1048576.0 + RUN_MEM_PER_PIXEL * pixels;
    double disk = RUN_DISK_PER_PIXEL * pixels + RUN_DISK_PER_FRAME * frames * views;
    char dir[4200];
    snprintf(dir, sizeof dir, "%s", out);
    while (!pg_path_exists(dir) && strrchr(dir, '/')) *strrchr(dir, '/') = '\0'; /* the nearest existing parent */
    if (!pg_path_exists(dir)) snprintf(dir, sizeof dir, ".");
    double have_mem = (double)pg_mem_available_bytes(), have_disk = (double)pg_disk_free_bytes(dir);
    if (have_mem > 0 && mem > have_mem)
        pg_warn("this run needs about %.1f GiB of memory (%d frames of %dx%d, %d views) but %.1f GiB is available: "
                "use --frames, --size or fewer --proxies", mem / 1073741824.0, frames, w, h, views, have_mem / 1073741824.0);
    if (have_disk > 0 && disk > have_disk)
        pg_warn("this run writes about %.1f GiB under %s but %.1f GiB is free there", disk / 1073741824.0, out,
                have_disk / 1073741824.0);
}

/* Resolves the cameras once (a name wins over an index) and picks the training size: an even
 * WxH with the input's aspect and the longer side at most the preset's. */
static pg_status make_plan(const pg_pipeline_config *c, const preset *p, pipeline_plan *plan, pg_pipeline_report *r)
{
    memset(plan, 0, sizeof *plan);
    pg_dataset *ds = NULL;
    io_dataset_options opt = io_dataset_defaults();
    PG_TRY(io_dataset_open(c->input, &opt, &ds));
    int cam = 0, tests[64], nt = 0;
    pg_status st = PG_OK;
    if (c->train_camera && io_dataset_resolve_camera(ds, c->train_camera, &cam) != PG_OK)
        st = pg_fail_context(PG_ERR_ARG, "%s: --train-cam", c->input);
    if (!st && c->test_cameras && io_dataset_resolve_cameras(ds, c->test_cameras, tests, 64, &nt) != PG_OK)
        st = pg_fail_context(PG_ERR_ARG, "%s: --test-cams", c->input);
    for (int k = 0; !st && k < nt; k++)
        if (tests[k] == cam)
            st = pg_fail(PG_ERR_ARG, "%s: camera %s is both the training camera and a test camera", c->input,
                         io_dataset_camera_name(ds, cam));
    if (!st) {
        snprintf(plan->train_camera, sizeof plan->train_camera, "%s", io_dataset_camera_name(ds, cam));
        io_dataset_camera_label(ds, cam, r->train_camera, sizeof r->train_camera);
        for (int k = 0; k < nt; k++) {
            char label[PG_CAMERA_LABEL];
            io_dataset_camera_label(ds, tests[k], label, sizeof label);
            size_t a = strlen(plan->test_cameras), b = strlen(r->test_cameras);
            snprintf(plan->test_cameras + a, sizeof plan->test_cameras - a, "%s%s", k ? "," : "", io_dataset_camera_name(ds, tests[k]));
            snprintf(r->test_cameras + b, sizeof r->test_cameras - b, "%s%s", k ? ", " : "", label);
        }
        io_dataset_kind kind = io_dataset_get_kind(ds);
        if (kind == IO_DATASET_VIDEO || kind == IO_DATASET_FOLDER) {
            /* proxies' baselines and the scene's shape follow from it: say which one was used */
            if (c->fov > 0) fprintf(stderr, "prodygs: field of view %g degrees (--fov)\n", c->fov);
            else fprintf(stderr, "prodygs: field of view 60 degrees (the default: %s records none; give --fov if you know it)\n",
                         c->input);
        }
        plan->width = c->width;
        plan->height = c->height;
        int w = io_dataset_width(ds), h = io_dataset_height(ds), side = w > h ? w : h;
        if (!c->width && !c->height && side > p->max_side) {
            plan->width = (int)((double)w * p->max_side / side + 0.5) & ~1;
            plan->height = (int)((double)h * p->max_side / side + 0.5) & ~1;
        }
    }
    int frames = c->frames > 0 ? c->frames : io_dataset_num_frames(ds), cams = io_dataset_num_cameras(ds);
    io_video_options vo = io_video_defaults(); /* the working size, as the stages will resize */
    vo.width = plan->width;
    vo.height = plan->height;
    int fw, fh;
    io_video_target_size(&vo, io_dataset_width(ds), io_dataset_height(ds), &fw, &fh);
    io_dataset_close(ds);
    PG_TRY(st);
    plan->iters = c->iters;
    plan->coarse_iters = -1; /* the trainer's default */
    plan->densify_until = 0;
    plan->densify_movable = c->densify_movable;
    if (c->iters <= 0) { /* the preset's, raised for a long clip; the coarse (still) stage stays the preset's */
        int crops = c->motion_crops >= 0 ? c->motion_crops : train_default_config().motion_crops;
        train_budget b = train_budget_for_clip(p->iters, frames, crops, (long)fw * fh);
        plan->iters = b.iters;
        plan->coarse_iters = b.coarse_iters;
        plan->densify_until = b.densify_until;
        /* a budget past the preset's cap (a long clip at a small working size) keeps a long
         * clip's movers' density: its steps, not its Gaussians, fit the motion (the 300-frame
         * sample clip: 37.28 dB on the movers in 638 s of training at 3x, 39.40 in 949 s at 1x;
         * docs/train.md) */
        if (plan->densify_movable == -1 && (long)b.iters * 3 > (long)p->iters * TRAIN_MAX_BUDGET_THIRDS)
            plan->densify_movable = TRAIN_LONG_CLIP_DENSIFY_MOVABLE;
        if (plan->iters > p->iters)
            fprintf(stderr, "prodygs: %d training iterations (the %s preset's %d, raised for %d frames: each frame's "
                    "motion is fitted ~%d times; densification stops at the preset's %d; --iters to choose)\n",
                    plan->iters, p->name, p->iters, frames,
                    (plan->iters - plan->coarse_iters) * train_fits_per_step(crops) / (frames > 0 ? frames : 1),
                    plan->densify_until);
    }
    if (c->densify_until > 0) plan->densify_until = c->densify_until;
    plan->fit_steps = p->fit_steps;
    plan->full_size = p->full_size;
    plan->proxies = c->proxies >= 0 ? c->proxies : (nt > 0 ? -1 : p->proxies);
    plan->poses = c->poses ? c->poses : nt > 0 ? "dataset" : "hemisphere";
    plan->threads = stage_use_threads(c->threads);
    int views = 1 + (plan->proxies >= 0 ? plan->proxies : cams);
    warn_if_too_big(c->out, frames, fw, fh, views);
    r->width = plan->width;
    r->height = plan->height;
    r->iters = plan->iters;
    r->proxies = plan->proxies;
    r->threads = plan->threads;
    return PG_OK;
}

/* The pipeline's view of one stage: its marker decides whether it runs. */
typedef struct {
    const pg_pipeline_config *c;
    pg_pipeline_report *r;
    cJSON *stages; /* {stage: {seconds, threads, ran, peak_mib, disk_mib}} for metrics.json and report.md */
    int rerun_rest;
    pg_peak_window window; /* the running stage's memory */
} pipeline_run;

/* Records a stage's peak memory (its window's) and its folder's disk use into me and extra (the
 * marker, so a skipped stage still reports them). */
static void record_resources(pipeline_run *p, int stage, cJSON *me, cJSON *extra)
{
    long kb = pg_peak_window_end(&p->window);
    char dir[4300];
    snprintf(dir, sizeof dir, "%s/%s", p->c->out, stage_dirs[stage]);
    double peak = kb / 1024.0, disk = (double)pg_dir_bytes(dir) / (1024.0 * 1024.0);
    cJSON_AddNumberToObject(me, "peak_mib", peak);
    cJSON_AddNumberToObject(me, "disk_mib", disk);
    if (extra) {
        cJSON_AddNumberToObject(extra, "peak_mib", peak);
        cJSON_AddNumberToObject(extra, "disk_mib", disk);
    }
}

/* 1 when the stage can be skipped; otherwise logs why it runs, and from then on every later
 * stage runs too (its inputs are being rebuilt). */
static int stage_is_current(pipeline_run *p, int stage, const cJSON *config, const cJSON *inputs)
{
    char why[512];
    const char *name = stage_names[stage];
    if (!p->rerun_rest && stage_marker_matches(p->c->out, name, "done", config, inputs, why, sizeof why)) {
        fprintf(stderr, "prodygs: %s: already done with these settings and inputs, skipping\n", name);
        p->r->seconds[stage] = stage_marker_number(p->c->out, name, "seconds");
        cJSON *me = cJSON_AddObjectToObject(p->stages, name);
        cJSON_AddNumberToObject(me, "seconds", p->r->seconds[stage]);
        cJSON_AddNumberToObject(me, "threads", stage_marker_number(p->c->out, name, "threads"));
        cJSON_AddBoolToObject(me, "ran", 0);
        cJSON_AddNumberToObject(me, "peak_mib", stage_marker_number(p->c->out, name, "peak_mib"));
        cJSON_AddNumberToObject(me, "disk_mib", stage_marker_number(p->c->out, name, "disk_mib"));
        return 1;
    }
    /* a first run says nothing; a rerun says why the earlier result does not count */
    if (p->rerun_rest) snprintf(why, sizeof why, "an earlier stage ran again");
    char path[4200];
    snprintf(path, sizeof path, "%s/%s.done", p->c->out, name);
    if (pg_path_exists(path)) fprintf(stderr, "prodygs: %s: running again: %s\n", name, why);
    p->rerun_rest = 1;
    stage_marker_remove(p->c->out, name, "done");
    pg_peak_window_end(&p->window);
    pg_peak_window_begin(&p->window);
    return 0;
}

static pg_status stage_finished(pipeline_run *p, int stage, const cJSON *config, const cJSON *inputs, double seconds,
                                int threads)
{
    const char *name = stage_names[stage];
    p->r->ran[stage] = 1;
    p->r->seconds[stage] = seconds;
    cJSON *extra = cJSON_CreateObject();
    cJSON_AddNumberToObject(extra, "seconds", seconds);
    cJSON_AddNumberToObject(extra, "threads", threads);
    cJSON *me = cJSON_AddObjectToObject(p->stages, name);
    cJSON_AddNumberToObject(me, "seconds", seconds);
    cJSON_AddNumberToObject(me, "threads", threads);
    cJSON_AddBoolToObject(me, "ran", 1);
    record_resources(p, stage, me, extra);
    pg_status st = stage_marker_write(p->c->out, name, "done", config, inputs, extra);
    cJSON_Delete(extra);
    return st;
}

/* The content hashes of a stage's two inputs. */
static pg_status hash_inputs(cJSON **inputs, const char *name_a, const char *path_a, const char *name_b, const char *path_b)
{
    *inputs = cJSON_CreateObject();
    PG_TRY(stage_hash_input(*inputs, name_a, path_a));
    return stage_hash_input(*inputs, name_b, path_b);
}

static pg_status run_prepare(pipeline_run *p, const pipeline_plan *plan, const char *dir)
{
    const pg_pipeline_config *c = p->c;
    pg_prepare_config pc;
    pg_prepare_defaults(&pc);
    pc.input = c->input;
    pc.depth = plan->depth;
    pc.out = dir;
    pc.train_camera = plan->train_camera;
    if (c->depth_kind && !c->depth_model) pc.depth_kind = c->depth_kind; /* a model's output is depth */
    if (c->depth_scale > 0 && !c->depth_model) pc.depth_scale = c->depth_scale;
    if (!c->refine) pc.refine = "none";
    pc.align = c->align;
    pc.fuse = c->fuse;
    pc.planes = c->planes;
    pc.ground = c->ground;
    pc.fov = c->fov;
    pc.movers_front = c->movers_front;
    pc.frames = c->frames;
    pc.width = plan->width;
    pc.height = plan->height;
    pc.threads = plan->threads;
    cJSON *config = stage_prepare_config_json(&pc), *inputs;
    pg_status st = hash_inputs(&inputs, "input", c->input, "depth", plan->depth);
    if (!st && !stage_is_current(p, ST_PREPARE, config, inputs)) {
        pg_prepare_report pr;
        st = pg_prepare_run(&pc, &pr);
        if (!st) st = stage_finished(p, ST_PREPARE, config, inputs, pr.seconds, pr.threads);
    }
    cJSON_Delete(config);
    cJSON_Delete(inputs);
    return st;
}

/* The depth network into OUT/depth/depth.npy; its marker holds the model's and the input's
 * content hashes, so a new model reruns it and (through the depth file's hash) every stage after. */
static pg_status run_depth(pipeline_run *p, pipeline_plan *plan, const char *dir)
{
    const pg_pipeline_config *c = p->c;
    PG_TRY(pg_path_join(plan->depth, sizeof plan->depth, dir, "depth.npy"));
    pg_depth_config dc;
    pg_depth_defaults(&dc);
    dc.input = c->input;
    dc.model = c->depth_model;
    dc.out = plan->depth;
    dc.train_camera = plan->train_camera;
    dc.frames = c->frames;
    dc.threads = plan->threads;
    dc.out_width = plan->width; /* prepare reads depth at its working size: nothing larger is kept */
    dc.out_height = plan->height;
    /* the model is keyed on its content (inputs), not its path: the built-in one's path follows
     * XDG_CACHE_HOME */
    cJSON *config = cJSON_CreateObject(), *inputs;
    cJSON_AddStringToObject(config, "train_camera", plan->train_camera);
    cJSON_AddNumberToObject(config, "frames", c->frames);
    cJSON_AddNumberToObject(config, "width", plan->width);
    cJSON_AddNumberToObject(config, "height", plan->height);
    pg_status st = hash_inputs(&inputs, "input", c->input, "depth_model", c->depth_model);
    if (!st && !stage_is_current(p, ST_DEPTH, config, inputs)) {
        pg_depth_report dr;
        st = pg_mkdir_p(dir);
        if (!st) st = pg_depth_run(&dc, &dr);
        if (!st) st = stage_finished(p, ST_DEPTH, config, inputs, dr.seconds, dr.threads);
    }
    cJSON_Delete(config);
    cJSON_Delete(inputs);
    return st;
}

static pg_status run_proxies(pipeline_run *p, const pipeline_plan *plan, const char *prepare_dir, const char *dir)
{
    const pg_pipeline_config *c = p->c;
    char depth[4200];
    PG_TRY(pg_path_join(depth, sizeof depth, prepare_dir, "depth_aligned.npy"));
    pg_proxies_config xc;
    pg_proxies_defaults(&xc);
    xc.input = c->input;
    xc.depth = depth;
    xc.out = dir;
    xc.train_camera = plan->train_camera;
    xc.test_cameras = plan->test_cameras[0] ? plan->test_cameras : NULL;
    xc.poses = plan->poses;
    xc.proxies = plan->proxies;
    if (c->max_angle > 0) xc.max_angle = c->max_angle;
    if (c->fov > 0) xc.fov = c->fov;
    if (c->pad >= 0) xc.pad = c->pad;
    xc.fit_steps = plan->fit_steps;
    xc.render = c->proxy_render;
    xc.pose_scale = c->pose_scale;
    xc.pose_shift = c->pose_shift;
    PG_TRY(stage_depth_unit(depth, &xc.depth_unit)); /* in the config: a new --depth-scale reruns proxies */
    xc.frames = c->frames;
    xc.width = plan->width;
    xc.height = plan->height;
    xc.threads = plan->threads;
    cJSON *config = stage_proxies_config_json(&xc), *inputs;
    pg_status st = hash_inputs(&inputs, "input", c->input, "depth", depth);
    if (!st && !stage_is_current(p, ST_PROXIES, config, inputs)) {
        pg_proxies_report xr;
        st = pg_proxies_run(&xc, &xr);
        if (!st) st = stage_finished(p, ST_PROXIES, config, inputs, xr.seconds, xr.threads);
    }
    cJSON_Delete(config);
    cJSON_Delete(inputs);
    return st;
}

/* A finished training's figures from its train.json, when the stage is already done. */
static pg_status read_train_scores(const char *dir, pg_train_report *r)
{
    char path[4200];
    cJSON *root = NULL;
    PG_TRY(pg_path_join(path, sizeof path, dir, "train.json"));
    PG_TRY(io_json_load(path, &root));
    double v;
    if (!io_json_get_number(root, "iterations", path, &v)) r->iterations = (int)v;
    if (!io_json_get_number(root, "gaussians", path, &v)) r->gaussians = (int)v;
    if (!io_json_get_number(root, "static_gaussians", path, &v)) r->static_gaussians = (int)v;
    if (!io_json_get_number(root, "train_real_psnr", path, &v)) r->train_psnr = v;
    if (!io_json_get_number(root, "train_real_psnr_moving", path, &v)) r->train_psnr_moving = v;
    if (!io_json_get_number(root, "train_real_psnr_static", path, &v)) r->train_psnr_static = v;
    const cJSON *full = cJSON_GetObjectItem(root, "full_size");
    if (cJSON_IsObject(full)) {
        r->full_width = (int)io_json_number_or(full, "width", 0);
        r->full_height = (int)io_json_number_or(full, "height", 0);
        r->full_still_added = (int)io_json_number_or(full, "still_added", 0);
        r->full_psnr = io_json_number_or(full, "psnr", NAN);
        r->full_psnr_moving = io_json_number_or(full, "psnr_moving", NAN);
        r->full_psnr_static = io_json_number_or(full, "psnr_static", NAN);
        r->full_seconds = io_json_number_or(full, "seconds", NAN);
        r->full_psnr_before = io_json_number_or(full, "psnr_before", NAN);
        r->full_psnr_moving_before = io_json_number_or(full, "psnr_moving_before", NAN);
    }
    cJSON_Delete(root);
    return PG_OK;
}

/* Training resumes its checkpoint only when OUT/train.started shows the same settings and
 * inputs (an interrupted run); a checkpoint of other settings or data is removed first. */
static pg_status run_train(pipeline_run *p, const pipeline_plan *plan, const char *proxies_dir, const char *dir)
{
    const pg_pipeline_config *c = p->c;
    char set_file[4200], proxies_done[4200];
    PG_TRY(pg_path_join(set_file, sizeof set_file, proxies_dir, "trainset.json"));
    snprintf(proxies_done, sizeof proxies_done, "%s/proxies.done", c->out);
    pg_train_config tc;
    pg_train_defaults(&tc);
    tc.input = proxies_dir;
    tc.out = dir;
    tc.iters = plan->iters;
    tc.coarse_iters = plan->coarse_iters;
    tc.densify_until = plan->densify_until;
    tc.deform_width = c->deform_width;
    tc.deform_head_width = c->deform_head_width;
    tc.motion_crops = c->motion_crops;
    tc.views_per_step = c->views_per_step;
    tc.deform_time_coarsen = c->deform_time_coarsen;
    tc.deform_time_warmup = c->deform_time_warmup;
    tc.densify_movable = plan->densify_movable;
    tc.proxy_downscale = c->proxy_downscale;
    tc.proxy_moving_weight = c->proxy_moving_weight;
    tc.real_weight = c->real_weight;
    tc.sh_degree = c->sh_degree;
    tc.seed = c->seed;
    tc.threads = plan->threads;
    tc.eval_train = 1; /* the training camera's moving/static PSNR: whether the motion was captured */
    if (plan->full_size) { /* the source's frames at their own size, after the working size */
        tc.full_size_input = c->input;
        tc.full_size_camera = plan->train_camera;
    }
    /* the proxies' marker holds the hashes of the video and depth they were made from */
    cJSON *config = stage_train_config_json(&tc), *inputs;
    pg_status st = hash_inputs(&inputs, "trainset", set_file, "proxies", proxies_done);
    if (!st && !stage_is_current(p, ST_TRAIN, config, inputs)) {
        char why[512], ckpt[4200];
        st = pg_path_join(ckpt, sizeof ckpt, dir, "model.ckpt");
        tc.resume = stage_marker_matches(c->out, "train", "started", config, inputs, why, sizeof why);
        if (!st && !tc.resume && pg_path_exists(ckpt)) {
            fprintf(stderr, "prodygs: train: starting over; the checkpoint in %s is from another run (%s)\n", dir, why);
            remove(ckpt);
        }
        if (!st) st = stage_marker_write(c->out, "train", "started", config, inputs, NULL);
        if (!st) st = pg_train_run(&tc, &p->r->train);
        if (!st && p->r->train.finished)
            st = stage_finished(p, ST_TRAIN, config, inputs, p->r->train.seconds, p->r->train.threads);
        if (!st && !p->r->train.finished) st = pg_fail(PG_ERR_INTERNAL, "train: stopped before the last iteration");
    } else if (!st) {
        st = read_train_scores(dir, &p->r->train);
    }
    cJSON_Delete(config);
    cJSON_Delete(inputs);
    return st;
}

static cJSON *config_record(const pg_pipeline_config *c, const pipeline_plan *plan, const pg_pipeline_report *r)
{
    cJSON *j = cJSON_CreateObject();
    if (c->command) cJSON_AddStringToObject(j, "command", c->command);
    cJSON_AddStringToObject(j, "input", c->input);
    if (c->depth) cJSON_AddStringToObject(j, "depth", c->depth);
    if (c->depth_model) cJSON_AddStringToObject(j, "depth_model", c->depth_model);
    cJSON_AddStringToObject(j, "preset", c->preset ? c->preset : "fast");
    cJSON_AddStringToObject(j, "train_camera", r->train_camera);
    if (r->test_cameras[0]) cJSON_AddStringToObject(j, "test_cameras", r->test_cameras);
    cJSON_AddStringToObject(j, "poses", plan->poses);
    cJSON_AddNumberToObject(j, "proxies", plan->proxies);
    if (c->pad >= 0) cJSON_AddNumberToObject(j, "pad", c->pad);
    cJSON_AddStringToObject(j, "proxy_render", c->proxy_render ? c->proxy_render : "mesh");
    cJSON_AddBoolToObject(j, "refine", c->refine);
    cJSON_AddBoolToObject(j, "align", c->align);
    cJSON_AddBoolToObject(j, "fuse", c->fuse);
    cJSON_AddBoolToObject(j, "planes", c->planes);
    cJSON_AddBoolToObject(j, "ground", c->ground);
    cJSON_AddBoolToObject(j, "movers_front", c->movers_front);
    cJSON_AddNumberToObject(j, "iters", plan->iters);
    cJSON_AddNumberToObject(j, "frames", c->frames);
    if (plan->width || plan->height) {
        char size[32];
        snprintf(size, sizeof size, "%dx%d", plan->width, plan->height);
        cJSON_AddStringToObject(j, "size", size);
    }
    if (c->render_width || c->render_height) {
        char size[32];
        snprintf(size, sizeof size, "%dx%d", c->render_width, c->render_height);
        cJSON_AddStringToObject(j, "render_size", size);
    }
    cJSON_AddNumberToObject(j, "threads", plan->threads);
    cJSON_AddNumberToObject(j, "seed", c->seed);
    return j;
}

/* OUT/run.md for a run without evaluation: the command, settings, stages and peak memory. */
static pg_status write_run_report(const pg_pipeline_config *c, const cJSON *config, const cJSON *stages,
                                  const pg_pipeline_report *r)
{
    char path[4200];
    PG_TRY(pg_path_join(path, sizeof path, c->out, "report.md"));
    char *cfg = cJSON_Print(config);
    size_t cap = 16384 + (cfg ? strlen(cfg) : 0), len = 0;
    char *buf = pg_malloc(cap, "run report");
    if (!buf) {
        free(cfg);
        return PG_ERR_NOMEM;
    }
#define EMIT(...) do { if (len < cap) len += (size_t)snprintf(buf + len, cap - len, __VA_ARGS__); } while (0)
    EMIT("# prodygs run\n\n");
    if (c->command) EMIT("```\n%s\n```\n\n", c->command);
    EMIT("Training camera %s. Peak memory %.1f MiB. Disk %.1f MiB under %s. Total %.1f s.\n\n", r->train_camera,
         r->peak_rss_kb / 1024.0, r->disk_mib, c->out, r->seconds_total);
    EMIT("| stage | seconds | threads | peak memory MiB | disk MiB | |\n|---|---|---|---|---|---|\n");
    const cJSON *it;
    cJSON_ArrayForEach(it, stages)
        EMIT("| %s | %.1f | %d | %.0f | %.1f | %s |\n", it->string, cJSON_GetObjectItem(it, "seconds")->valuedouble,
             (int)cJSON_GetObjectItem(it, "threads")->valuedouble, io_json_number_or(it, "peak_mib", 0),
             io_json_number_or(it, "disk_mib", 0), cJSON_IsTrue(cJSON_GetObjectItem(it, "ran")) ? "ran" : "already done");
    if (r->train.iterations)
        EMIT("\nTraining: %d iterations, %d Gaussians (%d static).\n", r->train.iterations, r->train.gaussians,
             r->train.static_gaussians);
    if (r->train.full_width > 0)
        EMIT("\nThe model at the training camera at the input's size, %dx%d, against the decoded input frames (%d frames "
             "evenly spaced): PSNR %.2f dB; moving pixels %.2f dB, static pixels %.2f dB (moving: colour off the still "
             "scene's median by > 0.12 in a channel, dilated 2 px). Before the full-size phase, the working-size model "
             "drawn at that size: %.2f dB, moving %.2f dB. The phase added %d still Gaussians in %.0f s.\n",
             r->train.full_width, r->train.full_height, TRAIN_DETAIL_SCORE_FRAMES, r->train.full_psnr,
             r->train.full_psnr_moving, r->train.full_psnr_static, r->train.full_psnr_before,
             r->train.full_psnr_moving_before, r->train.full_still_added, r->train.full_seconds);
    if (isfinite(r->train.train_psnr))
        EMIT("\nThe model at the training camera against the input frames at the working size%s: PSNR %.2f dB; moving "
             "pixels %.2f dB, static pixels %.2f dB (moving: colour off the pixel's temporal median by > 0.12, dilated 2 px).\n",
             r->train.full_width > 0 ? " (the training set's)" : "",
             r->train.train_psnr, r->train.train_psnr_moving, r->train.train_psnr_static);
    if (cfg) EMIT("\n## Configuration\n\n```json\n%s\n```\n", cfg);
#undef EMIT
    free(cfg);
    if (len >= cap) len = cap - 1;
    pg_status st = pg_write_file_atomic(path, buf, len);
    free(buf);
    return st;
}

/* The folders a run writes under OUT besides its markers; the run claims them (core/output.h)
 * with OUT for its whole life, so a standalone stage pointed into a running pipeline is refused
 * however far the run has got. */
static const char *run_dirs[] = { "prepare", "proxies", "model", "renders", "depth" };
#define RUN_CLAIMS (1 + (int)(sizeof run_dirs / sizeof run_dirs[0]) + 1) /* OUT, the folders, depth.npy */

/* The k-th output a run claims into path: OUT, its stage folders, then the depth stage's file. */
static pg_status run_claim_path(const pg_pipeline_config *c, int k, char *path, size_t size)
{
    if (k == 0) return snprintf(path, size, "%s", c->out) < (int)size ? PG_OK : pg_fail(PG_ERR_ARG, "%s: path too long", c->out);
    if (k < RUN_CLAIMS - 1) return pg_path_join(path, size, c->out, run_dirs[k - 1]);
    return pg_path_join(path, size, c->out, "depth/depth.npy");
}

/* Claims every output of the run; *claimed counts those taken (release_run gives them back). */
static pg_status claim_run(const pg_pipeline_config *c, int *claimed)
{
    char path[4200];
    *claimed = 0;
    for (int k = 0; k < RUN_CLAIMS; k++) {
        if (k == RUN_CLAIMS - 1 && !c->depth_model) break;
        PG_TRY(run_claim_path(c, k, path, sizeof path));
        PG_TRY(k == RUN_CLAIMS - 1 ? pg_output_claim_file(path) : pg_output_claim_dir(path));
        (*claimed)++;
    }
    return PG_OK;
}

/* Gives back the run's claims, last first; a failed run that created OUT removes the folders it
 * left empty (OUT/depth made for the depth file's lock, OUT itself), so a refused run leaves
 * nothing. */
static void release_run(const pg_pipeline_config *c, int claimed, int failed, int created)
{
    char path[4200];
    for (int k = claimed - 1; k >= 0; k--)
        if (run_claim_path(c, k, path, sizeof path) == PG_OK) pg_output_release(path);
    if (failed && created && pg_path_join(path, sizeof path, c->out, "depth") == PG_OK) {
        rmdir(path); /* only when empty */
        rmdir(c->out);
    }
}

/* prepare -> proxies -> train (-> evaluate, -> render) under OUT, claimed by the caller. */
static pg_status run_stages(const pg_pipeline_config *c, const pipeline_plan *planned, pg_pipeline_report *r)
{
    pipeline_plan plan = *planned; /* run_depth fills in its depth file */
    double t0 = pg_time_seconds();
    char prepare_dir[4200], proxies_dir[4200], model_dir[4200];
    r->started = 1;
    PG_TRY(pg_path_join(prepare_dir, sizeof prepare_dir, c->out, "prepare"));
    PG_TRY(pg_path_join(proxies_dir, sizeof proxies_dir, c->out, "proxies"));
    PG_TRY(pg_path_join(model_dir, sizeof model_dir, c->out, "model"));
    pipeline_run p;
    memset(&p, 0, sizeof p);
    p.c = c;
    p.r = r;
    p.stages = cJSON_CreateObject();
    cJSON *config = config_record(c, &plan, r);
    pg_status st = PG_OK;
    if (c->depth_model) {
        char depth_dir[4200];
        st = pg_path_join(depth_dir, sizeof depth_dir, c->out, "depth");
        if (!st) st = run_depth(&p, &plan, depth_dir);
    } else
        snprintf(plan.depth, sizeof plan.depth, "%s", c->depth);
    if (!st) st = run_prepare(&p, &plan, prepare_dir);
    if (!st) st = run_proxies(&p, &plan, prepare_dir, proxies_dir);
    if (!st) st = run_train(&p, &plan, proxies_dir, model_dir);
    if (!st && c->evaluate) {
        pg_evaluate_config ec;
        pg_evaluate_defaults(&ec);
        ec.dataset = c->input;
        ec.model = model_dir;
        ec.trainset = proxies_dir;
        ec.out = c->out;
        ec.threads = plan.threads;
        char *cfg = cJSON_PrintUnformatted(config), *stages = cJSON_PrintUnformatted(p.stages);
        ec.config_json = cfg;
        ec.stages_json = stages;
        st = pg_evaluate_run(&ec, &r->evaluation);
        free(cfg);
        free(stages);
        r->ran[ST_EVALUATE] = st == PG_OK;
        r->seconds[ST_EVALUATE] = r->evaluation.seconds;
    }
    if (!st && c->render_videos) {
        static const char *paths[3] = { "fixed", "orbit", "spiral" };
        char renders[4300], reference[4500];
        snprintf(renders, sizeof renders, "%s/renders", c->out);
        snprintf(reference, sizeof reference, "%s/%s/rgb", proxies_dir, plan.train_camera);
        int fallback = 0;
        double tr = pg_time_seconds();
        pg_peak_window_begin(&p.window);
        /* the videos are one set: all of them go into renders.partial and move into renders/
         * together, so a kill or a full disk mid-orbit never leaves renders/ with fixed*.mp4 alone */
        pg_staged_dir set;
        st = pg_staged_dir_begin(&set, renders, 0);
        set.replace = 1; /* renders/ holds this run's videos only (no older size's fixed_compare.mp4) */
        for (int k = 0; k < 3 && !st; k++) {
            pg_render_config rc;
            pg_render_defaults(&rc);
            rc.model = model_dir;
            rc.out = set.work;
            rc.path = paths[k];
            rc.threads = plan.threads;
            rc.width = c->render_width;
            rc.height = c->render_height;
            /* the side-by-side of the fixed view: the input at the model's size (not after the full-size phase) */
            rc.reference_frames = k == 0 && !plan.full_size && pg_path_is_dir(reference) ? reference : NULL;
            pg_render_report rr;
            st = pg_render_run(&rc, &rr);
            fallback |= rr.fallback_png;
        }
        if (st) pg_staged_dir_abort(&set);
        else st = pg_staged_dir_commit(&set);
        if (fallback) pg_warn("no H.264/MPEG-4 encoder; wrote PNG sequences instead of MP4");
        r->ran[ST_RENDER] = st == PG_OK;
        r->seconds[ST_RENDER] = pg_time_seconds() - tr;
        cJSON *me = cJSON_AddObjectToObject(p.stages, "render");
        cJSON_AddNumberToObject(me, "seconds", r->seconds[ST_RENDER]);
        cJSON_AddNumberToObject(me, "threads", plan.threads);
        cJSON_AddBoolToObject(me, "ran", 1);
        record_resources(&p, ST_RENDER, me, NULL);
    }
    r->seconds_total = pg_time_seconds() - t0;
    pg_peak_window_end(&p.window); /* a stage that failed */
    r->peak_rss_kb = pg_peak_rss_kb();
    r->disk_mib = (double)pg_dir_bytes(c->out) / (1024.0 * 1024.0);
    if (!st && !c->evaluate) st = write_run_report(c, config, p.stages, r);
    cJSON_Delete(config);
    cJSON_Delete(p.stages);
    return st;
}

pg_status pg_pipeline_run(const pg_pipeline_config *c, pg_pipeline_report *r)
{
    memset(r, 0, sizeof *r);
    r->train.test_psnr = r->train.train_psnr = r->train.train_psnr_moving = r->train.train_psnr_static = NAN;
    r->evaluation.psnr = r->evaluation.ssim = r->evaluation.psnr_moving = NAN;
    r->evaluation.train_psnr_moving = r->evaluation.train_psnr_static = NAN;
    const preset *ps = NULL;
    PG_TRY(check_config(c, &ps));
    int created = !pg_path_exists(c->out);
    int claimed = 0;
    pg_status st = claim_run(c, &claimed);
    pipeline_plan plan;
    if (!st) st = make_plan(c, ps, &plan, r);
    if (!st && c->on_plan) c->on_plan(r, c->user);
    if (!st) st = pg_mkdir_p(c->out);
    if (!st) st = run_stages(c, &plan, r);
    release_run(c, claimed, st != PG_OK, created);
    return st;
}

