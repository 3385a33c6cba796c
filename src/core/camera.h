/* camera.h - pinhole camera in the OpenCV convention.
 *
 * x right, y down, z forward. x_cam = R * x_world + t. A point projects to the
 * continuous pixel coordinate (u, v) = (fx x/z + cx, fy y/z + cy); pixel (i, j)
 * covers [i, i+1) x [j, j+1), so its centre is (i + 0.5, j + 0.5).
 */
#ifndef PG_CAMERA_H
#define PG_CAMERA_H

typedef struct {
    int width, height;
    float fx, fy, cx, cy;
    float R[9]; /* world-to-camera rotation, row-major */
    float t[3]; /* world-to-camera translation */
} pg_camera;

/* Identity pose, principal point at the image centre, horizontal field of view in degrees. */
void pg_camera_from_fov(pg_camera *cam, int width, int height, float fov_x_deg);
/* Projects a world point; returns the camera-space depth z (<= 0 means behind). */
float pg_camera_project(const pg_camera *cam, const float Xw[3], float uv[2]);
/* World point at continuous pixel (u, v) with z-depth `depth`. */
void pg_camera_unproject(const pg_camera *cam, float u, float v, float depth, float Xw[3]);
void pg_camera_world_to_cam(const pg_camera *cam, const float Xw[3], float Xc[3]);
void pg_camera_cam_to_world(const pg_camera *cam, const float Xc[3], float Xw[3]);
/* Camera centre in world coordinates: -R^T t. */
void pg_camera_center(const pg_camera *cam, float C[3]);
/* Sets the pose so the camera sits at eye, looks at target, with image "up" (-y) closest to up. */
void pg_camera_look_at(pg_camera *cam, const float eye[3], const float target[3], const float up[3]);
/* Scales intrinsics for an image resized to width x height. */
void pg_camera_resize(pg_camera *cam, int width, int height);

#endif
