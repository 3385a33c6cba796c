/* synth_dataset.c - writes the sample scene to disk (DyNeRF or Panoptic layout) and simulates
 * a monocular depth estimate of cam00.
 */
#include "synth/synth.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

#include "core/fileutil.h"
#include "core/output.h"
#include "core/mathx.h"
#include "core/progress.h"
#include "core/rng.h"
#include "io/image_io.h"
#include "io/json.h"
#include "io/npy.h"
#include "io/video.h"

void synth_options_default(synth_options *o)
{
    memset(o, 0, sizeof *o);
    o->cams = 10;
    o->frames = 30;
    o->width = 160;
    o->height = 120;
    o->seed = 1;
    o->spp = 2;
    o->fps = 30;
    o->layout = SYNTH_LAYOUT_DYNERF;
    o->video = 0;
    o->all_depth = 1;
}

/* ---------------------------------------------------------------- simulated monocular depth */

/* Separable Gaussian blur of one (H, W) plane, borders clamped. tmp is (H, W) scratch. */
static void blur_plane(float *img, float *tmp, int H, int W, float sigma)
{
    int r = (int)ceilf(3 * sigma);
    if (r < 1) return;
    float k[64];
    if (r > 31) r = 31;
    float sum = 0;
    for (int i = -r; i <= r; i++) sum += k[i + r] = expf(-0.5f * i * i / (sigma * sigma));
    for (int i = 0; i < 2 * r + 1; i++) k[i] /= sum;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            float a = 0;
            for (int i = -r; i <= r; i++) a += k[i + r] * img[(size_t)y * W + clampi(x + i, 0, W - 1)];
            tmp[(size_t)y * W + x] = a;
        }
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            float a = 0;
            for (int i = -r; i <= r; i++) a += k[i + r] * tmp[(size_t)clampi(y + i, 0, H - 1) * W + x];
            img[(size_t)y * W + x] = a;
        }
}

void synth_mono_info_destroy(synth_mono_info *info)
{
    if (!info) return;
    free(info->frame_scale);
    info->frame_scale = NULL;
}

pg_status synth_depth_mono(const float *gt, int F, int H, int W, uint64_t seed, float *mono, synth_mono_info *info)
{
    if (F < 1 || H < 1 || W < 1) return pg_fail(PG_ERR_ARG, "synth: bad depth shape (%d, %d, %d)", F, H, W);
    size_t plane = (size_t)H * W;
    float *tmp = pg_malloc(plane * sizeof(float), "depth_mono scratch");
    float *scale = pg_malloc((size_t)F * sizeof(float), "depth_mono scales");
    if (!tmp || !scale) {
        free(tmp);
        free(scale);
        return PG_ERR_NOMEM;
    }
    pg_rng rng;
    pg_rng_seed(&rng, seed * 0xD1B54A32D192ED03ull + 777);
    const float G = 1.25f, A = 0.05f, SN = 0.015f, LF = 0.03f, PN = 0.005f, SIGMA = 1.2f;
    /* shift: about 2 % of the median-ish scene depth, in mono units */
    double mean = 0;
    size_t nvalid = 0;
    for (size_t i = 0; i < plane; i++)
        if (gt[i] > 0) { mean += gt[i]; nvalid++; }
    mean = nvalid ? mean / nvalid : 1.0;
    const float shift = (float)(0.02 * G * mean);
    const float phase = (float)pg_rng_range(&rng, 0, 2 * PG_PI);
    for (int f = 0; f < F; f++) {
        float drift = A * sinf(2 * (float)PG_PI * 1.1f * (float)f / (float)(F > 1 ? F - 1 : 1) + phase) +
                      SN * (float)pg_rng_normal(&rng);
        scale[f] = G * (1 + drift);
    }
    /* low-frequency multiplicative field: three slow waves, slowly moving over time */
    float wk[3][5];
    for (int k = 0; k < 3; k++) {
        wk[k][0] = (float)pg_rng_range(&rng, -1.2, 1.2);     /* cycles across the width */
        wk[k][1] = (float)pg_rng_range(&rng, -1.2, 1.2);     /* cycles across the height */
        wk[k][2] = (float)pg_rng_range(&rng, 0, 2 * PG_PI);  /* phase */
        wk[k][3] = (float)pg_rng_range(&rng, -1.5, 1.5);     /* phase speed over the sequence */
        wk[k][4] = (float)pg_rng_range(&rng, 0.5, 1.0);      /* amplitude */
    }
    float asum = wk[0][4] + wk[1][4] + wk[2][4];
    for (int f = 0; f < F; f++) {
        const float *g = gt + (size_t)f * plane;
        float *m = mono + (size_t)f * plane;
        memcpy(m, g, plane * sizeof(float));
        blur_plane(m, tmp, H, W, SIGMA);
        float s = (float)f / (float)(F > 1 ? F - 1 : 1);
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++) {
                size_t i = (size_t)y * W + x;
                if (!(g[i] > 0)) {
                    m[i] = 0;
                    continue;
                }
                float field = 0;
                for (int k = 0; k < 3; k++)
                    field += wk[k][4] * sinf(2 * (float)PG_PI * (wk[k][0] * x / W + wk[k][1] * y / H) + wk[k][2] + wk[k][3] * s);
                float v = scale[f] * (1 + LF * field / asum) * m[i] + shift;
                v *= 1 + PN * (float)pg_rng_normal(&rng);
                m[i] = v > 1e-6f ? v : 1e-6f;
            }
    }
    free(tmp);
    if (info) {
        info->global_scale = G;
        info->shift = shift;
        info->drift_amplitude = A;
        info->drift_noise = SN;
        info->blur_sigma_px = SIGMA;
        info->lowfreq_amplitude = LF;
        info->pixel_noise = PN;
        info->frame_scale = scale;
        info->frames = F;
    } else {
        free(scale);
    }
    return PG_OK;
}

