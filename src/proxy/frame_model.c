/* frame_model.c - the per-frame model: outpainted RGB-D frame rendered as a depth mesh, or (splat)
 * Gaussians seeded from its pixels, fitted briefly by Adam and splatted. */
#include "proxy/frame_model.h"
#include "splat/sh.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/image.h"
#include "core/mathx.h"
#include "core/parallel.h"
#include "optim/adam.h"
#include "optim/loss_image.h"
#include "proxy/outpaint.h"
#include "splat/gaussians.h"
#include "splat/raster.h"

#define MARGIN_BLOCK 4 /* margin Gaussians cover MARGIN_BLOCK k x MARGIN_BLOCK k pixels: the outpainted
                        * content is a smooth guess, and fewer Gaussians keep proxy renders cheap */

struct proxy_frame_model {
    int W, H;              /* modelled frame size: the source frame plus the margin on each side */
    int src_W, src_H;      /* source frame size */
    int pad;               /* margin in pixels (a multiple of the margin block MARGIN_BLOCK * k) */
    int n_fit;             /* the first n_fit Gaussians (the frame's and the margin blocks touching it)
                            * are fitted; the outer margin's stay at their outpainted targets */
    proxy_fit_options opt;
    pg_gaussians g, grad;  /* parameters and their gradients (N) */
    optim_adam *adam;      /* shared Adam over the groups of fit_groups (N rows), rebuilt per frame */
    splat_raster *raster;
    pg_camera cam;         /* source camera widened by the margin (seeding, masks) */
    float *rgb;            /* (H, W, 3) source colours, outpainted margin included */
    float *depth;          /* (H, W) source depth in pose units, 0 = invalid, margin included */
    /* The fit sees the real frame only (the margin Gaussians start at their targets; they move
     * only where they overlap the frame), so its buffers have the source size SH x SW: */
    pg_camera src_cam;     /* source camera */
    optim_ssim_ws *ssim;   /* SSIM workspace at the source size */
    float *src_rgb;        /* (SH, SW, 3) source colours */
    float *src_depth;      /* (SH, SW) source depth, 0 = invalid */
    float *vmask;          /* (SH, SW) 1 where the source depth is valid (loss mask) */
    float *d_rgb;          /* (SH, SW, 3) loss gradient w.r.t. rendered colour */
    float *d_depth;        /* (SH, SW) w.r.t. rendered (unnormalised) depth */
    float *d_alpha;        /* (SH, SW) w.r.t. rendered alpha */
    float *zmesh;          /* (view H, view W) mesh depth scratch for masks */
    unsigned char *vmargin; /* (view H, view W) 1 where the mesh shows the margin */
    float *block_depths;   /* (MARGIN_BLOCK k)^2 scratch: the depths of one seeding block */
    size_t zmesh_size;
    float median_depth;
    int valid_pixels;
    proxy_model_stats stats;
};

/* The parameter groups the fit optimises (rotations and SH beyond DC stay fixed). */
enum { FIT_MEANS, FIT_SCALES, FIT_OPACITY, FIT_DC, FIT_GROUPS };
static const optim_group_desc fit_groups[FIT_GROUPS] = {
    { "means", 3, 0, 3 }, { "log_scales", 3, 0, 3 }, { "opacity", 1, 0, 1 }, { "sh_dc", 3, 0, 3 },
};

proxy_fit_options proxy_default_fit_options(void)
{
    proxy_fit_options o;
    o.render = PROXY_RENDER_MESH;
    o.block = 1;
    o.steps = 50;
    o.ssim_weight = 0.2f;
    o.ssim_every = 8;
    o.depth_weight = 0.1f;
    o.init_opacity = 0.8f;
    o.scale_mult = 0.6f;
    o.surfels = 1;
    o.surfel_thickness = 0.2f;
    o.lr_means = 2e-5f;
    o.lr_scales = 0.005f;
    o.lr_opacity = 0.02f;
    o.lr_color = 0.005f;
    o.pad = 0.3f;
    o.mask = proxy_default_mask_options();
    return o;
}

