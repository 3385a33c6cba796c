/* cmd_prepare.c - `prodygs prepare`: refine and temporally align per-frame depth.
 *
 *   prodygs prepare INPUT --depth PATH --out DIR [--depth-kind depth|disparity] [--depth-scale S]
 *                   [--no-refine] [--no-align] [--frames N] [--size WxH] [--train-cam NAME]
 *
 * INPUT is a video, a frame folder or a dataset (DyNeRF: camera --train-cam, default the first).
 * Writes DIR/depth_aligned.npy, DIR/static_masks.npy, DIR/prepare.json and DIR/vis/ (FORMATS.md).
 */
#include "cli/cli.h"
#include "core/parallel.h"
#include "depth/prepare.h"
#include "io/dataset.h"
#include "io/depth_io.h"

#include <cjson/cJSON.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Parses "320x240" (either side may be 0 to keep the aspect ratio): -1 not WxH, -2 out of range. */
static int parse_size(const char *text, int *w, int *h)
{
    char tail;
    long lw, lh;
    if (sscanf(text, "%ldx%ld%c", &lw, &lh, &tail) != 2) return -1;
    if (lw < 0 || lh < 0 || (lw == 0 && lh == 0) || lw > CLI_MAX_SIDE || lh > CLI_MAX_SIDE) return -2;
    *w = (int)lw;
    *h = (int)lh;
    return 0;
}

