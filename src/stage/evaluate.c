/* evaluate.c - the evaluate stage: the DyNeRF protocol on a trained model (every frame of the
 * held-out cameras, plus the training camera's moving and static pixels); writes
 * OUT/metrics.json, OUT/report.md and OUT/side_by_side/. */
#include "stage/stage_internal.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "core/fileutil.h"
#include "core/parallel.h"
#include "core/status.h"
#include "eval/baselines.h"
#include "eval/protocol.h"
#include "eval/report.h"

void pg_evaluate_defaults(pg_evaluate_config *c)
{
    memset(c, 0, sizeof *c);
}

/* Parses an optional JSON object handed in as text; NULL text gives NULL. */
static pg_status parse_object(const char *text, const char *what, cJSON **out)
{
    *out = NULL;
    if (!text) return PG_OK;
    *out = cJSON_Parse(text);
    if (!cJSON_IsObject(*out)) {
        cJSON_Delete(*out);
        *out = NULL;
        return pg_fail(PG_ERR_ARG, "evaluate: %s is not a JSON object", what);
    }
    return PG_OK;
}

pg_status pg_evaluate_run(const pg_evaluate_config *c, pg_evaluate_report *r)
{
    memset(r, 0, sizeof *r);
    r->psnr = r->ssim = r->psnr_moving = r->train_psnr_moving = r->train_psnr_static = NAN;
    r->flat_psnr = r->as_is_psnr = r->warp_psnr = r->warp_psnr_moving = NAN;
    if (!c->dataset || !c->model || !c->out) return pg_fail(PG_ERR_ARG, "evaluate: dataset, model and out are required");
    cJSON *config = NULL, *stages = NULL;
    PG_TRY(parse_object(c->config_json, "the config record", &config));
    pg_status st = parse_object(c->stages_json, "the stages record", &stages);
    stage_use_threads(c->threads);
    char sbs[4200], path[4200];
    eval_results res = { 0 };
    double t0 = pg_time_seconds();
    if (st == PG_OK) st = pg_mkdir_p(c->out);
    if (st == PG_OK) st = pg_path_join(sbs, sizeof sbs, c->out, "side_by_side");
    if (st == PG_OK) st = eval_protocol_run(c->dataset, c->model, c->trainset, sbs, &res);
    r->seconds = pg_time_seconds() - t0;
    if (st == PG_OK) {
        /* the record of this stage goes in with the ones the caller passed */
        if (!stages) stages = cJSON_CreateObject();
        cJSON *me = cJSON_CreateObject();
        cJSON_AddNumberToObject(me, "seconds", r->seconds);
        cJSON_AddNumberToObject(me, "threads", pg_get_threads());
        cJSON_AddBoolToObject(me, "ran", 1);
        cJSON_DeleteItemFromObject(stages, "evaluate");
        cJSON_AddItemToObject(stages, "evaluate", me);
    }
    if (st == PG_OK) st = pg_path_join(path, sizeof path, c->out, "metrics.json");
    if (st == PG_OK) st = eval_write_metrics_json(path, &res, config, stages);
    if (st == PG_OK) st = pg_path_join(path, sizeof path, c->out, "report.md");
    if (st == PG_OK) st = eval_write_report_md(path, &res, config, stages);
    if (st == PG_OK) {
        eval_scores m, tr;
        r->frames = eval_results_mean(&res, NULL, EVAL_ROLE_TEST, &m);
        int ntr = eval_results_mean(&res, NULL, EVAL_ROLE_TRAIN, &tr);
        if (r->frames) {
            r->psnr = m.psnr;
            r->ssim = m.ssim;
            r->psnr_moving = eval_region_psnr(&m.region[EVAL_MOVING]);
        }
        double *base_psnr[EVAL_BASELINES] = { &r->flat_psnr, &r->as_is_psnr, &r->warp_psnr };
        for (int b = 0; b < EVAL_BASELINES && res.baseline; b++) {
            eval_scores bs;
            if (!eval_results_mean(&res.baseline[b], NULL, EVAL_ROLE_TEST, &bs)) continue;
            *base_psnr[b] = bs.psnr;
            if (b == EVAL_BASE_WARP) r->warp_psnr_moving = eval_region_psnr(&bs.region[EVAL_MOVING]);
        }
        if (ntr) {
            r->train_psnr_moving = eval_region_psnr(&tr.region[EVAL_MOVING]);
            r->train_psnr_static = eval_region_psnr(&tr.region[EVAL_STATIC]);
        }
    }
    eval_results_destroy(&res);
    cJSON_Delete(config);
    cJSON_Delete(stages);
    return st;
}
