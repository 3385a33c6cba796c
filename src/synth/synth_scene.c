/* synth_scene.c - the procedural tabletop: layout, rigid motion, ray casting, textures, shading.
 *
 * Everything is traced in the scene frame (z up); public points and cameras are in the world
 * frame (= cam00's camera frame) and converted on entry. Primary rays use the un-normalised
 * camera direction (x, y, 1), so the hit parameter of a primary ray IS its z-depth.
 */
#include "synth/synth.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "core/mathx.h"
#include "core/rng.h"

#define DEG2RAD ((float)PG_PI / 180.0f)

/* Rig of a DyNeRF-like frontal arc: (azimuth, elevation offset) in degrees. The first ten match
 * the shared tabletop_dev sample; the rest fill a 7 x 3 grid. */
static const float RIG[SYNTH_MAX_CAMS][2] = {
    { 0, 0 },  { 21, 7 }, { -21, 7 }, { 7, -7 },  { -7, 0 },  { 0, 7 },   { -21, 0 },
    { 21, -7 }, { -14, 0 }, { 7, 7 },  { 14, 0 },  { 21, 0 },  { -7, 7 },  { 14, 7 },
    { -14, 7 }, { -21, -7 }, { -14, -7 }, { -7, -7 }, { 0, -7 }, { 14, -7 }, { 7, 0 },
};

/* ---------------------------------------------------------------- scene layout */

static synth_object *add_object(synth_scene *sc, const char *name, synth_shape shape, synth_texture tex, int dynamic)
{
    synth_object *o = &sc->objects[sc->num_objects++];
    memset(o, 0, sizeof *o);
    snprintf(o->name, sizeof o->name, "%s", name);
    o->shape = shape;
    o->texture = tex;
    o->dynamic = dynamic;
    o->axis[2] = 1;
    o->tex_scale = 0.1f;
    return o;
}

static void set3(float v[3], float a, float b, float c) { v[0] = a; v[1] = b; v[2] = c; }

/* Static placement: p0 = p1 = (x, y, z). */
static void place(synth_object *o, float x, float y, float z)
{
    set3(o->p0, x, y, z);
    set3(o->p1, x, y, z);
}

static void jitter_color(pg_rng *rng, float c[3], float amount)
{
    for (int i = 0; i < 3; i++) c[i] = clampf(c[i] * (1.0f + amount * (float)pg_rng_range(rng, -1, 1)), 0.02f, 0.98f);
}

