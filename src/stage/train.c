/* train.c - the train stage: the 4D model (canonical Gaussians + HexPlane deformation, paper
 * 3.3) on a training set from the proxies stage or on the real cameras of a DyNeRF dataset.
 * Writes OUT/model.ckpt, OUT/train.json (settings, scores, time) and OUT/cameras.json (the
 * set's cameras in the trainset.json layout), so render, export and evaluate need nothing else. */
#include "stage/stage_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/fileutil.h"
#include "core/output.h"
#include "core/parallel.h"
#include "core/status.h"
#include "io/dataset.h"
#include "io/json.h"
#include "io/trainset.h"
#include "train/train.h"
#include "train/trainset.h"
#include "train/detail.h"

void pg_train_defaults(pg_train_config *c)
{
    memset(c, 0, sizeof *c);
    c->iters = 3000;
    c->coarse_iters = -1;
    c->seed = 1;
    c->max_gaussians = 200000;
    c->init_points = 30000;
    c->checkpoint_every = 500;
    c->sh_degree = -1;
    c->proxies = -1;
    c->views_per_step = train_default_config().views_per_step;
    c->real_weight = c->moving_weight = c->lambda_depth = c->lambda_dssim = c->proxy_moving_weight = -1;
    c->use_static = c->use_cull = 1;
    c->motion_crops = -1;
    c->deform_time_coarsen = -1;
    c->deform_time_warmup = -1;
    c->densify_movable = -1;
}

cJSON *stage_train_config_json(const pg_train_config *c)
{
    cJSON *j = cJSON_CreateObject();
    const int ints[] = { c->iters, c->coarse_iters, c->seed, c->max_gaussians, c->init_points, c->sh_degree,
                         c->proxies, c->frames, c->width, c->views_per_step, c->deform_res, c->deform_width,
                         c->deform_head_width, c->static_check_every, c->use_static, c->use_cull, c->deform_tres,
                         c->times_per_step, c->motion_crops, c->deform_time_coarsen, c->densify_until,
                         c->proxy_downscale };
    static const char *int_names[] = { "iters", "coarse_iters", "seed", "max_gaussians", "init_points", "sh_degree",
                                       "proxies", "frames", "width", "views_per_step", "deform_res", "deform_width",
                                       "deform_head_width", "static_check_every", "use_static", "use_cull", "deform_tres",
                                       "times_per_step", "motion_crops", "deform_time_coarsen",
                                       "densify_until", "proxy_downscale" };
    for (size_t k = 0; k < sizeof ints / sizeof ints[0]; k++) cJSON_AddNumberToObject(j, int_names[k], ints[k]);
    const float floats[] = { c->real_weight, c->moving_weight, c->lambda_depth, c->lambda_dssim, c->proxy_moving_weight,
                             c->deform_time_warmup, c->densify_movable };
    static const char *float_names[] = { "real_weight", "moving_weight", "lambda_depth", "lambda_dssim",
                                         "proxy_moving_weight", "deform_time_warmup", "densify_movable" };
    for (size_t k = 0; k < sizeof floats / sizeof floats[0]; k++) cJSON_AddNumberToObject(j, float_names[k], floats[k]);
    cJSON_AddStringToObject(j, "real_cameras", c->real_cameras ? c->real_cameras : "");
    cJSON_AddStringToObject(j, "test_cameras", c->test_cameras ? c->test_cameras : "");
    if (c->full_size_input) { /* the source's content is the proxies' input, hashed there */
        cJSON_AddStringToObject(j, "full_size_camera", c->full_size_camera ? c->full_size_camera : "");
        cJSON_AddNumberToObject(j, "full_size_steps", c->full_size_steps);
    }
    return j;
}

