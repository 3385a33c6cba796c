/* pipeline.c - stage sequencing with resumable markers (see pipeline.h). */
#include "cli/pipeline.h"
#include "cli/cli.h"
#include "core/fileutil.h"
#include "core/parallel.h"
#include "io/dataset.h"
#include "io/json.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAX_ARGS 48

typedef struct {
    const char *name;
    int iters;
    int proxies;
    int max_side; /* shrink larger inputs so the longer side is at most this */
} preset;

/* fast: minutes on 2 cores for a short clip at up to 320 px; quality: 5x the iterations at up to 640 px. */
static const preset presets[] = {
    { "fast", 1500, 8, 320 },
    { "quality", 8000, -1, 640 },
};

/* Picks an even WxH with the input's aspect ratio and the longer side at most max_side;
 * leaves o->size unset when the input is already small enough or cannot be probed (the
 * stages then report the real problem with the input). */
static void pick_size(pipeline_options *o, int max_side)
{
    pg_dataset *ds = NULL;
    io_dataset_options opt = io_dataset_defaults();
    if (io_dataset_open(o->input, &opt, &ds) != PG_OK) return;
    int w = io_dataset_width(ds), h = io_dataset_height(ds);
    io_dataset_close(ds);
    int side = w > h ? w : h;
    if (side <= max_side || side <= 0) return;
    int nw = (int)((double)w * max_side / side + 0.5) & ~1, nh = (int)((double)h * max_side / side + 0.5) & ~1;
    snprintf(o->size_buf, sizeof o->size_buf, "%dx%d", nw, nh);
    o->size = o->size_buf;
}

/* Rejects bad numbers and names before any stage runs, so a typo fails at once with one line
 * instead of after minutes of depth preparation (0 means "default" for the numeric fields). */
static int validate_options(const pipeline_options *o)
{
    if (o->iters < 0) return cli_usage_error("--iters must be >= 1 (got %d)", o->iters);
    if (o->frames < 0) return cli_usage_error("--frames must be >= 1 (got %d)", o->frames);
    if (o->threads < 0 || o->threads > 256) return cli_usage_error("--threads must be in 1..256 (got %d)", o->threads);
    if (o->seed < 0) return cli_usage_error("--seed must be >= 0 (got %d)", o->seed);
    if (o->depth_scale < 0) return cli_usage_error("--depth-scale must be > 0 (got %g)", o->depth_scale);
    if (o->pose_scale < 0) return cli_usage_error("--pose-scale must be > 0 (got %g)", o->pose_scale);
    if (o->max_angle < 0 || o->max_angle >= 90)
        return cli_usage_error("--max-angle must be in (0, 90) degrees (got %g)", o->max_angle);
    if (o->pad > 1 || (o->pad < 0 && o->pad != -1)) return cli_usage_error("--pad must be in [0, 1] (got %g)", o->pad);
    if (o->poses && strcmp(o->poses, "hemisphere") != 0 && strcmp(o->poses, "dataset") != 0)
        return cli_usage_error("--poses must be hemisphere or dataset (got '%s')", o->poses);
    if (o->depth_kind && strcmp(o->depth_kind, "depth") != 0 && strcmp(o->depth_kind, "disparity") != 0)
        return cli_usage_error("--depth-kind must be depth or disparity (got '%s')", o->depth_kind);
    if (o->size) {
        int w = -1, h = -1;
        char tail = 0;
        if (sscanf(o->size, "%dx%d%c", &w, &h, &tail) != 2 || w < 0 || h < 0 || w > 8192 || h > 8192 || (w == 0 && h == 0))
            return cli_usage_error("--size expects WxH with sides up to 8192 (0 keeps the aspect), got '%s'", o->size);
    }
    return 0;
}

/* Resolves --train-cam and --test-cams against the input once (io_dataset_resolve_camera) and
 * rewrites them as camera names, so every stage picks the same cameras whatever the spelling.
 * A single video has one camera and nothing to resolve. */
