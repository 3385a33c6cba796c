/* depth_net.c - a depth network on video frames (see depth_net.h). */
#include "depth/depth_net.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/fileutil.h"
#include "io/json.h"
#include "nn/nn.h"

struct depth_net {
    nn_model *model;
    depth_net_info info;
    char path[4096];
    float *in, *out;      /* network input / output buffers */
    size_t in_count, out_count;
};

void depth_net_close(depth_net *net)
{
    if (!net) return;
    nn_model_destroy(net->model);
    free(net->in);
    free(net->out);
    free(net);
}

const depth_net_info *depth_net_get_info(const depth_net *net) { return &net->info; }

static pg_status parse_kind(const char *text, const char *what, int *disparity)
{
    if (!strcmp(text, "depth")) *disparity = 0;
    else if (!strcmp(text, "disparity")) *disparity = 1;
    else return pg_fail(PG_ERR_ARG, "%s: output kind must be depth or disparity (got '%s')", what, text);
    return PG_OK;
}

/* MODEL.json's "input_size" [w, h] into wh, 0 0 when the sidecar or the key is absent: the one
 * check of it for fixed and dynamic models alike, so a malformed, NaN, fractional or negative
 * size is blamed on the sidecar, never on the model. */
static pg_status sidecar_input_size(const char *model_path, int wh[2])
{
    char side[4200];
    snprintf(side, sizeof side, "%s.json", model_path);
    wh[0] = wh[1] = 0;
    if (!pg_path_exists(side)) return PG_OK;
    cJSON *j;
    PG_TRY(io_json_load(side, &j));
    const cJSON *it = cJSON_GetObjectItemCaseSensitive(j, "input_size");
    pg_status st = PG_OK;
    if (it) {
        int ok = cJSON_IsArray(it) && cJSON_GetArraySize(it) == 2;
        for (int k = 0; ok && k < 2; k++) {
            const cJSON *v = cJSON_GetArrayItem(it, k);
            ok = cJSON_IsNumber(v) && v->valuedouble >= 1 && v->valuedouble <= 8192 && v->valuedouble == floor(v->valuedouble);
            if (ok) wh[k] = (int)v->valuedouble;
        }
        if (!ok) {
            char *text = cJSON_PrintUnformatted(it);
            st = pg_fail(PG_ERR_FORMAT, "%s: \"input_size\" must be [width, height], whole numbers in 1..8192 (got %.60s)", side,
                         text ? text : "?");
            free(text);
            wh[0] = wh[1] = 0;
        }
    }
    cJSON_Delete(j);
    return st;
}

/* Reads MODEL.json when it exists; keys are optional, wrong types or values fail. */
static pg_status read_sidecar(depth_net *net)
{
    char side[4200];
    snprintf(side, sizeof side, "%s.json", net->path);
    if (!pg_path_exists(side)) return PG_OK;
    cJSON *j;
    PG_TRY(io_json_load(side, &j));
    depth_net_info *in = &net->info;
    pg_status st = cJSON_IsObject(j) ? PG_OK : pg_fail(PG_ERR_FORMAT, "%s: must be a JSON object", side);
    in->sidecar = 1;
    const cJSON *it;
    if ((it = cJSON_GetObjectItemCaseSensitive(j, "name")) && cJSON_IsString(it)) snprintf(in->name, sizeof in->name, "%s", it->valuestring);
    if ((it = cJSON_GetObjectItemCaseSensitive(j, "license")) && cJSON_IsString(it)) snprintf(in->license, sizeof in->license, "%s", it->valuestring);
    if (!st && !in->dynamic) { /* dynamic: used (and checked) at load */
        int wh[2];
        st = sidecar_input_size(net->path, wh);
        if (!st && wh[0] && (wh[0] != in->width || wh[1] != in->height))
            st = pg_fail(PG_ERR_FORMAT, "%s: input_size %dx%d, but the model's input is fixed at %dx%d", side, wh[0], wh[1], in->width,
                         in->height);
    }
    if (!st && cJSON_GetObjectItemCaseSensitive(j, "mean")) st = io_json_get_floats(j, "mean", side, in->mean, 3);
    if (!st && cJSON_GetObjectItemCaseSensitive(j, "std")) st = io_json_get_floats(j, "std", side, in->std, 3);
    /* normalisation of [0, 1] pixels: anything far outside these bounds is a broken file */
    for (int k = 0; !st && k < 3; k++)
        if (!(in->std[k] >= 1e-6f && in->std[k] <= 1e3f) || !(fabsf(in->mean[k]) <= 1e3f))
            st = pg_fail(PG_ERR_FORMAT, "%s: mean must be within +-1000 and std in [1e-6, 1000] (got mean %g, std %g)", side,
                         in->mean[k], in->std[k]);
    if (!st && (it = cJSON_GetObjectItemCaseSensitive(j, "channel_order"))) {
        if (!cJSON_IsString(it) || (strcmp(it->valuestring, "rgb") && strcmp(it->valuestring, "bgr")))
            st = pg_fail(PG_ERR_FORMAT, "%s: \"channel_order\" must be \"rgb\" or \"bgr\"", side);
        else in->bgr = !strcmp(it->valuestring, "bgr");
    }
    if (!st && (it = cJSON_GetObjectItemCaseSensitive(j, "output"))) {
        if (!cJSON_IsString(it)) st = pg_fail(PG_ERR_FORMAT, "%s: \"output\" must be \"depth\" or \"disparity\"", side);
        else st = parse_kind(it->valuestring, side, &in->disparity);
        if (st == PG_ERR_ARG) st = PG_ERR_FORMAT;
    }
    if (!st && (it = cJSON_GetObjectItemCaseSensitive(j, "flip_average"))) {
        if (!cJSON_IsBool(it)) st = pg_fail(PG_ERR_FORMAT, "%s: \"flip_average\" must be true or false", side);
        else in->flip = cJSON_IsTrue(it);
    }
    if (!st && cJSON_GetObjectItemCaseSensitive(j, "scale")) {
        double s;
        st = io_json_get_number(j, "scale", side, &s);
        if (!st && !(s >= 1e-12 && s <= 1e12)) st = pg_fail(PG_ERR_FORMAT, "%s: scale must be in [1e-12, 1e12] (got %g)", side, s);
        if (!st) in->scale = (float)s;
    }
    cJSON_Delete(j);
    return st;
}

