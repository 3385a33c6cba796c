/* test_render_path.c - camera paths keep looking at the centre, keep the distance, swing as asked. */
#include "testlib.h"
#include "core/mathx.h"
#include "render/render_path.h"

#include <math.h>

int main(void)
{
    pg_camera real;
    pg_camera_from_fov(&real, 160, 120, 60);
    float center[3] = { 0.2f, -0.1f, 3.0f };
    render_path_kind kinds[3] = { RENDER_PATH_FIXED, RENDER_PATH_ORBIT, RENDER_PATH_SPIRAL };
    for (int k = 0; k < 3; k++) {
        render_path_options opt = { kinds[k], 24, 15.0f, 0.5f, 10.0f, 3.0f };
        float worst_center = 0, worst_dist = 0, max_angle = 0;
        float eye0[3], r0[3];
        pg_camera_center(&real, eye0);
        vec3_sub(r0, eye0, center);
        float dist0 = vec3_norm(r0);
        for (int i = 0; i < opt.steps; i++) {
            pg_camera cam;
            float t, uv[2];
            render_path_camera(&opt, &real, center, i, &cam, &t);
            float z = pg_camera_project(&cam, center, uv);
            worst_center = fmaxf(worst_center, fabsf(uv[0] - real.cx) + fabsf(uv[1] - real.cy));
            CHECK(z > 0 && t >= 0 && t <= 1, "path %d step %d: z=%g t=%g", k, i, z, t);
            float eye[3], r[3];
            pg_camera_center(&cam, eye);
            vec3_sub(r, eye, center);
            worst_dist = fmaxf(worst_dist, fabsf(vec3_norm(r) - dist0));
            float c = vec3_dot(r, r0) / (vec3_norm(r) * dist0);
            max_angle = fmaxf(max_angle, acosf(fminf(1.0f, c)) * 180.0f / (float)PG_PI);
            if (kinds[k] == RENDER_PATH_ORBIT) CHECK(fabsf(t - 0.5f) < 1e-6f, "orbit must freeze time, t=%g", t);
        }
        CHECK(worst_center < 1e-2f, "path %d: centre drifts %g px off the principal point", k, worst_center);
        CHECK(worst_dist < 1e-4f * dist0, "path %d: distance to centre changes by %g", k, worst_dist);
        CHECK(max_angle > 5.0f && max_angle < 16.5f, "path %d: swing of %g deg", k, max_angle);
    }
    render_path_kind kind;
    CHECK(render_path_parse("spiral", &kind) == PG_OK && kind == RENDER_PATH_SPIRAL, "parse spiral");
    CHECK(render_path_parse("zigzag", &kind) == PG_ERR_ARG, "bad path name accepted");
    return test_summary("test_render_path");
}
