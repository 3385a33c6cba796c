/* cmd_run.c - `prodygs run INPUT --depth PATH --out DIR`: the whole pipeline on a user's video
 * (prepare -> proxies -> train -> novel-view videos) through pg_pipeline_run. */
#include "cli/pipeline_cli.h"

int cmd_run(int argc, char **argv)
{
    pg_pipeline_config c;
    pipeline_cli_text t;
    cli_option options[41];
    int n = pipeline_cli_options(&c, &t, options, 40);
    const char *render_size = NULL;
    options[n++] = (cli_option){ "--render-size", CLI_STR, &render_size,
                                 "size of the novel-view videos, WxH (default: the working size; e.g. the input's "
                                 "1920x1080 costs ~75 s a video on 2 cores for a 300-frame clip)" };
    const cli_spec spec = { "prodygs run", "INPUT (--depth PATH | --depth-model FILE) --out DIR [options]",
                            "The whole pipeline on a static-camera video (file, frame folder, or a dataset with\n"
                            "--train-cam): depth preparation -> proxy views -> 4D training -> novel-view videos\n"
                            "(DIR/renders: fixed.mp4 with fixed_compare.mp4, orbit.mp4, spiral.mp4, *_depth.mp4)\n"
                            "and DIR/report.md. With --test-cams the held-out cameras are scored too (as eval).\n"
                            "Rerunning continues from the last finished stage; changed settings or input content\n"
                            "rerun the stages they affect.\n\n"
                            "example: prodygs run clip.mp4 --depth depth.npy --out out",
                            options, n, 1, 1 };
    int rc = pipeline_cli_parse(&spec, argc, argv, &c, &t);
    if (rc) return rc < 0 ? 0 : rc;
    if ((rc = cli_parse_size("--render-size", render_size, &c.render_width, &c.render_height))) return rc;
    c.evaluate = c.test_cameras != NULL;
    c.render_videos = 1;
    return pipeline_cli_run(&c);
}
