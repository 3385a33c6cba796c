/* prepare.c - the prepare stage: refine and temporally align the training camera's depth
 * (paper 3.1); writes OUT/depth_aligned.npy, static_masks.npy, prepare.json, vis/. */
#include "stage/stage_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/fileutil.h"
#include "core/output.h"
#include "core/mathx.h"
#include "core/parallel.h"
#include "core/status.h"
#include "depth/depth_check.h"
#include "depth/ground.h"
#include "depth/prepare.h"
#include "io/dataset.h"
#include "io/depth_io.h"

void pg_prepare_defaults(pg_prepare_config *c)
{
    memset(c, 0, sizeof *c);
    c->depth_kind = "depth";
    c->depth_scale = 1.0f;
    c->refine = "edge-snap";
    c->align = 1;
    c->fuse = 1;
    c->planes = 1;
    c->ground = 1;
    c->movers_front = 1;
    c->keep_flow_vis = 1;
}

cJSON *stage_prepare_config_json(const pg_prepare_config *c)
{
    cJSON *j = cJSON_CreateObject();
    cJSON_AddStringToObject(j, "train_camera", c->train_camera ? c->train_camera : "");
    cJSON_AddStringToObject(j, "depth_kind", c->depth_kind ? c->depth_kind : "depth");
    cJSON_AddNumberToObject(j, "depth_scale", c->depth_scale);
    cJSON_AddStringToObject(j, "refine", c->refine ? c->refine : "edge-snap");
    cJSON_AddBoolToObject(j, "align", c->align);
    cJSON_AddBoolToObject(j, "fuse", c->fuse);
    cJSON_AddBoolToObject(j, "planes", c->planes);
    cJSON_AddBoolToObject(j, "ground", c->ground);
    cJSON_AddNumberToObject(j, "fov", c->fov);
    cJSON_AddBoolToObject(j, "movers_front", c->movers_front);
    cJSON_AddNumberToObject(j, "frames", c->frames);
    cJSON_AddNumberToObject(j, "width", c->width);
    cJSON_AddNumberToObject(j, "height", c->height);
    return j;
}

static pg_status check_config(const pg_prepare_config *c, io_depth_kind *kind, depth_prepare_options *popt)
{
    if (!c->input || !c->depth || !c->out) return pg_fail(PG_ERR_ARG, "prepare: input, depth (or depth_model) and out are required");
    PG_TRY(stage_check_size("prepare", "--size", c->width, c->height, 0));
    PG_TRY(stage_check_threads("prepare", c->threads));
    if (c->frames < 0) return pg_fail(PG_ERR_ARG, "prepare: --frames %d must be >= 1 (0 = all)", c->frames);
    if (!(c->depth_scale > 0.0f)) return pg_fail(PG_ERR_ARG, "prepare: --depth-scale %g must be > 0", c->depth_scale);
    const char *k = c->depth_kind ? c->depth_kind : "depth";
    if (strcmp(k, "depth") == 0) *kind = IO_DEPTH_KIND_DEPTH;
    else if (strcmp(k, "disparity") == 0) *kind = IO_DEPTH_KIND_DISPARITY;
    else return pg_fail(PG_ERR_ARG, "prepare: --depth-kind must be depth or disparity, not '%s'", k);
    depth_prepare_defaults(popt);
    if (c->refine) {
        popt->refine = depth_refine_kind_parse(c->refine);
        if (popt->refine == DEPTH_REFINE_COUNT)
            return pg_fail(PG_ERR_ARG, "prepare: --refine must be edge-snap, bilateral or none, not '%s'", c->refine);
    }
    popt->align = c->align;
    popt->fuse_static = c->fuse;
    popt->snap_planes = c->planes;
    popt->ground = c->ground;
    popt->movers_front = c->movers_front;
    popt->keep_flow = c->keep_flow_vis;
    return PG_OK;
}

/* Depth passed as disparity (or the reverse) trains a scene with inverted parallax and no error
 * anywhere, so a file whose near side is at the top of most frames is pointed out. */
static void warn_if_inverted(const char *path, io_depth_kind kind, const io_depth *d)
{
    double share = depth_share_inverted_frames(d->data, d->frames, d->width, d->height);
    if (share <= 0.5) return;
    if (kind == IO_DEPTH_KIND_DEPTH)
        pg_warn("%s: looks like disparity, not depth: larger values sit at the bottom of the frame in %.0f%% of the "
                "frames; if larger means nearer, pass --depth-kind disparity", path, 100 * share);
    else
        pg_warn("%s: read as disparity, the result is nearer at the top of the frame in %.0f%% of the frames; "
                "if larger values mean farther, pass --depth-kind depth", path, 100 * share);
}

