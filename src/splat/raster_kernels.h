/* raster_kernels.h - internal: per-tile forward/backward kernels shared by raster.c and the
 * SIMD kernels in raster_avx512.c and raster_avx2.c. Not a public header. */
#ifndef PG_RASTER_KERNELS_H
#define PG_RASTER_KERNELS_H

#include <math.h>
#include <stdint.h>

#define SPLAT_TILE 16
#define SPLAT_TILE_PIX (SPLAT_TILE * SPLAT_TILE)
#define SPLAT_ALPHA_MIN (1.0f / 255.0f)
#define SPLAT_ALPHA_MAX 0.99f
#define SPLAT_T_EPS 1e-4f
#define SPLAT_GRAD_STRIDE 10 /* per (Gaussian, tile) slot: dx dy da db dc dopacity dr dg db dz */

/* What the tile kernels read per Gaussian: 64 bytes, one cache line. */
typedef struct {
    float x, y;          /* projected mean, pixels */
    float ha, cb, hc;    /* half conic: sigma = ha dx^2 + cb dx dy + hc dy^2 (ha = a/2, hc = c/2) */
    float o;             /* opacity (activated) */
    float col[3];        /* SH colour */
    float z;             /* camera depth */
    float thr;           /* ln(255 o): the Gaussian counts at a pixel iff sigma <= thr (alpha >= 1/255) */
    int ymin, ymax;      /* pixel rows the opacity-aware box covers (clamped to the image) */
    int slot_base;       /* first gradient slot of this Gaussian */
    int tx0, tw;         /* first tile column of the box, tile columns in the box */
} splat_rec;

/* Everything one tile kernel call needs. */
typedef struct {
    int x0, y0, w, h;          /* tile pixel origin and size (w, h <= 16) */
    int tx, ty;                /* tile coordinates */
    int width;                 /* image width (row stride) */
    const int *list;           /* (n) Gaussian ids front to back */
    int n;
    const splat_rec *rec;      /* (N) */
    float bg[3];
    /* forward outputs / saved state, image-sized */
    float *rgb, *depth, *alpha, *tfinal; /* (H,W,3) (H,W) (H,W) (H,W) */
    int *last;                 /* (H,W) index into list of the last contributor, -1 none */
    /* backward inputs (may be NULL) and the slot array */
    const float *d_rgb, *d_depth, *d_alpha;
    float *grad_slots;         /* (M, SPLAT_GRAD_STRIDE) */
} splat_tile_job;

/* exp(x) for x <= 0 via 2^n * poly(f): rel. error ~2e-7. The SIMD kernels compute the same
 * operations (fused multiply-adds in the same places) so both paths agree to rounding. */
static inline float splat_exp_poly(float x)
{
    x = x < -87.0f ? -87.0f : x;
    float n = rintf(x * 1.44269504088896341f);
    float f = fmaf(n, -0.693359375f, x);
    f = fmaf(n, 2.12194440e-4f, f);
    float p = 1.0f / 720.0f;
    p = fmaf(p, f, 1.0f / 120.0f);
    p = fmaf(p, f, 1.0f / 24.0f);
    p = fmaf(p, f, 1.0f / 6.0f);
    p = fmaf(p, f, 0.5f);
    p = fmaf(p, f, 1.0f);
    p = fmaf(p, f, 1.0f);
    union { float f; int32_t i; } s;
    s.i = ((int32_t)n + 127) << 23;
    return p * s.f;
}

/* log(x) for positive normal x: x = m 2^e with m in [sqrt(1/2), sqrt(2)), log(1 + f) = f - f^2/2 +
 * f^3 P(f) with Cephes' logf polynomial (~1 ulp). splat_log_poly16 is the same operations on 16
 * lanes, so the rasterizer's scalar and vector paths agree to the bit. */
