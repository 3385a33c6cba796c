/* image_io.h - load and save float RGB images as PNG or JPEG. */
#ifndef PG_IMAGE_IO_H
#define PG_IMAGE_IO_H

#include <stdint.h>

#include "core/image.h"

/* Loads a PNG or JPEG (chosen by the file's magic bytes) as 3-channel float in [0,1]. A 16-bit
 * PNG's samples are divided by 65535, as for 8 bits by 255 (the same colours as its 8-bit
 * version: no linear-light conversion); grey is repeated, alpha dropped. */
pg_status io_image_load(const char *path, pg_image *img);
/* A PNG's raw samples, as the file stores them (no gamma or colour-space conversion): palettes
 * expanded to RGB, bit depths below 8 to 8; maxval 255 or 65535. */
typedef struct {
    int width, height, channels, maxval;
    uint16_t *samples; /* (height, width, channels), malloc'd */
} io_png_samples;
pg_status io_png_read_samples(const char *path, io_png_samples *out);
/* Saves 1- or 3-channel float images (clamped to [0,1]) as 8-bit PNG, atomically. */
pg_status io_image_save_png(const char *path, const pg_image *img);
/* Saves a 3-channel float image as JPEG with the given quality (1-100), atomically. */
pg_status io_image_save_jpeg(const char *path, const pg_image *img, int quality);

#endif
