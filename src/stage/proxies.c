/* proxies.c - the proxies stage: every frame of the real view forward-warped (depth mesh, or the
 * paper's per-frame Gaussians) into virtual cameras, written as a training-set directory (paper
 * 3.2, docs/proxy.md, docs/FORMATS.md). */
#include "stage/stage_internal.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/fileutil.h"
#include "core/output.h"
#include "core/mathx.h"
#include "core/parallel.h"
#include "core/status.h"
#include "io/dataset.h"
#include "io/depth_io.h"
#include "proxy/colmap_align.h"
#include "proxy/poses.h"
#include "proxy/proxy.h"
#include "stage/proxies_diagnose.h"

#define MAX_CAMS 256

typedef struct {
    pg_dataset *ds;
    int cams[1 + MAX_CAMS]; /* dataset index of the real camera, then of each test camera */
} frame_source;

static pg_status source_frame(void *ctx, int camera, int frame, pg_image *out)
{
    frame_source *s = ctx;
    return io_dataset_frame(s->ds, s->cams[camera], frame, out);
}

static float median_valid(const float *d, size_t n)
{
    float *t = malloc(n * sizeof(float));
    if (!t) return 0;
    size_t k = 0;
    for (size_t i = 0; i < n; i++)
        if (d[i] > 0) t[k++] = d[i];
    qsort(t, k, sizeof(float), pg_cmp_float);
    float m = k ? t[k / 2] : 0;
    free(t);
    return m;
}

/* The dataset's cameras other than the real and the test ones, in index order: their poses,
 * names and indices. */
static void other_cameras(pg_dataset *ds, int ncam, int train_cam, const int *tests, int ntest, pg_camera *cams,
                          const char **names, int *idx)
{
    int m = 0;
    for (int c = 0; c < ncam; c++) {
        int is_test = 0;
        for (int k = 0; k < ntest; k++) is_test |= tests[k] == c;
        if (c == train_cam || is_test) continue;
        io_dataset_camera(ds, c, &cams[m]);
        names[m] = io_dataset_camera_name(ds, c);
        idx[m++] = c;
    }
}

/* How frame 0's depth was brought to pose units (evaluation only). */
typedef struct {
    float scale, shift;
    char method[160]; /* for trainset.json and the report */
    double cost;      /* photometric: the warp's cost at the scale */
} pose_fit;

/* Frame 0 of the real camera and of the n cameras idx[] at the dataset's current frame size. */
static pg_status load_first_frames(pg_dataset *ds, int real_idx, int n, const int *idx, pg_image *real_img,
                                   pg_image *imgs, const float **ptrs)
{
    pg_status st = io_dataset_frame(ds, real_idx, 0, real_img);
    for (int k = 0; k < n && !st; k++) {
        st = io_dataset_frame(ds, idx[k], 0, &imgs[k]);
        ptrs[k] = imgs[k].data;
    }
    return st;
}

/* Frees what load_first_frames made and drops the other cameras' decoded frames (the real
 * camera's stay: the proxies render from them next). */
static void free_first_frames(pg_dataset *ds, int n, const int *idx, pg_image *real_img, pg_image *imgs)
{
    pg_image_destroy(real_img);
    for (int k = 0; k < n && imgs; k++) pg_image_destroy(&imgs[k]);
    for (int k = 0; k < n; k++) io_dataset_release(ds, idx[k]);
}

/* COLMAP's scale and shift, on frame 0 at the source resolution (long side at most 1280): SIFT
 * finds few features at the working size (Panoptic at 320x180: 13 usable points, at 640x360 36).
 * The dataset goes back to the working size after. *done = 1 when the fit holds. */
