/* test_core.c - core math, camera, rng, image and PNG/JPEG round trips, CLI basics. */
#include "testlib.h"
#include "core/camera.h"
#include "core/fileutil.h"
#include "core/image.h"
#include "core/mathx.h"
#include "core/resources.h"
#include "core/rng.h"
#include "io/image_io.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void test_quat_roundtrip(void)
{
    pg_rng rng;
    pg_rng_seed(&rng, 7);
    double worst = 0;
    for (int k = 0; k < 1000; k++) {
        float q[4] = { (float)pg_rng_normal(&rng), (float)pg_rng_normal(&rng), (float)pg_rng_normal(&rng),
                       (float)pg_rng_normal(&rng) };
        float n = sqrtf(q[0]*q[0] + q[1]*q[1] + q[2]*q[2] + q[3]*q[3]);
        for (int i = 0; i < 4; i++) q[i] /= n;
        if (q[0] < 0) for (int i = 0; i < 4; i++) q[i] = -q[i];
        float m[9], q2[4];
        quat_to_mat3(m, q);
        mat3_to_quat(q2, m);
        for (int i = 0; i < 4; i++) worst = fmax(worst, fabs(q[i] - q2[i]));
    }
    CHECK(worst < 1e-4, "quat -> mat3 -> quat error %g", worst);
}

static void test_camera(void)
{
    pg_camera cam;
    pg_camera_from_fov(&cam, 320, 240, 60);
    float eye[3] = { 1, -0.5f, -2 }, target[3] = { 0, 0, 3 }, up[3] = { 0, -1, 0 };
    pg_camera_look_at(&cam, eye, target, up);
    float C[3];
    pg_camera_center(&cam, C);
    CHECK(fabsf(C[0] - 1) < 1e-5f && fabsf(C[1] + 0.5f) < 1e-5f && fabsf(C[2] + 2) < 1e-5f, "centre %g %g %g", C[0], C[1], C[2]);
    float uv[2];
    float z = pg_camera_project(&cam, target, uv);
    CHECK(z > 0 && fabsf(uv[0] - 160) < 1e-3f && fabsf(uv[1] - 120) < 1e-3f, "target projects to %g %g", uv[0], uv[1]);
    float X[3];
    pg_camera_unproject(&cam, 10.5f, 200.25f, 4.0f, X);
    z = pg_camera_project(&cam, X, uv);
    CHECK(fabsf(z - 4) < 1e-4f && fabsf(uv[0] - 10.5f) < 1e-3f && fabsf(uv[1] - 200.25f) < 1e-3f,
          "unproject/project mismatch %g %g %g", uv[0], uv[1], z);
    /* Image "up" stays up: a world point above the target (smaller y is up here) has smaller v. */
    float above[3] = { 0, -1, 3 };
    pg_camera_project(&cam, above, uv);
    CHECK(uv[1] < 120, "up vector not respected, v=%g", uv[1]);
}

static void test_rng(void)
{
    pg_rng a, b;
    pg_rng_seed(&a, 42);
    pg_rng_seed(&b, 42);
    int same = 1;
    double mean = 0;
    for (int i = 0; i < 10000; i++) {
        double x = pg_rng_uniform(&a);
        if (x != pg_rng_uniform(&b)) same = 0;
        mean += x;
    }
    CHECK(same, "same seed gave different streams");
    CHECK(fabs(mean / 10000 - 0.5) < 0.01, "uniform mean %g", mean / 10000);
}

