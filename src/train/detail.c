/* detail.c - the full-size phase (detail.h): the still scene once at the input's size, then the
 * movers in their boxes. */
#include "train/detail.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/mathx.h"
#include "core/parallel.h"
#include "core/progress.h"
#include "io/dataset.h"
#include "splat/filter3d.h"
#include "train/train_internal.h"

/* frames whose per-pixel median is the still scene: enough that a mover covering a pixel in under
 * half of them drops out */
#define DETAIL_STILL_SAMPLES 31
/* a box's margin at full size, in pixels (the working-size box is already dilated) */
#define DETAIL_BOX_PAD 8
/* a box is kept in tiles of this many pixels a side, the moving ones only */
#define DETAIL_TILE 32
/* the still fit: full-size steps on the new Gaussians (90 left the edges and the movers' holes
 * off the median by 0.019 L1, 300 under 0.003) */
#define DETAIL_STILL_STEPS 300
#define DETAIL_STILL_LR_COLOUR 8.0f
/* a pixel whose colour is this far (largest channel) from the working-size model's gets its own
 * still Gaussian */
#define DETAIL_STILL_RESIDUAL 0.02f
/* the movers' densification: every this many steps in the first half of the phase, at most this
 * many new Gaussians in all */
#define DETAIL_DENSIFY_EVERY 100
#define DETAIL_MAX_NEW_MOVERS 150000
/* pixels off the still scene by more than this (largest channel) are the movers' in the crops'
 * loss weights (the trainer's TRAIN_MOVING_THRESH) */
#define DETAIL_MOVING 0.1f
/* the scores' moving pixels: evaluation's threshold and dilation (eval/metrics.h) */
#define DETAIL_SCORE_MOVING 0.12f
#define DETAIL_SCORE_DILATE 2

int train_detail_default_steps(int frames)
{
    int k = TRAIN_DETAIL_STEPS_PER_FRAME * frames;
    return k < TRAIN_DETAIL_MIN_STEPS ? TRAIN_DETAIL_MIN_STEPS : k > TRAIN_DETAIL_STEPS ? TRAIN_DETAIL_STEPS : k;
}

void train_detail_destroy(train_detail *d)
{
    if (!d) return;
    free(d->still);
    free(d->score_rgb);
    free(d->score_moving);
    for (int f = 0; d->crop && f < d->frames; f++) free(d->crop[f]);
    for (int f = 0; d->tiles && f < d->frames; f++) free(d->tiles[f]);
    free(d->crop);
    free(d->tiles);
    free(d->rect);
    free(d);
}

static inline float max3(float a, float b, float c) { return fmaxf(a, fmaxf(b, c)); }

void train_detail_target(const train_session *s, int f, const int *r, float *rgb, float *mask)
{
    const train_detail *d = s->detail;
    const int *box = d->rect + 4 * (size_t)f, W = d->cam.width, T = DETAIL_TILE, tw = (box[2] + T - 1) / T;
    const uint8_t *crop = d->crop[f];
    const int *tiles = d->tiles[f];
    const float mw = s->cfg.moving_weight;
    #pragma omp parallel for schedule(static)
    for (int y = 0; y < r[3]; y++)
        for (int x = 0; x < r[2]; x++) {
            size_t i = (size_t)y * r[2] + x;
            const float *bg = d->still + 3 * ((size_t)(r[1] + y) * W + r[0] + x);
            const int bx = r[0] - box[0] + x, by = r[1] - box[1] + y, k = tiles[(by / T) * tw + bx / T];
            if (k < 0) { /* a still tile: the median */
                memcpy(rgb + 3 * i, bg, 3 * sizeof(float));
                mask[i] = 1.0f;
                continue;
            }
            const uint8_t *src = crop + (((size_t)k * T + by % T) * T + bx % T) * 3;
            float diff = 0;
            for (int c = 0; c < 3; c++) {
                rgb[3 * i + c] = src[c] * (1.0f / 255.0f);
                diff = fmaxf(diff, fabsf(rgb[3 * i + c] - bg[c]));
            }
            mask[i] = diff > DETAIL_MOVING ? 1.0f + mw : 1.0f;
        }
}

static int cmp_u8(const void *a, const void *b) { return (int)*(const uint8_t *)a - (int)*(const uint8_t *)b; }

/* The per-pixel, per-channel median of the n sampled frames into still (floats in [0, 1]). */
static void median_frames(uint8_t *const *samples, int n, size_t values, float *still)
{
    #pragma omp parallel for schedule(static)
    for (size_t i = 0; i < values; i++) {
        uint8_t v[DETAIL_STILL_SAMPLES];
        for (int k = 0; k < n; k++) v[k] = samples[k][i];
        qsort(v, (size_t)n, 1, cmp_u8);
        still[i] = v[n / 2] * (1.0f / 255.0f);
    }
}

