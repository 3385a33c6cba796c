/* test_io_video.c - video encode -> decode round trip, same bytes whatever the heap held, frame folders,
 * selection, resize, bad files. */
#include "testlib.h"
#include "core/fileutil.h"
#include "io/image_io.h"
#include "io/video.h"

#include <libavformat/avformat.h>
#include <libavutil/display.h>
#include <libavutil/pixfmt.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define W 96
#define H 64
#define F 12

/* Smooth moving pattern: low frequencies only, so a good encoder reproduces it closely. */
static void pattern(pg_image *img, int w, int h, int t)
{
    pg_image_create(img, w, h, 3);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            float *p = pg_image_at(img, x, y);
            p[0] = 0.5f + 0.35f * sinf(0.07f * x + 0.2f * t);
            p[1] = 0.5f + 0.35f * cosf(0.09f * y - 0.1f * t);
            p[2] = 0.3f + 0.4f * (float)(x + y) / (w + h);
        }
}

static void test_roundtrip(const char *dir)
{
    char path[4096];
    pg_path_join(path, sizeof path, dir, "rt.mp4");
    pg_image frames[F];
    for (int t = 0; t < F; t++) pattern(&frames[t], W, H, t);
    io_video_write_options wo = io_video_write_defaults();
    wo.fps = 24;
    wo.crf = 12;
    io_video_backend be = IO_VIDEO_PNG_SEQUENCE;
    CHECK_OK(io_video_write(path, frames, F, &wo, &be));
    CHECK(be == IO_VIDEO_H264, "backend %d (libx264 expected)", (int)be);
    io_video_info info;
    CHECK_OK(io_video_probe(path, &info));
    CHECK(info.width == W && info.height == H, "probe size %d x %d", info.width, info.height);
    CHECK(fabs(info.fps - 24) < 1e-6, "probe fps %g", info.fps);
    CHECK(info.frames == F, "probe frames %d", info.frames);
    int counted = 0;
    CHECK_OK(io_video_count_frames(path, &counted));
    CHECK(counted == F, "counted %d", counted);

    io_frames fr;
    io_video_options opt = io_video_defaults();
    CHECK_OK(io_frames_read(path, &opt, &fr));
    CHECK(fr.count == F && fr.width == W && fr.height == H, "read %d frames %d x %d", fr.count, fr.width, fr.height);
    double worst = 1e9;
    for (int t = 0; t < fr.count && t < F; t++) {
        pg_image img;
        CHECK_OK(io_frames_image(&fr, t, &img));
        double p = pg_image_psnr(&img, &frames[t], NULL);
        if (p < worst) worst = p;
        pg_image_destroy(&img);
    }
    printf("video round trip: worst frame PSNR %.2f dB (crf 12, %dx%d)\n", worst, W, H);
    CHECK(worst > 40.0, "encode->decode PSNR %.2f dB", worst);
    io_frames_destroy(&fr);

    /* Range + stride + resize: frames 3, 5, 7 at half size. */
    opt.first = 3;
    opt.stride = 2;
    opt.count = 3;
    opt.width = W / 2;
    CHECK_OK(io_frames_read(path, &opt, &fr));
    CHECK(fr.count == 3 && fr.width == W / 2 && fr.height == H / 2, "selection %d frames %d x %d", fr.count, fr.width,
          fr.height);
    if (fr.count == 3) {
        pg_image img, ref;
        CHECK_OK(io_frames_image(&fr, 1, &img));
        pg_image_resize(&ref, &frames[5], W / 2, H / 2);
        double p = pg_image_psnr(&img, &ref, NULL);
        CHECK(p > 35.0, "strided resized frame 5 PSNR %.2f", p);
        pg_image_destroy(&img);
        pg_image_destroy(&ref);
    }
    io_frames_destroy(&fr);
    opt = io_video_defaults();
    opt.count = F + 1;
    CHECK(io_frames_read(path, &opt, &fr) == PG_ERR_ARG, "asking for too many frames must fail");
    CHECK(strstr(pg_last_error(), "rt.mp4") != NULL, "message names file: %s", pg_last_error());

    /* Odd size is padded to even. */
    pg_path_join(path, sizeof path, dir, "odd.mp4");
    pg_image odd;
    pattern(&odd, 33, 21, 0);
    CHECK_OK(io_video_write(path, &odd, 1, NULL, NULL));
    CHECK_OK(io_video_probe(path, &info));
    CHECK(info.width == 34 && info.height == 22, "odd padded to %d x %d", info.width, info.height);
    pg_image_destroy(&odd);

    /* Unwritable destination: an error, not a silent fallback. */
    pg_path_join(path, sizeof path, dir, "no/such/dir/x.mp4");
    io_video_writer *vw = NULL;
    CHECK(io_video_writer_open(&vw, path, W, H, NULL) == PG_ERR_ENV && !vw, "unwritable: %s", pg_last_error());
    /* Forced PNG fallback. */
    pg_path_join(path, sizeof path, dir, "fb.mp4");
    wo.force_png = 1;
    CHECK_OK(io_video_write(path, frames, 3, &wo, &be));
    CHECK(be == IO_VIDEO_PNG_SEQUENCE, "fallback backend %d", (int)be);
    char folder[4096];
    pg_path_join(folder, sizeof folder, dir, "fb_frames");
    CHECK(pg_path_is_dir(folder), "fallback folder %s", folder);
    opt = io_video_defaults();
    CHECK_OK(io_frames_read(folder, &opt, &fr));
    CHECK(fr.count == 3, "fallback frames %d", fr.count);
    io_frames_destroy(&fr);

    for (int t = 0; t < F; t++) pg_image_destroy(&frames[t]);
}

