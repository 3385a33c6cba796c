/* dataset.h - one API over multi-view / single-view video datasets.
 *
 * io_dataset_open auto-detects the layout of PATH:
 *  - DyNeRF / Neural 3D Video: DIR/poses_bounds.npy (N x 17) + DIR/camXX.mp4 (any video
 *    container) or DIR/camXX/images/NNNN.png (or DIR/camXX/ holding frames), N cameras in
 *    natural name order matching the rows.
 *  - Dynamic3DGaussians / CMU Panoptic: DIR/train_meta.json and/or DIR/test_meta.json with
 *    w, h, k[t][c] (3x3), w2c[t][c] (4x4), fn[t][c] (paths under DIR/ims/), cam_id[t][c].
 *  - A single video file or a folder of frames: one static camera at the identity pose with
 *    intrinsics from options.fov_deg (horizontal, default 60) or options.focal (pixels of the
 *    source frames).
 * All poses are OpenCV world-to-camera (x right, y down, z forward). Frames decode lazily the
 * first time a camera is asked for, and stay cached (uint8) until io_dataset_release.
 *
 *   io_dataset_options o = io_dataset_defaults();
 *   o.max_side = 480;
 *   pg_dataset *ds;
 *   PG_TRY(io_dataset_open("data/coffee_martini", &o, &ds));
 *   pg_camera cam;
 *   io_dataset_camera(ds, 0, &cam);
 *   pg_image img;
 *   PG_TRY(io_dataset_frame(ds, 0, 10, &img));   // camera 0, frame 10 (float RGB)
 *   pg_image_destroy(&img);
 *   io_dataset_close(ds);
 */
#ifndef PG_DATASET_H
#define PG_DATASET_H

#include "core/camera.h"
#include "core/image.h"

typedef struct pg_dataset pg_dataset;

typedef enum { IO_DATASET_DYNERF = 0, IO_DATASET_PANOPTIC, IO_DATASET_VIDEO, IO_DATASET_FOLDER, IO_DATASET_KIND_COUNT } io_dataset_kind;

typedef struct {
    int width, height;  /* resize every camera's frames (0 = keep; one alone keeps the aspect) */
    int max_side;       /* or shrink so the longer side <= max_side */
    int first, count, stride; /* frame selection (count 0 = all frames every camera has) */
    float fov_deg;      /* single video/folder: horizontal field of view (default 60) */
    float focal;        /* single video/folder: focal length in source pixels (overrides fov) */
    double fps;         /* fps for frame folders / Panoptic (default 30) */
} io_dataset_options;

io_dataset_options io_dataset_defaults(void);

/* Detects the layout and reads metadata (poses, sizes, frame counts); no frames are decoded.
 * Fails naming the file on an unknown layout, malformed poses or missing camera sources. */
pg_status io_dataset_open(const char *path, const io_dataset_options *opt, pg_dataset **ds);
/* Frees everything; accepts NULL. */
void io_dataset_close(pg_dataset *ds);

io_dataset_kind io_dataset_get_kind(const pg_dataset *ds);
const char *io_dataset_kind_name(io_dataset_kind kind); /* "dynerf", "panoptic", "video", "folder" */
int io_dataset_num_cameras(const pg_dataset *ds);
const char *io_dataset_camera_name(const pg_dataset *ds, int cam);
/* Index of the camera with this name, or -1. */
int io_dataset_find_camera(const pg_dataset *ds, const char *name);
/* The one rule every option that names a camera follows (--train-cam, --test-cams, --real-cams,
 * --camera): a token equal to a camera name means that camera; otherwise a plain integer is an
 * index. Anything else fails (PG_ERR_ARG) with a message listing the camera names. On Panoptic
 * data names are numbers out of index order, so the name must win. */
pg_status io_dataset_resolve_camera(const pg_dataset *ds, const char *token, int *index);
/* A comma-separated list of such tokens; *count gets how many (at most max, no duplicates). */
pg_status io_dataset_resolve_cameras(const pg_dataset *ds, const char *list, int *out, int max, int *count);
/* "cam00 (index 0)" for messages and reports. */
void io_dataset_camera_label(const pg_dataset *ds, int cam, char *out, size_t size);
/* "train" / "test" for Panoptic cameras (from which meta file they came), "" otherwise. */
const char *io_dataset_camera_role(const pg_dataset *ds, int cam);
/* Camera (intrinsics scaled to the output frame size) at the first selected frame. */
void io_dataset_camera(const pg_dataset *ds, int cam, pg_camera *out);
/* Camera at selected frame t (Panoptic stores one per frame; the others are static). */
void io_dataset_camera_at(const pg_dataset *ds, int cam, int t, pg_camera *out);
/* Scene depth bounds of a camera (DyNeRF poses_bounds); 0, 0 when the layout has none. */
void io_dataset_near_far(const pg_dataset *ds, int cam, float *near_z, float *far_z);
/* Number of selected frames (the same for every camera). */
int io_dataset_num_frames(const pg_dataset *ds);
double io_dataset_fps(const pg_dataset *ds);
/* Output frame size (after resize). */
int io_dataset_width(const pg_dataset *ds);
int io_dataset_height(const pg_dataset *ds);
/* Size of the source frames (before resize). */
int io_dataset_source_width(const pg_dataset *ds);
int io_dataset_source_height(const pg_dataset *ds);
/* Changes the size frames are decoded at (decoded frames are dropped), e.g. once a consumer
 * knows it needs less than the source: the decoder's scaler resizes, no full-size copy is kept. */
void io_dataset_set_frame_size(pg_dataset *ds, int width, int height);
/* Where camera cam's frames come from (video file, frame folder, or the Panoptic ims/ folder). */
const char *io_dataset_camera_source(const pg_dataset *ds, int cam);
/* Selected frame t of camera cam as a new float (H, W, 3) image. Decodes and caches the camera. */
pg_status io_dataset_frame(pg_dataset *ds, int cam, int t, pg_image *img);
/* Drops the decoded frames of one camera (cam < 0: all cameras). */
void io_dataset_release(pg_dataset *ds, int cam);

/* LLFF pose (3x5 row-major [R | t | hwf] with R's columns the camera's down/right/back axes in
 * world coordinates, t the camera centre) to an OpenCV camera of size hwf (width = hwf[1]). */
void io_llff_to_camera(const float P[15], pg_camera *cam);

#endif
