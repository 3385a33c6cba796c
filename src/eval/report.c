/* report.c - writes the evaluation results for machines (JSON) and people (markdown, PNG). */
#include "eval/report.h"
#include "core/fileutil.h"
#include "io/image_io.h"
#include "io/json.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static cJSON *scores_json(const eval_scores *s, int frames)
{
    cJSON *o = cJSON_CreateObject();
    cJSON_AddNumberToObject(o, "psnr", s->psnr);
    cJSON_AddNumberToObject(o, "ssim", s->ssim);
    cJSON_AddNumberToObject(o, "psnr_masked", s->psnr_masked);
    cJSON_AddNumberToObject(o, "ssim_masked", s->ssim_masked);
    cJSON_AddNumberToObject(o, "coverage", s->coverage);
    if (frames >= 0) cJSON_AddNumberToObject(o, "frames", frames);
    return o;
}

/* Distinct camera names in record order. */
static int list_cameras(const eval_results *r, const char **names, int max)
{
    int n = 0;
    for (int i = 0; i < r->count; i++) {
        int seen = 0;
        for (int k = 0; k < n; k++) seen |= strcmp(names[k], r->records[i].camera) == 0;
        if (!seen && n < max) names[n++] = r->records[i].camera;
    }
    return n;
}

pg_status eval_write_metrics_json(const char *path, const eval_results *r, const cJSON *config, const cJSON *seconds)
{
    eval_scores mean;
    eval_results_mean(r, NULL, &mean);
    cJSON *root = scores_json(&mean, r->count);
    cJSON_AddNullToObject(root, "lpips");
    cJSON *per_cam = cJSON_AddObjectToObject(root, "per_camera");
    const char *names[256];
    int ncam = list_cameras(r, names, 256);
    for (int k = 0; k < ncam; k++) {
        eval_scores s;
        int n = eval_results_mean(r, names[k], &s);
        cJSON_AddItemToObject(per_cam, names[k], scores_json(&s, n));
    }
    cJSON *frames = cJSON_AddArrayToObject(root, "per_frame");
    for (int i = 0; i < r->count; i++) {
        cJSON *f = scores_json(&r->records[i].s, -1);
        cJSON_AddStringToObject(f, "camera", r->records[i].camera);
        cJSON_AddNumberToObject(f, "frame", r->records[i].frame);
        cJSON_AddItemToArray(frames, f);
    }
    cJSON_AddItemToObject(root, "config", config ? cJSON_Duplicate(config, 1) : cJSON_CreateObject());
    cJSON_AddItemToObject(root, "seconds", seconds ? cJSON_Duplicate(seconds, 1) : cJSON_CreateObject());
    pg_status st = io_json_write_atomic(path, root);
    cJSON_Delete(root);
    return st;
}

pg_status eval_write_report_md(const char *path, const eval_results *r, const cJSON *config, const cJSON *seconds)
{
    size_t cap = 1 << 16, len = 0;
    char *buf = pg_malloc(cap, "report");
    if (!buf) return PG_ERR_NOMEM;
#define EMIT(...) do { if (len < cap) len += (size_t)snprintf(buf + len, cap - len, __VA_ARGS__); } while (0)
    eval_scores mean;
    eval_results_mean(r, NULL, &mean);
    EMIT("# prodygs evaluation\n\n");
    EMIT("Novel views at held-out cameras, every frame (DyNeRF protocol: one real training camera plus\n"
         "proxy views; the test cameras are never trained on). Masked scores use the pixels where the\n"
         "model's alpha > 0.5, as MoDGS reports them.\n\n");
    EMIT("| camera | frames | PSNR | SSIM | PSNR (masked) | SSIM (masked) | coverage |\n");
    EMIT("|---|---|---|---|---|---|---|\n");
    const char *names[256];
    int ncam = list_cameras(r, names, 256);
    for (int k = 0; k < ncam; k++) {
        eval_scores s;
        int n = eval_results_mean(r, names[k], &s);
        EMIT("| %s | %d | %.2f | %.4f | %.2f | %.4f | %.1f %% |\n", names[k], n, s.psnr, s.ssim, s.psnr_masked,
             s.ssim_masked, 100 * s.coverage);
    }
    EMIT("| **all** | %d | **%.2f** | **%.4f** | **%.2f** | **%.4f** | %.1f %% |\n\n", r->count, mean.psnr, mean.ssim,
         mean.psnr_masked, mean.ssim_masked, 100 * mean.coverage);
    EMIT("LPIPS: not reported. It needs the AlexNet or VGG backbone weights, which are not available on this\n"
         "machine (only the LPIPS linear heads are); `metrics.json` has `\"lpips\": null`.\n\n");
    if (seconds && cJSON_GetArraySize(seconds) > 0) {
        EMIT("## Wall time per stage\n\n| stage | seconds |\n|---|---|\n");
        const cJSON *it;
        cJSON_ArrayForEach(it, seconds) if (cJSON_IsNumber(it)) EMIT("| %s | %.1f |\n", it->string, it->valuedouble);
        EMIT("\n");
    }
    if (config) {
        char *text = cJSON_Print(config);
        if (text) {
            EMIT("## Configuration\n\n```json\n%s\n```\n\nSide-by-side images (truth | render | error x4) are in `side_by_side/`.\n", text);
            free(text);
        }
    }
#undef EMIT
    if (len >= cap) len = cap - 1;
    pg_status st = pg_write_file_atomic(path, buf, len);
    free(buf);
    return st;
}

pg_status eval_write_side_by_side(const char *path, const pg_image *truth, const pg_image *render)
{
    const int W = truth->width, H = truth->height;
    if (render->width != W || render->height != H || truth->channels != 3 || render->channels != 3)
        return pg_fail(PG_ERR_SIZE, "%s: render and truth sizes differ", path);
    pg_image out;
    PG_TRY(pg_image_create(&out, 3 * W, H, 3));
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            const float *a = pg_image_at(truth, x, y), *b = pg_image_at(render, x, y);
            float *o0 = pg_image_at(&out, x, y), *o1 = pg_image_at(&out, x + W, y), *o2 = pg_image_at(&out, x + 2 * W, y);
            for (int c = 0; c < 3; c++) {
                o0[c] = a[c];
                o1[c] = b[c];
                o2[c] = fminf(1.0f, 4.0f * fabsf(a[c] - b[c]));
            }
        }
    pg_status st = io_image_save_png(path, &out);
    pg_image_destroy(&out);
    return st;
}