void synth_scene_default(synth_scene *sc, uint64_t seed)
{
    memset(sc, 0, sizeof *sc);
    sc->seed = seed;
    pg_rng rng;
    pg_rng_seed(&rng, seed * 0x9E3779B97F4A7C15ull + 12345);
    synth_object *o;

    o = add_object(sc, "table", SYNTH_SHAPE_PLANE, SYNTH_TEX_WOOD, 0);
    place(o, 0, 0, 0);
    set3(o->color_a, 0.52f, 0.32f, 0.16f);
    set3(o->color_b, 0.36f, 0.21f, 0.10f);
    o->tex_scale = 0.3f;

    o = add_object(sc, "wall", SYNTH_SHAPE_PLANE, SYNTH_TEX_BRICK, 0);
    place(o, 0, 1.3f, 0);
    set3(o->axis, 1, 0, 0); /* local z (normal) -> scene -y, local y -> scene z */
    o->angle0 = o->angle1 = 90 * DEG2RAD;
    set3(o->color_a, 0.55f, 0.22f, 0.15f);
    set3(o->color_b, 0.80f, 0.78f, 0.72f);
    o->tex_scale = 0.26f;

    o = add_object(sc, "crate", SYNTH_SHAPE_BOX, SYNTH_TEX_CHECKER, 0);
    place(o, -0.62f, 0.6f, 0.2f);
    set3(o->size, 0.18f, 0.18f, 0.2f);
    o->yaw = 25 * DEG2RAD;
    set3(o->color_a, 0.12f, 0.30f, 0.70f);
    set3(o->color_b, 0.88f, 0.88f, 0.82f);
    o->tex_scale = 0.09f;

    o = add_object(sc, "globe", SYNTH_SHAPE_SPHERE, SYNTH_TEX_STRIPES, 0);
    place(o, 0.62f, 0.65f, 0.2f);
    o->size[0] = 0.2f;
    set3(o->axis, 0.3f, 0.2f, 1.0f);
    vec3_normalize(o->axis);
    o->angle0 = o->angle1 = 0.5f;
    set3(o->color_a, 0.15f, 0.55f, 0.25f);
    set3(o->color_b, 0.92f, 0.80f, 0.25f);
    o->tex_scale = 0.08f;

    o = add_object(sc, "vase", SYNTH_SHAPE_CYLINDER, SYNTH_TEX_MARBLE, 0);
    place(o, -0.18f, 1.0f, 0.3f);
    set3(o->size, 0.13f, 0.3f, 0);
    set3(o->color_a, 0.78f, 0.76f, 0.72f);
    set3(o->color_b, 0.30f, 0.26f, 0.40f);
    o->tex_scale = 0.12f;

    o = add_object(sc, "book", SYNTH_SHAPE_BOX, SYNTH_TEX_STRIPES, 0);
    place(o, 0.32f, 1.02f, 0.06f);
    set3(o->size, 0.22f, 0.15f, 0.06f);
    o->yaw = -15 * DEG2RAD;
    set3(o->color_a, 0.65f, 0.12f, 0.16f);
    set3(o->color_b, 0.92f, 0.90f, 0.84f);
    o->tex_scale = 0.05f;

    o = add_object(sc, "mug", SYNTH_SHAPE_CYLINDER, SYNTH_TEX_CHECKER, 0);
    place(o, 0.78f, 0.0f, 0.1f);
    set3(o->size, 0.08f, 0.1f, 0);
    set3(o->color_a, 0.85f, 0.45f, 0.10f);
    set3(o->color_b, 0.95f, 0.92f, 0.85f);
    o->tex_scale = 0.05f;

    /* moving objects */
    o = add_object(sc, "slider", SYNTH_SHAPE_BOX, SYNTH_TEX_CHECKER, 1);
    set3(o->p0, -0.55f, -0.05f, 0.12f);
    set3(o->p1, 0.15f, 0.15f, 0.12f);
    set3(o->size, 0.12f, 0.12f, 0.12f);
    o->angle0 = 0;
    o->angle1 = 100 * DEG2RAD;
    set3(o->color_a, 0.85f, 0.10f, 0.08f);
    set3(o->color_b, 0.95f, 0.82f, 0.15f);
    o->tex_scale = 0.06f;

    o = add_object(sc, "ball", SYNTH_SHAPE_SPHERE, SYNTH_TEX_SEGMENTS, 1);
    set3(o->p0, 0.55f, 0.35f, 0.11f);
    set3(o->p1, -0.25f, 0.45f, 0.11f);
    o->size[0] = 0.11f;
    set3(o->color_a, 0.10f, 0.35f, 0.85f);
    set3(o->color_b, 0.95f, 0.95f, 0.95f);

    o = add_object(sc, "hopper", SYNTH_SHAPE_BOX, SYNTH_TEX_STRIPES, 1);
    set3(o->p0, 0.32f, -0.3f, 0.07f);
    set3(o->p1, 0.45f, -0.1f, 0.07f);
    set3(o->size, 0.07f, 0.07f, 0.07f);
    o->hop_height = 0.15f;
    o->hop_count = 2;
    set3(o->axis, 1, 0, 0);
    o->angle0 = 0;
    o->angle1 = 2 * (float)PG_PI;
    set3(o->color_a, 0.10f, 0.60f, 0.30f);
    set3(o->color_b, 0.95f, 0.95f, 0.90f);
    o->tex_scale = 0.035f;

    /* seeded variation: small moves of the static props, colours, texture phases */
    for (int k = 0; k < sc->num_objects; k++) {
        o = &sc->objects[k];
        if (o->shape != SYNTH_SHAPE_PLANE && !o->dynamic) {
            float dx = (float)pg_rng_range(&rng, -0.04, 0.04), dy = (float)pg_rng_range(&rng, -0.04, 0.04);
            o->p0[0] += dx; o->p1[0] += dx;
            o->p0[1] += dy; o->p1[1] += dy;
            o->yaw += (float)pg_rng_range(&rng, -0.15, 0.15);
        }
        jitter_color(&rng, o->color_a, 0.12f);
        jitter_color(&rng, o->color_b, 0.06f);
        for (int i = 0; i < 3; i++) o->tex_offset[i] = (float)pg_rng_range(&rng, 0, 100);
    }
    /* the ball rolls without slipping: axis = up x direction, angle = distance / radius */
    o = &sc->objects[8];
    {
        float d[3], up[3] = { 0, 0, 1 };
        vec3_sub(d, o->p1, o->p0);
        float dist = vec3_norm(d);
        vec3_cross(o->axis, up, d);
        vec3_normalize(o->axis);
        o->angle0 = 0;
        o->angle1 = dist / o->size[0];
    }

    set3(sc->light_dir, -0.45f, -0.55f, 0.85f);
    vec3_normalize(sc->light_dir);
    sc->ambient = 0.38f;
    sc->diffuse = 0.72f;
    sc->shadows = 1;
    sc->spp = 2;
    set3(sc->background, 0.6f, 0.7f, 0.85f);

    set3(sc->target, 0.0f, 0.42f, 0.12f);
    sc->radius = 2.45f;
    sc->elevation_deg = 30;
    sc->fov_x_deg = 60;
    for (int i = 0; i < SYNTH_MAX_CAMS; i++) {
        sc->cam_az[i] = RIG[i][0];
        sc->cam_el[i] = RIG[i][1];
    }
    /* world frame = cam00's camera frame */
    pg_camera c0;
    pg_camera_from_fov(&c0, 160, 120, sc->fov_x_deg);
    float eye[3], up[3] = { 0, 0, 1 };
    float el = sc->elevation_deg * DEG2RAD;
    set3(eye, sc->target[0], sc->target[1] - sc->radius * cosf(el), sc->target[2] + sc->radius * sinf(el));
    pg_camera_look_at(&c0, eye, sc->target, up);
    memcpy(sc->world_R, c0.R, sizeof sc->world_R);
    memcpy(sc->world_t, c0.t, sizeof sc->world_t);
}

void synth_scene_to_world(const synth_scene *sc, const float Xs[3], float Xw[3])
{
    float r[3];
    mat3_mul_vec(r, sc->world_R, Xs);
    vec3_add(Xw, r, sc->world_t);
}

void synth_world_to_scene(const synth_scene *sc, const float Xw[3], float Xs[3])
{
    float d[3];
    vec3_sub(d, Xw, sc->world_t);
    mat3_tmul_vec(Xs, sc->world_R, d);
}

