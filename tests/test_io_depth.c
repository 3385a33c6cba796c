/* test_io_depth.c - depth inputs: npy dtypes, PFM round trip, 16-bit PNG, OpenEXR (files made by
 * libavcodec's independent EXR encoder), disparity, resize, invalid counting, bad files. */
#include "testlib.h"
#include "core/image.h"
#include "core/fileutil.h"
#include "io/depth_io.h"
#include "io/image_io.h"
#include "io/npy.h"

#include <libavcodec/avcodec.h>
#include <libavutil/opt.h>
#include <png.h>
#include <zlib.h>

#include <math.h>
#include <sys/stat.h>
#include <unistd.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* Writes a .npy with any descr from raw little-endian bytes (test-only: the library only writes f4/u1). */
static void write_npy_raw(const char *path, const char *descr, const char *shape, const void *data, size_t bytes)
{
    char dict[256];
    int n = snprintf(dict, sizeof dict, "{'descr': '%s', 'fortran_order': False, 'shape': %s, }", descr, shape);
    size_t pad = (64 - (10 + (size_t)n + 1) % 64) % 64;
    size_t hlen = (size_t)n + pad + 1;
    FILE *fp = fopen(path, "wb");
    uint8_t pre[10] = { 0x93, 'N', 'U', 'M', 'P', 'Y', 1, 0, (uint8_t)(hlen & 0xff), (uint8_t)(hlen >> 8) };
    fwrite(pre, 1, 10, fp);
    fwrite(dict, 1, (size_t)n, fp);
    for (size_t i = 0; i < pad; i++) fputc(' ', fp);
    fputc('\n', fp);
    if (bytes) fwrite(data, 1, bytes, fp);
    fclose(fp);
}

static float ref_depth(int t, int x, int y) { return 1.0f + 0.01f * x + 0.02f * y + 0.1f * t; }

