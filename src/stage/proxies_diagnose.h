/* proxies_diagnose.h - scores proxies rendered at dataset cameras against those cameras' real
 * frames (`prodygs proxies --diagnose`). */
#ifndef PG_STAGE_PROXIES_DIAGNOSE_H
#define PG_STAGE_PROXIES_DIAGNOSE_H

#include "core/camera.h"
#include "core/status.h"
#include "io/dataset.h"

typedef struct {
    int views;                /* proxies scored (those named like a dataset camera) */
    double psnr_reprojected;  /* pooled over every scored view and frame; NaN without pixels */
    double psnr_guessed;
    double psnr_moving;
} proxies_diagnosis;

/* For each of the M proxies in the training-set directory dir (names, poses cams; real: the real
 * camera) that is a dataset camera: PSNR of its frames against that camera's real frames over the
 * pixels its mask marks as reprojected (weight 1), as guessed (margin, filled holes: weight 0.5)
 * and over the camera's own moving pixels (eval's definition) that the proxy covers. Writes
 * dir/diagnose.json (per view and pooled, with each class's share of the pixels) and
 * dir/vis/diagnose_NAME_NNNN.png (real | proxy | error) at the first, middle and last frame. */
pg_status stage_proxies_diagnose(pg_dataset *ds, const char *dir, const pg_camera *real, int M, const char *const *names,
                                 const pg_camera *cams, int F, int W, int H, proxies_diagnosis *out);

#endif
