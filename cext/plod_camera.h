/* plod_camera.h -- the camera in Blender's conventions: what Blender holds
 * in, planet-space axes, view window and frustum planes out.  The
 * visibility tests of sectors against it are the refiner's (bound.c).
 */
#ifndef PLOD_CAMERA_H
#define PLOD_CAMERA_H

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

/* PLOD_ERR_NULL; PLOD_ERR_BAD_CAMERA for non-finite values, a singular or
 * projective matrix, lens or sensor <= 0 (perspective), ortho_scale <= 0
 * (orthographic), resolution or pixel aspect <= 0, clip_start <= 0,
 * clip_start >= clip_end, an unknown sensor fit, or a view whose derived
 * values are not finite.  On failure *camera may be partly written. */
plod_status plod_camera_init(plod_camera *camera, const plod_camera_desc *desc);
/* Blender's defaults (lens 50, 36x24 sensor, AUTO fit, ortho scale 7,
 * 1920x1080, clip 0.1..1000) with an identity matrix. */
void plod_camera_desc_default(plod_camera_desc *desc);

/* 1 if `point` is inside the camera's frustum (all 6 planes). */
int plod_camera_contains(const plod_camera *camera, const double point[3]);

#ifdef __cplusplus
}
#endif
#endif /* PLOD_CAMERA_H */
