/* test_train_full_size.c - `--preset full`: a clip is trained at its working size, then its still
 * scene and its movers at the input's own size. The model scored at that size must beat the
 * working-size model drawn there (the only thing a working-size run can give), its cameras must be
 * at the input's size, and the report says so. */
#include "testlib.h"
#include "core/fileutil.h"
#include "io/json.h"
#include "synth/synth.h"

#include <prodygs.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int main(void)
{
    char dir[1024], data[1100], depth[1200], out[1200], path[1400];
    test_tmpdir("train_full_size", dir, sizeof dir);
    snprintf(data, sizeof data, "%s/data", dir);
    synth_options so;
    synth_options_default(&so);
    so.cams = 1;
    so.frames = 6;
    so.width = 128;
    so.height = 96;
    so.spp = 1;
    CHECK_OK(synth_write_dataset(data, &so));
    snprintf(depth, sizeof depth, "%s/depth_mono/cam00.npy", data);
    snprintf(out, sizeof out, "%s/run", dir);

    pg_pipeline_config c;
    pg_pipeline_defaults(&c);
    c.input = data;
    c.depth = depth;
    c.out = out;
    c.preset = "full";
    c.width = 64; /* the working size: half the input's */
    c.height = 48;
    c.iters = 120;
    c.threads = 2;
    pg_pipeline_report r;
    CHECK(pg_pipeline_run(&c, &r) == PG_OK, "full preset: %s", pg_last_error());
    const pg_train_report *t = &r.train;
    CHECK(t->full_width == 128 && t->full_height == 96, "scored at %dx%d, the input is 128x96", t->full_width, t->full_height);
    printf("full size: %.2f dB (moving %.2f, still %.2f); the working-size model drawn there %.2f (moving %.2f); %d still "
           "Gaussians added\n", t->full_psnr, t->full_psnr_moving, t->full_psnr_static, t->full_psnr_before,
           t->full_psnr_moving_before, t->full_still_added);
    CHECK(t->full_still_added > 0, "no still Gaussians added");
    CHECK(isfinite(t->full_psnr) && t->full_psnr >= t->full_psnr_before + 1.0, "full size %.2f dB, before %.2f: less than 1 dB gained",
          t->full_psnr, t->full_psnr_before);
    CHECK(isfinite(t->full_psnr_moving) && t->full_psnr_moving >= t->full_psnr_moving_before,
          "moving pixels at full size %.2f dB, before %.2f", t->full_psnr_moving, t->full_psnr_moving_before);

    /* the model's cameras are at the input's size, so renders, exports and the viewer are too */
    snprintf(path, sizeof path, "%s/model/cameras.json", out);
    cJSON *cams = NULL;
    CHECK_OK(io_json_load(path, &cams));
    CHECK(io_json_number_or(cams, "width", 0) == 128 && io_json_number_or(cams, "height", 0) == 96,
          "cameras.json is %gx%g", io_json_number_or(cams, "width", 0), io_json_number_or(cams, "height", 0));
    cJSON_Delete(cams);
    snprintf(path, sizeof path, "%s/report.md", out);
    char *text = NULL;
    size_t len = 0;
    CHECK_OK(pg_read_file(path, 1 << 20, &text, &len));
    CHECK(text && strstr(text, "at the input's size, 128x96"), "report.md does not score the input's size");
    free(text);

    /* a rerun finds the stage done and reports the same full-size figures from train.json */
    pg_pipeline_report again;
    CHECK(pg_pipeline_run(&c, &again) == PG_OK, "rerun: %s", pg_last_error());
    CHECK(!again.ran[2] && fabs(again.train.full_psnr - t->full_psnr) < 1e-6, "rerun: train ran %d, full %.4f vs %.4f",
          again.ran[2], again.train.full_psnr, t->full_psnr);
    return test_summary("test_train_full_size");
}
