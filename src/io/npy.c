/* npy.c - reader/writer for NumPy's .npy format. The header is a Python dict literal;
 * we parse just the three keys it always has ('descr', 'fortran_order', 'shape'). */
#include "io/npy.h"
#include "core/fileutil.h"

#include <stdint.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <errno.h>
#include <string.h>

#define NPY_MAX_ELEMENTS ((size_t)1 << 31)

void pg_array_destroy(pg_array *arr)
{
    if (!arr) return;
    free(arr->data);
    memset(arr, 0, sizeof *arr);
}

typedef struct {
    char kind;     /* 'f', 'u', 'i', 'b' */
    int bytes;
    int big_endian;
} npy_dtype;

static int parse_descr(const char *h, npy_dtype *dt)
{
    const char *p = strstr(h, "'descr'");
    if (!p) return -1;
    p = strchr(p + 7, ':');
    if (!p) return -1;
    p = strchr(p, '\'');
    if (!p) return -1;
    p++;
    char order = *p;
    if (order != '<' && order != '>' && order != '|' && order != '=') return -1;
    dt->big_endian = order == '>';
    dt->kind = p[1]; /* the header is NUL-terminated: stop at its end, never step over it */
    if (dt->kind == '\0' || strchr("fuib", dt->kind) == NULL) return -1;
    p += 2;
    if (*p < '1' || *p > '9') return -1;
    dt->bytes = *p - '0';
    if (p[1] >= '0' && p[1] <= '9') return -1; /* no supported type is 10 bytes or more */
    if (dt->kind == 'f' && dt->bytes != 4 && dt->bytes != 8 && dt->bytes != 2) return -1;
    if ((dt->kind == 'u' || dt->kind == 'i') && dt->bytes != 1 && dt->bytes != 2 && dt->bytes != 4 && dt->bytes != 8) return -1;
    if (dt->kind == 'b' && dt->bytes != 1) return -1;
    return 0;
}

static int parse_shape(const char *h, pg_array *arr)
{
    const char *p = strstr(h, "'shape'");
    if (!p) return -1;
    p = strchr(p, '(');
    if (!p) return -1;
    p++;
    arr->ndim = 0;
    arr->count = 1;
    for (;;) {
        while (*p == ' ' || *p == ',') p++;
        if (*p == ')') break;
        if (*p < '0' || *p > '9') return -1;
        char *end;
        unsigned long long v = strtoull(p, &end, 10);
        if (arr->ndim >= PG_NPY_MAX_DIMS) return -2;
        if (v > NPY_MAX_ELEMENTS) return -3;
        arr->shape[arr->ndim++] = (size_t)v;
        if (pg_size_mul(arr->count, (size_t)v, &arr->count) || arr->count > NPY_MAX_ELEMENTS) return -3;
        p = end;
    }
    return 0;
}

float io_half_to_float(uint16_t h)
{
    uint32_t sign = (uint32_t)(h >> 15) << 31, exp = (h >> 10) & 0x1f, mant = h & 0x3ff, bits;
    if (exp == 0) {
        if (mant == 0) bits = sign;
        else {
            exp = 127 - 15 + 1;
            while (!(mant & 0x400)) { mant <<= 1; exp--; }
            bits = sign | (exp << 23) | ((mant & 0x3ff) << 13);
        }
    } else if (exp == 31) bits = sign | 0x7f800000u | (mant << 13);
    else bits = sign | ((exp + 127 - 15) << 23) | (mant << 13);
    float f;
    memcpy(&f, &bits, 4);
    return f;
}

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>

__attribute__((target("avx,f16c"))) static void halves_to_floats_f16c(const uint16_t *h, size_t n, float scale,
                                                                    float *out)
{
    const __m256 k = _mm256_set1_ps(scale);
    size_t i = 0;
    for (; i + 8 <= n; i += 8)
        _mm256_storeu_ps(out + i, _mm256_mul_ps(_mm256_cvtph_ps(_mm_loadu_si128((const __m128i *)(h + i))), k));
    for (; i < n; i++) out[i] = io_half_to_float(h[i]) * scale;
}
#endif

