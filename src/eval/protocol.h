/* protocol.h - the DyNeRF evaluation protocol on a trained model.
 *
 * Renders every frame of every held-out camera (role "test" in the model's trainset.json,
 * poses already in the model's units) and scores it against that camera's real frames from
 * the dataset, resized to the training size. Writes side-by-side PNGs for a few frames.
 */
#ifndef PG_EVAL_PROTOCOL_H
#define PG_EVAL_PROTOCOL_H

#include <stdint.h>

#include "eval/metrics.h"
#include "io/dataset.h"

/* The moving-pixel definition of the evaluation: colour off the temporal median by > 0.12 in any
 * channel, dilated 2 px. */
#define EVAL_MOVING_THRESH 0.12f
#define EVAL_MOVING_DILATE 2

/* The first `frames` frames of dataset camera cam (decoded at W x H) -> *moving (frames, H, W),
 * 1 = moving by the definition above; malloc'd, NULL on failure. */
pg_status eval_dataset_moving_masks(pg_dataset *ds, int cam, int frames, int W, int H, uint8_t **moving);
/* 1 for the frames that get a side-by-side PNG (first, middle, last of `frames`), in eval and in
 * `proxies --diagnose`, so both show the same moments. */
int eval_wants_side_by_side(int f, int frames);

/* dataset: the DyNeRF (or Panoptic) directory; model: the trained model directory (with
 * trainset.json); trainset: the training set it was trained on (its real camera's depth gives the
 * warp baseline; NULL: none); sbs_dir: where truth|render|error PNGs go (NULL: none). The
 * baselines (eval/baselines.h) are scored into results->baseline when the dataset has the
 * training camera. */
pg_status eval_protocol_run(const char *dataset, const char *model, const char *trainset, const char *sbs_dir,
                            eval_results *results);

#endif
