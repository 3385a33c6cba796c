/* cmd_prepare.c - `prodygs prepare`: options -> pg_prepare_config -> pg_prepare_run -> one line. */
#include "cli/cli.h"
#include "cli/pipeline_cli.h"

#include <math.h>
#include <stdio.h>

int cmd_prepare(int argc, char **argv)
{
    pg_prepare_config c;
    pg_prepare_defaults(&c);
    const char *size = NULL, *kind = NULL;
    float scale = NAN; /* NAN: not given (the parser refuses NaN values) */
    int no_refine = 0, no_align = 0, no_fuse = 0, no_planes = 0, no_ground = 0, no_movers_front = 0, no_flow_vis = 0;
    const cli_option options[] = {
        { "--depth", CLI_STR, &c.depth, "per-frame depth: (F,H,W) .npy or a folder of .npy/.pfm/.png/.exr (or --depth-model)" },
        { "--depth-model", CLI_STR, &c.depth_model, "instead of --depth: a depth network (.tflite/.onnx) run first into DIR/depth.npy (default: the built-in FastDepth)" },
        { "--out", CLI_STR, &c.out, "output directory (required)" },
        { "--depth-kind", CLI_STR, &kind, "depth (z along the optical axis, default) or disparity (1/depth)" },
        { "--depth-scale", CLI_FLOAT, &scale, "multiply raw depth values by S first (default 1)" },
        { "--refine", CLI_STR, &c.refine, "refiner: edge-snap (default), bilateral or none" },
        { "--no-refine", CLI_FLAG, &no_refine, "skip the edge-aware refinement (= --refine none)" },
        { "--no-align", CLI_FLAG, &no_align, "skip the per-frame scale/shift alignment (alpha=1, beta=0)" },
        { "--no-fuse", CLI_FLAG, &no_fuse, "keep per-frame depth on static pixels (default: their temporal median)" },
        { "--no-planes", CLI_FLAG, &no_planes, "do not snap static depth onto the scene's dominant planes (default: snap)" },
        { "--no-ground", CLI_FLAG, &no_ground, "do not place the floor and the wall by the vertical vanishing point (default: place)" },
        { "--no-movers-front", CLI_FLAG, &no_movers_front, "leave moving blobs behind the still scene they cover where the depth put them (default: bring them in front)" },
        { "--fov", CLI_FLOAT, &c.fov, "single video: horizontal field of view in degrees (default 60; datasets use their own)" },
        { "--frames", CLI_INT, &c.frames, "use only the first N frames (default: all)" },
        { "--size", CLI_STR, &size, "resize frames and depth to WxH (0 for one side keeps the aspect)" },
        { "--train-cam", CLI_STR, &c.train_camera, "dataset camera, name or index (default: the first)" },
        { "--threads", CLI_INT, &c.threads, "worker threads (default: all cores)" },
        { "--no-flow-vis", CLI_FLAG, &no_flow_vis, "do not keep flow fields for vis/flow_*.png (automatic above 1 GiB)" },
    };
    const cli_spec spec = { "prodygs prepare", "INPUT [--depth PATH | --depth-model FILE] --out DIR [options]",
                            "Refines per-frame depth at colour edges, finds static pixels and aligns the depth\n"
                            "scale over time. Writes DIR/depth_aligned.npy, static_masks.npy, prepare.json, vis/.\n\n"
                            "example: prodygs prepare clip.mp4 --depth depth.npy --out out/prepare",
                            options, (int)(sizeof options / sizeof options[0]), 1, 1 };
    int rc = cli_parse(&spec, argc, argv, &c.input, NULL);
    if (rc) return rc < 0 ? 0 : rc;
    if (!c.out) return cli_usage_error("prepare: --out DIR is required");
    if (c.depth && c.depth_model) return cli_usage_error("prepare: give --depth or --depth-model, not both");
    if (!c.depth && (kind || !isnan(scale)))
        return cli_usage_error("prepare: --depth-kind and --depth-scale apply to --depth; a model's output kind comes from "
                               "MODEL.json (\"output\": \"depth\" or \"disparity\")");
    char default_model[4096];
    if (!c.depth && !c.depth_model) {
        if ((rc = pipeline_cli_default_depth("--depth/--depth-model", default_model, sizeof default_model))) return rc;
        c.depth_model = default_model;
    }
    if (kind) c.depth_kind = kind;
    if (!isnan(scale)) c.depth_scale = scale;
    if ((rc = cli_parse_size("--size", size, &c.width, &c.height))) return rc;
    if (no_refine) c.refine = "none";
    c.align = !no_align;
    c.fuse = !no_fuse;
    c.planes = !no_planes;
    c.ground = !no_ground;
    c.movers_front = !no_movers_front;
    c.keep_flow_vis = !no_flow_vis;

    pg_prepare_report r;
    pg_status st = pg_prepare_run(&c, &r);
    if (st) return cli_fail(st);
    printf("prepare: training camera %s; %d frames %dx%d, reference frame %d, mean residual vs reference %.4f -> "
           "%.4f, %d fallback frame(s), %.1f s, %d threads; wrote %s\n",
           r.train_camera, r.frames, r.width, r.height, r.reference, r.residual_before, r.residual_after,
           r.fallback_frames, r.seconds, r.threads, c.out);
    return 0;
}
