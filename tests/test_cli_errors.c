/* test_cli_errors.c - bad-input sweep over every `prodygs` command: missing arguments, unknown
 * options, bad numbers, missing/truncated/garbled files, absurd sizes. Each case must exit with
 * code 2 and print exactly one "prodygs: ..." line that names the file or option at fault; every
 * --help must exit 0. Inputs are tiny fixtures made here, so the whole sweep takes seconds. */
#include "testlib.h"
#include "core/fileutil.h"
#include "io/npy.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>

static char dir[4096];

/* Writes n bytes of data (or n pseudo-random bytes if data is NULL) to dir/name. */
static void write_bytes(const char *name, const void *data, size_t n)
{
    char path[4300];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    unsigned char *buf = malloc(n ? n : 1);
    if (data) memcpy(buf, data, n);
    else
        for (size_t i = 0; i < n; i++) buf[i] = (unsigned char)((i * 2654435761u) >> 13);
    FILE *fp = fopen(path, "wb");
    CHECK(fp != NULL, "cannot write %s", path);
    if (fp) {
        fwrite(buf, 1, n, fp);
        fclose(fp);
    }
    free(buf);
}

static void write_text(const char *name, const char *text) { write_bytes(name, text, strlen(text)); }

/* Saves a float32 .npy of shape (F,H,W) filled with value. */
static void write_npy(const char *name, int F, int H, int W, float value)
{
    char path[4300];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    size_t n = (size_t)F * H * W;
    float *d = malloc(n * sizeof *d);
    for (size_t i = 0; i < n; i++) d[i] = value;
    size_t shape[3] = { (size_t)F, (size_t)H, (size_t)W };
    CHECK_OK(io_npy_save(path, d, 3, shape));
    free(d);
}

/* Copies the first `keep` bytes (or half, if keep is 0) of dir/src to dir/dst. */
static void truncate_copy(const char *src, const char *dst, size_t keep)
{
    char path[4300];
    snprintf(path, sizeof path, "%s/%s", dir, src);
    char *data = NULL;
    size_t size = 0;
    CHECK_OK(pg_read_file(path, 1u << 30, &data, &size));
    if (!data) return;
    write_bytes(dst, data, keep ? (keep < size ? keep : size) : size / 2);
    free(data);
}

/* Lines of err that are not progress reports. */
static int error_lines(const char *err)
{
    int n = 0;
    for (const char *p = err; *p;) {
        const char *nl = strchr(p, '\n');
        size_t len = nl ? (size_t)(nl - p) : strlen(p);
        if (len > 0 && strncmp(p, "progress ", 9) != 0) n++;
        p += len + (nl ? 1 : 0);
    }
    return n;
}

/* Runs `prodygs ARGS` (paths relative to the fixture dir) and checks exit `code`, one error
 * line starting "prodygs: ", which contains `needle`. */
static void expect_exit(const char *args, const char *needle, int code)
{
    char cmd[8192], err[8192];
    snprintf(cmd, sizeof cmd, "%s", args);
    /* fixture paths: "@/name" -> "<dir>/name" */
    char expanded[8192];
    size_t k = 0;
    for (const char *p = cmd; *p && k + 4200 < sizeof expanded; p++) {
        if (p[0] == '@' && p[1] == '/') k += (size_t)snprintf(expanded + k, sizeof expanded - k, "%s", dir);
        else expanded[k++] = *p;
    }
    expanded[k] = '\0';
    int rc = test_run_cli(expanded, err, sizeof err);
    int lines = error_lines(err);
    int named = strstr(err, needle) != NULL;
    CHECK(rc == code && lines == 1 && named && strncmp(err, "prodygs: ", 9) == 0,
          "prodygs %s: exit %d (want %d), %d line(s) (want 1), names '%s': %s; stderr: %s", args, rc, code, lines, needle,
          named ? "yes" : "NO", err);
}

/* Bad input: exit 2. */
static void expect_error(const char *args, const char *needle) { expect_exit(args, needle, 2); }

