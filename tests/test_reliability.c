/* test_reliability.c - issue 70, a fault and hostile-input sweep: one check per row, on small
 * synthetic scenes through the CLI (what a user runs) and, where a race needs a held lock, in
 * process. Every check failed on 5ede5bb. */
#include "testlib.h"
#include "core/fileutil.h"
#include "core/output.h"
#include "core/progress.h"
#include "io/npy.h"
#include "io/video.h"
#include "prodygs.h"
#include "tflite_writer.h"

#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

static char dir[4096];
static char err[16384], args[16384];

#define R "--iters 30 --proxies 2 --threads 1"
#define MODEL ".cache/prodygs/fastdepth_224_int8.tflite" /* the built-in model, cached by main */
#define M "--model " MODEL

/* dir/name into a static buffer (one of four in turn, so a call may take a few). */
static const char *at(const char *name)
{
    static char buf[4][4300];
    static int next;
    char *p = buf[next++ & 3];
    snprintf(p, sizeof buf[0], "%s/%s", dir, name);
    return p;
}

/* Runs the CLI with a time limit: a FIFO that hangs a reader fails the check instead of the suite. */
static int run(const char *fmt_args)
{
    char tmp[4300], cmd[20000];
    snprintf(tmp, sizeof tmp, "%s/stderr.txt", dir);
    snprintf(cmd, sizeof cmd, "cd '%s' && timeout 60 '%s' %s 2>'%s' >/dev/null </dev/null", dir, PG_CLI_PATH, fmt_args, tmp);
    int rc = system(cmd);
    err[0] = '\0';
    FILE *fp = fopen(tmp, "rb");
    if (fp) {
        size_t n = fread(err, 1, sizeof err - 1, fp);
        err[n] = '\0';
        fclose(fp);
    }
    return rc == -1 || !WIFEXITED(rc) ? -1 : WEXITSTATUS(rc);
}

static int one_line(void) { return strchr(err, '\n') == strrchr(err, '\n'); }

static int exists(const char *name) { return pg_path_exists(at(name)); }

static void write_text(const char *name, const char *text) { CHECK_OK(pg_write_file_atomic(at(name), text, strlen(text))); }

/* Row 1: the cache folder of the built-in model is used only when it is ours, 0700 and no symlink. */
static void cache_folder(void)
{
    char path[4300];
    CHECK_OK(pg_mkdir_p(at("cache_link")));
    CHECK(symlink(at("s1"), at("cache_link/prodygs")) == 0, "symlink");
    setenv("XDG_CACHE_HOME", at("cache_link"), 1);
    int rc = run("depth s1/cam00.mp4 --out link.npy");
    CHECK(rc == 3 && strstr(err, "cache_link/prodygs") && strstr(err, "symbolic link"), "a symlinked cache: exit %d, %s", rc, err);
    snprintf(path, sizeof path, "%s/s1/fastdepth_224_int8.tflite", dir);
    CHECK(!pg_path_exists(path), "the model was written through the symlink");

    CHECK_OK(pg_mkdir_p(at("cache_open/prodygs")));
    chmod(at("cache_open/prodygs"), 0777);
    setenv("XDG_CACHE_HOME", at("cache_open"), 1);
    if (geteuid() == 0) { /* another user's folder: only root can make one here */
        CHECK(chown(at("cache_open/prodygs"), 65534, 65534) == 0, "chown");
        rc = run("depth s1/cam00.mp4 --out other.npy");
        CHECK(rc == 3 && strstr(err, "belongs to uid 65534"), "another user's 0777 cache: exit %d, %s", rc, err);
        CHECK(!exists("cache_open/prodygs/fastdepth_224_int8.tflite") && !exists("other.npy"), "files written into another user's cache");
        CHECK(chown(at("cache_open/prodygs"), 0, 0) == 0, "chown back");
    }
    rc = run("depth s1/cam00.mp4 --out own.npy"); /* our own folder left open: closed, then used */
    struct stat st;
    CHECK(rc == 0 && stat(at("cache_open/prodygs"), &st) == 0 && (st.st_mode & 0777) == 0700, "own 0777 cache: exit %d, mode %o, %s",
          rc, (unsigned)(st.st_mode & 0777), err);
    CHECK(exists("cache_open/prodygs/fastdepth_224_int8.tflite"), "the model was not cached");
    unsetenv("XDG_CACHE_HOME");
}

