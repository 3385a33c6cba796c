/* test_train.c - trainer machinery on a tiny rendered scene: training-set loader, training
 * lowers the error, checkpoint -> render gives the session's image, kill + --resume gives a
 * byte-identical final checkpoint (in process and through the CLI), clean CLI errors. */
#include <dirent.h>
#include <math.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <zlib.h>

#include "core/fileutil.h"
#include "core/parallel.h"
#include "render/model_render.h"
#include "splat/random_scene.h"
#include "splat/raster.h"
#include "testlib.h"
#include "core/rng.h"
#include "train/train.h"
#include "train/train_internal.h" /* white-box: the parameters' average */
#include "train/trainset.h"
#include "train_toy.h"

static long file_bytes(const char *path)
{
    struct stat sb;
    return stat(path, &sb) == 0 ? (long)sb.st_size : -1;
}

/* The training set's float16 depth: 11 significant bits at any unit (relative to the view's
 * median), invalid values stay invalid, and far outliers keep a valid (clamped) depth. */
static void test_depth_storage(void)
{
    enum { N = 1000 };
    float d[N];
    uint16_t h[N];
    train_view v;
    memset(&v, 0, sizeof v);
    v.depth = h;
    for (int unit = 0; unit < 3; unit++) {
        float u = unit == 0 ? 1e-4f : unit == 1 ? 1.0f : 1e5f; /* 0.1 mm .. 100 km per depth unit */
        for (int i = 0; i < N; i++) d[i] = u * (0.5f + 0.01f * i);
        d[3] = NAN;
        d[4] = -1.0f;
        d[5] = 0.0f;
        d[6] = u * 1e9f;
        size_t valid = train_view_set_depth(&v, d, N);
        double worst = 0;
        for (int i = 7; i < N; i++) worst = fmax(worst, fabs(train_view_depth(&v, i) / d[i] - 1.0));
        CHECK(valid == N - 3 && worst <= 1.0 / 2048, "unit %g: %zu valid, relative error %.3g", u, valid, worst);
        CHECK(h[3] == 0 && h[4] == 0 && h[5] == 0 && train_view_depth(&v, 6) > 1000 * train_view_depth(&v, 500),
              "unit %g: invalid kept invalid, the outlier far (%g)", u, train_view_depth(&v, 6));
        /* a float16 file's raw halves, scaled in place (d NULL), store what their float values do */
        uint16_t hr[N];
        float dr[N];
        train_view vr = v;
        vr.depth = hr;
        for (int i = 0; i < N; i++) {
            hr[i] = io_float_to_half(d[i]);
            dr[i] = io_half_to_float(hr[i]);
        }
        size_t valid_f = train_view_set_depth(&v, dr, N), valid_h = train_view_set_depth(&vr, NULL, N);
        CHECK(valid_f == valid_h && vr.depth_scale == v.depth_scale && memcmp(h, hr, sizeof h) == 0,
              "unit %g: in place from halves: %zu vs %zu valid, scale %g vs %g", u, valid_h, valid_f, vr.depth_scale,
              v.depth_scale);
    }
}

/* A broken frame file stops the load with its own name: the first broken frame's, though the
 * frames decode on several threads. */
static void test_load_errors(const char *dir)
{
    char data[1100], path[1300];
    snprintf(data, sizeof data, "%s/broken", dir);
    CHECK_OK(toy_write_trainset(data, 64, 48, 12, 2, 0));
    for (int f = 9; f >= 5; f -= 4) { /* frames 5 and 9 of proxy01: garbage */
        snprintf(path, sizeof path, "%s/proxy01/rgb/%04d.png", data, f);
        FILE *fp = fopen(path, "wb");
        CHECK(fp != NULL, "open %s", path);
        if (fp) {
            fputs("not a png", fp);
            fclose(fp);
        }
    }
    train_set ts;
    pg_status st = train_set_load(data, &ts);
    CHECK(st != PG_OK && strstr(pg_last_error(), "proxy01/rgb/0005.png") != NULL, "broken frame: %s", pg_last_error());
    if (st == PG_OK) train_set_destroy(&ts);
    /* a mask of the wrong size */
    snprintf(data, sizeof data, "%s/badmask", dir);
    CHECK_OK(toy_write_trainset(data, 64, 48, 6, 2, 0));
    snprintf(path, sizeof path, "%s/proxy02/mask/0003.png", data);
    pg_image small;
    CHECK_OK(pg_image_create(&small, 8, 8, 3));
    CHECK_OK(io_image_save_png(path, &small));
    pg_image_destroy(&small);
    st = train_set_load(data, &ts);
    CHECK(st == PG_ERR_SIZE && strstr(pg_last_error(), "proxy02/mask/0003.png: mask is 8x8, expected 64x48"),
          "wrong-size mask: %s", pg_last_error());
    if (st == PG_OK) train_set_destroy(&ts);
}

static train_config small_config(void)
{
    train_config c = train_default_config();
    c.iters = 60;
    c.coarse_iters = 20;
    c.init_points = 2000;
    c.max_gaussians = 4000;
    c.densify_from = 10;
    c.densify_every = 10;
    c.densify_until = 50;
    c.sh_ramp_every = 20;
    c.deform_res = 8;
    c.deform_width = 32;
    c.deform_channels = 8;
    c.seed = 3;
    c.static_check_every = 8;
    return c;
}

/* The model a run ends with is the moving average of its parameters from densify_until on
 * (kept here in double alongside the session, Gaussians and network), not the last step's. */
