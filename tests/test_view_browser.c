/* test_view_browser.c - the web viewer in headless Chromium (WebGL2 on SwiftShader).
 *
 * 1. `prodygs view MODEL --port 0` serves a model's viewer; the page's shot mode
 *    (?shot=1&camera=train&times=0,1) draws the training camera at t = 0 and 1 and logs the
 *    canvases as PNG; they are compared with the CPU renderer (what `prodygs render` draws)
 *    over the pixels the model covers, and t = 0 vs 1 must differ where the scene moves.
 * 2. A 200k-Gaussian scene (20 % moving) is played and orbited for 3 s (?bench=3): load time and
 *    frames per second.
 * MODEL is $PG_VIEW_MODEL (e.g. the demo's model) or a toy model trained here in seconds.
 * $PG_VIEW_SCREENSHOT=FILE also saves a screenshot of the interactive page (docs/viewer.png).
 * Skips (77) when no Chromium is installed.
 */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <cjson/cJSON.h>

#include "core/fileutil.h"
#include "io/image_io.h"
#include "io/json.h"
#include "prodygs.h"
#include "render/model_render.h"
#include "render/scene_cameras.h"
#include "splat/random_scene.h"
#include "testlib.h"
#include "train_toy.h"
#include "view/http_server.h"
#include "view/view_page.h"
#include "view/view_scene.h"

#define SKIP 77
#define BROWSER_SECONDS 90

static const char *find_chromium(char *out, size_t size)
{
    const char *env = getenv("PG_CHROMIUM");
    if (env && *env) return access(env, X_OK) == 0 ? env : NULL;
    static const char *names[] = { "chromium", "chromium-browser", "google-chrome" };
    const char *path = getenv("PATH");
    for (int k = 0; k < 3; k++) {
        char dirs[4096];
        snprintf(dirs, sizeof dirs, "%s", path ? path : "/usr/bin");
        for (char *d = strtok(dirs, ":"); d; d = strtok(NULL, ":")) {
            snprintf(out, size, "%s/%s", d, names[k]);
            if (access(out, X_OK) == 0) return out;
        }
    }
    return NULL;
}

/* Runs argv with stdout (or stderr) into a pipe; returns the read end, the pid in *pid. */
static int spawn(char *const argv[], int want_stderr, pid_t *pid)
{
    int fd[2];
    if (pipe(fd) != 0) return -1;
    *pid = fork();
    if (*pid == 0) {
        setpgid(0, 0); /* its own group, so its helpers end with it */
        int null = open("/dev/null", O_RDWR);
        dup2(null, 0);
        dup2(want_stderr ? null : fd[1], 1);
        dup2(want_stderr ? fd[1] : null, 2);
        close(fd[0]);
        execvp(argv[0], argv);
        _exit(127);
    }
    close(fd[1]);
    return fd[0];
}

static void stop_group(pid_t pid)
{
    if (pid <= 0) return;
    kill(-pid, SIGKILL);
    kill(pid, SIGKILL);
    waitpid(pid, NULL, 0);
}

/* Reads fd until a line holding `key` arrives (or EOF / the deadline); returns that line (malloc'd). */
static char *read_line_with(int fd, const char *key, double seconds)
{
    size_t cap = 1 << 20, len = 0;
    char *buf = malloc(cap);
    time_t end = time(NULL) + (time_t)seconds;
    while (buf && time(NULL) < end) {
        struct pollfd p = { fd, POLLIN, 0 };
        if (poll(&p, 1, 500) <= 0) continue;
        if (len + 65536 + 1 > cap) {
            char *b = realloc(buf, cap *= 2);
            if (!b) break;
            buf = b;
        }
        ssize_t r = read(fd, buf + len, 65536);
        if (r <= 0) break;
        len += (size_t)r;
        buf[len] = '\0';
        char *hit = strstr(buf, key);
        if (hit) {
            char *nl = strchr(hit, '\n');
            if (!nl) continue; /* the line is not complete yet */
            *nl = '\0';
            char *line = strdup(hit);
            free(buf);
            return line;
        }
    }
    free(buf);
    return NULL;
}

