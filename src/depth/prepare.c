/* prepare.c - depth preparation pipeline and its outputs (see prepare.h). */
#include "depth/prepare.h"
#include "depth/fuse.h"
#include "depth/moving_mask.h"
#include "depth/plane.h"

#include "core/fileutil.h"
#include "core/mathx.h"
#include "core/parallel.h"
#include "core/progress.h"
#include "io/image_io.h"
#include "io/npy.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PREPARE_VIS_FRAMES 60 /* frames of each kind written to vis/ */

void depth_prepare_defaults(depth_prepare_options *opt)
{
    memset(opt, 0, sizeof *opt);
    opt->refine = DEPTH_REFINE_EDGE_SNAP;
    opt->align = 1;
    opt->fuse_static = 1;
    opt->ground = 1;
    opt->snap_planes = 1;
    opt->movers_front = 1;
    opt->min_valid_fraction = 0.01f;
    depth_refine_defaults(&opt->refine_params);
    depth_static_defaults(&opt->static_params);
    depth_align_defaults(&opt->align_params);
    depth_ground_defaults(&opt->ground_params);
    depth_scene_planes_defaults(&opt->planes_params);
}

void depth_prepare_result_destroy(depth_prepare_result *res)
{
    if (!res) return;
    free(res->depth);
    free(res->static_masks);
    free(res->dynamic_prob);
    free(res->flow);
    free(res->info);
    free(res->plane_label);
    memset(res, 0, sizeof *res);
}

static const char *fallback_name(depth_fallback f)
{
    switch (f) {
    case DEPTH_FALLBACK_COPIED: return "copied";
    case DEPTH_FALLBACK_ALL_PIXELS: return "all_pixels";
    case DEPTH_FALLBACK_IDENTITY: return "identity";
    default: return "none";
    }
}

static pg_status prepare_check(const pg_image *frames, int F, const float *depth)
{
    if (F < 1 || !frames) return pg_fail(PG_ERR_ARG, "depth preparation: no frames");
    if (!depth) return pg_fail(PG_ERR_ARG, "depth preparation: no depth");
    for (int i = 0; i < F; i++) {
        if (!frames[i].data || frames[i].width != frames[0].width || frames[i].height != frames[0].height)
            return pg_fail(PG_ERR_SIZE, "depth preparation: frame %d is %d x %d, frame 0 is %d x %d", i,
                           frames[i].width, frames[i].height, frames[0].width, frames[0].height);
    }
    return PG_OK;
}

/* Pixels whose colour is off their temporal median (the background wherever something passes
 * less than half of the time) are dynamic too. The flow and colour tests compare each frame with
 * the reference only, so where the moving object stands in the reference as well (a person
 * dancing on the spot) they call it static, and its depth was fused into the background's. */
#define PREPARE_MOVING_THRESH 0.1f
#define PREPARE_MOVING_DILATE 2
static pg_status mark_off_background(const pg_image *frames, int F, unsigned char *static_masks)
{
    const int W = frames[0].width, H = frames[0].height;
    const size_t n = (size_t)W * H;
    if (F < 3) return PG_OK;
    uint8_t *rgb = pg_malloc((size_t)F * n * 3, "prepare moving masks");
    uint8_t *moving = pg_malloc((size_t)F * n, "prepare moving masks");
    pg_status st = rgb && moving ? PG_OK : PG_ERR_NOMEM;
    for (int i = 0; i < F && !st; i++) pg_image_to_rgb8(&frames[i], rgb + (size_t)i * n * 3);
    if (!st) st = depth_moving_masks(rgb, F, W, H, PREPARE_MOVING_THRESH, PREPARE_MOVING_DILATE, moving);
    for (size_t k = 0; !st && k < (size_t)F * n; k++)
        if (moving[k]) static_masks[k] = 0;
    free(rgb);
    free(moving);
    return st;
}