static void test_parameter_average(const train_set *ts)
{
    train_config tc = small_config();
    tc.static_check_every = 0;
    tc.average_decay = 0.8f;
    train_session *s = NULL;
    CHECK_OK(train_session_create(&s, ts, &tc, NULL, 0));
    if (!s) return;
    double *avg = NULL;
    size_t nm = 0, np = 0;
    double worst = 0, moved = 0;
    while (train_session_iteration(s) < tc.iters) {
        CHECK_OK(train_session_step(s));
        if (train_session_iteration(s) < tc.densify_until) continue;
        const float *net = train_net_params(s->net);
        if (!avg) {
            nm = (size_t)s->g.count * 3;
            np = train_net_num_params(s->net);
            avg = malloc((nm + np) * sizeof *avg);
            if (!avg) break;
            for (size_t k = 0; k < nm; k++) avg[k] = s->g.means[k];
            for (size_t k = 0; k < np; k++) avg[nm + k] = net[k];
            continue;
        }
        CHECK(s->g.count * 3 == (int)nm, "no densification while averaging");
        for (size_t k = 0; k < nm; k++) avg[k] = 0.8 * avg[k] + 0.2 * s->g.means[k];
        for (size_t k = 0; k < np; k++) avg[nm + k] = 0.8 * avg[nm + k] + 0.2 * net[k];
        for (size_t k = 0; k < nm; k++) moved = fmax(moved, fabs(avg[k] - s->g.means[k]));
    }
    CHECK_OK(train_session_run(s)); /* nothing left to step: the average becomes the model */
    const float *net = train_net_params(s->net);
    for (size_t k = 0; avg && k < nm; k++) worst = fmax(worst, fabs(s->g.means[k] - avg[k]) / (1e-3 + fabs(avg[k])));
    for (size_t k = 0; avg && k < np; k++) worst = fmax(worst, fabs(net[k] - avg[nm + k]) / (1e-3 + fabs(avg[nm + k])));
    CHECK(avg && worst < 1e-4, "final model vs the parameters' average: relative error %.3g", worst);
    CHECK(moved > 1e-6, "the average differs from the last step (%.3g)", moved);
    free(avg);
    train_session_destroy(s);
}

/* The movers' 10x loss weight inflates their view-space gradients: with densify_movable K a
 * movable Gaussian densifies only at K times the still ones' statistic. Every Gaussian gets twice
 * the threshold here, so K = 1 doubles both kinds and K = 3 only the still ones. */
static void test_densify_movable(const train_set *ts)
{
    for (int k = 0; k < 2; k++) {
        train_config tc = small_config();
        tc.max_gaussians = 100000;
        tc.densify_movable = k ? 3.0f : 1.0f;
        train_session *s = NULL;
        CHECK_OK(train_session_create(&s, ts, &tc, NULL, 0));
        if (!s) return;
        int n0 = s->g.count, st0 = train_session_static_count(s);
        for (int i = 0; i < n0; i++) {
            s->grad_accum[i] = 2 * tc.densify_grad;
            s->grad_denom[i] = 1;
        }
        CHECK_OK(train_densify_and_prune(s, 1));
        int n1 = s->g.count, st1 = train_session_static_count(s);
        int mov0 = n0 - st0, mov1 = n1 - st1;
        CHECK(st0 > 0 && mov0 > 0, "the toy has still (%d) and movable (%d) Gaussians", st0, mov0);
        CHECK(st1 == 2 * st0 && mov1 == (k ? mov0 : 2 * mov0),
              "densify_movable %g: still %d -> %d, movable %d -> %d", tc.densify_movable, st0, st1, mov0, mov1);
        train_session_destroy(s);
    }
    /* the rule (densify_movable 0): 3 while the toy's 4 time rows get < 40 fits each, else 1 */
    for (int k = 0; k < 2; k++) {
        train_config tc = small_config();
        tc.densify_movable = 0;
        tc.iters = k ? 400 : 60; /* fine steps x 3 fits: 120 < 4 x 40, 1140 >= 160 */
        train_session *s = NULL;
        CHECK_OK(train_session_create(&s, ts, &tc, NULL, 0));
        if (!s) return;
        CHECK(train_session_densify_movable(s) == (k ? 1.0f : TRAIN_LONG_CLIP_DENSIFY_MOVABLE),
              "%d iterations on 4 frames: densify_movable %g", tc.iters, train_session_densify_movable(s));
        train_session_destroy(s);
    }
}

/* From static_steps on the still Gaussians keep their scales, rotation, opacity and colour and
 * no longer densify, while the movable ones go on training (TRAIN_STATIC_STEPS); with two real
 * cameras (multi_real) they go on too. */
static void test_static_steps(const train_set *ts, int multi_real)
{
    train_config tc = small_config();
    tc.static_check_every = 0;
    tc.static_steps = 30;
    tc.densify_until = 30; /* no row changes after the stop: rows compare one to one */
    tc.max_gaussians = 100000;
    train_session *s = NULL;
    CHECK_OK(train_session_create(&s, ts, &tc, NULL, 0));
    if (!s) return;
    while (train_session_iteration(s) < tc.static_steps) CHECK_OK(train_session_step(s));
    const int n = s->g.count, sh = s->g.sh_stride;
    float *before = malloc((size_t)n * (8 + sh) * sizeof(float));
    if (!before) { train_session_destroy(s); return; }
    memcpy(before, s->g.log_scales, (size_t)n * 3 * sizeof(float));
    memcpy(before + 3 * n, s->g.quats, (size_t)n * 4 * sizeof(float));
    memcpy(before + 7 * n, s->g.opacity, (size_t)n * sizeof(float));
    memcpy(before + 8 * n, s->g.sh, (size_t)n * sh * sizeof(float));
    for (int k = 0; k < 10; k++) CHECK_OK(train_session_step(s));
    int still_changed = 0, movable_changed = 0, still = 0;
    for (int i = 0; i < n && s->g.count == n; i++) {
        int changed = memcmp(before + 3 * i, s->g.log_scales + 3 * i, 3 * sizeof(float)) ||
                      memcmp(before + 3 * n + 4 * i, s->g.quats + 4 * i, 4 * sizeof(float)) ||
                      before[7 * n + i] != s->g.opacity[i] ||
                      memcmp(before + 8 * n + (size_t)i * sh, s->g.sh + (size_t)i * sh, (size_t)sh * sizeof(float));
        still += s->is_static[i] != 0;
        if (s->is_static[i]) still_changed += changed;
        else movable_changed += changed;
    }
    if (multi_real) {
        CHECK(s->g.count == n && still_changed > still / 2, "two real cameras: %d of %d still Gaussians changed",
              still_changed, still);
    } else {
        CHECK(s->g.count == n && still > 0 && still_changed == 0 && movable_changed > 0,
              "after static_steps: %d of %d still Gaussians changed (want 0), %d movable changed (want > 0)",
              still_changed, still, movable_changed);
        for (int i = 0; i < n; i++) { /* over the threshold of both kinds (the movable one is up to 3x) */
            s->grad_accum[i] = 4 * tc.densify_grad;
            s->grad_denom[i] = 1;
        }
        int st0 = train_session_static_count(s), mov0 = s->g.count - st0;
        CHECK_OK(train_densify_and_prune(s, 1));
        int st1 = train_session_static_count(s), mov1 = s->g.count - st1;
        CHECK(st1 <= st0 && mov1 > mov0, "densify after static_steps: still %d -> %d (want no more), movable %d -> %d",
              st0, st1, mov0, mov1);
    }
    free(before);
    train_session_destroy(s);
}

