/* test_io_synth.c - conventions across modules: datasets written by the built-in synthetic scene
 * (DyNeRF and Panoptic layouts) load through io_dataset with cameras that project every scene
 * point to the same pixel as synth's own cameras (<= 0.01 px), frames equal to synth's renders,
 * and depth_gt shaped like the frames. */
#include "testlib.h"
#include "core/camera.h"
#include "core/rng.h"
#include "io/dataset.h"
#include "io/depth_io.h"
#include "synth/synth.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define NC 4
#define NFR 3
#define SW 64
#define SH 48

static void check_layout(const char *dir, synth_layout layout, int video)
{
    synth_options so;
    synth_options_default(&so);
    so.cams = NC;
    so.frames = NFR;
    so.width = SW;
    so.height = SH;
    so.spp = 1;
    so.layout = layout;
    so.video = video;
    so.all_depth = 0;
    CHECK_OK(synth_write_dataset(dir, &so));
    if (video) {
        /* Keep only camXX.mp4 so the loader decodes the videos (it prefers frame folders). */
        char cmd[8400];
        snprintf(cmd, sizeof cmd, "rm -rf '%s'/cam[0-9][0-9]", dir);
        CHECK(system(cmd) == 0, "rm");
    }
    pg_dataset *ds = NULL;
    io_dataset_options o = io_dataset_defaults();
    CHECK_OK(io_dataset_open(dir, &o, &ds));
    if (!ds) return;
    const char *lname = layout == SYNTH_LAYOUT_PANOPTIC ? "panoptic" : "dynerf";
    CHECK(io_dataset_num_cameras(ds) == NC && io_dataset_num_frames(ds) == NFR, "%s: %d cams %d frames", lname,
          io_dataset_num_cameras(ds), io_dataset_num_frames(ds));
    synth_scene sc;
    synth_scene_default(&sc, so.seed);
    sc.spp = so.spp;
    pg_rng rng;
    pg_rng_seed(&rng, 5);
    double worst = 0;
    int checked = 0;
    for (int c = 0; c < io_dataset_num_cameras(ds); c++) {
        /* Synth camera index from the dataset camera's name (camXX or the Panoptic cam_id). */
        const char *name = io_dataset_camera_name(ds, c);
        int idx = atoi(name[0] == 'c' ? name + 3 : name);
        pg_camera mine, ref;
        io_dataset_camera(ds, c, &mine);
        CHECK_OK(synth_camera(&sc, idx, SW, SH, &ref));
        for (int k = 0; k < 200; k++) {
            float X[3] = { (float)pg_rng_range(&rng, -1, 1), (float)pg_rng_range(&rng, -1, 1), (float)pg_rng_range(&rng, 1.5, 5) };
            float a[2], b[2];
            if (pg_camera_project(&ref, X, a) <= 0.05f || pg_camera_project(&mine, X, b) <= 0.05f) continue;
            if (fabsf(a[0]) > 4 * SW || fabsf(a[1]) > 4 * SH) continue;
            worst = fmax(worst, hypot(a[0] - b[0], a[1] - b[1]));
            checked++;
        }
        /* Frame 1 equals synth's render (PNG exact up to 8-bit rounding; JPEG/H.264 lossy). */
        pg_image got, want = { 0 };
        CHECK_OK(io_dataset_frame(ds, c, 1, &got));
        CHECK_OK(synth_render_frame(&sc, &ref, synth_frame_time(1, NFR), &want, NULL, NULL));
        if (got.data && want.data) {
            double p = pg_image_psnr(&got, &want, NULL);
            /* PNG: exact up to rounding. JPEG / H.264 (4:2:0 chroma) on tiny textured frames: ~27 dB. */
            double need = (layout == SYNTH_LAYOUT_DYNERF && !video) ? 45 : 24;
            CHECK(p > need, "%s %s frame 1 PSNR %.2f (need %.0f)", lname, name, p, need);
            /* The frame index is right: the neighbouring frames' renders fit worse. */
            for (int f = 0; f < NFR; f += 2) {
                pg_image other = { 0 };
                CHECK_OK(synth_render_frame(&sc, &ref, synth_frame_time(f, NFR), &other, NULL, NULL));
                double po = other.data ? pg_image_psnr(&got, &other, NULL) : 99;
                CHECK(po < p, "%s %s: frame 1 matches render %d better (%.2f vs %.2f)", lname, name, f, po, p);
                pg_image_destroy(&other);
            }
        }
        pg_image_destroy(&got);
        pg_image_destroy(&want);
    }
    printf("%s%s: synth cameras vs loader, worst reprojection %.2e px over %d points\n", lname, video ? " (mp4)" : "",
           worst, checked);
    CHECK(checked > 300 && worst <= 0.01, "%s: loader camera differs from synth by %.4f px", lname, worst);
    /* depth_gt/cam00.npy validates against the frames. */
    char p[4300];
    snprintf(p, sizeof p, "%s/depth_gt/cam00.npy", dir);
    io_depth_options dop = io_depth_defaults();
    dop.expect_frames = io_dataset_num_frames(ds);
    dop.width = io_dataset_width(ds);
    dop.height = io_dataset_height(ds);
    io_depth d;
    CHECK_OK(io_depth_load(p, &dop, &d));
    CHECK(d.frames == NFR && d.width == SW && d.invalid < (size_t)SW * SH, "depth_gt %d frames, %zu invalid", d.frames, d.invalid);
    io_depth_destroy(&d);
    io_dataset_close(ds);
}

int main(void)
{
    char dir[4096], sub[4200];
    test_tmpdir("test_io_synth", dir, sizeof dir);
    snprintf(sub, sizeof sub, "%s/dynerf", dir);
    check_layout(sub, SYNTH_LAYOUT_DYNERF, 0);
    snprintf(sub, sizeof sub, "%s/dynerf_mp4", dir);
    check_layout(sub, SYNTH_LAYOUT_DYNERF, 1);
    snprintf(sub, sizeof sub, "%s/panoptic", dir);
    check_layout(sub, SYNTH_LAYOUT_PANOPTIC, 0);
    return test_summary("test_io_synth");
}