/* Opens url in headless Chromium and returns the page's report (the JSON after "PGVIEW "). */
static cJSON *browse(const char *chromium, const char *url, const char *window, const char *tmp)
{
    char profile[1200], win[64];
    snprintf(profile, sizeof profile, "--user-data-dir=%s/chromium-profile", tmp);
    snprintf(win, sizeof win, "--window-size=%s", window);
    char *argv[] = { (char *)chromium, "--headless", "--no-sandbox", "--use-angle=swiftshader",
                     "--enable-unsafe-swiftshader", "--enable-logging=stderr", "--v=0", "--no-first-run",
                     "--disable-extensions", "--disable-background-networking", profile, win, (char *)url, NULL };
    pid_t pid;
    int fd = spawn(argv, 1, &pid);
    char *line = fd >= 0 ? read_line_with(fd, "PGVIEW ", BROWSER_SECONDS) : NULL;
    stop_group(pid);
    if (fd >= 0) close(fd);
    if (!line) return NULL;
    char *start = strstr(line, "PGVIEW ") + 7, *end = strrchr(line, '}');
    cJSON *j = NULL;
    if (end && end > start) {
        end[1] = '\0';
        j = cJSON_Parse(start);
    }
    free(line);
    return j;
}

static int b64_value(int c)
{
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    return c == '+' ? 62 : c == '/' ? 63 : -1;
}

/* A data:image/png;base64 URL -> an image (via a temporary file). */
static pg_status load_data_url(const char *url, const char *file, pg_image *img)
{
    const char *p = strstr(url, "base64,");
    if (!p) return pg_fail(PG_ERR_FORMAT, "not a base64 data URL");
    p += 7;
    size_t n = strlen(p), len = 0;
    unsigned char *bytes = malloc(n);
    unsigned acc = 0;
    int bits = 0;
    for (size_t i = 0; bytes && i < n; i++) {
        int v = b64_value(p[i]);
        if (v < 0) continue;
        acc = (acc << 6) | (unsigned)v;
        bits += 6;
        if (bits >= 8) {
            bits -= 8;
            bytes[len++] = (unsigned char)(acc >> bits);
        }
    }
    pg_status st = bytes ? pg_write_file_atomic(file, bytes, len) : PG_ERR_NOMEM;
    free(bytes);
    return st ? st : io_image_load(file, img);
}

static double clamp01(double v) { return v < 0 ? 0 : v > 1 ? 1 : v; }

/* PSNR of a vs the float render over pixels with alpha > 0.5 (both as 8-bit values). */
static double masked_psnr(const pg_image *a, const float *ref, const float *alpha, int *count)
{
    double se = 0;
    size_t n = 0, px = (size_t)a->width * a->height;
    for (size_t i = 0; i < px; i++) {
        if (!(alpha[i] > 0.5f)) continue;
        for (int c = 0; c < 3; c++) {
            double d = round(255 * clamp01(a->data[3 * i + c])) - round(255 * clamp01(ref[3 * i + c]));
            se += d * d;
        }
        n += 3;
    }
    *count = (int)(n / 3);
    return n ? 10 * log10(255.0 * 255.0 / (se / (double)n + 1e-12)) : 0;
}

#define LARGER 3 /* the viewer's canvas at 3x the training camera's size */

/* The viewer at LARGER x the training size against the CPU render of the camera scaled alike:
 * both draw with a training pixel's screen-space filter (splat_lowpass_for), so the viewer must be
 * clearly closer to that render than to one with the output pixel's filter (49.3 vs 44.2 dB). */