/* Proxies train at half size (TRAIN_PROXY_DOWNSCALE): the full render box-averaged 2x2 must be
 * the half camera's render. A principal point off by half a pixel (the usual mistake) lands
 * every splat a quarter of a half-size pixel off; the test tells the two apart. Depth leaves
 * invalid (zero) pixels out of its average. */
static void test_half_size_proxies(void)
{
    const int W = 96, H = 64, N = 1500;
    pg_camera cam;
    pg_camera_from_fov(&cam, W, H, 60);
    cam.cx += 0.3f, cam.cy -= 0.2f; /* a principal point off the centre */
    pg_gaussians g;
    CHECK_OK(splat_gaussians_create(&g, N));
    CHECK_OK(splat_random_scene(&g, &cam, N, 2.5f, 0, 23));
    splat_raster *r = NULL;
    CHECK_OK(splat_raster_create(&r));
    pg_render_settings rs = splat_default_settings();
    pg_image full = {0}, half = {0}, shifted = {0};
    CHECK_OK(pg_image_create(&full, W, H, 3));
    CHECK_OK(pg_image_create(&half, W / 2, H / 2, 3));
    CHECK_OK(pg_image_create(&shifted, W / 2, H / 2, 3));
    pg_render_output out;
    CHECK_OK(splat_render_forward(r, &g, &cam, &rs, &out));
    if (r && full.data) memcpy(full.data, out.rgb, (size_t)W * H * 3 * sizeof(float));
    train_halve_in_place(full.data, W, H, 3, 0);
    full.width = W / 2, full.height = H / 2;
    pg_camera hc = train_half_camera(&cam);
    CHECK(hc.width == W / 2 && hc.height == H / 2, "half camera %dx%d", hc.width, hc.height);
    CHECK_OK(splat_render_forward(r, &g, &hc, &rs, &out));
    if (half.data) memcpy(half.data, out.rgb, (size_t)(W / 2) * (H / 2) * 3 * sizeof(float));
    hc.cx += 0.5f, hc.cy += 0.5f;
    CHECK_OK(splat_render_forward(r, &g, &hc, &rs, &out));
    if (shifted.data) memcpy(shifted.data, out.rgb, (size_t)(W / 2) * (H / 2) * 3 * sizeof(float));
    double right = pg_image_psnr(&half, &full, NULL), wrong = pg_image_psnr(&shifted, &full, NULL);
    CHECK(right > 40 && right > wrong + 10, /* measured 45.3 and 26.9 */ "half-size render vs the full one averaged 2x2: %.2f dB (half a pixel off: %.2f)",
          right, wrong);
    float d[4 * 2] = { 0, 2, 5, 5, 4, 0, 5, 5 }; /* two rows of 4: blocks {0,2,4,0} and {5,5,5,5} */
    train_halve_in_place(d, 4, 2, 1, 1);
    CHECK(d[0] == 3.0f && d[1] == 5.0f, "depth halved without its zeros: %g %g (want 3 5)", d[0], d[1]);
    pg_image_destroy(&full);
    pg_image_destroy(&half);
    pg_image_destroy(&shifted);
    splat_raster_destroy(r);
    splat_gaussians_destroy(&g);
}

/* A config trains (real-view PSNR up by > 3 dB) and a run killed at iteration 33 and resumed
 * writes the same final checkpoint as the uninterrupted run. */
static void check_learns_and_resumes(const train_set *ts, train_config tc, const char *dir, const char *what)
{
    char c1[1200], c3[1200];
    snprintf(c1, sizeof c1, "%s/%s_a.ckpt", dir, what);
    snprintf(c3, sizeof c3, "%s/%s_b.ckpt", dir, what);
    tc.checkpoint_every = 20;
    double q0 = 0, q1 = 0;
    train_session *s = NULL;
    CHECK_OK(train_session_create(&s, ts, &tc, c1, 0));
    if (s) {
        CHECK_OK(train_session_evaluate(s, IO_ROLE_REAL, &q0));
        CHECK_OK(train_session_run(s));
        CHECK_OK(train_session_evaluate(s, IO_ROLE_REAL, &q1));
        CHECK(q1 > q0 + 3, "%s: real-view PSNR %.2f -> %.2f", what, q0, q1);
    }
    train_session_destroy(s);
    tc.stop_at_iter = 33;
    s = NULL;
    CHECK_OK(train_session_create(&s, ts, &tc, c3, 0));
    if (s) CHECK_OK(train_session_run(s));
    train_session_destroy(s);
    tc.stop_at_iter = 0;
    s = NULL;
    CHECK_OK(train_session_create(&s, ts, &tc, c3, 1));
    if (s) CHECK_OK(train_session_run(s));
    train_session_destroy(s);
    CHECK(test_files_equal(c1, c3), "%s: resumed checkpoint differs", what);
}

/* A real camera facing a textured wall that fills its frame, trained briefly: a view turned right
 * by a quarter of the field of view has its right fifth past the real frame, where only the
 * outpainted margin's Gaussians can be (without them: a black wedge). */