static int resolve_cameras(pipeline_options *o)
{
    pg_dataset *ds = NULL;
    io_dataset_options opt = io_dataset_defaults();
    if (io_dataset_open(o->input, &opt, &ds) != PG_OK) return 0; /* the first stage reports the input */
    int rc = 0, cam = 0, tests[64], nt = 0;
    if (o->train_cam && io_dataset_resolve_camera(ds, o->train_cam, &cam) != PG_OK)
        rc = cli_usage_error("%s: --train-cam: %s", o->input, pg_last_error());
    if (!rc && o->test_cams && io_dataset_resolve_cameras(ds, o->test_cams, tests, 64, &nt) != PG_OK)
        rc = cli_usage_error("%s: --test-cams: %s", o->input, pg_last_error());
    for (int k = 0; !rc && k < nt; k++)
        if (tests[k] == cam)
            rc = cli_usage_error("%s: camera %s is both the training camera and a test camera", o->input,
                                 io_dataset_camera_name(ds, cam));
    if (!rc) {
        if (o->train_cam) {
            snprintf(o->train_cam_buf, sizeof o->train_cam_buf, "%s", io_dataset_camera_name(ds, cam));
            o->train_cam = o->train_cam_buf;
        }
        io_dataset_camera_label(ds, cam, o->train_label, sizeof o->train_label);
        o->test_cams_buf[0] = o->test_labels[0] = '\0';
        for (int k = 0; k < nt; k++) {
            char label[160];
            io_dataset_camera_label(ds, tests[k], label, sizeof label);
            size_t a = strlen(o->test_cams_buf), b = strlen(o->test_labels);
            snprintf(o->test_cams_buf + a, sizeof o->test_cams_buf - a, "%s%s", k ? "," : "", io_dataset_camera_name(ds, tests[k]));
            snprintf(o->test_labels + b, sizeof o->test_labels - b, "%s%s", k ? ", " : "", label);
        }
        if (nt > 0) o->test_cams = o->test_cams_buf;
        printf("training camera %s%s%s\n", o->train_label, nt ? "; test cameras " : "", o->test_labels);
        fflush(stdout);
    }
    io_dataset_close(ds);
    return rc;
}

int pipeline_apply_preset(pipeline_options *o)
{
    int rc = validate_options(o);
    if (rc) return rc;
    if (!o->preset) o->preset = "fast";
    for (size_t i = 0; i < sizeof presets / sizeof presets[0]; i++) {
        if (strcmp(o->preset, presets[i].name) != 0) continue;
        if (o->iters <= 0) o->iters = presets[i].iters;
        if (o->proxies < 0 && presets[i].proxies >= 0 && !o->test_cams) o->proxies = presets[i].proxies;
        if (!o->size) pick_size(o, presets[i].max_side);
        if (!o->poses) o->poses = o->test_cams ? "dataset" : "hemisphere";
        return resolve_cameras(o);
    }
    return cli_usage_error("unknown preset '%s' (fast, quality)", o->preset);
}

void pipeline_paths(const pipeline_options *o, char *prepare_dir, char *proxies_dir, char *model_dir, size_t size)
{
    snprintf(prepare_dir, size, "%s/prepare", o->out);
    snprintf(proxies_dir, size, "%s/proxies", o->out);
    snprintf(model_dir, size, "%s/model", o->out);
}

typedef struct {
    char *argv[MAX_ARGS];
    int argc;
    char storage[MAX_ARGS][4200];
} arg_list;

static void args_add(arg_list *a, const char *s)
{
    if (a->argc >= MAX_ARGS - 1) return;
    snprintf(a->storage[a->argc], sizeof a->storage[a->argc], "%s", s);
    a->argv[a->argc] = a->storage[a->argc];
    a->argc++;
    a->argv[a->argc] = NULL;
}

