/* test_depth_model.c - learned depth in the pipeline's first stage, on a tiny synthetic TFLite
 * model (tests/tflite_writer.h) and a generated clip: pg_depth_run (resume after an interrupt,
 * the result equal to one uninterrupted run, skip when current, the MODEL.json sidecar) and the
 * CLI (`prodygs depth`, `prepare --depth-model`, hostile model files: exit 2 with one line). */
#include "testlib.h"
#include "tflite_writer.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/fileutil.h"
#include "depth/depth_net.h"
#include "io/npy.h"
#include "io/video.h"
#include "synth/synth.h"

#define VW 48
#define VH 32
#define VF 8

/* x (1,16,24,3) -> CONV_2D 3x3 SAME, one output channel: 0.3 * (r + g + b) summed over the
 * window + 1 (a positive "depth" brighter = farther) -> (1,16,24,1). */
static float tiny_w[27], tiny_b[1] = { 1.0f };

/* unsupported: 1 adds a SOFTMAX; 2 makes the conv read its own output (a cycle); 3 gives the
 * input a 2^30 dimension; 4 makes the weights' shape lie about their buffer. */
static uint8_t *tiny_model(size_t *n, int unsupported)
{
    for (int i = 0; i < 27; i++) tiny_w[i] = 0.3f / 9.0f;
    tw_model *m = calloc(1, sizeof *m);
    int x = tw_tensor(m, "image", 4, (int[]){ 1, 16, 24, 3 }, TW_F32, NULL, 0);
    int w = tw_tensor(m, "w", 4, (int[]){ 1, 3, 3, 3 }, TW_F32, tiny_w, sizeof tiny_w);
    int b = tw_tensor(m, "b", 1, (int[]){ 1 }, TW_F32, tiny_b, sizeof tiny_b);
    int y = tw_tensor(m, "depth", 4, (int[]){ 1, 16, 24, 1 }, TW_F32, NULL, 0);
    tw_op(m, 3, (int[]){ x, w, b }, 3, y, 1, 4, (int32_t[]){ 0, 1, 1, 0 }, "biib");
    if (unsupported == 2) m->ops[0].inputs[0] = y;
    if (unsupported == 3) m->tensors[x].dims[1] = 1 << 30;
    if (unsupported == 4) m->tensors[w].dims[0] = 4;
    if (unsupported == 1) {
        int z = tw_tensor(m, "probs", 4, (int[]){ 1, 16, 24, 1 }, TW_F32, NULL, 0);
        tw_op(m, 25, (int[]){ y }, 1, z, 0, 0, NULL, ""); /* SOFTMAX */
        y = z;
    }
    m->inputs[m->num_inputs++] = x;
    m->outputs[m->num_outputs++] = y;
    uint8_t *bytes = tw_build(m, n);
    free(m);
    return bytes;
}

static void write_bytes(const char *path, const uint8_t *b, size_t n) { CHECK_OK(pg_write_file_atomic(path, b, n)); }

static void write_clip(const char *path)
{
    pg_image frames[VF];
    for (int t = 0; t < VF; t++) {
        pg_image_create(&frames[t], VW, VH, 3);
        for (int y = 0; y < VH; y++)
            for (int x = 0; x < VW; x++) {
                float *p = pg_image_at(&frames[t], x, y);
                p[0] = (float)x / VW;
                p[1] = (float)y / VH;
                p[2] = (float)((x + 3 * t) % VW) / VW;
            }
    }
    CHECK_OK(io_video_write(path, frames, VF, NULL, NULL));
    for (int t = 0; t < VF; t++) pg_image_destroy(&frames[t]);
}

/* A depth-stage config for clip through model into out. */
static pg_depth_config depth_config(const char *clip, const char *model, const char *out, int threads)
{
    pg_depth_config c;
    pg_depth_defaults(&c);
    c.input = clip;
    c.model = model;
    c.out = out;
    c.threads = threads;
    return c;
}

static int count_files(const char *dir, const char *suffix)
{
    char cmd[4400], out[64] = "";
    snprintf(cmd, sizeof cmd, "ls '%s' 2>/dev/null | grep -c '%s$'", dir, suffix);
    FILE *p = popen(cmd, "r");
    if (!p) return -1;
    if (!fgets(out, sizeof out, p)) out[0] = '\0';
    pclose(p);
    return atoi(out);
}

