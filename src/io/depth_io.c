/* depth_io.c - depth inputs: .npy stacks, per-frame .npy/.pfm/.png/.exr folders, PFM output,
 * and a small OpenEXR scanline reader (no external EXR library). */
#include "io/depth_io.h"
#include "io/image_io.h"
#include "io/npy.h"
#include "io/video.h"
#include "core/fileutil.h"
#include "core/image.h"

#include <zlib.h>

#include <ctype.h>
#include <dirent.h>
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <errno.h>
#include <string.h>
#include <strings.h>

io_depth_options io_depth_defaults(void)
{
    io_depth_options o;
    memset(&o, 0, sizeof o);
    o.scale = 1.0f;
    o.stride = 1;
    o.max_aspect_error = 0.05f;
    return o;
}

pg_status io_depth_kind_parse(const char *text, io_depth_kind *kind)
{
    if (text && !strcmp(text, "depth")) *kind = IO_DEPTH_KIND_DEPTH;
    else if (text && !strcmp(text, "disparity")) *kind = IO_DEPTH_KIND_DISPARITY;
    else return pg_fail(PG_ERR_ARG, "--depth-kind must be 'depth' or 'disparity', got '%s'", text ? text : "");
    return PG_OK;
}

void io_depth_destroy(io_depth *d)
{
    if (!d) return;
    free(d->data);
    memset(d, 0, sizeof *d);
}

static pg_status alloc_array(pg_array *arr, const char *path, int w, int h)
{
    memset(arr, 0, sizeof *arr);
    if (w <= 0 || h <= 0 || w > PG_MAX_IMAGE_SIDE || h > PG_MAX_IMAGE_SIDE)
        return pg_fail(PG_ERR_SIZE, "%s: image size %d x %d is out of range", path, w, h);
    arr->ndim = 2;
    arr->shape[0] = (size_t)h;
    arr->shape[1] = (size_t)w;
    arr->count = (size_t)w * h;
    arr->data = pg_malloc(arr->count * sizeof(float), path);
    return arr->data ? PG_OK : PG_ERR_NOMEM;
}

/* ---------------- PFM ---------------- */

/* Reads one whitespace-delimited token of the PFM header (at most size-1 characters). */
static int pfm_token(FILE *fp, char *buf, size_t size)
{
    int c;
    while ((c = fgetc(fp)) != EOF && isspace(c)) {}
    size_t n = 0;
    while (c != EOF && !isspace(c)) {
        if (n + 1 >= size) return -1;
        buf[n++] = (char)c;
        c = fgetc(fp);
    }
    buf[n] = '\0';
    return n ? 0 : -1; /* the single whitespace after the scale token was consumed */
}

