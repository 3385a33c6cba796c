/* test_eval_metrics.c - scores, masked scores and the metrics.json / report writers. */
#include "testlib.h"
#include "core/fileutil.h"
#include "eval/metrics.h"
#include "eval/report.h"
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

    eval_results r = {0};
    CHECK_OK(eval_results_add(&r, "cam05", 0, &s));
    eval_scores s2 = s;
    s2.psnr = 30;
    CHECK_OK(eval_results_add(&r, "cam06", 0, &s2));
    eval_scores m;
    CHECK(eval_results_mean(&r, NULL, &m) == 2 && fabs(m.psnr - (s.psnr + 30) / 2) < 1e-9, "mean psnr %f", m.psnr);
    CHECK(eval_results_mean(&r, "cam06", &m) == 1 && m.psnr == 30, "cam06 mean %f", m.psnr);

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
        CHECK(cJSON_GetArraySize(cJSON_GetObjectItem(root, "per_frame")) == 2, "per_frame count");
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
