/* render.c - the render stage: a trained model along a camera path as MP4 (or PNG) videos of
 * colour and depth, the cameras read from the model directory. */
#include "stage/stage_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/fileutil.h"
#include "core/output.h"
#include "core/status.h"
#include "io/image_io.h"
#include "render/camera_path_file.h"
#include "render/render_video.h"
#include "render/scene_cameras.h"

void pg_render_defaults(pg_render_config *c)
{
    memset(c, 0, sizeof *c);
    c->path = "fixed";
    c->angle = 15.0f;
    c->yaw = 10.0f;
    c->pitch = 5.0f;
    c->time = 0.5f;
    c->write_depth = 1;
}

/* A camera of the model by name, else by its position in the model's camera list. */
static pg_status find_camera(const scene_cameras *sc, const char *model, const char *token, int *out)
{
    *out = scene_cameras_find(sc, token);
    char *end;
    long v = strtol(token, &end, 10);
    if (*out < 0 && end != token && *end == '\0' && v >= 0 && v < sc->count) *out = (int)v;
    if (*out >= 0) return PG_OK;
    char names[1024] = "";
    for (int c = 0; c < sc->count && strlen(names) + 40 < sizeof names; c++)
        snprintf(names + strlen(names), sizeof names - strlen(names), "%s%s", c ? ", " : "", sc->names[c]);
    return pg_fail(PG_ERR_ARG, "render: %s: no camera '%.64s' (cameras: %s)", model, token, names);
}

typedef struct {
    const char *dir; /* NNNN.png frames of the input */
    int frames;
} reference_frames;

/* The fixed path's side-by-side partner: the input frame at the step's time (a path may have
 * more steps than the video has frames, e.g. 60 steps over a 1-frame input). */
static pg_status reference_frame(void *ctx, int step, float time, pg_image *img)
{
    (void)step;
    const reference_frames *ref = ctx;
    int f = ref->frames > 1 ? (int)lroundf(time * (float)(ref->frames - 1)) : 0;
    char file[32], path[4300];
    snprintf(file, sizeof file, "%04d.png", f < 0 ? 0 : f >= ref->frames ? ref->frames - 1 : f);
    PG_TRY(pg_path_join(path, sizeof path, ref->dir, file));
    return io_image_load(path, img);
}

