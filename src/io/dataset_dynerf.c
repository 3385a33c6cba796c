/* dataset_dynerf.c - DyNeRF / Neural 3D Video layout: poses_bounds.npy + camXX videos or folders.
 *
 * poses_bounds.npy is (N, 17): per camera a 3x5 matrix (row-major) [R | t | hwf] followed by
 * near and far. This is the LLFF convention: R's columns are the camera's DOWN, RIGHT and BACK
 * axes expressed in world coordinates (camera-to-world), t is the camera centre, and
 * hwf = (image height, image width, focal length in pixels). OpenCV wants x right, y down,
 * z forward, so camera-to-world in OpenCV is [right | down | -back] = [col1 | col0 | -col2];
 * world-to-camera is its transpose with t_w2c = -R_w2c * centre. The principal point is the
 * image centre (LLFF has none). Intrinsics are scaled from the hwf size to the frames' size.
 */
#include "io/dataset_internal.h"
#include "core/fileutil.h"
#include "core/mathx.h"
#include "io/npy.h"

#include <ctype.h>
#include <dirent.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

void io_llff_to_camera(const float P[15], pg_camera *cam)
{
    memset(cam, 0, sizeof *cam);
    float down[3], right[3], back[3], C[3];
    for (int r = 0; r < 3; r++) {
        down[r] = P[r * 5 + 0];
        right[r] = P[r * 5 + 1];
        back[r] = P[r * 5 + 2];
        C[r] = P[r * 5 + 3];
    }
    for (int k = 0; k < 3; k++) {
        cam->R[0 * 3 + k] = right[k];
        cam->R[1 * 3 + k] = down[k];
        cam->R[2 * 3 + k] = -back[k];
    }
    for (int r = 0; r < 3; r++) cam->t[r] = -(cam->R[r * 3] * C[0] + cam->R[r * 3 + 1] * C[1] + cam->R[r * 3 + 2] * C[2]);
    cam->height = (int)lroundf(P[4]);
    cam->width = (int)lroundf(P[9]);
    cam->fx = cam->fy = P[14];
    cam->cx = 0.5f * cam->width;
    cam->cy = 0.5f * cam->height;
}

static int is_video_name(const char *name)
{
    static const char *ext[] = { ".mp4", ".mov", ".avi", ".mkv", ".webm", ".m4v", ".mpg", ".mpeg" };
    const char *dot = strrchr(name, '.');
    if (!dot) return 0;
    for (size_t i = 0; i < sizeof ext / sizeof ext[0]; i++)
        if (!strcasecmp(dot, ext[i])) return 1;
    return 0;
}

/* camXX entries: a video file or a folder (camXX/images/ if present, else camXX/), in natural
 * order of the entry names. When both a video and a folder exist for one camera name, the folder
 * (already-decoded frames) wins. */
static pg_status list_camera_sources(pg_dataset *ds, char ***out, int *count)
{
    DIR *d = opendir(ds->path);
    if (!d) return pg_fail(PG_ERR_IO, "%s: cannot open folder", ds->path);
    char **list = NULL;
    int n = 0, cap = 0;
    pg_status st = PG_OK;
    struct dirent *e;
    while ((e = readdir(d)) != NULL && st == PG_OK) {
        const char *nm = e->d_name;
        if (strncasecmp(nm, "cam", 3) || !isdigit((unsigned char)nm[3 + (nm[3] == '_')])) continue;
        char full[4200];
        if (pg_path_join(full, sizeof full, ds->path, nm)) continue;
        if (!pg_path_is_dir(full) && !is_video_name(nm)) continue;
        if (n == cap) {
            cap = cap ? 2 * cap : 32;
            char **nl = realloc(list, sizeof *list * (size_t)cap);
            if (!nl) { st = pg_fail(PG_ERR_NOMEM, "%s: out of memory", ds->path); break; }
            list = nl;
        }
        list[n] = strdup(nm);
        if (!list[n]) { st = pg_fail(PG_ERR_NOMEM, "%s: out of memory", ds->path); break; }
        n++;
    }
    closedir(d);
    if (st) { io_free_names(list, n); return st; }
    io_sort_names(list, n);
    char **res = pg_calloc((size_t)(n ? n : 1), sizeof *res, "camera list");
    if (!res) { io_free_names(list, n); return PG_ERR_NOMEM; }
    int m = 0;
    for (int i = 0; i < n && st == PG_OK; i++) {
        char full[4200], img[4300];
        pg_path_join(full, sizeof full, ds->path, list[i]);
        int dir = pg_path_is_dir(full), dup = 0;
        if (!dir) /* a video: skip when a folder with its stem exists */
            for (int j = 0; j < n; j++) {
                size_t l = strlen(list[j]);
                char other[4200];
                pg_path_join(other, sizeof other, ds->path, list[j]);
                if (j != i && !strncmp(list[i], list[j], l) && list[i][l] == '.' && pg_path_is_dir(other)) dup = 1;
            }
        if (dir) {
            snprintf(img, sizeof img, "%s/images", full);
            if (pg_path_is_dir(img) && strlen(img) < sizeof full) memcpy(full, img, strlen(img) + 1);
        }
        if (dup) continue;
        res[m] = strdup(full);
        if (!res[m]) st = pg_fail(PG_ERR_NOMEM, "%s: out of memory", ds->path);
        else m++;
    }
    io_free_names(list, n);
    list = res;
    if (st) { io_free_names(list, m); return st; }
    *out = list;
    *count = m;
    return PG_OK;
}

