/* test_view_scene.c - the viewer's scene file and the exports other tools read.
 *
 * 1. view_scene_write on a synthetic 4D set: header, layout size, static/moving split, dropped
 *    invisible Gaussians, --max-gaussians, and every stored value within its quantisation step.
 * 2. On a tiny trained model through the CLI: `export --format ply|splat` (visible Gaussians only,
 *    unit quaternions, cameras.json), `render --camera-path` at the training camera equal to
 *    `render --path dataset-cam`, `view --out` (a self-contained page), and bad input -> exit 2.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/fileutil.h"
#include "core/rng.h"
#include "io/image_io.h"
#include "io/json.h"
#include "io/ply.h"
#include "prodygs.h"
#include "render/scene_cameras.h"
#include "testlib.h"
#include "train_toy.h"
#include "view/view_page.h"
#include "view/view_scene.h"

#define N_ALL 1000
#define N_MOVE 300 /* the last ones drift along x by t */
#define FRAMES 5

static pg_status drift_at(void *ctx, float t, pg_gaussians *out)
{
    const pg_gaussians *g = ctx;
    PG_TRY(splat_gaussians_copy(g, out));
    size_t n = (size_t)g->count;
    for (size_t i = n - N_MOVE; i < n; i++) out->means[3 * i] += t;
    return PG_OK;
}

static uint32_t u32_at(const uint8_t *p) { uint32_t v; memcpy(&v, p, 4); return v; }
static float f32_at(const uint8_t *p) { float v; memcpy(&v, p, 4); return v; }
static size_t pad4(size_t n) { return (n + 3) & ~(size_t)3; }
static size_t block(size_t n) { return pad4(6 * n) + pad4(3 * n) + 8 * n; }

