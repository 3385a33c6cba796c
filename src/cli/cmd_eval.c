/* cmd_eval.c - `prodygs eval DATASET`: the DyNeRF protocol end to end through pg_pipeline_run:
 * train on one real camera plus proxies at the other cameras' poses (never the test cameras),
 * then score every frame of the held-out cameras. */
#include "cli/pipeline_cli.h"

int cmd_eval(int argc, char **argv)
{
    pg_pipeline_config c;
    pipeline_cli_text t;
    cli_option options[40];
    int n = pipeline_cli_options(&c, &t, options, 40);
    const cli_spec spec = { "prodygs eval", "DATASET (--depth PATH | --depth-model FILE) --out DIR [options]",
                            "DyNeRF protocol: trains on one real camera (--train-cam, default the first) plus\n"
                            "proxies at the other cameras' poses (never the test cameras, default cam05,cam06),\n"
                            "then scores every frame of the test cameras. Writes DIR/metrics.json, DIR/report.md\n"
                            "and side-by-side PNGs (truth | render | error). Rerunning continues from the last\n"
                            "finished stage.\n\n"
                            "example: prodygs eval data/coffee_martini --depth depth/cam00.npy --out out --test-cams cam05,cam06",
                            options, n, 1, 1 };
    int rc = pipeline_cli_parse(&spec, argc, argv, &c, &t);
    if (rc) return rc < 0 ? 0 : rc;
    if (!c.test_cameras) c.test_cameras = "cam05,cam06";
    c.evaluate = 1;
    return pipeline_cli_run(&c);
}
