/* plod_cull.h -- the camera in Blender's conventions, and conservative
 * visibility tests of sector prisms (horizon/backface and frustum).
 */
#ifndef PLOD_CULL_H
#define PLOD_CULL_H

#include "plod_planet.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum plod_sensor_fit {
    PLOD_SENSOR_AUTO = 0, PLOD_SENSOR_HORIZONTAL, PLOD_SENSOR_VERTICAL
} plod_sensor_fit;

/* Given: what Blender's Object.matrix_world and Camera data hold.  The
 * camera looks down its local -Z with +Y up; matrix in planet space (the
 * planet object's inverse world matrix already applied by the caller). */
typedef struct plod_camera_desc {
    double matrix_world[16];   /* row-major 4x4, as Blender's Matrix rows */
    int orthographic;          /* 0 perspective, 1 orthographic */
    double lens;               /* mm */
    double sensor_width, sensor_height; /* mm */
    plod_sensor_fit sensor_fit;
    double ortho_scale;
    double shift_x, shift_y;
    double clip_start, clip_end;
    int resolution_x, resolution_y;
    double pixel_aspect_x, pixel_aspect_y;
} plod_camera_desc;

/* Returned by plod_camera_init: derived, planet-space quantities. */
typedef struct plod_camera {
    plod_camera_desc desc;
    double position[3];
    double right[3], up[3], forward[3]; /* unit; forward = -Z column */
    double planes[6][4];       /* inward frustum planes: n.x + d >= 0 inside */
    double pixels_per_radian;  /* perspective: screen scale at unit depth,
                                  raised by the off-axis magnification at
                                  the frame corners (conservative) */
    double pixels_per_metre;   /* orthographic */
    double tan_left, tan_right, tan_bottom, tan_top; /* view window at unit
                                  depth (perspective) or metres (ortho) */
} plod_camera;

/* PLOD_ERR_BAD_CAMERA for non-finite values, a singular matrix, lens <= 0,
 * zero resolution, ortho_scale <= 0, clip_start >= clip_end ... */
plod_status plod_camera_init(plod_camera *camera, const plod_camera_desc *desc);
/* Blender's defaults (lens 50, 36x24 sensor, AUTO fit, 1920x1080, clip
 * 0.1..1000) with an identity matrix. */
void plod_camera_desc_default(plod_camera_desc *desc);

/* ---- sector bounding volumes -------------------------------------------
 * A cap prism: every point r*d with the unit direction d within `angle`
 * radians of `axis` and r in [r_min, r_max] (metres from the planet
 * centre).  Sectors are bounded by one; all tests below are exact for the
 * cap prism, hence conservative for the sector inside it. */
typedef struct plod_cap_prism {
    double axis[3];   /* unit */
    double angle;     /* radians, [0, pi] */
    double r_min, r_max;
} plod_cap_prism;

/* Euclidean distance from `point` to the nearest point of the prism (0
 * inside). */
double plod_cap_prism_distance(const plod_cap_prism *prism, const double point[3]);
/* 1 if every point of the prism is hidden from `eye` by the ball of radius
 * `occluder_radius` around the centre (beyond the horizon); 0 otherwise
 * (always 0 when the eye is inside that ball). */
int plod_cap_prism_beyond_horizon(const plod_cap_prism *prism, const double eye[3],
                                  double occluder_radius);
/* 1 if the whole prism lies outside one of the camera's frustum planes. */
int plod_cap_prism_outside_frustum(const plod_cap_prism *prism,
                                   const plod_camera *camera);
/* 1 if `point` is inside the camera's frustum (all 6 planes). */
int plod_camera_contains(const plod_camera *camera, const double point[3]);

#ifdef __cplusplus
}
#endif
#endif /* PLOD_CULL_H */
