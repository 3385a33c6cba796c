/* project.c - EWA projection forward and backward (chain: conic <- Sigma2D <- J, Sigma <- R(q), S). */
#include "splat/project.h"
#include "core/mathx.h"
#include "splat/raster_kernels.h"

#include <math.h>

/* Frustum limits of x/z (y/z) widened by 15% of the view width on each side: 1.3x the half-width
 * for a centred principal point; then the screen-space filter. */
void splat_project_limits(const pg_camera *cam, float lowpass, float lim[SPLAT_LIM_COUNT])
{
    float x0 = -cam->cx / cam->fx, x1 = (cam->width - cam->cx) / cam->fx;
    float y0 = -cam->cy / cam->fy, y1 = (cam->height - cam->cy) / cam->fy;
    lim[0] = x0 - 0.15f * (x1 - x0); lim[1] = x1 + 0.15f * (x1 - x0);
    lim[2] = y0 - 0.15f * (y1 - y0); lim[3] = y1 + 0.15f * (y1 - y0);
    lim[4] = lowpass;
}

/* Sigma = M M^T with M = R(q/|q|) diag(exp(log_scale)); also returns R and the scales. */
static void cov3d_forward(const float log_scale[3], const float quat[4], float Rq[9], float s[3], float M[9], float cov[9])
{
    float qn = sqrtf(quat[0]*quat[0] + quat[1]*quat[1] + quat[2]*quat[2] + quat[3]*quat[3]);
    float inv = qn > 0 ? 1.0f / qn : 0.0f;
    float q[4] = { quat[0]*inv, quat[1]*inv, quat[2]*inv, quat[3]*inv };
    if (qn == 0) q[0] = 1;
    quat_to_mat3(Rq, q);
    for (int k = 0; k < 3; k++) s[k] = expf(log_scale[k]);
    for (int i = 0; i < 3; i++)
        for (int k = 0; k < 3; k++) M[3*i+k] = Rq[3*i+k] * s[k];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) cov[3*i+j] = M[3*i]*M[3*j] + M[3*i+1]*M[3*j+1] + M[3*i+2]*M[3*j+2];
}

/* J (2x3, row-major) for camera point t; clamp flags say which of x/z, y/z hit the limits. */
static void jacobian(const pg_camera *cam, const float lim[SPLAT_LIM_COUNT], const float t[3], float J[6], int clampflag[2], float uv_c[2])
{
    float z = t[2], iz = 1.0f / z, u = t[0] * iz, w = t[1] * iz;
    float uc = clampf(u, lim[0], lim[1]), wc = clampf(w, lim[2], lim[3]);
    clampflag[0] = uc != u;
    clampflag[1] = wc != w;
    uv_c[0] = uc; uv_c[1] = wc;
    J[0] = cam->fx * iz; J[1] = 0; J[2] = -cam->fx * uc * iz;
    J[3] = 0; J[4] = cam->fy * iz; J[5] = -cam->fy * wc * iz;
}

/* Everything the forward computes on the way to Sigma2D, kept for the backward. */
typedef struct {
    float Rq[9], s[3], M[9], cov[9]; /* 3D covariance factors (cov3d_forward) */
    float J[6], uvc[2];              /* projection Jacobian and clamped x/z, y/z */
    int cf[2];                       /* which of x/z, y/z were clamped */
    float Tm[6], TC[6];              /* T = J W (2x3) and T cov (2x3) */
    float sxx, sxy, syy;             /* Sigma2D = T cov T^T plus the low-pass term */
} sigma2d_state;

/* Sigma2D of a Gaussian whose mean is at camera point t (shared by forward and backward). */
static void sigma2d_forward(const float log_scale[3], const float quat[4], const pg_camera *cam, const float lim[SPLAT_LIM_COUNT],
                            const float t[3], sigma2d_state *S)
{
    cov3d_forward(log_scale, quat, S->Rq, S->s, S->M, S->cov);
    jacobian(cam, lim, t, S->J, S->cf, S->uvc);
    const float *J = S->J, *cov = S->cov;
    float *Tm = S->Tm, *TC = S->TC;
    for (int r = 0; r < 2; r++)
        for (int j = 0; j < 3; j++)
            Tm[3*r+j] = J[3*r]*cam->R[j] + J[3*r+1]*cam->R[3+j] + J[3*r+2]*cam->R[6+j];
    for (int r = 0; r < 2; r++)
        for (int j = 0; j < 3; j++)
            TC[3*r+j] = Tm[3*r]*cov[j] + Tm[3*r+1]*cov[3+j] + Tm[3*r+2]*cov[6+j];
    S->sxx = TC[0]*Tm[0] + TC[1]*Tm[1] + TC[2]*Tm[2] + lim[4];
    S->sxy = TC[0]*Tm[3] + TC[1]*Tm[4] + TC[2]*Tm[5];
    S->syy = TC[3]*Tm[3] + TC[4]*Tm[4] + TC[5]*Tm[5] + lim[4];
}

