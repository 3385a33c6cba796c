/* test_stage_api.c - the pipeline in-process through the public stage API (include/prodygs.h):
 * stage markers skip current stages and rerun stale ones (new depth content under the same path
 * retrains), every stage runs with the thread count asked for, the seed reaches training, a bad
 * size fails before any stage, --depth-scale is a unit (same training, lengths scaled), and
 * docs/example_pipeline.c runs the stages one by one. */
#include "testlib.h"
#include "core/fileutil.h"
#include "io/json.h"
#include "io/npy.h"
#include "synth/synth.h"

#include <prodygs.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static double marker_number(const char *out, const char *stage, const char *field)
{
    char path[1400];
    snprintf(path, sizeof path, "%s/%s.done", out, stage);
    cJSON *m = NULL;
    if (io_json_load(path, &m) != PG_OK) return -1;
    double v = io_json_number_or(m, field, -1);
    cJSON_Delete(m);
    return v;
}

static void run_pipeline(const char *data, const char *depth, const char *out, int threads, pg_pipeline_report *r)
{
    pg_pipeline_config c;
    pg_pipeline_defaults(&c);
    c.input = data;
    c.depth = depth;
    c.out = out;
    c.test_cameras = "cam05,cam06";
    c.iters = 12;
    c.threads = threads;
    c.seed = 7;
    c.evaluate = 1;
    pg_status st = pg_pipeline_run(&c, r);
    CHECK(st == PG_OK, "pipeline in %s: %s", out, pg_last_error());
}

/* Every stage of a run with `threads` threads records that count. */
static void check_threads(const char *out, int threads)
{
    static const char *stages[3] = { "prepare", "proxies", "train" };
    for (int k = 0; k < 3; k++)
        CHECK(marker_number(out, stages[k], "threads") == threads, "%s: %s ran with %g threads, asked %d", out, stages[k],
              marker_number(out, stages[k], "threads"), threads);
    char path[1400];
    snprintf(path, sizeof path, "%s/metrics.json", out);
    cJSON *m = NULL;
    CHECK_OK(io_json_load(path, &m));
    const cJSON *ev = cJSON_GetObjectItem(cJSON_GetObjectItem(m, "stages"), "evaluate");
    CHECK(io_json_number_or(ev, "threads", -1) == threads, "evaluate recorded %g threads", io_json_number_or(ev, "threads", -1));
    cJSON_Delete(m);
}

/* Proxy 0's camera centre's distance from the real one (at the origin) in OUT/model/cameras.json. */
static double proxy_distance(const char *out)
{
    char path[4200];
    snprintf(path, sizeof path, "%s/model/cameras.json", out);
    cJSON *m = NULL;
    if (io_json_load(path, &m) != PG_OK) return -1;
    const cJSON *cams = cJSON_GetObjectItem(m, "cameras");
    double dist = -1;
    for (int k = 0; k < cJSON_GetArraySize(cams); k++) {
        const cJSON *cam = cJSON_GetArrayItem(cams, k);
        if (strcmp(io_json_string_or(cam, "name", ""), "proxy00") != 0) continue;
        pg_camera pc;
        if (io_json_to_camera(cam, path, &pc, NULL, 0) == PG_OK)
            dist = sqrt((double)pc.t[0] * pc.t[0] + (double)pc.t[1] * pc.t[1] + (double)pc.t[2] * pc.t[2]);
    }
    cJSON_Delete(m);
    return dist;
}

static int same_file(const char *a, const char *b)
{
    char *x = NULL, *y = NULL;
    size_t nx = 0, ny = 0;
    int same = pg_read_file(a, 1u << 26, &x, &nx) == PG_OK && pg_read_file(b, 1u << 26, &y, &ny) == PG_OK && nx == ny &&
               memcmp(x, y, nx) == 0;
    free(x);
    free(y);
    return same;
}

/* A single video's depth given in other units through --depth-scale trains the same model: every
 * stage computes on the same numbers (prepare brings depth to the clip's own unit and the factor
 * travels beside it), so the training camera's scores are equal to the bit and only the lengths
 * the model reports (cameras.json) are K times larger. */
