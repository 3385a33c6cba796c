/* video_write.c - stream float frames into an H.264 MP4 (libavcodec/libavformat), with
 * MPEG-4 part 2 and PNG-sequence fallbacks. Output goes to a temporary name first and is
 * renamed into place on close, so a crash never leaves a complete-looking file. */
#include "io/video.h"
#include "io/image_io.h"
#include "core/fileutil.h"

#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/opt.h>
#include <libswscale/swscale.h>

#include <dirent.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

struct io_video_writer {
    io_video_backend backend;
    int width, height;      /* frames given by the caller */
    int enc_w, enc_h;       /* encoded size (even) */
    int frames;
    char path[4096];        /* final output (file or PNG folder) */
    char tmp[4200];         /* temporary file or folder */
    AVFormatContext *oc;
    AVCodecContext *enc;
    AVStream *st;
    AVFrame *yuv;
    AVPacket *pkt;
    struct SwsContext *sws;
    uint8_t *rgb;           /* (enc_h, enc_w, 3) staging buffer */
};

io_video_write_options io_video_write_defaults(void)
{
    io_video_write_options o;
    memset(&o, 0, sizeof o);
    o.fps = 30.0;
    o.crf = 18;
    return o;
}

io_video_backend io_video_writer_backend(const io_video_writer *w) { return w->backend; }

static void free_codec(io_video_writer *w)
{
    if (w->oc) {
        if (w->oc->pb) avio_closep(&w->oc->pb);
        avformat_free_context(w->oc);
        w->oc = NULL;
    }
    avcodec_free_context(&w->enc);
    av_frame_free(&w->yuv);
    av_packet_free(&w->pkt);
    sws_freeContext(w->sws);
    w->sws = NULL;
}

/* Tries one encoder; on any failure everything it set up is released and nonzero returned. */
static int try_encoder(io_video_writer *w, const char *encoder_name, const io_video_write_options *opt)
{
    const AVCodec *codec = avcodec_find_encoder_by_name(encoder_name);
    if (!codec) return -1;
    if (avformat_alloc_output_context2(&w->oc, NULL, "mp4", w->tmp) < 0 || !w->oc) return -1;
    w->st = avformat_new_stream(w->oc, NULL);
    w->enc = avcodec_alloc_context3(codec);
    w->yuv = av_frame_alloc();
    w->pkt = av_packet_alloc();
    if (!w->st || !w->enc || !w->yuv || !w->pkt) goto fail;
    AVRational fr = av_d2q(opt->fps, 100000);
    w->enc->width = w->enc_w;
    w->enc->height = w->enc_h;
    w->enc->pix_fmt = AV_PIX_FMT_YUV420P;
    w->enc->time_base = av_inv_q(fr);
    w->enc->framerate = fr;
    w->enc->gop_size = 12;
    w->enc->thread_count = 1; /* deterministic bytes, and the machine is shared */
    if (w->oc->oformat->flags & AVFMT_GLOBALHEADER) w->enc->flags |= AV_CODEC_FLAG_GLOBAL_HEADER;
    AVDictionary *d = NULL;
    if (!strcmp(encoder_name, "libx264")) {
        char crf[16];
        snprintf(crf, sizeof crf, "%d", opt->crf > 0 ? opt->crf : 18);
        av_dict_set(&d, "crf", crf, 0);
        av_dict_set(&d, "preset", "medium", 0);
        /* No macroblock-tree rate control: with it, libx264 (0.164, Debian 12) reads heap memory
         * it never wrote, so the same frames gave other bytes, and decoded frames up to ~30/255
         * apart, depending on what the process had allocated and freed before (issue 27 item 3: a
         * render after other renders differed from the same render alone). The cost on an orbit
         * render (docs/io.md): colour 3% smaller at 0.4 dB lower PSNR, depth 37% bigger at 0.3 dB
         * higher. test_io_video checks the bytes under three heap fills. */
        av_dict_set(&d, "mbtree", "0", 0);
    } else {
        w->enc->qmin = 1;
        w->enc->qmax = 4; /* mpeg4: high quality */
        w->enc->bit_rate = 0;
        w->enc->flags |= AV_CODEC_FLAG_QSCALE;
        w->enc->global_quality = FF_QP2LAMBDA * 2;
    }
    int r = avcodec_open2(w->enc, codec, &d);
    av_dict_free(&d);
    if (r < 0) goto fail;
    if (avcodec_parameters_from_context(w->st->codecpar, w->enc) < 0) goto fail;
    w->st->time_base = w->enc->time_base;
    w->st->avg_frame_rate = fr;
    if (avio_open(&w->oc->pb, w->tmp, AVIO_FLAG_WRITE) < 0) goto fail;
    if (avformat_write_header(w->oc, NULL) < 0) goto fail;
    w->yuv->format = AV_PIX_FMT_YUV420P;
    w->yuv->width = w->enc_w;
    w->yuv->height = w->enc_h;
    if (av_frame_get_buffer(w->yuv, 0) < 0) goto fail;
    w->sws = sws_getContext(w->enc_w, w->enc_h, AV_PIX_FMT_RGB24, w->enc_w, w->enc_h, AV_PIX_FMT_YUV420P,
                            SWS_BICUBIC | SWS_ACCURATE_RND, NULL, NULL, NULL);
    if (!w->sws) goto fail;
    return 0;
fail:
    free_codec(w);
    remove(w->tmp);
    return -1;
}