int splat_project_forward(const float mean[3], const float log_scale[3], const float quat[4],
                          const pg_camera *cam, float near_clip, splat_proj *p)
{
    float lim[SPLAT_LIM_COUNT];
    splat_project_limits(cam, SPLAT_LOWPASS, lim);
    return splat_project_forward_lim(mean, log_scale, quat, cam, lim, near_clip, p);
}

int splat_project_forward_lim(const float mean[3], const float log_scale[3], const float quat[4],
                              const pg_camera *cam, const float lim[SPLAT_LIM_COUNT], float near_clip, splat_proj *p)
{
    float t[3];
    mat3_mul_vec(t, cam->R, mean);
    vec3_add(t, t, cam->t);
    if (!(t[2] >= near_clip)) return 0;
    sigma2d_state S;
    sigma2d_forward(log_scale, quat, cam, lim, t, &S);
    float sxx = S.sxx, sxy = S.sxy, syy = S.syy;
    float det = sxx * syy - sxy * sxy;
    if (!(det > 0)) return 0;
    float id = 1.0f / det;
    p->xy[0] = cam->fx * t[0] / t[2] + cam->cx;
    p->xy[1] = cam->fy * t[1] / t[2] + cam->cy;
    p->z = t[2];
    p->cov2d[0] = sxx; p->cov2d[1] = sxy; p->cov2d[2] = syy;
    p->conic[0] = syy * id; p->conic[1] = -sxy * id; p->conic[2] = sxx * id;
    return 1;
}

void splat_project_backward(const float mean[3], const float log_scale[3], const float quat[4],
                            const pg_camera *cam, const float d_xy[2], const float d_conic[3], float d_z,
                            float d_mean[3], float d_log_scale[3], float d_quat[4])
{
    float lim[SPLAT_LIM_COUNT];
    splat_project_limits(cam, SPLAT_LOWPASS, lim);
    splat_project_backward_lim(mean, log_scale, quat, cam, lim, d_xy, d_conic, d_z, d_mean, d_log_scale, d_quat);
}