void proxy_model_destroy(proxy_frame_model *m)
{
    if (!m) return;
    splat_gaussians_destroy(&m->g);
    splat_gaussians_destroy(&m->grad);
    splat_raster_destroy(m->raster);
    optim_ssim_destroy(m->ssim);
    free(m->vmask);
    optim_adam_destroy(m->adam);
    free(m->rgb);
    free(m->depth);
    free(m->src_rgb);
    free(m->src_depth);
    free(m->d_rgb);
    free(m->d_depth);
    free(m->d_alpha);
    free(m->zmesh);
    free(m->vmargin);
    free(m->block_depths);
    free(m);
}

pg_status proxy_model_create(proxy_frame_model **out, int width, int height, const proxy_fit_options *o)
{
    *out = NULL;
    if (width < 1 || height < 1 || width > PG_MAX_IMAGE_SIDE || height > PG_MAX_IMAGE_SIDE)
        return pg_fail(PG_ERR_SIZE, "proxy model: frame size %dx%d out of range", width, height);
    proxy_fit_options opt = o ? *o : proxy_default_fit_options();
    if (opt.block < 1 || opt.block > 64) return pg_fail(PG_ERR_ARG, "proxy model: block %d not in 1..64", opt.block);
    if (opt.ssim_every < 1) return pg_fail(PG_ERR_ARG, "proxy model: ssim_every %d < 1", opt.ssim_every);
    if (opt.steps < 0) return pg_fail(PG_ERR_ARG, "proxy model: negative step count %d", opt.steps);
    if (!(opt.pad >= 0 && opt.pad <= 1)) return pg_fail(PG_ERR_ARG, "proxy model: pad %g not in [0, 1]", opt.pad);
    proxy_frame_model *m = pg_calloc(1, sizeof *m, "proxy model");
    if (!m) return PG_ERR_NOMEM;
    int km = MARGIN_BLOCK * opt.block;
    m->pad = (int)ceilf(opt.pad * (width > height ? width : height) / km) * km;
    m->src_W = width;
    m->src_H = height;
    m->W = width + 2 * m->pad;
    m->H = height + 2 * m->pad;
    m->opt = opt;
    size_t npix = (size_t)width * height, npad = (size_t)m->W * m->H;
    m->rgb = pg_malloc(npad * 3 * sizeof(float), "proxy padded rgb");
    m->depth = pg_malloc(npad * sizeof(float), "proxy padded depth");
    m->src_rgb = pg_malloc(npix * 3 * sizeof(float), "proxy source rgb");
    m->src_depth = pg_malloc(npix * sizeof(float), "proxy source depth");
    if (!m->rgb || !m->depth || !m->src_rgb || !m->src_depth) {
        proxy_model_destroy(m);
        return PG_ERR_NOMEM;
    }
    if (opt.render == PROXY_RENDER_MESH) { /* no Gaussians, no fit */
        *out = m;
        return PG_OK;
    }
    size_t ng = (size_t)((width + opt.block - 1) / opt.block) * ((height + opt.block - 1) / opt.block) +
                (size_t)((m->W + km - 1) / km) * ((m->H + km - 1) / km);
    pg_status st = splat_gaussians_create_sh(&m->g, (int)ng, 0); /* colour of degree 0: 3 floats a row */
    if (!st) st = splat_gaussians_create_sh(&m->grad, (int)ng, 0);
    if (!st) st = splat_raster_create(&m->raster);
    if (!st) st = optim_ssim_create(&m->ssim, height, width, 3);
    if (st) { proxy_model_destroy(m); return st; }
    m->d_rgb = pg_malloc(npix * 3 * sizeof(float), "proxy d_rgb");
    m->d_depth = pg_malloc(npix * sizeof(float), "proxy d_depth");
    m->d_alpha = pg_malloc(npix * sizeof(float), "proxy d_alpha");
    m->vmask = pg_malloc(npix * sizeof(float), "proxy loss mask");
    m->block_depths = pg_malloc((size_t)km * km * sizeof(float), "proxy block depths");
    if (!m->vmask || !m->block_depths || !m->d_rgb || !m->d_depth || !m->d_alpha) {
        proxy_model_destroy(m);
        return PG_ERR_NOMEM;
    }
    *out = m;
    return PG_OK;
}

