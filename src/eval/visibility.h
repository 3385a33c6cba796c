/* visibility.h - where a test camera's pixels come from, seen from the real camera.
 *
 * A novel view mixes three kinds of content, and each is a different problem: pixels the real
 * camera SAW (reconstruction), pixels behind something in the real view (DISOCCLUDED, only the
 * proxies and the motion can reveal them) and pixels OUTSIDE the real frame (pure guesswork,
 * the proxies' outpainted margin). Labels use the model's own rendered depth at both cameras.
 */
#ifndef PG_EVAL_VISIBILITY_H
#define PG_EVAL_VISIBILITY_H

#include <stdint.h>

#include "core/camera.h"

/* test_depth, test_alpha: the render at the test camera (expected depth NOT normalised, alpha);
 * real_zdepth: the render at the real camera at the same time, normalised by alpha (0 = empty).
 * labels (test H*W) get EVAL_SEEN, EVAL_DISOCCLUDED or EVAL_OUTSIDE; a pixel where the model
 * renders nothing (alpha <= 0.5) counts as outside (no surface the real camera could have seen). */
void eval_visibility_labels(const pg_camera *test, const float *test_depth, const float *test_alpha,
                            const pg_camera *real, const float *real_zdepth, uint8_t *labels);

#endif
