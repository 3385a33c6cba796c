/* raster_simd.c - AVX-512 tile kernels: one 16-pixel tile row per vector, Gaussian-major loops.
 *
 * Per pixel the kernels do exactly the operations of the scalar reference (raster_tile.c) in
 * the same order, with fused multiply-adds in the same places, so the forward matches it bit for
 * bit and the backward differs only in the order the per-pixel terms are summed. Rows outside a
 * Gaussian's box, rows whose pixels are all finished, and rows where no lane can reach
 * alpha >= 1/255 are skipped before the exponential is evaluated.
 */
#include "splat/raster_kernels.h"

#include <string.h>

#if defined(__AVX512F__)
#include <immintrin.h>

#define SPLAT_PREFETCH 6

int splat_simd_available(void) { return 1; }
const char *splat_simd_name(void) { return "avx512"; }

/* Vector twin of splat_exp_poly. */
static inline __m512 exp_poly16(__m512 x)
{
    x = _mm512_max_ps(x, _mm512_set1_ps(-87.0f));
    __m512 n = _mm512_roundscale_ps(_mm512_mul_ps(x, _mm512_set1_ps(1.44269504088896341f)),
                                    _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
    __m512 f = _mm512_fmadd_ps(n, _mm512_set1_ps(-0.693359375f), x);
    f = _mm512_fmadd_ps(n, _mm512_set1_ps(2.12194440e-4f), f);
    __m512 p = _mm512_set1_ps(1.0f / 720.0f);
    p = _mm512_fmadd_ps(p, f, _mm512_set1_ps(1.0f / 120.0f));
    p = _mm512_fmadd_ps(p, f, _mm512_set1_ps(1.0f / 24.0f));
    p = _mm512_fmadd_ps(p, f, _mm512_set1_ps(1.0f / 6.0f));
    p = _mm512_fmadd_ps(p, f, _mm512_set1_ps(0.5f));
    p = _mm512_fmadd_ps(p, f, _mm512_set1_ps(1.0f));
    p = _mm512_fmadd_ps(p, f, _mm512_set1_ps(1.0f));
    __m512i e = _mm512_slli_epi32(_mm512_add_epi32(_mm512_cvtps_epi32(n), _mm512_set1_epi32(127)), 23);
    return _mm512_mul_ps(p, _mm512_castsi512_ps(e));
}

static inline __m512 lane_centres(int x0)
{
    /* (float)(x0 + i) + 0.5f exactly as the scalar path computes gx + 0.5f */
    __m512 gx = _mm512_cvtepi32_ps(_mm512_add_epi32(_mm512_set1_epi32(x0),
                                                    _mm512_set_epi32(15, 14, 13, 12, 11, 10, 9, 8, 7, 6, 5, 4, 3, 2, 1, 0)));
    return _mm512_add_ps(gx, _mm512_set1_ps(0.5f));
}

void splat_tile_forward_simd(const splat_tile_job *j)
{
    float T[SPLAT_TILE_PIX] __attribute__((aligned(64)));
    float Cr[SPLAT_TILE_PIX] __attribute__((aligned(64))), Cg[SPLAT_TILE_PIX] __attribute__((aligned(64)));
    float Cb[SPLAT_TILE_PIX] __attribute__((aligned(64))), D[SPLAT_TILE_PIX] __attribute__((aligned(64)));
    int last[SPLAT_TILE_PIX] __attribute__((aligned(64)));
    __mmask16 active[SPLAT_TILE];
    __mmask16 lanes = (__mmask16)((1u << j->w) - 1u);
    for (int row = 0; row < SPLAT_TILE; row++) active[row] = row < j->h ? lanes : 0;
    for (int i = 0; i < SPLAT_TILE_PIX; i += 16) {
        _mm512_store_ps(T + i, _mm512_set1_ps(1.0f));
        _mm512_store_ps(Cr + i, _mm512_setzero_ps());
        _mm512_store_ps(Cg + i, _mm512_setzero_ps());
        _mm512_store_ps(Cb + i, _mm512_setzero_ps());
        _mm512_store_ps(D + i, _mm512_setzero_ps());
        _mm512_store_si512((void *)(last + i), _mm512_set1_epi32(-1));
    }
    int alive = j->h;
    const __m512 px = lane_centres(j->x0);
    const __m512 one = _mm512_set1_ps(1.0f), amax = _mm512_set1_ps(SPLAT_ALPHA_MAX);
    const __m512 amin = _mm512_set1_ps(SPLAT_ALPHA_MIN), teps = _mm512_set1_ps(SPLAT_T_EPS);
    for (int k = 0; k < j->n && alive > 0; k++) {
        /* records are scattered in memory: fetch a few ahead */
        if (k + SPLAT_PREFETCH < j->n) _mm_prefetch((const char *)&j->rec[j->list[k + SPLAT_PREFETCH]], _MM_HINT_T0);
        const splat_rec *r = &j->rec[j->list[k]];
        int r0 = r->ymin - j->y0, r1 = r->ymax - j->y0;
        if (r0 < 0) r0 = 0;
        if (r1 > j->h - 1) r1 = j->h - 1;
        if (r0 > r1) continue;
        const __m512 dx = _mm512_sub_ps(px, _mm512_set1_ps(r->x));
        const __m512 thr = _mm512_set1_ps(r->thr), op = _mm512_set1_ps(r->o);
        const __m512 cr = _mm512_set1_ps(r->col[0]), cg = _mm512_set1_ps(r->col[1]), cb = _mm512_set1_ps(r->col[2]);
        const __m512 cz = _mm512_set1_ps(r->z), kv = _mm512_castsi512_ps(_mm512_set1_epi32(k));
        for (int row = r0; row <= r1; row++) {
            __mmask16 m = active[row];
            if (!m) continue;
            float dy = (j->y0 + row + 0.5f) - r->y;
            float bdy = r->cb * dy, cdy = 0.5f * r->cc * dy * dy;
            /* sigma = fmaf(dx, fmaf(ha, dx, bdy), cdy) as in the scalar kernel */
            __m512 inner = _mm512_fmadd_ps(_mm512_set1_ps(0.5f * r->ca), dx, _mm512_set1_ps(bdy));
            __m512 sig = _mm512_fmadd_ps(dx, inner, _mm512_set1_ps(cdy));
            m = _mm512_mask_cmp_ps_mask(m, sig, thr, _CMP_LE_OQ);
            if (!m) continue;
            __m512 G = exp_poly16(_mm512_sub_ps(_mm512_setzero_ps(), sig));
            __m512 oG = _mm512_mul_ps(op, G);
            __m512 a = _mm512_min_ps(oG, amax);
            m = _mm512_mask_cmp_ps_mask(m, a, amin, _CMP_GE_OQ);
            if (!m) continue;
            float *Tp = T + row * 16;
            __m512 Tv = _mm512_load_ps(Tp);
            __m512 tT = _mm512_mul_ps(Tv, _mm512_sub_ps(one, a));
            __mmask16 fin = _mm512_mask_cmp_ps_mask(m, tT, teps, _CMP_LT_OQ);
            if (fin) {
                active[row] &= (__mmask16)~fin;
                m &= (__mmask16)~fin;
                if (!active[row]) alive--;
            }
            __m512 w = _mm512_mul_ps(a, Tv);
            _mm512_store_ps(Cr + row * 16, _mm512_mask3_fmadd_ps(cr, w, _mm512_load_ps(Cr + row * 16), m));
            _mm512_store_ps(Cg + row * 16, _mm512_mask3_fmadd_ps(cg, w, _mm512_load_ps(Cg + row * 16), m));
            _mm512_store_ps(Cb + row * 16, _mm512_mask3_fmadd_ps(cb, w, _mm512_load_ps(Cb + row * 16), m));
            _mm512_store_ps(D + row * 16, _mm512_mask3_fmadd_ps(cz, w, _mm512_load_ps(D + row * 16), m));
            _mm512_mask_store_ps(Tp, m, tT);
            _mm512_mask_store_ps((float *)(last + row * 16), m, kv);
        }
    }
    for (int row = 0; row < j->h; row++) {
        size_t p0 = (size_t)(j->y0 + row) * j->width + j->x0;
        for (int i = 0; i < j->w; i++) {
            int t = row * 16 + i;
            size_t p = p0 + i;
            j->rgb[3*p] = fmaf(T[t], j->bg[0], Cr[t]);
            j->rgb[3*p+1] = fmaf(T[t], j->bg[1], Cg[t]);
            j->rgb[3*p+2] = fmaf(T[t], j->bg[2], Cb[t]);
            j->depth[p] = D[t];
            j->alpha[p] = 1.0f - T[t];
            j->tfinal[p] = T[t];
            j->last[p] = last[t];
        }
    }
}

void splat_tile_backward_simd(const splat_tile_job *j)
{
    float T[SPLAT_TILE_PIX] __attribute__((aligned(64))), Q[SPLAT_TILE_PIX] __attribute__((aligned(64)));
    float Dr[SPLAT_TILE_PIX] __attribute__((aligned(64))), Dg[SPLAT_TILE_PIX] __attribute__((aligned(64)));
    float Db[SPLAT_TILE_PIX] __attribute__((aligned(64))), Dd[SPLAT_TILE_PIX] __attribute__((aligned(64)));
    int last[SPLAT_TILE_PIX] __attribute__((aligned(64)));
    int kmax = -1;
    for (int row = 0; row < SPLAT_TILE; row++)
        for (int i = 0; i < SPLAT_TILE; i++) {
            int t = row * 16 + i;
            if (row >= j->h || i >= j->w) {
                T[t] = Q[t] = Dr[t] = Dg[t] = Db[t] = Dd[t] = 0;
                last[t] = -1;
                continue;
            }
            size_t p = (size_t)(j->y0 + row) * j->width + j->x0 + i;
            float dl[3] = { 0, 0, 0 }, dd = j->d_depth ? j->d_depth[p] : 0.0f;
            if (j->d_rgb) for (int c = 0; c < 3; c++) dl[c] = j->d_rgb[3*p + c];
            float da = j->d_alpha ? j->d_alpha[p] : 0.0f;
            float bgdot = fmaf(j->bg[2], dl[2], fmaf(j->bg[1], dl[1], j->bg[0] * dl[0]));
            T[t] = j->tfinal[p];
            Q[t] = -(T[t] * (da - bgdot));
            Dr[t] = dl[0]; Dg[t] = dl[1]; Db[t] = dl[2]; Dd[t] = dd;
            last[t] = j->last[p];
            if (last[t] > kmax) kmax = last[t];
        }
    for (int k = kmax + 1; k < j->n; k++)
        memset(j->grad_slots + (size_t)SPLAT_GRAD_STRIDE * splat_slot(&j->rec[j->list[k]], j->tx, j->ty), 0,
               SPLAT_GRAD_STRIDE * sizeof(float));
    const __m512 px = lane_centres(j->x0);
    const __m512 one = _mm512_set1_ps(1.0f), amax = _mm512_set1_ps(SPLAT_ALPHA_MAX);
    const __m512 amin = _mm512_set1_ps(SPLAT_ALPHA_MIN), zero = _mm512_setzero_ps();
    for (int k = kmax; k >= 0; k--) {
        if (k >= SPLAT_PREFETCH) _mm_prefetch((const char *)&j->rec[j->list[k - SPLAT_PREFETCH]], _MM_HINT_T0);
        const splat_rec *r = &j->rec[j->list[k]];
        float *slot = j->grad_slots + (size_t)SPLAT_GRAD_STRIDE * splat_slot(r, j->tx, j->ty);
        __m512 a_x = zero, a_y = zero, a_ca = zero, a_cb = zero, a_cc = zero, a_o = zero;
        __m512 a_r = zero, a_g = zero, a_b = zero, a_z = zero;
        int r0 = r->ymin - j->y0, r1 = r->ymax - j->y0;
        if (r0 < 0) r0 = 0;
        if (r1 > j->h - 1) r1 = j->h - 1;
        const __m512 dx = _mm512_sub_ps(px, _mm512_set1_ps(r->x));
        const __m512 ha = _mm512_set1_ps(0.5f * r->ca), ca = _mm512_set1_ps(r->ca), cbv = _mm512_set1_ps(r->cb);
        const __m512 thr = _mm512_set1_ps(r->thr), op = _mm512_set1_ps(r->o);
        const __m512 cr = _mm512_set1_ps(r->col[0]), cg = _mm512_set1_ps(r->col[1]), cb = _mm512_set1_ps(r->col[2]);
        const __m512 cz = _mm512_set1_ps(r->z);
        const __m512i kv = _mm512_set1_epi32(k);
        const __m512 hdx2 = _mm512_mul_ps(_mm512_mul_ps(_mm512_set1_ps(0.5f), dx), dx);
        for (int row = r0; row <= r1; row++) {
            __mmask16 m = _mm512_cmp_epi32_mask(kv, _mm512_load_si512((const void *)(last + row * 16)), _MM_CMPINT_LE);
            if (!m) continue;
            float dy = (j->y0 + row + 0.5f) - r->y;
            float bdy = r->cb * dy, cdy = 0.5f * r->cc * dy * dy;
            __m512 bdyv = _mm512_set1_ps(bdy);
            __m512 sig = _mm512_fmadd_ps(dx, _mm512_fmadd_ps(ha, dx, bdyv), _mm512_set1_ps(cdy));
            m = _mm512_mask_cmp_ps_mask(m, sig, thr, _CMP_LE_OQ);
            if (!m) continue;
            __m512 G = exp_poly16(_mm512_sub_ps(zero, sig));
            __m512 oG = _mm512_mul_ps(op, G);
            __m512 a = _mm512_min_ps(oG, amax);
            m = _mm512_mask_cmp_ps_mask(m, a, amin, _CMP_GE_OQ);
            if (!m) continue;
            __m512 inv = _mm512_div_ps(one, _mm512_sub_ps(one, a));
            __m512 Ti = _mm512_mul_ps(_mm512_load_ps(T + row * 16), inv);
            __m512 dr = _mm512_load_ps(Dr + row * 16), dg = _mm512_load_ps(Dg + row * 16);
            __m512 db = _mm512_load_ps(Db + row * 16), dd = _mm512_load_ps(Dd + row * 16);
            __m512 q = _mm512_fmadd_ps(dd, cz, _mm512_fmadd_ps(db, cb, _mm512_fmadd_ps(dg, cg, _mm512_mul_ps(dr, cr))));
            __m512 w = _mm512_mul_ps(a, Ti);
            __m512 Qv = _mm512_load_ps(Q + row * 16);
            __m512 dLda = _mm512_fmsub_ps(Ti, q, _mm512_mul_ps(Qv, inv));
            _mm512_mask_store_ps(Q + row * 16, m, _mm512_fmadd_ps(w, q, Qv));
            _mm512_mask_store_ps(T + row * 16, m, Ti);
            a_r = _mm512_mask3_fmadd_ps(w, dr, a_r, m);
            a_g = _mm512_mask3_fmadd_ps(w, dg, a_g, m);
            a_b = _mm512_mask3_fmadd_ps(w, db, a_b, m);
            a_z = _mm512_mask3_fmadd_ps(w, dd, a_z, m);
            __mmask16 mu = _mm512_mask_cmp_ps_mask(m, oG, amax, _CMP_LT_OQ);
            if (!mu) continue;
            __m512 dLds = _mm512_sub_ps(zero, _mm512_mul_ps(dLda, a));
            a_o = _mm512_mask3_fmadd_ps(dLda, G, a_o, mu);
            __m512 gu = _mm512_sub_ps(zero, _mm512_fmadd_ps(ca, dx, bdyv));
            __m512 gv = _mm512_sub_ps(zero, _mm512_fmadd_ps(cbv, dx, _mm512_set1_ps(r->cc * dy)));
            a_x = _mm512_mask3_fmadd_ps(dLds, gu, a_x, mu);
            a_y = _mm512_mask3_fmadd_ps(dLds, gv, a_y, mu);
            a_ca = _mm512_mask3_fmadd_ps(dLds, hdx2, a_ca, mu);
            a_cb = _mm512_mask3_fmadd_ps(dLds, _mm512_mul_ps(dx, _mm512_set1_ps(dy)), a_cb, mu);
            a_cc = _mm512_mask3_fmadd_ps(dLds, _mm512_set1_ps(0.5f * dy * dy), a_cc, mu);
        }
        slot[0] = _mm512_reduce_add_ps(a_x);
        slot[1] = _mm512_reduce_add_ps(a_y);
        slot[2] = _mm512_reduce_add_ps(a_ca);
        slot[3] = _mm512_reduce_add_ps(a_cb);
        slot[4] = _mm512_reduce_add_ps(a_cc);
        slot[5] = _mm512_reduce_add_ps(a_o);
        slot[6] = _mm512_reduce_add_ps(a_r);
        slot[7] = _mm512_reduce_add_ps(a_g);
        slot[8] = _mm512_reduce_add_ps(a_b);
        slot[9] = _mm512_reduce_add_ps(a_z);
    }
}

#else /* no AVX-512 at compile time: the scalar kernels stand in */

int splat_simd_available(void) { return 0; }
const char *splat_simd_name(void) { return "scalar"; }
void splat_tile_forward_simd(const splat_tile_job *job) { splat_tile_forward_scalar(job); }
void splat_tile_backward_simd(const splat_tile_job *job) { splat_tile_backward_scalar(job); }

#endif
