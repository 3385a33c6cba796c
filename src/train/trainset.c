/* trainset.c - load a training set (docs/FORMATS.md) or build one from a DyNeRF dataset. */
#include "train/trainset.h"
#include "io/json.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/fileutil.h"
#include "core/mathx.h"
#include "io/dataset.h"
#include "io/image_io.h"
#include "io/npy.h"

#define TS_MAX_VIEWS 4096
#define TS_MAX_FRAMES 100000

void train_set_destroy(train_set *ts)
{
    if (!ts) return;
    for (int i = 0; i < ts->num_views; i++) {
        free(ts->views[i].rgb);
        free(ts->views[i].mask);
        free(ts->views[i].depth);
    }
    free(ts->views);
    memset(ts, 0, sizeof *ts);
}

int train_set_count_role(const train_set *ts, io_view_role role)
{
    int n = 0;
    for (int i = 0; i < ts->num_views; i++) n += ts->views[i].role == role;
    return n;
}

void train_set_frame_rgb(const train_set *ts, int v, int f, pg_image *img)
{
    size_t px = (size_t)ts->width * ts->height;
    const uint8_t *src = ts->views[v].rgb + (size_t)f * px * 3;
    #pragma omp parallel for schedule(static)
    for (size_t i = 0; i < px * 3; i++) img->data[i] = src[i] * (1.0f / 255.0f);
}

float train_view_depth(const train_view *v, size_t i) { return io_half_to_float(v->depth[i]) * v->depth_scale; }

void train_view_depth_frame(const train_view *v, int f, size_t px, float *out)
{
    const uint16_t *h = v->depth + (size_t)f * px;
    io_halves_to_floats(h, px, v->depth_scale, out); /* a frame is ~0.1 ms: no threads */
}

/* Value i of the depth being stored: of the float array, or (d NULL) the raw half in the view. */
static inline float depth_in(const train_view *v, const float *d, size_t i) { return d ? d[i] : io_half_to_float(v->depth[i]); }

size_t train_view_set_depth(train_view *v, const float *d, size_t n)
{
    /* the scale: the median of up to 4k strided valid values */
    size_t stride = n / 4096 + 1, m = 0, valid = 0;
    float sample[4200];
    for (size_t i = 0; i < n; i += stride) {
        float x = depth_in(v, d, i);
        if (isfinite(x) && x > 0 && m < 4200) sample[m++] = x;
    }
    float scale = 1.0f;
    if (m > 0) {
        qsort(sample, m, sizeof(float), pg_cmp_float);
        scale = sample[m / 2];
    }
    v->depth_scale = scale;
    float inv = 1.0f / scale;
    #pragma omp parallel for schedule(static) reduction(+ : valid)
    for (size_t i = 0; i < n; i++) {
        float x = depth_in(v, d, i); /* in place when d is NULL: element i is read before it is written */
        int ok = isfinite(x) && x > 0;
        uint16_t h = ok ? io_float_to_half(x * inv) : 0;
        if (ok && (h & 0x7fff) >= 0x7c00) h = 0x7bff; /* beyond 65504 medians: the largest half */
        if (ok && h == 0) h = 1;                      /* below the smallest: still valid */
        v->depth[i] = h;
        valid += (size_t)ok;
    }
    return valid;
}

/* Median of the valid depth of the real views, from at most ~64k evenly strided samples. */
static float real_depth_median(const train_set *ts)
{
    size_t px = (size_t)ts->width * ts->height * ts->frames, total = 0;
    for (int v = 0; v < ts->num_views; v++)
        if (ts->views[v].role == IO_ROLE_REAL && ts->views[v].depth) total += px;
    if (total == 0) return 0;
    size_t stride = total / 65536 + 1, n = 0, k = 0;
    float *sample = pg_malloc((total / stride + 1) * sizeof(float), "depth median");
    if (!sample) return 0;
    for (int v = 0; v < ts->num_views; v++) {
        if (ts->views[v].role != IO_ROLE_REAL || !ts->views[v].depth) continue;
        for (size_t i = 0; i < px; i++, k++)
            if (k % stride == 0 && ts->views[v].depth[i]) sample[n++] = train_view_depth(&ts->views[v], i);
    }
    float med = 0;
    if (n > 0) {
        qsort(sample, n, sizeof(float), pg_cmp_float);
        med = sample[n / 2];
    }
    free(sample);
    return med;
}