static void args_addf(arg_list *a, const char *flag, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static void args_addf(arg_list *a, const char *flag, const char *fmt, ...)
{
    char buf[4200];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    args_add(a, flag);
    args_add(a, buf);
}

/* The stage's arguments as one string, with the output directory written as "$OUT" so a
 * finished stage still counts after the directory is moved or copied. */
static void args_join(const arg_list *a, const char *out_dir, char *out, size_t size)
{
    out[0] = '\0';
    size_t n = strlen(out_dir);
    for (int i = 0; i < a->argc; i++) {
        const char *arg = a->argv[i];
        if (strncmp(arg, out_dir, n) == 0 && (arg[n] == '/' || arg[n] == '\0')) {
            strncat(out, "$OUT", size - strlen(out) - 1);
            arg += n;
        }
        strncat(out, arg, size - strlen(out) - 1);
        strncat(out, " ", size - strlen(out) - 1);
    }
}

/* Returns 1 if OUT/<stage>.done exists with the same arguments (and adds its time). */
static int stage_done(const char *out, const char *stage, const char *args, cJSON *seconds)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/%s.done", out, stage);
    if (!pg_path_exists(path)) return 0;
    cJSON *root;
    if (io_json_load(path, &root) != PG_OK) return 0;
    int same = strcmp(io_json_string_or(root, "args", ""), args) == 0;
    if (same && seconds) cJSON_AddNumberToObject(seconds, stage, io_json_number_or(root, "seconds", 0));
    cJSON_Delete(root);
    return same;
}

static int stage_mark(const char *out, const char *stage, const char *args, double secs)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/%s.done", out, stage);
    cJSON *root = cJSON_CreateObject();
    cJSON_AddStringToObject(root, "args", args);
    cJSON_AddNumberToObject(root, "seconds", secs);
    pg_status st = io_json_write_atomic(path, root);
    cJSON_Delete(root);
    return st ? cli_fail(st) : 0;
}

/* Runs one stage unless its marker says it already finished with these arguments. A stage that
 * runs again invalidates the markers of every later stage (their inputs changed). */
static int run_stage(const pipeline_options *o, const char *stage, int (*fn)(int, char **), arg_list *a,
                     cJSON *seconds, int *rerun_rest)
{
    char joined[8192];
    args_join(a, o->out, joined, sizeof joined);
    if (!*rerun_rest && stage_done(o->out, stage, joined, seconds)) {
        fprintf(stderr, "prodygs: %s: already done, skipping (delete %s/%s.done to redo)\n", stage, o->out, stage);
        return 0;
    }
    *rerun_rest = 1;
    char marker[4096];
    snprintf(marker, sizeof marker, "%s/%s.done", o->out, stage);
    remove(marker);
    double t0 = pg_time_seconds();
    int rc = fn(a->argc, a->argv);
    if (rc) {
        /* bad input (2) already printed its one line; rerunning only helps after other failures */
        if (rc != 2) fprintf(stderr, "prodygs: stage %s failed (exit %d); rerun the same command to continue\n", stage, rc);
        return rc;
    }
    double secs = pg_time_seconds() - t0;
    if (seconds) cJSON_AddNumberToObject(seconds, stage, secs);
    return stage_mark(o->out, stage, joined, secs);
}