/* The source's frames in increasing order, DETAIL_CHUNK decoded at a time: a dataset caches every
 * frame of a camera it decodes, and 300 frames of 1080p are 1.9 GB. */
#define DETAIL_CHUNK 40
typedef struct {
    const train_detail_config *c;
    pg_dataset *ds;
    int cam, first; /* the open chunk's first frame */
    int width, height, source_width, source_height, frames;
} frame_reader;

static pg_status reader_open_at(frame_reader *r, int first)
{
    io_dataset_close(r->ds);
    r->ds = NULL;
    io_dataset_options opt = io_dataset_defaults();
    opt.max_side = TRAIN_DETAIL_MAX_SIDE;
    opt.first = first;
    opt.count = r->frames - first < DETAIL_CHUNK ? r->frames - first : DETAIL_CHUNK;
    PG_TRY(io_dataset_open(r->c->input, &opt, &r->ds));
    r->cam = 0;
    if (r->c->camera && io_dataset_resolve_camera(r->ds, r->c->camera, &r->cam) != PG_OK)
        return pg_fail_context(PG_ERR_ARG, "%s: the training camera", r->c->input);
    r->first = first;
    r->width = io_dataset_width(r->ds), r->height = io_dataset_height(r->ds);
    r->source_width = io_dataset_source_width(r->ds), r->source_height = io_dataset_source_height(r->ds);
    return PG_OK;
}

/* Opens the source (its frame count and size known after). */
static pg_status reader_open(frame_reader *r, const train_detail_config *c)
{
    memset(r, 0, sizeof *r);
    r->c = c;
    io_dataset_options opt = io_dataset_defaults();
    opt.max_side = TRAIN_DETAIL_MAX_SIDE;
    PG_TRY(io_dataset_open(c->input, &opt, &r->ds));
    r->frames = io_dataset_num_frames(r->ds);
    io_dataset_close(r->ds);
    r->ds = NULL;
    return reader_open_at(r, 0);
}

/* Frame f into img (its old pixels freed first: the dataset hands out a new image). */
static pg_status reader_frame(frame_reader *r, int f, pg_image *img)
{
    pg_image_destroy(img);
    if (f < r->first || f >= r->first + DETAIL_CHUNK) PG_TRY(reader_open_at(r, f));
    return io_dataset_frame(r->ds, r->cam, f - r->first, img);
}

static void reader_close(frame_reader *r)
{
    io_dataset_close(r->ds);
    r->ds = NULL;
}

/* The k-th of n scored frames of a clip of F: evenly spaced, first and last included. */
static int score_frame(int k, int n, int F) { return n > 1 ? (int)lround((double)k * (F - 1) / (n - 1)) : 0; }

/* The scored frames' moving pixels: colour off the still scene by more than 0.12 in a channel,
 * dilated 2 px (a square), once for the scores before and after the phase. */
static void score_masks(train_detail *d)
{
    const int W = d->cam.width, H = d->cam.height;
    const size_t px = (size_t)W * H;
    for (int k = 0; k < d->score_frames; k++) {
        const uint8_t *rgb = d->score_rgb + (size_t)k * px * 3;
        uint8_t *grown = d->score_moving + (size_t)k * px, *mv = grown; /* off the still scene, then grown in place by rows */
        for (size_t i = 0; i < px; i++) {
            const float *b = d->still + 3 * i;
            mv[i] = max3(fabsf(rgb[3 * i] / 255.0f - b[0]), fabsf(rgb[3 * i + 1] / 255.0f - b[1]),
                         fabsf(rgb[3 * i + 2] / 255.0f - b[2])) > DETAIL_SCORE_MOVING;
        }
        uint8_t *row = pg_malloc(px, "score masks");
        if (!row) continue; /* the moving part then counts without its border */
        memcpy(row, mv, px);
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++) {
                int on = 0;
                for (int dy = -DETAIL_SCORE_DILATE; dy <= DETAIL_SCORE_DILATE && !on; dy++)
                    for (int dx = -DETAIL_SCORE_DILATE; dx <= DETAIL_SCORE_DILATE && !on; dx++) {
                        int yy = y + dy, xx = x + dx;
                        on = yy >= 0 && yy < H && xx >= 0 && xx < W && row[(size_t)yy * W + xx];
                    }
                grown[(size_t)y * W + x] = (uint8_t)on;
            }
        free(row);
    }
}

/* Frame f's box (d->rect) kept in DETAIL_TILE tiles: those holding a moving pixel of the
 * working-size view (its trainer mask, dilated) get their pixels, the others are the still scene's
 * (the median) - a box holds every mover of the frame, half of a classroom's, and most of it is
 * still. */