/* ---------------------------------------------------------------- JSON helpers */

/* Rounds to 7 significant digits so the JSON reads well (float precision anyway). */
static double jnum(double x)
{
    char buf[32];
    snprintf(buf, sizeof buf, "%.7g", x);
    return strtod(buf, NULL);
}

static cJSON *jarray(const float *v, int n)
{
    cJSON *a = cJSON_CreateArray();
    for (int i = 0; i < n; i++) cJSON_AddItemToArray(a, cJSON_CreateNumber(jnum(v[i])));
    return a;
}

static cJSON *jcamera(const pg_camera *c, const char *name)
{
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "name", name);
    cJSON_AddNumberToObject(o, "width", c->width);
    cJSON_AddNumberToObject(o, "height", c->height);
    cJSON_AddNumberToObject(o, "fx", jnum(c->fx));
    cJSON_AddNumberToObject(o, "fy", jnum(c->fy));
    cJSON_AddNumberToObject(o, "cx", jnum(c->cx));
    cJSON_AddNumberToObject(o, "cy", jnum(c->cy));
    cJSON_AddItemToObject(o, "R", jarray(c->R, 9));
    cJSON_AddItemToObject(o, "t", jarray(c->t, 3));
    return o;
}

/* Writes root atomically and frees it. */
static pg_status write_json(const char *path, cJSON *root)
{
    pg_status st = io_json_write_atomic(path, root);
    cJSON_Delete(root);
    return st;
}

static const char *SHAPE_NAMES[SYNTH_SHAPE_COUNT] = { "plane", "box", "sphere", "cylinder" };
static const char *TEX_NAMES[SYNTH_TEX_COUNT] = { "wood", "brick", "checker", "stripes", "marble", "segments" };

