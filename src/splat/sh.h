/* sh.h - real spherical harmonics colour (degree 0..3), forward and backward.
 *
 * rgb[c] = max(0, sum_k sh[k][c] * Y_k(d / |d|) + 0.5), d = mean - camera centre.
 * Constants and basis order follow the 3DGS reference.
 */
#ifndef PG_SH_H
#define PG_SH_H

#define SPLAT_SH_C0 0.28209479177387814f /* Y_0^0: colour = 0.5 + SPLAT_SH_C0 * DC coefficient */

/* Degrees 1-3 (sh.c); splat_sh_forward / _backward below are what callers use. */
void splat_sh_forward_dir(int degree, const float *sh, const float dir[3], float rgb[3], int clamped[3]);
void splat_sh_backward_dir(int degree, const float *sh, const float dir[3], const int clamped[3],
                           const float d_rgb[3], float *d_sh, float d_dir[3]);

/* sh (16, 3); dir (3) unnormalised view direction. clamped[c] = 1 where the max(0, .) clamps.
 * Degree 0 (a constant colour, what a single-camera run trains) is inline: it runs for every
 * Gaussian of every rendered view, where a call cost more than the colour. */
static inline void splat_sh_forward(int degree, const float *sh, const float dir[3], float rgb[3], int clamped[3])
{
    if (degree > 0) {
        splat_sh_forward_dir(degree, sh, dir, rgb, clamped);
        return;
    }
    for (int c = 0; c < 3; c++) {
        float v = 0.5f + SPLAT_SH_C0 * sh[c];
        clamped[c] = v < 0;
        rgb[c] = v < 0 ? 0 : v;
    }
}

/* Adds the gradients of rgb (d_rgb, before the clamp mask is applied) into d_sh (16, 3) and
 * d_dir (3, unnormalised direction). Clamped channels pass no gradient. */
static inline void splat_sh_backward(int degree, const float *sh, const float dir[3], const int clamped[3],
                                     const float d_rgb[3], float *d_sh, float d_dir[3])
{
    if (degree > 0) {
        splat_sh_backward_dir(degree, sh, dir, clamped, d_rgb, d_sh, d_dir);
        return;
    }
    for (int c = 0; c < 3; c++) d_sh[c] += clamped[c] ? 0.0f : SPLAT_SH_C0 * d_rgb[c];
}

#endif
