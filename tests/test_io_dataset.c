/* test_io_dataset.c - DyNeRF (LLFF -> OpenCV), Panoptic and single-video loaders on layouts the
 * test writes; bad layouts; the shared tabletop_dev sample when present. */
#include "testlib.h"
#include "core/camera.h"
#include "core/fileutil.h"
#include "core/mathx.h"
#include "io/dataset.h"
#include "io/depth_io.h"
#include "io/image_io.h"
#include "io/json.h"
#include "io/npy.h"
#include "io/video.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define FW 48
#define FH 32
#define NF 4

static void frame_image(pg_image *img, int cam, int t)
{
    pg_image_create(img, FW, FH, 3);
    for (int y = 0; y < FH; y++)
        for (int x = 0; x < FW; x++) {
            float *p = pg_image_at(img, x, y);
            p[0] = 0.2f + 0.15f * cam;
            p[1] = 0.1f + 0.2f * t;
            p[2] = (float)x / FW;
        }
}

/* OpenCV camera-to-world rotation -> LLFF row [down right back | C | hwf] + near far. */
static void llff_row(float *row, const float Rc2w[9], const float C[3], float h, float w, float f, float nearz, float farz)
{
    for (int r = 0; r < 3; r++) {
        row[r * 5 + 0] = Rc2w[r * 3 + 1];  /* down = OpenCV y */
        row[r * 5 + 1] = Rc2w[r * 3 + 0];  /* right = OpenCV x */
        row[r * 5 + 2] = -Rc2w[r * 3 + 2]; /* back = -forward */
        row[r * 5 + 3] = C[r];
    }
    row[4] = h;
    row[9] = w;
    row[14] = f;
    row[15] = nearz;
    row[16] = farz;
}

