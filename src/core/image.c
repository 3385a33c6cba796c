/* image.c - float image container and small whole-image helpers. */
#include "core/image.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

pg_status pg_image_create(pg_image *img, int width, int height, int channels)
{
    img->width = img->height = img->channels = 0;
    img->data = NULL;
    if (width <= 0 || height <= 0 || channels <= 0 || width > PG_MAX_IMAGE_SIDE ||
        height > PG_MAX_IMAGE_SIDE || channels > 4)
        return pg_fail(PG_ERR_SIZE, "image size %d x %d x %d is out of range", width, height, channels);
    size_t n = (size_t)width * height * channels;
    img->data = pg_calloc(n, sizeof(float), "image");
    if (!img->data) return PG_ERR_NOMEM;
    img->width = width;
    img->height = height;
    img->channels = channels;
    return PG_OK;
}

void pg_image_destroy(pg_image *img)
{
    if (!img) return;
    free(img->data);
    img->data = NULL;
    img->width = img->height = img->channels = 0;
}

pg_status pg_image_copy(pg_image *dst, const pg_image *src)
{
    PG_TRY(pg_image_create(dst, src->width, src->height, src->channels));
    memcpy(dst->data, src->data, sizeof(float) * (size_t)src->width * src->height * src->channels);
    return PG_OK;
}

/* Samples src with a box of the destination pixel's footprint when shrinking (avoids aliasing),
 * bilinear otherwise. Pixel centres sit at (x + 0.5, y + 0.5). */
pg_status pg_image_resize(pg_image *dst, const pg_image *src, int width, int height)
{
    PG_TRY(pg_image_create(dst, width, height, src->channels));
    const int C = src->channels;
    const float sx = (float)src->width / width, sy = (float)src->height / height;
    for (int y = 0; y < height; y++) {
        for (int x = 0; x < width; x++) {
            float *out = pg_image_at(dst, x, y);
            if (sx > 1.0f || sy > 1.0f) {
                int x0 = (int)floorf(x * sx), x1 = (int)ceilf((x + 1) * sx);
                int y0 = (int)floorf(y * sy), y1 = (int)ceilf((y + 1) * sy);
                if (x1 > src->width) x1 = src->width;
                if (y1 > src->height) y1 = src->height;
                if (x1 <= x0) x1 = x0 + 1;
                if (y1 <= y0) y1 = y0 + 1;
                float acc[4] = {0, 0, 0, 0};
                for (int yy = y0; yy < y1; yy++)
                    for (int xx = x0; xx < x1; xx++)
                        for (int c = 0; c < C; c++) acc[c] += pg_image_at(src, xx, yy)[c];
                float inv = 1.0f / ((x1 - x0) * (y1 - y0));
                for (int c = 0; c < C; c++) out[c] = acc[c] * inv;
            } else {
                float fx = (x + 0.5f) * sx - 0.5f, fy = (y + 0.5f) * sy - 0.5f;
                int ix = (int)floorf(fx), iy = (int)floorf(fy);
                float ax = fx - ix, ay = fy - iy;
                int xa = ix < 0 ? 0 : ix, xb = ix + 1 >= src->width ? src->width - 1 : ix + 1;
                int ya = iy < 0 ? 0 : iy, yb = iy + 1 >= src->height ? src->height - 1 : iy + 1;
                if (xa >= src->width) xa = src->width - 1;
                if (ya >= src->height) ya = src->height - 1;
                for (int c = 0; c < C; c++) {
                    float top = pg_image_at(src, xa, ya)[c] * (1 - ax) + pg_image_at(src, xb, ya)[c] * ax;
                    float bot = pg_image_at(src, xa, yb)[c] * (1 - ax) + pg_image_at(src, xb, yb)[c] * ax;
                    out[c] = top * (1 - ay) + bot * ay;
                }
            }
        }
    }
    return PG_OK;
}

double pg_image_psnr(const pg_image *a, const pg_image *b, const float *mask)
{
    double se = 0;
    size_t count = 0;
    const size_t npix = (size_t)a->width * a->height;
    const int C = a->channels;
    for (size_t i = 0; i < npix; i++) {
        if (mask && mask[i] <= 0.5f) continue;
        for (int c = 0; c < C; c++) {
            double d = (double)a->data[i * C + c] - b->data[i * C + c];
            se += d * d;
        }
        count += C;
    }
    if (count == 0) return 0.0;
    double mse = se / count;
    if (mse < 1e-12) mse = 1e-12;
    return -10.0 * log10(mse);
}

void pg_color_ramp(const float (*stops)[3], int n, float s, float rgb[3])
{
    s = s >= 0 ? (s > 1 ? 1 : s) : 0; /* NaN -> 0: it must never reach the (int) below */
    float x = s * (float)(n - 1);
    int i = (int)x;
    if (i > n - 2) i = n - 2;
    float f = x - i;
    for (int c = 0; c < 3; c++) rgb[c] = stops[i][c] * (1 - f) + stops[i + 1][c] * f;
}

void pg_image_to_rgb8(const pg_image *img, unsigned char *out)
{
    const size_t n = (size_t)img->width * img->height;
    const int C = img->channels;
    for (size_t k = 0; k < n; k++)
        for (int c = 0; c < 3; c++) {
            float v = img->data[k * C + (C >= 3 ? c : 0)] * 255.0f + 0.5f;
            out[k * 3 + c] = (unsigned char)(v < 0 ? 0 : v > 255 ? 255 : v);
        }
}
