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

plod_status plod_filter_from_name(const char *name, plod_filter *out);

/* Fills every texel of `cubemap` (already created with the wanted size,
 * channels, type and projection; channels must equal the source's) from the
 * CAR image `source`.  progress may be NULL. */
plod_status plod_resample_car_to_cube(plod_cubemap *cubemap,
                                      const plod_image *source,
                                      plod_filter filter,
                                      plod_progress_fn progress, void *user);

/* Cross layout image of a cube map (4*size x 3*size, empty cells zero), or
 * one face as an image; `image` is allocated (free with plod_image_free). */
plod_status plod_cubemap_to_cross(plod_image *image, const plod_cubemap *cubemap);
plod_status plod_cubemap_face_to_image(plod_image *image,
                                       const plod_cubemap *cubemap, int face);
/* Cube map from a cross-layout image (inverse of plod_cubemap_to_cross). */
plod_status plod_cubemap_from_cross(plod_cubemap **out, const plod_image *cross,
                                    plod_projection projection);

#ifdef __cplusplus
}
#endif
#endif /* PLOD_RESAMPLE_H */