static pg_status write_scene_json(const char *path, const synth_scene *sc, const synth_options *o, const pg_camera *cams,
                                  const float *near_far, const synth_mono_info *mono, int video_backend)
{
    cJSON *root = cJSON_CreateObject();
    cJSON_AddNumberToObject(root, "version", 1);
    cJSON_AddStringToObject(root, "generator", "prodygs synth");
    cJSON_AddNumberToObject(root, "seed", (double)o->seed);
    cJSON_AddStringToObject(root, "layout", o->layout == SYNTH_LAYOUT_PANOPTIC ? "panoptic" : "dynerf");
    cJSON_AddNumberToObject(root, "frames", o->frames);
    cJSON_AddNumberToObject(root, "width", o->width);
    cJSON_AddNumberToObject(root, "height", o->height);
    cJSON_AddNumberToObject(root, "fps", jnum(o->fps));
    cJSON_AddNumberToObject(root, "spp", o->spp * o->spp);
    cJSON_AddStringToObject(root, "time", "normalised s = f / (frames - 1)");
    cJSON_AddStringToObject(root, "world_frame", "cam00 camera frame (OpenCV: x right, y down, z forward)");
    cJSON_AddStringToObject(root, "scene_frame", "x right, y away from the viewer, z up; table top z = 0");
    cJSON *s2w = cJSON_AddObjectToObject(root, "world_from_scene");
    cJSON_AddItemToObject(s2w, "R", jarray(sc->world_R, 9));
    cJSON_AddItemToObject(s2w, "t", jarray(sc->world_t, 3));
    cJSON_AddStringToObject(s2w, "note", "X_world = R X_scene + t");
    float lw[3];
    mat3_mul_vec(lw, sc->world_R, sc->light_dir);
    cJSON *light = cJSON_AddObjectToObject(root, "light");
    cJSON_AddItemToObject(light, "direction_world", jarray(lw, 3));
    cJSON_AddItemToObject(light, "direction_scene", jarray(sc->light_dir, 3));
    cJSON_AddNumberToObject(light, "ambient", jnum(sc->ambient));
    cJSON_AddNumberToObject(light, "diffuse", jnum(sc->diffuse));
    cJSON_AddBoolToObject(light, "shadows", sc->shadows);

    cJSON *objs = cJSON_AddArrayToObject(root, "objects");
    for (int k = 0; k < sc->num_objects; k++) {
        const synth_object *ob = &sc->objects[k];
        cJSON *j = cJSON_CreateObject();
        cJSON_AddStringToObject(j, "name", ob->name);
        cJSON_AddStringToObject(j, "shape", SHAPE_NAMES[ob->shape]);
        cJSON_AddStringToObject(j, "texture", TEX_NAMES[ob->texture]);
        cJSON_AddBoolToObject(j, "dynamic", ob->dynamic);
        cJSON_AddItemToObject(j, "size", jarray(ob->size, 3));
        cJSON *m = cJSON_AddObjectToObject(j, "motion_scene");
        cJSON_AddItemToObject(m, "p0", jarray(ob->p0, 3));
        cJSON_AddItemToObject(m, "p1", jarray(ob->p1, 3));
        cJSON_AddNumberToObject(m, "hop_height", jnum(ob->hop_height));
        cJSON_AddNumberToObject(m, "hop_count", jnum(ob->hop_count));
        cJSON_AddItemToObject(m, "axis", jarray(ob->axis, 3));
        cJSON_AddNumberToObject(m, "angle0", jnum(ob->angle0));
        cJSON_AddNumberToObject(m, "angle1", jnum(ob->angle1));
        cJSON_AddNumberToObject(m, "yaw", jnum(ob->yaw));
        cJSON_AddStringToObject(m, "formula",
                                "p(s) = p0 + (p1-p0) s + (0,0,hop_height |sin(pi hop_count s)|); "
                                "R(s) = Rot(axis, angle0 + (angle1-angle0) s) Rot(z, yaw)");
        /* per-frame world poses (X_world = R X_local + t) */
        cJSON *traj = cJSON_AddArrayToObject(j, "poses_world");
        int nf = ob->dynamic ? o->frames : 1;
        for (int f = 0; f < nf; f++) {
            float R[9], p[3];
            synth_object_pose(sc, k, synth_frame_time(f, o->frames), R, p);
            cJSON *pj = cJSON_CreateObject();
            cJSON_AddItemToObject(pj, "R", jarray(R, 9));
            cJSON_AddItemToObject(pj, "t", jarray(p, 3));
            cJSON_AddItemToArray(traj, pj);
        }
        cJSON_AddItemToArray(objs, j);
    }

    cJSON *cj = cJSON_AddArrayToObject(root, "cameras");
    for (int c = 0; c < o->cams; c++) {
        char name[16];
        snprintf(name, sizeof name, "cam%02d", c);
        cJSON *j = jcamera(&cams[c], name);
        cJSON_AddNumberToObject(j, "azimuth_deg", jnum(sc->cam_az[c]));
        cJSON_AddNumberToObject(j, "elevation_offset_deg", jnum(sc->cam_el[c]));
        cJSON_AddNumberToObject(j, "near", jnum(near_far[2 * c]));
        cJSON_AddNumberToObject(j, "far", jnum(near_far[2 * c + 1]));
        cJSON_AddItemToArray(cj, j);
    }
    cJSON *rig = cJSON_AddObjectToObject(root, "rig_scene");
    cJSON_AddItemToObject(rig, "target", jarray(sc->target, 3));
    cJSON_AddNumberToObject(rig, "radius", jnum(sc->radius));
    cJSON_AddNumberToObject(rig, "elevation_deg", jnum(sc->elevation_deg));
    cJSON_AddNumberToObject(rig, "fov_x_deg", jnum(sc->fov_x_deg));

    cJSON *dm = cJSON_AddObjectToObject(root, "depth_mono");
    cJSON_AddStringToObject(dm, "file", "depth_mono/cam00.npy");
    cJSON_AddStringToObject(dm, "model",
                            "mono = frame_scale[f] * (1 + lowfreq(x,y,f)) * blur(depth_gt) + shift, times (1 + pixel_noise N(0,1))");
    cJSON_AddNumberToObject(dm, "global_scale", jnum(mono->global_scale));
    cJSON_AddNumberToObject(dm, "shift", jnum(mono->shift));
    cJSON_AddNumberToObject(dm, "drift_amplitude", jnum(mono->drift_amplitude));
    cJSON_AddNumberToObject(dm, "drift_noise", jnum(mono->drift_noise));
    cJSON_AddNumberToObject(dm, "blur_sigma_px", jnum(mono->blur_sigma_px));
    cJSON_AddNumberToObject(dm, "lowfreq_amplitude", jnum(mono->lowfreq_amplitude));
    cJSON_AddNumberToObject(dm, "pixel_noise", jnum(mono->pixel_noise));
    cJSON_AddItemToObject(dm, "frame_scale", jarray(mono->frame_scale, mono->frames));
    cJSON *files = cJSON_AddObjectToObject(root, "files");
    cJSON_AddStringToObject(files, "depth_gt", "depth_gt/camXX.npy float32 (F,H,W) z-depth, 0 = no hit");
    if (video_backend >= 0)
        cJSON_AddStringToObject(files, "video", video_backend == IO_VIDEO_H264    ? "camXX.mp4 (H.264)"
                                                : video_backend == IO_VIDEO_MPEG4 ? "camXX.mp4 (MPEG-4 part 2 fallback)"
                                                                                  : "camXX_frames/ (PNG fallback: no video encoder)");
    cJSON_AddStringToObject(files, "masks_dynamic", "masks_dynamic/camXX.npy uint8 (F,H,W) 1 = moving object");
    cJSON_AddStringToObject(files, "covis_cam00",
                            "covis_cam00/camXX.npy uint8 (F,H,W) 1 = camXX pixel's surface point is also seen by cam00");
    return write_json(path, root);
}

