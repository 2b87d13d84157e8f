/* plod_cubemap.h -- in-memory cube maps in a cube projection, seamless
 * bilinear sampling by direction, a min/max pyramid for culling, normal
 * maps of height maps, and the rules by which images become cube maps.
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
/* Face sizes, texels a side.  Two limits, on purpose:
 * PLOD_CUBEMAP_MAX_SIZE is the core's hard limit: plod_cubemap_create
 * refuses larger (texel coordinates are ints; a CAR face row holds 2 size
 * texels).  PLOD_CUBEMAP_MAX_MAP_SIZE is the Python API's, for maps it
 * creates, reads or resamples (CubeMap, from_image, resample, Planet's
 * heightmap_size): six faces of 16384^2 are 1.6 G texels, 6.4 GB as f32
 * before the pyramid; larger data is read out of core (TiledMap). */
#define PLOD_CUBEMAP_MAX_SIZE 32768
#define PLOD_CUBEMAP_MAX_MAP_SIZE 16384

/* size in [1, PLOD_CUBEMAP_MAX_SIZE], channels in [1, 4]; texels zeroed.
 * PLOD_ERR_NULL, PLOD_ERR_BAD_PROJECTION, PLOD_ERR_BAD_PARAM,
 * PLOD_ERR_NO_MEMORY; *out is NULL on failure.  Release with
 * plod_cubemap_destroy (NULL is a no-op). */
plod_status plod_cubemap_create(plod_cubemap **out, plod_projection projection,
                                int size, int channels, plod_texel_type type);
void plod_cubemap_destroy(plod_cubemap *cubemap);

/* ---- queries ------------------------------------------------------------ */
plod_projection plod_cubemap_projection(const plod_cubemap *cubemap);
int plod_cubemap_size(const plod_cubemap *cubemap);
int plod_cubemap_channels(const plod_cubemap *cubemap);
int plod_cubemap_face_count(const plod_cubemap *cubemap); /* 6, or 1 for CAR */
plod_texel_type plod_cubemap_texel_type(const plod_cubemap *cubemap);
/* Texel storage of one face (writable: invalidates the pyramid, so call
 * plod_cubemap_build_pyramid after writing), and its byte size. */
void *plod_cubemap_face_data(plod_cubemap *cubemap, int face);
const void *plod_cubemap_face_data_const(const plod_cubemap *cubemap, int face);
size_t plod_cubemap_face_bytes(const plod_cubemap *cubemap);
/* Texels per face row (size, or 2*size for CAR) and rows per face (size). */
int plod_cubemap_face_width(const plod_cubemap *cubemap);
int plod_cubemap_face_height(const plod_cubemap *cubemap);

/* ---- sampling ----------------------------------------------------------- */
/* Bilinear sample at a direction (finite, non-zero); out gets `channels`
 * values.  Seamless: across face edges and corners the taps come from the
 * neighbouring faces, so a direction on an edge gives the same value from
 * either face (to 1e-6 relative). */
void plod_cubemap_sample(const plod_cubemap *cubemap, const double dir[3],
                         float *out);
/* Same, for channel 0 only, as double (heights).  NaN for a zero or
 * non-finite direction (plod_cubemap_sample writes NaNs then). */
double plod_cubemap_sample_height(const plod_cubemap *cubemap,
                                  const double dir[3]);
/* Bilinear sample at face coordinates (u, v clamped to [-1, 1]); for CAR
 * face 0 with u = lon / 180 deg, v = lat / 90 deg.  Seam rule: a tap one
 * texel beyond an edge reads the neighbour's texel next to the shared edge;
 * the tap diagonal beyond a corner reads the average of the three texels
 * meeting at that cube corner, so the exact corner gives (A + B + C) / 3
 * from each face.  CAR maps wrap in longitude and reflect across the poles
 * (row -1 is row 0 at lon + 180).  NaNs for a bad face or non-finite u, v. */