static pg_status colmap_fit(pg_dataset *ds, int real_idx, const pg_camera *real, const float *depth0, int n,
                            const int *idx, const pg_camera *cams, const char *workdir, int threads, pose_fit *fit,
                            int *done)
{
    int W = real->width, H = real->height, Ws = io_dataset_source_width(ds), Hs = io_dataset_source_height(ds);
    double shrink = fmax(Ws, Hs) > 1280 ? 1280.0 / fmax(Ws, Hs) : 1.0;
    int Wc = (int)lround(Ws * shrink), Hc = (int)lround(Hs * shrink);
    pg_image real_img = { 0 };
    pg_image *imgs = calloc((size_t)n, sizeof(pg_image));
    const float **ptrs = calloc((size_t)n, sizeof(float *));
    pg_camera rc = *real, *cc = calloc((size_t)n, sizeof(pg_camera));
    pg_status st = (!imgs || !ptrs || !cc) ? pg_fail(PG_ERR_NOMEM, "pose alignment: out of memory") : PG_OK;
    if (!st) {
        io_dataset_set_frame_size(ds, Wc, Hc);
        pg_camera_resize(&rc, Wc, Hc);
        for (int k = 0; k < n; k++) cc[k] = cams[k], pg_camera_resize(&cc[k], Wc, Hc);
        st = load_first_frames(ds, real_idx, n, idx, &real_img, imgs, ptrs);
    }
    proxy_colmap_report cr;
    pg_status cs = st ? st : proxy_colmap_align(workdir, &rc, real_img.data, depth0, W, H, n, cc, ptrs, threads, &cr);
    pg_remove_tree(workdir);
    free_first_frames(ds, n, idx, &real_img, imgs);
    io_dataset_set_frame_size(ds, W, H); /* drops the real camera's frames at the COLMAP size too */
    free(imgs);
    free(ptrs);
    free(cc);
    if (cs == PG_OK) {
        fit->scale = cr.scale, fit->shift = cr.shift, fit->cost = NAN;
        snprintf(fit->method, sizeof fit->method,
                 "COLMAP scale and shift at %dx%d (%d points, median error %.1f %%; scale alone %.1f %%)", Wc, Hc,
                 cr.points, 100 * cr.abs_rel, 100 * cr.abs_rel_scale_only);
        *done = 1;
        return PG_OK;
    }
    if (cs == PG_ERR_NOMEM) return cs;
    fprintf(stderr, "prodygs: pose alignment: %s; fitting a scale alone photometrically\n", pg_last_error());
    snprintf(fit->method, sizeof fit->method, "photometric scale (COLMAP failed: no shift)");
    return PG_OK;
}

/* Fits the depth-to-pose map on frame 0 against the proxy (training) cameras: with `shift` and
 * COLMAP installed, scale and disparity shift to COLMAP's points at the known poses (workdir holds
 * its files while it runs); otherwise, or when COLMAP finds too few points, a scale alone by the
 * photometric warp fit. */
static pg_status fit_scale(pg_dataset *ds, int real_idx, const pg_camera *real, const float *depth0, int n,
                           const int *idx, const pg_camera *cams, int shift, const char *workdir, int threads,
                           pose_fit *fit)
{
    int W = real->width, H = real->height, done = 0;
    pg_status st = PG_OK;
    fit->shift = 0;
    snprintf(fit->method, sizeof fit->method, "%s",
             !shift ? "photometric scale" : "photometric scale (COLMAP not installed: no shift)");
    if (shift && proxy_colmap_available())
        PG_TRY(colmap_fit(ds, real_idx, real, depth0, n, idx, cams, workdir, threads, fit, &done));
    if (done) return PG_OK;
    pg_image real_img = { 0 };
    pg_image *imgs = calloc((size_t)n, sizeof(pg_image));
    const float **ptrs = calloc((size_t)n, sizeof(float *));
    st = (!imgs || !ptrs) ? pg_fail(PG_ERR_NOMEM, "pose scale fit: out of memory") : PG_OK;
    if (!st) st = load_first_frames(ds, real_idx, n, idx, &real_img, imgs, ptrs);
    if (!st) {
        proxy_scale_options so = proxy_default_scale_options();
        float near_z = 0, far_z = 0, med = median_valid(depth0, (size_t)W * H);
        io_dataset_near_far(ds, real_idx, &near_z, &far_z);
        if (near_z > 0 && far_z > near_z && med > 0) {
            /* The bounds say roughly where the scene is in pose units. */
            float s0 = sqrtf(near_z * far_z) / med;
            so.scale_min = s0 / 4;
            so.scale_max = s0 * 4;
        } else {
            so.scale_min = 1.0f / 16;
            so.scale_max = 16;
        }
        proxy_scale_report rep;
        st = proxy_fit_pose_scale(real, real_img.data, depth0, n, cams, ptrs, &so, &rep);
        fit->scale = rep.scale, fit->cost = rep.cost;
    }
    free_first_frames(ds, n, idx, &real_img, imgs);
    free(imgs);
    free(ptrs);
    return st;
}