pg_status io_pfm_load(const char *path, pg_array *arr)
{
    memset(arr, 0, sizeof *arr);
    FILE *fp;
    PG_TRY(pg_open_read(path, &fp));
    char tag[8], ws[32], hs[32], ss[64];
    pg_status st = PG_OK;
    float *row = NULL;
    if (pfm_token(fp, tag, sizeof tag) || (strcmp(tag, "Pf") && strcmp(tag, "PF"))) {
        st = pg_fail(PG_ERR_FORMAT, "%s: not a PFM file (magic must be Pf or PF)", path);
        goto done;
    }
    int channels = tag[1] == 'F' ? 3 : 1;
    if (pfm_token(fp, ws, sizeof ws) || pfm_token(fp, hs, sizeof hs) || pfm_token(fp, ss, sizeof ss)) {
        st = pg_fail(PG_ERR_FORMAT, "%s: bad PFM header", path);
        goto done;
    }
    char *e1, *e2, *e3;
    long w = strtol(ws, &e1, 10), h = strtol(hs, &e2, 10);
    double scale = strtod(ss, &e3);
    if (*e1 || *e2 || *e3 || !isfinite(scale) || scale == 0) {
        st = pg_fail(PG_ERR_FORMAT, "%s: bad PFM header (size '%s x %s', scale '%s')", path, ws, hs, ss);
        goto done;
    }
    if (w <= 0 || h <= 0 || w > PG_MAX_IMAGE_SIDE || h > PG_MAX_IMAGE_SIDE) {
        st = pg_fail(PG_ERR_SIZE, "%s: PFM size %ld x %ld is out of range", path, w, h);
        goto done;
    }
    int big = scale > 0;
    long pos = ftell(fp);
    fseek(fp, 0, SEEK_END);
    long end = ftell(fp);
    fseek(fp, pos, SEEK_SET);
    size_t need = (size_t)w * h * channels * 4;
    if (end - pos < (long)need) {
        st = pg_fail(PG_ERR_FORMAT, "%s: truncated: %ld x %ld x %d floats need %zu bytes, file has %ld", path, w, h,
                     channels, need, end - pos);
        goto done;
    }
    st = alloc_array(arr, path, (int)w, (int)h);
    if (st) goto done;
    row = pg_malloc((size_t)w * channels * 4, path);
    if (!row) { st = PG_ERR_NOMEM; goto done; }
    for (long y = h - 1; y >= 0; y--) { /* PFM stores the bottom row first */
        if (fread(row, 4, (size_t)w * channels, fp) != (size_t)w * channels) {
            st = pg_fail(PG_ERR_FORMAT, "%s: truncated pixel data", path);
            goto done;
        }
        for (long x = 0; x < w; x++) {
            uint8_t b[4];
            memcpy(b, &row[x * channels], 4);
            if (big) { uint8_t t = b[0]; b[0] = b[3]; b[3] = t; t = b[1]; b[1] = b[2]; b[2] = t; }
            float v;
            memcpy(&v, b, 4);
            arr->data[y * w + x] = v;
        }
    }
done:
    fclose(fp);
    free(row);
    if (st) pg_array_destroy(arr);
    return st;
}

pg_status io_pfm_save(const char *path, const float *data, int width, int height, int channels)
{
    if (width <= 0 || height <= 0 || (channels != 1 && channels != 3))
        return pg_fail(PG_ERR_ARG, "%s: cannot write PFM of %d x %d x %d", path, width, height, channels);
    pg_atomic_file f;
    PG_TRY(pg_atomic_open(&f, path));
    fprintf(f.fp, "%s\n%d %d\n-1.0\n", channels == 3 ? "PF" : "Pf", width, height);
    for (int y = height - 1; y >= 0; y--)
        if (fwrite(data + (size_t)y * width * channels, sizeof(float), (size_t)width * channels, f.fp) !=
            (size_t)width * channels) {
            pg_atomic_abort(&f);
            return pg_fail(PG_ERR_ENV, "%s: write failed: %s", path, strerror(errno));
        }
    return pg_atomic_commit(&f);
}

/* ---------------- 16-bit PNG ---------------- */

pg_status io_png16_load(const char *path, pg_array *arr)
{
    memset(arr, 0, sizeof *arr);
    io_png_samples px;
    PG_TRY(io_png_read_samples(path, &px));
    pg_status st = alloc_array(arr, path, px.width, px.height);
    for (size_t i = 0; st == PG_OK && i < (size_t)px.width * px.height; i++)
        arr->data[i] = (float)px.samples[i * px.channels]; /* the first channel */
    free(px.samples);
    return st;
}

/* ---------------- OpenEXR ---------------- */

enum { EXR_UINT = 0, EXR_HALF = 1, EXR_FLOAT = 2 };
enum { EXR_NO_COMPRESSION = 0, EXR_RLE = 1, EXR_ZIPS = 2, EXR_ZIP = 3 };
#define EXR_MAX_CHANNELS 64

typedef struct {
    char name[256];
    int type, xs, ys;
} exr_channel;

static uint32_t rd32(const uint8_t *p) { return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24; }
static uint64_t rd64(const uint8_t *p) { return (uint64_t)rd32(p) | (uint64_t)rd32(p + 4) << 32; }

