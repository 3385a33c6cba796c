/* trainset.h - the training-set directory written by `prodygs proxies` (docs/FORMATS.md).
 *
 *   DIR/trainset.json
 *   DIR/<camera>/rgb/0000.png      DIR/<camera>/mask/0000.png      DIR/<camera>/depth.npy
 *
 * Depth stored here is in the pose units of the cameras (aligned depth times pose_scale).
 */
#ifndef PG_PROXY_TRAINSET_H
#define PG_PROXY_TRAINSET_H

#include "core/camera.h"
#include "core/status.h"

typedef enum { PROXY_ROLE_REAL, PROXY_ROLE_PROXY, PROXY_ROLE_TEST } proxy_role;

typedef struct {
    char name[64];
    pg_camera cam;
    proxy_role role;
    int has_rgb;   /* DIR/<name>/rgb/NNNN.png written */
    int has_mask;  /* DIR/<name>/mask/NNNN.png written */
    int has_depth; /* DIR/<name>/depth.npy written */
} proxy_trainset_camera;

typedef struct {
    int frames, width, height;
    double fps;
    float center[3], radius, near, far; /* "scene" */
    const char *input, *depth;          /* "source" paths (may be NULL) */
    float pose_scale;
} proxy_trainset_info;

const char *proxy_role_name(proxy_role role);

/* out = DIR/<camera>/<kind>/NNNN.png (kind "rgb" or "mask"). */
pg_status proxy_frame_path(char *out, size_t size, const char *dir, const char *camera, const char *kind,
                           int frame);

/* Creates DIR/<camera>/rgb and DIR/<camera>/mask. */
pg_status proxy_trainset_make_dirs(const char *dir, const char *camera, int with_mask);

/* Writes DIR/trainset.json atomically. */
pg_status proxy_trainset_write_json(const char *dir, const proxy_trainset_info *info,
                                    const proxy_trainset_camera *cams, int n);

#endif