static void test_dynerf(const char *dir)
{
    char root[4096], p[4300];
    pg_path_join(root, sizeof root, dir, "dynerf");
    pg_mkdir_p(root);
    /* cam00: identity at the origin; cam01: rotated 30 deg about an oblique axis, centred at (1, -0.5, 0.2).
     * hwf is given at twice the frame size to check the intrinsics scaling. */
    float rows[2 * 17];
    float I[9], Rb[9], axis[3] = { 0.3f, 1.0f, 0.2f }, C0[3] = { 0, 0, 0 }, C1[3] = { 1.0f, -0.5f, 0.2f };
    mat3_identity(I);
    vec3_normalize(axis);
    mat3_axis_angle(Rb, axis, 0.5236f);
    llff_row(rows, I, C0, 2 * FH, 2 * FW, 80.0f, 0.5f, 9.0f);
    llff_row(rows + 17, Rb, C1, 2 * FH, 2 * FW, 80.0f, 0.6f, 8.0f);
    size_t shape[2] = { 2, 17 };
    pg_path_join(p, sizeof p, root, "poses_bounds.npy");
    CHECK_OK(io_npy_save(p, rows, 2, shape));
    /* cam00 as a PNG folder (camXX/images), cam01 as a video. */
    pg_image frames[NF];
    snprintf(p, sizeof p, "%s/cam00/images", root);
    pg_mkdir_p(p);
    for (int t = 0; t < NF; t++) {
        pg_image img;
        frame_image(&img, 0, t);
        snprintf(p, sizeof p, "%s/cam00/images/%04d.png", root, t);
        CHECK_OK(io_image_save_png(p, &img));
        pg_image_destroy(&img);
        frame_image(&frames[t], 1, t);
    }
    io_video_write_options wo = io_video_write_defaults();
    wo.crf = 10;
    pg_path_join(p, sizeof p, root, "cam01.mp4");
    CHECK_OK(io_video_write(p, frames, NF, &wo, NULL));

    pg_dataset *ds = NULL;
    io_dataset_options o = io_dataset_defaults();
    CHECK_OK(io_dataset_open(root, &o, &ds));
    if (!ds) return;
    CHECK(io_dataset_get_kind(ds) == IO_DATASET_DYNERF, "kind %d", (int)io_dataset_get_kind(ds));
    CHECK(io_dataset_num_cameras(ds) == 2 && io_dataset_num_frames(ds) == NF, "cams %d frames %d",
          io_dataset_num_cameras(ds), io_dataset_num_frames(ds));
    CHECK(!strcmp(io_dataset_camera_name(ds, 1), "cam01") && io_dataset_find_camera(ds, "cam00") == 0, "names %s",
          io_dataset_camera_name(ds, 1));
    float nz, fz;
    io_dataset_near_far(ds, 1, &nz, &fz);
    CHECK(nz == 0.6f && fz == 8.0f, "near/far %g %g", nz, fz);
    /* A point given in cam01's OpenCV frame must project where the pinhole model says. */
    pg_camera cam;
    io_dataset_camera(ds, 1, &cam);
    CHECK(cam.width == FW && fabsf(cam.fx - 40.0f) < 1e-4f && fabsf(cam.cx - FW / 2.0f) < 1e-4f, "intrinsics fx %g cx %g",
          cam.fx, cam.cx);
    float xc[3] = { 0.3f, -0.2f, 3.0f }, Xw[3], tmp[3], uv[2];
    mat3_mul_vec(tmp, Rb, xc);
    vec3_add(Xw, tmp, C1);
    float z = pg_camera_project(&cam, Xw, uv);
    float eu = 40.0f * 0.1f + FW / 2.0f, ev = 40.0f * (-0.2f / 3.0f) + FH / 2.0f;
    double perr = hypot(uv[0] - eu, uv[1] - ev);
    CHECK(fabsf(z - 3.0f) < 1e-4f && perr < 1e-3, "LLFF->OpenCV projection off by %g px (z %g)", perr, z);
    float Cc[3];
    pg_camera_center(&cam, Cc);
    CHECK(fabsf(Cc[0] - 1.0f) < 1e-5f && fabsf(Cc[1] + 0.5f) < 1e-5f, "centre %g %g %g", Cc[0], Cc[1], Cc[2]);
    pg_image img;
    CHECK_OK(io_dataset_frame(ds, 0, 2, &img));
    if (img.data) CHECK(fabsf(pg_image_at(&img, 5, 5)[1] - (0.1f + 0.4f)) < 0.01f, "cam00 frame 2 value");
    pg_image_destroy(&img);
    CHECK_OK(io_dataset_frame(ds, 1, 3, &img));
    if (img.data) CHECK(pg_image_psnr(&img, &frames[3], NULL) > 35, "cam01 frame 3 psnr %g", pg_image_psnr(&img, &frames[3], NULL));
    pg_image_destroy(&img);
    CHECK(io_dataset_frame(ds, 1, NF, &img) == PG_ERR_ARG, "frame out of range");
    io_dataset_close(ds);

    /* Resize + selection: half size, frames 1 and 3. */
    o.width = FW / 2;
    o.first = 1;
    o.stride = 2;
    CHECK_OK(io_dataset_open(root, &o, &ds));
    if (ds) {
        io_dataset_camera(ds, 1, &cam);
        CHECK(io_dataset_num_frames(ds) == 2 && io_dataset_height(ds) == FH / 2, "selection %d frames h %d",
              io_dataset_num_frames(ds), io_dataset_height(ds));
        CHECK(fabsf(cam.fx - 20.0f) < 1e-4f && fabsf(cam.cy - FH / 4.0f) < 1e-4f, "resized fx %g cy %g", cam.fx, cam.cy);
        CHECK_OK(io_dataset_frame(ds, 0, 1, &img));
        if (img.data) CHECK(fabsf(pg_image_at(&img, 2, 2)[1] - 0.7f) < 0.01f && img.width == FW / 2, "frame 3 via stride");
        pg_image_destroy(&img);
        io_dataset_close(ds);
    }

    /* poses_bounds of the wrong size; camera count mismatch. */
    char err[1024], args[8300];
    pg_path_join(p, sizeof p, root, "poses_bounds.npy");
    size_t bad[2] = { 2, 16 };
    CHECK_OK(io_npy_save(p, rows, 2, bad));
    CHECK(io_dataset_open(root, &o, &ds) == PG_ERR_FORMAT, "wrong size: %s", pg_last_error());
    CHECK(strstr(pg_last_error(), "poses_bounds.npy") != NULL, "names file: %s", pg_last_error());
    snprintf(args, sizeof args, "info '%s'", root);
    int rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 2 && strstr(err, "poses_bounds.npy"), "info rc %d: %s", rc, err);
    size_t one[2] = { 1, 17 };
    CHECK_OK(io_npy_save(p, rows, 2, one));
    CHECK(io_dataset_open(root, &o, &ds) == PG_ERR_FORMAT, "count mismatch: %s", pg_last_error());
    for (int t = 0; t < NF; t++) pg_image_destroy(&frames[t]);
}