/* World point of pixel (x, y) at its depth, if valid and on the same surface as depth ref. */
static int surface_point(const proxy_frame_model *m, const pg_camera *cam, int x, int y, float ref, float X[3])
{
    if (x < 0 || y < 0 || x >= m->W || y >= m->H) return 0;
    float d = m->depth[(size_t)y * m->W + x];
    if (!(d > 0) || fabsf(d - ref) > m->opt.mask.edge_rel * ref) return 0;
    pg_camera_unproject(cam, x + 0.5f, y + 0.5f, d, X);
    return 1;
}

/* Surfel initialisation: a flat Gaussian in the local tangent plane of the depth map, stretched
 * along the tilt direction by 1/cos(view angle) so that it still covers about one pixel (k for
 * blocks) in the source view. Seen from a proxy camera it then foreshortens like the surface
 * does, where an isotropic blob would not. Returns 0 (caller falls back to isotropic) when the
 * normal cannot be estimated (depth edge or image border on both sides). */
static int init_surfel(const proxy_frame_model *m, const pg_camera *cam, int x, int y, int k, const float mu[3],
                       float sigma, float q[4], float ls[3])
{
    if (x >= m->W) x = m->W - 1;
    if (y >= m->H) y = m->H - 1;
    float ref = m->depth[(size_t)y * m->W + x];
    if (!(ref > 0)) return 0;
    float c[3], a[3], b[3], tx[3], ty[3], n[3];
    if (!surface_point(m, cam, x, y, ref, c)) return 0;
    /* tangents by central differences where possible, else one-sided */
    int ha = surface_point(m, cam, x + k, y, ref, a), hb = surface_point(m, cam, x - k, y, ref, b);
    if (ha && hb) vec3_sub(tx, a, b);
    else if (ha) vec3_sub(tx, a, c);
    else if (hb) vec3_sub(tx, c, b);
    else return 0;
    ha = surface_point(m, cam, x, y + k, ref, a);
    hb = surface_point(m, cam, x, y - k, ref, b);
    if (ha && hb) vec3_sub(ty, a, b);
    else if (ha) vec3_sub(ty, a, c);
    else if (hb) vec3_sub(ty, c, b);
    else return 0;
    vec3_cross(n, tx, ty);
    if (!(vec3_norm(n) > 0)) return 0;
    vec3_normalize(n);
    float eye[3], r[3];
    pg_camera_center(cam, eye);
    vec3_sub(r, mu, eye);
    vec3_normalize(r);
    float cosv = fabsf(vec3_dot(r, n));
    float t1[3], t2[3];
    for (int i = 0; i < 3; i++) t1[i] = r[i] - vec3_dot(r, n) * n[i];
    if (vec3_norm(t1) < 1e-4f) { /* facing the camera: any tangent */
        float ax[3] = { 1, 0, 0 };
        if (fabsf(n[0]) > 0.9f) { ax[0] = 0; ax[1] = 1; }
        vec3_cross(t1, ax, n);
    }
    vec3_normalize(t1);
    vec3_cross(t2, n, t1);
    /* local axes (x, y, z) = (t1, t2, n) are the columns of the rotation */
    float R[9] = { t1[0], t2[0], n[0], t1[1], t2[1], n[1], t1[2], t2[2], n[2] };
    mat3_to_quat(q, R);
    ls[0] = logf(sigma / fmaxf(cosv, 0.3f));
    ls[1] = logf(sigma);
    ls[2] = logf(sigma * m->opt.surfel_thickness);
    return 1;
}

/* Whether pixel (x, y) of the padded frame lies in the real frame (not the margin). */
static int in_frame(const proxy_frame_model *m, int x, int y)
{
    return x >= m->pad && y >= m->pad && x < m->pad + m->src_W && y < m->pad + m->src_H;
}

/* One Gaussian for the k x k block at (bx, by), restricted to the frame's (interior = 1) or the
 * margin's (interior = 0) pixels, at the block's median depth; its colour and position average the
 * block pixels on that surface (within 5 % of the median), so blocks on an edge do not blend the
 * foreground with the background. Returns 1 if a Gaussian was written at index n. */
