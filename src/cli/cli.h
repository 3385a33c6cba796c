/* cli.h - shared pieces of the `prodygs` command line: option parsing, errors, progress.
 *
 * Each subcommand lives in cmd_<name>.c as `int cmd_<name>(int argc, char **argv)` and
 * returns the process exit code (0 ok, 2 bad input or usage, 1 internal failure).
 */
#ifndef PG_CLI_H
#define PG_CLI_H

#include "core/status.h"
#include "prodygs.h"

typedef enum { CLI_STR, CLI_INT, CLI_FLOAT, CLI_FLAG } cli_kind;

typedef struct {
    const char *name;  /* "--out" */
    cli_kind kind;
    void *dest;        /* const char **, int *, float *, or int * (flag set to 1) */
    const char *help;
} cli_option;

typedef struct {
    const char *command;     /* "prodygs info" */
    const char *usage;       /* "PATH [options]" */
    const char *summary;     /* one line of what it does */
    const cli_option *options;
    int num_options;
    int min_positional, max_positional;
} cli_spec;

/* Parses argv[1..] (argv[0] is the subcommand name). Positionals go to positional[].
 * Returns 0 on success, 2 after printing a usage error, or -1 after printing --help
 * (the caller then returns 0). */
int cli_parse(const cli_spec *spec, int argc, char **argv, const char **positional, int *num_positional);
/* Prints "prodygs: <last error>" and returns the exit code for st. */
int cli_fail(pg_status st);
/* Prints "prodygs: <message>" and returns 2. */
int cli_usage_error(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
/* Installs the progress printer: a live line on a terminal, key=value lines otherwise. */
void cli_install_progress(void);
/* Environment that OpenBLAS and libgomp read when they load (the CPU's BLAS kernels; passive
 * OpenMP waiting on a busy machine): when a setting is missing, runs the process again (argv) with
 * it (load_env.c). */
void cli_set_load_env(char **argv);
/* The core OpenBLAS runs (for --version and the benchmarks' JSON). */
const char *cli_blas_core(void);
/* Parses "a,b,c" integers into out (max n); returns the count or -1 on a bad list. */
int cli_parse_int_list(const char *text, int *out, int n);
/* The option kinds every command shares, one parser each (0 ok, else 2 after a usage error):
 * --size WxH (0 for one side keeps the aspect; NULL text leaves *w, *h alone), and counts that
 * also take "all" (--proxies N|all: *n = -1 for all). */
int cli_parse_size(const char *option, const char *text, int *w, int *h);
int cli_parse_count_or_all(const char *option, const char *text, int *n);
/* A JSON number with `decimals` decimals, or null for a value that was not measured (NaN). */
const char *cli_json_number(double v, int decimals, char *buf, size_t size);
/* Largest image side the commands accept for a requested size (--width, --size). */
#define CLI_MAX_SIDE 8192

int cmd_info(int argc, char **argv);
int cmd_synth(int argc, char **argv);
int cmd_depth(int argc, char **argv);
int cmd_prepare(int argc, char **argv);
int cmd_proxies(int argc, char **argv);
int cmd_train(int argc, char **argv);
int cmd_render(int argc, char **argv);
int cmd_export(int argc, char **argv);
int cmd_view(int argc, char **argv);
int cmd_eval(int argc, char **argv);
int cmd_run(int argc, char **argv);
int cmd_demo(int argc, char **argv);
int cmd_bench(int argc, char **argv);

#endif