static void test_margin_past_frame(const char *dir)
{
    enum { W = 64, H = 48, F = 2 };
    train_set ts = { .frames = F, .width = W, .height = H, .fps = 30, .num_views = 1 };
    ts.views = calloc(1, sizeof *ts.views);
    if (!ts.views) return;
    train_view *v = &ts.views[0];
    snprintf(v->name, sizeof v->name, "cam00");
    v->role = IO_ROLE_REAL;
    toy_camera(&v->cam, W, H, 0, 0);
    pg_camera_look_at(&v->cam, (const float[3]){ 0, 0, 0 }, (const float[3]){ 0, 0, 1 }, (const float[3]){ 0, -1, 0 });
    v->rgb = malloc((size_t)F * W * H * 3);
    v->depth = malloc((size_t)F * W * H * sizeof *v->depth);
    float *five = malloc((size_t)F * W * H * sizeof(float));
    for (int i = 0; v->rgb && v->depth && five && i < F * W * H; i++) {
        int x = i % W, y = i / W % H;
        for (int k = 0; k < 3; k++) v->rgb[3 * i + k] = (uint8_t)(60 + 40 * k + ((x / 8 + y / 8) & 1) * 60);
        five[i] = 5.0f;
    }
    if (v->depth && five) train_view_set_depth(v, five, (size_t)F * W * H);
    free(five);
    train_config c = small_config();
    c.iters = 4;
    c.coarse_iters = 4;
    c.max_gaussians = 8000; /* room for the margin: ~2,800 blocks of 2 px around 64 x 48 */
    char ckpt[1200];
    snprintf(ckpt, sizeof ckpt, "%s/wall.ckpt", dir);
    train_session *s = NULL;
    CHECK_OK(train_session_create(&s, &ts, &c, ckpt, 0));
    if (s) CHECK_OK(train_session_run(s));
    train_session_destroy(s);
    render_model *rm = NULL;
    CHECK_OK(render_model_open(ckpt, &rm));
    if (rm) {
        pg_camera turned = v->cam;
        float th = 0.5f * atanf(0.5f * W / turned.fx), cs = cosf(th), sn = sinf(th);
        const float Q[9] = { cs, 0, -sn, 0, 1, 0, sn, 0, cs };
        for (int i = 0; i < 3; i++) {
            for (int j = 0; j < 3; j++)
                turned.R[3 * i + j] = Q[3 * i] * v->cam.R[j] + Q[3 * i + 1] * v->cam.R[3 + j] + Q[3 * i + 2] * v->cam.R[6 + j];
            turned.t[i] = Q[3 * i] * v->cam.t[0] + Q[3 * i + 1] * v->cam.t[1] + Q[3 * i + 2] * v->cam.t[2];
        }
        pg_render_output out;
        CHECK_OK(render_model_frame(rm, &turned, 0.0f, &out));
        int covered = 0, total = 0;
        for (int y = 0; y < H; y++)
            for (int x = W * 4 / 5; x < W; x++, total++) covered += out.alpha[y * W + x] > 0.5f;
        CHECK(covered >= total * 9 / 10, "view turned past the real frame: %d of %d outside pixels covered", covered,
              total);
    }
    render_model_close(rm);
    train_set_destroy(&ts);
}

/* The preset's budget on a long clip: short clips keep it, a 120-frame clip gets 64 fits of each
 * frame in the fine stage, and no clip gets more than TRAIN_MAX_BUDGET_THIRDS / 3 times it. */
static void test_iterations_for_clip(void)
{
    CHECK(train_iterations_for_clip(1500, 30, 2, 320L * 180) == 1500, "30 frames keep 1500, got %d", train_iterations_for_clip(1500, 30, 2, 320L * 180));
    CHECK(train_iterations_for_clip(1500, 50, 2, 320L * 180) == 1500, "50 frames keep 1500");
    int it = train_iterations_for_clip(1500, 120, 2, 320L * 180);
    CHECK(it == 250 + 2560, "120 frames, 3 fits per step: 250 coarse + 2560 fine, got %d", it);
    CHECK((it - 250) * 3 >= 120 * TRAIN_FITS_PER_FRAME, "each frame fitted %d times", TRAIN_FITS_PER_FRAME);
    CHECK(train_iterations_for_clip(1500, 30, 0, 320L * 180) == 250 + 1920, "no crops: one fit per step");
    CHECK(train_iterations_for_clip(1500, 300, 2, 320L * 180) == 1500 * TRAIN_MAX_BUDGET_THIRDS / 3, "300 frames: the cap, got %d",
          train_iterations_for_clip(1500, 300, 2, 320L * 180));
    CHECK(train_iterations_for_clip(3000, 300, 2, 320L * 180) == 250 + 6400, "the quality preset's 3000 raised to fit 300 frames %d times each, got %d",
          TRAIN_FITS_PER_FRAME, train_iterations_for_clip(3000, 300, 2, 320L * 180));
    /* the coarse stage: a sixth of a short budget, never longer than the fast preset's */
    CHECK(train_default_coarse_iters(600) == 100 && train_default_coarse_iters(1500) == 250 &&
          train_default_coarse_iters(8000) == TRAIN_MAX_COARSE_ITERS, "coarse stage %d, %d, %d",
          train_default_coarse_iters(600), train_default_coarse_iters(1500), train_default_coarse_iters(8000));
    /* the raised budget fits longer; it does not densify longer (memory and checkpoint size) */
    train_budget b = train_budget_for_clip(1500, 300, 2, 320L * 180);
    CHECK(b.iters == 4000 && b.coarse_iters == 250 && b.densify_until == 1050,
          "300 frames: 4000 iterations, coarse 250, densify until 1050; got %d, %d, %d", b.iters, b.coarse_iters,
          b.densify_until);
    b = train_budget_for_clip(1500, 30, 2, 320L * 180);
    CHECK(b.iters == 1500 && b.densify_until == 1050, "30 frames: the preset's 1500, densify until 1050");
    /* the cap in compute: a smaller working size buys more steps, at most 3x the cap */
    int small = train_iterations_for_clip(1500, 300, 2, 160L * 120);
    CHECK(small == 250 + 6400, "300 frames at 160x120: 64 fits of each frame, got %d", small);
    CHECK(train_iterations_for_clip(1500, 10000, 2, 8L * 8) == 12000, "10,000 frames at 8x8: 3x the cap, got %d",
          train_iterations_for_clip(1500, 10000, 2, 8L * 8));
    CHECK(train_iterations_for_clip(1500, 300, 2, 640L * 360) == 4000, "a bigger size keeps the cap");
    CHECK(train_time_texels(10000, 11750 * 3) == TRAIN_MAX_TIME_TEXELS, "time rows capped at %d, got %d",
          TRAIN_MAX_TIME_TEXELS, train_time_texels(10000, 11750 * 3));
}

/* The network's rates: full for a short fine stage (heavy_train's toy), half for a preset's, and
 * never rising with the budget. */
static void test_net_lr_scale(void)
{
    CHECK(train_net_lr_scale(110) == 1.0f, "110 fine steps keep the full rates, got %g", train_net_lr_scale(110));
    CHECK(train_net_lr_scale(TRAIN_NET_LR_FULL_STEPS) == 1.0f, "the full rates up to %d steps", TRAIN_NET_LR_FULL_STEPS);
    CHECK(train_net_lr_scale(1250) == TRAIN_NET_LR_MIN_SCALE, "the fast preset's 1250 fine steps: %g, got %g",
          TRAIN_NET_LR_MIN_SCALE, train_net_lr_scale(1250));
    CHECK(train_net_lr_scale(100000) == TRAIN_NET_LR_MIN_SCALE, "the floor holds for long budgets");
    float last = 2.0f;
    for (int n = 0; n <= 4000; n += 50) {
        float k = train_net_lr_scale(n);
        CHECK(k <= last && k >= TRAIN_NET_LR_MIN_SCALE && k <= 1.0f, "%d fine steps: %g after %g", n, k, last);
        last = k;
    }
}

