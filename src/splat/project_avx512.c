/* project_avx512.c - the EWA projection of 16 Gaussians at once on AVX-512 (compiled with AVX-512
 * flags; the rasterizer calls it only when the CPU has AVX-512 and its kernels were chosen). The
 * same operations as project.c per lane, so results differ from the scalar path by rounding only. */
#include "splat/project.h"
#include "splat/raster_kernels.h"

#include <math.h>

#if defined(__AVX512F__)

/* exp(x) for |x| < 87 (rel. error ~2e-7). */
static inline __m512 exp16(__m512 x)
{
    x = _mm512_min_ps(_mm512_max_ps(x, _mm512_set1_ps(-87.0f)), _mm512_set1_ps(87.0f));
    return splat_exp_poly16(x);
}

/* t = W m + t_cam for 16 means (one vector per coordinate). */
static inline void cam_point16(const pg_camera *cam, const __m512 m[3], __m512 t[3])
{
    const float *W = cam->R;
    for (int r = 0; r < 3; r++)
        t[r] = _mm512_fmadd_ps(_mm512_set1_ps(W[3*r]), m[0],
                               _mm512_fmadd_ps(_mm512_set1_ps(W[3*r+1]), m[1],
                                               _mm512_fmadd_ps(_mm512_set1_ps(W[3*r+2]), m[2], _mm512_set1_ps(cam->t[r]))));
}

/* What forward16 and backward16 both compute on the way to Sigma2D (vector twin of sigma2d_state). */
typedef struct {
    __m512 w, x, y, z, iq;        /* normalised quaternion (identity where zero) and 1/|q| (0 there) */
    __mmask16 nz;                 /* lanes with a non-zero quaternion */
    __m512 R[9], sc[3], M[9];     /* R(q), exp(log_scale), M = R diag(sc) */
    __m512 fx, fy, iz, u, v, uc, vc; /* focal lengths, 1/z, x/z and y/z before and after the clamp */
    __m512 T0[3], T1[3], TC0[3], TC1[3]; /* rows of T = J W and of T cov */
    __m512 sxx, sxy, syy;         /* Sigma2D plus the low-pass term */
} sigma16;