/* Replaces the PNG-sequence folder: removes an older one (only its .png files) first. */
static void remove_png_folder(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d) return;
    struct dirent *e;
    char p[8192];
    while ((e = readdir(d)) != NULL) {
        const char *dot = strrchr(e->d_name, '.');
        if (dot && !strcmp(dot, ".png")) {
            snprintf(p, sizeof p, "%s/%s", dir, e->d_name);
            remove(p);
        }
    }
    closedir(d);
    rmdir(dir);
}

pg_status io_video_writer_open(io_video_writer **out, const char *path, int width, int height,
                               const io_video_write_options *opt)
{
    *out = NULL;
    io_video_write_options def = io_video_write_defaults();
    if (!opt) opt = &def;
    if (width <= 0 || height <= 0 || width > PG_MAX_IMAGE_SIDE || height > PG_MAX_IMAGE_SIDE)
        return pg_fail(PG_ERR_ARG, "%s: video size %d x %d is out of range", path, width, height);
    if (!(opt->fps > 0 && opt->fps < 10000)) return pg_fail(PG_ERR_ARG, "%s: fps %g is out of range", path, opt->fps);
    if (strlen(path) >= 4000) return pg_fail(PG_ERR_ARG, "%s: path too long", path);
    io_video_writer *w = pg_calloc(1, sizeof *w, path);
    if (!w) return PG_ERR_NOMEM;
    w->width = width;
    w->height = height;
    w->enc_w = width + (width & 1);
    w->enc_h = height + (height & 1);
    av_log_set_level(AV_LOG_QUIET);
    snprintf(w->path, sizeof w->path, "%s", path);
    snprintf(w->tmp, sizeof w->tmp, "%s.tmp.%ld", path, (long)getpid());
    /* An unwritable destination is an error, not a reason to fall back to PNGs. */
    FILE *probe = fopen(w->tmp, "wb");
    if (!probe) {
        pg_status st = pg_fail(PG_ERR_ENV, "%s: cannot write: %s", path, strerror(errno));
        free(w);
        return st;
    }
    fclose(probe);
    remove(w->tmp);
    int ok = 0;
    if (!opt->force_png) {
        if (try_encoder(w, "libx264", opt) == 0) { w->backend = IO_VIDEO_H264; ok = 1; }
        else if (try_encoder(w, "mpeg4", opt) == 0) { w->backend = IO_VIDEO_MPEG4; ok = 1; }
    }
    if (ok) {
        w->rgb = pg_malloc((size_t)w->enc_w * w->enc_h * 3, path);
        if (!w->rgb) { io_video_writer_abort(w); return PG_ERR_NOMEM; }
    } else {
        w->backend = IO_VIDEO_PNG_SEQUENCE;
        char base[4096];
        snprintf(base, sizeof base, "%s", path);
        char *dot = strrchr(base, '.'), *slash = strrchr(base, '/');
        if (dot && (!slash || dot > slash)) *dot = '\0';
        if (snprintf(w->path, sizeof w->path, "%.4000s_frames", base) < 0) w->path[0] = '\0';
        snprintf(w->tmp, sizeof w->tmp, "%s.tmp.%ld", w->path, (long)getpid());
        remove_png_folder(w->tmp);
        pg_status st = pg_mkdir_p(w->tmp);
        if (st) { free(w); return pg_fail_context(st, "%s", path); }
    }
    *out = w;
    return PG_OK;
}

static pg_status write_packets(io_video_writer *w, const AVFrame *frame)
{
    int r = avcodec_send_frame(w->enc, frame);
    if (r < 0) return pg_fail(PG_ERR_INTERNAL, "%s: encoder rejected frame %d", w->path, w->frames);
    for (;;) {
        r = avcodec_receive_packet(w->enc, w->pkt);
        if (r == AVERROR(EAGAIN) || r == AVERROR_EOF) return PG_OK;
        if (r < 0) return pg_fail(PG_ERR_INTERNAL, "%s: encoding failed", w->path);
        av_packet_rescale_ts(w->pkt, w->enc->time_base, w->st->time_base);
        w->pkt->stream_index = w->st->index;
        r = av_interleaved_write_frame(w->oc, w->pkt);
        if (r < 0) return pg_fail(PG_ERR_ENV, "%s: write failed", w->path);
    }
}

