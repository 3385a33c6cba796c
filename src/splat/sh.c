/* sh.c - spherical harmonics colour and its backward (basis and basis gradient in one place). */
#include "splat/sh.h"

#include <math.h>
#include <stddef.h>

static const float SH_C1 = 0.4886025119029199f;
static const float SH_C2[5] = { 1.0925484305920792f, -1.0925484305920792f, 0.31539156525252005f,
                                -1.0925484305920792f, 0.5462742152960396f };
static const float SH_C3[7] = { -0.5900435899266435f, 2.890611442640554f, -0.4570457994644658f,
                                0.3731763325901154f, -0.4570457994644658f, 1.445305721320277f,
                                -0.5900435899266435f };

/* Basis Y (16) at unit direction (x, y, z) and, if grad != NULL, dY/d(x, y, z) (16, 3)
 * treating x, y, z as independent (the normalisation is chained separately). */
static int sh_basis(int degree, float x, float y, float z, float Y[16], float grad[48])
{
    int n = (degree + 1) * (degree + 1);
    Y[0] = SPLAT_SH_C0;
    if (grad) for (int i = 0; i < 48; i++) grad[i] = 0;
    if (degree >= 1) {
        Y[1] = -SH_C1 * y; Y[2] = SH_C1 * z; Y[3] = -SH_C1 * x;
        if (grad) { grad[3*1+1] = -SH_C1; grad[3*2+2] = SH_C1; grad[3*3+0] = -SH_C1; }
    }
    if (degree >= 2) {
        float xx = x*x, yy = y*y, zz = z*z, xy = x*y, yz = y*z, xz = x*z;
        Y[4] = SH_C2[0] * xy;
        Y[5] = SH_C2[1] * yz;
        Y[6] = SH_C2[2] * (2*zz - xx - yy);
        Y[7] = SH_C2[3] * xz;
        Y[8] = SH_C2[4] * (xx - yy);
        if (grad) {
            grad[12] = SH_C2[0]*y;    grad[13] = SH_C2[0]*x;
            grad[16] = SH_C2[1]*z;    grad[17] = SH_C2[1]*y;
            grad[18] = -2*SH_C2[2]*x; grad[19] = -2*SH_C2[2]*y; grad[20] = 4*SH_C2[2]*z;
            grad[21] = SH_C2[3]*z;    grad[23] = SH_C2[3]*x;
            grad[24] = 2*SH_C2[4]*x;  grad[25] = -2*SH_C2[4]*y;
        }
        if (degree >= 3) {
            Y[9]  = SH_C3[0] * y * (3*xx - yy);
            Y[10] = SH_C3[1] * xy * z;
            Y[11] = SH_C3[2] * y * (4*zz - xx - yy);
            Y[12] = SH_C3[3] * z * (2*zz - 3*xx - 3*yy);
            Y[13] = SH_C3[4] * x * (4*zz - xx - yy);
            Y[14] = SH_C3[5] * z * (xx - yy);
            Y[15] = SH_C3[6] * x * (xx - 3*yy);
            if (grad) {
                grad[27] = 6*SH_C3[0]*xy;           grad[28] = SH_C3[0]*(3*xx - 3*yy);
                grad[30] = SH_C3[1]*yz;             grad[31] = SH_C3[1]*xz;   grad[32] = SH_C3[1]*xy;
                grad[33] = -2*SH_C3[2]*xy;          grad[34] = SH_C3[2]*(4*zz - xx - 3*yy); grad[35] = 8*SH_C3[2]*yz;
                grad[36] = -6*SH_C3[3]*xz;          grad[37] = -6*SH_C3[3]*yz; grad[38] = SH_C3[3]*(6*zz - 3*xx - 3*yy);
                grad[39] = SH_C3[4]*(4*zz - 3*xx - yy); grad[40] = -2*SH_C3[4]*xy; grad[41] = 8*SH_C3[4]*xz;
                grad[42] = 2*SH_C3[5]*xz;           grad[43] = -2*SH_C3[5]*yz; grad[44] = SH_C3[5]*(xx - yy);
                grad[45] = SH_C3[6]*(3*xx - 3*yy);  grad[46] = -6*SH_C3[6]*xy;
            }
        }
    }
    return n;
}

void splat_sh_forward_dir(int degree, const float *sh, const float dir[3], float rgb[3], int clamped[3])
{
    float inv = 1.0f / sqrtf(dir[0]*dir[0] + dir[1]*dir[1] + dir[2]*dir[2] + 1e-30f);
    float Y[16];
    int n = sh_basis(degree, dir[0]*inv, dir[1]*inv, dir[2]*inv, Y, NULL);
    for (int c = 0; c < 3; c++) {
        float v = 0.5f;
        for (int k = 0; k < n; k++) v += Y[k] * sh[3*k + c];
        clamped[c] = v < 0;
        rgb[c] = v < 0 ? 0 : v;
    }
}

void splat_sh_backward_dir(int degree, const float *sh, const float dir[3], const int clamped[3],
                           const float d_rgb[3], float *d_sh, float d_dir[3])
{
    float len = sqrtf(dir[0]*dir[0] + dir[1]*dir[1] + dir[2]*dir[2] + 1e-30f), inv = 1.0f / len;
    float n3[3] = { dir[0]*inv, dir[1]*inv, dir[2]*inv };
    float Y[16], G[48];
    int n = sh_basis(degree, n3[0], n3[1], n3[2], Y, degree > 0 ? G : NULL);
    float g[3];
    for (int c = 0; c < 3; c++) g[c] = clamped[c] ? 0.0f : d_rgb[c];
    float dn[3] = { 0, 0, 0 };
    for (int k = 0; k < n; k++) {
        float s = 0;
        for (int c = 0; c < 3; c++) {
            d_sh[3*k + c] += Y[k] * g[c];
            s += sh[3*k + c] * g[c];
        }
        if (k > 0) for (int a = 0; a < 3; a++) dn[a] += s * G[3*k + a];
    }
    if (degree == 0) return;
    /* n = d / |d|: dn/dd = (I - n n^T) / |d|. */
    float proj = dn[0]*n3[0] + dn[1]*n3[1] + dn[2]*n3[2];
    for (int a = 0; a < 3; a++) d_dir[a] += (dn[a] - proj * n3[a]) * inv;
}
