/* model_render.h - render a trained 4D model at any (camera, t) from its checkpoint alone.
 *
 *   render_model *rm;
 *   PG_TRY(render_model_open("out/model", &rm));          // MODEL dir or the .ckpt file
 *   pg_render_output out;
 *   PG_TRY(render_model_frame(rm, &cam, 0.25f, &out));     // out.rgb (H,W,3), depth, alpha
 *   const pg_gaussians *g;
 *   PG_TRY(render_model_gaussians_at(rm, 0.25f, &g));      // deformed Gaussians (PLY export)
 *   render_model_close(rm);
 *
 * t in [0,1] covers the training video (frame f of F is f / (F - 1), see train_frame_time).
 * Output buffers stay valid until the next call on the same render_model.
 */
#ifndef PG_MODEL_RENDER_H
#define PG_MODEL_RENDER_H

#include "core/camera.h"
#include "splat/raster.h"
#include "train/model.h"

typedef struct render_model render_model;

/* path: a model directory (holding model.ckpt) or a checkpoint file. */
pg_status render_model_open(const char *path, render_model **rm);
void render_model_close(render_model *rm);
/* Resolves MODEL (dir or file) to the checkpoint path. */
pg_status render_model_checkpoint_path(const char *path, char *out, size_t size);
pg_status render_model_frame(render_model *rm, const pg_camera *cam, float t, pg_render_output *out);
pg_status render_model_gaussians_at(render_model *rm, float t, const pg_gaussians **g);
/* Frames of the training video (t = f / (frames - 1)). */
int render_model_frames(const render_model *rm);

#endif
