/* cmd_render.c - `prodygs render`: options -> pg_render_config -> pg_render_run -> JSON line. */
#include "cli/cli.h"

#include <stdio.h>
#include <string.h>

int cmd_render(int argc, char **argv)
{
    pg_render_config c;
    pg_render_defaults(&c);
    int no_depth = 0;
    const char *size_text = NULL;
    const cli_option options[] = {
        { "--out", CLI_STR, &c.out, "output directory (required)" },
        { "--path", CLI_STR, &c.path, "fixed (default), orbit (frozen time), spiral, or dataset-cam" },
        { "--camera", CLI_STR, &c.camera, "camera for --path dataset-cam: name (e.g. cam05) or index in the model's cameras" },
        { "--steps", CLI_INT, &c.steps, "frames of the path (default: the video's frame count)" },
        { "--angle", CLI_FLOAT, &c.angle, "how far orbit/spiral swing from the real view, degrees (default 15)" },
        { "--yaw", CLI_FLOAT, &c.yaw, "fixed path: sideways angle of the novel view, degrees (default 10)" },
        { "--pitch", CLI_FLOAT, &c.pitch, "fixed path: upward angle of the novel view, degrees (default 5)" },
        { "--time", CLI_FLOAT, &c.time, "frozen time of the orbit in [0,1] (default 0.5)" },
        { "--fps", CLI_FLOAT, &c.fps, "video frame rate (default: the input's)" },
        { "--no-depth", CLI_FLAG, &no_depth, "skip the depth video" },
        { "--png", CLI_FLAG, &c.write_frames, "also write every frame as PNG" },
        { "--camera-path", CLI_STR, &c.camera_path, "render a camera_path.json (nerfstudio's, docs/FORMATS.md): one frame per entry" },
        { "--size", CLI_STR, &size_text, "output WxH (default: the camera's; 0 for one side keeps the aspect)" },
        { "--threads", CLI_INT, &c.threads, "worker threads (default: all cores)" },
    };
    const cli_spec spec = { "prodygs render", "MODEL --out DIR [options]",
                            "Renders a trained model along a camera path: MP4 videos (colour, depth) and optional\n"
                            "PNG frames. fixed = the video from one novel viewpoint; orbit = bullet time; spiral =\n"
                            "moving camera while time runs; dataset-cam = a dataset camera's view. The cameras come\n"
                            "from MODEL/cameras.json, written by training.\n\n"
                            "example: prodygs render out/model --out out/renders --path dataset-cam --camera cam05\n"
                            "         prodygs render out/model --out out/shot --camera-path shot.json --size 640x480",
                            options, (int)(sizeof options / sizeof options[0]), 1, 1 };
    int rc = cli_parse(&spec, argc, argv, &c.model, NULL);
    if (rc) return rc < 0 ? 0 : rc;
    if (!c.out) return cli_usage_error("render: --out DIR is required");
    if (c.threads < 0) return cli_usage_error("render: --threads must be >= 0, got %d", c.threads);
    c.write_depth = !no_depth;
    if ((rc = cli_parse_size("render: --size", size_text, &c.width, &c.height))) return rc;

    pg_render_report r;
    pg_status st = pg_render_run(&c, &r);
    if (st) return cli_fail(st);
    const char *name = c.camera_path ? "camera_path" : strcmp(c.path, "dataset-cam") == 0 ? c.camera : c.path;
    printf("{\"path\": \"%s\", \"frames\": %d, \"seconds\": %.2f, \"video\": \"%s\"}\n", name, r.frames, r.seconds,
           r.fallback_png ? "png-sequence" : "mp4");
    if (r.fallback_png) fprintf(stderr, "prodygs: warning: no H.264/MPEG-4 encoder; wrote PNG sequences instead of MP4\n");
    return 0;
}
