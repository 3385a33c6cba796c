/* cmd_eval.c - `prodygs eval DATASET`: the DyNeRF protocol of the paper, end to end.
 * Train on one real camera plus proxies at the other cameras' poses (never the test
 * cameras), then score every frame of the held-out cameras. */
#include "cli/cli.h"
#include "cli/pipeline.h"
#include "core/fileutil.h"
#include "core/parallel.h"
#include "eval/protocol.h"
#include "eval/report.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Scores the model in OUT/model against DATASET; writes metrics.json, report.md, side_by_side/. */
int pipeline_evaluate(const pipeline_options *o, cJSON *seconds)
{
    char prepare_dir[4096], proxies_dir[4096], model_dir[4096], sbs[4200], path[4200];
    pipeline_paths(o, prepare_dir, proxies_dir, model_dir, sizeof prepare_dir);
    snprintf(sbs, sizeof sbs, "%s/side_by_side", o->out);
    eval_results r = {0};
    double t0 = pg_time_seconds();
    pg_status st = eval_protocol_run(o->input, model_dir, sbs, &r);
    cJSON_AddNumberToObject(seconds, "eval", pg_time_seconds() - t0);
    cJSON *config = pipeline_config_json(o);
    if (st == PG_OK) st = pg_path_join(path, sizeof path, o->out, "metrics.json");
    if (st == PG_OK) st = eval_write_metrics_json(path, &r, config, seconds);
    if (st == PG_OK) st = pg_path_join(path, sizeof path, o->out, "report.md");
    if (st == PG_OK) st = eval_write_report_md(path, &r, config, seconds);
    if (st == PG_OK) {
        cJSON *summary = eval_summary_json(&r);
        snprintf(path, sizeof path, "%s/metrics.json", o->out);
        cJSON_AddStringToObject(summary, "metrics", path);
        char *text = cJSON_PrintUnformatted(summary);
        if (text) printf("%s\n", text);
        fflush(stdout);
        free(text);
        cJSON_Delete(summary);
    }
    cJSON_Delete(config);
    eval_results_destroy(&r);
    return st ? cli_fail(st) : 0;
}

int cmd_eval(int argc, char **argv)
{
    pipeline_options o;
    const char *proxies_text;
    cli_option options[40];
    int n = pipeline_cli_options(&o, &proxies_text, options, 38);
    o.test_cams = "5,6";
    options[n++] = (cli_option){ "--test-cams", CLI_STR, &o.test_cams, "held-out cameras, comma-separated indices or names (default 5,6)" };
    const cli_spec spec = { "prodygs eval", "DATASET --depth PATH --out DIR [options]",
                            "DyNeRF protocol: trains on one real camera (--train-cam, default the first) plus\n"
                            "proxies at the other cameras' poses (never the test cameras), then scores every\n"
                            "frame of the test cameras. Writes DIR/metrics.json, DIR/report.md and side-by-side\n"
                            "PNGs (truth | render | error). Rerunning continues from the last finished stage.",
                            options, n, 1, 1 };
    int rc = pipeline_cli_parse(&spec, argc, argv, &o, &proxies_text);
    if (rc) return rc < 0 ? 0 : rc;
    cJSON *seconds = cJSON_CreateObject();
    rc = pipeline_run_stages(&o, seconds);
    if (rc == 0) rc = pipeline_evaluate(&o, seconds);
    cJSON_Delete(seconds);
    return rc;
}
