/* project_avx2.c - the EWA projection of 16 Gaussians as two 8-lane halves on AVX2 + FMA, for CPUs
 * without AVX-512 (compiled with AVX2 flags and without AVX-512 whatever the build's target; the
 * rasterizer calls it only when the CPU has AVX2 and its AVX2 kernels were chosen). Per lane the
 * operations are those of project_avx512.c (the same fused multiply-adds in the same order), so
 * both should give the same floats (test_splat_grad compares them where a CPU runs both); against
 * the scalar path they differ by rounding only. Without the
 * vector kernels the scalar projection was ~10 % of a training step on an AVX2-only CPU. */
#include "splat/project.h"
#include "splat/raster_kernels.h"

#include <math.h>

#if defined(__AVX2__) && defined(__FMA__)

#define V __m256
#define SET(x) _mm256_set1_ps(x)
#define ADD _mm256_add_ps
#define SUB _mm256_sub_ps
#define MUL _mm256_mul_ps
#define FMA _mm256_fmadd_ps
#define FMS _mm256_fmsub_ps
#define ZERO _mm256_setzero_ps()
#define AND _mm256_and_ps
/* mask ? b : a */
#define BLEND(a, b, mask) _mm256_blendv_ps(a, b, mask)

/* exp(x) for |x| < 87 (rel. error ~2e-7), as exp16 in project_avx512.c. */
static inline V exp8(V x)
{
    x = _mm256_min_ps(_mm256_max_ps(x, SET(-87.0f)), SET(87.0f));
    return splat_exp_poly8(x);
}

/* t = W m + t_cam for 8 means (one vector per coordinate). */
static inline void cam_point8(const pg_camera *cam, const V m[3], V t[3])
{
    const float *W = cam->R;
    for (int r = 0; r < 3; r++)
        t[r] = FMA(SET(W[3*r]), m[0], FMA(SET(W[3*r+1]), m[1], FMA(SET(W[3*r+2]), m[2], SET(cam->t[r]))));
}

/* What forward and backward both compute on the way to Sigma2D (8-lane twin of sigma16). */
typedef struct {
    V w, x, y, z, iq;        /* normalised quaternion (identity where zero) and 1/|q| (0 there) */
    V nz;                    /* all-ones in lanes with a non-zero quaternion */
    V R[9], sc[3], M[9];     /* R(q), exp(log_scale), M = R diag(sc) */
    V fx, fy, iz, u, v, uc, vc; /* focal lengths, 1/z, x/z and y/z before and after the clamp */
    V T0[3], T1[3], TC0[3], TC1[3]; /* rows of T = J W and of T cov */
    V sxx, sxy, syy;         /* Sigma2D plus the low-pass term */
} sigma8;

