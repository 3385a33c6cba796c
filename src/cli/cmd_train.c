/* cmd_train.c - `prodygs train`: options -> pg_train_config -> pg_train_run -> JSON line. */
#include "cli/cli.h"

#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

int cmd_train(int argc, char **argv)
{
    pg_train_config c;
    pg_train_defaults(&c);
    c.coarse_iters = INT_MIN; /* unset: train_default_coarse_iters */
    const char *proxies = NULL;
    int no_static = 0, no_cull = 0;
    cli_option opts[] = {
        {"--out", CLI_STR, &c.out, "model directory to write (model.ckpt, train.json, cameras.json) (required)"},
        {"--iters", CLI_INT, &c.iters, "total iterations, coarse included (3000)"},
        {"--coarse-iters", CLI_INT, &c.coarse_iters, "static-Gaussian iterations before the deformation (iters/6, at most 250)"},
        {"--densify-until", CLI_INT, &c.densify_until, "no densification from this iteration on (70 % of --iters)"},
        {"--resume", CLI_FLAG, &c.resume, "continue from MODEL/model.ckpt if present"},
        {"--threads", CLI_INT, &c.threads, "worker threads (default: all cores)"},
        {"--seed", CLI_INT, &c.seed, "random seed (1)"},
        {"--max-gaussians", CLI_INT, &c.max_gaussians, "cap on the number of Gaussians (200000)"},
        {"--init-points", CLI_INT, &c.init_points, "Gaussians after voxel downsampling of the depth (30000)"},
        {"--checkpoint-every", CLI_INT, &c.checkpoint_every, "write a checkpoint every K iterations (500, 0 = end only)"},
        {"--proxies", CLI_STR, &proxies, "training set: use N of the proxy views, evenly spaced, or all (all)"},
        {"--real-cams", CLI_STR, &c.real_cameras, "DyNeRF input: all, or training cameras by name or index"},
        {"--test-cams", CLI_STR, &c.test_cameras, "DyNeRF input: held-out cameras by name or index, e.g. cam05,cam06"},
        {"--depth", CLI_STR, &c.depth, "DyNeRF input: depth .npy (F,H,W) of the first training camera"},
        {"--frames", CLI_INT, &c.frames, "DyNeRF input: use only the first N frames"},
        {"--width", CLI_INT, &c.width, "DyNeRF input: resize to this width"},
        {"--sh-degree", CLI_INT, &c.sh_degree, "largest SH degree 0..3 (default: 3 with several real cameras, 0 with one)"},
        {"--motion-crops", CLI_INT, &c.motion_crops, "extra times per fine step over the box around the movers only, the real view and a proxy in turn (2; 0 = off)"},
        {"--times-per-step", CLI_INT, &c.times_per_step, "times (each its own deformation and views) per optimiser step (1)"},
        {"--views-per-step", CLI_INT, &c.views_per_step, "views trained per deformation: the real view + proxies of one time (2)"},
        {"--proxy-moving-weight", CLI_FLOAT, &c.proxy_moving_weight, "loss weight of proxy pixels that show the real view's moving pixels (1)"},
        {"--real-weight", CLI_FLOAT, &c.real_weight, "share of a step's loss on the real view when proxies are in it (0.75)"},
        {"--moving-weight", CLI_FLOAT, &c.moving_weight, "extra loss weight on the real view's moving pixels (9)"},
        {"--lambda-depth", CLI_FLOAT, &c.lambda_depth, "weight of the SSI depth loss (0.05)"},
        {"--lambda-dssim", CLI_FLOAT, &c.lambda_dssim, "weight of D-SSIM (0.2)"},
        {"--deform-res", CLI_INT, &c.deform_res, "HexPlane spatial resolution of the coarse scale (64)"},
        {"--deform-width", CLI_INT, &c.deform_width, "deformation MLP width (64)"},
        {"--deform-time-res", CLI_INT, &c.deform_tres, "HexPlane time texels (default: one per frame, at most what the iterations can train)"},
        {"--deform-time-coarsen", CLI_INT, &c.deform_time_coarsen, "coarse HexPlane scale: one time texel per 2^K of the fine scale's (default 2; 0 = same)"},
        {"--deform-time-warmup", CLI_FLOAT, &c.deform_time_warmup, "share of the fine stage trained on a quarter of the HexPlane time rows, then refined (default 0.4; 0 = off)"},
        {"--densify-movable", CLI_FLOAT, &c.densify_movable, "the movable Gaussians' densification threshold, a multiple of the still ones' (default: 3 for a long clip, whose time rows get < 40 fits each; else 1)"},
        {"--proxy-downscale", CLI_INT, &c.proxy_downscale, "proxies train at 1/S of the working size per side: 1 or 2 (default 2; the real view keeps every pixel)"},
        {"--deform-head-width", CLI_INT, &c.deform_head_width, "hidden width of each deformation head (default 32)"},
        {"--static-check-every", CLI_INT, &c.static_check_every, "learn static flags every K fine iterations (0 = off)"},
        {"--no-static", CLI_FLAG, &no_static, "send every Gaussian through the network"},
        {"--no-cull", CLI_FLAG, &no_cull, "no frustum culling before the network"},
        {"--eval-train", CLI_FLAG, &c.eval_train, "also report PSNR of the real views' moving and static pixels"},
        {"--full-size", CLI_STR, &c.full_size_input, "after the iterations, fit the still scene and the movers at the size of this source's frames (the video or dataset the set was made from; one real view)"},
        {"--full-size-camera", CLI_STR, &c.full_size_camera, "the --full-size source's camera that is the real view (default: its first)"},
        {"--full-size-steps", CLI_INT, &c.full_size_steps, "the movers' steps at full size (default: 3 per frame, 100 to 1200)"},
    };
    cli_spec spec = {"prodygs train", "DIR --out MODEL [options]",
                     "Trains the 4D Gaussian model on a training set (from `prodygs proxies`) or a DyNeRF dataset.\n\n"
                     "example: prodygs train out/proxies --out out/model --iters 1500",
                     opts, (int)(sizeof opts / sizeof opts[0]), 1, 1};
    int rc = cli_parse(&spec, argc, argv, &c.input, NULL);
    if (rc) return rc < 0 ? 0 : rc;
    if (!c.out) return cli_usage_error("train: --out MODEL is required");
    if ((rc = cli_parse_count_or_all("--proxies", proxies, &c.proxies))) return rc;
    if (c.coarse_iters == INT_MIN) c.coarse_iters = -1;
    else if (c.coarse_iters < 0) return cli_usage_error("train: --coarse-iters %d must be >= 0", c.coarse_iters);
    c.use_static = !no_static;
    c.use_cull = !no_cull;
    const char *stop = getenv("PG_TEST_STOP_AT_ITER");
    if (stop) c.stop_at_iter = atoi(stop);

    pg_train_report r;
    pg_status st = pg_train_run(&c, &r);
    if (st) return cli_fail(st);
    if (!r.finished) return 0; /* simulated kill (tests) */
    char a[32], b[32], d[32], e[32], f[32], g[32];
    printf("{\"iterations\": %d, \"gaussians\": %d, \"static\": %d, \"test_psnr\": %s, \"train_real_psnr\": %s, "
           "\"train_real_psnr_moving\": %s, \"train_real_psnr_static\": %s, ",
           r.iterations, r.gaussians, r.static_gaussians, cli_json_number(r.test_psnr, 3, a, sizeof a),
           cli_json_number(r.train_psnr, 3, b, sizeof b), cli_json_number(r.train_psnr_moving, 3, d, sizeof d),
           cli_json_number(r.train_psnr_static, 3, e, sizeof e));
    if (r.full_width > 0)
        printf("\"full_size\": \"%dx%d\", \"full_psnr\": %s, \"full_psnr_moving\": %s, ", r.full_width, r.full_height,
               cli_json_number(r.full_psnr, 3, f, sizeof f), cli_json_number(r.full_psnr_moving, 3, g, sizeof g));
    printf("\"threads\": %d, \"seed\": %d, \"seconds\": %.1f}\n", r.threads, r.seed, r.seconds);
    return 0;
}
