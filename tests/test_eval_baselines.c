/* test_eval_baselines.c - the report's yardsticks: the 2.5D warp (geometry, background fill) and
 * the report's verdict beside a flat image that must lose in one case and win in the other. */
#include "testlib.h"
#include "core/fileutil.h"
#include "eval/baselines.h"
#include "eval/metrics.h"
#include "eval/report.h"
#include "io/json.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { W = 64, H = 48 };

/* The scene: a textured wall at z = 4 and a red box |X|, |Y| < 0.5 at z = 2. Colour and depth of
 * the ray through pixel (x, y) of camera c. */
static float scene_ray(const pg_camera *c, int x, int y, int with_box, float rgb[3])
{
    float X[3], C[3], dir[3];
    pg_camera_center(c, C);
    pg_camera_unproject(c, x + 0.5f, y + 0.5f, 1.0f, X);
    for (int k = 0; k < 3; k++) dir[k] = X[k] - C[k];
    float tb = (2.0f - C[2]) / dir[2], bx = C[0] + tb * dir[0], by = C[1] + tb * dir[1];
    if (with_box && fabsf(bx) < 0.5f && fabsf(by) < 0.5f) {
        rgb[0] = 0.9f, rgb[1] = 0.1f, rgb[2] = 0.1f;
        return 2.0f - C[2];
    }
    float tw = (4.0f - C[2]) / dir[2], wx = C[0] + tw * dir[0], wy = C[1] + tw * dir[1];
    for (int k = 0; k < 3; k++) rgb[k] = 0.5f + 0.3f * sinf(3.0f * wx + k) * cosf(2.0f * wy);
    return 4.0f - C[2];
}

static void render_scene(const pg_camera *c, int with_box, float *rgb, float *depth)
{
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            float z = scene_ray(c, x, y, with_box, rgb + 3 * ((size_t)y * W + x));
            if (depth) depth[(size_t)y * W + x] = z;
        }
}

static double psnr_rows(const float *a, const float *b, int x0, int x1)
{
    double se = 0;
    long n = 0;
    for (int y = 0; y < H; y++)
        for (int x = x0; x < x1; x++)
            for (int c = 0; c < 3; c++, n++) {
                double d = a[3 * ((size_t)y * W + x) + c] - b[3 * ((size_t)y * W + x) + c];
                se += d * d;
            }
    return se > 0 ? -10 * log10(se / n) : 200;
}

/* Warp of the real view into a camera 0.3 to the right: the wall matches the truth where the real
 * camera saw it, the strip the box uncovers shows the wall (not the red box), and no pixel is left
 * black. */
static void test_warp(void)
{
    pg_camera real, dst;
    pg_camera_from_fov(&real, W, H, 60);
    dst = real;
    dst.t[0] = -0.3f; /* centre at x = +0.3 */
    float *rgb = malloc(sizeof(float) * 3 * W * H), *depth = malloc(sizeof(float) * W * H);
    float *truth = malloc(sizeof(float) * 3 * W * H), *out = malloc(sizeof(float) * 3 * W * H);
    render_scene(&real, 0, rgb, depth);
    render_scene(&dst, 0, truth, NULL);
    const float grey[3] = { 0.5f, 0.5f, 0.5f };
    CHECK_OK(eval_warp_baseline(&real, rgb, depth, &dst, grey, out));
    /* the left 3/4 of dst sees what the real camera saw; the right border came from the row fill */
    double seen = psnr_rows(out, truth, 2, 3 * W / 4);
    CHECK(seen > 26.0, "warp of a wall: %.2f dB on the seen part", seen);

    render_scene(&real, 1, rgb, depth);
    render_scene(&dst, 1, truth, NULL);
    CHECK_OK(eval_warp_baseline(&real, rgb, depth, &dst, grey, out));
    int red = 0, black = 0, hole_px = 0;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            const float *p = out + 3 * ((size_t)y * W + x);
            black += p[0] == 0 && p[1] == 0 && p[2] == 0;
            float tr[3], rr[3];
            /* a pixel of dst that shows wall the real camera had behind the box */
            if (scene_ray(&dst, x, y, 1, tr) < 3.0f) continue;
            float X[3], uv[2];
            pg_camera_unproject(&dst, x + 0.5f, y + 0.5f, 4.0f, X);
            pg_camera_project(&real, X, uv);
            int rx = (int)uv[0], ry = (int)uv[1];
            if (rx < 0 || ry < 0 || rx >= W || ry >= H || scene_ray(&real, rx, ry, 1, rr) > 3.0f) continue;
            hole_px++;
            red += p[0] > 0.8f && p[1] < 0.2f;
        }
    CHECK(black == 0, "%d warp pixels left black", black);
    CHECK(hole_px > 20 && red * 10 < hole_px, "disoccluded strip: %d of %d pixels took the box's red", red, hole_px);
    free(rgb), free(depth), free(truth), free(out);
}

