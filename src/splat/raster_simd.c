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
    /* no clamp at -87 as in the scalar twin: only lanes with x >= -ln(255) - 1e-3 are used */
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
    return _mm512_scalef_ps(p, n); /* exact p * 2^n, like the scalar exponent-bits product */
}

static inline __m512 lane_centres(int x0)
{
    /* (float)(x0 + i) + 0.5f exactly as the scalar path computes gx + 0.5f */
    __m512 gx = _mm512_cvtepi32_ps(_mm512_add_epi32(_mm512_set1_epi32(x0),
                                                    _mm512_set_epi32(15, 14, 13, 12, 11, 10, 9, 8, 7, 6, 5, 4, 3, 2, 1, 0)));
    return _mm512_add_ps(gx, _mm512_set1_ps(0.5f));
}

/* Hides a vector's origin from the compiler so a blend followed by a full store is not turned
 * into a masked store (masked stores block store-to-load forwarding for the next load). */
#define OPAQUE(v) __asm__("" : "+v"(v))

#define CHUNK 256 /* Gaussians copied into the tile-local buffer at a time */

/* Row-major, two rows at a time: the tile's Gaussians are copied, CHUNK at a time, into a local
 * buffer (one cache line each, contiguous); each pair of tile rows keeps transmittance, colour,
 * depth and last contributor in registers while it walks the Gaussians whose box covers either
 * row (found with a vector compress over the local row ranges), and stops once all its pixels
 * are saturated. Two rows share the per-Gaussian broadcasts and give two independent chains. */
