/* pipeline_cli.c - options and output shared by `run`, `eval` and `demo` (see pipeline_cli.h). */
#include "cli/pipeline_cli.h"

#include "depth/depth_default.h"

#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

int pipeline_cli_options(pg_pipeline_config *c, pipeline_cli_text *t, cli_option *opts, int max)
{
    pg_pipeline_defaults(c);
    /* unset until given: a given --pad -1 or --iters 0 is refused, not read as "the default" */
    c->pad = NAN;
    c->iters = INT_MIN;
    memset(t, 0, sizeof *t);
    const cli_option shared[] = {
        { "--depth", CLI_STR, &c->depth, "per-frame depth of the training camera: .npy (F,H,W) or a folder (or --depth-model)" },
        { "--depth-model", CLI_STR, &c->depth_model, "instead of --depth: a depth network (.tflite/.onnx) run first into DIR/depth/ (default: the built-in FastDepth)" },
        { "--out", CLI_STR, &c->out, "output directory (required)" },
        { "--preset", CLI_STR, &c->preset, "fast (default: 1,500 steps, 8 proxies, at 320 px: ~10 min and ~1.2 GiB for 10 s of 1080p on 2 cores), quality (3,000 steps, 18 proxies: ~3x the time, the real view's movers ~4 dB sharper, novel views the same) or full (fast, then the still scene and the movers at the input's size up to 1920x1080, and videos at that size: sharp at full screen)" },
        { "--train-cam", CLI_STR, &c->train_camera, "dataset camera that is the real view: name or index (default: the first)" },
        { "--test-cams", CLI_STR, &c->test_cameras, "held-out dataset cameras: names or indices, e.g. cam05,cam06" },
        { "--proxies", CLI_STR, &t->proxies, "proxy cameras: a count or all (default: the preset's; all with --test-cams)" },
        { "--poses", CLI_STR, &c->poses, "proxy poses: hemisphere or dataset (default: dataset with --test-cams)" },
        { "--max-angle", CLI_FLOAT, &c->max_angle, "hemisphere cap angle in degrees (default 20)" },
        { "--fov", CLI_FLOAT, &c->fov, "single video: horizontal field of view in degrees (default 60)" },
        { "--pad", CLI_FLOAT, &c->pad, "proxies: outpainted margin, fraction of the larger side (0.3; 0 = none)" },
        { "--proxy-render", CLI_STR, &c->proxy_render, "proxy renderer: mesh (default) or splat (the paper's per-frame Gaussians)" },
        { "--no-refine", CLI_FLAG, &t->no_refine, "skip edge-aware depth refinement (ablation)" },
        { "--no-align", CLI_FLAG, &t->no_align, "skip temporal scale/shift alignment (ablation)" },
        { "--no-fuse", CLI_FLAG, &t->no_fuse, "keep per-frame depth on static pixels (no temporal median; ablation)" },
        { "--no-planes", CLI_FLAG, &t->no_planes, "do not snap static depth onto the scene's dominant planes (ablation)" },
        { "--no-ground", CLI_FLAG, &t->no_ground, "do not place the floor and the wall by the vertical vanishing point (ablation)" },
        { "--no-movers-front", CLI_FLAG, &t->no_movers_front, "leave moving blobs where the depth put them, even behind the still scene they cover (ablation)" },
        { "--depth-kind", CLI_STR, &c->depth_kind, "depth (default) or disparity" },
        { "--depth-scale", CLI_FLOAT, &c->depth_scale, "multiply raw depth by S" },
        { "--frames", CLI_INT, &c->frames, "use only the first N frames (default: all)" },
        { "--size", CLI_STR, &t->size, "resize to WxH (default: the preset's longest side)" },
        { "--iters", CLI_INT, &c->iters, "training iterations (default: the preset's 1500 or 3000, raised for clips over ~90 or ~500 frames, at most 8/3 of it)" },
        { "--deform-width", CLI_INT, &c->deform_width, "deformation MLP width (default: the trainer's)" },
        { "--deform-head-width", CLI_INT, &c->deform_head_width, "hidden width of each deformation head (default 32)" },
        { "--deform-time-coarsen", CLI_INT, &c->deform_time_coarsen, "coarse HexPlane scale: one time texel per 2^K of the fine scale's (default 2; 0 = same)" },
        { "--deform-time-warmup", CLI_FLOAT, &c->deform_time_warmup, "share of the fine stage trained on a quarter of the HexPlane time rows, then refined (default 0.4; 0 = off)" },
        { "--densify-movable", CLI_FLOAT, &c->densify_movable, "the movable Gaussians' densification threshold, a multiple of the still ones' (default: 3 for a long clip, whose time rows get < 40 fits each; else 1)" },
        { "--densify-until", CLI_INT, &c->densify_until, "no densification from this step on (default: 70 % of --iters, or of the preset's steps when they are raised for a long clip)" },
        { "--proxy-downscale", CLI_INT, &c->proxy_downscale, "proxies train at 1/S of the working size per side: 1 or 2 (default 2; the real view keeps every pixel)" },
        { "--motion-crops", CLI_INT, &c->motion_crops, "extra renders per fine step over the box around the movers, the real view and a proxy in turn (default 2; 0 = off)" },
        { "--views-per-step", CLI_INT, &c->views_per_step, "views trained per deformation: the real view + proxies of one time (default 2)" },
        { "--proxy-moving-weight", CLI_FLOAT, &c->proxy_moving_weight, "loss weight of proxy pixels that show the real view's movers (default 1)" },
        { "--real-weight", CLI_FLOAT, &c->real_weight, "share of each step's loss on the real view when proxies are in it (default 0.75)" },
        { "--sh-degree", CLI_INT, &c->sh_degree, "largest spherical-harmonics degree of the colours, 0..3 (default: 0 with one real camera)" },
        { "--pose-scale", CLI_FLOAT, &c->pose_scale, "depth-to-pose scale instead of fitting it (dataset poses)" },
        { "--no-pose-shift", CLI_FLAG, &t->no_pose_shift, "dataset poses: fit the depth-to-pose scale alone, no disparity shift (ablation)" },
        { "--threads", CLI_INT, &c->threads, "worker threads for every stage (default: all cores)" },
        { "--seed", CLI_INT, &c->seed, "random seed (default 1)" },
    };
    int n = (int)(sizeof shared / sizeof shared[0]);
    if (n > max) n = max;
    memcpy(opts, shared, (size_t)n * sizeof *opts);
    return n;
}

