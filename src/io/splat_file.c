/* splat_file.c - writes the 32-byte ".splat" rows (see splat_file.h). */
#include "io/splat_file.h"
#include "splat/sh.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "core/fileutil.h"
#include "core/mathx.h"


static uint8_t to_u8(float v) { return (uint8_t)lroundf(clampf(v, 0.0f, 255.0f)); }

pg_status io_splat_save(const char *path, const pg_gaussians *g)
{
    if (g->count < 0 || (g->count > 0 && (!g->means || !g->sh)))
        return pg_fail(PG_ERR_ARG, "%s: Gaussians are empty or invalid", path);
    pg_atomic_file f;
    PG_TRY(pg_atomic_open(&f, path));
    for (int i = 0; i < g->count; i++) {
        uint8_t row[IO_SPLAT_ROW_BYTES];
        float pos_scale[6];
        for (int k = 0; k < 3; k++) {
            pos_scale[k] = g->means[3 * (size_t)i + k];
            pos_scale[3 + k] = expf(g->log_scales[3 * (size_t)i + k]);
        }
        memcpy(row, pos_scale, sizeof pos_scale); /* little-endian hosts (x86-64) */
        const float *dc = splat_gaussians_sh(g, (size_t)i);
        for (int k = 0; k < 3; k++) row[24 + k] = to_u8((0.5f + SPLAT_SH_C0 * dc[k]) * 255.0f);
        row[27] = to_u8(255.0f / (1.0f + expf(-g->opacity[i])));
        const float *q = g->quats + 4 * (size_t)i;
        float n = sqrtf(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
        for (int k = 0; k < 4; k++) row[28 + k] = to_u8((n > 0 ? q[k] / n : (float)(k == 0)) * 128.0f + 128.0f);
        if (fwrite(row, 1, sizeof row, f.fp) != sizeof row) {
            pg_atomic_abort(&f);
            return pg_fail(PG_ERR_ENV, "%s: write failed: %s", path, strerror(errno));
        }
    }
    return pg_atomic_commit(&f);
}