/* A record of `psnr` dB at camera cam, frame f, with a moving region of the same error. */
static void add_record(eval_results *r, const char *cam, eval_role role, int f, double psnr)
{
    eval_scores s;
    memset(&s, 0, sizeof s);
    s.psnr = psnr, s.ssim = 0.5;
    s.region[EVAL_MOVING].pixels = 100;
    s.region[EVAL_MOVING].total = 1000;
    s.region[EVAL_MOVING].sse = 300 * pow(10, -psnr / 10);
    CHECK_OK(eval_results_add(r, cam, role, f, &s));
}

/* The report and metrics.json with a model at model_db against baselines at 18 (flat), 17 (as is)
 * and 20 dB (warp); returns report.md's text (malloc'd) and checks the JSON's margins. */
static char *report_for(const char *dir, double model_db)
{
    eval_results r = { 0 };
    r.baseline = calloc(EVAL_BASELINES, sizeof *r.baseline);
    const double base_db[EVAL_BASELINES] = { 18, 17, 20 };
    for (int f = 0; f < 2; f++) {
        add_record(&r, "cam00", EVAL_ROLE_TRAIN, f, 40);
        add_record(&r, "cam05", EVAL_ROLE_TEST, f, model_db);
        for (int b = 0; b < EVAL_BASELINES; b++) add_record(&r.baseline[b], "cam05", EVAL_ROLE_TEST, f, base_db[b]);
    }
    char path[1200];
    snprintf(path, sizeof path, "%s/metrics.json", dir);
    CHECK_OK(eval_write_metrics_json(path, &r, NULL, NULL));
    cJSON *m = NULL;
    CHECK_OK(io_json_load(path, &m));
    const cJSON *margin = cJSON_GetObjectItem(m, "margin_db");
    double flat = io_json_number_or(margin, "flat", NAN), warp = io_json_number_or(margin, "warp", NAN);
    CHECK(fabs(flat - (model_db - 18)) < 1e-9 && fabs(warp - (model_db - 20)) < 1e-9, "margins %g / %g", flat, warp);
    const cJSON *bf = cJSON_GetObjectItem(cJSON_GetObjectItem(m, "baselines"), "flat");
    CHECK(fabs(io_json_number_or(bf, "psnr", 0) - 18) < 1e-9 &&
              cJSON_GetObjectItem(cJSON_GetObjectItem(bf, "per_camera"), "cam05"),
          "baselines.flat in metrics.json");
    cJSON_Delete(m);
    snprintf(path, sizeof path, "%s/report.md", dir);
    CHECK_OK(eval_write_report_md(path, &r, NULL, NULL));
    eval_results_destroy(&r);
    char *text = NULL;
    size_t len = 0;
    CHECK_OK(pg_read_file(path, 1 << 20, &text, &len));
    return text;
}

static void test_verdicts(void)
{
    char dir[1024];
    test_tmpdir("eval_baselines", dir, sizeof dir);
    /* a model that learnt the scene: above all three */
    char *good = report_for(dir, 25);
    CHECK(good && strstr(good, "## Against the trivial baselines") && strstr(good, "above every baseline") &&
              !strstr(good, "loses to"),
          "a 25 dB model against 18/17/20 dB baselines:\n%s", good ? good : "");
    CHECK(good && strstr(good, "| **all** | 25.00 / 0.500 / 25.00 | 18.00 / 0.500 / 18.00 |"), "the pooled row");
    free(good);
    /* a model under the flat image: the report says so, and that it also loses to the warp */
    char *bad = report_for(dir, 17.5);
    CHECK(bad && strstr(bad, "loses to the flat image") && strstr(bad, "loses to the 2.5D warp") &&
              strstr(bad, "broken") && !strstr(bad, "loses to the training frame"),
          "a 17.5 dB model:\n%s", bad ? bad : "");
    free(bad);
}

int main(void)
{
    test_warp();
    test_verdicts();
    return test_summary("test_eval_baselines");
}