static void test_npy(const char *dir)
{
    char path[4096];
    enum { F = 3, H = 6, W = 8 };
    float f32[F * H * W];
    double f64[F * H * W];
    uint16_t u16[F * H * W];
    for (int t = 0; t < F; t++)
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++) {
                int i = (t * H + y) * W + x;
                f32[i] = ref_depth(t, x, y);
                f64[i] = ref_depth(t, x, y);
                u16[i] = (uint16_t)(1000 + x * 10 + y * 100 + t);
            }
    f32[0] = NAN;
    f32[1] = INFINITY;
    f32[2] = -1.0f;
    f32[3] = 0.0f;
    size_t shape[3] = { F, H, W };
    pg_path_join(path, sizeof path, dir, "d32.npy");
    CHECK_OK(io_npy_save(path, f32, 3, shape));
    io_depth d;
    io_depth_options o = io_depth_defaults();
    CHECK_OK(io_depth_load(path, &o, &d));
    CHECK(d.frames == F && d.width == W && d.height == H, "shape %d %d %d", d.frames, d.height, d.width);
    CHECK(d.invalid == 4, "invalid count %zu", d.invalid);
    CHECK(d.total == (size_t)F * H * W, "total %zu", d.total);
    CHECK(d.data[0] == 0 && d.data[1] == 0 && d.data[2] == 0 && d.data[4] == f32[4], "invalid -> 0");
    CHECK(fabsf(d.max - ref_depth(2, W - 1, H - 1)) < 1e-6f, "max %g", d.max);
    io_depth_destroy(&d);

    /* float64 and uint16 with scale; frame selection. */
    pg_path_join(path, sizeof path, dir, "d64.npy");
    write_npy_raw(path, "<f8", "(3, 6, 8)", f64, sizeof f64);
    o.first = 1;
    o.count = 2;
    o.expect_frames = 2;
    CHECK_OK(io_depth_load(path, &o, &d));
    CHECK(d.frames == 2 && d.src_frames == 3, "selected %d of %d", d.frames, d.src_frames);
    if (d.data) CHECK(fabsf(d.data[W * H + 5] - ref_depth(2, 5, 0)) < 1e-6f, "f64 value %g", d.data[W * H + 5]);
    io_depth_destroy(&d);
    o.expect_frames = 3;
    CHECK(io_depth_load(path, &o, &d) == PG_ERR_SIZE, "frame count mismatch: %s", pg_last_error());
    CHECK(strstr(pg_last_error(), "d64.npy") != NULL, "names file");

    pg_path_join(path, sizeof path, dir, "d16.npy");
    write_npy_raw(path, "<u2", "(3, 6, 8)", u16, sizeof u16);
    o = io_depth_defaults();
    o.scale = 0.001f;
    CHECK_OK(io_depth_load(path, &o, &d));
    if (d.data) CHECK(fabsf(d.data[9] - (1000 + 10 + 100) * 0.001f) < 1e-6f, "u16 scaled %g", d.data[9]);
    io_depth_destroy(&d);

    io_depth_kind kind = IO_DEPTH_KIND_DEPTH;
    CHECK_OK(io_depth_kind_parse("disparity", &kind));
    CHECK(kind == IO_DEPTH_KIND_DISPARITY && io_depth_kind_parse("inverse", &kind) == PG_ERR_ARG, "kind parse");
    /* Disparity: depth = 1 / (value * scale). */
    o = io_depth_defaults();
    o.kind = IO_DEPTH_KIND_DISPARITY;
    o.scale = 2.0f;
    pg_path_join(path, sizeof path, dir, "d64.npy");
    CHECK_OK(io_depth_load(path, &o, &d));
    if (d.data) CHECK(fabsf(d.data[7] - 1.0f / (2.0f * ref_depth(0, 7, 0))) < 1e-6f, "disparity %g", d.data[7]);
    io_depth_destroy(&d);

    /* Resize to 2x: nearest keeps values; bilinear stays between neighbours and skips invalid. */
    o = io_depth_defaults();
    o.width = 2 * W;
    o.height = 2 * H;
    pg_path_join(path, sizeof path, dir, "d32.npy");
    CHECK_OK(io_depth_load(path, &o, &d));
    if (d.data) {
        CHECK(d.width == 2 * W && d.height == 2 * H, "resized %d x %d", d.width, d.height);
        CHECK(d.data[(size_t)(2 * 3) * 2 * W + 2 * 5 + 1] == f32[3 * W + 5], "nearest upsample");
    }
    io_depth_destroy(&d);
    o.bilinear = 1;
    CHECK_OK(io_depth_load(path, &o, &d));
    if (d.data) {
        float v = d.data[(size_t)(2 * 3 + 1) * 2 * W + 2 * 5 + 1]; /* between source (5,3) and (6,4) */
        CHECK(v > f32[3 * W + 5] && v < f32[4 * W + 6], "bilinear %g", v);
        CHECK(d.data[0] == 0 || d.data[0] > 0.5f, "bilinear near invalid stays valid-only %g", d.data[0]);
    }
    io_depth_destroy(&d);
    o = io_depth_defaults();
    o.width = H;
    o.height = W; /* transposed: aspect mismatch */
    CHECK(io_depth_load(path, &o, &d) == PG_ERR_SIZE, "aspect mismatch must fail: %s", pg_last_error());

    /* (H, W) single frame and a 4-D array. */
    pg_path_join(path, sizeof path, dir, "one.npy");
    size_t s2[2] = { H, W };
    CHECK_OK(io_npy_save(path, f32 + H * W, 2, s2));
    CHECK_OK(io_depth_load(path, NULL, &d));
    CHECK(d.frames == 1 && d.invalid == 0, "single frame %d %zu", d.frames, d.invalid);
    io_depth_destroy(&d);
    size_t s4t[4] = { F, 1, H, W };
    pg_path_join(path, sizeof path, dir, "torch.npy");
    CHECK_OK(io_npy_save(path, f32, 4, s4t));
    CHECK_OK(io_depth_load(path, NULL, &d));
    CHECK(d.frames == F && d.height == H && d.width == W, "(F,1,H,W) %d %d %d", d.frames, d.height, d.width);
    io_depth_destroy(&d);
    size_t s4[4] = { 1, 2, H, W / 2 };
    pg_path_join(path, sizeof path, dir, "bad4.npy");
    CHECK_OK(io_npy_save(path, f32, 4, s4));
    CHECK(io_depth_load(path, NULL, &d) == PG_ERR_SIZE, "4-D must fail: %s", pg_last_error());
}

