/* test_depth_flow.c - TV-L1 flow accuracy on textured images with known synthetic warps
 * (translation, rotation, smooth field), forward-backward consistency, determinism, speed. */
#include "testlib.h"
#include "core/image.h"
#include "core/parallel.h"
#include "core/rng.h"
#include "depth/flow.h"
#include "depth/plane.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define W 320
#define H 240
#define NWAVES 48

typedef struct { float kx, ky, ph, amp; int ch; } wave;
static wave waves[NWAVES];

static void texture_init(void)
{
    pg_rng rng;
    pg_rng_seed(&rng, 11);
    for (int i = 0; i < NWAVES; i++) {
        float lambda = (float)pg_rng_range(&rng, 5.0, 60.0), ang = (float)pg_rng_range(&rng, 0.0, 2 * M_PI);
        waves[i].kx = 2 * (float)M_PI / lambda * cosf(ang);
        waves[i].ky = 2 * (float)M_PI / lambda * sinf(ang);
        waves[i].ph = (float)pg_rng_range(&rng, 0.0, 2 * M_PI);
        waves[i].amp = (float)pg_rng_range(&rng, 0.3, 1.0);
        waves[i].ch = i % 3;
    }
}

/* Smooth colour texture at continuous pixel coordinates. */
static void texture(float x, float y, float *rgb)
{
    float acc[3] = { 0, 0, 0 };
    for (int i = 0; i < NWAVES; i++) acc[waves[i].ch] += waves[i].amp * sinf(waves[i].kx * x + waves[i].ky * y + waves[i].ph);
    for (int c = 0; c < 3; c++) rgb[c] = 0.5f + 0.5f * tanhf(acc[c] / 3.0f);
}

typedef enum { WARP_TRANSLATE, WARP_ROTATE, WARP_SMOOTH } warp_kind;

/* Displacement d(x) of the motion m(x) = x + d(x) mapping frame-0 points into frame 1. */
static void warp_disp(warp_kind k, float x, float y, float *dx, float *dy)
{
    if (k == WARP_TRANSLATE) {
        *dx = 3.4f;
        *dy = -2.3f;
    } else if (k == WARP_ROTATE) {
        float a = 4.0f * (float)M_PI / 180.0f, cx = W / 2.0f, cy = H / 2.0f;
        float rx = x - cx, ry = y - cy;
        *dx = cosf(a) * rx - sinf(a) * ry + cx - x;
        *dy = sinf(a) * rx + cosf(a) * ry + cy - y;
    } else {
        *dx = 2.5f * sinf(2 * (float)M_PI * x / 200.0f) * cosf(2 * (float)M_PI * y / 170.0f) + 0.8f;
        *dy = 2.0f * cosf(2 * (float)M_PI * x / 150.0f + 0.7f) * sinf(2 * (float)M_PI * y / 230.0f);
    }
}

/* img0 = texture; img1(z) = texture(m^-1(z)) with the inverse found by fixed-point iteration. */
static void make_pair(warp_kind k, pg_image *i0, pg_image *i1, float *truth, float *mask)
{
    for (int y = 0; y < H; y++) {
        for (int x = 0; x < W; x++) {
            size_t id = (size_t)y * W + x;
            texture((float)x, (float)y, i0->data + 3 * id);
            float dx, dy;
            warp_disp(k, (float)x, (float)y, &dx, &dy);
            truth[2 * id] = dx;
            truth[2 * id + 1] = dy;
            float tx = x + dx, ty = y + dy;
            mask[id] = (tx >= 4 && ty >= 4 && tx <= W - 5 && ty <= H - 5 && x >= 4 && y >= 4 && x <= W - 5 && y <= H - 5) ? 1.0f : 0.0f;
            float px = (float)x, py = (float)y;
            for (int it = 0; it < 30; it++) {
                warp_disp(k, px, py, &dx, &dy);
                px = x - dx;
                py = y - dy;
            }
            texture(px, py, i1->data + 3 * id);
        }
    }
}