static void test_image_io(void)
{
    char dir[1024], path[1100];
    test_tmpdir("core", dir, sizeof dir);
    pg_image img, back;
    CHECK_OK(pg_image_create(&img, 37, 23, 3));
    for (int i = 0; i < 37 * 23 * 3; i++) img.data[i] = (float)((i * 7919) % 256) / 255.0f;
    snprintf(path, sizeof path, "%s/a.png", dir);
    CHECK_OK(io_image_save_png(path, &img));
    CHECK_OK(io_image_load(path, &back));
    CHECK(back.width == 37 && back.height == 23, "png size %dx%d", back.width, back.height);
    double psnr = pg_image_psnr(&img, &back, NULL);
    CHECK(psnr > 100, "png round trip psnr %g", psnr);
    pg_image_destroy(&back);
    snprintf(path, sizeof path, "%s/a.jpg", dir);
    for (int i = 0; i < 37 * 23 * 3; i++) img.data[i] = 0.5f + 0.3f * sinf(i * 0.01f);
    CHECK_OK(io_image_save_jpeg(path, &img, 95));
    CHECK_OK(io_image_load(path, &back));
    psnr = pg_image_psnr(&img, &back, NULL);
    CHECK(psnr > 35, "jpeg round trip psnr %g", psnr);
    pg_image_destroy(&back);
    /* A truncated PNG fails cleanly with the file named. */
    snprintf(path, sizeof path, "%s/a.png", dir);
    char cut[1200];
    snprintf(cut, sizeof cut, "%s/cut.png", dir);
    char *data; size_t size;
    CHECK_OK(pg_read_file(path, 1 << 20, &data, &size));
    CHECK_OK(pg_write_file_atomic(cut, data, size / 2));
    free(data);
    pg_status st = io_image_load(cut, &back);
    CHECK(st != PG_OK && strstr(pg_last_error(), "cut.png"), "truncated png: %s", pg_last_error());
    pg_image_destroy(&img);
}

static void test_cli_basics(void)
{
    char err[4096];
    int rc = test_run_cli("nosuchcommand", err, sizeof err);
    CHECK(rc == 2 && strstr(err, "unknown command"), "rc=%d err=%s", rc, err);
    rc = test_run_cli("--help", err, sizeof err);
    CHECK(rc == 0, "help rc=%d", rc);
}

/* A stage's memory window sees a 64 MiB buffer touched inside it (against a window that
 * allocates nothing), the process's peak is never lowered, and a folder's bytes count its files. */
static void test_resources(void)
{
    pg_peak_window w;
    memset(&w, 0, sizeof w);
    pg_peak_window_begin(&w);
    long base = pg_peak_window_end(&w); /* nothing allocated: about the resident size now */
    pg_peak_window_end(&w);             /* twice: harmless */
    pg_peak_window_begin(&w);
    size_t n = (size_t)64 << 20;
    char *big = malloc(n);
    if (big) memset(big, 1, n);
    long in = pg_peak_window_end(&w);
    CHECK(big && in - base >= 60 * 1024, "window peak %ld KiB after touching 64 MiB (%ld KiB before)", in, base);
    free(big);
    CHECK(pg_peak_rss_kb() >= in - 1024, "process peak %ld KiB below the window's %ld", pg_peak_rss_kb(), in);
    printf("memory windows: %ld KiB before, %ld KiB with the buffer\n", base, in);
    char dir[4096], path[4200];
    test_tmpdir("test_core_resources", dir, sizeof dir);
    snprintf(path, sizeof path, "%s/sub", dir);
    pg_mkdir_p(path);
    snprintf(path, sizeof path, "%s/sub/file.bin", dir);
    char *data = calloc(1, 1 << 20);
    if (data) memset(data, 7, 1 << 20);
    CHECK_OK(pg_write_file_atomic(path, data, 1 << 20));
    free(data);
    uint64_t bytes = pg_dir_bytes(dir);
    CHECK(bytes >= (1u << 20) && bytes < (3u << 20), "folder holds %llu bytes (1 MiB written)", (unsigned long long)bytes);
    CHECK(pg_dir_bytes("/nonexistent/prodygs") == 0, "a missing folder holds nothing");
    CHECK(pg_mem_available_bytes() > ((uint64_t)16 << 20), "available memory %llu", (unsigned long long)pg_mem_available_bytes());
    CHECK(pg_disk_free_bytes(dir) > 0, "free disk unknown");
}

int main(void)
{
    test_resources();
    test_quat_roundtrip();
    test_camera();
    test_rng();
    test_image_io();
    test_cli_basics();
    return test_summary("test_core");
}