static void test_pfm(const char *dir)
{
    char path[4096];
    enum { H = 5, W = 7 };
    float img[H * W], rgb[H * W * 3];
    for (int i = 0; i < H * W; i++) img[i] = 0.5f + i * 0.25f;
    for (int i = 0; i < H * W * 3; i++) rgb[i] = (float)i;
    pg_path_join(path, sizeof path, dir, "a.pfm");
    CHECK_OK(io_pfm_save(path, img, W, H, 1));
    pg_array arr;
    CHECK_OK(io_pfm_load(path, &arr));
    CHECK(arr.shape[0] == H && arr.shape[1] == W, "pfm shape");
    int same = arr.data && memcmp(arr.data, img, sizeof img) == 0;
    CHECK(same, "pfm round trip exact");
    pg_array_destroy(&arr);
    pg_path_join(path, sizeof path, dir, "c.pfm");
    CHECK_OK(io_pfm_save(path, rgb, W, H, 3));
    CHECK_OK(io_pfm_load(path, &arr));
    CHECK(arr.data && arr.data[W + 2] == rgb[(W + 2) * 3], "colour PFM keeps channel 0");
    pg_array_destroy(&arr);
    /* Big-endian PFM written by hand (positive scale), top row is stored last. */
    pg_path_join(path, sizeof path, dir, "be.pfm");
    FILE *fp = fopen(path, "wb");
    fprintf(fp, "Pf\n2 2\n1.0\n");
    float vals[4] = { 3, 4, 1, 2 }; /* bottom row (3,4), then top (1,2) */
    for (int i = 0; i < 4; i++) {
        uint8_t b[4];
        memcpy(b, &vals[i], 4);
        uint8_t r[4] = { b[3], b[2], b[1], b[0] };
        fwrite(r, 1, 4, fp);
    }
    fclose(fp);
    CHECK_OK(io_pfm_load(path, &arr));
    CHECK(arr.data && arr.data[0] == 1 && arr.data[1] == 2 && arr.data[2] == 3, "big-endian PFM");
    pg_array_destroy(&arr);
    /* Per-frame folder of PFMs (natural order) through io_depth_load. */
    char sub[4096], p[4200];
    pg_path_join(sub, sizeof sub, dir, "pfms");
    pg_mkdir_p(sub);
    for (int t = 0; t < 3; t++) {
        for (int i = 0; i < H * W; i++) img[i] = 1.0f + t;
        snprintf(p, sizeof p, "%s/%d.pfm", sub, t * 5);
        CHECK_OK(io_pfm_save(p, img, W, H, 1));
    }
    io_depth d;
    CHECK_OK(io_depth_load(sub, NULL, &d));
    CHECK(d.frames == 3 && d.data && d.data[H * W] == 2.0f && d.data[2 * H * W] == 3.0f, "pfm folder order");
    io_depth_destroy(&d);
}

