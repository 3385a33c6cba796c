/* dataset.c - dataset detection, the common accessors, lazy frame decoding, single video/folder. */
#include "io/dataset_internal.h"
#include "core/fileutil.h"
#include "io/image_io.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

io_dataset_options io_dataset_defaults(void)
{
    io_dataset_options o;
    memset(&o, 0, sizeof o);
    o.stride = 1;
    o.fov_deg = 60.0f;
    o.fps = 30.0;
    return o;
}

static const char *const kind_names[IO_DATASET_KIND_COUNT] = { "dynerf", "panoptic", "video", "folder" };

const char *io_dataset_kind_name(io_dataset_kind kind)
{
    return (int)kind >= 0 && kind < IO_DATASET_KIND_COUNT ? kind_names[kind] : "unknown";
}

pg_status ds_alloc_cameras(pg_dataset *ds, int n)
{
    ds->cams = pg_calloc((size_t)n, sizeof *ds->cams, "dataset cameras");
    if (!ds->cams) return PG_ERR_NOMEM;
    ds->num_cams = n;
    return PG_OK;
}

pg_status ds_select_frames(pg_dataset *ds, const char *what, int available)
{
    const io_dataset_options *o = &ds->opt;
    ds->first = o->first > 0 ? o->first : 0;
    ds->stride = o->stride > 0 ? o->stride : 1;
    if (available <= 0) return pg_fail(PG_ERR_FORMAT, "%s: has no frames", what);
    if (ds->first >= available)
        return pg_fail(PG_ERR_ARG, "%s: first frame %d is past the end (%d frames)", what, ds->first, available);
    int can = (available - ds->first + ds->stride - 1) / ds->stride;
    if (o->count > can)
        return pg_fail(PG_ERR_ARG, "%s: asked for %d frames from %d with stride %d, but only %d exist", what, o->count,
                       ds->first, ds->stride, can);
    ds->frames = o->count > 0 ? o->count : can;
    return PG_OK;
}

void ds_set_sizes(pg_dataset *ds, int src_w, int src_h)
{
    io_video_options vo = io_video_defaults();
    vo.width = ds->opt.width;
    vo.height = ds->opt.height;
    vo.max_side = ds->opt.max_side;
    ds->src_width = src_w;
    ds->src_height = src_h;
    io_video_target_size(&vo, src_w, src_h, &ds->width, &ds->height);
    /* A WxH that changes the aspect stretches the picture; the camera model follows, but the user
     * probably meant one side only. Said once per process (every stage reopens the input), and
     * only for the user's --size: a stage's own decode size (io_dataset_set_frame_size) is not one. */
    static int warned;
    double a0 = (double)src_w / src_h, a1 = (double)ds->width / ds->height;
    if (!warned && !ds->internal_size && fabs(a1 / a0 - 1.0) > 0.01) {
        warned = 1;
        pg_warn("%s: --size %dx%d changes the aspect ratio of the %dx%d input (%.3f -> %.3f): frames are stretched; "
                "give one side (e.g. --size %dx0) to keep it", ds->path, ds->width, ds->height, src_w, src_h, a0, a1,
                ds->width);
    }
}

/* One static camera at the identity: the in-the-wild case. */
static pg_status open_single(pg_dataset *ds)
{
    io_video_info info;
    PG_TRY(io_video_probe(ds->path, &info));
    int available = info.frames;
    if (!info.frames_exact || available <= 0) PG_TRY(io_video_count_frames(ds->path, &available));
    ds->kind = info.is_folder ? IO_DATASET_FOLDER : IO_DATASET_VIDEO;
    ds->fps = info.is_folder ? ds->opt.fps : info.fps;
    PG_TRY(ds_select_frames(ds, ds->path, available));
    PG_TRY(ds_alloc_cameras(ds, 1));
    ds_camera *c = &ds->cams[0];
    const char *base = strrchr(ds->path, '/');
    base = base && base[1] ? base + 1 : ds->path;
    snprintf(c->name, sizeof c->name, "%.40s", base);
    char *dot = strrchr(c->name, '.');
    if (dot && dot != c->name && !info.is_folder) *dot = '\0';
    snprintf(c->source, sizeof c->source, "%s", ds->path);
    c->cams = pg_calloc(1, sizeof *c->cams, "camera");
    if (!c->cams) return PG_ERR_NOMEM;
    c->num_cams = 1;
    if (!(ds->opt.fov_deg > 0 && ds->opt.fov_deg < 179) && !(ds->opt.focal > 0))
        return pg_fail(PG_ERR_ARG, "%s: field of view %g must be in (0, 179) degrees", ds->path, ds->opt.fov_deg);
    pg_camera_from_fov(c->cams, info.width, info.height, ds->opt.fov_deg > 0 ? ds->opt.fov_deg : 60.0f);
    if (ds->opt.focal > 0) c->cams->fx = c->cams->fy = ds->opt.focal;
    ds_set_sizes(ds, info.width, info.height);
    return PG_OK;
}