void io_halves_to_floats(const uint16_t *h, size_t n, float scale, float *out)
{
#if defined(__x86_64__) && defined(__GNUC__)
    if (__builtin_cpu_supports("avx2")) { /* every AVX2 CPU has F16C (clang 14 cannot ask for "f16c") */
        halves_to_floats_f16c(h, n, scale, out);
        return;
    }
#endif
    for (size_t i = 0; i < n; i++) out[i] = io_half_to_float(h[i]) * scale;
}

uint16_t io_float_to_half(float f)
{
    uint32_t x;
    memcpy(&x, &f, 4);
    uint32_t sign = (x >> 16) & 0x8000u, e = (x >> 23) & 0xff, m = x & 0x7fffffu;
    if (e == 0xff) return (uint16_t)(sign | 0x7c00u | (m ? 0x200u : 0)); /* inf, NaN */
    int ex = (int)e - 127 + 15;
    if (ex >= 31) return (uint16_t)(sign | 0x7c00u);                      /* overflow -> inf */
    if (ex <= 0) {                                                        /* subnormal or zero */
        if (ex < -10) return (uint16_t)sign;
        m |= 0x800000u;
        int shift = 14 - ex;
        uint32_t h = m >> shift, rest = m & ((1u << shift) - 1), half = 1u << (shift - 1);
        if (rest > half || (rest == half && (h & 1))) h++;
        return (uint16_t)(sign | h);
    }
    uint32_t h = ((uint32_t)ex << 10) | (m >> 13), rest = m & 0x1fffu;
    if (rest > 0x1000u || (rest == 0x1000u && (h & 1))) h++; /* round to nearest even; may carry into the exponent */
    return (uint16_t)(sign | h);
}

static float convert_one(const uint8_t *src, const npy_dtype *dt)
{
    uint8_t b[8];
    for (int i = 0; i < dt->bytes; i++) b[i] = dt->big_endian ? src[dt->bytes - 1 - i] : src[i];
    switch (dt->kind) {
    case 'f':
        if (dt->bytes == 4) { float f; memcpy(&f, b, 4); return f; }
        if (dt->bytes == 8) { double d; memcpy(&d, b, 8); return (float)d; }
        { uint16_t h; memcpy(&h, b, 2); return io_half_to_float(h); }
    case 'u':
        if (dt->bytes == 1) return b[0];
        if (dt->bytes == 2) { uint16_t v; memcpy(&v, b, 2); return v; }
        if (dt->bytes == 4) { uint32_t v; memcpy(&v, b, 4); return (float)v; }
        { uint64_t v; memcpy(&v, b, 8); return (float)v; }
    case 'i':
        if (dt->bytes == 1) return (int8_t)b[0];
        if (dt->bytes == 2) { int16_t v; memcpy(&v, b, 2); return v; }
        if (dt->bytes == 4) { int32_t v; memcpy(&v, b, 4); return (float)v; }
        { int64_t v; memcpy(&v, b, 8); return (float)v; }
    default:
        return b[0] ? 1.0f : 0.0f;
    }
}

/* Opens path and reads its header: dtype and shape (arr->ndim, shape, count; no data); the file
 * is left at the first data byte, with at least the data's size behind it. */
