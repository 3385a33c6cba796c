/* test_view_server.c - the viewer's HTTP server: localhost only, a fixed table of files, path
 * tricks refused, and 1,000 malformed requests (random bytes, cut heads, oversized heads, NUL
 * bytes, bad methods and hosts, idle and abandoned connections) without a crash or a hang;
 * afterwards it still serves the page. */
#include <arpa/inet.h>
#include <errno.h>
#include <ifaddrs.h>
#include <netinet/in.h>
#include <poll.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/time.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "core/rng.h"
#include "testlib.h"
#include "view/http_server.h"

static const char PAGE[] = "<!doctype html><title>x</title>";
static char scene[100000];

typedef struct {
    view_http_server *server;
    view_http_file files[3];
    atomic_int stop;
} server_thread;

static void *serve(void *arg)
{
    server_thread *s = arg;
    view_http_serve(s->server, s->files, 3, 0, &s->stop);
    return NULL;
}

static int connect_to(int port)
{
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in a = { .sin_family = AF_INET, .sin_port = htons((uint16_t)port) };
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (connect(fd, (struct sockaddr *)&a, sizeof a) != 0) {
        close(fd);
        return -1;
    }
    struct timeval tv = { 5, 0 };
    setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    return fd;
}

/* Sends req (len bytes), half-closes, reads the whole answer into out (NUL-terminated, cut at
 * size); returns the bytes read or -1 if the connection failed. */
static long exchange(int port, const char *req, size_t len, char *out, size_t size)
{
    int fd = connect_to(port);
    if (fd < 0) return -1;
    size_t sent = 0;
    while (sent < len) {
        ssize_t w = send(fd, req + sent, len - sent, MSG_NOSIGNAL);
        if (w <= 0) break;
        sent += (size_t)w;
    }
    shutdown(fd, SHUT_WR);
    size_t got = 0;
    for (;;) {
        char buf[65536];
        ssize_t r = recv(fd, buf, sizeof buf, 0);
        if (r <= 0) break;
        size_t take = got + (size_t)r < size - 1 ? (size_t)r : size - 1 - got;
        memcpy(out + got, buf, take);
        got += take;
    }
    out[got] = '\0';
    close(fd);
    return (long)got;
}

static int status_of(const char *resp)
{
    int code = 0;
    return sscanf(resp, "HTTP/1.1 %d", &code) == 1 ? code : 0;
}

static int get_status(int port, const char *request)
{
    static char resp[200000];
    return exchange(port, request, strlen(request), resp, sizeof resp) >= 0 ? status_of(resp) : -1;
}

/* Sends req and waits up to 3 s for the reply without closing the sending side (a client that
 * waits for an answer); the status, or 0 when none came in time. */
static int status_while_open(int port, const char *req)
{
    int fd = connect_to(port);
    if (fd < 0) return -1;
    struct timeval tv = { 3, 0 };
    setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    if (send(fd, req, strlen(req), MSG_NOSIGNAL) < 0) {
        close(fd);
        return -1;
    }
    char resp[4096];
    ssize_t r = recv(fd, resp, sizeof resp - 1, 0);
    resp[r > 0 ? r : 0] = '\0';
    close(fd);
    return r > 0 ? status_of(resp) : 0;
}

/* A first non-loopback IPv4 address of this machine ("" if none). */
static void other_address(char *out, size_t size)
{
    out[0] = '\0';
    struct ifaddrs *list = NULL, *a;
    if (getifaddrs(&list) != 0) return;
    for (a = list; a; a = a->ifa_next)
        if (a->ifa_addr && a->ifa_addr->sa_family == AF_INET) {
            struct in_addr ip = ((struct sockaddr_in *)a->ifa_addr)->sin_addr;
            if ((ntohl(ip.s_addr) >> 24) != 127) {
                inet_ntop(AF_INET, &ip, out, (socklen_t)size);
                break;
            }
        }
    freeifaddrs(list);
}

