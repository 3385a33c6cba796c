/* holes.h - fills a proxy view's disocclusion holes from the background side.
 *
 * A proxy camera beside the real one sees, next to every foreground edge, a strip of surface the
 * real camera never saw. Masked out, those strips get no supervision from any view, no Gaussian
 * ever lands there, and every novel view shows them as black wedges beside the objects (0.9 % of
 * the held-out pixels of tabletop_dev at 13-15 dB). What hides there is almost always the surface
 * behind the object, so each hole run bounded by valid pixels on both sides (a row first, then a
 * column, whose runs may end on the row pass's fills) takes the colour and depth of its FARTHER
 * end, or the blend of both ends where they lie on one surface, and a reduced training weight,
 * like the outpainted margin: a plausible guess the trainer may overrule, not an observation.
 * Runs longer than max_run pixels stay holes.
 */
#ifndef PG_PROXY_HOLES_H
#define PG_PROXY_HOLES_H

/* rgb (H,W,3), depth (H,W), mask (H,W): 0 = hole, else valid; filled pixels get mask = weight.
 * scratch: W*H bytes. Returns the number of pixels filled. */
long proxy_fill_holes(int width, int height, float *rgb, float *depth, unsigned char *mask, int max_run,
                      unsigned char weight, unsigned char *scratch);

#endif
