/* proxy.c - proxy_generate: the per-frame loop, on-disk cache and training-set assembly. */
#include "proxy/proxy.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/fileutil.h"
#include "core/parallel.h"
#include "core/progress.h"
#include "io/image_io.h"
#include "io/npy.h"
#include "io/trainset.h"
#include "proxy/holes.h"

#define PROXY_JPEG_QUALITY 95 /* proxy frames: JPEG error ~45 dB PSNR, far below the proxy's own */

proxy_options proxy_default_options(void)
{
    proxy_options o;
    o.fit = proxy_default_fit_options();
    o.threads = 2;
    o.force = 0;
    o.fill_holes = 1;
    return o;
}

/* FNV-1a, 64 bit. */
static unsigned long long hash_bytes(unsigned long long h, const void *data, size_t n)
{
    const unsigned char *p = data;
    for (size_t i = 0; i < n; i++) {
        h ^= p[i];
        h *= 1099511628211ULL;
    }
    return h;
}

static unsigned long long hash_float(unsigned long long h, float x) { return hash_bytes(h, &x, sizeof x); }
static unsigned long long hash_int(unsigned long long h, int x) { return hash_bytes(h, &x, sizeof x); }

static unsigned long long hash_camera(unsigned long long h, const char *name, const pg_camera *c)
{
    h = hash_bytes(h, name, strlen(name) + 1);
    h = hash_int(h, c->width);
    h = hash_int(h, c->height);
    h = hash_float(h, c->fx);
    h = hash_float(h, c->fy);
    h = hash_float(h, c->cx);
    h = hash_float(h, c->cy);
    for (int i = 0; i < 9; i++) h = hash_float(h, c->R[i]);
    for (int i = 0; i < 3; i++) h = hash_float(h, c->t[i]);
    return h;
}

/* Everything that changes a proxy frame's content: fit settings, cameras, scale, input and depth. */
static unsigned long long settings_hash(const proxy_options *o, const proxy_job *j)
{
    unsigned long long h = 1469598103934665603ULL;
    const proxy_fit_options *f = &o->fit;
    h = hash_int(h, 6); /* format version of the cache (3: shared Adam, 4: filled holes, 5: mesh renderer, 6: JPEG frames) */
    h = hash_int(h, o->fill_holes);
    h = hash_int(h, f->render);
    h = hash_int(h, f->block);
    h = hash_int(h, f->steps);
    h = hash_int(h, f->surfels);
    h = hash_int(h, f->ssim_every);
    h = hash_float(h, f->surfel_thickness);
    h = hash_float(h, f->pad);
    float fl[] = { f->ssim_weight, f->depth_weight, f->init_opacity, f->scale_mult, f->lr_means, f->lr_scales,
                   f->lr_opacity, f->lr_color, f->mask.alpha_min, f->mask.edge_rel, f->mask.stretch_max,
                   f->mask.depth_tol, j->pose_scale };
    for (size_t i = 0; i < sizeof fl / sizeof fl[0]; i++) h = hash_float(h, fl[i]);
    h = hash_int(h, j->frames);
    h = hash_camera(h, j->real_name, &j->real);
    for (int k = 0; k < j->num_proxies; k++) h = hash_camera(h, j->proxy_names[k], &j->proxies[k]);
    if (j->input_path) h = hash_bytes(h, j->input_path, strlen(j->input_path));
    h = hash_bytes(h, j->depth, (size_t)j->frames * j->width * j->height * sizeof(float));
    return h;
}

static pg_status cache_path(char *out, size_t size, const char *dir, const char *sub, const char *cam, int frame,
                            const char *ext)
{
    int n = cam ? snprintf(out, size, "%s/.cache/%s/%s/%04d.%s", dir, sub, cam, frame, ext)
                : snprintf(out, size, "%s/.cache/%s/%04d.%s", dir, sub, frame, ext);
    if (n < 0 || (size_t)n >= size) return pg_fail(PG_ERR_ARG, "%s: path too long", dir);
    return PG_OK;
}

static int frame_is_done(const char *dir, int frame, const char *hash_hex)
{
    char path[4096];
    if (cache_path(path, sizeof path, dir, "done", NULL, frame, "txt")) return 0;
    char *text = NULL;
    size_t size = 0;
    if (pg_read_file(path, 64, &text, &size)) return 0;
    int ok = strncmp(text, hash_hex, strlen(hash_hex)) == 0;
    free(text);
    return ok;
}

static pg_status save_mask_png(const char *path, const unsigned char *mask, int W, int H, float *scratch)
{
    for (size_t i = 0; i < (size_t)W * H; i++) scratch[i] = mask[i] / (float)PROXY_MASK_REAL;
    pg_image img = { W, H, 1, scratch };
    return io_image_save_png(path, &img);
}