/* Runs everything that may fail after allocation; the caller frees on failure. */
static pg_status prepare_frames(const depth_prepare_options *opt, const pg_image *frames, int F, const float *depth,
                                depth_prepare_result *res, float *refined)
{
    const int W = res->width, H = res->height;
    const size_t n = (size_t)W * H;
    depth_refine_backend builtin = depth_refine_backend_get(opt->refine, &opt->refine_params);
    const depth_refine_backend *refiner = opt->refiner ? opt->refiner : &builtin;
    depth_flow_backend tvl1 = depth_flow_backend_default();
    const depth_flow_backend *flow = opt->flow ? opt->flow : &tvl1;
    int *valid = pg_calloc((size_t)F, sizeof(int), "frame validity");
    if (!valid) return PG_ERR_NOMEM;
    pg_status st = PG_OK;

    /* 1. Refinement of every frame (invalid frames are only counted). */
    double t0 = pg_time_seconds();
    for (int i = 0; i < F && !st; i++) {
        const float *d = depth + (size_t)i * n;
        depth_prepare_frame *fi = &res->info[i];
        fi->alpha = 1.0;
        fi->source_frame = i;
        for (size_t k = 0; k < n; k++) fi->invalid_in += !depth_valid(d[k]);
        valid[i] = (double)(n - fi->invalid_in) >= opt->min_valid_fraction * n && n - fi->invalid_in >= 1;
        if (!valid[i]) continue;
        st = depth_refine_run(refiner, &frames[i], d, refined + (size_t)i * n);
        if (st) st = pg_fail_context(st, "frame %d: ", i);
    }
    res->seconds_refine = pg_time_seconds() - t0;
    int ref = -1;
    for (int i = 0; i < F && ref < 0; i++)
        if (valid[i]) ref = i;
    if (!st && ref < 0) st = pg_fail(PG_ERR_ARG, "depth preparation: no frame has valid depth (all NaN, inf or <= 0)");
    res->reference = ref;
    const float *dref = ref >= 0 ? refined + (size_t)ref * n : NULL;

    /* 2. Flow and static mask of each frame against the reference. Frames run in parallel (one
     * thread per frame, single-threaded flow inside): far fewer barriers than parallel loops
     * inside the iterative solver, and the result does not depend on the thread count. */
    double tf = pg_time_seconds();
    pg_status *fst = pg_calloc((size_t)F, sizeof(pg_status), "per-frame status");
    char (*msg)[256] = pg_calloc((size_t)F, 256, "per-frame messages");
    if (!fst || !msg) st = st ? st : PG_ERR_NOMEM;
    long done = 0;
    depth_mask_reference sref = {0};
    if (!st) st = depth_mask_reference_create(&opt->static_params, &frames[ref], &sref);
    if (!st) {
        #pragma omp parallel
        {
            float *work = malloc(n * 5 * sizeof(float));
            #pragma omp for schedule(dynamic, 1)
            for (int i = 0; i < F; i++) {
                unsigned char *mask = res->static_masks + (size_t)i * n;
                float *prob = res->dynamic_prob + (size_t)i * n;
                if (i == ref) {
                    memset(mask, 1, n);
                    memset(prob, 0, n * sizeof(float));
                    continue;
                }
                if (!work) {
                    fst[i] = PG_ERR_NOMEM;
                    snprintf(msg[i], 256, "out of memory for flow buffers");
                    continue;
                }
                float *f_ir = work, *f_ri = work + 2 * n, *conf = work + 4 * n;
                pg_status s1 = depth_flow_compute(flow, &frames[i], &frames[ref], f_ir);
                if (!s1) s1 = depth_flow_compute(flow, &frames[ref], &frames[i], f_ri);
                if (!s1) {
                    depth_flow_consistency(f_ir, f_ri, W, H, conf);
                    s1 = depth_static_mask(&opt->static_params, &frames[i], &sref, f_ir, conf, prob, mask);
                }
                if (s1) {
                    fst[i] = s1;
                    snprintf(msg[i], 256, "%s", pg_last_error()); /* messages are per thread */
                    continue;
                }
                if (res->flow) memcpy(res->flow + (size_t)i * n * 2, f_ir, n * 2 * sizeof(float));
                #pragma omp critical(prepare_progress)
                {
                    done++;
                    pg_progress_report("prepare", done, 2L * F, "flow frame %d", i);
                }
            }
            free(work);
        }
        for (int i = 0; i < F && !st; i++)
            if (fst[i]) st = pg_fail(fst[i], "frame %d: %s", i, msg[i]);
    }
    depth_mask_reference_free(&sref);
    free(fst);
    free(msg);
    if (!st) st = mark_off_background(frames, F, res->static_masks);
    res->seconds_flow = pg_time_seconds() - tf;

    /* 3. Robust scale/shift of each frame against the reference on its static mask. */
    for (int i = 0; i < F && !st; i++) {
        depth_prepare_frame *fi = &res->info[i];
        unsigned char *mask = res->static_masks + (size_t)i * n;
        for (size_t k = 0; k < n; k++) fi->static_pixels += mask[k];
        double ta = pg_time_seconds();
        if (valid[i] && i != ref && opt->align) {
            const float *di = refined + (size_t)i * n;
            depth_align_result ar;
            pg_status fs = depth_align_fit(&opt->align_params, di, dref, mask, n, &ar);
            if (fs != PG_OK) {
                fi->fallback = DEPTH_FALLBACK_ALL_PIXELS;
                fs = depth_align_fit(&opt->align_params, di, dref, NULL, n, &ar);
            }
            if (fs == PG_OK) {
                fi->alpha = ar.alpha;
                fi->beta = ar.beta;
                fi->resid_before = ar.resid_before;
                fi->resid_after = ar.resid_after;
                fi->fit_pixels = ar.used;
                fi->fit_inliers = ar.inliers;
                fi->shift_fitted = ar.shift_fitted;
            } else {
                fi->fallback = DEPTH_FALLBACK_IDENTITY;
            }
        }
        if (valid[i]) depth_align_apply(refined + (size_t)i * n, n, fi->alpha, fi->beta, res->depth + (size_t)i * n);
        res->seconds_align += pg_time_seconds() - ta;
        pg_progress_report("prepare", (long)F + i + 1, 2L * F, "frame %d alpha=%.4f beta=%.4f static=%.1f%%",
                           i, fi->alpha, fi->beta, 100.0 * fi->static_pixels / n);
    }

    /* 4. One depth per static surface: pixels static in at least a quarter of the valid frames (and
     *    3) take their median over those frames (invalid frames are still zero here, so they do not
     *    count; they copy a fused frame next). */
    const int min_static = F / 4 > 3 ? F / 4 : 3;
    if (!st && opt->fuse_static) {
        res->fused_pixels = depth_fuse_static(res->depth, res->static_masks, F, n, min_static);
        if (res->fused_pixels < 0) st = pg_fail(PG_ERR_NOMEM, "depth preparation: out of memory fusing static depth");
    }

    /* 4a. The floor and the wall behind it placed by the camera's vertical direction (ground.h). */
    if (!st && opt->ground && opt->ground_params.focal > 0) {
        float *still = pg_malloc(n * sizeof(float), "still scene depth");
        if (!still || depth_static_reference(res->depth, res->static_masks, F, n, min_static, still) < 0)
            st = pg_fail(PG_ERR_NOMEM, "depth preparation: out of memory placing the floor");
        if (!st) st = depth_ground_snap(&opt->ground_params, frames, F, res->depth, res->static_masks, still, W, H, &res->ground);
        free(still);
    }

    /* 4b. Static depth near a dominant plane of the scene takes the plane's depth (scene_planes.h). */
    if (!st && opt->snap_planes) {
        depth_scene_planes_params pp = opt->planes_params;
        pp.min_frames = min_static;
        res->plane_label = pg_malloc(n, "plane labels");
        st = res->plane_label ? depth_scene_planes_snap(&pp, res->depth, res->static_masks, F, W, H, &res->planes,
                                                        res->plane_label)
                              : PG_ERR_NOMEM;
    }

    /* 4c. Moving blobs behind the still surface they cover come in front of it (movers_front.h):
     *     the blobs are the pixels not static in their frame. */
    if (!st && opt->movers_front && F >= 3) {
        depth_movers_front_params mp = opt->movers_params;
        if (mp.min_area <= 0) depth_movers_front_defaults(&mp, W, H);
        float *background = pg_malloc(n * sizeof(float), "still scene depth");
        res->movers_moved = -1;
        if (background && depth_static_reference(res->depth, res->static_masks, F, n, min_static, background) >= 0)
            res->movers_moved = depth_movers_in_front(res->depth, res->static_masks, background, F, W, H, &mp);
        free(background);
        if (res->movers_moved < 0) st = pg_fail(PG_ERR_NOMEM, "depth preparation: out of memory placing movers");
    }

    /* 5. Invalid frames copy the nearest earlier valid frame (later one if none earlier). */
    for (int i = 0; i < F && !st; i++) {
        if (valid[i]) continue;
        int src = -1;
        for (int j = i - 1; j >= 0 && src < 0; j--)
            if (valid[j]) src = j;
        for (int j = i + 1; j < F && src < 0; j++)
            if (valid[j]) src = j;
        res->info[i].fallback = DEPTH_FALLBACK_COPIED;
        res->info[i].source_frame = src;
        memcpy(res->depth + (size_t)i * n, res->depth + (size_t)src * n, n * sizeof(float));
    }
    for (int i = 0; i < F && !st; i++) {
        const float *d = res->depth + (size_t)i * n;
        for (size_t k = 0; k < n; k++) res->info[i].invalid_out += !depth_valid(d[k]);
    }
    free(valid);
    return st;
}