/* `prodygs ARGS` must exit 0 and print usage text on stdout with nothing on stderr. */
static void expect_help(const char *args, const char *needle)
{
    char cmd[8192];
    snprintf(cmd, sizeof cmd, "'%s' %s 2>&1", PG_CLI_PATH, args);
    FILE *fp = popen(cmd, "r");
    CHECK(fp != NULL, "popen %s", cmd);
    if (!fp) return;
    static char out[1 << 16];
    size_t n = fread(out, 1, sizeof out - 1, fp);
    out[n] = '\0';
    int st = pclose(fp);
    int rc = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
    /* needle: words separated by '|', each must appear */
    char words[512];
    snprintf(words, sizeof words, "%s", needle);
    int all = 1;
    for (char *w = strtok(words, "|"); w; w = strtok(NULL, "|")) all &= strstr(out, w) != NULL;
    CHECK(rc == 0 && strstr(out, "usage:") && all, "prodygs %s: exit %d, wants '%s', output: %.300s", args, rc, needle, out);
}

static void make_fixtures(void)
{
    char err[8192], args[8400];
    /* a tiny DyNeRF-layout dataset with an MP4 per camera */
    snprintf(args, sizeof args, "synth '%s/ds' --cams 2 --frames 3 --size 16x12 --spp 1 --video --threads 1", dir);
    int rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 0, "synth fixture failed (%d): %s", rc, err);

    write_npy("wrongshape.npy", 3, 5, 5, 1.0f);
    write_npy("wrongframes.npy", 2, 12, 16, 1.0f);
    write_npy("nan.npy", 3, 12, 16, NAN);
    write_npy("good.npy", 3, 12, 16, 2.0f);
    truncate_copy("good.npy", "trunc.npy", 0);
    truncate_copy("good.npy", "hdr_only.npy", 40);
    write_bytes("garbled.npy", NULL, 3000);
    write_bytes("empty.npy", "", 0);
    const char *huge_hdr = "{'descr': '<f4', 'fortran_order': False, 'shape': (1000000000, 1000000000), }";
    char huge[256];
    size_t hl = strlen(huge_hdr);
    size_t pad = 64 - (10 + hl + 1) % 64;
    memcpy(huge, "\x93NUMPY\x01\x00", 8);
    huge[8] = (char)((hl + pad + 1) & 0xff);
    huge[9] = (char)((hl + pad + 1) >> 8);
    memcpy(huge + 10, huge_hdr, hl);
    memset(huge + 10 + hl, ' ', pad);
    huge[10 + hl + pad] = '\n';
    write_bytes("huge.npy", huge, 10 + hl + pad + 1 + 16);
    const char *fourd = "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3, 4, 5), }";
    char fd[256];
    size_t fl = strlen(fourd), fpad = 64 - (10 + fl + 1) % 64;
    memcpy(fd, "\x93NUMPY\x01\x00", 8);
    fd[8] = (char)(fl + fpad + 1);
    fd[9] = 0;
    memcpy(fd + 10, fourd, fl);
    memset(fd + 10 + fl, ' ', fpad);
    fd[10 + fl + fpad] = '\n';
    char *fdall = calloc(1, 10 + fl + fpad + 1 + 120 * 4);
    memcpy(fdall, fd, 10 + fl + fpad + 1);
    write_bytes("4d.npy", fdall, 10 + fl + fpad + 1 + 120 * 4);
    free(fdall);

    truncate_copy("ds/cam00.mp4", "trunc.mp4", 600);
    write_bytes("garbled.mp4", NULL, 5000);
    write_bytes("empty.mp4", "", 0);
    truncate_copy("ds/cam00/images/0000.png", "trunc.png", 0);
    write_bytes("garbled.png", "\x89PNG\r\n\x1a\n\x01\x02\x03\x04garbage-garbage-garbage", 32);

    const char *ply_hdr = "ply\nformat binary_little_endian 1.0\nelement vertex %s\n"
                          "property float x\nproperty float y\nproperty float z\nproperty float opacity\nend_header\n";
    char ply[1024];
    snprintf(ply, sizeof ply, ply_hdr, "1000");
    size_t pl = strlen(ply);
    memset(ply + pl, 0, 64);
    write_bytes("trunc.ply", ply, pl + 64);
    snprintf(ply, sizeof ply, ply_hdr, "1000000000000");
    write_text("huge.ply", ply);
    snprintf(ply, sizeof ply, ply_hdr, "-5");
    write_text("negcount.ply", ply);
    write_bytes("garbled.ply", NULL, 2000);

    /* a frame folder whose last frame is cut short */
    char sub[4300];
    snprintf(sub, sizeof sub, "%s/frames_bad", dir);
    CHECK_OK(pg_mkdir_p(sub));
    truncate_copy("ds/cam00/images/0000.png", "frames_bad/0000.png", (size_t)1 << 30);
    truncate_copy("ds/cam00/images/0001.png", "frames_bad/0001.png", (size_t)1 << 30);
    truncate_copy("ds/cam00/images/0002.png", "frames_bad/0002.png", 0);

    /* models: an empty folder and one with a garbled checkpoint */
    snprintf(sub, sizeof sub, "%s/m_empty", dir);
    CHECK_OK(pg_mkdir_p(sub));
    snprintf(sub, sizeof sub, "%s/m_garb", dir);
    CHECK_OK(pg_mkdir_p(sub));
    write_bytes("m_garb/model.ckpt", NULL, 4000);
    snprintf(sub, sizeof sub, "%s/m_badcam", dir);
    CHECK_OK(pg_mkdir_p(sub));
    write_text("m_badcam/cameras.json", "{\"version\": 1, \"cameras\": [");

    /* a depth folder whose frames disagree in size */
    snprintf(sub, sizeof sub, "%s/dfold", dir);
    CHECK_OK(pg_mkdir_p(sub));
    write_npy("dfold/0000.npy", 1, 12, 16, 2.0f);
    write_npy("dfold/0001.npy", 1, 6, 8, 2.0f);
    write_npy("dfold/0002.npy", 1, 12, 16, 2.0f);
}