/* Row 2: a second run with --render-size: renders/ holds exactly what it made. */
static void renders_replaced(void)
{
    int rc = run("run s1/cam00.mp4 --depth s1/depth_mono/cam00.npy " R " --out r0 --render-size 48x36");
    CHECK(rc == 0, "run --render-size 48x36: exit %d, %s", rc, err);
    CHECK(!exists("r0/renders/fixed_compare.mp4"), "renders/ kept the first run's fixed_compare.mp4");
    static const char *names[] = { "fixed.mp4", "orbit.mp4", "spiral.mp4", "fixed_depth.mp4" };
    for (int k = 0; k < 4; k++) {
        char name[64];
        snprintf(name, sizeof name, "r0/renders/%s", names[k]);
        io_video_info vi = { 0 };
        CHECK(io_video_probe(at(name), &vi) == PG_OK && vi.width == 48 && vi.height == 36, "%s is %dx%d, not 48x36", name, vi.width,
              vi.height);
    }
}

/* Row 3: odd or too small render sizes are refused before anything is written. */
static void render_sizes(void)
{
    int rc = run("render r0/model --out ro9 --size 9x9 --png");
    CHECK(rc == 2 && strstr(err, "even") && one_line() && !exists("ro9") && !exists("ro9.partial"), "--size 9x9: exit %d, %s", rc, err);
    rc = run("render r0/model --out ro8 --size 8x0 --png");
    CHECK(rc == 2 && strstr(err, "8x6") && !exists("ro8"), "--size 8x0: exit %d, %s", rc, err);
    rc = run("render r0/model --out ro10 --size 10x0 --no-depth");
    io_video_info vi = { 0 };
    CHECK(rc == 0 && io_video_probe(at("ro10/fixed.mp4"), &vi) == PG_OK && vi.width == 10 && vi.height == 8,
          "--size 10x0: exit %d, %dx%d, %s", rc, vi.width, vi.height, err);
    rc = run("run s1/cam00.mp4 --depth s1/depth_mono/cam00.npy " R " --out r9 --render-size 9x9");
    CHECK(rc == 2 && strstr(err, "--render-size") && !exists("r9"), "run --render-size 9x9: exit %d, %s", rc, err);
}

/* Row 4: an --out that is a regular file is refused before any work, nothing left. */
static void out_is_a_file(void)
{
    static const char *cmds[] = {
        "export r0/model --out rf",
        "prepare s1/cam00.mp4 --depth s1/depth_mono/cam00.npy --out rf",
        "proxies s1/cam00.mp4 --depth r0/prepare/depth_aligned.npy --out rf",
        "render r0/model --out rf",
        "synth rf --cams 1 --frames 2 --size 32x24",
        "train r0/proxies --out rf --iters 2",
        "run s1/cam00.mp4 --depth s1/depth_mono/cam00.npy --iters 2 --out rf",
    };
    write_text("rf", "x\n");
    for (size_t k = 0; k < sizeof cmds / sizeof cmds[0]; k++) {
        int rc = run(cmds[k]);
        CHECK(rc == 2 && strstr(err, "rf: exists and is not a folder") && one_line(), "%s: exit %d, %s", cmds[k], rc, err);
        CHECK(!exists("rf.partial") && !exists("rf.lock"), "%s left rf.partial or rf.lock", cmds[k]);
    }
    char *text = NULL;
    size_t n = 0;
    CHECK(pg_read_file(at("rf"), 64, &text, &n) == PG_OK && n == 2, "rf was changed");
    free(text);
    CHECK_OK(pg_mkdir_p(at("dnpy.npy")));
    int rc = run("depth s1/cam00.mp4 --out dnpy.npy");
    CHECK(rc == 2 && strstr(err, "not a regular file"), "depth --out FOLDER.npy: exit %d, %s", rc, err);
}

typedef struct {
    int polled, rc;
    char err[sizeof err];
} busy_probe;

