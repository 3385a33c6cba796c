/* cmd_info.c - `prodygs info PATH [--json]`: like ffprobe for our inputs. Says what a video,
 * frame folder, dataset (DyNeRF / Panoptic), depth file or folder, or Gaussian PLY holds.
 * Bad input: one line "prodygs: <file>: <problem>" and exit code 2. */
#include "cli/cli.h"
#include "core/fileutil.h"
#include "io/dataset.h"
#include "io/depth_io.h"
#include "io/image_io.h"
#include "io/json.h"
#include "io/ply.h"
#include "io/video.h"
#include "train/model.h"

#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

static const char *ext_of(const char *path)
{
    const char *dot = strrchr(path, '.'), *slash = strrchr(path, '/');
    return (dot && (!slash || dot > slash)) ? dot : "";
}

static int print_json(cJSON *o)
{
    char *s = cJSON_Print(o);
    cJSON_Delete(o);
    if (!s) {
        fprintf(stderr, "prodygs: out of memory\n");
        return 1;
    }
    printf("%s\n", s);
    cJSON_free(s);
    return 0;
}

static int info_dataset(const char *path, int json, pg_status *st_out)
{
    pg_dataset *ds;
    io_dataset_options o = io_dataset_defaults();
    pg_status st = io_dataset_open(path, &o, &ds);
    *st_out = st;
    if (st) return -1;
    int n = io_dataset_num_cameras(ds);
    io_dataset_kind kind = io_dataset_get_kind(ds);
    /* Decode the first frame of the first camera so a broken source is reported here (through
     * a one-frame selection: the dataset caches whole cameras). */
    pg_dataset *one = NULL;
    o.count = 1;
    st = io_dataset_open(path, &o, &one);
    pg_image img = { 0 };
    if (st == PG_OK) st = io_dataset_frame(one, 0, 0, &img);
    pg_image_destroy(&img);
    io_dataset_close(one);
    if (st) {
        io_dataset_close(ds);
        *st_out = st;
        return -1;
    }
    if (json) {
        cJSON *root = cJSON_CreateObject();
        cJSON_AddStringToObject(root, "path", path);
        cJSON_AddStringToObject(root, "type", kind == IO_DATASET_VIDEO || kind == IO_DATASET_FOLDER ? kind == IO_DATASET_VIDEO ? "video" : "frame_folder" : "dataset");
        cJSON_AddStringToObject(root, "layout", io_dataset_kind_name(kind));
        cJSON_AddNumberToObject(root, "frames", io_dataset_num_frames(ds));
        cJSON_AddNumberToObject(root, "fps", io_dataset_fps(ds));
        cJSON_AddNumberToObject(root, "width", io_dataset_width(ds));
        cJSON_AddNumberToObject(root, "height", io_dataset_height(ds));
        if (kind == IO_DATASET_VIDEO || kind == IO_DATASET_FOLDER) {
            io_video_info vi;
            if (io_video_probe(path, &vi) == PG_OK) cJSON_AddStringToObject(root, "codec", vi.codec);
        }
        cJSON *cams = cJSON_AddArrayToObject(root, "cameras");
        for (int c = 0; c < n; c++) {
            pg_camera cam;
            float C[3], nz, fz;
            io_dataset_camera(ds, c, &cam);
            pg_camera_center(&cam, C);
            io_dataset_near_far(ds, c, &nz, &fz);
            cJSON *co = io_json_from_camera(&cam, io_dataset_camera_name(ds, c));
            if (!co) continue;
            cJSON_AddItemToObject(co, "center", io_json_float_array(C, 3));
            cJSON_AddNumberToObject(co, "near", nz);
            cJSON_AddNumberToObject(co, "far", fz);
            if (io_dataset_camera_role(ds, c)[0]) cJSON_AddStringToObject(co, "role", io_dataset_camera_role(ds, c));
            cJSON_AddStringToObject(co, "source", io_dataset_camera_source(ds, c));
            cJSON_AddItemToArray(cams, co);
        }
        io_dataset_close(ds);
        return print_json(root);
    }
    if (kind == IO_DATASET_VIDEO || kind == IO_DATASET_FOLDER) {
        io_video_info vi;
        memset(&vi, 0, sizeof vi);
        io_video_probe(path, &vi);
        printf("%s: %s (%s), %d x %d, %d frames, %.3f fps\n", path, kind == IO_DATASET_VIDEO ? "video" : "frame folder",
               vi.codec, io_dataset_width(ds), io_dataset_height(ds), io_dataset_num_frames(ds), io_dataset_fps(ds));
    } else {
        printf("%s: %s dataset, %d cameras, %d frames, %.3f fps, %d x %d\n", path, io_dataset_kind_name(kind), n,
               io_dataset_num_frames(ds), io_dataset_fps(ds), io_dataset_width(ds), io_dataset_height(ds));
        for (int c = 0; c < n; c++) {
            pg_camera cam;
            float C[3], nz, fz;
            io_dataset_camera(ds, c, &cam);
            pg_camera_center(&cam, C);
            io_dataset_near_far(ds, c, &nz, &fz);
            printf("  %-8s%s%-5s f %.2f %.2f  c %.1f %.1f  centre (%.3f, %.3f, %.3f)", io_dataset_camera_name(ds, c),
                   io_dataset_camera_role(ds, c)[0] ? " " : "", io_dataset_camera_role(ds, c), cam.fx, cam.fy, cam.cx,
                   cam.cy, C[0], C[1], C[2]);
            if (nz > 0 || fz > 0) printf("  near %.3f far %.3f", nz, fz);
            printf("\n");
        }
    }
    io_dataset_close(ds);
    return 0;
}

