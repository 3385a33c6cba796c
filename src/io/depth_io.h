/* depth_io.h - per-frame depth maps from .npy / .pfm / 16-bit .png / .exr, and PFM output.
 *
 * A depth input is either one .npy holding (F,H,W), (H,W), (F,H,W,1) or (F,1,H,W) (any dtype),
 * or a folder of per-frame files (.npy, .pfm, .png, .exr, natural name order). Values are
 * multiplied by `scale`; with kind DISPARITY they are then inverted (depth = 1 / value).
 * NaN, inf and values <= 0 become 0 (= invalid) and are counted.
 *
 *   io_depth_options o = io_depth_defaults();
 *   o.width = 320; o.height = 240;     // resize to the frame size
 *   o.expect_frames = frames.count;     // fail on a shape mismatch
 *   io_depth d;
 *   PG_TRY(io_depth_load("depth.npy", &o, &d));
 *   float z = d.data[((size_t)t * d.height + y) * d.width + x];
 *   io_depth_destroy(&d);
 */
#ifndef PG_DEPTH_IO_H
#define PG_DEPTH_IO_H

#include <stddef.h>
#include "core/status.h"
#include "io/npy.h"

typedef enum { IO_DEPTH_KIND_DEPTH = 0, IO_DEPTH_KIND_DISPARITY } io_depth_kind;

typedef struct {
    io_depth_kind kind;
    float scale;          /* raw value multiplier (e.g. 0.001 for millimetre PNGs); default 1 */
    int width, height;    /* resize to this size (the frame size); 0 = keep */
    int bilinear;         /* resize by bilinear interpolation over valid pixels (default: nearest) */
    int first, count, stride; /* frame selection, as in io_video_options (count 0 = all) */
    int expect_frames;    /* > 0: fail unless exactly this many frames are selected */
    float max_aspect_error; /* resize only if aspect ratios agree within this fraction (default 0.05) */
} io_depth_options;

io_depth_options io_depth_defaults(void);
/* Parses "depth" / "disparity" (the --depth-kind flag); fails naming the bad value. */
pg_status io_depth_kind_parse(const char *text, io_depth_kind *kind);

typedef struct {
    int frames, width, height;  /* after selection and resize */
    int src_width, src_height;  /* as stored */
    int src_frames;             /* frames available in the input */
    float *data;                /* (frames, height, width) z-depth, 0 = invalid */
    size_t invalid;             /* pixels that were NaN/inf/<=0 in the input (before resize) */
    size_t total;               /* pixels examined (before resize) */
    float min, max;             /* over valid pixels (0, 0 if none) */
} io_depth;

/* Loads and converts a depth input (file or folder). Fails naming the file on bad content,
 * unsupported layout, or a frame count / aspect that does not match the options. */
pg_status io_depth_load(const char *path, const io_depth_options *opt, io_depth *out);
void io_depth_destroy(io_depth *d);

/* Single-image readers, all giving a (H, W) float32 array (top row first). */
pg_status io_pfm_load(const char *path, pg_array *arr);   /* Pf (grey); PF (colour) keeps channel 0 */
pg_status io_png16_load(const char *path, pg_array *arr); /* 8/16-bit grey (or first channel), raw integer values */
/* OpenEXR scanline images, uncompressed / RLE / ZIPS / ZIP, HALF/FLOAT/UINT channels. Picks the
 * channel Z, then *.Z, then Y, then R, then the only channel. Tiled / multi-part / deep files fail. */
pg_status io_exr_load(const char *path, pg_array *arr);
/* Any of the above chosen by extension (.npy/.pfm/.png/.exr) as (H, W) (a leading 1 is dropped). */
pg_status io_depth_load_image(const char *path, pg_array *arr);
/* Writes a little-endian PFM ("Pf" for 1 channel, "PF" for 3), bottom row first as the format wants. */
pg_status io_pfm_save(const char *path, const float *data, int width, int height, int channels);

/* Resizes one (h, w) depth map to (dh, dw): nearest, or bilinear that ignores invalid (0) samples. */
void io_depth_resize(float *dst, int dw, int dh, const float *src, int w, int h, int bilinear);

#endif
