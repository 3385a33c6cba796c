/* synth.h - the built-in sample scene: a small ray-traced dynamic tabletop.
 *
 * A procedural scene (textured table and brick wall, static boxes / spheres / cylinders, three
 * rigidly moving objects) rendered by ray tracing with Lambert + ambient shading, hard shadows
 * from one directional light and regular n x n supersampling. It gives exact ground truth for
 * the tests and the demo: colour, z-depth, moving-object masks, camera poses, visibility.
 *
 * Frames. The scene is modelled in a "scene frame" (x right, y away from the viewer, z up,
 * table top at z = 0). The WORLD frame used by every public function is cam00's camera frame
 * (OpenCV: x right, y down, z forward; cam00 has R = I, t = 0), so a cam00 depth map
 * unprojected with an identity camera gives world points directly.
 * Time: normalised s in [0, 1] over the sequence; frame f of F is s = f / (F - 1) (s = 0 if F = 1).
 *
 *   synth_scene sc;
 *   synth_scene_default(&sc, 1);
 *   pg_camera cam;
 *   synth_camera(&sc, 0, 160, 120, &cam);
 *   pg_image rgb = {0};
 *   float *depth = malloc(160 * 120 * sizeof(float));          // (H, W) z-depth, 0 = no hit
 *   synth_render_frame(&sc, &cam, 0.5f, &rgb, depth, NULL);
 *
 *   synth_options o; synth_options_default(&o);
 *   synth_write_dataset("out/synth", &o);                       // DyNeRF layout on disk
 */
#ifndef PG_SYNTH_H
#define PG_SYNTH_H

#include <stdint.h>

#include "core/camera.h"
#include "core/image.h"
#include "core/status.h"

#define SYNTH_MAX_OBJECTS 16
#define SYNTH_MAX_CAMS 21

typedef enum { SYNTH_SHAPE_PLANE, SYNTH_SHAPE_BOX, SYNTH_SHAPE_SPHERE, SYNTH_SHAPE_CYLINDER, SYNTH_SHAPE_COUNT } synth_shape;

typedef enum {
    SYNTH_TEX_WOOD,     /* wooden tiles with grain (table) */
    SYNTH_TEX_BRICK,    /* bricks and mortar (wall) */
    SYNTH_TEX_CHECKER,  /* 3D checker */
    SYNTH_TEX_STRIPES,  /* bands along a local axis */
    SYNTH_TEX_MARBLE,   /* noise-warped bands */
    SYNTH_TEX_SEGMENTS, /* beach-ball sectors around the local z axis (shows rotation) */
    SYNTH_TEX_COUNT
} synth_texture;

/* One rigid object. Local frame: box centred (half extents size[0..2]); sphere centred
 * (radius size[0]); cylinder along local z (radius size[0], half height size[1]); plane z = 0
 * with normal +z (infinite). Pose at time s (scene frame):
 *   position(s) = p0 + (p1 - p0) s + (0, 0, hop_height |sin(pi hop_count s)|)
 *   rotation(s) = Rot(axis, angle0 + (angle1 - angle0) s) * Rot(z, yaw)        (radians)
 * Static objects have p1 = p0, angle1 = angle0, hop_height = 0. */
typedef struct {
    char name[32];
    synth_shape shape;
    synth_texture texture;
    int dynamic;
    float size[3];
    float color_a[3], color_b[3]; /* texture colours, linear RGB */
    float tex_scale;              /* texture period in scene units */
    float tex_offset[3];          /* noise phase (seeded) */
    float p0[3], p1[3];
    float hop_height, hop_count;
    float axis[3];
    float angle0, angle1, yaw;
} synth_object;

typedef struct {
    uint64_t seed;
    int num_objects;
    synth_object objects[SYNTH_MAX_OBJECTS];
    float light_dir[3];       /* unit vector towards the light, scene frame */
    float ambient, diffuse;   /* shading = albedo (ambient + diffuse max(0, n.l) shadow) */
    int shadows;              /* 1: hard shadows */
    int spp;                  /* supersampling: spp x spp samples per pixel */
    float background[3];      /* colour of rays that hit nothing */
    /* camera rig (scene frame): cameras on a sphere of radius `radius` around `target`,
     * cam i at azimuth az[i], elevation elevation_deg + el[i] (degrees), horizontal FOV fov_x_deg */
    float target[3], radius, elevation_deg, fov_x_deg;
    float cam_az[SYNTH_MAX_CAMS], cam_el[SYNTH_MAX_CAMS];
    /* world (= cam00 frame) from scene frame: X_world = world_R X_scene + world_t */
    float world_R[9], world_t[3];
} synth_scene;

/* Fills the default tabletop; the seed jitters positions, colours and texture phases a little
 * (the layout stays the same). Can't fail. */
void synth_scene_default(synth_scene *scene, uint64_t seed);
/* Camera `index` (0 .. SYNTH_MAX_CAMS-1) of the rig at width x height, world frame (cam00 = identity). */
pg_status synth_camera(const synth_scene *scene, int index, int width, int height, pg_camera *cam);
/* Ray traces one frame at normalised time s. rgb: if rgb->data is NULL it is created (H, W, 3),
 * else it must already be cam->width x cam->height x 3. depth (H, W) z-depth of the pixel-centre
 * ray (0 where nothing is hit) and dynamic_mask (H, W) (1 where the pixel-centre ray hits a
 * moving object) may be NULL. OpenMP over rows; deterministic. */