void plod_cubemap_sample_face(const plod_cubemap *cubemap, int face, double u,
                              double v, float *out);

/* Where a direction samples: face and (u, v) as plod_cubemap_sample_face
 * takes them (CAR: lon / 180 deg, lat / 90 deg).  Returns 0 for a zero or
 * non-finite direction.  plod_cubemap_sample(dir) is exactly
 * plod_cubemap_sample_face_d at the located point. */
int plod_cubemap_locate(const plod_cubemap *cubemap, const double dir[3],
                        int *face, double *u, double *v);
/* plod_cubemap_sample_face in double precision; returns 0 (out untouched)
 * for a bad face or non-finite u, v. */
int plod_cubemap_sample_face_d(const plod_cubemap *cubemap, int face, double u,
                               double v, double *out);

/* plod_cubemap_locate over n directions (dirs: 3 n doubles); faces[i] = -1
 * where it fails.  Bit for bit the single-point results. */
void plod_cubemap_locate_n(const plod_cubemap *cubemap, size_t n, const double *dirs,
                           int *faces, double *u, double *v);
/* plod_cubemap_sample_face_d at n points, bit for bit; out gets n *
 * channels doubles, NaNs for a point with a bad face or non-finite u, v. */
void plod_cubemap_sample_face_n(const plod_cubemap *cubemap, size_t n, const int *faces,
                                const double *u, const double *v, double *out);

/* plod_cubemap_sample_face_n on two maps at the same points (out_a: n *
 * channels of a, out_b: n * channels of b), bit for bit; a 1-channel height
 * map and its u16x3 normal map on one grid share the per-point work. */
void plod_cubemap_sample_pair_n(const plod_cubemap *a, const plod_cubemap *b, size_t n,
                                const int *faces, const double *u, const double *v,
                                double *out_a, double *out_b);

/* ---- maps sampled together ------------------------------------------------- */
/* A 1-channel height map, its u16x3 normal map and optionally a 1-channel
 * 8-bit map (the detail's modulation), all on one texel grid, interleaved
 * texel by texel: a bilinear sample of the three reads two or three cache
 * lines where the maps apart read six or more.  Sampling vertices texels
 * apart (a planet seen from orbit) is bound by those misses.  The bundle
 * borrows the maps (points on a face's last row or column are sampled
 * from them) and copies their texels: caller keeps the maps alive and
 * unchanged while it lives. */
typedef struct plod_cubemap_bundle plod_cubemap_bundle;

/* Largest bundle plod_cubemap_bundle_create makes (16 bytes a texel):
 * six faces of 1024^2 texels and their rings.  Bigger maps are sampled map
 * by map. */
#define PLOD_CUBEMAP_BUNDLE_MAX_BYTES ((size_t)6 * 1026 * 1026 * 16)

/* *out: the bundle of `heights` (1 channel, any type), `normals` (3
 * channels u16) and `extra` (1 channel u8, or NULL), or NULL (PLOD_OK)
 * when they do not share a grid and layout or it would exceed
 * PLOD_CUBEMAP_BUNDLE_MAX_BYTES.  PLOD_ERR_NULL, PLOD_ERR_NO_MEMORY. */
plod_status plod_cubemap_bundle_create(plod_cubemap_bundle **out, const plod_cubemap *heights,
                                       const plod_cubemap *normals, const plod_cubemap *extra);
void plod_cubemap_bundle_destroy(plod_cubemap_bundle *bundle);
/* Non-zero when bundle holds exactly these maps (extra NULL: none). */
int plod_cubemap_bundle_holds(const plod_cubemap_bundle *bundle, const plod_cubemap *heights,
                              const plod_cubemap *normals, const plod_cubemap *extra);
/* plod_cubemap_sample_pair_n(heights, normals) and, when the bundle has an
 * extra map, plod_cubemap_sample_face_n(extra) into extra_out (n doubles),
 * bit for bit. */