static inline void sigma2d8(const pg_camera *cam, const float lim[SPLAT_LIM_COUNT], const V t[3], const V ls[3],
                            const V q[4], sigma8 *S)
{
    const float *W = cam->R;
    const V one = SET(1.0f), two = SET(2.0f);
    V qn2 = FMA(q[0], q[0], FMA(q[1], q[1], FMA(q[2], q[2], MUL(q[3], q[3]))));
    S->nz = _mm256_cmp_ps(qn2, ZERO, _CMP_GT_OQ);
    S->iq = AND(S->nz, _mm256_div_ps(one, _mm256_sqrt_ps(qn2)));
    V w = S->w = BLEND(one, MUL(q[0], S->iq), S->nz);
    V x = S->x = MUL(q[1], S->iq), y = S->y = MUL(q[2], S->iq), z = S->z = MUL(q[3], S->iq);
    V *R = S->R;
    R[0] = _mm256_fnmadd_ps(two, FMA(y, y, MUL(z, z)), one);
    R[1] = MUL(two, FMS(x, y, MUL(w, z)));
    R[2] = MUL(two, FMA(x, z, MUL(w, y)));
    R[3] = MUL(two, FMA(x, y, MUL(w, z)));
    R[4] = _mm256_fnmadd_ps(two, FMA(x, x, MUL(z, z)), one);
    R[5] = MUL(two, FMS(y, z, MUL(w, x)));
    R[6] = MUL(two, FMS(x, z, MUL(w, y)));
    R[7] = MUL(two, FMA(y, z, MUL(w, x)));
    R[8] = _mm256_fnmadd_ps(two, FMA(x, x, MUL(y, y)), one);
    for (int k = 0; k < 3; k++) S->sc[k] = exp8(ls[k]);
    V *M = S->M, C[9];
    for (int i = 0; i < 3; i++)
        for (int k = 0; k < 3; k++) M[3*i+k] = MUL(R[3*i+k], S->sc[k]);
    for (int i = 0; i < 3; i++)
        for (int j = i; j < 3; j++) C[3*i+j] = C[3*j+i] = FMA(M[3*i], M[3*j], FMA(M[3*i+1], M[3*j+1], MUL(M[3*i+2], M[3*j+2])));
    S->iz = _mm256_div_ps(one, t[2]);
    S->u = MUL(t[0], S->iz);
    S->v = MUL(t[1], S->iz);
    S->uc = _mm256_min_ps(_mm256_max_ps(S->u, SET(lim[0])), SET(lim[1]));
    S->vc = _mm256_min_ps(_mm256_max_ps(S->v, SET(lim[2])), SET(lim[3]));
    S->fx = SET(cam->fx);
    S->fy = SET(cam->fy);
    V J00 = MUL(S->fx, S->iz), J02 = SUB(ZERO, MUL(MUL(S->fx, S->uc), S->iz));
    V J11 = MUL(S->fy, S->iz), J12 = SUB(ZERO, MUL(MUL(S->fy, S->vc), S->iz));
    V *T0 = S->T0, *T1 = S->T1, *TC0 = S->TC0, *TC1 = S->TC1;
    for (int j = 0; j < 3; j++) {
        T0[j] = FMA(J00, SET(W[j]), MUL(J02, SET(W[6+j])));
        T1[j] = FMA(J11, SET(W[3+j]), MUL(J12, SET(W[6+j])));
    }
    for (int j = 0; j < 3; j++) {
        TC0[j] = FMA(T0[0], C[j], FMA(T0[1], C[3+j], MUL(T0[2], C[6+j])));
        TC1[j] = FMA(T1[0], C[j], FMA(T1[1], C[3+j], MUL(T1[2], C[6+j])));
    }
    V lp = SET(lim[4]);
    S->sxx = ADD(FMA(TC0[0], T0[0], FMA(TC0[1], T0[1], MUL(TC0[2], T0[2]))), lp);
    S->sxy = FMA(TC0[0], T1[0], FMA(TC0[1], T1[1], MUL(TC0[2], T1[2])));
    S->syy = ADD(FMA(TC1[0], T1[0], FMA(TC1[1], T1[1], MUL(TC1[2], T1[2]))), lp);
}

/* all-ones in lane l where bit l of mask is set */
static inline V lanes_of(int mask)
{
    const __m256i bits = _mm256_and_si256(_mm256_set1_epi32(mask), _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128));
    return _mm256_castsi256_ps(_mm256_cmpgt_epi32(bits, _mm256_setzero_si256()));
}

/* Loads rows i0 .. i0+7 of a (N, stride) array, one vector per column (lanes off mask read fill). */
static inline void load_rows8(const float *base, int stride, int cols, int mask, float fill, V *out)
{
    const __m256i idx = _mm256_mullo_epi32(_mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7), _mm256_set1_epi32(stride));
    const V m = lanes_of(mask);
    for (int c = 0; c < cols; c++) out[c] = _mm256_mask_i32gather_ps(SET(fill), base + c, idx, m, 4);
}

/* Adds column vectors to rows i0 .. i0+7 of a (N, stride) array, lanes in mask only (AVX2 has no
 * scatter). */
static inline void add_rows8(float *base, int stride, int cols, int mask, const V *val)
{
    float tmp[4][8];
    for (int c = 0; c < cols; c++) _mm256_storeu_ps(tmp[c], val[c]);
    for (int l = 0; l < 8; l++)
        if (mask >> l & 1)
            for (int c = 0; c < cols; c++) base[(size_t)stride * l + c] += tmp[c][l];
}

