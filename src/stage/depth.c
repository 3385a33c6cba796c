/* depth.c - the depth stage: a depth network over the frames of a video (pg_depth_run, see
 * prodygs.h), with a per-frame cache so an interrupted run resumes.
 *
 * Frames are decoded at the smallest size that covers the network's input (the decoder's scaler
 * shrinks a 1080p frame as it decodes it), go in batches of one per thread, each thread with its
 * own copy of the network running single-threaded (a lone frame uses all threads in one network),
 * and the network's output is resampled once to the output size.
 * OUT.cache/ holds key.json (the content hashes of the model and the camera's source, and the
 * settings) and one NNNNN.npy (H, W) per finished frame. A cache whose key differs is emptied
 * first. Once every frame is there, OUT is written atomically, then the key beside it as
 * OUT-minus-.npy + .json, and the cache is removed; a rerun whose key matches that file does
 * nothing. */
#include "stage/stage_internal.h"

#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cblas.h>

#include "core/fileutil.h"
#include "core/output.h"
#include "core/parallel.h"
#include "core/progress.h"
#include "depth/depth_net.h"
#include "io/dataset.h"
#include "io/json.h"
#include "io/npy.h"
#include "io/video.h"
#include "stage/marker.h"

#define DEPTH_MAX_NETS 16 /* networks run side by side (one per thread, one frame each) */

void pg_depth_defaults(pg_depth_config *c) { memset(c, 0, sizeof *c); }

static pg_status check_config(const pg_depth_config *c)
{
    if (!c->input || !c->model || !c->out) return pg_fail(PG_ERR_ARG, "depth: input, model and out are required");
    if (c->kind && strcmp(c->kind, "depth") != 0 && strcmp(c->kind, "disparity") != 0)
        return pg_fail(PG_ERR_ARG, "--kind must be depth or disparity (got '%s')", c->kind);
    if (c->frames < 0) return pg_fail(PG_ERR_ARG, "--frames must be >= 1 (got %d)", c->frames);
    if (c->size < 0 || c->size > STAGE_MAX_SIDE) return pg_fail(PG_ERR_ARG, "--size must be in 1..%d (got %d)", STAGE_MAX_SIDE, c->size);
    if (c->out_width < 0 || c->out_height < 0 || c->out_width > STAGE_MAX_SIDE || c->out_height > STAGE_MAX_SIDE)
        return pg_fail(PG_ERR_ARG, "--out-size must be in 0..%d per side (got %dx%d)", STAGE_MAX_SIDE, c->out_width, c->out_height);
    size_t n = strlen(c->out);
    if (n < 5 || strcmp(c->out + n - 4, ".npy") != 0) return pg_fail(PG_ERR_ARG, "%s: --out must name a .npy file", c->out);
    return stage_check_threads("depth", c->threads);
}

/* Everything the result depends on: the model's and the source's content and the settings. */
static pg_status make_key(const pg_depth_config *c, const char *source, const char *camera, const depth_net_info *info,
                          const pg_depth_report *r, cJSON **key)
{
    cJSON *k = cJSON_CreateObject();
    pg_status st = stage_hash_input(k, "model", c->model);
    if (!st) st = stage_hash_input(k, "source", source);
    cJSON_AddStringToObject(k, "camera", camera);
    cJSON_AddStringToObject(k, "kind", info->disparity ? "disparity" : "depth");
    cJSON_AddNumberToObject(k, "scale", info->scale);
    cJSON_AddNumberToObject(k, "input_width", info->width);
    cJSON_AddNumberToObject(k, "input_height", info->height);
    cJSON_AddItemToObject(k, "mean", io_json_float_array(info->mean, 3));
    cJSON_AddItemToObject(k, "std", io_json_float_array(info->std, 3));
    if (info->bgr) cJSON_AddStringToObject(k, "channel_order", "bgr"); /* absent for rgb: older keys stay valid */
    cJSON_AddBoolToObject(k, "flip_average", info->flip);
    cJSON_AddNumberToObject(k, "frames", r->frames);
    cJSON_AddNumberToObject(k, "decode_width", r->decode_width);
    cJSON_AddNumberToObject(k, "decode_height", r->decode_height);
    cJSON_AddNumberToObject(k, "width", r->width);
    cJSON_AddNumberToObject(k, "height", r->height);
    if (st) {
        cJSON_Delete(k);
        return st;
    }
    *key = k;
    return PG_OK;
}