/* Camera i of the rig in the SCENE frame (x_cam = R x_scene + t). */
static void rig_camera_scene(const synth_scene *sc, int index, int width, int height, pg_camera *cam)
{
    pg_camera_from_fov(cam, width, height, sc->fov_x_deg);
    float az = sc->cam_az[index] * DEG2RAD, el = (sc->elevation_deg + sc->cam_el[index]) * DEG2RAD;
    float eye[3] = { sc->target[0] + sc->radius * cosf(el) * sinf(az),
                     sc->target[1] - sc->radius * cosf(el) * cosf(az),
                     sc->target[2] + sc->radius * sinf(el) };
    float up[3] = { 0, 0, 1 };
    pg_camera_look_at(cam, eye, sc->target, up);
}

pg_status synth_camera(const synth_scene *sc, int index, int width, int height, pg_camera *cam)
{
    if (index < 0 || index >= SYNTH_MAX_CAMS)
        return pg_fail(PG_ERR_ARG, "synth: camera index %d out of range 0..%d", index, SYNTH_MAX_CAMS - 1);
    if (width < 1 || height < 1 || width > PG_MAX_IMAGE_SIDE || height > PG_MAX_IMAGE_SIDE)
        return pg_fail(PG_ERR_ARG, "synth: bad image size %d x %d", width, height);
    pg_camera cs;
    rig_camera_scene(sc, index, width, height, &cs);
    /* x_c = Rc x_s + tc, x_s = W^T (x_w - tw)  =>  R = Rc W^T, t = tc - R tw */
    *cam = cs;
    float Wt[9], Rtw[3];
    mat3_transpose(Wt, sc->world_R);
    mat3_mul(cam->R, cs.R, Wt);
    mat3_mul_vec(Rtw, cam->R, sc->world_t);
    vec3_sub(cam->t, cs.t, Rtw);
    if (index == 0) { /* exact identity (avoid round-off) */
        mat3_identity(cam->R);
        cam->t[0] = cam->t[1] = cam->t[2] = 0;
    }
    return PG_OK;
}

/* ---------------------------------------------------------------- motion */

/* Pose of object k at time s in the scene frame: X_scene = R X_local + p. */
static void object_pose_scene(const synth_object *o, float s, float R[9], float p[3])
{
    for (int i = 0; i < 3; i++) p[i] = o->p0[i] + (o->p1[i] - o->p0[i]) * s;
    if (o->hop_height > 0) p[2] += o->hop_height * fabsf(sinf((float)PG_PI * o->hop_count * s));
    float Ra[9], Ry[9], z[3] = { 0, 0, 1 };
    mat3_axis_angle(Ra, o->axis, o->angle0 + (o->angle1 - o->angle0) * s);
    mat3_axis_angle(Ry, z, o->yaw);
    mat3_mul(R, Ra, Ry);
}

void synth_object_pose(const synth_scene *sc, int k, float s, float R[9], float p[3])
{
    float Rs[9], ps[3];
    object_pose_scene(&sc->objects[k], s, Rs, ps);
    mat3_mul(R, sc->world_R, Rs);
    synth_scene_to_world(sc, ps, p);
}

/* ---------------------------------------------------------------- ray casting */

typedef struct {
    float R[9], p[3]; /* local -> scene */
    float bound;      /* bounding-sphere radius (0: infinite plane) */
} pose_cache;

typedef struct {
    const synth_scene *sc;
    pose_cache pose[SYNTH_MAX_OBJECTS];
} frame_state;

static void frame_state_init(frame_state *fs, const synth_scene *sc, float s)
{
    fs->sc = sc;
    for (int k = 0; k < sc->num_objects; k++) {
        const synth_object *o = &sc->objects[k];
        object_pose_scene(o, s, fs->pose[k].R, fs->pose[k].p);
        switch (o->shape) {
        case SYNTH_SHAPE_BOX: fs->pose[k].bound = vec3_norm(o->size); break;
        case SYNTH_SHAPE_SPHERE: fs->pose[k].bound = o->size[0]; break;
        case SYNTH_SHAPE_CYLINDER: fs->pose[k].bound = sqrtf(o->size[0] * o->size[0] + o->size[1] * o->size[1]); break;
        default: fs->pose[k].bound = 0; break;
        }
        fs->pose[k].bound *= 1.001f;
    }
}

typedef struct {
    float t;          /* ray parameter */
    int object;       /* -1: miss */
    float nl[3];      /* local normal (unnormalised allowed) */
} hit_info;

