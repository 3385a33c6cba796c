/* metrics.h - image quality scores for novel views and the evaluation record.
 *
 * Scores follow the DyNeRF protocol as MoDGS and ProDyGS report it: PSNR and SSIM over the
 * whole image, and "masked" versions over the pixels where the model's alpha > 0.5. Averages
 * over frames are means of per-frame scores. SSIM is the 3DGS one (11-tap Gaussian, sigma 1.5).
 */
#ifndef PG_EVAL_METRICS_H
#define PG_EVAL_METRICS_H

#include "core/image.h"
#include "optim/loss_image.h"

typedef struct {
    double psnr, ssim;
    double psnr_masked, ssim_masked;
    double coverage; /* fraction of pixels with alpha > 0.5 */
} eval_scores;

typedef struct {
    char camera[32];
    int frame;
    eval_scores s;
} eval_frame_record;

typedef struct {
    eval_frame_record *records; /* (count) */
    int count, capacity;
} eval_results;

/* Scores a rendered image against the truth; alpha (H, W) may be NULL (masked = unmasked).
 * ws must be sized for the image (optim_ssim_create(H, W, 3)). */
pg_status eval_score_image(optim_ssim_ws *ws, const pg_image *pred, const pg_image *truth, const float *alpha,
                           eval_scores *out);
pg_status eval_results_add(eval_results *r, const char *camera, int frame, const eval_scores *s);
/* Mean over the records of one camera (camera NULL: all records); returns the record count. */
int eval_results_mean(const eval_results *r, const char *camera, eval_scores *mean);
void eval_results_destroy(eval_results *r);

#endif
