/* http_server.h - a minimal HTTP/1.1 server for the viewer, on 127.0.0.1 only.
 *
 * It answers GET and HEAD for a fixed table of in-memory files; any other path is 404, so
 * nothing outside the table can be reached (no file system access at all). Request targets
 * with "..", "%", a backslash or not starting with "/" are refused (400); a Host header that
 * is not 127.0.0.1 / localhost is refused (403, against DNS rebinding). Heads are limited to
 * 8 KiB, connections to 10 s and 32 at a time; every response closes its connection.
 *
 *   view_http_server *s;
 *   PG_TRY(view_http_open(8080, &s));                   // 0: any free port
 *   printf("http://127.0.0.1:%d/\n", view_http_port(s));
 *   view_http_file files[] = { { "/", "text/html", html, html_len }, ... };
 *   PG_TRY(view_http_serve(s, files, 1, 0, &stop));    // until stop != 0
 *   view_http_close(s);
 */
#ifndef PG_HTTP_SERVER_H
#define PG_HTTP_SERVER_H

#include <stdatomic.h>
#include <stddef.h>

#include "core/status.h"

typedef struct {
    const char *path;         /* exact request path, e.g. "/index.html" (query strings are ignored) */
    const char *content_type;
    const void *data;
    size_t size;
} view_http_file;

typedef struct view_http_server view_http_server;

/* Listens on 127.0.0.1:port (0: a free port the system picks). */
pg_status view_http_open(int port, view_http_server **s);
int view_http_port(const view_http_server *s);
/* Answers requests until *stop is nonzero (checked at least every 200 ms) or, with
 * max_requests > 0, that many responses were sent. The table is borrowed. */
pg_status view_http_serve(view_http_server *s, const view_http_file *files, int n_files, long max_requests,
                          atomic_int *stop);
void view_http_close(view_http_server *s);

#endif