static void check_depth_scale_is_a_unit(const char *frames_dir, const char *depth, const char *dir)
{
    static const float scales[3] = { 1.0f, 0.01f, 100.0f };
    pg_train_report t[3];
    double dist[3];
    char out[3][1300], a[1500], b[1500];
    for (int k = 0; k < 3; k++) {
        pg_pipeline_config c;
        pg_pipeline_defaults(&c);
        c.input = frames_dir;
        c.depth = depth;
        c.depth_scale = scales[k];
        snprintf(out[k], sizeof out[k], "%s/scale_%g", dir, scales[k]);
        c.out = out[k];
        c.iters = 30;
        c.proxies = 3;
        c.threads = 2;
        c.render_videos = 0;
        pg_pipeline_report r;
        CHECK(pg_pipeline_run(&c, &r) == PG_OK, "--depth-scale %g: %s", scales[k], pg_last_error());
        t[k] = r.train;
        dist[k] = proxy_distance(out[k]);
    }
    CHECK(t[0].train_psnr > 10 && dist[0] > 0, "depth scale 1: PSNR %.2f, proxy 0 at %g", t[0].train_psnr, dist[0]);
    for (int k = 1; k < 3; k++) {
        CHECK(t[k].train_psnr == t[0].train_psnr && t[k].train_psnr_moving == t[0].train_psnr_moving &&
                  t[k].train_psnr_static == t[0].train_psnr_static && t[k].gaussians == t[0].gaussians,
              "--depth-scale %g: PSNR %.6f / moving %.6f / static %.6f, %d Gaussians; x1: %.6f / %.6f / %.6f, %d",
              scales[k], t[k].train_psnr, t[k].train_psnr_moving, t[k].train_psnr_static, t[k].gaussians, t[0].train_psnr,
              t[0].train_psnr_moving, t[0].train_psnr_static, t[0].gaussians);
        snprintf(a, sizeof a, "%s/proxies/proxy01/depth.npy", out[0]);
        snprintf(b, sizeof b, "%s/proxies/proxy01/depth.npy", out[k]);
        CHECK(same_file(a, b), "--depth-scale %g: proxy depth differs from x1's (%s)", scales[k], b);
        CHECK(fabs(dist[k] / (dist[0] * scales[k]) - 1) < 1e-5, "--depth-scale %g: proxy 0 at %g, x1 at %g", scales[k],
              dist[k], dist[0]);
    }
}