/* A 16-bit PNG of ch (1: grey, 3: RGB) interleaved samples per pixel. */
static void write_png16_ch(const char *path, int w, int h, int ch, const uint16_t *v, int interlace)
{
    FILE *fp = fopen(path, "wb");
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
    png_infop info = png_create_info_struct(png);
    png_init_io(png, fp);
    png_set_IHDR(png, info, (png_uint_32)w, (png_uint_32)h, 16, ch == 3 ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_GRAY,
                 interlace ? PNG_INTERLACE_ADAM7 : PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_write_info(png, info);
    int passes = png_set_interlace_handling(png);
    uint8_t *row = malloc((size_t)w * ch * 2);
    for (int pass = 0; pass < passes; pass++)
        for (int y = 0; y < h; y++) {
            for (int i = 0; i < w * ch; i++) {
                row[2 * i] = (uint8_t)(v[y * w * ch + i] >> 8);
                row[2 * i + 1] = (uint8_t)(v[y * w * ch + i] & 0xff);
            }
            png_write_row(png, row);
        }
    png_write_end(png, NULL);
    png_destroy_write_struct(&png, &info);
    free(row);
    fclose(fp);
}

static void write_png16_il(const char *path, int w, int h, const uint16_t *v, int interlace)
{
    write_png16_ch(path, w, h, 1, v, interlace);
}
static void write_png16(const char *path, int w, int h, const uint16_t *v) { write_png16_il(path, w, h, v, 0); }

/* A video frame saved as 16-bit PNG (ffmpeg -pix_fmt rgb48be) loads as the same colours as its
 * 8-bit version: issue 27 found 189 read as 222 (libpng's simplified API took 16 bits for linear
 * light). Grey 16-bit frames repeat their one channel. */
static void test_png16_frames(const char *dir)
{
    enum { W = 16, H = 16 };
    uint16_t rgb16[W * H * 3], grey16[W * H];
    pg_image ref;
    CHECK_OK(pg_image_create(&ref, W, H, 3));
    for (int i = 0; i < W * H; i++) {
        for (int c = 0; c < 3; c++) {
            int v8 = (i * 7 + c * 60) % 256;
            if (i == 0 && c == 0) v8 = 189;
            rgb16[i * 3 + c] = (uint16_t)(v8 * 257);
            ref.data[i * 3 + c] = v8 / 255.0f;
        }
        grey16[i] = rgb16[i * 3];
    }
    char p8[4200], p16[4200], pg[4200];
    pg_path_join(p8, sizeof p8, dir, "frame8.png");
    pg_path_join(p16, sizeof p16, dir, "frame16.png");
    pg_path_join(pg, sizeof pg, dir, "frame16_grey.png");
    CHECK_OK(io_image_save_png(p8, &ref));
    write_png16_ch(p16, W, H, 3, rgb16, 0);
    write_png16_ch(pg, W, H, 1, grey16, 1);
    pg_image a = { 0 }, b = { 0 }, g = { 0 };
    CHECK_OK(io_image_load(p8, &a));
    CHECK_OK(io_image_load(p16, &b));
    CHECK_OK(io_image_load(pg, &g));
    double worst = 0, worst_grey = 0;
    for (int i = 0; a.data && b.data && g.data && i < W * H * 3; i++) {
        worst = fmax(worst, fabs(a.data[i] - b.data[i]));
        worst_grey = fmax(worst_grey, fabs(g.data[i] - a.data[(i / 3) * 3]));
    }
    CHECK(b.data && worst <= 1.0 / 255 / 2, "16-bit frame off its 8-bit version by %.1f/255 (189 read as %.1f)", worst * 255,
          b.data ? b.data[0] * 255 : -1);
    CHECK(g.data && worst_grey <= 1.0 / 255 / 2, "grey 16-bit frame off by %.1f/255", worst_grey * 255);
    pg_image_destroy(&a);
    pg_image_destroy(&b);
    pg_image_destroy(&g);
    pg_image_destroy(&ref);
}

static void test_png16(const char *dir)
{
    char sub[4096], p[4200];
    pg_path_join(sub, sizeof sub, dir, "png16");
    pg_mkdir_p(sub);
    uint16_t v[4 * 6];
    for (int t = 0; t < 2; t++) {
        for (int i = 0; i < 24; i++) v[i] = (uint16_t)(i == 0 ? 0 : 60000 + i + t);
        snprintf(p, sizeof p, "%s/frame_%02d.png", sub, t);
        write_png16(p, 6, 4, v);
    }
    io_depth_options o = io_depth_defaults();
    o.scale = 1.0f / 1000;
    io_depth d;
    CHECK_OK(io_depth_load(sub, &o, &d));
    CHECK(d.frames == 2 && d.width == 6 && d.height == 4, "png16 folder %d %d %d", d.frames, d.width, d.height);
    CHECK(d.invalid == 2, "png16 zeros counted %zu", d.invalid);
    if (d.data) CHECK(fabsf(d.data[24 + 5] - 60.006f) < 1e-4f, "png16 value %g", d.data[24 + 5]);
    io_depth_destroy(&d);
    /* Interlaced (Adam7) 16-bit PNG. */
    char p2[4200];
    uint16_t big[13 * 11];
    for (int i = 0; i < 13 * 11; i++) big[i] = (uint16_t)(i * 397 + 11);
    snprintf(p2, sizeof p2, "%s/../adam7.png", sub);
    write_png16_il(p2, 13, 11, big, 1);
    pg_array arr;
    CHECK_OK(io_png16_load(p2, &arr));
    int okv = arr.data != NULL;
    for (int i = 0; okv && i < 13 * 11; i++) okv = arr.data[i] == big[i];
    CHECK(okv, "interlaced 16-bit PNG values");
    pg_array_destroy(&arr);
}

/* Encodes a grayf32 frame with libavcodec's EXR encoder (an independent writer; channel "Y"). */
static int write_exr_ffmpeg(const char *path, int w, int h, const float *v, const char *compression, const char *format)
{
    const AVCodec *codec = avcodec_find_encoder_by_name("exr");
    if (!codec) return -1;
    AVCodecContext *c = avcodec_alloc_context3(codec);
    c->width = w;
    c->height = h;
    c->pix_fmt = AV_PIX_FMT_GRAYF32LE;
    c->time_base = (AVRational){ 1, 25 };
    av_opt_set(c->priv_data, "compression", compression, 0);
    av_opt_set(c->priv_data, "format", format, 0);
    int rc = -1;
    if (avcodec_open2(c, codec, NULL) >= 0) {
        AVFrame *f = av_frame_alloc();
        f->format = c->pix_fmt;
        f->width = w;
        f->height = h;
        av_frame_get_buffer(f, 0);
        for (int y = 0; y < h; y++) memcpy(f->data[0] + (size_t)y * f->linesize[0], v + (size_t)y * w, sizeof(float) * w);
        AVPacket *pkt = av_packet_alloc();
        if (avcodec_send_frame(c, f) >= 0 && avcodec_receive_packet(c, pkt) >= 0) {
            FILE *fp = fopen(path, "wb");
            fwrite(pkt->data, 1, (size_t)pkt->size, fp);
            fclose(fp);
            rc = 0;
        }
        av_packet_free(&pkt);
        av_frame_free(&f);
    }
    avcodec_free_context(&c);
    return rc;
}

static void test_exr(const char *dir)
{
    enum { H = 37, W = 29 }; /* 37 rows: a partial last ZIP block of 16 lines */
    float v[H * W];
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) v[y * W + x] = 0.5f + 0.125f * x + 0.25f * y; /* exact in half */
    const char *comp[] = { "none", "rle", "zip1", "zip16" };
    const char *fmt[] = { "float", "half" };
    int tried = 0;
    for (int c = 0; c < 4; c++)
        for (int f = 0; f < 2; f++) {
            char name[64], path[4096];
            snprintf(name, sizeof name, "d_%s_%s.exr", comp[c], fmt[f]);
            pg_path_join(path, sizeof path, dir, name);
            if (write_exr_ffmpeg(path, W, H, v, comp[c], fmt[f])) continue;
            tried++;
            pg_array arr;
            pg_status st = io_exr_load(path, &arr);
            CHECK(st == PG_OK, "%s: %s", name, pg_last_error());
            if (st == PG_OK) {
                double worst = 0;
                for (int i = 0; i < H * W; i++) worst = fmax(worst, fabs(arr.data[i] - v[i]));
                CHECK(arr.shape[0] == H && arr.shape[1] == W && worst == 0, "%s: max error %g", name, worst);
                pg_array_destroy(&arr);
            }
        }
    CHECK(tried == 8, "libavcodec EXR encoder produced %d of 8 files", tried);
    /* Truncated EXR. */
    char path[4096], tpath[4096];
    pg_path_join(path, sizeof path, dir, "d_zip16_float.exr");
    pg_path_join(tpath, sizeof tpath, dir, "trunc.exr");
    char *data;
    size_t size;
    if (pg_read_file(path, 1 << 24, &data, &size) == PG_OK) {
        pg_write_file_atomic(tpath, data, size - 40);
        pg_array arr;
        CHECK(io_exr_load(tpath, &arr) == PG_ERR_FORMAT, "truncated exr: %s", pg_last_error());
        CHECK(strstr(pg_last_error(), "trunc.exr") != NULL, "names file");
        free(data);
    }
}