static pg_status keep_box(const train_session *s, train_detail *d, int f, int real, const uint8_t *frame)
{
    const train_set *ts = s->ts;
    const int *r = d->rect + 4 * (size_t)f, W = d->cam.width, T = DETAIL_TILE;
    const int tw = (r[2] + T - 1) / T, th = (r[3] + T - 1) / T;
    const float kx = (float)W / ts->width, ky = (float)d->cam.height / ts->height;
    const uint8_t *mv = s->moving[real] + (size_t)f * ts->width * ts->height;
    int *tiles = pg_malloc((size_t)tw * th * sizeof(int), "full-size box"), kept = 0;
    if (!tiles) return PG_ERR_NOMEM;
    for (int ty = 0; ty < th; ty++)
        for (int tx = 0; tx < tw; tx++) {
            int X0 = (int)((r[0] + tx * T) / kx), X1 = (int)ceilf((r[0] + (tx + 1) * T) / kx);
            int Y0 = (int)((r[1] + ty * T) / ky), Y1 = (int)ceilf((r[1] + (ty + 1) * T) / ky);
            X1 = X1 > ts->width ? ts->width : X1, Y1 = Y1 > ts->height ? ts->height : Y1;
            int on = 0;
            for (int y = Y0; y < Y1 && !on; y++)
                for (int x = X0; x < X1 && !on; x++) on = mv[(size_t)y * ts->width + x];
            tiles[ty * tw + tx] = on ? kept++ : -1;
        }
    uint8_t *px = pg_malloc((size_t)(kept > 0 ? kept : 1) * T * T * 3, "full-size box");
    if (!px) {
        free(tiles);
        return PG_ERR_NOMEM;
    }
    for (int ty = 0; ty < th; ty++)
        for (int tx = 0; tx < tw; tx++) {
            int k = tiles[ty * tw + tx];
            if (k < 0) continue;
            const int X = r[0] + tx * T, w = X + T <= r[0] + r[2] ? T : r[0] + r[2] - X;
            for (int y = 0; y < T && r[1] + ty * T + y < r[1] + r[3]; y++)
                memcpy(px + ((size_t)k * T + y) * T * 3, frame + ((size_t)(r[1] + ty * T + y) * W + X) * 3, (size_t)w * 3);
        }
    d->crop[f] = px;
    d->tiles[f] = tiles;
    return PG_OK;
}

/* One pass over the source's frames at full size: the sampled frames' median (the still scene)
 * and each frame's movers' box, cut out. */
