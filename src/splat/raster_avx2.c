/* raster_avx2.c - AVX2 + FMA tile kernels for CPUs without AVX-512 (compiled with AVX2 flags and
 * without AVX-512 whatever the build's target; raster.c calls them only on CPUs that have AVX2).
 *
 * Same algorithm as the AVX-512 kernels (raster_simd.c) with 8-lane vectors: a tile row is two
 * halves. Per pixel the operations match the scalar reference (raster_tile.c), so the forward
 * images are bit-identical to it; the backward differs only in summation order.
 */
#include "splat/raster_kernels.h"

#include <string.h>

#if defined(__AVX2__) && defined(__FMA__)
#include <immintrin.h>

#define CHUNK 256


/* exp(-s) = splat_exp_poly(-s) for the lanes that are used (s <= ln 255); the clamp keeps
 * unused lanes away from denormals. */
static inline __m256 exp_neg8(__m256 s)
{
    return splat_exp_poly8(_mm256_sub_ps(_mm256_setzero_ps(), _mm256_min_ps(s, _mm256_set1_ps(20.0f))));
}

static inline __m256 lanes8(int x0)
{
    return _mm256_add_ps(_mm256_cvtepi32_ps(_mm256_add_epi32(_mm256_set1_epi32(x0), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7))),
                         _mm256_set1_ps(0.5f));
}

/* all-ones in lanes < w (of 8) */
static inline __m256 lane_mask8(int w)
{
    __m256i idx = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    return _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(w), idx));
}

static inline float hsum8(__m256 v)
{
    __m128 a = _mm_add_ps(_mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1));
    a = _mm_add_ps(a, _mm_movehl_ps(a, a));
    a = _mm_add_ss(a, _mm_movehdup_ps(a));
    return _mm_cvtss_f32(a);
}

/* Row-major forward: each tile row walks the Gaussians whose box covers it with its state in
 * registers (two 8-lane halves), and stops when all its pixels are saturated. */
