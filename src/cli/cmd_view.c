/* cmd_view.c - `prodygs view`: options -> pg_view_config -> pg_view_run (-> pg_view_serve). */
#include "cli/cli.h"

#include <stdio.h>

#include "core/fileutil.h"

static void print_url(const char *url, void *user)
{
    (void)user;
    printf("{\"url\": \"%s\"}\n", url);
    fprintf(stderr, "prodygs: viewer at %s (Ctrl-C stops)\n", url);
    fflush(stdout);
}

int cmd_view(int argc, char **argv)
{
    pg_view_config c;
    pg_view_defaults(&c);
    int port = 8080;
    const cli_option options[] = {
        { "--port", CLI_INT, &port, "serve on 127.0.0.1:PORT (default 8080; 0 picks a free port)" },
        { "--out", CLI_STR, &c.out, "only write the viewer directory here (no server)" },
        { "--frames", CLI_INT, &c.frames, "time samples in the scene (default: the video's frames)" },
        { "--max-gaussians", CLI_INT, &c.max_gaussians, "keep the N most visible Gaussians (default: all)" },
    };
    const cli_spec spec = { "prodygs view", "MODEL [--port 8080] [--frames N] [--max-gaussians N] [--out DIR]",
                            "Writes a self-contained web viewer of the model (index.html with the WebGL2 renderer\n"
                            "inline, and scene.pgvs) into MODEL/viewer and serves it on http://127.0.0.1:PORT/\n"
                            "(localhost only) until Ctrl-C: time slider, play/pause, orbit/pan/zoom, a button per\n"
                            "dataset camera. With --out the directory is written elsewhere and nothing is served.\n\n"
                            "example: prodygs view out/model --port 8080",
                            options, (int)(sizeof options / sizeof options[0]), 1, 1 };
    const char *model = NULL;
    int rc = cli_parse(&spec, argc, argv, &model, NULL);
    if (rc) return rc < 0 ? 0 : rc;
    if (port < 0 || port > 65535) return cli_usage_error("view: --port %d is not in 0..65535", port);
    if (c.frames < 0) return cli_usage_error("view: --frames must be >= 1, got %d", c.frames);
    if (c.max_gaussians < 0) return cli_usage_error("view: --max-gaussians must be >= 1, got %d", c.max_gaussians);
    c.model = model;
    int serve = c.out == NULL;
    char dir[4200];
    if (serve) { /* MODEL/viewer, or beside a checkpoint file */
        if (pg_path_join_beside(dir, sizeof dir, model, "viewer") != PG_OK)
            return cli_usage_error("view: %s: path too long", model);
        c.out = dir;
    }
    pg_view_report r;
    pg_status st = pg_view_run(&c, &r);
    if (st) return cli_fail(st);
    printf("{\"out\": \"%s\", \"static\": %d, \"moving\": %d, \"dropped\": %d, \"frames\": %d, \"sh_degree\": %d, "
           "\"scene_bytes\": %.0f, \"bytes_per_video_second\": %.0f, \"seconds\": %.2f}\n",
           c.out, r.static_gaussians, r.moving_gaussians, r.dropped, r.frames, r.sh_degree, r.scene_bytes,
           r.bytes_per_second, r.seconds);
    fflush(stdout);
    if (!serve) return 0;
    st = pg_view_serve(c.out, port, 0, print_url, NULL);
    return st ? cli_fail(st) : 0;
}