static int seed_block(proxy_frame_model *m, int bx, int by, int k, int interior, int n, float logit, float *depth_out)
{
    const int W = m->W, H = m->H;
    const pg_camera *cam = &m->cam;
    float *vals = m->block_depths;
    int cnt = 0;
    for (int y = by; y < by + k && y < H; y++)
        for (int x = bx; x < bx + k && x < W; x++)
            if (in_frame(m, x, y) == interior && m->depth[(size_t)y * W + x] > 0)
                vals[cnt++] = m->depth[(size_t)y * W + x];
    if (cnt == 0) return 0;
    qsort(vals, cnt, sizeof(float), pg_cmp_float);
    float dm = vals[cnt / 2];
    float col[3] = { 0, 0, 0 }, su = 0, sv = 0, sd = 0;
    int used = 0;
    for (int y = by; y < by + k && y < H; y++)
        for (int x = bx; x < bx + k && x < W; x++) {
            float d = m->depth[(size_t)y * W + x];
            if (in_frame(m, x, y) != interior || !(d > 0) || fabsf(d - dm) > 0.05f * dm) continue;
            const float *p = m->rgb + ((size_t)y * W + x) * 3;
            col[0] += p[0]; col[1] += p[1]; col[2] += p[2];
            su += x + 0.5f; sv += y + 0.5f; sd += d;
            used++;
        }
    pg_gaussians *g = &m->g;
    float d = sd / used;
    float *mu = g->means + (size_t)n * 3;
    pg_camera_unproject(cam, su / used, sv / used, d, mu);
    float sigma = m->opt.scale_mult * k * d / cam->fx;
    float *q = g->quats + (size_t)n * 4, *ls = g->log_scales + (size_t)n * 3;
    if (!(m->opt.surfels && init_surfel(m, cam, bx + k / 2, by + k / 2, k, mu, sigma, q, ls))) {
        ls[0] = ls[1] = ls[2] = logf(sigma);
        q[0] = 1; q[1] = q[2] = q[3] = 0;
    }
    g->opacity[n] = logit;
    float *sh = splat_gaussians_sh(g, (size_t)n);
    for (int c = 0; c < 3; c++) sh[c] = (col[c] / used - 0.5f) / SPLAT_SH_C0;
    *depth_out = d;
    return 1;
}

/* Seeds the frame's k x k blocks, then the margin's larger blocks: the ring touching the frame
 * (fitted with it), then the rest (not fitted). */
