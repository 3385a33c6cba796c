/* outpaint.h - extends an RGB-D frame beyond its borders so proxy views have no empty margins.
 *
 * A proxy camera turned away from the real one sees past the real frame's border. Without help
 * those regions render as empty background and every novel view gets black wedges, which costs far
 * more PSNR than any blur. The frame is therefore padded by `pad` pixels on each side:
 *   - depth: inverse depth is continued linearly from a least-squares fit over the last `fit_px`
 *     pixels of each row (left/right) and then each column (top/bottom, corners included). Inverse
 *     depth is affine in the image coordinates on a plane, so walls, floors and tables continue
 *     exactly; the slope is smoothed along the border and the result clamped to the frame's range.
 *   - colour: the border colours, box-averaged along the border over a window that widens with the
 *     distance from the border, i.e. an increasingly blurred continuation (the least-squares guess
 *     for content nobody saw).
 *
 *   int W2 = W + 2 * pad, H2 = H + 2 * pad;
 *   proxy_outpaint(W, H, rgb, depth, pad, rgb2, depth2);      // rgb2 (H2,W2,3), depth2 (H2,W2)
 *
 * The interior is copied unchanged (invalid depth stays 0); margin pixels whose border had no valid
 * depth nearby get depth 0.
 */
#ifndef PG_PROXY_OUTPAINT_H
#define PG_PROXY_OUTPAINT_H

#include "core/status.h"

/* rgb (H,W,3), depth (H,W) with 0 = invalid -> rgb_out (H+2p, W+2p, 3), depth_out (H+2p, W+2p). */
pg_status proxy_outpaint(int width, int height, const float *rgb, const float *depth, int pad, float *rgb_out,
                         float *depth_out);

#endif