pg_status io_dataset_open(const char *path, const io_dataset_options *opt, pg_dataset **out)
{
    *out = NULL;
    if (strlen(path) >= 4000) return pg_fail(PG_ERR_ARG, "%s: path too long", path);
    pg_dataset *ds = pg_calloc(1, sizeof *ds, "dataset");
    if (!ds) return PG_ERR_NOMEM;
    ds->opt = opt ? *opt : io_dataset_defaults();
    if (ds->opt.fps <= 0) ds->opt.fps = 30.0;
    snprintf(ds->path, sizeof ds->path, "%s", path);
    size_t n = strlen(ds->path);
    while (n > 1 && ds->path[n - 1] == '/') ds->path[--n] = '\0';
    pg_status st;
    char probe[4200];
    if (!pg_path_exists(path)) {
        st = pg_fail(PG_ERR_IO, "%s: no such file or folder", path);
    } else if ((st = pg_check_input(path)) != PG_OK) {
        /* a FIFO or device: nothing to open */
    } else if (pg_path_is_dir(path) &&
               ((pg_path_join(probe, sizeof probe, ds->path, "train_meta.json"), pg_path_exists(probe)) ||
                (pg_path_join(probe, sizeof probe, ds->path, "test_meta.json"), pg_path_exists(probe)))) {
        /* Checked first: a Panoptic folder may carry a poses_bounds.npy as well. */
        ds->kind = IO_DATASET_PANOPTIC;
        st = ds_open_panoptic(ds);
    } else if (pg_path_is_dir(path) &&
               (pg_path_join(probe, sizeof probe, ds->path, "poses_bounds.npy"), pg_path_exists(probe))) {
        ds->kind = IO_DATASET_DYNERF;
        st = ds_open_dynerf(ds);
    } else {
        st = open_single(ds);
        if (st && st != PG_ERR_ARG && pg_path_is_dir(path)) /* a bad option is not a layout problem */
            pg_fail_context(st, "%s: not a DyNeRF (poses_bounds.npy), Panoptic (train_meta.json) or frame folder", path);
    }
    if (st) {
        io_dataset_close(ds);
        return st;
    }
    *out = ds;
    return PG_OK;
}

void io_dataset_close(pg_dataset *ds)
{
    if (!ds) return;
    for (int i = 0; i < ds->num_cams; i++) {
        ds_camera *c = &ds->cams[i];
        io_frames_destroy(&c->cache);
        if (c->frame_paths)
            for (int t = 0; t < ds->frames; t++) free(c->frame_paths[t]);
        free(c->frame_paths);
        free(c->cams);
    }
    free(ds->cams);
    free(ds);
}

io_dataset_kind io_dataset_get_kind(const pg_dataset *ds) { return ds->kind; }
int io_dataset_num_cameras(const pg_dataset *ds) { return ds->num_cams; }
int io_dataset_num_frames(const pg_dataset *ds) { return ds->frames; }
double io_dataset_fps(const pg_dataset *ds) { return ds->fps; }
int io_dataset_width(const pg_dataset *ds) { return ds->width; }
int io_dataset_height(const pg_dataset *ds) { return ds->height; }
int io_dataset_source_width(const pg_dataset *ds) { return ds->src_width; }
int io_dataset_source_height(const pg_dataset *ds) { return ds->src_height; }

