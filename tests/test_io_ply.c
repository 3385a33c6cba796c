/* test_io_ply.c - Gaussian PLY: exact round trip, channel-major f_rest mapping, other property
 * orders/types, missing optional properties, truncation, absurd counts, garbage; `prodygs info`. */
#include "testlib.h"
#include "core/fileutil.h"
#include "core/rng.h"
#include "io/ply.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static void fill(pg_gaussians *g, int n, unsigned seed)
{
    pg_rng rng;
    pg_rng_seed(&rng, seed);
    splat_gaussians_create(g, n);
    splat_gaussians_resize(g, n);
    g->sh_degree = 2;
    for (int i = 0; i < n * 3; i++) g->means[i] = (float)pg_rng_normal(&rng);
    for (int i = 0; i < n * 3; i++) g->log_scales[i] = (float)pg_rng_normal(&rng) - 3;
    for (int i = 0; i < n * 4; i++) g->quats[i] = (float)pg_rng_normal(&rng);
    for (int i = 0; i < n; i++) g->opacity[i] = (float)pg_rng_normal(&rng);
    for (int i = 0; i < n * PG_SH_COEFFS * 3; i++) g->sh[i] = (float)pg_rng_normal(&rng);
}

static int same(const float *a, const float *b, size_t n) { return memcmp(a, b, n * sizeof(float)) == 0; }

static void test_roundtrip(const char *dir)
{
    char path[4096];
    pg_path_join(path, sizeof path, dir, "g.ply");
    pg_gaussians g, h;
    fill(&g, 57, 3);
    CHECK_OK(io_ply_save(path, &g));
    CHECK_OK(io_ply_load(path, &h));
    CHECK(h.count == 57 && h.sh_degree == 2, "count %d degree %d", h.count, h.sh_degree);
    if (h.count == 57) {
        CHECK(same(g.means, h.means, 57 * 3) && same(g.log_scales, h.log_scales, 57 * 3) && same(g.quats, h.quats, 57 * 4) &&
                  same(g.opacity, h.opacity, 57) && same(g.sh, h.sh, 57 * 48),
              "round trip is not bit exact");
    }
    /* Channel-major f_rest: read the raw row of vertex 0 and find SH coefficient 1 of green at f_rest_15. */
    char *data;
    size_t size;
    if (pg_read_file(path, 1 << 24, &data, &size) == PG_OK) {
        const char *end = strstr(data, "end_header\n");
        CHECK(end != NULL, "header end");
        CHECK(strstr(data, "property float f_rest_44\nproperty float opacity\nproperty float scale_0") != NULL,
              "standard 3DGS property order");
        if (end) {
            float row[62];
            memcpy(row, end + 11, sizeof row);
            CHECK(row[6] == g.sh[0] && row[7] == g.sh[1] && row[9 + 15] == g.sh[1 * 3 + 1] && row[9 + 2 * 15 + 14] == g.sh[15 * 3 + 2],
                  "f_rest channel-major mapping");
            CHECK(row[54] == g.opacity[0] && row[55] == g.log_scales[0] && row[58] == g.quats[0], "opacity/scale/rot slots");
        }
        free(data);
    }
    io_ply_info info;
    CHECK_OK(io_ply_probe(path, &info));
    CHECK(info.count == 57 && info.sh_degree == 2 && info.bbox_min[0] <= g.means[0] && info.bbox_max[0] >= g.means[0], "probe");
    char err[1024], args[8300];
    snprintf(args, sizeof args, "info '%s'", path);
    CHECK(test_run_cli(args, err, sizeof err) == 0, "info on a good PLY: %s", err);
    splat_gaussians_destroy(&g);
    splat_gaussians_destroy(&h);
}

