/* raster_tile.c - scalar reference tile kernels (one pixel at a time, front to back / back to
 * front). The SIMD kernels in raster_simd.c perform the same operations in the same order per
 * pixel, 16 pixels at a time; tests compare the two. */
#include "splat/raster_kernels.h"

#include <string.h>

/* One Gaussian at one pixel: offsets, the Gaussian G, o*G and the clamped alpha. */
typedef struct {
    float dx, dy, bdy, G, oG, a;
} tile_hit;

/* Evaluates Gaussian r at pixel centre (fx, fy) of row gy; 0 when the row is outside its box
 * or alpha < 1/255 (the forward and backward skip the same Gaussians). */
static inline int tile_eval(const splat_rec *r, int gy, float fx, float fy, tile_hit *h)
{
    if (gy < r->ymin || gy > r->ymax) return 0;
    float dx = fx - r->x, dy = fy - r->y;
    float bdy = r->cb * dy, cdy = (r->hc * dy) * dy;
    float sig = fmaf(dx, fmaf(r->ha, dx, bdy), cdy);
    if (!(sig <= r->thr)) return 0;
    h->dx = dx;
    h->dy = dy;
    h->bdy = bdy;
    h->G = splat_exp_poly(-sig);
    h->oG = r->o * h->G;
    h->a = h->oG < SPLAT_ALPHA_MAX ? h->oG : SPLAT_ALPHA_MAX;
    return 1;
}

void splat_tile_forward_scalar(const splat_tile_job *j)
{
    for (int py = 0; py < j->h; py++) {
        int gy = j->y0 + py;
        float fy = gy + 0.5f;
        for (int px = 0; px < j->w; px++) {
            int gx = j->x0 + px;
            float fx = gx + 0.5f;
            float T = 1.0f, C[3] = { 0, 0, 0 }, D = 0;
            int last = -1;
            for (int k = 0; k < j->n; k++) {
                const splat_rec *r = &j->rec[j->list[k]];
                tile_hit h;
                if (!tile_eval(r, gy, fx, fy, &h)) continue;
                float a = h.a;
                float tT = T * (1.0f - a);
                if (tT < SPLAT_T_EPS) break;
                float w = a * T;
                for (int c = 0; c < 3; c++) C[c] = fmaf(r->col[c], w, C[c]);
                D = fmaf(r->z, w, D);
                T = tT;
                last = k;
            }
            size_t p = (size_t)gy * j->width + gx;
            for (int c = 0; c < 3; c++) j->rgb[3*p + c] = fmaf(T, j->bg[c], C[c]);
            j->depth[p] = D;
            j->alpha[p] = 1.0f - T;
            j->tfinal[p] = T;
            j->last[p] = last;
        }
    }
}

void splat_tile_backward_scalar(const splat_tile_job *j)
{
    for (int k = 0; k < j->n; k++)
        memset(j->grad_slots + (size_t)SPLAT_GRAD_STRIDE * splat_slot(&j->rec[j->list[k]], j->tx, j->ty), 0,
               SPLAT_GRAD_STRIDE * sizeof(float));
    for (int py = 0; py < j->h; py++) {
        int gy = j->y0 + py;
        float fy = gy + 0.5f;
        for (int px = 0; px < j->w; px++) {
            int gx = j->x0 + px;
            float fx = gx + 0.5f;
            size_t p = (size_t)gy * j->width + gx;
            float dl[3] = { 0, 0, 0 }, dd = j->d_depth ? j->d_depth[p] : 0.0f;
            if (j->d_rgb) for (int c = 0; c < 3; c++) dl[c] = j->d_rgb[3*p + c];
            float T = j->tfinal[p];
            float da = j->d_alpha ? j->d_alpha[p] : 0.0f;
            /* C = sum c_i a_i T_i + T_final bg and alpha = 1 - T_final both depend on every a_i
             * through T_final: dT_final/da_i = -T_final / (1 - a_i). Q carries that term plus the
             * suffix sum of what lies behind Gaussian i. */
            float bgdot = fmaf(j->bg[2], dl[2], fmaf(j->bg[1], dl[1], j->bg[0] * dl[0]));
            float Q = -(T * (da - bgdot));
            for (int k = j->last[p]; k >= 0; k--) {
                const splat_rec *r = &j->rec[j->list[k]];
                tile_hit h;
                if (!tile_eval(r, gy, fx, fy, &h)) continue;
                float dx = h.dx, dy = h.dy, bdy = h.bdy, G = h.G, oG = h.oG, a = h.a;
                float inv = 1.0f / (1.0f - a);
                float Ti = T * inv;
                float q = fmaf(dd, r->z, fmaf(dl[2], r->col[2], fmaf(dl[1], r->col[1], dl[0] * r->col[0])));
                float w = a * Ti;
                float dLda = fmaf(Ti, q, -(Q * inv));
                Q = fmaf(w, q, Q);
                T = Ti;
                float *s = j->grad_slots + (size_t)SPLAT_GRAD_STRIDE * splat_slot(r, j->tx, j->ty);
                s[6] = fmaf(w, dl[0], s[6]);
                s[7] = fmaf(w, dl[1], s[7]);
                s[8] = fmaf(w, dl[2], s[8]);
                s[9] = fmaf(w, dd, s[9]);
                if (oG < SPLAT_ALPHA_MAX) {
                    float dLds = -(dLda * a);
                    s[5] = fmaf(dLda, G, s[5]);
                    s[0] = fmaf(dLds, -fmaf(2.0f * r->ha, dx, bdy), s[0]);
                    s[1] = fmaf(dLds, -fmaf(r->cb, dx, (2.0f * r->hc) * dy), s[1]);
                    s[2] = fmaf(dLds, 0.5f * dx * dx, s[2]);
                    s[3] = fmaf(dLds, dx * dy, s[3]);
                    s[4] = fmaf(dLds, 0.5f * dy * dy, s[4]);
                }
            }
        }
    }
}
