/* metrics.c - PSNR/SSIM (plain and alpha-masked) and the per-frame evaluation record. */
#include "eval/metrics.h"
#include "eval/baselines.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

pg_status eval_score_image(optim_ssim_ws *ws, const pg_image *pred, const pg_image *truth, const float *alpha,
                           eval_scores *out)
{
    const int W = truth->width, H = truth->height, C = truth->channels;
    if (pred->width != W || pred->height != H || pred->channels != C)
        return pg_fail(PG_ERR_SIZE, "render is %dx%dx%d but the reference frame is %dx%dx%d", pred->width,
                       pred->height, pred->channels, W, H, C);
    const size_t npix = (size_t)W * H;
    float *mask = NULL;
    size_t covered = npix;
    if (alpha) {
        mask = pg_malloc(npix * sizeof(float), "evaluation mask");
        if (!mask) return PG_ERR_NOMEM;
        covered = 0;
        for (size_t i = 0; i < npix; i++) {
            mask[i] = alpha[i] > 0.5f ? 1.0f : 0.0f;
            covered += alpha[i] > 0.5f;
        }
    }
    memset(out->region, 0, sizeof out->region);
    out->psnr = pg_image_psnr(pred, truth, NULL);
    out->ssim = optim_ssim_forward(ws, pred->data, truth->data, NULL, H, W, C);
    out->coverage = (double)covered / npix;
    if (mask && covered > 0) {
        out->psnr_masked = pg_image_psnr(pred, truth, mask);
        out->ssim_masked = optim_ssim_forward(ws, pred->data, truth->data, mask, H, W, C);
    } else if (mask) {
        out->psnr_masked = out->ssim_masked = 0; /* nothing rendered: no score to give */
    } else {
        out->psnr_masked = out->psnr;
        out->ssim_masked = out->ssim;
    }
    free(mask);
    if (isnan(out->ssim) || isnan(out->ssim_masked))
        return pg_fail(PG_ERR_INTERNAL, "SSIM workspace does not match a %dx%d image", W, H);
    return PG_OK;
}

const char *const eval_region_names[EVAL_REGIONS] = { "moving", "static", "seen", "disoccluded", "outside" };

pg_status eval_score_regions(optim_ssim_ws *ws, const pg_image *pred, const pg_image *truth, const uint8_t *labels,
                             int first, int count, eval_scores *out)
{
    const int W = truth->width, H = truth->height, C = truth->channels;
    const size_t npix = (size_t)W * H;
    float *mask = pg_malloc(npix * sizeof(float), "region mask");
    if (!mask) return PG_ERR_NOMEM;
    for (int k = first; k < first + count; k++) {
        double sse = 0, n = 0;
        out->region[k].total += (double)npix;
        int any = 0;
        for (size_t i = 0; i < npix; i++) any |= labels[i] == k;
        if (!any) continue;
        for (size_t i = 0; i < npix; i++) {
            mask[i] = labels[i] == k;
            if (labels[i] != k) continue;
            n += 1;
            for (int c = 0; c < C; c++) {
                double d = (double)pred->data[i * C + c] - truth->data[i * C + c];
                sse += d * d;
            }
        }
        float ssim = optim_ssim_forward(ws, pred->data, truth->data, mask, H, W, C);
        eval_region *g = &out->region[k];
        g->sse += sse;
        g->ssim_sum += ssim * n;
        g->pixels += n;
    }
    free(mask);
    return PG_OK;
}

double eval_region_psnr(const eval_region *g)
{
    if (!(g->pixels > 0)) return NAN;
    double mse = g->sse / (3.0 * g->pixels);
    return mse > 1e-20 ? -10.0 * log10(mse) : 200.0;
}
double eval_region_ssim(const eval_region *g) { return g->pixels > 0 ? g->ssim_sum / g->pixels : NAN; }
double eval_region_fraction(const eval_region *g) { return g->total > 0 ? g->pixels / g->total : NAN; }

pg_status eval_results_add(eval_results *r, const char *camera, eval_role role, int frame, const eval_scores *s)
{
    if (r->count == r->capacity) {
        int cap = r->capacity ? 2 * r->capacity : 64;
        eval_frame_record *grown = realloc(r->records, (size_t)cap * sizeof *grown);
        if (!grown) return pg_fail(PG_ERR_NOMEM, "out of memory growing the evaluation record");
        r->records = grown;
        r->capacity = cap;
    }
    eval_frame_record *rec = &r->records[r->count++];
    snprintf(rec->camera, sizeof rec->camera, "%s", camera);
    rec->role = role;
    rec->frame = frame;
    rec->s = *s;
    return PG_OK;
}

int eval_results_mean(const eval_results *r, const char *camera, eval_role role, eval_scores *mean)
{
    memset(mean, 0, sizeof *mean);
    int n = 0;
    for (int i = 0; i < r->count; i++) {
        const eval_frame_record *rec = &r->records[i];
        if (camera ? strcmp(rec->camera, camera) != 0 : rec->role != role) continue;
        for (int k = 0; k < EVAL_REGIONS; k++) {
            mean->region[k].sse += rec->s.region[k].sse;
            mean->region[k].ssim_sum += rec->s.region[k].ssim_sum;
            mean->region[k].pixels += rec->s.region[k].pixels;
            mean->region[k].total += rec->s.region[k].total;
        }
        mean->psnr += rec->s.psnr;
        mean->ssim += rec->s.ssim;
        mean->psnr_masked += rec->s.psnr_masked;
        mean->ssim_masked += rec->s.ssim_masked;
        mean->coverage += rec->s.coverage;
        n++;
    }
    if (n) {
        mean->psnr /= n;
        mean->ssim /= n;
        mean->psnr_masked /= n;
        mean->ssim_masked /= n;
        mean->coverage /= n;
    }
    return n;
}

void eval_results_destroy(eval_results *r)
{
    if (!r) return;
    if (r->baseline)
        for (int b = 0; b < EVAL_BASELINES; b++) eval_results_destroy(&r->baseline[b]);
    free(r->baseline);
    free(r->records);
    memset(r, 0, sizeof *r);
}
