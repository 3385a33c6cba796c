/* filter3d_avx512.c - the 3D filter's forward on 16 Gaussians at a time (filter3d.c has the model
 * and the scalar twin). Compiled with AVX-512 flags whatever the build's target; filter3d.c calls
 * it only when the rasterizer's AVX-512 kernels are the ones in use.
 *
 * Every rendered time filters every Gaussian it deforms (and once per step the fixed ones): ~8
 * libm exponentials and logarithms a Gaussian were ~4 % of a classroom training step. Here they
 * are polynomials on 16 lanes, the rasterizer's (splat_exp_poly16, splat_log_poly16), within ~2 ulp
 * of libm.
 */
#include "splat/filter3d_kernels.h"

#if defined(__AVX512F__)
#include "splat/raster_kernels.h"

#include <immintrin.h>

/* e^x for x <= 88; below -104 the result is 0 (scalef makes the subnormals exactly). */
static inline __m512 exp16(__m512 x)
{
    return splat_exp_poly16(_mm512_max_ps(x, _mm512_set1_ps(-104.0f)));
}

/* log(1 + u) for u in [0, 1] without losing the small u: log(w) u / (w - 1) with w = 1 + u rounded
 * (the rounding of w cancels to first order); u itself where w rounds to 1. */
static inline __m512 log1p16(__m512 u)
{
    __m512 w = _mm512_add_ps(_mm512_set1_ps(1.0f), u), d = _mm512_sub_ps(w, _mm512_set1_ps(1.0f));
    __mmask16 moved = _mm512_cmp_ps_mask(d, _mm512_setzero_ps(), _CMP_NEQ_OQ);
    return _mm512_mask_mul_ps(u, moved, splat_log_poly16(w), _mm512_maskz_div_ps(moved, u, d));
}

void splat_filter3d_forward16_avx512(float *log_scales, float *opacity, const float *var, const int *rows, int i0,
                                     int n, float *saved)
{
    const __m512 zero = _mm512_setzero_ps(), one = _mm512_set1_ps(1.0f), half = _mm512_set1_ps(0.5f);
    const __mmask16 lanes = (__mmask16)((1u << n) - 1u);
    __m512i idx = rows ? _mm512_maskz_loadu_epi32(lanes, rows)
                       : _mm512_add_epi32(_mm512_set1_epi32(i0), _mm512_set_epi32(15, 14, 13, 12, 11, 10, 9, 8, 7, 6, 5, 4, 3, 2, 1, 0));
    __m512 v = _mm512_mask_i32gather_ps(zero, lanes, idx, var, 4);
    const __mmask16 live = _mm512_mask_cmp_ps_mask(lanes, v, zero, _CMP_GT_OQ);
    if (!live) return;
    v = _mm512_mask_blend_ps(live, one, v); /* dead lanes compute on harmless numbers */
    const __m512i idx3 = _mm512_mullo_epi32(idx, _mm512_set1_epi32(3));
    const __m512 lv = splat_log_poly16(v);
    __m512 w[3], log_keep = zero;
    for (int k = 0; k < 3; k++) {
        __m512 ls = _mm512_mask_i32gather_ps(zero, live, idx3, log_scales + k, 4);
        __m512 d = _mm512_fnmadd_ps(_mm512_set1_ps(2.0f), ls, lv);
        __m512 e = exp16(_mm512_sub_ps(zero, _mm512_abs_ps(d))), inv = _mm512_div_ps(one, _mm512_add_ps(one, e));
        __m512 sp = _mm512_add_ps(_mm512_max_ps(d, zero), log1p16(e));
        __mmask16 pos = _mm512_cmp_ps_mask(d, zero, _CMP_GE_OQ);
        w[k] = _mm512_mask_blend_ps(pos, _mm512_mul_ps(e, inv), inv);
        _mm512_mask_i32scatter_ps(log_scales + k, live, idx3, _mm512_fmadd_ps(half, sp, ls), 4);
        log_keep = _mm512_sub_ps(log_keep, sp);
    }
    const __m512 log_rho = _mm512_mul_ps(half, log_keep), rho = exp16(log_rho);
    const __m512 lost = _mm512_fmadd_ps(_mm512_sub_ps(one, w[0]),
                                        _mm512_fmadd_ps(_mm512_sub_ps(one, w[1]), w[2], w[1]), w[0]);
    const __m512 o = _mm512_mask_i32gather_ps(zero, live, idx, opacity, 4);
    const __m512 eo = exp16(_mm512_sub_ps(zero, _mm512_abs_ps(o))), inv = _mm512_div_ps(one, _mm512_add_ps(one, eo));
    const __mmask16 opos = _mm512_cmp_ps_mask(o, zero, _CMP_GE_OQ);
    const __m512 a = _mm512_mask_blend_ps(opos, _mm512_mul_ps(eo, inv), inv);
    const __m512 na = _mm512_mask_blend_ps(opos, inv, _mm512_mul_ps(eo, inv));
    const __m512 na_filtered = _mm512_fmadd_ps(a, _mm512_div_ps(lost, _mm512_add_ps(one, rho)), na);
    const __m512 log_a_rho = _mm512_sub_ps(log_rho, _mm512_add_ps(_mm512_max_ps(_mm512_sub_ps(zero, o), zero), log1p16(eo)));
    const __mmask16 plain = _mm512_cmp_ps_mask(log_a_rho, _mm512_set1_ps(-30.0f), _CMP_GT_OQ);
    const __m512 ratio = _mm512_div_ps(_mm512_mul_ps(a, rho), na_filtered);
    const __m512 o_new = _mm512_mask_blend_ps(plain, log_a_rho, splat_log_poly16(_mm512_mask_blend_ps(plain, one, ratio)));
    _mm512_mask_i32scatter_ps(opacity, live, idx, o_new, 4);
    if (saved) {
        const __m512i idx5 = _mm512_mullo_epi32(idx, _mm512_set1_epi32(SPLAT_FILTER3D_SAVED));
        const __m512 sv[SPLAT_FILTER3D_SAVED] = { w[0], w[1], w[2], _mm512_div_ps(na, na_filtered),
                                                  _mm512_div_ps(one, na_filtered) };
        for (int k = 0; k < SPLAT_FILTER3D_SAVED; k++) _mm512_mask_i32scatter_ps(saved + k, live, idx5, sv[k], 4);
    }
}

#endif