/* A minimal uncompressed scanline EXR: one FLOAT channel Z, the given dataWindow and one chunk
 * per row whose y values are ys[] (crafted files: overflowing windows, repeated rows). */
static void write_exr_raw(const char *path, int32_t xmin, int32_t ymin, int32_t xmax, int32_t ymax, const int32_t *ys,
                          int nchunks, float value)
{
    uint8_t buf[4096];
    size_t n = 0;
#define PUT(ptr, len) do { memcpy(buf + n, (ptr), (len)); n += (len); } while (0)
#define PUT32(v) do { uint32_t u_ = (uint32_t)(v); uint8_t b_[4] = { (uint8_t)u_, (uint8_t)(u_ >> 8), (uint8_t)(u_ >> 16), (uint8_t)(u_ >> 24) }; PUT(b_, 4); } while (0)
    PUT32(20000630u);
    PUT32(2);
    PUT("channels\0chlist\0", 16);
    PUT32(19); /* "Z\0", type, pLinear + 3 reserved, x/y sampling, list terminator */
    PUT("Z\0", 2);
    PUT32(2); /* FLOAT */
    PUT("\0\0\0\0", 4);
    PUT32(1);
    PUT32(1);
    PUT("\0", 1);
    PUT("compression\0compression\0", 24);
    PUT32(1);
    PUT("\0", 1);
    PUT("dataWindow\0box2i\0", 17);
    PUT32(16);
    PUT32(xmin);
    PUT32(ymin);
    PUT32(xmax);
    PUT32(ymax);
    PUT("\0", 1);
    int w = xmax - xmin + 1;
    size_t table = n;
    n += (size_t)nchunks * 8;
    for (int c = 0; c < nchunks; c++) {
        uint64_t off = n;
        for (int k = 0; k < 8; k++) buf[table + 8 * (size_t)c + k] = (uint8_t)(off >> (8 * k));
        PUT32(ys[c]);
        PUT32(4 * w);
        for (int x = 0; x < w; x++) PUT(&value, 4);
    }
#undef PUT32
#undef PUT
    pg_write_file_atomic(path, buf, n);
}

