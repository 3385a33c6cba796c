/* http_server.c - poll() loop over non-blocking sockets (see http_server.h for the rules). */
#include "view/http_server.h"
#include "core/parallel.h"

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/socket.h>
#include <unistd.h>

#include "core/status.h"

#define HTTP_MAX_HEAD 8192
#define HTTP_MAX_CONN 32
#define HTTP_CONN_SECONDS 10.0

struct view_http_server {
    int fd, port;
};

enum { CONN_READ, CONN_WRITE, CONN_DRAIN };

typedef struct {
    int fd;                   /* -1: free slot */
    double started;           /* for the per-connection deadline */
    char in[HTTP_MAX_HEAD + 1];
    size_t in_len;
    int state;                /* reading the head, writing the response, or draining the input */
    char head[768];           /* response status line and headers */
    size_t head_len, head_sent;
    const char *body;
    size_t body_len, body_sent;
} http_conn;

pg_status view_http_open(int port, view_http_server **out)
{
    *out = NULL;
    if (port < 0 || port > 65535) return pg_fail(PG_ERR_ARG, "view: --port %d is not in 0..65535", port);
    int fd = socket(AF_INET, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (fd < 0) return pg_fail(PG_ERR_ENV, "view: socket: %s", strerror(errno));
    int one = 1;
    setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_port = htons((uint16_t)port);
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK); /* localhost only: never reachable from the network */
    socklen_t len = sizeof a;
    if (bind(fd, (struct sockaddr *)&a, sizeof a) < 0 || listen(fd, 64) < 0 ||
        getsockname(fd, (struct sockaddr *)&a, &len) < 0) {
        int e = errno;
        close(fd);
        return pg_fail(PG_ERR_ENV, "view: 127.0.0.1:%d: %s", port, strerror(e));
    }
    view_http_server *s = pg_calloc(1, sizeof *s, "http server");
    if (!s) {
        close(fd);
        return PG_ERR_NOMEM;
    }
    s->fd = fd;
    s->port = ntohs(a.sin_port);
    *out = s;
    return PG_OK;
}

int view_http_port(const view_http_server *s) { return s->port; }

void view_http_close(view_http_server *s)
{
    if (!s) return;
    close(s->fd);
    free(s);
}

static void conn_close(http_conn *c)
{
    if (c->fd >= 0) close(c->fd);
    c->fd = -1;
}

static void respond(http_conn *c, int code, const char *type, const char *body, size_t body_len, int head_only)
{
    const char *reason = code == 200 ? "OK" : code == 400 ? "Bad Request" : code == 403 ? "Forbidden"
                       : code == 404 ? "Not Found" : code == 405 ? "Method Not Allowed"
                       : code == 431 ? "Request Header Fields Too Large" : "Error";
    if (code != 200) { /* a short plain-text reason as the body */
        body = reason;
        body_len = strlen(reason);
        type = "text/plain";
    }
    int n = snprintf(c->head, sizeof c->head,
                     "HTTP/1.1 %d %s\r\nContent-Type: %s\r\nContent-Length: %zu\r\nCache-Control: no-store\r\n"
                     "X-Content-Type-Options: nosniff\r\nContent-Security-Policy: default-src 'self'; "
                     "script-src 'self' 'unsafe-inline' blob:; worker-src 'self' blob:; style-src 'self' 'unsafe-inline'; "
                     "img-src 'self' data: blob:\r\nConnection: close\r\n\r\n",
                     code, reason, type, body_len);
    c->head_len = n > 0 && (size_t)n < sizeof c->head ? (size_t)n : 0;
    c->head_sent = 0;
    c->body = body;
    c->body_len = head_only ? 0 : body_len;
    c->body_sent = 0;
    c->state = CONN_WRITE;
}

/* 1 if the Host value names this machine's loopback (with or without a port). */
static int host_is_local(const char *v, size_t n)
{
    static const char *names[] = { "127.0.0.1", "localhost" };
    for (int k = 0; k < 2; k++) {
        size_t l = strlen(names[k]);
        if (n >= l && strncasecmp(v, names[k], l) == 0 && (n == l || v[l] == ':')) return 1;
    }
    return 0;
}

