/* status.c - thread-local error message store. */
#include "core/status.h"

#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static _Thread_local char last_error[1024];

/* Messages quote bytes from files (PLY/PFM headers, names): control characters become \xNN so an
 * error line can never carry terminal escapes or break into several lines. */
static void escape_controls(char *msg, size_t size)
{
    char out[sizeof last_error];
    size_t o = 0;
    for (const unsigned char *p = (const unsigned char *)msg; *p && o + 5 < sizeof out; p++) {
        if (*p < 0x20 || *p == 0x7f) o += (size_t)snprintf(out + o, sizeof out - o, "\\x%02x", *p);
        else out[o++] = (char)*p;
    }
    out[o] = '\0';
    snprintf(msg, size, "%s", out);
}

pg_status pg_fail(pg_status code, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(last_error, sizeof last_error, fmt, ap);
    va_end(ap);
    escape_controls(last_error, sizeof last_error);
    return code;
}

pg_status pg_fail_context(pg_status code, const char *fmt, ...)
{
    char prefix[512], old[sizeof last_error];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(prefix, sizeof prefix, fmt, ap);
    va_end(ap);
    memcpy(old, last_error, sizeof old);
    size_t n = strlen(prefix);
    if (n > sizeof last_error - 3) n = sizeof last_error - 3;
    memcpy(last_error, prefix, n);
    last_error[n] = ':';
    last_error[n + 1] = ' ';
    size_t room = sizeof last_error - n - 3;
    size_t m = strlen(old);
    if (m > room) m = room;
    memcpy(last_error + n + 2, old, m);
    last_error[n + 2 + m] = '\0';
    escape_controls(last_error, sizeof last_error);
    return code;
}

static pg_warning_handler warning_handler;
static void *warning_ctx;

void pg_set_warning_handler(pg_warning_handler handler, void *ctx)
{
    warning_handler = handler;
    warning_ctx = ctx;
}

void pg_warn(const char *fmt, ...)
{
    char msg[sizeof last_error];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    escape_controls(msg, sizeof msg);
    if (warning_handler) warning_handler(msg, warning_ctx);
    else fprintf(stderr, "prodygs: warning: %s\n", msg);
}

const char *pg_last_error(void)
{
    return last_error[0] ? last_error : "unknown error";
}

const char *pg_status_name(pg_status code)
{
    static const char *names[PG_STATUS_COUNT] = {
        "ok", "bad argument", "i/o error", "bad format", "bad size", "out of memory", "internal error",
        "environment failure",
    };
    _Static_assert(PG_STATUS_COUNT == 8, "update names[] when adding a status");
    return (code >= 0 && code < PG_STATUS_COUNT) ? names[code] : "unknown status";
}

int pg_status_exit_code(pg_status code)
{
    switch (code) {
    case PG_OK: return 0;
    case PG_ERR_NOMEM:
    case PG_ERR_INTERNAL: return 1;
    case PG_ERR_ENV: return 3;
    default: return 2;
    }
}

int pg_size_mul(size_t a, size_t b, size_t *out)
{
    if (a != 0 && b > SIZE_MAX / a) return -1; /* catch size_t overflow */
    *out = a * b;
    return 0;
}

void *pg_malloc(size_t bytes, const char *what)
{
    void *p = malloc(bytes ? bytes : 1);
    if (!p) pg_fail(PG_ERR_NOMEM, "out of memory allocating %zu bytes for %s", bytes, what);
    return p;
}

void *pg_calloc(size_t count, size_t size, const char *what)
{
    void *p = calloc(count ? count : 1, size ? size : 1);
    if (!p) pg_fail(PG_ERR_NOMEM, "out of memory allocating %zu x %zu bytes for %s", count, size, what);
    return p;
}
