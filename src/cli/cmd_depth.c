/* cmd_depth.c - `prodygs depth INPUT --model FILE --out depth.npy`: a depth network (TFLite or
 * ONNX) on every frame, through pg_depth_run; prints one line. */
#include "cli/cli.h"
#include "cli/pipeline_cli.h"

#include <stdio.h>

int cmd_depth(int argc, char **argv)
{
    pg_depth_config c;
    pg_depth_defaults(&c);
    const char *out_size = NULL;
    const cli_option options[] = {
        { "--model", CLI_STR, &c.model, "depth network: .tflite or .onnx (default: the built-in FastDepth); MODEL.json beside it is read" },
        { "--out", CLI_STR, &c.out, "output .npy (F,H,W) depth, float16 when it fits, else float32 (required)" },
        { "--out-size", CLI_STR, &out_size, "output WxH (default: the network's resolution at the video's aspect; 0 for one side keeps the aspect)" },
        { "--kind", CLI_STR, &c.kind, "the model's raw output: depth or disparity (default: MODEL.json, else by format)" },
        { "--size", CLI_INT, &c.size, "inference size, longer side: models with a dynamic input (a fixed one must match)" },
        { "--frames", CLI_INT, &c.frames, "only the first N frames (default: all)" },
        { "--train-cam", CLI_STR, &c.train_camera, "dataset camera, name or index (default: the first)" },
        { "--threads", CLI_INT, &c.threads, "worker threads (default: all cores)" },
    };
    const cli_spec spec = { "prodygs depth", "INPUT [--model FILE] --out depth.npy [options]",
                            "Runs a monocular depth network on every frame: each frame is resized to the model's\n"
                            "input (decoded straight to that size) and the output written at the network's resolution\n"
                            "fitted to the video's aspect, or --out-size. Writes depth (larger = farther; a disparity\n"
                            "model's output is inverted) in the model's relative units, and beside it a .json of the same\n"
                            "name (model, content hashes, kind). Finished frames are cached in OUT.cache/, so an\n"
                            "interrupted run resumes.\n\n"
                            "example: prodygs depth clip.mp4 --model pydnet++_matterport.tflite --out depth.npy",
                            options, (int)(sizeof options / sizeof options[0]), 1, 1 };
    int rc = cli_parse(&spec, argc, argv, &c.input, NULL);
    if (rc) return rc < 0 ? 0 : rc;
    if (out_size && (rc = cli_parse_size("--out-size", out_size, &c.out_width, &c.out_height))) return rc;
    if (!c.out) return cli_usage_error("depth: --out FILE.npy is required");
    char default_model[4096];
    if (!c.model) {
        if ((rc = pipeline_cli_default_depth("--model", default_model, sizeof default_model))) return rc;
        c.model = default_model;
    }
    pg_depth_report r;
    pg_status st = pg_depth_run(&c, &r);
    if (st) return cli_fail(st);
    if (r.skipped)
        printf("depth: %s is already current for this model and input; nothing to do\n", c.out);
    else
        printf("depth: %s (%dx%d input, output %s) on %s: %d frames %dx%d (%d computed, %d cached), %.0f ms/frame, %.1f s, "
               "%d threads; wrote %s\n",
               r.model_name, r.model_width, r.model_height, r.kind, r.train_camera, r.frames, r.width, r.height, r.computed,
               r.reused, r.ms_per_frame, r.seconds, r.threads, c.out);
    return 0;
}