static void test_stage(const char *tmp, const char *clip, const char *model)
{
    char out[4200], cache[4300], fresh[4200];
    snprintf(out, sizeof out, "%s/a/depth.npy", tmp);
    snprintf(cache, sizeof cache, "%s.cache", out);
    snprintf(fresh, sizeof fresh, "%s/b/depth.npy", tmp);
    char dir[4200];
    snprintf(dir, sizeof dir, "%s/a", tmp);
    pg_mkdir_p(dir);
    snprintf(dir, sizeof dir, "%s/b", tmp);
    pg_mkdir_p(dir);

    pg_depth_config c = depth_config(clip, model, out, 2);
    c.stop_after = 3;
    pg_depth_report r;
    CHECK_OK(pg_depth_run(&c, &r));
    CHECK(!r.finished && r.computed == 3 && !pg_path_exists(out), "interrupted: %d computed, finished %d", r.computed, r.finished);
    CHECK(count_files(cache, ".npy") == 3, "three frames cached (%d)", count_files(cache, ".npy"));
    c.stop_after = 0;
    CHECK_OK(pg_depth_run(&c, &r));
    CHECK(r.finished && r.reused == 3 && r.computed == VF - 3, "resumed: %d reused, %d computed", r.reused, r.computed);
    CHECK(pg_path_exists(out) && !pg_path_exists(cache), "output written, cache removed");
    c.out = fresh;
    CHECK_OK(pg_depth_run(&c, &r));
    CHECK(test_files_equal(out, fresh), "resumed result equals one uninterrupted run");
    CHECK_OK(pg_depth_run(&c, &r));
    CHECK(r.skipped, "a rerun with the same model and input does nothing");

    /* the tiny model's input (and output) is 24 x 16: frames are decoded at that size, and the
     * output stays at it (a 48 x 32 map would only interpolate what the network saw) */
    CHECK(r.decode_width == VW / 2 && r.decode_height == VH / 2 && r.width == VW / 2 && r.height == VH / 2,
          "decoded at %dx%d, written at %dx%d (24x16 both wanted)", r.decode_width, r.decode_height, r.width, r.height);
    pg_array a;
    CHECK_OK(io_npy_load(out, &a));
    CHECK(a.ndim == 3 && a.shape[0] == VF && a.shape[1] == VH / 2 && a.shape[2] == VW / 2, "shape (%zu, %zu, %zu)", a.shape[0],
          a.shape[1], a.shape[2]);
    int ok = 1;
    for (size_t i = 0; i < a.count; i++) ok &= isfinite(a.data[i]) && a.data[i] >= 1.0f && a.data[i] < 4.0f;
    CHECK(ok, "depth finite in the model's range [1, 4)");

    /* the sidecar: disparity with scale 2 -> depth = 1 / (2 * raw), and the key changes */
    char side[4300];
    snprintf(side, sizeof side, "%s.json", model);
    const char *js = "{\"name\": \"tiny\", \"output\": \"disparity\", \"scale\": 2, \"input_size\": [24, 16]}";
    write_bytes(side, (const uint8_t *)js, strlen(js));
    c.out = out;
    CHECK_OK(pg_depth_run(&c, &r));
    CHECK(!r.skipped && r.computed == VF && !strcmp(r.kind, "disparity") && !strcmp(r.model_name, "tiny"), "sidecar read (kind %s)", r.kind);
    pg_array d;
    CHECK_OK(io_npy_load(out, &d));
    double worst = 0;
    for (size_t i = 0; a.data && d.data && i < a.count; i++) worst = fmax(worst, fabs(d.data[i] * a.data[i] * 2 - 1));
    CHECK(worst < 2.0 / 2048, "disparity inverted: |2 * raw * depth - 1| <= %g (both stored float16)", worst);
    pg_array_destroy(&a);
    pg_array_destroy(&d);
    /* an output size asked for (the working size a run trains at): written at it, a new key */
    c.out_width = VW;
    c.out_height = 0;
    CHECK_OK(pg_depth_run(&c, &r));
    CHECK(!r.skipped && r.width == VW && r.height == VH && r.decode_width == VW / 2, "out size %dx%d (48x32 wanted), decoded %dx%d",
          r.width, r.height, r.decode_width, r.decode_height);
    CHECK_OK(io_npy_load(out, &d));
    CHECK(d.ndim == 3 && d.shape[1] == VH && d.shape[2] == VW, "shape (%zu, %zu, %zu)", d.shape[0], d.shape[1], d.shape[2]);
    pg_array_destroy(&d);
    c.out_width = -1;
    CHECK(pg_depth_run(&c, &r) == PG_ERR_ARG && strstr(pg_last_error(), "--out-size"), "bad out size: %s", pg_last_error());
    c.out_width = 0;
    /* a sidecar that contradicts the model */
    js = "{\"input_size\": [640, 448]}";
    write_bytes(side, (const uint8_t *)js, strlen(js));
    CHECK(pg_depth_run(&c, &r) == PG_ERR_FORMAT && strstr(pg_last_error(), "input_size"), "bad sidecar: %s", pg_last_error());
    remove(side);
    /* --size cannot change a fixed input */
    c.size = 320;
    CHECK(pg_depth_run(&c, &r) == PG_ERR_ARG && strstr(pg_last_error(), "fixed"), "size: %s", pg_last_error());
}