/* Progress sink: at the run's first proxies step, a standalone prepare into the run's prepare
 * folder (the run is past it; before, it swapped the run's data). */
static void probe_prepare(void *ctx, const char *stage, long step, long total, const char *detail)
{
    (void)step, (void)total, (void)detail;
    busy_probe *b = ctx;
    if (b->polled || strcmp(stage, "proxies") != 0) return;
    b->polled = 1;
    b->rc = run("prepare s1/cam00.mp4 --depth s1/depth_mono/cam00.npy --out rl/prepare");
    snprintf(b->err, sizeof b->err, "%s", err);
}

/* Row 5: a second process on one output stops at once naming the first's PID; a run holds its
 * folders for its whole life. */
static void locks(void)
{
    char pid[32];
    snprintf(pid, sizeof pid, "PID %ld", (long)getpid());
    static const char *cmds[] = {
        "prepare s1/cam00.mp4 --depth s1/depth_mono/cam00.npy --out busy",
        "proxies s1/cam00.mp4 --depth r0/prepare/depth_aligned.npy --out busy",
        "export r0/model --out busy",
        "render r0/model --out busy",
        "train r0/proxies --out busy --iters 2",
        "synth busy --cams 1 --frames 2 --size 32x24",
        "run s1/cam00.mp4 --depth s1/depth_mono/cam00.npy --iters 2 --out busy",
    };
    CHECK_OK(pg_output_claim_dir(at("busy")));
    for (size_t k = 0; k < sizeof cmds / sizeof cmds[0]; k++) {
        int rc = run(cmds[k]);
        CHECK(rc == 3 && strstr(err, "in use") && strstr(err, pid) && one_line(), "%s on a busy folder: exit %d, %s", cmds[k], rc, err);
        CHECK(!exists("busy") && !exists("busy.partial"), "%s wrote into a busy folder", cmds[k]);
    }
    pg_output_release(at("busy"));
    CHECK(!exists("busy.lock"), "the released lock file stayed");
    CHECK_OK(pg_output_claim_file(at("busy.npy")));
    int rc = run("depth s1/cam00.mp4 " M " --out busy.npy");
    CHECK(rc == 3 && strstr(err, pid), "depth on a busy file: exit %d, %s", rc, err);
    CHECK(!exists("busy.npy.cache"), "depth on a busy file made its cache");
    pg_output_release(at("busy.npy"));

    pg_pipeline_config c;
    pg_pipeline_defaults(&c);
    char input[4300], depth[4300], out[4300];
    snprintf(input, sizeof input, "%s", at("s1/cam00.mp4"));
    snprintf(depth, sizeof depth, "%s", at("s1/depth_mono/cam00.npy"));
    snprintf(out, sizeof out, "%s", at("rl"));
    c.input = input;
    c.depth = depth;
    c.out = out;
    c.iters = 30;
    c.proxies = 2;
    c.threads = 1;
    busy_probe b = { 0, -1, "" };
    pg_progress_set_sink(probe_prepare, &b);
    pg_pipeline_report r;
    CHECK_OK(pg_pipeline_run(&c, &r));
    pg_progress_set_sink(NULL, NULL);
    CHECK(b.polled && b.rc == 3 && strstr(b.err, pid), "prepare into a running run's folder: exit %d, %s", b.rc, b.err);
    CHECK(!exists("rl.lock") && !exists("rl/prepare.lock"), "the run left its locks");
    rc = run("run s1/cam00.mp4 --depth s1/depth_mono/cam00.npy " R " --out rl");
    CHECK(rc == 0 && strstr(err, "prepare: already done") && strstr(err, "train: already done") && !strstr(err, "running again"),
          "the rerun after a refused prepare: exit %d, %s", rc, err);
    snprintf(args, sizeof args, "find '%s/rl' -name '*.tmp.*' | grep -q .", dir);
    CHECK(system(args) != 0, "a *.tmp.PID file was left in the run's folders");
}