/* 1 when path holds a JSON object whose "key" equals key. */
static int key_matches(const char *path, const cJSON *key)
{
    if (!pg_path_exists(path)) return 0;
    cJSON *j;
    if (io_json_load(path, &j) != PG_OK) return 0;
    int same = cJSON_Compare(cJSON_GetObjectItemCaseSensitive(j, "key"), key, 1);
    cJSON_Delete(j);
    return same;
}

static pg_status write_key(const char *path, const cJSON *key, const pg_depth_config *c, const depth_net_info *info)
{
    cJSON *j = cJSON_CreateObject();
    cJSON_AddStringToObject(j, "model", c->model);
    cJSON_AddStringToObject(j, "model_name", info->name);
    cJSON_AddStringToObject(j, "output", "depth");
    cJSON_AddStringToObject(j, "model_output", info->disparity ? "disparity" : "depth");
    cJSON_AddItemToObject(j, "key", cJSON_Duplicate(key, 1));
    pg_status st = io_json_write_atomic(path, j);
    cJSON_Delete(j);
    return st;
}

/* Removes the files of a cache directory and the directory. */
static void remove_cache(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d) return;
    struct dirent *e;
    char path[4400];
    while ((e = readdir(d)))
        if (e->d_name[0] != '.') {
            snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
            remove(path);
        }
    closedir(d);
    rmdir(dir);
}

/* The smallest size at the source's aspect that covers need_w x need_h in both axes (no axis is
 * upsampled into the network), never above the source. */
static void cover_size(int need_w, int need_h, int src_w, int src_h, int *w, int *h)
{
    double s = fmax((double)need_w / src_w, (double)need_h / src_h);
    if (s >= 1.0) {
        *w = src_w;
        *h = src_h;
        return;
    }
    *w = (int)ceil(src_w * s - 1e-6);
    *h = (int)ceil(src_h * s - 1e-6);
}

/* The output size: out_width x out_height (one side 0 keeps the source's aspect), else the
 * network's output resolution at the source's aspect (never above the decoded frames). */
static void output_size(const pg_depth_config *c, const depth_net_info *info, int src_w, int src_h, int dec_w, int dec_h,
                        int *w, int *h)
{
    if (c->out_width > 0 || c->out_height > 0) {
        io_video_options vo = io_video_defaults();
        vo.width = c->out_width;
        vo.height = c->out_height;
        io_video_target_size(&vo, src_w, src_h, w, h);
        return;
    }
    cover_size(info->out_width, info->out_height, src_w, src_h, w, h);
    if (*w > dec_w || *h > dec_h) {
        *w = dec_w;
        *h = dec_h;
    }
}