/* A hand-written PLY: other element first, shuffled order, double x, uchar colours, no f_rest/rot/scale. */
static void test_variants(const char *dir)
{
    char path[4096];
    pg_path_join(path, sizeof path, dir, "pc.ply");
    FILE *fp = fopen(path, "wb");
    fprintf(fp, "ply\r\nformat binary_little_endian 1.0\r\ncomment hello\r\nelement camera 1\r\nproperty float fov\r\n"
                "element vertex 2\r\nproperty uchar red\r\nproperty double x\r\nproperty float z\r\nproperty float y\r\n"
                "property uchar green\r\nproperty uchar blue\r\nproperty float opacity\r\n"
                "element face 1\r\nproperty list uchar int vertex_indices\r\nend_header\r\n");
    float fov = 1;
    fwrite(&fov, 4, 1, fp);
    for (int i = 0; i < 2; i++) {
        uint8_t r = 255, gb = 0;
        double x = 1.5 + i;
        float z = 3, y = -2, o = 0.5f;
        fwrite(&r, 1, 1, fp);
        fwrite(&x, 8, 1, fp);
        fwrite(&z, 4, 1, fp);
        fwrite(&y, 4, 1, fp);
        fwrite(&gb, 1, 1, fp);
        fwrite(&gb, 1, 1, fp);
        fwrite(&o, 4, 1, fp);
    }
    fclose(fp);
    pg_gaussians g;
    CHECK_OK(io_ply_load(path, &g));
    if (g.count == 2) {
        CHECK(g.means[3] == 2.5f && g.means[4] == -2 && g.means[5] == 3, "shuffled props %g %g %g", g.means[3], g.means[4], g.means[5]);
        CHECK(fabsf(g.sh[0] * 0.28209479f + 0.5f - 1.0f) < 1e-5f && fabsf(g.sh[1] * 0.28209479f + 0.5f) < 1e-5f, "rgb -> dc");
        CHECK(g.quats[0] == 1 && g.quats[1] == 0 && fabsf(g.log_scales[0] - logf(0.01f)) < 1e-5f && g.sh_degree == 0, "defaults");
        CHECK(g.opacity[1] == 0.5f, "opacity");
    } else
        CHECK(0, "variant count %d", g.count);
    splat_gaussians_destroy(&g);
}

static void write_bytes(const char *path, const char *text, size_t extra_zero_bytes)
{
    FILE *fp = fopen(path, "wb");
    fputs(text, fp);
    for (size_t i = 0; i < extra_zero_bytes; i++) fputc(0, fp);
    fclose(fp);
}

static void expect_bad(const char *dir, const char *name, const char *text, size_t extra, pg_status want)
{
    char path[4096], err[1024], args[8300];
    pg_path_join(path, sizeof path, dir, name);
    write_bytes(path, text, extra);
    pg_gaussians g;
    pg_status st = io_ply_load(path, &g);
    CHECK(st == want && strstr(pg_last_error(), name), "%s: status %d (%s)", name, (int)st, pg_last_error());
    snprintf(args, sizeof args, "info '%s'", path);
    int rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 2 && strstr(err, name) && !strchr(strchr(err, '\n') ? strchr(err, '\n') + 1 : "", '\n'),
          "info %s rc %d: %s", name, rc, err);
}

static void test_bad(const char *dir)
{
    const char *hdr = "ply\nformat binary_little_endian 1.0\nelement vertex 10\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
    expect_bad(dir, "trunc.ply", hdr, 12 * 9 + 5, PG_ERR_FORMAT);
    expect_bad(dir, "huge.ply",
               "ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000000000\nproperty float x\nproperty float y\n"
               "property float z\nend_header\n", 12, PG_ERR_SIZE);
    expect_bad(dir, "bigcount.ply",
               "ply\nformat binary_little_endian 1.0\nelement vertex 100000000\nproperty float x\nproperty float y\n"
               "property float z\nend_header\n", 12, PG_ERR_FORMAT);
    expect_bad(dir, "ascii.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n", 0, PG_ERR_FORMAT);
    expect_bad(dir, "garbage.ply", "\x01\x02garbage", 100, PG_ERR_FORMAT);
    expect_bad(dir, "noxyz.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nend_header\n", 4,
               PG_ERR_FORMAT);
    expect_bad(dir, "noend.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\n", 0, PG_ERR_FORMAT);
    /* f_rest count that is not 0/9/24/45. */
    char text[2048] = "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n";
    for (int k = 0; k < 5; k++) snprintf(text + strlen(text), sizeof text - strlen(text), "property float f_rest_%d\n", k);
    strcat(text, "end_header\n");
    expect_bad(dir, "rest5.ply", text, 32, PG_ERR_FORMAT);
}

int main(void)
{
    char dir[4096];
    test_tmpdir("test_io_ply", dir, sizeof dir);
    test_roundtrip(dir);
    test_variants(dir);
    test_bad(dir);
    return test_summary("test_io_ply");
}
