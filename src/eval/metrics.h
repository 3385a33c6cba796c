/* metrics.h - image quality scores for novel views and the evaluation record.
 *
 * Scores follow the DyNeRF protocol as MoDGS and ProDyGS report it: PSNR and SSIM over the
 * whole image, and "masked" versions over the pixels where the model's alpha > 0.5. Averages
 * over frames are means of per-frame scores. SSIM is the 3DGS one (11-tap Gaussian, sigma 1.5).
 */
#ifndef PG_EVAL_METRICS_H
#define PG_EVAL_METRICS_H

#include <stdint.h>

#include "core/image.h"
#include "optim/loss_image.h"

/* Pixel subsets scored on their own. moving / static: from the camera's own video (colour vs
 * the pixel's temporal median, depth/moving_mask.h); seen / disoccluded / outside: test cameras
 * only, where each rendered pixel lands in the real camera (eval/visibility.h). */
enum { EVAL_MOVING, EVAL_STATIC, EVAL_SEEN, EVAL_DISOCCLUDED, EVAL_OUTSIDE, EVAL_REGIONS };
extern const char *const eval_region_names[EVAL_REGIONS];

/* Sums over one region, so frames pool into one score: PSNR from the summed squared error of
 * all the region's pixels, SSIM as the pixel-weighted mean of the per-frame region SSIM. */
typedef struct {
    double sse;      /* squared error summed over the region's pixels and channels */
    double ssim_sum; /* region SSIM x pixels */
    double pixels;   /* 0: the region is empty (its scores are undefined) */
    double total;    /* pixels of the frames the region was taken from (for its fraction) */
} eval_region;

typedef struct {
    double psnr, ssim;
    double psnr_masked, ssim_masked;
    double coverage; /* fraction of pixels with alpha > 0.5 */
    eval_region region[EVAL_REGIONS];
} eval_scores;

typedef enum { EVAL_ROLE_TEST = 0, EVAL_ROLE_TRAIN } eval_role;

typedef struct {
    char camera[32];
    int frame;
    eval_role role; /* test: held out; train: the real training camera (not in the headline means) */
    eval_scores s;
} eval_frame_record;

typedef struct eval_results {
    eval_frame_record *records; /* (count) */
    int count, capacity;
    /* (EVAL_BASELINES, eval/baselines.h) the yardsticks' scores at the test cameras, the same
     * frames and pixels as the model's; NULL: not scored */
    struct eval_results *baseline;
} eval_results;

/* Scores a rendered image against the truth; alpha (H, W) may be NULL (masked = unmasked).
 * ws must be sized for the image (optim_ssim_create(H, W, 3)). */
pg_status eval_score_image(optim_ssim_ws *ws, const pg_image *pred, const pg_image *truth, const float *alpha,
                           eval_scores *out);
/* Adds the scores of the regions first .. first+count-1 to out, labels (H*W) giving each pixel's
 * region (every pixel in one of them). Call after eval_score_image (which zeroes the regions);
 * ws as for eval_score_image. */
pg_status eval_score_regions(optim_ssim_ws *ws, const pg_image *pred, const pg_image *truth, const uint8_t *labels,
                             int first, int count, eval_scores *out);
/* Region PSNR / SSIM / fraction of the frame; NaN when the region is empty. */
double eval_region_psnr(const eval_region *g);
double eval_region_ssim(const eval_region *g);
double eval_region_fraction(const eval_region *g);
pg_status eval_results_add(eval_results *r, const char *camera, eval_role role, int frame, const eval_scores *s);
/* Mean over the records of one camera (camera NULL: every record of the role); returns the
 * record count. Regions are pooled (summed), the other scores are means of per-frame scores. */
int eval_results_mean(const eval_results *r, const char *camera, eval_role role, eval_scores *mean);
/* Frees the records and the baselines' records. */
void eval_results_destroy(eval_results *r);

#endif