int main(void)
{
    test_tmpdir("test_cli_errors", dir, sizeof dir);
    make_fixtures();
    const char *dep = "--depth @/ds/depth_mono/cam00.npy";
    char a[2048];

    /* top level */
    expect_error("frobnicate", "frobnicate");
    expect_error("", "usage");

    /* info */
    expect_error("info", "usage");
    expect_error("info @/missing.mp4", "missing.mp4");
    expect_error("info --bogus @/ds", "--bogus");
    expect_error("info @/trunc.npy", "trunc.npy");
    expect_error("info @/hdr_only.npy", "hdr_only.npy");
    expect_error("info @/garbled.npy", "garbled.npy");
    expect_error("info @/empty.npy", "empty.npy");
    expect_error("info @/huge.npy", "huge.npy");
    expect_error("info @/4d.npy", "4 dimensions");
    expect_error("info @/trunc.mp4", "trunc.mp4");
    expect_error("info @/garbled.mp4", "garbled.mp4");
    expect_error("info @/empty.mp4", "empty.mp4");
    expect_error("info @/trunc.png", "trunc.png");
    expect_error("info @/garbled.png", "garbled.png");
    expect_error("info @/trunc.ply", "trunc.ply");
    expect_error("info @/huge.ply", "huge.ply");
    expect_error("info @/negcount.ply", "negcount.ply");
    expect_error("info @/garbled.ply", "garbled.ply");
    expect_error("info @/m_empty", "m_empty");
    expect_error("info @/dfold", "dfold/0001.npy");
    expect_error("info @/m_garb/model.ckpt", "m_garb/model.ckpt");

    /* synth */
    expect_error("synth", "usage");
    expect_error("synth @/s --size 100000x100000", "--size");
    expect_error("synth @/s --size abc", "--size");
    expect_error("synth @/s --frames -1", "--frames");
    expect_error("synth @/s --cams abc", "--cams");
    expect_error("synth @/s --spp 0", "--spp");
    expect_error("synth @/s --fps nan", "--fps");
    expect_error("synth @/s --threads -3", "--threads");
    expect_error("synth @/s --layout foo", "--layout");
    /* the machine refuses the output (issue 27: not exit 2, which means bad input) */
    expect_exit("synth /proc/nope/x --frames 1 --cams 1 --size 8x8", "/proc/nope", 3);

    /* prepare */
    expect_error("prepare @/ds", "--out"); /* without --depth / --depth-model the built-in model runs */
    expect_error("prepare @/ds --depth @/missing.npy --out @/p", "missing.npy");
    expect_error("prepare @/missing_ds --depth @/good.npy --out @/p", "missing_ds");
    expect_error("prepare @/ds --depth @/trunc.npy --out @/p", "trunc.npy");
    expect_error("prepare @/ds --depth @/garbled.npy --out @/p", "garbled.npy");
    expect_error("prepare @/ds --depth @/huge.npy --out @/p", "huge.npy");
    expect_error("prepare @/ds --depth @/wrongshape.npy --out @/p", "wrongshape.npy");
    expect_error("prepare @/ds --depth @/wrongframes.npy --out @/p", "wrongframes.npy");
    expect_error("prepare @/ds --depth @/dfold --out @/p", "dfold/0001.npy");
    expect_error("prepare @/ds --depth @/nan.npy --out @/p", "nan.npy: no valid depth");
    expect_error("prepare @/garbled.mp4 --depth @/good.npy --out @/p", "garbled.mp4");
    expect_error("prepare @/frames_bad --depth @/good.npy --out @/p", "0002.png");
    snprintf(a, sizeof a, "prepare @/ds %s --out @/p --depth-kind foo", dep);
    expect_error(a, "--depth-kind");
    snprintf(a, sizeof a, "prepare @/ds %s --out @/p --frames -1", dep);
    expect_error(a, "--frames");
    snprintf(a, sizeof a, "prepare @/ds %s --out @/p --size 100000x100000", dep);
    expect_error(a, "out of range");
    snprintf(a, sizeof a, "prepare @/ds %s --out @/p --threads -1", dep);
    expect_error(a, "--threads");

    /* proxies */
    expect_error("proxies @/ds --depth @/missing.npy --out @/x", "missing.npy");
    expect_error("proxies @/ds --depth @/wrongshape.npy --out @/x", "wrongshape.npy");
    expect_error("proxies @/ds --depth @/nan.npy --out @/x", "nan.npy: no valid depth");
    snprintf(a, sizeof a, "proxies @/ds %s --out @/x --proxies -5", dep);
    expect_error(a, "--proxies");
    snprintf(a, sizeof a, "proxies @/ds %s --out @/x --poses foo", dep);
    expect_error(a, "--poses");
    snprintf(a, sizeof a, "proxies @/ds %s --out @/x --threads -2", dep);
    expect_error(a, "--threads");
    snprintf(a, sizeof a, "proxies @/ds %s --out @/x --render foo", dep);
    expect_error(a, "--render must be mesh or splat, not 'foo'");

    /* train */
    expect_error("train", "usage");
    expect_error("train @/missing_set --out @/t", "missing_set");
    expect_error("train @/ds --out @/t --iters -5", "--iters");
    expect_error("train @/ds --out @/t --iters abc", "--iters");
    expect_error("train @/ds --out @/t --lambda-depth inf", "--lambda-depth");
    expect_error("train @/ds --out @/t --sh-degree 9", "--sh-degree");
    expect_error("train @/ds --out @/t --deform-time-warmup 1", "--deform-time-warmup must be in [0, 1) (got 1)");
    expect_error("train @/ds --out @/t --densify-movable 0.5", "--densify-movable must be in [1, 100] (got 0.5)");
    expect_error("train @/ds --out @/t --proxy-downscale 3", "--proxy-downscale must be 1 or 2 (got 3)");
    expect_error("train @/ds --out @/t --threads -1", "--threads");
    /* train and run/eval share one check and one wording for the trainer's options */
    expect_error("train @/ds --out @/t --motion-crops 99", "train: --motion-crops must be in 0..16 (got 99)");
    expect_error("train @/ds --out @/t --proxy-moving-weight 2", "train: --proxy-moving-weight must be in [0, 1] (got 2)");
    expect_error("train @/ds --out @/t --real-weight 1.5", "train: --real-weight must be in [0, 1] (got 1.5)");
    expect_error("train @/ds --out @/t --depth @/trunc.npy", "trunc.npy");
    expect_error("train @/ds --out @/t --iters 2 --depth @/wrongshape.npy", "wrongshape.npy: depth is (3, 5, 5) but the frames are (3, 12, 16)");
    expect_error("train @/ds --out @/t --iters 2 --depth @/nan.npy", "nan.npy: no valid depth");
    expect_error("train @/ds --out @/t --iters 2 --width 100000", "--width");
    expect_error("train @/ds --out @/t --iters 2 --width -3", "--width");
    expect_error("train @/ds --out @/t --iters 2 --coarse-iters -1", "--coarse-iters");
    expect_error("train @/ds --out @/t --iters 2 --densify-until 3", "train: --densify-until 3 must be in 0..2 (--iters)");
    expect_error("train @/ds --out @/t --iters 2 --init-points -1", "--init-points");
    expect_error("train @/ds --out @/t --iters 2 --views-per-step 0", "--views-per-step");
    expect_error("train @/ds --out @/t --iters 2 --frames -1", "--frames");
    expect_error("train @/ds --out @/t --iters 2 --proxies -2", "--proxies");

    /* render */
    expect_error("render @/m_garb", "--out");
    expect_error("render @/missing_model --out @/r", "missing_model");
    expect_error("render @/m_garb --out @/r", "m_garb");
    expect_error("render @/m_badcam --out @/r", "cameras.json");
    expect_error("render @/m_garb --out @/r --path foo", "foo");
    expect_error("render @/m_garb --out @/r --time 5", "--time");
    expect_error("render @/m_garb --out @/r --steps -1", "--steps");
    expect_error("render @/m_garb --out @/r --fps -1", "--fps");
    expect_error("render @/m_garb --out @/r --angle 1000", "--angle");
    expect_error("render @/m_garb --out @/r --threads -1", "--threads");

    /* export */
    expect_error("export @/m_garb", "--out");
    expect_error("export @/missing_model --out @/e", "missing_model");
    expect_error("export @/m_empty --out @/e", "model.ckpt");
    expect_error("export @/m_garb --out @/e", "model.ckpt");
    expect_error("export @/m_garb --out @/e --times abc", "--times");
    /* issue 27: two times that name one file were silently written over each other */
    expect_error("export @/m_garb --out @/e --times 0,0.0004", "time_0.000.ply");
    expect_error("export @/m_garb --out @/e --frame-list 3,3", "frame 3 twice");

    /* eval and run: options are checked before any stage runs */
    expect_error("eval @/ds", "--out");
    snprintf(a, sizeof a, "eval @/ds %s --out @/v --iters -5", dep);
    expect_error(a, "--iters");
    snprintf(a, sizeof a, "eval @/ds %s --out @/v --preset foo", dep);
    expect_error(a, "foo");
    snprintf(a, sizeof a, "eval @/ds %s --out @/v --max-angle 500", dep);
    expect_error(a, "--max-angle");
    snprintf(a, sizeof a, "eval @/ds %s --out @/v --proxy-moving-weight 2", dep);
    expect_error(a, "--proxy-moving-weight must be in [0, 1] (got 2)");
    snprintf(a, sizeof a, "eval @/ds %s --out @/v --real-weight -0.5", dep);
    expect_error(a, "pipeline: --real-weight must be in [0, 1] (got -0.5)");
    snprintf(a, sizeof a, "eval @/ds %s --out @/v --motion-crops 99", dep);
    expect_error(a, "pipeline: --motion-crops must be in 0..16 (got 99)");
    snprintf(a, sizeof a, "eval @/ds %s --out @/v --views-per-step 17", dep);
    expect_error(a, "--views-per-step must be in 1..16 (got 17)");
    snprintf(a, sizeof a, "eval @/ds %s --out @/v --views-per-step 0", dep);
    expect_error(a, "pipeline: --views-per-step must be in 1..16 (got 0)");
    snprintf(a, sizeof a, "eval @/ds %s --out @/v --sh-degree 9", dep);
    expect_error(a, "--sh-degree must be in 0..3 (got 9)");
    snprintf(a, sizeof a, "eval @/ds %s --out @/v --deform-time-warmup -0.5", dep);
    expect_error(a, "--deform-time-warmup must be in [0, 1) (got -0.5)");
    snprintf(a, sizeof a, "run @/ds %s --out @/v --densify-movable 200", dep);
    expect_error(a, "--densify-movable must be in [1, 100] (got 200)");
    snprintf(a, sizeof a, "run @/ds %s --out @/v --proxy-downscale 4", dep);
    expect_error(a, "--proxy-downscale must be 1 or 2 (got 4)");
    snprintf(a, sizeof a, "eval @/ds %s --out @/v --proxy-render foo", dep);
    expect_error(a, "--proxy-render must be mesh or splat, not 'foo'");
    expect_error("eval @/ds --depth @/trunc.npy --out @/v --test-cams 1", "trunc.npy");
    expect_error("run @/ds", "--out");
    expect_error("run @/garbled.mp4 --depth @/good.npy --out @/u", "garbled.mp4");
    expect_error("run @/ds --depth @/wrongframes.npy --out @/u", "wrongframes.npy");
    snprintf(a, sizeof a, "run @/ds %s --out @/u --size 100000x100000", dep);
    expect_error(a, "--size");
    snprintf(a, sizeof a, "run @/ds %s --out @/u --frames -1", dep);
    expect_error(a, "--frames");
    snprintf(a, sizeof a, "run @/ds %s --out @/u --threads -1", dep);
    expect_error(a, "--threads");
    snprintf(a, sizeof a, "run @/ds %s --out @/u --proxies -3", dep);
    expect_error(a, "--proxies");
    snprintf(a, sizeof a, "run @/ds %s --out @/u --depth-scale -1", dep);
    expect_error(a, "--depth-scale");
    snprintf(a, sizeof a, "run @/ds %s --out @/u --densify-until -2", dep);
    expect_error(a, "--densify-until must be >= 1 (got -2)");
    expect_error("run @/ds --depth @/nan.npy --out @/u2", "valid depth");
    {
        char marker[4300];
        snprintf(marker, sizeof marker, "%s/u2/prepare.done", dir);
        CHECK(!pg_path_exists(marker), "a failed run must not leave %s", marker);
    }

    /* demo and bench */
    expect_error("demo --bogus", "--bogus");
    expect_error("demo --frames -1", "--frames");
    expect_error("demo --iters -5", "--iters");
    expect_error("bench", "bench");
    expect_error("bench foo", "foo");
    expect_error("bench raster --gaussians -5", "--gaussians");
    expect_error("bench raster --width 100000 --height 100000", "--width");
    expect_error("bench proxy --num -1", "--num");
    expect_error("bench proxy --frames -1", "--frames");
    expect_error("bench proxy --render foo", "--render must be mesh or splat");
    expect_error("bench iteration --gaussians -5", "--gaussians");
    expect_error("bench loss --width -1", "--width");
    expect_error("bench deform --bogus", "--bogus");
    expect_error("bench deform --points 1000000000", "--points");
    expect_error("bench flow --bogus", "--bogus");

    /* --help everywhere */
    expect_help("--help", "  run |  demo |  info |  synth |  prepare |  proxies |  train |  render |  export |  eval |  bench ");
    {
        static const char *cmds[] = { "run", "demo", "info", "synth", "prepare", "proxies", "train", "render", "export",
                                      "eval", "bench" };
        for (size_t i = 0; i < sizeof cmds / sizeof cmds[0]; i++) {
            snprintf(a, sizeof a, "%s --help", cmds[i]);
            expect_help(a, cmds[i]);
        }
        static const char *benches[] = { "raster", "proxy", "iteration", "deform", "loss", "flow" };
        for (size_t i = 0; i < sizeof benches / sizeof benches[0]; i++) {
            snprintf(a, sizeof a, "bench %s --help", benches[i]);
            expect_help(a, benches[i]);
        }
    }
    return test_summary("test_cli_errors");
}