static pg_status npy_open(const char *path, FILE **out, npy_dtype *dt, pg_array *arr)
{
    memset(arr, 0, sizeof *arr);
    *out = NULL;
    FILE *fp;
    PG_TRY(pg_open_read(path, &fp));
    uint8_t pre[12];
    pg_status st = PG_OK;
    char *header = NULL;
    if (fread(pre, 1, 10, fp) != 10 || memcmp(pre, "\x93NUMPY", 6) != 0) {
        st = pg_fail(PG_ERR_FORMAT, "%s: not a .npy file (bad magic)", path);
        goto done;
    }
    size_t hlen;
    if (pre[6] == 1) hlen = pre[8] | (pre[9] << 8);
    else if (pre[6] == 2 || pre[6] == 3) {
        if (fread(pre + 10, 1, 2, fp) != 2) { st = pg_fail(PG_ERR_FORMAT, "%s: truncated header", path); goto done; }
        hlen = (size_t)pre[8] | ((size_t)pre[9] << 8) | ((size_t)pre[10] << 16) | ((size_t)pre[11] << 24);
    } else {
        st = pg_fail(PG_ERR_FORMAT, "%s: unsupported .npy version %d", path, pre[6]);
        goto done;
    }
    if (hlen > (1 << 20)) { st = pg_fail(PG_ERR_FORMAT, "%s: header length %zu is absurd", path, hlen); goto done; }
    header = pg_malloc(hlen + 1, path);
    if (!header) { st = PG_ERR_NOMEM; goto done; }
    if (fread(header, 1, hlen, fp) != hlen) { st = pg_fail(PG_ERR_FORMAT, "%s: truncated header", path); goto done; }
    header[hlen] = '\0';
    if (parse_descr(header, dt)) { st = pg_fail(PG_ERR_FORMAT, "%s: unsupported or bad dtype in header", path); goto done; }
    if (strstr(header, "'fortran_order': True")) {
        st = pg_fail(PG_ERR_FORMAT, "%s: Fortran-ordered arrays are not supported (save with C order)", path);
        goto done;
    }
    int sr = parse_shape(header, arr);
    if (sr == -2) { st = pg_fail(PG_ERR_SIZE, "%s: more than %d dimensions", path, PG_NPY_MAX_DIMS); goto done; }
    if (sr == -3) { st = pg_fail(PG_ERR_SIZE, "%s: array shape in header is absurdly large", path); goto done; }
    if (sr) { st = pg_fail(PG_ERR_FORMAT, "%s: cannot parse shape in header", path); goto done; }
    size_t bytes = arr->count * (size_t)dt->bytes;
    long pos = ftell(fp);
    fseek(fp, 0, SEEK_END);
    long end = ftell(fp);
    fseek(fp, pos, SEEK_SET);
    if (end - pos < (long)bytes)
        st = pg_fail(PG_ERR_FORMAT, "%s: truncated: header promises %zu bytes of data, file has %ld", path, bytes, end - pos);
done:
    free(header);
    if (st) fclose(fp);
    else *out = fp;
    return st;
}

pg_status io_npy_load(const char *path, pg_array *arr)
{
    FILE *fp;
    npy_dtype dt;
    PG_TRY(npy_open(path, &fp, &dt, arr));
    pg_status st = PG_OK;
    size_t bytes = arr->count * (size_t)dt.bytes;
    uint8_t *raw = pg_malloc(bytes, path);
    arr->data = pg_malloc(arr->count * sizeof(float), path);
    if (!raw || !arr->data) { st = PG_ERR_NOMEM; goto done; }
    if (fread(raw, 1, bytes, fp) != bytes) { st = pg_fail(PG_ERR_FORMAT, "%s: truncated data", path); goto done; }
    if (dt.kind == 'f' && dt.bytes == 4 && !dt.big_endian) memcpy(arr->data, raw, bytes);
    else {
        /* whole-clip depth (hundreds of millions of values) converts on every thread */
        const long count = (long)arr->count;
        #pragma omp parallel for schedule(static)
        for (long i = 0; i < count; i++) arr->data[i] = convert_one(raw + (size_t)i * dt.bytes, &dt);
    }
done:
    fclose(fp);
    free(raw);
    if (st != PG_OK) pg_array_destroy(arr);
    return st;
}

