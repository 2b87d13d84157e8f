/* plod_cubemap.h -- in-memory cube maps in a cube projection, seamless
 * bilinear sampling by direction, and a min/max pyramid for culling.
 *
 * Layout: 6 faces (FITS numbering, see plod_projection.h), each size x size
 * texels, row-major, rows along +v, columns along +u, texel (i, j) centred at
 * u = -1 + (i + 0.5) * 2 / size, v = -1 + (j + 0.5) * 2 / size; channels
 * interleaved.  A CAR map (projection PLOD_PROJ_CAR) has one face of
 * 2*size x size texels (lon -180..180, lat -90..90, row 0 = south).
 * Integer texels are normalised on sampling (u8 / 255, u16 / 65535).
 */
#ifndef PLOD_CUBEMAP_H
#define PLOD_CUBEMAP_H

#include <stddef.h>
#include <stdint.h>
#include "plod_projection.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum plod_texel_type {
    PLOD_TEXEL_U8 = 0,
    PLOD_TEXEL_U16,
    PLOD_TEXEL_F32,
    PLOD_TEXEL_TYPE_COUNT
} plod_texel_type;

typedef struct plod_cubemap plod_cubemap; /* opaque */

/* ---- create / destroy -------------------------------------------------- */
/* size in [1, 32768], channels in [1, 4]; texels zeroed.  *out is NULL on
 * failure.  Release with plod_cubemap_destroy (NULL is a no-op). */
plod_status plod_cubemap_create(plod_cubemap **out, plod_projection projection,
                                int size, int channels, plod_texel_type type);
void plod_cubemap_destroy(plod_cubemap *cubemap);

/* ---- queries ------------------------------------------------------------ */
plod_projection plod_cubemap_projection(const plod_cubemap *cubemap);
int plod_cubemap_size(const plod_cubemap *cubemap);
int plod_cubemap_channels(const plod_cubemap *cubemap);
int plod_cubemap_face_count(const plod_cubemap *cubemap); /* 6, or 1 for CAR */
plod_texel_type plod_cubemap_texel_type(const plod_cubemap *cubemap);
/* Texel storage of one face (writable), and its byte size. */
void *plod_cubemap_face_data(plod_cubemap *cubemap, int face);
const void *plod_cubemap_face_data_const(const plod_cubemap *cubemap, int face);
size_t plod_cubemap_face_bytes(const plod_cubemap *cubemap);

/* ---- sampling ----------------------------------------------------------- */
/* Bilinear sample at a direction (finite, non-zero); out gets `channels`
 * values.  Seamless: across face edges and corners the taps come from the
 * neighbouring faces, so a direction on an edge gives the same value from
 * either face (to 1e-6 relative). */
void plod_cubemap_sample(const plod_cubemap *cubemap, const double dir[3],
                         float *out);
/* Same, for channel 0 only, as double (heights). */
double plod_cubemap_sample_height(const plod_cubemap *cubemap,
                                  const double dir[3]);

/* ---- min/max pyramid (culling bounds) ----------------------------------- */
/* Builds the min/max pyramid of channel 0 (idempotent; call again after
 * editing texels). */
plod_status plod_cubemap_build_pyramid(plod_cubemap *cubemap);
/* Conservative bounds of channel 0 (normalised as sampling) over the face
 * rectangle [u0,u1]x[v0,v1] (clamped to the face), including every texel a
 * bilinear sample inside it can touch.  Requires the pyramid. */
void plod_cubemap_range(const plod_cubemap *cubemap, int face, double u0,
                        double v0, double u1, double v1, double *min_value,
                        double *max_value);
/* Bounds over the whole map (channel 0). */
void plod_cubemap_global_range(const plod_cubemap *cubemap, double *min_value,
                               double *max_value);

#ifdef __cplusplus
}
#endif
#endif /* PLOD_CUBEMAP_H */