static pg_status read_frames(train_session *s, const train_detail_config *c, train_detail *d)
{
    const train_set *ts = s->ts;
    frame_reader rd;
    pg_status st = reader_open(&rd, c);
    if (st) {
        reader_close(&rd);
        return st;
    }
    const int W = rd.width, H = rd.height, F = ts->frames;
    if (rd.source_width > W)
        fprintf(stderr, "prodygs: train: %s is %dx%d; the full-size phase works at %dx%d (its longer side at most %d)\n",
                c->input, rd.source_width, rd.source_height, W, H, TRAIN_DETAIL_MAX_SIDE);
    if (rd.frames < F)
        st = pg_fail(PG_ERR_FORMAT, "%s: %d frames, but the training set has %d", c->input, rd.frames, F);
    else if (W < ts->width || H < ts->height || fabs((double)W / H - (double)ts->width / ts->height) > 0.02)
        st = pg_fail(PG_ERR_FORMAT, "%s: %dx%d frames do not scale to the training set's %dx%d", c->input, W, H,
                     ts->width, ts->height);
    const float kx = (float)W / ts->width, ky = (float)H / ts->height;
    int real = 0;
    while (ts->views[real].role != IO_ROLE_REAL) real++;
    const pg_camera *rc = &ts->views[real].cam;
    d->cam = *rc;
    d->cam.width = W, d->cam.height = H;
    d->cam.fx *= kx, d->cam.fy *= ky, d->cam.cx *= kx, d->cam.cy *= ky;
    d->frames = F;
    int n_samples = F < DETAIL_STILL_SAMPLES ? F : DETAIL_STILL_SAMPLES;
    uint8_t *samples[DETAIL_STILL_SAMPLES] = { 0 };
    const size_t values = (size_t)W * H * 3;
    d->crop = pg_calloc((size_t)F, sizeof *d->crop, "full-size boxes");
    d->tiles = pg_calloc((size_t)F, sizeof *d->tiles, "full-size boxes");
    d->rect = pg_calloc((size_t)F * 4, sizeof *d->rect, "full-size boxes");
    d->still = pg_malloc(values * sizeof(float), "still scene");
    if (!st && (!d->crop || !d->tiles || !d->rect || !d->still)) st = PG_ERR_NOMEM;
    for (int k = 0; k < n_samples && !st; k++)
        if (!(samples[k] = pg_malloc(values, "still samples"))) st = PG_ERR_NOMEM;
    const int n_score = F < TRAIN_DETAIL_SCORE_FRAMES ? F : TRAIN_DETAIL_SCORE_FRAMES;
    d->score_frames = n_score;
    d->score_rgb = pg_malloc((size_t)n_score * values, "score frames");
    d->score_moving = pg_malloc((size_t)n_score * W * H, "score frames");
    uint8_t *frame = pg_malloc(values, "full-size frame");
    if (!st && (!d->score_rgb || !d->score_moving || !frame)) st = PG_ERR_NOMEM;
    pg_image img = { 0 };
    double t0 = pg_time_seconds();
    for (int f = 0, next_score = 0; f < F && !st; f++) {
        const int sample = (int)((long)f * n_samples / F), first = (int)(((long)sample * F + n_samples - 1) / n_samples);
        const train_region *b = s->crop_view >= 0 ? train_motion_regions_at(&s->regions[s->crop_view], f) : NULL;
        const int scored = next_score < n_score && f == score_frame(next_score, n_score, F);
        if (f != first && !b && !scored) continue;
        if ((st = reader_frame(&rd, f, &img))) break;
        pg_image_to_rgb8(&img, frame);
        if (f == first) memcpy(samples[sample], frame, values);
        if (scored) memcpy(d->score_rgb + (size_t)next_score++ * values, frame, values);
        if (b) {
            int x0 = (int)floorf(b->x * kx) - DETAIL_BOX_PAD, y0 = (int)floorf(b->y * ky) - DETAIL_BOX_PAD;
            int x1 = (int)ceilf((b->x + b->w) * kx) + DETAIL_BOX_PAD, y1 = (int)ceilf((b->y + b->h) * ky) + DETAIL_BOX_PAD;
            x0 = x0 < 0 ? 0 : x0, y0 = y0 < 0 ? 0 : y0, x1 = x1 > W ? W : x1, y1 = y1 > H ? H : y1;
            int *r = d->rect + 4 * (size_t)f;
            r[0] = x0, r[1] = y0, r[2] = x1 - x0, r[3] = y1 - y0;
            if ((st = keep_box(s, d, f, real, frame))) break;
            const int w = r[2] < TRAIN_DETAIL_WINDOW ? r[2] : TRAIN_DETAIL_WINDOW, h = r[3] < TRAIN_DETAIL_WINDOW ? r[3] : TRAIN_DETAIL_WINDOW;
            if ((size_t)w * h > d->max_px) d->max_px = (size_t)w * h;
            if (w > d->max_w) d->max_w = w;
            if (h > d->max_h) d->max_h = h;
        }
        if ((f + 1) % 10 == 0 || f + 1 == F) {
            double el = pg_time_seconds() - t0;
            pg_progress_report("detail", f + 1, F, "frame %d/%d at %dx%d eta=%.0fs", f + 1, F, W, H, el / (f + 1) * (F - f - 1));
        }
    }
    pg_image_destroy(&img);
    reader_close(&rd);
    free(frame);
    if (!st) median_frames(samples, n_samples, values, d->still);
    for (int k = 0; k < n_samples; k++) free(samples[k]);
    if (!st) score_masks(d);
    return st;
}

/* The session's per-pixel buffers, grown to the largest full-size box. */
static pg_status grow_buffers(train_session *s)
{
    const train_detail *d = s->detail;
    const size_t px = d->max_px > (size_t)s->ts->width * s->ts->height ? d->max_px : (size_t)s->ts->width * s->ts->height;
    float *t = realloc(s->target.data, px * 3 * sizeof(float));
    if (t) s->target.data = t;
    float *m = realloc(s->mask, px * sizeof(float));
    if (m) s->mask = m;
    float *r = realloc(s->d_rgb, px * 3 * sizeof(float));
    if (r) s->d_rgb = r;
    float *g = realloc(s->d_depth, px * sizeof(float));
    if (g) s->d_depth = g;
    if (!t || !m || !r || !g) return pg_fail(PG_ERR_NOMEM, "train: out of memory for %zu-pixel crops", px);
    optim_ssim_destroy(s->ssim_crop);
    s->ssim_crop = NULL;
    int w = d->max_w > s->ts->width ? d->max_w : s->ts->width, h = d->max_h > s->ts->height ? d->max_h : s->ts->height;
    return optim_ssim_create(&s->ssim_crop, h, w, 3);
}

