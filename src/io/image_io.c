/* image_io.c - PNG through libpng, JPEG through libjpeg(-turbo). */
#include "io/image_io.h"
#include "core/fileutil.h"

#include <png.h>
#include <jpeglib.h>
#include <errno.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    jmp_buf jump;
    char message[200];
} png_err_ctx;

static void png_error_jump(png_structp png, png_const_charp msg)
{
    png_err_ctx *ctx = png_get_error_ptr(png);
    snprintf(ctx->message, sizeof ctx->message, "%s", msg);
    longjmp(ctx->jump, 1);
}

static void png_warning_quiet(png_structp png, png_const_charp msg)
{
    (void)png;
    (void)msg;
}

pg_status io_png_read_samples(const char *path, io_png_samples *out)
{
    memset(out, 0, sizeof *out);
    FILE *fp;
    PG_TRY(pg_open_read(path, &fp));
    png_err_ctx ctx;
    ctx.message[0] = '\0';
    png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &ctx, png_error_jump, png_warning_quiet);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    uint8_t *volatile rowbuf = NULL;
    if (!png || !info) {
        png_destroy_read_struct(&png, &info, NULL);
        fclose(fp);
        return pg_fail(PG_ERR_NOMEM, "%s: cannot allocate PNG reader", path);
    }
    if (setjmp(ctx.jump)) {
        png_destroy_read_struct(&png, &info, NULL);
        fclose(fp);
        free(rowbuf);
        free(out->samples);
        memset(out, 0, sizeof *out);
        return pg_fail(PG_ERR_FORMAT, "%s: corrupt PNG: %s", path, ctx.message);
    }
    png_set_user_limits(png, PG_MAX_IMAGE_SIDE, PG_MAX_IMAGE_SIDE);
    png_init_io(png, fp);
    png_read_info(png, info);
    int w = (int)png_get_image_width(png, info), h = (int)png_get_image_height(png, info);
    int depth = png_get_bit_depth(png, info), ct = png_get_color_type(png, info);
    if (ct == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
    if (depth < 8) png_set_expand_gray_1_2_4_to_8(png);
    int passes = png_set_interlace_handling(png);
    png_read_update_info(png, info);
    int ch = png_get_channels(png, info);
    int bytes = png_get_bit_depth(png, info) == 16 ? 2 : 1;
    /* The whole image is buffered so interlaced files (several passes over the rows) work too. */
    size_t rb = png_get_rowbytes(png, info);
    rowbuf = malloc(rb * (size_t)h);
    out->samples = malloc((size_t)w * h * ch * sizeof *out->samples);
    if (!rowbuf || !out->samples) { snprintf(ctx.message, sizeof ctx.message, "out of memory"); longjmp(ctx.jump, 3); }
    for (int pass = 0; pass < passes; pass++)
        for (int y = 0; y < h; y++) png_read_row(png, rowbuf + rb * (size_t)y, NULL);
    for (int y = 0; y < h; y++)
        for (int i = 0; i < w * ch; i++) {
            const uint8_t *p = rowbuf + rb * (size_t)y + (size_t)i * bytes;
            out->samples[(size_t)y * w * ch + i] = bytes == 2 ? (uint16_t)((p[0] << 8) | p[1]) : p[0];
        }
    png_read_end(png, NULL);
    png_destroy_read_struct(&png, &info, NULL);
    free(rowbuf);
    fclose(fp);
    out->width = w;
    out->height = h;
    out->channels = ch;
    out->maxval = bytes == 2 ? 65535 : 255;
    return PG_OK;
}

/* A 16-bit PNG through the sample reader: libpng's simplified API would take 16-bit data for
 * linear light and brighten it on the way to 8 bits (189 became 222). */
static pg_status load_png16(const char *path, pg_image *img)
{
    io_png_samples px;
    PG_TRY(io_png_read_samples(path, &px));
    pg_status st = pg_image_create(img, px.width, px.height, 3);
    float inv = 1.0f / (float)px.maxval;
    int colour = px.channels >= 3;
    for (size_t i = 0; st == PG_OK && i < (size_t)px.width * px.height; i++)
        for (int c = 0; c < 3; c++) img->data[i * 3 + c] = px.samples[i * px.channels + (colour ? c : 0)] * inv;
    free(px.samples);
    return st;
}