int main(void)
{
    char dir[1024], data[1100], depth[1200], out[1200], path[1400], cmd[8192];
    test_tmpdir("stage_api", dir, sizeof dir);
    snprintf(data, sizeof data, "%s/data", dir);
    synth_options so;
    synth_options_default(&so);
    so.cams = 7;
    so.frames = 3;
    so.width = 32;
    so.height = 24;
    so.spp = 1;
    CHECK_OK(synth_write_dataset(data, &so));
    /* the depth lives outside the dataset so that rewriting it changes only the depth input */
    snprintf(path, sizeof path, "%s/depth_mono/cam00.npy", data);
    snprintf(depth, sizeof depth, "%s/depth.npy", dir);
    pg_array d = { 0 };
    CHECK_OK(io_npy_load(path, &d));
    CHECK_OK(io_npy_save(depth, d.data, d.ndim, d.shape));

    /* first run: every stage runs, with one thread, and the seed reaches training */
    snprintf(out, sizeof out, "%s/one", dir);
    pg_pipeline_report r;
    run_pipeline(data, depth, out, 1, &r);
    CHECK(r.ran[0] && r.ran[1] && r.ran[2] && r.ran[3], "first run: every stage runs (%d %d %d %d)", r.ran[0], r.ran[1],
          r.ran[2], r.ran[3]);
    CHECK(r.threads == 1 && r.train.threads == 1 && r.train.seed == 7, "threads %d/%d, seed %d", r.threads, r.train.threads,
          r.train.seed);
    CHECK(strcmp(r.train_camera, "cam00 (index 0)") == 0 && strcmp(r.test_cameras, "cam05 (index 5), cam06 (index 6)") == 0,
          "cameras '%s' / '%s'", r.train_camera, r.test_cameras);
    check_threads(out, 1);
    snprintf(path, sizeof path, "%s/model/train.json", out);
    cJSON *tj = NULL;
    CHECK_OK(io_json_load(path, &tj));
    CHECK(io_json_number_or(tj, "seed", -1) == 7, "train.json seed %g", io_json_number_or(tj, "seed", -1));
    CHECK(io_json_number_or(tj, "sh_degree", -1) == 0, "one real camera trains SH degree 0, train.json says %g",
          io_json_number_or(tj, "sh_degree", -1));
    cJSON_Delete(tj);
    double psnr = r.evaluation.psnr;
    CHECK(psnr > 5 && psnr < 60, "test PSNR %.2f", psnr);

    /* identical inputs: nothing but the evaluation runs, same scores */
    run_pipeline(data, depth, out, 1, &r);
    CHECK(!r.ran[0] && !r.ran[1] && !r.ran[2] && r.ran[3], "rerun: stages skipped (%d %d %d)", r.ran[0], r.ran[1], r.ran[2]);
    CHECK(r.evaluation.psnr == psnr, "rerun: PSNR %.4f vs %.4f", r.evaluation.psnr, psnr);

    /* new depth content under the same path: prepare, proxies and training run again */
    for (size_t i = 0; i < d.count; i++) d.data[i] *= (i % 7) ? 1.0f : 1.3f;
    CHECK_OK(io_npy_save(depth, d.data, d.ndim, d.shape));
    run_pipeline(data, depth, out, 1, &r);
    CHECK(r.ran[0] && r.ran[1] && r.ran[2], "new depth: stages rerun (%d %d %d)", r.ran[0], r.ran[1], r.ran[2]);
    CHECK(r.train.iterations == 12, "new depth: trained from scratch to %d iterations", r.train.iterations);
    pg_array_destroy(&d);

    /* two threads: every stage records two */
    snprintf(out, sizeof out, "%s/two", dir);
    run_pipeline(data, depth, out, 2, &r);
    CHECK(r.threads == 2 && r.train.threads == 2, "threads %d/%d", r.threads, r.train.threads);
    check_threads(out, 2);

    /* a bad size fails before any stage runs */
    pg_pipeline_config c;
    pg_pipeline_defaults(&c);
    c.input = data;
    c.depth = depth;
    snprintf(out, sizeof out, "%s/bad", dir);
    c.out = out;
    c.width = 320;
    c.height = -4;
    CHECK(pg_pipeline_run(&c, &r) == PG_ERR_ARG && strstr(pg_last_error(), "--size"), "bad size: %s", pg_last_error());
    CHECK(!pg_path_exists(out), "a bad size must not create %s", out);

    /* a 1-frame video runs to the end, videos included (the render stage read frame 1 before) */
    pg_pipeline_defaults(&c);
    char frames_dir[1300];
    snprintf(frames_dir, sizeof frames_dir, "%s/cam00/images", data);
    c.input = frames_dir;
    c.depth = depth;
    snprintf(out, sizeof out, "%s/one_frame", dir);
    c.out = out;
    c.frames = 1;
    c.iters = 5;
    c.proxies = 2;
    c.render_videos = 1;
    CHECK(pg_pipeline_run(&c, &r) == PG_OK && r.ran[4], "1-frame video: %s", pg_last_error());

    check_depth_scale_is_a_unit(frames_dir, depth, dir);

    /* the documented example: the four stages one by one */
    snprintf(out, sizeof out, "%s/example", dir);
    snprintf(cmd, sizeof cmd, "'%s' '%s' '%s' '%s' > '%s/example.log' 2>&1", PG_EXAMPLE_PATH, data, depth, out, dir);
    CHECK(system(cmd) == 0, "example_pipeline failed (see %s/example.log)", dir);
    snprintf(path, sizeof path, "%s/metrics.json", out);
    cJSON *m = NULL;
    CHECK_OK(io_json_load(path, &m));
    CHECK(io_json_number_or(m, "psnr", 0) > 5, "example PSNR %g", io_json_number_or(m, "psnr", 0));
    cJSON_Delete(m);
    return test_summary("test_stage_api");
}
