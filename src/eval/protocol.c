/* protocol.c - scores a trained model against a dataset's cameras: the held-out test cameras
 * (the headline numbers) and the real training camera, each split into moving and static pixels
 * of its own video; test pixels are also split by what the real camera saw of them. */
#include "eval/protocol.h"
#include "eval/baselines.h"
#include "core/fileutil.h"
#include "core/progress.h"
#include "depth/moving_mask.h"
#include "eval/report.h"
#include "eval/visibility.h"
#include "io/dataset.h"
#include "io/npy.h"
#include "render/model_render.h"
#include "render/scene_cameras.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    const scene_cameras *sc;
    render_model *rm;
    pg_dataset *ds;
    optim_ssim_ws *ws;
    int frames, done, total;
    const char *sbs_dir;
    float *real_z;    /* (frames, H, W) alpha-normalised depth rendered at the real camera */
    int have_real_z;
    eval_results *results;
    int real_cam;        /* the training camera in the dataset (-1: absent, no baselines) */
    double colour_sum[3]; /* over every pixel of its frames: the flat baseline's colour */
    double colour_pixels;
    const float *warp_depth; /* (frames, H, W) the trained-on depth of the real camera, pose units (NULL: no warp) */
} eval_ctx;

int eval_wants_side_by_side(int f, int frames) { return f == 0 || f == frames / 2 || f == frames - 1; }

pg_status eval_dataset_moving_masks(pg_dataset *ds, int cam, int frames, int W, int H, uint8_t **moving)
{
    size_t px = (size_t)W * H;
    uint8_t *rgb = pg_malloc((size_t)frames * px * 3, "evaluation frames");
    *moving = pg_malloc((size_t)frames * px, "moving masks");
    pg_status st = rgb && *moving ? PG_OK : PG_ERR_NOMEM;
    for (int f = 0; st == PG_OK && f < frames; f++) {
        pg_image img = {0};
        st = io_dataset_frame(ds, cam, f, &img);
        if (st == PG_OK && (img.width != W || img.height != H || img.channels != 3))
            st = pg_fail(PG_ERR_SIZE, "camera %s: frame %d is %dx%d, expected %dx%d", io_dataset_camera_name(ds, cam), f,
                         img.width, img.height, W, H);
        if (st == PG_OK) pg_image_to_rgb8(&img, rgb + (size_t)f * px * 3);
        pg_image_destroy(&img);
    }
    if (st == PG_OK) st = depth_moving_masks(rgb, frames, W, H, EVAL_MOVING_THRESH, EVAL_MOVING_DILATE, *moving);
    free(rgb);
    if (st) {
        free(*moving);
        *moving = NULL;
    }
    return st;
}

/* Scores the yardsticks of test frame f (truth, moving labels) into the results' baselines:
 * the flat mean colour, the real frame as is (when it has the test camera's size) and its warp. */
static pg_status score_baselines(eval_ctx *c, const pg_camera *pc, int f, const pg_image *truth,
                                 const uint8_t *labels, pg_image *work)
{
    const size_t px = (size_t)pc->width * pc->height;
    float mean[3];
    for (int ch = 0; ch < 3; ch++) mean[ch] = (float)(c->colour_sum[ch] / c->colour_pixels);
    eval_results *base = c->results->baseline;
    const char *name = c->sc->names[pc - c->sc->cams];
    eval_scores s;
    for (size_t i = 0; i < px; i++) memcpy(work->data + 3 * i, mean, sizeof mean);
    pg_status st = eval_score_image(c->ws, work, truth, NULL, &s);
    if (st == PG_OK) st = eval_score_regions(c->ws, work, truth, labels, EVAL_MOVING, 2, &s);
    if (st == PG_OK) st = eval_results_add(&base[EVAL_BASE_FLAT], name, EVAL_ROLE_TEST, f, &s);
    pg_image real = { 0 };
    if (st == PG_OK) st = io_dataset_frame(c->ds, c->real_cam, f, &real);
    const pg_camera *rc = &c->sc->cams[c->sc->real];
    if (st == PG_OK && real.width == pc->width && real.height == pc->height) {
        st = eval_score_image(c->ws, &real, truth, NULL, &s);
        if (st == PG_OK) st = eval_score_regions(c->ws, &real, truth, labels, EVAL_MOVING, 2, &s);
        if (st == PG_OK) st = eval_results_add(&base[EVAL_BASE_AS_IS], name, EVAL_ROLE_TEST, f, &s);
    }
    if (st == PG_OK && c->warp_depth && real.width == rc->width && real.height == rc->height) {
        st = eval_warp_baseline(rc, real.data, c->warp_depth + (size_t)f * rc->width * rc->height, pc, mean, work->data);
        if (st == PG_OK) st = eval_score_image(c->ws, work, truth, NULL, &s);
        if (st == PG_OK) st = eval_score_regions(c->ws, work, truth, labels, EVAL_MOVING, 2, &s);
        if (st == PG_OK) st = eval_results_add(&base[EVAL_BASE_WARP], name, EVAL_ROLE_TEST, f, &s);
    }
    pg_image_destroy(&real);
    return st;
}