/* Undoes the ZIP/RLE pre-filter: a byte-delta predictor, then the two-halves byte split. */
static void exr_unfilter(uint8_t *buf, uint8_t *tmp, size_t n)
{
    for (size_t i = 1; i < n; i++) buf[i] = (uint8_t)(buf[i - 1] + buf[i] - 128);
    const uint8_t *a = buf, *b = buf + (n + 1) / 2;
    for (size_t i = 0; i < n; i++) tmp[i] = (i & 1) ? *b++ : *a++;
    memcpy(buf, tmp, n);
}

static int exr_rle_decode(const uint8_t *src, size_t n, uint8_t *dst, size_t want)
{
    size_t o = 0, i = 0;
    while (i < n) {
        int c = (int8_t)src[i++];
        if (c < 0) {
            size_t run = (size_t)(-c);
            if (i + run > n || o + run > want) return -1;
            memcpy(dst + o, src + i, run);
            i += run;
            o += run;
        } else {
            size_t run = (size_t)c + 1;
            if (i >= n || o + run > want) return -1;
            memset(dst + o, src[i++], run);
            o += run;
        }
    }
    return o == want ? 0 : -1;
}

static int pick_channel(const exr_channel *ch, int n)
{
    const char *order[] = { "Z", "Y", "R" };
    for (int k = 0; k < 3; k++) {
        for (int i = 0; i < n; i++)
            if (!strcmp(ch[i].name, order[k])) return i;
        if (k == 0)
            for (int i = 0; i < n; i++) {
                size_t l = strlen(ch[i].name);
                if (l > 2 && !strcmp(ch[i].name + l - 2, ".Z")) return i;
            }
    }
    return n == 1 ? 0 : -1;
}