static pg_status load_png(const char *path, pg_image *img)
{
    png_image pi;
    memset(&pi, 0, sizeof pi);
    pi.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&pi, path))
        return pg_fail(PG_ERR_FORMAT, "%s: not a readable PNG: %s", path, pi.message);
    if (pi.width == 0 || pi.height == 0 || pi.width > PG_MAX_IMAGE_SIDE || pi.height > PG_MAX_IMAGE_SIDE) {
        png_image_free(&pi);
        return pg_fail(PG_ERR_SIZE, "%s: PNG size %u x %u is out of range", path, pi.width, pi.height);
    }
    if (pi.format & PNG_FORMAT_FLAG_LINEAR) { /* 16 bits per sample */
        png_image_free(&pi);
        return load_png16(path, img);
    }
    pi.format = PNG_FORMAT_RGB;
    size_t n = (size_t)pi.width * pi.height * 3;
    uint8_t *buf = pg_malloc(n, path);
    if (!buf) { png_image_free(&pi); return PG_ERR_NOMEM; }
    if (!png_image_finish_read(&pi, NULL, buf, 0, NULL)) {
        free(buf);
        return pg_fail(PG_ERR_FORMAT, "%s: corrupt PNG: %s", path, pi.message);
    }
    pg_status st = pg_image_create(img, (int)pi.width, (int)pi.height, 3);
    if (st == PG_OK)
        for (size_t i = 0; i < n; i++) img->data[i] = buf[i] * (1.0f / 255.0f);
    free(buf);
    return st;
}

struct jpeg_error_jump {
    struct jpeg_error_mgr mgr;
    jmp_buf jump;
    char message[JMSG_LENGTH_MAX];
};

static void jpeg_error_exit_jump(j_common_ptr cinfo)
{
    struct jpeg_error_jump *err = (struct jpeg_error_jump *)cinfo->err;
    (*cinfo->err->format_message)(cinfo, err->message);
    longjmp(err->jump, 1);
}

static pg_status load_jpeg(const char *path, pg_image *img)
{
    FILE *fp;
    PG_TRY(pg_open_read(path, &fp));
    struct jpeg_decompress_struct cinfo;
    struct jpeg_error_jump err;
    uint8_t *volatile row = NULL;
    img->data = NULL;
    cinfo.err = jpeg_std_error(&err.mgr);
    err.mgr.error_exit = jpeg_error_exit_jump;
    if (setjmp(err.jump)) {
        jpeg_destroy_decompress(&cinfo);
        fclose(fp);
        free(row);
        pg_image_destroy(img);
        return pg_fail(PG_ERR_FORMAT, "%s: corrupt JPEG: %s", path, err.message);
    }
    jpeg_create_decompress(&cinfo);
    jpeg_stdio_src(&cinfo, fp);
    jpeg_read_header(&cinfo, TRUE);
    cinfo.out_color_space = JCS_RGB;
    jpeg_start_decompress(&cinfo);
    pg_status st = pg_image_create(img, (int)cinfo.output_width, (int)cinfo.output_height, 3);
    if (st == PG_OK) row = pg_malloc((size_t)cinfo.output_width * 3, path);
    if (st == PG_OK && !row) st = PG_ERR_NOMEM;
    if (st != PG_OK) {
        jpeg_destroy_decompress(&cinfo);
        fclose(fp);
        return pg_fail_context(st, "%s", path);
    }
    while (cinfo.output_scanline < cinfo.output_height) {
        int y = (int)cinfo.output_scanline;
        JSAMPROW rows[1] = { row };
        jpeg_read_scanlines(&cinfo, rows, 1);
        float *dst = pg_image_at(img, 0, y);
        for (int i = 0; i < img->width * 3; i++) dst[i] = row[i] * (1.0f / 255.0f);
    }
    jpeg_finish_decompress(&cinfo);
    jpeg_destroy_decompress(&cinfo);
    fclose(fp);
    free(row);
    return PG_OK;
}

pg_status io_image_load(const char *path, pg_image *img)
{
    img->data = NULL;
    img->width = img->height = img->channels = 0;
    FILE *fp;
    PG_TRY(pg_open_read(path, &fp));
    uint8_t magic[8] = {0};
    size_t got = fread(magic, 1, sizeof magic, fp);
    fclose(fp);
    if (got >= 8 && png_sig_cmp(magic, 0, 8) == 0) return load_png(path, img);
    if (got >= 3 && magic[0] == 0xFF && magic[1] == 0xD8 && magic[2] == 0xFF) return load_jpeg(path, img);
    return pg_fail(PG_ERR_FORMAT, "%s: not a PNG or JPEG image", path);
}