/* Nearest hit of the local ray o + t d with t in (tmin, tmax); writes the local normal. */
static int intersect_local(const synth_object *ob, const float o[3], const float d[3], float tmin, float tmax,
                           float *t_out, float n_out[3])
{
    switch (ob->shape) {
    case SYNTH_SHAPE_PLANE: {
        if (d[2] == 0) return 0;
        float t = -o[2] / d[2];
        if (t <= tmin || t >= tmax) return 0;
        *t_out = t;
        set3(n_out, 0, 0, 1);
        return 1;
    }
    case SYNTH_SHAPE_BOX: {
        float t0 = tmin, t1 = tmax;
        int axis0 = -1;
        float sign0 = 0;
        for (int a = 0; a < 3; a++) {
            float h = ob->size[a];
            if (d[a] == 0) {
                if (o[a] < -h || o[a] > h) return 0;
                continue;
            }
            float inv = 1.0f / d[a];
            float ta = (-h - o[a]) * inv, tb = (h - o[a]) * inv;
            float sgn = -1;
            if (ta > tb) { float tmp = ta; ta = tb; tb = tmp; sgn = 1; }
            if (ta > t0) { t0 = ta; axis0 = a; sign0 = sgn; }
            if (tb < t1) t1 = tb;
            if (t0 > t1) return 0;
        }
        if (axis0 < 0) return 0; /* ray starts inside: not a surface hit from outside */
        *t_out = t0;
        set3(n_out, 0, 0, 0);
        n_out[axis0] = sign0;
        return 1;
    }
    case SYNTH_SHAPE_SPHERE: {
        float r = ob->size[0];
        float a = vec3_dot(d, d), b = vec3_dot(o, d), c = vec3_dot(o, o) - r * r;
        float disc = b * b - a * c;
        if (disc < 0) return 0;
        float sq = sqrtf(disc);
        float t = (-b - sq) / a;
        if (t <= tmin) t = (-b + sq) / a;
        if (t <= tmin || t >= tmax) return 0;
        *t_out = t;
        for (int i = 0; i < 3; i++) n_out[i] = o[i] + t * d[i];
        return 1;
    }
    case SYNTH_SHAPE_CYLINDER: {
        float r = ob->size[0], hh = ob->size[1];
        float best = tmax;
        int found = 0;
        float a = d[0] * d[0] + d[1] * d[1];
        if (a > 0) {
            float b = o[0] * d[0] + o[1] * d[1], c = o[0] * o[0] + o[1] * o[1] - r * r;
            float disc = b * b - a * c;
            if (disc >= 0) {
                float sq = sqrtf(disc);
                float ts[2] = { (-b - sq) / a, (-b + sq) / a };
                for (int i = 0; i < 2; i++) {
                    float t = ts[i];
                    if (t <= tmin || t >= best) continue;
                    float z = o[2] + t * d[2];
                    if (z < -hh || z > hh) continue;
                    best = t;
                    set3(n_out, o[0] + t * d[0], o[1] + t * d[1], 0);
                    found = 1;
                    break;
                }
            }
        }
        if (d[2] != 0) {
            for (int side = -1; side <= 1; side += 2) {
                float t = (side * hh - o[2]) / d[2];
                if (t <= tmin || t >= best) continue;
                float x = o[0] + t * d[0], y = o[1] + t * d[1];
                if (x * x + y * y > r * r) continue;
                best = t;
                set3(n_out, 0, 0, (float)side);
                found = 1;
            }
        }
        if (found) *t_out = best;
        return found;
    }
    default: return 0;
    }
}

/* Nearest hit along the scene-frame ray o + t d, t in (tmin, tmax), over the objects whose bit
 * is set in candidates. If any_hit, stops at the first hit found (shadow rays). */
#define ALL_OBJECTS 0xFFFFFFFFu

static int trace_scene(const frame_state *fs, const float o[3], const float d[3], float tmin, float tmax, int any_hit,
                       uint32_t candidates, hit_info *hit)
{
    const synth_scene *sc = fs->sc;
    hit->t = tmax;
    hit->object = -1;
    float dd = vec3_dot(d, d);
    for (int k = 0; k < sc->num_objects; k++) {
        if (!(candidates >> k & 1u)) continue;
        const pose_cache *pc = &fs->pose[k];
        float rel[3];
        vec3_sub(rel, o, pc->p);
        if (pc->bound > 0) { /* bounding-sphere reject */
            float b = vec3_dot(rel, d), c = vec3_dot(rel, rel) - pc->bound * pc->bound;
            if (c > 0 && (b > 0 || b * b < dd * c)) continue;
        }
        float ol[3], dl[3], t, nl[3];
        mat3_tmul_vec(ol, pc->R, rel);
        mat3_tmul_vec(dl, pc->R, d);
        if (intersect_local(&sc->objects[k], ol, dl, tmin, hit->t, &t, nl)) {
            hit->t = t;
            hit->object = k;
            memcpy(hit->nl, nl, sizeof nl);
            if (any_hit) return 1;
        }
    }
    return hit->object >= 0;
}

/* ---------------------------------------------------------------- textures */

static inline uint32_t hash3(int x, int y, int z, uint32_t seed)
{
    uint32_t h = seed ^ 0x9E3779B9u;
    h ^= (uint32_t)x * 0x85EBCA6Bu; h = (h << 13) | (h >> 19); h *= 5; h += 0xE6546B64u;
    h ^= (uint32_t)y * 0xC2B2AE35u; h = (h << 13) | (h >> 19); h *= 5; h += 0xE6546B64u;
    h ^= (uint32_t)z * 0x27D4EB2Fu;
    h ^= h >> 16; h *= 0x85EBCA6Bu; h ^= h >> 13; h *= 0xC2B2AE35u; h ^= h >> 16;
    return h;
}

static inline float hashf(int x, int y, int z, uint32_t seed) { return (float)(hash3(x, y, z, seed) >> 8) * (1.0f / 16777216.0f); }

/* Trilinear value noise in [0, 1]. */
static float value_noise(float x, float y, float z, uint32_t seed)
{
    float fx = floorf(x), fy = floorf(y), fz = floorf(z);
    int ix = (int)fx, iy = (int)fy, iz = (int)fz;
    float u = x - fx, v = y - fy, w = z - fz;
    u = u * u * (3 - 2 * u); v = v * v * (3 - 2 * v); w = w * w * (3 - 2 * w);
    float c[2][2][2];
    for (int a = 0; a < 2; a++)
        for (int b = 0; b < 2; b++)
            for (int e = 0; e < 2; e++) c[a][b][e] = hashf(ix + a, iy + b, iz + e, seed);
    float x00 = c[0][0][0] + (c[1][0][0] - c[0][0][0]) * u, x10 = c[0][1][0] + (c[1][1][0] - c[0][1][0]) * u;
    float x01 = c[0][0][1] + (c[1][0][1] - c[0][0][1]) * u, x11 = c[0][1][1] + (c[1][1][1] - c[0][1][1]) * u;
    float y0 = x00 + (x10 - x00) * v, y1 = x01 + (x11 - x01) * v;
    return y0 + (y1 - y0) * w;
}