static void check_scene_file(const char *dir)
{
    pg_gaussians g = { 0 };
    CHECK_OK(splat_gaussians_create(&g, N_ALL));
    CHECK_OK(splat_gaussians_resize(&g, N_ALL));
    pg_rng rng;
    pg_rng_seed(&rng, 5);
    uint8_t is_static[N_ALL];
    for (int i = 0; i < N_ALL; i++) {
        for (int k = 0; k < 3; k++) {
            g.means[3 * i + k] = (float)pg_rng_range(&rng, -1, 1);
            g.log_scales[3 * i + k] = (float)pg_rng_range(&rng, -5, -2);
            g.sh[i * 48 + k] = (float)pg_rng_range(&rng, -1.5, 1.5);
        }
        for (int k = 0; k < 4; k++) g.quats[4 * i + k] = (float)pg_rng_range(&rng, -2, 2);
        g.opacity[i] = i % 20 == 0 ? -9.0f : (float)pg_rng_range(&rng, -3, 4); /* every 20th invisible */
        is_static[i] = i < N_ALL - N_MOVE;
    }
    g.log_scales[0] = -200.0f; /* a flat axis as trained models have: clamps, does not spoil the range */
    g.sh_degree = 0;
    char path[1200];
    snprintf(path, sizeof path, "%s/s.pgvs", dir);
    view_scene_source src = { .canonical = &g, .is_static = is_static, .at_time = drift_at, .ctx = &g,
                              .frames = FRAMES, .fps = 30 };
    view_scene_stats st;
    const char *meta = "{\"cameras\": []}";
    CHECK_OK(view_scene_write(path, &src, meta, &st));
    int invisible_static = 0, invisible_moving = 0;
    for (int i = 0; i < N_ALL; i += 20) *(is_static[i] ? &invisible_static : &invisible_moving) += 1;
    CHECK(st.static_count == N_ALL - N_MOVE - invisible_static && st.moving_count == N_MOVE - invisible_moving,
          "static %d moving %d", st.static_count, st.moving_count);
    CHECK(st.dropped == invisible_static + invisible_moving, "dropped %d", st.dropped);
    uint8_t *d = NULL;
    size_t size = 0;
    CHECK_OK(pg_read_file(path, 1 << 26, (char **)&d, &size));
    if (!d) return;
    size_t S = (size_t)st.static_count, M = (size_t)st.moving_count;
    size_t want = 128 + pad4(strlen(meta)) + block(S) + 0 + FRAMES * block(M);
    CHECK(size == want && size == st.bytes, "file %zu bytes, layout %zu, stats %zu", size, want, st.bytes);
    CHECK(memcmp(d, "PGVS", 4) == 0 && u32_at(d + 4) == VIEW_SCENE_VERSION && u32_at(d + 8) == 128 &&
              u32_at(d + 16) == S && u32_at(d + 20) == M && u32_at(d + 24) == FRAMES && u32_at(d + 28) == 0,
          "header");
    CHECK(memcmp(d + 128, meta, strlen(meta)) == 0, "metadata stored as is");
    float bmin[3], bmax[3], ls_lo = f32_at(d + 56), ls_hi = f32_at(d + 60), c_lo = f32_at(d + 64), c_hi = f32_at(d + 68);
    for (int k = 0; k < 3; k++) bmin[k] = f32_at(d + 32 + 4 * k), bmax[k] = f32_at(d + 44 + 4 * k);
    CHECK(ls_hi - ls_lo < 15 && ls_lo > -12, "log-scale range %g..%g", ls_lo, ls_hi);
    CHECK(bmax[0] > 1.9f, "the box covers the movers at t = 1 (x max %g)", bmax[0]);
    /* decode every stored record and compare with the source */
    double worst_pos = 0, worst_col = 0, worst_q = 0, worst_ls = 0;
    const uint8_t *base = d + 128 + pad4(strlen(meta));
    for (int f = -1; f < FRAMES; f++) { /* -1: the static block */
        size_t n = f < 0 ? S : M;
        const uint8_t *b = f < 0 ? base : base + block(S) + (size_t)f * block(M);
        float t = f < 0 ? 0.0f : (float)f / (FRAMES - 1);
        int j = 0;
        for (int i = 0; i < N_ALL && (size_t)j < n; i++) {
            if (g.opacity[i] < -5.54f || (f < 0) != (is_static[i] != 0)) continue;
            const uint16_t *pos = (const uint16_t *)b + 3 * j;
            const uint8_t *ls = b + pad4(6 * n) + 3 * j, *rot = b + pad4(6 * n) + pad4(3 * n) + 4 * j;
            const uint8_t *rgba = b + pad4(6 * n) + pad4(3 * n) + 4 * n + 4 * j;
            for (int k = 0; k < 3; k++) {
                float p = bmin[k] + pos[k] / 65535.0f * (bmax[k] - bmin[k]);
                float want_p = g.means[3 * i + k] + (k == 0 && !is_static[i] ? t : 0.0f);
                worst_pos = fmax(worst_pos, fabs(p - want_p) / (bmax[k] - bmin[k]) * 65535);
                float l = ls_lo + ls[k] / 255.0f * (ls_hi - ls_lo);
                if (g.log_scales[3 * i + k] > ls_lo) worst_ls = fmax(worst_ls, fabs(l - g.log_scales[3 * i + k]) / (ls_hi - ls_lo) * 255);
                float c = c_lo + rgba[k] / 255.0f * (c_hi - c_lo), want_c = 0.5f + 0.28209479f * g.sh[i * 48 + k];
                worst_col = fmax(worst_col, fabs(c - want_c) / (c_hi - c_lo) * 255);
            }
            const float *q = g.quats + 4 * i;
            float len = sqrtf(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]), sg = q[0] < 0 ? -1.0f : 1.0f;
            for (int k = 0; k < 4; k++) worst_q = fmax(worst_q, fabs((rot[k] - 127.5) / 127.5 - sg * q[k] / len) * 127.5);
            CHECK(fabs(rgba[3] / 255.0 - 1 / (1 + exp(-g.opacity[i]))) <= 0.5 / 255 + 1e-6, "opacity of %d", i);
            j++;
        }
        CHECK((size_t)j == n, "block %d: %d records matched, %zu stored", f, j, n);
    }
    fprintf(stderr, "scene file: %zu bytes for %zu static + %zu moving x %d frames; worst error in steps: position %.2f, "
                    "log-scale %.2f, colour %.2f, quaternion %.2f\n", size, S, M, FRAMES, worst_pos, worst_ls, worst_col,
            worst_q);
    CHECK(worst_pos <= 0.51 && worst_ls <= 0.51 && worst_col <= 0.51 && worst_q <= 0.51, "values beyond half a step");
    free(d);

    src.max_gaussians = 100;
    CHECK_OK(view_scene_write(path, &src, meta, &st));
    CHECK(st.static_count + st.moving_count == 100, "max_gaussians kept %d", st.static_count + st.moving_count);
    src.frames = 0;
    CHECK(view_scene_write(path, &src, meta, &st) == PG_ERR_ARG, "0 frames refused");
    splat_gaussians_destroy(&g);
}

