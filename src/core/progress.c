/* progress.c - forwards progress to the sink the application installed. */
#include "core/progress.h"

#include <stdarg.h>
#include <stdio.h>

static pg_progress_fn sink_fn;
static void *sink_ctx;

void pg_progress_set_sink(pg_progress_fn fn, void *ctx)
{
    sink_fn = fn;
    sink_ctx = ctx;
}

void pg_progress_report(const char *stage, long step, long total, const char *fmt, ...)
{
    if (!sink_fn) return;
    char detail[256] = "";
    if (fmt) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(detail, sizeof detail, fmt, ap);
        va_end(ap);
    }
    sink_fn(sink_ctx, stage, step, total, detail);
}