pg_status io_exr_load(const char *path, pg_array *arr)
{
    memset(arr, 0, sizeof *arr);
    char *file;
    size_t size;
    PG_TRY(pg_read_file(path, (size_t)1 << 31, &file, &size));
    const uint8_t *d = (const uint8_t *)file, *end = d + size;
    pg_status st = PG_OK;
    uint8_t *block = NULL, *tmp = NULL, *seen = NULL;
    exr_channel ch[EXR_MAX_CHANNELS];
    int nch = 0, compression = -1, have_dw = 0;
    int32_t xmin = 0, ymin = 0, xmax = -1, ymax = -1;
#define EXR_FAIL(code, ...) do { st = pg_fail(code, __VA_ARGS__); goto done; } while (0)
    if (size < 8 || rd32(d) != 20000630u) EXR_FAIL(PG_ERR_FORMAT, "%s: not an OpenEXR file (bad magic)", path);
    uint32_t ver = rd32(d + 4);
    if ((ver & 0xff) != 2) EXR_FAIL(PG_ERR_FORMAT, "%s: unsupported OpenEXR version %u", path, ver & 0xff);
    if (ver & 0x200) EXR_FAIL(PG_ERR_FORMAT, "%s: tiled OpenEXR is not supported (save as scanlines)", path);
    if (ver & 0x1800) EXR_FAIL(PG_ERR_FORMAT, "%s: multi-part or deep OpenEXR is not supported", path);
    const uint8_t *p = d + 8;
    for (;;) { /* header attributes: name\0 type\0 int32 size, value */
        if (p >= end) EXR_FAIL(PG_ERR_FORMAT, "%s: truncated header", path);
        if (*p == 0) { p++; break; }
        const uint8_t *name = p;
        const uint8_t *z1 = memchr(p, 0, (size_t)(end - p));
        if (!z1 || z1 - p > 255) EXR_FAIL(PG_ERR_FORMAT, "%s: bad attribute name", path);
        const uint8_t *type = z1 + 1;
        const uint8_t *z2 = type < end ? memchr(type, 0, (size_t)(end - type)) : NULL;
        if (!z2 || z2 + 5 > end) EXR_FAIL(PG_ERR_FORMAT, "%s: truncated header", path);
        uint32_t asz = rd32(z2 + 1);
        const uint8_t *val = z2 + 5;
        if (asz > (size_t)(end - val)) EXR_FAIL(PG_ERR_FORMAT, "%s: truncated header attribute '%s'", path, (const char *)name);
        if (!strcmp((const char *)name, "channels")) {
            const uint8_t *q = val, *qe = val + asz;
            while (q < qe && *q) {
                const uint8_t *z = memchr(q, 0, (size_t)(qe - q));
                if (!z || z + 17 > qe || z - q > 255) EXR_FAIL(PG_ERR_FORMAT, "%s: bad channel list", path);
                if (nch >= EXR_MAX_CHANNELS) EXR_FAIL(PG_ERR_FORMAT, "%s: too many channels", path);
                memcpy(ch[nch].name, q, (size_t)(z - q));
                ch[nch].name[z - q] = '\0';
                ch[nch].type = (int)rd32(z + 1);
                ch[nch].xs = (int)rd32(z + 9);
                ch[nch].ys = (int)rd32(z + 13);
                if (ch[nch].type < 0 || ch[nch].type > 2) EXR_FAIL(PG_ERR_FORMAT, "%s: bad channel type", path);
                if (ch[nch].xs != 1 || ch[nch].ys != 1)
                    EXR_FAIL(PG_ERR_FORMAT, "%s: subsampled channels are not supported", path);
                nch++;
                q = z + 17;
            }
        } else if (!strcmp((const char *)name, "compression") && asz >= 1) {
            compression = val[0];
        } else if (!strcmp((const char *)name, "dataWindow") && asz >= 16) {
            xmin = (int32_t)rd32(val);
            ymin = (int32_t)rd32(val + 4);
            xmax = (int32_t)rd32(val + 8);
            ymax = (int32_t)rd32(val + 12);
            have_dw = 1;
        } else if (!strcmp((const char *)name, "type") && asz >= 9 && memcmp(val, "scanline", 8)) {
            EXR_FAIL(PG_ERR_FORMAT, "%s: only scanline OpenEXR images are supported", path);
        }
        p = val + asz;
    }
    if (!have_dw || nch == 0) EXR_FAIL(PG_ERR_FORMAT, "%s: header lacks channels or dataWindow", path);
    int64_t w64 = (int64_t)xmax - xmin + 1, h64 = (int64_t)ymax - ymin + 1;
    if (w64 <= 0 || h64 <= 0 || w64 > PG_MAX_IMAGE_SIDE || h64 > PG_MAX_IMAGE_SIDE)
        EXR_FAIL(PG_ERR_SIZE, "%s: OpenEXR size %lld x %lld is out of range", path, (long long)w64, (long long)h64);
    int w = (int)w64, h = (int)h64;
    int lines;
    if (compression == EXR_NO_COMPRESSION || compression == EXR_RLE || compression == EXR_ZIPS) lines = 1;
    else if (compression == EXR_ZIP) lines = 16;
    else EXR_FAIL(PG_ERR_FORMAT, "%s: OpenEXR compression %d not supported (use none, RLE, ZIP or ZIPS)", path, compression);
    int pick = pick_channel(ch, nch);
    if (pick < 0) EXR_FAIL(PG_ERR_FORMAT, "%s: no Z, Y or R channel among %d channels", path, nch);
    /* Channels are stored in the (alphabetical) order of the channel list, each a full line. */
    size_t line_bytes = 0, chan_off = 0;
    for (int i = 0; i < nch; i++) {
        if (i == pick) chan_off = line_bytes;
        line_bytes += (size_t)w * (ch[i].type == EXR_HALF ? 2 : 4);
    }
    int nchunks = (h + lines - 1) / lines;
    if ((size_t)(end - p) < (size_t)nchunks * 8) EXR_FAIL(PG_ERR_FORMAT, "%s: truncated offset table", path);
    st = alloc_array(arr, path, w, h);
    if (st) goto done;
    size_t block_bytes = line_bytes * lines;
    block = pg_malloc(block_bytes, path);
    tmp = pg_malloc(block_bytes, path);
    seen = pg_calloc((size_t)nchunks, 1, path);
    if (!block || !tmp || !seen) { st = PG_ERR_NOMEM; goto done; }
    for (int c = 0; c < nchunks; c++) {
        uint64_t off = rd64(p + (size_t)c * 8);
        if (off > size || size - off < 8) EXR_FAIL(PG_ERR_FORMAT, "%s: truncated: chunk %d lies past the end", path, c);
        const uint8_t *chunk = d + off;
        int32_t y0 = (int32_t)rd32(chunk);
        uint32_t dsz = rd32(chunk + 4);
        if (dsz > size - off - 8) EXR_FAIL(PG_ERR_FORMAT, "%s: truncated: chunk %d data past the end", path, c);
        int64_t row64 = (int64_t)y0 - ymin; /* 64-bit: ymin may be INT_MIN */
        if (row64 < 0 || row64 >= h || row64 % lines) EXR_FAIL(PG_ERR_FORMAT, "%s: chunk %d has bad y %d", path, c, y0);
        int row0 = (int)row64;
        /* every block of lines exactly once: a repeated y would leave other rows unwritten */
        if (seen[row0 / lines]) EXR_FAIL(PG_ERR_FORMAT, "%s: chunk %d repeats y %d (rows left unwritten)", path, c, y0);
        seen[row0 / lines] = 1;
        int nl = h - row0 < lines ? h - row0 : lines;
        size_t want = line_bytes * nl;
        const uint8_t *src = chunk + 8;
        if (dsz == want) {
            memcpy(block, src, want); /* stored raw (also when compression would not help) */
        } else if (compression == EXR_ZIP || compression == EXR_ZIPS) {
            uLongf got = (uLongf)want;
            if (uncompress(block, &got, src, dsz) != Z_OK || got != want)
                EXR_FAIL(PG_ERR_FORMAT, "%s: corrupt ZIP data in chunk %d", path, c);
            exr_unfilter(block, tmp, want);
        } else if (compression == EXR_RLE) {
            if (exr_rle_decode(src, dsz, block, want)) EXR_FAIL(PG_ERR_FORMAT, "%s: corrupt RLE data in chunk %d", path, c);
            exr_unfilter(block, tmp, want);
        } else {
            EXR_FAIL(PG_ERR_FORMAT, "%s: chunk %d has %u bytes, expected %zu", path, c, dsz, want);
        }
        for (int l = 0; l < nl; l++) {
            const uint8_t *q = block + line_bytes * l + chan_off;
            float *dst = arr->data + (size_t)(row0 + l) * w;
            for (int x = 0; x < w; x++) {
                if (ch[pick].type == EXR_HALF) dst[x] = io_half_to_float((uint16_t)(q[2 * x] | q[2 * x + 1] << 8));
                else if (ch[pick].type == EXR_UINT) dst[x] = (float)rd32(q + 4 * x);
                else { uint32_t b = rd32(q + 4 * x); memcpy(&dst[x], &b, 4); }
            }
        }
    }
#undef EXR_FAIL
done:
    free(file);
    free(block);
    free(tmp);
    free(seen);
    if (st) pg_array_destroy(arr);
    return st;
}

