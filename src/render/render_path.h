/* render_path.h - camera paths for novel-view videos.
 *
 * fixed:  one novel viewpoint (the real camera swung sideways/up by an angle around the
 *         scene centre) for every frame of the video.
 * orbit:  "bullet time": time frozen, the camera swings along a horizontal arc around the
 *         scene centre and back.
 * spiral: the camera circles on a widening cone around the real view while time runs.
 * Every path keeps the real camera's intrinsics and up direction and looks at the centre.
 */
#ifndef PG_RENDER_PATH_H
#define PG_RENDER_PATH_H

#include "core/camera.h"
#include "core/status.h"

typedef enum { RENDER_PATH_FIXED, RENDER_PATH_ORBIT, RENDER_PATH_SPIRAL, RENDER_PATH_COUNT } render_path_kind;

typedef struct {
    render_path_kind kind;
    int steps;           /* number of output frames */
    float max_angle_deg; /* how far the path swings from the real view */
    float time;          /* frozen time for orbit, in [0, 1] */
    float fixed_yaw_deg, fixed_pitch_deg; /* the novel viewpoint of the fixed path */
} render_path_options;

/* Parses "fixed", "orbit" or "spiral". */
pg_status render_path_parse(const char *name, render_path_kind *kind);
/* Camera i (of opt->steps) of the path and its time in [0, 1]. `center` is the point the
 * cameras look at (e.g. median depth on the real camera's optical axis). */
void render_path_camera(const render_path_options *opt, const pg_camera *real, const float center[3], int i,
                        pg_camera *cam, float *time);

#endif