void train_set_normalize_units(train_set *ts)
{
    float scene = real_depth_median(ts);
    if (!(scene > 0) && ts->has_scene) scene = ts->radius;
    float unit = isfinite(scene) && scene > 0 ? scene / TRAIN_SET_UNIT_DEPTH : 1.0f;
    float inv = 1.0f / unit;
    for (int v = 0; v < ts->num_views; v++) {
        for (int k = 0; k < 3; k++) ts->views[v].cam.t[k] *= inv;
        ts->views[v].depth_scale *= inv;
    }
    for (int k = 0; k < 3; k++) ts->center[k] *= inv;
    ts->radius *= inv;
    ts->near_z *= inv;
    ts->far_z *= inv;
    ts->unit = unit * train_set_unit(ts);
}

pg_camera train_set_user_camera(const train_set *ts, int v)
{
    pg_camera c = ts->views[v].cam;
    float unit = train_set_unit(ts);
    for (int k = 0; k < 3; k++) c.t[k] *= unit;
    return c;
}

pg_status train_set_add_view(train_set *ts, const char *name, io_view_role role, const pg_camera *cam,
                             int with_mask, int with_depth, int *index)
{
    if (ts->num_views >= TS_MAX_VIEWS) return pg_fail(PG_ERR_SIZE, "training set: more than %d views", TS_MAX_VIEWS);
    train_view *nv = realloc(ts->views, sizeof(train_view) * (size_t)(ts->num_views + 1));
    if (!nv) return pg_fail(PG_ERR_NOMEM, "training set: out of memory for views");
    ts->views = nv;
    train_view *v = &ts->views[ts->num_views];
    memset(v, 0, sizeof *v);
    snprintf(v->name, sizeof v->name, "%s", name);
    v->role = role;
    v->cam = *cam;
    size_t px, n;
    if (pg_size_mul((size_t)ts->width, (size_t)ts->height, &px) || pg_size_mul(px, (size_t)ts->frames, &n))
        return pg_fail(PG_ERR_SIZE, "training set: %d frames of %dx%d overflow", ts->frames, ts->width, ts->height);
    ts->num_views++; /* counted now so destroy frees partial allocations */
    v->rgb = pg_malloc(n * 3, "training-set images");
    if (!v->rgb) return PG_ERR_NOMEM;
    if (with_mask) {
        v->mask = pg_malloc(n, "training-set masks");
        if (!v->mask) return PG_ERR_NOMEM;
        memset(v->mask, TRAIN_MASK_FULL, n);
    }
    if (with_depth) {
        v->depth = pg_calloc(n, sizeof *v->depth, "training-set depth");
        v->depth_scale = 1.0f;
        if (!v->depth) return PG_ERR_NOMEM;
    }
    if (index) *index = ts->num_views - 1;
    return PG_OK;
}

void train_set_limit_proxies(train_set *ts, int n)
{
    int P = train_set_count_role(ts, IO_ROLE_PROXY);
    if (n < 0 || n >= P) return;
    int k = 0, w = 0, next = 0;
    for (int i = 0; i < ts->num_views; i++) {
        train_view *v = &ts->views[i];
        int keep = 1;
        if (v->role == IO_ROLE_PROXY) {
            /* keep proxy k when it is the next of the n evenly spaced picks */
            keep = next < n && k == (int)((long)next * P / n);
            if (keep) next++;
            k++;
        }
        if (!keep) {
            free(v->rgb);
            free(v->mask);
            free(v->depth);
            continue;
        }
        if (w != i) ts->views[w] = *v;
        w++;
    }
    ts->num_views = w;
}

/* Stores a float image (any size equal to the set's) as uint8 frame f of view v. */
static void store_rgb(train_set *ts, int v, int f, const pg_image *img)
{
    size_t px = (size_t)ts->width * ts->height;
    uint8_t *dst = ts->views[v].rgb + (size_t)f * px * 3;
    for (size_t i = 0; i < px * 3; i++) {
        float x = img->data[i];
        x = x < 0 ? 0 : (x > 1 ? 1 : x);
        dst[i] = (uint8_t)lrintf(x * 255.0f);
    }
}

/* ---------- trainset.json directory ---------- */

/* One frame file of a view: its colours (a proxy's frames are JPEG) or its mask. */
typedef struct {
    train_set *ts;
    int vi, is_mask;
    const char *sub; /* the folder */
} frame_files;