/* ---------------- depth stacks ---------------- */

static const char *ext_of(const char *path)
{
    const char *dot = strrchr(path, '.'), *slash = strrchr(path, '/');
    return (dot && (!slash || dot > slash)) ? dot : "";
}

static int is_depth_file(const char *name)
{
    const char *e = ext_of(name);
    return !strcasecmp(e, ".npy") || !strcasecmp(e, ".pfm") || !strcasecmp(e, ".png") || !strcasecmp(e, ".exr");
}

/* Drops leading/trailing singleton axes so (1,H,W) and (H,W,1) read as (H,W). */
static pg_status squeeze_2d(const char *path, pg_array *arr)
{
    int n = 0;
    size_t dims[PG_NPY_MAX_DIMS];
    for (int i = 0; i < arr->ndim; i++)
        if (arr->shape[i] != 1 || (arr->ndim - i + n) <= 2) dims[n++] = arr->shape[i];
    if (n != 2) return pg_fail(PG_ERR_SIZE, "%s: expected a 2-D depth map, got %d dimensions", path, arr->ndim);
    arr->ndim = 2;
    arr->shape[0] = dims[0];
    arr->shape[1] = dims[1];
    return PG_OK;
}

pg_status io_depth_load_image(const char *path, pg_array *arr)
{
    const char *e = ext_of(path);
    pg_status st;
    if (!strcasecmp(e, ".npy")) st = io_npy_load(path, arr);
    else if (!strcasecmp(e, ".pfm")) st = io_pfm_load(path, arr);
    else if (!strcasecmp(e, ".png")) st = io_png16_load(path, arr);
    else if (!strcasecmp(e, ".exr")) st = io_exr_load(path, arr);
    else return pg_fail(PG_ERR_FORMAT, "%s: unknown depth file type (use .npy, .pfm, .png or .exr)", path);
    if (st) return st;
    st = squeeze_2d(path, arr);
    if (st) pg_array_destroy(arr);
    return st;
}

