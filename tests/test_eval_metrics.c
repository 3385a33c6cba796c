/* test_eval_metrics.c - scores, masked scores and the metrics.json / report writers. */
#include "testlib.h"
#include "core/fileutil.h"
#include "eval/metrics.h"
#include "eval/report.h"
#include "eval/visibility.h"
#include "depth/moving_mask.h"
#include "io/json.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

int main(void)
{
    const int W = 48, H = 32;
    pg_image truth, pred;
    CHECK_OK(pg_image_create(&truth, W, H, 3));
    CHECK_OK(pg_image_create(&pred, W, H, 3));
    float alpha[48 * 32];
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            float *t = pg_image_at(&truth, x, y), *p = pg_image_at(&pred, x, y);
            for (int c = 0; c < 3; c++) t[c] = 0.5f + 0.4f * sinf(0.3f * x + c) * cosf(0.2f * y);
            /* right half exact, left half off by 0.1 and "not rendered" */
            int good = x >= W / 2;
            for (int c = 0; c < 3; c++) p[c] = t[c] + (good ? 0.0f : 0.1f);
            alpha[y * W + x] = good ? 0.9f : 0.1f;
        }
    optim_ssim_ws *ws;
    CHECK_OK(optim_ssim_create(&ws, H, W, 3));
    eval_scores s;
    CHECK_OK(eval_score_image(ws, &pred, &truth, alpha, &s));
    /* MSE over the whole image = 0.01 / 2 -> PSNR = 10 log10(200) = 23.01 dB */
    CHECK(fabs(s.psnr - 23.0103) < 1e-3, "psnr %f", s.psnr);
    CHECK(s.psnr_masked > 100, "masked psnr should be perfect, got %f", s.psnr_masked);
    CHECK(fabs(s.coverage - 0.5) < 1e-9, "coverage %f", s.coverage);
    CHECK(s.ssim < s.ssim_masked && s.ssim_masked > 0.95, "ssim %f masked %f", s.ssim, s.ssim_masked);

    /* regions: the left half (off by 0.1 everywhere -> MSE 0.01 -> 20 dB) labelled moving */
    uint8_t labels[48 * 32];
    for (int i = 0; i < W * H; i++) labels[i] = (i % W) < W / 2 ? EVAL_MOVING : EVAL_STATIC;
    CHECK_OK(eval_score_regions(ws, &pred, &truth, labels, EVAL_MOVING, 2, &s));
    CHECK(fabs(eval_region_psnr(&s.region[EVAL_MOVING]) - 20.0) < 1e-3, "moving psnr %f",
          eval_region_psnr(&s.region[EVAL_MOVING]));
    CHECK(eval_region_psnr(&s.region[EVAL_STATIC]) > 100, "static psnr %f", eval_region_psnr(&s.region[EVAL_STATIC]));
    CHECK(fabs(eval_region_fraction(&s.region[EVAL_MOVING]) - 0.5) < 1e-9, "moving fraction");
    CHECK(isnan(eval_region_psnr(&s.region[EVAL_SEEN])), "an unscored region has no PSNR");

    /* moving masks: a 4x4 bright square crossing a dark 24x8 video over 6 frames */
    {
        enum { F = 6, VW = 24, VH = 8 };
        uint8_t *rgb = calloc((size_t)F * VW * VH * 3, 1), *mv = malloc((size_t)F * VW * VH);
        for (int f = 0; f < F; f++)
            for (int y = 2; y < 6; y++)
                for (int x = 3 * f; x < 3 * f + 4; x++)
                    for (int c = 0; c < 3; c++) rgb[(((size_t)f * VH + y) * VW + x) * 3 + c] = 200;
        CHECK_OK(depth_moving_masks(rgb, F, VW, VH, 0.12f, 0, mv));
        int wrong = 0;
        for (int f = 0; f < F; f++)
            for (int y = 0; y < VH; y++)
                for (int x = 0; x < VW; x++)
                    wrong += mv[((size_t)f * VH + y) * VW + x] != (y >= 2 && y < 6 && x >= 3 * f && x < 3 * f + 4);
        CHECK(wrong == 0, "moving mask: %d wrong pixels without dilation", wrong);
        CHECK_OK(depth_moving_masks(rgb, F, VW, VH, 0.12f, 2, mv));
        CHECK(mv[(size_t)0 * VW + 3] && mv[(size_t)1 * VW + 3] && !mv[(size_t)0 * VW + 7 + 2],
              "dilation by 2 px reaches 2 px around the square, not 3");
        free(rgb);
        free(mv);
    }

    /* visibility: real camera at the origin looking at a wall at z = 4 with a box at z = 2 in
     * front of its centre; a test camera shifted right sees the wall behind the box's left side
     * (disoccluded), wall the real camera saw, and wall beyond the real frame's right border */
    {
        pg_camera real, test;
        pg_camera_from_fov(&real, 40, 30, 60);
        test = real;
        test.t[0] = -1.0f; /* camera centre at x = +1 */
        float real_z[40 * 30], tdepth[40 * 30], talpha[40 * 30];
        uint8_t lab[40 * 30];
        /* depth of a ray through pixel (x, y) of camera c: the box |X| < 0.4, |Y| < 0.4 at z = 2, else the wall */
        for (int pass = 0; pass < 2; pass++) {
            const pg_camera *c = pass ? &test : &real;
            for (int y = 0; y < 30; y++)
                for (int x = 0; x < 40; x++) {
                    float X[3], z = 2.0f;
                    pg_camera_unproject(c, x + 0.5f, y + 0.5f, z, X);
                    if (!(fabsf(X[0]) < 0.4f && fabsf(X[1]) < 0.4f)) z = 4.0f;
                    if (pass) {
                        tdepth[y * 40 + x] = z * 0.9f; /* expected depth with alpha 0.9 */
                        talpha[y * 40 + x] = 0.9f;
                    } else {
                        real_z[y * 40 + x] = z;
                    }
                }
        }
        eval_visibility_labels(&test, tdepth, talpha, &real, real_z, lab);
        int count[EVAL_REGIONS] = {0};
        for (int i = 0; i < 40 * 30; i++) count[lab[i]]++;
        CHECK(count[EVAL_SEEN] > 0 && count[EVAL_DISOCCLUDED] > 0 && count[EVAL_OUTSIDE] > 0,
              "visibility labels seen %d disoccluded %d outside %d", count[EVAL_SEEN], count[EVAL_DISOCCLUDED],
              count[EVAL_OUTSIDE]);
        /* the right edge of the test view is beyond the real frame; its centre row left of the
         * box's projection shows wall hidden by the box */
        CHECK(lab[15 * 40 + 39] == EVAL_OUTSIDE && lab[15 * 40 + 0] == EVAL_SEEN, "outside / seen at the borders");
        talpha[15 * 40 + 10] = 0.2f;
        eval_visibility_labels(&test, tdepth, talpha, &real, real_z, lab);
        CHECK(lab[15 * 40 + 10] == EVAL_OUTSIDE, "nothing rendered counts as outside");
    }

    eval_results r = {0};
    CHECK_OK(eval_results_add(&r, "cam05", EVAL_ROLE_TEST, 0, &s));
    eval_scores s2 = s;
    s2.psnr = 30;
    CHECK_OK(eval_results_add(&r, "cam06", EVAL_ROLE_TEST, 0, &s2));
    eval_scores s3 = s;
    s3.psnr = 50; /* the training camera: reported apart, never in the test means */
    CHECK_OK(eval_results_add(&r, "cam00", EVAL_ROLE_TRAIN, 0, &s3));
    eval_scores m;
    CHECK(eval_results_mean(&r, NULL, EVAL_ROLE_TRAIN, &m) == 1 && m.psnr == 50, "train mean %f", m.psnr);
    CHECK(eval_results_mean(&r, NULL, EVAL_ROLE_TEST, &m) == 2 && fabs(m.psnr - (s.psnr + 30) / 2) < 1e-9, "mean psnr %f", m.psnr);
    CHECK(eval_results_mean(&r, "cam06", EVAL_ROLE_TEST, &m) == 1 && m.psnr == 30, "cam06 mean %f", m.psnr);

    char dir[1024], path[1200];
    test_tmpdir("eval_metrics", dir, sizeof dir);
    snprintf(path, sizeof path, "%s/metrics.json", dir);
    cJSON *seconds = cJSON_CreateObject();
    cJSON_AddNumberToObject(seconds, "train", 12.5);
    CHECK_OK(eval_write_metrics_json(path, &r, NULL, seconds));
    cJSON *root = NULL;
    CHECK_OK(io_json_load(path, &root));
    if (root) {
        const cJSON *cams = cJSON_GetObjectItem(root, "per_camera");
        CHECK(cJSON_GetObjectItem(cams, "cam05") && cJSON_GetObjectItem(cams, "cam06"), "per_camera entries");
        CHECK(cJSON_GetArraySize(cJSON_GetObjectItem(root, "per_frame")) == 3, "per_frame count");
        const cJSON *tc = cJSON_GetObjectItem(root, "train_camera");
        CHECK(tc && strcmp(io_json_string_or(tc, "camera", ""), "cam00") == 0, "train_camera block");
        const cJSON *mv = cJSON_GetObjectItem(cJSON_GetObjectItem(tc, "regions"), "moving");
        CHECK(mv && fabs(io_json_number_or(mv, "psnr", 0) - 20.0) < 1e-3, "train camera moving psnr in json");
        CHECK(cJSON_IsNull(cJSON_GetObjectItem(cJSON_GetObjectItem(cJSON_GetObjectItem(root, "regions"), "moving"), "ssim")) == 0,
              "moving ssim is a number");
        CHECK(fabs(io_json_number_or(root, "psnr", 0) - (s.psnr + 30) / 2) < 1e-6, "json psnr");
        CHECK(cJSON_IsNull(cJSON_GetObjectItem(root, "lpips")), "lpips must be null when unavailable");
        cJSON_Delete(root);
    }
    snprintf(path, sizeof path, "%s/report.md", dir);
    CHECK_OK(eval_write_report_md(path, &r, NULL, seconds));
    char *text = NULL;
    size_t size;
    CHECK_OK(pg_read_file(path, 1 << 20, &text, &size));
    CHECK(text && strstr(text, "cam06") && strstr(text, "LPIPS") && strstr(text, "train"), "report content");
    free(text);
    snprintf(path, sizeof path, "%s/sbs.png", dir);
    CHECK_OK(eval_write_side_by_side(path, &truth, &pred));
    cJSON_Delete(seconds);
    eval_results_destroy(&r);
    optim_ssim_destroy(ws);
    pg_image_destroy(&truth);
    pg_image_destroy(&pred);
    return test_summary("test_eval_metrics");
}
