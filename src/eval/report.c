/* report.c - writes the evaluation results for machines (JSON) and people (markdown, PNG). */
#include "eval/report.h"
#include "eval/baselines.h"
#include "core/fileutil.h"
#include "io/image_io.h"
#include "io/json.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* A number, or null when undefined (an empty region). */
static void add_number_or_null(cJSON *o, const char *key, double v)
{
    if (isfinite(v))
        cJSON_AddNumberToObject(o, key, v);
    else
        cJSON_AddNullToObject(o, key);
}

/* {"moving": {"psnr", "ssim", "fraction"}, ...} for the regions that were scored. */
static void add_regions(cJSON *o, const eval_scores *s)
{
    cJSON *regions = cJSON_AddObjectToObject(o, "regions");
    for (int k = 0; k < EVAL_REGIONS; k++) {
        const eval_region *g = &s->region[k];
        if (!(g->total > 0)) continue;
        cJSON *r = cJSON_AddObjectToObject(regions, eval_region_names[k]);
        add_number_or_null(r, "psnr", eval_region_psnr(g));
        add_number_or_null(r, "ssim", eval_region_ssim(g));
        cJSON_AddNumberToObject(r, "fraction", eval_region_fraction(g));
    }
}

static cJSON *scores_json(const eval_scores *s, int frames)
{
    cJSON *o = cJSON_CreateObject();
    cJSON_AddNumberToObject(o, "psnr", s->psnr);
    cJSON_AddNumberToObject(o, "ssim", s->ssim);
    cJSON_AddNumberToObject(o, "psnr_masked", s->psnr_masked);
    cJSON_AddNumberToObject(o, "ssim_masked", s->ssim_masked);
    cJSON_AddNumberToObject(o, "coverage", s->coverage);
    if (frames >= 0) cJSON_AddNumberToObject(o, "frames", frames);
    add_regions(o, s);
    return o;
}

static const char *role_name(eval_role role) { return role == EVAL_ROLE_TRAIN ? "train" : "test"; }