static pg_status load_frame_file(const frame_files *ff, int f)
{
    train_set *ts = ff->ts;
    char path[4200], name[32];
    const size_t px = (size_t)ts->width * ts->height;
    snprintf(name, sizeof name, "%04d.png", f);
    PG_TRY(pg_path_join(path, sizeof path, ff->sub, name));
    if (!ff->is_mask && !pg_path_exists(path)) {
        snprintf(name, sizeof name, "%04d.jpg", f);
        PG_TRY(pg_path_join(path, sizeof path, ff->sub, name));
    }
    pg_image img = {0};
    PG_TRY(io_image_load(path, &img));
    pg_status st = PG_OK;
    if (img.width != ts->width || img.height != ts->height)
        st = pg_fail(PG_ERR_SIZE, "%s: %s is %dx%d, %s %dx%d", path, ff->is_mask ? "mask" : "image", img.width,
                     img.height, ff->is_mask ? "expected" : "trainset.json says", ts->width, ts->height);
    else if (ff->is_mask)
        for (size_t i = 0; i < px; i++)
            ts->views[ff->vi].mask[(size_t)f * px + i] = (unsigned char)lroundf(clampf(img.data[i * 3], 0, 1) * TRAIN_MASK_FULL);
    else
        store_rgb(ts, ff->vi, f, &img);
    pg_image_destroy(&img);
    return st;
}

/* Every frame file of a folder, decoded on the run's threads (each frame is its own file: the
 * loading was one core's PNG and JPEG decoding while the other waited). The error reported is the
 * first failing frame's, as a serial loop would report it. */
static pg_status load_frame_files(const frame_files *ff)
{
    int first_bad = ff->ts->frames;
    pg_status bad = PG_OK;
    char msg[1024] = "";
    #pragma omp parallel for schedule(dynamic, 4)
    for (int f = 0; f < ff->ts->frames; f++) {
        pg_status st = load_frame_file(ff, f);
        if (st) {
            #pragma omp critical(trainset_frame_error)
            if (f < first_bad) {
                first_bad = f;
                bad = st;
                snprintf(msg, sizeof msg, "%s", pg_last_error());
            }
        }
    }
    return bad ? pg_fail(bad, "%s", msg) : PG_OK;
}

static pg_status load_view_files(train_set *ts, int vi, const char *dir, const char *rgb_rel, const char *mask_rel,
                                 const char *depth_rel)
{
    char sub[4096], path[4200];
    size_t px = (size_t)ts->width * ts->height;
    pg_status st = PG_OK;
    PG_TRY(pg_path_join(sub, sizeof sub, dir, rgb_rel));
    frame_files ff = { ts, vi, 0, sub };
    st = load_frame_files(&ff);
    if (!st && mask_rel) {
        if ((st = pg_path_join(sub, sizeof sub, dir, mask_rel))) return st;
        ff.is_mask = 1;
        st = load_frame_files(&ff);
    }
    if (!st && depth_rel) {
        pg_array arr = {0};
        if ((st = pg_path_join(path, sizeof path, dir, depth_rel))) return st;
        /* a float16 file (what `proxies` writes) goes straight into the view's store and is scaled
         * there: no float copy of the whole clip */
        int halves = 0;
        if ((st = io_npy_load_half(path, ts->views[vi].depth, px * (size_t)ts->frames, &halves))) return st;
        if (halves) {
            train_view_set_depth(&ts->views[vi], NULL, px * (size_t)ts->frames);
            return PG_OK;
        }
        if ((st = io_npy_load(path, &arr))) return st;
        if (arr.count != px * (size_t)ts->frames)
            st = pg_fail(PG_ERR_SIZE, "%s: depth has %zu values, expected (%d, %d, %d)", path, arr.count, ts->frames,
                         ts->height, ts->width);
        else
            train_view_set_depth(&ts->views[vi], arr.data, arr.count);
        pg_array_destroy(&arr);
    }
    return st;
}

static const char *json_str_or_null(const cJSON *obj, const char *key)
{
    const cJSON *it = cJSON_GetObjectItemCaseSensitive(obj, key);
    return cJSON_IsString(it) ? it->valuestring : NULL;
}