static void test_panoptic(const char *dir)
{
    char root[4096], p[4300];
    pg_path_join(root, sizeof root, dir, "panoptic");
    int ids[3] = { 4, 7, 9 };
    for (int c = 0; c < 3; c++)
        for (int t = 0; t < 3; t++) {
            snprintf(p, sizeof p, "%s/ims/%d", root, ids[c]);
            pg_mkdir_p(p);
            pg_image img;
            frame_image(&img, c, t);
            snprintf(p, sizeof p, "%s/ims/%d/%06d.jpg", root, ids[c], t);
            CHECK_OK(io_image_save_jpeg(p, &img, 95));
            pg_image_destroy(&img);
        }
    /* train: cams 4, 7; test: cam 9. w2c = [R | t] with R about z by 10 deg per camera. */
    for (int f = 0; f < 2; f++) {
        int c0 = f == 0 ? 0 : 2, nc = f == 0 ? 2 : 1;
        cJSON *root_j = cJSON_CreateObject();
        cJSON_AddNumberToObject(root_j, "w", FW);
        cJSON_AddNumberToObject(root_j, "h", FH);
        cJSON *k = cJSON_AddArrayToObject(root_j, "k"), *w2c = cJSON_AddArrayToObject(root_j, "w2c");
        cJSON *fn = cJSON_AddArrayToObject(root_j, "fn"), *cid = cJSON_AddArrayToObject(root_j, "cam_id");
        for (int t = 0; t < 3; t++) {
            cJSON *kt = cJSON_CreateArray(), *wt = cJSON_CreateArray(), *ft = cJSON_CreateArray(), *ct = cJSON_CreateArray();
            for (int c = c0; c < c0 + nc; c++) {
                float K[9] = { 50 + c, 0, 24, 0, 51 + c, 16, 0, 0, 1 };
                float a = 0.1745f * c, M[16] = { cosf(a), -sinf(a), 0, 0.1f * c, sinf(a), cosf(a), 0, 0.2f, 0, 0, 1, 3, 0, 0, 0, 1 };
                cJSON *km = cJSON_CreateArray(), *wm = cJSON_CreateArray();
                for (int r = 0; r < 3; r++) cJSON_AddItemToArray(km, io_json_float_array(K + 3 * r, 3));
                for (int r = 0; r < 4; r++) cJSON_AddItemToArray(wm, io_json_float_array(M + 4 * r, 4));
                cJSON_AddItemToArray(kt, km);
                cJSON_AddItemToArray(wt, wm);
                char name[64];
                snprintf(name, sizeof name, "%d/%06d.jpg", ids[c], t);
                cJSON_AddItemToArray(ft, cJSON_CreateString(name));
                cJSON_AddItemToArray(ct, cJSON_CreateNumber(ids[c]));
            }
            cJSON_AddItemToArray(k, kt);
            cJSON_AddItemToArray(w2c, wt);
            cJSON_AddItemToArray(fn, ft);
            cJSON_AddItemToArray(cid, ct);
        }
        pg_path_join(p, sizeof p, root, f == 0 ? "train_meta.json" : "test_meta.json");
        CHECK_OK(io_json_write_atomic(p, root_j));
        cJSON_Delete(root_j);
    }
    pg_dataset *ds = NULL;
    io_dataset_options o = io_dataset_defaults();
    o.first = 1;
    CHECK_OK(io_dataset_open(root, &o, &ds));
    if (!ds) return;
    CHECK(io_dataset_get_kind(ds) == IO_DATASET_PANOPTIC && io_dataset_num_cameras(ds) == 3 && io_dataset_num_frames(ds) == 2,
          "panoptic kind %d cams %d frames %d", (int)io_dataset_get_kind(ds), io_dataset_num_cameras(ds),
          io_dataset_num_frames(ds));
    CHECK(!strcmp(io_dataset_camera_name(ds, 2), "9") && !strcmp(io_dataset_camera_role(ds, 2), "test") &&
              !strcmp(io_dataset_camera_role(ds, 0), "train"), "names/roles");
    pg_camera cam;
    io_dataset_camera(ds, 1, &cam);
    CHECK(cam.fx == 51 && cam.fy == 52 && cam.cx == 24 && fabsf(cam.R[1] + sinf(0.1745f)) < 1e-6f && cam.t[2] == 3,
          "panoptic camera fx %g R01 %g", cam.fx, cam.R[1]);
    pg_image img;
    CHECK_OK(io_dataset_frame(ds, 2, 1, &img)); /* camera "9", source frame 2 */
    if (img.data) CHECK(fabsf(pg_image_at(&img, 10, 10)[0] - 0.5f) < 0.03f && fabsf(pg_image_at(&img, 10, 10)[1] - 0.5f) < 0.03f,
                        "panoptic pixel %g %g", pg_image_at(&img, 10, 10)[0], pg_image_at(&img, 10, 10)[1]);
    pg_image_destroy(&img);
    io_dataset_close(ds);
    /* Missing key -> error naming the meta file. */
    pg_path_join(p, sizeof p, root, "test_meta.json");
    pg_write_file_atomic(p, "{\"w\": 48, \"h\": 32}", 18);
    CHECK(io_dataset_open(root, &o, &ds) == PG_ERR_FORMAT && strstr(pg_last_error(), "test_meta.json"), "bad meta: %s",
          pg_last_error());
    pg_write_file_atomic(p, "{\"w\": 48, \"h\": ", 15);
    CHECK(io_dataset_open(root, &o, &ds) == PG_ERR_FORMAT && strstr(pg_last_error(), "test_meta.json"), "garbled meta: %s",
          pg_last_error());
}

