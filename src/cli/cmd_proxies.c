/* cmd_proxies.c - `prodygs proxies INPUT --depth PATH --out DIR`: render proxy views from
 * per-frame RGB-D Gaussians into a training-set directory (docs/FORMATS.md, docs/proxy.md). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli/cli.h"
#include "core/parallel.h"
#include "io/dataset.h"
#include "io/depth_io.h"
#include "proxy/poses.h"
#include "proxy/proxy.h"

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

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

static float median_valid(const float *d, size_t n)
{
    float *t = malloc(n * sizeof(float));
    if (!t) return 0;
    size_t k = 0;
    for (size_t i = 0; i < n; i++)
        if (d[i] > 0) t[k++] = d[i];
    qsort(t, k, sizeof(float), cmp_float);
    float m = k ? t[k / 2] : 0;
    free(t);
    return m;
}

/* Fits the depth-to-pose scale on frame 0 against the proxy (training) cameras. */
static pg_status fit_scale(pg_dataset *ds, int real_idx, const pg_camera *real, const float *depth0, int n,
                           const int *idx, const pg_camera *cams, float *scale, proxy_scale_report *rep)
{
    int W = real->width, H = real->height;
    pg_image real_img = { 0 };
    pg_image *imgs = calloc((size_t)n, sizeof(pg_image));
    const float **ptrs = calloc((size_t)n, sizeof(float *));
    pg_status st = (!imgs || !ptrs) ? pg_fail(PG_ERR_NOMEM, "pose scale fit: out of memory") : PG_OK;
    if (!st) st = io_dataset_frame(ds, real_idx, 0, &real_img);
    for (int k = 0; k < n && !st; k++) {
        st = io_dataset_frame(ds, idx[k], 0, &imgs[k]);
        ptrs[k] = imgs[k].data;
    }
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
            so.coarse_steps = 64;
        }
        st = proxy_fit_pose_scale(real, real_img.data, depth0, n, cams, ptrs, &so, rep);
        *scale = rep->scale;
    }
    pg_image_destroy(&real_img);
    for (int k = 0; k < n && imgs; k++) pg_image_destroy(&imgs[k]);
    free(imgs);
    free(ptrs);
    for (int k = 0; k < n; k++) io_dataset_release(ds, idx[k]);
    return st;
}