/* Rows of g with flag set into out, through the 3D filter of var (as the renderer draws them). */
static pg_status filtered_rows(const pg_gaussians *g, const uint8_t *flag, const float *var, pg_gaussians *out,
                               float **out_var)
{
    int n = 0;
    for (int i = 0; i < g->count; i++) n += flag[i] != 0;
    PG_TRY(splat_gaussians_create_sh(out, n > 0 ? n : 1, splat_gaussians_sh_max(g)));
    PG_TRY(splat_gaussians_resize(out, n));
    out->sh_degree = g->sh_degree;
    *out_var = pg_malloc((size_t)(n > 0 ? n : 1) * sizeof(float), "still filter");
    if (!*out_var) return PG_ERR_NOMEM;
    for (int i = 0, k = 0; i < g->count; i++) {
        if (!flag[i]) continue;
        memcpy(out->means + 3 * (size_t)k, g->means + 3 * (size_t)i, 3 * sizeof(float));
        memcpy(out->log_scales + 3 * (size_t)k, g->log_scales + 3 * (size_t)i, 3 * sizeof(float));
        memcpy(out->quats + 4 * (size_t)k, g->quats + 4 * (size_t)i, 4 * sizeof(float));
        out->opacity[k] = g->opacity[i];
        memcpy(splat_gaussians_sh(out, (size_t)k), splat_gaussians_sh(g, (size_t)i), (size_t)out->sh_stride * sizeof(float));
        (*out_var)[k++] = var[i];
    }
    return PG_OK;
}

/* The still rows' surface depth per pixel of o (depth over alpha where they cover it), and
 * where they do not (alpha <= 0.5: what the movers always hid from the working-size model, a
 * hole in the still scene) the farther of the nearest covered pixels left and right on the row -
 * the background beside the hole, as the median image shows it there. 0 where a row has none. */
static void surface_depth(const pg_render_output *o, int W, int H, float *z)
{
    #pragma omp parallel for schedule(static)
    for (int y = 0; y < H; y++) {
        const size_t row = (size_t)y * W;
        float last = 0;
        for (int x = 0; x < W; x++) { /* the nearest covered pixel on the left */
            size_t i = row + x;
            if (o->alpha[i] > 0.5f) last = o->depth[i] / o->alpha[i];
            z[i] = o->alpha[i] > 0.5f ? -last : last; /* negative: covered */
        }
        last = 0;
        for (int x = W - 1; x >= 0; x--) {
            size_t i = row + x;
            if (z[i] < 0) {
                z[i] = last = -z[i];
                continue;
            }
            z[i] = fmaxf(z[i], last);
        }
    }
}

/* New still Gaussians, one per full-size pixel where the working-size model's still scene (rendered
 * at full size) misses the median image by more than DETAIL_STILL_RESIDUAL, the largest misses
 * first up to max_new: each a disc facing the camera, half a pixel wide, on the model's own
 * surface there (just in front of it), of the pixel's colour. */
static pg_status spawn_still(train_session *s, const pg_gaussians *still, int max_new, pg_gaussians *out)
{
    const train_detail *d = s->detail;
    const pg_camera *cam = &d->cam;
    const int W = cam->width, H = cam->height;
    const size_t px = (size_t)W * H;
    pg_render_settings rs = splat_default_settings();
    memcpy(rs.background, s->cfg.bg, sizeof rs.background);
    pg_render_output o;
    PG_TRY(splat_render_forward(s->raster, still, cam, &rs, &o));
    float *res = pg_malloc(px * sizeof(float), "still residual"), *zs = pg_malloc(px * sizeof(float), "still depth");
    if (!res || !zs) {
        free(res);
        free(zs);
        return PG_ERR_NOMEM;
    }
    surface_depth(&o, W, H, zs);
    int n = 0;
    for (size_t i = 0; i < px; i++) {
        const float *a = o.rgb + 3 * i, *b = d->still + 3 * i;
        res[i] = zs[i] > 0 ? max3(fabsf(a[0] - b[0]), fabsf(a[1] - b[1]), fabsf(a[2] - b[2])) : 0.0f;
        n += res[i] > DETAIL_STILL_RESIDUAL;
    }
    /* the threshold that keeps max_new: a histogram of the residuals above the floor */
    float thr = DETAIL_STILL_RESIDUAL;
    if (n > max_new) {
        enum { BINS = 1024 };
        long hist[BINS] = { 0 };
        for (size_t i = 0; i < px; i++)
            if (res[i] > DETAIL_STILL_RESIDUAL) hist[(int)fminf(res[i] * BINS, BINS - 1)]++;
        long kept = 0;
        int b = BINS - 1;
        while (b > 0 && kept + hist[b] <= max_new) kept += hist[b--];
        thr = (float)(b + 1) / BINS;
    }
    n = 0;
    for (size_t i = 0; i < px; i++) n += res[i] > thr;
    pg_status st = splat_gaussians_create_sh(out, n > 0 ? n : 1, splat_gaussians_sh_max(still));
    if (!st) st = splat_gaussians_resize(out, n);
    if (st) {
        free(res);
        free(zs);
        return st;
    }
    out->sh_degree = still->sh_degree;
    float Rt[9], q[4];
    mat3_transpose(Rt, cam->R); /* the camera's axes in the world: the discs face it */
    mat3_to_quat(q, Rt);
    const float op = 0.8f, logit = logf(op / (1.0f - op)), c0 = 0.28209479177387814f;
    int k = 0;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            size_t i = (size_t)y * W + x;
            if (!(res[i] > thr)) continue;
            float z = zs[i] * 0.997f, X[3];
            pg_camera_unproject(cam, x + 0.5f, y + 0.5f, z, X);
            memcpy(out->means + 3 * (size_t)k, X, sizeof X);
            float side = 0.5f * z / cam->fx;
            out->log_scales[3 * (size_t)k + 0] = logf(side);
            out->log_scales[3 * (size_t)k + 1] = logf(side);
            out->log_scales[3 * (size_t)k + 2] = logf(0.2f * side);
            memcpy(out->quats + 4 * (size_t)k, q, sizeof q);
            out->opacity[k] = logit;
            float *sh = splat_gaussians_sh(out, (size_t)k);
            for (int c = 0; c < 3; c++) sh[c] = (d->still[3 * i + c] - 0.5f) / c0;
            k++;
        }
    free(res);
    free(zs);
    return PG_OK;
}