/* Copies src into dst (mp4) adding a display matrix: how phones tag portrait video. In FFmpeg 5.1
 * av_display_rotation_set takes the clockwise angle that players (ffmpeg -autorotate) apply. */
static int remux_rotated(const char *src, const char *dst, double cw_degrees)
{
    AVFormatContext *in = NULL, *out = NULL;
    if (avformat_open_input(&in, src, NULL, NULL) < 0) return -1;
    avformat_find_stream_info(in, NULL);
    avformat_alloc_output_context2(&out, NULL, "mp4", dst);
    AVStream *os = avformat_new_stream(out, NULL);
    avcodec_parameters_copy(os->codecpar, in->streams[0]->codecpar);
    os->codecpar->codec_tag = 0;
    os->time_base = in->streams[0]->time_base;
    uint8_t *m = av_stream_new_side_data(os, AV_PKT_DATA_DISPLAYMATRIX, 9 * sizeof(int32_t));
    av_display_rotation_set((int32_t *)m, cw_degrees);
    int rc = avio_open(&out->pb, dst, AVIO_FLAG_WRITE) < 0 || avformat_write_header(out, NULL) < 0 ? -1 : 0;
    AVPacket *pkt = av_packet_alloc();
    while (rc == 0 && av_read_frame(in, pkt) >= 0) {
        av_packet_rescale_ts(pkt, in->streams[0]->time_base, os->time_base);
        pkt->stream_index = 0;
        av_interleaved_write_frame(out, pkt);
        av_packet_unref(pkt);
    }
    if (rc == 0) av_write_trailer(out);
    av_packet_free(&pkt);
    avio_closep(&out->pb);
    avformat_free_context(out);
    avformat_close_input(&in);
    return rc;
}