static void check_larger_shot(const cJSON *rep, render_model *rm, const pg_camera *cam, const char *tmp)
{
    const cJSON *shots = cJSON_GetObjectItem(rep, "shots");
    CHECK(cJSON_GetArraySize(shots) == 1, "expected 1 shot at %dx", LARGER);
    if (cJSON_GetArraySize(shots) != 1) return;
    char file[1300];
    snprintf(file, sizeof file, "%s/shot_x%d.png", tmp, LARGER);
    pg_image shot = { 0 };
    CHECK_OK(load_data_url(cJSON_GetStringValue(cJSON_GetObjectItem(cJSON_GetArrayItem(shots, 0), "png")), file, &shot));
    pg_camera big = *cam;
    pg_camera_resize(&big, LARGER * cam->width, LARGER * cam->height);
    CHECK(shot.width == big.width && shot.height == big.height, "shot %dx%d, camera %dx%d", shot.width, shot.height,
          big.width, big.height);
    pg_render_output out;
    CHECK_OK(render_model_frame(rm, &big, 0.5f, &out));
    if (shot.width == big.width && shot.height == big.height) {
        size_t px = (size_t)big.width * big.height;
        float *ref = malloc(px * 3 * sizeof(float)), *alpha = malloc(px * sizeof(float));
        memcpy(ref, out.rgb, px * 3 * sizeof(float));
        memcpy(alpha, out.alpha, px * sizeof(float));
        int covered;
        double psnr = masked_psnr(&shot, ref, alpha, &covered);
        const pg_gaussians *g;
        splat_raster *plain = NULL;
        double psnr_plain = 0;
        CHECK_OK(render_model_gaussians_at(rm, 0.5f, &g));
        CHECK_OK(splat_raster_create(&plain));
        pg_render_settings s = splat_default_settings();
        if (plain && splat_render_forward(plain, g, &big, &s, &out) == PG_OK) {
            int c2;
            psnr_plain = masked_psnr(&shot, out.rgb, alpha, &c2);
        }
        splat_raster_destroy(plain);
        fprintf(stderr, "viewer vs render at %dx the training camera, t = 0.5: PSNR %.2f dB over %d covered pixels "
                        "(against the output pixel's filter: %.2f)\n", LARGER, psnr, covered, psnr_plain);
        CHECK(psnr >= 28.0, "PSNR %.2f dB at %dx (>= 28 wanted)", psnr, LARGER);
        CHECK(psnr >= psnr_plain + 2.0, "the viewer at %dx is as close to the output pixel's filter (%.2f dB) as to the "
              "training pixel's (%.2f)", LARGER, psnr_plain, psnr);
        free(ref);
        free(alpha);
    }
    pg_image_destroy(&shot);
}

