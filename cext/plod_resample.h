/* plod_resample.h -- the CubeResampler: equirectangular (CAR) image -> cube
 * map in TSC, CSC or QSC, seamless across face edges, poles and lon +-180.
 */
#ifndef PLOD_RESAMPLE_H
#define PLOD_RESAMPLE_H

#include "plod_image.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum plod_filter {
    PLOD_FILTER_NEAREST = 0,
    PLOD_FILTER_BILINEAR,
    PLOD_FILTER_BICUBIC,
    PLOD_FILTER_COUNT
} plod_filter;

/* Progress: called with fraction done in [0, 1]; return non-zero to cancel
 * (then PLOD_ERR_CANCELLED and the cube map content is unspecified). */
typedef int (*plod_progress_fn)(void *user, double fraction);

/* "nearest", "bilinear", "bicubic"; PLOD_ERR_BAD_PARAM otherwise.
 * Bicubic is Catmull-Rom clamped per channel to the min/max of the central
 * 2x2 source taps (no overshoot; all-zero 2x2 footprints stay 0). */
plod_status plod_filter_from_name(const char *name, plod_filter *out);

/* Fills every texel of `cubemap` (already created with the wanted size,
 * channels, type and projection, cube or CAR) from the CAR image `source`
 * (any size; lon wraps, rows beyond a pole reflect to lon + 180), then
 * rebuilds its pyramid.  Channels are converted as plod_image_convert does.
 * Values are normalised (u8 / 255, u16 / 65535, f32 as is) and quantised
 * with rounding and clamping to [0, 1] for integer cube maps (NaN -> 0;
 * NaN stays NaN in f32 maps).  Uses 2
 * threads; progress (may be NULL) is called from the calling thread only,
 * about every 2 %, and last with 1.0. */
plod_status plod_resample_car_to_cube(plod_cubemap *cubemap,
                                      const plod_image *source,
                                      plod_filter filter,
                                      plod_progress_fn progress, void *user);
/* Same with an explicit thread count (clamped to 1..16); the result is
 * identical for every thread count. */
plod_status plod_resample_car_to_cube_threads(plod_cubemap *cubemap,
                                              const plod_image *source,
                                              plod_filter filter, int threads,
                                              plod_progress_fn progress,
                                              void *user);

/* Cross layout image of a cube map (4*size x 3*size, empty cells zero), or
 * one face as an image; `image` is allocated (free with plod_image_free). */
plod_status plod_cubemap_to_cross(plod_image *image, const plod_cubemap *cubemap);
plod_status plod_cubemap_face_to_image(plod_image *image,
                                       const plod_cubemap *cubemap, int face);
/* Cube map from a cross-layout image (inverse of plod_cubemap_to_cross),
 * pyramid built.  PLOD_ERR_BAD_IMAGE unless width:height is 4:3 with
 * width % 4 == 0. */
plod_status plod_cubemap_from_cross(plod_cubemap **out, const plod_image *cross,
                                    plod_projection projection);

/* Layout (cube maps): cross 4N x 3N, faces 1 2 3 4 left to right in the
 * middle band, face 0 above face 1 and face 5 below it (the FITS cross,
 * x = phi_c + 45 chi); each cell has u to the right and v up (image rows
 * top-down, face rows bottom-up).  A CAR map is written as one 2N x N
 * image with north up. */
/* General form: cross (layout_cross != 0) or one face, converted to
 * `channels` (1..4) and `type` as plod_image_convert does. */
plod_status plod_cubemap_to_image(plod_image *image, const plod_cubemap *cubemap,
                                  int layout_cross, int face, int channels,
                                  plod_texel_type type);

/* ---- pixel conversion ------------------------------------------------- */
/* New image with `channels` and `type`: grey is replicated into RGB, a
 * missing alpha is opaque (1.0), extra channels are dropped (RGB -> 1
 * channel keeps R); values normalised (u8 / 255, u16 / 65535) and
 * quantised with rounding, clamped to [0, 1] for integer types. */
plod_status plod_image_convert(plod_image *out, const plod_image *image,
                               int channels, plod_texel_type type);

#ifdef __cplusplus
}
#endif
#endif /* PLOD_RESAMPLE_H */
