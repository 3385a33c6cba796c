/* ground.h - the floor and the wall behind it, placed by the camera's vertical direction.
 *
 * A monocular network gets a static camera's large surfaces wrong in shape, not only in scale:
 * FastDepth sees tabletop_dev's table as almost one depth (the truth spans 2x from the bottom row
 * to the wall) and its wall as turned by ~20 degrees; neither a per-frame scale nor the temporal
 * median nor a plane fitted to that depth can undo it, and at a test camera 7-21 degrees away the
 * whole image lands in the wrong place (held out ~19.5 dB, a flat grey image 18.6). The image
 * itself holds what the depth lacks: vertical edges (wall stripes, window frames, table legs,
 * people) meet in the vertical vanishing point, which gives the floor's normal in camera
 * coordinates. A plane with a known normal has one unknown left, its distance, and the depth's
 * own floor fixes that in its units.
 *
 *  1. The still image (per-pixel median of up to 15 frames); unless the up direction is given (a
 *     dataset's rig, see stage/prepare.c), its near-vertical edge pixels vote
 *     for the vertical vanishing point by RANSAC (the line through each edge pixel along its edge
 *     direction), refined by least squares in homogeneous coordinates (a camera that looks level
 *     has it at infinity). Accepted when its inliers carry min_vp_share of the edge weight and it
 *     is within max_tilt_deg of the image's up.
 *  2. The floor: the region grown from the bottom rows (below the horizon) whose blurred colour is
 *     within colour_sigma (Mahalanobis) of the bottom rows' colour; it needs min_floor_share.
 *  3. Its height: the median of what the still depth implies over the floor. Static floor pixels
 *     take the plane's depth.
 *  4. Everything else stands on the floor. The rest factor makes the pixels just above the floor's
 *     top edge meet it (FastDepth puts tabletop_dev's wall 27 % too far for its table). Then each
 *     frame's non-floor pixels are grouped into objects (movers by connection, still ones by depth
 *     continuity too). A still object with floor directly below it is scaled by the floor's own
 *     correction there (plane / depth), or by the rest factor when that puts it nearer: an object
 *     is never behind the floor seen below it. A mover with floor below becomes a vertical sheet
 *     through its contact, facing the camera (a person is drawn whole at his feet's distance).
 *  5. The wall: where the floor's top edge is a straight line in 3D over at least wall_min_span
 *     of the image width (RANSAC on the floor plane, within wall_tolerance), a vertical plane
 *     stands on it; static pixels above the edge whose rescaled depth is within wall_band (in
 *     log) of that plane take its depth.
 *
 * A depth whose floor already is that plane within min_disagreement (the vanishing point is good to
 * about a degree; tabletop_dev's depth_mono and ground truth miss it by less) is left alone.
 *
 * Needs the focal length (pixels at the depth's size; the principal point is the centre); skipped
 * without one, without a vanishing point or without a floor (result.found = 0).
 * tabletop_dev, FastDepth: median |log error| of the depth against the ground truth (global
 * scale removed) 0.21 -> 0.05. */
#ifndef PG_DEPTH_GROUND_H
#define PG_DEPTH_GROUND_H

#include <stdint.h>

#include "core/camera.h"
#include "core/image.h"
#include "core/status.h"

typedef struct {
    float focal;            /* pixels at the depth's size; <= 0 skips the stage */
    int up_known;           /* up (camera coordinates) is given (a camera rig's vertical): no vanishing point */
    float up[3];
    float min_vp_share;     /* share of the near-vertical edge weight on the vanishing point (0.15) */
    float max_tilt_deg;     /* the up direction within this of the image's up (60) */
    float colour_sigma;     /* floor colour: Mahalanobis radius around the bottom rows' (3) */
    float min_floor_share;  /* a floor covers at least this share of the image (0.1) */
    float wall_tolerance;   /* a contact point's distance to the wall line, relative to its range (0.02) */
    float wall_min_span;    /* the wall line's inliers span this share of the width (0.4) */
    float wall_band;        /* |log(d / d_wall)| within which a pixel takes the wall (0.35) */
    float min_disagreement; /* the depth's floor must miss the plane by this (median |log|, 0.05) */
    float floor_colour;     /* a moving pixel over the floor within this of the still colour is floor (0.08) */
    float object_join;      /* neighbours of one object differ by less than this in log depth (0.04) */
    int min_contact;        /* an object meets the floor in at least this many pixels (3) */
    uint64_t seed;
} depth_ground_params;

typedef struct {
    int found;              /* the floor plane was placed */
    double vp_share;        /* edge weight on the vanishing point (0 when the rig gave up) */
    double tilt_deg;        /* angle between the up direction and the image's up */
    double up[3];           /* camera coordinates (x right, y down, z forward) */
    double height;          /* the floor is up . X = -height, depth units */
    double floor_share;     /* share of the image that is floor */
    double floor_disagreement; /* median |log| between the still depth's floor and the plane */
    double rest_scale;      /* the factor on everything that is not floor */
    int wall;               /* a wall plane was placed */
    double wall_span;       /* share of the width its contact inliers span */
    long blobs;             /* objects over all frames (movers, and depth-continuous groups of still non-floor pixels) */
    long anchored;          /* of them, standing on the floor (a sheet or their own contact's factor) */
    long changed;           /* (frame, pixel) values changed */
} depth_ground_result;

void depth_ground_defaults(depth_ground_params *p);

/* The up direction in camera ref's coordinates from a rig of count cameras around the scene (see
 * ground.c); 0 when the rig does not tell (a forward-facing row, fewer than 4 cameras). */
int depth_ground_rig_up(const pg_camera *cams, int count, int ref, float up[3]);

/* frames: F RGB images (W x H); depth (F, W*H) aligned depth, 0 = invalid, updated in place;
 * static_masks (F, W*H); still (W*H) the still scene's depth (0 = unknown). Fails only for memory. */
pg_status depth_ground_snap(const depth_ground_params *p, const pg_image *frames, int F, float *depth,
                            const unsigned char *static_masks, const float *still, int W, int H, depth_ground_result *res);

#endif