pg_status proxy_model_init(proxy_frame_model *m, const pg_camera *cam, const float *rgb, const float *depth)
{
    double t0 = pg_time_seconds();
    int W = m->W, H = m->H, k = m->opt.block, p = m->pad;
    if (cam->width != m->src_W || cam->height != m->src_H)
        return pg_fail(PG_ERR_SIZE, "proxy model: camera is %dx%d, model %dx%d", cam->width, cam->height, m->src_W,
                       m->src_H);
    size_t npix = (size_t)m->src_W * m->src_H;
    int valid = 0;
    memcpy(m->src_rgb, rgb, npix * 3 * sizeof(float));
    for (size_t i = 0; i < npix; i++) {
        int ok = isfinite(depth[i]) && depth[i] > 0;
        m->src_depth[i] = ok ? depth[i] : 0;
        if (m->vmask) m->vmask[i] = (float)ok;
        valid += ok;
    }
    if (valid == 0) return pg_fail(PG_ERR_ARG, "proxy model: the depth map has no valid pixel");
    m->valid_pixels = valid;
    PG_TRY(proxy_outpaint(m->src_W, m->src_H, m->src_rgb, m->src_depth, p, m->rgb, m->depth));
    m->src_cam = *cam;
    m->cam = *cam;
    m->cam.width = W;
    m->cam.height = H;
    m->cam.cx += p;
    m->cam.cy += p;
    if (m->opt.render == PROXY_RENDER_MESH) {
        m->stats.init_s += pg_time_seconds() - t0;
        return PG_OK;
    }

    int n = 0;
    double dsum = 0;
    pg_gaussians *g = &m->g;
    PG_TRY(splat_gaussians_resize(g, g->capacity));
    const float logit = logf(m->opt.init_opacity / (1.0f - m->opt.init_opacity));
    float d;
    for (int by = p; by < p + m->src_H; by += k)
        for (int bx = p; bx < p + m->src_W; bx += k)
            if (seed_block(m, bx, by, k, 1, n, logit, &d)) n++, dsum += d;
    m->median_depth = (float)(dsum / n);
    /* Margin blocks touching the frame go first and are fitted with it (they spill into its border
     * pixels); the outer ones only render. */
    const int km = MARGIN_BLOCK * k;
    for (int pass = 0; pass < 2 && p > 0; pass++) {
        for (int by = 0; by < H; by += km)
            for (int bx = 0; bx < W; bx += km) {
                int touching = bx + km >= p && by + km >= p && bx <= p + m->src_W && by <= p + m->src_H;
                if (touching == (pass == 0) && seed_block(m, bx, by, km, 0, n, logit, &d)) n++;
            }
        if (pass == 0) m->n_fit = n;
    }
    if (p == 0) m->n_fit = n;
    g->count = n;
    g->sh_degree = 0;
    n = m->n_fit; /* the fit's arrays hold the frame's Gaussians only */
    PG_TRY(splat_gaussians_resize(&m->grad, n));
    m->grad.sh_degree = 0;
    /* The fit never reads these gradients: zeroed once per frame instead of every step. */
    memset(m->grad.quats, 0, (size_t)n * 4 * sizeof(float));
    /* Fresh moments and step counts for every frame. */
    optim_adam_destroy(m->adam);
    m->adam = NULL;
    PG_TRY(optim_adam_create(&m->adam, fit_groups, FIT_GROUPS, n, 1e-15f));
    m->stats.gaussians = g->count;
    m->stats.init_s += pg_time_seconds() - t0;
    return PG_OK;
}

static pg_render_settings model_settings(void)
{
    pg_render_settings s = splat_default_settings();
    s.background[0] = s.background[1] = s.background[2] = 0;
    s.sh_degree = 0;
    return s;
}

/* Loss on the source view and its gradient w.r.t. the rendered rgb/depth/alpha:
 * (1 - w) L1 + w D-SSIM on pixels with valid depth (the others have no Gaussian behind them),
 * plus depth_weight * mean |depth/alpha - D| / D. Without with_ssim the D-SSIM term (and its
 * gradient) is left out. Returns the loss; its L1 part only with want_value (the gradient
 * alone is enough for the steps whose loss nobody reads). */
static float source_loss(proxy_frame_model *m, const pg_render_output *out, int with_ssim, int want_value)
{
    int W = m->src_W, H = m->src_H;
    size_t npix = (size_t)W * H;
    const float ws = with_ssim ? m->opt.ssim_weight : 0, wl1 = 1.0f - m->opt.ssim_weight, wd = m->opt.depth_weight;
    const float inv_v = 1.0f / m->valid_pixels;
    memset(m->d_rgb, 0, npix * 3 * sizeof(float));
    if (!(wd > 0)) { /* otherwise the depth loop below writes every pixel */
        memset(m->d_depth, 0, npix * sizeof(float));
        memset(m->d_alpha, 0, npix * sizeof(float));
    }
    float loss = want_value ? wl1 * optim_l1_forward(out->rgb, m->src_rgb, m->vmask, H, W, 3) : 0;
    optim_l1_backward(m->d_rgb, wl1, out->rgb, m->src_rgb, m->vmask, H, W, 3);
    if (ws > 0) {
        loss += ws * (1.0f - optim_ssim_forward(m->ssim, out->rgb, m->src_rgb, m->vmask, H, W, 3));
        optim_ssim_backward(m->ssim, m->d_rgb, -ws, out->rgb, m->src_rgb, m->vmask, H, W, 3);
    }
    double ld = 0;
    if (wd > 0) {
        for (size_t i = 0; i < npix; i++) {
            float D = m->src_depth[i], a = out->alpha[i];
            if (!(D > 0) || a <= 0.05f) {
                m->d_depth[i] = m->d_alpha[i] = 0;
                continue;
            }
            float dn = out->depth[i] / a, e = (dn - D) / D;
            ld += fabsf(e);
            float gdn = wd * inv_v * (float)((e > 0) - (e < 0)) / D;
            m->d_depth[i] = gdn / a;
            m->d_alpha[i] = -gdn * out->depth[i] / (a * a);
        }
    }
    return loss + (float)(wd * ld * inv_v);
}