int cmd_proxies(int argc, char **argv)
{
    const char *depth_path = NULL, *out = NULL, *poses = NULL, *test_list = NULL, *size = NULL, *train_text = NULL;
    int num = -1, steps = 100, block = 1, train_cam = 0, frames = 0, threads = 2, force = 0;
    float max_angle = 20, pose_scale = 0, fov = 60, pad = proxy_default_fit_options().pad;
    cli_option opts[] = {
        { "--depth", CLI_STR, &depth_path, "aligned depth (depth_aligned.npy from `prodygs prepare`) or raw depth" },
        { "--out", CLI_STR, &out, "output training-set directory" },
        { "--poses", CLI_STR, &poses, "hemisphere | dataset (default: dataset for multi-camera inputs)" },
        { "--num", CLI_INT, &num, "proxy cameras M (hemisphere 18; dataset: all others, or the M closest in angle)" },
        { "--max-angle", CLI_FLOAT, &max_angle, "hemisphere: max angle from the real camera in degrees (20)" },
        { "--steps", CLI_INT, &steps, "Adam steps per frame (100)" },
        { "--block", CLI_INT, &block, "one Gaussian per k x k pixel block (1)" },
        { "--pad", CLI_FLOAT, &pad, "outpainted margin around the real view, fraction of the larger side (0.3; 0 = none)" },
        { "--train-cam", CLI_STR, &train_text, "the real (training) camera: index or name (0)" },
        { "--test-cams", CLI_STR, &test_list, "test camera indices, never used (dataset default 5,6)" },
        { "--pose-scale", CLI_FLOAT, &pose_scale, "pose units per depth unit (dataset: fitted if absent)" },
        { "--frames", CLI_INT, &frames, "use the first N frames (all)" },
        { "--size", CLI_STR, &size, "resize frames to WxH" },
        { "--fov", CLI_FLOAT, &fov, "single video/folder: horizontal field of view in degrees (60)" },
        { "--threads", CLI_INT, &threads, "frames processed in parallel (2)" },
        { "--force", CLI_FLAG, &force, "recompute frames even if cached" },
    };
    cli_spec spec = { "prodygs proxies", "INPUT --depth PATH --out DIR [options]",
                      "render proxy views of every frame from virtual cameras (paper 3.2)", opts,
                      (int)(sizeof opts / sizeof opts[0]), 1, 1 };
    const char *input = NULL;
    int rc = cli_parse(&spec, argc, argv, &input, NULL);
    if (rc) return rc < 0 ? 0 : rc;
    if (!depth_path) return cli_usage_error("proxies: --depth PATH is required");
    if (!out) return cli_usage_error("proxies: --out DIR is required");
    if (num < -1 || num > MAX_CAMS) return cli_usage_error("proxies: --num %d not in 0..%d", num, MAX_CAMS);
    if (!(max_angle > 0 && max_angle < 90)) return cli_usage_error("proxies: --max-angle %g not in (0, 90)", max_angle);
    if (steps < 0 || steps > 100000) return cli_usage_error("proxies: --steps %d out of range", steps);
    if (block < 1 || block > 64) return cli_usage_error("proxies: --block %d not in 1..64", block);
    if (!(pad >= 0 && pad <= 1)) return cli_usage_error("proxies: --pad %g not in [0, 1]", pad);
    if (threads < 1 || threads > 64) return cli_usage_error("proxies: --threads %d not in 1..64", threads);
    if (frames < 0) return cli_usage_error("proxies: --frames %d is negative", frames);
    if (pose_scale < 0 || !isfinite(pose_scale)) return cli_usage_error("proxies: --pose-scale must be positive");
    int use_dataset_poses = -1;
    if (poses) {
        if (!strcmp(poses, "hemisphere")) use_dataset_poses = 0;
        else if (!strcmp(poses, "dataset") || !strcmp(poses, "given")) use_dataset_poses = 1;
        else return cli_usage_error("proxies: --poses '%s' is not hemisphere or dataset", poses);
    }
    io_dataset_options dopt = io_dataset_defaults();
    if (size && (sscanf(size, "%dx%d", &dopt.width, &dopt.height) != 2 || dopt.width < 8 || dopt.height < 8 ||
                 dopt.width > PG_MAX_IMAGE_SIDE || dopt.height > PG_MAX_IMAGE_SIDE))
        return cli_usage_error("proxies: --size '%s' is not WxH", size);
    dopt.count = frames;
    dopt.fov_deg = fov;
    cli_install_progress();

    pg_dataset *ds = NULL;
    io_depth depth = { 0 };
    pg_camera *cams = NULL;
    const char **names = NULL;
    char(*hnames)[16] = NULL;
    int *idx = NULL;
    frame_source src = { 0 };
    pg_status st = io_dataset_open(input, &dopt, &ds);
    if (st) return cli_fail(st);
    int ncam = io_dataset_num_cameras(ds), F = io_dataset_num_frames(ds);
    int W = io_dataset_width(ds), H = io_dataset_height(ds);
    if (train_text && io_dataset_resolve_camera(ds, train_text, &train_cam) != PG_OK) {
        io_dataset_close(ds);
        return cli_usage_error("proxies: %s: --train-cam: %s", input, pg_last_error());
    }
    int tests[MAX_CAMS], ntest = 0;
    if (test_list) {
        if (io_dataset_resolve_cameras(ds, test_list, tests, MAX_CAMS, &ntest) != PG_OK) {
            io_dataset_close(ds);
            return cli_usage_error("proxies: %s: --test-cams: %s", input, pg_last_error());
        }
        for (int k = 0; k < ntest; k++)
            if (tests[k] == train_cam) {
                char label[96];
                io_dataset_camera_label(ds, train_cam, label, sizeof label);
                io_dataset_close(ds);
                return cli_usage_error("proxies: test camera %s is the training camera", label);
            }
    } else if (ncam >= 7) {
        /* the DyNeRF protocol: cam05 and cam06 held out (unless one of them is the real camera) */
        tests[0] = 5; tests[1] = 6; ntest = 2;
        if (train_cam == 5 || train_cam == 6) ntest = 0;
    }
    {
        char label[96];
        io_dataset_camera_label(ds, train_cam, label, sizeof label);
        printf("proxies: training camera %s", label);
        for (int k = 0; k < ntest; k++) {
            io_dataset_camera_label(ds, tests[k], label, sizeof label);
            printf("%s%s", k ? ", " : "; test cameras ", label);
        }
        printf("\n");
        fflush(stdout);
    }
    if (use_dataset_poses < 0) use_dataset_poses = ncam > 1;
    if (use_dataset_poses && ncam - 1 - ntest < 1) {
        io_dataset_close(ds);
        return cli_usage_error("proxies: %s has no camera left for dataset poses (use --poses hemisphere)", input);
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
    int M = use_dataset_poses ? ncam - 1 - ntest : (num < 0 ? 18 : num);
    cams = calloc((size_t)M + 1, sizeof *cams);
    names = calloc((size_t)M + MAX_CAMS, sizeof *names);
    hnames = calloc((size_t)M + 1, sizeof *hnames);
    idx = calloc((size_t)M + 1, sizeof *idx);
    pg_camera *tcams = calloc((size_t)ntest + 1, sizeof *tcams);
    const char **tnames = names + M;
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
    proxy_scale_report rep = { 0 };
    int fitted = 0;
    if (use_dataset_poses) {
        int m = 0;
        for (int c = 0; c < ncam; c++) {
            int is_test = 0;
            for (int k = 0; k < ntest; k++) is_test |= tests[k] == c;
            if (c == train_cam || is_test) continue;
            io_dataset_camera(ds, c, &cams[m]);
            names[m] = io_dataset_camera_name(ds, c);
            idx[m++] = c;
        }
        if (pose_scale == 0) {
            st = fit_scale(ds, train_cam, &real, depth.data, M, idx, cams, &pose_scale, &rep);
            if (st) { free(tcams); goto done; }
            fitted = 1;
        }
        if (num >= 0 && num < M) {
            /* keep the num cameras closest in viewing direction to the real one (stable order) */
            for (int a = 1; a < M; a++)
                for (int b = a; b > 0 && proxy_camera_angle_deg(&real, &cams[b]) < proxy_camera_angle_deg(&real, &cams[b - 1]); b--) {
                    pg_camera tc = cams[b]; cams[b] = cams[b - 1]; cams[b - 1] = tc;
                    const char *tn = names[b]; names[b] = names[b - 1]; names[b - 1] = tn;
                }
            M = num;
        }
    } else {
        if (pose_scale == 0) pose_scale = 1;
    }
    proxy_job job = { 0 };
    st = proxy_scene_center(&real, depth.data, pose_scale, job.center, &job.radius);
    if (!st && !use_dataset_poses) {
        if (M > 0) st = proxy_poses_hemisphere(&real, job.center, M, max_angle, cams);
        for (int k = 0; k < M; k++) {
            snprintf(hnames[k], sizeof hnames[k], "proxy%02d", k);
            names[k] = hnames[k];
        }
    }
    if (st) { free(tcams); goto done; }
    job.frames = F; job.width = W; job.height = H; job.fps = io_dataset_fps(ds);
    job.get_frame = source_frame; job.frame_ctx = &src;
    job.depth = depth.data; job.pose_scale = pose_scale;
    job.real_name = io_dataset_camera_name(ds, train_cam); job.real = real;
    job.num_proxies = M; job.proxy_names = names; job.proxies = cams;
    job.num_tests = ntest; job.test_names = tnames; job.tests = tcams;
    job.input_path = input; job.depth_path = depth_path;
    proxy_options po = proxy_default_options();
    po.threads = threads;
    po.force = force;
    po.fit.steps = steps;
    po.fit.block = block;
    po.fit.pad = pad;
    pg_set_threads(threads);
    proxy_result res;
    st = proxy_generate(&po, &job, out, &res);
    free(tcams);
    if (st) goto done;
    printf("{\"out\": \"%s\", \"frames\": %d, \"computed\": %d, \"reused\": %d, \"proxies\": %d, \"poses\": \"%s\", "
           "\"pose_scale\": %.6g, \"pose_scale_fitted\": %s, \"pose_scale_cost\": %.5f, \"mean_valid_fraction\": %.4f, "
           "\"mean_source_psnr\": %.2f, \"seconds\": %.1f}\n",
           out, F, res.frames_done, res.frames_skipped, M, use_dataset_poses ? "dataset" : "hemisphere", pose_scale,
           fitted ? "true" : "false", rep.cost, res.mean_valid_fraction, res.mean_source_psnr, res.wall_s);
done:
    free(cams);
    free(names);
    free(hnames);
    free(idx);
    io_depth_destroy(&depth);
    io_dataset_close(ds);
    return st ? cli_fail(st) : 0;
}
