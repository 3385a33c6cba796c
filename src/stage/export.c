/* export.c - the export stage: deformed Gaussians at chosen times or frames as binary PLY in
 * the standard 3DGS layout (OUT/frame_NNNN.ply, OUT/time_T.ply). */
#include "stage/stage_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/fileutil.h"
#include "core/status.h"
#include "io/ply.h"
#include "render/model_render.h"

void pg_export_defaults(pg_export_config *c)
{
    memset(c, 0, sizeof *c);
}

static pg_status export_one(render_model *rm, const char *dir, const char *file, float t, pg_export_report *r)
{
    const pg_gaussians *g;
    char path[4200];
    PG_TRY(render_model_gaussians_at(rm, t, &g));
    PG_TRY(pg_path_join(path, sizeof path, dir, file));
    PG_TRY(io_ply_save(path, g));
    r->files++;
    r->gaussians = g->count;
    return PG_OK;
}

pg_status pg_export_run(const pg_export_config *c, pg_export_report *r)
{
    memset(r, 0, sizeof *r);
    if (!c->model || !c->out) return pg_fail(PG_ERR_ARG, "export: model and out are required");
    if ((c->num_times > 0) + (c->num_frames > 0) + (c->all_frames != 0) > 1)
        return pg_fail(PG_ERR_ARG, "export: give only one of --times, --frame-list");
    for (int i = 0; i < c->num_times; i++)
        if (!(c->times[i] >= 0.0f && c->times[i] <= 1.0f))
            return pg_fail(PG_ERR_ARG, "export: --times: %g is not in [0, 1]", c->times[i]);
    render_model *rm = NULL;
    PG_TRY(render_model_open(c->model, &rm));
    int frames = render_model_frames(rm);
    pg_status st = PG_OK;
    for (int i = 0; i < c->num_frames && st == PG_OK; i++) /* all checked before the first file */
        if (c->frames[i] < 0 || c->frames[i] >= frames)
            st = pg_fail(PG_ERR_ARG, "export: %s: --frame-list: frame %d is not in 0..%d", c->model, c->frames[i], frames - 1);
    if (st == PG_OK) st = pg_mkdir_p(c->out);
    char file[64];
    if (c->num_frames > 0 || c->all_frames) {
        int n = c->all_frames ? frames : c->num_frames;
        for (int i = 0; st == PG_OK && i < n; i++) {
            int f = c->all_frames ? i : c->frames[i];
            snprintf(file, sizeof file, "frame_%04d.ply", f);
            st = export_one(rm, c->out, file, train_frame_time(f, frames), r);
        }
    } else {
        int n = c->num_times > 0 ? c->num_times : 1;
        for (int i = 0; st == PG_OK && i < n; i++) {
            float t = c->num_times > 0 ? c->times[i] : 0.0f;
            snprintf(file, sizeof file, "time_%.3f.ply", t);
            st = export_one(rm, c->out, file, t, r);
        }
    }
    render_model_close(rm);
    return st;
}
