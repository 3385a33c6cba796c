/* cmd_demo.c - `prodygs demo [--out DIR]`: builds the sample scene, runs the whole pipeline with
 * the fast preset on its centre camera and simulated monocular depth, evaluates on two held-out
 * cameras and renders the novel-view videos. The README's first command. */
#include "cli/pipeline_cli.h"
#include "core/fileutil.h"
#include "synth/synth.h"

#include <stdio.h>

int cmd_demo(int argc, char **argv)
{
    const char *out = "demo-out";
    int frames = 0, iters = 0, threads = 0;
    const cli_option options[] = {
        { "--out", CLI_STR, &out, "output directory (default demo-out)" },
        { "--frames", CLI_INT, &frames, "frames of the sample scene (default 20)" },
        { "--iters", CLI_INT, &iters, "training iterations (default: the fast preset's)" },
        { "--threads", CLI_INT, &threads, "worker threads (default: all cores)" },
    };
    const cli_spec spec = { "prodygs demo", "[--out DIR]",
                            "Renders the built-in sample scene (10 cameras, moving objects), then runs the\n"
                            "pipeline on cam00 with its simulated monocular depth (fast preset), scores the\n"
                            "held-out cameras cam05/cam06 and renders novel-view videos. Results:\n"
                            "DIR/report.md, DIR/metrics.json, DIR/renders/*.mp4.\n\n"
                            "example: prodygs demo --out demo-out",
                            options, (int)(sizeof options / sizeof options[0]), 0, 0 };
    int rc = cli_parse(&spec, argc, argv, NULL, NULL);
    if (rc) return rc < 0 ? 0 : rc;
    if (frames < 0 || frames > 1000) return cli_usage_error("demo: --frames %d is out of range", frames);
    /* checked here as well as in the pipeline: before minutes of rendering the scene */
    if (iters < 0) return cli_usage_error("demo: --iters must be >= 1 (got %d)", iters);
    if (threads < 0 || threads > 256) return cli_usage_error("demo: --threads must be in 1..256 (got %d)", threads);

    char scene_dir[4096], depth[4200], marker[4200];
    snprintf(scene_dir, sizeof scene_dir, "%s/scene", out);
    snprintf(depth, sizeof depth, "%s/depth_mono/cam00.npy", scene_dir);
    snprintf(marker, sizeof marker, "%s/scene.json", scene_dir);
    pg_status st = pg_mkdir_p(out);
    if (st == PG_OK && !pg_path_exists(marker)) { /* the dataset writer finishes with scene.json */
        synth_options so;
        synth_options_default(&so);
        so.frames = frames > 0 ? frames : 20; /* keeps the demo to a few minutes on 2 cores */
        fprintf(stderr, "prodygs: demo: rendering the sample scene into %s\n", scene_dir);
        st = synth_write_dataset(scene_dir, &so);
    }
    if (st) return cli_fail(st);

    pg_pipeline_config c;
    pg_pipeline_defaults(&c);
    c.input = scene_dir;
    c.depth = depth;
    c.out = out;
    c.test_cameras = "cam05,cam06";
    c.iters = iters;
    c.threads = threads;
    c.evaluate = 1;
    c.render_videos = 1;
    c.command = "prodygs demo";
    rc = pipeline_cli_run(&c);
    if (rc == 0) fprintf(stderr, "prodygs: demo done: see %s/report.md and %s/renders/\n", out, out);
    return rc;
}
