/* export.c - the export stage: deformed Gaussians at chosen times or frames as binary PLY in
 * the standard 3DGS layout or as antimatter15's .splat (OUT/frame_NNNN.ply, OUT/time_T.splat),
 * cleaned for other viewers (invisible Gaussians dropped, unit quaternions), with the model's
 * cameras.json beside them. */
#include "stage/stage_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/fileutil.h"
#include "core/output.h"
#include "core/status.h"
#include "io/ply.h"
#include "io/splat_file.h"
#include "render/model_render.h"

#define LOGIT_VISIBLE (-5.537334f) /* logit(1/255): fainter Gaussians change no pixel */

void pg_export_defaults(pg_export_config *c)
{
    memset(c, 0, sizeof *c);
}

/* Copies the Gaussians of g that are visible (opacity >= 1/255) into out, quaternions normalised
 * (a zero one becomes the identity). */
static pg_status clean_copy(const pg_gaussians *g, pg_gaussians *out)
{
    if (out->capacity < g->count || out->sh_stride != g->sh_stride) {
        splat_gaussians_destroy(out);
        PG_TRY(splat_gaussians_create_sh(out, g->count, splat_gaussians_sh_max(g)));
    }
    int n = 0;
    for (int i = 0; i < g->count; i++) {
        if (!(g->opacity[i] >= LOGIT_VISIBLE)) continue;
        size_t a = (size_t)i, b = (size_t)n;
        memcpy(out->means + 3 * b, g->means + 3 * a, 3 * sizeof(float));
        memcpy(out->log_scales + 3 * b, g->log_scales + 3 * a, 3 * sizeof(float));
        memcpy(splat_gaussians_sh(out, b), splat_gaussians_sh(g, a), (size_t)g->sh_stride * sizeof(float));
        out->opacity[b] = g->opacity[a];
        const float *q = g->quats + 4 * a;
        float len = sqrtf(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
        for (int k = 0; k < 4; k++) out->quats[4 * b + k] = len > 0 ? q[k] / len : (float)(k == 0);
        n++;
    }
    out->count = n;
    out->sh_degree = g->sh_degree;
    return PG_OK;
}

static pg_status export_one(render_model *rm, const char *dir, const char *file, int splat, float t,
                            pg_gaussians *clean, pg_export_report *r)
{
    const pg_gaussians *g;
    char path[4200];
    PG_TRY(render_model_gaussians_at(rm, t, &g));
    PG_TRY(clean_copy(g, clean));
    PG_TRY(pg_path_join(path, sizeof path, dir, file));
    PG_TRY(splat ? io_splat_save(path, clean) : io_ply_save(path, clean));
    r->files++;
    r->gaussians = clean->count;
    r->dropped = g->count - clean->count;
    return PG_OK;
}

/* OUT/cameras.json: a copy of the one beside the model (none: nothing written). */
static pg_status copy_cameras(const char *model, const char *out, pg_export_report *r)
{
    char src[4200], dst[4200];
    PG_TRY(pg_path_join_beside(src, sizeof src, model, "cameras.json"));
    PG_TRY(pg_path_join(dst, sizeof dst, out, "cameras.json"));
    if (!pg_path_exists(src)) return PG_OK;
    char *data = NULL;
    size_t size = 0;
    PG_TRY(pg_read_file(src, (size_t)64 << 20, &data, &size));
    pg_status st = pg_write_file_atomic(dst, data, size);
    free(data);
    r->cameras = st == PG_OK;
    return st;
}

/* The file of a time request: to 3 decimals, so nearer times share a name (refused up front). */
static void time_file_name(char *out, size_t size, float t, const char *format)
{
    snprintf(out, size, "time_%.3f.%s", t == 0 ? 0.0f : t, format); /* -0 is 0: one file, not time_-0.000 beside it */
}

static pg_status export_run(const pg_export_config *c, pg_export_report *r)
{
    memset(r, 0, sizeof *r);
    if (!c->model || !c->out) return pg_fail(PG_ERR_ARG, "export: model and out are required");
    if ((c->num_times > 0) + (c->num_frames > 0) + (c->all_frames != 0) > 1)
        return pg_fail(PG_ERR_ARG, "export: give only one of --times, --frame-list");
    const char *format = c->format ? c->format : "ply";
    int splat = strcmp(format, "splat") == 0;
    if (!splat && strcmp(format, "ply") != 0)
        return pg_fail(PG_ERR_ARG, "export: --format must be ply or splat, got '%.32s'", format);
    for (int i = 0; i < c->num_times; i++)
        if (!(c->times[i] >= 0.0f && c->times[i] <= 1.0f))
            return pg_fail(PG_ERR_ARG, "export: --times: %g is not in [0, 1]", c->times[i]);
    /* one file per request: two requests that name the same file would overwrite each other */
    char a[64], b[64];
    for (int i = 0; i < c->num_times; i++)
        for (int k = 0; k < i; k++) {
            time_file_name(a, sizeof a, c->times[k], format);
            time_file_name(b, sizeof b, c->times[i], format);
            if (!strcmp(a, b))
                return pg_fail(PG_ERR_ARG, "export: --times %g and %g would both be written to %s (files are named to "
                               "3 decimals): give distinct times", c->times[k], c->times[i], a);
        }
    for (int i = 0; i < c->num_frames; i++)
        for (int k = 0; k < i; k++)
            if (c->frames[i] == c->frames[k])
                return pg_fail(PG_ERR_ARG, "export: --frame-list names frame %d twice", c->frames[i]);
    render_model *rm = NULL;
    PG_TRY(render_model_open(c->model, &rm));
    int frames = render_model_frames(rm);
    pg_status st = PG_OK;
    for (int i = 0; i < c->num_frames && st == PG_OK; i++) /* all checked before the first file */
        if (c->frames[i] < 0 || c->frames[i] >= frames)
            st = pg_fail(PG_ERR_ARG, "export: %s: --frame-list: frame %d is not in 0..%d", c->model, c->frames[i], frames - 1);
    pg_staged_dir out = { 0 };
    if (st == PG_OK) st = pg_staged_dir_begin(&out, c->out, 0);
    int staged = st == PG_OK;
    if (st == PG_OK) st = copy_cameras(c->model, out.work, r);
    pg_gaussians clean = { 0 };
    char file[64];
    if (c->num_frames > 0 || c->all_frames) {
        int n = c->all_frames ? frames : c->num_frames;
        for (int i = 0; st == PG_OK && i < n; i++) {
            int f = c->all_frames ? i : c->frames[i];
            snprintf(file, sizeof file, "frame_%04d.%s", f, format);
            st = export_one(rm, out.work, file, splat, train_frame_time(f, frames), &clean, r);
        }
    } else {
        int n = c->num_times > 0 ? c->num_times : 1;
        for (int i = 0; st == PG_OK && i < n; i++) {
            float t = c->num_times > 0 ? c->times[i] : 0.0f;
            time_file_name(file, sizeof file, t, format);
            st = export_one(rm, out.work, file, splat, t, &clean, r);
        }
    }
    splat_gaussians_destroy(&clean);
    render_model_close(rm);
    if (staged && st) pg_staged_dir_abort(&out);
    else if (staged) st = pg_staged_dir_commit(&out);
    return st;
}

/* The output is claimed (checked and locked, core/output.h) before any work and held for the
 * whole stage. */
pg_status pg_export_run(const pg_export_config *c, pg_export_report *r)
{
    memset(r, 0, sizeof *r);
    if (!c->out) return export_run(c, r); /* its own check names what is missing */
    PG_TRY(pg_output_claim_dir(c->out));
    pg_status st = export_run(c, r);
    pg_output_release(c->out);
    return st;
}