pg_status synth_render_frame(const synth_scene *scene, const pg_camera *cam, float s, pg_image *rgb,
                             float *depth, unsigned char *dynamic_mask);
/* Traces the ray through continuous pixel (u, v) at time s; returns its z-depth (0 if nothing
 * is hit) and the index of the hit object in *object (-1 if none; object may be NULL). */
float synth_trace_depth(const synth_scene *scene, const pg_camera *cam, float u, float v, float s, int *object);
/* 1 if world point Xw lies on (within tol of the surface of) or inside a moving object at time s. */
int synth_point_is_dynamic(const synth_scene *scene, const float Xw[3], float s, float tol);
/* 1 if world point Xw (a surface point) is seen by cam at time s: it projects inside the image,
 * lies in front, and nothing is hit before it along the ray (relative tolerance rel_tol on the
 * distance, e.g. 1e-3). */
int synth_point_visible(const synth_scene *scene, const pg_camera *cam, const float Xw[3], float s, float rel_tol);
/* Ground-truth co-visibility: mask (H, W) of cam is 1 where the pixel-centre ray of cam hits a
 * surface point that ref also sees at time s (inside ref's image, unoccluded; rel_tol as above).
 * With ref = cam00 this is the region a proxy view warped from cam00 can get right. */
pg_status synth_render_covisibility(const synth_scene *scene, const pg_camera *cam, const pg_camera *ref, float s,
                                    float rel_tol, unsigned char *mask);
/* Ground-truth optical flow of cam from time s0 to s1: flow (H, W, 2) = where the surface point
 * under each pixel centre at s0 projects at s1, minus the pixel centre (0 on static surfaces).
 * valid (H, W) (may be NULL): 1 where that point is inside the image and unoccluded at s1. */
pg_status synth_render_flow(const synth_scene *scene, const pg_camera *cam, float s0, float s1, float *flow,
                            unsigned char *valid);
/* Pose of object k at time s in the WORLD frame: X_world = R X_local + p. */
void synth_object_pose(const synth_scene *scene, int k, float s, float R[9], float p[3]);
/* Scene frame <-> world frame. */
void synth_scene_to_world(const synth_scene *scene, const float Xs[3], float Xw[3]);
void synth_world_to_scene(const synth_scene *scene, const float Xw[3], float Xs[3]);
/* Normalised time of frame f out of F. */
static inline float synth_frame_time(int f, int F) { return F > 1 ? (float)f / (float)(F - 1) : 0.0f; }

/* ---- simulated monocular depth ---- */

/* What synth_depth_mono did, so tests can check alignment: per frame
 * mono ~= frame_scale[f] * lowfreq(x, y, f) * blur(gt) + shift, times (1 + noise). */
typedef struct {
    float global_scale;   /* ~1.25 */
    float shift;          /* additive, in mono units */
    float drift_amplitude, drift_noise; /* sinusoid amplitude and per-frame noise (relative) */
    float blur_sigma_px, lowfreq_amplitude, pixel_noise;
    float *frame_scale;   /* (F) global_scale * (1 + drift_f); owned, free with synth_mono_info_destroy */
    int frames;
} synth_mono_info;

/* Simulates a monocular estimate of gt (F, H, W) z-depth into mono (F, H, W); pixels with
 * gt <= 0 stay 0. Deterministic for the seed. Fills info (may be NULL). */
pg_status synth_depth_mono(const float *gt, int F, int H, int W, uint64_t seed, float *mono, synth_mono_info *info);
void synth_mono_info_destroy(synth_mono_info *info);

/* ---- dataset writer ---- */

typedef enum { SYNTH_LAYOUT_DYNERF, SYNTH_LAYOUT_PANOPTIC, SYNTH_LAYOUT_COUNT } synth_layout;

typedef struct {
    int cams;          /* 1 .. SYNTH_MAX_CAMS (default 10) */
    int frames;        /* default 30 */
    int width, height; /* default 160 x 120 */
    uint64_t seed;     /* default 1 */
    int spp;           /* supersampling side (default 2 -> 2x2) */
    float fps;         /* default 30 */
    synth_layout layout;
    int video;         /* DyNeRF: also write camXX.mp4 (needs the io video writer) */
    int all_depth;     /* ground truth for every camera (default 1), else cam00 only */
} synth_options;

void synth_options_default(synth_options *o);
/* Renders and writes the dataset into out_dir (created). DyNeRF layout:
 *   poses_bounds.npy (N, 17)                 LLFF c2w [down right back | centre | hwf], near, far
 *   camXX/images/0000.png                    8-bit RGB (camXX.mp4 too with `video`)
 *   depth_gt/camXX.npy     float32 (F, H, W) z-depth, 0 = no hit
 *   masks_dynamic/camXX.npy  uint8 (F, H, W) 1 = moving object
 *   covis_cam00/camXX.npy    uint8 (F, H, W) XX >= 1: 1 = point also seen by cam00
 *   depth_mono/cam00.npy   float32 (F, H, W) simulated monocular depth of cam00
 *   scene.json                               objects, motions, cameras, depth_mono truth
 * (depth_gt, masks_dynamic, covis for every camera with all_depth, else cam00 only.)
 * Panoptic layout: train_meta.json, test_meta.json (test = cams 5 and 6 when present),
 *   ims/<c>/<ffffff>.jpg, plus the ground-truth files and scene.json as above.
 * Reports progress as stage "synth". */
pg_status synth_write_dataset(const char *out_dir, const synth_options *o);

#endif