/* ---------------------------------------------------------------- poses_bounds */

/* near, far = 0.1 / 99.9 percentiles of the valid depths of one (H, W) map. */
static void depth_bounds(const float *depth, size_t n, float *scratch, float *near, float *far)
{
    size_t m = 0;
    for (size_t i = 0; i < n; i++)
        if (depth[i] > 0) scratch[m++] = depth[i];
    if (m == 0) {
        *near = 0.1f;
        *far = 100.0f;
        return;
    }
    qsort(scratch, m, sizeof(float), pg_cmp_float);
    *near = scratch[(size_t)(0.001 * (m - 1))];
    *far = scratch[(size_t)(0.999 * (m - 1))];
}

/* One row of poses_bounds.npy: 3x5 [R|t|hwf] camera-to-world in LLFF order (columns down,
 * right, back = cam y, cam x, -cam z in world coordinates; t = camera centre; hwf = height,
 * width, focal), then near, far. */
static void llff_row(const pg_camera *c, float near, float far, float row[17])
{
    float C[3];
    pg_camera_center(c, C);
    for (int r = 0; r < 3; r++) {
        /* c2w = R^T: column j of c2w is row j of R */
        row[5 * r + 0] = c->R[3 + r];   /* down = cam y */
        row[5 * r + 1] = c->R[0 + r];   /* right = cam x */
        row[5 * r + 2] = -c->R[6 + r];  /* back = -cam z */
        row[5 * r + 3] = C[r];
    }
    row[4] = (float)c->height;
    row[9] = (float)c->width;
    row[14] = c->fx;
    row[15] = near;
    row[16] = far;
}

/* ---------------------------------------------------------------- Panoptic meta */