static void forward8(const float *means, const float *log_scales, const float *quats, int i0, const pg_camera *cam,
                     const float lim[SPLAT_LIM_COUNT], float near_clip, float out[9][16], int h, unsigned *valid)
{
    V m[3], ls[3], q[4], t[3];
    load_rows8(means + 3 * (size_t)i0, 3, 3, 0xff, 0.0f, m);
    load_rows8(log_scales + 3 * (size_t)i0, 3, 3, 0xff, 0.0f, ls);
    load_rows8(quats + 4 * (size_t)i0, 4, 4, 0xff, 0.0f, q);
    cam_point8(cam, m, t);
    V ok = _mm256_cmp_ps(t[2], SET(near_clip), _CMP_GE_OQ);
    sigma8 S;
    sigma2d8(cam, lim, t, ls, q, &S);
    V one = SET(1.0f), sxx = S.sxx, sxy = S.sxy, syy = S.syy;
    V det = FMS(sxx, syy, MUL(sxy, sxy));
    ok = AND(ok, _mm256_cmp_ps(det, ZERO, _CMP_GT_OQ));
    V id = _mm256_div_ps(one, det);
    const int o = 8 * h;
    _mm256_storeu_ps(out[0] + o, FMA(MUL(S.fx, t[0]), S.iz, SET(cam->cx)));
    _mm256_storeu_ps(out[1] + o, FMA(MUL(S.fy, t[1]), S.iz, SET(cam->cy)));
    _mm256_storeu_ps(out[2] + o, t[2]);
    _mm256_storeu_ps(out[3] + o, sxx);
    _mm256_storeu_ps(out[4] + o, sxy);
    _mm256_storeu_ps(out[5] + o, syy);
    _mm256_storeu_ps(out[6] + o, MUL(syy, id));
    _mm256_storeu_ps(out[7] + o, SUB(ZERO, MUL(sxy, id)));
    _mm256_storeu_ps(out[8] + o, MUL(sxx, id));
    *valid |= (unsigned)_mm256_movemask_ps(ok) << o;
}

int splat_project_forward16_avx2(const float *means, const float *log_scales, const float *quats, int i0,
                                 const pg_camera *cam, const float lim[SPLAT_LIM_COUNT], float near_clip, float out[9][16],
                                 unsigned *valid)
{
    *valid = 0;
    for (int h = 0; h < 2; h++) forward8(means, log_scales, quats, i0 + 8 * h, cam, lim, near_clip, out, h, valid);
    return 1;
}

