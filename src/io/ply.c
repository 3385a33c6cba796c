/* ply.c - Gaussian PLY load/save (3DGS attribute layout); see ply.h for the mapping. */
#include "io/ply.h"
#include "io/ply_internal.h"
#include "core/fileutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <errno.h>
#include <string.h>

#define SH_C0 0.28209479177387814

pg_status io_ply_load(const char *path, pg_gaussians *g)
{
    memset(g, 0, sizeof *g);
    ply_file pf;
    PG_TRY(ply_read(path, &pf));
    int pos[3] = { ply_find(&pf, "x"), ply_find(&pf, "y"), ply_find(&pf, "z") };
    if (pos[0] < 0 || pos[1] < 0 || pos[2] < 0) {
        ply_free(&pf);
        return pg_fail(PG_ERR_FORMAT, "%s: vertex element lacks x, y or z", path);
    }
    int dc[3], sc[3], rot[4], rest[45], rgb[3], op = ply_find(&pf, "opacity"), nrest = 0;
    char name[32];
    for (int k = 0; k < 3; k++) {
        snprintf(name, sizeof name, "f_dc_%d", k);
        dc[k] = ply_find(&pf, name);
        snprintf(name, sizeof name, "scale_%d", k);
        sc[k] = ply_find(&pf, name);
    }
    rgb[0] = ply_find(&pf, "red");
    rgb[1] = ply_find(&pf, "green");
    rgb[2] = ply_find(&pf, "blue");
    for (int k = 0; k < 4; k++) {
        snprintf(name, sizeof name, "rot_%d", k);
        rot[k] = ply_find(&pf, name);
    }
    for (int k = 0; k < 45; k++) {
        snprintf(name, sizeof name, "f_rest_%d", k);
        rest[k] = ply_find(&pf, name);
        if (rest[k] >= 0) nrest = k + 1;
    }
    /* f_rest holds 3 x K coefficients, channel-major; K = (degree+1)^2 - 1. */
    int K = nrest / 3;
    if (nrest % 3 || (K != 0 && K != 3 && K != 8 && K != 15)) {
        ply_free(&pf);
        return pg_fail(PG_ERR_FORMAT, "%s: %d f_rest properties (expected 0, 9, 24 or 45)", path, nrest);
    }
    for (int k = 0; k < nrest; k++)
        if (rest[k] < 0) {
            ply_free(&pf);
            return pg_fail(PG_ERR_FORMAT, "%s: f_rest_%d is missing", path, k);
        }
    int degree = K == 15 ? 3 : K == 8 ? 2 : K == 3 ? 1 : 0;
    if (pf.sh_degree_comment >= 0 && pf.sh_degree_comment <= degree) degree = pf.sh_degree_comment;
    pg_status st = splat_gaussians_create(g, pf.count);
    if (st == PG_OK) st = splat_gaussians_resize(g, pf.count);
    if (st) {
        ply_free(&pf);
        splat_gaussians_destroy(g);
        return pg_fail_context(st, "%s", path);
    }
    g->sh_degree = degree;
    int rgb_u8 = rgb[0] >= 0 && pf.props[rgb[0]].type == PLY_U8;
    for (int i = 0; i < pf.count && st == PG_OK; i++) {
        float *m = g->means + (size_t)i * 3, *s = g->log_scales + (size_t)i * 3, *q = g->quats + (size_t)i * 4;
        float *sh = splat_gaussians_sh(g, (size_t)i);
        for (int k = 0; k < 3; k++) {
            m[k] = (float)ply_get(&pf, i, pos[k]);
            s[k] = sc[k] >= 0 ? (float)ply_get(&pf, i, sc[k]) : -4.6051702f; /* log(0.01) */
            if (dc[k] >= 0) sh[k] = (float)ply_get(&pf, i, dc[k]);
            else if (rgb[0] >= 0 && rgb[1] >= 0 && rgb[2] >= 0) {
                double c = ply_get(&pf, i, rgb[k]);
                if (rgb_u8) c /= 255.0;
                sh[k] = (float)((c - 0.5) / SH_C0);
            }
        }
        for (int c = 0; c < 3; c++)
            for (int k = 0; k < K; k++) sh[(k + 1) * 3 + c] = (float)ply_get(&pf, i, rest[c * K + k]);
        if (rot[0] >= 0 && rot[1] >= 0 && rot[2] >= 0 && rot[3] >= 0)
            for (int k = 0; k < 4; k++) q[k] = (float)ply_get(&pf, i, rot[k]);
        else
            q[0] = 1, q[1] = q[2] = q[3] = 0;
        g->opacity[i] = op >= 0 ? (float)ply_get(&pf, i, op) : 2.0f;
        int bad = !isfinite(g->opacity[i]);
        for (int k = 0; k < 3; k++) bad |= !isfinite(m[k]) || !isfinite(s[k]);
        for (int k = 0; k < 4; k++) bad |= !isfinite(q[k]);
        for (int k = 0; k < PG_SH_COEFFS * 3; k++) bad |= !isfinite(sh[k]);
        if (bad) st = pg_fail(PG_ERR_FORMAT, "%s: vertex %d has a non-finite value", path, i);
        else if (q[0] == 0 && q[1] == 0 && q[2] == 0 && q[3] == 0)
            st = pg_fail(PG_ERR_FORMAT, "%s: vertex %d has a zero rotation quaternion", path, i);
    }
    ply_free(&pf);
    if (st) splat_gaussians_destroy(g);
    return st;
}