/* MODEL.json's "multiple_of" (def when absent or unreadable; read_sidecar reports errors). */
static int sidecar_multiple(const char *model_path, int def)
{
    char side[4200];
    snprintf(side, sizeof side, "%s.json", model_path);
    cJSON *j;
    if (!pg_path_exists(side) || io_json_load(side, &j) != PG_OK) return def;
    double v = io_json_number_or(j, "multiple_of", def);
    cJSON_Delete(j);
    return v >= 1 && v <= 1024 ? (int)v : def;
}

/* A dynamic-input model as NCHW (1, 3, h, w): longer side size, the frame's aspect, sides
 * rounded to multiples of the sidecar's multiple_of; without a size, the sidecar's input_size. */
static pg_status load_dynamic(depth_net *net, int size, int frame_width, int frame_height)
{
    int wh[2];
    PG_TRY(sidecar_input_size(net->path, wh));
    if (!size && wh[0]) {
        int64_t fixed[4] = { 1, 3, wh[1], wh[0] };
        net->info.dynamic = 1;
        return nn_model_load_shaped(net->path, 4, fixed, &net->model);
    }
    if (!size) return pg_fail(PG_ERR_ARG, "%s: the model's input size is not fixed; give one with --size N (longer side) or "
                                          "\"input_size\" in %s.json", net->path, net->path);
    int mult = sidecar_multiple(net->path, 14);
    double aspect = frame_width > 0 && frame_height > 0 ? (double)frame_height / frame_width : 1.0;
    double lw = aspect <= 1 ? size : size / aspect, lh = aspect <= 1 ? size * aspect : size;
    int64_t w = (int64_t)(lw / mult + 0.5) * mult, h = (int64_t)(lh / mult + 0.5) * mult;
    if (w < mult) w = mult;
    if (h < mult) h = mult;
    int64_t dims[4] = { 1, 3, h, w };
    net->info.dynamic = 1;
    return nn_model_load_shaped(net->path, 4, dims, &net->model);
}