static int info_depth(const char *path, int json, pg_status *st_out)
{
    io_depth d;
    pg_status st = io_depth_load(path, NULL, &d);
    *st_out = st;
    if (st) return -1;
    double frac = d.total ? (double)d.invalid / d.total : 0;
    if (json) {
        cJSON *root = cJSON_CreateObject();
        cJSON_AddStringToObject(root, "path", path);
        cJSON_AddStringToObject(root, "type", "depth");
        cJSON_AddNumberToObject(root, "frames", d.frames);
        cJSON_AddNumberToObject(root, "width", d.width);
        cJSON_AddNumberToObject(root, "height", d.height);
        cJSON_AddNumberToObject(root, "min", d.min);
        cJSON_AddNumberToObject(root, "max", d.max);
        cJSON_AddNumberToObject(root, "invalid", (double)d.invalid);
        cJSON_AddNumberToObject(root, "invalid_fraction", frac);
        io_depth_destroy(&d);
        return print_json(root);
    }
    printf("%s: depth, %d frames of %d x %d, range [%g, %g], %zu invalid pixels (%.2f%%)\n", path, d.frames, d.width,
           d.height, d.min, d.max, d.invalid, 100 * frac);
    io_depth_destroy(&d);
    return 0;
}

static int info_ply(const char *path, int json, pg_status *st_out)
{
    io_ply_info pi;
    pg_status st = io_ply_probe(path, &pi);
    *st_out = st;
    if (st) return -1;
    if (json) {
        cJSON *root = cJSON_CreateObject();
        cJSON_AddStringToObject(root, "path", path);
        cJSON_AddStringToObject(root, "type", "gaussians");
        cJSON_AddNumberToObject(root, "count", pi.count);
        cJSON_AddNumberToObject(root, "sh_degree", pi.sh_degree);
        cJSON_AddItemToObject(root, "bbox_min", io_json_float_array(pi.bbox_min, 3));
        cJSON_AddItemToObject(root, "bbox_max", io_json_float_array(pi.bbox_max, 3));
        cJSON_AddNumberToObject(root, "mean_opacity", pi.mean_opacity);
        return print_json(root);
    }
    printf("%s: %d Gaussians, SH degree %d, bbox (%.3f, %.3f, %.3f) - (%.3f, %.3f, %.3f), mean opacity %.3f\n", path,
           pi.count, pi.sh_degree, pi.bbox_min[0], pi.bbox_min[1], pi.bbox_min[2], pi.bbox_max[0], pi.bbox_max[1],
           pi.bbox_max[2], pi.mean_opacity);
    return 0;
}