static pg_status check_config(const pg_train_config *c)
{
    if (!c->input || !c->out) return pg_fail(PG_ERR_ARG, "train: input and out are required");
    if (c->iters < 1) return pg_fail(PG_ERR_ARG, "train: --iters %d must be >= 1", c->iters);
    if (c->coarse_iters < -1 || c->coarse_iters > c->iters)
        return pg_fail(PG_ERR_ARG, "train: --coarse-iters %d must be in 0..%d (--iters)", c->coarse_iters, c->iters);
    if (c->densify_until < 0 || c->densify_until > c->iters)
        return pg_fail(PG_ERR_ARG, "train: --densify-until %d must be in 0..%d (--iters)", c->densify_until, c->iters);
    if (c->init_points < 1) return pg_fail(PG_ERR_ARG, "train: --init-points %d must be >= 1", c->init_points);
    if (c->times_per_step < 0 || c->times_per_step > TRAIN_MAX_BATCH)
        return pg_fail(PG_ERR_ARG, "train: --times-per-step %d must be in 1..%d", c->times_per_step, TRAIN_MAX_BATCH);
    if (c->moving_weight != -1 && !(c->moving_weight >= 0 && c->moving_weight <= 100))
        return pg_fail(PG_ERR_ARG, "train: --moving-weight %g must be in [0, 100]", c->moving_weight);
    if (c->frames < 0) return pg_fail(PG_ERR_ARG, "train: --frames %d must be >= 1 (0 = all)", c->frames);
    if (c->width < 0 || (c->width > 0 && c->width < STAGE_MIN_SIDE) || c->width > STAGE_MAX_SIDE)
        return pg_fail(PG_ERR_ARG, "train: --width %d out of range %d..%d (0 = keep)", c->width, STAGE_MIN_SIDE, STAGE_MAX_SIDE);
    if (c->proxies < -1) return pg_fail(PG_ERR_ARG, "train: --proxies %d must be >= 0 or all", c->proxies);
    if (c->max_gaussians < 16) return pg_fail(PG_ERR_ARG, "train: --max-gaussians must be >= 16");
    PG_TRY(stage_check_threads("train", c->threads));
    if (c->seed < 0) return pg_fail(PG_ERR_ARG, "train: --seed %d must be >= 0", c->seed);
    if (c->deform_res < 0 || c->deform_res > 1024)
        return pg_fail(PG_ERR_ARG, "train: --deform-res %d out of range 0..1024", c->deform_res);
    PG_TRY(stage_check_trainer_options("train", c->deform_width, c->deform_head_width, c->deform_time_coarsen, c->deform_time_warmup,
                                       c->densify_movable, c->proxy_downscale,
                                       c->motion_crops, c->views_per_step, c->proxy_moving_weight, c->real_weight,
                                       c->sh_degree));
    if (c->deform_tres < 0 || c->deform_tres == 1 || c->deform_tres > 100000)
        return pg_fail(PG_ERR_ARG, "train: --deform-time-res %d out of range 2..100000 (0 = the trainer's rule)", c->deform_tres);
    if (c->checkpoint_every < 0) return pg_fail(PG_ERR_ARG, "train: --checkpoint-every must be >= 0");
    if (c->static_check_every < 0) return pg_fail(PG_ERR_ARG, "train: --static-check-every must be >= 0");
    if (c->full_size_steps < 0 || c->full_size_steps > 1000000)
        return pg_fail(PG_ERR_ARG, "train: --full-size-steps %d out of range 0..1000000", c->full_size_steps);
    return PG_OK;
}

/* Loads the training set: a proxies-stage directory (trainset.json) or a DyNeRF dataset, whose
 * camera lists resolve like every other camera option (names first, then indices). */