static void test_single(const char *dir)
{
    char p[4096];
    pg_path_join(p, sizeof p, dir, "clip.mp4");
    pg_image frames[NF];
    for (int t = 0; t < NF; t++) frame_image(&frames[t], 0, t);
    CHECK_OK(io_video_write(p, frames, NF, NULL, NULL));
    pg_dataset *ds = NULL;
    io_dataset_options o = io_dataset_defaults();
    CHECK_OK(io_dataset_open(p, &o, &ds));
    if (ds) {
        pg_camera cam;
        io_dataset_camera(ds, 0, &cam);
        CHECK(io_dataset_get_kind(ds) == IO_DATASET_VIDEO && io_dataset_num_cameras(ds) == 1 && io_dataset_num_frames(ds) == NF,
              "single video");
        CHECK(fabsf(cam.fx - (FW / 2.0f) / tanf(0.5236f)) < 1e-3f && cam.R[0] == 1 && cam.t[2] == 0, "fov 60 fx %g", cam.fx);
        CHECK(!strcmp(io_dataset_camera_name(ds, 0), "clip"), "name %s", io_dataset_camera_name(ds, 0));
        io_dataset_close(ds);
    }
    o.focal = 100;
    o.max_side = FW / 2;
    CHECK_OK(io_dataset_open(p, &o, &ds));
    if (ds) {
        pg_camera cam;
        io_dataset_camera(ds, 0, &cam);
        CHECK(fabsf(cam.fx - 50) < 1e-4f && io_dataset_width(ds) == FW / 2, "focal option fx %g", cam.fx);
        io_dataset_close(ds);
    }
    for (int t = 0; t < NF; t++) pg_image_destroy(&frames[t]);
    pg_path_join(p, sizeof p, dir, "nothing_here");
    pg_mkdir_p(p);
    CHECK(io_dataset_open(p, &o, &ds) != PG_OK && strstr(pg_last_error(), "nothing_here"), "empty dir: %s", pg_last_error());
}