static int one_line(const char *s)
{
    const char *nl = strchr(s, '\n');
    return nl && nl[1] == '\0' && strncmp(s, "prodygs: ", 9) == 0;
}

static void test_cli(const char *tmp, const char *clip, const char *model)
{
    char args[32768], err[4096], path[4200];
    snprintf(args, sizeof args, "depth '%s' --model '%s' --out '%s/cli/depth.npy' --threads 2", clip, model, tmp);
    snprintf(path, sizeof path, "%s/cli", tmp);
    pg_mkdir_p(path);
    int rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 0, "prodygs depth: rc %d: %s", rc, err);
    snprintf(path, sizeof path, "%s/cli/depth.npy", tmp);
    CHECK(pg_path_exists(path), "depth.npy written");

    /* hostile models: truncated, unsupported op, not a model */
    size_t n;
    uint8_t *good = tiny_model(&n, 0);
    char bad[4200];
    snprintf(bad, sizeof bad, "%s/truncated.tflite", tmp);
    write_bytes(bad, good, n / 2);
    snprintf(args, sizeof args, "depth '%s' --model '%s' --out '%s/x.npy'", clip, bad, tmp);
    rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 2 && one_line(err) && strstr(err, "truncated.tflite"), "truncated model: rc %d: %s", rc, err);
    free(good);
    uint8_t *uns = tiny_model(&n, 1);
    snprintf(bad, sizeof bad, "%s/softmax.tflite", tmp);
    write_bytes(bad, uns, n);
    free(uns);
    snprintf(args, sizeof args, "depth '%s' --model '%s' --out '%s/x.npy'", clip, bad, tmp);
    rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 2 && one_line(err) && strstr(err, "SOFTMAX") && strstr(err, "operator 1"), "unsupported op: rc %d: %s", rc, err);
    snprintf(args, sizeof args, "depth '%s' --model '%s' --out '%s/x.npy'", clip, clip, tmp);
    rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 2 && one_line(err), "a video as the model: rc %d: %s", rc, err);
    static const char *hostile[3] = { "cycle", "huge_dims", "lying_size" };
    for (int k = 0; k < 3; k++) {
        uint8_t *hb = tiny_model(&n, 2 + k);
        snprintf(bad, sizeof bad, "%s/%s.tflite", tmp, hostile[k]);
        write_bytes(bad, hb, n);
        free(hb);
        snprintf(args, sizeof args, "depth '%s' --model '%s' --out '%s/x.npy'", clip, bad, tmp);
        rc = test_run_cli(args, err, sizeof err);
        CHECK(rc == 2 && one_line(err) && strstr(err, hostile[k]), "%s model: rc %d: %s", hostile[k], rc, err);
    }
    /* no --model: the built-in FastDepth, written to the cache folder and said so on stderr */
    char cache[4200], built_in[4300], shipped[4300];
    snprintf(cache, sizeof cache, "%s/xdg_cache", tmp);
    setenv("XDG_CACHE_HOME", cache, 1);
    snprintf(args, sizeof args, "depth '%s' --out '%s/default.npy' --threads 2", clip, tmp);
    rc = test_run_cli(args, err, sizeof err);
    snprintf(path, sizeof path, "%s/default.npy", tmp);
    CHECK(rc == 0 && strstr(err, "depth: no --model given, using the embedded FastDepth (MIT") && pg_path_exists(path),
          "no --model: rc %d: %s", rc, err);
    snprintf(built_in, sizeof built_in, "%s/prodygs/fastdepth_224_int8.tflite", cache);
    snprintf(shipped, sizeof shipped, "%s/models/fastdepth_224_int8.tflite", PG_SOURCE_DIR);
    char *a = NULL, *b = NULL;
    size_t na = 0, nb = 0;
    CHECK(pg_read_file(built_in, (size_t)8 << 20, &a, &na) == PG_OK && pg_read_file(shipped, (size_t)8 << 20, &b, &nb) == PG_OK &&
              na == nb && memcmp(a, b, na) == 0,
          "the embedded model is models/fastdepth_224_int8.tflite byte for byte (%zu, %zu bytes)", na, nb);
    free(a);
    free(b);
    snprintf(args, sizeof args, "prepare '%s' --depth-model '%s' --depth '%s/cli/depth.npy' --out '%s/p'", clip, model, tmp, tmp);
    rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 2 && one_line(err) && strstr(err, "not both"), "both --depth and --depth-model: rc %d: %s", rc, err);

    /* prepare straight from the model */
    snprintf(args, sizeof args, "prepare '%s' --depth-model '%s' --out '%s/prep' --threads 2 --no-flow-vis", clip, model, tmp);
    rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 0, "prepare --depth-model: rc %d: %s", rc, err);
    snprintf(path, sizeof path, "%s/prep/depth.npy", tmp);
    CHECK(pg_path_exists(path), "prepare ran the depth stage into DIR/depth.npy");
    snprintf(path, sizeof path, "%s/prep/depth_aligned.npy", tmp);
    CHECK(pg_path_exists(path), "prepare finished");

    /* prepare without --depth / --depth-model: the built-in FastDepth first */
    snprintf(args, sizeof args, "prepare '%s' --out '%s/prep_default' --threads 2 --no-flow-vis", clip, tmp);
    rc = test_run_cli(args, err, sizeof err);
    snprintf(path, sizeof path, "%s/prep_default/depth_aligned.npy", tmp);
    CHECK(rc == 0 && strstr(err, "depth: no --depth/--depth-model given, using the embedded FastDepth (MIT") && pg_path_exists(path),
          "prepare with the built-in model: rc %d: %s", rc, err);
}