static pg_status load_set(const pg_train_config *c, train_set *ts, const char **source)
{
    char path[4096];
    if (pg_path_join(path, sizeof path, c->input, "trainset.json") == PG_OK && pg_path_exists(path)) {
        *source = "trainset";
        if (c->real_cameras || c->test_cameras)
            return pg_fail(PG_ERR_ARG, "train: %s: --real-cams/--test-cams apply to DyNeRF datasets, not training sets", c->input);
        return train_set_load(c->input, ts);
    }
    if (!(pg_path_join(path, sizeof path, c->input, "poses_bounds.npy") == PG_OK && pg_path_exists(path)))
        return pg_fail(PG_ERR_ARG, "train: %s: neither a training set (trainset.json) nor a DyNeRF dataset (poses_bounds.npy)",
                       c->input);
    *source = "dynerf";
    int tlist[64], rlist[64];
    train_set_dynerf_options o = train_set_dynerf_defaults();
    int some_real = c->real_cameras && strcmp(c->real_cameras, "all") != 0;
    if (c->test_cameras || some_real) {
        pg_dataset *ds = NULL;
        io_dataset_options dopt = io_dataset_defaults();
        PG_TRY(io_dataset_open(c->input, &dopt, &ds));
        pg_status st = PG_OK;
        if (c->test_cameras && io_dataset_resolve_cameras(ds, c->test_cameras, tlist, 64, &o.num_test) != PG_OK)
            st = pg_fail_context(PG_ERR_ARG, "train: %s: --test-cams", c->input);
        if (!st && some_real && io_dataset_resolve_cameras(ds, c->real_cameras, rlist, 64, &o.num_real) != PG_OK)
            st = pg_fail_context(PG_ERR_ARG, "train: %s: --real-cams", c->input);
        io_dataset_close(ds);
        PG_TRY(st);
        if (c->test_cameras) o.test_cams = tlist;
        if (some_real) {
            o.all_real = 0;
            o.real_cams = rlist;
        }
    }
    o.depth_path = c->depth;
    o.max_frames = c->frames;
    o.width = c->width;
    return train_set_from_dynerf(c->input, &o, ts);
}

