/* test_io_json.c - JSON helpers: camera round trip, checked getters, bad files; npy dtypes. */
#include "testlib.h"
#include "core/fileutil.h"
#include "core/mathx.h"
#include "io/json.h"
#include "io/npy.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static void test_camera(const char *dir)
{
    pg_camera cam;
    float eye[3] = { 1, -2, 0.5f }, target[3] = { 0, 0, 3 }, up[3] = { 0, -1, 0 };
    pg_camera_from_fov(&cam, 321, 239, 57.5f);
    cam.cx = 160.25f;
    pg_camera_look_at(&cam, eye, target, up);
    cJSON *root = cJSON_CreateObject();
    cJSON_AddItemToObject(root, "camera", io_json_from_camera(&cam, "cam07"));
    cJSON_AddNumberToObject(root, "fps", 29.97);
    char path[4096];
    pg_path_join(path, sizeof path, dir, "cam.json");
    CHECK_OK(io_json_write_atomic(path, root));
    cJSON_Delete(root);
    CHECK_OK(io_json_load(path, &root));
    if (!root) return;
    pg_camera back;
    char name[64];
    CHECK_OK(io_json_to_camera(cJSON_GetObjectItem(root, "camera"), path, &back, name, sizeof name));
    CHECK(!strcmp(name, "cam07") && memcmp(&back, &cam, sizeof cam) == 0, "camera JSON round trip is not exact (%s)", name);
    double fps;
    CHECK_OK(io_json_get_number(root, "fps", path, &fps));
    CHECK(fps == 29.97, "fps %g", fps);
    int n;
    CHECK(io_json_get_int(root, "fps", path, 0, 100, &n) == PG_ERR_FORMAT, "non-integer rejected");
    CHECK(io_json_get_number(root, "nope", path, &fps) == PG_ERR_FORMAT && strstr(pg_last_error(), "'nope'"), "missing key");
    /* A camera with a non-rotation R and one missing fx. */
    cJSON *c = cJSON_GetObjectItem(root, "camera");
    cJSON_ReplaceItemInObject(c, "R", io_json_float_array((float[9]){ 2, 0, 0, 0, 1, 0, 0, 0, 1 }, 9));
    CHECK(io_json_to_camera(c, path, &back, NULL, 0) == PG_ERR_FORMAT && strstr(pg_last_error(), "rotation"), "bad R: %s",
          pg_last_error());
    cJSON_DeleteItemFromObject(c, "fx");
    CHECK(io_json_to_camera(c, path, &back, NULL, 0) == PG_ERR_FORMAT && strstr(pg_last_error(), "'fx'"), "no fx: %s",
          pg_last_error());
    cJSON_Delete(root);
    pg_path_join(path, sizeof path, dir, "bad.json");
    pg_write_file_atomic(path, "{\"a\": [1, 2,", 12);
    CHECK(io_json_load(path, &root) == PG_ERR_FORMAT && strstr(pg_last_error(), "bad.json"), "garbled: %s", pg_last_error());
}

static void test_npy(const char *dir)
{
    char path[4096];
    /* float32 round trip, (2, 3, 4). */
    float v[24];
    for (int i = 0; i < 24; i++) v[i] = i * 0.5f - 3;
    size_t shape[3] = { 2, 3, 4 };
    pg_path_join(path, sizeof path, dir, "a.npy");
    CHECK_OK(io_npy_save(path, v, 3, shape));
    pg_array arr;
    CHECK_OK(io_npy_load(path, &arr));
    CHECK(arr.ndim == 3 && arr.shape[2] == 4 && arr.data && !memcmp(arr.data, v, sizeof v), "npy f32 round trip");
    pg_array_destroy(&arr);
    /* uint8 mask. */
    uint8_t m[6] = { 0, 1, 255, 3, 4, 5 };
    size_t ms[2] = { 2, 3 };
    pg_path_join(path, sizeof path, dir, "m.npy");
    CHECK_OK(io_npy_save_u8(path, m, 2, ms));
    CHECK_OK(io_npy_load(path, &arr));
    CHECK(arr.data && arr.data[2] == 255 && arr.count == 6, "npy u8");
    pg_array_destroy(&arr);
    /* Big-endian float64 written by hand. */
    pg_path_join(path, sizeof path, dir, "be.npy");
    FILE *fp = fopen(path, "wb");
    const char *dict = "{'descr': '>f8', 'fortran_order': False, 'shape': (2,), }";
    char hdr[128];
    int hl = snprintf(hdr, sizeof hdr, "%-117s\n", dict);
    uint8_t pre[10] = { 0x93, 'N', 'U', 'M', 'P', 'Y', 1, 0, (uint8_t)hl, 0 };
    fwrite(pre, 1, 10, fp);
    fwrite(hdr, 1, (size_t)hl, fp);
    double d[2] = { 1.25, -7.5 };
    for (int i = 0; i < 2; i++) {
        uint8_t b[8], r[8];
        memcpy(b, &d[i], 8);
        for (int k = 0; k < 8; k++) r[k] = b[7 - k];
        fwrite(r, 1, 8, fp);
    }
    fclose(fp);
    CHECK_OK(io_npy_load(path, &arr));
    CHECK(arr.data && arr.data[0] == 1.25f && arr.data[1] == -7.5f, "big-endian f8");
    pg_array_destroy(&arr);
}

/* `prodygs info` on a training-set directory (docs/FORMATS.md) and on a broken one. */
static void test_trainset_info(const char *dir)
{
    char sub[4096], path[4200], err[1024], args[8400];
    pg_path_join(sub, sizeof sub, dir, "trainset");
    pg_mkdir_p(sub);
    pg_camera cam;
    pg_camera_from_fov(&cam, 64, 48, 60);
    cJSON *root = cJSON_CreateObject();
    cJSON_AddNumberToObject(root, "version", 1);
    cJSON_AddNumberToObject(root, "frames", 5);
    cJSON_AddNumberToObject(root, "width", 64);
    cJSON_AddNumberToObject(root, "height", 48);
    cJSON_AddNumberToObject(root, "fps", 30);
    cJSON *cams = cJSON_AddArrayToObject(root, "cameras");
    cJSON *c = io_json_from_camera(&cam, "cam00");
    cJSON_AddStringToObject(c, "role", "real");
    cJSON_AddItemToArray(cams, c);
    snprintf(path, sizeof path, "%s/trainset.json", sub);
    CHECK_OK(io_json_write_atomic(path, root));
    snprintf(args, sizeof args, "info '%s'", sub);
    CHECK(test_run_cli(args, err, sizeof err) == 0, "info trainset: %s", err);
    cJSON_ReplaceItemInObject(c, "R", io_json_float_array((float[9]){ 1, 1, 0, 0, 1, 0, 0, 0, 1 }, 9));
    CHECK_OK(io_json_write_atomic(path, root));
    int rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 2 && strstr(err, "trainset.json") && strstr(err, "rotation"), "info bad trainset rc %d: %s", rc, err);
    cJSON_Delete(root);
}

int main(void)
{
    char dir[4096];
    test_tmpdir("test_io_json", dir, sizeof dir);
    test_camera(dir);
    test_npy(dir);
    test_trainset_info(dir);
    return test_summary("test_io_json");
}
