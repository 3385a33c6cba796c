/* fuse.h - one depth per static pixel: the temporal median over the frames where it is static.
 *
 * A static camera sees the same static surface in every frame, but a monocular network's depth
 * of it wobbles from frame to frame (low-frequency shape changes that a per-frame scale/shift
 * cannot absorb). Left in, the wobble becomes geometry that moves: proxies of the background
 * shift from frame to frame and the 4D model blurs them. On tabletop_dev's simulated mono depth
 * the per-frame error on static pixels is 1.9 % after alignment; the temporal median has 0.7 %
 * (the frame-to-frame correlation of the error is about -0.1). */
#ifndef PG_DEPTH_FUSE_H
#define PG_DEPTH_FUSE_H

#include <stddef.h>

/* depth (F, n): aligned depth, 0 = invalid; static_masks (F, n): 1 = static in that frame. Each
 * pixel static and valid in at least min_frames frames gets its median over those frames in
 * each of them; other frames and pixels are unchanged. Returns the number of pixels fused, -1 when
 * out of memory. */
long depth_fuse_static(float *depth, const unsigned char *static_masks, int frames, size_t n, int min_frames);

/* ref (n): each pixel's median over the frames where it is static with valid depth, 0 where it has
 * fewer than min_frames such frames. Returns the number of pixels given a value, -1 when out of
 * memory. */
long depth_static_reference(const float *depth, const unsigned char *static_masks, int frames, size_t n,
                            int min_frames, float *ref);

#endif