static void test_rotation(const char *dir)
{
    char src[4096], dst[4096];
    pg_path_join(src, sizeof src, dir, "rt.mp4");
    pg_path_join(dst, sizeof dst, dir, "rot.mp4");
    int angles[3] = { 90, 180, 270 };
    for (int a = 0; a < 3; a++) {
        int cw = angles[a];
        CHECK(remux_rotated(src, dst, cw) == 0, "remux");
        io_video_info info;
        CHECK_OK(io_video_probe(dst, &info));
        int swap = cw != 180;
        CHECK(info.rotation == cw && info.width == (swap ? H : W), "rotation %d probe %d -> %d x %d", cw, info.rotation,
              info.width, info.height);
        io_frames A, B;
        io_video_options opt = io_video_defaults();
        opt.count = 2;
        CHECK_OK(io_frames_read(src, &opt, &A));
        CHECK_OK(io_frames_read(dst, &opt, &B));
        if (A.count == 2 && B.count == 2) {
            CHECK(B.width == (swap ? H : W) && B.height == (swap ? W : H), "rotated size %d x %d", B.width, B.height);
            int bad = 0;
            for (int y = 0; y < B.height; y++)
                for (int x = 0; x < B.width; x++) {
                    int sx, sy; /* source pixel that lands on (x, y) after a clockwise rotation */
                    if (cw == 90) { sx = y; sy = H - 1 - x; }
                    else if (cw == 270) { sx = W - 1 - y; sy = x; }
                    else { sx = W - 1 - x; sy = H - 1 - y; }
                    bad += memcmp(B.rgb + ((size_t)y * B.width + x) * 3, A.rgb + ((size_t)sy * W + sx) * 3, 3) != 0;
                }
            CHECK(bad == 0, "rotation %d: %d pixels differ", cw, bad);
        }
        io_frames_destroy(&A);
        io_frames_destroy(&B);
    }
    /* Resize applies to the upright frame. */
    io_frames B;
    io_video_options opt = io_video_defaults();
    opt.max_side = W / 2;
    remux_rotated(src, dst, 90);
    CHECK_OK(io_frames_read(dst, &opt, &B));
    CHECK(B.width == H / 2 && B.height == W / 2, "rotated+resized %d x %d", B.width, B.height);
    io_frames_destroy(&B);
}

/* Writes an uncompressed RGB video (NUT container, millisecond time base) whose frames sit at the
 * given times: a variable-rate file without needing an encoder. */
static int write_raw_timed(const char *path, const int64_t *pts_ms, int n)
{
    AVFormatContext *out = NULL;
    if (avformat_alloc_output_context2(&out, NULL, "nut", path) < 0) return -1;
    AVStream *st = avformat_new_stream(out, NULL);
    st->codecpar->codec_type = AVMEDIA_TYPE_VIDEO;
    st->codecpar->codec_id = AV_CODEC_ID_RAWVIDEO;
    st->codecpar->format = AV_PIX_FMT_RGB24;
    st->codecpar->width = W;
    st->codecpar->height = H;
    st->time_base = (AVRational){ 1, 1000 };
    int rc = avio_open(&out->pb, path, AVIO_FLAG_WRITE) < 0 || avformat_write_header(out, NULL) < 0 ? -1 : 0;
    AVPacket *pkt = av_packet_alloc();
    for (int i = 0; rc == 0 && i < n; i++) {
        pg_image img;
        pattern(&img, W, H, i);
        int bad = av_new_packet(pkt, W * H * 3) < 0;
        for (int k = 0; !bad && k < W * H * 3; k++) pkt->data[k] = (uint8_t)lroundf(img.data[k] * 255.0f);
        pg_image_destroy(&img);
        if (bad) { rc = -1; break; }
        pkt->pts = pkt->dts = av_rescale_q(pts_ms[i], (AVRational){ 1, 1000 }, st->time_base);
        pkt->flags |= AV_PKT_FLAG_KEY;
        pkt->stream_index = 0;
        if (av_interleaved_write_frame(out, pkt) < 0) rc = -1;
        av_packet_unref(pkt);
    }
    if (rc == 0) av_write_trailer(out);
    av_packet_free(&pkt);
    avio_closep(&out->pb);
    avformat_free_context(out);
    return rc;
}

static char last_warning[1024];
static int warnings;
static void catch_warning(const char *message, void *ctx)
{
    (void)ctx;
    snprintf(last_warning, sizeof last_warning, "%s", message);
    warnings++;
}

/* A variable-rate video reads like any other but says that its timing is approximated; a
 * constant-rate one whose timestamps jitter by a millisecond (30 fps in a 1 ms time base) does not. */
static void test_variable_rate(const char *dir)
{
    char vfr[4096], cfr[4096];
    pg_path_join(vfr, sizeof vfr, dir, "vfr.nut");
    pg_path_join(cfr, sizeof cfr, dir, "cfr.nut");
    const int64_t uneven[6] = { 0, 33, 67, 150, 183, 400 }, even[6] = { 0, 33, 67, 100, 133, 167 };
    CHECK(write_raw_timed(vfr, uneven, 6) == 0 && write_raw_timed(cfr, even, 6) == 0, "cannot write test videos");
    pg_set_warning_handler(catch_warning, NULL);
    io_frames fr;
    CHECK_OK(io_frames_read(cfr, NULL, &fr));
    CHECK(fr.count == 6 && warnings == 0, "constant-rate video: %d frames, warning '%s'", fr.count, last_warning);
    io_frames_destroy(&fr);
    CHECK_OK(io_frames_read(vfr, NULL, &fr));
    CHECK(fr.count == 6 && warnings == 1 && strstr(last_warning, "variable frame rate") && strstr(last_warning, "vfr.nut"),
          "variable-rate video: %d frames, %d warnings, '%s'", fr.count, warnings, last_warning);
    io_frames_destroy(&fr);
    pg_set_warning_handler(NULL, NULL);
}