/* tabletop_dev: reproject cam00 frame 0 into cam01 with depth_gt; colours must agree. */
static void test_tabletop(void)
{
    char root[4096], p[4300];
    if (!test_shared_data("tabletop_dev", root, sizeof root)) {
        printf("tabletop_dev absent: skipped\n");
        return;
    }
    pg_dataset *ds = NULL;
    io_dataset_options o = io_dataset_defaults();
    o.count = 1;
    CHECK_OK(io_dataset_open(root, &o, &ds));
    if (!ds) return;
    CHECK(io_dataset_num_cameras(ds) == 10, "tabletop cameras %d", io_dataset_num_cameras(ds));
    io_depth d;
    io_depth_options dopt = io_depth_defaults();
    dopt.count = 1;
    snprintf(p, sizeof p, "%s/depth_gt/cam00.npy", root);
    CHECK_OK(io_depth_load(p, &dopt, &d));
    pg_image a, b;
    pg_camera c0, c1;
    CHECK_OK(io_dataset_frame(ds, 0, 0, &a));
    CHECK_OK(io_dataset_frame(ds, 1, 0, &b));
    io_dataset_camera(ds, 0, &c0);
    io_dataset_camera(ds, 1, &c1);
    if (a.data && b.data && d.data) {
        int n = 0, good = 0, good_shift = 0;
        double sum = 0;
        for (int y = 0; y < a.height; y += 2)
            for (int x = 0; x < a.width; x += 2) {
                float z = d.data[(size_t)y * d.width + x], Xw[3], uv[2];
                if (z <= 0) continue;
                pg_camera_unproject(&c0, x + 0.5f, y + 0.5f, z, Xw);
                if (pg_camera_project(&c1, Xw, uv) <= 0) continue;
                int u = (int)floorf(uv[0]), v = (int)floorf(uv[1]);
                if (u < 4 || v < 4 || u >= b.width - 4 || v >= b.height - 4) continue;
                const float *pa = pg_image_at(&a, x, y), *pb = pg_image_at(&b, u, v), *ps = pg_image_at(&b, u + 4, v + 3);
                float e = (fabsf(pa[0] - pb[0]) + fabsf(pa[1] - pb[1]) + fabsf(pa[2] - pb[2])) / 3;
                float es = (fabsf(pa[0] - ps[0]) + fabsf(pa[1] - ps[1]) + fabsf(pa[2] - ps[2])) / 3;
                n++;
                sum += e;
                good += e < 0.06f;
                good_shift += es < 0.06f;
            }
        double frac = n ? (double)good / n : 0, frac_shift = n ? (double)good_shift / n : 0;
        printf("tabletop cam00->cam01 reprojection: %d px, mean |diff| %.4f, %.1f%% within 0.06 (shifted by (4,3) px: %.1f%%)\n",
               n, n ? sum / n : 0, 100 * frac, 100 * frac_shift);
        CHECK(n > 1000 && frac > 0.8 && frac > frac_shift + 0.1, "reprojection agreement %.3f (shifted %.3f)", frac, frac_shift);
    }
    pg_image_destroy(&a);
    pg_image_destroy(&b);
    io_depth_destroy(&d);
    io_dataset_close(ds);
}

int main(void)
{
    char dir[4096];
    test_tmpdir("test_io_dataset", dir, sizeof dir);
    test_dynerf(dir);
    test_panoptic(dir);
    test_single(dir);
    test_tabletop();
    return test_summary("test_io_dataset");
}
