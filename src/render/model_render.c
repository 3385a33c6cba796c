/* model_render.c - load checkpoint -> deform at t -> rasterize. */
#include "render/model_render.h"

#include <stdlib.h>
#include <string.h>

#include "core/fileutil.h"
#include "render/scene_cameras.h"

struct render_model {
    train_model model;
    pg_gaussians at_t; /* deformed copy */
    int at_t_filled;   /* at_t holds the model at some time: a new time redoes only the movers */
    splat_raster *raster;
    float train_focal; /* the real view's focal length in pixels (0: no cameras beside the model) */
};

/* The focal length the model was trained at, from the cameras.json beside it: renders finer than
 * that keep a training pixel's screen-space filter (splat_lowpass_for). A model without its
 * cameras renders with the plain filter. */
static float training_focal(const char *path)
{
    scene_cameras *sc = pg_calloc(1, sizeof *sc, "model cameras");
    float f = 0.0f;
    if (sc && scene_cameras_for_model(path, NULL, sc) == PG_OK) {
        const pg_camera *c = &sc->cams[sc->real];
        f = c->fx > c->fy ? c->fx : c->fy;
    }
    free(sc);
    return f;
}

pg_status render_model_checkpoint_path(const char *path, char *out, size_t size)
{
    if (pg_path_is_dir(path)) return pg_path_join(out, size, path, "model.ckpt");
    if ((size_t)snprintf(out, size, "%s", path) >= size) return pg_fail(PG_ERR_ARG, "%s: path too long", path);
    return PG_OK;
}

pg_status render_model_open(const char *path, render_model **rm)
{
    char ck[4096];
    *rm = NULL;
    PG_TRY(render_model_checkpoint_path(path, ck, sizeof ck));
    if (!pg_path_exists(ck)) return pg_fail(PG_ERR_IO, "%s: no trained model (missing %s)", path, ck);
    render_model *r = pg_calloc(1, sizeof *r, "render model");
    if (!r) return PG_ERR_NOMEM;
    pg_status st = train_model_load(ck, &r->model);
    if (!st) st = splat_raster_create(&r->raster);
    if (st) {
        render_model_close(r);
        return st;
    }
    r->train_focal = training_focal(path);
    *rm = r;
    return PG_OK;
}

void render_model_close(render_model *rm)
{
    if (!rm) return;
    train_model_destroy(&rm->model);
    splat_gaussians_destroy(&rm->at_t);
    splat_raster_destroy(rm->raster);
    free(rm);
}

pg_status render_model_gaussians_at(render_model *rm, float t, const pg_gaussians **g)
{
    if (!(t >= 0.0f && t <= 1.0f)) return pg_fail(PG_ERR_ARG, "render: time %g is outside [0, 1]", t);
    if (rm->at_t_filled) PG_TRY(train_model_deform_movers(&rm->model, t, &rm->at_t));
    else PG_TRY(train_model_deform(&rm->model, t, &rm->at_t));
    rm->at_t_filled = 1;
    *g = &rm->at_t;
    return PG_OK;
}

pg_status render_model_frame(render_model *rm, const pg_camera *cam, float t, pg_render_output *out)
{
    const pg_gaussians *g = NULL;
    PG_TRY(render_model_gaussians_at(rm, t, &g));
    pg_render_settings s = splat_default_settings();
    memcpy(s.background, rm->model.bg, sizeof s.background);
    s.train_focal = rm->train_focal;
    return splat_render_forward(rm->raster, g, cam, &s, out);
}

int render_model_frames(const render_model *rm) { return rm->model.frames; }
