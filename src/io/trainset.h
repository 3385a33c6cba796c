/* trainset.h - the training-set format (docs/FORMATS.md): its directory layout, trainset.json
 * writer and the one role enum every reader of the format uses.
 *
 *   DIR/trainset.json
 *   DIR/<camera>/rgb/0000.png      DIR/<camera>/mask/0000.png      DIR/<camera>/depth.npy
 *   (a proxy's rgb frames are 0000.jpg)
 *
 * Depth stored here is in the pose units of the cameras (aligned depth times pose_scale).
 */
#ifndef PG_IO_TRAINSET_H
#define PG_IO_TRAINSET_H

#include "core/camera.h"
#include "core/status.h"

/* What a camera of a training set is for: the input video, a virtual view rendered from it, or a
 * held-out camera that training never sees. */
typedef enum { IO_ROLE_REAL = 0, IO_ROLE_PROXY, IO_ROLE_TEST } io_view_role;

typedef struct {
    char name[64];
    pg_camera cam;
    io_view_role role;
    int has_rgb;   /* DIR/<name>/rgb/NNNN.png written */
    int has_mask;  /* DIR/<name>/mask/NNNN.png written */
    int has_depth; /* DIR/<name>/depth.npy written */
} io_trainset_camera;

typedef struct {
    int frames, width, height;
    double fps;
    float center[3], radius, near, far; /* "scene" */
    const char *input, *depth;          /* "source" paths (may be NULL) */
    float pose_scale;                   /* pose units per value of the source depth file */
    float pose_shift;                   /* with it: pose depth = pose_scale * d / (1 + pose_shift * d) */
    const char *pose_fit;               /* how they were found (NULL: not recorded) */
    double unit;                        /* the user's length per length of the set (0 or 1: the same) */
} io_trainset_info;

const char *io_view_role_name(io_view_role role);
/* "real", "proxy" or "test" -> role; -1 for anything else. */
int io_view_role_parse(const char *name);

/* out = DIR/<camera>/<kind>/NNNN.png (kind "rgb" or "mask"). */
pg_status io_trainset_frame_path(char *out, size_t size, const char *dir, const char *camera, const char *kind,
                           int frame);
/* The same with another extension: proxies' rgb frames are "jpg" (rendered approximations, where
 * JPEG's error is far below the proxy's own and the files are 4x smaller). */
pg_status io_trainset_frame_path_ext(char *out, size_t size, const char *dir, const char *camera, const char *kind,
                                     int frame, const char *ext);

/* Creates DIR/<camera>/rgb and DIR/<camera>/mask. */
pg_status io_trainset_make_dirs(const char *dir, const char *camera, int with_mask);

/* Writes DIR/trainset.json atomically. */
pg_status io_trainset_write_json(const char *dir, const io_trainset_info *info, const io_trainset_camera *cams, int n);
/* The same layout under another name (a model's cameras.json: cameras without image paths). */
pg_status io_trainset_write_json_named(const char *dir, const char *file, const io_trainset_info *info,
                                       const io_trainset_camera *cams, int n);

#endif
