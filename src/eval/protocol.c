/* protocol.c - scores held-out cameras of a dataset against a trained model's renders. */
#include "eval/protocol.h"
#include "core/fileutil.h"
#include "core/progress.h"
#include "eval/report.h"
#include "io/dataset.h"
#include "render/model_render.h"
#include "render/scene_cameras.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Frames that get a side-by-side PNG: first, middle, last. */
static int wants_side_by_side(int f, int frames) { return f == 0 || f == frames / 2 || f == frames - 1; }

pg_status eval_protocol_run(const char *dataset, const char *model, const char *sbs_dir, eval_results *results)
{
    scene_cameras *sc = pg_malloc(sizeof *sc, "cameras");
    if (!sc) return PG_ERR_NOMEM;
    render_model *rm = NULL;
    pg_dataset *ds = NULL;
    optim_ssim_ws *ws = NULL;
    pg_image pred = {0}, truth = {0};
    pg_status st = scene_cameras_for_model(model, NULL, sc);
    if (st == PG_OK) st = render_model_open(model, &rm);
    const pg_camera *real = &sc->cams[sc->real];
    int frames = rm ? render_model_frames(rm) : 0;
    int tests = 0;
    for (int k = 0; st == PG_OK && k < sc->count; k++) tests += sc->roles[k] == SCENE_ROLE_TEST;
    if (st == PG_OK && tests == 0) st = pg_fail(PG_ERR_ARG, "%s: the model's trainset.json lists no test cameras", model);
    if (st == PG_OK) {
        io_dataset_options opt = io_dataset_defaults();
        opt.width = real->width;
        opt.height = real->height;
        opt.count = frames;
        st = io_dataset_open(dataset, &opt, &ds);
    }
    if (st == PG_OK && io_dataset_num_frames(ds) < frames)
        st = pg_fail(PG_ERR_SIZE, "%s: has %d frames, the model was trained on %d", dataset, io_dataset_num_frames(ds), frames);
    if (st == PG_OK) st = optim_ssim_create(&ws, real->height, real->width, 3);
    if (st == PG_OK) st = pg_image_create(&pred, real->width, real->height, 3);
    if (st == PG_OK && sbs_dir) st = pg_mkdir_p(sbs_dir);
    int done = 0;
    for (int k = 0; st == PG_OK && k < sc->count; k++) {
        if (sc->roles[k] != SCENE_ROLE_TEST) continue;
        int cam = io_dataset_find_camera(ds, sc->names[k]);
        if (cam < 0) {
            st = pg_fail(PG_ERR_ARG, "%s: no camera named %s (held out in the model)", dataset, sc->names[k]);
            break;
        }
        for (int f = 0; st == PG_OK && f < frames; f++) {
            pg_render_output out;
            st = render_model_frame(rm, &sc->cams[k], train_frame_time(f, frames), &out);
            if (st == PG_OK) st = io_dataset_frame(ds, cam, f, &truth);
            if (st != PG_OK) break;
            memcpy(pred.data, out.rgb, sizeof(float) * 3 * (size_t)pred.width * pred.height);
            eval_scores s;
            st = eval_score_image(ws, &pred, &truth, out.alpha, &s);
            if (st == PG_OK) st = eval_results_add(results, sc->names[k], f, &s);
            if (st == PG_OK && sbs_dir && wants_side_by_side(f, frames)) {
                char file[96], path[4200];
                snprintf(file, sizeof file, "%s_%04d.png", sc->names[k], f);
                st = pg_path_join(path, sizeof path, sbs_dir, file);
                if (st == PG_OK) st = eval_write_side_by_side(path, &truth, &pred);
            }
            pg_image_destroy(&truth);
            pg_progress_report("eval", ++done, (long)tests * frames, "camera=%s psnr=%.2f", sc->names[k], s.psnr);
        }
        io_dataset_release(ds, cam);
    }
    pg_image_destroy(&pred);
    optim_ssim_destroy(ws);
    io_dataset_close(ds);
    render_model_close(rm);
    free(sc);
    return st;
}