static int info_image(const char *path, int json, pg_status *st_out)
{
    pg_image img;
    pg_status st = io_image_load(path, &img);
    *st_out = st;
    if (st) return -1;
    double mean = 0;
    size_t n = (size_t)img.width * img.height * img.channels;
    for (size_t i = 0; i < n; i++) mean += img.data[i];
    mean /= (double)n;
    int w = img.width, h = img.height;
    pg_image_destroy(&img);
    if (json) {
        cJSON *root = cJSON_CreateObject();
        cJSON_AddStringToObject(root, "path", path);
        cJSON_AddStringToObject(root, "type", "image");
        cJSON_AddNumberToObject(root, "width", w);
        cJSON_AddNumberToObject(root, "height", h);
        cJSON_AddNumberToObject(root, "mean", mean);
        return print_json(root);
    }
    printf("%s: image, %d x %d, mean value %.4f\n", path, w, h, mean);
    return 0;
}

/* A training checkpoint (model.ckpt from `prodygs train`). */
static int info_checkpoint(const char *path, int json, pg_status *st_out)
{
    train_model m;
    memset(&m, 0, sizeof m);
    pg_status st = train_model_load(path, &m);
    *st_out = st;
    if (st) return -1;
    int count = m.g.count, frames = m.frames, deform = m.net != NULL;
    long statics = 0;
    for (int i = 0; m.is_static && i < count; i++) statics += m.is_static[i] != 0;
    train_model_destroy(&m);
    if (json) {
        cJSON *root = cJSON_CreateObject();
        cJSON_AddStringToObject(root, "path", path);
        cJSON_AddStringToObject(root, "type", "checkpoint");
        cJSON_AddNumberToObject(root, "gaussians", count);
        cJSON_AddNumberToObject(root, "static", (double)statics);
        cJSON_AddNumberToObject(root, "frames", frames);
        cJSON_AddBoolToObject(root, "deformation", deform);
        return print_json(root);
    }
    printf("%s: trained model, %d Gaussians (%ld static), %d frames, deformation network %s\n", path, count, statics,
           frames, deform ? "yes" : "no (coarse stage only)");
    return 0;
}

/* A training-set directory (docs/FORMATS.md): DIR/trainset.json. */
static int info_trainset(const char *dir, const char *path, int json, pg_status *st_out)
{
    cJSON *root;
    pg_status st = io_json_load(path, &root);
    int frames = 0, w = 0, h = 0;
    const cJSON *cams = NULL;
    if (st == PG_OK) st = io_json_get_int(root, "frames", path, 1, 1000000, &frames);
    if (st == PG_OK) st = io_json_get_int(root, "width", path, 1, PG_MAX_IMAGE_SIDE, &w);
    if (st == PG_OK) st = io_json_get_int(root, "height", path, 1, PG_MAX_IMAGE_SIDE, &h);
    if (st == PG_OK) {
        cams = cJSON_GetObjectItemCaseSensitive(root, "cameras");
        if (!cJSON_IsArray(cams) || cJSON_GetArraySize(cams) == 0) st = pg_fail(PG_ERR_FORMAT, "%s: 'cameras' must be a non-empty array", path);
    }
    const cJSON *c;
    cJSON_ArrayForEach(c, cams)
    {
        pg_camera cam;
        if (st == PG_OK) st = io_json_to_camera(c, path, &cam, NULL, 0);
    }
    *st_out = st;
    if (st) {
        cJSON_Delete(root);
        return -1;
    }
    if (json) {
        cJSON *out = cJSON_Duplicate(root, 1);
        cJSON_Delete(root);
        if (!out) return 1;
        cJSON_AddStringToObject(out, "path", dir);
        cJSON_AddStringToObject(out, "type", "trainset");
        return print_json(out);
    }
    printf("%s: training set, %d cameras, %d frames of %d x %d, %.3f fps\n", dir, cJSON_GetArraySize(cams), frames, w, h,
           io_json_number_or(root, "fps", 0));
    cJSON_ArrayForEach(c, cams)
    {
        pg_camera cam;
        char name[128];
        float C[3];
        io_json_to_camera(c, path, &cam, name, sizeof name);
        pg_camera_center(&cam, C);
        const cJSON *mask = cJSON_GetObjectItemCaseSensitive(c, "mask"), *depth = cJSON_GetObjectItemCaseSensitive(c, "depth");
        printf("  %-10s %-6s f %.2f %.2f  centre (%.3f, %.3f, %.3f)%s%s\n", name, io_json_string_or(c, "role", "?"), cam.fx,
               cam.fy, C[0], C[1], C[2], cJSON_IsString(mask) ? "  mask" : "", cJSON_IsString(depth) ? "  depth" : "");
    }
    cJSON_Delete(root);
    return 0;
}

