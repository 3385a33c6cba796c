/* splat_ref.h - double-precision reference of the rasterizer forward for tests (projection,
 * SH colour, brute-force per-pixel compositing with the same rules as the tile kernels).
 * Header-only so several test programs can include it. */
#ifndef PG_SPLAT_REF_H
#define PG_SPLAT_REF_H

#include "core/camera.h"
#include "splat/gaussians.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* One Gaussian in double: mean 3, log_scale 3, quat 4, opacity logit 1, sh 48 = 59 values. */
#define REF_NP 59
enum { REF_MEAN = 0, REF_SCALE = 3, REF_QUAT = 6, REF_OPAC = 10, REF_SH = 11 };

static void ref_pack(const pg_gaussians *g, int i, double *p)
{
    for (int k = 0; k < 3; k++) p[REF_MEAN + k] = g->means[3*i + k];
    for (int k = 0; k < 3; k++) p[REF_SCALE + k] = g->log_scales[3*i + k];
    for (int k = 0; k < 4; k++) p[REF_QUAT + k] = g->quats[4*i + k];
    p[REF_OPAC] = g->opacity[i];
    for (int k = 0; k < 48; k++) p[REF_SH + k] = g->sh[48*i + k];
}

static double ref_grad_of(const pg_gaussians *gr, int i, int k)
{
    if (k < 3) return gr->means[3*i + k];
    if (k < 6) return gr->log_scales[3*i + k - 3];
    if (k < 10) return gr->quats[4*i + k - 6];
    if (k < 11) return gr->opacity[i];
    return gr->sh[48*i + k - 11];
}

/* xy, conic (a, b, c), z of the projection; returns 0 when culled. */
static int ref_project(const double *p, const pg_camera *cam, double xy[2], double conic[3], double *z, double cov2d[3])
{
    double t[3];
    for (int r = 0; r < 3; r++)
        t[r] = cam->R[3*r]*p[0] + cam->R[3*r+1]*p[1] + cam->R[3*r+2]*p[2] + cam->t[r];
    if (t[2] < 0.01) return 0;
    const double *q0 = p + REF_QUAT;
    double qn = sqrt(q0[0]*q0[0] + q0[1]*q0[1] + q0[2]*q0[2] + q0[3]*q0[3]);
    double w = q0[0]/qn, x = q0[1]/qn, y = q0[2]/qn, zq = q0[3]/qn;
    double R[9] = { 1 - 2*(y*y + zq*zq), 2*(x*y - w*zq), 2*(x*zq + w*y),
                    2*(x*y + w*zq), 1 - 2*(x*x + zq*zq), 2*(y*zq - w*x),
                    2*(x*zq - w*y), 2*(y*zq + w*x), 1 - 2*(x*x + y*y) };
    double s[3] = { exp(p[REF_SCALE]), exp(p[REF_SCALE+1]), exp(p[REF_SCALE+2]) };
    double M[9], cov[9];
    for (int i = 0; i < 3; i++) for (int k = 0; k < 3; k++) M[3*i+k] = R[3*i+k] * s[k];
    for (int i = 0; i < 3; i++) for (int j = 0; j < 3; j++) cov[3*i+j] = M[3*i]*M[3*j] + M[3*i+1]*M[3*j+1] + M[3*i+2]*M[3*j+2];
    double fx = cam->fx, fy = cam->fy;
    double x0 = -cam->cx / fx, x1 = (cam->width - cam->cx) / fx, y0 = -cam->cy / fy, y1 = (cam->height - cam->cy) / fy;
    double lx0 = x0 - 0.15*(x1 - x0), lx1 = x1 + 0.15*(x1 - x0), ly0 = y0 - 0.15*(y1 - y0), ly1 = y1 + 0.15*(y1 - y0);
    double u = t[0]/t[2], v = t[1]/t[2];
    u = u < lx0 ? lx0 : (u > lx1 ? lx1 : u);
    v = v < ly0 ? ly0 : (v > ly1 ? ly1 : v);
    double J[6] = { fx/t[2], 0, -fx*u/t[2], 0, fy/t[2], -fy*v/t[2] };
    double T[6], TC[6];
    for (int r = 0; r < 2; r++) for (int j = 0; j < 3; j++)
        T[3*r+j] = J[3*r]*cam->R[j] + J[3*r+1]*cam->R[3+j] + J[3*r+2]*cam->R[6+j];
    for (int r = 0; r < 2; r++) for (int j = 0; j < 3; j++)
        TC[3*r+j] = T[3*r]*cov[j] + T[3*r+1]*cov[3+j] + T[3*r+2]*cov[6+j];
    double a = TC[0]*T[0] + TC[1]*T[1] + TC[2]*T[2] + 0.1;
    double b = TC[0]*T[3] + TC[1]*T[4] + TC[2]*T[5];
    double c = TC[3]*T[3] + TC[4]*T[4] + TC[5]*T[5] + 0.1;
    double det = a*c - b*b;
    conic[0] = c/det; conic[1] = -b/det; conic[2] = a/det;
    if (cov2d) { cov2d[0] = a; cov2d[1] = b; cov2d[2] = c; }
    xy[0] = fx*t[0]/t[2] + cam->cx;
    xy[1] = fy*t[1]/t[2] + cam->cy;
    *z = t[2];
    return 1;
}