static inline void sigma2d16(const pg_camera *cam, const float lim[SPLAT_LIM_COUNT], const __m512 t[3], const __m512 ls[3],
                             const __m512 q[4], sigma16 *S)
{
    const float *W = cam->R;
    const __m512 zero = _mm512_setzero_ps(), one = _mm512_set1_ps(1.0f), two = _mm512_set1_ps(2.0f);
    /* rotation of the normalised quaternion (identity for a zero quaternion) */
    __m512 qn2 = _mm512_fmadd_ps(q[0], q[0], _mm512_fmadd_ps(q[1], q[1], _mm512_fmadd_ps(q[2], q[2], _mm512_mul_ps(q[3], q[3]))));
    S->nz = _mm512_cmp_ps_mask(qn2, zero, _CMP_GT_OQ);
    S->iq = _mm512_maskz_div_ps(S->nz, one, _mm512_sqrt_ps(qn2));
    __m512 w = S->w = _mm512_mask_blend_ps(S->nz, one, _mm512_mul_ps(q[0], S->iq));
    __m512 x = S->x = _mm512_mul_ps(q[1], S->iq), y = S->y = _mm512_mul_ps(q[2], S->iq), z = S->z = _mm512_mul_ps(q[3], S->iq);
    __m512 *R = S->R;
    R[0] = _mm512_fnmadd_ps(two, _mm512_fmadd_ps(y, y, _mm512_mul_ps(z, z)), one);
    R[1] = _mm512_mul_ps(two, _mm512_fmsub_ps(x, y, _mm512_mul_ps(w, z)));
    R[2] = _mm512_mul_ps(two, _mm512_fmadd_ps(x, z, _mm512_mul_ps(w, y)));
    R[3] = _mm512_mul_ps(two, _mm512_fmadd_ps(x, y, _mm512_mul_ps(w, z)));
    R[4] = _mm512_fnmadd_ps(two, _mm512_fmadd_ps(x, x, _mm512_mul_ps(z, z)), one);
    R[5] = _mm512_mul_ps(two, _mm512_fmsub_ps(y, z, _mm512_mul_ps(w, x)));
    R[6] = _mm512_mul_ps(two, _mm512_fmsub_ps(x, z, _mm512_mul_ps(w, y)));
    R[7] = _mm512_mul_ps(two, _mm512_fmadd_ps(y, z, _mm512_mul_ps(w, x)));
    R[8] = _mm512_fnmadd_ps(two, _mm512_fmadd_ps(x, x, _mm512_mul_ps(y, y)), one);
    for (int k = 0; k < 3; k++) S->sc[k] = exp16(ls[k]);
    __m512 *M = S->M, C[9];
    for (int i = 0; i < 3; i++)
        for (int k = 0; k < 3; k++) M[3*i+k] = _mm512_mul_ps(R[3*i+k], S->sc[k]);
    /* cov = M M^T (symmetric, 6 entries) */
    for (int i = 0; i < 3; i++)
        for (int j = i; j < 3; j++)
            C[3*i+j] = C[3*j+i] = _mm512_fmadd_ps(M[3*i], M[3*j], _mm512_fmadd_ps(M[3*i+1], M[3*j+1], _mm512_mul_ps(M[3*i+2], M[3*j+2])));
    /* Jacobian with the clamped x/z, y/z */
    S->iz = _mm512_div_ps(one, t[2]);
    S->u = _mm512_mul_ps(t[0], S->iz);
    S->v = _mm512_mul_ps(t[1], S->iz);
    S->uc = _mm512_min_ps(_mm512_max_ps(S->u, _mm512_set1_ps(lim[0])), _mm512_set1_ps(lim[1]));
    S->vc = _mm512_min_ps(_mm512_max_ps(S->v, _mm512_set1_ps(lim[2])), _mm512_set1_ps(lim[3]));
    S->fx = _mm512_set1_ps(cam->fx);
    S->fy = _mm512_set1_ps(cam->fy);
    __m512 J00 = _mm512_mul_ps(S->fx, S->iz), J02 = _mm512_sub_ps(zero, _mm512_mul_ps(_mm512_mul_ps(S->fx, S->uc), S->iz));
    __m512 J11 = _mm512_mul_ps(S->fy, S->iz), J12 = _mm512_sub_ps(zero, _mm512_mul_ps(_mm512_mul_ps(S->fy, S->vc), S->iz));
    __m512 *T0 = S->T0, *T1 = S->T1, *TC0 = S->TC0, *TC1 = S->TC1;
    for (int j = 0; j < 3; j++) {
        T0[j] = _mm512_fmadd_ps(J00, _mm512_set1_ps(W[j]), _mm512_mul_ps(J02, _mm512_set1_ps(W[6+j])));
        T1[j] = _mm512_fmadd_ps(J11, _mm512_set1_ps(W[3+j]), _mm512_mul_ps(J12, _mm512_set1_ps(W[6+j])));
    }
    for (int j = 0; j < 3; j++) {
        TC0[j] = _mm512_fmadd_ps(T0[0], C[j], _mm512_fmadd_ps(T0[1], C[3+j], _mm512_mul_ps(T0[2], C[6+j])));
        TC1[j] = _mm512_fmadd_ps(T1[0], C[j], _mm512_fmadd_ps(T1[1], C[3+j], _mm512_mul_ps(T1[2], C[6+j])));
    }
    __m512 lp = _mm512_set1_ps(lim[4]);
    S->sxx = _mm512_add_ps(_mm512_fmadd_ps(TC0[0], T0[0], _mm512_fmadd_ps(TC0[1], T0[1], _mm512_mul_ps(TC0[2], T0[2]))), lp);
    S->sxy = _mm512_fmadd_ps(TC0[0], T1[0], _mm512_fmadd_ps(TC0[1], T1[1], _mm512_mul_ps(TC0[2], T1[2])));
    S->syy = _mm512_add_ps(_mm512_fmadd_ps(TC1[0], T1[0], _mm512_fmadd_ps(TC1[1], T1[1], _mm512_mul_ps(TC1[2], T1[2]))), lp);
}

