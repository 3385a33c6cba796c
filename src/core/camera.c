/* camera.c - pinhole projection helpers (OpenCV convention). */
#include "core/camera.h"
#include "core/mathx.h"

void pg_camera_from_fov(pg_camera *cam, int width, int height, float fov_x_deg)
{
    cam->width = width;
    cam->height = height;
    cam->fx = cam->fy = 0.5f * width / tanf(0.5f * fov_x_deg * (float)PG_PI / 180.0f);
    cam->cx = 0.5f * width;
    cam->cy = 0.5f * height;
    mat3_identity(cam->R);
    cam->t[0] = cam->t[1] = cam->t[2] = 0;
}

void pg_camera_world_to_cam(const pg_camera *cam, const float Xw[3], float Xc[3])
{
    mat3_mul_vec(Xc, cam->R, Xw);
    vec3_add(Xc, Xc, cam->t);
}

void pg_camera_cam_to_world(const pg_camera *cam, const float Xc[3], float Xw[3])
{
    float d[3];
    vec3_sub(d, Xc, cam->t);
    mat3_tmul_vec(Xw, cam->R, d);
}

float pg_camera_project(const pg_camera *cam, const float Xw[3], float uv[2])
{
    float Xc[3];
    pg_camera_world_to_cam(cam, Xw, Xc);
    float z = Xc[2];
    float iz = (z != 0) ? 1.0f / z : 0.0f;
    uv[0] = cam->fx * Xc[0] * iz + cam->cx;
    uv[1] = cam->fy * Xc[1] * iz + cam->cy;
    return z;
}

void pg_camera_unproject(const pg_camera *cam, float u, float v, float depth, float Xw[3])
{
    float Xc[3] = { (u - cam->cx) / cam->fx * depth, (v - cam->cy) / cam->fy * depth, depth };
    pg_camera_cam_to_world(cam, Xc, Xw);
}

void pg_camera_center(const pg_camera *cam, float C[3])
{
    float mt[3] = { -cam->t[0], -cam->t[1], -cam->t[2] };
    mat3_tmul_vec(C, cam->R, mt);
}

void pg_camera_look_at(pg_camera *cam, const float eye[3], const float target[3], const float up[3])
{
    float z[3], x[3], y[3], down[3] = { -up[0], -up[1], -up[2] };
    vec3_sub(z, target, eye);
    vec3_normalize(z);
    vec3_cross(x, down, z); /* y (down) x z (forward) = x (right) */
    vec3_normalize(x);
    vec3_cross(y, z, x);
    for (int j = 0; j < 3; j++) {
        cam->R[0 + j] = x[j];
        cam->R[3 + j] = y[j];
        cam->R[6 + j] = z[j];
    }
    float Re[3];
    mat3_mul_vec(Re, cam->R, eye);
    cam->t[0] = -Re[0]; cam->t[1] = -Re[1]; cam->t[2] = -Re[2];
}

void pg_camera_resize(pg_camera *cam, int width, int height)
{
    float sx = (float)width / cam->width, sy = (float)height / cam->height;
    cam->fx *= sx; cam->cx *= sx;
    cam->fy *= sy; cam->cy *= sy;
    cam->width = width;
    cam->height = height;
}