/* Bilinear value noise in [0, 1] (planes: half the hashes of the 3D version). */
static float value_noise2(float x, float y, uint32_t seed)
{
    float fx = floorf(x), fy = floorf(y);
    int ix = (int)fx, iy = (int)fy;
    float u = x - fx, v = y - fy;
    u = u * u * (3 - 2 * u); v = v * v * (3 - 2 * v);
    float c00 = hashf(ix, iy, 0, seed), c10 = hashf(ix + 1, iy, 0, seed);
    float c01 = hashf(ix, iy + 1, 0, seed), c11 = hashf(ix + 1, iy + 1, 0, seed);
    float a = c00 + (c10 - c00) * u, b = c01 + (c11 - c01) * u;
    return a + (b - a) * v;
}

static float fbm2(float x, float y, uint32_t seed)
{
    return 0.57f * value_noise2(x, y, seed) + 0.29f * value_noise2(2.03f * x, 2.03f * y, seed + 1) +
           0.14f * value_noise2(4.1f * x, 4.1f * y, seed + 2);
}

/* Fine detail noise (2 octaves), roughly in [0, 1]. */
static float detail_noise(const float q[3], const float off[3], int planar, uint32_t seed)
{
    float x = q[0] * 40 + off[0], y = q[1] * 40 + off[1], z = q[2] * 40 + off[2];
    if (planar) return 0.67f * value_noise2(x, y, seed) + 0.33f * value_noise2(2.03f * x, 2.03f * y, seed + 1);
    return 0.67f * value_noise(x, y, z, seed) + 0.33f * value_noise(2.03f * x, 2.03f * y, 2.03f * z, seed + 1);
}

/* Fractal noise (3 octaves), roughly in [0, 1]. */
static float fbm(float x, float y, float z, uint32_t seed)
{
    return 0.57f * value_noise(x, y, z, seed) + 0.29f * value_noise(2.03f * x, 2.03f * y, 2.03f * z, seed + 1) +
           0.14f * value_noise(4.1f * x, 4.1f * y, 4.1f * z, seed + 2);
}

static inline float smooth_step(float e0, float e1, float x)
{
    float t = clampf((x - e0) / (e1 - e0), 0, 1);
    return t * t * (3 - 2 * t);
}

static void mix3(float out[3], const float a[3], const float b[3], float t)
{
    for (int i = 0; i < 3; i++) out[i] = a[i] + (b[i] - a[i]) * t;
}

/* Albedo (linear RGB) at local point q of object ob. Every texture carries fine noise so no
 * region is flat (optical flow and photometric fitting need texture everywhere). */
static void texture_eval(const synth_object *ob, uint32_t seed, const float q[3], float out[3])
{
    const float s = ob->tex_scale;
    const float *off = ob->tex_offset;
    float x = q[0] / s, y = q[1] / s, z = q[2] / s;
    float detail = detail_noise(q, off, ob->shape == SYNTH_SHAPE_PLANE, seed + 17);
    float t = 0;
    switch (ob->texture) {
    case SYNTH_TEX_WOOD: {
        /* planks along x, checker-offset tiles, grain stretched along the plank */
        int ti = (int)floorf(x), tj = (int)floorf(y * 2.5f);
        int along_x = ((ti + tj) & 1) == 0;
        float ga = along_x ? q[0] : q[1], gb = along_x ? q[1] : q[0];
        float tile_tone = hashf(ti, tj, 0, seed + 5);
        float grain = fbm2(ga * 4 + off[0] + tile_tone * 10, gb * 70 + off[1], seed + 3);
        t = 0.45f * tile_tone + 0.55f * smooth_step(0.35f, 0.65f, grain);
        mix3(out, ob->color_a, ob->color_b, t);
        float fx = x - floorf(x), fy = y * 2.5f - floorf(y * 2.5f);
        float seam = fminf(fminf(fx, 1 - fx) * s, fminf(fy, 1 - fy) * s / 2.5f);
        if (seam < 0.006f) for (int i = 0; i < 3; i++) out[i] *= 0.45f;
        break;
    }
    case SYNTH_TEX_BRICK: {
        float row = floorf(y * 2.2f);
        float xs = x + 0.5f * ((int)row & 1);
        float col = floorf(xs);
        float fx = xs - col, fy = y * 2.2f - row;
        float mortar_w = 0.02f / s;
        int mortar = fx < mortar_w || fx > 1 - mortar_w || fy < mortar_w * 2.2f || fy > 1 - mortar_w * 2.2f;
        if (mortar) {
            for (int i = 0; i < 3; i++) out[i] = ob->color_b[i] * (0.8f + 0.3f * detail);
        } else {
            float tone = hashf((int)col, (int)row, 1, seed + 9);
            for (int i = 0; i < 3; i++) out[i] = ob->color_a[i] * (0.7f + 0.6f * tone);
            float stain = fbm2(q[0] * 6 + off[0], q[1] * 6 + off[1], seed + 11);
            for (int i = 0; i < 3; i++) out[i] *= 0.75f + 0.5f * stain;
        }
        break;
    }
    case SYNTH_TEX_CHECKER: {
        int par = ((int)floorf(x + 1e-4f) + (int)floorf(y + 1e-4f) + (int)floorf(z + 1e-4f)) & 1;
        mix3(out, ob->color_a, ob->color_b, (float)par);
        break;
    }
    case SYNTH_TEX_STRIPES: {
        float w = x * 0.8f + z * 0.6f + 0.7f * fbm(q[0] * 3 + off[0], q[1] * 3, q[2] * 3, seed + 13);
        t = smooth_step(-0.25f, 0.25f, sinf(2 * (float)PG_PI * w));
        mix3(out, ob->color_a, ob->color_b, t);
        break;
    }
    case SYNTH_TEX_MARBLE: {
        float n = fbm(q[0] * 5 + off[0], q[1] * 5 + off[1], q[2] * 5 + off[2], seed + 19);
        t = 0.5f + 0.5f * sinf(2 * (float)PG_PI * (z * 0.7f + 4 * n));
        mix3(out, ob->color_a, ob->color_b, t * t);
        break;
    }
    case SYNTH_TEX_SEGMENTS: {
        float ang = atan2f(q[1], q[0]);
        int seg = (int)floorf((ang + (float)PG_PI) / (2 * (float)PG_PI) * 6) % 6;
        static const float pal[6][3] = { { 0.85f, 0.10f, 0.10f }, { 0.95f, 0.95f, 0.95f }, { 0.10f, 0.35f, 0.85f },
                                         { 0.95f, 0.80f, 0.10f }, { 0.10f, 0.60f, 0.25f }, { 0.95f, 0.95f, 0.95f } };
        for (int i = 0; i < 3; i++) out[i] = pal[seg][i];
        float r = ob->size[0];
        if (fabsf(q[2]) > 0.85f * r) mix3(out, out, ob->color_b, 1); /* white poles */
        if (fabsf(q[2]) < 0.08f * r) mix3(out, out, ob->color_a, 1); /* equator band */
        break;
    }
    default: set3(out, 0.5f, 0.5f, 0.5f); break;
    }
    float m = 0.85f + 0.3f * detail;
    for (int i = 0; i < 3; i++) out[i] = clampf(out[i] * m, 0, 1);
}