static void test_exr_hostile(const char *dir)
{
    char path[4096];
    pg_array arr;
    /* dataWindow at the ends of int32: legal, must load without signed overflow */
    pg_path_join(path, sizeof path, dir, "ymin_intmin.exr");
    int32_t lo[2] = { INT32_MIN, INT32_MIN + 1 };
    write_exr_raw(path, 0, INT32_MIN, 2, INT32_MIN + 1, lo, 2, 3.0f);
    pg_status st = io_exr_load(path, &arr);
    CHECK(st == PG_OK && arr.shape[0] == 2 && arr.shape[1] == 3 && arr.data[5] == 3.0f, "ymin INT_MIN: %s",
          st ? pg_last_error() : "ok");
    if (st == PG_OK) pg_array_destroy(&arr);
    pg_path_join(path, sizeof path, dir, "ymax_intmax.exr");
    int32_t hi[2] = { INT32_MAX - 1, INT32_MAX };
    write_exr_raw(path, 0, INT32_MAX - 1, 2, INT32_MAX, hi, 2, 4.0f);
    st = io_exr_load(path, &arr);
    CHECK(st == PG_OK && arr.data[0] == 4.0f, "ymax INT_MAX: %s", st ? pg_last_error() : "ok");
    if (st == PG_OK) pg_array_destroy(&arr);
    /* a chunk y far from ymin = INT_MIN: y - ymin overflowed int32 (UBSan) before the fix */
    pg_path_join(path, sizeof path, dir, "far_y.exr");
    int32_t far[2] = { 0, INT32_MIN };
    write_exr_raw(path, 0, INT32_MIN, 2, INT32_MIN + 1, far, 2, 1.0f);
    CHECK(io_exr_load(path, &arr) == PG_ERR_FORMAT && strstr(pg_last_error(), "bad y"), "far y: %s", pg_last_error());
    /* a window whose height overflows int32 arithmetic */
    pg_path_join(path, sizeof path, dir, "huge_window.exr");
    write_exr_raw(path, 0, INT32_MIN, 2, INT32_MAX, lo, 1, 1.0f);
    CHECK(io_exr_load(path, &arr) == PG_ERR_SIZE && strstr(pg_last_error(), "huge_window.exr"), "huge window: %s",
          pg_last_error());
    /* every chunk carries the same y: the other rows would be read uninitialised */
    pg_path_join(path, sizeof path, dir, "same_y.exr");
    int32_t same[3] = { 0, 0, 0 };
    write_exr_raw(path, 0, 0, 3, 2, same, 3, 2.0f);
    CHECK(io_exr_load(path, &arr) == PG_ERR_FORMAT && strstr(pg_last_error(), "repeats"), "repeated y: %s",
          pg_last_error());
}

/* npy header that ends right after 'descr': '< (read past the header before the fix), and depth
 * values below FLT_MIN (their inverse overflowed into a NaN colour index in prepare). */
static void test_npy_hostile(const char *dir)
{
    char path[4096];
    pg_path_join(path, sizeof path, dir, "descr_cut.npy");
    const char head[] = "{'descr': '<";
    uint8_t file[10 + sizeof head - 1];
    uint8_t pre[10] = { 0x93, 'N', 'U', 'M', 'P', 'Y', 1, 0, (uint8_t)(sizeof head - 1), 0 };
    memcpy(file, pre, 10);
    memcpy(file + 10, head, sizeof head - 1);
    pg_write_file_atomic(path, file, sizeof file);
    pg_array arr;
    CHECK(io_npy_load(path, &arr) == PG_ERR_FORMAT && strstr(pg_last_error(), "descr_cut.npy"), "cut descr: %s",
          pg_last_error());
    enum { H = 10, W = 10 };
    float v[H * W];
    for (int i = 0; i < H * W; i++) v[i] = i % 3 ? 2.0f : 1e-40f; /* a third subnormal */
    size_t shape[3] = { 1, H, W };
    pg_path_join(path, sizeof path, dir, "subnormal.npy");
    CHECK_OK(io_npy_save(path, v, 3, shape));
    io_depth d;
    io_depth_options o = io_depth_defaults();
    CHECK_OK(io_depth_load(path, &o, &d));
    CHECK(d.invalid == 34 && d.data && d.data[0] == 0.0f && d.data[1] == 2.0f, "subnormal depth: %zu invalid", d.invalid);
    io_depth_destroy(&d);
    /* header bytes quoted in an error are escaped: no terminal escape reaches the user */
    pg_path_join(path, sizeof path, dir, "escape.pfm");
    pg_write_file_atomic(path, "Pf\n\x1b[31mX 4\n-1.0\n", 17);
    CHECK(io_pfm_load(path, &arr) == PG_ERR_FORMAT && !strchr(pg_last_error(), 0x1b) && strstr(pg_last_error(), "\\x1b"),
          "escaped header bytes: %s", pg_last_error());
    float rgb[3];
    static const float stops[2][3] = { { 0, 0, 0 }, { 1, 1, 1 } };
    pg_color_ramp(stops, 2, NAN, rgb);
    CHECK(rgb[0] == 0.0f, "colour ramp of NaN: %g", rgb[0]);
}