pg_status depth_prepare_run(const depth_prepare_options *opt, const pg_image *frames, int F, const float *depth,
                            depth_prepare_result *res)
{
    memset(res, 0, sizeof *res);
    PG_TRY(prepare_check(frames, F, depth));
    double t0 = pg_time_seconds();
    const int W = frames[0].width, H = frames[0].height;
    const size_t n = (size_t)W * H;
    size_t fn;
    if (pg_size_mul(n, (size_t)F, &fn) || fn > ((size_t)1 << 31))
        return pg_fail(PG_ERR_SIZE, "depth preparation: %d frames of %d x %d is too large", F, W, H);
    res->frames = F;
    res->width = W;
    res->height = H;
    res->depth = pg_calloc(fn, sizeof(float), "aligned depth");
    res->static_masks = pg_calloc(fn, 1, "static masks");
    res->dynamic_prob = pg_calloc(fn, sizeof(float), "dynamic probability");
    res->info = pg_calloc((size_t)F, sizeof(depth_prepare_frame), "per-frame report");
    if (opt->keep_flow) res->flow = pg_calloc(fn * 2, sizeof(float), "flow");
    float *refined = pg_calloc(fn, sizeof(float), "refined depth");
    pg_status st = PG_OK;
    if (!res->depth || !res->static_masks || !res->dynamic_prob || !res->info || (opt->keep_flow && !res->flow) ||
        !refined)
        st = PG_ERR_NOMEM;
    if (!st) st = prepare_frames(opt, frames, F, depth, res, refined);
    free(refined);
    if (st) {
        depth_prepare_result_destroy(res);
        return st;
    }
    res->seconds_total = pg_time_seconds() - t0;
    return PG_OK;
}