void splat_tile_forward_simd(const splat_tile_job *j)
{
    splat_rec loc[CHUNK] __attribute__((aligned(64)));
    int ylo[CHUNK] __attribute__((aligned(64))), yhi[CHUNK] __attribute__((aligned(64)));
    int idx[CHUNK + 16];
    float sT[SPLAT_TILE][16] __attribute__((aligned(64))), sR[SPLAT_TILE][16] __attribute__((aligned(64)));
    float sG[SPLAT_TILE][16] __attribute__((aligned(64))), sB[SPLAT_TILE][16] __attribute__((aligned(64)));
    float sD[SPLAT_TILE][16] __attribute__((aligned(64)));
    int sL[SPLAT_TILE][16] __attribute__((aligned(64)));
    __mmask16 active[SPLAT_TILE];
    const __m512 px = lane_centres(j->x0);
    const __m512 one = _mm512_set1_ps(1.0f), amax = _mm512_set1_ps(SPLAT_ALPHA_MAX);
    const __m512 amin = _mm512_set1_ps(SPLAT_ALPHA_MIN), teps = _mm512_set1_ps(SPLAT_T_EPS);
    const __m512 zero = _mm512_setzero_ps();
    const __mmask16 lanes = (__mmask16)((1u << j->w) - 1u);
    for (int row = 0; row < SPLAT_TILE; row++) {
        active[row] = row < j->h ? lanes : 0;
        _mm512_store_ps(sT[row], one);
        _mm512_store_ps(sR[row], zero);
        _mm512_store_ps(sG[row], zero);
        _mm512_store_ps(sB[row], zero);
        _mm512_store_ps(sD[row], zero);
        _mm512_store_si512((void *)sL[row], _mm512_set1_epi32(-1));
    }
    int alive = j->h;
    for (int k0 = 0; k0 < j->n && alive; k0 += CHUNK) {
        int cn = j->n - k0 < CHUNK ? j->n - k0 : CHUNK;
        for (int i = 0; i < cn; i++) {
            if (i + 8 < cn) _mm_prefetch((const char *)&j->rec[j->list[k0 + i + 8]], _MM_HINT_T0);
            const splat_rec *r = &j->rec[j->list[k0 + i]];
            _mm512_store_si512((void *)&loc[i], _mm512_loadu_si512((const void *)r));
            ylo[i] = r->ymin;
            yhi[i] = r->ymax;
        }
        int cpad = (cn + 15) & ~15;
        for (int i = cn; i < cpad; i++) { ylo[i] = 1 << 30; yhi[i] = -1; }
        for (int row = 0; row < j->h; row += 2) {
            __mmask16 act0 = active[row], act1 = active[row + 1];
            if (!(act0 | act1)) continue;
            int gy = j->y0 + row;
            float fy0 = gy + 0.5f, fy1 = (gy + 1) + 0.5f;
            /* indices of the chunk's Gaussians whose box covers either row, in depth order */
            int cnt = 0;
            const __m512i gy0v = _mm512_set1_epi32(gy), gy1v = _mm512_set1_epi32(gy + 1);
            for (int i = 0; i < cpad; i += 16) {
                __mmask16 cov = _mm512_cmp_epi32_mask(_mm512_load_si512((const void *)(ylo + i)), gy1v, _MM_CMPINT_LE) &
                                _mm512_cmp_epi32_mask(_mm512_load_si512((const void *)(yhi + i)), gy0v, _MM_CMPINT_NLT);
                __m512i iv = _mm512_add_epi32(_mm512_set1_epi32(i),
                                              _mm512_set_epi32(15, 14, 13, 12, 11, 10, 9, 8, 7, 6, 5, 4, 3, 2, 1, 0));
                _mm512_mask_compressstoreu_epi32(idx + cnt, cov, iv);
                cnt += __builtin_popcount(cov);
            }
            __m512 T0 = _mm512_load_ps(sT[row]), R0 = _mm512_load_ps(sR[row]), G0 = _mm512_load_ps(sG[row]);
            __m512 B0 = _mm512_load_ps(sB[row]), D0 = _mm512_load_ps(sD[row]);
            __m512i L0 = _mm512_load_si512((const void *)sL[row]);
            __m512 T1 = _mm512_load_ps(sT[row + 1]), R1 = _mm512_load_ps(sR[row + 1]), G1 = _mm512_load_ps(sG[row + 1]);
            __m512 B1 = _mm512_load_ps(sB[row + 1]), D1 = _mm512_load_ps(sD[row + 1]);
            __m512i L1 = _mm512_load_si512((const void *)sL[row + 1]);
            for (int c = 0; c < cnt; c++) {
                const splat_rec *r = &loc[idx[c]];
                /* rows outside the box are skipped exactly as in the scalar kernel */
                __mmask16 in0 = (gy >= r->ymin && gy <= r->ymax) ? lanes : 0;
                __mmask16 in1 = (gy + 1 <= r->ymax && gy + 1 >= r->ymin) ? lanes : 0;
                float dy0 = fy0 - r->y, dy1 = fy1 - r->y;
                /* sigma = fmaf(dx, fmaf(ha, dx, b dy), 0.5 c dy dy) as in the scalar kernel */
                __m512 dx = _mm512_sub_ps(px, _mm512_set1_ps(r->x));
                __m512 ha = _mm512_set1_ps(0.5f * r->ca), thr = _mm512_set1_ps(r->thr);
                __m512 s0 = _mm512_fmadd_ps(dx, _mm512_fmadd_ps(ha, dx, _mm512_set1_ps(r->cb * dy0)),
                                            _mm512_set1_ps(0.5f * r->cc * dy0 * dy0));
                __m512 s1 = _mm512_fmadd_ps(dx, _mm512_fmadd_ps(ha, dx, _mm512_set1_ps(r->cb * dy1)),
                                            _mm512_set1_ps(0.5f * r->cc * dy1 * dy1));
                /* branch on the box test alone: it resolves early, unlike one that waits on the
                 * previous Gaussian's transmittance through the active masks */
                __mmask16 m0 = _mm512_mask_cmp_ps_mask(in0, s0, thr, _CMP_LE_OQ);
                __mmask16 m1 = _mm512_mask_cmp_ps_mask(in1, s1, thr, _CMP_LE_OQ);
                if (!(m0 | m1)) continue;
                __m512 op = _mm512_set1_ps(r->o);
                __m512 a0 = _mm512_min_ps(_mm512_mul_ps(op, exp_poly16(_mm512_sub_ps(zero, s0))), amax);
                __m512 a1 = _mm512_min_ps(_mm512_mul_ps(op, exp_poly16(_mm512_sub_ps(zero, s1))), amax);
                m0 = _mm512_mask_cmp_ps_mask(m0 & act0, a0, amin, _CMP_GE_OQ);
                m1 = _mm512_mask_cmp_ps_mask(m1 & act1, a1, amin, _CMP_GE_OQ);
                __m512 t0 = _mm512_mul_ps(T0, _mm512_sub_ps(one, a0));
                __m512 t1 = _mm512_mul_ps(T1, _mm512_sub_ps(one, a1));
                __mmask16 f0 = _mm512_mask_cmp_ps_mask(m0, t0, teps, _CMP_LT_OQ);
                __mmask16 f1 = _mm512_mask_cmp_ps_mask(m1, t1, teps, _CMP_LT_OQ);
                act0 &= (__mmask16)~f0; m0 &= (__mmask16)~f0;
                act1 &= (__mmask16)~f1; m1 &= (__mmask16)~f1;
                __m512 w0 = _mm512_mul_ps(a0, T0), w1 = _mm512_mul_ps(a1, T1);
                __m512 cr = _mm512_set1_ps(r->col[0]), cg = _mm512_set1_ps(r->col[1]);
                __m512 cb = _mm512_set1_ps(r->col[2]), cz = _mm512_set1_ps(r->z);
                __m512i kv = _mm512_set1_epi32(k0 + idx[c]);
                R0 = _mm512_mask3_fmadd_ps(cr, w0, R0, m0); R1 = _mm512_mask3_fmadd_ps(cr, w1, R1, m1);
                G0 = _mm512_mask3_fmadd_ps(cg, w0, G0, m0); G1 = _mm512_mask3_fmadd_ps(cg, w1, G1, m1);
                B0 = _mm512_mask3_fmadd_ps(cb, w0, B0, m0); B1 = _mm512_mask3_fmadd_ps(cb, w1, B1, m1);
                D0 = _mm512_mask3_fmadd_ps(cz, w0, D0, m0); D1 = _mm512_mask3_fmadd_ps(cz, w1, D1, m1);
                T0 = _mm512_mask_blend_ps(m0, T0, t0); T1 = _mm512_mask_blend_ps(m1, T1, t1);
                L0 = _mm512_mask_blend_epi32(m0, L0, kv); L1 = _mm512_mask_blend_epi32(m1, L1, kv);
                if (!(act0 | act1)) break;
            }
            _mm512_store_ps(sT[row], T0); _mm512_store_ps(sT[row + 1], T1);
            _mm512_store_ps(sR[row], R0); _mm512_store_ps(sR[row + 1], R1);
            _mm512_store_ps(sG[row], G0); _mm512_store_ps(sG[row + 1], G1);
            _mm512_store_ps(sB[row], B0); _mm512_store_ps(sB[row + 1], B1);
            _mm512_store_ps(sD[row], D0); _mm512_store_ps(sD[row + 1], D1);
            _mm512_store_si512((void *)sL[row], L0); _mm512_store_si512((void *)sL[row + 1], L1);
            if (active[row] && !act0) alive--;
            if (active[row + 1] && !act1) alive--;
            active[row] = act0;
            active[row + 1] = act1;
        }
    }
    for (int row = 0; row < j->h; row++) {
        size_t p0 = (size_t)(j->y0 + row) * j->width + j->x0;
        __m512 T = _mm512_load_ps(sT[row]);
        _mm512_mask_storeu_ps(j->depth + p0, lanes, _mm512_load_ps(sD[row]));
        _mm512_mask_storeu_ps(j->alpha + p0, lanes, _mm512_sub_ps(one, T));
        _mm512_mask_storeu_ps(j->tfinal + p0, lanes, T);
        _mm512_mask_storeu_epi32(j->last + p0, lanes, _mm512_load_si512((const void *)sL[row]));
        for (int i = 0; i < j->w; i++) {
            size_t p = p0 + i;
            j->rgb[3*p] = fmaf(sT[row][i], j->bg[0], sR[row][i]);
            j->rgb[3*p+1] = fmaf(sT[row][i], j->bg[1], sG[row][i]);
            j->rgb[3*p+2] = fmaf(sT[row][i], j->bg[2], sB[row][i]);
        }
    }
}