static void backward8(const float *means, const float *log_scales, const float *quats, int i0, const pg_camera *cam,
                      const float lim[SPLAT_LIM_COUNT], const float d_xy[2][16], const float d_conic[3][16],
                      const float d_z[16], int h, int km, float *d_means, float *d_log_scales, float *d_quats)
{
    const V one = SET(1.0f), two = SET(2.0f);
    const int o = 8 * h;
    V m[3], ls[3], q[4], t[3];
    load_rows8(means + 3 * (size_t)i0, 3, 3, km, 0.0f, m);
    load_rows8(log_scales + 3 * (size_t)i0, 3, 3, km, 0.0f, ls);
    load_rows8(quats + 4 * (size_t)i0, 4, 4, km, 1.0f, q);
    const V kmv = lanes_of(km);
    const float *W = cam->R;
    cam_point8(cam, m, t);
    t[2] = BLEND(one, t[2], kmv); /* unused lanes: keep the arithmetic tame */
    sigma8 S;
    sigma2d8(cam, lim, t, ls, q, &S);
    V iq = S.iq, w = S.w, x = S.x, y = S.y, z = S.z, fx = S.fx, fy = S.fy, iz = S.iz, uc = S.uc, vc = S.vc;
    const V *R = S.R, *sc = S.sc, *M = S.M, *T0 = S.T0, *T1 = S.T1, *TC0 = S.TC0, *TC1 = S.TC1;
    V sxx = S.sxx, sxy = S.sxy, syy = S.syy;
    V iz2 = MUL(iz, iz);
    V cfx = _mm256_cmp_ps(uc, S.u, _CMP_NEQ_UQ), cfy = _mm256_cmp_ps(vc, S.v, _CMP_NEQ_UQ);
    V id = _mm256_div_ps(one, FMS(sxx, syy, MUL(sxy, sxy)));
    V Qa = MUL(syy, id), Qb = SUB(ZERO, MUL(sxy, id)), Qc = MUL(sxx, id);
    V ga = _mm256_loadu_ps(d_conic[0] + o), gb = MUL(SET(0.5f), _mm256_loadu_ps(d_conic[1] + o));
    V gc = _mm256_loadu_ps(d_conic[2] + o);
    V QG00 = FMA(Qa, ga, MUL(Qb, gb)), QG01 = FMA(Qa, gb, MUL(Qb, gc));
    V QG10 = FMA(Qb, ga, MUL(Qc, gb)), QG11 = FMA(Qb, gb, MUL(Qc, gc));
    V G00 = SUB(ZERO, FMA(QG00, Qa, MUL(QG01, Qb)));
    V G01 = SUB(ZERO, FMA(QG00, Qb, MUL(QG01, Qc)));
    V G10 = SUB(ZERO, FMA(QG10, Qa, MUL(QG11, Qb)));
    V G11 = SUB(ZERO, FMA(QG10, Qb, MUL(QG11, Qc)));
    V dT0[3], dT1[3], u0[3], u1[3];
    for (int j = 0; j < 3; j++) {
        dT0[j] = MUL(two, FMA(G00, TC0[j], MUL(G01, TC1[j])));
        dT1[j] = MUL(two, FMA(G10, TC0[j], MUL(G11, TC1[j])));
        u0[j] = FMA(G00, T0[j], MUL(G01, T1[j]));
        u1[j] = FMA(G10, T0[j], MUL(G11, T1[j]));
    }
    V dC[9];
    for (int i = 0; i < 3; i++)
        for (int j = i; j < 3; j++) dC[3*i+j] = dC[3*j+i] = FMA(T0[i], u0[j], MUL(T1[i], u1[j]));
    V dR[9], dls[3];
    for (int k = 0; k < 3; k++) {
        V ds = ZERO;
        for (int i = 0; i < 3; i++) {
            V dM = MUL(two, FMA(dC[3*i], M[k], FMA(dC[3*i+1], M[3+k], MUL(dC[3*i+2], M[6+k]))));
            ds = FMA(dM, R[3*i+k], ds);
            dR[3*i+k] = MUL(dM, sc[k]);
        }
        dls[k] = MUL(ds, sc[k]);
    }
    V dq[4];
    dq[0] = MUL(two, ADD(ADD(FMS(y, dR[2], MUL(z, dR[1])), FMS(z, dR[3], MUL(x, dR[5]))), FMS(x, dR[7], MUL(y, dR[6]))));
    dq[1] = MUL(two, ADD(ADD(FMA(y, ADD(dR[1], dR[3]), MUL(z, ADD(dR[2], dR[6]))), MUL(w, SUB(dR[7], dR[5]))),
                         MUL(MUL(two, x), SUB(ZERO, ADD(dR[4], dR[8])))));
    dq[2] = MUL(two, ADD(ADD(FMA(x, ADD(dR[1], dR[3]), MUL(z, ADD(dR[5], dR[7]))), MUL(w, SUB(dR[2], dR[6]))),
                         MUL(MUL(two, y), SUB(ZERO, ADD(dR[0], dR[8])))));
    dq[3] = MUL(two, ADD(ADD(FMA(x, ADD(dR[2], dR[6]), MUL(y, ADD(dR[5], dR[7]))), MUL(w, SUB(dR[3], dR[1]))),
                         MUL(MUL(two, z), SUB(ZERO, ADD(dR[0], dR[4])))));
    V qq[4] = { w, x, y, z };
    V dot = FMA(dq[0], w, FMA(dq[1], x, FMA(dq[2], y, MUL(dq[3], z))));
    V dJ00 = ZERO, dJ02 = ZERO, dJ11 = ZERO, dJ12 = ZERO;
    for (int j = 0; j < 3; j++) {
        dJ00 = FMA(dT0[j], SET(W[j]), dJ00);
        dJ02 = FMA(dT0[j], SET(W[6+j]), dJ02);
        dJ11 = FMA(dT1[j], SET(W[3+j]), dJ11);
        dJ12 = FMA(dT1[j], SET(W[6+j]), dJ12);
    }
    V dxy0 = _mm256_loadu_ps(d_xy[0] + o), dxy1 = _mm256_loadu_ps(d_xy[1] + o);
    V fxi2 = MUL(fx, iz2), fyi2 = MUL(fy, iz2);
    V dt0 = MUL(MUL(fx, iz), dxy0), dt1 = MUL(MUL(fy, iz), dxy1);
    V dt2 = SUB(_mm256_loadu_ps(d_z + o), FMA(fxi2, dJ00, MUL(fyi2, dJ11)));
    dt2 = SUB(dt2, FMA(MUL(fxi2, t[0]), dxy0, MUL(MUL(fyi2, t[1]), dxy1)));
    /* x: clamped -> J02 = -fx uc / z (uc constant); free -> J02 = -fx x / z^2 */
    dt2 = BLEND(dt2, ADD(dt2, MUL(MUL(fxi2, uc), dJ02)), cfx);
    dt0 = BLEND(_mm256_fnmadd_ps(fxi2, dJ02, dt0), dt0, cfx);
    dt2 = BLEND(ADD(dt2, MUL(MUL(MUL(two, fxi2), MUL(t[0], iz)), dJ02)), dt2, cfx);
    dt2 = BLEND(dt2, ADD(dt2, MUL(MUL(fyi2, vc), dJ12)), cfy);
    dt1 = BLEND(_mm256_fnmadd_ps(fyi2, dJ12, dt1), dt1, cfy);
    dt2 = BLEND(ADD(dt2, MUL(MUL(MUL(two, fyi2), MUL(t[1], iz)), dJ12)), dt2, cfy);
    V dt[3] = { dt0, dt1, dt2 }, dm[3], g[4];
    for (int k = 0; k < 3; k++) dm[k] = FMA(SET(W[k]), dt[0], FMA(SET(W[3+k]), dt[1], MUL(SET(W[6+k]), dt[2])));
    add_rows8(d_means + 3 * (size_t)i0, 3, 3, km, dm);
    add_rows8(d_log_scales + 3 * (size_t)i0, 3, 3, km, dls);
    for (int c = 0; c < 4; c++) g[c] = MUL(_mm256_fnmadd_ps(dot, qq[c], dq[c]), iq);
    add_rows8(d_quats + 4 * (size_t)i0, 4, 4, km & _mm256_movemask_ps(S.nz), g);
}