/* Row 6: --out inside the input folder is not part of the input's hash. */
static void out_inside_input(void)
{
    snprintf(args, sizeof args, "cp -r '%s/s1/cam00/images' '%s/frames'", dir, dir);
    CHECK(system(args) == 0, "copy frames");
    for (int k = 0; k < 3; k++) {
        int rc = run("run frames --depth s1/depth_mono/cam00.npy " R " --out frames/out");
        CHECK(rc == 0, "run %d with --out inside the input: exit %d, %s", k, rc, err);
        if (k > 0)
            CHECK(strstr(err, "prepare: already done") && !strstr(err, "has new content"), "rerun %d repeated the stages: %s", k, err);
    }
}

/* A one-layer depth network with an 8x8 input (a conv of the three channels). */
static void write_8x8_model(const char *path)
{
    static float w[27], b[1] = { 1.0f };
    for (int i = 0; i < 27; i++) w[i] = 0.1f;
    tw_model *m = calloc(1, sizeof *m);
    int x = tw_tensor(m, "image", 4, (int[]){ 1, 8, 8, 3 }, TW_F32, NULL, 0);
    int tw = tw_tensor(m, "w", 4, (int[]){ 1, 3, 3, 3 }, TW_F32, w, sizeof w);
    int tb = tw_tensor(m, "b", 1, (int[]){ 1 }, TW_F32, b, sizeof b);
    int y = tw_tensor(m, "depth", 4, (int[]){ 1, 8, 8, 1 }, TW_F32, NULL, 0);
    tw_op(m, 3, (int[]){ x, tw, tb }, 3, y, 1, 4, (int32_t[]){ 0, 1, 1, 0 }, "biib");
    m->inputs[m->num_inputs++] = x;
    m->outputs[m->num_outputs++] = y;
    size_t n;
    uint8_t *bytes = tw_build(m, &n);
    CHECK_OK(pg_write_file_atomic(path, bytes, n));
    free(bytes);
    free(m);
}

/* A copy of an MP4 whose mdat payload is zeroed from `from` (0..1) on: the header still promises
 * every frame, the last ones no longer decode, as in a file cut short and padded. */
static void damage_mp4(const char *src, const char *dst, double from)
{
    char *data = NULL;
    size_t n = 0;
    CHECK_OK(pg_read_file(src, 1 << 24, &data, &n));
    for (size_t at = 0; data && at + 8 <= n;) {
        const unsigned char *h = (const unsigned char *)data + at;
        size_t box = (size_t)h[0] << 24 | (size_t)h[1] << 16 | (size_t)h[2] << 8 | h[3];
        if (box < 8 || at + box > n) break;
        if (memcmp(h + 4, "mdat", 4) == 0) {
            size_t cut = at + 8 + (size_t)((box - 8) * from);
            memset(data + cut, 0, at + box - cut);
        }
        at += box;
    }
    CHECK_OK(pg_write_file_atomic(dst, data, n));
    free(data);
}