int pipeline_run_stages(const pipeline_options *o, cJSON *seconds)
{
    char prepare_dir[4096], proxies_dir[4096], model_dir[4096];
    pipeline_paths(o, prepare_dir, proxies_dir, model_dir, sizeof prepare_dir);
    pg_status st = pg_mkdir_p(o->out);
    if (st) return cli_fail(st);
    int rerun_rest = 0, rc;

    arg_list a = {0};
    args_add(&a, "prepare");
    args_add(&a, o->input);
    args_addf(&a, "--depth", "%s", o->depth);
    args_addf(&a, "--out", "%s", prepare_dir);
    if (o->depth_kind) args_addf(&a, "--depth-kind", "%s", o->depth_kind);
    if (o->depth_scale > 0) args_addf(&a, "--depth-scale", "%g", o->depth_scale);
    if (o->no_refine) args_add(&a, "--no-refine");
    if (o->no_align) args_add(&a, "--no-align");
    if (o->frames > 0) args_addf(&a, "--frames", "%d", o->frames);
    if (o->size) args_addf(&a, "--size", "%s", o->size);
    if (o->train_cam) args_addf(&a, "--train-cam", "%s", o->train_cam);
    if ((rc = run_stage(o, "prepare", cmd_prepare, &a, seconds, &rerun_rest))) return rc;

    memset(&a, 0, sizeof a);
    args_add(&a, "proxies");
    args_add(&a, o->input);
    args_addf(&a, "--depth", "%s/depth_aligned.npy", prepare_dir);
    args_addf(&a, "--out", "%s", proxies_dir);
    args_addf(&a, "--poses", "%s", o->poses);
    if (o->proxies >= 0) args_addf(&a, "--num", "%d", o->proxies);
    if (o->max_angle > 0) args_addf(&a, "--max-angle", "%g", o->max_angle);
    if (o->fov > 0) args_addf(&a, "--fov", "%g", o->fov);
    if (o->pad >= 0) args_addf(&a, "--pad", "%g", o->pad);
    if (o->train_cam) args_addf(&a, "--train-cam", "%s", o->train_cam);
    if (o->test_cams) args_addf(&a, "--test-cams", "%s", o->test_cams);
    if (o->pose_scale > 0) args_addf(&a, "--pose-scale", "%g", o->pose_scale);
    if (o->frames > 0) args_addf(&a, "--frames", "%d", o->frames);
    if (o->size) args_addf(&a, "--size", "%s", o->size);
    if ((rc = run_stage(o, "proxies", cmd_proxies, &a, seconds, &rerun_rest))) return rc;

    memset(&a, 0, sizeof a);
    args_add(&a, "train");
    args_add(&a, proxies_dir);
    args_addf(&a, "--out", "%s", model_dir);
    args_addf(&a, "--iters", "%d", o->iters);
    if (o->seed) args_addf(&a, "--seed", "%d", o->seed);
    args_add(&a, "--resume");
    if ((rc = run_stage(o, "train", cmd_train, &a, seconds, &rerun_rest))) return rc;

    /* renders and evaluations find the cameras next to the model */
    char src[4200], dst[4200];
    snprintf(src, sizeof src, "%s/trainset.json", proxies_dir);
    snprintf(dst, sizeof dst, "%s/trainset.json", model_dir);
    char *data;
    size_t size;
    st = pg_read_file(src, 64u << 20, &data, &size);
    if (st == PG_OK) {
        st = pg_write_file_atomic(dst, data, size);
        free(data);
    }
    return st ? cli_fail(st) : 0;
}

cJSON *pipeline_config_json(const pipeline_options *o)
{
    cJSON *c = cJSON_CreateObject();
    cJSON_AddStringToObject(c, "input", o->input);
    cJSON_AddStringToObject(c, "depth", o->depth);
    cJSON_AddStringToObject(c, "preset", o->preset);
    cJSON_AddStringToObject(c, "poses", o->poses ? o->poses : "hemisphere");
    cJSON_AddNumberToObject(c, "proxies", o->proxies);
    if (o->pad >= 0) cJSON_AddNumberToObject(c, "pad", o->pad);
    if (o->train_cam) cJSON_AddStringToObject(c, "train_cam", o->train_cam);
    if (o->test_cams) cJSON_AddStringToObject(c, "test_cams", o->test_cams);
    if (o->train_label[0]) cJSON_AddStringToObject(c, "train_camera", o->train_label);
    if (o->test_labels[0]) cJSON_AddStringToObject(c, "test_cameras", o->test_labels);
    cJSON_AddBoolToObject(c, "refine", !o->no_refine);
    cJSON_AddBoolToObject(c, "align", !o->no_align);
    cJSON_AddNumberToObject(c, "iters", o->iters);
    cJSON_AddNumberToObject(c, "frames", o->frames);
    if (o->size) cJSON_AddStringToObject(c, "size", o->size);
    cJSON_AddNumberToObject(c, "threads", pg_get_threads());
    cJSON_AddNumberToObject(c, "seed", o->seed);
    return c;
}