void splat_tile_forward_avx2(const splat_tile_job *j)
{
    splat_rec loc[CHUNK] __attribute__((aligned(64)));
    int idx[CHUNK];
    float sT[SPLAT_TILE][16] __attribute__((aligned(32))), sR[SPLAT_TILE][16] __attribute__((aligned(32)));
    float sG[SPLAT_TILE][16] __attribute__((aligned(32))), sB[SPLAT_TILE][16] __attribute__((aligned(32)));
    float sD[SPLAT_TILE][16] __attribute__((aligned(32)));
    int sL[SPLAT_TILE][16] __attribute__((aligned(32)));
    int active[SPLAT_TILE]; /* bit i: pixel i of the row still accumulating */
    const __m256 px0 = lanes8(j->x0), px1 = lanes8(j->x0 + 8);
    const __m256 one = _mm256_set1_ps(1.0f), amax = _mm256_set1_ps(SPLAT_ALPHA_MAX), teps = _mm256_set1_ps(SPLAT_T_EPS);
    const __m256 lm0 = lane_mask8(j->w), lm1 = lane_mask8(j->w - 8);
    const int lanes = (1 << j->w) - 1;
    for (int row = 0; row < SPLAT_TILE; row++) {
        active[row] = row < j->h ? lanes : 0;
        for (int i = 0; i < 16; i++) { sT[row][i] = 1; sR[row][i] = sG[row][i] = sB[row][i] = sD[row][i] = 0; sL[row][i] = -1; }
    }
    int alive = j->h;
    for (int k0 = 0; k0 < j->n && alive; k0 += CHUNK) {
        int cn = j->n - k0 < CHUNK ? j->n - k0 : CHUNK;
        for (int i = 0; i < cn; i++) {
            if (i + 8 < cn) _mm_prefetch((const char *)&j->rec[j->list[k0 + i + 8]], _MM_HINT_T0);
            memcpy(&loc[i], &j->rec[j->list[k0 + i]], sizeof(splat_rec));
        }
        for (int row = 0; row < j->h; row++) {
            if (!active[row]) continue;
            int gy = j->y0 + row, cnt = 0;
            for (int i = 0; i < cn; i++) { idx[cnt] = i; cnt += (gy >= loc[i].ymin) & (gy <= loc[i].ymax); }
            const __m256 fy = _mm256_set1_ps(gy + 0.5f);
            __m256 act0 = _mm256_and_ps(lm0, _mm256_castsi256_ps(_mm256_cmpgt_epi32(
                              _mm256_and_si256(_mm256_set1_epi32(active[row]), _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128)),
                              _mm256_setzero_si256())));
            __m256 act1 = _mm256_and_ps(lm1, _mm256_castsi256_ps(_mm256_cmpgt_epi32(
                              _mm256_and_si256(_mm256_set1_epi32(active[row] >> 8), _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128)),
                              _mm256_setzero_si256())));
            __m256 T0 = _mm256_load_ps(sT[row]), T1 = _mm256_load_ps(sT[row] + 8);
            __m256 R0 = _mm256_load_ps(sR[row]), R1 = _mm256_load_ps(sR[row] + 8);
            __m256 G0 = _mm256_load_ps(sG[row]), G1 = _mm256_load_ps(sG[row] + 8);
            __m256 B0 = _mm256_load_ps(sB[row]), B1 = _mm256_load_ps(sB[row] + 8);
            __m256 D0 = _mm256_load_ps(sD[row]), D1 = _mm256_load_ps(sD[row] + 8);
            __m256 L0 = _mm256_load_ps((const float *)sL[row]), L1 = _mm256_load_ps((const float *)sL[row] + 8);
            for (int c = 0; c < cnt; c++) {
                const splat_rec *r = &loc[idx[c]];
                __m256 dy = _mm256_sub_ps(fy, _mm256_set1_ps(r->y));
                __m256 bdy = _mm256_mul_ps(_mm256_set1_ps(r->cb), dy);
                __m256 cdy = _mm256_mul_ps(_mm256_mul_ps(_mm256_set1_ps(r->hc), dy), dy);
                __m256 ha = _mm256_set1_ps(r->ha), thr = _mm256_set1_ps(r->thr), xb = _mm256_set1_ps(r->x);
                __m256 dx0 = _mm256_sub_ps(px0, xb), dx1 = _mm256_sub_ps(px1, xb);
                __m256 s0 = _mm256_fmadd_ps(dx0, _mm256_fmadd_ps(ha, dx0, bdy), cdy);
                __m256 s1 = _mm256_fmadd_ps(dx1, _mm256_fmadd_ps(ha, dx1, bdy), cdy);
                __m256 m0 = _mm256_and_ps(_mm256_cmp_ps(s0, thr, _CMP_LE_OQ), lm0);
                __m256 m1 = _mm256_and_ps(_mm256_cmp_ps(s1, thr, _CMP_LE_OQ), lm1);
                if (!_mm256_movemask_ps(_mm256_or_ps(m0, m1))) continue;
                __m256 op = _mm256_set1_ps(r->o);
                __m256 a0 = _mm256_min_ps(_mm256_mul_ps(op, exp_neg8(s0)), amax);
                __m256 a1 = _mm256_min_ps(_mm256_mul_ps(op, exp_neg8(s1)), amax);
                m0 = _mm256_and_ps(m0, act0);
                m1 = _mm256_and_ps(m1, act1);
                __m256 t0 = _mm256_mul_ps(T0, _mm256_sub_ps(one, a0)), t1 = _mm256_mul_ps(T1, _mm256_sub_ps(one, a1));
                __m256 f0 = _mm256_and_ps(m0, _mm256_cmp_ps(t0, teps, _CMP_LT_OQ));
                __m256 f1 = _mm256_and_ps(m1, _mm256_cmp_ps(t1, teps, _CMP_LT_OQ));
                act0 = _mm256_andnot_ps(f0, act0); m0 = _mm256_andnot_ps(f0, m0);
                act1 = _mm256_andnot_ps(f1, act1); m1 = _mm256_andnot_ps(f1, m1);
                __m256 w0 = _mm256_mul_ps(a0, T0), w1 = _mm256_mul_ps(a1, T1);
                __m256 cr = _mm256_set1_ps(r->col[0]), cg = _mm256_set1_ps(r->col[1]), cb = _mm256_set1_ps(r->col[2]);
                __m256 cz = _mm256_set1_ps(r->z);
                R0 = _mm256_blendv_ps(R0, _mm256_fmadd_ps(cr, w0, R0), m0); R1 = _mm256_blendv_ps(R1, _mm256_fmadd_ps(cr, w1, R1), m1);
                G0 = _mm256_blendv_ps(G0, _mm256_fmadd_ps(cg, w0, G0), m0); G1 = _mm256_blendv_ps(G1, _mm256_fmadd_ps(cg, w1, G1), m1);
                B0 = _mm256_blendv_ps(B0, _mm256_fmadd_ps(cb, w0, B0), m0); B1 = _mm256_blendv_ps(B1, _mm256_fmadd_ps(cb, w1, B1), m1);
                D0 = _mm256_blendv_ps(D0, _mm256_fmadd_ps(cz, w0, D0), m0); D1 = _mm256_blendv_ps(D1, _mm256_fmadd_ps(cz, w1, D1), m1);
                T0 = _mm256_blendv_ps(T0, t0, m0); T1 = _mm256_blendv_ps(T1, t1, m1);
                __m256 kv = _mm256_castsi256_ps(_mm256_set1_epi32(k0 + idx[c]));
                L0 = _mm256_blendv_ps(L0, kv, m0); L1 = _mm256_blendv_ps(L1, kv, m1);
                if (!_mm256_movemask_ps(_mm256_or_ps(act0, act1))) break;
            }
            _mm256_store_ps(sT[row], T0); _mm256_store_ps(sT[row] + 8, T1);
            _mm256_store_ps(sR[row], R0); _mm256_store_ps(sR[row] + 8, R1);
            _mm256_store_ps(sG[row], G0); _mm256_store_ps(sG[row] + 8, G1);
            _mm256_store_ps(sB[row], B0); _mm256_store_ps(sB[row] + 8, B1);
            _mm256_store_ps(sD[row], D0); _mm256_store_ps(sD[row] + 8, D1);
            _mm256_store_ps((float *)sL[row], L0); _mm256_store_ps((float *)sL[row] + 8, L1);
            active[row] = _mm256_movemask_ps(act0) | _mm256_movemask_ps(act1) << 8;
            if (!active[row]) alive--;
        }
    }
    for (int row = 0; row < j->h; row++) {
        size_t p0 = (size_t)(j->y0 + row) * j->width + j->x0;
        for (int i = 0; i < j->w; i++) {
            size_t p = p0 + i;
            float T = sT[row][i];
            j->rgb[3*p] = fmaf(T, j->bg[0], sR[row][i]);
            j->rgb[3*p+1] = fmaf(T, j->bg[1], sG[row][i]);
            j->rgb[3*p+2] = fmaf(T, j->bg[2], sB[row][i]);
            j->depth[p] = sD[row][i];
            j->alpha[p] = 1.0f - T;
            j->tfinal[p] = T;
            j->last[p] = sL[row][i];
        }
    }
}