static uint8_t to_u8(float v)
{
    v = v < 0 ? 0 : (v > 1 ? 1 : v);
    return (uint8_t)(v * 255.0f + 0.5f);
}

/* 8-bit rows to fp at zlib level 1 with the Sub filter: the proxy stage writes thousands of frames
 * and masks, and libpng's defaults (level 6, every filter tried on every row) spent ~10 % of it in
 * zlib. 0 with ctx->message set on failure. */
static int write_png_rows(FILE *fp, const uint8_t *buf, int width, int height, int channels, png_err_ctx *ctx)
{
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, ctx, png_error_jump, png_warning_quiet);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    if (!info) {
        png_destroy_write_struct(&png, NULL);
        snprintf(ctx->message, sizeof ctx->message, "out of memory");
        return 0;
    }
    if (setjmp(ctx->jump)) {
        png_destroy_write_struct(&png, &info);
        return 0;
    }
    png_init_io(png, fp);
    png_set_IHDR(png, info, (png_uint_32)width, (png_uint_32)height, 8,
                 channels == 3 ? PNG_COLOR_TYPE_RGB : PNG_COLOR_TYPE_GRAY, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_set_compression_level(png, 1);
    png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_SUB);
    png_write_info(png, info);
    for (int y = 0; y < height; y++) png_write_row(png, buf + (size_t)y * width * channels);
    png_write_end(png, NULL);
    png_destroy_write_struct(&png, &info);
    return 1;
}

pg_status io_image_save_png(const char *path, const pg_image *img)
{
    if (img->channels != 1 && img->channels != 3)
        return pg_fail(PG_ERR_ARG, "%s: PNG writer takes 1 or 3 channels, got %d", path, img->channels);
    size_t n = (size_t)img->width * img->height * img->channels;
    uint8_t *buf = pg_malloc(n, path);
    if (!buf) return PG_ERR_NOMEM;
    for (size_t i = 0; i < n; i++) buf[i] = to_u8(img->data[i]);
    pg_atomic_file f;
    pg_status st = pg_atomic_open(&f, path);
    if (st == PG_OK) {
        png_err_ctx ctx;
        ctx.message[0] = '\0';
        if (!write_png_rows(f.fp, buf, img->width, img->height, img->channels, &ctx)) {
            pg_atomic_abort(&f);
            st = pg_fail(PG_ERR_ENV, "%s: PNG write failed: %s", path, ctx.message);
        } else {
            st = pg_atomic_commit(&f);
        }
    }
    free(buf);
    return st;
}

pg_status io_image_save_jpeg(const char *path, const pg_image *img, int quality)
{
    if (img->channels != 3) return pg_fail(PG_ERR_ARG, "%s: JPEG writer takes 3 channels", path);
    pg_atomic_file f;
    PG_TRY(pg_atomic_open(&f, path));
    uint8_t *row = pg_malloc((size_t)img->width * 3, path);
    if (!row) { pg_atomic_abort(&f); return PG_ERR_NOMEM; }
    struct jpeg_compress_struct cinfo;
    struct jpeg_error_mgr jerr;
    cinfo.err = jpeg_std_error(&jerr);
    jpeg_create_compress(&cinfo);
    jpeg_stdio_dest(&cinfo, f.fp);
    cinfo.image_width = (JDIMENSION)img->width;
    cinfo.image_height = (JDIMENSION)img->height;
    cinfo.input_components = 3;
    cinfo.in_color_space = JCS_RGB;
    jpeg_set_defaults(&cinfo);
    jpeg_set_quality(&cinfo, quality, TRUE);
    jpeg_start_compress(&cinfo, TRUE);
    for (int y = 0; y < img->height; y++) {
        const float *src = pg_image_at(img, 0, y);
        for (int i = 0; i < img->width * 3; i++) row[i] = to_u8(src[i]);
        JSAMPROW rows[1] = { row };
        jpeg_write_scanlines(&cinfo, rows, 1);
    }
    jpeg_finish_compress(&cinfo);
    jpeg_destroy_compress(&cinfo);
    free(row);
    return pg_atomic_commit(&f);
}
