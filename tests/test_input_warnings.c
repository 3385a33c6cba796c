/* test_input_warnings.c - inputs that run but are probably not what the user meant get one
 * warning line (and still exit 0): disparity passed as depth, a --size that changes the aspect.
 * (The variable-frame-rate warning is tested in test_io_video.c, where the test makes such a
 * video.) */
#include "testlib.h"
#include "core/fileutil.h"
#include "depth/depth_check.h"
#include "io/npy.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static char dir[4096];

static int count_lines(const char *text, const char *needle)
{
    int n = 0;
    for (const char *p = strstr(text, needle); p; p = strstr(p + 1, needle)) n++;
    return n;
}

int main(void)
{
    char err[8192], args[16000], path[4300];
    test_tmpdir("input_warnings", dir, sizeof dir);
    snprintf(args, sizeof args, "synth '%s/ds' --cams 1 --frames 4 --size 64x48 --spp 1 --threads 1", dir);
    CHECK(test_run_cli(args, err, sizeof err) == 0, "synth fixture: %s", err);

    /* the check itself: the scene's depth grows towards the top, its inverse does not */
    pg_array depth = { 0 };
    snprintf(path, sizeof path, "%s/ds/depth_mono/cam00.npy", dir);
    CHECK_OK(io_npy_load(path, &depth));
    if (depth.ndim == 3) {
        int F = (int)depth.shape[0], H = (int)depth.shape[1], W = (int)depth.shape[2];
        double as_depth = depth_share_inverted_frames(depth.data, F, W, H);
        for (size_t i = 0; i < depth.count; i++) depth.data[i] = depth.data[i] > 0 ? 1.0f / depth.data[i] : 0.0f;
        double as_inverse = depth_share_inverted_frames(depth.data, F, W, H);
        CHECK(as_depth <= 0.25 && as_inverse >= 0.75, "inverted-frame share: depth %.2f, inverse %.2f", as_depth, as_inverse);
        snprintf(path, sizeof path, "%s/disparity.npy", dir);
        CHECK_OK(io_npy_save(path, depth.data, 3, depth.shape));
        /* a square depth, as a user would make for a squashed --size (columns sampled) */
        float *square = malloc((size_t)F * H * H * sizeof(float));
        for (int f = 0; f < F; f++)
            for (int y = 0; y < H; y++)
                for (int x = 0; x < H; x++)
                    square[((size_t)f * H + y) * H + x] = 1.0f / depth.data[((size_t)f * H + y) * W + x * W / H];
        const size_t shape[3] = { (size_t)F, (size_t)H, (size_t)H };
        snprintf(path, sizeof path, "%s/square.npy", dir);
        CHECK_OK(io_npy_save(path, square, 3, shape));
        free(square);
    }
    pg_array_destroy(&depth);

    /* disparity given as depth: warned, exit 0; declared as disparity: silent */
    snprintf(args, sizeof args, "prepare '%s/ds' --depth '%s/disparity.npy' --out '%s/p1' --threads 1", dir, dir, dir);
    int rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 0 && count_lines(err, "warning:") == 1 && strstr(err, "looks like disparity") &&
          strstr(err, "--depth-kind disparity"), "disparity as depth: exit %d, %s", rc, err);
    snprintf(args, sizeof args, "prepare '%s/ds' --depth '%s/disparity.npy' --depth-kind disparity --out '%s/p2' --threads 1",
             dir, dir, dir);
    rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 0 && !strstr(err, "warning:"), "disparity declared: exit %d, %s", rc, err);

    /* a size that stretches the frames is warned about once; one side given keeps the aspect */
    snprintf(args, sizeof args, "prepare '%s/ds' --depth '%s/square.npy' --size 48x48 --out '%s/p3' --threads 1",
             dir, dir, dir);
    rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 0 && count_lines(err, "warning:") == 1 && strstr(err, "aspect ratio") && strstr(err, "64x48"),
          "--size 48x48: exit %d, %s", rc, err);
    snprintf(args, sizeof args, "prepare '%s/ds' --depth '%s/ds/depth_mono/cam00.npy' --size 32x0 --out '%s/p4' --threads 1",
             dir, dir, dir);
    rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 0 && !strstr(err, "warning:"), "--size 32x0: exit %d, %s", rc, err);

    /* issue 27: a frame folder with a number missing (0000, 0001, 0003) was read as consecutive
     * frames without a word; a complete folder says nothing */
    snprintf(args, sizeof args, "info '%s/ds/cam00/images'", dir);
    rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 0 && !strstr(err, "warning:"), "complete frame folder: exit %d, %s", rc, err);
    snprintf(path, sizeof path, "%s/gap", dir);
    pg_mkdir_p(path);
    for (int k = 0; k < 4; k++) {
        if (k == 2) continue;
        char src[4300], dst[4300], cmd[9000];
        snprintf(src, sizeof src, "%s/ds/cam00/images/%04d.png", dir, k);
        snprintf(dst, sizeof dst, "%s/gap/%04d.png", dir, k);
        snprintf(cmd, sizeof cmd, "cp '%s' '%s'", src, dst);
        CHECK(system(cmd) == 0, "%s", cmd);
    }
    snprintf(args, sizeof args, "info '%s/gap'", dir);
    rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 0 && count_lines(err, "warning:") == 1 && strstr(err, "jump from 1 to 3") && strstr(err, "0003.png"),
          "folder with a missing frame: exit %d, %s", rc, err);
    return test_summary("test_input_warnings");
}