int main(void)
{
    test_depth_storage();
    test_iterations_for_clip();
    test_net_lr_scale();
    char dir[1024], data[1100], a[1200], b[1200], cmd[8192], err[4096];
    test_tmpdir("test_train", dir, sizeof dir);
    snprintf(data, sizeof data, "%s/set", dir);
    pg_set_threads(2);
    test_margin_past_frame(dir);
    test_load_errors(dir);
    CHECK_OK(toy_write_trainset(data, 64, 48, 4, 3, 1));

    train_set ts;
    CHECK_OK(train_set_load(data, &ts));
    CHECK(ts.num_views == 5 && ts.frames == 4 && ts.width == 64, "loaded %d views %d frames", ts.num_views, ts.frames);
    CHECK(train_set_count_role(&ts, IO_ROLE_PROXY) == 3, "proxies");
    CHECK(ts.views[1].mask && ts.views[1].mask[0] == 0 && ts.views[1].mask[63] == TRAIN_MASK_FULL, "proxy mask loaded");
    CHECK(ts.views[0].depth && train_view_depth(&ts.views[0], 64 * 24 + 32) > 3, "depth loaded");

    {
        train_set t2;
        CHECK_OK(train_set_load(data, &t2));
        train_set_limit_proxies(&t2, 2);
        CHECK(t2.num_views == 4 && train_set_count_role(&t2, IO_ROLE_PROXY) == 2 &&
                  strcmp(t2.views[1].name, "proxy01") == 0 && strcmp(t2.views[2].name, "proxy02") == 0,
              "limit proxies: %d views", t2.num_views);
        train_set_destroy(&t2);
    }

    /* one real camera: no view-dependent colour to learn (its proxies carry its colours); two: SH 3 */
    {
        CHECK(train_default_sh_degree(&ts) == 0, "one real view: SH degree %d, want 0", train_default_sh_degree(&ts));
        train_set t2;
        CHECK_OK(train_set_load(data, &t2));
        t2.views[1].role = IO_ROLE_REAL;
        CHECK(train_default_sh_degree(&t2) == 3, "two real views: SH degree %d, want 3", train_default_sh_degree(&t2));
        train_set_destroy(&t2);
    }

    /* depth flickering by +-20 % per frame (as monocular networks give) must not make every
     * Gaussian movable: movers are found from colour, so the still scene stays static */
    {
        train_set tf;
        CHECK_OK(train_set_load(data, &tf));
        size_t px = (size_t)tf.width * tf.height;
        float *d = malloc(px * (size_t)tf.frames * sizeof(float));
        for (int f = 0; d && f < tf.frames; f++)
            for (size_t i = 0; i < px; i++)
                d[(size_t)f * px + i] = train_view_depth(&tf.views[0], (size_t)f * px + i) * ((f % 2) ? 1.2f : 0.8f);
        if (d) train_view_set_depth(&tf.views[0], d, px * (size_t)tf.frames);
        free(d);
        train_config fc = small_config();
        train_session *sf = NULL;
        CHECK_OK(train_session_create(&sf, &tf, &fc, NULL, 0));
        if (sf) {
            int n = train_session_gaussians(sf), st = train_session_static_count(sf);
            CHECK(st >= n / 2 && st < n, "flickering depth: %d of %d Gaussians static (want >= half, not all)", st, n);
        }
        train_session_destroy(sf);
        train_set_destroy(&tf);
    }

    test_densify_movable(&ts);
    test_static_steps(&ts, 0);
    {
        train_set t2;
        CHECK_OK(train_set_load(data, &t2));
        t2.views[1].role = IO_ROLE_REAL;
        test_static_steps(&t2, 1);
        train_set_destroy(&t2);
    }
    test_half_size_proxies();

    /* uninterrupted run */
    train_config cfg = small_config();
    cfg.checkpoint_every = 20;
    snprintf(a, sizeof a, "%s/a.ckpt", dir);
    train_session *s = NULL;
    double psnr0 = 0, psnr1 = 0, test_psnr = 0;
    CHECK_OK(train_session_create(&s, &ts, &cfg, a, 0));
    if (s) {
        CHECK_OK(train_session_evaluate(s, IO_ROLE_REAL, &psnr0));
        CHECK_OK(train_session_run(s));
        CHECK_OK(train_session_evaluate(s, IO_ROLE_REAL, &psnr1));
        CHECK_OK(train_session_evaluate(s, IO_ROLE_TEST, &test_psnr));
        CHECK(psnr1 > psnr0 + 3, "training should help: real-view PSNR %.2f -> %.2f", psnr0, psnr1);
        fprintf(stderr, "toy: real PSNR %.2f -> %.2f, test %.2f, %d Gaussians\n", psnr0, psnr1, test_psnr,
                train_session_gaussians(s));
    }

    /* the checkpoint alone renders what the session renders */
    render_model *rm = NULL;
    CHECK_OK(render_model_open(a, &rm));
    if (rm && s) {
        pg_image truth = {0};
        pg_image_create(&truth, 64, 48, 3);
        train_set_frame_rgb(&ts, 0, 2, &truth);
        pg_render_output out;
        CHECK_OK(render_model_frame(rm, &ts.views[0].cam, 2.0f / 3.0f, &out));
        pg_image r = {64, 48, 3, out.rgb};
        double p = pg_image_psnr(&r, &truth, NULL);
        CHECK(p > psnr0 + 3, "render from checkpoint: PSNR %.2f (untrained %.2f)", p, psnr0);
        CHECK(render_model_frame(rm, &ts.views[0].cam, 1.5f, &out) == PG_ERR_ARG, "t outside [0,1] rejected");
        pg_image_destroy(&truth);
    }
    render_model_close(rm);
    train_session_destroy(s);

    /* killed at iteration 47 (last checkpoint at 40), then resumed: same bytes */
    snprintf(b, sizeof b, "%s/b.ckpt", dir);
    train_config c2 = small_config();
    c2.checkpoint_every = 20;
    c2.stop_at_iter = 47;
    s = NULL;
    CHECK_OK(train_session_create(&s, &ts, &c2, b, 0));
    if (s) CHECK_OK(train_session_run(s));
    CHECK(s && train_session_iteration(s) == 47, "stopped at 47");
    train_session_destroy(s);
    /* the periodic checkpoint carries the optimiser state, the final one only the model */
    long mid = file_bytes(b), fin = file_bytes(a);
    CHECK(mid > 0 && fin > 0 && fin * 2 < mid, "final checkpoint %ld bytes, periodic %ld (final should be < half)", fin, mid);
    c2.stop_at_iter = 0;
    s = NULL;
    CHECK_OK(train_session_create(&s, &ts, &c2, b, 1));
    CHECK(s && train_session_iteration(s) == 40, "resumed from the checkpoint at 40, got %d",
          s ? train_session_iteration(s) : -1);
    if (s) CHECK_OK(train_session_run(s));
    train_session_destroy(s);
    CHECK(test_files_equal(a, b), "resumed final checkpoint differs from the uninterrupted one");
    /* the time rows' warm-up: killed inside it (iteration 30, the switch is at 20 + 0.4 x 40 = 36), and
     * after it, resumed from the checkpoint at 20 (before the network exists): same bytes */
    for (int stop = 30; stop <= 39; stop += 9) {
        c2.stop_at_iter = stop;
        remove(b);
        s = NULL;
        CHECK_OK(train_session_create(&s, &ts, &c2, b, 0));
        if (s) CHECK_OK(train_session_run(s));
        int rows = 0, warm = 0;
        if (s) train_session_time_rows(s, &rows, &warm);
        CHECK(warm == 2 && rows == (stop < 36 ? 2 : 4), "stopped at %d: %d time rows (warm-up %d; want %d of 2 -> 4)", stop,
              rows, warm, stop < 36 ? 2 : 4);
        train_session_destroy(s);
    }
    c2.stop_at_iter = 0;
    s = NULL;
    CHECK_OK(train_session_create(&s, &ts, &c2, b, 1));
    CHECK(s && train_session_iteration(s) == 20, "resumed from the checkpoint at 20, got %d", s ? train_session_iteration(s) : -1);
    if (s) CHECK_OK(train_session_run(s));
    train_session_destroy(s);
    CHECK(test_files_equal(a, b), "resumed across the time refinement: final checkpoint differs from the uninterrupted one");
    /* a finished model continued with more iterations: Adam starts afresh, training goes on */
    c2.iters += 20;
    s = NULL;
    CHECK_OK(train_session_create(&s, &ts, &c2, b, 1));
    CHECK(s && train_session_iteration(s) == c2.iters - 20, "continued from the finished model at %d", c2.iters - 20);
    if (s) CHECK_OK(train_session_run(s));
    CHECK(s && train_session_iteration(s) == c2.iters, "continued to %d", c2.iters);
    train_session_destroy(s);

    /* SH degree 1: the checkpoint stores 12 of each Gaussian's 48 SH floats, and a resume from it
     * still gives the same bytes */
    {
        train_config tc = small_config();
        tc.sh_max_degree = 1;
        check_learns_and_resumes(&ts, tc, dir, "SH degree 1");
        /* smaller than the Gaussians alone would be with all 48 SH floats per row */
        char path[1200];
        snprintf(path, sizeof path, "%s/SH degree 1_a.ckpt", dir);
        train_model m;
        memset(&m, 0, sizeof m);
        CHECK_OK(train_model_load(path, &m));
        long full = (long)m.g.count * (3 + 3 + 4 + 1 + 48) * 4, bytes = file_bytes(path);
        CHECK(m.g.count > 0 && bytes > 0 && bytes < full, "SH degree 1: checkpoint %ld bytes for %d Gaussians, "
              "the rows alone at 48 SH floats would be %ld", bytes, m.g.count, full);
        train_model_destroy(&m);
    }

    /* two times per step (each its own deformation, one optimiser step): learns, and a resume
     * still gives the same bytes */
    {
        train_config tc = small_config();
        tc.times_per_step = 2;
        tc.views_per_step = 2;
        check_learns_and_resumes(&ts, tc, dir, "two times per step");
    }

    /* motion crops: every frame of the toy has a moving region smaller than the frame, training
     * with two crops per step learns, and a resume (crops draw from the checkpointed RNG) still
     * gives the same bytes */
    {
        train_config tc = small_config();
        tc.motion_crops = 2;
        s = NULL;
        CHECK_OK(train_session_create(&s, &ts, &tc, NULL, 0));
        if (s) {
            int crop_frames = 0, crop_proxies = 0;
            double crop_area = 0;
            train_session_motion_regions(s, &crop_frames, &crop_area, &crop_proxies);
            CHECK(crop_frames == ts.frames && crop_area > 0.02 && crop_area < 0.8,
                  "moving regions: %d of %d frames, mean area %.3f of the frame", crop_frames, ts.frames, crop_area);
            CHECK(crop_proxies == train_set_count_role(&ts, IO_ROLE_PROXY),
                  "proxies with a moving region: %d of %d (the toy's mover is in every proxy)", crop_proxies,
                  train_set_count_role(&ts, IO_ROLE_PROXY));
        }
        train_session_destroy(s);
        check_learns_and_resumes(&ts, tc, dir, "motion crops");
    }

    /* the parameters' average: the final model, and a resume from a checkpoint taken while
     * averaging (densification ends at 15, checkpoint at 20, killed at 33) gives the same bytes */
    test_parameter_average(&ts);
    {
        train_config tc = small_config();
        tc.coarse_iters = 10;
        tc.densify_until = 15;
        check_learns_and_resumes(&ts, tc, dir, "parameter average");
        /* the checkpoint at 20 (the one resumed from) carries the average: flags 3 */
        char path[1200];
        snprintf(path, sizeof path, "%s/average_mid.ckpt", dir);
        tc.checkpoint_every = 20;
        tc.stop_at_iter = 33;
        s = NULL;
        CHECK_OK(train_session_create(&s, &ts, &tc, path, 0));
        if (s) CHECK_OK(train_session_run(s));
        train_session_destroy(s);
        unsigned char head[16] = {0};
        FILE *f = fopen(path, "rb");
        size_t got = f ? fread(head, 1, sizeof head, f) : 0;
        if (f) fclose(f);
        CHECK(got == sizeof head && head[12] == 3, "periodic checkpoint while averaging: flags %d (want 3)", head[12]);
    }

    /* units: the same set in millimetres normalises to the same lengths, and the model trained
     * on it comes back in millimetres (it renders from the millimetre cameras as well as the
     * metre model renders from the metre cameras) */
    {
        train_set mm;
        CHECK_OK(train_set_load(data, &mm));
        size_t px = (size_t)mm.width * mm.height * mm.frames;
        for (int v = 0; v < mm.num_views; v++) {
            for (int k = 0; k < 3; k++) mm.views[v].cam.t[k] *= 1000.0f;
            mm.views[v].depth_scale *= 1000.0f; /* the same float16 values, in millimetres */
        }
        mm.radius *= 1000.0f;
        for (int k = 0; k < 3; k++) mm.center[k] *= 1000.0f;
        train_set m1;
        CHECK_OK(train_set_load(data, &m1));
        pg_camera user_cam = mm.views[0].cam;
        train_set_normalize_units(&mm);
        train_set_normalize_units(&m1);
        CHECK(fabsf(mm.unit / m1.unit - 1000.0f) < 0.01f, "unit %g vs %g: not 1000x", mm.unit, m1.unit);
        double worst = 0;
        for (int v = 0; v < mm.num_views; v++)
            for (int k = 0; k < 3; k++)
                worst = fmax(worst, fabs(mm.views[v].cam.t[k] - m1.views[v].cam.t[k]) / (fabs(m1.views[v].cam.t[k]) + 1e-3));
        for (size_t i = 0; i < px; i++)
            worst = fmax(worst, fabs(train_view_depth(&mm.views[0], i) - train_view_depth(&m1.views[0], i)) /
                                    (train_view_depth(&m1.views[0], i) + 1e-3));
        CHECK(worst < 1e-5, "normalised millimetre set differs from the metre one by %g (relative)", worst);
        pg_camera back = train_set_user_camera(&mm, 0);
        CHECK(fabsf(back.t[0] - user_cam.t[0]) <= 1e-3f * (fabsf(user_cam.t[0]) + 1.0f), "user camera %g vs %g",
              back.t[0], user_cam.t[0]);
        char c4[1200];
        snprintf(c4, sizeof c4, "%s/mm.ckpt", dir);
        train_config uc = small_config();
        s = NULL;
        CHECK_OK(train_session_create(&s, &mm, &uc, c4, 0));
        if (s) CHECK_OK(train_session_run(s));
        train_session_destroy(s);
        render_model *rmm = NULL;
        CHECK_OK(render_model_open(c4, &rmm));
        if (rmm) {
            pg_image truth = {0};
            pg_image_create(&truth, 64, 48, 3);
            train_set_frame_rgb(&mm, 0, 2, &truth);
            pg_render_output out;
            CHECK_OK(render_model_frame(rmm, &user_cam, 2.0f / 3.0f, &out));
            pg_image r = {64, 48, 3, out.rgb};
            double p = pg_image_psnr(&r, &truth, NULL);
            CHECK(p > psnr0 + 3, "millimetre model from millimetre cameras: PSNR %.2f (untrained %.2f)", p, psnr0);
            pg_image_destroy(&truth);
        }
        render_model_close(rmm);
        train_set_destroy(&mm);
        train_set_destroy(&m1);
    }

    /* corrupt checkpoints fail cleanly */
    char *blob = NULL;
    size_t n = 0;
    if (pg_read_file(a, 1u << 30, &blob, &n) == PG_OK) {
        char c[1200];
        snprintf(c, sizeof c, "%s/cut.ckpt", dir);
        pg_write_file_atomic(c, blob, n / 2);
        train_model m;
        CHECK(train_model_load(c, &m) == PG_ERR_FORMAT, "truncated checkpoint rejected");
        /* another format version (here the old ones) is refused, in one line naming the file */
        const char version = blob[8];
        blob[8] = 3; /* before the head width */
        pg_write_file_atomic(c, blob, n);
        CHECK(train_model_load(c, &m) == PG_ERR_FORMAT && strstr(pg_last_error(), "format version 3"),
              "version 3 checkpoint: %s", pg_last_error());
        blob[8] = 1;
        pg_write_file_atomic(c, blob, n);
        CHECK(train_model_load(c, &m) == PG_ERR_FORMAT && strstr(pg_last_error(), "cut.ckpt") &&
                  strstr(pg_last_error(), "version 1") && !strchr(pg_last_error(), '\n'),
              "version 1 checkpoint: %s", pg_last_error());
        train_session *sv = NULL;
        CHECK(train_session_create(&sv, &ts, &c2, c, 1) == PG_ERR_FORMAT && !sv && strstr(pg_last_error(), "cut.ckpt"),
              "resume from a version 1 checkpoint: %s", pg_last_error());
        blob[8] = version;
        /* every flipped bit is caught (the CRC), in one line naming the file */
        pg_rng fr;
        pg_rng_seed(&fr, 99);
        int accepted = 0;
        for (int k = 0; k < 200; k++) {
            size_t bit = (size_t)(pg_rng_uniform(&fr) * (double)(n * 8));
            blob[bit / 8] ^= (char)(1 << (bit % 8));
            pg_write_file_atomic(c, blob, n);
            if (train_model_load(c, &m) == PG_OK) {
                accepted++;
                train_model_destroy(&m);
            }
            blob[bit / 8] ^= (char)(1 << (bit % 8));
        }
        CHECK(accepted == 0, "%d of 200 bit-flipped checkpoints accepted", accepted);
        /* a crafted file with a valid CRC: iteration -1000000 in the header */
        char *crafted = malloc(n);
        if (crafted) {
            memcpy(crafted, blob, n);
            uint32_t tl;
            memcpy(&tl, crafted + 16, 4); /* magic, version, flags, text length */
            int32_t iter = -1000000;
            memcpy(crafted + 20 + tl, &iter, 4);
            uint32_t crc = (uint32_t)crc32(crc32(0L, Z_NULL, 0), (const unsigned char *)crafted, (uInt)(n - 4));
            memcpy(crafted + n - 4, &crc, 4);
            pg_write_file_atomic(c, crafted, n);
            CHECK(train_model_load(c, &m) == PG_ERR_FORMAT && strstr(pg_last_error(), "iteration -1000000"),
                  "negative iteration: %s", pg_last_error());
            /* densify_movable 0 (the unresolved rule) in the config text: every mover would densify */
            memcpy(crafted, blob, n);
            char *dm = memmem(crafted, n, "densify_movable=", 16);
            CHECK(dm && dm[16] >= '1' && dm[16] <= '9', "the config text holds a resolved densify_movable");
            if (dm) {
                dm[16] = '0';
                crc = (uint32_t)crc32(crc32(0L, Z_NULL, 0), (const unsigned char *)crafted, (uInt)(n - 4));
                memcpy(crafted + n - 4, &crc, 4);
                pg_write_file_atomic(c, crafted, n);
                CHECK(train_model_load(c, &m) == PG_ERR_FORMAT && strstr(pg_last_error(), "(densify_movable)"),
                      "densify_movable 0: %s", pg_last_error());
            }
            /* cut short anywhere with a valid CRC (fuzz_checkpoint found reads past the end when the
             * cut fell inside a section the loader skips) */
            for (int part = 1; part < 10; part++) {
                size_t cut = n * (size_t)part / 10;
                memcpy(crafted, blob, cut);
                crc = (uint32_t)crc32(crc32(0L, Z_NULL, 0), (const unsigned char *)crafted, (uInt)(cut - 4));
                memcpy(crafted + cut - 4, &crc, 4);
                pg_write_file_atomic(c, crafted, cut);
                CHECK(train_model_load(c, &m) == PG_ERR_FORMAT && strstr(pg_last_error(), "cut.ckpt"),
                      "checkpoint cut at %zu of %zu bytes: %s", cut, n, pg_last_error());
            }
            free(crafted);
        }
        /* resuming with other settings is refused, naming the setting */
        pg_write_file_atomic(c, blob, n);
        train_config c3 = c2;
        c3.lambda_dssim = 0.5f;
        train_session *sr = NULL;
        CHECK(train_session_create(&sr, &ts, &c3, c, 1) == PG_ERR_ARG && !sr && strstr(pg_last_error(), "lambda_dssim"),
              "resume with another lambda_dssim: %s", pg_last_error());
        c3 = c2;
        c3.deform_head_width = 16;
        CHECK(train_session_create(&sr, &ts, &c3, c, 1) == PG_ERR_ARG && !sr &&
                  strstr(pg_last_error(), "deform_head_width=16"),
              "resume with another head width: %s", pg_last_error());
        /* a temporary file of a killed checkpoint write is removed by the next run */
        char tmp[1300];
        snprintf(tmp, sizeof tmp, "%s.tmp.12345", c);
        pg_write_file_atomic(tmp, "x", 1);
        CHECK_OK(train_session_create(&sr, &ts, &c2, c, 1));
        train_session_destroy(sr);
        CHECK(!pg_path_exists(tmp), "stale %s left behind", tmp);
        blob[0] = 'X';
        pg_write_file_atomic(c, blob, n);
        CHECK(train_model_load(c, &m) == PG_ERR_FORMAT, "bad magic rejected");
        free(blob);
    }
    train_set_destroy(&ts);

    /* CLI: kill via PG_TEST_STOP_AT_ITER, resume, same bytes as one run (heads narrower than the
     * network: the head width goes through the checkpoint) */
    const char *opts = "--iters 24 --coarse-iters 8 --checkpoint-every 8 --init-points 1500 --threads 2 --seed 5 "
                       "--deform-res 8 --deform-width 32 --deform-head-width 16";
    snprintf(cmd, sizeof cmd, "train '%s' --out '%s/m1' %s", data, dir, opts);
    CHECK(test_run_cli(cmd, err, sizeof err) == 0, "train CLI: %s", err);
    setenv("PG_TEST_STOP_AT_ITER", "19", 1);
    snprintf(cmd, sizeof cmd, "train '%s' --out '%s/m2' %s", data, dir, opts);
    CHECK(test_run_cli(cmd, err, sizeof err) == 0, "train CLI stop: %s", err);
    unsetenv("PG_TEST_STOP_AT_ITER");
    snprintf(cmd, sizeof cmd, "train '%s' --out '%s/m2' %s --resume", data, dir, opts);
    CHECK(test_run_cli(cmd, err, sizeof err) == 0, "train CLI resume: %s", err);
    snprintf(a, sizeof a, "%s/m1/model.ckpt", dir);
    snprintf(b, sizeof b, "%s/m2/model.ckpt", dir);
    CHECK(test_files_equal(a, b), "CLI resume: final checkpoints differ");
    snprintf(cmd, sizeof cmd, "train '%s' --out '%s/m2' %s --deform-head-width 32 --resume", data, dir, opts);
    CHECK(test_run_cli(cmd, err, sizeof err) != 0 && strstr(err, "deform_head_width=16"),
          "CLI resume with another head width: %s", err);
    snprintf(a, sizeof a, "%s/m1/train.json", dir);
    CHECK(pg_path_exists(a), "train.json written");

    /* a full disk while the checkpoint streams out (writes capped at 100 kB, EFBIG): exit 3 naming
     * the checkpoint, and neither it nor its temporary is left */
    {
        struct rlimit old_lim, capped;
        getrlimit(RLIMIT_FSIZE, &old_lim);
        capped = old_lim;
        capped.rlim_cur = 100000;
        signal(SIGXFSZ, SIG_IGN);
        setrlimit(RLIMIT_FSIZE, &capped);
        snprintf(cmd, sizeof cmd, "train '%s' --out '%s/m3' %s", data, dir, opts);
        int rc = test_run_cli(cmd, err, sizeof err);
        setrlimit(RLIMIT_FSIZE, &old_lim);
        signal(SIGXFSZ, SIG_DFL);
        CHECK(rc == 3 && strstr(err, "model.ckpt") && strstr(err, "File too large"), "checkpoint on a full disk: exit %d, %s",
              rc, err);
        snprintf(a, sizeof a, "%s/m3/model.ckpt", dir);
        CHECK(!pg_path_exists(a), "a failed checkpoint write left %s", a);
        int temps = 0;
        snprintf(a, sizeof a, "%s/m3", dir);
        DIR *d = opendir(a);
        for (struct dirent *e; d && (e = readdir(d));) temps += strstr(e->d_name, ".tmp") != NULL;
        if (d) closedir(d);
        CHECK(temps == 0, "a failed checkpoint write left %d temporary files", temps);
    }

    /* bad input */
    CHECK(test_run_cli("train", err, sizeof err) == 2, "no args -> 2");
    snprintf(cmd, sizeof cmd, "train '%s/nothing' --out '%s/x'", dir, dir);
    CHECK(test_run_cli(cmd, err, sizeof err) == 2, "missing dir -> 2: %s", err);
    snprintf(cmd, sizeof cmd, "train '%s' --out '%s/x' --iters 0", data, dir);
    CHECK(test_run_cli(cmd, err, sizeof err) == 2, "bad iters -> 2");
    snprintf(a, sizeof a, "%s/bad/trainset.json", dir);
    snprintf(b, sizeof b, "%s/bad", dir);
    pg_mkdir_p(b);
    pg_write_file_atomic(a, "{\"frames\": 4", 12);
    snprintf(cmd, sizeof cmd, "train '%s/bad' --out '%s/x'", dir, dir);
    CHECK(test_run_cli(cmd, err, sizeof err) == 2 && strstr(err, "trainset.json"), "garbled json -> 2: %s", err);
    return test_summary("test_train");
}
