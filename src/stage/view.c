/* view.c - the view stage: a trained model as a self-contained web viewer directory
 * (index.html + scene.pgvs, docs/viewer.md) and the localhost server that shows it. */
#include "stage/stage_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/fileutil.h"
#include "core/output.h"
#include "core/parallel.h"
#include "core/status.h"
#include "io/json.h"
#include "render/model_render.h"
#include "render/scene_cameras.h"
#include "train/model.h"
#include "view/http_server.h"
#include "view/view_page.h"
#include "view/view_scene.h"

#define VIEW_MAX_FILE ((size_t)4 << 30) /* what pg_view_serve loads into memory */

void pg_view_defaults(pg_view_config *c)
{
    memset(c, 0, sizeof *c);
}

static pg_status deform_at(void *ctx, float t, pg_gaussians *out) { return train_model_deform(ctx, t, out); }

/* The scene file's metadata: the model's cameras (home = the real one) and the scene centre. */
static char *meta_json(const scene_cameras *sc, int video_frames)
{
    cJSON *root = cJSON_CreateObject(), *cams = cJSON_CreateArray();
    cJSON_AddItemToObject(root, "cameras", cams);
    for (int k = 0; k < sc->count; k++) {
        cJSON *c = io_json_from_camera(&sc->cams[k], sc->names[k]);
        if (c) cJSON_AddStringToObject(c, "role", io_view_role_name(sc->roles[k]));
        cJSON_AddItemToArray(cams, c);
    }
    cJSON_AddNumberToObject(root, "home", sc->real);
    cJSON_AddItemToObject(root, "center", io_json_float_array(sc->center, 3));
    cJSON_AddNumberToObject(root, "video_frames", video_frames);
    char *text = cJSON_PrintUnformatted(root);
    cJSON_Delete(root);
    return text;
}

static pg_status view_run(const pg_view_config *c, pg_view_report *r)
{
    memset(r, 0, sizeof *r);
    if (!c->model || !c->out) return pg_fail(PG_ERR_ARG, "view: model and out are required");
    if (c->frames < 0 || c->frames > VIEW_SCENE_MAX_FRAMES)
        return pg_fail(PG_ERR_ARG, "view: --frames %d is not in 1..%d", c->frames, VIEW_SCENE_MAX_FRAMES);
    if (c->max_gaussians < 0) return pg_fail(PG_ERR_ARG, "view: --max-gaussians %d must be >= 0", c->max_gaussians);
    const double t0 = pg_time_seconds();
    char ck[4096], path[4200];
    PG_TRY(render_model_checkpoint_path(c->model, ck, sizeof ck));
    if (!pg_path_exists(ck)) return pg_fail(PG_ERR_IO, "%s: no trained model (missing %s)", c->model, ck);
    scene_cameras *sc = pg_malloc(sizeof *sc, "cameras");
    if (!sc) return PG_ERR_NOMEM;
    train_model m = { 0 };
    char *meta = NULL;
    pg_status st = scene_cameras_for_model(c->model, NULL, sc);
    if (st == PG_OK) st = train_model_load(ck, &m);
    if (st == PG_OK && !(meta = meta_json(sc, m.frames))) st = pg_fail(PG_ERR_NOMEM, "view: out of memory");
    if (st == PG_OK) st = pg_mkdir_p(c->out);
    view_scene_stats ss;
    if (st == PG_OK) {
        view_scene_source src = { .canonical = &m.g, .is_static = m.is_static, .at_time = m.net ? deform_at : NULL,
                                  .ctx = &m, .frames = c->frames > 0 ? c->frames : m.frames,
                                  .max_gaussians = c->max_gaussians, .fps = (float)sc->fps };
        memcpy(src.background, m.bg, sizeof src.background);
        st = pg_path_join(path, sizeof path, c->out, "scene.pgvs");
        if (st == PG_OK) st = view_scene_write(path, &src, meta, &ss);
    }
    if (st == PG_OK) st = pg_path_join(path, sizeof path, c->out, "index.html");
    if (st == PG_OK) st = pg_write_file_atomic(path, view_page_html, view_page_html_size);
    if (st == PG_OK) {
        r->static_gaussians = ss.static_count;
        r->moving_gaussians = ss.moving_count;
        r->dropped = ss.dropped;
        r->frames = ss.frames;
        r->sh_degree = ss.sh_degree;
        r->scene_bytes = (double)ss.bytes;
        double video_seconds = (m.frames > 0 ? m.frames : 1) / (sc->fps > 0 ? sc->fps : 30.0);
        r->bytes_per_second = r->scene_bytes / video_seconds;
        r->seconds = pg_time_seconds() - t0;
    }
    cJSON_free(meta);
    train_model_destroy(&m);
    free(sc);
    return st;
}

/* The output is claimed (checked and locked, core/output.h) before any work. */
pg_status pg_view_run(const pg_view_config *c, pg_view_report *r)
{
    memset(r, 0, sizeof *r);
    if (!c->out) return view_run(c, r); /* its own check names what is missing */
    PG_TRY(pg_output_claim_dir(c->out));
    pg_status st = view_run(c, r);
    pg_output_release(c->out);
    return st;
}

pg_status pg_view_serve(const char *dir, int port, long max_requests, void (*on_listen)(const char *url, void *user),
                        void *user)
{
    if (!dir) return pg_fail(PG_ERR_ARG, "view: no directory to serve");
    char path[4200];
    char *html = NULL, *scene = NULL;
    size_t html_size = 0, scene_size = 0;
    PG_TRY(pg_path_join(path, sizeof path, dir, "index.html"));
    pg_status st = pg_read_file(path, VIEW_MAX_FILE, &html, &html_size);
    if (st == PG_OK) st = pg_path_join(path, sizeof path, dir, "scene.pgvs");
    if (st == PG_OK) st = pg_read_file(path, VIEW_MAX_FILE, &scene, &scene_size);
    view_http_server *s = NULL;
    if (st == PG_OK) st = view_http_open(port, &s);
    if (st == PG_OK) {
        /* the whole table: nothing else exists for a client */
        const view_http_file files[] = {
            { "/", "text/html; charset=utf-8", html, html_size },
            { "/index.html", "text/html; charset=utf-8", html, html_size },
            { "/scene.pgvs", "application/octet-stream", scene, scene_size },
        };
        char url[64];
        snprintf(url, sizeof url, "http://127.0.0.1:%d/", view_http_port(s));
        if (on_listen) on_listen(url, user);
        st = view_http_serve(s, files, (int)(sizeof files / sizeof files[0]), max_requests, NULL);
    }
    view_http_close(s);
    free(html);
    free(scene);
    return st;
}
