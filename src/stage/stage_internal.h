/* stage_internal.h - what the stage implementations share: thread setup, config records for
 * the pipeline's stage markers, and limits on sizes a config may ask for. */
#ifndef PG_STAGE_INTERNAL_H
#define PG_STAGE_INTERNAL_H

#include <cjson/cJSON.h>

#include "prodygs.h"

/* Image sides a config may ask for (resize options). */
#define STAGE_MIN_SIDE 8
#define STAGE_MAX_SIDE 8192

/* Sets the worker threads for a stage (<= 0: all cores) and returns the count in use. */
int stage_use_threads(int threads);
/* Checks a thread count: 0 (all cores) .. 256. */
pg_status stage_check_threads(const char *stage, int threads);
/* The one check of a requested size (--size, --render-size; option names it in the message):
 * 0x0 keeps the input's, one side 0 keeps the aspect, else sides in
 * STAGE_MIN_SIDE..STAGE_MAX_SIDE; even = 1 for videos, whose encoder would round an odd side up
 * unasked (9x9 written as 10x10). */
pg_status stage_check_size(const char *stage, const char *option, int width, int height, int even);
/* Checks the request as stage_check_size and resolves it against a source of from_w x from_h: a
 * 0 side follows the aspect (rounded to even for videos) and is refused outside the sides'
 * range, so 8x0 is never written as 8x6. */
pg_status stage_resolve_size(const char *stage, const char *option, int width, int height, int from_w, int from_h,
                             int even, int *w, int *h);
/* Checks the trainer options that both `train` and `run`/`eval` take, with one wording for both
 * (-1 = the trainer's default; widths 0 = the trainer's default too). */
pg_status stage_check_trainer_options(const char *stage, int deform_width, int deform_head_width,
                                      int deform_time_coarsen, float deform_time_warmup, float densify_movable,
                                      int proxy_downscale, int motion_crops, int views_per_step, float proxy_moving_weight,
                                      float real_weight, int sh_degree);

/* The user's length per value of a depth file: prepare.json beside a prepare stage's
 * depth_aligned.npy records it (source.depth_unit: the clip's own unit times --depth-scale); 1
 * for a depth file from elsewhere. */
pg_status stage_depth_unit(const char *depth_path, double *unit);

/* The settings that decide a stage's result, as JSON (threads and output paths left out), so
 * a marker can tell whether a finished stage is still current. */
cJSON *stage_prepare_config_json(const pg_prepare_config *c);
cJSON *stage_proxies_config_json(const pg_proxies_config *c);
cJSON *stage_train_config_json(const pg_train_config *c);

#endif