/* Part 1: screenshots of the model's viewer against the CPU renderer. */
static void check_model(const char *chromium, const char *model, const char *tmp)
{
    char cli[1200];
    snprintf(cli, sizeof cli, "%s", PG_CLI_PATH);
    char *argv[] = { cli, "view", (char *)model, "--port", "0", NULL };
    pid_t server;
    int fd = spawn(argv, 0, &server);
    char *line = fd >= 0 ? read_line_with(fd, "\"url\"", 120) : NULL;
    CHECK(line != NULL, "prodygs view printed no URL");
    char url[256] = "", *u = line ? strstr(line, "http://") : NULL;
    if (u) snprintf(url, sizeof url, "%.*s", (int)strcspn(u, "\""), u);
    free(line);
    char page[512];
    snprintf(page, sizeof page, "%s?shot=1&camera=train&times=0,1", url);
    cJSON *rep = u ? browse(chromium, page, "400,300", tmp) : NULL;
    CHECK(rep != NULL, "no report from the page %s", page);
    snprintf(page, sizeof page, "%s?shot=1&camera=train&times=0.5&scale=%d", url, LARGER);
    cJSON *rep_larger = u ? browse(chromium, page, "400,300", tmp) : NULL;
    CHECK(rep_larger != NULL, "no report from the page %s", page);
    const char *screenshot = getenv("PG_VIEW_SCREENSHOT");
    if (u && screenshot && *screenshot) { /* the interactive page, for the README */
        char shot_arg[1200], view_url[512];
        snprintf(shot_arg, sizeof shot_arg, "--screenshot=%s", screenshot);
        snprintf(view_url, sizeof view_url, "%s?time=0.5", url);
        char *sargv[] = { (char *)chromium, "--headless", "--no-sandbox", "--use-angle=swiftshader",
                          "--enable-unsafe-swiftshader", "--window-size=960,640", "--virtual-time-budget=20000",
                          "--hide-scrollbars", shot_arg, view_url, NULL };
        pid_t pid;
        int sfd = spawn(sargv, 1, &pid);
        int status = 0;
        waitpid(pid, &status, 0);
        if (sfd >= 0) close(sfd);
        fprintf(stderr, "screenshot %s: %s\n", screenshot, pg_path_exists(screenshot) ? "written" : "FAILED");
    }
    stop_group(server);
    if (fd >= 0) close(fd);
    if (!rep) {
        cJSON_Delete(rep_larger);
        return;
    }
    const cJSON *err = cJSON_GetObjectItem(rep, "error");
    CHECK(!err, "page error: %s", cJSON_GetStringValue(err));
    const cJSON *shots = cJSON_GetObjectItem(rep, "shots");
    double load_ms = io_json_number_or(rep, "load_ms", -1);
    fprintf(stderr, "model: %d Gaussians (%d moving), scene %.1f MB, ready in %.0f ms (WebGL context %.0f, fetch %.0f, "
                    "decode + upload %.0f)\n", (int)io_json_number_or(rep, "n", 0), (int)io_json_number_or(rep, "moving", 0),
            io_json_number_or(rep, "bytes", 0) / 1048576.0, load_ms, io_json_number_or(rep, "webgl_ms", -1),
            io_json_number_or(rep, "fetch_ms", -1), io_json_number_or(rep, "decode_ms", -1));
    CHECK(cJSON_GetArraySize(shots) == 2, "expected 2 shots");
    scene_cameras *sc = malloc(sizeof *sc);
    render_model *rm = NULL;
    CHECK_OK(scene_cameras_for_model(model, NULL, sc));
    CHECK_OK(render_model_open(model, &rm));
    pg_image shot[2] = { { 0 } };
    float *ref[2] = { NULL, NULL }, *alpha = NULL;
    const pg_camera *cam = &sc->cams[sc->real];
    size_t px = (size_t)cam->width * cam->height;
    for (int k = 0; rm && k < 2 && cJSON_GetArraySize(shots) == 2; k++) {
        char file[1300];
        snprintf(file, sizeof file, "%s/shot_t%d.png", tmp, k);
        CHECK_OK(load_data_url(cJSON_GetStringValue(cJSON_GetObjectItem(cJSON_GetArrayItem(shots, k), "png")), file,
                               &shot[k]));
        pg_render_output out;
        CHECK_OK(render_model_frame(rm, cam, (float)k, &out));
        CHECK(shot[k].width == cam->width && shot[k].height == cam->height, "shot %dx%d, camera %dx%d", shot[k].width,
              shot[k].height, cam->width, cam->height);
        ref[k] = malloc(px * 3 * sizeof(float));
        memcpy(ref[k], out.rgb, px * 3 * sizeof(float));
        if (k == 0) {
            alpha = malloc(px * sizeof(float));
            memcpy(alpha, out.alpha, px * sizeof(float));
        }
        if (shot[k].width != cam->width || shot[k].height != cam->height) continue;
        int covered;
        double psnr = masked_psnr(&shot[k], ref[k], alpha, &covered);
        fprintf(stderr, "viewer vs render at the training camera, t = %d: PSNR %.2f dB over %d covered pixels\n", k,
                psnr, covered);
        CHECK(psnr >= 28.0, "PSNR %.2f dB at t = %d (>= 28 wanted)", psnr, k);
        CHECK(covered > (int)(px / 4), "only %d of %zu pixels covered", covered, px);
    }
    if (ref[1] && shot[1].data && shot[0].width == cam->width && shot[1].width == cam->width) {
        /* moving = where the render changes between t = 0 and 1; the viewer must change there */
        double mov = 0, sta = 0;
        size_t nm = 0, ns = 0;
        for (size_t i = 0; i < px; i++) {
            float dr = 0, dv = 0;
            for (int c = 0; c < 3; c++) {
                dr = fmaxf(dr, fabsf(ref[1][3 * i + c] - ref[0][3 * i + c]));
                dv += fabsf(shot[1].data[3 * i + c] - shot[0].data[3 * i + c]) / 3;
            }
            if (dr > 0.1f) mov += dv, nm++;
            else if (dr < 0.02f) sta += dv, ns++;
        }
        double ratio = (mov / (nm ? nm : 1)) / (sta / (ns ? ns : 1) + 1e-6);
        fprintf(stderr, "t = 0 vs 1 in the viewer: mean |difference| %.4f on %zu moving pixels, %.4f on %zu static: "
                        "ratio %.1f\n", mov / (nm ? nm : 1), nm, sta / (ns ? ns : 1), ns, ratio);
        CHECK(nm > 20, "the model does not move (%zu moving pixels)", nm);
        CHECK(ratio >= 5.0, "moving/static difference ratio %.2f (>= 5 wanted)", ratio);
    }
    if (rm && rep_larger) check_larger_shot(rep_larger, rm, cam, tmp);
    cJSON_Delete(rep_larger);
    CHECK(load_ms > 0 && load_ms < 5000, "scene load took %.0f ms", load_ms);
    for (int k = 0; k < 2; k++) {
        pg_image_destroy(&shot[k]);
        free(ref[k]);
    }
    free(alpha);
    render_model_close(rm);
    free(sc);
    cJSON_Delete(rep);
}