pg_status io_ply_save(const char *path, const pg_gaussians *g)
{
    if (g->count < 0 || (g->count > 0 && (!g->means || !g->sh)))
        return pg_fail(PG_ERR_ARG, "%s: Gaussians are empty or invalid", path);
    pg_atomic_file f;
    PG_TRY(pg_atomic_open(&f, path));
    fprintf(f.fp, "ply\nformat binary_little_endian 1.0\ncomment prodygs 3D Gaussians\ncomment sh_degree %d\n"
                  "element vertex %d\n", g->sh_degree, g->count);
    const char *fixed[] = { "x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2" };
    for (int k = 0; k < 9; k++) fprintf(f.fp, "property float %s\n", fixed[k]);
    for (int k = 0; k < 45; k++) fprintf(f.fp, "property float f_rest_%d\n", k);
    fprintf(f.fp, "property float opacity\n");
    for (int k = 0; k < 3; k++) fprintf(f.fp, "property float scale_%d\n", k);
    for (int k = 0; k < 4; k++) fprintf(f.fp, "property float rot_%d\n", k);
    fprintf(f.fp, "end_header\n");
    enum { ROW = 62 };
    float row[ROW];
    for (int i = 0; i < g->count; i++) {
        const float *sh = splat_gaussians_sh(g, (size_t)i);
        int n = 0;
        for (int k = 0; k < 3; k++) row[n++] = g->means[(size_t)i * 3 + k];
        row[n++] = 0; row[n++] = 0; row[n++] = 0;
        for (int c = 0; c < 3; c++) row[n++] = sh[c];
        for (int c = 0; c < 3; c++)
            for (int k = 1; k < PG_SH_COEFFS; k++) row[n++] = k * 3 + c < g->sh_stride ? sh[k * 3 + c] : 0.0f;
        row[n++] = g->opacity[i];
        for (int k = 0; k < 3; k++) row[n++] = g->log_scales[(size_t)i * 3 + k];
        for (int k = 0; k < 4; k++) row[n++] = g->quats[(size_t)i * 4 + k];
        if (fwrite(row, sizeof(float), ROW, f.fp) != ROW) {
            pg_atomic_abort(&f);
            return pg_fail(PG_ERR_ENV, "%s: write failed: %s", path, strerror(errno));
        }
    }
    return pg_atomic_commit(&f);
}