/* Worker scratch for one frame: the model plus output buffers of one view. */
typedef struct {
    proxy_frame_model *model;
    float *rgb, *depth, *fmask; /* (H,W,3), (H,W), (H,W) */
    unsigned char *mask;        /* (H,W) */
    unsigned char *observed;    /* (H,W) scratch of the hole filling */
    int fill_max_run;           /* longest hole run filled (0: no filling) */
    unsigned char fill_weight;  /* mask value of filled pixels (the margin's weight) */
    int fitted;                 /* the model is fitted (SPLAT): it has a source-view PSNR */
    double write_s, valid_sum, psnr_sum;
    long views, frames;
} worker;

static pg_status process_frame(const proxy_job *j, const char *dir, const char *hash_hex, worker *w, int f)
{
    int W = j->width, H = j->height;
    size_t npix = (size_t)W * H;
    char path[4096];
    pg_image frame = { 0 };
    pg_status st = PG_OK;
    /* Recorded frames: the real camera (used here) and the test cameras (only copied). */
    for (int c = 0; c <= j->num_tests && !st; c++) {
        pg_image img = { 0 };
#pragma omp critical(proxy_frame_source)
        st = j->get_frame(j->frame_ctx, c, f, &img);
        if (st) break;
        if (img.width != W || img.height != H || img.channels != 3) {
            st = pg_fail(PG_ERR_SIZE, "frame %d of camera %s is %dx%dx%d, expected %dx%dx3", f,
                         c ? j->test_names[c - 1] : j->real_name, img.width, img.height, img.channels, W, H);
            pg_image_destroy(&img);
            break;
        }
        double t0 = pg_time_seconds();
        st = io_trainset_frame_path(path, sizeof path, dir, c ? j->test_names[c - 1] : j->real_name, "rgb", f);
        if (!st) st = io_image_save_png(path, &img);
        w->write_s += pg_time_seconds() - t0;
        if (c == 0) frame = img;
        else pg_image_destroy(&img);
    }
    if (st) {
        pg_image_destroy(&frame);
        return st;
    }
    const float *d = j->depth + (size_t)f * npix;
    for (size_t i = 0; i < npix; i++) w->depth[i] = d[i] * j->pose_scale;
    int empty = 1;
    for (size_t i = 0; i < npix && empty; i++) empty = !(w->depth[i] > 0);
    /* A frame without any valid depth gives empty proxies (all masked out) instead of failing the
     * run: the trainer then simply gets no proxy pixels for that frame. Without proxy cameras
     * (the --proxies 0 ablation) there is nothing to render, so no model is fitted. */
    if (!empty && j->num_proxies > 0) {
        st = proxy_model_init(w->model, &j->real, frame.data, w->depth);
        if (!st) st = proxy_model_fit(w->model);
    }
    pg_image_destroy(&frame);
    if (st) return pg_fail_context(st, "frame %d: ", f);
    if (!empty && j->num_proxies > 0 && w->fitted) {
        w->psnr_sum += proxy_model_get_stats(w->model)->source_psnr;
        w->frames++;
    }
    for (int k = 0; k < j->num_proxies; k++) {
        float valid = 0;
        if (empty) {
            memset(w->rgb, 0, npix * 3 * sizeof(float));
            memset(w->depth, 0, npix * sizeof(float));
            memset(w->mask, 0, npix);
        } else {
            PG_TRY(proxy_model_render(w->model, &j->proxies[k], w->rgb, w->depth, w->mask, &valid));
            if (w->fill_max_run > 0)
                proxy_fill_holes(W, H, w->rgb, w->depth, w->mask, w->fill_max_run, w->fill_weight, w->observed);
        }
        w->valid_sum += valid;
        w->views++;
        double t0 = pg_time_seconds();
        pg_image img = { W, H, 3, w->rgb };
        PG_TRY(io_trainset_frame_path_ext(path, sizeof path, dir, j->proxy_names[k], "rgb", f, "jpg"));
        PG_TRY(io_image_save_jpeg(path, &img, PROXY_JPEG_QUALITY));
        PG_TRY(io_trainset_frame_path(path, sizeof path, dir, j->proxy_names[k], "mask", f));
        PG_TRY(save_mask_png(path, w->mask, W, H, w->fmask));
        PG_TRY(cache_path(path, sizeof path, dir, "depth", j->proxy_names[k], f, "npy"));
        size_t shape[2] = { (size_t)H, (size_t)W };
        PG_TRY(io_npy_save_compact(path, w->depth, 2, shape));
        w->write_s += pg_time_seconds() - t0;
    }
    PG_TRY(cache_path(path, sizeof path, dir, "done", NULL, f, "txt"));
    return pg_write_file_atomic(path, hash_hex, strlen(hash_hex));
}