static pg_status write_summary(const char *path, const train_set *ts, const train_config *cfg, train_session *s,
                               const pg_train_report *r, const char *source)
{
    cJSON *root = cJSON_CreateObject();
    cJSON_AddNumberToObject(root, "version", 1);
    cJSON_AddStringToObject(root, "source", source);
    cJSON_AddNumberToObject(root, "frames", ts->frames);
    cJSON_AddNumberToObject(root, "width", ts->width);
    cJSON_AddNumberToObject(root, "height", ts->height);
    cJSON_AddNumberToObject(root, "fps", ts->fps);
    cJSON_AddNumberToObject(root, "unit", ts->unit); /* the user's length per trainer length */
    cJSON_AddNumberToObject(root, "iterations", r->iterations);
    cJSON_AddNumberToObject(root, "gaussians", r->gaussians);
    cJSON_AddNumberToObject(root, "static_gaussians", r->static_gaussians);
    double md, mm;
    train_session_deform_stats(s, &md, &mm);
    cJSON_AddNumberToObject(root, "mean_deformed_per_iteration", md);
    cJSON_AddNumberToObject(root, "mean_movable_per_iteration", mm);
    int crop_frames, crop_proxies;
    double crop_area;
    train_session_motion_regions(s, &crop_frames, &crop_area, &crop_proxies);
    cJSON_AddNumberToObject(root, "motion_crops", cfg->motion_crops);
    cJSON_AddNumberToObject(root, "motion_crop_frames", crop_frames);
    cJSON_AddNumberToObject(root, "motion_crop_area", crop_area);
    cJSON_AddNumberToObject(root, "motion_crop_proxies", crop_proxies);
    cJSON_AddNumberToObject(root, "seed", (double)cfg->seed);
    cJSON_AddNumberToObject(root, "threads", r->threads);
    cJSON_AddNumberToObject(root, "coarse_iters", cfg->coarse_iters);
    cJSON_AddNumberToObject(root, "sh_degree", cfg->sh_max_degree);
    int rows, warm_rows;
    train_session_time_rows(s, &rows, &warm_rows);
    cJSON_AddNumberToObject(root, "time_rows", rows);
    cJSON_AddNumberToObject(root, "time_rows_warmup", warm_rows);
    cJSON_AddNumberToObject(root, "densify_movable", train_session_densify_movable(s));
    cJSON_AddNumberToObject(root, "proxy_downscale", cfg->proxy_downscale);
    const double scores[] = { r->test_psnr, r->train_psnr, r->train_psnr_moving, r->train_psnr_static };
    static const char *names[] = { "test_psnr", "train_real_psnr", "train_real_psnr_moving", "train_real_psnr_static" };
    for (int k = 0; k < 4; k++)
        if (isfinite(scores[k])) cJSON_AddNumberToObject(root, names[k], scores[k]);
        else cJSON_AddNullToObject(root, names[k]);
    if (r->full_width > 0) { /* the full-size phase: the model at the input's size */
        cJSON *full = cJSON_AddObjectToObject(root, "full_size");
        cJSON_AddNumberToObject(full, "width", r->full_width);
        cJSON_AddNumberToObject(full, "height", r->full_height);
        cJSON_AddNumberToObject(full, "frames_scored", TRAIN_DETAIL_SCORE_FRAMES);
        cJSON_AddNumberToObject(full, "still_added", r->full_still_added);
        cJSON_AddNumberToObject(full, "movers_frozen", r->full_movers_frozen);
        cJSON_AddNumberToObject(full, "psnr", r->full_psnr);
        cJSON_AddNumberToObject(full, "psnr_moving", r->full_psnr_moving);
        cJSON_AddNumberToObject(full, "psnr_static", r->full_psnr_static);
        cJSON_AddNumberToObject(full, "seconds", r->full_seconds);
        cJSON_AddNumberToObject(full, "psnr_before", r->full_psnr_before);
        cJSON_AddNumberToObject(full, "psnr_moving_before", r->full_psnr_moving_before);
    }
    cJSON_AddNumberToObject(root, "seconds", r->seconds);
    train_timing tt;
    train_session_timing_total(s, &tt);
    cJSON *ph = cJSON_AddObjectToObject(root, "phase_seconds"); /* this process's steps, where the time went */
    const double phases[] = { tt.targets, tt.deform_forward, tt.deform_backward, tt.regularize, tt.raster_forward,
                              tt.raster_backward, tt.loss, tt.optimizer, tt.other };
    static const char *phase_names[] = { "targets", "deform_forward", "deform_backward", "regularize", "raster_forward",
                                         "raster_backward", "loss", "optimizer", "other" };
    for (int k = 0; k < 9; k++) cJSON_AddNumberToObject(ph, phase_names[k], phases[k] * 1e-3);
    cJSON *cams = cJSON_AddArrayToObject(root, "cameras");
    for (int i = 0; i < ts->num_views; i++) {
        pg_camera user = train_set_user_camera(ts, i);
        cJSON *c = io_json_from_camera(&user, ts->views[i].name);
        if (c) cJSON_AddStringToObject(c, "role", io_view_role_name(ts->views[i].role));
        cJSON_AddItemToArray(cams, c);
    }
    char *text = cJSON_Print(root);
    cJSON_Delete(root);
    if (!text) return pg_fail(PG_ERR_NOMEM, "%s: out of memory", path);
    pg_status st = pg_write_file_atomic(path, text, strlen(text));
    free(text);
    return st;
}

/* OUT/cameras.json: the set's cameras and scene box in the trainset.json layout (no image
 * paths) and in the user's units (the model's), which renders and evaluations read next to the
 * checkpoint. */
