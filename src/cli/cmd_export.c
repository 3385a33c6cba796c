/* cmd_export.c - `prodygs export MODEL --out DIR`: deformed Gaussians as standard 3DGS PLY. */
#include "cli/cli.h"
#include "core/fileutil.h"
#include "io/ply.h"
#include "render/model_render.h"

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
    const char *out = NULL, *times_text = NULL, *frames_text = NULL;
    int all_frames = 0;
    const cli_option options[] = {
        { "--out", CLI_STR, &out, "output directory (required)" },
        { "--times", CLI_STR, &times_text, "comma-separated times in [0,1] (default 0)" },
        { "--frames", CLI_STR, &frames_text, "comma-separated frame indices of the training video" },
        { "--all-frames", CLI_FLAG, &all_frames, "one PLY per frame of the training video" },
    };
    const cli_spec spec = { "prodygs export", "MODEL --out DIR [--times T,...|--frames F,...|--all-frames]",
                            "Writes the deformed Gaussians at the requested times as binary little-endian PLY in\n"
                            "the standard 3DGS layout (opens in common 3DGS viewers). Files: DIR/frame_NNNN.ply\n"
                            "for frames, DIR/time_0.500.ply for times.",
                            options, (int)(sizeof options / sizeof options[0]), 1, 1 };
    const char *pos[1];
    int rc = cli_parse(&spec, argc, argv, pos, NULL);
    if (rc) return rc < 0 ? 0 : rc;
    if (!out) return cli_usage_error("export: --out DIR is required");
    if ((times_text != NULL) + (frames_text != NULL) + all_frames > 1)
        return cli_usage_error("export: give only one of --times, --frames, --all-frames");
    if (times_text) { /* check the list before the (slow) model load */
        float *check = malloc(EXPORT_MAX_TIMES * sizeof(float));
        int nt = check ? parse_times(times_text, check, EXPORT_MAX_TIMES) : 0;
        free(check);
        if (nt <= 0) return cli_usage_error("export: --times must be comma-separated numbers in [0, 1], got '%s'", times_text);
    }

    render_model *rm = NULL;
    pg_status st = render_model_open(pos[0], &rm);
    if (st) return cli_fail(st);
    int frames = render_model_frames(rm);
    float *times = malloc(EXPORT_MAX_TIMES * sizeof(float));
    int *frame_ids = malloc(EXPORT_MAX_TIMES * sizeof(int));
    int n = 0, by_frame = 0;
    if (!times || !frame_ids) {
        st = pg_fail(PG_ERR_NOMEM, "out of memory");
    } else if (frames_text || all_frames) {
        by_frame = 1;
        if (all_frames) {
            n = frames < EXPORT_MAX_TIMES ? frames : EXPORT_MAX_TIMES;
            for (int i = 0; i < n; i++) frame_ids[i] = i;
        } else {
            n = cli_parse_int_list(frames_text, frame_ids, EXPORT_MAX_TIMES);
        }
        for (int i = 0; i < n; i++) {
            if (frame_ids[i] < 0 || frame_ids[i] >= frames) n = -1;
            else times[i] = train_frame_time(frame_ids[i], frames);
            if (n < 0) break;
        }
        if (n <= 0) st = pg_fail(PG_ERR_ARG, "export: --frames must list frames in [0, %d)", frames);
    } else {
        n = times_text ? parse_times(times_text, times, EXPORT_MAX_TIMES) : 1;
        if (!times_text) times[0] = 0.0f;
        if (n <= 0) st = pg_fail(PG_ERR_ARG, "export: --times must be comma-separated numbers in [0, 1]");
    }
    if (st == PG_OK) st = pg_mkdir_p(out);
    for (int i = 0; st == PG_OK && i < n; i++) {
        const pg_gaussians *g;
        st = render_model_gaussians_at(rm, times[i], &g);
        char file[64], path[4200];
        if (by_frame) snprintf(file, sizeof file, "frame_%04d.ply", frame_ids[i]);
        else snprintf(file, sizeof file, "time_%.3f.ply", times[i]);
        if (st == PG_OK) st = pg_path_join(path, sizeof path, out, file);
        if (st == PG_OK) st = io_ply_save(path, g);
        if (st == PG_OK) printf("%s %d gaussians t=%.4f\n", path, g->count, times[i]);
    }
    free(times);
    free(frame_ids);
    render_model_close(rm);
    return st ? cli_fail(st) : 0;
}