/* Parses a complete head in c->in and prepares the response. */
static void handle_request(http_conn *c, const view_http_file *files, int n_files)
{
    char *line_end = strstr(c->in, "\r\n");
    for (size_t i = 0; i < c->in_len; i++) { /* control bytes other than CR LF TAB are never valid */
        unsigned char ch = (unsigned char)c->in[i];
        if ((ch < 32 && ch != '\r' && ch != '\n' && ch != '\t') || ch == 127) {
            respond(c, 400, NULL, NULL, 0, 0);
            return;
        }
    }
    char method[8], target[1024], version[16];
    *line_end = '\0';
    const char *t0 = strchr(c->in, ' ');
    if (!t0 || strcspn(t0 + 1, " ") >= sizeof target - 1 || /* too long to be in the table */
        sscanf(c->in, "%7s %1023s %15s", method, target, version) != 3 || strncmp(version, "HTTP/1.", 7) != 0) {
        respond(c, 400, NULL, NULL, 0, 0);
        return;
    }
    int head_only = strcmp(method, "HEAD") == 0;
    if (!head_only && strcmp(method, "GET") != 0) {
        respond(c, 405, NULL, NULL, 0, 0);
        return;
    }
    /* only origin-form paths: no absolute URIs, no parent steps, no escapes that could hide them */
    if (target[0] != '/' || strstr(target, "..") || strchr(target, '%') || strchr(target, '\\') ||
        strstr(target, "//")) {
        respond(c, 400, NULL, NULL, 0, head_only);
        return;
    }
    for (const char *h = line_end + 2; *h && !(h[0] == '\r' && h[1] == '\n');) {
        const char *e = strstr(h, "\r\n");
        const char *colon = memchr(h, ':', e ? (size_t)(e - h) : 0);
        if (!e || !colon) {
            respond(c, 400, NULL, NULL, 0, head_only);
            return;
        }
        if ((size_t)(colon - h) == 4 && strncasecmp(h, "Host", 4) == 0) {
            const char *v = colon + 1;
            while (v < e && (*v == ' ' || *v == '\t')) v++;
            size_t vn = (size_t)(e - v);
            while (vn > 0 && (v[vn - 1] == ' ' || v[vn - 1] == '\t')) vn--;
            if (!host_is_local(v, vn)) {
                respond(c, 403, NULL, NULL, 0, head_only);
                return;
            }
        }
        h = e + 2;
    }
    target[strcspn(target, "?#")] = '\0';
    for (int k = 0; k < n_files; k++)
        if (strcmp(target, files[k].path) == 0) {
            respond(c, 200, files[k].content_type, files[k].data, files[k].size, head_only);
            return;
        }
    respond(c, 404, NULL, NULL, 0, head_only);
}

/* Reads what is available; prepares a response once the head is complete. 0: close now. */
static int conn_read(http_conn *c, const view_http_file *files, int n_files)
{
    for (;;) {
        ssize_t r = recv(c->fd, c->in + c->in_len, HTTP_MAX_HEAD - c->in_len, 0);
        if (r == 0) return 0;
        if (r < 0) return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR;
        c->in_len += (size_t)r;
        c->in[c->in_len] = '\0';
        if (memchr(c->in, '\0', c->in_len)) { /* a NUL byte hides the rest from string parsing */
            respond(c, 400, NULL, NULL, 0, 0);
            return 1;
        }
        if (strstr(c->in, "\r\n\r\n")) {
            handle_request(c, files, n_files);
            return 1;
        }
        /* a head that can never complete gets its 400 now, not after the idle timeout: a bare LF
         * line end, or a finished request line without an HTTP/1.x version (HTTP/0.9) */
        const char *lf = memchr(c->in, '\n', c->in_len), *eol = strstr(c->in, "\r\n");
        int bare_lf = lf && (lf == c->in || lf[-1] != '\r');
        int old_line = eol && (eol - c->in < 9 || strncmp(eol - 9, " HTTP/1.", 8) != 0);
        if (bare_lf || old_line) {
            respond(c, 400, NULL, NULL, 0, 0);
            return 1;
        }
        if (c->in_len == HTTP_MAX_HEAD) {
            respond(c, 431, NULL, NULL, 0, 0);
            return 1;
        }
    }
}