/* Renders and scores every frame of model camera k against dataset camera `cam`. */
static pg_status score_camera(eval_ctx *c, int k, int cam, eval_role role)
{
    const scene_cameras *sc = c->sc;
    const pg_camera *pc = &sc->cams[k];
    const int W = pc->width, H = pc->height;
    const size_t px = (size_t)W * H;
    uint8_t *moving = NULL, *labels = pg_malloc(px, "evaluation labels");
    pg_image pred = {0}, truth = {0}, work = {0};
    pg_status st = labels ? PG_OK : PG_ERR_NOMEM;
    if (st == PG_OK) st = eval_dataset_moving_masks(c->ds, cam, c->frames, W, H, &moving);
    if (st == PG_OK) st = pg_image_create(&pred, W, H, 3);
    if (st == PG_OK) st = pg_image_create(&work, W, H, 3);
    for (int f = 0; st == PG_OK && f < c->frames; f++) {
        pg_render_output out;
        st = render_model_frame(c->rm, pc, train_frame_time(f, c->frames), &out);
        if (st == PG_OK) st = io_dataset_frame(c->ds, cam, f, &truth);
        if (st != PG_OK) break;
        memcpy(pred.data, out.rgb, sizeof(float) * 3 * px);
        eval_scores s;
        st = eval_score_image(c->ws, &pred, &truth, out.alpha, &s);
        for (size_t i = 0; i < px; i++) labels[i] = moving[(size_t)f * px + i] ? EVAL_MOVING : EVAL_STATIC;
        if (st == PG_OK) st = eval_score_regions(c->ws, &pred, &truth, labels, EVAL_MOVING, 2, &s);
        if (st == PG_OK && role == EVAL_ROLE_TEST && c->results->baseline && c->colour_pixels > 0)
            st = score_baselines(c, pc, f, &truth, labels, &work);
        if (role == EVAL_ROLE_TRAIN) {
            for (size_t i = 0; i < 3 * px; i++) c->colour_sum[i % 3] += truth.data[i];
            c->colour_pixels += (double)px;
            float *z = c->real_z + (size_t)f * px;
            for (size_t i = 0; i < px; i++) z[i] = out.alpha[i] > 0.5f ? out.depth[i] / out.alpha[i] : 0.0f;
        } else if (c->have_real_z) {
            eval_visibility_labels(pc, out.depth, out.alpha, &sc->cams[sc->real], c->real_z + (size_t)f * px, labels);
            if (st == PG_OK) st = eval_score_regions(c->ws, &pred, &truth, labels, EVAL_SEEN, 3, &s);
        }
        if (st == PG_OK) st = eval_results_add(c->results, sc->names[k], role, f, &s);
        if (st == PG_OK && c->sbs_dir && eval_wants_side_by_side(f, c->frames)) {
            char file[96], path[4200];
            snprintf(file, sizeof file, "%s_%04d.png", sc->names[k], f);
            st = pg_path_join(path, sizeof path, c->sbs_dir, file);
            if (st == PG_OK) st = eval_write_side_by_side(path, &truth, &pred);
        }
        pg_image_destroy(&truth);
        pg_progress_report("eval", ++c->done, c->total, "camera=%s psnr=%.2f moving=%.2f", sc->names[k], s.psnr,
                           eval_region_psnr(&s.region[EVAL_MOVING]));
    }
    /* the test cameras' baselines show the real camera's frames again: keep them decoded */
    if (!(role == EVAL_ROLE_TRAIN && c->results->baseline)) io_dataset_release(c->ds, cam);
    pg_image_destroy(&pred);
    pg_image_destroy(&work);
    free(moving);
    free(labels);
    return st;
}