/* Zeroes the gradients the fit reads. Rotations are fixed: the quaternion gradients are zeroed
 * per frame. */
static void zero_grads(pg_gaussians *gr)
{
    size_t n = (size_t)gr->count;
    memset(gr->means, 0, n * 3 * sizeof(float));
    memset(gr->log_scales, 0, n * 3 * sizeof(float));
    memset(gr->opacity, 0, n * sizeof(float));
    memset(gr->sh, 0, n * (size_t)gr->sh_stride * sizeof(float));
}

/* PSNR of a source-view render over the pixels with valid depth, into the stats. The fit uses the
 * render of its last step (before that step's update) rather than paying one more forward. */
static void source_psnr(proxy_frame_model *m, const pg_render_output *out)
{
    double se = 0;
    size_t cnt = 0;
    for (size_t i = 0; i < (size_t)m->src_W * m->src_H; i++) {
        if (!(m->src_depth[i] > 0)) continue;
        for (int c = 0; c < 3; c++) {
            double d = out->rgb[i * 3 + c] - m->src_rgb[i * 3 + c];
            se += d * d;
        }
        cnt += 3;
    }
    m->stats.source_psnr = cnt ? (float)(-10.0 * log10(fmax(se / cnt, 1e-12))) : 0;
}

static pg_status fit_steps(proxy_frame_model *m);

/* Fits the frame's Gaussians alone: the margin's are hidden from the steps by the count. */
pg_status proxy_model_fit(proxy_frame_model *m)
{
    if (m->opt.render == PROXY_RENDER_MESH) return PG_OK;
    double t0 = pg_time_seconds();
    int n_all = m->g.count;
    m->g.count = m->n_fit;
    pg_status st = fit_steps(m);
    m->g.count = n_all;
    m->stats.fit_s += pg_time_seconds() - t0;
    return st;
}

static pg_status fit_steps(proxy_frame_model *m)
{
    pg_render_settings s = model_settings();
    pg_render_output out;
    pg_gaussians *g = &m->g, *gr = &m->grad;
    /* Fewer steps than the reference 100 get proportionally larger steps (at most 2x): 50 steps
     * at 2x lost ~0.25 dB of proxy PSNR against 100 at 1x on the sample scene, 50 at 1x ~1 dB. */
    const float boost = m->opt.steps > 0 ? clampf(100.0f / m->opt.steps, 1.0f, 2.0f) : 1.0f;
    const float lr_mean = m->opt.lr_means * m->median_depth;
    const float lr_scales = m->opt.lr_scales * boost, lr_opacity = m->opt.lr_opacity * boost;
    const float lr_color = m->opt.lr_color * boost;
    for (int it = 0; it < m->opt.steps; it++) {
        PG_TRY(splat_render_forward(m->raster, g, &m->src_cam, &s, &out));
        /* D-SSIM is ~20 % of a step and changes slowly: every ssim_every-th step and the last. */
        int with_ssim = it % m->opt.ssim_every == 0 || it == m->opt.steps - 1;
        int last = it == m->opt.steps - 1;
        float loss = source_loss(m, &out, with_ssim, it == 0 || last);
        if (it == 0) m->stats.first_loss = loss;
        if (last) {
            m->stats.last_loss = loss;
            source_psnr(m, &out);
        }
        zero_grads(gr);
        PG_TRY(splat_render_backward(m->raster, g, &m->src_cam, &s, m->d_rgb, m->d_depth, m->d_alpha, gr, NULL));
        if (lr_mean > 0) PG_TRY(optim_adam_step_group(m->adam, FIT_MEANS, g->means, gr->means, lr_mean));
        PG_TRY(optim_adam_step_group(m->adam, FIT_SCALES, g->log_scales, gr->log_scales, lr_scales));
        PG_TRY(optim_adam_step_group(m->adam, FIT_OPACITY, g->opacity, gr->opacity, lr_opacity));
        PG_TRY(optim_adam_step_group(m->adam, FIT_DC, g->sh, gr->sh, lr_color));
    }
    if (m->opt.steps == 0) { /* no step rendered the source view: report the initial model */
        PG_TRY(splat_render_forward(m->raster, g, &m->src_cam, &s, &out));
        source_psnr(m, &out);
    }
    return PG_OK;
}

