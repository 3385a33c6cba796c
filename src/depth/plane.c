/* plane.c - single-channel float plane helpers for the depth stage (see plane.h). */
#include "depth/plane.h"

#define PAR_OK ((size_t)w * h >= PLANE_PAR_MIN_PIXELS)

#include <math.h>
#include <stdlib.h>
#include <string.h>

static inline int clampi(int v, int lo, int hi) { return v < lo ? lo : (v > hi ? hi : v); }

void depth_plane_from_image(const pg_image *img, float scale, float *gray)
{
    const size_t n = (size_t)img->width * img->height;
    const int C = img->channels;
    for (size_t i = 0; i < n; i++) {
        const float *px = img->data + i * C;
        gray[i] = scale * (C >= 3 ? 0.299f * px[0] + 0.587f * px[1] + 0.114f * px[2] : px[0]);
    }
}

void depth_plane_gaussian_blur(const float *src, int w, int h, float sigma, float *tmp, float *dst)
{
    if (sigma <= 0.0f) {
        if (dst != src) memcpy(dst, src, sizeof(float) * (size_t)w * h);
        return;
    }
    int r = (int)ceilf(3.0f * sigma);
    if (r > 32) r = 32;
    float k[65], sum = 0.0f;
    for (int i = -r; i <= r; i++) sum += (k[i + r] = expf(-0.5f * i * i / (sigma * sigma)));
    for (int i = 0; i <= 2 * r; i++) k[i] /= sum;
    #pragma omp parallel for schedule(static) if (PAR_OK)
    for (int y = 0; y < h; y++) {
        const float *row = src + (size_t)y * w;
        float *out = tmp + (size_t)y * w;
        for (int x = 0; x < w; x++) {
            float acc = 0.0f;
            for (int i = -r; i <= r; i++) acc += k[i + r] * row[clampi(x + i, 0, w - 1)];
            out[x] = acc;
        }
    }
    #pragma omp parallel for schedule(static) if (PAR_OK)
    for (int y = 0; y < h; y++) {
        float *out = dst + (size_t)y * w;
        for (int x = 0; x < w; x++) out[x] = 0.0f;
        for (int i = -r; i <= r; i++) {
            const float *row = tmp + (size_t)clampi(y + i, 0, h - 1) * w;
            const float ki = k[i + r];
            for (int x = 0; x < w; x++) out[x] += ki * row[x];
        }
    }
}

float depth_plane_sample_bilinear(const float *p, int w, int h, float x, float y)
{
    if (x < 0.0f) x = 0.0f;
    if (y < 0.0f) y = 0.0f;
    if (x > w - 1) x = (float)(w - 1);
    if (y > h - 1) y = (float)(h - 1);
    int ix = (int)x, iy = (int)y;
    if (ix > w - 2) ix = w > 1 ? w - 2 : 0;
    if (iy > h - 2) iy = h > 1 ? h - 2 : 0;
    float ax = x - ix, ay = y - iy;
    int ix1 = w > 1 ? ix + 1 : ix, iy1 = h > 1 ? iy + 1 : iy;
    const float *r0 = p + (size_t)iy * w, *r1 = p + (size_t)iy1 * w;
    float top = r0[ix] + ax * (r0[ix1] - r0[ix]);
    float bot = r1[ix] + ax * (r1[ix1] - r1[ix]);
    return top + ay * (bot - top);
}

static inline void keys_weights(float t, float wt[4])
{
    /* Keys cubic convolution kernel with a = -0.5 at offsets -1, 0, 1, 2. */
    float t2 = t * t, t3 = t2 * t;
    wt[0] = -0.5f * t3 + t2 - 0.5f * t;
    wt[1] = 1.5f * t3 - 2.5f * t2 + 1.0f;
    wt[2] = -1.5f * t3 + 2.0f * t2 + 0.5f * t;
    wt[3] = 0.5f * t3 - 0.5f * t2;
}

void depth_plane_sample_bicubic(const float *const *planes, int n, int w, int h, float x, float y, float *out)
{
    if (x < 0.0f) x = 0.0f;
    if (y < 0.0f) y = 0.0f;
    if (x > w - 1) x = (float)(w - 1);
    if (y > h - 1) y = (float)(h - 1);
    int ix = (int)floorf(x), iy = (int)floorf(y);
    float wx[4], wy[4];
    keys_weights(x - ix, wx);
    keys_weights(y - iy, wy);
    int xs[4], ys[4];
    for (int i = 0; i < 4; i++) {
        xs[i] = clampi(ix - 1 + i, 0, w - 1);
        ys[i] = clampi(iy - 1 + i, 0, h - 1);
    }
    for (int k = 0; k < n; k++) {
        float acc = 0.0f;
        for (int j = 0; j < 4; j++) {
            const float *row = planes[k] + (size_t)ys[j] * w;
            acc += wy[j] * (wx[0] * row[xs[0]] + wx[1] * row[xs[1]] + wx[2] * row[xs[2]] + wx[3] * row[xs[3]]);
        }
        out[k] = acc;
    }
}

