/* procedural.c - analytic ray-cast RGB-D scene (see procedural.h). */
#include "proxy/procedural.h"

#include <float.h>
#include <stddef.h>
#include <math.h>

#include "core/mathx.h"

/* Smooth but detailed colour patterns (features of a few pixels at 320x240). */
static void wall_color(float x, float y, float c[3])
{
    float a = sinf(9.0f * x) * cosf(7.0f * y), b = sinf(23.0f * x + 11.0f * y), s = cosf(17.0f * y - 5.0f * x);
    c[0] = 0.55f + 0.25f * a + 0.1f * b;
    c[1] = 0.45f + 0.2f * s + 0.1f * a;
    c[2] = 0.40f + 0.2f * b * s;
}

static void card_color(float x, float y, float c[3])
{
    int check = ((int)floorf(x * 8.0f) + (int)floorf(y * 8.0f)) & 1;
    float r = sinf(31.0f * x) * sinf(29.0f * y);
    c[0] = check ? 0.85f : 0.2f + 0.1f * r;
    c[1] = 0.3f + 0.2f * r;
    c[2] = check ? 0.25f : 0.75f;
}

/* Intersects the world ray o + s d with the scene; returns the ray parameter (FLT_MAX: miss). */
static float trace(const float o[3], const float d[3], float time, float c[3])
{
    float best = FLT_MAX;
    /* back wall z = 4 */
    if (fabsf(d[2]) > 1e-9f) {
        float s = (4.0f - o[2]) / d[2];
        if (s > 0 && s < best) {
            best = s;
            wall_color(o[0] + s * d[0], o[1] + s * d[1], c);
        }
    }
    /* slanted card z = 2.5 - 0.3 x  <=>  0.3 x + z = 2.5 */
    float den = 0.3f * d[0] + d[2];
    if (fabsf(den) > 1e-9f) {
        float s = (2.5f - 0.3f * o[0] - o[2]) / den;
        float x = o[0] + s * d[0], y = o[1] + s * d[1];
        if (s > 0 && s < best && fabsf(x) <= 0.6f && fabsf(y) <= 0.45f) {
            best = s;
            card_color(x, y, c);
        }
    }
    /* small moving card z = 2 */
    if (fabsf(d[2]) > 1e-9f) {
        float s = (2.0f - o[2]) / d[2];
        float cx = -0.55f + 0.3f * time, cy = 0.3f;
        float x = o[0] + s * d[0], y = o[1] + s * d[1];
        if (s > 0 && s < best && fabsf(x - cx) <= 0.15f && fabsf(y - cy) <= 0.12f) {
            best = s;
            c[0] = 0.9f * (0.5f + 0.5f * sinf(40.0f * (x - cx)));
            c[1] = 0.8f;
            c[2] = 0.1f + 0.3f * (y > cy);
        }
    }
    return best;
}

void proxy_procedural_render(const pg_camera *cam, float time, int ss, float *rgb, float *depth)
{
    int W = cam->width, H = cam->height;
    if (ss < 1) ss = 1;
    float o[3];
    pg_camera_center(cam, o);
    for (int v = 0; v < H; v++) {
        for (int u = 0; u < W; u++) {
            float acc[3] = { 0, 0, 0 };
            for (int sy = 0; sy < ss; sy++) {
                for (int sx = 0; sx < ss; sx++) {
                    float pu = u + (sx + 0.5f) / ss, pv = v + (sy + 0.5f) / ss;
                    float X[3], d[3], c[3] = { 0, 0, 0 };
                    pg_camera_unproject(cam, pu, pv, 1.0f, X);
                    vec3_sub(d, X, o);
                    trace(o, d, time, c);
                    vec3_add(acc, acc, c);
                }
            }
            if (rgb)
                for (int k = 0; k < 3; k++) rgb[((size_t)v * W + u) * 3 + k] = clampf(acc[k] / (ss * ss), 0, 1);
            if (depth) {
                /* d has unit z in camera space, so the ray parameter is the z-depth. */
                float X[3], d[3], c[3];
                pg_camera_unproject(cam, u + 0.5f, v + 0.5f, 1.0f, X);
                vec3_sub(d, X, o);
                float s = trace(o, d, time, c);
                depth[(size_t)v * W + u] = s == FLT_MAX ? 0 : s;
            }
        }
    }
}