void io_depth_resize(float *dst, int dw, int dh, const float *src, int w, int h, int bilinear)
{
    float sx = (float)w / dw, sy = (float)h / dh;
    for (int y = 0; y < dh; y++)
        for (int x = 0; x < dw; x++) {
            float fx = (x + 0.5f) * sx - 0.5f, fy = (y + 0.5f) * sy - 0.5f;
            float out = 0;
            if (!bilinear) {
                int ix = (int)floorf(fx + 0.5f), iy = (int)floorf(fy + 0.5f);
                ix = ix < 0 ? 0 : ix >= w ? w - 1 : ix;
                iy = iy < 0 ? 0 : iy >= h ? h - 1 : iy;
                out = src[(size_t)iy * w + ix];
            } else {
                int x0 = (int)floorf(fx), y0 = (int)floorf(fy);
                float ax = fx - x0, ay = fy - y0, acc = 0, wsum = 0;
                for (int k = 0; k < 4; k++) {
                    int xx = x0 + (k & 1), yy = y0 + (k >> 1);
                    xx = xx < 0 ? 0 : xx >= w ? w - 1 : xx;
                    yy = yy < 0 ? 0 : yy >= h ? h - 1 : yy;
                    float v = src[(size_t)yy * w + xx];
                    float wt = ((k & 1) ? ax : 1 - ax) * ((k >> 1) ? ay : 1 - ay);
                    if (v > 0 && wt > 0) { acc += wt * v; wsum += wt; }
                }
                out = wsum > 1e-6f ? acc / wsum : 0;
            }
            dst[(size_t)y * dw + x] = out;
        }
}

/* Converts raw values of one frame in place (scale, disparity inversion, invalid -> 0). */
static void convert_frame(io_depth *d, float *v, size_t n, const io_depth_options *o)
{
    for (size_t i = 0; i < n; i++) {
        float x = v[i] * o->scale;
        if (o->kind == IO_DEPTH_KIND_DISPARITY && isfinite(x) && x > 0) x = 1.0f / x;
        if (!(x >= FLT_MIN) || !isfinite(x)) { /* NaN, inf, <= 0 and subnormal (1/x would overflow) */
            x = 0;
            d->invalid++;
        }
        v[i] = x;
    }
    d->total += n;
}

/* Stores frame k of the output from a (h, w) source map, resizing when needed. */
static pg_status put_frame(const char *path, io_depth *d, int k, float *src, int w, int h, const io_depth_options *o)
{
    if (k == 0) {
        d->src_width = w;
        d->src_height = h;
        d->width = o->width > 0 ? o->width : w;
        d->height = o->height > 0 ? o->height : h;
        if (o->width > 0 && o->height <= 0) d->height = (int)lround((double)h * o->width / w);
        if (o->height > 0 && o->width <= 0) d->width = (int)lround((double)w * o->height / h);
        double ar_src = (double)w / h, ar_dst = (double)d->width / d->height;
        if (fabs(ar_src / ar_dst - 1.0) > o->max_aspect_error)
            return pg_fail(PG_ERR_SIZE, "%s: depth is %d x %d but frames are %d x %d (aspect ratios differ)", path, w, h,
                           d->width, d->height);
        size_t bytes;
        if (pg_size_mul((size_t)d->width * d->height * sizeof(float), (size_t)d->frames, &bytes))
            return pg_fail(PG_ERR_SIZE, "%s: depth stack is too large", path);
        d->data = pg_malloc(bytes ? bytes : 1, path);
        if (!d->data) return PG_ERR_NOMEM;
    } else if (w != d->src_width || h != d->src_height) {
        return pg_fail(PG_ERR_SIZE, "%s: frame %d is %d x %d, the first is %d x %d", path, k, w, h, d->src_width,
                       d->src_height);
    }
    convert_frame(d, src, (size_t)w * h, o);
    float *dst = d->data + (size_t)k * d->width * d->height;
    if (w == d->width && h == d->height) memcpy(dst, src, sizeof(float) * (size_t)w * h);
    else io_depth_resize(dst, d->width, d->height, src, w, h, o->bilinear);
    return PG_OK;
}