void depth_plane_resize(const float *src, int w, int h, float *dst, int w2, int h2)
{
    const float sx = (float)w / w2, sy = (float)h / h2;
    #pragma omp parallel for schedule(static) if (PAR_OK)
    for (int y = 0; y < h2; y++)
        for (int x = 0; x < w2; x++)
            dst[(size_t)y * w2 + x] = depth_plane_sample_bilinear(src, w, h, (x + 0.5f) * sx - 0.5f, (y + 0.5f) * sy - 0.5f);
}

static inline void sort9(float *v)
{
    for (int i = 1; i < 9; i++) {
        float t = v[i];
        int j = i - 1;
        while (j >= 0 && v[j] > t) { v[j + 1] = v[j]; j--; }
        v[j + 1] = t;
    }
}

/* Median of the clamped 3x3 neighbourhood by sorting (reference and border path). */
static inline float median3_at(const float *src, int w, int h, int x, int y)
{
    float v[9];
    int k = 0;
    for (int dy = -1; dy <= 1; dy++)
        for (int dx = -1; dx <= 1; dx++)
            v[k++] = src[(size_t)clampi(y + dy, 0, h - 1) * w + clampi(x + dx, 0, w - 1)];
    sort9(v);
    return v[4];
}

void depth_plane_median3_ref(const float *src, int w, int h, float *dst)
{
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) dst[(size_t)y * w + x] = median3_at(src, w, h, x, y);
}

/* Compare-exchange: a gets the smaller, b the larger (branch-free, vectorises). */
#define CE(a, b) do { float lo_ = (a) < (b) ? (a) : (b), hi_ = (a) < (b) ? (b) : (a); (a) = lo_; (b) = hi_; } while (0)

/* Interior pixels use the classic 19 compare-exchange median-of-9 network (same result as
 * sorting for finite values), written so the compiler can vectorise across x. */
void depth_plane_gradient(const float *src, int w, int h, float *gx, float *gy)
{
    #pragma omp parallel for schedule(static) if (PAR_OK)
    for (int y = 0; y < h; y++) {
        for (int x = 0; x < w; x++) {
            int xl = x > 0 ? x - 1 : 0, xr = x < w - 1 ? x + 1 : w - 1;
            int yu = y > 0 ? y - 1 : 0, yd = y < h - 1 ? y + 1 : h - 1;
            gx[(size_t)y * w + x] = (src[(size_t)y * w + xr] - src[(size_t)y * w + xl]) / (float)(xr - xl > 0 ? xr - xl : 1);
            gy[(size_t)y * w + x] = (src[(size_t)yd * w + x] - src[(size_t)yu * w + x]) / (float)(yd - yu > 0 ? yd - yu : 1);
        }
    }
}

void depth_plane_median3(const float *src, int w, int h, float *dst)
{
    #pragma omp parallel for schedule(static) if (PAR_OK)
    for (int y = 0; y < h; y++) {
        float *out = dst + (size_t)y * w;
        if (y == 0 || y == h - 1 || w < 3) {
            for (int x = 0; x < w; x++) out[x] = median3_at(src, w, h, x, y);
            continue;
        }
        const float *r0 = src + (size_t)(y - 1) * w, *r1 = src + (size_t)y * w, *r2 = src + (size_t)(y + 1) * w;
        out[0] = median3_at(src, w, h, 0, y);
        out[w - 1] = median3_at(src, w, h, w - 1, y);
        for (int x = 1; x < w - 1; x++) {
            float p0 = r0[x - 1], p1 = r0[x], p2 = r0[x + 1], p3 = r1[x - 1], p4 = r1[x], p5 = r1[x + 1];
            float p6 = r2[x - 1], p7 = r2[x], p8 = r2[x + 1];
            CE(p1, p2); CE(p4, p5); CE(p7, p8);
            CE(p0, p1); CE(p3, p4); CE(p6, p7);
            CE(p1, p2); CE(p4, p5); CE(p7, p8);
            CE(p0, p3); CE(p5, p8); CE(p4, p7);
            CE(p3, p6); CE(p1, p4); CE(p2, p5);
            CE(p4, p7); CE(p4, p2); CE(p6, p4);
            CE(p4, p2);
            out[x] = p4;
        }
    }
}
#undef CE

/* Disc-shaped min/max filter (|d|^2 <= r^2 + r); out-of-image pixels are ignored. Each row of the
 * disc is a horizontal run, so with per-row prefix counts of set pixels a pixel costs 2r + 1
 * look-ups instead of a scan of the whole disc (without memory for the counts, each run is
 * counted directly). */