static void worker_free(worker *w)
{
    proxy_model_destroy(w->model);
    free(w->rgb);
    free(w->depth);
    free(w->fmask);
    free(w->mask);
    free(w->observed);
}

static pg_status worker_init(worker *w, const proxy_options *o, const proxy_job *j)
{
    memset(w, 0, sizeof *w);
    size_t npix = (size_t)j->width * j->height;
    PG_TRY(proxy_model_create(&w->model, j->width, j->height, &o->fit));
    w->fitted = o->fit.render == PROXY_RENDER_SPLAT;
    w->rgb = pg_malloc(npix * 3 * sizeof(float), "proxy view rgb");
    w->depth = pg_malloc(npix * sizeof(float), "proxy view depth");
    w->fmask = pg_malloc(npix * sizeof(float), "proxy mask image");
    w->mask = pg_malloc(npix, "proxy mask");
    w->observed = pg_malloc(npix, "proxy hole scratch");
    /* holes up to a tenth of the larger side: beside objects, not whole regions nobody saw */
    w->fill_max_run = o->fill_holes ? (j->width > j->height ? j->width : j->height) / 10 : 0;
    float mw = o->fit.mask.margin_weight < 0 ? 0 : o->fit.mask.margin_weight > 1 ? 1 : o->fit.mask.margin_weight;
    w->fill_weight = (unsigned char)lroundf(mw * PROXY_MASK_REAL);
    if (!w->rgb || !w->depth || !w->fmask || !w->mask || !w->observed) {
        worker_free(w);
        return PG_ERR_NOMEM;
    }
    return PG_OK;
}

/* Joins the per-frame proxy depth maps of one camera into DIR/<cam>/depth.npy (F,H,W) and then
 * deletes them: the volume holds the same values, and keeping both doubled the stage's disk. A
 * frame whose done marker survived but whose map was deleted (a rerun after an earlier
 * assembly) is taken from the earlier volume. */
static pg_status assemble_depth(const proxy_job *j, const char *dir, const char *cam)
{
    size_t npix = (size_t)j->width * j->height, total;
    if (pg_size_mul(npix, (size_t)j->frames, &total)) return pg_fail(PG_ERR_SIZE, "%s: depth too large", cam);
    float *all = pg_malloc(total * sizeof(float), "proxy depth volume");
    if (!all) return PG_ERR_NOMEM;
    char path[4096], volume[4096];
    int n = snprintf(volume, sizeof volume, "%s/%s/depth.npy", dir, cam);
    pg_status st = (n < 0 || (size_t)n >= sizeof volume) ? pg_fail(PG_ERR_ARG, "%s: path too long", dir) : PG_OK;
    pg_array old = { 0 };
    for (int f = 0; f < j->frames && !st; f++) {
        pg_array a = { 0 };
        st = cache_path(path, sizeof path, dir, "depth", cam, f, "npy");
        if (!st && !pg_path_exists(path)) {
            if (!old.data) st = io_npy_load(volume, &old);
            if (!st && old.count != total)
                st = pg_fail(PG_ERR_FORMAT, "%s: expected %zu values, found %zu", volume, total, old.count);
            if (!st) memcpy(all + (size_t)f * npix, old.data + (size_t)f * npix, npix * sizeof(float));
            continue;
        }
        if (!st) st = io_npy_load(path, &a);
        if (!st && a.count != npix) st = pg_fail(PG_ERR_FORMAT, "%s: expected %zu values, found %zu", path, npix, a.count);
        if (!st) memcpy(all + (size_t)f * npix, a.data, npix * sizeof(float));
        pg_array_destroy(&a);
    }
    pg_array_destroy(&old);
    size_t shape[3] = { (size_t)j->frames, (size_t)j->height, (size_t)j->width };
    if (!st) st = io_npy_save_compact(volume, all, 3, shape);
    for (int f = 0; f < j->frames && !st; f++)
        if (cache_path(path, sizeof path, dir, "depth", cam, f, "npy") == PG_OK) remove(path);
    free(all);
    return st;
}

