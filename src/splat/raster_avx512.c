/* raster_avx512.c - AVX-512 tile kernels: one 16-pixel tile row per vector. Compiled with AVX-512
 * flags whatever the build's target; raster.c calls them only on CPUs that have AVX-512.
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


/* exp(-s) = splat_exp_poly(-s). Lanes outside a Gaussian's reach carry huge s; their results
 * are masked off, but denormal intermediates would still cost microcode assists (several times
 * slower for small Gaussians). Used lanes have s <= ln(255), so the clamp at 20 never changes
 * them. */
static inline __m512 exp_neg16(__m512 s)
{
    return splat_exp_poly16(_mm512_sub_ps(_mm512_setzero_ps(), _mm512_min_ps(s, _mm512_set1_ps(20.0f))));
}

/* Lane sums of ten vectors at once (about a third of the shuffles of ten separate
 * reductions): pairs fold their 256-bit halves, quads fold 128-bit blocks, then each block
 * is summed in place. Returns lane i = sum of the lanes of v[i] (i < 10). The sums stay in a
 * register: stored and read back one float at a time, they stalled the backward kernel on store
 * forwarding at every (Gaussian, tile) (docs/splat.md). */
static inline __m512 hsum10(const __m512 v[10])
{
    __m512 p[6];
    for (int i = 0; i < 5; i++) {
        __m512 a = v[2 * i], b = v[2 * i + 1];
        p[i] = _mm512_add_ps(_mm512_shuffle_f32x4(a, b, _MM_SHUFFLE(1, 0, 1, 0)),
                             _mm512_shuffle_f32x4(a, b, _MM_SHUFFLE(3, 2, 3, 2)));
    }
    p[5] = _mm512_setzero_ps();
    __m512 q[3];
    for (int i = 0; i < 3; i++) {
        __m512 x = p[2 * i], y = p[2 * i + 1];
        q[i] = _mm512_add_ps(_mm512_shuffle_f32x4(x, y, _MM_SHUFFLE(2, 0, 2, 0)),
                             _mm512_shuffle_f32x4(x, y, _MM_SHUFFLE(3, 1, 3, 1)));
        q[i] = _mm512_add_ps(q[i], _mm512_permute_ps(q[i], _MM_SHUFFLE(1, 0, 3, 2)));
        q[i] = _mm512_add_ps(q[i], _mm512_permute_ps(q[i], _MM_SHUFFLE(2, 3, 0, 1)));
    }
    /* after the two folds, block b of q[g] holds the sum of vector 4g + b in each of its lanes */
    const __m512i first8 = _mm512_set_epi32(0, 0, 0, 0, 0, 0, 0, 0, 28, 24, 20, 16, 12, 8, 4, 0);
    const __m512i last2 = _mm512_set_epi32(0, 0, 0, 0, 0, 0, 20, 16, 7, 6, 5, 4, 3, 2, 1, 0);
    return _mm512_permutex2var_ps(_mm512_permutex2var_ps(q[0], first8, q[1]), last2, q[2]);
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
void splat_tile_forward_avx512(const splat_tile_job *j)
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
    const __m512 teps = _mm512_set1_ps(SPLAT_T_EPS);
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
            const __m512 fy0 = _mm512_set1_ps(gy + 0.5f), fy1 = _mm512_set1_ps((gy + 1) + 0.5f);
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
                /* sigma = fmaf(dx, fmaf(ha, dx, b dy), (hc dy) dy) as in the scalar kernel, with
                 * memory-broadcast operands (no scalar work or register broadcasts per row) */
                __m512 dx = _mm512_sub_ps(px, _mm512_set1_ps(r->x));
                __m512 yb = _mm512_set1_ps(r->y), cbv = _mm512_set1_ps(r->cb), hcv = _mm512_set1_ps(r->hc);
                __m512 ha = _mm512_set1_ps(r->ha), thr = _mm512_set1_ps(r->thr);
                __m512 dy0 = _mm512_sub_ps(fy0, yb), dy1 = _mm512_sub_ps(fy1, yb);
                __m512 hdx = _mm512_fmadd_ps(ha, dx, _mm512_mul_ps(cbv, dy0));
                __m512 s0 = _mm512_fmadd_ps(dx, hdx, _mm512_mul_ps(_mm512_mul_ps(hcv, dy0), dy0));
                hdx = _mm512_fmadd_ps(ha, dx, _mm512_mul_ps(cbv, dy1));
                __m512 s1 = _mm512_fmadd_ps(dx, hdx, _mm512_mul_ps(_mm512_mul_ps(hcv, dy1), dy1));
                /* sigma <= ln(255 o) is the alpha >= 1/255 test. Branch on it alone: it resolves
                 * early, unlike one that waits on the previous Gaussian through the active masks */
                __mmask16 m0 = _mm512_mask_cmp_ps_mask(in0, s0, thr, _CMP_LE_OQ);
                __mmask16 m1 = _mm512_mask_cmp_ps_mask(in1, s1, thr, _CMP_LE_OQ);
                if (!(m0 | m1)) continue;
                __m512 op = _mm512_set1_ps(r->o);
                __m512 a0 = _mm512_min_ps(_mm512_mul_ps(op, exp_neg16(s0)), amax);
                __m512 a1 = _mm512_min_ps(_mm512_mul_ps(op, exp_neg16(s1)), amax);
                m0 &= act0;
                m1 &= act1;
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
    const __m512i idx3 = _mm512_mullo_epi32(_mm512_set_epi32(15, 14, 13, 12, 11, 10, 9, 8, 7, 6, 5, 4, 3, 2, 1, 0),
                                            _mm512_set1_epi32(3));
    for (int row = 0; row < j->h; row++) {
        size_t p0 = (size_t)(j->y0 + row) * j->width + j->x0;
        __m512 T = _mm512_load_ps(sT[row]);
        _mm512_mask_storeu_ps(j->depth + p0, lanes, _mm512_load_ps(sD[row]));
        _mm512_mask_storeu_ps(j->alpha + p0, lanes, _mm512_sub_ps(one, T));
        _mm512_mask_storeu_ps(j->tfinal + p0, lanes, T);
        _mm512_mask_storeu_epi32(j->last + p0, lanes, _mm512_load_si512((const void *)sL[row]));
        float *b = j->rgb + 3 * p0;
        _mm512_mask_i32scatter_ps(b, lanes, idx3, _mm512_fmadd_ps(T, _mm512_set1_ps(j->bg[0]), _mm512_load_ps(sR[row])), 4);
        _mm512_mask_i32scatter_ps(b + 1, lanes, idx3, _mm512_fmadd_ps(T, _mm512_set1_ps(j->bg[1]), _mm512_load_ps(sG[row])), 4);
        _mm512_mask_i32scatter_ps(b + 2, lanes, idx3, _mm512_fmadd_ps(T, _mm512_set1_ps(j->bg[2]), _mm512_load_ps(sB[row])), 4);
    }
}