static pg_status write_panoptic_meta(const char *path, const synth_options *o, const pg_camera *cams, const int *ids,
                                     int n)
{
    cJSON *root = cJSON_CreateObject();
    cJSON_AddNumberToObject(root, "w", o->width);
    cJSON_AddNumberToObject(root, "h", o->height);
    cJSON *k = cJSON_AddArrayToObject(root, "k"), *w2c = cJSON_AddArrayToObject(root, "w2c");
    cJSON *fn = cJSON_AddArrayToObject(root, "fn"), *cid = cJSON_AddArrayToObject(root, "cam_id");
    for (int f = 0; f < o->frames; f++) {
        cJSON *kt = cJSON_CreateArray(), *wt = cJSON_CreateArray(), *ft = cJSON_CreateArray(), *ct = cJSON_CreateArray();
        for (int i = 0; i < n; i++) {
            const pg_camera *c = &cams[ids[i]];
            float K[3][3] = { { c->fx, 0, c->cx }, { 0, c->fy, c->cy }, { 0, 0, 1 } };
            cJSON *km = cJSON_CreateArray();
            for (int r = 0; r < 3; r++) cJSON_AddItemToArray(km, jarray(K[r], 3));
            cJSON_AddItemToArray(kt, km);
            cJSON *wm = cJSON_CreateArray();
            for (int r = 0; r < 3; r++) {
                float row[4] = { c->R[3 * r], c->R[3 * r + 1], c->R[3 * r + 2], c->t[r] };
                cJSON_AddItemToArray(wm, jarray(row, 4));
            }
            float last[4] = { 0, 0, 0, 1 };
            cJSON_AddItemToArray(wm, jarray(last, 4));
            cJSON_AddItemToArray(wt, wm);
            char name[64];
            snprintf(name, sizeof name, "%d/%06d.jpg", ids[i], f);
            cJSON_AddItemToArray(ft, cJSON_CreateString(name));
            cJSON_AddItemToArray(ct, cJSON_CreateNumber(ids[i]));
        }
        cJSON_AddItemToArray(k, kt);
        cJSON_AddItemToArray(w2c, wt);
        cJSON_AddItemToArray(fn, ft);
        cJSON_AddItemToArray(cid, ct);
    }
    return write_json(path, root);
}

/* ---------------------------------------------------------------- the writer */

/* Frames are rendered CHUNK at a time and their images encoded in parallel (PNG/JPEG encoding
 * is serial per image and would otherwise dominate small datasets). */
#define CHUNK 8

typedef struct {
    float *depth;          /* (F, H, W) */
    float *mono;           /* (F, H, W) */
    unsigned char *mask;   /* (F, H, W) */
    float *scratch;        /* (H, W) */
    pg_image rgb[CHUNK];
    synth_mono_info mono_info;
    int video_backend;     /* io_video_backend used for camXX.mp4, -1 = none */
} writer_buffers;

static void writer_free(writer_buffers *b)
{
    free(b->depth);
    free(b->mono);
    free(b->mask);
    free(b->scratch);
    for (int i = 0; i < CHUNK; i++) pg_image_destroy(&b->rgb[i]);
    synth_mono_info_destroy(&b->mono_info);
}

/* Encodes frames [f0, f0 + n) of one camera into dir, in parallel; returns the first failure
 * (in frame order) with its message. */
static pg_status save_chunk(const writer_buffers *b, const char *dir, int f0, int n, int jpeg)
{
    pg_status st[CHUNK];
    char msg[CHUNK][512];
#pragma omp parallel for schedule(dynamic, 1)
    for (int i = 0; i < n; i++) {
        char path[4096];
        int len = snprintf(path, sizeof path, jpeg ? "%s/%06d.jpg" : "%s/%04d.png", dir, f0 + i);
        if (len < 0 || (size_t)len >= sizeof path) st[i] = pg_fail(PG_ERR_ARG, "synth: output path too long");
        else st[i] = jpeg ? io_image_save_jpeg(path, &b->rgb[i], 95) : io_image_save_png(path, &b->rgb[i]);
        msg[i][0] = '\0';
        if (st[i]) snprintf(msg[i], sizeof msg[i], "%s", pg_last_error());
    }
    for (int i = 0; i < n; i++)
        if (st[i]) return pg_fail(st[i], "%s", msg[i]);
    return PG_OK;
}