static pg_status write_cameras(const char *dir, const train_set *ts, int width, int height)
{
    /* the model's size: the set's, or the input's after the full-size phase (intrinsics scaled) */
    const float kx = width > 0 ? (float)width / ts->width : 1.0f, ky = height > 0 ? (float)height / ts->height : 1.0f;
    io_trainset_camera *cams = pg_calloc((size_t)ts->num_views, sizeof *cams, "model cameras");
    if (!cams) return PG_ERR_NOMEM;
    int real = -1;
    for (int i = 0; i < ts->num_views; i++) {
        snprintf(cams[i].name, sizeof cams[i].name, "%s", ts->views[i].name);
        cams[i].cam = train_set_user_camera(ts, i);
        cams[i].cam.width = (int)lroundf(cams[i].cam.width * kx), cams[i].cam.height = (int)lroundf(cams[i].cam.height * ky);
        cams[i].cam.fx *= kx, cams[i].cam.cx *= kx, cams[i].cam.fy *= ky, cams[i].cam.cy *= ky;
        cams[i].role = ts->views[i].role;
        if (real < 0 && cams[i].role == IO_ROLE_REAL) real = i;
    }
    io_trainset_info info = { 0 };
    info.frames = ts->frames;
    info.width = (int)lroundf(ts->width * kx);
    info.height = (int)lroundf(ts->height * ky);
    info.fps = ts->fps;
    const float unit = train_set_unit(ts);
    info.near = ts->near_z * unit;
    info.far = ts->far_z * unit;
    if (ts->has_scene) {
        for (int k = 0; k < 3; k++) info.center[k] = ts->center[k] * unit;
        info.radius = ts->radius * unit;
    } else if (real >= 0) {
        /* no scene box: look at the middle of the depth range (1 unit ahead without one) */
        float d = info.far > info.near && info.near > 0 ? 0.5f * (info.near + info.far) : unit;
        float ahead[3] = { 0, 0, d };
        pg_camera_cam_to_world(&cams[real].cam, ahead, info.center);
        info.radius = d;
    }
    pg_status st = io_trainset_write_json_named(dir, "cameras.json", &info, cams, ts->num_views);
    free(cams);
    return st;
}

