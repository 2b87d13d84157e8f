/* plod_projection.h -- cube-sphere projections (TSC, CSC, QSC, spherified)
 * and plate carree (CAR), WCSLIB-style: one block per family, a forward
 * (sphere -> plane) and inverse (plane -> sphere) pair, dispatched by code.
 *
 * Conventions (Calabretta & Greisen 2002, FITS):
 *   - direction (x, y, z) = (cos lat cos lon, cos lat sin lon, sin lat),
 *     north pole +Z, lon 0 = +X, lon 90 = +Y (Blender's Z-up world).
 *   - faces: 0 north pole, 1..4 equator centred at lon 0, 90, 180, 270,
 *     5 south pole.  Face coordinates (chi, psi) in [-1, 1] are called
 *     (u, v) in this code; their orientation is WCSLIB's.
 *   - cross layout [deg]: x = phi_c + 45 chi, y = theta_c + 45 psi.
 *   - CAR: x = lon, y = lat [deg]; its refinement domain is the octahedral
 *     square (face 0, (u, v) in [-1, 1]^2, |u|+|v| <= 1 northern hemisphere):
 *     lat = 90 (1 - |u| - |v|); lon = 90 |v| / (|u| + |v|) north of the
 *     equator, 90 (1 - |u|) / (2 - |u| - |v|) south of it (the outer
 *     triangles fold), then x takes the sign of u and y the sign of v
 *     ((1,0) lon 0, (0,1) lon 90, (-1,0) lon 180, (0,-1) lon -90; the
 *     border maps onto the meridians south of the equator, the corners onto
 *     the south pole).  Details in projection.c.
 * Angles at the API are degrees; internal maths is double precision.
 */
#ifndef PLOD_PROJECTION_H
#define PLOD_PROJECTION_H

#include <stddef.h>
#include "plod_base.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum plod_projection {
    PLOD_PROJ_TSC = 0,     /* tangential spherical cube (gnomonic per face) */
    PLOD_PROJ_CSC,         /* COBE quadrilateralized spherical cube */
    PLOD_PROJ_QSC,         /* quadrilateralized spherical cube, equal-area */
    PLOD_PROJ_SPHERIFIED,  /* x*sqrt(1 - y^2/2 - z^2/2 + y^2 z^2/3) */
    PLOD_PROJ_CAR,         /* plate carree, octahedral quad-sphere base */
    PLOD_PROJ_COUNT
} plod_projection;

#define PLOD_FACE_COUNT 6

/* ---- names ------------------------------------------------------------ */
/* "tsc", "csc", "qsc", "spherified", "car" (case-insensitive).
 * Returns PLOD_ERR_BAD_PROJECTION for anything else. */
plod_status plod_projection_from_name(const char *name, plod_projection *out);
/* Lower-case name; NULL for an invalid code. */
const char *plod_projection_name(plod_projection projection);
/* 1 for the cube projections (6 faces), 0 for CAR. */
int plod_projection_is_cube(plod_projection projection);

/* ---- direction <-> face coordinates (cube maps, LOD tree, emission) ---- */
/* dir need not be unit length but must be finite and non-zero.
 * Writes face in [0,5] and u, v in [-1, 1].  Directions exactly on a face
 * edge go to the lowest-numbered face containing them (canonical face).
 * PLOD_ERR_NULL, PLOD_ERR_BAD_PROJECTION, PLOD_ERR_BAD_COORD. */
plod_status plod_dir_to_face(plod_projection projection, const double dir[3],
                             int *face, double *u, double *v);
/* u, v in [-1, 1] (finite); writes a unit direction.  For CAR, face must be 0
 * and (u, v) is the octahedral square.  Bit-identical results for the same
 * point reached from two faces: the point is canonicalised first.
 * PLOD_ERR_NULL, PLOD_ERR_BAD_PROJECTION, PLOD_ERR_BAD_PARAM (face),
 * PLOD_ERR_BAD_COORD (u or v outside [-1, 1] or NaN). */
plod_status plod_face_to_dir(plod_projection projection, int face, double u,
                             double v, double dir[3]);
/* The frame of cube face `face` (the one table of them, the same for every
 * cube projection): frame[0] its centre c, frame[1] e_u and frame[2] e_v
 * (the +u and +v directions at the centre), signed unit axes with
 * components in {-1, 0, 1}.  PLOD_ERR_BAD_PARAM for a face outside 0..5
 * (frame untouched). */
plod_status plod_face_frame(int face, int frame[3][3]);

/* Vectorised forms over n points; dirs is 3n doubles (x, y, z per point).
 * stat may be NULL; otherwise stat[i] gets each point's status.  Failed
 * points get face -1 and NaN u, v (resp. NaN directions).  Returns PLOD_OK
 * if every point succeeded, else the first failure's status (PLOD_ERR_NULL
 * or PLOD_ERR_BAD_PROJECTION before any point).  These are the hot paths
 * (no per-point call overhead beyond the inline kernels). */
plod_status plod_dir_to_face_n(plod_projection projection, size_t n,
                               const double *dirs, int *faces, double *u,
                               double *v, int *stat);
plod_status plod_face_to_dir_n(plod_projection projection, size_t n,
                               const int *faces, const double *u,
                               const double *v, double *dirs, int *stat);

/* ---- spherical <-> cross layout [deg] --------------------------------- */
/* lon any finite value (wrapped), lat in [-90, 90]; NaN/inf -> BAD_COORD. */
plod_status plod_sphere_to_cube(plod_projection projection, double lon_deg,
                                double lat_deg, double *x_deg, double *y_deg);
/* (x, y) must lie on a face of the cross layout; else BAD_COORD. */
plod_status plod_cube_to_sphere(plod_projection projection, double x_deg,
                                double y_deg, double *lon_deg, double *lat_deg);

/* Vectorised forms over n points.  stat may be NULL; otherwise stat[i] gets
 * each point's status.  Failed points get NaN outputs.  Returns PLOD_OK if
 * every point succeeded, else the first failure's status. */
plod_status plod_sphere_to_cube_n(plod_projection projection, size_t n,
                                  const double *lon_deg, const double *lat_deg,
                                  double *x_deg, double *y_deg, int *stat);
plod_status plod_cube_to_sphere_n(plod_projection projection, size_t n,
                                  const double *x_deg, const double *y_deg,
                                  double *lon_deg, double *lat_deg, int *stat);

#ifdef __cplusplus
}
#endif
#endif /* PLOD_PROJECTION_H */