/* A dynamic-input ONNX model (exported here with torch when /usr/bin/python3 has it, else
 * skipped): refused without --size, run at the longer side rounded to multiples of 14. */
static void test_dynamic_onnx(const char *tmp, const char *clip)
{
    char script[4200], model[4200], cmd[16384], out[4200];
    snprintf(script, sizeof script, "%s/mkdyn.py", tmp);
    snprintf(model, sizeof model, "%s/dyn_depth.onnx", tmp);
    const char *py =
        "import sys, torch, torch.nn as nn\n"
        "class Net(nn.Module):\n"
        "    def __init__(s):\n"
        "        super().__init__(); s.a = nn.Conv2d(3, 4, 3, padding=1); s.b = nn.Conv2d(4, 1, 3, padding=1)\n"
        "    def forward(s, x): return torch.relu(s.b(torch.relu(s.a(x)))) + 1.0\n"
        "torch.manual_seed(0)\n"
        "with torch.no_grad():\n"
        "    torch.onnx.export(Net().eval(), (torch.rand(1, 3, 28, 42),), sys.argv[1], opset_version=17, input_names=['image'],\n"
        "                      output_names=['depth'], dynamic_axes={'image': {2: 'h', 3: 'w'}, 'depth': {2: 'h', 3: 'w'}})\n";
    write_bytes(script, (const uint8_t *)py, strlen(py));
    snprintf(cmd, sizeof cmd, "/usr/bin/python3 '%s' '%s' >/dev/null 2>&1", script, model);
    if (system(cmd) != 0 || !pg_path_exists(model)) {
        printf("SKIP dynamic ONNX model: /usr/bin/python3 with torch not available\n");
        return;
    }
    snprintf(out, sizeof out, "%s/dyn.npy", tmp);
    pg_depth_config c = depth_config(clip, model, out, 2);
    pg_depth_report r;
    CHECK(pg_depth_run(&c, &r) == PG_ERR_ARG && strstr(pg_last_error(), "--size"), "no size: %s", pg_last_error());
    c.size = 100;
    CHECK_OK(pg_depth_run(&c, &r));
    CHECK(r.model_width == 98 && r.model_height == 70 && !strcmp(r.kind, "disparity"), "dynamic input %dx%d (98x70 wanted), kind %s",
          r.model_width, r.model_height, r.kind);
    pg_array a;
    CHECK_OK(io_npy_load(out, &a));
    CHECK(a.ndim == 3 && a.shape[0] == VF && a.shape[1] == VH && a.shape[2] == VW, "dynamic model output (%zu, %zu, %zu)", a.shape[0],
          a.shape[1], a.shape[2]);
    pg_array_destroy(&a);
    /* or the size from the sidecar (as the pipeline's --depth-model has no --size) */
    char side[4300];
    snprintf(side, sizeof side, "%s.json", model);
    const char *js = "{\"input_size\": [56, 42]}";
    write_bytes(side, (const uint8_t *)js, strlen(js));
    c.size = 0;
    CHECK_OK(pg_depth_run(&c, &r));
    CHECK(r.model_width == 56 && r.model_height == 42, "sidecar input_size %dx%d (56x42 wanted)", r.model_width, r.model_height);
}