/* Row 7: one line naming the real file and problem. */
static void messages(void)
{
    CHECK_OK(pg_mkdir_p(at("model_dir")));
    int rc = run("depth s1/cam00.mp4 --model model_dir --out m.npy");
    CHECK(rc == 2 && strstr(err, "model_dir: is a folder") && !strstr(err, "bytes"), "a folder as --model: exit %d, %s", rc, err);
    write_text("empty.tflite", "");
    rc = run("depth s1/cam00.mp4 --model empty.tflite --out m.npy");
    CHECK(rc == 2 && strstr(err, "empty.tflite: empty file") && !strstr(err, "ONNX"), "an empty .tflite: exit %d, %s", rc, err);
    write_text("magic.tflite", "0123456789abcdef");
    rc = run("depth s1/cam00.mp4 --model magic.tflite --out m.npy");
    CHECK(rc == 2 && strstr(err, "not a TFLite model") && !strstr(err, "ONNX"), "a bad-magic .tflite: exit %d, %s", rc, err);

    snprintf(args, sizeof args, "cp -r '%s/s1/cam00/images' '%s/mixed'", dir, dir);
    CHECK(system(args) == 0, "copy frames");
    rc = run("render r0/model --out small --size 48x36 --png --no-depth");
    snprintf(args, sizeof args, "cp '%s/small/fixed/0003.png' '%s/mixed/0003.png'", dir, dir);
    CHECK(rc == 0 && system(args) == 0, "a small frame: %s", err);
    rc = run("depth mixed " M " --out mx.npy");
    CHECK(rc == 2 && strstr(err, "0003.png") && !strstr(err, ": :") && !strstr(err, "frame 0") && one_line(), "mixed frame sizes: exit %d, %s",
          rc, err);

    damage_mp4(at("s2/cam00.mp4"), at("cut.mp4"), 0.6);
    rc = run("prepare cut.mp4 --depth s2/depth_mono/cam00.npy --out pcut");
    CHECK(rc == 2 && strstr(err, "cut.mp4: truncated") && !strstr(err, "asked for") && one_line(), "a truncated mp4: exit %d, %s", rc, err);

    CHECK_OK(pg_mkdir_p(at("bare")));
    snprintf(args, sizeof args, "cp '%s/r0/model/model.ckpt' '%s/bare/'", dir, dir);
    CHECK(system(args) == 0, "copy model");
    rc = run("render bare --out rb");
    CHECK(rc == 2 && strstr(err, "cameras.json") && !strstr(err, "--cameras"), "render without cameras.json: exit %d, %s", rc, err);

    snprintf(args, sizeof args, "cp '%s/.cache/prodygs/fastdepth_224_int8.tflite' '%s/side.tflite'", dir, dir);
    CHECK(system(args) == 0, "copy the built-in model");
    static const char *sizes[] = { "[64.5, 224]", "[-224, 224]", "\"224\"", "[224]" };
    for (int k = 0; k < 4; k++) {
        char json[128];
        snprintf(json, sizeof json, "{\"input_size\": %s}\n", sizes[k]);
        write_text("side.tflite.json", json);
        rc = run("depth s1/cam00.mp4 --model side.tflite --out m.npy");
        CHECK(rc == 2 && strstr(err, "side.tflite.json") && strstr(err, "input_size") && one_line(), "input_size %s: exit %d, %s", sizes[k],
              rc, err);
    }
    write_8x8_model(at("m8.tflite"));
    rc = run("depth s1/cam00.mp4 --model m8.tflite --out m8.npy");
    CHECK(rc == 0 && !strstr(err, "--size"), "an 8x8-input model without --size: exit %d, %s", rc, err);
}

/* Row 8: a FIFO where a file is read is refused at once (exit 2), not waited on. */
static void fifos(void)
{
    CHECK(mkfifo(at("f.npy"), 0600) == 0 && mkfifo(at("f.mp4"), 0600) == 0 && mkfifo(at("f.tflite"), 0600) == 0, "mkfifo");
    struct {
        const char *cmd, *what;
    } cases[] = {
        { "prepare s1/cam00.mp4 --depth f.npy --out pf", "f.npy" },
        { "info f.mp4", "f.mp4" },
        { "info f.npy", "f.npy" },
        { "depth s1/cam00.mp4 --model f.tflite --out fm.npy", "f.tflite" },
        { "depth f.mp4 " M " --out fv.npy", "f.mp4" },
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        int rc = run(cases[k].cmd);
        CHECK(rc == 2 && strstr(err, cases[k].what) && strstr(err, "FIFO") && one_line(), "%s: exit %d, %s", cases[k].cmd, rc, err);
    }
    /* the cached built-in model replaced by a FIFO: rewritten, not read */
    CHECK_OK(pg_mkdir_p(at("cache_fifo/prodygs")));
    chmod(at("cache_fifo/prodygs"), 0700);
    CHECK(mkfifo(at("cache_fifo/prodygs/fastdepth_224_int8.tflite"), 0600) == 0, "mkfifo");
    setenv("XDG_CACHE_HOME", at("cache_fifo"), 1);
    int rc = run("depth s1/cam00.mp4 --out cf.npy");
    CHECK(rc == 0 || rc == 2, "a FIFO as the cached model hung or crashed: exit %d, %s", rc, err);
    unsetenv("XDG_CACHE_HOME");
}

