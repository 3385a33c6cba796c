/* scene_cameras.h - the cameras a trained model was made with (from a trainset.json).
 *
 * Renders need the real camera (paths swing around it), the scene centre (paths look at it)
 * and, for dataset-cam paths and evaluation, the named cameras. They are read from the
 * training-set description (docs/FORMATS.md) that `prodygs proxies` wrote.
 */
#ifndef PG_SCENE_CAMERAS_H
#define PG_SCENE_CAMERAS_H

#include "core/camera.h"
#include "core/status.h"
#include "io/trainset.h"

#define RENDER_MAX_CAMERAS 256


typedef struct {
    int count, real;                        /* real: index of the real camera */
    pg_camera cams[RENDER_MAX_CAMERAS];
    char names[RENDER_MAX_CAMERAS][32];
    io_view_role roles[RENDER_MAX_CAMERAS];
    float center[3];                        /* what camera paths look at */
    int frames;
    double fps;
} scene_cameras;

/* Loads path (a trainset.json file or a directory holding one). */
pg_status scene_cameras_load(const char *path, scene_cameras *sc);
/* Finds a model's cameras: explicit (may be NULL), MODEL/cameras.json, MODEL/trainset.json. */
pg_status scene_cameras_for_model(const char *model, const char *explicit_path, scene_cameras *sc);
int scene_cameras_find(const scene_cameras *sc, const char *name);

#endif