static pg_status check_job(const proxy_job *j)
{
    if (j->frames < 1 || j->width < 1 || j->height < 1 || !j->depth || !j->get_frame)
        return pg_fail(PG_ERR_ARG, "proxies: empty input (%d frames of %dx%d)", j->frames, j->width, j->height);
    if (!(j->pose_scale > 0) || !isfinite(j->pose_scale))
        return pg_fail(PG_ERR_ARG, "proxies: pose scale %g must be positive", j->pose_scale);
    if (j->real.width != j->width || j->real.height != j->height)
        return pg_fail(PG_ERR_SIZE, "proxies: real camera is %dx%d but frames are %dx%d", j->real.width,
                       j->real.height, j->width, j->height);
    if (j->num_proxies < 0) return pg_fail(PG_ERR_ARG, "proxies: negative proxy camera count");
    for (int k = 0; k < j->num_proxies + j->num_tests; k++) {
        const pg_camera *c = k < j->num_proxies ? &j->proxies[k] : &j->tests[k - j->num_proxies];
        const char *name = k < j->num_proxies ? j->proxy_names[k] : j->test_names[k - j->num_proxies];
        if (!name || !name[0] || strlen(name) > 63 || strchr(name, '/'))
            return pg_fail(PG_ERR_ARG, "proxies: bad camera name '%s'", name ? name : "(null)");
        if (c->width != j->width || c->height != j->height)
            return pg_fail(PG_ERR_SIZE, "proxies: camera %s is %dx%d, frames are %dx%d", name, c->width, c->height,
                           j->width, j->height);
    }
    return PG_OK;
}

