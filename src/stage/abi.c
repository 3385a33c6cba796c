/* abi.c - what bindings of the library need beyond the stages: the sizes of the public structs
 * (python/prodygs checks its ctypes copies against these when it loads the library, so a header
 * change that the mirror missed fails at import instead of corrupting memory), the version, and
 * the path of the built-in depth network (the stages take a model path; the CLI passes this one
 * when the user names no depth). */
#include "prodygs.h"

#include "core/status.h"
#include "depth/depth_default.h"

#include <stddef.h>
#include <string.h>

#define PG_ABI_TYPE(T) { #T, sizeof(T) }

static const struct {
    const char *name;
    size_t size;
} pg_abi_types[] = {
    PG_ABI_TYPE(pg_depth_config),    PG_ABI_TYPE(pg_depth_report),    PG_ABI_TYPE(pg_prepare_config),
    PG_ABI_TYPE(pg_prepare_report),  PG_ABI_TYPE(pg_proxies_config),  PG_ABI_TYPE(pg_proxies_report),
    PG_ABI_TYPE(pg_train_config),    PG_ABI_TYPE(pg_train_report),    PG_ABI_TYPE(pg_evaluate_config),
    PG_ABI_TYPE(pg_evaluate_report), PG_ABI_TYPE(pg_render_config),   PG_ABI_TYPE(pg_render_report),
    PG_ABI_TYPE(pg_export_config),   PG_ABI_TYPE(pg_export_report),   PG_ABI_TYPE(pg_view_config),
    PG_ABI_TYPE(pg_view_report),     PG_ABI_TYPE(pg_pipeline_config), PG_ABI_TYPE(pg_pipeline_report),
};

size_t pg_struct_size(const char *name)
{
    if (!name) return 0;
    for (size_t i = 0; i < sizeof pg_abi_types / sizeof pg_abi_types[0]; i++)
        if (strcmp(pg_abi_types[i].name, name) == 0) return pg_abi_types[i].size;
    return 0;
}

const char *pg_version(void)
{
    return PRODYGS_VERSION;
}

pg_status pg_depth_default_model(char *path, size_t size)
{
    if (!path || size == 0) return pg_fail(PG_ERR_ARG, "pg_depth_default_model: no buffer");
    return depth_default_model(path, size);
}