/* Fits the new still Gaussians (fresh) to the median image at full size, in front of the old
 * still ones (held): L1 over the whole frame, Adam at 3DGS's rates. */
static pg_status fit_still(train_session *s, const pg_gaussians *held, pg_gaussians *fresh, const float *fresh_var)
{
    const train_detail *d = s->detail;
    const pg_camera *cam = &d->cam;
    const int W = cam->width, H = cam->height, nh = held->count, nf = fresh->count;
    pg_gaussians all = { 0 }, grad = { 0 }, fgrad = { 0 };
    optim_adam *opt = NULL;
    float *saved = pg_malloc((size_t)(nf > 0 ? nf : 1) * SPLAT_FILTER3D_SAVED * sizeof(float), "still fit");
    float *d_rgb = pg_malloc((size_t)W * H * 3 * sizeof(float), "still fit");
    pg_status st = saved && d_rgb ? PG_OK : PG_ERR_NOMEM;
    if (!st) st = splat_gaussians_create_sh(&all, nh + nf, splat_gaussians_sh_max(held));
    if (!st) st = splat_gaussians_create_sh(&grad, nh + nf, splat_gaussians_sh_max(held));
    if (!st) st = splat_gaussians_create_sh(&fgrad, nf > 0 ? nf : 1, splat_gaussians_sh_max(held));
    if (!st) st = splat_gaussians_resize(&fgrad, nf);
    if (!st) st = optim_adam_create_gaussians(&opt, nf, fresh->sh_stride, 1e-15f);
    if (!st) {
        st = splat_gaussians_copy(held, &all);
        if (!st) st = splat_gaussians_resize(&all, nh + nf);
        if (!st) st = splat_gaussians_resize(&grad, nh + nf);
    }
    /* colour and opacity at several times 3DGS's rates: every Gaussian starts near its pixel's colour
     * and the fit is ~100 steps, not thousands */
    const float lr[OPTIM_GAUSS_GROUPS] = { 1.6e-5f * s->extent, s->cfg.lr_scales, s->cfg.lr_quats, 2.0f * s->cfg.lr_opacity,
                                           DETAIL_STILL_LR_COLOUR * s->cfg.lr_sh_dc, s->cfg.lr_sh_rest };
    pg_render_settings rs = splat_default_settings();
    memcpy(rs.background, s->cfg.bg, sizeof rs.background);
    const size_t sh = (size_t)fresh->sh_stride;
    double t0 = pg_time_seconds();
    for (int it = 0; it < DETAIL_STILL_STEPS && !st; it++) {
        /* the fresh rows through the filter, after the held ones */
        memcpy(all.means + 3 * (size_t)nh, fresh->means, (size_t)nf * 3 * sizeof(float));
        memcpy(all.log_scales + 3 * (size_t)nh, fresh->log_scales, (size_t)nf * 3 * sizeof(float));
        memcpy(all.quats + 4 * (size_t)nh, fresh->quats, (size_t)nf * 4 * sizeof(float));
        memcpy(all.opacity + nh, fresh->opacity, (size_t)nf * sizeof(float));
        memcpy(splat_gaussians_sh(&all, (size_t)nh), fresh->sh, (size_t)nf * sh * sizeof(float));
        splat_filter3d_forward(all.log_scales + 3 * (size_t)nh, all.opacity + nh, fresh_var, nf, saved);
        pg_render_output o;
        if ((st = splat_render_forward(s->raster, &all, cam, &rs, &o))) break;
        double l1 = optim_l1_forward(o.rgb, d->still, NULL, H, W, 3);
        memset(d_rgb, 0, (size_t)W * H * 3 * sizeof(float));
        optim_l1_backward(d_rgb, 1.0f, o.rgb, d->still, NULL, H, W, 3);
        splat_gaussians_zero(&grad);
        if ((st = splat_render_backward(s->raster, &all, cam, &rs, d_rgb, NULL, NULL, &grad, NULL))) break;
        memcpy(fgrad.means, grad.means + 3 * (size_t)nh, (size_t)nf * 3 * sizeof(float));
        memcpy(fgrad.log_scales, grad.log_scales + 3 * (size_t)nh, (size_t)nf * 3 * sizeof(float));
        memcpy(fgrad.quats, grad.quats + 4 * (size_t)nh, (size_t)nf * 4 * sizeof(float));
        memcpy(fgrad.opacity, grad.opacity + nh, (size_t)nf * sizeof(float));
        memcpy(fgrad.sh, splat_gaussians_sh(&grad, (size_t)nh), (size_t)nf * sh * sizeof(float));
        splat_filter3d_backward(saved, fresh_var, nf, fgrad.log_scales, fgrad.opacity);
        if ((st = optim_adam_step_gaussians(opt, fresh, &fgrad, lr))) break;
        if ((it + 1) % 10 == 0) {
            double el = pg_time_seconds() - t0;
            pg_progress_report("detail", it + 1, DETAIL_STILL_STEPS, "still scene at %dx%d: step %d/%d l1=%.4f gaussians=%d eta=%.0fs",
                               W, H, it + 1, DETAIL_STILL_STEPS, l1, nf, el / (it + 1) * (DETAIL_STILL_STEPS - it - 1));
        }
    }
    optim_adam_destroy(opt);
    splat_gaussians_destroy(&all);
    splat_gaussians_destroy(&grad);
    splat_gaussians_destroy(&fgrad);
    free(saved);
    free(d_rgb);
    return st;
}

