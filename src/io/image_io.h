/* image_io.h - load and save float RGB images as PNG or JPEG. */
#ifndef PG_IMAGE_IO_H
#define PG_IMAGE_IO_H

#include "core/image.h"

/* Loads a PNG or JPEG (chosen by the file's magic bytes) as 3-channel float in [0,1]. */
pg_status io_image_load(const char *path, pg_image *img);
/* Saves 1- or 3-channel float images (clamped to [0,1]) as 8-bit PNG, atomically. */
pg_status io_image_save_png(const char *path, const pg_image *img);
/* Saves a 3-channel float image as JPEG with the given quality (1-100), atomically. */
pg_status io_image_save_jpeg(const char *path, const pg_image *img, int quality);

#endif