void pg_proxies_defaults(pg_proxies_config *c)
{
    memset(c, 0, sizeof *c);
    c->proxies = -1;
    c->max_angle = 20;
    c->fov = 60;
    c->pad = -1;
    c->fit_steps = 50;
    c->fit_block = 1;
    c->pose_shift = 1;
}

cJSON *stage_proxies_config_json(const pg_proxies_config *c)
{
    cJSON *j = cJSON_CreateObject();
    cJSON_AddStringToObject(j, "train_camera", c->train_camera ? c->train_camera : "");
    cJSON_AddStringToObject(j, "test_cameras", c->test_cameras ? c->test_cameras : "");
    cJSON_AddStringToObject(j, "poses", c->poses ? c->poses : "");
    cJSON_AddNumberToObject(j, "proxies", c->proxies);
    cJSON_AddNumberToObject(j, "max_angle", c->max_angle);
    cJSON_AddNumberToObject(j, "fov", c->fov);
    cJSON_AddNumberToObject(j, "pad", c->pad);
    cJSON_AddNumberToObject(j, "pose_scale", c->pose_scale);
    cJSON_AddBoolToObject(j, "pose_shift", c->pose_shift);
    cJSON_AddNumberToObject(j, "depth_unit", c->depth_unit);
    cJSON_AddStringToObject(j, "render", c->render ? c->render : "mesh");
    cJSON_AddNumberToObject(j, "fit_steps", c->fit_steps);
    cJSON_AddNumberToObject(j, "fit_block", c->fit_block);
    cJSON_AddNumberToObject(j, "frames", c->frames);
    cJSON_AddNumberToObject(j, "width", c->width);
    cJSON_AddNumberToObject(j, "height", c->height);
    return j;
}

/* Rejects bad values before the dataset is opened; *dataset_poses: 1 dataset poses asked
 * for, 0 the hemisphere, -1 the default (dataset poses for a multi-camera input). */
static pg_status check_config(const pg_proxies_config *c, int *dataset_poses)
{
    if (!c->input || !c->depth || !c->out) return pg_fail(PG_ERR_ARG, "proxies: input, depth and out are required");
    if (c->proxies < -1 || c->proxies > MAX_CAMS)
        return pg_fail(PG_ERR_ARG, "proxies: --proxies %d not in 0..%d", c->proxies, MAX_CAMS);
    if (!(c->max_angle > 0 && c->max_angle < 90))
        return pg_fail(PG_ERR_ARG, "proxies: --max-angle %g not in (0, 90) degrees", c->max_angle);
    if (!(c->fov > 0 && c->fov < 179)) return pg_fail(PG_ERR_ARG, "proxies: --fov %g not in (0, 179) degrees", c->fov); /* the dataset's limit */
    if (c->render && strcmp(c->render, "mesh") != 0 && strcmp(c->render, "splat") != 0)
        return pg_fail(PG_ERR_ARG, "proxies: --render must be mesh or splat, not '%s'", c->render);
    if (c->fit_steps < 0 || c->fit_steps > 100000)
        return pg_fail(PG_ERR_ARG, "proxies: --fit-steps %d out of range 0..100000", c->fit_steps);
    if (c->fit_block < 1 || c->fit_block > 64) return pg_fail(PG_ERR_ARG, "proxies: --fit-block %d not in 1..64", c->fit_block);
    if (c->pad > 1 || (c->pad < 0 && c->pad != -1)) return pg_fail(PG_ERR_ARG, "proxies: --pad %g not in [0, 1]", c->pad);
    if (c->frames < 0) return pg_fail(PG_ERR_ARG, "proxies: --frames %d is negative", c->frames);
    if (c->pose_scale < 0 || !isfinite(c->pose_scale)) return pg_fail(PG_ERR_ARG, "proxies: --pose-scale must be positive");
    if (c->depth_unit < 0 || !isfinite(c->depth_unit)) return pg_fail(PG_ERR_ARG, "proxies: depth unit must be positive");
    PG_TRY(stage_check_size("proxies", "--size", c->width, c->height, 0));
    PG_TRY(stage_check_threads("proxies", c->threads));
    *dataset_poses = -1;
    if (c->poses) {
        if (!strcmp(c->poses, "hemisphere")) *dataset_poses = 0;
        else if (!strcmp(c->poses, "dataset")) *dataset_poses = 1;
        else return pg_fail(PG_ERR_ARG, "proxies: --poses '%s' is not hemisphere or dataset", c->poses);
    }
    return PG_OK;
}