/* ---------------------------------------------------------------- shading and rendering */

/* Colour (linear) of the scene-frame ray o + t d. */
static void shade_ray(const frame_state *fs, const float o[3], const float d[3], uint32_t candidates, float out[3],
                      hit_info *hit_out)
{
    const synth_scene *sc = fs->sc;
    hit_info hit;
    if (!trace_scene(fs, o, d, 0, 1e30f, 0, candidates, &hit)) {
        memcpy(out, sc->background, 3 * sizeof(float));
        if (hit_out) *hit_out = hit;
        return;
    }
    const pose_cache *pc = &fs->pose[hit.object];
    const synth_object *ob = &sc->objects[hit.object];
    float X[3], rel[3], ql[3], n[3];
    for (int i = 0; i < 3; i++) X[i] = o[i] + hit.t * d[i];
    vec3_sub(rel, X, pc->p);
    mat3_tmul_vec(ql, pc->R, rel);
    mat3_mul_vec(n, pc->R, hit.nl);
    vec3_normalize(n);
    if (vec3_dot(n, d) > 0) vec3_scale(n, n, -1); /* two-sided planes */
    float albedo[3];
    texture_eval(ob, (uint32_t)sc->seed * 2654435761u + (uint32_t)hit.object * 97u, ql, albedo);
    float ndl = vec3_dot(n, sc->light_dir);
    float light = sc->ambient;
    if (ndl > 0) {
        float vis = 1;
        if (sc->shadows) {
            float so[3];
            for (int i = 0; i < 3; i++) so[i] = X[i] + 1e-4f * n[i];
            hit_info sh;
            if (trace_scene(fs, so, sc->light_dir, 1e-5f, 1e30f, 1, ALL_OBJECTS, &sh)) vis = 0;
        }
        light += sc->diffuse * ndl * vis;
    }
    for (int i = 0; i < 3; i++) out[i] = albedo[i] * light;
    if (hit_out) *hit_out = hit;
}

/* The camera expressed in the scene frame: centre and rotation (x_cam = Rs x_scene + ts). */
static void camera_in_scene(const synth_scene *sc, const pg_camera *cam, float Rs[9], float C[3])
{
    mat3_mul(Rs, cam->R, sc->world_R);
    float Cw[3];
    pg_camera_center(cam, Cw);
    synth_world_to_scene(sc, Cw, C);
}

static inline void pixel_ray(const pg_camera *cam, const float Rs[9], float u, float v, float d[3])
{
    float dc[3] = { (u - cam->cx) / cam->fx, (v - cam->cy) / cam->fy, 1 };
    mat3_tmul_vec(d, Rs, dc);
}

static inline float linear_to_display(float x) { return powf(clampf(x, 0, 1), 1.0f / 2.2f); }

/* Conservative pixel box (x0, y0, x1, y1) of each object's bounding sphere on screen, so primary
 * rays only test the objects that can cover their pixel (planes and spheres reaching behind the
 * camera get the whole image). X/Z is monotone in X and Z over the sphere's bounding box (Z > 0),
 * so its extremes sit at the box corners. */