int splat_project_backward16_avx2(const float *means, const float *log_scales, const float *quats, int i0,
                                  const pg_camera *cam, const float lim[SPLAT_LIM_COUNT], const float d_xy[2][16],
                                  const float d_conic[3][16], const float d_z[16], unsigned mask,
                                  float *d_means, float *d_log_scales, float *d_quats)
{
    for (int h = 0; h < 2; h++) {
        int km = (int)(mask >> (8 * h)) & 0xff;
        if (km)
            backward8(means, log_scales, quats, i0 + 8 * h, cam, lim, d_xy, d_conic, d_z, h, km, d_means,
                      d_log_scales, d_quats);
    }
    return 1;
}
#else
int splat_project_forward16_avx2(const float *means, const float *log_scales, const float *quats, int i0,
                                 const pg_camera *cam, const float lim[SPLAT_LIM_COUNT], float near_clip, float out[9][16],
                                 unsigned *valid)
{
    (void)means; (void)log_scales; (void)quats; (void)i0; (void)cam; (void)lim; (void)near_clip; (void)out;
    *valid = 0;
    return 0;
}

int splat_project_backward16_avx2(const float *means, const float *log_scales, const float *quats, int i0,
                                  const pg_camera *cam, const float lim[SPLAT_LIM_COUNT], const float d_xy[2][16],
                                  const float d_conic[3][16], const float d_z[16], unsigned mask,
                                  float *d_means, float *d_log_scales, float *d_quats)
{
    (void)means; (void)log_scales; (void)quats; (void)i0; (void)cam; (void)lim; (void)d_xy; (void)d_conic;
    (void)d_z; (void)mask; (void)d_means; (void)d_log_scales; (void)d_quats;
    return 0;
}
#endif
