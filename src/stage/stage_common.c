/* stage_common.c - thread setup and size checks shared by the stages. */
#include "stage/stage_internal.h"

#include <math.h>

#include "core/fileutil.h"
#include "core/parallel.h"
#include "core/status.h"
#include "io/json.h"
#include "deform/hexplane.h"
#include "train/train.h"

int stage_use_threads(int threads)
{
    pg_set_threads(threads);
    return pg_get_threads();
}

pg_status stage_check_size(const char *stage, const char *option, int width, int height, int even)
{
    if (width == 0 && height == 0) return PG_OK;
    int ok_w = width == 0 || (width >= STAGE_MIN_SIDE && width <= STAGE_MAX_SIDE);
    int ok_h = height == 0 || (height >= STAGE_MIN_SIDE && height <= STAGE_MAX_SIDE);
    if (!ok_w || !ok_h)
        return pg_fail(PG_ERR_ARG, "%s: %s %dx%d out of range (sides %d..%d, or 0 for one side to keep the aspect)",
                       stage, option, width, height, STAGE_MIN_SIDE, STAGE_MAX_SIDE);
    if (even && (width % 2 || height % 2))
        return pg_fail(PG_ERR_ARG, "%s: %s %dx%d: video sides must be even (H.264 keeps colour at half resolution), "
                       "e.g. %dx%d", stage, option, width, height, width + width % 2, height + height % 2);
    return PG_OK;
}

pg_status stage_resolve_size(const char *stage, const char *option, int width, int height, int from_w, int from_h,
                             int even, int *w, int *h)
{
    PG_TRY(stage_check_size(stage, option, width, height, even));
    *w = from_w;
    *h = from_h;
    if (width == 0 && height == 0) return PG_OK;
    double other = width ? (double)width * from_h / from_w : (double)height * from_w / from_h;
    long side = even ? 2 * lround(other / 2) : lround(other);
    *w = width ? width : (int)side;
    *h = height ? height : (int)side;
    if (side < STAGE_MIN_SIDE || side > STAGE_MAX_SIDE)
        return pg_fail(PG_ERR_ARG, "%s: %s %dx%d gives %dx%d at the source's %dx%d aspect: sides must be %d..%d", stage,
                       option, width, height, *w, *h, from_w, from_h, STAGE_MIN_SIDE, STAGE_MAX_SIDE);
    return PG_OK;
}

pg_status stage_check_threads(const char *stage, int threads)
{
    if (threads < 0 || threads > 256) return pg_fail(PG_ERR_ARG, "%s: --threads %d must be in 1..256 (0 = all cores)", stage, threads);
    return PG_OK;
}

pg_status stage_check_trainer_options(const char *stage, int deform_width, int deform_head_width,
                                      int deform_time_coarsen, float deform_time_warmup, float densify_movable,
                                      int proxy_downscale, int motion_crops, int views_per_step, float proxy_moving_weight,
                                      float real_weight, int sh_degree)
{
    if (deform_width < 0 || deform_width > 1024)
        return pg_fail(PG_ERR_ARG, "%s: --deform-width must be in 1..1024 (got %d)", stage, deform_width);
    if (deform_head_width < 0 || deform_head_width > 1024)
        return pg_fail(PG_ERR_ARG, "%s: --deform-head-width must be in 1..1024 (got %d)", stage, deform_head_width);
    if (deform_time_coarsen < -1 || deform_time_coarsen > HEX_MAX_TIME_COARSEN)
        return pg_fail(PG_ERR_ARG, "%s: --deform-time-coarsen must be in 0..%d (got %d)", stage, HEX_MAX_TIME_COARSEN,
                       deform_time_coarsen);
    if (deform_time_warmup != -1 && !(deform_time_warmup >= 0 && deform_time_warmup < 1))
        return pg_fail(PG_ERR_ARG, "%s: --deform-time-warmup must be in [0, 1) (got %g)", stage, deform_time_warmup);
    if (densify_movable != -1 && !(densify_movable >= 1 && densify_movable <= 100))
        return pg_fail(PG_ERR_ARG, "%s: --densify-movable must be in [1, 100] (got %g)", stage, densify_movable);
    if (proxy_downscale != 0 && proxy_downscale != 1 && proxy_downscale != 2)
        return pg_fail(PG_ERR_ARG, "%s: --proxy-downscale must be 1 or 2 (got %d)", stage, proxy_downscale);
    if (motion_crops < -1 || motion_crops > TRAIN_MAX_BATCH)
        return pg_fail(PG_ERR_ARG, "%s: --motion-crops must be in 0..%d (got %d)", stage, TRAIN_MAX_BATCH, motion_crops);
    if (views_per_step < 1 || views_per_step > TRAIN_MAX_BATCH)
        return pg_fail(PG_ERR_ARG, "%s: --views-per-step must be in 1..%d (got %d)", stage, TRAIN_MAX_BATCH,
                       views_per_step);
    if (sh_degree < -1 || sh_degree > 3)
        return pg_fail(PG_ERR_ARG, "%s: --sh-degree must be in 0..3 (got %d)", stage, sh_degree);
    if (proxy_moving_weight != -1 && !(proxy_moving_weight >= 0 && proxy_moving_weight <= 1))
        return pg_fail(PG_ERR_ARG, "%s: --proxy-moving-weight must be in [0, 1] (got %g)", stage, proxy_moving_weight);
    if (real_weight != -1 && !(real_weight >= 0 && real_weight <= 1))
        return pg_fail(PG_ERR_ARG, "%s: --real-weight must be in [0, 1] (got %g)", stage, real_weight);
    return PG_OK;
}

pg_status stage_depth_unit(const char *depth_path, double *unit)
{
    char path[4200];
    *unit = 1;
    PG_TRY(pg_path_join_beside(path, sizeof path, depth_path, "prepare.json"));
    if (!pg_path_exists(path)) return PG_OK;
    cJSON *root;
    PG_TRY(io_json_load(path, &root));
    pg_status st = io_json_get_source_unit(root, "depth_unit", path, unit);
    cJSON_Delete(root);
    return st;
}