int main(void)
{
    pg_set_threads(2);
    texture_init();
    pg_image i0, i1;
    CHECK_OK(pg_image_create(&i0, W, H, 3));
    CHECK_OK(pg_image_create(&i1, W, H, 3));
    float *truth = malloc(sizeof(float) * W * H * 2), *mask = malloc(sizeof(float) * W * H);
    float *flow = malloc(sizeof(float) * W * H * 2), *back = malloc(sizeof(float) * W * H * 2);
    float *conf = malloc(sizeof(float) * W * H);
    depth_flow_backend be = depth_flow_backend_default();
    const char *names[3] = { "translation", "rotation", "smooth field" };
    double slowest = 0.0;
    for (int k = 0; k < 3; k++) {
        make_pair((warp_kind)k, &i0, &i1, truth, mask);
        double t0 = pg_time_seconds();
        CHECK_OK(depth_flow_compute(&be, &i0, &i1, flow));
        double dt = pg_time_seconds() - t0;
        if (dt > slowest) slowest = dt;
        double epe = depth_flow_epe(flow, truth, W, H, mask);
        printf("flow %-12s EPE %.3f px  (%.3f s)\n", names[k], epe, dt);
        CHECK(epe <= 0.3, "%s: EPE %.3f px > 0.3", names[k], epe);
        if (k == 1) {
            /* Forward-backward: consistent inside, low confidence where the flow leaves the image. */
            CHECK_OK(depth_flow_compute(&be, &i1, &i0, back));
            depth_flow_consistency(flow, back, W, H, conf);
            double cin = 0;
            size_t nin = 0;
            for (size_t id = 0; id < (size_t)W * H; id++)
                if (mask[id] > 0.5f) { cin += conf[id]; nin++; }
            cin /= nin;
            printf("flow fb-consistency: mean confidence inside %.3f\n", cin);
            CHECK(cin > 0.9, "mean forward-backward confidence %.3f", cin);
            /* Corrupt the backward flow in a block: confidence there must drop. */
            for (int y = 100; y < 140; y++)
                for (int x = 140; x < 180; x++) back[2 * ((size_t)y * W + x)] += 5.0f;
            depth_flow_consistency(flow, back, W, H, conf);
            CHECK(conf[(size_t)120 * W + 160 - 2] < 0.1f || conf[(size_t)120 * W + 160 + 2] < 0.1f,
                  "corrupted block not flagged (%.3f)", conf[(size_t)120 * W + 160]);
        }
    }
    printf("flow slowest pair %.3f s at %dx%d\n", slowest, W, H);

    /* Zero motion gives (near) zero flow; identical inputs twice give identical bytes. */
    CHECK_OK(depth_flow_compute(&be, &i0, &i0, flow));
    double maxf = 0;
    for (size_t id = 0; id < (size_t)W * H * 2; id++) maxf = fmax(maxf, fabs(flow[id]));
    CHECK(maxf < 0.05, "identical frames gave flow up to %.3f", maxf);
    CHECK_OK(depth_flow_compute(&be, &i0, &i1, flow));
    CHECK_OK(depth_flow_compute(&be, &i0, &i1, back));
    CHECK(memcmp(flow, back, sizeof(float) * W * H * 2) == 0, "flow not deterministic");

    /* The median-of-9 network equals the sorting reference (also with ties). */
    {
        pg_rng rng;
        pg_rng_seed(&rng, 3);
        const int mw = 37, mh = 23;
        float a[37 * 23], m1[37 * 23], m2[37 * 23];
        for (int k = 0; k < mw * mh; k++) a[k] = (float)pg_rng_below(&rng, 6) + (k % 5 == 0 ? 0.5f : 0.0f);
        depth_plane_median3(a, mw, mh, m1);
        depth_plane_median3_ref(a, mw, mh, m2);
        CHECK(memcmp(m1, m2, sizeof m1) == 0, "median network differs from the sorting reference");
    }

    /* Size mismatch is an error, not a crash. */
    pg_image small;
    CHECK_OK(pg_image_create(&small, 100, 80, 3));
    CHECK(depth_flow_compute(&be, &i0, &small, flow) == PG_ERR_SIZE, "size mismatch accepted");
    pg_image_destroy(&small);

    pg_image out;
    CHECK_OK(pg_image_create(&out, W, H, 3));
    depth_flow_to_color(truth, W, H, 0, &out);
    CHECK(out.data[0] >= 0 && out.data[0] <= 1, "colour out of range");
    pg_image_destroy(&out);
    pg_image_destroy(&i0);
    pg_image_destroy(&i1);
    free(truth); free(mask); free(flow); free(back); free(conf);
    return test_summary("test_depth_flow");
}