/* A folder with depth files but no images is a depth folder. */
static int is_depth_folder(const char *path)
{
    DIR *d = opendir(path);
    if (!d) return 0;
    int depth = 0, image = 0;
    struct dirent *e;
    while ((e = readdir(d)) != NULL) {
        const char *x = ext_of(e->d_name);
        if (!strcasecmp(x, ".npy") || !strcasecmp(x, ".pfm") || !strcasecmp(x, ".exr")) depth++;
        if (!strcasecmp(x, ".jpg") || !strcasecmp(x, ".jpeg")) image++;
    }
    closedir(d);
    return depth > 0 && image == 0;
}

int cmd_info(int argc, char **argv)
{
    int json = 0;
    cli_option opts[] = { { "--json", CLI_FLAG, &json, "print JSON instead of text" } };
    cli_spec spec = { "prodygs info", "PATH [--json]",
                      "Describe a video, frame folder, dataset (DyNeRF/Panoptic), training set, depth file/folder,\n"
                      "Gaussian PLY or training checkpoint (.ckpt).\n\n"
                      "example: prodygs info depth.npy",
                      opts, 1, 1, 1 };
    const char *pos[1];
    int npos = 0;
    int rc = cli_parse(&spec, argc, argv, pos, &npos);
    if (rc) return rc < 0 ? 0 : rc;
    const char *path = pos[0];
    pg_status st = PG_OK;
    const char *x = ext_of(path);
    if (!pg_path_exists(path)) {
        fprintf(stderr, "prodygs: %s: no such file or folder\n", path);
        return 2;
    }
    char probe[4200];
    int is_dir = pg_path_is_dir(path);
    int dataset_dir = is_dir && ((pg_path_join(probe, sizeof probe, path, "poses_bounds.npy") == PG_OK && pg_path_exists(probe)) ||
                                 (pg_path_join(probe, sizeof probe, path, "train_meta.json") == PG_OK && pg_path_exists(probe)) ||
                                 (pg_path_join(probe, sizeof probe, path, "test_meta.json") == PG_OK && pg_path_exists(probe)));
    char trainset[4200];
    if (is_dir && pg_path_join(trainset, sizeof trainset, path, "trainset.json") == PG_OK && pg_path_exists(trainset))
        rc = info_trainset(path, trainset, json, &st);
    else if (!dataset_dir && is_dir && is_depth_folder(path)) rc = info_depth(path, json, &st);
    else if (!is_dir && (!strcasecmp(x, ".npy") || !strcasecmp(x, ".pfm") || !strcasecmp(x, ".exr"))) rc = info_depth(path, json, &st);
    else if (!is_dir && (!strcasecmp(x, ".png") || !strcasecmp(x, ".jpg") || !strcasecmp(x, ".jpeg")))
        rc = info_image(path, json, &st);
    else if (!is_dir && !strcasecmp(x, ".ply")) rc = info_ply(path, json, &st);
    else if (!is_dir && !strcasecmp(x, ".ckpt")) rc = info_checkpoint(path, json, &st);
    else rc = info_dataset(path, json, &st);
    if (rc < 0) return cli_fail(st);
    return rc;
}