static void screen_boxes(const frame_state *fs, const pg_camera *cam, const float Rs[9], const float C[3],
                         float box[][4])
{
    for (int k = 0; k < fs->sc->num_objects; k++) {
        const pose_cache *pc = &fs->pose[k];
        float rel[3], Xc[3], r = pc->bound;
        vec3_sub(rel, pc->p, C);
        mat3_mul_vec(Xc, Rs, rel);
        if (r <= 0 || Xc[2] - r <= 1e-3f) {
            box[k][0] = box[k][1] = -1e30f;
            box[k][2] = box[k][3] = 1e30f;
            continue;
        }
        float umin = 1e30f, umax = -1e30f, vmin = 1e30f, vmax = -1e30f;
        for (int a = -1; a <= 1; a += 2)
            for (int b = -1; b <= 1; b += 2) {
                float z = Xc[2] + b * r;
                float u = cam->fx * (Xc[0] + a * r) / z + cam->cx, v = cam->fy * (Xc[1] + a * r) / z + cam->cy;
                umin = fminf(umin, u); umax = fmaxf(umax, u);
                vmin = fminf(vmin, v); vmax = fmaxf(vmax, v);
            }
        box[k][0] = umin - 1; box[k][1] = vmin - 1; box[k][2] = umax + 1; box[k][3] = vmax + 1;
    }
}

/* Bit k set when object k's screen box overlaps pixel (x, y). */
static inline uint32_t pixel_candidates(const float box[][4], int n, int x, int y)
{
    uint32_t m = 0;
    for (int k = 0; k < n; k++)
        if (x + 1 >= box[k][0] && x <= box[k][2] && y + 1 >= box[k][1] && y <= box[k][3]) m |= 1u << k;
    return m;
}

pg_status synth_render_frame(const synth_scene *sc, const pg_camera *cam, float s, pg_image *rgb, float *depth,
                             unsigned char *dynamic_mask)
{
    const int W = cam->width, H = cam->height;
    if (W < 1 || H < 1 || W > PG_MAX_IMAGE_SIDE || H > PG_MAX_IMAGE_SIDE)
        return pg_fail(PG_ERR_ARG, "synth: bad camera size %d x %d", W, H);
    if (rgb) {
        if (!rgb->data) PG_TRY(pg_image_create(rgb, W, H, 3));
        else if (rgb->width != W || rgb->height != H || rgb->channels != 3)
            return pg_fail(PG_ERR_SIZE, "synth: image is %d x %d x %d, camera is %d x %d", rgb->width, rgb->height,
                           rgb->channels, W, H);
    }
    frame_state fs;
    frame_state_init(&fs, sc, s);
    float Rs[9], C[3];
    camera_in_scene(sc, cam, Rs, C);
    const int n = sc->spp < 1 ? 1 : sc->spp;
    const float inv = 1.0f / (float)(n * n);
    float box[SYNTH_MAX_OBJECTS][4];
    screen_boxes(&fs, cam, Rs, C, box);

#pragma omp parallel for schedule(dynamic, 2)
    for (int y = 0; y < H; y++) {
        for (int x = 0; x < W; x++) {
            size_t idx = (size_t)y * W + x;
            float d[3];
            uint32_t cand = pixel_candidates(box, sc->num_objects, x, y);
            if (rgb) {
                float acc[3] = { 0, 0, 0 };
                for (int sy = 0; sy < n; sy++)
                    for (int sx = 0; sx < n; sx++) {
                        pixel_ray(cam, Rs, x + (sx + 0.5f) / n, y + (sy + 0.5f) / n, d);
                        float c[3];
                        shade_ray(&fs, C, d, cand, c, NULL);
                        vec3_add(acc, acc, c);
                    }
                float *px = rgb->data + idx * 3;
                for (int i = 0; i < 3; i++) px[i] = linear_to_display(acc[i] * inv);
            }
            if (depth || dynamic_mask) {
                pixel_ray(cam, Rs, x + 0.5f, y + 0.5f, d);
                hit_info hit;
                int any = trace_scene(&fs, C, d, 0, 1e30f, 0, cand, &hit);
                if (depth) depth[idx] = any ? hit.t : 0.0f;
                if (dynamic_mask) dynamic_mask[idx] = (unsigned char)(any && sc->objects[hit.object].dynamic);
            }
        }
    }
    return PG_OK;
}

float synth_trace_depth(const synth_scene *sc, const pg_camera *cam, float u, float v, float s, int *object)
{
    frame_state fs;
    frame_state_init(&fs, sc, s);
    float Rs[9], C[3], d[3];
    camera_in_scene(sc, cam, Rs, C);
    pixel_ray(cam, Rs, u, v, d);
    hit_info hit;
    int any = trace_scene(&fs, C, d, 0, 1e30f, 0, ALL_OBJECTS, &hit);
    if (object) *object = any ? hit.object : -1;
    return any ? hit.t : 0.0f;
}

/* Signed-distance-like test: is local point q within tol of (or inside) the solid? */
static int near_solid(const synth_object *ob, const float q[3], float tol)
{
    switch (ob->shape) {
    case SYNTH_SHAPE_BOX:
        return fabsf(q[0]) <= ob->size[0] + tol && fabsf(q[1]) <= ob->size[1] + tol && fabsf(q[2]) <= ob->size[2] + tol;
    case SYNTH_SHAPE_SPHERE: return vec3_norm(q) <= ob->size[0] + tol;
    case SYNTH_SHAPE_CYLINDER:
        return sqrtf(q[0] * q[0] + q[1] * q[1]) <= ob->size[0] + tol && fabsf(q[2]) <= ob->size[1] + tol;
    case SYNTH_SHAPE_PLANE: return fabsf(q[2]) <= tol;
    default: return 0;
    }
}