/* Gaussian-major backward, back to front, ten per-lane sums per (Gaussian, tile). */
void splat_tile_backward_avx2(const splat_tile_job *j)
{
    float T[SPLAT_TILE_PIX] __attribute__((aligned(32))), Q[SPLAT_TILE_PIX] __attribute__((aligned(32)));
    float Dr[SPLAT_TILE_PIX] __attribute__((aligned(32))), Dg[SPLAT_TILE_PIX] __attribute__((aligned(32)));
    float Db[SPLAT_TILE_PIX] __attribute__((aligned(32))), Dd[SPLAT_TILE_PIX] __attribute__((aligned(32)));
    int last[SPLAT_TILE_PIX] __attribute__((aligned(32)));
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
    const __m256 pxh[2] = { lanes8(j->x0), lanes8(j->x0 + 8) };
    const __m256 one = _mm256_set1_ps(1.0f), amax = _mm256_set1_ps(SPLAT_ALPHA_MAX), zero = _mm256_setzero_ps();
    for (int k = kmax; k >= 0; k--) {
        if (k >= 8) _mm_prefetch((const char *)&j->rec[j->list[k - 8]], _MM_HINT_T0);
        const splat_rec *r = &j->rec[j->list[k]];
        __m256 a_x = zero, a_y = zero, a_xx = zero, a_xy = zero, a_yy = zero, a_o = zero;
        __m256 a_r = zero, a_g = zero, a_b = zero, a_z = zero;
        int r0 = r->ymin - j->y0, r1 = r->ymax - j->y0;
        if (r0 < 0) r0 = 0;
        if (r1 > j->h - 1) r1 = j->h - 1;
        const __m256 ha = _mm256_set1_ps(r->ha), cbv = _mm256_set1_ps(r->cb), hcv = _mm256_set1_ps(r->hc);
        const __m256 thr = _mm256_set1_ps(r->thr), op = _mm256_set1_ps(r->o), xb = _mm256_set1_ps(r->x);
        const __m256i kv = _mm256_set1_epi32(k);
        for (int row = r0; row <= r1; row++) {
            if (rowmax[row] < k) continue;
            __m256 dyv = _mm256_sub_ps(_mm256_set1_ps((j->y0 + row) + 0.5f), _mm256_set1_ps(r->y));
            __m256 bdy = _mm256_mul_ps(cbv, dyv), cdy = _mm256_mul_ps(_mm256_mul_ps(hcv, dyv), dyv);
            for (int h = 0; h < 2; h++) {
                int t = row * 16 + 8 * h;
                __m256 m = _mm256_castsi256_ps(_mm256_cmpgt_epi32(kv, _mm256_load_si256((const __m256i *)(last + t))));
                m = _mm256_andnot_ps(m, _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_load_si256((const __m256i *)(last + t)),
                                                                             _mm256_set1_epi32(-1)))); /* k <= last */
                __m256 dx = _mm256_sub_ps(pxh[h], xb);
                __m256 sig = _mm256_fmadd_ps(dx, _mm256_fmadd_ps(ha, dx, bdy), cdy);
                m = _mm256_and_ps(m, _mm256_cmp_ps(sig, thr, _CMP_LE_OQ));
                if (!_mm256_movemask_ps(m)) continue;
                __m256 G = exp_neg8(sig);
                __m256 oG = _mm256_mul_ps(op, G);
                __m256 a = _mm256_min_ps(oG, amax);
                __m256 inv = _mm256_div_ps(one, _mm256_sub_ps(one, a));
                __m256 Tv = _mm256_load_ps(T + t), Ti = _mm256_mul_ps(Tv, inv);
                __m256 dr = _mm256_load_ps(Dr + t), dg = _mm256_load_ps(Dg + t), db = _mm256_load_ps(Db + t);
                __m256 dd = _mm256_load_ps(Dd + t);
                __m256 q = _mm256_fmadd_ps(dd, _mm256_set1_ps(r->z),
                                           _mm256_fmadd_ps(db, _mm256_set1_ps(r->col[2]),
                                                           _mm256_fmadd_ps(dg, _mm256_set1_ps(r->col[1]),
                                                                           _mm256_mul_ps(dr, _mm256_set1_ps(r->col[0])))));
                __m256 w = _mm256_and_ps(m, _mm256_mul_ps(a, Ti));
                __m256 Qv = _mm256_load_ps(Q + t);
                __m256 dLda = _mm256_fmsub_ps(Ti, q, _mm256_mul_ps(Qv, inv));
                _mm256_store_ps(Q + t, _mm256_blendv_ps(Qv, _mm256_fmadd_ps(w, q, Qv), m));
                _mm256_store_ps(T + t, _mm256_blendv_ps(Tv, Ti, m));
                a_r = _mm256_fmadd_ps(w, dr, a_r);
                a_g = _mm256_fmadd_ps(w, dg, a_g);
                a_b = _mm256_fmadd_ps(w, db, a_b);
                a_z = _mm256_fmadd_ps(w, dd, a_z);
                __m256 mu = _mm256_and_ps(m, _mm256_cmp_ps(oG, amax, _CMP_LT_OQ)); /* clamped alpha: no gradient */
                __m256 gs = _mm256_and_ps(mu, _mm256_mul_ps(dLda, a));         /* -dL/dsigma */
                a_o = _mm256_add_ps(a_o, gs);
                __m256 gdx = _mm256_mul_ps(gs, dx), gdy = _mm256_mul_ps(gs, dyv);
                a_x = _mm256_add_ps(a_x, gdx);
                a_y = _mm256_add_ps(a_y, gdy);
                a_xx = _mm256_fmadd_ps(gdx, dx, a_xx);
                a_xy = _mm256_fmadd_ps(gdx, dyv, a_xy);
                a_yy = _mm256_fmadd_ps(gdy, dyv, a_yy);
            }
        }
        float s0 = hsum8(a_x), s1 = hsum8(a_y);
        float *slot = j->grad_slots + (size_t)SPLAT_GRAD_STRIDE * splat_slot(r, j->tx, j->ty);
        slot[0] = (2.0f * r->ha) * s0 + r->cb * s1;
        slot[1] = r->cb * s0 + (2.0f * r->hc) * s1;
        slot[2] = -0.5f * hsum8(a_xx);
        slot[3] = -hsum8(a_xy);
        slot[4] = -0.5f * hsum8(a_yy);
        slot[5] = hsum8(a_o) / r->o; /* sum dL/dalpha G = sum gs / o where alpha = o G */
        slot[6] = hsum8(a_r);
        slot[7] = hsum8(a_g);
        slot[8] = hsum8(a_b);
        slot[9] = hsum8(a_z);
    }
}

#endif