static void test_folder(const char *dir)
{
    char sub[4096], p[4200];
    pg_path_join(sub, sizeof sub, dir, "frames");
    pg_mkdir_p(sub);
    /* Natural order: f2 before f10. Frame value encodes its index. */
    int idx[4] = { 1, 2, 10, 11 };
    for (int i = 0; i < 4; i++) {
        pg_image img;
        pg_image_create(&img, 20, 10, 3);
        for (int k = 0; k < 20 * 10 * 3; k++) img.data[k] = idx[i] / 20.0f;
        snprintf(p, sizeof p, "%s/f%d.png", sub, idx[i]);
        CHECK_OK(io_image_save_png(p, &img));
        pg_image_destroy(&img);
    }
    io_frames fr;
    io_video_options opt = io_video_defaults();
    opt.first = 1;
    CHECK_OK(io_frames_read(sub, &opt, &fr));
    CHECK(fr.count == 3, "folder count %d", fr.count);
    if (fr.count == 3) {
        int v = (int)lround(fr.rgb[0] / 255.0 * 20.0);
        int v2 = (int)lround(fr.rgb[(size_t)20 * 10 * 3] / 255.0 * 20.0);
        CHECK(v == 2 && v2 == 10, "natural order gave %d, %d", v, v2);
    }
    io_frames_destroy(&fr);
    io_video_info info;
    CHECK_OK(io_video_probe(sub, &info));
    CHECK(info.is_folder && info.frames == 4 && info.width == 20, "folder probe %d %d", info.frames, info.width);
    /* Mismatched sizes in a folder. */
    pg_image img;
    pg_image_create(&img, 8, 8, 3);
    pg_path_join(p, sizeof p, sub, "f12.png");
    io_image_save_png(p, &img);
    pg_image_destroy(&img);
    opt = io_video_defaults();
    CHECK(io_frames_read(sub, &opt, &fr) == PG_ERR_SIZE, "mixed sizes must fail: %s", pg_last_error());
}

static void test_bad(const char *dir)
{
    char path[4096], good[4096], err[1024], args[8500];
    io_frames fr;
    io_video_options opt = io_video_defaults();
    pg_path_join(path, sizeof path, dir, "missing.mp4");
    CHECK(io_frames_read(path, &opt, &fr) == PG_ERR_IO, "missing file");
    CHECK(strstr(pg_last_error(), "missing.mp4") != NULL, "names file: %s", pg_last_error());

    pg_path_join(path, sizeof path, dir, "garbled.mp4");
    char junk[5000];
    for (int i = 0; i < (int)sizeof junk; i++) junk[i] = (char)(i * 7919 % 251);
    pg_write_file_atomic(path, junk, sizeof junk);
    pg_status st = io_frames_read(path, &opt, &fr);
    CHECK(st == PG_ERR_FORMAT, "garbled -> %d %s", (int)st, pg_last_error());
    CHECK(strstr(pg_last_error(), "garbled.mp4") != NULL, "names file: %s", pg_last_error());
    snprintf(args, sizeof args, "info '%s'", path);
    int rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 2 && strstr(err, "garbled.mp4"), "info garbled rc %d err %s", rc, err);

    /* Truncated: the first half of a valid file. */
    pg_path_join(good, sizeof good, dir, "rt.mp4");
    char *data;
    size_t size;
    if (pg_read_file(good, 1 << 26, &data, &size) == PG_OK) {
        pg_path_join(path, sizeof path, dir, "trunc.mp4");
        pg_write_file_atomic(path, data, size / 2);
        st = io_frames_read(path, &opt, &fr);
        CHECK(st != PG_OK, "truncated video must fail");
        CHECK(strstr(pg_last_error(), "trunc.mp4") != NULL, "names file: %s", pg_last_error());
        snprintf(args, sizeof args, "info '%s'", path);
        rc = test_run_cli(args, err, sizeof err);
        CHECK(rc == 2 && strstr(err, "trunc.mp4"), "info truncated rc %d err %s", rc, err);
        free(data);
    }
    pg_path_join(path, sizeof path, dir, "empty_dir");
    pg_mkdir_p(path);
    CHECK(io_frames_read(path, &opt, &fr) == PG_ERR_FORMAT, "empty folder: %s", pg_last_error());

    /* A y4m header claiming 16385 x 16: the size error read the closed input (ASan use-after-free)
     * and printed garbage; it must name the claimed size. */
    pg_path_join(path, sizeof path, dir, "wide.y4m");
    const char y4m[] = "YUV4MPEG2 W16385 H16 F30:1 Ip A1:1 C420jpeg\nFRAME\n";
    pg_write_file_atomic(path, y4m, sizeof y4m - 1);
    st = io_frames_read(path, &opt, &fr);
    CHECK(st == PG_ERR_SIZE && strstr(pg_last_error(), "16385 x 16") && strstr(pg_last_error(), "wide.y4m"),
          "oversized y4m: %s", pg_last_error());
}