int cmd_prepare(int argc, char **argv)
{
    const char *out = NULL, *depth_path = NULL, *kind = "depth", *size = NULL, *train_cam = NULL, *refine = NULL;
    float depth_scale = 1.0f;
    int no_refine = 0, no_align = 0, frames_n = 0, threads = 0, no_vis_flow = 0;
    const cli_option options[] = {
        { "--depth", CLI_STR, &depth_path, "per-frame depth: (F,H,W) .npy or a folder of .npy/.pfm/.png/.exr (required)" },
        { "--out", CLI_STR, &out, "output directory (required)" },
        { "--depth-kind", CLI_STR, &kind, "depth (z along the optical axis, default) or disparity (1/depth)" },
        { "--depth-scale", CLI_FLOAT, &depth_scale, "multiply raw depth values by S first (default 1)" },
        { "--no-refine", CLI_FLAG, &no_refine, "skip the edge-aware refinement" },
        { "--refine", CLI_STR, &refine, "refiner: edge-snap (default), bilateral or none" },
        { "--no-align", CLI_FLAG, &no_align, "skip the per-frame scale/shift alignment (alpha=1, beta=0)" },
        { "--frames", CLI_INT, &frames_n, "use only the first N frames" },
        { "--size", CLI_STR, &size, "resize frames and depth to WxH (0 for one side keeps the aspect)" },
        { "--train-cam", CLI_STR, &train_cam, "dataset camera to use (default: the first, e.g. cam00)" },
        { "--threads", CLI_INT, &threads, "worker threads (default: all cores)" },
        { "--no-flow-vis", CLI_FLAG, &no_vis_flow, "do not keep flow fields for vis/flow_*.png (saves memory; automatic above 1 GiB)" },
    };
    const cli_spec spec = { "prodygs prepare", "INPUT --depth PATH --out DIR [options]",
                            "refine per-frame depth at colour edges, find static pixels, align depth scale over time",
                            options, (int)(sizeof options / sizeof options[0]), 1, 1 };
    const char *pos[1];
    int npos = 0, rc = cli_parse(&spec, argc, argv, pos, &npos);
    if (rc == -1) return 0;
    if (rc) return rc;
    if (!depth_path) return cli_usage_error("prepare: --depth PATH is required");
    if (!out) return cli_usage_error("prepare: --out DIR is required");
    int want_w = 0, want_h = 0;
    int size_rc = size ? parse_size(size, &want_w, &want_h) : 0;
    if (size_rc == -1) return cli_usage_error("prepare: --size '%s' is not WxH", size);
    if (size_rc == -2) return cli_usage_error("prepare: --size '%s' out of range (sides 0..%d, not both 0)", size, CLI_MAX_SIDE);
    if (threads < 0 || threads > 256) return cli_usage_error("prepare: --threads %d must be in 1..256", threads);
    if (frames_n < 0) return cli_usage_error("prepare: --frames must be >= 1");
    if (!(depth_scale > 0.0f)) return cli_usage_error("prepare: --depth-scale must be > 0");
    io_depth_kind dkind;
    if (strcmp(kind, "depth") == 0) dkind = IO_DEPTH_KIND_DEPTH;
    else if (strcmp(kind, "disparity") == 0) dkind = IO_DEPTH_KIND_DISPARITY;
    else return cli_usage_error("prepare: --depth-kind must be depth or disparity, not '%s'", kind);
    depth_prepare_options popt;
    depth_prepare_defaults(&popt);
    if (refine) {
        popt.refine = depth_refine_kind_parse(refine);
        if (popt.refine == DEPTH_REFINE_COUNT)
            return cli_usage_error("prepare: --refine must be edge-snap, bilateral or none, not '%s'", refine);
    }
    if (no_refine) popt.refine = DEPTH_REFINE_NONE;
    popt.align = !no_align;
    popt.keep_flow = !no_vis_flow;
    if (threads > 0) pg_set_threads(threads); /* else keep what the caller (e.g. `prodygs run`) set */

    pg_status st;
    pg_dataset *ds = NULL;
    io_dataset_options dopt = io_dataset_defaults();
    dopt.width = want_w;
    dopt.height = want_h;
    dopt.count = frames_n;
    if ((st = io_dataset_open(pos[0], &dopt, &ds))) return cli_fail(st);
    int cam = 0;
    if (train_cam && io_dataset_resolve_camera(ds, train_cam, &cam) != PG_OK) {
        io_dataset_close(ds);
        return cli_usage_error("prepare: %s: --train-cam: %s", pos[0], pg_last_error());
    }
    char label[96];
    io_dataset_camera_label(ds, cam, label, sizeof label);
    printf("prepare: training camera %s\n", label);
    fflush(stdout);
    const int F = io_dataset_num_frames(ds), W = io_dataset_width(ds), H = io_dataset_height(ds);
    pg_image *frames = calloc((size_t)(F > 0 ? F : 1), sizeof(pg_image));
    io_depth depth;
    memset(&depth, 0, sizeof depth);
    depth_prepare_result res;
    memset(&res, 0, sizeof res);
    st = frames ? PG_OK : pg_fail(PG_ERR_NOMEM, "prepare: out of memory for %d frames", F);
    for (int t = 0; t < F && !st; t++) st = io_dataset_frame(ds, cam, t, &frames[t]);
    io_dataset_release(ds, -1);
    if (!st) {
        io_depth_options o = io_depth_defaults();
        o.kind = dkind;
        o.scale = depth_scale;
        o.width = W;
        o.height = H;
        o.count = frames_n; /* --frames N takes the first N depth frames too */
        o.expect_frames = F;
        st = io_depth_load(depth_path, &o, &depth);
        if (!st && !(depth.max > 0))
            st = pg_fail(PG_ERR_FORMAT, "%s: no valid depth in any frame (every value is NaN, inf or <= 0)", depth_path);
    }
    /* Flow fields are kept only for the pictures; skip them when they would be large. */
    if (popt.keep_flow && (double)F * W * H * 2 * sizeof(float) > 1024.0 * 1024 * 1024) popt.keep_flow = 0;
    if (!st) st = depth_prepare_run(&popt, frames, F, depth.data, &res);
    if (!st) {
        cJSON *src = cJSON_CreateObject();
        cJSON_AddStringToObject(src, "input", pos[0]);
        cJSON_AddStringToObject(src, "camera", io_dataset_camera_name(ds, cam));
        cJSON_AddStringToObject(src, "depth", depth_path);
        cJSON_AddStringToObject(src, "depth_kind", kind);
        cJSON_AddNumberToObject(src, "depth_scale", depth_scale);
        cJSON_AddNumberToObject(src, "depth_invalid_input_pixels", (double)depth.invalid);
        cJSON_AddNumberToObject(src, "fps", io_dataset_fps(ds));
        char *text = cJSON_PrintUnformatted(src);
        cJSON_Delete(src);
        st = depth_prepare_write(out, &popt, &res, frames, depth.data, text);
        free(text);
    }
    if (!st) {
        double rb = 0, ra = 0;
        int fallbacks = 0;
        for (int i = 0; i < F; i++) {
            rb += res.info[i].resid_before / F;
            ra += res.info[i].resid_after / F;
            fallbacks += res.info[i].fallback != DEPTH_FALLBACK_NONE;
        }
        printf("prepare: %d frames %dx%d, reference frame %d, mean residual vs reference %.4f -> %.4f, "
               "%d fallback frame(s), %.1f s; wrote %s\n",
               F, W, H, res.reference, rb, ra, fallbacks, res.seconds_total, out);
        for (int i = 0; i < F; i++)
            if (res.info[i].fallback == DEPTH_FALLBACK_COPIED)
                fprintf(stderr, "prodygs: warning: frame %d has no valid depth; copied frame %d\n", i,
                        res.info[i].source_frame);
    }
    depth_prepare_result_destroy(&res);
    io_depth_destroy(&depth);
    if (frames)
        for (int t = 0; t < F; t++) pg_image_destroy(&frames[t]);
    free(frames);
    io_dataset_close(ds);
    return st ? cli_fail(st) : 0;
}
