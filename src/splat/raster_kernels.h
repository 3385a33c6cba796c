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

void splat_tile_forward_scalar(const splat_tile_job *job);
void splat_tile_backward_scalar(const splat_tile_job *job);
/* The SIMD kernels (x86-64 builds only; raster.c checks the CPU before calling them). */
void splat_tile_forward_avx512(const splat_tile_job *job);
void splat_tile_backward_avx512(const splat_tile_job *job);
void splat_tile_forward_avx2(const splat_tile_job *job);
void splat_tile_backward_avx2(const splat_tile_job *job);

#endif