/* Proxies are computed in OUT.partial, which a crashed run leaves for the next one to resume (the
 * finished frames are reused when the settings match); a finished earlier result in OUT is moved
 * there first for the same reason. */
static pg_status begin_output(const char *out, pg_staged_dir *staged)
{
    char done_file[4300];
    PG_TRY(pg_staged_dir_begin(staged, out, 1));
    snprintf(done_file, sizeof done_file, "%s/trainset.json", staged->final);
    int fresh = !pg_path_exists(staged->work) || rmdir(staged->work) == 0; /* nothing to resume */
    if (fresh && pg_path_exists(done_file) && rename(staged->final, staged->work) != 0)
        return pg_fail(PG_ERR_ENV, "%s: cannot move to %s: %s", staged->final, staged->work, strerror(errno));
    return pg_mkdir_p(staged->work);
}

static pg_status proxies_run(const pg_proxies_config *c, pg_proxies_report *r)
{
    memset(r, 0, sizeof *r);
    int use_dataset_poses;
    PG_TRY(check_config(c, &use_dataset_poses));
    const char *input = c->input, *depth_path = c->depth, *out = c->out;
    int num = c->proxies, train_cam = 0;
    float pose_scale = c->pose_scale;
    r->threads = stage_use_threads(c->threads);
    io_dataset_options dopt = io_dataset_defaults();
    dopt.width = c->width;
    dopt.height = c->height;
    dopt.count = c->frames;
    dopt.fov_deg = c->fov;
    io_depth depth = { 0 };
    pg_camera *cams = NULL;
    const char **names = NULL;
    char(*hnames)[24] = NULL; /* "proxy" and any int */
    int *idx = NULL;
    frame_source src = { 0 };
    pg_dataset *ds = NULL;
    pg_status st = io_dataset_open(input, &dopt, &ds);
    if (st) return st;
    int ncam = io_dataset_num_cameras(ds), F = io_dataset_num_frames(ds);
    int W = io_dataset_width(ds), H = io_dataset_height(ds);
    if (c->train_camera && io_dataset_resolve_camera(ds, c->train_camera, &train_cam) != PG_OK) {
        io_dataset_close(ds);
        return pg_fail_context(PG_ERR_ARG, "proxies: %s: --train-cam", input);
    }
    int tests[MAX_CAMS], ntest = 0;
    if (c->test_cameras) {
        if (io_dataset_resolve_cameras(ds, c->test_cameras, tests, MAX_CAMS, &ntest) != PG_OK) {
            io_dataset_close(ds);
            return pg_fail_context(PG_ERR_ARG, "proxies: %s: --test-cams", input);
        }
        for (int k = 0; k < ntest; k++)
            if (tests[k] == train_cam) {
                char label[96];
                io_dataset_camera_label(ds, train_cam, label, sizeof label);
                io_dataset_close(ds);
                return pg_fail(PG_ERR_ARG, "proxies: %s: test camera %s is the training camera", input, label);
            }
    } else if (ncam >= 7) {
        /* the DyNeRF protocol: cam05 and cam06 held out (unless one of them is the real camera) */
        tests[0] = 5; tests[1] = 6; ntest = 2;
        if (train_cam == 5 || train_cam == 6) ntest = 0;
    }
    io_dataset_camera_label(ds, train_cam, r->train_camera, sizeof r->train_camera);
    for (int k = 0; k < ntest; k++) {
        char label[PG_CAMERA_LABEL];
        io_dataset_camera_label(ds, tests[k], label, sizeof label);
        size_t n = strlen(r->test_cameras);
        snprintf(r->test_cameras + n, sizeof r->test_cameras - n, "%s%s", k ? ", " : "", label);
    }
    if (use_dataset_poses < 0) use_dataset_poses = ncam > 1;
    if (use_dataset_poses && ncam - 1 - ntest < 1) {
        io_dataset_close(ds);
        return pg_fail(PG_ERR_ARG, "proxies: %s has no camera left for dataset poses (use --poses hemisphere)", input);
    }
    if (c->diagnose && !use_dataset_poses) {
        io_dataset_close(ds);
        return pg_fail(PG_ERR_ARG, "proxies: %s: --diagnose needs proxies at dataset cameras (--poses dataset on a "
                       "multi-camera input): nothing was recorded where hemisphere proxies look from", input);
    }

    double depth_unit = c->depth_unit;
    if (!(depth_unit > 0)) st = stage_depth_unit(depth_path, &depth_unit);
    if (st) {
        io_dataset_close(ds);
        return st;
    }
    io_depth_options zo = io_depth_defaults();
    zo.width = W;
    zo.height = H;
    zo.count = F;
    st = io_depth_load(depth_path, &zo, &depth);
    if (!st && depth.frames != F)
        st = pg_fail(PG_ERR_SIZE, "%s: %d depth frames for %d video frames", depth_path, depth.frames, F);
    if (!st) {
        /* The scene centre and the scale fit read frame 0: it must have some depth. */
        size_t valid0 = 0;
        for (size_t i = 0; i < (size_t)W * H; i++) valid0 += depth.data[i] > 0;
        if (!valid0)
            st = pg_fail(PG_ERR_FORMAT, "%s: no valid depth in frame 0 (every value is NaN, inf or <= 0)", depth_path);
    }
    if (st) goto done;

    pg_camera real;
    io_dataset_camera(ds, train_cam, &real);
    const int nother = ncam - 1 - ntest; /* dataset cameras neither real nor test */
    int M = use_dataset_poses ? nother : (num < 0 ? 18 : num);
    const int cap = M > nother ? M : nother; /* cams/names hold the other cameras, then the proxies */
    cams = calloc((size_t)cap + 1, sizeof *cams);
    names = calloc((size_t)cap + MAX_CAMS, sizeof *names);
    hnames = calloc((size_t)M + 1, sizeof *hnames);
    idx = calloc((size_t)cap + 1, sizeof *idx);
    pg_camera *tcams = calloc((size_t)ntest + 1, sizeof *tcams);
    const char **tnames = names + cap;
    if (!cams || !names || !hnames || !idx || !tcams) {
        free(tcams);
        st = pg_fail(PG_ERR_NOMEM, "proxies: out of memory");
        goto done;
    }
    src.ds = ds;
    src.cams[0] = train_cam;
    for (int k = 0; k < ntest; k++) {
        src.cams[1 + k] = tests[k];
        io_dataset_camera(ds, tests[k], &tcams[k]);
        tnames[k] = io_dataset_camera_name(ds, tests[k]);
    }
    pose_fit fit = { 0, 0, "given", NAN };
    int fitted = 0;
    /* Dataset poses train at the other cameras; test cameras need the depth in pose units whatever
     * the proxies' poses (hemisphere proxies scored at test cameras would otherwise see the scene at
     * the depth's scale). Either way the scale is fitted on the other cameras' frame 0. */
    const int use_others = use_dataset_poses || ntest > 0;
    if (use_others) other_cameras(ds, ncam, train_cam, tests, ntest, cams, names, idx);
    /* Hemisphere poses keep the depth file's numbers (the same for any --depth-scale) and carry
     * the user's unit beside them; a given pose scale is per user depth unit. */
    double length_unit = 1;
    if (pose_scale == 0 && use_others && nother > 0) {
        char workdir[4200];
        snprintf(workdir, sizeof workdir, "%s.colmap", out);
        st = fit_scale(ds, train_cam, &real, depth.data, nother, idx, cams, c->pose_shift, workdir, r->threads, &fit);
        if (st) { free(tcams); goto done; }
        pose_scale = fit.scale;
        /* every frame takes frame 0's shift: one global map, as the paper's alignment */
        proxy_shift_disparity(depth.data, (size_t)F * W * H, fit.shift);
        fitted = 1;
    } else if (pose_scale == 0) {
        pose_scale = 1;
        length_unit = depth_unit;
    } else {
        pose_scale = (float)(pose_scale * depth_unit);
    }
    if (use_dataset_poses && num >= 0 && num < M) {
        /* keep the num cameras closest in viewing direction to the real one (stable order) */
        for (int a = 1; a < M; a++)
            for (int b = a; b > 0 && proxy_camera_angle_deg(&real, &cams[b]) < proxy_camera_angle_deg(&real, &cams[b - 1]); b--) {
                pg_camera tc = cams[b]; cams[b] = cams[b - 1]; cams[b - 1] = tc;
                const char *tn = names[b]; names[b] = names[b - 1]; names[b - 1] = tn;
            }
        M = num;
    }
    proxy_job job = { 0 };
    st = proxy_scene_center(&real, depth.data, pose_scale, job.center, &job.radius);
    if (!st && !use_dataset_poses) {
        if (M > 0) st = proxy_poses_hemisphere(&real, job.center, M, c->max_angle, cams);
        for (int k = 0; k < M; k++) {
            snprintf(hnames[k], sizeof hnames[k], "proxy%02d", k);
            names[k] = hnames[k];
        }
    }
    if (st) { free(tcams); goto done; }
    job.frames = F; job.width = W; job.height = H; job.fps = io_dataset_fps(ds);
    job.get_frame = source_frame; job.frame_ctx = &src;
    job.depth = depth.data; job.pose_scale = pose_scale; job.pose_shift = fit.shift; job.pose_fit = fit.method; job.unit = length_unit;
    job.real_name = io_dataset_camera_name(ds, train_cam); job.real = real;
    job.num_proxies = M; job.proxy_names = names; job.proxies = cams;
    job.num_tests = ntest; job.test_names = tnames; job.tests = tcams;
    job.input_path = input; job.depth_path = depth_path;
    proxy_options po = proxy_default_options();
    po.threads = r->threads;
    po.force = c->force;
    po.fit.render = c->render && strcmp(c->render, "splat") == 0 ? PROXY_RENDER_SPLAT : PROXY_RENDER_MESH;
    po.fit.steps = c->fit_steps;
    po.fit.block = c->fit_block;
    if (c->pad >= 0) po.fit.pad = c->pad;
    proxy_result res;
    pg_staged_dir staged;
    proxies_diagnosis diag = { 0, NAN, NAN, NAN };
    st = begin_output(out, &staged);
    if (!st) {
        st = proxy_generate(&po, &job, staged.work, &res);
        if (st) pg_staged_dir_abort(&staged);
        else st = pg_staged_dir_commit(&staged);
        /* After the commit: the proxies are complete whatever the diagnosis meets (diagnose.json
         * is written atomically on its own). */
        if (!st && c->diagnose) st = stage_proxies_diagnose(ds, out, &real, M, names, cams, F, W, H, &diag);
    }
    free(tcams);
    if (st) goto done;
    r->frames = F;
    r->computed = res.frames_done;
    r->reused = res.frames_skipped;
    r->proxies = M;
    snprintf(r->poses, sizeof r->poses, "%s", use_dataset_poses ? "dataset" : "hemisphere");
    r->pose_scale = pose_scale / depth_unit; /* per user depth unit, as --pose-scale */
    r->pose_scale_fitted = fitted;
    r->pose_scale_cost = fit.cost;
    r->pose_shift = fit.shift / depth_unit; /* per user depth unit, as pose_scale */
    snprintf(r->pose_fit, sizeof r->pose_fit, "%s", fitted ? fit.method : c->pose_scale > 0 ? "given" : "none");
    r->mean_valid_fraction = res.mean_valid_fraction;
    r->mean_source_psnr = res.mean_source_psnr;
    r->seconds = res.wall_s;
    r->diagnosed_views = diag.views;
    r->diagnose_psnr_reprojected = diag.psnr_reprojected;
    r->diagnose_psnr_guessed = diag.psnr_guessed;
    r->diagnose_psnr_moving = diag.psnr_moving;
done:
    free(cams);
    free(names);
    free(hnames);
    free(idx);
    io_depth_destroy(&depth);
    io_dataset_close(ds);
    return st;
}

/* The output is claimed (checked and locked, core/output.h) before any work and held for the
 * whole stage. */
pg_status pg_proxies_run(const pg_proxies_config *c, pg_proxies_report *r)
{
    memset(r, 0, sizeof *r);
    if (!c->out) return proxies_run(c, r); /* its own check names what is missing */
    PG_TRY(pg_output_claim_dir(c->out));
    pg_status st = proxies_run(c, r);
    pg_output_release(c->out);
    return st;
}
