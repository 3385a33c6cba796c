/* render_video.h - renders a trained model along a camera path into PNG frames and MP4s.
 *
 * For each path step: the colour image (NAME/NNNN.png and NAME.mp4), optionally the depth as
 * a false-colour video (NAME_depth.mp4) and a side-by-side video (NAME_compare.mp4) of a
 * reference frame (the input video, or a held-out camera's truth) next to the render.
 */
#ifndef PG_RENDER_VIDEO_H
#define PG_RENDER_VIDEO_H

#include "core/camera.h"
#include "core/image.h"
#include "render/model_render.h"
#include "render/render_path.h"

typedef struct {
    render_path_options path;
    int use_camera;        /* 1: every step uses `camera` (dataset-cam path), time runs over the video */
    pg_camera camera;
    /* A user's path (camera_path_file.h): step i renders keys[i] at key_times[i]; all of one size. */
    const pg_camera *keys;
    const float *key_times;
    int num_keys;
    int write_depth;       /* also NAME_depth.mp4 */
    int write_frames;      /* also NAME/NNNN.png */
    double fps;
    /* Optional reference frames for the side-by-side video: reference(ctx, step, time, img). */
    pg_status (*reference)(void *ctx, int step, float time, pg_image *img);
    void *reference_ctx;
} render_video_options;

typedef struct {
    int frames;
    int fallback_png;      /* 1 if no MP4 encoder was available (PNG sequences written instead) */
    double seconds;
} render_video_report;

/* Renders opt->path.steps frames (the video's frame count for a dataset camera path, num_keys
 * for a user's path) at the size of the camera used (keys, camera or real). */
pg_status render_video_write(render_model *rm, const pg_camera *real, const float center[3],
                             const render_video_options *opt, const char *out_dir, const char *name,
                             render_video_report *report);

#endif
