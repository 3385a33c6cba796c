/* protocol.h - the DyNeRF evaluation protocol on a trained model.
 *
 * Renders every frame of every held-out camera (role "test" in the model's trainset.json,
 * poses already in the model's units) and scores it against that camera's real frames from
 * the dataset, resized to the training size. Writes side-by-side PNGs for a few frames.
 */
#ifndef PG_EVAL_PROTOCOL_H
#define PG_EVAL_PROTOCOL_H

#include "eval/metrics.h"

/* dataset: the DyNeRF (or Panoptic) directory; model: the trained model directory (with
 * trainset.json); sbs_dir: where truth|render|error PNGs go (NULL: none). */
pg_status eval_protocol_run(const char *dataset, const char *model, const char *sbs_dir, eval_results *results);

#endif