pg_status proxy_generate(const proxy_options *opt_in, const proxy_job *j, const char *dir, proxy_result *res)
{
    proxy_options o = opt_in ? *opt_in : proxy_default_options();
    memset(res, 0, sizeof *res);
    PG_TRY(check_job(j));
    double t_start = pg_time_seconds();
    char path[4096], hash_hex[32];
    res->settings_hash = settings_hash(&o, j);
    snprintf(hash_hex, sizeof hash_hex, "%016llx", res->settings_hash);

    PG_TRY(pg_mkdir_p(dir));
    PG_TRY(io_trainset_make_dirs(dir, j->real_name, 0));
    for (int k = 0; k < j->num_tests; k++) PG_TRY(io_trainset_make_dirs(dir, j->test_names[k], 0));
    for (int k = 0; k < j->num_proxies; k++) {
        PG_TRY(io_trainset_make_dirs(dir, j->proxy_names[k], 1));
        int n = snprintf(path, sizeof path, "%s/.cache/depth/%s", dir, j->proxy_names[k]);
        if (n < 0 || (size_t)n >= sizeof path) return pg_fail(PG_ERR_ARG, "%s: path too long", dir);
        PG_TRY(pg_mkdir_p(path));
    }
    PG_TRY(pg_path_join(path, sizeof path, dir, ".cache/done"));
    PG_TRY(pg_mkdir_p(path));

    /* Frames still to compute. */
    int *todo = pg_malloc((size_t)j->frames * sizeof(int), "frame list");
    if (!todo) return PG_ERR_NOMEM;
    int ntodo = 0;
    for (int f = 0; f < j->frames; f++) {
        if (!o.force && frame_is_done(dir, f, hash_hex)) res->frames_skipped++;
        else todo[ntodo++] = f;
    }

    int threads = o.threads < 1 ? 1 : o.threads;
    if (threads > ntodo) threads = ntodo > 0 ? ntodo : 1;
    worker *workers = pg_calloc((size_t)threads, sizeof(worker), "proxy workers");
    if (!workers) { free(todo); return PG_ERR_NOMEM; }
    pg_status first_err = PG_OK;
    int stop_flag = 0; /* set (atomically) once first_err is: the other workers skip their frames */
    char err_msg[512] = "";
    int done = 0;
    pg_progress_report("proxies", res->frames_skipped, j->frames, "starting %d frames on %d workers", ntodo, threads);
    if (ntodo > 0) {
#pragma omp parallel num_threads(threads)
        {
            int tid = pg_thread_index();
            worker *w = &workers[tid];
            pg_status st = worker_init(w, &o, j);
            if (st) {
#pragma omp critical(proxy_error)
                if (!first_err) {
                    first_err = st;
                    snprintf(err_msg, sizeof err_msg, "%s", pg_last_error());
#pragma omp atomic write
                    stop_flag = 1;
                }
            }
#pragma omp barrier
#pragma omp for schedule(dynamic, 1)
            for (int i = 0; i < ntodo; i++) {
                int stop;
#pragma omp atomic read
                stop = stop_flag;
                if (stop) continue;
                pg_status fs = process_frame(j, dir, hash_hex, w, todo[i]);
#pragma omp critical(proxy_error)
                {
                    if (fs && !first_err) {
                        first_err = fs;
                        snprintf(err_msg, sizeof err_msg, "%s", pg_last_error());
#pragma omp atomic write
                        stop_flag = 1;
                    }
                    if (!fs) {
                        done++;
                        const proxy_model_stats *ms = proxy_model_get_stats(w->model);
                        if (w->fitted)
                            pg_progress_report("proxies", res->frames_skipped + done, j->frames,
                                               "frame=%d source_psnr=%.2f loss=%.4f->%.4f", todo[i], ms->source_psnr,
                                               ms->first_loss, ms->last_loss);
                        else
                            pg_progress_report("proxies", res->frames_skipped + done, j->frames, "frame=%d", todo[i]);
                    }
                }
            }
        }
    }
    for (int t = 0; t < threads; t++) {
        worker *w = &workers[t];
        if (w->model) {
            const proxy_model_stats *ms = proxy_model_get_stats(w->model);
            res->init_s += ms->init_s;
            res->fit_s += ms->fit_s;
            res->render_s += ms->render_s;
        }
        res->write_s += w->write_s;
        res->mean_valid_fraction += w->valid_sum;
        res->mean_source_psnr += w->psnr_sum;
    }
    long views = 0, frames = 0;
    for (int t = 0; t < threads; t++) { views += workers[t].views; frames += workers[t].frames; }
    if (views) res->mean_valid_fraction /= views;
    res->mean_source_psnr = frames ? res->mean_source_psnr / frames : NAN;
    res->frames_done = done;
    for (int t = 0; t < threads; t++) worker_free(&workers[t]);
    free(workers);
    free(todo);
    if (first_err) return pg_fail(first_err, "%s", err_msg);

    /* Depth volumes and the index. */
    double t0 = pg_time_seconds();
    for (int k = 0; k < j->num_proxies; k++) PG_TRY(assemble_depth(j, dir, j->proxy_names[k]));
    size_t npix = (size_t)j->width * j->height, total;
    if (pg_size_mul(npix, (size_t)j->frames, &total)) return pg_fail(PG_ERR_SIZE, "proxies: depth too large");
    float *scaled = pg_malloc(total * sizeof(float), "scaled real depth");
    if (!scaled) return PG_ERR_NOMEM;
    float near = INFINITY, far = 0;
    for (size_t i = 0; i < total; i++) {
        float d = j->depth[i];
        scaled[i] = (isfinite(d) && d > 0) ? d * j->pose_scale : 0;
        if (scaled[i] > 0) {
            if (scaled[i] < near) near = scaled[i];
            if (scaled[i] > far) far = scaled[i];
        }
    }
    int n = snprintf(path, sizeof path, "%s/%s/depth.npy", dir, j->real_name);
    size_t shape[3] = { (size_t)j->frames, (size_t)j->height, (size_t)j->width };
    pg_status st = (n < 0 || (size_t)n >= sizeof path) ? pg_fail(PG_ERR_ARG, "%s: path too long", dir)
                                                        : io_npy_save_compact(path, scaled, 3, shape);
    free(scaled);
    PG_TRY(st);

    int ncam = 1 + j->num_proxies + j->num_tests;
    io_trainset_camera *cams = pg_calloc((size_t)ncam, sizeof *cams, "trainset cameras");
    if (!cams) return PG_ERR_NOMEM;
    snprintf(cams[0].name, sizeof cams[0].name, "%s", j->real_name);
    cams[0].cam = j->real;
    cams[0].role = IO_ROLE_REAL;
    cams[0].has_rgb = cams[0].has_depth = 1;
    for (int k = 0; k < j->num_proxies; k++) {
        io_trainset_camera *c = &cams[1 + k];
        snprintf(c->name, sizeof c->name, "%s", j->proxy_names[k]);
        c->cam = j->proxies[k];
        c->role = IO_ROLE_PROXY;
        c->has_rgb = c->has_mask = c->has_depth = 1;
    }
    for (int k = 0; k < j->num_tests; k++) {
        io_trainset_camera *c = &cams[1 + j->num_proxies + k];
        snprintf(c->name, sizeof c->name, "%s", j->test_names[k]);
        c->cam = j->tests[k];
        c->role = IO_ROLE_TEST;
        c->has_rgb = 1;
    }
    io_trainset_info info = { j->frames, j->width, j->height, j->fps, { j->center[0], j->center[1], j->center[2] },
                                 j->radius, far > 0 ? near : 0, far, j->input_path, j->depth_path, j->pose_scale,
                                 j->pose_shift, j->pose_fit, j->unit };
    st = io_trainset_write_json(dir, &info, cams, ncam);
    free(cams);
    res->write_s += pg_time_seconds() - t0;
    res->wall_s = pg_time_seconds() - t_start;
    return st;
}