static pg_status check_options(const synth_options *o)
{
    if (o->cams < 1 || o->cams > SYNTH_MAX_CAMS)
        return pg_fail(PG_ERR_ARG, "synth: --cams must be 1..%d (got %d)", SYNTH_MAX_CAMS, o->cams);
    if (o->frames < 1 || o->frames > 10000) return pg_fail(PG_ERR_ARG, "synth: --frames must be 1..10000 (got %d)", o->frames);
    if (o->width < 8 || o->height < 8 || o->width > 4096 || o->height > 4096)
        return pg_fail(PG_ERR_ARG, "synth: --size must be between 8x8 and 4096x4096 (got %dx%d)", o->width, o->height);
    if (o->spp < 1 || o->spp > 8) return pg_fail(PG_ERR_ARG, "synth: --spp must be 1..8 (got %d)", o->spp);
    if (o->layout < 0 || o->layout >= SYNTH_LAYOUT_COUNT) return pg_fail(PG_ERR_ARG, "synth: unknown layout %d", (int)o->layout);
    if (!(o->fps > 0)) return pg_fail(PG_ERR_ARG, "synth: fps must be > 0");
    return PG_OK;
}

static pg_status join_fmt(char *out, size_t size, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static pg_status join_fmt(char *out, size_t size, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(out, size, fmt, ap);
    va_end(ap);
    if (n < 0 || (size_t)n >= size) return pg_fail(PG_ERR_ARG, "synth: output path too long");
    return PG_OK;
}

static pg_status write_dataset_impl(const char *out, const synth_options *o, writer_buffers *b)
{
    synth_scene sc;
    synth_scene_default(&sc, o->seed);
    sc.spp = o->spp;
    const int F = o->frames, H = o->height, W = o->width, N = o->cams;
    const size_t plane = (size_t)H * W, vol = plane * (size_t)F;
    b->depth = pg_malloc(vol * sizeof(float), "synth depth");
    b->mono = pg_malloc(vol * sizeof(float), "synth mono depth");
    b->mask = pg_malloc(vol, "synth masks");
    b->scratch = pg_malloc(plane * sizeof(float), "synth scratch");
    if (!b->depth || !b->mono || !b->mask || !b->scratch) return PG_ERR_NOMEM;
    for (int i = 0; i < CHUNK; i++) PG_TRY(pg_image_create(&b->rgb[i], W, H, 3));

    char path[4096];
    PG_TRY(pg_mkdir_p(out));
    PG_TRY(join_fmt(path, sizeof path, "%s/depth_gt", out));
    PG_TRY(pg_mkdir_p(path));
    PG_TRY(join_fmt(path, sizeof path, "%s/masks_dynamic", out));
    PG_TRY(pg_mkdir_p(path));
    PG_TRY(join_fmt(path, sizeof path, "%s/depth_mono", out));
    PG_TRY(pg_mkdir_p(path));
    if (o->all_depth && N > 1) {
        PG_TRY(join_fmt(path, sizeof path, "%s/covis_cam00", out));
        PG_TRY(pg_mkdir_p(path));
    }

    pg_camera cams[SYNTH_MAX_CAMS];
    float near_far[2 * SYNTH_MAX_CAMS];
    float *rows = pg_calloc((size_t)N * 17, sizeof(float), "poses_bounds");
    if (!rows) return PG_ERR_NOMEM;
    pg_status st = PG_OK;
    const size_t shape3[3] = { (size_t)F, (size_t)H, (size_t)W };
    for (int c = 0; c < N && !st; c++) {
        st = synth_camera(&sc, c, W, H, &cams[c]);
        char dir[4096];
        if (!st) {
            if (o->layout == SYNTH_LAYOUT_PANOPTIC) st = join_fmt(dir, sizeof dir, "%s/ims/%d", out, c);
            else st = join_fmt(dir, sizeof dir, "%s/cam%02d/images", out, c);
        }
        if (!st) st = pg_mkdir_p(dir);
        io_video_writer *vw = NULL;
        if (!st && o->video && o->layout == SYNTH_LAYOUT_DYNERF) {
            io_video_write_options vo = io_video_write_defaults();
            vo.fps = o->fps;
            vo.crf = 10;
            st = join_fmt(path, sizeof path, "%s/cam%02d.mp4", out, c);
            if (!st) st = io_video_writer_open(&vw, path, W, H, &vo);
            if (!st) b->video_backend = (int)io_video_writer_backend(vw);
        }
        for (int f0 = 0; f0 < F && !st; f0 += CHUNK) {
            int n = F - f0 < CHUNK ? F - f0 : CHUNK;
            pg_progress_report("synth", (long)c * F + f0, (long)N * F, "cam%02d frame %d", c, f0);
            for (int i = 0; i < n && !st; i++) {
                int f = f0 + i;
                st = synth_render_frame(&sc, &cams[c], synth_frame_time(f, F), &b->rgb[i], b->depth + f * plane,
                                        b->mask + f * plane);
            }
            if (!st) st = save_chunk(b, dir, f0, n, o->layout == SYNTH_LAYOUT_PANOPTIC);
            for (int i = 0; i < n && !st && vw; i++) st = io_video_writer_add(vw, &b->rgb[i]);
        }
        if (vw) {
            if (st) io_video_writer_abort(vw);
            else st = io_video_writer_close(vw);
        }
        if (st) break;
        depth_bounds(b->depth, plane, b->scratch, &near_far[2 * c], &near_far[2 * c + 1]);
        llff_row(&cams[c], near_far[2 * c], near_far[2 * c + 1], rows + 17 * c);
        if (c == 0 || o->all_depth) {
            st = join_fmt(path, sizeof path, "%s/depth_gt/cam%02d.npy", out, c);
            if (!st) st = io_npy_save(path, b->depth, 3, shape3);
            if (!st) st = join_fmt(path, sizeof path, "%s/masks_dynamic/cam%02d.npy", out, c);
            if (!st) st = io_npy_save_u8(path, b->mask, 3, shape3);
        }
        if (!st && c > 0 && o->all_depth) {
            for (int f = 0; f < F && !st; f++)
                st = synth_render_covisibility(&sc, &cams[c], &cams[0], synth_frame_time(f, F), 1e-3f, b->mask + f * plane);
            if (!st) st = join_fmt(path, sizeof path, "%s/covis_cam00/cam%02d.npy", out, c);
            if (!st) st = io_npy_save_u8(path, b->mask, 3, shape3);
        }
        if (!st && c == 0) {
            st = synth_depth_mono(b->depth, F, H, W, o->seed, b->mono, &b->mono_info);
            if (!st) st = join_fmt(path, sizeof path, "%s/depth_mono/cam00.npy", out);
            if (!st) st = io_npy_save(path, b->mono, 3, shape3);
        }
    }
    if (!st && o->layout == SYNTH_LAYOUT_DYNERF) { /* (a Panoptic folder must not look like DyNeRF) */
        const size_t shape2[2] = { (size_t)N, 17 };
        st = join_fmt(path, sizeof path, "%s/poses_bounds.npy", out);
        if (!st) st = io_npy_save(path, rows, 2, shape2);
    }
    free(rows);
    if (!st && o->layout == SYNTH_LAYOUT_PANOPTIC) {
        int train[SYNTH_MAX_CAMS], test[SYNTH_MAX_CAMS], ntr = 0, nte = 0;
        for (int c = 0; c < N; c++) {
            if ((c == 5 || c == 6) && N > 2) test[nte++] = c;
            else train[ntr++] = c;
        }
        st = join_fmt(path, sizeof path, "%s/train_meta.json", out);
        if (!st) st = write_panoptic_meta(path, o, cams, train, ntr);
        if (!st && nte > 0) {
            st = join_fmt(path, sizeof path, "%s/test_meta.json", out);
            if (!st) st = write_panoptic_meta(path, o, cams, test, nte);
        }
    }
    if (!st) {
        st = join_fmt(path, sizeof path, "%s/scene.json", out);
        if (!st) st = write_scene_json(path, &sc, o, cams, near_far, &b->mono_info, b->video_backend);
    }
    if (!st) pg_progress_report("synth", (long)N * F, (long)N * F, "done");
    return st;
}

pg_status synth_write_dataset(const char *out_dir, const synth_options *o)
{
    PG_TRY(check_options(o));
    writer_buffers b;
    memset(&b, 0, sizeof b);
    b.video_backend = -1;
    pg_staged_dir out;
    PG_TRY(pg_output_claim_dir(out_dir)); /* checked and locked before any work (core/output.h) */
    pg_status st = pg_staged_dir_begin(&out, out_dir, 0);
    if (!st) {
        st = write_dataset_impl(out.work, o, &b);
        if (st) pg_staged_dir_abort(&out);
        else st = pg_staged_dir_commit(&out);
    }
    writer_free(&b);
    pg_output_release(out_dir);
    return st;
}