static pg_status select_frames(const char *path, const io_depth_options *o, int available, int *first, int *count,
                               int *stride)
{
    *first = o->first > 0 ? o->first : 0;
    *stride = o->stride > 0 ? o->stride : 1;
    if (*first >= available)
        return pg_fail(PG_ERR_SIZE, "%s: first frame %d is past the end (%d depth frames)", path, *first, available);
    int can = (available - *first + *stride - 1) / *stride;
    *count = o->count > 0 ? o->count : can;
    if (*count > can)
        return pg_fail(PG_ERR_SIZE, "%s: has %d depth frames, %d needed (first %d, stride %d)", path, available,
                       *first + (*count - 1) * *stride + 1, *first, *stride);
    if (o->expect_frames > 0 && *count != o->expect_frames)
        return pg_fail(PG_ERR_SIZE, "%s: %d depth frames selected but the video has %d", path, *count, o->expect_frames);
    return PG_OK;
}

static void finish_stats(io_depth *d)
{
    size_t n = (size_t)d->frames * d->width * d->height;
    float mn = INFINITY, mx = 0;
    for (size_t i = 0; i < n; i++) {
        float v = d->data[i];
        if (v > 0) {
            if (v < mn) mn = v;
            if (v > mx) mx = v;
        }
    }
    d->min = mx > 0 ? mn : 0;
    d->max = mx;
}

static pg_status load_stack(const char *path, const io_depth_options *o, io_depth *d)
{
    pg_array arr;
    PG_TRY(io_npy_load(path, &arr));
    size_t F, H, W;
    if (arr.ndim == 2) { F = 1; H = arr.shape[0]; W = arr.shape[1]; }
    else if (arr.ndim == 3) { F = arr.shape[0]; H = arr.shape[1]; W = arr.shape[2]; }
    else if (arr.ndim == 4 && arr.shape[3] == 1) { F = arr.shape[0]; H = arr.shape[1]; W = arr.shape[2]; }
    else if (arr.ndim == 4 && arr.shape[1] == 1) { F = arr.shape[0]; H = arr.shape[2]; W = arr.shape[3]; } /* torch (F,1,H,W) */
    else {
        int ndim = arr.ndim; /* read before destroy, which clears the array */
        pg_array_destroy(&arr);
        return pg_fail(PG_ERR_SIZE, "%s: depth must have shape (F,H,W), (H,W), (F,H,W,1) or (F,1,H,W); got %d dimensions", path, ndim);
    }
    if (H == 0 || W == 0 || F == 0 || H > PG_MAX_IMAGE_SIDE || W > PG_MAX_IMAGE_SIDE) {
        pg_array_destroy(&arr);
        return pg_fail(PG_ERR_SIZE, "%s: depth shape (%zu, %zu, %zu) is out of range", path, F, H, W);
    }
    int first, count, stride;
    pg_status st = select_frames(path, o, (int)F, &first, &count, &stride);
    d->src_frames = (int)F;
    d->frames = count;
    for (int k = 0; st == PG_OK && k < count; k++)
        st = put_frame(path, d, k, arr.data + (size_t)(first + k * stride) * H * W, (int)W, (int)H, o);
    pg_array_destroy(&arr);
    return st;
}

