/* test_proxy_generate.c - proxy_generate end to end on the analytic scene: directory layout,
 * trainset.json, depth volumes, resume (skip finished frames), settings change, determinism, errors. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

#include "core/fileutil.h"
#include "core/parallel.h"
#include "io/image_io.h"
#include "io/npy.h"
#include "proxy/poses.h"
#include "proxy/procedural.h"
#include "proxy/proxy.h"
#include "testlib.h"

enum { W = 96, H = 72, F = 3, M = 3 };

typedef struct {
    pg_camera cams[2]; /* real, test */
    int calls, fail_frame;
} source;

static pg_status get_frame(void *ctx, int camera, int frame, pg_image *out)
{
    source *s = ctx;
    s->calls++;
    if (frame == s->fail_frame) return pg_fail(PG_ERR_IO, "frame%04d.png: cannot read", frame);
    PG_TRY(pg_image_create(out, W, H, 3));
    proxy_procedural_render(&s->cams[camera], (float)frame, 2, out->data, NULL);
    return PG_OK;
}

int main(void)
{
    pg_set_threads(2);
    char base[1024], dir[1100], dir2[1100], path[2048], path2[2048];
    test_tmpdir("test_proxy_generate", base, sizeof base);
    snprintf(dir2, sizeof dir2, "%s/second", base);
    snprintf(dir, sizeof dir, "%s/first", base);

    source src = { .fail_frame = -1 };
    pg_camera_from_fov(&src.cams[0], W, H, 60);
    float *depth = malloc(sizeof(float) * F * W * H);
    for (int f = 0; f < F; f++) proxy_procedural_render(&src.cams[0], (float)f, 1, NULL, depth + (size_t)f * W * H);
    const float scale = 2.0f; /* depth given in half units */
    for (int i = 0; i < F * W * H; i++) depth[i] /= scale;

    float c[3], r;
    CHECK_OK(proxy_scene_center(&src.cams[0], depth, scale, c, &r));
    pg_camera proxies[M];
    CHECK_OK(proxy_poses_hemisphere(&src.cams[0], c, M, 15.0f, proxies));
    src.cams[1] = proxies[0];
    src.cams[1].cx += 1; /* a "test" camera (never used for proxies) */
    const char *pnames[M] = { "proxy00", "proxy01", "proxy02" };
    const char *tnames[1] = { "cam05" };

    proxy_job job = { 0 };
    job.frames = F; job.width = W; job.height = H; job.fps = 30;
    job.get_frame = get_frame; job.frame_ctx = &src;
    job.depth = depth; job.pose_scale = scale;
    job.real_name = "cam00"; job.real = src.cams[0];
    job.num_proxies = M; job.proxy_names = pnames; job.proxies = proxies;
    job.num_tests = 1; job.test_names = tnames; job.tests = &src.cams[1];
    memcpy(job.center, c, sizeof c); job.radius = r;
    job.input_path = "procedural"; job.depth_path = "procedural-depth";

    proxy_options o = proxy_default_options();
    o.fit.steps = 3;
    o.threads = 2;
    proxy_result res;
    CHECK_OK(proxy_generate(&o, &job, dir, &res));
    CHECK(res.frames_done == F && res.frames_skipped == 0, "done %d skipped %d", res.frames_done, res.frames_skipped);
    CHECK(res.mean_valid_fraction > 0.5, "mean valid fraction %g", res.mean_valid_fraction);
    CHECK(isnan(res.mean_source_psnr), "the mesh renderer fits nothing, yet reports source PSNR %g", res.mean_source_psnr);
    snprintf(path, sizeof path, "%s/.cache/depth/proxy00/0000.npy", dir);
    CHECK(!pg_path_exists(path), "per-frame depth kept after the volume was written (%s)", path);

    /* Layout and index. */
    for (int k = 0; k < M; k++)
        for (int f = 0; f < F; f++) {
            snprintf(path, sizeof path, "%s/%s/rgb/%04d.jpg", dir, pnames[k], f);
            CHECK(pg_path_exists(path), "%s missing", path);
            snprintf(path, sizeof path, "%s/%s/mask/%04d.png", dir, pnames[k], f);
            CHECK(pg_path_exists(path), "%s missing", path);
        }
    snprintf(path, sizeof path, "%s/cam05/rgb/0002.png", dir);
    CHECK(pg_path_exists(path), "test camera frame %s missing", path);
    pg_array a = { 0 };
    snprintf(path, sizeof path, "%s/proxy01/depth.npy", dir);
    CHECK_OK(io_npy_load(path, &a));
    CHECK(a.ndim == 3 && a.shape[0] == F && a.shape[1] == H && a.shape[2] == W, "proxy depth shape");
    pg_array_destroy(&a);
    snprintf(path, sizeof path, "%s/cam00/depth.npy", dir);
    CHECK_OK(io_npy_load(path, &a));
    CHECK(a.count == (size_t)F * W * H && fabsf(a.data[W * H / 2 + W / 2] - depth[W * H / 2 + W / 2] * scale) <= depth[W * H / 2 + W / 2] * scale / 2048,
          "real depth.npy not in pose units");
    pg_array_destroy(&a);

    char *text = NULL;
    size_t len = 0;
    snprintf(path, sizeof path, "%s/trainset.json", dir);
    CHECK_OK(pg_read_file(path, 1 << 20, &text, &len));
    cJSON *root = text ? cJSON_Parse(text) : NULL;
    CHECK(root != NULL, "trainset.json does not parse");
    if (root) {
        cJSON *cams = cJSON_GetObjectItem(root, "cameras");
        CHECK(cJSON_GetArraySize(cams) == 1 + M + 1, "%d cameras", cJSON_GetArraySize(cams));
        int nreal = 0, nproxy = 0, ntest = 0;
        cJSON *cam;
        cJSON_ArrayForEach(cam, cams)
        {
            const char *role = cJSON_GetStringValue(cJSON_GetObjectItem(cam, "role"));
            nreal += role && !strcmp(role, "real");
            nproxy += role && !strcmp(role, "proxy");
            ntest += role && !strcmp(role, "test");
            if (role && !strcmp(role, "proxy"))
                CHECK(cJSON_IsString(cJSON_GetObjectItem(cam, "mask")), "proxy without mask");
        }
        CHECK(nreal == 1 && nproxy == M && ntest == 1, "roles %d %d %d", nreal, nproxy, ntest);
        CHECK(cJSON_GetObjectItem(root, "frames")->valueint == F, "frames");
        double ps = cJSON_GetObjectItem(cJSON_GetObjectItem(root, "source"), "pose_scale")->valuedouble;
        CHECK(fabs(ps - scale) < 1e-6, "pose_scale %g", ps);
        cJSON_Delete(root);
    }
    free(text);

    /* Resume: same settings -> nothing recomputed, frames not even read. */
    int calls = src.calls;
    CHECK_OK(proxy_generate(&o, &job, dir, &res));
    CHECK(res.frames_done == 0 && res.frames_skipped == F, "rerun: done %d skipped %d", res.frames_done,
          res.frames_skipped);
    CHECK(src.calls == calls, "rerun read %d frames", src.calls - calls);
    /* Interrupted run: a missing marker recomputes just that frame. */
    snprintf(path, sizeof path, "%s/.cache/done/0001.txt", dir);
    remove(path);
    CHECK_OK(proxy_generate(&o, &job, dir, &res));
    CHECK(res.frames_done == 1 && res.frames_skipped == F - 1, "resume: done %d skipped %d", res.frames_done,
          res.frames_skipped);

    /* Determinism: a fresh directory gives the same bytes. */
    CHECK_OK(proxy_generate(&o, &job, dir2, &res));
    snprintf(path, sizeof path, "%s/proxy02/rgb/0001.jpg", dir);
    snprintf(path2, sizeof path2, "%s/proxy02/rgb/0001.jpg", dir2);
    CHECK(test_files_equal(path, path2), "%s and %s differ", path, path2);
    snprintf(path, sizeof path, "%s/proxy02/depth.npy", dir);
    snprintf(path2, sizeof path2, "%s/proxy02/depth.npy", dir2);
    CHECK(test_files_equal(path, path2), "%s and %s differ", path, path2);

    /* The paper's splat renderer through the same stage: fitted, so it reports a source PSNR. */
    proxy_options os = o;
    os.fit.render = PROXY_RENDER_SPLAT;
    snprintf(path, sizeof path, "%s_splat", dir2);
    CHECK_OK(proxy_generate(&os, &job, path, &res));
    CHECK(res.frames_done == F && res.mean_source_psnr > 20, "splat: %d frames, source PSNR %g", res.frames_done,
          res.mean_source_psnr);

    /* Changed settings -> everything recomputed. */
    o.fit.steps = 4;
    CHECK_OK(proxy_generate(&o, &job, dir, &res));
    CHECK(res.frames_done == F, "settings change recomputed %d frames", res.frames_done);

    /* Errors: a frame that cannot be read names the frame; bad scale is rejected. */
    o.fit.steps = 5;
    src.fail_frame = 2;
    pg_status st = proxy_generate(&o, &job, dir, &res);
    CHECK(st == PG_ERR_IO && strstr(pg_last_error(), "frame0002"), "read error: %d %s", st, pg_last_error());
    src.fail_frame = -1;
    job.pose_scale = 0;
    CHECK(proxy_generate(&o, &job, dir, &res) == PG_ERR_ARG, "pose scale 0 accepted");
    job.pose_scale = scale;
    job.num_proxies = -1;
    CHECK(proxy_generate(&o, &job, dir, &res) == PG_ERR_ARG, "negative proxy count accepted");
    /* A frame without valid depth: empty (fully masked) proxies, the run goes on. */
    memset(depth + (size_t)1 * W * H, 0, sizeof(float) * W * H);
    snprintf(path, sizeof path, "%s/nodepth", base);
    job.num_proxies = M;
    CHECK_OK(proxy_generate(&o, &job, path, &res));
    CHECK(res.frames_done == F, "frames with an empty depth map: done %d", res.frames_done);
    snprintf(path, sizeof path, "%s/nodepth/proxy00/mask/0001.png", base);
    pg_image mk = { 0 };
    CHECK_OK(io_image_load(path, &mk));
    float mmax = 0;
    for (size_t i = 0; i < (size_t)mk.width * mk.height * 3; i++) mmax = fmaxf(mmax, mk.data[i]);
    CHECK(mk.data && mmax == 0, "mask of a frame without depth is not empty (max %g)", mmax);
    pg_image_destroy(&mk);
    /* No proxies: the real view (and test cameras) only. */
    job.proxies = NULL;
    job.num_proxies = 0;
    snprintf(path, sizeof path, "%s/none", base);
    CHECK_OK(proxy_generate(&o, &job, path, &res));
    snprintf(path, sizeof path, "%s/none/cam00/rgb/0002.png", base);
    CHECK(pg_path_exists(path), "real frames missing without proxies");
    free(depth);
    return test_summary("test_proxy_generate");
}