/* The Gaussians splatted into the view; the mask also needs the mesh to agree (mask.h). */
static pg_status render_splat(proxy_frame_model *m, const pg_camera *view, float *rgb, float *depth,
                              unsigned char *mask, float *valid_fraction)
{
    pg_render_settings s = model_settings();
    pg_render_output out;
    PG_TRY(splat_render_forward(m->raster, &m->g, view, &s, &out));
    size_t n = (size_t)view->width * view->height;
    /* Depth normalised by alpha, into the caller's buffer or a temporary. */
    float *dn = depth;
    float *tmp = NULL;
    if (!dn) {
        tmp = pg_malloc(n * sizeof(float), "proxy depth");
        if (!tmp) return PG_ERR_NOMEM;
        dn = tmp;
    }
    for (size_t i = 0; i < n; i++) dn[i] = out.alpha[i] > 1e-3f ? out.depth[i] / out.alpha[i] : 0;
    if (rgb) memcpy(rgb, out.rgb, n * 3 * sizeof(float));
    pg_status st = PG_OK;
    if (mask || valid_fraction) {
        st = proxy_mesh_depth(&m->cam, m->depth, m->pad, view, &m->opt.mask, m->zmesh, m->vmargin, NULL, NULL);
        if (!st) {
            unsigned char *mk = mask ? mask : pg_malloc(n, "proxy mask");
            if (!mk) {
                st = PG_ERR_NOMEM;
            } else {
                float f = proxy_mask_combine(view->width, view->height, out.alpha, dn, m->zmesh, m->vmargin,
                                               &m->opt.mask, mk);
                if (valid_fraction) *valid_fraction = f;
                if (depth)
                    for (size_t i = 0; i < n; i++)
                        if (!mk[i]) depth[i] = 0;
                if (!mask) free(mk);
            }
        }
    }
    free(tmp);
    return st;
}

/* The frame's depth mesh rasterised into the view: colour, depth and mask in one pass. */
static pg_status render_mesh(proxy_frame_model *m, const pg_camera *view, float *rgb, float *depth,
                             unsigned char *mask, float *valid_fraction)
{
    PG_TRY(proxy_mesh_depth(&m->cam, m->depth, m->pad, view, &m->opt.mask, m->zmesh, m->vmargin,
                            rgb ? m->rgb : NULL, rgb));
    size_t n = (size_t)view->width * view->height;
    if (depth) memcpy(depth, m->zmesh, n * sizeof(float));
    float f = proxy_mask_mesh(view->width, view->height, m->zmesh, m->vmargin, &m->opt.mask, mask);
    if (valid_fraction) *valid_fraction = f;
    return PG_OK;
}

pg_status proxy_model_render(proxy_frame_model *m, const pg_camera *view, float *rgb, float *depth,
                             unsigned char *mask, float *valid_fraction)
{
    double t0 = pg_time_seconds();
    size_t n = (size_t)view->width * view->height;
    if (m->zmesh_size < n) {
        free(m->zmesh);
        free(m->vmargin);
        m->zmesh = pg_malloc(n * sizeof(float), "proxy mesh depth");
        m->vmargin = pg_malloc(n, "proxy margin flags");
        m->zmesh_size = m->zmesh && m->vmargin ? n : 0;
        if (!m->zmesh_size) return PG_ERR_NOMEM;
    }
    pg_status st = m->opt.render == PROXY_RENDER_MESH ? render_mesh(m, view, rgb, depth, mask, valid_fraction)
                                                      : render_splat(m, view, rgb, depth, mask, valid_fraction);
    m->stats.render_s += pg_time_seconds() - t0;
    return st;
}

const proxy_model_stats *proxy_model_get_stats(const proxy_frame_model *m) { return &m->stats; }
