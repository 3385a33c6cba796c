/* colmap_align.c - the depth's scale and disparity shift from COLMAP's points at known poses. */
#define _POSIX_C_SOURCE 200809L
#include "proxy/colmap_align.h"

#include <fcntl.h>
#include <signal.h>
#include <time.h>
#include <math.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "core/fileutil.h"
#include "core/image.h"
#include "core/mathx.h"
#include "io/image_io.h"

extern char **environ;

enum { MIN_POINTS = 12 };

int proxy_colmap_available(void)
{
    const char *off = getenv("PG_COLMAP");
    if (off && strcmp(off, "0") == 0) return 0;
    const char *path = getenv("PATH");
    if (!path) return 0;
    char dir[4096];
    while (*path) {
        size_t len = strcspn(path, ":");
        if (len > 0 && len < sizeof dir - 8) {
            memcpy(dir, path, len);
            snprintf(dir + len, sizeof dir - len, "/colmap");
            if (access(dir, X_OK) == 0) return 1;
        }
        path += len + (path[len] == ':');
    }
    return 0;
}

/* Runs `colmap ARGS...` once with its output appended to workdir/colmap.log, killed after
 * limit_s seconds; fails naming the step (*timed_out set when it was killed). */
static pg_status run_colmap_once(const char *workdir, const char *const *args, double limit_s, int *timed_out)
{
    char log[4200];
    PG_TRY(pg_path_join(log, sizeof log, workdir, "colmap.log"));
    const char *argv[24] = { "colmap" };
    int argc = 1;
    for (; args[argc - 1] && argc < 23; argc++) argv[argc] = args[argc - 1];
    argv[argc] = NULL;
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_addopen(&fa, 1, log, O_WRONLY | O_CREAT | O_APPEND, 0644);
    posix_spawn_file_actions_adddup2(&fa, 1, 2);
    pid_t pid;
    int rc = posix_spawnp(&pid, "colmap", &fa, NULL, (char *const *)argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    if (rc != 0) return pg_fail(PG_ERR_IO, "colmap %s: could not start colmap", args[0]);
    int status = 0;
    *timed_out = 0;
    for (double waited = 0;; waited += 0.05) {
        pid_t got = waitpid(pid, &status, WNOHANG);
        if (got == pid) break;
        if (got < 0) return pg_fail(PG_ERR_IO, "colmap %s: lost the process", args[0]);
        if (waited > limit_s) {
            kill(pid, SIGKILL);
            waitpid(pid, &status, 0);
            *timed_out = 1;
            return pg_fail(PG_ERR_IO, "colmap %s did not finish in %.0f s; its output is in %s", args[0], limit_s, log);
        }
        nanosleep(&(struct timespec){ 0, 50000000 }, NULL);
    }
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
        return pg_fail(PG_ERR_IO, "colmap %s failed (exit %d); its output is in %s", args[0],
                       WIFEXITED(status) ? WEXITSTATUS(status) : -1, log);
    return PG_OK;
}

/* run_colmap_once, and once more when it timed out: COLMAP 3.8's feature extractor now and then
 * hangs in a futex after writing its features (seen once in ~60 runs, Panoptic at 640x360); a
 * rerun skips the images already in the database. */
static pg_status run_colmap(const char *workdir, const char *const *args, double limit_s)
{
    int timed_out = 0;
    pg_status st = run_colmap_once(workdir, args, limit_s, &timed_out);
    if (st && timed_out) st = run_colmap_once(workdir, args, limit_s, &timed_out);
    return st;
}

/* COLMAP's quaternion (w, x, y, z) of a world-to-camera rotation (row-major R). */
static void rotation_quaternion(const float R[9], double q[4])
{
    double t = R[0] + R[4] + R[8];
    if (t > 0) {
        double s = 2 * sqrt(1 + t);
        q[0] = s / 4, q[1] = (R[7] - R[5]) / s, q[2] = (R[2] - R[6]) / s, q[3] = (R[3] - R[1]) / s;
    } else if (R[0] > R[4] && R[0] > R[8]) {
        double s = 2 * sqrt(1 + R[0] - R[4] - R[8]);
        q[0] = (R[7] - R[5]) / s, q[1] = s / 4, q[2] = (R[1] + R[3]) / s, q[3] = (R[2] + R[6]) / s;
    } else if (R[4] > R[8]) {
        double s = 2 * sqrt(1 + R[4] - R[0] - R[8]);
        q[0] = (R[2] - R[6]) / s, q[1] = (R[1] + R[3]) / s, q[2] = s / 4, q[3] = (R[5] + R[7]) / s;
    } else {
        double s = 2 * sqrt(1 + R[8] - R[0] - R[4]);
        q[0] = (R[3] - R[1]) / s, q[1] = (R[2] + R[6]) / s, q[2] = (R[5] + R[7]) / s, q[3] = s / 4;
    }
}

/* One image per camera (v000.png = the real one), each extracted with its own intrinsics (COLMAP
 * numbers images and cameras 1, 2, ... in that order), matched all against all; then the known
 * poses as a sparse model with no points, triangulated, written as text. */
static pg_status run_reconstruction(const char *workdir, int n, const pg_camera *cams, const float *const *rgb,
                                    int threads)
{
    char images[4200], db[4200], list[4200], in[4200], out[4200], path[4300], params[160], thr[16];
    PG_TRY(pg_path_join(images, sizeof images, workdir, "images"));
    PG_TRY(pg_path_join(db, sizeof db, workdir, "database.db"));
    PG_TRY(pg_path_join(list, sizeof list, workdir, "list.txt"));
    PG_TRY(pg_path_join(in, sizeof in, workdir, "known"));
    PG_TRY(pg_path_join(out, sizeof out, workdir, "triangulated"));
    PG_TRY(pg_mkdir_p(images));
    PG_TRY(pg_mkdir_p(in));
    PG_TRY(pg_mkdir_p(out));
    snprintf(thr, sizeof thr, "%d", threads > 0 ? threads : 1);
    FILE *fc = NULL, *fi = NULL;
    pg_status st = PG_OK;
    for (int k = 0; k < n && !st; k++) {
        const pg_camera *c = &cams[k];
        char name[32];
        snprintf(name, sizeof name, "v%03d.png", k);
        pg_image img = { c->width, c->height, 3, (float *)rgb[k] };
        st = pg_path_join(path, sizeof path, images, name);
        if (!st) st = io_image_save_png(path, &img);
        if (!st) st = pg_write_file_atomic(list, name, strlen(name));
        snprintf(params, sizeof params, "%.9g,%.9g,%.9g,%.9g", c->fx, c->fy, c->cx, c->cy);
        const char *args[] = { "feature_extractor", "--database_path", db, "--image_path", images,
                               "--image_list_path", list, "--ImageReader.camera_model", "PINHOLE",
                               "--ImageReader.camera_params", params, "--SiftExtraction.use_gpu", "0",
                               "--SiftExtraction.num_threads", thr, NULL };
        if (!st) st = run_colmap(workdir, args, 120);
    }
    if (!st) {
        const char *args[] = { "exhaustive_matcher", "--database_path", db, "--SiftMatching.use_gpu", "0",
                               "--SiftMatching.num_threads", thr, NULL };
        st = run_colmap(workdir, args, 900);
    }
    if (!st) st = pg_path_join(path, sizeof path, in, "cameras.txt");
    if (!st && !(fc = fopen(path, "w"))) st = pg_fail(PG_ERR_IO, "%s: cannot write", path);
    if (!st) st = pg_path_join(path, sizeof path, in, "images.txt");
    if (!st && !(fi = fopen(path, "w"))) st = pg_fail(PG_ERR_IO, "%s: cannot write", path);
    for (int k = 0; k < n && !st; k++) {
        const pg_camera *c = &cams[k];
        double q[4];
        rotation_quaternion(c->R, q);
        fprintf(fc, "%d PINHOLE %d %d %.9g %.9g %.9g %.9g\n", k + 1, c->width, c->height, c->fx, c->fy, c->cx, c->cy);
        fprintf(fi, "%d %.12g %.12g %.12g %.12g %.9g %.9g %.9g %d v%03d.png\n\n", k + 1, q[0], q[1], q[2], q[3],
                c->t[0], c->t[1], c->t[2], k + 1, k);
    }
    if (fc && fclose(fc) != 0 && !st) st = pg_fail(PG_ERR_IO, "%s: write failed", in);
    if (fi && fclose(fi) != 0 && !st) st = pg_fail(PG_ERR_IO, "%s: write failed", in);
    if (!st) st = pg_path_join(path, sizeof path, in, "points3D.txt");
    if (!st) st = pg_write_file_atomic(path, "", 0);
    if (!st) {
        const char *args[] = { "point_triangulator", "--database_path", db, "--image_path", images,
                               "--input_path", in, "--output_path", out, NULL };
        st = run_colmap(workdir, args, 900);
    }
    if (!st) {
        const char *args[] = { "model_converter", "--input_path", out, "--output_path", out, "--output_type", "TXT", NULL };
        st = run_colmap(workdir, args, 120);
    }
    return st;
}

typedef struct {
    long id;
    double X[3], error;
    int track;
} colmap_point;

static int cmp_point(const void *a, const void *b)
{
    long x = ((const colmap_point *)a)->id, y = ((const colmap_point *)b)->id;
    return (x > y) - (x < y);
}

/* points3D.txt -> points sorted by id (malloc'd). Lines: ID X Y Z R G B ERROR (IMAGE_ID IDX)... */
static pg_status read_points(const char *path, colmap_point **out, int *count)
{
    char *text = NULL;
    size_t len = 0;
    PG_TRY(pg_read_file(path, (size_t)1 << 30, &text, &len));
    int cap = 1024, n = 0;
    colmap_point *p = pg_malloc((size_t)cap * sizeof *p, "COLMAP points");
    pg_status st = p ? PG_OK : PG_ERR_NOMEM;
    for (char *line = text; line && *line && !st;) {
        char *next = strchr(line, '\n');
        if (next) *next++ = 0;
        colmap_point q;
        int r, g, b, used = 0;
        if (line[0] != '#' && sscanf(line, "%ld %lf %lf %lf %d %d %d %lf%n", &q.id, &q.X[0], &q.X[1], &q.X[2], &r, &g,
                                     &b, &q.error, &used) == 8) {
            q.track = 0;
            for (char *s = line + used; *s;) {
                long img, idx;
                int k = 0;
                if (sscanf(s, "%ld %ld%n", &img, &idx, &k) != 2) break;
                q.track++;
                s += k;
            }
            if (n == cap) {
                colmap_point *grown = realloc(p, (size_t)(cap *= 2) * sizeof *p);
                if (!grown) { st = pg_fail(PG_ERR_NOMEM, "out of memory reading %s", path); break; }
                p = grown;
            }
            p[n++] = q;
        }
        line = next;
    }
    free(text);
    if (st) {
        free(p);
        return st;
    }
    qsort(p, (size_t)n, sizeof *p, cmp_point);
    *out = p;
    *count = n;
    return PG_OK;
}

/* The real camera's observations in images.txt (image line "v000.png", then its "X Y POINT3D_ID"
 * triples) paired with the depth map at their pixels: d[i] from depth0, z[i] the point's depth. */
static pg_status read_pairs(const char *path, const colmap_point *pts, int npts, const pg_camera *real,
                            const float *depth0, int dw, int dh, double **d_out, double **z_out, int *count)
{
    char *text = NULL;
    size_t len = 0;
    PG_TRY(pg_read_file(path, (size_t)1 << 30, &text, &len));
    char *obs = NULL;
    int after_real = 0;
    for (char *line = text; line && *line;) {
        char *next = strchr(line, '\n');
        if (next) *next++ = 0;
        if (line[0] != '#') {
            if (after_real) {
                obs = line;
                break;
            }
            size_t l = strlen(line);
            after_real = l >= 8 && strcmp(line + l - 8, "v000.png") == 0;
        }
        line = next;
    }
    int cap = 0, n = 0;
    for (char *s = obs; s && *s; s++) cap += *s == ' ';
    double *d = pg_malloc(((size_t)cap / 3 + 1) * sizeof *d, "COLMAP pairs");
    double *z = pg_malloc(((size_t)cap / 3 + 1) * sizeof *z, "COLMAP pairs");
    if (!d || !z) {
        free(text), free(d), free(z);
        return PG_ERR_NOMEM;
    }
    for (char *s = obs; s && *s && n <= cap / 3;) {
        double x, y;
        long id;
        int k = 0;
        if (sscanf(s, "%lf %lf %ld%n", &x, &y, &id, &k) != 3) break;
        s += k;
        if (id < 0) continue;
        colmap_point key = { .id = id };
        const colmap_point *p = bsearch(&key, pts, (size_t)npts, sizeof *pts, cmp_point);
        /* seen from three cameras or more and reprojected within 2 px: a point, not a lucky pair */
        if (!p || p->track < 3 || p->error > 2.0) continue;
        int u = (int)floor(x * dw / real->width), v = (int)floor(y * dh / real->height);
        if (u < 0 || v < 0 || u >= dw || v >= dh) continue;
        float Xw[3] = { (float)p->X[0], (float)p->X[1], (float)p->X[2] }, Xc[3];
        pg_camera_world_to_cam(real, Xw, Xc);
        float dv = depth0[(size_t)v * dw + u];
        if (!(Xc[2] > 0) || !(dv > 0) || !isfinite(dv)) continue;
        d[n] = dv, z[n] = Xc[2];
        n++;
    }
    free(text);
    *d_out = d, *z_out = z, *count = n;
    return PG_OK;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Median of v (n values, reordered). */
static double median_of(double *v, int n)
{
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

pg_status proxy_fit_scale_shift(const double *d, const double *z, int n, proxy_colmap_report *rep)
{
    if (n < MIN_POINTS) return pg_fail(PG_ERR_FORMAT, "depth alignment: %d usable points (at least %d needed)", n, MIN_POINTS);
    double *w = pg_malloc((size_t)n * 2 * sizeof *w, "alignment weights"), *r = w + n;
    if (!w) return PG_ERR_NOMEM;
    for (int i = 0; i < n; i++) w[i] = 1;
    double a = 1, b = 0;
    /* The residual is absolute in inverse depth: a triangulated point's depth error grows as z^2
     * (fixed pixel error and baseline), so its inverse depth is equally good near and far. Huber
     * weights at 2.5 robust sigmas (1.4826 x the median residual): least squares on the points that
     * agree, mismatches let go. On tabletop_dev (FastDepth, 511 points) this gave the frame's depth
     * 15.2 % mean error against the ground truth; L1 17.2 %, relative residuals 15.4-18.2 %. */
    for (int it = 0; it < 30; it++) {
        double s00 = 0, s01 = 0, s11 = 0, t0 = 0, t1 = 0;
        for (int i = 0; i < n; i++) {
            double x = 1 / d[i], y = 1 / z[i], wi = w[i];
            s00 += wi * x * x, s01 += wi * x, s11 += wi, t0 += wi * x * y, t1 += wi * y;
        }
        double det = s00 * s11 - s01 * s01;
        if (!(fabs(det) > 1e-300)) break;
        a = (t0 * s11 - t1 * s01) / det;
        b = (s00 * t1 - s01 * t0) / det;
        for (int i = 0; i < n; i++) r[i] = fabs(a / d[i] + b - 1 / z[i]);
        memcpy(w, r, (size_t)n * sizeof *w);
        double k = 2.5 * 1.4826 * median_of(w, n);
        for (int i = 0; i < n; i++) w[i] = r[i] <= k ? 1 : k / r[i];
    }
    if (!(a > 0) || !isfinite(b)) {
        free(w);
        return pg_fail(PG_ERR_FORMAT, "depth alignment: the points give no positive scale (a = %g)", a);
    }
    rep->scale = (float)(1 / a);
    rep->shift = (float)(b / a);
    rep->points = n;
    for (int i = 0; i < n; i++) r[i] = fabs(rep->scale * d[i] / (1 + rep->shift * d[i]) / z[i] - 1);
    rep->abs_rel = median_of(r, n);
    for (int i = 0; i < n; i++) r[i] = z[i] / d[i];
    double s0 = median_of(r, n);
    for (int i = 0; i < n; i++) r[i] = fabs(s0 * d[i] / z[i] - 1);
    rep->abs_rel_scale_only = median_of(r, n);
    free(w);
    return PG_OK;
}

pg_status proxy_colmap_align(const char *workdir, const pg_camera *real, const float *real_rgb, const float *depth0,
                             int dw, int dh, int n, const pg_camera *cams, const float *const *rgb, int threads,
                             proxy_colmap_report *rep)
{
    if (n < 2) return pg_fail(PG_ERR_ARG, "depth alignment: COLMAP needs at least two other cameras (got %d)", n);
    pg_camera *all = pg_malloc((size_t)(n + 1) * sizeof *all, "COLMAP cameras");
    const float **imgs = pg_malloc((size_t)(n + 1) * sizeof *imgs, "COLMAP images");
    pg_status st = all && imgs ? PG_OK : PG_ERR_NOMEM;
    if (!st) {
        all[0] = *real, imgs[0] = real_rgb;
        for (int k = 0; k < n; k++) all[k + 1] = cams[k], imgs[k + 1] = rgb[k];
        st = pg_mkdir_p(workdir);
    }
    if (!st) st = run_reconstruction(workdir, n + 1, all, imgs, threads);
    free(all);
    free(imgs);
    char path[4300];
    colmap_point *pts = NULL;
    int npts = 0, npairs = 0;
    double *d = NULL, *z = NULL;
    if (!st) st = pg_path_join(path, sizeof path, workdir, "triangulated/points3D.txt");
    if (!st) st = read_points(path, &pts, &npts);
    if (!st) st = pg_path_join(path, sizeof path, workdir, "triangulated/images.txt");
    if (!st) st = read_pairs(path, pts, npts, real, depth0, dw, dh, &d, &z, &npairs);
    if (!st) st = proxy_fit_scale_shift(d, z, npairs, rep);
    if (st == PG_ERR_FORMAT) st = pg_fail_context(PG_ERR_FORMAT, "COLMAP triangulated %d points", npts);
    free(pts);
    free(d);
    free(z);
    return st;
}