void io_dataset_set_frame_size(pg_dataset *ds, int width, int height)
{
    io_dataset_release(ds, -1);
    ds->opt.width = width;
    ds->opt.height = height;
    ds->opt.max_side = 0;
    ds->internal_size = 1;
    ds_set_sizes(ds, ds->src_width, ds->src_height);
}

const char *io_dataset_camera_name(const pg_dataset *ds, int cam)
{
    return cam >= 0 && cam < ds->num_cams ? ds->cams[cam].name : "";
}

const char *io_dataset_camera_role(const pg_dataset *ds, int cam)
{
    return cam >= 0 && cam < ds->num_cams ? ds->cams[cam].role : "";
}

const char *io_dataset_camera_source(const pg_dataset *ds, int cam)
{
    return cam >= 0 && cam < ds->num_cams ? ds->cams[cam].source : "";
}

int io_dataset_find_camera(const pg_dataset *ds, const char *name)
{
    for (int i = 0; i < ds->num_cams; i++)
        if (!strcmp(ds->cams[i].name, name)) return i;
    return -1;
}

/* The camera names, comma-separated, cut short for very long lists. */
static void list_names(const pg_dataset *ds, char *out, size_t size)
{
    size_t len = 0;
    out[0] = '\0';
    for (int i = 0; i < ds->num_cams && len + 8 < size; i++) {
        int n = snprintf(out + len, size - len, "%s%s", i ? ", " : "", ds->cams[i].name);
        if (n < 0 || (size_t)n >= size - len) {
            snprintf(out + (size > 4 ? size - 4 : 0), 4, "...");
            return;
        }
        len += (size_t)n;
    }
}

pg_status io_dataset_resolve_camera(const pg_dataset *ds, const char *token, int *index)
{
    int by_name = io_dataset_find_camera(ds, token);
    if (by_name >= 0) {
        *index = by_name;
        return PG_OK;
    }
    char *end;
    errno = 0;
    long v = strtol(token, &end, 10);
    int plain = end != token && *end == '\0' && !errno && token[0] >= '0' && token[0] <= '9';
    if (plain && v >= 0 && v < ds->num_cams) {
        *index = (int)v;
        return PG_OK;
    }
    char names[1024];
    list_names(ds, names, sizeof names);
    if (plain)
        return pg_fail(PG_ERR_ARG, "camera '%s': no camera has that name and index %ld is out of range 0..%d (cameras: %s)",
                       token, v, ds->num_cams - 1, names);
    return pg_fail(PG_ERR_ARG, "camera '%s': no camera has that name (cameras: %s)", token, names);
}

pg_status io_dataset_resolve_cameras(const pg_dataset *ds, const char *list, int *out, int max, int *count)
{
    *count = 0;
    const char *p = list;
    while (*p) {
        const char *e = strchr(p, ',');
        size_t n = e ? (size_t)(e - p) : strlen(p);
        char token[128];
        if (n == 0 || n >= sizeof token) return pg_fail(PG_ERR_ARG, "camera list '%s': empty or overlong entry", list);
        memcpy(token, p, n);
        token[n] = '\0';
        int idx;
        PG_TRY(io_dataset_resolve_camera(ds, token, &idx));
        for (int k = 0; k < *count; k++)
            if (out[k] == idx) return pg_fail(PG_ERR_ARG, "camera list '%s': camera %s named twice", list, token);
        if (*count >= max) return pg_fail(PG_ERR_ARG, "camera list '%s': more than %d cameras", list, max);
        out[(*count)++] = idx;
        p += n;
        if (*p == ',') p++;
    }
    if (*count == 0) return pg_fail(PG_ERR_ARG, "camera list '%s' is empty", list);
    return PG_OK;
}

void io_dataset_camera_label(const pg_dataset *ds, int cam, char *out, size_t size)
{
    snprintf(out, size, "%s (index %d)", io_dataset_camera_name(ds, cam), cam);
}

void io_dataset_camera_at(const pg_dataset *ds, int cam, int t, pg_camera *out)
{
    memset(out, 0, sizeof *out);
    if (cam < 0 || cam >= ds->num_cams) return;
    const ds_camera *c = &ds->cams[cam];
    int k = c->num_cams > 1 ? (t < 0 ? 0 : t >= c->num_cams ? c->num_cams - 1 : t) : 0;
    *out = c->cams[k];
    pg_camera_resize(out, ds->width, ds->height);
}