int pipeline_cli_default_depth(const char *missing, char *path, size_t size)
{
    pg_status st = depth_default_model(path, size);
    if (st) return cli_fail(st);
    fprintf(stderr, "depth: no %s given, %s: %s\n", missing, DEPTH_DEFAULT_NOTICE, path);
    return 0;
}

int pipeline_cli_parse(const cli_spec *spec, int argc, char **argv, pg_pipeline_config *c, pipeline_cli_text *t)
{
    int rc = cli_parse(spec, argc, argv, &c->input, NULL);
    if (rc) return rc;
    const char *verb = strchr(spec->command, ' ') ? strchr(spec->command, ' ') + 1 : spec->command;
    if (!c->out) return cli_usage_error("%s: --out is required", verb);
    if (isnan(c->pad)) c->pad = -1; /* the proxies' default */
    else if (!(c->pad >= 0 && c->pad <= 1)) return cli_usage_error("%s: --pad must be in [0, 1] (got %g)", verb, c->pad);
    if (c->iters == INT_MIN) c->iters = 0; /* the preset's */
    else if (c->iters < 1) return cli_usage_error("%s: --iters must be >= 1 (got %d)", verb, c->iters);
    if (c->depth && c->depth_model) return cli_usage_error("%s: give --depth or --depth-model, not both", verb);
    if (!c->depth && (c->depth_kind || c->depth_scale))
        return cli_usage_error("%s: --depth-kind and --depth-scale apply to --depth; a model's output kind comes from "
                               "MODEL.json (\"output\": \"depth\" or \"disparity\")", verb);
    if (!c->depth && !c->depth_model) {
        if ((rc = pipeline_cli_default_depth("--depth/--depth-model", t->depth_model, sizeof t->depth_model))) return rc;
        c->depth_model = t->depth_model;
    }
    if ((rc = cli_parse_size("--size", t->size, &c->width, &c->height))) return rc;
    if ((rc = cli_parse_count_or_all("--proxies", t->proxies, &c->proxies))) return rc;
    c->refine = !t->no_refine;
    c->align = !t->no_align;
    c->fuse = !t->no_fuse;
    c->planes = !t->no_planes;
    c->ground = !t->no_ground;
    c->movers_front = !t->no_movers_front;
    c->pose_shift = !t->no_pose_shift;
    size_t len = (size_t)snprintf(t->command, sizeof t->command, "prodygs");
    for (int i = 0; i < argc && len < sizeof t->command; i++)
        len += (size_t)snprintf(t->command + len, sizeof t->command - len, " %s", argv[i]);
    c->command = t->command;
    return 0;
}