pg_status io_video_writer_add(io_video_writer *w, const pg_image *frame)
{
    if (frame->width != w->width || frame->height != w->height || (frame->channels != 3 && frame->channels != 1))
        return pg_fail(PG_ERR_ARG, "%s: frame %d is %d x %d x %d, video is %d x %d x 3", w->path, w->frames,
                       frame->width, frame->height, frame->channels, w->width, w->height);
    if (w->backend == IO_VIDEO_PNG_SEQUENCE) {
        char name[32], p[8300];
        snprintf(name, sizeof name, "%04d.png", w->frames);
        PG_TRY(pg_path_join(p, sizeof p, w->tmp, name));
        PG_TRY(io_image_save_png(p, frame));
        w->frames++;
        return PG_OK;
    }
    /* Float -> RGB24 with edge replication into the even-sized staging buffer. */
    int C = frame->channels;
    for (int y = 0; y < w->enc_h; y++) {
        int sy = y < w->height ? y : w->height - 1;
        for (int x = 0; x < w->enc_w; x++) {
            int sx = x < w->width ? x : w->width - 1;
            const float *s = frame->data + ((size_t)sy * w->width + sx) * C;
            uint8_t *d = w->rgb + ((size_t)y * w->enc_w + x) * 3;
            for (int c = 0; c < 3; c++) {
                float v = s[C == 3 ? c : 0] * 255.0f + 0.5f;
                d[c] = (uint8_t)(v > 0 ? (v < 255 ? v : 255) : 0);
            }
        }
    }
    if (av_frame_make_writable(w->yuv) < 0) return pg_fail(PG_ERR_NOMEM, "%s: frame buffer", w->path);
    const uint8_t *src[4] = { w->rgb, NULL, NULL, NULL };
    int src_stride[4] = { w->enc_w * 3, 0, 0, 0 };
    sws_scale(w->sws, src, src_stride, 0, w->enc_h, w->yuv->data, w->yuv->linesize);
    w->yuv->pts = w->frames;
    PG_TRY(write_packets(w, w->yuv));
    w->frames++;
    return PG_OK;
}

void io_video_writer_abort(io_video_writer *w)
{
    if (!w) return;
    free_codec(w);
    if (w->backend == IO_VIDEO_PNG_SEQUENCE) remove_png_folder(w->tmp);
    else remove(w->tmp);
    free(w->rgb);
    free(w);
}

pg_status io_video_writer_close(io_video_writer *w)
{
    pg_status st = PG_OK;
    if (w->frames == 0) st = pg_fail(PG_ERR_ARG, "%s: no frames were written", w->path);
    if (w->backend == IO_VIDEO_PNG_SEQUENCE) {
        if (st == PG_OK) {
            remove_png_folder(w->path);
            if (rename(w->tmp, w->path) != 0)
                st = pg_fail(PG_ERR_ENV, "%s: cannot rename into place: %s", w->path, strerror(errno));
        }
    } else {
        if (st == PG_OK) st = write_packets(w, NULL);
        if (st == PG_OK && av_write_trailer(w->oc) < 0) st = pg_fail(PG_ERR_ENV, "%s: cannot finish the file", w->path);
        if (st == PG_OK && avio_closep(&w->oc->pb) < 0) st = pg_fail(PG_ERR_ENV, "%s: close failed", w->path);
        if (st == PG_OK && rename(w->tmp, w->path) != 0)
            st = pg_fail(PG_ERR_ENV, "%s: cannot rename into place: %s", w->path, strerror(errno));
    }
    if (st != PG_OK) {
        io_video_writer_abort(w);
        return st;
    }
    free_codec(w);
    free(w->rgb);
    free(w);
    return PG_OK;
}

pg_status io_video_write(const char *path, const pg_image *frames, int count, const io_video_write_options *opt,
                         io_video_backend *backend)
{
    if (count <= 0) return pg_fail(PG_ERR_ARG, "%s: no frames to write", path);
    io_video_writer *w;
    PG_TRY(io_video_writer_open(&w, path, frames[0].width, frames[0].height, opt));
    if (backend) *backend = w->backend;
    for (int i = 0; i < count; i++) {
        pg_status st = io_video_writer_add(w, &frames[i]);
        if (st) { io_video_writer_abort(w); return st; }
    }
    return io_video_writer_close(w);
}
