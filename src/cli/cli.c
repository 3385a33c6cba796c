/* cli.c - option parsing, error printing and the progress printer shared by subcommands. */
#include "cli/cli.h"
#include "core/parallel.h"
#include "core/progress.h"

#include <errno.h>
#include <stdarg.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static void print_help(const cli_spec *spec)
{
    printf("usage: %s %s\n\n%s\n", spec->command, spec->usage, spec->summary);
    if (spec->num_options > 0) printf("\noptions:\n");
    for (int i = 0; i < spec->num_options; i++) {
        const cli_option *o = &spec->options[i];
        const char *arg = o->kind == CLI_STR ? " VALUE" : o->kind == CLI_INT ? " N" : o->kind == CLI_FLOAT ? " X" : "";
        char left[64];
        snprintf(left, sizeof left, "%s%s", o->name, arg);
        printf("  %-24s %s\n", left, o->help);
    }
    printf("  %-24s %s\n", "--help", "show this help");
}

/* "prodygs info" -> "info": errors are already prefixed with "prodygs: ". */
static const char *short_name(const cli_spec *spec)
{
    const char *c = spec->command;
    return strncmp(c, "prodygs ", 8) == 0 ? c + 8 : c;
}

int cli_usage_error(const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "prodygs: ");
    vfprintf(stderr, fmt, ap);
    fprintf(stderr, "\n");
    va_end(ap);
    return 2;
}

int cli_fail(pg_status st)
{
    fprintf(stderr, "prodygs: %s\n", pg_last_error());
    return pg_status_exit_code(st);
}

static int parse_value(const cli_spec *spec, const cli_option *o, const char *text)
{
    char *end = NULL;
    errno = 0;
    switch (o->kind) {
    case CLI_STR:
        *(const char **)o->dest = text;
        return 0;
    case CLI_INT: {
        long v = strtol(text, &end, 10);
        if (errno || !end || *end || end == text || v < -2147483647L || v > 2147483647L)
            return cli_usage_error("%s: %s expects an integer, got '%s'", short_name(spec), o->name, text);
        *(int *)o->dest = (int)v;
        return 0;
    }
    case CLI_FLOAT: {
        float v = strtof(text, &end);
        if (errno || !end || *end || end == text || v != v || v - v != 0) /* NaN or inf */
            return cli_usage_error("%s: %s expects a number, got '%s'", short_name(spec), o->name, text);
        *(float *)o->dest = v;
        return 0;
    }
    case CLI_FLAG:
        *(int *)o->dest = 1;
        return 0;
    }
    return 2;
}

int cli_parse(const cli_spec *spec, int argc, char **argv, const char **positional, int *num_positional)
{
    int npos = 0;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            print_help(spec);
            return -1;
        }
        if (a[0] == '-' && a[1] == '-') {
            const char *eq = strchr(a, '=');
            size_t len = eq ? (size_t)(eq - a) : strlen(a);
            const cli_option *o = NULL;
            for (int k = 0; k < spec->num_options; k++)
                if (strlen(spec->options[k].name) == len && strncmp(spec->options[k].name, a, len) == 0)
                    o = &spec->options[k];
            if (!o) return cli_usage_error("%s: unknown option '%.*s' (see --help)", short_name(spec), (int)len, a);
            const char *val = NULL;
            if (o->kind != CLI_FLAG) {
                if (eq) val = eq + 1;
                else if (i + 1 < argc) val = argv[++i];
                else return cli_usage_error("%s: option %s needs a value", short_name(spec), o->name);
            }
            if (parse_value(spec, o, val)) return 2;
        } else {
            if (npos >= spec->max_positional)
                return cli_usage_error("%s: unexpected argument '%s' (see --help)", short_name(spec), a);
            positional[npos++] = a;
        }
    }
    if (npos < spec->min_positional)
        return cli_usage_error("%s: missing argument; usage: %s %s", short_name(spec), spec->command, spec->usage);
    if (num_positional) *num_positional = npos;
    return 0;
}

int cli_parse_int_list(const char *text, int *out, int n)
{
    int count = 0;
    const char *p = text;
    while (*p) {
        char *end;
        errno = 0;
        long v = strtol(p, &end, 10);
        if (end == p || errno || count >= n || v < -2147483647L || v > 2147483647L) return -1;
        out[count++] = (int)v;
        p = end;
        if (*p == ',') p++;
        else if (*p) return -1;
    }
    return count;
}

int cli_parse_size(const char *option, const char *text, int *w, int *h)
{
    if (!text) return 0;
    long lw = -1, lh = -1;
    char tail;
    if (sscanf(text, "%ldx%ld%c", &lw, &lh, &tail) != 2 || lw < 0 || lh < 0 || (lw == 0 && lh == 0) ||
        (lw != 0 && lw < 8) || (lh != 0 && lh < 8) || lw > CLI_MAX_SIDE || lh > CLI_MAX_SIDE)
        return cli_usage_error("%s '%s' is not WxH or out of range (sides 8..%d, 0 for one side keeps the aspect)", option,
                               text, CLI_MAX_SIDE);
    *w = (int)lw;
    *h = (int)lh;
    return 0;
}

const char *cli_json_number(double v, int decimals, char *buf, size_t size)
{
    if (isfinite(v)) snprintf(buf, size, "%.*f", decimals, v);
    else snprintf(buf, size, "null");
    return buf;
}

int cli_parse_count_or_all(const char *option, const char *text, int *n)
{
    if (!text) return 0;
    if (strcmp(text, "all") == 0) {
        *n = -1;
        return 0;
    }
    char *end;
    errno = 0;
    long v = strtol(text, &end, 10);
    if (errno || *end || end == text || v < 0 || v > 100000)
        return cli_usage_error("%s expects a count or 'all', got '%s'", option, text);
    *n = (int)v;
    return 0;
}

typedef struct {
    int tty;
    double start;
    char last_stage[64];
} progress_state;

static progress_state progress;

/* On a terminal: one live line with ETA. Otherwise: one "progress stage=... step=k/N" line per
 * report, throttled to about one per second per stage so logs stay readable. */
static void print_progress(void *ctx, const char *stage, long step, long total, const char *detail)
{
    progress_state *ps = ctx;
    double now = pg_time_seconds();
    static double last_print;
    if (strcmp(ps->last_stage, stage) != 0) {
        snprintf(ps->last_stage, sizeof ps->last_stage, "%s", stage);
        ps->start = now;
        last_print = 0;
    }
    double elapsed = now - ps->start;
    double eta = (step > 0 && total > 0) ? elapsed * (double)(total - step) / step : 0;
    int final = total > 0 && step >= total;
    if (ps->tty) {
        fprintf(stderr, "\r\033[K%s %ld/%ld %s  %.0fs elapsed, ETA %.0fs", stage, step, total, detail, elapsed, eta);
        if (final) fputc('\n', stderr);
    } else {
        if (!final && now - last_print < 1.0 && step != 0) return;
        last_print = now;
        fprintf(stderr, "progress stage=%s step=%ld total=%ld elapsed_s=%.1f eta_s=%.1f %s\n", stage, step, total,
                elapsed, eta, detail);
    }
    fflush(stderr);
}

void cli_install_progress(void)
{
    progress.tty = isatty(STDERR_FILENO);
    progress.start = pg_time_seconds();
    progress.last_stage[0] = '\0';
    pg_progress_set_sink(print_progress, &progress);
}