static pg_status load_folder(const char *path, const io_depth_options *o, io_depth *d)
{
    DIR *dir = opendir(path);
    if (!dir) return pg_fail(PG_ERR_IO, "%s: cannot open folder", path);
    /* Reuse the natural-order image lister's sort by collecting names ourselves. */
    char **names = NULL;
    int n = 0, cap = 0;
    pg_status st = PG_OK;
    struct dirent *e;
    while ((e = readdir(dir)) != NULL) {
        if (e->d_name[0] == '.' || !is_depth_file(e->d_name)) continue;
        if (n == cap) {
            cap = cap ? 2 * cap : 64;
            char **nn = realloc(names, sizeof *names * (size_t)cap);
            if (!nn) { st = pg_fail(PG_ERR_NOMEM, "%s: out of memory", path); break; }
            names = nn;
        }
        size_t len = strlen(path) + strlen(e->d_name) + 2;
        names[n] = pg_malloc(len, path);
        if (!names[n]) { st = PG_ERR_NOMEM; break; }
        snprintf(names[n], len, "%s/%s", path, e->d_name);
        n++;
        if (n > 1000000) { st = pg_fail(PG_ERR_SIZE, "%s: too many files", path); break; }
    }
    closedir(dir);
    if (st == PG_OK && n == 0) st = pg_fail(PG_ERR_FORMAT, "%s: folder has no .npy/.pfm/.png/.exr depth files", path);
    if (st == PG_OK) {
        io_sort_names(names, n);
        const char *e0 = ext_of(names[0]);
        for (int i = 1; i < n && st == PG_OK; i++)
            if (strcasecmp(ext_of(names[i]), e0))
                st = pg_fail(PG_ERR_FORMAT, "%s: mixes depth file types (%s and %s)", path, e0, ext_of(names[i]));
    }
    int first = 0, count = 0, stride = 1;
    if (st == PG_OK) st = select_frames(path, o, n, &first, &count, &stride);
    d->src_frames = n;
    d->frames = count;
    for (int k = 0; st == PG_OK && k < count; k++) {
        const char *name = names[first + k * stride];
        pg_array arr;
        st = io_depth_load_image(name, &arr);
        if (st) break;
        st = put_frame(name, d, k, arr.data, (int)arr.shape[1], (int)arr.shape[0], o);
        pg_array_destroy(&arr);
    }
    io_free_names(names, n);
    return st;
}

pg_status io_depth_load(const char *path, const io_depth_options *opt, io_depth *out)
{
    memset(out, 0, sizeof *out);
    io_depth_options o = opt ? *opt : io_depth_defaults();
    if (o.scale == 0) o.scale = 1.0f;
    if (o.max_aspect_error <= 0) o.max_aspect_error = 0.05f;
    if (!isfinite(o.scale) || o.scale < 0) return pg_fail(PG_ERR_ARG, "%s: depth scale %g must be positive", path, o.scale);
    if (o.width < 0 || o.height < 0 || o.width > PG_MAX_IMAGE_SIDE || o.height > PG_MAX_IMAGE_SIDE)
        return pg_fail(PG_ERR_ARG, "%s: bad depth resize target %d x %d", path, o.width, o.height);
    pg_status st;
    if (pg_path_is_dir(path)) st = load_folder(path, &o, out);
    else if (!pg_path_exists(path)) return pg_fail(PG_ERR_IO, "%s: no such file", path);
    else if (!strcasecmp(ext_of(path), ".npy")) st = load_stack(path, &o, out);
    else {
        /* A single image file: one frame. */
        pg_array arr;
        st = io_depth_load_image(path, &arr);
        if (st == PG_OK) {
            int first, count, stride;
            out->src_frames = 1;
            st = select_frames(path, &o, 1, &first, &count, &stride);
            out->frames = 1;
            if (st == PG_OK) st = put_frame(path, out, 0, arr.data, (int)arr.shape[1], (int)arr.shape[0], &o);
            pg_array_destroy(&arr);
        }
    }
    if (st) {
        io_depth_destroy(out);
        return st;
    }
    finish_stats(out);
    return PG_OK;
}
