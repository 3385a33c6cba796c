/* cmd_export.c - `prodygs export`: options -> pg_export_config -> pg_export_run. */
#include "cli/cli.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define EXPORT_MAX_TIMES 4096

/* Parses "0,0.5,1" into times in [0, 1]; returns the count or -1. */
static int parse_times(const char *text, float *out, int max)
{
    int n = 0;
    const char *p = text;
    while (*p) {
        char *end;
        float v = strtof(p, &end);
        if (end == p || n >= max || !(v >= 0.0f && v <= 1.0f)) return -1;
        out[n++] = v;
        p = end;
        if (*p == ',') p++;
        else if (*p) return -1;
    }
    return n;
}

int cmd_export(int argc, char **argv)
{
    pg_export_config c;
    pg_export_defaults(&c);
    const char *times_text = NULL, *frames_text = NULL;
    const cli_option options[] = {
        { "--out", CLI_STR, &c.out, "output directory (required)" },
        { "--times", CLI_STR, &times_text, "comma-separated times in [0,1] (default 0)" },
        { "--frame-list", CLI_STR, &frames_text, "comma-separated frame indices of the training video, or all" },
        { "--format", CLI_STR, &c.format, "ply (3DGS, default) or splat (antimatter15's 32-byte layout)" },
    };
    const cli_spec spec = { "prodygs export", "MODEL --out DIR [--times T,...|--frame-list F,...|all] [--format ply|splat]",
                            "Writes the deformed Gaussians at the requested times as binary little-endian PLY in\n"
                            "the standard 3DGS layout, or as .splat (antimatter15's 32-byte rows, read by web splat\n"
                            "viewers). Files: DIR/frame_NNNN.ply for frames, DIR/time_0.500.ply for times, and\n"
                            "DIR/cameras.json (the model's cameras). Each file holds the Gaussians visible at its time\n"
                            "(opacity >= 1/255) with unit quaternions.\n\n"
                            "example: prodygs export out/model --out out/ply --frame-list all\n"
                            "         prodygs export out/model --out out/splat --format splat --times 0,0.5,1",
                            options, (int)(sizeof options / sizeof options[0]), 1, 1 };
    int rc = cli_parse(&spec, argc, argv, &c.model, NULL);
    if (rc) return rc < 0 ? 0 : rc;
    if (!c.out) return cli_usage_error("export: --out DIR is required");
    if (times_text && frames_text) return cli_usage_error("export: give only one of --times, --frame-list");
    float *times = malloc(EXPORT_MAX_TIMES * sizeof(float));
    int *frames = malloc(EXPORT_MAX_TIMES * sizeof(int));
    if (!times || !frames) {
        free(times);
        free(frames);
        return cli_fail(pg_fail(PG_ERR_NOMEM, "export: out of memory"));
    }
    if (times_text && (c.num_times = parse_times(times_text, times, EXPORT_MAX_TIMES)) <= 0)
        rc = cli_usage_error("export: --times must be comma-separated numbers in [0, 1], got '%s'", times_text);
    if (frames_text && strcmp(frames_text, "all") == 0)
        c.all_frames = 1;
    else if (frames_text && (c.num_frames = cli_parse_int_list(frames_text, frames, EXPORT_MAX_TIMES)) <= 0)
        rc = cli_usage_error("export: --frame-list must be comma-separated frame indices or all, got '%s'", frames_text);
    c.times = times;
    c.frames = frames;
    pg_export_report r;
    pg_status st = rc ? PG_OK : pg_export_run(&c, &r);
    free(times);
    free(frames);
    if (rc) return rc;
    if (st) return cli_fail(st);
    printf("{\"out\": \"%s\", \"files\": %d, \"gaussians\": %d, \"dropped\": %d, \"cameras\": %s}\n", c.out, r.files,
           r.gaussians, r.dropped, r.cameras ? "true" : "false");
    return 0;
}
