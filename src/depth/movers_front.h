/* movers_front.h - a moving object is in front of the still scene it covers.
 *
 * A static camera sees each still surface in the frames where nothing passes in front of it, so
 * the prepared depth knows that surface's depth at every pixel a mover later covers (the temporal
 * median, fuse.h). A monocular network does not: on real footage it can put a person as far as
 * the wall behind the floor he stands on (PyDNet++ on Panoptic camera 10), and a proxy of that
 * frame then draws him on the wall. A mover seen against a surface cannot be behind it, so each
 * moving blob whose depth lies behind the surface it covers is brought toward the camera, whole
 * (one factor per blob keeps its shape), until nearly all of it is in front. Blobs already in
 * front (a ball in the air, a hand before the body) are left alone.
 *
 *   long moved = depth_movers_in_front(depth, static_masks, background, F, W, H, &params);
 */
#ifndef PG_DEPTH_MOVERS_FRONT_H
#define PG_DEPTH_MOVERS_FRONT_H

typedef struct {
    int min_area;     /* smallest blob in pixels (default 0.1 % of the image, at least 16) */
    float quantile;   /* fraction of a blob's pixels allowed to stay behind (default 0.03) */
    float tolerance;  /* relative depth noise ignored (default 0.05: behind by < 5 % is in front) */
    int window;       /* a blob's factor is the median over the blobs overlapping it within this
                         many frames before and after (default 3) */
} depth_movers_front_params;

void depth_movers_front_defaults(depth_movers_front_params *p, int width, int height);

/* depth (F, H*W): prepared depth, 0 = invalid, changed in place on moving blobs; still (F, H*W):
 * the static masks, 1 = still in that frame (the blobs are the 4-connected groups of the other
 * pixels); background (H*W): the still scene's depth per pixel, 0 = unknown. A blob's pixel
 * nearer the still depth seen there (background, else its median over the frames the pixel is
 * still, else the blob's median background) than the mover's keeps its depth: the ring of background a dilated mask puts around the
 * mover. Returns the number of blobs moved, -1 when out of memory. */
long depth_movers_in_front(float *depth, const unsigned char *still, const float *background, int frames, int width,
                           int height, const depth_movers_front_params *p);

#endif