static void check_exports(const char *dir, const char *model)
{
    char cmd[8192], err[4096], path[1400];
    snprintf(cmd, sizeof cmd, "export '%s' --out '%s/ex' --times 0.5", model, dir);
    CHECK(test_run_cli(cmd, err, sizeof err) == 0, "export ply: %s", err);
    snprintf(cmd, sizeof cmd, "export '%s' --out '%s/ex' --times 0.5 --format splat", model, dir);
    CHECK(test_run_cli(cmd, err, sizeof err) == 0, "export splat: %s", err);
    snprintf(path, sizeof path, "%s/ex/cameras.json", dir);
    scene_cameras *sc = malloc(sizeof *sc);
    CHECK_OK(scene_cameras_load(path, sc));
    { /* a frame count no int holds is refused in one line (fuzz_trainset: UB casting 3e62 to int) */
        cJSON *root = NULL;
        char bad[1500];
        snprintf(bad, sizeof bad, "%s/ex/cameras_bad.json", dir);
        CHECK_OK(io_json_load(path, &root));
        if (root) {
            cJSON_ReplaceItemInObject(root, "frames", cJSON_CreateNumber(3e62));
            CHECK_OK(io_json_write_atomic(bad, root));
            cJSON_Delete(root);
            CHECK(scene_cameras_load(bad, sc) == PG_ERR_FORMAT && strstr(pg_last_error(), "cameras_bad.json") &&
                      strstr(pg_last_error(), "frames") && !strchr(pg_last_error(), '\n'),
                  "frames 3e62: %s", pg_last_error());
        }
        CHECK_OK(scene_cameras_load(path, sc));
    }
    pg_gaussians g = { 0 };
    snprintf(path, sizeof path, "%s/ex/time_0.500.ply", dir);
    CHECK_OK(io_ply_load(path, &g));
    double worst_q = 0, min_opacity = 1e9;
    for (int i = 0; i < g.count; i++) {
        const float *q = g.quats + 4 * i;
        worst_q = fmax(worst_q, fabs(sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]) - 1));
        min_opacity = fmin(min_opacity, 1 / (1 + exp(-g.opacity[i])));
    }
    CHECK(g.count > 0 && worst_q < 1e-5 && min_opacity >= 1.0 / 255 - 1e-6, "PLY: %d Gaussians, |q| off by %g, "
          "opacity min %g", g.count, worst_q, min_opacity);
    char *splat = NULL;
    size_t size = 0;
    snprintf(path, sizeof path, "%s/ex/time_0.500.splat", dir);
    CHECK_OK(pg_read_file(path, 1 << 28, &splat, &size));
    CHECK(size == (size_t)g.count * 32, ".splat holds %zu bytes for %d Gaussians", size, g.count);
    if (splat && size == (size_t)g.count * 32 && g.count > 0) { /* row 0 against the PLY's */
        float row[6];
        memcpy(row, splat, sizeof row);
        const uint8_t *u = (const uint8_t *)splat + 24;
        CHECK(row[0] == g.means[0] && fabsf(row[3] - expf(g.log_scales[0])) <= 1e-6f * fmaxf(1, row[3]) &&
                  abs(u[3] - (int)lround(255 / (1 + exp(-g.opacity[0])))) <= 1 &&
                  abs(u[4] - (int)lround(g.quats[0] * 128 + 128)) <= 1,
              ".splat row 0 disagrees with the PLY");
    }
    free(splat);
    splat_gaussians_destroy(&g);

    /* a camera_path.json at the training camera (OpenGL axes, as nerfstudio writes) */
    const pg_camera *c = &sc->cams[sc->real];
    float C[3];
    pg_camera_center(c, C);
    double fov = 2 * atan(0.5 * c->height / c->fy) * 180 / 3.14159265358979323846;
    FILE *fp = fopen((snprintf(path, sizeof path, "%s/shot.json", dir), path), "w");
    fprintf(fp, "{\"render_width\": %d, \"render_height\": %d, \"camera_path\": [", c->width, c->height);
    for (int k = 0; k < 2; k++) {
        fprintf(fp, "%s{\"fov\": %.9g, \"time\": %d, \"camera_to_world\": [", k ? ", " : "", fov, k);
        for (int r = 0; r < 3; r++) /* columns: x, -y, -z camera axes in the world; then the centre */
            fprintf(fp, "%.9g, %.9g, %.9g, %.9g, ", c->R[r], -c->R[3 + r], -c->R[6 + r], C[r]);
        fprintf(fp, "0, 0, 0, 1]}");
    }
    fprintf(fp, "]}\n");
    fclose(fp);
    snprintf(cmd, sizeof cmd, "render '%s' --out '%s/r' --camera-path '%s' --png --no-depth", model, dir, path);
    CHECK(test_run_cli(cmd, err, sizeof err) == 0, "render --camera-path: %s", err);
    snprintf(cmd, sizeof cmd, "render '%s' --out '%s/r' --path dataset-cam --camera %s --png --no-depth", model, dir,
             sc->names[sc->real]);
    CHECK(test_run_cli(cmd, err, sizeof err) == 0, "render dataset-cam: %s", err);
    pg_image a = { 0 }, b = { 0 };
    char pa[1400], pb[1400];
    snprintf(pa, sizeof pa, "%s/r/camera_path/0001.png", dir);
    snprintf(pb, sizeof pb, "%s/r/%s/0002.png", dir, sc->names[sc->real]); /* t = 1 of 3 frames */
    CHECK_OK(io_image_load(pa, &a));
    CHECK_OK(io_image_load(pb, &b));
    double worst = 0;
    for (size_t i = 0; a.data && b.data && a.width == b.width && i < (size_t)a.width * a.height * 3; i++)
        worst = fmax(worst, fabs(a.data[i] - b.data[i]));
    CHECK(a.width == b.width && a.height == b.height && worst <= 2.0 / 255, "camera path vs dataset camera: %g", worst);
    pg_image_destroy(&a);
    pg_image_destroy(&b);
    snprintf(cmd, sizeof cmd, "render '%s' --out '%s/r2' --camera-path '%s' --size 40x0 --png --no-depth", model, dir, path);
    CHECK(test_run_cli(cmd, err, sizeof err) == 0, "render --size: %s", err);
    snprintf(pa, sizeof pa, "%s/r2/camera_path/0000.png", dir);
    CHECK_OK(io_image_load(pa, &a));
    CHECK(a.width == 40 && a.height == 30, "--size 40x0 gave %dx%d", a.width, a.height);
    pg_image_destroy(&a);
    FILE *bad = fopen((snprintf(path, sizeof path, "%s/bad.json", dir), path), "w");
    fprintf(bad, "{\"camera_path\": [{\"camera_to_world\": [1, 0, 0]}]}");
    fclose(bad);
    snprintf(cmd, sizeof cmd, "render '%s' --out '%s/r' --camera-path '%s'", model, dir, path);
    CHECK(test_run_cli(cmd, err, sizeof err) == 2 && strstr(err, "bad.json") && strstr(err, "camera_to_world"),
          "bad camera path: %s", err);
    snprintf(cmd, sizeof cmd, "export '%s' --out '%s/ex' --format obj", model, dir);
    CHECK(test_run_cli(cmd, err, sizeof err) == 2 && strstr(err, "--format"), "bad format: %s", err);
    free(sc);
}