/* Brings the depth to a unit of its own (the clip's median valid depth = 1), whatever the file's
 * units and --depth-scale, so every stage after this one computes on the same numbers for the same
 * scene: a unit change cannot move a rounding, a threshold or a densification decision. The
 * factor back to the user's units (K m for depth, m / K for disparity, K = --depth-scale) is
 * returned and travels beside the data (prepare.json's source.depth_unit). */
static pg_status normalize_depth_unit(const char *path, io_depth *d, io_depth_kind kind, float scale, double *unit)
{
    size_t total = (size_t)d->frames * d->width * d->height, stride = total / 65536 + 1, n = 0;
    float *sample = pg_malloc((total / stride + 1) * sizeof(float), "depth median");
    if (!sample) return PG_ERR_NOMEM;
    for (size_t i = 0; i < total; i += stride)
        if (d->data[i] > 0) sample[n++] = d->data[i];
    float median = 0;
    if (n > 0) {
        qsort(sample, n, sizeof(float), pg_cmp_float);
        median = sample[n / 2];
    }
    free(sample);
    if (!(median > 0) || !isfinite(median)) {
        /* too sparse for the sample: the largest value is still a length of the scene */
        median = d->max;
        if (!(median > 0)) return pg_fail(PG_ERR_FORMAT, "%s: no valid depth in any frame", path);
    }
    for (size_t i = 0; i < total; i++) d->data[i] /= median;
    d->min /= median;
    d->max /= median;
    *unit = kind == IO_DEPTH_KIND_DISPARITY ? (double)median / scale : (double)median * scale;
    return PG_OK;
}

/* depth_model: the depth stage writes OUT/depth.npy (resumable, skipped when current), then
 * prepare runs on it as on any depth file. */
static pg_status prepare_with_model(const pg_prepare_config *c, pg_prepare_report *r)
{
    if (c->depth) return pg_fail(PG_ERR_ARG, "prepare: give depth or depth_model, not both");
    if (!c->input || !c->out) return pg_fail(PG_ERR_ARG, "prepare: input, depth_model and out are required");
    char path[4200];
    PG_TRY(pg_mkdir_p(c->out));
    PG_TRY(pg_path_join(path, sizeof path, c->out, "depth.npy"));
    pg_depth_config dc;
    pg_depth_defaults(&dc);
    dc.input = c->input;
    dc.model = c->depth_model;
    dc.out = path;
    dc.train_camera = c->train_camera;
    dc.frames = c->frames;
    dc.threads = c->threads;
    dc.out_width = c->width; /* the size prepare works at (0, 0: the network's) */
    dc.out_height = c->height;
    pg_depth_report dr;
    PG_TRY(pg_depth_run(&dc, &dr));
    pg_prepare_config cc = *c;
    cc.depth = path;
    cc.depth_model = NULL;
    cc.depth_kind = "depth"; /* the depth stage's output is depth whatever the model's kind */
    cc.depth_scale = 1.0f;
    PG_TRY(pg_prepare_run(&cc, r));
    r->seconds += dr.seconds;
    return PG_OK;
}