int splat_project_forward16(const float *means, const float *log_scales, const float *quats, int i0,
                            const pg_camera *cam, const float lim[SPLAT_LIM_COUNT], float near_clip, float out[9][16],
                            unsigned *valid)
{
    const __m512i lane = _mm512_set_epi32(15, 14, 13, 12, 11, 10, 9, 8, 7, 6, 5, 4, 3, 2, 1, 0);
    const __m512i i3 = _mm512_mullo_epi32(lane, _mm512_set1_epi32(3)), i4 = _mm512_slli_epi32(lane, 2);
    const float *mb = means + 3 * (size_t)i0, *lb = log_scales + 3 * (size_t)i0, *qb = quats + 4 * (size_t)i0;
    __m512 m[3], ls[3], q[4];
    for (int c = 0; c < 3; c++) {
        m[c] = _mm512_i32gather_ps(i3, mb + c, 4);
        ls[c] = _mm512_i32gather_ps(i3, lb + c, 4);
    }
    for (int c = 0; c < 4; c++) q[c] = _mm512_i32gather_ps(i4, qb + c, 4);
    __m512 t[3];
    cam_point16(cam, m, t);
    __mmask16 ok = _mm512_cmp_ps_mask(t[2], _mm512_set1_ps(near_clip), _CMP_GE_OQ);
    sigma16 S;
    sigma2d16(cam, lim, t, ls, q, &S);
    __m512 one = _mm512_set1_ps(1.0f), fx = S.fx, fy = S.fy, iz = S.iz, sxx = S.sxx, sxy = S.sxy, syy = S.syy;
    __m512 det = _mm512_fmsub_ps(sxx, syy, _mm512_mul_ps(sxy, sxy));
    ok &= _mm512_cmp_ps_mask(det, _mm512_setzero_ps(), _CMP_GT_OQ);
    __m512 id = _mm512_div_ps(one, det);
    _mm512_storeu_ps(out[0], _mm512_fmadd_ps(_mm512_mul_ps(fx, t[0]), iz, _mm512_set1_ps(cam->cx)));
    _mm512_storeu_ps(out[1], _mm512_fmadd_ps(_mm512_mul_ps(fy, t[1]), iz, _mm512_set1_ps(cam->cy)));
    _mm512_storeu_ps(out[2], t[2]);
    _mm512_storeu_ps(out[3], sxx);
    _mm512_storeu_ps(out[4], sxy);
    _mm512_storeu_ps(out[5], syy);
    _mm512_storeu_ps(out[6], _mm512_mul_ps(syy, id));
    _mm512_storeu_ps(out[7], _mm512_sub_ps(_mm512_setzero_ps(), _mm512_mul_ps(sxy, id)));
    _mm512_storeu_ps(out[8], _mm512_mul_ps(sxx, id));
    *valid = ok;
    return 1;
}

