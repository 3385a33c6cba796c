/* pipeline_cli.h - the options `run`, `eval` and `demo` share, bound to a pg_pipeline_config,
 * and the summary line they print after pg_pipeline_run. */
#ifndef PG_PIPELINE_CLI_H
#define PG_PIPELINE_CLI_H

#include "cli/cli.h"

typedef struct {
    const char *size, *proxies; /* parsed by cli_parse_size / cli_parse_count_or_all */
    int no_refine, no_align, no_fuse, no_planes, no_ground, no_movers_front, no_pose_shift;
    char command[4096];         /* the command line, recorded in report.md */
    char depth_model[4096];     /* the built-in depth model's path when neither --depth nor --depth-model is given */
} pipeline_cli_text;

/* Sets c to the defaults and writes the shared options (bound to c and t) into opts; returns
 * how many (at most max). */
int pipeline_cli_options(pg_pipeline_config *c, pipeline_cli_text *t, cli_option *opts, int max);
/* Parses argv with spec (one positional: INPUT) and finishes c. Returns 0, -1 after --help, or
 * an exit code. */
/* Without --depth / --depth-model: writes out the built-in FastDepth (depth_default.h) into path
 * and says so on stderr; returns 0 or the exit code of the failure (printed). Shared with depth. */
int pipeline_cli_default_depth(const char *missing, char *path, size_t size);
int pipeline_cli_parse(const cli_spec *spec, int argc, char **argv, pg_pipeline_config *c, pipeline_cli_text *t);
/* Runs the pipeline, printing the resolved cameras first and a one-line JSON summary at the
 * end on stdout; returns the exit code. */
int pipeline_cli_run(pg_pipeline_config *c);

#endif
