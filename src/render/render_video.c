/* render_video.c - path rendering into videos (see render_video.h). */
#include "render/render_video.h"
#include "core/fileutil.h"
#include "core/parallel.h"
#include "core/progress.h"
#include "io/image_io.h"
#include "io/video.h"
#include "render/colormap.h"

#include <stdio.h>
#include <string.h>

typedef struct {
    io_video_writer *rgb, *depth, *compare;
} video_set;

static void video_set_abort(video_set *v)
{
    io_video_writer_abort(v->rgb);
    io_video_writer_abort(v->depth);
    io_video_writer_abort(v->compare);
    memset(v, 0, sizeof *v);
}

static pg_status open_writer(io_video_writer **w, const char *dir, const char *name, const char *suffix, int width,
                             int height, double fps, int *fallback)
{
    char file[512], path[4096];
    snprintf(file, sizeof file, "%s%s.mp4", name, suffix);
    PG_TRY(pg_path_join(path, sizeof path, dir, file));
    io_video_write_options vo = io_video_write_defaults();
    if (fps > 0) vo.fps = fps;
    PG_TRY(io_video_writer_open(w, path, width, height, &vo));
    if (io_video_writer_backend(*w) == IO_VIDEO_PNG_SEQUENCE) *fallback = 1;
    return PG_OK;
}

/* Copies src into dst at column offset x0 (dst is wider). */
static void blit(pg_image *dst, const pg_image *src, int x0)
{
    for (int y = 0; y < src->height && y < dst->height; y++)
        memcpy(pg_image_at(dst, x0, y), pg_image_at(src, 0, y), sizeof(float) * 3 * src->width);
}

pg_status render_video_write(render_model *rm, const pg_camera *real, const float center[3],
                             const render_video_options *opt, const char *out_dir, const char *name,
                             render_video_report *report)
{
    double start = pg_time_seconds();
    memset(report, 0, sizeof *report);
    const pg_camera *sized = opt->num_keys > 0 ? &opt->keys[0] : opt->use_camera ? &opt->camera : real;
    const int W = sized->width, H = sized->height;
    int steps = opt->path.steps;
    if (opt->num_keys > 0) steps = opt->num_keys;
    if (steps <= 0) return pg_fail(PG_ERR_ARG, "camera path '%s' has no steps", name);
    PG_TRY(pg_mkdir_p(out_dir));
    char frame_dir[4096];
    PG_TRY(pg_path_join(frame_dir, sizeof frame_dir, out_dir, name));
    if (opt->write_frames) PG_TRY(pg_mkdir_p(frame_dir));

    video_set v = {0};
    pg_image rgb = {0}, depth_rgb = {0}, ref = {0}, both = {0};
    pg_status st = open_writer(&v.rgb, out_dir, name, "", W, H, opt->fps, &report->fallback_png);
    if (st == PG_OK && opt->write_depth) st = open_writer(&v.depth, out_dir, name, "_depth", W, H, opt->fps, &report->fallback_png);
    if (st == PG_OK && opt->reference) {
        st = open_writer(&v.compare, out_dir, name, "_compare", 2 * W, H, opt->fps, &report->fallback_png);
        if (st == PG_OK) st = pg_image_create(&both, 2 * W, H, 3);
    }
    if (st == PG_OK) st = pg_image_create(&rgb, W, H, 3);
    for (int i = 0; st == PG_OK && i < steps; i++) {
        pg_camera cam;
        float t;
        if (opt->num_keys > 0) {
            cam = opt->keys[i];
            t = opt->key_times[i];
        } else if (opt->use_camera) {
            cam = opt->camera;
            t = train_frame_time(i, steps);
        } else {
            render_path_camera(&opt->path, real, center, i, &cam, &t);
        }
        pg_render_output out;
        st = render_model_frame(rm, &cam, t, &out);
        if (st != PG_OK) break;
        memcpy(rgb.data, out.rgb, sizeof(float) * 3 * (size_t)W * H);
        st = io_video_writer_add(v.rgb, &rgb);
        if (st == PG_OK && opt->write_frames) {
            char file[64], path[4200];
            snprintf(file, sizeof file, "%04d.png", i);
            st = pg_path_join(path, sizeof path, frame_dir, file);
            if (st == PG_OK) st = io_image_save_png(path, &rgb);
        }
        if (st == PG_OK && v.depth) {
            /* expected depth normalised by alpha, so half-covered pixels show their surface depth */
            for (size_t k = 0; k < (size_t)W * H; k++) out.depth[k] = out.alpha[k] > 0.5f ? out.depth[k] / out.alpha[k] : 0.0f;
            st = render_depth_colormap(out.depth, W, H, 0, 0, &depth_rgb);
            if (st == PG_OK) st = io_video_writer_add(v.depth, &depth_rgb);
            pg_image_destroy(&depth_rgb);
        }
        if (st == PG_OK && v.compare) {
            st = opt->reference(opt->reference_ctx, i, t, &ref);
            if (st == PG_OK && (ref.width != W || ref.height != H || ref.channels != 3))
                st = pg_fail(PG_ERR_SIZE, "reference frame %d is %dx%d, the render %dx%d", i, ref.width, ref.height, W, H);
            if (st == PG_OK) {
                blit(&both, &ref, 0);
                blit(&both, &rgb, W);
                st = io_video_writer_add(v.compare, &both);
            }
            pg_image_destroy(&ref);
        }
        pg_progress_report("render", i + 1, steps, "path=%s", name);
        report->frames = i + 1;
    }
    if (st == PG_OK) st = io_video_writer_close(v.rgb), v.rgb = NULL;
    if (st == PG_OK && v.depth) st = io_video_writer_close(v.depth), v.depth = NULL;
    if (st == PG_OK && v.compare) st = io_video_writer_close(v.compare), v.compare = NULL;
    if (st != PG_OK) video_set_abort(&v);
    pg_image_destroy(&rgb);
    pg_image_destroy(&both);
    report->seconds = pg_time_seconds() - start;
    return st;
}