/* The fitted still Gaussians appended to the session as still rows. */
static pg_status append_still(train_session *s, const pg_gaussians *fresh)
{
    const int n0 = s->g.count, nf = fresh->count;
    PG_TRY(train_resize_all(s, n0 + nf));
    const size_t sh = (size_t)s->g.sh_stride;
    memcpy(s->g.means + 3 * (size_t)n0, fresh->means, (size_t)nf * 3 * sizeof(float));
    memcpy(s->g.log_scales + 3 * (size_t)n0, fresh->log_scales, (size_t)nf * 3 * sizeof(float));
    memcpy(s->g.quats + 4 * (size_t)n0, fresh->quats, (size_t)nf * 4 * sizeof(float));
    memcpy(s->g.opacity + n0, fresh->opacity, (size_t)nf * sizeof(float));
    for (int k = 0; k < nf; k++) memcpy(splat_gaussians_sh(&s->g, (size_t)(n0 + k)), splat_gaussians_sh(fresh, (size_t)k), sh * sizeof(float));
    memset(s->is_static + n0, 1, (size_t)nf);
    return PG_OK;
}

/* The still scene at full size: the old still rows held, new ones spawned and fitted. */
static pg_status detail_still(train_session *s, int max_new, int *added)
{
    pg_gaussians held = { 0 }, fresh = { 0 };
    float *held_var = NULL, *fresh_var = NULL;
    train_update_filter(s); /* with the full-size camera */
    pg_status st = filtered_rows(&s->g, s->is_static, s->filter_var, &held, &held_var);
    if (!st) splat_filter3d_forward(held.log_scales, held.opacity, held_var, held.count, NULL);
    if (!st) st = spawn_still(s, &held, max_new, &fresh);
    if (!st && !(fresh_var = pg_malloc((size_t)(fresh.count > 0 ? fresh.count : 1) * sizeof(float), "still filter")))
        st = PG_ERR_NOMEM;
    if (!st) {
        splat_filter3d_compute(fresh.means, fresh.count, &s->detail->cam, 1, fresh_var);
        splat_filter3d_fit_init(fresh.log_scales, fresh.opacity, fresh_var, fresh.count);
        st = fit_still(s, &held, &fresh, fresh_var);
    }
    if (!st) st = append_still(s, &fresh);
    *added = fresh.count;
    splat_gaussians_destroy(&held);
    splat_gaussians_destroy(&fresh);
    free(held_var);
    free(fresh_var);
    if (!st) train_update_filter(s);
    return st;
}

/* The model at the input's size against the source's frames: TRAIN_DETAIL_SCORE_FRAMES evenly
 * spaced frames, PSNR over the image and on the moving pixels (colour off the still scene by more
 * than 0.12 in a channel, dilated 2 px, as evaluation defines them). */
