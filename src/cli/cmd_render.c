/* cmd_render.c - `prodygs render MODEL --out DIR [--path ...]`: videos of a trained model. */
#include "cli/cli.h"
#include "core/parallel.h"
#include "render/render_video.h"
#include "render/scene_cameras.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int cmd_render(int argc, char **argv)
{
    const char *out = NULL, *path_name = "fixed", *cameras = NULL, *dataset_cam = NULL;
    int steps = 0, no_depth = 0, frames_png = 0, threads = 0;
    float angle = 15.0f, time = 0.5f, fps = 0, yaw = 10.0f, pitch = 5.0f;
    const cli_option options[] = {
        { "--out", CLI_STR, &out, "output directory (required)" },
        { "--path", CLI_STR, &path_name, "fixed (default), orbit (frozen time), spiral, or dataset-cam" },
        { "--camera", CLI_STR, &dataset_cam, "camera name for --path dataset-cam (e.g. cam05)" },
        { "--steps", CLI_INT, &steps, "frames of an orbit/spiral/fixed path (default: the video's frame count)" },
        { "--angle", CLI_FLOAT, &angle, "how far orbit/spiral swing from the real view, degrees (default 15)" },
        { "--yaw", CLI_FLOAT, &yaw, "fixed path: sideways angle of the novel view, degrees (default 10)" },
        { "--pitch", CLI_FLOAT, &pitch, "fixed path: upward angle of the novel view, degrees (default 5)" },
        { "--time", CLI_FLOAT, &time, "frozen time of the orbit in [0,1] (default 0.5)" },
        { "--fps", CLI_FLOAT, &fps, "video frame rate (default: the input's)" },
        { "--cameras", CLI_STR, &cameras, "trainset.json with the cameras (default: found next to MODEL)" },
        { "--no-depth", CLI_FLAG, &no_depth, "skip the depth video" },
        { "--frames", CLI_FLAG, &frames_png, "also write every frame as PNG" },
        { "--threads", CLI_INT, &threads, "worker threads (default: all cores)" },
    };
    const cli_spec spec = { "prodygs render", "MODEL --out DIR [options]",
                            "Renders a trained model along a camera path: PNG frames and MP4 videos\n"
                            "(colour, depth). fixed = the video from one novel viewpoint; orbit = bullet time;\n"
                            "spiral = moving camera while time runs; dataset-cam = a dataset camera's view.",
                            options, (int)(sizeof options / sizeof options[0]), 1, 1 };
    const char *pos[1];
    int rc = cli_parse(&spec, argc, argv, pos, NULL);
    if (rc) return rc < 0 ? 0 : rc;
    if (!out) return cli_usage_error("render: --out DIR is required");

    render_video_options vo = {0};
    int use_dataset_cam = strcmp(path_name, "dataset-cam") == 0;
    if (!use_dataset_cam) {
        pg_status st = render_path_parse(path_name, &vo.path.kind);
        if (st) return cli_fail(st);
    } else if (!dataset_cam) {
        return cli_usage_error("render: --path dataset-cam needs --camera NAME");
    }
    if (time < 0 || time > 1) return cli_usage_error("render: --time must be in [0, 1], got %g", time);
    if (steps < 0 || steps > 100000) return cli_usage_error("render: --steps %d is out of range", steps);
    if (fps < 0 || fps > 1000) return cli_usage_error("render: --fps must be in (0, 1000], got %g", fps);
    if (angle < 0 || angle > 89) return cli_usage_error("render: --angle must be in [0, 89] degrees, got %g", angle);
    if (yaw < -89 || yaw > 89 || pitch < -89 || pitch > 89)
        return cli_usage_error("render: --yaw/--pitch must be in [-89, 89] degrees, got %g/%g", yaw, pitch);
    if (threads < 0) return cli_usage_error("render: --threads must be >= 0, got %d", threads);

    if (threads > 0) pg_set_threads(threads);

    scene_cameras *sc = pg_malloc(sizeof *sc, "cameras");
    if (!sc) return cli_fail(PG_ERR_NOMEM);
    render_model *rm = NULL;
    pg_status st = scene_cameras_for_model(pos[0], cameras, sc);
    if (st == PG_OK) st = render_model_open(pos[0], &rm);
    if (st == PG_OK) {
        int frames = render_model_frames(rm);
        vo.path.steps = steps > 0 ? steps : (frames > 1 ? frames : 60);
        vo.path.max_angle_deg = angle;
        vo.path.time = time;
        vo.path.fixed_yaw_deg = yaw;
        vo.path.fixed_pitch_deg = pitch;
        vo.write_depth = !no_depth;
        vo.write_frames = frames_png;
        vo.fps = fps > 0 ? fps : sc->fps;
        const char *name = path_name;
        if (use_dataset_cam) {
            int k = scene_cameras_find(sc, dataset_cam);
            if (k < 0) {
                char names[1024] = "";
                for (int c = 0; c < sc->count && strlen(names) + 40 < sizeof names; c++)
                    snprintf(names + strlen(names), sizeof names - strlen(names), "%s%s", c ? ", " : "", sc->names[c]);
                st = pg_fail(PG_ERR_ARG, "render: no camera named '%s' in the model (cameras: %s)", dataset_cam, names);
            }
            vo.use_camera = 1;
            if (k >= 0) vo.camera = sc->cams[k];
            name = dataset_cam;
        }
        render_video_report rep;
        if (st == PG_OK) st = render_video_write(rm, &sc->cams[sc->real], sc->center, &vo, out, name, &rep);
        if (st == PG_OK) {
            printf("{\"path\": \"%s\", \"frames\": %d, \"seconds\": %.2f, \"video\": \"%s\"}\n", name, rep.frames,
                   rep.seconds, rep.fallback_png ? "png-sequence" : "mp4");
            if (rep.fallback_png) fprintf(stderr, "prodygs: warning: no H.264/MPEG-4 encoder; wrote PNG sequences instead of MP4\n");
        }
    }
    render_model_close(rm);
    free(sc);
    return st ? cli_fail(st) : 0;
}
