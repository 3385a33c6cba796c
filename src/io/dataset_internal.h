/* dataset_internal.h - the pg_dataset structure shared by the layout loaders (not public). */
#ifndef PG_DATASET_INTERNAL_H
#define PG_DATASET_INTERNAL_H

#include "io/dataset.h"
#include "io/video.h"

typedef struct {
    char name[64];
    char role[8];
    char source[4096];   /* video file or frame folder; Panoptic: DIR/ims */
    char **frame_paths;  /* Panoptic: (frames) image paths of the selected frames, else NULL */
    pg_camera *cams;     /* (frames) for Panoptic, else (1); at the SOURCE image size */
    int num_cams;
    float near_z, far_z;
    io_frames cache;     /* decoded selected frames (uint8), count 0 until first use */
} ds_camera;

struct pg_dataset {
    io_dataset_kind kind;
    char path[4096];
    io_dataset_options opt;
    int num_cams;
    ds_camera *cams;     /* (num_cams) */
    int frames;          /* selected frames */
    int first, stride;   /* selection in source frame indices */
    double fps;
    int src_width, src_height; /* source frame size (all cameras) */
    int internal_size;         /* the size is a stage's own (io_dataset_set_frame_size), not the user's --size */
    int width, height;         /* output size */
};

/* Allocates n zeroed cameras. */
pg_status ds_alloc_cameras(pg_dataset *ds, int n);
/* Applies first/count/stride to `available` source frames; sets ds->frames/first/stride. */
pg_status ds_select_frames(pg_dataset *ds, const char *what, int available);
/* Sets src and output size (from options) and checks every camera's source size agrees. */
void ds_set_sizes(pg_dataset *ds, int src_w, int src_h);

pg_status ds_open_dynerf(pg_dataset *ds);
pg_status ds_open_panoptic(pg_dataset *ds);

#endif
