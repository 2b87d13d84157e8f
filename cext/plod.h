/* plod.h -- Planet LOD core, umbrella header.  One header per stage:
 *   plod_base.h        status codes (plod_status.h), constants, vectors,
 *                      the fork-join loop
 *   plod_projection.h  TSC / CSC / QSC / spherified / CAR mappings
 *   plod_cubemap.h     cube maps, seamless sampling, min/max pyramid
 *   plod_image.h       images and OpenImageIO file I/O
 *   plod_resample.h    the CubeResampler (CAR -> cube)
 *   plod_heightsource.h  height sources; tiled maps read out of core
 *   plod_planet.h      planet description and heights
 *   plod_detail.h      procedural detail field below the map's resolution
 *   plod_camera.h      the camera in Blender's conventions
 *   plod_refine.h      HRTMR split/merge refinement
 *   plod_mesh.h        sector templates and buffer emission
 *   plod_session.h     one planet's per-frame state: refine, then emit
 * Internal to the core, not included here: plod_bound.h (sector bounds,
 * the visibility and error tests) and plod_lodtree.h (the LOD tree under
 * plod_refine.h's refiner).
 */
#ifndef PLOD_H
#define PLOD_H
#include "plod_base.h"
#include "plod_projection.h"
#include "plod_cubemap.h"
#include "plod_image.h"
#include "plod_resample.h"
#include "plod_heightsource.h"
#include "plod_surface.h"
#include "plod_planet.h"
#include "plod_detail.h"
#include "plod_camera.h"
#include "plod_refine.h"
#include "plod_mesh.h"
#include "plod_session.h"
#endif