/* The bench scene: random Gaussians; the last fifth drift sideways over time. */
typedef struct {
    const pg_gaussians *g;
} drift;

static pg_status drift_at(void *ctx, float t, pg_gaussians *out)
{
    const pg_gaussians *g = ((drift *)ctx)->g;
    PG_TRY(splat_gaussians_copy(g, out));
    size_t n = (size_t)g->count;
    for (size_t i = n - n / 5; i < n; i++) out->means[3 * i] += 0.5f * t;
    return PG_OK;
}

typedef struct {
    view_http_server *server;
    view_http_file files[2];
    atomic_int stop;
} server_thread;

static void *serve_thread(void *arg)
{
    server_thread *s = arg;
    view_http_serve(s->server, s->files, 2, 0, &s->stop);
    return NULL;
}

/* Part 2: frames per second with 200k Gaussians. */
static void check_bench(const char *chromium, const char *tmp)
{
    const int N = 200000, W = 640, H = 480;
    pg_camera cam;
    pg_camera_from_fov(&cam, W, H, 60.0f);
    pg_gaussians g = { 0 };
    CHECK_OK(splat_gaussians_create(&g, N));
    CHECK_OK(splat_random_scene(&g, &cam, N, 1.5f, 1, 11));
    uint8_t *is_static = malloc((size_t)N);
    for (int i = 0; i < N; i++) is_static[i] = i < N - N / 5;
    drift d = { &g };
    view_scene_source src = { .canonical = &g, .is_static = is_static, .at_time = drift_at, .ctx = &d,
                              .frames = 30, .fps = 30 };
    char dir[1200], path[1300];
    snprintf(dir, sizeof dir, "%s/bench", tmp);
    CHECK_OK(pg_mkdir_p(dir));
    cJSON *meta = cJSON_CreateObject(), *cams = cJSON_CreateArray(), *c = io_json_from_camera(&cam, "bench");
    cJSON_AddStringToObject(c, "role", "real");
    cJSON_AddItemToArray(cams, c);
    cJSON_AddItemToObject(meta, "cameras", cams);
    cJSON_AddNumberToObject(meta, "home", 0);
    float center[3] = { 0, 0, 6 };
    cJSON_AddItemToObject(meta, "center", io_json_float_array(center, 3));
    cJSON_AddNumberToObject(meta, "video_frames", 30);
    char *meta_text = cJSON_PrintUnformatted(meta);
    view_scene_stats ss;
    snprintf(path, sizeof path, "%s/scene.pgvs", dir);
    CHECK_OK(view_scene_write(path, &src, meta_text, &ss));
    char *scene = NULL;
    size_t scene_size = 0;
    CHECK_OK(pg_read_file(path, (size_t)1 << 30, &scene, &scene_size));
    server_thread st = { .files = { { "/", "text/html", view_page_html, view_page_html_size },
                                    { "/scene.pgvs", "application/octet-stream", scene, scene_size } } };
    atomic_init(&st.stop, 0);
    CHECK_OK(view_http_open(0, &st.server));
    pthread_t th;
    int started = st.server && pthread_create(&th, NULL, serve_thread, &st) == 0;
    char url[128];
    snprintf(url, sizeof url, "http://127.0.0.1:%d/?bench=3", st.server ? view_http_port(st.server) : 0);
    cJSON *rep = started ? browse(chromium, url, "800,600", tmp) : NULL;
    CHECK(rep != NULL, "no report from the bench page");
    if (rep) {
        double fps = io_json_number_or(rep, "fps", 0), load = io_json_number_or(rep, "load_ms", -1);
        fprintf(stderr, "bench: %d Gaussians (%d moving), scene %.1f MB, load %.0f ms, %.1f fps over %d frames "
                        "(draw + finish %.1f ms) at 800x600 in headless Chromium / SwiftShader\n",
                (int)io_json_number_or(rep, "n", 0), (int)io_json_number_or(rep, "moving", 0), (double)ss.bytes / 1048576.0,
                load, fps, (int)io_json_number_or(rep, "bench_frames", 0), io_json_number_or(rep, "draw_ms", 0));
        CHECK(io_json_number_or(rep, "n", 0) == ss.static_count + ss.moving_count, "page saw a different count");
        CHECK(fps > 0 && io_json_number_or(rep, "bench_frames", 0) >= 1, "the page drew no frames"); /* 1: a loaded machine */
        CHECK(!cJSON_GetObjectItem(rep, "error"), "page error");
    }
    if (started) {
        atomic_store(&st.stop, 1);
        pthread_join(th, NULL);
    }
    view_http_close(st.server);
    cJSON_Delete(rep);
    cJSON_Delete(meta);
    cJSON_free(meta_text);
    free(scene);
    free(is_static);
    splat_gaussians_destroy(&g);
}

int main(void)
{
    char exe[1024];
    const char *chromium = find_chromium(exe, sizeof exe);
    if (!chromium) {
        fprintf(stderr, "SKIP: no chromium found (apt-get install chromium, or set PG_CHROMIUM)\n");
        return SKIP;
    }
    char dir[1024], model[1200];
    test_tmpdir("test_view_browser", dir, sizeof dir);
    const char *given = getenv("PG_VIEW_MODEL");
    if (given && *given) snprintf(model, sizeof model, "%s", given);
    else CHECK_OK(toy_train_model(dir, 96, 72, 5, 3, 300, 3000, 6000, 3, model, sizeof model));
    check_model(chromium, model, dir);
    if (!getenv("PG_VIEW_NO_BENCH")) check_bench(chromium, dir);
    return test_summary("test_view_browser");
}
