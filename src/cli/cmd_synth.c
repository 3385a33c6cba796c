/* cmd_synth.c - `prodygs synth OUT`: render the built-in sample scene as a dataset. */
#include "cli/cli.h"
#include "core/parallel.h"
#include "synth/synth.h"

#include <stdio.h>
#include <string.h>

int cmd_synth(int argc, char **argv)
{
    synth_options o;
    synth_options_default(&o);
    int seed = 1, spp = o.spp, threads = 0;
    const char *size = NULL, *layout = "dynerf";
    float fps = o.fps;
    const cli_option opts[] = {
        { "--cams", CLI_INT, &o.cams, "number of cameras on the frontal arc, 1..21 (default 10; cam00 = centre)" },
        { "--frames", CLI_INT, &o.frames, "frames per camera (default 30)" },
        { "--size", CLI_STR, &size, "image size WxH (default 160x120)" },
        { "--seed", CLI_INT, &seed, "scene seed: jitter of props, colours, textures, mono-depth noise (default 1)" },
        { "--layout", CLI_STR, &layout, "dynerf (poses_bounds.npy + camXX/images) or panoptic (train/test_meta.json + ims/)" },
        { "--spp", CLI_INT, &spp, "supersampling grid side: N gives NxN samples per pixel (default 2)" },
        { "--fps", CLI_FLOAT, &fps, "frame rate written to scene.json / videos (default 30)" },
        { "--video", CLI_FLAG, &o.video, "also write camXX.mp4 (DyNeRF layout)" },
        { "--threads", CLI_INT, &threads, "worker threads (default: all cores)" },
    };
    const cli_spec spec = { "prodygs synth", "OUT [options]",
                            "Ray-trace the built-in dynamic tabletop scene into a multi-camera dataset with ground-truth\n"
                            "depth (depth_gt/), moving-object masks (masks_dynamic/) and a simulated monocular depth of\n"
                            "cam00 (depth_mono/). World frame = cam00's camera frame.\n\n"
                            "example: prodygs synth data/sample --cams 10 --frames 30",
                            opts, (int)(sizeof opts / sizeof opts[0]), 1, 1 };
    const char *pos[1];
    int npos = 0;
    int rc = cli_parse(&spec, argc, argv, pos, &npos);
    if (rc) return rc < 0 ? 0 : rc;
    if ((rc = cli_parse_size("--size", size, &o.width, &o.height))) return rc;
    if (o.width < 8 || o.height < 8 || o.width > 4096 || o.height > 4096) /* a render needs both sides */
        return cli_usage_error("synth: --size '%s' needs both sides in 8..4096", size);
    if (strcmp(layout, "dynerf") == 0) o.layout = SYNTH_LAYOUT_DYNERF;
    else if (strcmp(layout, "panoptic") == 0) o.layout = SYNTH_LAYOUT_PANOPTIC;
    else return cli_usage_error("synth: --layout must be dynerf or panoptic, got '%s'", layout);
    if (seed < 0) return cli_usage_error("synth: --seed must be >= 0");
    o.seed = (uint64_t)seed;
    o.spp = spp;
    o.fps = fps;
    if (threads < 0) return cli_usage_error("synth: --threads must be >= 0 (got %d)", threads);
    if (threads > 0) pg_set_threads(threads);
    cli_install_progress();
    double t0 = pg_time_seconds();
    pg_status st = synth_write_dataset(pos[0], &o);
    if (st) return cli_fail(st);
    fprintf(stderr, "prodygs: synth: wrote %s (%d cams x %d frames, %dx%d, %d spp) in %.1f s\n", pos[0], o.cams, o.frames,
            o.width, o.height, o.spp * o.spp, pg_time_seconds() - t0);
    return 0;
}