static void test_bad(const char *dir)
{
    char path[4096], err[1024], args[8300];
    io_depth d;
    pg_array arr;
    /* Absurd header sizes. */
    pg_path_join(path, sizeof path, dir, "huge.npy");
    write_npy_raw(path, "<f4", "(1000000000, 1000000000)", NULL, 0);
    CHECK(io_depth_load(path, NULL, &d) == PG_ERR_SIZE, "huge npy: %s", pg_last_error());
    snprintf(args, sizeof args, "info '%s'", path);
    int rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 2 && strstr(err, "huge.npy"), "info huge npy rc %d: %s", rc, err);

    pg_path_join(path, sizeof path, dir, "huge.pfm");
    pg_write_file_atomic(path, "Pf\n1000000000 1000000000\n-1.0\n", 30);
    CHECK(io_pfm_load(path, &arr) == PG_ERR_SIZE, "huge pfm: %s", pg_last_error());
    snprintf(args, sizeof args, "info '%s'", path);
    rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 2 && strstr(err, "huge.pfm"), "info huge pfm rc %d: %s", rc, err);

    /* A PNG header claiming 10^9 x 10^9 (valid IHDR CRC not needed for the limit check to trip). */
    pg_path_join(path, sizeof path, dir, "huge.png");
    {
        uint16_t v[4] = { 1, 2, 3, 4 };
        write_png16(path, 2, 2, v);
        char *data;
        size_t size;
        pg_read_file(path, 1 << 20, &data, &size);
        /* IHDR width/height at bytes 16..23; patch and fix the CRC. */
        uint32_t big = 1000000000u;
        for (int k = 0; k < 2; k++) {
            data[16 + 4 * k] = (char)(big >> 24);
            data[17 + 4 * k] = (char)(big >> 16);
            data[18 + 4 * k] = (char)(big >> 8);
            data[19 + 4 * k] = (char)big;
        }
        uint32_t crc = (uint32_t)crc32(0, (const unsigned char *)data + 12, 17);
        data[29] = (char)(crc >> 24);
        data[30] = (char)(crc >> 16);
        data[31] = (char)(crc >> 8);
        data[32] = (char)crc;
        pg_write_file_atomic(path, data, size);
        free(data);
    }
    CHECK(io_png16_load(path, &arr) == PG_ERR_FORMAT, "huge png: %s", pg_last_error());
    CHECK(strstr(pg_last_error(), "huge.png") != NULL, "names file: %s", pg_last_error());
    snprintf(args, sizeof args, "info '%s'", path);
    rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 2 && strstr(err, "huge.png"), "info huge png rc %d: %s", rc, err);

    /* Truncated npy / pfm, garbled npy. */
    pg_path_join(path, sizeof path, dir, "trunc.npy");
    float z[100] = { 0 };
    write_npy_raw(path, "<f4", "(10, 20)", z, sizeof z);
    CHECK(io_depth_load(path, NULL, &d) == PG_ERR_FORMAT, "truncated npy: %s", pg_last_error());
    snprintf(args, sizeof args, "info '%s'", path);
    rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 2 && strstr(err, "trunc.npy"), "info trunc npy rc %d: %s", rc, err);
    pg_path_join(path, sizeof path, dir, "garbled.npy");
    pg_write_file_atomic(path, "\x93NUMPY\x01\x00\x10\x00{'descr': 'zz'}", 26);
    CHECK(io_depth_load(path, NULL, &d) == PG_ERR_FORMAT, "garbled npy: %s", pg_last_error());
    pg_path_join(path, sizeof path, dir, "trunc.pfm");
    pg_write_file_atomic(path, "Pf\n4 4\n-1.0\n\0\0\0\0", 16);
    CHECK(io_pfm_load(path, &arr) == PG_ERR_FORMAT, "truncated pfm: %s", pg_last_error());
    snprintf(args, sizeof args, "info '%s'", path);
    rc = test_run_cli(args, err, sizeof err);
    CHECK(rc == 2 && strstr(err, "trunc.pfm"), "info trunc pfm rc %d: %s", rc, err);
    pg_path_join(path, sizeof path, dir, "garbled.pfm");
    pg_write_file_atomic(path, "Pf\nabc 4\n-1.0\n", 14);
    CHECK(io_pfm_load(path, &arr) == PG_ERR_FORMAT, "garbled pfm: %s", pg_last_error());
    pg_path_join(path, sizeof path, dir, "nothere.npy");
    CHECK(io_depth_load(path, NULL, &d) == PG_ERR_IO, "missing");
}

static long file_size(const char *path)
{
    struct stat sb;
    return stat(path, &sb) == 0 ? (long)sb.st_size : -1;
}

/* float16 storage: every half round-trips exactly, floats round to the nearest half (ties to
 * even), and a map with values float16 cannot hold is kept as float32. */