/* Issue 27 item 3: the same frames must encode to the same bytes whatever the process allocated
 * and freed before: libx264 with its macroblock-tree rate control on read memory it never wrote
 * (three heap fills, three files). This binary encodes the frames in a child of itself
 * (--encode PATH) under three fills of every new allocation: glibc's MALLOC_PERTURB_, and under
 * the sanitizers their allocator's malloc_fill_byte, so the check runs in both passes. */
static pg_status encode_pattern(const char *path)
{
    enum { SW = 160, SH = 120, SF = 36 }; /* a render's size; enough frames for B-frames and lookahead */
    pg_image frames[SF];
    for (int t = 0; t < SF; t++) {
        pattern(&frames[t], SW, SH, t);
        for (int y = 0; y < SH; y++) /* a moving edge and texture, so the encoder has choices to make */
            for (int x = 0; x < SW; x++) {
                float *p = pg_image_at(&frames[t], x, y);
                p[0] = x > 40 + 2 * t ? 0.9f - 0.2f * (float)((x * 7 + y * 3) % 5) / 5 : p[0];
            }
    }
    pg_status st = io_video_write(path, frames, SF, NULL, NULL);
    for (int t = 0; t < SF; t++) pg_image_destroy(&frames[t]);
    return st;
}

static void test_same_bytes(const char *dir, const char *self)
{
    const char *asan = getenv("ASAN_OPTIONS");
    static const int fills[3] = { 0, 0x3F, 0xC0 }; /* 0: the allocators' defaults */
    char path[3][4200], cmd[16384];
    for (int k = 0; k < 3; k++) {
        snprintf(path[k], sizeof path[k], "%s/same_%d.mp4", dir, k);
        if (fills[k])
            snprintf(cmd, sizeof cmd,
                     "MALLOC_PERTURB_=%d ASAN_OPTIONS='%s%smalloc_fill_byte=%d:max_malloc_fill_size=1073741824' "
                     "'%s' --encode '%s'", fills[k], asan ? asan : "", asan && *asan ? ":" : "", fills[k], self, path[k]);
        else
            snprintf(cmd, sizeof cmd, "env -u MALLOC_PERTURB_ '%s' --encode '%s'", self, path[k]);
        CHECK(system(cmd) == 0, "encoding child under heap fill %d failed: %s", fills[k], cmd);
    }
    for (int k = 1; k < 3; k++)
        CHECK(test_files_equal(path[0], path[k]), "%s and %s differ: the encoder read memory it never wrote",
              path[0], path[k]);
}

int main(int argc, char **argv)
{
    if (argc == 3 && strcmp(argv[1], "--encode") == 0) return encode_pattern(argv[2]) == PG_OK ? 0 : 1;
    char dir[4096];
    test_tmpdir("test_io_video", dir, sizeof dir);
    test_roundtrip(dir);
    test_same_bytes(dir, argv[0]);
    test_rotation(dir);
    test_variable_rate(dir);
    test_folder(dir);
    test_bad(dir);
    return test_summary("test_io_video");
}
