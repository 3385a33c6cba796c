/* cmd_train.c - `prodygs train DIR --out MODEL`: train the 4D model on a training set
 * (docs/FORMATS.md, from `prodygs proxies`) or on the real cameras of a DyNeRF dataset.
 *
 * MODEL is a directory: model.ckpt (the checkpoint, renderable on its own) and train.json
 * (cameras of the training set with their roles, settings, held-out PSNR, seconds).
 */
#include <cjson/cJSON.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli/cli.h"
#include "core/fileutil.h"
#include "io/dataset.h"
#include "io/json.h"
#include "core/parallel.h"
#include "train/train.h"
#include "train/trainset.h"

static cJSON *camera_json(const train_view *v)
{
    cJSON *c = io_json_from_camera(&v->cam, v->name);
    if (c) cJSON_AddStringToObject(c, "role", io_view_role_name(v->role));
    return c;
}

static pg_status write_summary(const char *path, const train_set *ts, const train_config *cfg, train_session *s,
                               double test_psnr, const train_eval_scores *train_eval, double seconds, const char *source)
{
    cJSON *root = cJSON_CreateObject();
    cJSON_AddNumberToObject(root, "version", 1);
    cJSON_AddStringToObject(root, "source", source);
    cJSON_AddNumberToObject(root, "frames", ts->frames);
    cJSON_AddNumberToObject(root, "width", ts->width);
    cJSON_AddNumberToObject(root, "height", ts->height);
    cJSON_AddNumberToObject(root, "fps", ts->fps);
    cJSON_AddNumberToObject(root, "iterations", train_session_iteration(s));
    cJSON_AddNumberToObject(root, "gaussians", train_session_gaussians(s));
    cJSON_AddNumberToObject(root, "static_gaussians", train_session_static_count(s));
    double md, mm;
    train_session_deform_stats(s, &md, &mm);
    cJSON_AddNumberToObject(root, "mean_deformed_per_iteration", md);
    cJSON_AddNumberToObject(root, "mean_movable_per_iteration", mm);
    cJSON_AddNumberToObject(root, "seed", (double)cfg->seed);
    cJSON_AddNumberToObject(root, "coarse_iters", cfg->coarse_iters);
    if (test_psnr > 0) cJSON_AddNumberToObject(root, "test_psnr", test_psnr);
    if (train_eval) {
        cJSON_AddNumberToObject(root, "train_real_psnr", train_eval->psnr);
        if (isfinite(train_eval->psnr_moving)) cJSON_AddNumberToObject(root, "train_real_psnr_moving", train_eval->psnr_moving);
        if (isfinite(train_eval->psnr_static)) cJSON_AddNumberToObject(root, "train_real_psnr_static", train_eval->psnr_static);
        cJSON_AddNumberToObject(root, "train_real_moving_fraction", train_eval->moving_fraction);
    }
    cJSON_AddNumberToObject(root, "seconds", seconds);
    cJSON *cams = cJSON_AddArrayToObject(root, "cameras");
    for (int i = 0; i < ts->num_views; i++) cJSON_AddItemToArray(cams, camera_json(&ts->views[i]));
    char *text = cJSON_Print(root);
    cJSON_Delete(root);
    if (!text) return pg_fail(PG_ERR_NOMEM, "%s: out of memory", path);
    pg_status st = pg_write_file_atomic(path, text, strlen(text));
    free(text);
    return st;
}