void plod_cubemap_bundle_sample_n(const plod_cubemap_bundle *bundle, size_t n, const int *faces,
                                  const double *u, const double *v, double *heights_out,
                                  double *normals_out, double *extra_out);

/* ---- normal maps ----------------------------------------------------------- */
/* Unit outward normals of the surface dir * (radius + height_scale * h) at
 * every texel centre of `heights` (channel 0), from central differences of
 * the displaced texel-centre points (neighbours across face edges, or the
 * CAR wrap, as in sampling).  *out: a new map of the same projection and
 * size, 3 channels u16, n = 2 * sample - 1 (renormalise after sampling);
 * caller owns it.  PLOD_ERR_NULL, PLOD_ERR_BAD_PARAM (radius not finite
 * and > 0, height_scale not finite), PLOD_ERR_NO_MEMORY.  Built on
 * `threads` threads (< 1 counts as 1): the same map for any count.
 * Meshes sample it at each vertex instead of differencing heights there. */
plod_status plod_cubemap_build_normals(plod_cubemap **out, const plod_cubemap *heights,
                                       double radius, double height_scale, int threads);

/* ---- min/max pyramid (culling bounds) ----------------------------------- */
/* Builds the min/max pyramid of channel 0 (idempotent; call again after
 * editing texels).  PLOD_ERR_NULL or PLOD_ERR_NO_MEMORY. */
plod_status plod_cubemap_build_pyramid(plod_cubemap *cubemap);
/* Conservative bounds of channel 0 (normalised as sampling) over the face
 * rectangle [u0,u1]x[v0,v1] (clamped to the face), including every texel a
 * bilinear sample inside it can touch.  Requires the pyramid.  For CAR
 * maps (u, v) are as in plod_cubemap_sample_face.  Bad arguments give the
 * global range. */
void plod_cubemap_range(const plod_cubemap *cubemap, int face, double u0,
                        double v0, double u1, double v1, double *min_value,
                        double *max_value);
/* Bounds over the whole map (channel 0).  Requires the pyramid. */
void plod_cubemap_global_range(const plod_cubemap *cubemap, double *min_value,
                               double *max_value);
/* NaN texels of channel 0 counted by the last plod_cubemap_build_pyramid
 * (0 without a pyramid).  A height map with any is refused by
 * plod_planet_check: NaN heights would reach the emitted vertices. */
size_t plod_cubemap_nan_count(const plod_cubemap *cubemap);

/* ---- image layouts: how images on disk become cube maps --------------------
 * An image is either a cube map in the cross layout (4N x 3N, plod_resample.h)
 * or an equirectangular map (2:1: longitude -180..180 across, latitude
 * 90..-90 down) resampled into a projection; other shapes are resampled as
 * equirectangular anyway (callers warn).  Six-face output names a file per
 * face. */

/* Non-zero when a width x height image is read as a cross-layout cube map
 * (width divisible by 4 and height = 3/4 width). */
int plod_cubemap_is_cross_layout(int width, int height);
/* Non-zero when a width x height image has the equirectangular 2:1 shape. */
int plod_cubemap_is_equirectangular(int width, int height);
/* Face size an equirectangular image of `width` texels is resampled to when
 * the caller names none: as many texels per 90 degrees of longitude as the
 * image has (width / 4), in 1..PLOD_CUBEMAP_MAX_MAP_SIZE. */
int plod_cubemap_size_for_width(int width);
/* The file of face `face` when a cube map is written as six images: "{face}"
 * in `path` is replaced by the face number, else "_face<N>" goes before the
 * extension.  Writes at most `size` bytes to `out`; 0, or -1 when they do
 * not hold the name. */
int plod_cubemap_face_path(char *out, size_t size, const char *path, int face);

#ifdef __cplusplus
}
#endif
#endif /* PLOD_CUBEMAP_H */