/* The real camera's depth in the training set beside the model (DIR/<real>/depth.npy, pose units)
 * when it has the model's frames and size; NULL otherwise (the report then has no warp row). */
static float *load_warp_depth(const char *trainset, const char *real_name, int frames, int W, int H)
{
    char dir[4200], path[4200];
    if (!trainset || pg_path_join(dir, sizeof dir, trainset, real_name) != PG_OK ||
        pg_path_join(path, sizeof path, dir, "depth.npy") != PG_OK || !pg_path_exists(path))
        return NULL;
    pg_array a = { 0 };
    if (io_npy_load(path, &a) != PG_OK) return NULL;
    if (a.ndim == 3 && a.shape[0] >= (size_t)frames && a.shape[1] == (size_t)H && a.shape[2] == (size_t)W) {
        float *d = a.data;
        a.data = NULL;
        pg_array_destroy(&a);
        return d;
    }
    pg_array_destroy(&a);
    return NULL;
}

pg_status eval_protocol_run(const char *dataset, const char *model, const char *trainset, const char *sbs_dir,
                            eval_results *results)
{
    scene_cameras *sc = pg_malloc(sizeof *sc, "cameras");
    if (!sc) return PG_ERR_NOMEM;
    eval_ctx c = { .sc = sc, .sbs_dir = sbs_dir, .results = results };
    pg_status st = scene_cameras_for_model(model, NULL, sc);
    if (st == PG_OK) st = render_model_open(model, &c.rm);
    const pg_camera *real = &sc->cams[sc->real];
    c.frames = c.rm ? render_model_frames(c.rm) : 0;
    int tests = 0;
    for (int k = 0; st == PG_OK && k < sc->count; k++) tests += sc->roles[k] == IO_ROLE_TEST;
    if (st == PG_OK && tests == 0) st = pg_fail(PG_ERR_ARG, "%s: the model's cameras.json lists no test cameras", model);
    if (st == PG_OK) {
        io_dataset_options opt = io_dataset_defaults();
        opt.width = real->width;
        opt.height = real->height;
        opt.count = c.frames;
        st = io_dataset_open(dataset, &opt, &c.ds);
    }
    if (st == PG_OK && io_dataset_num_frames(c.ds) < c.frames)
        st = pg_fail(PG_ERR_SIZE, "%s: has %d frames, the model was trained on %d", dataset, io_dataset_num_frames(c.ds), c.frames);
    if (st == PG_OK) st = optim_ssim_create(&c.ws, real->height, real->width, 3);
    if (st == PG_OK && sbs_dir) st = pg_mkdir_p(sbs_dir);
    /* the real camera first: its renders give the depth the test pixels are checked against */
    int real_cam = st == PG_OK ? io_dataset_find_camera(c.ds, sc->names[sc->real]) : -1;
    c.real_cam = real_cam;
    c.total = (tests + (real_cam >= 0)) * c.frames;
    if (st == PG_OK && real_cam >= 0) {
        results->baseline = pg_calloc(EVAL_BASELINES, sizeof *results->baseline, "evaluation baselines");
        if (!results->baseline) st = PG_ERR_NOMEM;
        c.warp_depth = load_warp_depth(trainset, sc->names[sc->real], c.frames, real->width, real->height);
    }
    if (st == PG_OK && real_cam >= 0) {
        c.real_z = pg_malloc((size_t)c.frames * real->width * real->height * sizeof(float), "real-camera depth");
        st = c.real_z ? score_camera(&c, sc->real, real_cam, EVAL_ROLE_TRAIN) : PG_ERR_NOMEM;
        c.have_real_z = st == PG_OK;
    }
    for (int k = 0; st == PG_OK && k < sc->count; k++) {
        if (sc->roles[k] != IO_ROLE_TEST) continue;
        int cam = io_dataset_find_camera(c.ds, sc->names[k]);
        if (cam < 0) {
            st = pg_fail(PG_ERR_ARG, "%s: no camera named %s (held out in the model)", dataset, sc->names[k]);
            break;
        }
        st = score_camera(&c, k, cam, EVAL_ROLE_TEST);
    }
    free(c.real_z);
    free((void *)c.warp_depth);
    optim_ssim_destroy(c.ws);
    io_dataset_close(c.ds);
    render_model_close(c.rm);
    free(sc);
    return st;
}