static pg_status train_run(const pg_train_config *c, pg_train_report *r)
{
    memset(r, 0, sizeof *r);
    r->test_psnr = r->train_psnr = r->train_psnr_moving = r->train_psnr_static = NAN;
    PG_TRY(check_config(c));
    r->threads = stage_use_threads(c->threads);
    r->seed = c->seed;
    double t0 = pg_time_seconds();
    train_set ts;
    const char *source = NULL;
    PG_TRY(load_set(c, &ts, &source));
    train_set_limit_proxies(&ts, c->proxies);

    train_config cfg = train_default_config();
    cfg.iters = c->iters;
    cfg.coarse_iters = c->coarse_iters >= 0 ? c->coarse_iters : train_default_coarse_iters(c->iters);
    if (c->densify_until > 0) cfg.densify_until = c->densify_until;
    cfg.seed = (uint64_t)c->seed;
    cfg.threads = r->threads;
    cfg.max_gaussians = c->max_gaussians;
    cfg.init_points = c->init_points;
    cfg.checkpoint_every = c->checkpoint_every;
    cfg.sh_max_degree = c->sh_degree >= 0 ? c->sh_degree : train_default_sh_degree(&ts);
    cfg.views_per_step = c->views_per_step;
    if (c->times_per_step > 0) cfg.times_per_step = c->times_per_step;
    if (c->motion_crops >= 0) cfg.motion_crops = c->motion_crops;
    if (c->real_weight >= 0) cfg.real_weight = c->real_weight;
    if (c->proxy_moving_weight >= 0) cfg.proxy_moving_weight = c->proxy_moving_weight;
    if (c->moving_weight >= 0) cfg.moving_weight = c->moving_weight;
    if (c->lambda_depth >= 0) cfg.lambda_depth = c->lambda_depth;
    if (c->lambda_dssim >= 0) cfg.lambda_dssim = c->lambda_dssim;
    cfg.deform_res = c->deform_res;
    cfg.deform_width = c->deform_width;
    cfg.deform_tres = c->deform_tres;
    if (c->deform_time_coarsen >= 0) cfg.deform_time_coarsen = c->deform_time_coarsen;
    if (c->deform_time_warmup >= 0) cfg.deform_time_warmup = c->deform_time_warmup;
    if (c->densify_movable > 0) cfg.densify_movable = c->densify_movable;
    if (c->proxy_downscale > 0) cfg.proxy_downscale = c->proxy_downscale;
    if (c->deform_head_width > 0) cfg.deform_head_width = c->deform_head_width;
    cfg.use_static_flags = c->use_static;
    cfg.static_check_every = c->static_check_every;
    cfg.use_frustum_cull = c->use_cull;
    cfg.stop_at_iter = c->stop_at_iter;

    train_session *s = NULL;
    char ckpt[4096], summary[4096];
    pg_status st;
    if ((st = pg_mkdir_p(c->out)) || (st = pg_path_join(ckpt, sizeof ckpt, c->out, "model.ckpt")) ||
        (st = pg_path_join(summary, sizeof summary, c->out, "train.json")))
        goto done;
    if ((st = write_cameras(c->out, &ts, 0, 0))) goto done;
    train_set_normalize_units(&ts);
    if ((st = train_session_create(&s, &ts, &cfg, ckpt, c->resume))) goto done;
    if ((st = train_session_run(s))) goto done;
    r->full_psnr = r->full_psnr_moving = r->full_psnr_static = r->full_psnr_before = r->full_psnr_moving_before = NAN;
    if (c->full_size_input && train_session_iteration(s) <= cfg.iters && !(cfg.stop_at_iter > 0)) {
        train_detail_config dc = { c->full_size_input, c->full_size_camera, c->full_size_steps, 0 };
        train_detail_scores sc;
        if ((st = train_session_detail(s, &dc, &sc))) goto done;
        r->full_width = sc.width, r->full_height = sc.height, r->full_still_added = sc.still_added;
        r->full_movers_frozen = sc.movers_frozen;
        r->full_psnr = sc.psnr, r->full_psnr_moving = sc.psnr_moving, r->full_psnr_static = sc.psnr_static;
        r->full_seconds = sc.seconds;
        r->full_psnr_before = sc.psnr_before, r->full_psnr_moving_before = sc.psnr_moving_before;
        if ((st = write_cameras(c->out, &ts, sc.width, sc.height))) goto done;
    }
    r->iterations = train_session_iteration(s);
    r->gaussians = train_session_gaussians(s);
    r->static_gaussians = train_session_static_count(s);
    if (cfg.stop_at_iter > 0 && r->iterations < cfg.iters) goto done; /* simulated kill */
    r->finished = 1;
    if (train_set_count_role(&ts, IO_ROLE_TEST) > 0 && (st = train_session_evaluate(s, IO_ROLE_TEST, &r->test_psnr)))
        goto done;
    if (c->eval_train) {
        train_eval_scores e = { 0 };
        if ((st = train_session_evaluate_parts(s, IO_ROLE_REAL, &e))) goto done;
        r->train_psnr = e.psnr;
        r->train_psnr_moving = e.psnr_moving;
        r->train_psnr_static = e.psnr_static;
    }
    r->seconds = pg_time_seconds() - t0;
    st = write_summary(summary, &ts, &cfg, s, r, source);
done:
    train_session_destroy(s);
    train_set_destroy(&ts);
    return st;
}

/* The output is claimed (checked and locked, core/output.h) before any work and held for the
 * whole stage. */
pg_status pg_train_run(const pg_train_config *c, pg_train_report *r)
{
    memset(r, 0, sizeof *r);
    if (!c->out) return train_run(c, r); /* its own check names what is missing */
    PG_TRY(pg_output_claim_dir(c->out));
    pg_status st = train_run(c, r);
    pg_output_release(c->out);
    return st;
}