static pg_status render_run(const pg_render_config *c, pg_render_report *r)
{
    memset(r, 0, sizeof *r);
    if (!c->model || !c->out) return pg_fail(PG_ERR_ARG, "render: model and out are required");
    render_video_options vo = { 0 };
    const char *path_name = c->path ? c->path : "fixed";
    int dataset_cam = strcmp(path_name, "dataset-cam") == 0;
    if (c->camera_path) vo.path.kind = RENDER_PATH_FIXED; /* unused: the file gives every camera */
    else if (!dataset_cam) PG_TRY(render_path_parse(path_name, &vo.path.kind));
    else if (!c->camera) return pg_fail(PG_ERR_ARG, "render: --path dataset-cam needs --camera NAME");
    if (c->time < 0 || c->time > 1) return pg_fail(PG_ERR_ARG, "render: --time must be in [0, 1], got %g", c->time);
    if (c->steps < 0 || c->steps > 100000) return pg_fail(PG_ERR_ARG, "render: --steps %d out of range 0..100000", c->steps);
    if (c->fps < 0 || c->fps > 1000) return pg_fail(PG_ERR_ARG, "render: --fps must be in (0, 1000], got %g", c->fps);
    if (c->angle < 0 || c->angle > 89) return pg_fail(PG_ERR_ARG, "render: --angle must be in [0, 89] degrees, got %g", c->angle);
    if (c->yaw < -89 || c->yaw > 89 || c->pitch < -89 || c->pitch > 89)
        return pg_fail(PG_ERR_ARG, "render: --yaw/--pitch must be in [-89, 89] degrees, got %g/%g", c->yaw, c->pitch);
    PG_TRY(stage_check_threads("render", c->threads));
    PG_TRY(stage_check_size("render", "--size", c->width, c->height, 1));
    stage_use_threads(c->threads);

    scene_cameras *sc = pg_malloc(sizeof *sc, "cameras");
    if (!sc) return PG_ERR_NOMEM;
    render_model *rm = NULL;
    pg_status st = scene_cameras_for_model(c->model, NULL, sc);
    if (st == PG_OK) st = render_model_open(c->model, &rm);
    int k = -1;
    reference_frames ref = { NULL, 1 };
    pg_camera *keys = NULL;
    float *key_times = NULL;
    if (st == PG_OK && dataset_cam && !c->camera_path) st = find_camera(sc, c->model, c->camera, &k);
    if (st == PG_OK && c->camera_path)
        st = render_camera_path_load(c->camera_path, &sc->cams[sc->real], c->width, c->height, &keys, &key_times,
                                     &vo.num_keys);
    vo.keys = keys;
    vo.key_times = key_times;
    pg_camera real = { 0 }; /* the training camera at the asked size; paths keep its intrinsics */
    if (st == PG_OK) real = sc->cams[sc->real];
    if (st == PG_OK && (c->width || c->height)) {
        int w, h;
        st = stage_resolve_size("render", "--size", c->width, c->height, real.width, real.height, 1, &w, &h);
        if (st == PG_OK && k >= 0) pg_camera_resize(&sc->cams[k], w, h);
        if (st == PG_OK) pg_camera_resize(&real, w, h);
    }
    if (st == PG_OK) {
        int frames = render_model_frames(rm);
        vo.path.steps = c->steps > 0 ? c->steps : (frames > 1 ? frames : 60);
        if (vo.path.kind == RENDER_PATH_ORBIT && c->steps == 0 && vo.path.steps < 60) vo.path.steps = 60;
        vo.path.max_angle_deg = c->angle;
        vo.path.time = c->time;
        vo.path.fixed_yaw_deg = c->yaw;
        vo.path.fixed_pitch_deg = c->pitch;
        vo.write_depth = c->write_depth;
        vo.write_frames = c->write_frames;
        vo.fps = c->fps > 0 ? c->fps : sc->fps;
        if (c->reference_frames && !dataset_cam && !keys && !c->width && !c->height &&
            vo.path.kind == RENDER_PATH_FIXED) {
            ref.dir = c->reference_frames;
            ref.frames = frames > 0 ? frames : 1;
            vo.reference = reference_frame;
            vo.reference_ctx = &ref;
        }
        const char *name = c->name ? c->name : keys ? "camera_path" : dataset_cam ? sc->names[k] : path_name;
        if (dataset_cam && !keys) {
            vo.use_camera = 1;
            vo.camera = sc->cams[k];
            if (c->steps == 0) vo.path.steps = frames > 0 ? frames : 1; /* one render per input frame */
        }
        render_video_report rep;
        pg_staged_dir out;
        st = pg_staged_dir_begin(&out, c->out, 0);
        if (st == PG_OK) {
            st = render_video_write(rm, &real, sc->center, &vo, out.work, name, &rep);
            if (st) pg_staged_dir_abort(&out);
            else st = pg_staged_dir_commit(&out);
        }
        if (st == PG_OK) {
            r->frames = rep.frames;
            r->fallback_png = rep.fallback_png;
            r->seconds = rep.seconds;
        }
    }
    render_model_close(rm);
    free(keys);
    free(key_times);
    free(sc);
    return st;
}

/* The output is claimed (checked and locked, core/output.h) before any work and held for the
 * whole stage. */
pg_status pg_render_run(const pg_render_config *c, pg_render_report *r)
{
    memset(r, 0, sizeof *r);
    if (!c->out) return render_run(c, r); /* its own check names what is missing */
    PG_TRY(pg_output_claim_dir(c->out));
    pg_status st = render_run(c, r);
    pg_output_release(c->out);
    return st;
}
