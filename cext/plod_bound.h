/* plod_bound.h -- sector bounds and the only visibility and error tests of
 * the refinement (bound.c): used by the LOD tree, which builds a bound for
 * every sector it creates, and by the LOD update, which tests them every
 * frame.  Internal to the core: bindings use plod_refine.h.
 */
#ifndef PLOD_BOUND_H
#define PLOD_BOUND_H

#include "plod_refine.h"

#ifdef __cplusplus
extern "C" {
#endif

/* What a bound's distance test last decided, and for how long it holds:
 * the prism's distance moves no faster than the eye, so the decision
 * stands while the eye has travelled less than `until` (measured by
 * plod_bound_view.travelled) under the same thresholds (`key`). */
typedef struct plod_bound_memo {
    double until;
    uint32_t key;    /* plod_bound_view.memo_key it was made under; 0: none */
    uint8_t exceeds;
} plod_bound_memo;

/* A sector's cap prism (every point r d, d within the cap angle of `axis`,
 * r in [r_min, r_max]), the per-sector constants of its tests and the
 * memo of its distance test (moves with the bound; a new bound has none). */
typedef struct plod_bound {
    plod_bound_memo memo;
    double axis[3];
    double cos_angle, sin_angle; /* cap half-angle */
    double r_min, r_max;  /* metres from the centre */
    double size;          /* longest corner chord, metres at the radius */
    double sag0;          /* size^2 / (8 r_min): curvature sag, template 0 */
    double relief0;       /* (hmax - hmin) * min(1, extent / texel) */
    double twist0;        /* inside one bilinear cell: 3 (hmax - hmin) *
                             (extent / texel)^2; else infinity */
    double detail0;       /* the detail field's modulation maximum over the
                             sector (0: no detail there) */
    double band0;         /* the largest excess g(m) - m of the hills' band
                             over the sector (plod_detail.h) */
    int horizon;          /* 0: r_max below the occluder, never hidden */
    double horizon_cos, horizon_sin; /* of the cap angle + the angle at
                             which r_max peeks over the occluder ball */
    double sphere_z, sphere_radius; /* bounding ball: centre axis*sphere_z */
    float hmin, hmax;     /* metres, outward-rounded */
} plod_bound;

/* ---- construction ----------------------------------------------------------- */

/* Per-planet constants of the bounds, fixed for a refiner's life. */
typedef struct plod_bound_setup {
    const plod_planet *planet; /* borrowed */
    double texels_per_unit;    /* height map texels per unit of u or v (0:
                                  no map) */
    double occluder;           /* radius of the lowest surface: the ball
                                  that hides what lies beyond the horizon */
} plod_bound_setup;

void plod_bound_setup_init(plod_bound_setup *setup, const plod_planet *planet);

/* Up to four corner points of a split (a diamond parent's three corners
 * and its hypotenuse midpoint): directions, and map heights computed on
 * demand, once (the same calls: the same bits for every sector that
 * shares the point). */
typedef struct plod_bound_corners {
    double dir[4][3];  /* unit directions */
    double height[4];  /* plod_planet_map_height of dir[k] if bit k of known */
    unsigned known;
} plod_bound_corners;

/* Bound of sector s whose corners are corners->dir[idx[0..2]]; may fill
 * heights of those corners (and sets their bits in corners->known). */
void plod_bound_build(const plod_bound_setup *setup, const plod_sector *s,
                      plod_bound_corners *corners, const int idx[3], plod_bound *b);

/* ---- tests ------------------------------------------------------------------ */

/* Given: one frame's values the tests read, derived from the camera and
 * the refinement parameters by the LOD update. */
typedef struct plod_bound_view {
    const plod_camera *camera;   /* borrowed for the frame */
    const plod_detail *detail;   /* the planet's detail field or NULL */
    double eye[3], eye_unit[3], eye_dist;
    int horizon_on;              /* backface culling against the occluder */
    double eye_horizon_cos, eye_horizon_sin; /* of the eye's horizon angle */
    int frustum_culling;
    double error_scale, error_scale2; /* 2^-t, 4^-t for template level t */
    double distance_floor;       /* metres: distances below count as this */
    plod_criterion criterion;
    double split_border, max_pixel_error;
    double coarsening;           /* the budget's threshold factor */
    int split_mode;              /* 0 side/distance, 1 pixel, 2 ortho pixel */
    double split_scale;          /* its threshold, coarsening included */
    uint32_t memo_key;           /* names the thresholds above (0: memos off) */
    double travelled;            /* the eye's path length since memo_key was
                                    issued, rounded up */
} plod_bound_view;

/* The view's camera-derived values (eye, horizon against `occluder`,
 * culling switches, error thresholds); memos off, coarsening and split mode
 * left 0 for the caller.  eye_dist: |camera position|, as the caller
 * measured it (> 0). */
void plod_bound_view_init(plod_bound_view *view, const plod_planet *planet, double occluder,
                          const plod_camera *camera, const plod_refine_params *params,
                          double eye_dist);

/* bit i: the surface is inside frustum plane i */
#define PLOD_BOUND_ALL_PLANES 0x3Fu

/* PLOD_SECTOR_BACKFACING, PLOD_SECTOR_OUTSIDE_FRUSTUM or 0 (only the first
 * test that culls is reported).  parent_planes: the planes the parent's
 * surface is inside of (0 if unknown), whose tests are skipped with the
 * same result; *planes: parent_planes plus the planes this bound is
 * inside of. */
unsigned plod_bound_cull(const plod_bound_view *view, const plod_bound *b,
                         unsigned parent_planes, unsigned *planes);
/* Euclidean distance from the eye to the prism's nearest point (0 inside). */
double plod_bound_distance(const plod_bound_view *view, const plod_bound *b);
/* Refinement score at `distance` (> 1 wants a split, culling ignored):
 * projected error / max_pixel_error, or size / distance / split_border,
 * over the coarsening. */
double plod_bound_score(const plod_bound_view *view, const plod_bound *b, double distance);
/* score > 1 at plod_bound_distance, decided without it where cheaper
 * bounds settle it (the same result); from b's memo while it holds,
 * otherwise tested and, when view->memo_key is set, memoised. */
int plod_bound_exceeds_memo(const plod_bound_view *view, plod_bound *b);

#ifdef __cplusplus
}
#endif
#endif /* PLOD_BOUND_H */