static void ref_sh(int deg, const double *sh, const double dir[3], double rgb[3])
{
    const double C0 = 0.28209479177387814, C1 = 0.4886025119029199;
    const double C2[5] = { 1.0925484305920792, -1.0925484305920792, 0.31539156525252005, -1.0925484305920792, 0.5462742152960396 };
    const double C3[7] = { -0.5900435899266435, 2.890611442640554, -0.4570457994644658, 0.3731763325901154,
                           -0.4570457994644658, 1.445305721320277, -0.5900435899266435 };
    double n = sqrt(dir[0]*dir[0] + dir[1]*dir[1] + dir[2]*dir[2]);
    double x = dir[0]/n, y = dir[1]/n, z = dir[2]/n;
    double Y[16] = { C0 };
    if (deg >= 1) { Y[1] = -C1*y; Y[2] = C1*z; Y[3] = -C1*x; }
    if (deg >= 2) {
        double xx = x*x, yy = y*y, zz = z*z;
        Y[4] = C2[0]*x*y; Y[5] = C2[1]*y*z; Y[6] = C2[2]*(2*zz - xx - yy); Y[7] = C2[3]*x*z; Y[8] = C2[4]*(xx - yy);
        if (deg >= 3) {
            Y[9] = C3[0]*y*(3*xx - yy); Y[10] = C3[1]*x*y*z; Y[11] = C3[2]*y*(4*zz - xx - yy);
            Y[12] = C3[3]*z*(2*zz - 3*xx - 3*yy); Y[13] = C3[4]*x*(4*zz - xx - yy);
            Y[14] = C3[5]*z*(xx - yy); Y[15] = C3[6]*x*(xx - 3*yy);
        }
    }
    int nb = (deg + 1) * (deg + 1);
    for (int c = 0; c < 3; c++) {
        double v = 0.5;
        for (int k = 0; k < nb; k++) v += Y[k] * sh[3*k + c];
        rgb[c] = v < 0 ? 0 : v;
    }
}

/* Renders n Gaussians (params (n, REF_NP)) into rgb (H,W,3), depth, alpha in double. */
static void ref_render(const double *params, int n, int deg, const pg_camera *cam, const double bg[3],
                       double *rgb, double *depth, double *alpha)
{
    int W = cam->width, H = cam->height;
    double *xy = malloc(sizeof(double) * 2 * n), *con = malloc(sizeof(double) * 3 * n);
    double *zz = malloc(sizeof(double) * n), *op = malloc(sizeof(double) * n), *col = malloc(sizeof(double) * 3 * n);
    int *ok = malloc(sizeof(int) * n), *ord = malloc(sizeof(int) * n);
    double C[3];
    float Cf[3];
    pg_camera_center(cam, Cf);
    for (int k = 0; k < 3; k++) C[k] = Cf[k];
    for (int i = 0; i < n; i++) {
        const double *p = params + (size_t)REF_NP * i;
        ok[i] = ref_project(p, cam, xy + 2*i, con + 3*i, zz + i, NULL);
        op[i] = 1.0 / (1.0 + exp(-p[REF_OPAC]));
        double dir[3] = { p[0] - C[0], p[1] - C[1], p[2] - C[2] };
        ref_sh(deg, p + REF_SH, dir, col + 3*i);
        ord[i] = i;
    }
    for (int i = 1; i < n; i++) /* stable insertion sort by depth */
        for (int j = i; j > 0 && zz[ord[j]] < zz[ord[j-1]]; j--) { int t = ord[j]; ord[j] = ord[j-1]; ord[j-1] = t; }
    for (int py = 0; py < H; py++)
        for (int px = 0; px < W; px++) {
            double T = 1, Cc[3] = { 0, 0, 0 }, D = 0;
            for (int k = 0; k < n; k++) {
                int i = ord[k];
                if (!ok[i] || op[i] < 1.0 / 255) continue;
                double dx = px + 0.5 - xy[2*i], dy = py + 0.5 - xy[2*i+1];
                double sig = 0.5 * (con[3*i]*dx*dx + con[3*i+2]*dy*dy) + con[3*i+1]*dx*dy;
                double a = op[i] * exp(-sig);
                if (a > 0.99) a = 0.99;
                if (a < 1.0 / 255) continue;
                double tT = T * (1 - a);
                if (tT < 1e-4) break;
                for (int c = 0; c < 3; c++) Cc[c] += col[3*i+c] * a * T;
                D += zz[i] * a * T;
                T = tT;
            }
            size_t q = (size_t)py * W + px;
            for (int c = 0; c < 3; c++) rgb[3*q+c] = Cc[c] + T * bg[c];
            depth[q] = D;
            alpha[q] = 1 - T;
        }
    free(xy); free(con); free(zz); free(op); free(col); free(ok); free(ord);
}

#endif