int pipeline_cli_options(pipeline_options *o, const char **proxies_text, cli_option *opts, int max)
{
    memset(o, 0, sizeof *o);
    o->proxies = -1;
    o->pad = -1;
    *proxies_text = NULL;
    const cli_option shared[] = {
        { "--depth", CLI_STR, &o->depth, "per-frame depth of the (training) camera: .npy (F,H,W) or a folder (required)" },
        { "--out", CLI_STR, &o->out, "output directory (required)" },
        { "--preset", CLI_STR, &o->preset, "fast (default) or quality" },
        { "--proxies", CLI_STR, proxies_text, "number of proxy cameras, or all (0 = real view only)" },
        { "--poses", CLI_STR, &o->poses, "proxy poses: hemisphere or dataset (default: dataset with --test-cams)" },
        { "--max-angle", CLI_FLOAT, &o->max_angle, "hemisphere cap angle in degrees (default 20)" },
        { "--fov", CLI_FLOAT, &o->fov, "single video: horizontal field of view in degrees (default 60)" },
        { "--pad", CLI_FLOAT, &o->pad, "proxies: outpainted margin around the real view, fraction of the larger side (0.3; 0 = none)" },
        { "--no-refine", CLI_FLAG, &o->no_refine, "skip edge-aware depth refinement (ablation)" },
        { "--no-align", CLI_FLAG, &o->no_align, "skip temporal scale/shift alignment (ablation)" },
        { "--depth-kind", CLI_STR, &o->depth_kind, "depth (default) or disparity" },
        { "--depth-scale", CLI_FLOAT, &o->depth_scale, "multiply raw depth by S" },
        { "--train-cam", CLI_STR, &o->train_cam, "dataset camera that is the real view (default: first)" },
        { "--frames", CLI_INT, &o->frames, "use only the first N frames" },
        { "--size", CLI_STR, &o->size, "resize to WxH" },
        { "--iters", CLI_INT, &o->iters, "training iterations (default: from the preset)" },
        { "--pose-scale", CLI_FLOAT, &o->pose_scale, "depth-to-pose scale instead of fitting it (dataset poses)" },
        { "--threads", CLI_INT, &o->threads, "worker threads (default: all cores)" },
        { "--seed", CLI_INT, &o->seed, "random seed (default 0)" },
    };
    int n = (int)(sizeof shared / sizeof shared[0]);
    if (n > max) n = max;
    memcpy(opts, shared, (size_t)n * sizeof *opts);
    return n;
}

static int parse_proxies(pipeline_options *o, const char *text)
{
    if (!text) return 0;
    if (strcmp(text, "all") == 0) {
        o->proxies = -1;
        return 0;
    }
    char *end;
    long v = strtol(text, &end, 10);
    if (*end || end == text || v < 0 || v > 1000) return cli_usage_error("--proxies expects a count or 'all', got '%s'", text);
    o->proxies = (int)v;
    return 0;
}

int pipeline_cli_parse(const cli_spec *spec, int argc, char **argv, pipeline_options *o, const char **proxies_text)
{
    const char *pos[1];
    int rc = cli_parse(spec, argc, argv, pos, NULL);
    if (rc) return rc;
    const char *verb = strchr(spec->command, ' ') ? strchr(spec->command, ' ') + 1 : spec->command;
    if (!o->depth || !o->out) return cli_usage_error("%s: --depth and --out are required", verb);
    o->input = pos[0];
    if ((rc = parse_proxies(o, *proxies_text))) return rc;
    if ((rc = pipeline_apply_preset(o))) return rc;
    if (o->threads > 0) pg_set_threads(o->threads);
    return 0;
}