int synth_point_is_dynamic(const synth_scene *sc, const float Xw[3], float s, float tol)
{
    float Xs[3];
    synth_world_to_scene(sc, Xw, Xs);
    for (int k = 0; k < sc->num_objects; k++) {
        const synth_object *ob = &sc->objects[k];
        if (!ob->dynamic) continue;
        float R[9], p[3], rel[3], q[3];
        object_pose_scene(ob, s, R, p);
        vec3_sub(rel, Xs, p);
        mat3_tmul_vec(q, R, rel);
        if (near_solid(ob, q, tol)) return 1;
    }
    return 0;
}

/* Visibility of scene-frame point Xs (world Xw) from a camera with scene-frame centre C. */
static int visible_from(const frame_state *fs, const pg_camera *cam, const float C[3], const float Xw[3],
                        const float Xs[3], float rel_tol)
{
    float uv[2];
    float z = pg_camera_project(cam, Xw, uv);
    if (z <= 0 || uv[0] < 0 || uv[1] < 0 || uv[0] >= cam->width || uv[1] >= cam->height) return 0;
    float d[3];
    vec3_sub(d, Xs, C); /* the point sits at t = 1 */
    hit_info hit;
    if (!trace_scene(fs, C, d, 0, 1e30f, 0, ALL_OBJECTS, &hit)) return 1; /* nothing in the way (point off-surface) */
    return hit.t >= 1.0f - rel_tol;
}

int synth_point_visible(const synth_scene *sc, const pg_camera *cam, const float Xw[3], float s, float rel_tol)
{
    frame_state fs;
    frame_state_init(&fs, sc, s);
    float Rs[9], C[3], Xs[3];
    camera_in_scene(sc, cam, Rs, C);
    synth_world_to_scene(sc, Xw, Xs);
    return visible_from(&fs, cam, C, Xw, Xs, rel_tol);
}

pg_status synth_render_covisibility(const synth_scene *sc, const pg_camera *cam, const pg_camera *ref, float s,
                                    float rel_tol, unsigned char *mask)
{
    const int W = cam->width, H = cam->height;
    if (W < 1 || H < 1 || W > PG_MAX_IMAGE_SIDE || H > PG_MAX_IMAGE_SIDE)
        return pg_fail(PG_ERR_ARG, "synth: bad camera size %d x %d", W, H);
    frame_state fs;
    frame_state_init(&fs, sc, s);
    float Rs[9], C[3], Rr[9], Cr[3];
    camera_in_scene(sc, cam, Rs, C);
    camera_in_scene(sc, ref, Rr, Cr);
#pragma omp parallel for schedule(dynamic, 4)
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            float d[3], Xs[3], Xw[3];
            pixel_ray(cam, Rs, x + 0.5f, y + 0.5f, d);
            hit_info hit;
            unsigned char v = 0;
            if (trace_scene(&fs, C, d, 0, 1e30f, 0, ALL_OBJECTS, &hit)) {
                for (int i = 0; i < 3; i++) Xs[i] = C[i] + hit.t * d[i];
                synth_scene_to_world(sc, Xs, Xw);
                v = (unsigned char)visible_from(&fs, ref, Cr, Xw, Xs, rel_tol);
            }
            mask[(size_t)y * W + x] = v;
        }
    return PG_OK;
}

pg_status synth_render_flow(const synth_scene *sc, const pg_camera *cam, float s0, float s1, float *flow,
                            unsigned char *valid)
{
    const int W = cam->width, H = cam->height;
    if (W < 1 || H < 1 || W > PG_MAX_IMAGE_SIDE || H > PG_MAX_IMAGE_SIDE)
        return pg_fail(PG_ERR_ARG, "synth: bad camera size %d x %d", W, H);
    frame_state fs0, fs1;
    frame_state_init(&fs0, sc, s0);
    frame_state_init(&fs1, sc, s1);
    float Rs[9], C[3];
    camera_in_scene(sc, cam, Rs, C);
#pragma omp parallel for schedule(dynamic, 4)
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            size_t idx = (size_t)y * W + x;
            float d[3], X0[3], rel[3], q[3], X1[3], Xw[3], uv[2];
            pixel_ray(cam, Rs, x + 0.5f, y + 0.5f, d);
            hit_info hit;
            flow[2 * idx] = flow[2 * idx + 1] = 0;
            unsigned char ok = 0;
            if (trace_scene(&fs0, C, d, 0, 1e30f, 0, ALL_OBJECTS, &hit)) {
                const pose_cache *p0 = &fs0.pose[hit.object], *p1 = &fs1.pose[hit.object];
                for (int i = 0; i < 3; i++) X0[i] = C[i] + hit.t * d[i];
                vec3_sub(rel, X0, p0->p);
                mat3_tmul_vec(q, p0->R, rel);   /* local point: moves rigidly with its object */
                mat3_mul_vec(X1, p1->R, q);
                vec3_add(X1, X1, p1->p);
                synth_scene_to_world(sc, X1, Xw);
                float z = pg_camera_project(cam, Xw, uv);
                if (z > 0) {
                    flow[2 * idx] = uv[0] - (x + 0.5f);
                    flow[2 * idx + 1] = uv[1] - (y + 0.5f);
                    if (valid) {
                        float dd[3];
                        vec3_sub(dd, X1, C);
                        hit_info h1;
                        ok = uv[0] >= 0 && uv[1] >= 0 && uv[0] < W && uv[1] < H &&
                             (!trace_scene(&fs1, C, dd, 0, 1e30f, 0, ALL_OBJECTS, &h1) || h1.t >= 1.0f - 1e-3f);
                    }
                }
            }
            if (valid) valid[idx] = ok;
        }
    return PG_OK;
}
