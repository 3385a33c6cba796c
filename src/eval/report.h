/* report.h - what `prodygs eval` writes: metrics.json, report.md and side-by-side PNGs. */
#ifndef PG_EVAL_REPORT_H
#define PG_EVAL_REPORT_H

#include <cjson/cJSON.h>
#include "core/image.h"
#include "eval/metrics.h"

/* DIR/metrics.json: {"psnr", "ssim", "psnr_masked", "ssim_masked", "lpips": null,
 * "per_camera": {name: {...}}, "per_frame": [...], "config": config, "stages": stages, "seconds":
 * {stage: seconds}}. stages ({stage: {"seconds", "threads", "ran"}}) and config are copied (may be
 * NULL). Atomic. */
pg_status eval_write_metrics_json(const char *path, const eval_results *r, const cJSON *config, const cJSON *stages);
/* A short markdown report with the same numbers, the stages (time, threads) and a note on LPIPS. Atomic. */
pg_status eval_write_report_md(const char *path, const eval_results *r, const cJSON *config, const cJSON *stages);
/* One PNG: truth | render | error (|difference| x 4, clamped). Atomic. */
pg_status eval_write_side_by_side(const char *path, const pg_image *truth, const pg_image *render);

#endif