pg_status train_set_load(const char *dir, train_set *ts)
{
    memset(ts, 0, sizeof *ts);
    char path[4096];
    PG_TRY(pg_path_join(path, sizeof path, dir, "trainset.json"));
    char *text = NULL;
    size_t size = 0;
    PG_TRY(pg_read_file(path, 64u << 20, &text, &size));
    cJSON *root = cJSON_Parse(text);
    free(text);
    if (!root) return pg_fail(PG_ERR_FORMAT, "%s: not valid JSON", path);
    pg_status st = PG_OK;
    double frames = 0, width = 0, height = 0, fps = 30;
    if ((st = io_json_get_number(root, "frames", path, &frames)) || (st = io_json_get_number(root, "width", path, &width)) ||
        (st = io_json_get_number(root, "height", path, &height)))
        goto done;
    io_json_get_number(root, "fps", path, &fps);
    if (frames < 1 || frames > TS_MAX_FRAMES || width < 1 || height < 1 || width > PG_MAX_IMAGE_SIDE ||
        height > PG_MAX_IMAGE_SIDE) {
        st = pg_fail(PG_ERR_SIZE, "%s: absurd size %g frames of %g x %g", path, frames, width, height);
        goto done;
    }
    ts->frames = (int)frames;
    ts->width = (int)width;
    ts->height = (int)height;
    ts->fps = (float)fps;
    const cJSON *scene = cJSON_GetObjectItemCaseSensitive(root, "scene");
    if (cJSON_IsObject(scene)) {
        double r = 0, n = 0, fz = 0;
        if (!io_json_get_floats(scene, "center", path, ts->center, 3) && !io_json_get_number(scene, "radius", path, &r)) {
            ts->has_scene = 1;
            ts->radius = (float)r;
            if (!io_json_get_number(scene, "near", path, &n)) ts->near_z = (float)n;
            if (!io_json_get_number(scene, "far", path, &fz)) ts->far_z = (float)fz;
        }
    }
    /* source.unit: hemisphere proxies keep the depth file's numbers and carry --depth-scale here */
    double unit;
    if ((st = io_json_get_source_unit(root, "unit", path, &unit))) goto done;
    ts->unit = (float)unit;
    const cJSON *cams = cJSON_GetObjectItemCaseSensitive(root, "cameras");
    if (!cJSON_IsArray(cams) || cJSON_GetArraySize(cams) < 1) {
        st = pg_fail(PG_ERR_FORMAT, "%s: \"cameras\" must be a non-empty array", path);
        goto done;
    }
    const cJSON *c;
    cJSON_ArrayForEach(c, cams)
    {
        pg_camera cam;
        if ((st = io_json_to_camera(c, path, &cam, NULL, 0))) goto done;
        const char *name = json_str_or_null(c, "name");
        const char *role_s = json_str_or_null(c, "role");
        const char *rgb = json_str_or_null(c, "rgb");
        const char *mask = json_str_or_null(c, "mask");
        const char *depth = json_str_or_null(c, "depth");
        if (!name || !role_s || !rgb) {
            st = pg_fail(PG_ERR_FORMAT, "%s: every camera needs \"name\", \"role\" and \"rgb\"", path);
            goto done;
        }
        int role = io_view_role_parse(role_s);
        if (role < 0) {
            st = pg_fail(PG_ERR_FORMAT, "%s: camera %s has unknown role \"%s\"", path, name, role_s);
            goto done;
        }
        if (cam.width != ts->width || cam.height != ts->height) {
            st = pg_fail(PG_ERR_SIZE, "%s: camera %s is %dx%d but the set is %dx%d", path, name, cam.width,
                         cam.height, ts->width, ts->height);
            goto done;
        }
        int vi;
        if ((st = train_set_add_view(ts, name, (io_view_role)role, &cam, mask != NULL, depth != NULL, &vi))) goto done;
        if ((st = load_view_files(ts, vi, dir, rgb, mask, depth))) goto done;
    }
done:
    cJSON_Delete(root);
    if (st) train_set_destroy(ts);
    return st;
}

/* ---------- DyNeRF dataset (real cameras) ---------- */

train_set_dynerf_options train_set_dynerf_defaults(void)
{
    train_set_dynerf_options o;
    memset(&o, 0, sizeof o);
    o.all_real = 1;
    return o;
}

static int in_list(const int *list, int n, int x)
{
    for (int i = 0; i < n; i++)
        if (list[i] == x) return 1;
    return 0;
}