static pg_status score(train_session *s, double *psnr, double *psnr_moving, double *psnr_static)
{
    const train_detail *d = s->detail;
    const int W = d->cam.width, H = d->cam.height, F = s->ts->frames, n = d->score_frames;
    const size_t px = (size_t)W * H;
    pg_status st = PG_OK;
    double sum_db = 0, se_m = 0, se_s = 0, n_m = 0, n_s = 0;
    for (int k = 0; k < n && !st; k++) {
        const int f = score_frame(k, n, F);
        const uint8_t *rgb = d->score_rgb + (size_t)k * px * 3, *grown = d->score_moving + (size_t)k * px;
        pg_render_output o;
        if ((st = train_render_frame(s, f, &d->cam, &o))) break;
        double se = 0;
        for (size_t i = 0; i < (size_t)W * H; i++) {
            double e = 0;
            for (int ch = 0; ch < 3; ch++) {
                double v = fmin(fmax(o.rgb[3 * i + ch], 0.0), 1.0) - rgb[3 * i + ch] / 255.0;
                e += v * v;
            }
            se += e;
            if (grown[i]) se_m += e, n_m += 3;
            else se_s += e, n_s += 3;
        }
        double mse = se / (3.0 * W * H);
        sum_db += mse > 0 ? -10.0 * log10(mse) : 100.0;
        pg_progress_report("detail", k + 1, n, "scoring at %dx%d: frame %d", W, H, f);
    }
    *psnr = n > 0 ? sum_db / n : NAN;
    *psnr_moving = n_m > 0 ? -10.0 * log10(se_m / n_m) : NAN;
    *psnr_static = n_s > 0 ? -10.0 * log10(se_s / n_s) : NAN;
    return st;
}

pg_status train_session_detail(train_session *s, const train_detail_config *c, train_detail_scores *out)
{
    memset(out, 0, sizeof *out);
    out->psnr = out->psnr_moving = out->psnr_static = NAN;
    if (!s->fine || train_set_count_role(s->ts, IO_ROLE_REAL) != 1)
        return pg_fail(PG_ERR_ARG, "train: the full-size phase needs a trained model of one real view");
    double t0 = pg_time_seconds();
    train_detail_destroy(s->detail);
    if (!(s->detail = pg_calloc(1, sizeof *s->detail, "full-size phase"))) return PG_ERR_NOMEM;
    PG_TRY(read_frames(s, c, s->detail));
    out->width = s->detail->cam.width;
    out->height = s->detail->cam.height;
    out->frames_scored = s->ts->frames < TRAIN_DETAIL_SCORE_FRAMES ? s->ts->frames : TRAIN_DETAIL_SCORE_FRAMES;
    double unused;
    PG_TRY(score(s, &out->psnr_before, &out->psnr_moving_before, &unused));
    PG_TRY(grow_buffers(s));
    PG_TRY(train_freeze_off_motion(s, &out->movers_frozen));
    PG_TRY(detail_still(s, c->max_still > 0 ? c->max_still : TRAIN_DETAIL_MAX_STILL, &out->still_added));
    const int steps = c->steps > 0 ? c->steps : train_detail_default_steps(s->ts->frames), cap = s->cfg.max_gaussians;
    s->cfg.max_gaussians = s->g.count + DETAIL_MAX_NEW_MOVERS;
    memset(s->grad_accum, 0, (size_t)s->side_cap * sizeof(float));
    memset(s->grad_denom, 0, (size_t)s->side_cap * sizeof(float));
    double t1 = pg_time_seconds();
    pg_status st = PG_OK;
    for (int k = 0; k < steps && !st && s->crop_view >= 0; k++) { /* a clip without movers has the still scene only */
        s->detail->densify = k < steps / 2;
        st = train_session_step(s); /* its motion crops: the real view's a full-size window */
        if (!st && s->detail->densify && (k + 1) % DETAIL_DENSIFY_EVERY == 0) {
            st = train_densify_and_prune(s, 1);
            if (!st) train_update_filter(s);
        }
        if ((k + 1) % 10 == 0 || k + 1 == steps) {
            double el = pg_time_seconds() - t1;
            pg_progress_report("detail", k + 1, steps, "movers at %dx%d: step %d/%d loss=%.4f gaussians=%d eta=%.0fs",
                               out->width, out->height, k + 1, steps, s->last_loss, s->g.count, el / (k + 1) * (steps - k - 1));
        }
    }
    s->cfg.max_gaussians = cap > s->g.count ? cap : s->g.count;
    s->detail->densify = 0;
    if (!st) train_update_filter(s);
    if (!st && s->ckpt_path[0]) st = train_checkpoint_write(s, s->ckpt_path, 0);
    if (!st) st = score(s, &out->psnr, &out->psnr_moving, &out->psnr_static);
    out->gaussians = s->g.count;
    out->seconds = pg_time_seconds() - t0;
    return st;
}