/* One malformed request of kind k (bounded: at most 12 KB). */
static size_t bad_request(pg_rng *rng, int k, int port, char *req, size_t size)
{
    size_t n = 0;
    switch (k % 10) {
    case 0: /* random bytes */
        n = (size_t)pg_rng_range(rng, 0, 4000);
        for (size_t i = 0; i < n; i++) req[i] = (char)(pg_rng_u64(rng) & 0xff);
        break;
    case 1: /* a head larger than the limit */
        n = (size_t)snprintf(req, size, "GET / HTTP/1.1\r\nX-Big: ");
        while (n < 10000) req[n++] = 'a';
        break;
    case 2: /* cut in the middle of the head */
        n = (size_t)snprintf(req, size, "GET /index.html HTTP/1.1\r\nHost: 127.0.0.1:%d\r\nAcc", port);
        break;
    case 3: /* NUL byte inside */
        n = (size_t)snprintf(req, size, "GET /x HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n");
        req[6] = '\0';
        break;
    case 4: /* header line without a colon */
        n = (size_t)snprintf(req, size, "GET / HTTP/1.1\r\nthis is no header\r\n\r\n");
        break;
    case 5: /* another host (DNS rebinding) */
        n = (size_t)snprintf(req, size, "GET / HTTP/1.1\r\nHost: evil.example:%d\r\n\r\n", port);
        break;
    case 6: /* methods that are not served */
        n = (size_t)snprintf(req, size, "%s / HTTP/1.1\r\n\r\n", (const char *[]){ "POST", "PUT", "DELETE", "OPTIONS" }[k % 4]);
        break;
    case 7: /* bit-flipped valid request */
        n = (size_t)snprintf(req, size, "GET /scene.pgvs HTTP/1.1\r\nHost: 127.0.0.1:%d\r\n\r\n", port);
        for (int f = 0; f < 3; f++) req[pg_rng_u64(rng) % n] ^= (char)(1 << (pg_rng_u64(rng) % 8));
        break;
    case 8: /* control characters and a bad version */
        n = (size_t)snprintf(req, size, "GET /\x01\x7f HTTP/9.9\r\n\r\n");
        break;
    default: /* many empty header lines then garbage */
        n = (size_t)snprintf(req, size, "GET / HTTP/1.1\r\n");
        for (; n < 8000; n++) req[n] = (n % 2) ? '\n' : '\r';
        break;
    }
    return n;
}

