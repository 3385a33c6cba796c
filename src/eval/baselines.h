/* baselines.h - the trivial yardsticks a novel-view model is scored beside.
 *
 *   flat:  one image of the mean colour of all the training camera's frames;
 *   as_is: the training camera's frame, shown at the test camera unchanged;
 *   warp:  the training frame forward-warped into the test camera with the depth the model was
 *          trained on (z-buffered, holes filled from the background around them).
 *
 * A model that loses to the warp of one frame has learnt nothing a depth map did not already
 * give; one that loses to the flat image draws the scene in the wrong place.
 */
#ifndef PG_EVAL_BASELINES_H
#define PG_EVAL_BASELINES_H

#include "core/camera.h"
#include "core/status.h"

enum { EVAL_BASE_FLAT, EVAL_BASE_AS_IS, EVAL_BASE_WARP, EVAL_BASELINES };
extern const char *const eval_baseline_names[EVAL_BASELINES];

/* out (dst's H2, W2, 3): rgb (real's H, W, 3) with depth (H, W, pose units, <= 0 invalid) warped
 * into dst. Cracks (holes mostly surrounded) take the colour of their farthest neighbour; wider
 * holes the farther of the nearest filled pixels left and right on their row (a disocclusion shows
 * what is behind, not the occluder); a row with none takes `fill`. */
pg_status eval_warp_baseline(const pg_camera *real, const float *rgb, const float *depth, const pg_camera *dst,
                             const float fill[3], float *out);

#endif
