/* colormap.h - false-colour images of depth for people to look at. */
#ifndef PG_COLORMAP_H
#define PG_COLORMAP_H

#include "core/image.h"

/* Colours depth (H, W) into rgb (an allocated W x H x 3 image): near = warm, far = cool,
 * invalid (<= 0 or non-finite) = black. lo/hi <= 0: use the 2nd/98th percentile of valid depth. */
pg_status render_depth_colormap(const float *depth, int width, int height, float lo, float hi, pg_image *rgb);

#endif