/* Row 9: -0 is 0 for export --times. */
static void negative_zero(void)
{
    int rc = run("export r0/model --out ex0 --times -0,0");
    CHECK(rc == 2 && !exists("ex0"), "--times -0,0: exit %d, %s", rc, err);
    rc = run("export r0/model --out ex1 --times -0");
    CHECK(rc == 0 && exists("ex1/time_0.000.ply") && !exists("ex1/time_-0.000.ply"), "--times -0: exit %d, %s", rc, err);
}

/* Row 10: movers far behind their background are brought in front; the background ring around
 * them keeps its depth. */
static void movers_ring(void)
{
    pg_array mono = { 0 }, mask = { 0 }, on = { 0 }, off = { 0 };
    int rc;
    CHECK_OK(io_npy_load(at("s2/depth_mono/cam00.npy"), &mono));
    CHECK_OK(io_npy_load(at("s2/masks_dynamic/cam00.npy"), &mask));
    if (mono.count != mask.count || !mono.count) {
        CHECK(0, "depth %zu and mask %zu values", mono.count, mask.count);
        return;
    }
    for (size_t i = 0; i < mono.count; i++)
        if (mask.data[i] > 0.5f) mono.data[i] *= 20;
    CHECK_OK(io_npy_save(at("movers_far.npy"), mono.data, mono.ndim, mono.shape));
    rc = run("prepare s2/cam00.mp4 --depth movers_far.npy --out pmv --threads 1");
    CHECK(rc == 0, "prepare with far movers: %s", err);
    rc = run("prepare s2/cam00.mp4 --depth movers_far.npy --out pmv0 --threads 1 --no-movers-front");
    CHECK(rc == 0, "prepare --no-movers-front: %s", err);
    CHECK_OK(io_npy_load(at("pmv/depth_aligned.npy"), &on));
    CHECK_OK(io_npy_load(at("pmv0/depth_aligned.npy"), &off));
    long background = 0, changed = 0, movers = 0, moved = 0;
    for (size_t i = 0; i < on.count && on.count == off.count && on.count == mask.count; i++) {
        if (mask.data[i] > 0.5f) {
            movers++;
            moved += on.data[i] < 0.5f * off.data[i];
        } else {
            background++;
            changed += on.data[i] != off.data[i];
        }
    }
    printf("movers in front: %ld of %ld background pixels changed, %ld of %ld mover pixels brought forward\n", changed, background,
           moved, movers);
    CHECK(background > 0 && changed * 200 < background, "%ld of %ld background pixels changed (> 0.5 %%; 5.7 %% before)", changed, background);
    CHECK(movers > 0 && moved * 2 > movers, "only %ld of %ld mover pixels brought forward", moved, movers);
    pg_array_destroy(&mono);
    pg_array_destroy(&mask);
    pg_array_destroy(&on);
    pg_array_destroy(&off);
}

/* Row 11: a constant depth map is not taken for disparity. */
static void flat_depth(void)
{
    size_t shape[3] = { 6, 72, 96 }, n = 6 * 72 * 96;
    float *flat = malloc(n * sizeof *flat);
    for (size_t i = 0; i < n; i++) flat[i] = 2.0f;
    CHECK_OK(io_npy_save(at("const.npy"), flat, 3, shape));
    free(flat);
    int rc = run("prepare s1/cam00.mp4 --depth const.npy --out pc --threads 1");
    CHECK(rc == 0 && !strstr(err, "disparity"), "a flat map: exit %d, %s", rc, err);
}

/* Row 12: the built-in model's stages key on its content: another XDG_CACHE_HOME reruns nothing. */
static void model_by_content(void)
{
    setenv("XDG_CACHE_HOME", at("xq1"), 1);
    int rc = run("run s1/cam00.mp4 " R " --out rq");
    CHECK(rc == 0, "run with the built-in model: exit %d, %s", rc, err);
    setenv("XDG_CACHE_HOME", at("xq2"), 1);
    rc = run("run s1/cam00.mp4 " R " --out rq");
    CHECK(rc == 0 && strstr(err, "depth: already done") && strstr(err, "train: already done") && !strstr(err, "running again"),
          "another cache folder: exit %d, %s", rc, err);
    unsetenv("XDG_CACHE_HOME");
}

/* Acceptance: a run killed (-9) anywhere resumes to the same bytes as one never interrupted; the
 * kills land in different stages (depth, prepare, proxies, train, render) by their delay. */