static inline float splat_log_poly(float x)
{
    union { float f; uint32_t u; } b = { x };
    float e = (float)((int)(b.u >> 23 & 255) - 127);
    b.u = (b.u & 0x007fffffu) | 0x3f800000u; /* the mantissa in [1, 2) */
    float m = b.f;
    if (m > 1.41421356f) m = m * 0.5f, e = e + 1.0f;
    float f = m - 1.0f, z = f * f;
    float p = 7.0376836292e-2f;
    p = fmaf(p, f, -1.1514610310e-1f);
    p = fmaf(p, f, 1.1676998740e-1f);
    p = fmaf(p, f, -1.2420140846e-1f);
    p = fmaf(p, f, 1.4249322787e-1f);
    p = fmaf(p, f, -1.6668057665e-1f);
    p = fmaf(p, f, 2.0000714765e-1f);
    p = fmaf(p, f, -2.4999993993e-1f);
    p = fmaf(p, f, 3.3333331174e-1f);
    float y = p * f * z;
    y = fmaf(e, -2.12194440e-4f, y);
    y = fmaf(-0.5f, z, y);
    return fmaf(e, 0.693359375f, f + y);
}

/* The logistic sigmoid 1 / (1 + e^-x) from splat_exp_poly (NaN stays NaN). */
static inline float splat_sigmoid_poly(float x)
{
    if (!(x == x)) return x;
    float t = 0.0f - x;
    t = t < -87.0f ? -87.0f : (t > 88.0f ? 88.0f : t);
    return 1.0f / (1.0f + splat_exp_poly(t));
}

#if defined(__AVX512F__) || (defined(__AVX2__) && defined(__FMA__))
#include <immintrin.h>
#endif

#if defined(__AVX512F__)
/* splat_exp_poly on 16 lanes, without the clamp (callers clamp to the range they need): the same
 * fused multiply-adds in the same order, so every lane is bit-identical to the scalar result. */