void io_dataset_camera(const pg_dataset *ds, int cam, pg_camera *out)
{
    io_dataset_camera_at(ds, cam, 0, out);
}

void io_dataset_near_far(const pg_dataset *ds, int cam, float *near_z, float *far_z)
{
    *near_z = *far_z = 0;
    if (cam < 0 || cam >= ds->num_cams) return;
    *near_z = ds->cams[cam].near_z;
    *far_z = ds->cams[cam].far_z;
}

/* Decodes every selected frame of one camera into its uint8 cache. */
static pg_status decode_camera(pg_dataset *ds, ds_camera *c)
{
    io_frames *fr = &c->cache;
    if (!c->frame_paths) {
        io_video_options vo = io_video_defaults();
        vo.first = ds->first;
        vo.count = ds->frames;
        vo.stride = ds->stride;
        vo.width = ds->width;
        vo.height = ds->height;
        vo.folder_fps = ds->fps;
        PG_TRY(io_frames_read(c->source, &vo, fr));
        if (fr->src_width != ds->src_width || fr->src_height != ds->src_height) {
            pg_status st = pg_fail(PG_ERR_SIZE, "%s: frames are %d x %d, other cameras %d x %d", c->source,
                                   fr->src_width, fr->src_height, ds->src_width, ds->src_height);
            io_frames_destroy(fr);
            return st;
        }
        return PG_OK;
    }
    /* Panoptic: one image file per frame. */
    size_t per = (size_t)ds->width * ds->height * 3;
    fr->rgb = pg_malloc(per * (size_t)ds->frames, c->source);
    if (!fr->rgb) return PG_ERR_NOMEM;
    fr->width = ds->width;
    fr->height = ds->height;
    fr->src_width = ds->src_width;
    fr->src_height = ds->src_height;
    fr->fps = ds->fps;
    pg_image img = { 0 }, small = { 0 };
    pg_status st = PG_OK;
    for (int t = 0; t < ds->frames && st == PG_OK; t++) {
        st = io_image_load(c->frame_paths[t], &img);
        if (st) break;
        if (img.width != ds->src_width || img.height != ds->src_height) {
            st = pg_fail(PG_ERR_SIZE, "%s: is %d x %d, the dataset says %d x %d", c->frame_paths[t], img.width,
                         img.height, ds->src_width, ds->src_height);
        } else {
            const pg_image *use = &img;
            if (img.width != ds->width || img.height != ds->height) {
                st = pg_image_resize(&small, &img, ds->width, ds->height);
                use = &small;
            }
            if (st == PG_OK) {
                uint8_t *dst = fr->rgb + per * (size_t)t;
                for (size_t i = 0; i < per; i++) {
                    float v = use->data[i] * 255.0f + 0.5f;
                    dst[i] = (uint8_t)(v < 0 ? 0 : v > 255 ? 255 : v);
                }
            }
        }
        pg_image_destroy(&img);
        pg_image_destroy(&small);
    }
    if (st) io_frames_destroy(fr);
    else fr->count = ds->frames;
    return st;
}

pg_status io_dataset_frame(pg_dataset *ds, int cam, int t, pg_image *img)
{
    if (cam < 0 || cam >= ds->num_cams) return pg_fail(PG_ERR_ARG, "%s: camera %d out of range (0..%d)", ds->path, cam, ds->num_cams - 1);
    if (t < 0 || t >= ds->frames) return pg_fail(PG_ERR_ARG, "%s: frame %d out of range (0..%d)", ds->path, t, ds->frames - 1);
    ds_camera *c = &ds->cams[cam];
    if (c->cache.count == 0) PG_TRY(decode_camera(ds, c));
    return io_frames_image(&c->cache, t, img);
}

void io_dataset_release(pg_dataset *ds, int cam)
{
    for (int i = 0; i < ds->num_cams; i++)
        if (cam < 0 || cam == i) io_frames_destroy(&ds->cams[i].cache);
}
