/* stage_common.c - thread setup and size checks shared by the stages. */
#include "stage/stage_internal.h"

#include "core/parallel.h"
#include "core/status.h"

int stage_use_threads(int threads)
{
    pg_set_threads(threads);
    return pg_get_threads();
}

pg_status stage_check_size(const char *stage, int width, int height)
{
    if (width == 0 && height == 0) return PG_OK;
    int ok_w = width == 0 || (width >= STAGE_MIN_SIDE && width <= STAGE_MAX_SIDE);
    int ok_h = height == 0 || (height >= STAGE_MIN_SIDE && height <= STAGE_MAX_SIDE);
    if (!ok_w || !ok_h)
        return pg_fail(PG_ERR_ARG, "%s: --size %dx%d out of range (sides %d..%d, or 0 for one side to keep the aspect)",
                       stage, width, height, STAGE_MIN_SIDE, STAGE_MAX_SIDE);
    return PG_OK;
}

pg_status stage_check_threads(const char *stage, int threads)
{
    if (threads < 0 || threads > 256) return pg_fail(PG_ERR_ARG, "%s: --threads %d must be in 1..256 (0 = all cores)", stage, threads);
    return PG_OK;
}
