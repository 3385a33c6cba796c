/* cmd_run.c - `prodygs run INPUT --depth PATH --out DIR`: the whole pipeline for a user's video:
 * depth preparation, proxy views, 4D training, and novel-view videos. */
#include "cli/cli.h"
#include "cli/pipeline.h"
#include "core/fileutil.h"
#include "core/parallel.h"
#include "io/image_io.h"
#include "render/render_video.h"
#include "render/scene_cameras.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    char dir[4200]; /* the real camera's frames in the training set */
} input_frames;

/* The input video's frame at a render step (the fixed path renders one step per frame). */
static pg_status input_reference(void *ctx, int step, float time, pg_image *img)
{
    (void)time;
    input_frames *in = ctx;
    char file[32], path[4300];
    snprintf(file, sizeof file, "%04d.png", step);
    PG_TRY(pg_path_join(path, sizeof path, in->dir, file));
    return io_image_load(path, img);
}

/* Renders the three standard videos of a trained model into OUT/renders. */
int pipeline_render_videos(const pipeline_options *o, cJSON *seconds)
{
    char prepare_dir[4096], proxies_dir[4096], model_dir[4096], renders[4200];
    pipeline_paths(o, prepare_dir, proxies_dir, model_dir, sizeof prepare_dir);
    snprintf(renders, sizeof renders, "%s/renders", o->out);
    double t0 = pg_time_seconds();
    scene_cameras *sc = pg_malloc(sizeof *sc, "cameras");
    if (!sc) return cli_fail(PG_ERR_NOMEM);
    render_model *rm = NULL;
    pg_status st = scene_cameras_for_model(model_dir, NULL, sc);
    if (st == PG_OK) st = render_model_open(model_dir, &rm);
    input_frames in;
    if (st == PG_OK) snprintf(in.dir, sizeof in.dir, "%s/%s/rgb", proxies_dir, sc->names[sc->real]);
    const render_path_kind kinds[3] = { RENDER_PATH_FIXED, RENDER_PATH_ORBIT, RENDER_PATH_SPIRAL };
    int fallback = 0;
    for (int k = 0; st == PG_OK && k < 3; k++) {
        int frames = render_model_frames(rm);
        render_video_options vo = {0};
        vo.path = (render_path_options){ kinds[k], frames > 1 ? frames : 60, 15.0f, 0.5f, 10.0f, 5.0f };
        if (kinds[k] == RENDER_PATH_ORBIT && vo.path.steps < 60) vo.path.steps = 60;
        vo.write_depth = 1;
        vo.fps = sc->fps;
        if (kinds[k] == RENDER_PATH_FIXED) {
            vo.reference = input_reference;
            vo.reference_ctx = &in;
        }
        render_video_report rep;
        st = render_video_write(rm, &sc->cams[sc->real], sc->center, &vo, renders, render_path_name(kinds[k]), &rep);
        fallback |= rep.fallback_png;
    }
    if (fallback) fprintf(stderr, "prodygs: warning: no H.264/MPEG-4 encoder; wrote PNG sequences instead of MP4\n");
    render_model_close(rm);
    free(sc);
    cJSON_AddNumberToObject(seconds, "render", pg_time_seconds() - t0);
    return st ? cli_fail(st) : 0;
}

int cmd_run(int argc, char **argv)
{
    pipeline_options o;
    const char *proxies_text;
    cli_option options[40];
    int n = pipeline_cli_options(&o, &proxies_text, options, 40);
    const cli_spec spec = { "prodygs run", "INPUT --depth PATH --out DIR [options]",
                            "The whole pipeline on a static-camera video (file, frame folder, or a dataset with\n"
                            "--train-cam): depth preparation -> proxy views -> 4D training -> novel-view videos\n"
                            "(DIR/renders: fixed.mp4 with fixed_compare.mp4, orbit.mp4, spiral.mp4, *_depth.mp4).\n"
                            "Rerunning the same command continues from the last finished stage or checkpoint.",
                            options, n, 1, 1 };
    int rc = pipeline_cli_parse(&spec, argc, argv, &o, &proxies_text);
    if (rc) return rc < 0 ? 0 : rc;
    cJSON *seconds = cJSON_CreateObject();
    rc = pipeline_run_stages(&o, seconds);
    if (rc == 0) rc = pipeline_render_videos(&o, seconds);
    if (rc == 0) {
        char *text = cJSON_PrintUnformatted(seconds);
        printf("{\"out\": \"%s\", \"seconds\": %s}\n", o.out, text ? text : "{}");
        free(text);
    }
    cJSON_Delete(seconds);
    return rc;
}