/* Gaussian-major, back to front: each Gaussian walks the tile rows its box covers (skipping
 * rows whose pixels all stopped before it) with its ten gradient sums in registers, reduced
 * across lanes once per (Gaussian, tile). Pixel state (T, suffix term Q, loss gradients) lives
 * in tile-local arrays. The conic/mean gradients are accumulated as moments of dL/dsigma
 * (sum g dx, g dy, g dx^2, g dx dy, g dy^2) and combined with the conic at the end. */
void splat_tile_backward_avx512(const splat_tile_job *j)
{
    float T[SPLAT_TILE_PIX] __attribute__((aligned(64))), Q[SPLAT_TILE_PIX] __attribute__((aligned(64)));
    float Dr[SPLAT_TILE_PIX] __attribute__((aligned(64))), Dg[SPLAT_TILE_PIX] __attribute__((aligned(64)));
    float Db[SPLAT_TILE_PIX] __attribute__((aligned(64))), Dd[SPLAT_TILE_PIX] __attribute__((aligned(64)));
    int last[SPLAT_TILE_PIX] __attribute__((aligned(64)));
    splat_rec loc[CHUNK] __attribute__((aligned(64)));
    int rowmax[SPLAT_TILE];
    int kmax = -1;
    const __mmask16 lanes = (__mmask16)((1u << j->w) - 1u);
    const __m512i idx3 = _mm512_mullo_epi32(_mm512_set_epi32(15, 14, 13, 12, 11, 10, 9, 8, 7, 6, 5, 4, 3, 2, 1, 0),
                                            _mm512_set1_epi32(3));
    for (int row = 0; row < SPLAT_TILE; row++) {
        int t = row * 16;
        if (row >= j->h) {
            _mm512_store_ps(T + t, _mm512_setzero_ps()); _mm512_store_ps(Q + t, _mm512_setzero_ps());
            _mm512_store_ps(Dr + t, _mm512_setzero_ps()); _mm512_store_ps(Dg + t, _mm512_setzero_ps());
            _mm512_store_ps(Db + t, _mm512_setzero_ps()); _mm512_store_ps(Dd + t, _mm512_setzero_ps());
            _mm512_store_si512((void *)(last + t), _mm512_set1_epi32(-1));
            rowmax[row] = -1;
            continue;
        }
        /* the same per-pixel set-up as the scalar kernel, 16 pixels at a time */
        size_t p0 = (size_t)(j->y0 + row) * j->width + j->x0;
        __m512 z = _mm512_setzero_ps(), dr = z, dg = z, db = z, dd = z, da = z;
        if (j->d_rgb) {
            const float *b = j->d_rgb + 3 * p0;
            dr = _mm512_mask_i32gather_ps(z, lanes, idx3, b, 4);
            dg = _mm512_mask_i32gather_ps(z, lanes, idx3, b + 1, 4);
            db = _mm512_mask_i32gather_ps(z, lanes, idx3, b + 2, 4);
        }
        if (j->d_depth) dd = _mm512_maskz_loadu_ps(lanes, j->d_depth + p0);
        if (j->d_alpha) da = _mm512_maskz_loadu_ps(lanes, j->d_alpha + p0);
        __m512 bgdot = _mm512_fmadd_ps(_mm512_set1_ps(j->bg[2]), db,
                                       _mm512_fmadd_ps(_mm512_set1_ps(j->bg[1]), dg, _mm512_mul_ps(_mm512_set1_ps(j->bg[0]), dr)));
        __m512 Tf = _mm512_maskz_loadu_ps(lanes, j->tfinal + p0);
        __m512i L = _mm512_mask_loadu_epi32(_mm512_set1_epi32(-1), lanes, j->last + p0);
        _mm512_store_ps(T + t, Tf);
        _mm512_store_ps(Q + t, _mm512_sub_ps(z, _mm512_mul_ps(Tf, _mm512_sub_ps(da, bgdot))));
        _mm512_store_ps(Dr + t, dr); _mm512_store_ps(Dg + t, dg); _mm512_store_ps(Db + t, db); _mm512_store_ps(Dd + t, dd);
        _mm512_store_si512((void *)(last + t), L);
        rowmax[row] = _mm512_reduce_max_epi32(L);
        if (rowmax[row] > kmax) kmax = rowmax[row];
    }
    for (int k = kmax + 1; k < j->n; k++)
        memset(j->grad_slots + (size_t)SPLAT_GRAD_STRIDE * splat_slot(&j->rec[j->list[k]], j->tx, j->ty), 0,
               SPLAT_GRAD_STRIDE * sizeof(float));
    const __m512 px = lane_centres(j->x0);
    const __m512 one = _mm512_set1_ps(1.0f), amax = _mm512_set1_ps(SPLAT_ALPHA_MAX);
    const __m512 zero = _mm512_setzero_ps();
    for (int kc = (kmax / CHUNK) * CHUNK; kc >= 0 && kmax >= 0; kc -= CHUNK) {
        int kend = kc + CHUNK - 1 < kmax ? kc + CHUNK - 1 : kmax;
        for (int k = kend; k >= kc; k--) {
            if (k - 8 >= kc) _mm_prefetch((const char *)&j->rec[j->list[k - 8]], _MM_HINT_T0);
            _mm512_store_si512((void *)&loc[k - kc], _mm512_loadu_si512((const void *)&j->rec[j->list[k]]));
        }
        for (int k = kend; k >= kc; k--) {
            const splat_rec *r = &loc[k - kc];
            __m512 g0 = zero, g1 = zero, g2 = zero; /* per lane: sum gs, sum gs dy, sum gs dy^2 */
            __m512 a_r = zero, a_g = zero, a_b = zero, a_z = zero;
            int r0 = r->ymin - j->y0, r1 = r->ymax - j->y0;
            if (r0 < 0) r0 = 0;
            if (r1 > j->h - 1) r1 = j->h - 1;
            const __m512 dx = _mm512_sub_ps(px, _mm512_set1_ps(r->x));
            const __m512 ha = _mm512_set1_ps(r->ha), cbv = _mm512_set1_ps(r->cb), hcv = _mm512_set1_ps(r->hc);
            const __m512 yb = _mm512_set1_ps(r->y);
            const __m512 thr = _mm512_set1_ps(r->thr), op = _mm512_set1_ps(r->o);
            const __m512 cr = _mm512_set1_ps(r->col[0]), cg = _mm512_set1_ps(r->col[1]), cb = _mm512_set1_ps(r->col[2]);
            const __m512 cz = _mm512_set1_ps(r->z);
            const __m512i kv = _mm512_set1_epi32(k);
            const __m512 dx2 = _mm512_mul_ps(dx, dx);
            __m512 fy = _mm512_set1_ps((j->y0 + r0) + 0.5f); /* exact: small integers + 0.5 */
            for (int row = r0; row <= r1; row++, fy = _mm512_add_ps(fy, one)) {
                if (rowmax[row] < k) continue;
                __mmask16 m = _mm512_cmp_epi32_mask(kv, _mm512_load_si512((const void *)(last + row * 16)), _MM_CMPINT_LE);
                __m512 dyv = _mm512_sub_ps(fy, yb);
                __m512 bdyv = _mm512_mul_ps(cbv, dyv);
                __m512 sig = _mm512_fmadd_ps(dx, _mm512_fmadd_ps(ha, dx, bdyv), _mm512_mul_ps(_mm512_mul_ps(hcv, dyv), dyv));
                m = _mm512_mask_cmp_ps_mask(m, sig, thr, _CMP_LE_OQ); /* alpha >= 1/255 */
                if (!m) continue;
                __m512 G = exp_neg16(sig);
                __m512 oG = _mm512_mul_ps(op, G);
                __m512 a = _mm512_min_ps(oG, amax);
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
                __m512 gdy = _mm512_mul_ps(gs, dyv);
                g0 = _mm512_add_ps(g0, gs);
                g1 = _mm512_add_ps(g1, gdy);
                g2 = _mm512_fmadd_ps(gdy, dyv, g2);
            }
            /* dx is fixed per lane, so the dx moments come from g0, g1 after the row loop:
             * sum gs dx = dx g0, sum gs dx^2 = dx^2 g0, sum gs dx dy = dx g1. With alpha = o G
             * (unclamped lanes only), sum dL/dalpha G = sum gs / o. dsigma/dx_mean =
             * -(ca dx + cb dy), dsigma/dy_mean = -(cb dx + cc dy); gs = -dL/dsigma. */
            __m512 acc[10] = { _mm512_mul_ps(dx, g0), g1, _mm512_mul_ps(dx2, g0), _mm512_mul_ps(dx, g1), g2, g0,
                               a_r, a_g, a_b, a_z };
            /* slot = { 2ha s0 + cb s1, cb s0 + 2hc s1, -s2/2, -s3, -s4/2, s5/o, s6 .. s9 } with the
             * scalar kernel's roundings (separate multiply and add, a true division) */
            __m512 sum = hsum10(acc);
            __m512 swapped = _mm512_permutexvar_ps(_mm512_set_epi32(15, 14, 13, 12, 11, 10, 9, 8, 7, 6, 5, 4, 3, 2, 0, 1), sum);
            __m512 scale = _mm512_set_ps(1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, -0.5f, -1.0f, -0.5f, 0, 0);
            scale = _mm512_mask_mov_ps(scale, 0x1, _mm512_add_ps(ha, ha));
            scale = _mm512_mask_mov_ps(scale, 0x2, _mm512_add_ps(hcv, hcv));
            __m512 res = _mm512_mul_ps(scale, sum);
            res = _mm512_mask_add_ps(res, 0x3, res, _mm512_mul_ps(cbv, swapped));
            res = _mm512_mask_div_ps(res, 0x20, sum, op);
            _mm512_mask_storeu_ps(j->grad_slots + (size_t)SPLAT_GRAD_STRIDE * splat_slot(r, j->tx, j->ty), 0x3ff, res);
        }
    }
}

#endif