/* ---- outputs ---- */

void depth_to_color(const float *depth, int W, int H, float lo, float hi, pg_image *out)
{
    /* A short magma-like ramp in inverse depth: near pixels bright, far dark. */
    static const float ramp[6][3] = { { 0.05f, 0.03f, 0.15f }, { 0.32f, 0.07f, 0.45f }, { 0.62f, 0.16f, 0.45f },
                                      { 0.89f, 0.33f, 0.30f }, { 0.99f, 0.64f, 0.25f }, { 0.99f, 0.95f, 0.60f } };
    float ilo = 1.0f / hi, ihi = 1.0f / lo;
    for (size_t k = 0; k < (size_t)W * H; k++) {
        float *px = out->data + 3 * k;
        if (!depth_valid(depth[k])) {
            px[0] = px[1] = px[2] = 0.0f;
            continue;
        }
        pg_color_ramp(ramp, 6, (1.0f / depth[k] - ilo) / (ihi - ilo), px);
    }
}

/* 1st and 99th percentile of valid depth over a subsample of all frames (shared colour range). */
static void depth_range(const float *d, size_t count, float *lo, float *hi)
{
    size_t step = count / 200000 + 1, m = 0;
    float *v = malloc(sizeof(float) * (count / step + 1));
    *lo = 1.0f;
    *hi = 10.0f;
    if (!v) return;
    for (size_t k = 0; k < count; k += step)
        if (depth_valid(d[k])) v[m++] = d[k];
    if (m > 10) {
        qsort(v, m, sizeof(float), pg_cmp_float);
        *lo = v[m / 100];
        *hi = v[m - 1 - m / 100];
        if (!(*hi > *lo)) *hi = *lo * 1.01f + 1e-6f;
    }
    free(v);
}