static void test_npy_compact(const char *dir)
{
    int bad = 0;
    for (uint32_t h = 0; h < 0x10000u; h++) {
        float f = io_half_to_float((uint16_t)h);
        if (isnan(f)) continue;
        bad += io_float_to_half(f) != h;
    }
    CHECK(bad == 0, "%d halves do not round-trip", bad);
    { /* the array conversion (F16C where the CPU has it) gives io_half_to_float's numbers, scaled */
        static uint16_t all[0x10000 + 3];
        static float got[0x10000 + 3];
        for (uint32_t h = 0; h < 0x10000u + 3; h++) all[h] = (uint16_t)(h * 40503u); /* every value, shuffled, odd tail */
        io_halves_to_floats(all, 0x10000 + 3, 0.37f, got);
        int differ = 0;
        for (uint32_t h = 0; h < 0x10000u + 3; h++) {
            float want = io_half_to_float(all[h]) * 0.37f;
            differ += isnan(want) ? !isnan(got[h]) : memcmp(&want, &got[h], 4) != 0;
        }
        CHECK(differ == 0, "io_halves_to_floats differs from io_half_to_float in %d of 65539 values", differ);
    }
    CHECK(io_float_to_half(1.0f + 1.0f / 2048) == 0x3c00, "1 + 2^-11 ties to even (1.0)");
    CHECK(io_float_to_half(1.0f + 3.0f / 2048) == 0x3c02, "1 + 3 * 2^-11 ties to even (1 + 2^-9)");
    CHECK(io_float_to_half(70000.0f) == 0x7c00 && io_float_to_half(-1e-9f) == 0x8000, "overflow to inf, underflow to -0");
    double worst = 0;
    for (int i = 0; i < 100000; i++) {
        float f = 1e-4f * powf(1.0002f, (float)i); /* 1e-4 .. 4.8e4 */
        if (f > 65000.0f) break;
        worst = fmax(worst, fabs(io_half_to_float(io_float_to_half(f)) / f - 1.0));
    }
    CHECK(worst <= 1.0 / 2048 + 1e-9, "relative error %.3g > 2^-11", worst);

    char path[4096];
    float d[6] = { 0.0f, 1.5f, 3.25f, 12.0f, 0.001f, 1000.0f };
    size_t shape[2] = { 2, 3 };
    pg_path_join(path, sizeof path, dir, "half.npy");
    CHECK_OK(io_npy_save_compact(path, d, 2, shape));
    pg_array a;
    CHECK_OK(io_npy_load(path, &a));
    CHECK(file_size(path) == 128 + 12 && a.count == 6, "float16 file: %ld bytes", file_size(path));
    for (int i = 0; a.data && i < 6; i++) CHECK(fabsf(a.data[i] - d[i]) <= d[i] / 2048, "value %d: %g vs %g", i, a.data[i], d[i]);
    pg_array_destroy(&a);
    /* the raw halves as they are in the file: the same values io_npy_load converts */
    uint16_t h[6] = { 0 };
    int loaded = 0;
    CHECK_OK(io_npy_load_half(path, h, 6, &loaded));
    CHECK(loaded, "a float16 file of 6 values loads as halves");
    for (int i = 0; i < 6; i++) CHECK(h[i] == io_float_to_half(d[i]), "half %d: 0x%04x", i, h[i]);
    CHECK_OK(io_npy_load_half(path, h, 5, &loaded));
    CHECK(!loaded, "a count that differs is left to io_npy_load");
    d[5] = 1e6f; /* millimetres of a far wall: no longer float16 */
    CHECK_OK(io_npy_save_compact(path, d, 2, shape));
    CHECK_OK(io_npy_load(path, &a));
    CHECK(file_size(path) == 128 + 24 && a.data && a.data[5] == 1e6f, "kept as float32 (%ld bytes)", file_size(path));
    pg_array_destroy(&a);
    CHECK_OK(io_npy_load_half(path, h, 6, &loaded));
    CHECK(!loaded, "a float32 file is left to io_npy_load");
    CHECK(truncate(path, 128 + 4) == 0, "truncate"); /* truncated: the same error as io_npy_load's */
    CHECK(io_npy_load_half(path, h, 6, &loaded) == PG_ERR_FORMAT && strstr(pg_last_error(), "truncated"),
          "truncated file: %s", pg_last_error());
}

int main(void)
{
    char dir[4096];
    test_tmpdir("test_io_depth", dir, sizeof dir);
    test_npy(dir);
    test_npy_compact(dir);
    test_pfm(dir);
    test_png16(dir);
    test_png16_frames(dir);
    test_exr(dir);
    test_exr_hostile(dir);
    test_npy_hostile(dir);
    test_bad(dir);
    return test_summary("test_io_depth");
}