/* The pipeline with depth_model: the depth stage runs first and has its own marker; a rerun
 * skips it; a model with new content reruns it and every stage after. */
static void run_with_model(const char *data, const char *model, const char *out, pg_pipeline_report *r)
{
    pg_pipeline_config c;
    pg_pipeline_defaults(&c);
    c.input = data;
    c.depth_model = model;
    c.out = out;
    c.test_cameras = "cam05,cam06";
    c.iters = 12;
    c.threads = 2;
    c.evaluate = 1;
    pg_status st = pg_pipeline_run(&c, r);
    CHECK(st == PG_OK, "pipeline with a depth model: %s", st ? pg_last_error() : "");
}

static void test_pipeline(const char *tmp, const char *model)
{
    char data[4200], out[4200], path[4400];
    snprintf(data, sizeof data, "%s/synth", tmp);
    snprintf(out, sizeof out, "%s/pipe", tmp);
    synth_options so;
    synth_options_default(&so);
    so.cams = 7;
    so.frames = 3;
    so.width = 32;
    so.height = 24;
    so.spp = 1;
    CHECK_OK(synth_write_dataset(data, &so));
    pg_pipeline_report r;
    run_with_model(data, model, out, &r);
    CHECK(r.ran[5] && r.ran[0] && r.ran[1] && r.ran[2] && r.ran[3], "first run: depth and every stage ran (%d %d %d %d %d)", r.ran[5],
          r.ran[0], r.ran[1], r.ran[2], r.ran[3]);
    snprintf(path, sizeof path, "%s/depth/depth.npy", out);
    CHECK(pg_path_exists(path), "OUT/depth/depth.npy written");
    run_with_model(data, model, out, &r);
    CHECK(!r.ran[5] && !r.ran[0] && !r.ran[1] && !r.ran[2], "rerun: depth and stages skipped (%d %d %d %d)", r.ran[5], r.ran[0],
          r.ran[1], r.ran[2]);
    /* another model under the same path */
    tiny_b[0] = 2.0f;
    size_t n;
    uint8_t *bytes = tiny_model(&n, 0);
    write_bytes(model, bytes, n);
    free(bytes);
    tiny_b[0] = 1.0f;
    run_with_model(data, model, out, &r);
    CHECK(r.ran[5] && r.ran[0] && r.ran[1] && r.ran[2], "new model: depth and the stages after it rerun (%d %d %d %d)", r.ran[5],
          r.ran[0], r.ran[1], r.ran[2]);
}

/* Issue 27: sidecar numbers checked as double but used as float (1e39 became inf, 1e-300 zero,
 * and the run exited 0 with constant or invalid depth), sidecars that are not objects or carry
 * trailing data, and a network whose output is all invalid: each one line, exit 2, no output. */