static void add_score(char *buf, size_t size, const char *name, double v)
{
    size_t n = strlen(buf);
    if (isfinite(v)) snprintf(buf + n, size - n, ", \"%s\": %.3f", name, v);
    else snprintf(buf + n, size - n, ", \"%s\": null", name);
}

/* The resolved cameras, printed before the long stages (and flushed: a redirected log keeps
 * them on Ctrl-C). */
static void print_plan(const pg_pipeline_report *plan, void *user)
{
    (void)user;
    printf("training camera %s%s%s\n", plan->train_camera, plan->test_cameras[0] ? "; test cameras " : "",
           plan->test_cameras);
    fflush(stdout);
}

int pipeline_cli_run(pg_pipeline_config *c)
{
    pg_pipeline_report r;
    c->on_plan = print_plan;
    pg_status st = pg_pipeline_run(c, &r);
    if (st) {
        if (pg_status_exit_code(st) != 2 && r.started) /* work began: the next run continues it */
            fprintf(stderr, "prodygs: %s\nprodygs: rerun the same command to continue from the last finished stage\n",
                    pg_last_error());
        else
            fprintf(stderr, "prodygs: %s\n", pg_last_error());
        return pg_status_exit_code(st);
    }
    char line[2048];
    snprintf(line, sizeof line, "{\"out\": \"%s\", \"train_camera\": \"%s\", \"threads\": %d, \"seconds\": %.1f", c->out,
             r.train_camera, r.threads, r.seconds_total);
    if (c->evaluate) {
        add_score(line, sizeof line, "psnr", r.evaluation.psnr);
        add_score(line, sizeof line, "ssim", r.evaluation.ssim);
        add_score(line, sizeof line, "psnr_moving", r.evaluation.psnr_moving);
        add_score(line, sizeof line, "train_psnr_moving", r.evaluation.train_psnr_moving);
        add_score(line, sizeof line, "train_psnr_static", r.evaluation.train_psnr_static);
        add_score(line, sizeof line, "flat_psnr", r.evaluation.flat_psnr);
        add_score(line, sizeof line, "as_is_psnr", r.evaluation.as_is_psnr);
        add_score(line, sizeof line, "warp_psnr", r.evaluation.warp_psnr);
        add_score(line, sizeof line, "warp_psnr_moving", r.evaluation.warp_psnr_moving);
        size_t n = strlen(line);
        snprintf(line + n, sizeof line - n, ", \"frames\": %d, \"metrics\": \"%s/metrics.json\"", r.evaluation.frames, c->out);
    } else {
        add_score(line, sizeof line, "train_psnr", r.train.train_psnr);
        add_score(line, sizeof line, "train_psnr_moving", r.train.train_psnr_moving);
        add_score(line, sizeof line, "train_psnr_static", r.train.train_psnr_static);
        if (r.train.full_width > 0) {
            size_t m = strlen(line);
            snprintf(line + m, sizeof line - m, ", \"full_size\": \"%dx%d\"", r.train.full_width, r.train.full_height);
            add_score(line, sizeof line, "full_psnr", r.train.full_psnr);
            add_score(line, sizeof line, "full_psnr_moving", r.train.full_psnr_moving);
            add_score(line, sizeof line, "full_psnr_static", r.train.full_psnr_static);
        }
        size_t n = strlen(line);
        snprintf(line + n, sizeof line - n, ", \"gaussians\": %d, \"report\": \"%s/report.md\"", r.train.gaussians, c->out);
    }
    printf("%s, \"peak_rss_mib\": %.1f, \"disk_mib\": %.1f}\n", line, r.peak_rss_kb / 1024.0, r.disk_mib);
    fflush(stdout);
    return 0;
}