pg_status depth_net_open(const char *model_path, const char *kind, int size, int frame_width, int frame_height, depth_net **out)
{
    *out = NULL;
    depth_net *net = pg_calloc(1, sizeof *net, "depth network");
    if (!net) return PG_ERR_NOMEM;
    snprintf(net->path, sizeof net->path, "%s", model_path);
    pg_status st = nn_model_load(model_path, &net->model);
    if (st == PG_ERR_FORMAT && strstr(pg_last_error(), "symbolic")) st = load_dynamic(net, size, frame_width, frame_height);
    depth_net_info *in = &net->info;
    if (!st) {
        FILE *f = fopen(model_path, "rb");
        char head[8] = { 0 };
        if (f) {
            if (fread(head, 1, 8, f) != 8) head[0] = 0;
            fclose(f);
        }
        int tflite = memcmp(head + 4, "TFL3", 4) == 0;
        snprintf(in->format, sizeof in->format, "%s", tflite ? "tflite" : "onnx");
        const char *base = strrchr(model_path, '/');
        snprintf(in->name, sizeof in->name, "%s", base ? base + 1 : model_path);
        in->scale = 1;
        in->flip = 1;
        for (int k = 0; k < 3; k++) {
            in->mean[k] = tflite ? 0.0f : (float[]){ 0.485f, 0.456f, 0.406f }[k];
            in->std[k] = tflite ? 1.0f : (float[]){ 0.229f, 0.224f, 0.225f }[k];
        }
        in->disparity = !tflite;
        int64_t d[NN_MAX_DIMS];
        int nd = nn_model_input_shape(net->model, d);
        if (nd == 4 && d[0] == 1 && d[3] == 3) in->nchw = 0, in->height = (int)d[1], in->width = (int)d[2];
        else if (nd == 4 && d[0] == 1 && d[1] == 3) in->nchw = 1, in->height = (int)d[2], in->width = (int)d[3];
        else st = pg_fail(PG_ERR_FORMAT, "%s: the model's input is not one RGB image (1xHxWx3 or 1x3xHxW)", model_path);
        net->in_count = (size_t)3 * in->width * in->height;
    }
    if (!st) {
        int64_t d[NN_MAX_DIMS];
        int nd = nn_model_output_shape(net->model, d), big = 0;
        int64_t s[2] = { 0, 0 };
        for (int k = 0; k < nd; k++)
            if (d[k] > 1) {
                if (big < 2) s[big] = d[k];
                big++;
            }
        if (big != 2) st = pg_fail(PG_ERR_FORMAT, "%s: the model's first output is not one depth map (1xHxWx1, 1x1xHxW, 1xHxW, HxW)", model_path);
        in->out_height = (int)s[0], in->out_width = (int)s[1];
        net->out_count = (size_t)in->out_width * in->out_height;
    }
    if (!st) st = read_sidecar(net);
    if (!st && kind) st = parse_kind(kind, "--kind", &in->disparity);
    if (!st) {
        net->in = pg_malloc(net->in_count * sizeof(float), "depth network input");
        net->out = pg_malloc(net->out_count * sizeof(float), "depth network output");
        if (!net->in || !net->out) st = PG_ERR_NOMEM;
    }
    if (st) {
        depth_net_close(net);
        return st;
    }
    *out = net;
    return PG_OK;
}

pg_status depth_net_infer(depth_net *net, const pg_image *frame, float *depth, int width, int height, int threads)
{
    const depth_net_info *in = &net->info;
    if (frame->channels != 3) return pg_fail(PG_ERR_ARG, "depth network: frame has %d channels (3 needed)", frame->channels);
    pg_image small = { 0 }, full = { 0 }, mean = { 0 };
    PG_TRY(pg_image_resize(&small, frame, in->width, in->height));
    const int passes = in->flip ? 2 : 1;
    pg_status st = pg_image_create(&mean, in->out_width, in->out_height, 1);
    for (int pass = 0; pass < passes && !st; pass++) {
        /* pass 1 feeds the mirrored frame and mirrors its output back */
        for (int y = 0; y < in->height; y++)
            for (int x = 0; x < in->width; x++) {
                size_t p = (size_t)y * in->width + x, q = pass ? (size_t)y * in->width + (in->width - 1 - x) : p;
                for (int k = 0; k < 3; k++) {
                    float v = (small.data[q * 3 + (in->bgr ? 2 - k : k)] - in->mean[k]) / in->std[k];
                    if (in->nchw) net->in[(size_t)k * in->width * in->height + p] = v;
                    else net->in[p * 3 + k] = v;
                }
            }
        st = nn_model_run(net->model, net->in, net->out, threads);
        for (int y = 0; !st && y < in->out_height; y++)
            for (int x = 0; x < in->out_width; x++) {
                int xo = pass ? in->out_width - 1 - x : x;
                mean.data[(size_t)y * in->out_width + xo] += net->out[(size_t)y * in->out_width + x] / passes;
            }
    }
    pg_image_destroy(&small);
    if (!st) st = pg_image_resize(&full, &mean, width, height);
    pg_image_destroy(&mean);
    if (st) return st;
    size_t n = (size_t)width * height;
    for (size_t i = 0; i < n; i++) {
        float v = full.data[i] * in->scale;
        if (in->disparity) v = isfinite(v) && v > 0 ? 1.0f / v : 0.0f;
        depth[i] = isfinite(v) ? v : 0.0f;
    }
    pg_image_destroy(&full);
    return PG_OK;
}