/* Sends what the socket takes. 1: more to send, 0: done or failed (close). */
static int conn_write(http_conn *c)
{
    while (c->head_sent < c->head_len || c->body_sent < c->body_len) {
        int head = c->head_sent < c->head_len;
        const char *p = head ? c->head + c->head_sent : c->body + c->body_sent;
        size_t n = head ? c->head_len - c->head_sent : c->body_len - c->body_sent;
        ssize_t w = send(c->fd, p, n, MSG_NOSIGNAL);
        if (w < 0) return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR;
        if (head) c->head_sent += (size_t)w;
        else c->body_sent += (size_t)w;
    }
    return 0;
}

/* Discards what the client still sends after its response, until it closes: closing with
 * unread input would reset the connection and could destroy the response in flight. */
static int conn_drain(http_conn *c)
{
    char buf[4096];
    for (;;) {
        ssize_t r = recv(c->fd, buf, sizeof buf, 0);
        if (r == 0) return 0;
        if (r < 0) return errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR;
    }
}

/* Takes one pending connection into a free slot (evicting the oldest one not yet answered
 * when all are busy, so slow clients cannot lock the viewer out). 0: nothing was pending. */
static int accept_one(view_http_server *s, http_conn *conns)
{
    int fd = accept4(s->fd, NULL, NULL, SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (fd < 0) return 0;
    int slot = -1, oldest = -1;
    for (int k = 0; k < HTTP_MAX_CONN && slot < 0; k++)
        if (conns[k].fd < 0) slot = k;
        else if (conns[k].state != CONN_WRITE && (oldest < 0 || conns[k].started < conns[oldest].started)) oldest = k;
    if (slot < 0) slot = oldest;
    if (slot < 0) {
        close(fd);
        return 1;
    }
    conn_close(&conns[slot]);
    conns[slot].fd = fd;
    conns[slot].started = pg_time_seconds();
    conns[slot].in_len = 0;
    conns[slot].state = CONN_READ;
    return 1;
}

pg_status view_http_serve(view_http_server *s, const view_http_file *files, int n_files, long max_requests,
                          atomic_int *stop)
{
    http_conn *conns = pg_malloc(sizeof(http_conn) * HTTP_MAX_CONN, "http connections");
    if (!conns) return PG_ERR_NOMEM;
    for (int k = 0; k < HTTP_MAX_CONN; k++) conns[k].fd = -1;
    long answered = 0;
    struct pollfd pf[HTTP_MAX_CONN + 1];
    int who[HTTP_MAX_CONN + 1];
    while (!(stop && atomic_load(stop)) && (max_requests <= 0 || answered < max_requests)) {
        int n = 0;
        pf[n] = (struct pollfd){ s->fd, POLLIN, 0 };
        who[n++] = -1;
        double t = pg_time_seconds();
        for (int k = 0; k < HTTP_MAX_CONN; k++) {
            if (conns[k].fd < 0) continue;
            if (t - conns[k].started > HTTP_CONN_SECONDS) {
                conn_close(&conns[k]);
                continue;
            }
            pf[n] = (struct pollfd){ conns[k].fd, conns[k].state == CONN_WRITE ? POLLOUT : POLLIN, 0 };
            who[n++] = k;
        }
        int r = poll(pf, (nfds_t)n, 200);
        if (r < 0 && errno != EINTR) {
            int e = errno;
            for (int k = 0; k < HTTP_MAX_CONN; k++) conn_close(&conns[k]);
            free(conns);
            return pg_fail(PG_ERR_IO, "view: poll: %s", strerror(e));
        }
        for (int j = 1; r > 0 && j < n; j++) {
            http_conn *c = &conns[who[j]];
            if (!pf[j].revents) continue;
            int keep = c->state == CONN_DRAIN ? conn_drain(c) : c->state == CONN_READ ? conn_read(c, files, n_files) : 1;
            if (keep && c->state == CONN_WRITE && !conn_write(c)) {
                answered++;
                shutdown(c->fd, SHUT_WR); /* the client sees the end of the response now */
                c->state = CONN_DRAIN;
                c->started = pg_time_seconds() - HTTP_CONN_SECONDS + 1.0; /* drain for at most 1 s */
            }
            if (!keep) conn_close(c);
        }
        if (r > 0 && (pf[0].revents & POLLIN))
            for (int k = 0; k < 16 && accept_one(s, conns); k++) continue;
    }
    for (int k = 0; k < HTTP_MAX_CONN; k++) conn_close(&conns[k]);
    free(conns);
    return PG_OK;
}