int cmd_train(int argc, char **argv)
{
    const char *out = NULL, *real_cams = NULL, *test_cams = NULL, *depth = NULL;
    int iters = 3000, coarse = INT_MIN /* unset: iters/6 */, resume = 0, threads = 2, seed = 1, max_g = 200000, ck_every = 500;
    int init_points = 30000, frames = 0, width = 0, no_static = 0, no_cull = 0, sh = 3, views_per_step = 4;
    int eval_train = 0, proxies = -1, deform_res = 0, deform_width = 0, static_check = 0;
    float lambda_depth = -1, lambda_dssim = -1, real_weight = -1, moving_weight = -1;
    cli_option opts[] = {
        {"--out", CLI_STR, &out, "model directory to write (model.ckpt, train.json)"},
        {"--iters", CLI_INT, &iters, "total iterations, coarse included (3000)"},
        {"--coarse-iters", CLI_INT, &coarse, "static-Gaussian iterations before the deformation (iters/6)"},
        {"--resume", CLI_FLAG, &resume, "continue from MODEL/model.ckpt if present"},
        {"--threads", CLI_INT, &threads, "worker threads (2)"},
        {"--seed", CLI_INT, &seed, "random seed (1)"},
        {"--max-gaussians", CLI_INT, &max_g, "cap on the number of Gaussians (200000)"},
        {"--init-points", CLI_INT, &init_points, "Gaussians after voxel downsampling of the depth (30000)"},
        {"--checkpoint-every", CLI_INT, &ck_every, "write a checkpoint every K iterations (500, 0 = end only)"},
        {"--proxies", CLI_INT, &proxies, "training set: use N of the proxy views, evenly spaced (-1 = all)"},
        {"--real-cams", CLI_STR, &real_cams, "DyNeRF input: 'all' or a list like 0,1,2 of training cameras"},
        {"--test-cams", CLI_STR, &test_cams, "DyNeRF input: held-out cameras, e.g. 5,6"},
        {"--depth", CLI_STR, &depth, "DyNeRF input: depth .npy (F,H,W) of the first training camera"},
        {"--frames", CLI_INT, &frames, "DyNeRF input: use only the first N frames"},
        {"--width", CLI_INT, &width, "DyNeRF input: resize to this width"},
        {"--sh-degree", CLI_INT, &sh, "largest SH degree (3)"},
        {"--views-per-step", CLI_INT, &views_per_step, "views trained per deformation: the real view + proxies of one time (4)"},
        {"--real-weight", CLI_FLOAT, &real_weight, "share of a step's loss on the real view when proxies are in it (0.5)"},
        {"--moving-weight", CLI_FLOAT, &moving_weight, "extra loss weight on the real view's moving pixels (9)"},
        {"--lambda-depth", CLI_FLOAT, &lambda_depth, "weight of the SSI depth loss (0.05)"},
        {"--lambda-dssim", CLI_FLOAT, &lambda_dssim, "weight of D-SSIM (0.2)"},
        {"--deform-res", CLI_INT, &deform_res, "HexPlane spatial resolution of the coarse scale (64)"},
        {"--deform-width", CLI_INT, &deform_width, "deformation MLP width (128)"},
        {"--static-check-every", CLI_INT, &static_check, "learn static flags every K fine iterations (0 = off)"},
        {"--no-static", CLI_FLAG, &no_static, "send every Gaussian through the network"},
        {"--no-cull", CLI_FLAG, &no_cull, "no frustum culling before the network"},
        {"--eval-train", CLI_FLAG, &eval_train, "also report PSNR over all frames of the real views"},
    };
    cli_spec spec = {"prodygs train", "DIR --out MODEL [options]",
                     "Train the 4D Gaussian model on a training set (from `prodygs proxies`) or a DyNeRF dataset.",
                     opts, (int)(sizeof opts / sizeof opts[0]), 1, 1};
    const char *pos[1];
    int npos = 0;
    int rc = cli_parse(&spec, argc, argv, pos, &npos);
    if (rc == -1) return 0;
    if (rc) return rc;
    if (!out) return cli_usage_error("train: --out MODEL is required");
    if (iters < 1) return cli_usage_error("train: --iters must be >= 1");
    if (coarse != INT_MIN && (coarse < 0 || coarse > iters))
        return cli_usage_error("train: --coarse-iters %d must be in 0..--iters (%d)", coarse, iters);
    if (init_points < 1) return cli_usage_error("train: --init-points %d must be >= 1", init_points);
    if (views_per_step < 1 || views_per_step > TRAIN_MAX_BATCH)
        return cli_usage_error("train: --views-per-step %d must be in 1..%d", views_per_step, TRAIN_MAX_BATCH);
    if (real_weight != -1 && !(real_weight >= 0 && real_weight <= 1))
        return cli_usage_error("train: --real-weight %g must be in [0, 1]", real_weight);
    if (moving_weight != -1 && !(moving_weight >= 0 && moving_weight <= 100))
        return cli_usage_error("train: --moving-weight %g must be in [0, 100]", moving_weight);
    if (frames < 0) return cli_usage_error("train: --frames %d must be >= 1 (0 = all)", frames);
    if (width < 0 || width > CLI_MAX_SIDE)
        return cli_usage_error("train: --width %d out of range 1..%d (0 = keep)", width, CLI_MAX_SIDE);
    if (proxies < -1) return cli_usage_error("train: --proxies %d must be >= 0 (-1 = all)", proxies);
    if (max_g < 16) return cli_usage_error("train: --max-gaussians must be >= 16");
    if (threads < 1 || threads > 256) return cli_usage_error("train: --threads must be in 1..256");
    if (sh < 0 || sh > 3) return cli_usage_error("train: --sh-degree must be 0..3");
    if (deform_res < 0 || deform_res > 1024 || deform_width < 0 || deform_width > 1024)
        return cli_usage_error("train: --deform-res/--deform-width out of range");
    if (ck_every < 0) return cli_usage_error("train: --checkpoint-every must be >= 0");
    pg_set_threads(threads);
    cli_install_progress();

    char path[4096];
    train_set ts;
    pg_status st;
    const char *source;
    if (pg_path_join(path, sizeof path, pos[0], "trainset.json") == PG_OK && pg_path_exists(path)) {
        source = "trainset";
        if (real_cams || test_cams) return cli_usage_error("train: --real-cams/--test-cams apply to DyNeRF datasets");
        st = train_set_load(pos[0], &ts);
    } else if (pg_path_join(path, sizeof path, pos[0], "poses_bounds.npy") == PG_OK && pg_path_exists(path)) {
        source = "dynerf";
        int tlist[64], rlist[64];
        train_set_dynerf_options o = train_set_dynerf_defaults();
        if (test_cams || (real_cams && strcmp(real_cams, "all") != 0)) {
            /* camera tokens: names first, then indices (io_dataset_resolve_camera) */
            pg_dataset *ds = NULL;
            io_dataset_options dopt = io_dataset_defaults();
            if ((st = io_dataset_open(pos[0], &dopt, &ds))) return cli_fail(st);
            if (test_cams && io_dataset_resolve_cameras(ds, test_cams, tlist, 64, &o.num_test) != PG_OK)
                st = PG_ERR_ARG;
            if (!st && real_cams && strcmp(real_cams, "all") != 0) {
                o.all_real = 0;
                if (io_dataset_resolve_cameras(ds, real_cams, rlist, 64, &o.num_real) != PG_OK) st = PG_ERR_ARG;
            }
            io_dataset_close(ds);
            if (st) return cli_usage_error("train: %s: %s", pos[0], pg_last_error());
            if (test_cams) o.test_cams = tlist;
            if (!o.all_real) o.real_cams = rlist;
        }
        o.depth_path = depth;
        o.max_frames = frames;
        o.width = width;
        st = train_set_from_dynerf(pos[0], &o, &ts);
    } else {
        return cli_usage_error("train: %s: neither a training set (trainset.json) nor a DyNeRF dataset "
                               "(poses_bounds.npy)", pos[0]);
    }
    if (st) return cli_fail(st);
    train_set_limit_proxies(&ts, proxies);

    train_config cfg = train_default_config();
    cfg.iters = iters;
    cfg.coarse_iters = coarse != INT_MIN ? coarse : iters / 6;
    cfg.seed = (uint64_t)seed;
    cfg.threads = threads;
    cfg.max_gaussians = max_g;
    cfg.init_points = init_points;
    cfg.checkpoint_every = ck_every;
    cfg.sh_max_degree = sh;
    cfg.views_per_step = views_per_step;
    if (real_weight >= 0) cfg.real_weight = real_weight;
    if (moving_weight >= 0) cfg.moving_weight = moving_weight;
    if (lambda_depth >= 0) cfg.lambda_depth = lambda_depth;
    if (lambda_dssim >= 0) cfg.lambda_dssim = lambda_dssim;
    cfg.deform_res = deform_res;
    cfg.deform_width = deform_width;
    cfg.use_static_flags = !no_static;
    if (static_check < 0) return cli_usage_error("train: --static-check-every must be >= 0");
    cfg.static_check_every = static_check;
    cfg.use_frustum_cull = !no_cull;
    const char *stop = getenv("PG_TEST_STOP_AT_ITER");
    if (stop) cfg.stop_at_iter = atoi(stop);

    train_session *s = NULL;
    char ckpt[4096], summary[4096];
    double t0 = pg_time_seconds(), test_psnr = 0;
    train_eval_scores tr = {0};
    if ((st = pg_mkdir_p(out)) || (st = pg_path_join(ckpt, sizeof ckpt, out, "model.ckpt")) ||
        (st = pg_path_join(summary, sizeof summary, out, "train.json")))
        goto done;
    if ((st = train_session_create(&s, &ts, &cfg, ckpt, resume))) goto done;
    if ((st = train_session_run(s))) goto done;
    if (cfg.stop_at_iter > 0 && train_session_iteration(s) < cfg.iters) goto done; /* simulated kill */
    if (train_set_count_role(&ts, IO_ROLE_TEST) > 0 && (st = train_session_evaluate(s, IO_ROLE_TEST, &test_psnr)))
        goto done;
    if (eval_train && (st = train_session_evaluate_parts(s, IO_ROLE_REAL, &tr))) goto done;
    if ((st = write_summary(summary, &ts, &cfg, s, test_psnr, eval_train ? &tr : NULL, pg_time_seconds() - t0, source)))
        goto done;
    /* train_real_*: only measured with --eval-train (null otherwise, and for an empty part) */
    char v[3][32];
    double vals[3] = { eval_train ? tr.psnr : NAN, eval_train ? tr.psnr_moving : NAN, eval_train ? tr.psnr_static : NAN };
    for (int k = 0; k < 3; k++) {
        if (isfinite(vals[k]))
            snprintf(v[k], sizeof v[k], "%.3f", vals[k]);
        else
            snprintf(v[k], sizeof v[k], "null");
    }
    printf("{\"iterations\": %d, \"gaussians\": %d, \"static\": %d, \"test_psnr\": %.3f, \"train_real_psnr\": %s, "
           "\"train_real_psnr_moving\": %s, \"train_real_psnr_static\": %s, \"seconds\": %.1f}\n",
           train_session_iteration(s), train_session_gaussians(s), train_session_static_count(s), test_psnr, v[0], v[1],
           v[2], pg_time_seconds() - t0);
    fflush(stdout);
done:
    train_session_destroy(s);
    train_set_destroy(&ts);
    return st ? cli_fail(st) : 0;
}
