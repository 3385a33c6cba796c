/* gaussians.c - allocation of the Gaussian structure of arrays. */
#include "splat/gaussians.h"

#include <stdlib.h>
#include <string.h>

/* Row widths of the arrays, in floats. */
enum { G_MEAN = 3, G_SCALE = 3, G_QUAT = 4, G_OPAC = 1 };

pg_status splat_gaussians_create_sh(pg_gaussians *g, int capacity, int sh_max)
{
    memset(g, 0, sizeof(*g));
    if (capacity < 0) return pg_fail(PG_ERR_ARG, "gaussians: negative capacity %d", capacity);
    if (sh_max < 0 || sh_max > 3) return pg_fail(PG_ERR_ARG, "gaussians: SH degree %d (0..3)", sh_max);
    g->sh_degree = sh_max;
    g->sh_stride = splat_sh_floats(sh_max);
    pg_status st = splat_gaussians_resize(g, capacity);
    if (st) { splat_gaussians_destroy(g); return st; }
    g->count = 0;
    return PG_OK;
}

pg_status splat_gaussians_create(pg_gaussians *g, int capacity) { return splat_gaussians_create_sh(g, capacity, 3); }

void splat_gaussians_destroy(pg_gaussians *g)
{
    if (!g) return;
    free(g->means); free(g->log_scales); free(g->quats); free(g->opacity); free(g->sh);
    memset(g, 0, sizeof(*g));
}

/* Grows one array from old_cap to new_cap rows of `width` floats, zeroing the new rows. */
static pg_status grow_array(float **arr, int old_cap, int new_cap, int width, const char *what)
{
    size_t bytes;
    if (pg_size_mul((size_t)new_cap, (size_t)width * sizeof(float), &bytes))
        return pg_fail(PG_ERR_SIZE, "gaussians: %d rows overflow", new_cap);
    float *p = realloc(*arr, bytes ? bytes : sizeof(float));
    if (!p) return pg_fail(PG_ERR_NOMEM, "gaussians: out of memory for %s (%d rows)", what, new_cap);
    memset(p + (size_t)old_cap * width, 0, (size_t)(new_cap - old_cap) * width * sizeof(float));
    *arr = p;
    return PG_OK;
}

pg_status splat_gaussians_resize(pg_gaussians *g, int count)
{
    if (count < 0) return pg_fail(PG_ERR_ARG, "gaussians: negative count %d", count);
    if (count > g->count) {
        /* Rows between the old count and the capacity may hold stale values: zero them. */
        size_t n0 = (size_t)g->count, n = (size_t)((count < g->capacity ? count : g->capacity) - g->count);
        if (g->capacity > g->count && g->means) {
            memset(g->means + n0 * G_MEAN, 0, n * G_MEAN * sizeof(float));
            memset(g->log_scales + n0 * G_SCALE, 0, n * G_SCALE * sizeof(float));
            memset(g->quats + n0 * G_QUAT, 0, n * G_QUAT * sizeof(float));
            memset(g->opacity + n0 * G_OPAC, 0, n * G_OPAC * sizeof(float));
            memset(g->sh + n0 * g->sh_stride, 0, n * g->sh_stride * sizeof(float));
        }
    }
    if (count > g->capacity || !g->means) {
        if (!g->means && g->sh_stride == 0) g->sh_stride = PG_SH_FLOATS; /* a zeroed struct: every degree */
        int cap = g->capacity;
        int new_cap = count > cap + cap / 2 ? count : cap + cap / 2;
        if (new_cap < 1) new_cap = 1;
        PG_TRY(grow_array(&g->means, cap, new_cap, G_MEAN, "means"));
        PG_TRY(grow_array(&g->log_scales, cap, new_cap, G_SCALE, "log_scales"));
        PG_TRY(grow_array(&g->quats, cap, new_cap, G_QUAT, "quats"));
        PG_TRY(grow_array(&g->opacity, cap, new_cap, G_OPAC, "opacity"));
        PG_TRY(grow_array(&g->sh, cap, new_cap, g->sh_stride, "sh"));
        g->capacity = new_cap;
    }
    g->count = count;
    return PG_OK;
}

void splat_gaussians_zero(pg_gaussians *g)
{
    size_t n = (size_t)g->count;
    if (!g->means || n == 0) return;
    memset(g->means, 0, n * G_MEAN * sizeof(float));
    memset(g->log_scales, 0, n * G_SCALE * sizeof(float));
    memset(g->quats, 0, n * G_QUAT * sizeof(float));
    memset(g->opacity, 0, n * G_OPAC * sizeof(float));
    memset(g->sh, 0, n * g->sh_stride * sizeof(float));
}

pg_status splat_gaussians_copy(const pg_gaussians *src, pg_gaussians *dst)
{
    if (dst->capacity < src->count || dst->sh_stride != src->sh_stride) {
        splat_gaussians_destroy(dst);
        PG_TRY(splat_gaussians_create_sh(dst, src->count, splat_gaussians_sh_max(src)));
    }
    PG_TRY(splat_gaussians_resize(dst, src->count));
    size_t n = (size_t)src->count;
    memcpy(dst->means, src->means, n * 3 * sizeof(float));
    memcpy(dst->log_scales, src->log_scales, n * 3 * sizeof(float));
    memcpy(dst->quats, src->quats, n * 4 * sizeof(float));
    memcpy(dst->opacity, src->opacity, n * sizeof(float));
    memcpy(dst->sh, src->sh, n * src->sh_stride * sizeof(float));
    dst->sh_degree = src->sh_degree;
    return PG_OK;
}
