/* image.h - float images, (H, W, C) row-major, values as stored (sRGB in [0,1]). */
#ifndef PG_IMAGE_H
#define PG_IMAGE_H

#include "core/status.h"

typedef struct {
    int width, height, channels;
    float *data; /* (height, width, channels) */
} pg_image;

/* Largest image side accepted from any file or option (guards absurd headers). */
#define PG_MAX_IMAGE_SIDE 16384

/* Allocates a zeroed image; img is left empty on failure. */
pg_status pg_image_create(pg_image *img, int width, int height, int channels);
/* Frees the pixels; accepts an empty or already destroyed image. */
void pg_image_destroy(pg_image *img);
pg_status pg_image_copy(pg_image *dst, const pg_image *src);
static inline float *pg_image_at(const pg_image *img, int x, int y)
{
    return img->data + ((size_t)y * img->width + x) * img->channels;
}
/* Bilinear resample to a new size (area-weighted when shrinking by >2x). */
pg_status pg_image_resize(pg_image *dst, const pg_image *src, int width, int height);
/* Peak signal-to-noise ratio over all channels (pixels with mask <= 0.5 skipped if mask given). */
double pg_image_psnr(const pg_image *a, const pg_image *b, const float *mask);
/* The image as (H, W, 3) bytes (out holds W*H*3): rounded, clamped to [0, 255]; one channel is
 * repeated into three. What the byte-based moving-pixel masks (depth/moving_mask.h) take. */
void pg_image_to_rgb8(const pg_image *img, unsigned char *out);
/* Piecewise-linear colour ramp through n >= 2 evenly spaced RGB stops, at s in [0, 1] (clamped). */
void pg_color_ramp(const float (*stops)[3], int n, float s, float rgb[3]);

#endif
