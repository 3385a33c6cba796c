/* depth_check.h - plausibility checks on a user's depth before the method trusts it. */
#ifndef PG_DEPTH_CHECK_H
#define PG_DEPTH_CHECK_H

/* Share of frames (0..1) whose depth grows DOWN the image: rank correlation between the row
 * index and the row's mean depth > 0.3. In almost every real shot the bottom of the frame is
 * nearer than the top (floor, table, ground), so depth falls with the row index; when most frames
 * say the opposite the file is probably disparity (inverse depth) read as depth. Samples up to 32
 * frames; rows with fewer than 10 % valid pixels are skipped. depth: (F, H, W), <= 0 or NaN invalid. */
double depth_share_inverted_frames(const float *depth, int frames, int width, int height);

#endif