static void check_view_dir(const char *dir, const char *model)
{
    char cmd[8192], err[4096], path[1400];
    snprintf(cmd, sizeof cmd, "view '%s' --out '%s/v' --frames 4", model, dir);
    CHECK(test_run_cli(cmd, err, sizeof err) == 0, "view --out: %s", err);
    char *html = NULL, *scene = NULL;
    size_t hs = 0, ss = 0;
    snprintf(path, sizeof path, "%s/v/index.html", dir);
    CHECK_OK(pg_read_file(path, 1 << 24, &html, &hs));
    snprintf(path, sizeof path, "%s/v/scene.pgvs", dir);
    CHECK_OK(pg_read_file(path, 1 << 28, &scene, &ss));
    CHECK(html && hs == view_page_html_size && strncmp(html, "<!doctype html>", 15) == 0, "index.html is the page");
    CHECK(html && !strstr(html, "://") && !strstr(html, "<link") && !strstr(html, "import "), "the page loads nothing");
    CHECK(scene && ss > 128 && memcmp(scene, "PGVS", 4) == 0 && u32_at((uint8_t *)scene + 24) == 4, "scene.pgvs");
    free(html);
    free(scene);
    snprintf(cmd, sizeof cmd, "view '%s/nothing' --out '%s/v'", dir, dir);
    CHECK(test_run_cli(cmd, err, sizeof err) == 2 && strstr(err, "nothing"), "missing model: %s", err);
    snprintf(cmd, sizeof cmd, "view '%s' --port 99999", model);
    CHECK(test_run_cli(cmd, err, sizeof err) == 2, "bad port: %s", err);
}

int main(void)
{
    char dir[1024], model[1200];
    test_tmpdir("test_view_scene", dir, sizeof dir);
    check_scene_file(dir);
    CHECK_OK(toy_train_model(dir, 48, 36, 3, 2, 24, 1000, 0, 1, model, sizeof model));
    check_exports(dir, model);
    check_view_dir(dir, model);
    return test_summary("test_view_scene");
}
