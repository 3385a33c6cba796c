/* proxies_diagnose.c - `prodygs proxies --diagnose`: how close is each proxy to what its camera
 * really recorded? With dataset poses every proxy sits at a dataset camera, so its frames can be
 * scored against that camera's real frames before any training (issue 26): a change to the proxies
 * (depth, mesh, masks, hole filling) is judged in seconds instead of by a full `eval`. */
#include "stage/proxies_diagnose.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "core/fileutil.h"
#include "core/progress.h"
#include "eval/metrics.h"
#include "eval/protocol.h"
#include "eval/report.h"
#include "io/image_io.h"
#include "io/json.h"
#include "io/trainset.h"
#include "proxy/poses.h"

/* Mask weights at or above this are reprojections of what the real camera saw (255); between 0 and
 * this, plausible guesses (outpainted margin, filled holes: 128); 0 is invalid (docs/FORMATS.md). */
#define DIAG_REPROJECTED 0.75f

/* Adds one pixel's squared RGB error to a region (eval's pooled-PSNR sums; SSIM unused here). */
static void diag_add(eval_region *g, const float *a, const float *b)
{
    for (int c = 0; c < 3; c++) g->sse += (double)(a[c] - b[c]) * (a[c] - b[c]);
    g->pixels += 1;
}

enum { DIAG_REPROJ, DIAG_GUESS, DIAG_MOVING, DIAG_CLASSES };

/* One proxy view against dataset camera cam, every frame; sums into s (and the pooled totals). */
static pg_status diagnose_view(pg_dataset *ds, int cam, const char *dir, const char *name, int F, int W, int H,
                               eval_region s[DIAG_CLASSES], long *pixels)
{
    const size_t px = (size_t)W * H;
    uint8_t *moving = NULL;
    pg_status st = eval_dataset_moving_masks(ds, cam, F, W, H, &moving);
    for (int f = 0; st == PG_OK && f < F; f++) {
        char path[4400];
        pg_image real = { 0 }, proxy = { 0 }, mask = { 0 };
        st = io_dataset_frame(ds, cam, f, &real);
        if (st == PG_OK) st = io_trainset_frame_path_ext(path, sizeof path, dir, name, "rgb", f, "jpg");
        if (st == PG_OK) st = io_image_load(path, &proxy);
        if (st == PG_OK) st = io_trainset_frame_path(path, sizeof path, dir, name, "mask", f);
        if (st == PG_OK) st = io_image_load(path, &mask);
        if (st == PG_OK && (proxy.width != W || proxy.height != H || mask.width != W || mask.height != H))
            st = pg_fail(PG_ERR_SIZE, "%s: proxy %s frame %d is %dx%d, the dataset's frames %dx%d", dir, name, f,
                         proxy.width, proxy.height, W, H);
        for (size_t i = 0; st == PG_OK && i < px; i++) {
            const float w = mask.data[3 * i];
            if (w <= 0) continue;
            const float *a = proxy.data + 3 * i, *b = real.data + 3 * i;
            diag_add(&s[w >= DIAG_REPROJECTED ? DIAG_REPROJ : DIAG_GUESS], a, b);
            if (moving[(size_t)f * px + i]) diag_add(&s[DIAG_MOVING], a, b);
        }
        if (st == PG_OK && eval_wants_side_by_side(f, F)) {
            char file[128], vis[4400];
            snprintf(file, sizeof file, "vis/diagnose_%s_%04d.png", name, f);
            st = pg_path_join(vis, sizeof vis, dir, file);
            if (st == PG_OK) st = eval_write_side_by_side(vis, &real, &proxy);
        }
        pg_image_destroy(&real);
        pg_image_destroy(&proxy);
        pg_image_destroy(&mask);
    }
    *pixels += (long)(F * px);
    io_dataset_release(ds, cam);
    free(moving);
    return st;
}

static void add_region(cJSON *obj, const char *key, const eval_region *s, long pixels)
{
    cJSON *r = cJSON_AddObjectToObject(obj, key);
    double p = eval_region_psnr(s);
    if (isnan(p)) cJSON_AddNullToObject(r, "psnr");
    else cJSON_AddNumberToObject(r, "psnr", p);
    cJSON_AddNumberToObject(r, "fraction", pixels > 0 ? s->pixels / (double)pixels : 0.0);
}

pg_status stage_proxies_diagnose(pg_dataset *ds, const char *dir, const pg_camera *real, int M, const char *const *names,
                                 const pg_camera *cams, int F, int W, int H, proxies_diagnosis *out)
{
    char path[4300];
    PG_TRY(pg_path_join(path, sizeof path, dir, "vis"));
    PG_TRY(pg_mkdir_p(path));
    cJSON *root = cJSON_CreateObject(), *arr = cJSON_AddArrayToObject(root, "cameras");
    eval_region total[DIAG_CLASSES] = { 0 };
    long total_pixels = 0;
    pg_status st = PG_OK;
    out->views = 0;
    for (int k = 0; k < M && st == PG_OK; k++) {
        const int cam = io_dataset_find_camera(ds, names[k]);
        if (cam < 0) continue; /* not a dataset camera: nothing recorded there */
        eval_region s[DIAG_CLASSES] = { 0 };
        long pixels = 0;
        st = diagnose_view(ds, cam, dir, names[k], F, W, H, s, &pixels);
        if (st) break;
        cJSON *v = cJSON_CreateObject();
        cJSON_AddStringToObject(v, "name", names[k]);
        cJSON_AddNumberToObject(v, "angle_deg", proxy_camera_angle_deg(real, &cams[k]));
        add_region(v, "reprojected", &s[DIAG_REPROJ], pixels);
        add_region(v, "guessed", &s[DIAG_GUESS], pixels);
        add_region(v, "moving", &s[DIAG_MOVING], pixels);
        cJSON_AddItemToArray(arr, v);
        for (int c = 0; c < DIAG_CLASSES; c++) {
            total[c].sse += s[c].sse;
            total[c].pixels += s[c].pixels;
        }
        total_pixels += pixels;
        out->views++;
        pg_progress_report("diagnose", k + 1, M, "camera=%s reprojected=%.2f moving=%.2f", names[k],
                           eval_region_psnr(&s[DIAG_REPROJ]), eval_region_psnr(&s[DIAG_MOVING]));
    }
    out->psnr_reprojected = eval_region_psnr(&total[DIAG_REPROJ]);
    out->psnr_guessed = eval_region_psnr(&total[DIAG_GUESS]);
    out->psnr_moving = eval_region_psnr(&total[DIAG_MOVING]);
    if (st == PG_OK) {
        cJSON *all = cJSON_AddObjectToObject(root, "all");
        add_region(all, "reprojected", &total[DIAG_REPROJ], total_pixels);
        add_region(all, "guessed", &total[DIAG_GUESS], total_pixels);
        add_region(all, "moving", &total[DIAG_MOVING], total_pixels);
        st = pg_path_join(path, sizeof path, dir, "diagnose.json");
        if (st == PG_OK) st = io_json_write_atomic(path, root);
    }
    cJSON_Delete(root);
    return st;
}