static void kill_and_resume(void)
{
    static const char *files[] = { "depth/depth.npy", "prepare/depth_aligned.npy", "prepare/static_masks.npy", "model/model.ckpt" };
    int rc = run("run s1/cam00.mp4 --depth-model " MODEL " " R " --out rk_ref");
    CHECK(rc == 0, "reference run: exit %d, %s", rc, err);
    static const char *delays[] = { "0.3", "0.9", "1.8" };
    for (int k = 0; k < 3; k++) {
        snprintf(args, sizeof args, "cd '%s' && rm -rf rk rk.lock && timeout -s KILL %s '%s' run s1/cam00.mp4 --depth-model "
                 MODEL " " R " --out rk >/dev/null 2>&1", dir, delays[k], PG_CLI_PATH);
        int killed = system(args);
        rc = run("run s1/cam00.mp4 --depth-model " MODEL " " R " --out rk");
        CHECK(rc == 0, "resume after a kill at %s s (%d): exit %d, %s", delays[k], killed, rc, err);
        for (int i = 0; i < 4; i++) {
            char a[64], b[64];
            snprintf(a, sizeof a, "rk_ref/%s", files[i]);
            snprintf(b, sizeof b, "rk/%s", files[i]);
            CHECK(test_files_equal(at(a), at(b)), "killed at %s s: %s differs from the uninterrupted run's", delays[k], files[i]);
        }
    }
}

/* The minor rows: values the messages refuse are refused, a refused run leaves nothing. */
static void minor(void)
{
    int rc = run("run s1/cam00.mp4 --depth s1/depth_mono/cam00.npy --pad -1 --out rp");
    CHECK(rc == 2 && strstr(err, "--pad") && !exists("rp"), "--pad -1: exit %d, %s", rc, err);
    rc = run("proxies s1/cam00.mp4 --depth r0/prepare/depth_aligned.npy --pad -1 --out rp");
    CHECK(rc == 2 && strstr(err, "--pad") && !exists("rp"), "proxies --pad -1: exit %d, %s", rc, err);
    rc = run("run s1/cam00.mp4 --depth s1/depth_mono/cam00.npy --iters 0 --out rp");
    CHECK(rc == 2 && strstr(err, "--iters") && !exists("rp"), "--iters 0: exit %d, %s", rc, err);
    rc = run("run s1/cam00.mp4 --depth s1/depth_mono/cam00.npy --fov 179.5 --out rp");
    CHECK(rc == 2 && strstr(err, "(0, 179)") && !exists("rp"), "--fov 179.5: exit %d, %s", rc, err);
    rc = run("run s1/cam00.mp4 --depth-model model_dir " R " --out rdm");
    CHECK(rc == 2 && !exists("rdm") && !exists("rdm.lock"), "a refused --depth-model DIR: exit %d, left rdm: %d, %s", rc, exists("rdm"),
          err);
}

int main(void)
{
    test_tmpdir("reliability", dir, sizeof dir);
    setenv("HOME", dir, 1); /* the built-in model is cached under dir/.cache */
    unsetenv("XDG_CACHE_HOME");
    int rc = run("synth s1 --cams 3 --frames 6 --size 96x72 --video --threads 1");
    CHECK(rc == 0, "synth: %s", err);
    rc = run("synth s2 --cams 1 --frames 10 --size 128x96 --video --threads 1");
    CHECK(rc == 0, "synth s2: %s", err);
    rc = run("depth s1/cam00.mp4 --out warm.npy --threads 1"); /* caches the built-in model */
    CHECK(rc == 0, "depth: %s", err);
    rc = run("run s1/cam00.mp4 --depth s1/depth_mono/cam00.npy " R " --out r0");
    CHECK(rc == 0 && exists("r0/renders/fixed_compare.mp4"), "first run: exit %d, %s", rc, err);
    cache_folder();
    renders_replaced();
    render_sizes();
    out_is_a_file();
    locks();
    out_inside_input();
    messages();
    fifos();
    negative_zero();
    movers_ring();
    flat_depth();
    model_by_content();
    minor();
    kill_and_resume();
    return test_summary("test_reliability");
}
