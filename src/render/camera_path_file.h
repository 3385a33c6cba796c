/* camera_path_file.h - a user's own shot: a camera path file (nerfstudio's camera_path.json, or
 * the subset documented in docs/FORMATS.md) turned into one camera and time per output frame.
 *
 *   pg_camera *cams; float *times; int n;
 *   PG_TRY(render_camera_path_load("shot.json", &real, 0, 0, &cams, &times, &n));
 *   ... render cams[i] at times[i] ...
 *   free(cams); free(times);
 *
 * Each "camera_path" entry: "camera_to_world" (4x4 row-major, 16 numbers; OpenGL axes as in
 * nerfstudio unless the file says "convention": "opencv"), "fov" (vertical, degrees) and an
 * optional "time" in [0, 1] (default: evenly from 0 to 1 over the path).
 */
#ifndef PG_CAMERA_PATH_FILE_H
#define PG_CAMERA_PATH_FILE_H

#include "core/camera.h"
#include "core/status.h"

#define RENDER_MAX_PATH_FRAMES 100000

/* Image size: width x height when both > 0 (one 0 keeps the aspect of the file's
 * render_width/render_height, else of `fallback`); else the file's size, else fallback's. */
pg_status render_camera_path_load(const char *path, const pg_camera *fallback, int width, int height,
                                  pg_camera **cams, float **times, int *count);

#endif