/* Camera name from its source path: "camXX" from ".../camXX.mp4" or ".../camXX/images". */
static void camera_name(const char *src, char *name, size_t size)
{
    char tmp[4200];
    snprintf(tmp, sizeof tmp, "%s", src);
    size_t l = strlen(tmp);
    if (l > 7 && !strcmp(tmp + l - 7, "/images")) tmp[l - 7] = '\0';
    const char *b = strrchr(tmp, '/');
    b = b ? b + 1 : tmp;
    snprintf(name, size, "%.*s", (int)(size - 1), b);
    char *dot = strrchr(name, '.');
    if (dot && dot != name) *dot = '\0';
}

pg_status ds_open_dynerf(pg_dataset *ds)
{
    char pb[4200];
    PG_TRY(pg_path_join(pb, sizeof pb, ds->path, "poses_bounds.npy"));
    pg_array arr;
    PG_TRY(io_npy_load(pb, &arr));
    int N = 0;
    if (arr.ndim == 2 && arr.shape[1] == 17 && arr.shape[0] >= 1 && arr.shape[0] <= 10000) N = (int)arr.shape[0];
    else if (arr.ndim == 1 && arr.shape[0] == 17) N = 1;
    if (N == 0) {
        pg_status st = pg_fail(PG_ERR_FORMAT, "%s: expected shape (N, 17) (3x5 pose + near, far per camera), got %d-D with %zu values",
                               pb, arr.ndim, arr.count);
        pg_array_destroy(&arr);
        return st;
    }
    pg_status st = PG_OK;
    char **srcs = NULL;
    int nsrc = 0;
    st = list_camera_sources(ds, &srcs, &nsrc);
    if (st == PG_OK && nsrc != N)
        st = pg_fail(PG_ERR_FORMAT, "%s: %d cameras in poses_bounds.npy but %d camXX videos/folders next to it", pb, N, nsrc);
    if (st == PG_OK) st = ds_alloc_cameras(ds, N);
    int available = 0, src_w = 0, src_h = 0;
    for (int i = 0; st == PG_OK && i < N; i++) {
        const float *row = arr.data + (size_t)i * 17;
        for (int k = 0; k < 17; k++)
            if (!isfinite(row[k])) { st = pg_fail(PG_ERR_FORMAT, "%s: row %d has a non-finite value", pb, i); break; }
        if (st) break;
        if (!(row[4] >= 1 && row[9] >= 1 && row[14] > 0 && row[4] <= PG_MAX_IMAGE_SIDE && row[9] <= PG_MAX_IMAGE_SIDE)) {
            st = pg_fail(PG_ERR_FORMAT, "%s: row %d has bad hwf (%g, %g, %g)", pb, i, row[4], row[9], row[14]);
            break;
        }
        ds_camera *c = &ds->cams[i];
        c->cams = pg_calloc(1, sizeof *c->cams, "camera");
        if (!c->cams) { st = PG_ERR_NOMEM; break; }
        c->num_cams = 1;
        io_llff_to_camera(row, c->cams);
        if (!mat3_is_orthonormal(c->cams->R, 1e-2)) {
            st = pg_fail(PG_ERR_FORMAT, "%s: row %d rotation is not orthonormal", pb, i);
            break;
        }
        c->near_z = row[15];
        c->far_z = row[16];
        snprintf(c->source, sizeof c->source, "%s", srcs[i]);
        camera_name(srcs[i], c->name, sizeof c->name);
        io_video_info info;
        st = io_video_probe(c->source, &info);
        if (st) break;
        int frames = info.frames;
        if (!info.frames_exact) {
            st = io_video_count_frames(c->source, &frames);
            if (st) break;
        }
        if (i == 0) {
            src_w = info.width;
            src_h = info.height;
            available = frames;
            ds->fps = info.is_folder ? ds->opt.fps : info.fps;
        } else {
            if (info.width != src_w || info.height != src_h) {
                st = pg_fail(PG_ERR_SIZE, "%s: frames are %d x %d but %s has %d x %d", c->source, info.width,
                             info.height, ds->cams[0].source, src_w, src_h);
                break;
            }
            if (frames < available) available = frames;
        }
        /* Intrinsics from the hwf size to the real frame size; the aspect must agree. */
        double ar = (double)c->cams->width / c->cams->height, ar2 = (double)info.width / info.height;
        if (fabs(ar / ar2 - 1) > 0.02) {
            st = pg_fail(PG_ERR_SIZE, "%s: frames are %d x %d but poses_bounds row %d says %d x %d", c->source,
                         info.width, info.height, i, c->cams->width, c->cams->height);
            break;
        }
        pg_camera_resize(c->cams, info.width, info.height);
    }
    io_free_names(srcs, nsrc);
    pg_array_destroy(&arr);
    if (st) return st;
    PG_TRY(ds_select_frames(ds, ds->path, available));
    ds_set_sizes(ds, src_w, src_h);
    return PG_OK;
}