/* Small discs (r <= MORPH_SMALL_R, the moving masks' and bands'): every row's run of each
 * half-width the disc has is made once by OR/AND of shifted rows (byte vectors), then each output
 * row combines 2r + 1 of them; the same result as the prefix counts below, without their per-row
 * per-pixel lookups (a quarter of loading a long clip's training set). Out-of-image pixels are
 * the operation's identity in both. */
#define MORPH_SMALL_R 4
static int mask_morph_small(const unsigned char *src, int w, int h, int r, unsigned char *dst, int dilate)
{
    const size_t n = (size_t)w * h;
    int half_of[2 * MORPH_SMALL_R + 1];
    for (int dy = -r; dy <= r; dy++) {
        int half = 0;
        while ((half + 1) * (half + 1) + dy * dy <= r * r + r) half++;
        half_of[dy + r] = half;
    }
    unsigned char *runs = malloc(n * (size_t)(r + 1)); /* runs + half * n: the rows' runs of half-width half */
    if (!runs) return 0;
    #pragma omp parallel for schedule(static) if (PAR_OK)
    for (int y = 0; y < h; y++) {
        const unsigned char *row = src + (size_t)y * w;
        unsigned char *out = runs + (size_t)y * w;
        for (int x = 0; x < w; x++) out[x] = row[x] != 0;
        for (int k = 1; k <= r; k++) {
            const unsigned char *prev = out + (size_t)(k - 1) * n;
            unsigned char *cur = out + (size_t)k * n;
            for (int x = 0; x < w; x++) {
                unsigned char v = prev[x], a = x - k >= 0 ? row[x - k] != 0 : !dilate, b = x + k < w ? row[x + k] != 0 : !dilate;
                cur[x] = dilate ? (unsigned char)(v | a | b) : (unsigned char)(v & a & b);
            }
        }
    }
    #pragma omp parallel for schedule(static) if (PAR_OK)
    for (int y = 0; y < h; y++) {
        unsigned char *d = dst + (size_t)y * w;
        memset(d, dilate ? 0 : 1, (size_t)w);
        for (int dy = -r; dy <= r; dy++) {
            int yy = y + dy;
            if (yy < 0 || yy >= h) continue;
            const unsigned char *run = runs + (size_t)half_of[dy + r] * n + (size_t)yy * w;
            if (dilate)
                for (int x = 0; x < w; x++) d[x] |= run[x];
            else
                for (int x = 0; x < w; x++) d[x] &= run[x];
        }
    }
    free(runs);
    return 1;
}

static void mask_morph(const unsigned char *src, int w, int h, int r, unsigned char *dst, int dilate)
{
    if (r < 0) r = 0;
    if (r <= MORPH_SMALL_R && mask_morph_small(src, w, h, r, dst, dilate)) return;
    int *pre = malloc((size_t)h * (w + 1) * sizeof *pre);
    if (pre) {
        #pragma omp parallel for schedule(static) if (PAR_OK)
        for (int y = 0; y < h; y++) {
            int *p = pre + (size_t)y * (w + 1);
            p[0] = 0;
            for (int x = 0; x < w; x++) p[x + 1] = p[x] + (src[(size_t)y * w + x] != 0);
        }
    }
    memset(dst, dilate ? 0 : 1, (size_t)w * h);
    for (int dy = -r; dy <= r; dy++) {
        int half = 0; /* the disc's half-width on row dy */
        while ((half + 1) * (half + 1) + dy * dy <= r * r + r) half++;
        #pragma omp parallel for schedule(static) if (PAR_OK)
        for (int y = 0; y < h; y++) {
            int yy = y + dy;
            if (yy < 0 || yy >= h) continue;
            const unsigned char *row = src + (size_t)yy * w;
            for (int x = 0; x < w; x++) {
                int a = x - half > 0 ? x - half : 0, b = x + half + 1 < w ? x + half + 1 : w, set = 0;
                if (pre) set = pre[(size_t)yy * (w + 1) + b] - pre[(size_t)yy * (w + 1) + a];
                else
                    for (int i = a; i < b; i++) set += row[i] != 0;
                unsigned char *d = dst + (size_t)y * w + x;
                if (dilate) *d |= set > 0;
                else *d &= set == b - a;
            }
        }
    }
    free(pre);
}

void depth_mask_erode(const unsigned char *src, int w, int h, int r, unsigned char *dst) { mask_morph(src, w, h, r, dst, 0); }
void depth_mask_dilate(const unsigned char *src, int w, int h, int r, unsigned char *dst) { mask_morph(src, w, h, r, dst, 1); }