/* Gaussian-major, back to front: each Gaussian walks the tile rows its box covers (skipping
 * rows whose pixels all stopped before it) with its ten gradient sums in registers, reduced
 * across lanes once per (Gaussian, tile). Pixel state (T, suffix term Q, loss gradients) lives
 * in tile-local arrays. The conic/mean gradients are accumulated as moments of dL/dsigma
 * (sum g dx, g dy, g dx^2, g dx dy, g dy^2) and combined with the conic at the end. */
void splat_tile_backward_simd(const splat_tile_job *j)
{
    float T[SPLAT_TILE_PIX] __attribute__((aligned(64))), Q[SPLAT_TILE_PIX] __attribute__((aligned(64)));
    float Dr[SPLAT_TILE_PIX] __attribute__((aligned(64))), Dg[SPLAT_TILE_PIX] __attribute__((aligned(64)));
    float Db[SPLAT_TILE_PIX] __attribute__((aligned(64))), Dd[SPLAT_TILE_PIX] __attribute__((aligned(64)));
    int last[SPLAT_TILE_PIX] __attribute__((aligned(64)));
    splat_rec loc[CHUNK] __attribute__((aligned(64)));
    int rowmax[SPLAT_TILE];
    int kmax = -1;
    for (int row = 0; row < SPLAT_TILE; row++) {
        rowmax[row] = -1;
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
            if (last[t] > rowmax[row]) rowmax[row] = last[t];
        }
        if (rowmax[row] > kmax) kmax = rowmax[row];
    }
    for (int k = kmax + 1; k < j->n; k++)
        memset(j->grad_slots + (size_t)SPLAT_GRAD_STRIDE * splat_slot(&j->rec[j->list[k]], j->tx, j->ty), 0,
               SPLAT_GRAD_STRIDE * sizeof(float));
    const __m512 px = lane_centres(j->x0);
    const __m512 one = _mm512_set1_ps(1.0f), amax = _mm512_set1_ps(SPLAT_ALPHA_MAX);
    const __m512 amin = _mm512_set1_ps(SPLAT_ALPHA_MIN), zero = _mm512_setzero_ps();
    for (int kc = (kmax / CHUNK) * CHUNK; kc >= 0 && kmax >= 0; kc -= CHUNK) {
        int kend = kc + CHUNK - 1 < kmax ? kc + CHUNK - 1 : kmax;
        for (int k = kend; k >= kc; k--) {
            if (k - 8 >= kc) _mm_prefetch((const char *)&j->rec[j->list[k - 8]], _MM_HINT_T0);
            _mm512_store_si512((void *)&loc[k - kc], _mm512_loadu_si512((const void *)&j->rec[j->list[k]]));
        }
        for (int k = kend; k >= kc; k--) {
            const splat_rec *r = &loc[k - kc];
            __m512 a_m1 = zero, a_m2 = zero, a_xx = zero, a_xy = zero, a_yy = zero, a_o = zero;
            __m512 a_r = zero, a_g = zero, a_b = zero, a_z = zero;
            int r0 = r->ymin - j->y0, r1 = r->ymax - j->y0;
            if (r0 < 0) r0 = 0;
            if (r1 > j->h - 1) r1 = j->h - 1;
            const __m512 dx = _mm512_sub_ps(px, _mm512_set1_ps(r->x));
            const __m512 ha = _mm512_set1_ps(0.5f * r->ca);
            const __m512 thr = _mm512_set1_ps(r->thr), op = _mm512_set1_ps(r->o);
            const __m512 cr = _mm512_set1_ps(r->col[0]), cg = _mm512_set1_ps(r->col[1]), cb = _mm512_set1_ps(r->col[2]);
            const __m512 cz = _mm512_set1_ps(r->z);
            const __m512i kv = _mm512_set1_epi32(k);
            const __m512 dx2 = _mm512_mul_ps(dx, dx);
            for (int row = r0; row <= r1; row++) {
                if (rowmax[row] < k) continue;
                __mmask16 m = _mm512_cmp_epi32_mask(kv, _mm512_load_si512((const void *)(last + row * 16)), _MM_CMPINT_LE);
                float dy = (j->y0 + row + 0.5f) - r->y;
                float bdy = r->cb * dy, cdy = 0.5f * r->cc * dy * dy;
                __m512 sig = _mm512_fmadd_ps(dx, _mm512_fmadd_ps(ha, dx, _mm512_set1_ps(bdy)), _mm512_set1_ps(cdy));
                m = _mm512_mask_cmp_ps_mask(m, sig, thr, _CMP_LE_OQ);
                if (!m) continue;
                __m512 G = exp_poly16(_mm512_sub_ps(zero, sig));
                __m512 oG = _mm512_mul_ps(op, G);
                __m512 a = _mm512_min_ps(oG, amax);
                m = _mm512_mask_cmp_ps_mask(m, a, amin, _CMP_GE_OQ);
                /* 1 / (1 - a) by rcp14 + one Newton step (rel. error ~1e-8; 1 - a >= 0.01) */
                __m512 oma = _mm512_sub_ps(one, a);
                __m512 inv = _mm512_rcp14_ps(oma);
                inv = _mm512_mul_ps(inv, _mm512_fnmadd_ps(oma, inv, _mm512_set1_ps(2.0f)));
                float *Tp = T + row * 16, *Qp = Q + row * 16;
                __m512 Tv = _mm512_load_ps(Tp);
                __m512 Ti = _mm512_mul_ps(Tv, inv);
                __m512 dr = _mm512_load_ps(Dr + row * 16), dg = _mm512_load_ps(Dg + row * 16);
                __m512 db = _mm512_load_ps(Db + row * 16), dd = _mm512_load_ps(Dd + row * 16);
                __m512 q = _mm512_fmadd_ps(dd, cz, _mm512_fmadd_ps(db, cb, _mm512_fmadd_ps(dg, cg, _mm512_mul_ps(dr, cr))));
                __m512 w = _mm512_mul_ps(a, Ti);
                __m512 Qv = _mm512_load_ps(Qp);
                __m512 dLda = _mm512_fmsub_ps(Ti, q, _mm512_mul_ps(Qv, inv));
                __m512 Qn = _mm512_mask_blend_ps(m, Qv, _mm512_fmadd_ps(w, q, Qv));
                __m512 Tn = _mm512_mask_blend_ps(m, Tv, Ti);
                OPAQUE(Qn);
                OPAQUE(Tn);
                _mm512_store_ps(Qp, Qn);
                _mm512_store_ps(Tp, Tn);
                a_r = _mm512_mask3_fmadd_ps(w, dr, a_r, m);
                a_g = _mm512_mask3_fmadd_ps(w, dg, a_g, m);
                a_b = _mm512_mask3_fmadd_ps(w, db, a_b, m);
                a_z = _mm512_mask3_fmadd_ps(w, dd, a_z, m);
                m = _mm512_mask_cmp_ps_mask(m, oG, amax, _CMP_LT_OQ); /* clamped alpha: no gradient */
                __m512 gs = _mm512_maskz_mul_ps(m, dLda, a);           /* -dL/dsigma */
                __m512 dyv = _mm512_set1_ps(dy);
                a_o = _mm512_mask3_fmadd_ps(dLda, G, a_o, m);
                __m512 gdx = _mm512_mul_ps(gs, dx);
                a_m1 = _mm512_add_ps(a_m1, gdx);
                a_m2 = _mm512_fmadd_ps(gs, dyv, a_m2);
                a_xx = _mm512_fmadd_ps(gs, dx2, a_xx);
                a_xy = _mm512_fmadd_ps(gdx, dyv, a_xy);
                a_yy = _mm512_fmadd_ps(gs, _mm512_set1_ps(dy * dy), a_yy);
            }
            /* dsigma/dx_mean = -(ca dx + cb dy), dsigma/dy_mean = -(cb dx + cc dy); gs = -dL/dsigma */
            float s1 = _mm512_reduce_add_ps(a_m1), s2 = _mm512_reduce_add_ps(a_m2);
            float *slot = j->grad_slots + (size_t)SPLAT_GRAD_STRIDE * splat_slot(r, j->tx, j->ty);
            slot[0] = r->ca * s1 + r->cb * s2;
            slot[1] = r->cb * s1 + r->cc * s2;
            slot[2] = -0.5f * _mm512_reduce_add_ps(a_xx);
            slot[3] = -_mm512_reduce_add_ps(a_xy);
            slot[4] = -0.5f * _mm512_reduce_add_ps(a_yy);
            slot[5] = _mm512_reduce_add_ps(a_o);
            slot[6] = _mm512_reduce_add_ps(a_r);
            slot[7] = _mm512_reduce_add_ps(a_g);
            slot[8] = _mm512_reduce_add_ps(a_b);
            slot[9] = _mm512_reduce_add_ps(a_z);
        }
    }
}

#else /* no AVX-512 at compile time: the scalar kernels stand in */

int splat_simd_available(void) { return 0; }
const char *splat_simd_name(void) { return "scalar"; }
void splat_tile_forward_simd(const splat_tile_job *job) { splat_tile_forward_scalar(job); }
void splat_tile_backward_simd(const splat_tile_job *job) { splat_tile_backward_scalar(job); }

#endif
