/* detail.h - the last phase of a full-size run (`--preset full`): the training camera at the
 * input's own size after the model was trained at the working size.
 *
 *   train_detail_config dc = { "clip.mp4", "clip", 0, 0 };   // source, its camera, default steps and cap
 *   train_detail_scores sc;
 *   PG_TRY(train_session_detail(s, &dc, &sc));               // after train_session_run
 *   ... train_checkpoint_write(s, path, 0) ...
 *
 * The still scene (most pixels of a static camera) is fitted once at full size: its per-pixel
 * temporal median is what the camera saw behind the movers, and new still Gaussians are placed
 * on the model's own surface wherever the working-size model misses that image's detail. The
 * movers are then fitted at full size inside their boxes (motion crops of the real view, each
 * with a proxy's crop at the working size so the motion stays consistent with the other views).
 * Memory holds the median and the movers' boxes, never frames x full-size pixels.
 */
#ifndef PG_TRAIN_DETAIL_H
#define PG_TRAIN_DETAIL_H

#include "train/train.h"

typedef struct {
    const char *input;  /* the video, frame folder or dataset the training set was made from */
    const char *camera; /* its camera that is the set's real view (NULL: the first) */
    int steps;          /* full-size steps on the movers (0: train_detail_default_steps) */
    int max_still;      /* cap on the still scene's new Gaussians (0: TRAIN_DETAIL_MAX_STILL) */
} train_detail_config;

/* the movers' steps: TRAIN_DETAIL_STEPS_PER_FRAME per frame (each frame's box a few times),
 * within [TRAIN_DETAIL_MIN_STEPS, TRAIN_DETAIL_STEPS] */
#define TRAIN_DETAIL_STEPS 1200
#define TRAIN_DETAIL_STEPS_PER_FRAME 3
#define TRAIN_DETAIL_MIN_STEPS 100
int train_detail_default_steps(int frames);
#define TRAIN_DETAIL_MAX_STILL 900000

typedef struct {
    int width, height;      /* the size scored: the input's */
    int frames_scored;      /* TRAIN_DETAIL_SCORE_FRAMES, evenly spaced, or the clip's frames */
    double psnr, psnr_moving, psnr_static;
    double psnr_before, psnr_moving_before; /* the working-size model rendered at full size, as scored */
    int still_added;        /* still Gaussians added at full size */
    int movers_frozen;      /* movable Gaussians made still first: never over a moving pixel */
    int gaussians;          /* after the phase */
    double seconds;
} train_detail_scores;

#define TRAIN_DETAIL_SCORE_FRAMES 14
/* larger inputs are worked at this longer side (1920x1080 for 4K) */
#define TRAIN_DETAIL_MAX_SIDE 1920

/* Runs the phase on a trained session (one real view); the session's iteration count grows by
 * the steps. Fails naming the input when its frames disagree with the training set. */
pg_status train_session_detail(train_session *s, const train_detail_config *c, train_detail_scores *out);

#endif