static inline __m512 splat_exp_poly16(__m512 x)
{
    __m512 n = _mm512_roundscale_ps(_mm512_mul_ps(x, _mm512_set1_ps(1.44269504088896341f)),
                                    _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
    __m512 f = _mm512_fmadd_ps(n, _mm512_set1_ps(-0.693359375f), x);
    f = _mm512_fmadd_ps(n, _mm512_set1_ps(2.12194440e-4f), f);
    __m512 p = _mm512_set1_ps(1.0f / 720.0f);
    p = _mm512_fmadd_ps(p, f, _mm512_set1_ps(1.0f / 120.0f));
    p = _mm512_fmadd_ps(p, f, _mm512_set1_ps(1.0f / 24.0f));
    p = _mm512_fmadd_ps(p, f, _mm512_set1_ps(1.0f / 6.0f));
    p = _mm512_fmadd_ps(p, f, _mm512_set1_ps(0.5f));
    p = _mm512_fmadd_ps(p, f, _mm512_set1_ps(1.0f));
    p = _mm512_fmadd_ps(p, f, _mm512_set1_ps(1.0f));
    return _mm512_scalef_ps(p, n); /* exact p * 2^n, like the scalar exponent-bits product */
}
#endif

#if defined(__AVX512F__)
/* splat_log_poly on 16 lanes (positive finite x; subnormals too). */
static inline __m512 splat_log_poly16(__m512 x)
{
    const __m512 one = _mm512_set1_ps(1.0f);
    __m512 m = _mm512_getmant_ps(x, _MM_MANT_NORM_1_2, _MM_MANT_SIGN_zero);
    __m512 e = _mm512_getexp_ps(x);
    __mmask16 big = _mm512_cmp_ps_mask(m, _mm512_set1_ps(1.41421356f), _CMP_GT_OQ);
    m = _mm512_mask_mul_ps(m, big, m, _mm512_set1_ps(0.5f));
    e = _mm512_mask_add_ps(e, big, e, one);
    __m512 f = _mm512_sub_ps(m, one), z = _mm512_mul_ps(f, f);
    __m512 p = _mm512_set1_ps(7.0376836292e-2f);
    p = _mm512_fmadd_ps(p, f, _mm512_set1_ps(-1.1514610310e-1f));
    p = _mm512_fmadd_ps(p, f, _mm512_set1_ps(1.1676998740e-1f));
    p = _mm512_fmadd_ps(p, f, _mm512_set1_ps(-1.2420140846e-1f));
    p = _mm512_fmadd_ps(p, f, _mm512_set1_ps(1.4249322787e-1f));
    p = _mm512_fmadd_ps(p, f, _mm512_set1_ps(-1.6668057665e-1f));
    p = _mm512_fmadd_ps(p, f, _mm512_set1_ps(2.0000714765e-1f));
    p = _mm512_fmadd_ps(p, f, _mm512_set1_ps(-2.4999993993e-1f));
    p = _mm512_fmadd_ps(p, f, _mm512_set1_ps(3.3333331174e-1f));
    __m512 y = _mm512_mul_ps(_mm512_mul_ps(p, f), z);
    y = _mm512_fmadd_ps(e, _mm512_set1_ps(-2.12194440e-4f), y);
    y = _mm512_fnmadd_ps(_mm512_set1_ps(0.5f), z, y);
    return _mm512_fmadd_ps(e, _mm512_set1_ps(0.693359375f), _mm512_add_ps(f, y));
}

/* splat_sigmoid_poly on 16 lanes (max / min with the bound first keep a NaN lane NaN). */
static inline __m512 splat_sigmoid_poly16(__m512 x)
{
    __m512 t = _mm512_sub_ps(_mm512_setzero_ps(), x);
    t = _mm512_min_ps(_mm512_set1_ps(88.0f), _mm512_max_ps(_mm512_set1_ps(-87.0f), t));
    return _mm512_div_ps(_mm512_set1_ps(1.0f), _mm512_add_ps(_mm512_set1_ps(1.0f), splat_exp_poly16(t)));
}
#endif

#if defined(__AVX2__) && defined(__FMA__)
/* The 8-lane twin of splat_exp_poly16. */
static inline __m256 splat_exp_poly8(__m256 x)
{
    __m256 n = _mm256_round_ps(_mm256_mul_ps(x, _mm256_set1_ps(1.44269504088896341f)),
                               _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
    __m256 f = _mm256_fmadd_ps(n, _mm256_set1_ps(-0.693359375f), x);
    f = _mm256_fmadd_ps(n, _mm256_set1_ps(2.12194440e-4f), f);
    __m256 p = _mm256_set1_ps(1.0f / 720.0f);
    p = _mm256_fmadd_ps(p, f, _mm256_set1_ps(1.0f / 120.0f));
    p = _mm256_fmadd_ps(p, f, _mm256_set1_ps(1.0f / 24.0f));
    p = _mm256_fmadd_ps(p, f, _mm256_set1_ps(1.0f / 6.0f));
    p = _mm256_fmadd_ps(p, f, _mm256_set1_ps(0.5f));
    p = _mm256_fmadd_ps(p, f, _mm256_set1_ps(1.0f));
    p = _mm256_fmadd_ps(p, f, _mm256_set1_ps(1.0f));
    __m256i e = _mm256_slli_epi32(_mm256_add_epi32(_mm256_cvtps_epi32(n), _mm256_set1_epi32(127)), 23);
    return _mm256_mul_ps(p, _mm256_castsi256_ps(e));
}
#endif

/* Gradient slot of Gaussian r in tile (tx, ty): its box tiles are numbered row-major. */
static inline int splat_slot(const splat_rec *r, int tx, int ty)
{
    return r->slot_base + (ty - r->ymin / SPLAT_TILE) * r->tw + (tx - r->tx0);
}

/* A projected Gaussian's opacity-aware pixel box (finish in raster.c): its activated opacity, the
 * threshold ln(255 o), and the box's clamped pixel bounds; 16 lanes. */
typedef struct {
    float o[16], thr[16];
    int xmin[16], xmax[16], ymin[16], ymax[16];
} splat_box16;

/* The boxes of 16 projections (pr as splat_project_forward16 gives them, valid its mask) with the
 * opacity logits opacity[i0 ..]; returns the lanes that cover a pixel. The same operations per lane
 * as raster.c's scalar box_one. */
unsigned splat_box16_avx512(const float pr[9][16], unsigned valid, const float *opacity, int i0, int width, int height,
                            splat_box16 *b);

void splat_tile_forward_scalar(const splat_tile_job *job);
void splat_tile_backward_scalar(const splat_tile_job *job);
/* The SIMD kernels (x86-64 builds only; raster.c checks the CPU before calling them). */
void splat_tile_forward_avx512(const splat_tile_job *job);
void splat_tile_backward_avx512(const splat_tile_job *job);
void splat_tile_forward_avx2(const splat_tile_job *job);
void splat_tile_backward_avx2(const splat_tile_job *job);

#endif