static pg_status write_json(const char *path, const depth_prepare_options *opt, const depth_prepare_result *res,
                            const char *source_json)
{
    cJSON *root = cJSON_CreateObject();
    if (!root) return pg_fail(PG_ERR_NOMEM, "%s: out of memory building JSON", path);
    cJSON_AddNumberToObject(root, "version", 1);
    cJSON_AddNumberToObject(root, "frames", res->frames);
    cJSON_AddNumberToObject(root, "width", res->width);
    cJSON_AddNumberToObject(root, "height", res->height);
    cJSON_AddNumberToObject(root, "reference_frame", res->reference);
    cJSON_AddNumberToObject(root, "fused_static_pixels", (double)res->fused_pixels);
    cJSON_AddNumberToObject(root, "movers_moved", (double)res->movers_moved);
    cJSON_AddStringToObject(root, "depth_space", "depth, relative residuals (alpha*D_i + beta ~ D_ref)");
    cJSON *set = cJSON_AddObjectToObject(root, "settings");
    cJSON_AddStringToObject(set, "refine", opt->refiner ? opt->refiner->name : depth_refine_kind_name(opt->refine));
    cJSON_AddStringToObject(set, "flow", opt->flow ? opt->flow->name : "tvl1");
    cJSON_AddBoolToObject(set, "align", opt->align);
    cJSON_AddBoolToObject(set, "fuse_static", opt->fuse_static);
    cJSON_AddBoolToObject(set, "ground", opt->ground);
    cJSON_AddNumberToObject(set, "focal", opt->ground_params.focal);
    cJSON_AddBoolToObject(set, "snap_planes", opt->snap_planes);
    cJSON_AddBoolToObject(set, "movers_front", opt->movers_front);
    cJSON_AddNumberToObject(set, "plane_tolerance", opt->planes_params.tolerance);
    cJSON_AddNumberToObject(set, "plane_min_support", opt->planes_params.min_support);
    cJSON_AddNumberToObject(set, "refine_radius", opt->refine_params.radius);
    cJSON_AddNumberToObject(set, "refine_sigma_color", opt->refine_params.sigma_color);
    cJSON_AddNumberToObject(set, "refine_edge_thresh", opt->refine_params.edge_thresh);
    cJSON_AddNumberToObject(set, "static_flow_thresh", opt->static_params.flow_thresh);
    cJSON_AddNumberToObject(set, "static_color_thresh", opt->static_params.color_thresh);
    cJSON_AddNumberToObject(set, "static_texture_thresh", opt->static_params.texture_thresh);
    cJSON_AddNumberToObject(set, "align_iterations", opt->align_params.iterations);
    cJSON_AddBoolToObject(set, "align_fit_shift", opt->align_params.fit_shift);
    cJSON_AddNumberToObject(set, "min_valid_fraction", opt->min_valid_fraction);
    if (opt->ground) {
        const depth_ground_result *g = &res->ground;
        cJSON *o = cJSON_AddObjectToObject(root, "ground");
        cJSON_AddBoolToObject(o, "found", g->found);
        cJSON_AddStringToObject(o, "up_from", opt->ground_params.up_known ? "camera rig" : "vanishing point");
        cJSON_AddNumberToObject(o, "vanishing_point_share", g->vp_share);
        cJSON_AddNumberToObject(o, "tilt_deg", g->tilt_deg);
        cJSON *up = cJSON_AddArrayToObject(o, "up");
        for (int k = 0; k < 3; k++) cJSON_AddItemToArray(up, cJSON_CreateNumber(g->up[k]));
        cJSON_AddNumberToObject(o, "height", g->height);
        cJSON_AddNumberToObject(o, "floor_share", g->floor_share);
        cJSON_AddNumberToObject(o, "floor_disagreement", g->floor_disagreement);
        cJSON_AddNumberToObject(o, "rest_scale", g->rest_scale);
        cJSON_AddBoolToObject(o, "wall", g->wall);
        cJSON_AddNumberToObject(o, "wall_span", g->wall_span);
        cJSON_AddNumberToObject(o, "changed_values", (double)g->changed);
        cJSON_AddNumberToObject(o, "objects", (double)g->blobs);
        cJSON_AddNumberToObject(o, "objects_on_floor", (double)g->anchored);
    }
    if (opt->snap_planes) {
        /* 1/d = a x + b y + c with x, y the pixel centre over the width/height minus 0.5 */
        cJSON *pl = cJSON_AddArrayToObject(root, "planes");
        const double npx = (double)res->width * res->height;
        for (int i = 0; i < res->planes.count; i++) {
            const depth_scene_plane *p = &res->planes.planes[i];
            cJSON *o = cJSON_CreateObject();
            cJSON_AddNumberToObject(o, "a", p->a);
            cJSON_AddNumberToObject(o, "b", p->b);
            cJSON_AddNumberToObject(o, "c", p->c);
            cJSON_AddNumberToObject(o, "support", p->inliers / npx);
            cJSON_AddNumberToObject(o, "median_residual", p->median_residual);
            cJSON_AddItemToArray(pl, o);
        }
        cJSON_AddNumberToObject(root, "plane_snapped_values", (double)res->planes.snapped);
    }
    cJSON *tm = cJSON_AddObjectToObject(root, "timing");
    cJSON_AddNumberToObject(tm, "refine_s", res->seconds_refine);
    cJSON_AddNumberToObject(tm, "flow_s", res->seconds_flow);
    cJSON_AddNumberToObject(tm, "align_s", res->seconds_align);
    cJSON_AddNumberToObject(tm, "total_s", res->seconds_total);
    cJSON *arr[6] = { cJSON_AddArrayToObject(root, "alpha"), cJSON_AddArrayToObject(root, "beta"),
                      cJSON_AddArrayToObject(root, "residual_before"), cJSON_AddArrayToObject(root, "residual_after"),
                      cJSON_AddArrayToObject(root, "invalid_pixels"), cJSON_AddArrayToObject(root, "static_fraction") };
    cJSON *per = cJSON_AddArrayToObject(root, "per_frame");
    const double n = (double)res->width * res->height;
    for (int i = 0; i < res->frames; i++) {
        const depth_prepare_frame *fi = &res->info[i];
        cJSON_AddItemToArray(arr[0], cJSON_CreateNumber(fi->alpha));
        cJSON_AddItemToArray(arr[1], cJSON_CreateNumber(fi->beta));
        cJSON_AddItemToArray(arr[2], cJSON_CreateNumber(fi->resid_before));
        cJSON_AddItemToArray(arr[3], cJSON_CreateNumber(fi->resid_after));
        cJSON_AddItemToArray(arr[4], cJSON_CreateNumber((double)fi->invalid_out));
        cJSON_AddItemToArray(arr[5], cJSON_CreateNumber(fi->static_pixels / n));
        cJSON *o = cJSON_CreateObject();
        cJSON_AddNumberToObject(o, "frame", i);
        cJSON_AddNumberToObject(o, "alpha", fi->alpha);
        cJSON_AddNumberToObject(o, "beta", fi->beta);
        cJSON_AddNumberToObject(o, "residual_before", fi->resid_before);
        cJSON_AddNumberToObject(o, "residual_after", fi->resid_after);
        cJSON_AddNumberToObject(o, "invalid_in", (double)fi->invalid_in);
        cJSON_AddNumberToObject(o, "invalid_out", (double)fi->invalid_out);
        cJSON_AddNumberToObject(o, "static_pixels", (double)fi->static_pixels);
        cJSON_AddNumberToObject(o, "fit_pixels", (double)fi->fit_pixels);
        cJSON_AddNumberToObject(o, "fit_inliers", (double)fi->fit_inliers);
        cJSON_AddBoolToObject(o, "shift_fitted", fi->shift_fitted);
        cJSON_AddStringToObject(o, "fallback", fallback_name(fi->fallback));
        cJSON_AddNumberToObject(o, "source_frame", fi->source_frame);
        cJSON_AddItemToArray(per, o);
    }
    if (source_json) {
        cJSON *src = cJSON_Parse(source_json);
        if (src) cJSON_AddItemToObject(root, "source", src);
    }
    char *text = cJSON_Print(root);
    cJSON_Delete(root);
    if (!text) return pg_fail(PG_ERR_NOMEM, "%s: out of memory printing JSON", path);
    pg_status st = pg_write_file_atomic(path, text, strlen(text));
    free(text);
    return st;
}