void splat_project_backward_lim(const float mean[3], const float log_scale[3], const float quat[4],
                                const pg_camera *cam, const float lim[SPLAT_LIM_COUNT], const float d_xy[2],
                                const float d_conic[3], float d_z, float d_mean[3], float d_log_scale[3],
                                float d_quat[4])
{
    float t[3];
    mat3_mul_vec(t, cam->R, mean);
    vec3_add(t, t, cam->t);
    sigma2d_state S;
    sigma2d_forward(log_scale, quat, cam, lim, t, &S);
    const float *Rq = S.Rq, *s = S.s, *M = S.M, *Tm = S.Tm, *TC = S.TC, *uvc = S.uvc;
    const int *cf = S.cf;
    float sxx = S.sxx, sxy = S.sxy, syy = S.syy;
    float id = 1.0f / (sxx * syy - sxy * sxy);
    /* Conic Q = Sigma2D^-1 as a symmetric matrix; the off-diagonal b appears twice in
     * 0.5 d^T Q d, so dL/dQ01 = dL/db / 2. dL/dSigma2D = -Q G Q. */
    float Q[4] = { syy * id, -sxy * id, -sxy * id, sxx * id };
    float Gq[4] = { d_conic[0], 0.5f * d_conic[1], 0.5f * d_conic[1], d_conic[2] };
    float QG[4] = { Q[0]*Gq[0] + Q[1]*Gq[2], Q[0]*Gq[1] + Q[1]*Gq[3],
                    Q[2]*Gq[0] + Q[3]*Gq[2], Q[2]*Gq[1] + Q[3]*Gq[3] };
    float Gs[4] = { -(QG[0]*Q[0] + QG[1]*Q[2]), -(QG[0]*Q[1] + QG[1]*Q[3]),
                    -(QG[2]*Q[0] + QG[3]*Q[2]), -(QG[2]*Q[1] + QG[3]*Q[3]) };
    /* Sigma2D = T cov T^T: dL/dT = 2 Gs T cov (Gs symmetric), dL/dcov = T^T Gs T. */
    float dT[6];
    for (int r = 0; r < 2; r++)
        for (int j = 0; j < 3; j++)
            dT[3*r+j] = 2 * (Gs[2*r] * TC[j] + Gs[2*r+1] * TC[3+j]);
    /* dcov = T^T Gs T is symmetric, so d(M M^T)/dM gives dM = 2 dcov M. */
    float u0[3], u1[3];
    for (int j = 0; j < 3; j++) { u0[j] = Gs[0]*Tm[j] + Gs[1]*Tm[3+j]; u1[j] = Gs[2]*Tm[j] + Gs[3]*Tm[3+j]; }
    float dcov[9];
    for (int i = 0; i < 3; i++)
        for (int j = i; j < 3; j++) dcov[3*i+j] = dcov[3*j+i] = Tm[i] * u0[j] + Tm[3+i] * u1[j];
    float dM[9];
    for (int i = 0; i < 3; i++)
        for (int k = 0; k < 3; k++)
            dM[3*i+k] = 2 * (dcov[3*i]*M[k] + dcov[3*i+1]*M[3+k] + dcov[3*i+2]*M[6+k]);
    /* M = Rq diag(s). */
    float dR[9];
    for (int k = 0; k < 3; k++) {
        float ds = 0;
        for (int i = 0; i < 3; i++) { ds += dM[3*i+k] * Rq[3*i+k]; dR[3*i+k] = dM[3*i+k] * s[k]; }
        d_log_scale[k] += ds * s[k];
    }
    /* R(q) for unit q = (w, x, y, z), then project out the normalisation. */
    float qn = sqrtf(quat[0]*quat[0] + quat[1]*quat[1] + quat[2]*quat[2] + quat[3]*quat[3]);
    if (qn > 0) {
        float iq = 1.0f / qn;
        float q[4] = { quat[0]*iq, quat[1]*iq, quat[2]*iq, quat[3]*iq };
        float w = q[0], x = q[1], y = q[2], z = q[3];
        float dq[4];
        dq[0] = 2 * (-z*dR[1] + y*dR[2] + z*dR[3] - x*dR[5] - y*dR[6] + x*dR[7]);
        dq[1] = 2 * (y*dR[1] + z*dR[2] + y*dR[3] - 2*x*dR[4] - w*dR[5] + z*dR[6] + w*dR[7] - 2*x*dR[8]);
        dq[2] = 2 * (-2*y*dR[0] + x*dR[1] + w*dR[2] + x*dR[3] + z*dR[5] - w*dR[6] + z*dR[7] - 2*y*dR[8]);
        dq[3] = 2 * (-2*z*dR[0] - w*dR[1] + x*dR[2] + w*dR[3] - 2*z*dR[4] + y*dR[5] + x*dR[6] + y*dR[7]);
        float dot = dq[0]*q[0] + dq[1]*q[1] + dq[2]*q[2] + dq[3]*q[3];
        for (int i = 0; i < 4; i++) d_quat[i] += (dq[i] - dot * q[i]) * iq;
    }
    /* T = J W: dL/dJ = dT W^T. */
    const float *W = cam->R;
    float dJ[6];
    for (int r = 0; r < 2; r++)
        for (int k = 0; k < 3; k++)
            dJ[3*r+k] = dT[3*r]*W[3*k] + dT[3*r+1]*W[3*k+1] + dT[3*r+2]*W[3*k+2];
    /* J entries in terms of t; a clamped x/z (y/z) is a constant u: J02 = -fx u / z. */
    float z = t[2], iz = 1.0f / z, iz2 = iz * iz;
    float fx = cam->fx, fy = cam->fy;
    float dt[3] = { 0, 0, 0 };
    dt[2] += -fx * iz2 * dJ[0] - fy * iz2 * dJ[4];
    if (cf[0]) dt[2] += fx * uvc[0] * iz2 * dJ[2];
    else { dt[0] += -fx * iz2 * dJ[2]; dt[2] += 2 * fx * t[0] * iz2 * iz * dJ[2]; }
    if (cf[1]) dt[2] += fy * uvc[1] * iz2 * dJ[5];
    else { dt[1] += -fy * iz2 * dJ[5]; dt[2] += 2 * fy * t[1] * iz2 * iz * dJ[5]; }
    /* Projected mean and depth. */
    dt[0] += fx * iz * d_xy[0];
    dt[1] += fy * iz * d_xy[1];
    dt[2] += -fx * t[0] * iz2 * d_xy[0] - fy * t[1] * iz2 * d_xy[1] + d_z;
    float dm[3];
    mat3_tmul_vec(dm, cam->R, dt);
    vec3_add(d_mean, d_mean, dm);
}