static pg_status prepare_run(const pg_prepare_config *c, pg_prepare_report *r)
{
    memset(r, 0, sizeof *r);
    if (c->depth_model) return prepare_with_model(c, r);
    io_depth_kind dkind = IO_DEPTH_KIND_DEPTH;
    depth_prepare_options popt;
    PG_TRY(check_config(c, &dkind, &popt));
    r->threads = stage_use_threads(c->threads);

    pg_dataset *ds = NULL;
    io_dataset_options dopt = io_dataset_defaults();
    dopt.width = c->width;
    dopt.height = c->height;
    dopt.count = c->frames;
    if (c->fov > 0) dopt.fov_deg = c->fov;
    PG_TRY(io_dataset_open(c->input, &dopt, &ds));
    int cam = 0;
    if (c->train_camera && io_dataset_resolve_camera(ds, c->train_camera, &cam) != PG_OK) {
        io_dataset_close(ds);
        return pg_fail_context(PG_ERR_ARG, "%s: --train-cam", c->input);
    }
    io_dataset_camera_label(ds, cam, r->train_camera, sizeof r->train_camera);
    pg_staged_dir out;
    pg_status begun = pg_staged_dir_begin(&out, c->out, 0);
    if (begun != PG_OK) {
        io_dataset_close(ds);
        return begun;
    }
    const int F = io_dataset_num_frames(ds), W = io_dataset_width(ds), H = io_dataset_height(ds);
    pg_camera camera;
    io_dataset_camera(ds, cam, &camera);
    popt.ground_params.focal = camera.fx * (float)W / (float)camera.width; /* the floor needs the focal length */
    pg_camera rig[32];
    int rig_count = io_dataset_num_cameras(ds) < 32 ? io_dataset_num_cameras(ds) : 32, ref = -1;
    for (int k = 0; k < rig_count; k++) io_dataset_camera(ds, k, &rig[k]);
    if (cam < 32) ref = cam;
    popt.ground_params.up_known = depth_ground_rig_up(rig, rig_count, ref, popt.ground_params.up);
    pg_image *frames = calloc((size_t)(F > 0 ? F : 1), sizeof(pg_image));
    io_depth depth;
    memset(&depth, 0, sizeof depth);
    depth_prepare_result res;
    memset(&res, 0, sizeof res);
    double depth_unit = 1;
    pg_status st = frames ? PG_OK : pg_fail(PG_ERR_NOMEM, "prepare: out of memory for %d frames", F);
    for (int t = 0; t < F && !st; t++) st = io_dataset_frame(ds, cam, t, &frames[t]);
    io_dataset_release(ds, -1);
    if (!st) {
        io_depth_options o = io_depth_defaults();
        o.kind = dkind;
        o.scale = 1; /* --depth-scale is a unit: it travels as source.depth_unit */
        o.width = W;
        o.height = H;
        o.count = c->frames; /* the first N depth frames go with the first N video frames */
        o.expect_frames = F;
        st = io_depth_load(c->depth, &o, &depth);
        if (!st && !(depth.max > 0))
            st = pg_fail(PG_ERR_FORMAT, "%s: no valid depth in any frame (every value is NaN, inf or <= 0)", c->depth);
        if (!st) warn_if_inverted(c->depth, dkind, &depth);
        if (!st) st = normalize_depth_unit(c->depth, &depth, dkind, c->depth_scale, &depth_unit);
    }
    /* Flow fields are kept only for the pictures; skip them when they would be large. */
    if (popt.keep_flow && (double)F * W * H * 2 * sizeof(float) > 1024.0 * 1024 * 1024) popt.keep_flow = 0;
    if (!st) st = depth_prepare_run(&popt, frames, F, depth.data, &res);
    if (!st) {
        cJSON *src = cJSON_CreateObject();
        cJSON_AddStringToObject(src, "input", c->input);
        cJSON_AddStringToObject(src, "camera", io_dataset_camera_name(ds, cam));
        cJSON_AddStringToObject(src, "depth", c->depth);
        cJSON_AddStringToObject(src, "depth_kind", c->depth_kind ? c->depth_kind : "depth");
        cJSON_AddNumberToObject(src, "depth_scale", c->depth_scale);
        cJSON_AddNumberToObject(src, "depth_unit", depth_unit);
        cJSON_AddNumberToObject(src, "depth_invalid_input_pixels", (double)depth.invalid);
        cJSON_AddNumberToObject(src, "fps", io_dataset_fps(ds));
        char *text = cJSON_PrintUnformatted(src);
        cJSON_Delete(src);
        st = depth_prepare_write(out.work, &popt, &res, frames, depth.data, text);
        free(text);
    }
    if (!st) {
        r->frames = F;
        r->width = W;
        r->height = H;
        r->reference = res.reference;
        r->seconds = res.seconds_total;
        for (int i = 0; i < F; i++) {
            r->residual_before += res.info[i].resid_before / F;
            r->residual_after += res.info[i].resid_after / F;
            r->fallback_frames += res.info[i].fallback != DEPTH_FALLBACK_NONE;
            if (res.info[i].fallback == DEPTH_FALLBACK_COPIED)
                pg_warn("frame %d has no valid depth; copied frame %d", i,
                        res.info[i].source_frame);
        }
    }
    depth_prepare_result_destroy(&res);
    io_depth_destroy(&depth);
    if (frames)
        for (int t = 0; t < F; t++) pg_image_destroy(&frames[t]);
    free(frames);
    io_dataset_close(ds);
    if (st) pg_staged_dir_abort(&out);
    else st = pg_staged_dir_commit(&out);
    return st;
}

/* The output is claimed (checked and locked, core/output.h) before any work and held for the
 * whole stage. */
pg_status pg_prepare_run(const pg_prepare_config *c, pg_prepare_report *r)
{
    memset(r, 0, sizeof *r);
    if (!c->out) return prepare_run(c, r); /* its own check names what is missing */
    PG_TRY(pg_output_claim_dir(c->out));
    pg_status st = prepare_run(c, r);
    pg_output_release(c->out);
    return st;
}
