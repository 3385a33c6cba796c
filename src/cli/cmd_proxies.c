/* cmd_proxies.c - `prodygs proxies`: options -> pg_proxies_config -> pg_proxies_run -> JSON line. */
#include "cli/cli.h"

#include <math.h>
#include <stdio.h>

int cmd_proxies(int argc, char **argv)
{
    pg_proxies_config c;
    pg_proxies_defaults(&c);
    c.pad = NAN; /* unset until given: a given --pad -1 is refused, not read as "the default" */
    const char *size = NULL, *proxies = NULL;
    int no_pose_shift = 0;
    const cli_option opts[] = {
        { "--depth", CLI_STR, &c.depth, "aligned depth (F,H,W) .npy, e.g. prepare's depth_aligned.npy (required)" },
        { "--out", CLI_STR, &c.out, "training-set directory to write (required)" },
        { "--proxies", CLI_STR, &proxies, "proxy cameras: a count or all (18 on the hemisphere; dataset: all others)" },
        { "--poses", CLI_STR, &c.poses, "hemisphere or dataset (default: dataset for a multi-camera input)" },
        { "--max-angle", CLI_FLOAT, &c.max_angle, "hemisphere: max angle from the real camera in degrees (20)" },
        { "--render", CLI_STR, &c.render, "mesh (default: the depth map as a textured mesh) or splat (per-frame Gaussians)" },
        { "--fit-steps", CLI_INT, &c.fit_steps, "splat: Adam steps of the per-frame Gaussian fit (50)" },
        { "--fit-block", CLI_INT, &c.fit_block, "splat: one Gaussian per BxB pixel block (1)" },
        { "--pad", CLI_FLOAT, &c.pad, "outpainted margin around the real view, fraction of the larger side (0.3)" },
        { "--train-cam", CLI_STR, &c.train_camera, "the real (training) camera: name or index (default: the first)" },
        { "--test-cams", CLI_STR, &c.test_cameras, "held-out cameras, names or indices (dataset default cam05,cam06)" },
        { "--pose-scale", CLI_FLOAT, &c.pose_scale, "pose units per depth unit (dataset: fitted if absent)" },
        { "--no-pose-shift", CLI_FLAG, &no_pose_shift, "dataset poses: fit the pose scale alone, no disparity shift (ablation)" },
        { "--frames", CLI_INT, &c.frames, "use only the first N frames (default: all)" },
        { "--size", CLI_STR, &size, "resize frames to WxH (0 for one side keeps the aspect)" },
        { "--fov", CLI_FLOAT, &c.fov, "single video: horizontal field of view in degrees (60)" },
        { "--threads", CLI_INT, &c.threads, "worker threads (default: all cores)" },
        { "--force", CLI_FLAG, &c.force, "recompute frames even if cached" },
        { "--diagnose", CLI_FLAG, &c.diagnose, "dataset poses: score each proxy against its camera's real frames (OUT/diagnose.json, OUT/vis/)" },
    };
    cli_spec spec = { "prodygs proxies", "INPUT --depth PATH --out DIR [options]",
                      "Renders proxy views of every frame from virtual cameras (paper 3.2) into a training set.\n\n"
                      "example: prodygs proxies clip.mp4 --depth out/prepare/depth_aligned.npy --out out/proxies",
                      opts, (int)(sizeof opts / sizeof opts[0]), 1, 1 };
    int rc = cli_parse(&spec, argc, argv, &c.input, NULL);
    if (rc) return rc < 0 ? 0 : rc;
    if (!c.depth || !c.out) return cli_usage_error("proxies: --depth PATH and --out DIR are required");
    if (isnan(c.pad)) c.pad = -1; /* the default */
    else if (!(c.pad >= 0 && c.pad <= 1)) return cli_usage_error("proxies: --pad %g not in [0, 1]", c.pad);
    if ((rc = cli_parse_size("--size", size, &c.width, &c.height))) return rc;
    if ((rc = cli_parse_count_or_all("--proxies", proxies, &c.proxies))) return rc;
    c.pose_shift = !no_pose_shift;

    pg_proxies_report r;
    char psnr[32], cost[32];
    pg_status st = pg_proxies_run(&c, &r);
    if (st) return cli_fail(st);
    printf("proxies: training camera %s%s%s\n", r.train_camera, r.test_cameras[0] ? "; test cameras " : "",
           r.test_cameras);
    printf("{\"out\": \"%s\", \"frames\": %d, \"computed\": %d, \"reused\": %d, \"proxies\": %d, \"poses\": \"%s\", "
           "\"pose_scale\": %.6g, \"pose_shift\": %.6g, \"pose_fit\": \"%s\", \"pose_scale_fitted\": %s, \"pose_scale_cost\": %s, \"mean_valid_fraction\": %.4f, "
           "\"mean_source_psnr\": %s, \"threads\": %d, \"seconds\": %.1f}\n",
           c.out, r.frames, r.computed, r.reused, r.proxies, r.poses, r.pose_scale, r.pose_shift, r.pose_fit, r.pose_scale_fitted ? "true" : "false",
           cli_json_number(r.pose_scale_cost, 5, cost, sizeof cost), r.mean_valid_fraction,
           cli_json_number(r.mean_source_psnr, 2, psnr, sizeof psnr), r.threads, r.seconds);
    if (c.diagnose) {
        char a[32], b[32], m[32];
        printf("{\"diagnosed_views\": %d, \"psnr_reprojected\": %s, \"psnr_guessed\": %s, \"psnr_moving\": %s, "
               "\"diagnosis\": \"%s/diagnose.json\"}\n",
               r.diagnosed_views, cli_json_number(r.diagnose_psnr_reprojected, 2, a, sizeof a),
               cli_json_number(r.diagnose_psnr_guessed, 2, b, sizeof b),
               cli_json_number(r.diagnose_psnr_moving, 2, m, sizeof m), c.out);
    }
    return 0;
}