static pg_status depth_run(const pg_depth_config *c, pg_depth_report *r)
{
    memset(r, 0, sizeof *r);
    PG_TRY(check_config(c));
    double t0 = pg_time_seconds();
    r->threads = stage_use_threads(c->threads);
    pg_dataset *ds = NULL;
    io_dataset_options dopt = io_dataset_defaults();
    dopt.count = c->frames;
    PG_TRY(io_dataset_open(c->input, &dopt, &ds));
    int cam = 0;
    depth_net *net = NULL;
    pg_status st = PG_OK;
    if (c->train_camera && io_dataset_resolve_camera(ds, c->train_camera, &cam) != PG_OK)
        st = pg_fail_context(PG_ERR_ARG, "%s: --train-cam", c->input);
    if (!st) st = depth_net_open(c->model, c->kind, c->size, io_dataset_width(ds), io_dataset_height(ds), &net);
    const depth_net_info *info = net ? depth_net_get_info(net) : NULL;
    if (!st) {
        int side = info->width > info->height ? info->width : info->height;
        if (c->size && c->size != side && !info->dynamic)
            st = pg_fail(PG_ERR_ARG, "%s: the model's input is fixed at %dx%d; --size %d cannot change it", c->model, info->width,
                         info->height, c->size);
    }
    if (!st) {
        int sw = io_dataset_source_width(ds), sh = io_dataset_source_height(ds);
        cover_size(info->width, info->height, sw, sh, &r->decode_width, &r->decode_height);
        io_dataset_set_frame_size(ds, r->decode_width, r->decode_height);
        output_size(c, info, sw, sh, r->decode_width, r->decode_height, &r->width, &r->height);
        snprintf(r->model_name, sizeof r->model_name, "%s", info->name);
        snprintf(r->kind, sizeof r->kind, "%s", info->disparity ? "disparity" : "depth");
        r->model_width = info->width;
        r->model_height = info->height;
    }
    cJSON *key = NULL;
    char cache[4200], meta[4200], frame_path[4400];
    snprintf(cache, sizeof cache, "%s.cache", c->out);
    snprintf(meta, sizeof meta, "%.*s.json", (int)(strlen(c->out) - 4), c->out);
    float *all = NULL;
    if (!st) {
        io_dataset_camera_label(ds, cam, r->train_camera, sizeof r->train_camera);
        r->frames = io_dataset_num_frames(ds);
        st = make_key(c, io_dataset_camera_source(ds, cam), io_dataset_camera_name(ds, cam), info, r, &key);
    }
    if (!st && pg_path_exists(c->out) && key_matches(meta, key)) {
        r->skipped = r->finished = 1;
        goto done;
    }
    /* the cache: emptied when it belongs to another model, input or setting */
    if (!st) {
        char key_path[4300];
        snprintf(key_path, sizeof key_path, "%s/key.json", cache);
        if (!key_matches(key_path, key)) {
            remove_cache(cache);
            st = pg_mkdir_p(cache);
            if (!st) st = write_key(key_path, key, c, info);
        }
    }
    size_t plane = (size_t)r->width * r->height, total;
    if (!st && pg_size_mul(plane, (size_t)r->frames, &total)) st = pg_fail(PG_ERR_SIZE, "%s: too many frames", c->input);
    if (!st) {
        all = pg_malloc(total * sizeof(float), "depth frames");
        if (!all) st = PG_ERR_NOMEM;
    }
    /* one network per thread, each on its own frame with one thread: no fork/join per layer, which
     * on shared cores costs more than it gains (the threads wait for each other at every layer) */
    int T = r->threads < 1 ? 1 : r->threads > DEPTH_MAX_NETS ? DEPTH_MAX_NETS : r->threads, nets = 1;
    if (T > r->frames) T = r->frames > 0 ? r->frames : 1;
    depth_net *net_of[DEPTH_MAX_NETS] = { net };
    for (; !st && nets < T; nets++)
        if (depth_net_open(c->model, c->kind, c->size, io_dataset_source_width(ds), io_dataset_source_height(ds),
                           &net_of[nets]) != PG_OK)
            break; /* fewer copies */
    double infer_seconds = 0;
    int t = 0, stop = 0;
    int saved_blas = openblas_get_num_threads();
    openblas_set_num_threads(1); /* process-wide: set here, not by the nets side by side */
    while (!st && !stop && t < r->frames) {
        int batch[DEPTH_MAX_NETS], nb = 0;
        pg_image img[DEPTH_MAX_NETS];
        memset(img, 0, sizeof img);
        while (!st && t < r->frames && nb < nets) {
            snprintf(frame_path, sizeof frame_path, "%s/%05d.npy", cache, t);
            if (pg_path_exists(frame_path)) {
                pg_array a;
                if (io_npy_load(frame_path, &a) == PG_OK && a.ndim == 2 && a.shape[0] == (size_t)r->height &&
                    a.shape[1] == (size_t)r->width) {
                    memcpy(all + plane * (size_t)t, a.data, plane * sizeof(float));
                    pg_array_destroy(&a);
                    r->reused++;
                    pg_progress_report("depth", t + 1, r->frames, "frame %d cached", t);
                    t++;
                    continue;
                }
                pg_array_destroy(&a); /* unreadable (saves are atomic, so not a crash mid-write): recompute */
            }
            if (c->stop_after && r->computed + nb >= c->stop_after) {
                stop = 1;
                break;
            }
            st = io_dataset_frame(ds, cam, t, &img[nb]);
            if (!st) batch[nb++] = t; /* a failure's message names the file (the reader knows which) */
            t++;
        }
        pg_status bst[DEPTH_MAX_NETS];
        char msg[DEPTH_MAX_NETS][512];
        double ti = pg_time_seconds();
        int inner = nb > 1 ? 1 : r->threads;
        #pragma omp parallel for num_threads(nb > 1 ? nb : 1) schedule(static, 1)
        for (int b = 0; b < nb; b++) {
            bst[b] = depth_net_infer(net_of[b], &img[b], all + plane * (size_t)batch[b], r->width, r->height, inner);
            if (bst[b]) snprintf(msg[b], sizeof msg[b], "%s", pg_last_error()); /* messages are per thread */
        }
        infer_seconds += pg_time_seconds() - ti;
        for (int b = 0; b < nb; b++) {
            pg_image_destroy(&img[b]);
            if (st) continue;
            if (bst[b]) {
                st = pg_fail(bst[b], "%s: frame %d: %s", c->input, batch[b], msg[b]);
                continue;
            }
            size_t valid = 0;
            for (size_t i = 0; i < plane; i++) valid += all[plane * (size_t)batch[b] + i] > 0;
            if (!valid) {
                st = pg_fail(PG_ERR_FORMAT, "%s: frame %d: the network's output has no valid depth (all NaN, inf or <= 0): %s",
                             c->input, batch[b], c->model);
                continue;
            }
            snprintf(frame_path, sizeof frame_path, "%s/%05d.npy", cache, batch[b]);
            size_t shape[2] = { (size_t)r->height, (size_t)r->width };
            st = io_npy_save(frame_path, all + plane * (size_t)batch[b], 2, shape);
            r->computed++;
            pg_progress_report("depth", batch[b] + 1, r->frames, "%.0f ms/frame", 1e3 * infer_seconds / r->computed);
        }
    }
    openblas_set_num_threads(saved_blas);
    for (int k = 1; k < nets; k++) depth_net_close(net_of[k]);
    r->ms_per_frame = r->computed ? 1e3 * infer_seconds / r->computed : 0;
    r->finished = !st && r->computed + r->reused == r->frames;
    if (r->finished) {
        size_t shape[3] = { (size_t)r->frames, (size_t)r->height, (size_t)r->width };
        st = io_npy_save_compact(c->out, all, 3, shape); /* float16 when it fits (the cache stays float32) */
        if (!st) st = write_key(meta, key, c, info);
        if (!st) remove_cache(cache);
    }
done:
    r->seconds = pg_time_seconds() - t0;
    free(all);
    cJSON_Delete(key);
    io_dataset_close(ds);
    depth_net_close(net);
    return st;
}

/* The output is claimed (checked and locked, core/output.h) before any work and held for the
 * whole stage. */
pg_status pg_depth_run(const pg_depth_config *c, pg_depth_report *r)
{
    memset(r, 0, sizeof *r);
    if (!c->out) return depth_run(c, r); /* its own check names what is missing */
    PG_TRY(pg_output_claim_file(c->out));
    pg_status st = depth_run(c, r);
    pg_output_release(c->out);
    return st;
}
