/* render_path.c - camera paths around the real camera (see render_path.h). */
#include "render/render_path.h"
#include "core/mathx.h"

#include <string.h>

static const char *path_names[RENDER_PATH_COUNT] = { "fixed", "orbit", "spiral" };
_Static_assert(RENDER_PATH_COUNT == 3, "update path_names when adding a path");

pg_status render_path_parse(const char *name, render_path_kind *kind)
{
    for (int k = 0; k < RENDER_PATH_COUNT; k++)
        if (strcmp(name, path_names[k]) == 0) {
            *kind = (render_path_kind)k;
            return PG_OK;
        }
    return pg_fail(PG_ERR_ARG, "unknown camera path '%s' (fixed, orbit, spiral, dataset-cam NAME)", name);
}


/* Rotates the real camera's centre about `center` by yaw (around the camera's up axis) and
 * pitch (around its right axis), then looks back at the centre with the same up vector. */
static void swing_camera(const pg_camera *real, const float center[3], float yaw, float pitch, pg_camera *cam)
{
    float eye[3], offset[3], right[3], down[3], rot[9], tmp[3];
    pg_camera_center(real, eye);
    vec3_sub(offset, eye, center);
    for (int j = 0; j < 3; j++) {
        right[j] = real->R[j];
        down[j] = real->R[3 + j];
    }
    mat3_axis_angle(rot, down, yaw);
    mat3_mul_vec(tmp, rot, offset);
    mat3_axis_angle(rot, right, pitch);
    mat3_mul_vec(offset, rot, tmp);
    vec3_add(eye, center, offset);
    float up[3] = { -down[0], -down[1], -down[2] };
    *cam = *real;
    pg_camera_look_at(cam, eye, center, up);
}

void render_path_camera(const render_path_options *opt, const pg_camera *real, const float center[3], int i,
                        pg_camera *cam, float *time)
{
    const float deg = (float)PG_PI / 180.0f;
    int n = opt->steps > 1 ? opt->steps : 1;
    float s = n > 1 ? (float)i / (n - 1) : 0.0f;
    switch (opt->kind) {
    case RENDER_PATH_FIXED:
        swing_camera(real, center, opt->fixed_yaw_deg * deg, opt->fixed_pitch_deg * deg, cam);
        *time = s;
        break;
    case RENDER_PATH_ORBIT: {
        /* out to +max, across to -max and back: a smooth swing that starts at the real view */
        float yaw = sinf(2.0f * (float)PG_PI * (float)i / n) * opt->max_angle_deg * deg;
        swing_camera(real, center, yaw, 0.0f, cam);
        *time = opt->time;
        break;
    }
    case RENDER_PATH_SPIRAL: {
        float phase = 2.0f * (float)PG_PI * 2.0f * s; /* two turns over the video */
        float radius = opt->max_angle_deg * deg * (0.5f + 0.5f * s);
        swing_camera(real, center, radius * cosf(phase), radius * sinf(phase) * 0.5f, cam);
        *time = s;
        break;
    }
    default:
        *cam = *real;
        *time = s;
    }
}
