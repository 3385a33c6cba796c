/* sh.h - real spherical harmonics colour (degree 0..3), forward and backward.
 *
 * rgb[c] = max(0, sum_k sh[k][c] * Y_k(d / |d|) + 0.5), d = mean - camera centre.
 * Constants and basis order follow the 3DGS reference.
 */
#ifndef PG_SH_H
#define PG_SH_H

#define SPLAT_SH_C0 0.28209479177387814f /* Y_0^0: colour = 0.5 + SPLAT_SH_C0 * DC coefficient */

/* sh (16, 3); dir (3) unnormalised view direction. clamped[c] = 1 where the max(0, .) clamps. */
void splat_sh_forward(int degree, const float *sh, const float dir[3], float rgb[3], int clamped[3]);
/* Adds the gradients of rgb (d_rgb, before the clamp mask is applied) into d_sh (16, 3) and
 * d_dir (3, unnormalised direction). Clamped channels pass no gradient. */
void splat_sh_backward(int degree, const float *sh, const float dir[3], const int clamped[3],
                       const float d_rgb[3], float *d_sh, float d_dir[3]);

#endif