int main(void)
{
    for (size_t i = 0; i < sizeof scene; i++) scene[i] = (char)(i * 7);
    server_thread s = { .files = { { "/", "text/html", PAGE, sizeof PAGE - 1 },
                                   { "/index.html", "text/html", PAGE, sizeof PAGE - 1 },
                                   { "/scene.pgvs", "application/octet-stream", scene, sizeof scene } } };
    atomic_init(&s.stop, 0);
    CHECK_OK(view_http_open(0, &s.server));
    if (!s.server) return test_summary("test_view_server");
    int port = view_http_port(s.server);
    pthread_t th;
    CHECK(pthread_create(&th, NULL, serve, &s) == 0, "thread");
    static char resp[200000], req[16384];
    char line[512];

    /* the table */
    snprintf(line, sizeof line, "GET /scene.pgvs HTTP/1.1\r\nHost: 127.0.0.1:%d\r\n\r\n", port);
    long n = exchange(port, line, strlen(line), resp, sizeof resp);
    char *body = strstr(resp, "\r\n\r\n");
    CHECK(status_of(resp) == 200 && body && n - (body + 4 - resp) == (long)sizeof scene &&
              memcmp(body + 4, scene, sizeof scene) == 0, "GET /scene.pgvs: %ld bytes, status %d", n, status_of(resp));
    CHECK(get_status(port, "GET /?shot=1&time=0 HTTP/1.1\r\nHost: localhost\r\n\r\n") == 200, "GET / with a query");
    CHECK(get_status(port, "GET /index.html HTTP/1.0\r\n\r\n") == 200, "GET /index.html (HTTP/1.0, no Host)");
    n = exchange(port, "HEAD / HTTP/1.1\r\n\r\n", 19, resp, sizeof resp);
    CHECK(status_of(resp) == 200 && strstr(resp, "\r\n\r\n")[4] == '\0', "HEAD has no body");
    /* nothing else, whatever the spelling */
    const char *refused[] = { "GET /../etc/passwd HTTP/1.1\r\n\r\n", "GET /%2e%2e/etc/passwd HTTP/1.1\r\n\r\n",
                              "GET /..%2fetc/passwd HTTP/1.1\r\n\r\n", "GET //etc/passwd HTTP/1.1\r\n\r\n",
                              "GET /etc/passwd HTTP/1.1\r\n\r\n", "GET http://127.0.0.1/index.html HTTP/1.1\r\n\r\n",
                              "GET \\index.html HTTP/1.1\r\n\r\n", "GET /scene.pgvs/.. HTTP/1.1\r\n\r\n",
                              "GET /index.html/ HTTP/1.1\r\n\r\n", "GET etc/passwd HTTP/1.1\r\n\r\n" };
    for (size_t k = 0; k < sizeof refused / sizeof refused[0]; k++) {
        int code = get_status(port, refused[k]);
        CHECK(code == 400 || code == 404, "%.40s -> %d", refused[k], code);
    }
    CHECK(get_status(port, "GET /../etc/passwd HTTP/1.1\r\n\r\n") == 400, "'..' is a bad request");
    /* issue 27: heads that can never complete waited for the 10 s idle timeout */
    CHECK(status_while_open(port, "GET /\r\n") == 400, "an HTTP/0.9 request gets its 400 at once");
    CHECK(status_while_open(port, "GET / HTTP/1.1\nHost: localhost\n\n") == 400, "bare LF line ends get their 400 at once");
    CHECK(status_while_open(port, "GET / HTTP/1.1\r\nHost: localhost\r\n\r\n") == 200, "a complete request is answered");
    {
        static char resp[200000];
        const char *req = "GET / HTTP/1.1\r\nHost: localhost\r\n\r\n";
        exchange(port, req, strlen(req), resp, sizeof resp);
        CHECK(strstr(resp, "\r\nContent-Security-Policy: default-src 'self';") != NULL, "no Content-Security-Policy header");
    }
    CHECK(get_status(port, "GET / HTTP/1.1\r\nHost: attacker.example\r\n\r\n") == 403, "foreign Host refused");
    CHECK(get_status(port, "POST / HTTP/1.1\r\n\r\n") == 405, "POST refused");
    int len = snprintf(req, sizeof req, "GET /index.html");
    while (len < 3000) req[len++] = 'a';
    snprintf(req + len, sizeof req - (size_t)len, " HTTP/1.1\r\n\r\n");
    CHECK(get_status(port, req) == 400, "a 3000-byte target is a bad request");

    /* localhost only */
    char other[64];
    other_address(other, sizeof other);
    if (other[0]) {
        int fd = socket(AF_INET, SOCK_STREAM, 0);
        struct sockaddr_in a = { .sin_family = AF_INET, .sin_port = htons((uint16_t)port) };
        inet_pton(AF_INET, other, &a.sin_addr);
        int r = connect(fd, (struct sockaddr *)&a, sizeof a);
        CHECK(r != 0, "the server answered on %s", other);
        close(fd);
        fprintf(stderr, "connect to %s:%d refused, as wanted\n", other, port);
    } else {
        fprintf(stderr, "no non-loopback IPv4 address here; bind address checked only\n");
    }

    /* 1,000 malformed requests, with idle and abandoned connections in between */
    pg_rng rng;
    pg_rng_seed(&rng, 17);
    int answered = 0, bad_status = 0, errors = 0, idle[40];
    struct timespec a0, a1;
    clock_gettime(CLOCK_MONOTONIC, &a0);
    for (int k = 0; k < 40; k++) idle[k] = connect_to(port); /* more than the server's 32 slots */
    for (int k = 0; k < 1000; k++) {
        if (k % 100 == 50) { /* a client that connects, sends a little and vanishes */
            int fd = connect_to(port);
            if (fd >= 0) {
                send(fd, "GET / HT", 8, MSG_NOSIGNAL);
                close(fd);
            }
        }
        size_t len = bad_request(&rng, k, port, req, sizeof req);
        long got = exchange(port, req, len, resp, sizeof resp);
        if (got < 0) {
            errors++;
            continue;
        }
        if (got == 0) continue; /* an incomplete head ends without an answer when the client stops */
        answered++;
        int code = status_of(resp);
        if (!(code == 200 || (code >= 400 && code < 500))) {
            bad_status++;
            fprintf(stderr, "request %d answered '%.40s'\n", k, resp);
        }
    }
    for (int k = 0; k < 40; k++)
        if (idle[k] >= 0) close(idle[k]);
    clock_gettime(CLOCK_MONOTONIC, &a1);
    double secs = (double)(a1.tv_sec - a0.tv_sec) + 1e-9 * (double)(a1.tv_nsec - a0.tv_nsec);
    fprintf(stderr, "1000 malformed requests in %.2f s: %d answered with 4xx/200, %d not answered, %d refused "
                    "connections, %d bad status lines\n", secs, answered, 1000 - answered - errors, errors, bad_status);
    CHECK(errors == 0, "%d connections failed", errors);
    CHECK(bad_status == 0, "%d answers were not HTTP 4xx/200", bad_status);
    CHECK(answered >= 700, "only %d of 1000 answered", answered);
    CHECK(get_status(port, "GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n") == 200, "still serving after the storm");

    atomic_store(&s.stop, 1);
    pthread_join(th, NULL);
    view_http_close(s.server);
    CHECK(view_http_open(70000, &s.server) == PG_ERR_ARG, "port 70000 refused");
    return test_summary("test_view_server");
}