static void test_hostile_sidecars(const char *tmp, const char *clip)
{
    char model[4200], side[4300], out[4200];
    snprintf(model, sizeof model, "%s/hostile.tflite", tmp);
    snprintf(side, sizeof side, "%s.json", model);
    snprintf(out, sizeof out, "%s/hostile/depth.npy", tmp);
    size_t n;
    uint8_t *bytes = tiny_model(&n, 0);
    write_bytes(model, bytes, n);
    free(bytes);
    static const char *const bad[][2] = {
        { "{\"mean\": [1e39, 0, 0]}", "mean" },        { "{\"scale\": 1e39}", "scale" },
        { "{\"scale\": 1e-300}", "scale" },             { "{\"std\": [1e-30, 1, 1]}", "std" },
        { "null", "object" },                             { "[1, 2]", "object" },
        { "{\"scale\": 2} {\"scale\": 3}", "trailing" }, { "{\"channel_order\": \"grb\"}", "channel_order" },
    };
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; k++) {
        write_bytes(side, (const uint8_t *)bad[k][0], strlen(bad[k][0]));
        char args[16384], err[4096];
        snprintf(args, sizeof args, "depth '%s' --model '%s' --out '%s' --threads 1", clip, model, out);
        int rc = test_run_cli(args, err, sizeof err);
        CHECK(rc == 2 && strstr(err, bad[k][1]) && strstr(err, "hostile.tflite.json") && !pg_path_exists(out),
              "sidecar %s: exit %d, %s", bad[k][0], rc, err);
    }
    remove(side);
    /* every output value negative: an error at the depth stage, not an empty map later */
    tiny_b[0] = -50.0f;
    bytes = tiny_model(&n, 0);
    write_bytes(model, bytes, n);
    free(bytes);
    tiny_b[0] = 1.0f;
    pg_depth_config c = depth_config(clip, model, out, 1);
    pg_depth_report r;
    CHECK(pg_depth_run(&c, &r) == PG_ERR_FORMAT && strstr(pg_last_error(), "no valid depth") && !pg_path_exists(out),
          "all-invalid network output: %s", pg_last_error());
}

/* MODEL.json "channel_order": a 1x1 conv reading the network's channel 0 sees the frame's red,
 * or its blue with "bgr". */
static void test_channel_order(const char *tmp)
{
    static float w[3] = { 1, 0, 0 }, bias[1] = { 0.5f };
    tw_model *m = calloc(1, sizeof *m);
    int x = tw_tensor(m, "x", 4, (int[]){ 1, 4, 4, 3 }, TW_F32, NULL, 0);
    int tw = tw_tensor(m, "w", 4, (int[]){ 1, 1, 1, 3 }, TW_F32, w, sizeof w);
    int tb = tw_tensor(m, "b", 1, (int[]){ 1 }, TW_F32, bias, sizeof bias);
    int y = tw_tensor(m, "y", 4, (int[]){ 1, 4, 4, 1 }, TW_F32, NULL, 0);
    tw_op(m, 3, (int[]){ x, tw, tb }, 3, y, 1, 4, (int32_t[]){ 0, 1, 1, 0 }, "biib");
    m->inputs[m->num_inputs++] = x;
    m->outputs[m->num_outputs++] = y;
    size_t n;
    uint8_t *bytes = tw_build(m, &n);
    free(m);
    char model[4200], side[4300];
    snprintf(model, sizeof model, "%s/red.tflite", tmp);
    snprintf(side, sizeof side, "%s.json", model);
    write_bytes(model, bytes, n);
    free(bytes);
    float px[4 * 4 * 3], depth[16];
    for (int i = 0; i < 16; i++) px[3 * i] = 0.25f, px[3 * i + 1] = 0.5f, px[3 * i + 2] = 0.75f;
    pg_image frame = { 4, 4, 3, px };
    for (int bgr = 0; bgr < 2; bgr++) {
        const char *json = bgr ? "{\"channel_order\": \"bgr\"}" : "{\"channel_order\": \"rgb\"}";
        write_bytes(side, (const uint8_t *)json, strlen(json));
        depth_net *net = NULL;
        CHECK_OK(depth_net_open(model, NULL, 0, 4, 4, &net));
        if (!net) continue;
        CHECK_OK(depth_net_infer(net, &frame, depth, 4, 4, 1));
        float want = (bgr ? 0.75f : 0.25f) + 0.5f;
        CHECK(fabsf(depth[5] - want) < 1e-6f && depth_net_get_info(net)->bgr == bgr, "channel_order %s: %g, want %g", bgr ? "bgr" : "rgb",
              depth[5], want);
        depth_net_close(net);
    }
}