pg_status io_npy_load_half(const char *path, uint16_t *dst, size_t count, int *loaded)
{
    *loaded = 0;
    FILE *fp;
    npy_dtype dt;
    pg_array shape;
    PG_TRY(npy_open(path, &fp, &dt, &shape));
    pg_status st = PG_OK;
    const uint16_t one = 1;
    const int little_endian_host = *(const uint8_t *)&one == 1;
    if (dt.kind == 'f' && dt.bytes == 2 && !dt.big_endian && shape.count == count && little_endian_host) {
        if (fread(dst, 2, count, fp) != count) st = pg_fail(PG_ERR_FORMAT, "%s: truncated data", path);
        else *loaded = 1;
    }
    fclose(fp);
    return st;
}

static pg_status save_raw(const char *path, const void *data, const char *descr, size_t elem, int ndim, const size_t *shape)
{
    char dict[256], shp[160] = "";
    size_t count = 1;
    for (int i = 0; i < ndim; i++) {
        char part[32];
        snprintf(part, sizeof part, "%zu%s", shape[i], (ndim == 1 || i < ndim - 1) ? ", " : "");
        strncat(shp, part, sizeof shp - strlen(shp) - 1);
        count *= shape[i];
    }
    if (ndim == 1) shp[strlen(shp) - 1] = '\0'; /* "(5,)" */
    int n = snprintf(dict, sizeof dict, "{'descr': '%s', 'fortran_order': False, 'shape': (%s), }", descr, shp);
    size_t total = 10 + (size_t)n + 1;
    size_t pad = (64 - total % 64) % 64;
    size_t hlen = (size_t)n + pad + 1;
    uint8_t pre[10] = { 0x93, 'N', 'U', 'M', 'P', 'Y', 1, 0, (uint8_t)(hlen & 0xff), (uint8_t)(hlen >> 8) };
    pg_atomic_file f;
    PG_TRY(pg_atomic_open(&f, path));
    fwrite(pre, 1, 10, f.fp);
    fwrite(dict, 1, (size_t)n, f.fp);
    for (size_t i = 0; i < pad; i++) fputc(' ', f.fp);
    fputc('\n', f.fp);
    if (count && fwrite(data, elem, count, f.fp) != count) {
        pg_atomic_abort(&f);
        return pg_fail(PG_ERR_ENV, "%s: write failed: %s", path, strerror(errno));
    }
    return pg_atomic_commit(&f);
}

pg_status io_npy_save(const char *path, const float *data, int ndim, const size_t *shape)
{
    return save_raw(path, data, "<f4", sizeof(float), ndim, shape);
}

/* float16 keeps 11 significant bits between 2^-14 and 65504: enough for a depth map (a pixel of
 * a 320-wide map is 1/300 of the field), half the bytes. Anything outside that range keeps f4. */
pg_status io_npy_save_compact(const char *path, const float *data, int ndim, const size_t *shape)
{
    size_t count = 1;
    for (int i = 0; i < ndim; i++) count *= shape[i];
    for (size_t i = 0; i < count; i++) {
        float a = fabsf(data[i]);
        if (!(a == 0.0f || (a >= 6.103515625e-05f && a <= 65504.0f))) return io_npy_save(path, data, ndim, shape);
    }
    return io_npy_save_f16(path, data, ndim, shape);
}

pg_status io_npy_save_f16(const char *path, const float *data, int ndim, const size_t *shape)
{
    size_t count = 1;
    for (int i = 0; i < ndim; i++) count *= shape[i];
    uint16_t *h = pg_malloc((count ? count : 1) * sizeof *h, path);
    if (!h) return PG_ERR_NOMEM;
    for (size_t i = 0; i < count; i++) h[i] = io_float_to_half(data[i]);
    pg_status st = save_raw(path, h, "<f2", sizeof *h, ndim, shape);
    free(h);
    return st;
}

pg_status io_npy_save_u8(const char *path, const unsigned char *data, int ndim, const size_t *shape)
{
    return save_raw(path, data, "|u1", 1, ndim, shape);
}