pg_status depth_prepare_write(const char *dir, const depth_prepare_options *opt, const depth_prepare_result *res,
                              const pg_image *frames, const float *input_depth, const char *source_json)
{
    char path[4096], vis[4096], name[64];
    const int F = res->frames, W = res->width, H = res->height;
    const size_t n = (size_t)W * H;
    const size_t shape[3] = { (size_t)F, (size_t)H, (size_t)W };
    PG_TRY(pg_mkdir_p(dir));
    PG_TRY(pg_path_join(path, sizeof path, dir, "depth_aligned.npy"));
    PG_TRY(io_npy_save_compact(path, res->depth, 3, shape));
    PG_TRY(pg_path_join(path, sizeof path, dir, "static_masks.npy"));
    PG_TRY(io_npy_save_u8(path, res->static_masks, 3, shape));
    PG_TRY(pg_path_join(path, sizeof path, dir, "dynamic_prob.npy"));
    PG_TRY(io_npy_save_f16(path, res->dynamic_prob, 3, shape)); /* a probability: 3e-5 is plenty */
    PG_TRY(pg_path_join(path, sizeof path, dir, "prepare.json"));
    PG_TRY(write_json(path, opt, res, source_json));

    PG_TRY(pg_path_join(vis, sizeof vis, dir, "vis"));
    PG_TRY(pg_mkdir_p(vis));
    pg_image img, gray;
    PG_TRY(pg_image_create(&img, W, H, 3));
    pg_status st = pg_image_create(&gray, W, H, 1);
    if (st) {
        pg_image_destroy(&img);
        return st;
    }
    float lo, hi;
    depth_range(res->depth, n * F, &lo, &hi);
    float ilo = lo, ihi = hi;
    if (input_depth) depth_range(input_depth, n * F, &ilo, &ihi);
    /* at most PREPARE_VIS_FRAMES frames per kind, evenly spaced: enough to judge a clip, and a
     * 10-second clip's vis/ stays a few MB instead of 1,500 files */
    int every = (F + PREPARE_VIS_FRAMES - 1) / PREPARE_VIS_FRAMES;
    for (int i = 0; i < F && !st; i += every) {
        depth_to_color(res->depth + (size_t)i * n, W, H, lo, hi, &img);
        snprintf(name, sizeof name, "depth_%04d.png", i);
        st = pg_path_join(path, sizeof path, vis, name);
        if (!st) st = io_image_save_png(path, &img);
        if (!st && input_depth) {
            depth_to_color(input_depth + (size_t)i * n, W, H, ilo, ihi, &img);
            snprintf(name, sizeof name, "input_depth_%04d.png", i);
            st = pg_path_join(path, sizeof path, vis, name);
            if (!st) st = io_image_save_png(path, &img);
        }
        if (!st && frames) {
            /* Mask over the frame: static pixels as they are, dynamic ones tinted red. */
            const unsigned char *m = res->static_masks + (size_t)i * n;
            depth_plane_from_image(&frames[i], 1.0f, gray.data);
            for (size_t k = 0; k < n; k++) {
                float g = gray.data[k];
                img.data[3 * k] = m[k] ? g : 0.5f + 0.5f * g;
                img.data[3 * k + 1] = m[k] ? g : 0.15f * g;
                img.data[3 * k + 2] = m[k] ? g : 0.15f * g;
            }
            snprintf(name, sizeof name, "mask_%04d.png", i);
            st = pg_path_join(path, sizeof path, vis, name);
            if (!st) st = io_image_save_png(path, &img);
        }
        if (!st) {
            const float *pb = res->dynamic_prob + (size_t)i * n;
            for (size_t k = 0; k < n; k++) gray.data[k] = pb[k];
            snprintf(name, sizeof name, "dynamic_prob_%04d.png", i);
            st = pg_path_join(path, sizeof path, vis, name);
            if (!st) st = io_image_save_png(path, &gray);
        }
        if (!st && res->flow && i != res->reference) {
            depth_flow_to_color(res->flow + (size_t)i * n * 2, W, H, 0.0f, &img);
            snprintf(name, sizeof name, "flow_%04d.png", i);
            st = pg_path_join(path, sizeof path, vis, name);
            if (!st) st = io_image_save_png(path, &img);
        }
    }
    if (!st && res->plane_label && frames) {
        /* The reference frame in grey with each plane's pixels tinted in its own colour. */
        static const float tint[6][3] = { { 0.9f, 0.3f, 0.2f }, { 0.2f, 0.7f, 0.9f }, { 0.3f, 0.9f, 0.3f },
                                          { 0.9f, 0.8f, 0.2f }, { 0.7f, 0.3f, 0.9f }, { 0.9f, 0.5f, 0.7f } };
        depth_plane_from_image(&frames[res->reference > 0 ? res->reference : 0], 1.0f, gray.data);
        for (size_t k = 0; k < n; k++) {
            float g = gray.data[k];
            int l = res->plane_label[k];
            for (int c = 0; c < 3; c++) img.data[3 * k + c] = l < 0 ? 0.5f * g : 0.4f * g + 0.6f * tint[l % 6][c];
        }
        st = pg_path_join(path, sizeof path, vis, "planes.png");
        if (!st) st = io_image_save_png(path, &img);
    }
    pg_image_destroy(&img);
    pg_image_destroy(&gray);
    return st;
}