/* The built-in FastDepth with its mirrored pass: the output is the mean of the plain output and
 * the mirrored output of the mirrored frame, so it differs from the plain one; "flip_average":
 * false gives the plain one, a non-boolean is refused. */
static void test_flip_average(const char *tmp)
{
    char model[4200], side[4300], src[4200];
    snprintf(src, sizeof src, "%s/models/fastdepth_224_int8.tflite", PG_SOURCE_DIR);
    snprintf(model, sizeof model, "%s/fd.tflite", tmp);
    snprintf(side, sizeof side, "%s.json", model);
    char *bytes = NULL;
    size_t n = 0;
    CHECK_OK(pg_read_file(src, 1 << 24, &bytes, &n));
    if (!bytes) return;
    write_bytes(model, (const uint8_t *)bytes, n);
    free(bytes);
    enum { W = 224, H = 224 };
    pg_image frame, mirror;
    CHECK_OK(pg_image_create(&frame, W, H, 3));
    CHECK_OK(pg_image_create(&mirror, W, H, 3));
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            for (int c = 0; c < 3; c++) {
                float v = 0.5f + 0.4f * sinf(0.07f * x * (c + 1) + 0.05f * y) * (x < W / 3 ? 0.3f : 1.0f);
                frame.data[((size_t)y * W + x) * 3 + c] = v;
                mirror.data[((size_t)y * W + (W - 1 - x)) * 3 + c] = v;
            }
    float *plain = malloc(sizeof(float) * W * H * 3), *plain_m = plain + W * H, *both = plain_m + W * H;
    const char *off = "{\"channel_order\": \"bgr\", \"flip_average\": false}", *on = "{\"channel_order\": \"bgr\"}";
    depth_net *net = NULL;
    write_bytes(side, (const uint8_t *)off, strlen(off));
    CHECK_OK(depth_net_open(model, NULL, 0, W, H, &net));
    if (net) {
        CHECK(!depth_net_get_info(net)->flip, "flip_average false read");
        CHECK_OK(depth_net_infer(net, &frame, plain, W, H, 1));
        CHECK_OK(depth_net_infer(net, &mirror, plain_m, W, H, 1));
        depth_net_close(net);
    }
    write_bytes(side, (const uint8_t *)on, strlen(on));
    net = NULL;
    CHECK_OK(depth_net_open(model, NULL, 0, W, H, &net));
    if (net) {
        CHECK(depth_net_get_info(net)->flip, "flip_average is the default");
        CHECK_OK(depth_net_infer(net, &frame, both, W, H, 1));
        depth_net_close(net);
    }
    double err = 0, diff = 0;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            size_t i = (size_t)y * W + x, m = (size_t)y * W + (W - 1 - x);
            err = fmax(err, fabs(both[i] - 0.5 * (plain[i] + plain_m[m])) / plain[i]);
            diff = fmax(diff, fabs(both[i] - plain[i]) / plain[i]);
        }
    CHECK(err < 1e-4 && diff > 0.01, "flip average: off the mean of both passes by %g, off the plain pass by %g", err, diff);
    write_bytes(side, (const uint8_t *)"{\"flip_average\": 1}", 19);
    net = NULL;
    CHECK(depth_net_open(model, NULL, 0, W, H, &net) == PG_ERR_FORMAT && strstr(pg_last_error(), "flip_average"),
          "a non-boolean flip_average is refused: %s", pg_last_error());
    depth_net_close(net);
    free(plain);
    pg_image_destroy(&frame);
    pg_image_destroy(&mirror);
}

int main(void)
{
    char tmp[4096], clip[4200], model[4200];
    test_tmpdir("depth_model", tmp, sizeof tmp);
    snprintf(clip, sizeof clip, "%s/clip.mp4", tmp);
    snprintf(model, sizeof model, "%s/tiny.tflite", tmp);
    write_clip(clip);
    size_t n;
    uint8_t *bytes = tiny_model(&n, 0);
    write_bytes(model, bytes, n);
    free(bytes);
    test_stage(tmp, clip, model);
    test_cli(tmp, clip, model);
    test_dynamic_onnx(tmp, clip);
    test_pipeline(tmp, model);
    test_hostile_sidecars(tmp, clip);
    test_channel_order(tmp);
    test_flip_average(tmp);
    return test_summary("test_depth_model");
}