/* Vector twin of splat_project_backward_lim for Gaussians i0 .. i0+15 (lanes in `mask`). */
int splat_project_backward16(const float *means, const float *log_scales, const float *quats, int i0,
                             const pg_camera *cam, const float lim[SPLAT_LIM_COUNT], const float d_xy[2][16],
                             const float d_conic[3][16], const float d_z[16], unsigned mask,
                             float *d_means, float *d_log_scales, float *d_quats)
{
    const __m512i lane = _mm512_set_epi32(15, 14, 13, 12, 11, 10, 9, 8, 7, 6, 5, 4, 3, 2, 1, 0);
    const __m512i i3 = _mm512_mullo_epi32(lane, _mm512_set1_epi32(3)), i4 = _mm512_slli_epi32(lane, 2);
    const __mmask16 km = (__mmask16)mask;
    const size_t b3 = 3 * (size_t)i0, b4 = 4 * (size_t)i0;
    const __m512 zero = _mm512_setzero_ps(), one = _mm512_set1_ps(1.0f), two = _mm512_set1_ps(2.0f);
    __m512 m[3], ls[3], q[4];
    for (int c = 0; c < 3; c++) {
        m[c] = _mm512_mask_i32gather_ps(zero, km, i3, means + b3 + c, 4);
        ls[c] = _mm512_mask_i32gather_ps(zero, km, i3, log_scales + b3 + c, 4);
    }
    for (int c = 0; c < 4; c++) q[c] = _mm512_mask_i32gather_ps(one, km, i4, quats + b4 + c, 4);
    const float *W = cam->R;
    __m512 t[3];
    cam_point16(cam, m, t);
    t[2] = _mm512_mask_blend_ps(km, one, t[2]); /* unused lanes: keep the arithmetic tame */
    sigma16 S;
    sigma2d16(cam, lim, t, ls, q, &S);
    __mmask16 nz = S.nz;
    __m512 iq = S.iq, w = S.w, x = S.x, y = S.y, z = S.z, fx = S.fx, fy = S.fy, iz = S.iz, uc = S.uc, vc = S.vc;
    const __m512 *R = S.R, *sc = S.sc, *M = S.M, *T0 = S.T0, *T1 = S.T1, *TC0 = S.TC0, *TC1 = S.TC1;
    __m512 sxx = S.sxx, sxy = S.sxy, syy = S.syy;
    __m512 iz2 = _mm512_mul_ps(iz, iz);
    __mmask16 cfx = _mm512_cmp_ps_mask(uc, S.u, _CMP_NEQ_UQ), cfy = _mm512_cmp_ps_mask(vc, S.v, _CMP_NEQ_UQ);
    __m512 id = _mm512_div_ps(one, _mm512_fmsub_ps(sxx, syy, _mm512_mul_ps(sxy, sxy)));
    /* dL/dSigma2D = -Q Gq Q, Gq = [[da, db/2], [db/2, dc]] */
    __m512 Qa = _mm512_mul_ps(syy, id), Qb = _mm512_sub_ps(zero, _mm512_mul_ps(sxy, id)), Qc = _mm512_mul_ps(sxx, id);
    __m512 ga = _mm512_loadu_ps(d_conic[0]), gb = _mm512_mul_ps(_mm512_set1_ps(0.5f), _mm512_loadu_ps(d_conic[1]));
    __m512 gc = _mm512_loadu_ps(d_conic[2]);
    __m512 QG00 = _mm512_fmadd_ps(Qa, ga, _mm512_mul_ps(Qb, gb)), QG01 = _mm512_fmadd_ps(Qa, gb, _mm512_mul_ps(Qb, gc));
    __m512 QG10 = _mm512_fmadd_ps(Qb, ga, _mm512_mul_ps(Qc, gb)), QG11 = _mm512_fmadd_ps(Qb, gb, _mm512_mul_ps(Qc, gc));
    __m512 G00 = _mm512_sub_ps(zero, _mm512_fmadd_ps(QG00, Qa, _mm512_mul_ps(QG01, Qb)));
    __m512 G01 = _mm512_sub_ps(zero, _mm512_fmadd_ps(QG00, Qb, _mm512_mul_ps(QG01, Qc)));
    __m512 G10 = _mm512_sub_ps(zero, _mm512_fmadd_ps(QG10, Qa, _mm512_mul_ps(QG11, Qb)));
    __m512 G11 = _mm512_sub_ps(zero, _mm512_fmadd_ps(QG10, Qb, _mm512_mul_ps(QG11, Qc)));
    __m512 dT0[3], dT1[3], u0[3], u1[3];
    for (int j = 0; j < 3; j++) {
        dT0[j] = _mm512_mul_ps(two, _mm512_fmadd_ps(G00, TC0[j], _mm512_mul_ps(G01, TC1[j])));
        dT1[j] = _mm512_mul_ps(two, _mm512_fmadd_ps(G10, TC0[j], _mm512_mul_ps(G11, TC1[j])));
        u0[j] = _mm512_fmadd_ps(G00, T0[j], _mm512_mul_ps(G01, T1[j]));
        u1[j] = _mm512_fmadd_ps(G10, T0[j], _mm512_mul_ps(G11, T1[j]));
    }
    __m512 dC[9];
    for (int i = 0; i < 3; i++)
        for (int j = i; j < 3; j++) dC[3*i+j] = dC[3*j+i] = _mm512_fmadd_ps(T0[i], u0[j], _mm512_mul_ps(T1[i], u1[j]));
    __m512 dR[9], dls[3];
    for (int k = 0; k < 3; k++) {
        __m512 ds = zero;
        for (int i = 0; i < 3; i++) {
            __m512 dM = _mm512_mul_ps(two, _mm512_fmadd_ps(dC[3*i], M[k], _mm512_fmadd_ps(dC[3*i+1], M[3+k], _mm512_mul_ps(dC[3*i+2], M[6+k]))));
            ds = _mm512_fmadd_ps(dM, R[3*i+k], ds);
            dR[3*i+k] = _mm512_mul_ps(dM, sc[k]);
        }
        dls[k] = _mm512_mul_ps(ds, sc[k]);
    }
    __m512 dq[4];
    dq[0] = _mm512_mul_ps(two, _mm512_add_ps(_mm512_add_ps(_mm512_fmsub_ps(y, dR[2], _mm512_mul_ps(z, dR[1])),
                                                           _mm512_fmsub_ps(z, dR[3], _mm512_mul_ps(x, dR[5]))),
                                             _mm512_fmsub_ps(x, dR[7], _mm512_mul_ps(y, dR[6]))));
    dq[1] = _mm512_mul_ps(two, _mm512_add_ps(_mm512_add_ps(_mm512_fmadd_ps(y, _mm512_add_ps(dR[1], dR[3]), _mm512_mul_ps(z, _mm512_add_ps(dR[2], dR[6]))),
                                                           _mm512_mul_ps(w, _mm512_sub_ps(dR[7], dR[5]))),
                                             _mm512_mul_ps(_mm512_mul_ps(two, x), _mm512_sub_ps(zero, _mm512_add_ps(dR[4], dR[8])))));
    dq[2] = _mm512_mul_ps(two, _mm512_add_ps(_mm512_add_ps(_mm512_fmadd_ps(x, _mm512_add_ps(dR[1], dR[3]), _mm512_mul_ps(z, _mm512_add_ps(dR[5], dR[7]))),
                                                           _mm512_mul_ps(w, _mm512_sub_ps(dR[2], dR[6]))),
                                             _mm512_mul_ps(_mm512_mul_ps(two, y), _mm512_sub_ps(zero, _mm512_add_ps(dR[0], dR[8])))));
    dq[3] = _mm512_mul_ps(two, _mm512_add_ps(_mm512_add_ps(_mm512_fmadd_ps(x, _mm512_add_ps(dR[2], dR[6]), _mm512_mul_ps(y, _mm512_add_ps(dR[5], dR[7]))),
                                                           _mm512_mul_ps(w, _mm512_sub_ps(dR[3], dR[1]))),
                                             _mm512_mul_ps(_mm512_mul_ps(two, z), _mm512_sub_ps(zero, _mm512_add_ps(dR[0], dR[4])))));
    __m512 qq[4] = { w, x, y, z };
    __m512 dot = _mm512_fmadd_ps(dq[0], w, _mm512_fmadd_ps(dq[1], x, _mm512_fmadd_ps(dq[2], y, _mm512_mul_ps(dq[3], z))));
    /* dL/dJ (only the non-zero entries) and then dt */
    __m512 dJ00 = zero, dJ02 = zero, dJ11 = zero, dJ12 = zero;
    for (int j = 0; j < 3; j++) {
        dJ00 = _mm512_fmadd_ps(dT0[j], _mm512_set1_ps(W[j]), dJ00);
        dJ02 = _mm512_fmadd_ps(dT0[j], _mm512_set1_ps(W[6+j]), dJ02);
        dJ11 = _mm512_fmadd_ps(dT1[j], _mm512_set1_ps(W[3+j]), dJ11);
        dJ12 = _mm512_fmadd_ps(dT1[j], _mm512_set1_ps(W[6+j]), dJ12);
    }
    __m512 dxy0 = _mm512_loadu_ps(d_xy[0]), dxy1 = _mm512_loadu_ps(d_xy[1]);
    __m512 fxi2 = _mm512_mul_ps(fx, iz2), fyi2 = _mm512_mul_ps(fy, iz2);
    __m512 dt0 = _mm512_mul_ps(_mm512_mul_ps(fx, iz), dxy0), dt1 = _mm512_mul_ps(_mm512_mul_ps(fy, iz), dxy1);
    __m512 dt2 = _mm512_sub_ps(_mm512_loadu_ps(d_z), _mm512_fmadd_ps(fxi2, dJ00, _mm512_mul_ps(fyi2, dJ11)));
    dt2 = _mm512_sub_ps(dt2, _mm512_fmadd_ps(_mm512_mul_ps(fxi2, t[0]), dxy0, _mm512_mul_ps(_mm512_mul_ps(fyi2, t[1]), dxy1)));
    /* x: clamped -> J02 = -fx uc / z (uc constant); free -> J02 = -fx x / z^2 */
    dt2 = _mm512_mask_add_ps(dt2, cfx, dt2, _mm512_mul_ps(_mm512_mul_ps(fxi2, uc), dJ02));
    dt0 = _mm512_mask3_fnmadd_ps(fxi2, dJ02, dt0, (__mmask16)~cfx);
    dt2 = _mm512_mask_add_ps(dt2, (__mmask16)~cfx, dt2,
                             _mm512_mul_ps(_mm512_mul_ps(_mm512_mul_ps(two, fxi2), _mm512_mul_ps(t[0], iz)), dJ02));
    dt2 = _mm512_mask_add_ps(dt2, cfy, dt2, _mm512_mul_ps(_mm512_mul_ps(fyi2, vc), dJ12));
    dt1 = _mm512_mask3_fnmadd_ps(fyi2, dJ12, dt1, (__mmask16)~cfy);
    dt2 = _mm512_mask_add_ps(dt2, (__mmask16)~cfy, dt2,
                             _mm512_mul_ps(_mm512_mul_ps(_mm512_mul_ps(two, fyi2), _mm512_mul_ps(t[1], iz)), dJ12));
    __m512 dt[3] = { dt0, dt1, dt2 };
    /* accumulate into the gradient rows of the lanes in mask */
    for (int k = 0; k < 3; k++) {
        __m512 dm = _mm512_fmadd_ps(_mm512_set1_ps(W[k]), dt[0],
                                    _mm512_fmadd_ps(_mm512_set1_ps(W[3+k]), dt[1], _mm512_mul_ps(_mm512_set1_ps(W[6+k]), dt[2])));
        __m512 old = _mm512_mask_i32gather_ps(zero, km, i3, d_means + b3 + k, 4);
        _mm512_mask_i32scatter_ps(d_means + b3 + k, km, i3, _mm512_add_ps(old, dm), 4);
        old = _mm512_mask_i32gather_ps(zero, km, i3, d_log_scales + b3 + k, 4);
        _mm512_mask_i32scatter_ps(d_log_scales + b3 + k, km, i3, _mm512_add_ps(old, dls[k]), 4);
    }
    __mmask16 kq = km & nz;
    for (int c = 0; c < 4; c++) {
        __m512 g = _mm512_mul_ps(_mm512_fnmadd_ps(dot, qq[c], dq[c]), iq);
        __m512 old = _mm512_mask_i32gather_ps(zero, kq, i4, d_quats + b4 + c, 4);
        _mm512_mask_i32scatter_ps(d_quats + b4 + c, kq, i4, _mm512_add_ps(old, g), 4);
    }
    return 1;
}
unsigned splat_box16_avx512(const float pr[9][16], unsigned valid, const float *opacity, int i0, int width, int height,
                            splat_box16 *b)
{
    const __m512 half = _mm512_set1_ps(0.5f), zero = _mm512_setzero_ps(), reach = _mm512_set1_ps(3.33f);
    const __m512 wmax = _mm512_set1_ps((float)(width - 1)), hmax = _mm512_set1_ps((float)(height - 1));
    const __m512 x = _mm512_loadu_ps(pr[0]), y = _mm512_loadu_ps(pr[1]);
    const __m512 sx = _mm512_sqrt_ps(_mm512_loadu_ps(pr[3])), sy = _mm512_sqrt_ps(_mm512_loadu_ps(pr[5]));
    enum { up = _MM_FROUND_TO_POS_INF | _MM_FROUND_NO_EXC, down = _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC };
    /* the box at the largest reach first: most of a crop's Gaussians leave here */
    __m512 rx = _mm512_roundscale_ps(_mm512_mul_ps(reach, sx), up), ry = _mm512_roundscale_ps(_mm512_mul_ps(reach, sy), up);
    __mmask16 k = (__mmask16)valid;
    k = _mm512_mask_cmp_ps_mask(k, _mm512_roundscale_ps(_mm512_sub_ps(_mm512_add_ps(x, rx), half), down), zero, _CMP_GE_OQ);
    k = _mm512_mask_cmp_ps_mask(k, _mm512_roundscale_ps(_mm512_sub_ps(_mm512_add_ps(y, ry), half), down), zero, _CMP_GE_OQ);
    k = _mm512_mask_cmp_ps_mask(k, _mm512_roundscale_ps(_mm512_sub_ps(_mm512_sub_ps(x, rx), half), up), wmax, _CMP_LE_OQ);
    k = _mm512_mask_cmp_ps_mask(k, _mm512_roundscale_ps(_mm512_sub_ps(_mm512_sub_ps(y, ry), half), up), hmax, _CMP_LE_OQ);
    if (!k) return 0;
    const __m512 o = splat_sigmoid_poly16(_mm512_loadu_ps(opacity + i0));
    k = _mm512_mask_cmp_ps_mask(k, o, _mm512_set1_ps(SPLAT_ALPHA_MIN), _CMP_GE_OQ);
    if (!k) return 0;
    const __m512 lim = splat_log_poly16(_mm512_mask_mul_ps(_mm512_set1_ps(1.0f), k, _mm512_set1_ps(255.0f), o));
    const __m512 e = _mm512_min_ps(_mm512_sqrt_ps(_mm512_mul_ps(_mm512_set1_ps(2.0f), _mm512_max_ps(lim, zero))), reach);
    rx = _mm512_roundscale_ps(_mm512_mul_ps(e, sx), up);
    ry = _mm512_roundscale_ps(_mm512_mul_ps(e, sy), up);
    const __m512 fxmin = _mm512_roundscale_ps(_mm512_sub_ps(_mm512_sub_ps(x, rx), half), up);
    const __m512 fxmax = _mm512_roundscale_ps(_mm512_sub_ps(_mm512_add_ps(x, rx), half), down);
    const __m512 fymin = _mm512_roundscale_ps(_mm512_sub_ps(_mm512_sub_ps(y, ry), half), up);
    const __m512 fymax = _mm512_roundscale_ps(_mm512_sub_ps(_mm512_add_ps(y, ry), half), down);
    k = _mm512_mask_cmp_ps_mask(k, fxmax, zero, _CMP_GE_OQ);
    k = _mm512_mask_cmp_ps_mask(k, fymax, zero, _CMP_GE_OQ);
    k = _mm512_mask_cmp_ps_mask(k, fxmin, wmax, _CMP_LE_OQ);
    k = _mm512_mask_cmp_ps_mask(k, fymin, hmax, _CMP_LE_OQ);
    const __m512i xmin = _mm512_cvttps_epi32(_mm512_max_ps(fxmin, zero)), xmax = _mm512_cvttps_epi32(_mm512_min_ps(fxmax, wmax));
    const __m512i ymin = _mm512_cvttps_epi32(_mm512_max_ps(fymin, zero)), ymax = _mm512_cvttps_epi32(_mm512_min_ps(fymax, hmax));
    k = _mm512_mask_cmp_epi32_mask(k, xmin, xmax, _MM_CMPINT_LE);
    k = _mm512_mask_cmp_epi32_mask(k, ymin, ymax, _MM_CMPINT_LE);
    _mm512_storeu_ps(b->o, o);
    _mm512_storeu_ps(b->thr, lim);
    _mm512_storeu_si512((void *)b->xmin, xmin);
    _mm512_storeu_si512((void *)b->xmax, xmax);
    _mm512_storeu_si512((void *)b->ymin, ymin);
    _mm512_storeu_si512((void *)b->ymax, ymax);
    return k;
}
#else
unsigned splat_box16_avx512(const float pr[9][16], unsigned valid, const float *opacity, int i0, int width, int height,
                            splat_box16 *b)
{
    (void)pr; (void)valid; (void)opacity; (void)i0; (void)width; (void)height; (void)b;
    return 0;
}

int splat_project_forward16(const float *means, const float *log_scales, const float *quats, int i0,
                            const pg_camera *cam, const float lim[SPLAT_LIM_COUNT], float near_clip, float out[9][16],
                            unsigned *valid)
{
    (void)means; (void)log_scales; (void)quats; (void)i0; (void)cam; (void)lim; (void)near_clip; (void)out;
    *valid = 0;
    return 0;
}

int splat_project_backward16(const float *means, const float *log_scales, const float *quats, int i0,
                             const pg_camera *cam, const float lim[SPLAT_LIM_COUNT], const float d_xy[2][16],
                             const float d_conic[3][16], const float d_z[16], unsigned mask,
                             float *d_means, float *d_log_scales, float *d_quats)
{
    (void)means; (void)log_scales; (void)quats; (void)i0; (void)cam; (void)lim; (void)d_xy; (void)d_conic;
    (void)d_z; (void)mask; (void)d_means; (void)d_log_scales; (void)d_quats;
    return 0;
}
#endif