/* Copies depth (F', H', W') into view vi, nearest-neighbour resampled to the set's size. */
static pg_status store_depth(train_set *ts, int vi, const char *path)
{
    pg_array dep = {0};
    PG_TRY(io_npy_load(path, &dep));
    pg_status st = PG_OK;
    if (dep.ndim != 3 || dep.shape[0] < (size_t)ts->frames) {
        st = pg_fail(PG_ERR_SIZE, "%s: depth must be (F>=%d, H, W)", path, ts->frames);
    } else if (dep.shape[1] < 1 || dep.shape[2] < 1 ||
               fabs((double)dep.shape[2] * ts->height / ((double)dep.shape[1] * ts->width) - 1.0) > 0.05) {
        /* Resampling is fine for another resolution, not for another aspect (wrong file). */
        st = pg_fail(PG_ERR_SIZE, "%s: depth is (%zu, %zu, %zu) but the frames are (%d, %d, %d) (F, H, W): aspect differs",
                     path, dep.shape[0], dep.shape[1], dep.shape[2], ts->frames, ts->height, ts->width);
    } else {
        int dh = (int)dep.shape[1], dw = (int)dep.shape[2];
        size_t px = (size_t)ts->width * ts->height, valid = 0;
        float *d = pg_malloc(px * (size_t)ts->frames * sizeof(float), path);
        if (!d) st = PG_ERR_NOMEM;
        for (int f = 0; d && f < ts->frames; f++)
            for (int y = 0; y < ts->height; y++)
                for (int x = 0; x < ts->width; x++) {
                    int sx = (int)((x + 0.5f) * dw / ts->width), sy = (int)((y + 0.5f) * dh / ts->height);
                    d[(size_t)f * px + (size_t)y * ts->width + x] = dep.data[((size_t)f * dh + sy) * dw + sx];
                }
        if (d) valid = train_view_set_depth(&ts->views[vi], d, px * (size_t)ts->frames);
        free(d);
        if (!st && !valid) st = pg_fail(PG_ERR_FORMAT, "%s: no valid depth (every value is NaN, inf or <= 0)", path);
    }
    pg_array_destroy(&dep);
    return st;
}

pg_status train_set_from_dynerf(const char *dir, const train_set_dynerf_options *opt, train_set *ts)
{
    memset(ts, 0, sizeof *ts);
    io_dataset_options o = io_dataset_defaults();
    if (opt->width > 0) o.width = opt->width;
    if (opt->max_frames > 0) o.count = opt->max_frames;
    pg_dataset *ds = NULL;
    PG_TRY(io_dataset_open(dir, &o, &ds));
    pg_status st = PG_OK;
    pg_image img = {0};
    int ncam = io_dataset_num_cameras(ds);
    for (int i = 0; i < opt->num_test; i++)
        if (opt->test_cams[i] < 0 || opt->test_cams[i] >= ncam) {
            st = pg_fail(PG_ERR_ARG, "%s: test camera %d does not exist (%d cameras)", dir, opt->test_cams[i], ncam);
            goto done;
        }
    for (int i = 0; !opt->all_real && i < opt->num_real; i++)
        if (opt->real_cams[i] < 0 || opt->real_cams[i] >= ncam) {
            st = pg_fail(PG_ERR_ARG, "%s: camera %d does not exist (%d cameras)", dir, opt->real_cams[i], ncam);
            goto done;
        }
    ts->frames = io_dataset_num_frames(ds);
    ts->width = io_dataset_width(ds);
    ts->height = io_dataset_height(ds);
    ts->fps = (float)io_dataset_fps(ds);
    float near_min = 1e30f, far_max = 0;
    int depth_view = -1;
    for (int c = 0; c < ncam; c++) {
        int is_test = in_list(opt->test_cams, opt->num_test, c);
        int is_real = opt->all_real ? !is_test : in_list(opt->real_cams, opt->num_real, c);
        if (!is_test && !is_real) continue;
        pg_camera cam;
        io_dataset_camera(ds, c, &cam);
        float zn, zf;
        io_dataset_near_far(ds, c, &zn, &zf);
        if (zn > 0 && zn < near_min) near_min = zn;
        if (zf > far_max) far_max = zf;
        int want_depth = is_real && depth_view < 0 && opt->depth_path;
        int vi;
        if ((st = train_set_add_view(ts, io_dataset_camera_name(ds, c), is_test ? IO_ROLE_TEST : IO_ROLE_REAL,
                                     &cam, 0, want_depth, &vi)))
            goto done;
        if (want_depth) depth_view = vi;
        for (int f = 0; f < ts->frames; f++) {
            if ((st = io_dataset_frame(ds, c, f, &img))) goto done;
            store_rgb(ts, vi, f, &img);
            pg_image_destroy(&img);
        }
        io_dataset_release(ds, c);
    }
    if (ts->num_views == 0) {
        st = pg_fail(PG_ERR_ARG, "%s: no cameras selected", dir);
        goto done;
    }
    if (depth_view >= 0 && (st = store_depth(ts, depth_view, opt->depth_path))) goto done;
    ts->near_z = near_min < 1e30f ? near_min : 0;
    ts->far_z = far_max;
done:
    pg_image_destroy(&img);
    io_dataset_close(ds);
    if (st) train_set_destroy(ts);
    return st;
}
