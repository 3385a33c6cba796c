/* video.h - read frames from a video file or a folder of images; write H.264 MP4.
 *
 * Reading decodes any container/codec Debian's FFmpeg libraries handle (libavformat +
 * libavcodec, converted to RGB24 with libswscale), or a folder of PNG/JPEG frames sorted
 * by name (natural order: "f2" < "f10"). A rotation tag (display matrix, as phones write) is
 * applied, so frames come out upright as players show them. Frames are kept as uint8 RGB to save memory and
 * converted to float pg_image on demand:
 *
 *   io_video_options opt = io_video_defaults();
 *   opt.first = 10; opt.count = 40; opt.stride = 2; opt.max_side = 480;
 *   io_frames fr;
 *   PG_TRY(io_frames_read("cam00.mp4", &opt, &fr));
 *   pg_image img;
 *   PG_TRY(io_frames_image(&fr, 0, &img));   // float (H, W, 3) in [0,1]
 *   ...
 *   pg_image_destroy(&img);
 *   io_frames_destroy(&fr);
 *
 * Writing: io_video_writer_open / _add / _close stream frames into an H.264 (libx264, crf)
 * yuv420p MP4 written to a temporary file and renamed into place on close. Odd sizes are
 * padded by one replicated row/column (yuv420p needs even sizes). When no H.264 encoder can
 * be opened it falls back to MPEG-4 part 2 and then to a PNG sequence in the folder
 * "<path minus extension>_frames/"; `fallback` in the writer tells the caller (the library
 * never prints).
 */
#ifndef PG_VIDEO_H
#define PG_VIDEO_H

#include <stdint.h>
#include "core/image.h"

typedef struct {
    int first;     /* first frame index to keep (0-based, in decode order) */
    int count;     /* number of frames to keep; 0 = all that remain. Asking for more than exist fails. */
    int stride;    /* keep every stride-th frame from first (>= 1) */
    int width;     /* resize target; 0 = keep. One of width/height alone keeps the aspect ratio */
    int height;
    int max_side;  /* if > 0 and no width/height given: shrink so the longer side <= max_side */
    double folder_fps; /* fps reported for image folders (default 30) */
} io_video_options;

io_video_options io_video_defaults(void);

typedef struct {
    int is_folder;
    int width, height;   /* source size as displayed (after the rotation tag) */
    int rotation;        /* clockwise degrees from the display matrix, applied when reading */
    int frames;          /* frame count (exact for folders; header or duration estimate for video) */
    int frames_exact;    /* 1 when `frames` was counted or read from the container index, 0 if estimated */
    double fps;
    double duration;     /* seconds, 0 if unknown */
    char codec[32];      /* "h264", "png", ... */
    char container[32];  /* "mov,mp4,m4a,3gp,3g2,mj2", "folder" */
} io_video_info;

typedef struct {
    int count;           /* frames held */
    int width, height;   /* size of the held frames (after resize) */
    int src_width, src_height;
    double fps;          /* of the source (not divided by stride) */
    uint8_t *rgb;        /* (count, height, width, 3) */
} io_frames;

/* Cheap look at a video or folder: size, fps, frame count, codec. Counts folder images exactly;
 * for video uses the container's frame count, else duration x fps (then frames_exact = 0). */
pg_status io_video_probe(const char *path, io_video_info *info);
/* Counts a video's frames exactly by demuxing every packet (no decoding). */
pg_status io_video_count_frames(const char *path, int *frames);
/* Decodes the selected frames (see io_video_options) of a video file or image folder.
 * Fails naming the file on a missing, garbled or truncated input, or when fewer frames
 * exist than requested. out is empty on failure. */
pg_status io_frames_read(const char *path, const io_video_options *opt, io_frames *out);
void io_frames_destroy(io_frames *fr);
/* Frame i as a new float (H, W, 3) image in [0,1]. */
pg_status io_frames_image(const io_frames *fr, int i, pg_image *img);
/* The resize target io_frames_read would use for a source of src_w x src_h. */
void io_video_target_size(const io_video_options *opt, int src_w, int src_h, int *w, int *h);
/* Lists the PNG/JPEG files of a folder in natural name order. names is a malloc'd array of
 * malloc'd full paths (free with io_free_names). Fails if the folder has none. */
pg_status io_list_images(const char *dir, char ***names, int *count);
void io_free_names(char **names, int count);
/* Sorts paths by their file names in natural order ("f2" < "f10"). */
void io_sort_names(char **names, int count);

/* ---- writing ---- */

typedef enum { IO_VIDEO_H264 = 0, IO_VIDEO_MPEG4, IO_VIDEO_PNG_SEQUENCE } io_video_backend;

typedef struct io_video_writer io_video_writer;

typedef struct {
    double fps;     /* default 30 */
    int crf;        /* x264 constant rate factor, 0 = default 18 (lower = better) */
    int force_png;  /* write a PNG sequence even if an encoder exists */
} io_video_write_options;

io_video_write_options io_video_write_defaults(void);

/* Opens a writer for width x height frames. *backend says what will be written; when it is
 * not IO_VIDEO_H264 the caller should warn the user (fallback_path names what is written). */
pg_status io_video_writer_open(io_video_writer **w, const char *path, int width, int height,
                               const io_video_write_options *opt);
/* Appends one frame: a 3-channel (or 1-channel, shown as grey) float image of the opened size. */
pg_status io_video_writer_add(io_video_writer *w, const pg_image *frame);
/* Flushes and renames into place. Frees the writer (also on failure). */
pg_status io_video_writer_close(io_video_writer *w);
/* Frees the writer and removes partial output without committing. Accepts NULL. */
void io_video_writer_abort(io_video_writer *w);
io_video_backend io_video_writer_backend(const io_video_writer *w);
/* One-shot helper: writes count frames. *backend (may be NULL) gets the backend used. */
pg_status io_video_write(const char *path, const pg_image *frames, int count, const io_video_write_options *opt,
                         io_video_backend *backend);

#endif