/* The role of a camera's records (they all share it). */
static eval_role camera_role(const eval_results *r, const char *camera)
{
    for (int i = 0; i < r->count; i++)
        if (strcmp(r->records[i].camera, camera) == 0) return r->records[i].role;
    return EVAL_ROLE_TEST;
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

/* Mean of baseline b's records (one camera, or every test record); 0 when it was not scored. */
static int baseline_mean(const eval_results *r, int b, const char *camera, eval_scores *s)
{
    memset(s, 0, sizeof *s);
    return r->baseline ? eval_results_mean(&r->baseline[b], camera, EVAL_ROLE_TEST, s) : 0;
}

/* {"psnr", "ssim", "psnr_moving"} of one set of scores. */
static cJSON *brief_json(const eval_scores *s)
{
    cJSON *o = cJSON_CreateObject();
    add_number_or_null(o, "psnr", s->psnr);
    add_number_or_null(o, "ssim", s->ssim);
    add_number_or_null(o, "psnr_moving", eval_region_psnr(&s->region[EVAL_MOVING]));
    return o;
}

/* "baselines": each yardstick pooled and per test camera; "margin_db": the model's held-out PSNR
 * minus each one's. */
static void add_baselines(cJSON *root, const eval_results *r, const eval_scores *model, const char **names, int ncam)
{
    cJSON *base = cJSON_AddObjectToObject(root, "baselines"), *margin = cJSON_AddObjectToObject(root, "margin_db");
    for (int b = 0; b < EVAL_BASELINES; b++) {
        eval_scores s;
        if (!baseline_mean(r, b, NULL, &s)) {
            cJSON_AddNullToObject(base, eval_baseline_names[b]);
            cJSON_AddNullToObject(margin, eval_baseline_names[b]);
            continue;
        }
        cJSON *o = brief_json(&s), *per = cJSON_AddObjectToObject(o, "per_camera");
        for (int k = 0; k < ncam; k++) {
            eval_scores c;
            if (camera_role(r, names[k]) == EVAL_ROLE_TEST && baseline_mean(r, b, names[k], &c))
                cJSON_AddItemToObject(per, names[k], brief_json(&c));
        }
        cJSON_AddItemToObject(base, eval_baseline_names[b], o);
        cJSON_AddNumberToObject(margin, eval_baseline_names[b], model->psnr - s.psnr);
    }
}

pg_status eval_write_metrics_json(const char *path, const eval_results *r, const cJSON *config, const cJSON *stages)
{
    eval_scores mean, train;
    int ntest = eval_results_mean(r, NULL, EVAL_ROLE_TEST, &mean);
    cJSON *root = scores_json(&mean, ntest);
    cJSON_AddNullToObject(root, "lpips");
    const char *names[256];
    int ncam = list_cameras(r, names, 256);
    int ntrain = eval_results_mean(r, NULL, EVAL_ROLE_TRAIN, &train);
    if (ntrain > 0) {
        cJSON *tc = scores_json(&train, ntrain);
        for (int k = 0; k < ncam; k++)
            if (camera_role(r, names[k]) == EVAL_ROLE_TRAIN) cJSON_AddStringToObject(tc, "camera", names[k]);
        cJSON_AddItemToObject(root, "train_camera", tc);
    } else {
        cJSON_AddNullToObject(root, "train_camera");
    }
    cJSON *per_cam = cJSON_AddObjectToObject(root, "per_camera");
    for (int k = 0; k < ncam; k++) {
        eval_scores s;
        int n = eval_results_mean(r, names[k], EVAL_ROLE_TEST, &s);
        cJSON *o = scores_json(&s, n);
        cJSON_AddStringToObject(o, "role", role_name(camera_role(r, names[k])));
        cJSON_AddItemToObject(per_cam, names[k], o);
    }
    if (ntest > 0) add_baselines(root, r, &mean, names, ncam);
    cJSON *frames = cJSON_AddArrayToObject(root, "per_frame");
    for (int i = 0; i < r->count; i++) {
        cJSON *f = scores_json(&r->records[i].s, -1);
        cJSON_AddStringToObject(f, "camera", r->records[i].camera);
        cJSON_AddStringToObject(f, "role", role_name(r->records[i].role));
        cJSON_AddNumberToObject(f, "frame", r->records[i].frame);
        cJSON_AddItemToArray(frames, f);
    }
    cJSON_AddItemToObject(root, "config", config ? cJSON_Duplicate(config, 1) : cJSON_CreateObject());
    cJSON *seconds = cJSON_AddObjectToObject(root, "seconds");
    const cJSON *it;
    if (stages) {
        cJSON_ArrayForEach(it, stages) cJSON_AddNumberToObject(seconds, it->string, io_json_number_or(it, "seconds", 0));
        cJSON_AddItemToObject(root, "stages", cJSON_Duplicate(stages, 1));
    }
    pg_status st = io_json_write_atomic(path, root);
    cJSON_Delete(root);
    return st;
}

pg_status eval_write_report_md(const char *path, const eval_results *r, const cJSON *config, const cJSON *stages)
{
    size_t cap = 1 << 16, len = 0;
    char *buf = pg_malloc(cap, "report");
    if (!buf) return PG_ERR_NOMEM;
#define EMIT(...) do { if (len < cap) len += (size_t)snprintf(buf + len, cap - len, __VA_ARGS__); } while (0)
    eval_scores mean;
    int ntest = eval_results_mean(r, NULL, EVAL_ROLE_TEST, &mean);
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
        if (camera_role(r, names[k]) != EVAL_ROLE_TEST) continue;
        int n = eval_results_mean(r, names[k], EVAL_ROLE_TEST, &s);
        EMIT("| %s | %d | %.2f | %.4f | %.2f | %.4f | %.1f %% |\n", names[k], n, s.psnr, s.ssim, s.psnr_masked,
             s.ssim_masked, 100 * s.coverage);
    }
    EMIT("| **all** | %d | **%.2f** | **%.4f** | **%.2f** | **%.4f** | %.1f %% |\n\n", ntest, mean.psnr, mean.ssim,
         mean.psnr_masked, mean.ssim_masked, 100 * mean.coverage);
    EMIT("## Moving and static parts\n\n"
         "Moving pixels: colour differs from that pixel's temporal median in the camera's own video by\n"
         "> 0.12 in a channel, dilated 2 px. For test cameras, pixels are also split by where they land\n"
         "in the real camera (model depth): seen by it, disoccluded (behind what it saw), or outside its\n"
         "frame (or nothing rendered). PSNR pools the squared error of all frames of a region.\n\n");
    EMIT("| camera | role | PSNR moving | SSIM moving | moving %% | PSNR static | SSIM static | PSNR seen | PSNR disoccluded | PSNR outside | seen / disocc. / outside %% |\n");
    EMIT("|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (int k = 0; k <= ncam; k++) {
        eval_scores s;
        const char *name = k < ncam ? names[k] : "**all test**";
        eval_role role = k < ncam ? camera_role(r, names[k]) : EVAL_ROLE_TEST;
        eval_results_mean(r, k < ncam ? names[k] : NULL, role, &s);
        const eval_region *g = s.region;
        EMIT("| %s | %s | %.2f | %.4f | %.1f | %.2f | %.4f |", name, role_name(role), eval_region_psnr(&g[EVAL_MOVING]),
             eval_region_ssim(&g[EVAL_MOVING]), 100 * eval_region_fraction(&g[EVAL_MOVING]),
             eval_region_psnr(&g[EVAL_STATIC]), eval_region_ssim(&g[EVAL_STATIC]));
        if (g[EVAL_SEEN].total > 0)
            EMIT(" %.2f | %.2f | %.2f | %.1f / %.1f / %.1f |\n", eval_region_psnr(&g[EVAL_SEEN]),
                 eval_region_psnr(&g[EVAL_DISOCCLUDED]), eval_region_psnr(&g[EVAL_OUTSIDE]),
                 100 * eval_region_fraction(&g[EVAL_SEEN]), 100 * eval_region_fraction(&g[EVAL_DISOCCLUDED]),
                 100 * eval_region_fraction(&g[EVAL_OUTSIDE]));
        else
            EMIT(" - | - | - | - |\n");
    }
    EMIT("\n");
    if (ntest > 0 && r->baseline) {
        static const char *const label[EVAL_BASELINES] = { "flat image of the training camera's mean colour",
                                                            "training frame shown as is",
                                                            "2.5D warp of the training frame (trained-on depth)" };
        EMIT("## Against the trivial baselines\n\n"
             "Each held-out frame is also scored as three yardsticks would draw it: a %s; the %s; a %s,\n"
             "z-buffered, holes filled from the background beside them. PSNR / SSIM / moving-pixel PSNR.\n\n",
             label[0], label[1], label[2]);
        EMIT("| camera | model | flat | as is | warp | model minus flat / as is / warp (dB) |\n|---|---|---|---|---|---|\n");
        for (int k = 0; k <= ncam; k++) {
            if (k < ncam && camera_role(r, names[k]) != EVAL_ROLE_TEST) continue;
            const char *cam = k < ncam ? names[k] : NULL;
            eval_scores m, b[EVAL_BASELINES];
            int have[EVAL_BASELINES];
            eval_results_mean(r, cam, EVAL_ROLE_TEST, &m);
            EMIT("| %s | %.2f / %.3f / %.2f |", cam ? cam : "**all**", m.psnr, m.ssim, eval_region_psnr(&m.region[EVAL_MOVING]));
            for (int j = 0; j < EVAL_BASELINES; j++) {
                have[j] = baseline_mean(r, j, cam, &b[j]);
                if (have[j])
                    EMIT(" %.2f / %.3f / %.2f |", b[j].psnr, b[j].ssim, eval_region_psnr(&b[j].region[EVAL_MOVING]));
                else
                    EMIT(" - |");
            }
            for (int j = 0; j < EVAL_BASELINES; j++) {
                if (have[j]) EMIT(" %+.2f", m.psnr - b[j].psnr);
                else EMIT(" -");
                EMIT("%s", j + 1 < EVAL_BASELINES ? " /" : " |\n");
            }
        }
        eval_scores b;
        int lost = 0;
        EMIT("\n");
        for (int j = 0; j < EVAL_BASELINES; j++) {
            if (!baseline_mean(r, j, NULL, &b) || mean.psnr > b.psnr) continue;
            EMIT("**The model loses to the %s (%.2f dB against %.2f)%s**\n", label[j], mean.psnr, b.psnr,
                 j == EVAL_BASE_WARP ? ": it adds nothing to what the depth map already gives; broken."
                 : j == EVAL_BASE_FLAT ? ": it draws the scene in the wrong place." : ".");
            lost = 1;
        }
        if (!lost) EMIT("The model is above every baseline it was scored against.\n");
        EMIT("\n");
    }
    EMIT("LPIPS: not reported. It needs the AlexNet or VGG backbone weights, which are not available on this\n"
         "machine (only the LPIPS linear heads are); `metrics.json` has `\"lpips\": null`.\n\n");
    if (stages && cJSON_GetArraySize(stages) > 0) {
        EMIT("## Stages\n\n| stage | seconds | threads | |\n|---|---|---|---|\n");
        const cJSON *it;
        cJSON_ArrayForEach(it, stages)
            EMIT("| %s | %.1f | %d | %s |\n", it->string, io_json_number_or(it, "seconds", 0),
                 (int)io_json_number_or(it, "threads", 0), cJSON_IsTrue(cJSON_GetObjectItem(it, "ran")) ? "ran" : "already done");
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
