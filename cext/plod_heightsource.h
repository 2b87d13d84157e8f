/* plod_heightsource.h -- height data the planet samples without holding it
 * in a cube map: a small interface (sample at a direction, conservative
 * bounds over a spherical cap, texel size, no-data count) and its
 * out-of-core implementation, a tiled equirectangular map read through a
 * bounded cache (plod_tiles); regional insets.  (The finished surface the
 * mesh emitter samples is plod_surface.h.)
 *
 * A tile file is written once from an equirectangular map (RAW/R16/HGT
 * grid, or any image the caller's reader gives a band of rows at a time): a header, the
 * min/max of every tile, then the tiles (tile x tile texels, row-major,
 * north first, each tile contiguous, edge tiles padded).  Reading it keeps
 * the per-tile bounds (8 bytes per tile) and at most `cache_bytes` of
 * tiles in memory, whatever the map's size.
 */
#ifndef PLOD_HEIGHTSOURCE_H
#define PLOD_HEIGHTSOURCE_H

#include <stddef.h>
#include <stdint.h>
#include "plod_image.h"
#include "plod_resample.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- the interface the planet samples ------------------------------------ */
typedef struct plod_height_source_ops {
    /* Map value (normalised as cube maps sample: u8 / 255, u16 / 65535,
     * f32 as stored) at a unit direction; NaN where it cannot be read. */
    double (*sample)(const void *self, const double dir[3]);
    /* Conservative value bounds over the spherical cap of unit centre
     * `axis` and angular radius `angle` (radians); *texels: the cap's
     * extent in texels (INFINITY when unknown). */
    void (*range_cap)(const void *self, const double axis[3], double angle, double *lo,
                      double *hi, double *texels);
    /* Value bounds over the whole sphere. */
    void (*global_range)(const void *self, double *lo, double *hi);
    /* Angular size of a texel at a unit direction (radians): the data's
     * local resolution (detail below it, normals from differences). */
    double (*texel_angle)(const void *self, const double dir[3]);
    /* No-data (NaN) values in the data; may be NULL (none known). */
    size_t (*nan_count)(const void *self);
} plod_height_source_ops;

typedef struct plod_height_source {
    const plod_height_source_ops *ops;
    const void *self;
} plod_height_source;

/* Bounds of a width x height equirectangular map (u = lon / 180 deg,
 * v = lat / 90 deg) over the spherical cap (axis, angle), through the
 * cap's lon/lat box: one box, two across the +-180 deg seam, the full
 * width where a pole is inside.  range_uv(context, u0, v0, u1, v1, lo, hi)
 * gives a box's bounds.  For a cap not inside a hemisphere *lo and *hi are
 * left as they are (the caller's global range) and *texels is INFINITY;
 * else *texels is the box's larger side in map texels. */
typedef void (*plod_range_uv_fn)(const void *context, double u0, double v0, double u1,
                                 double v1, double *lo, double *hi);
void plod_lonlat_cap_range(const double axis[3], double angle, int width, int height,
                           plod_range_uv_fn range_uv, const void *context, double *lo,
                           double *hi, double *texels);

/* ---- tiled equirectangular maps (heighttiles.c) ------------------------- */
typedef struct plod_tiles plod_tiles; /* opaque */

#define PLOD_TILES_DEFAULT_TILE 128
#define PLOD_TILES_DEFAULT_CACHE_BYTES ((size_t)128 << 20)

/* Writes the tile file of an equirectangular map.  `raw` (may be NULL)
 * gives a headerless grid's layout; NULL: .hgt/.r16/.raw by their size,
 * other files through `reader` (may be NULL for grids), a band of rows at a
 * time: no size cap.  Channel 0 only; i16 grids become
 * f32 integer values.  `is_signed`: u8/u16 samples are two's complement
 * (stored as f32).  The file is written to a temporary name and renamed,
 * so a cancelled or failed build leaves nothing.  progress may be NULL.
 * `tile`: a power of two in 16..4096, 0 = PLOD_TILES_DEFAULT_TILE.
 * PLOD_ERR_NULL, PLOD_ERR_BAD_PARAM (tile size; no reader for an image),
 * the reading errors of the grid or reader, PLOD_ERR_IO (writing), PLOD_ERR_CANCELLED,
 * PLOD_ERR_NO_MEMORY; `message` (may be NULL) explains. */
plod_status plod_tiles_build(const char *source, const plod_raw_format *raw,
                             const plod_image_rows_reader *reader, int is_signed,
                             const char *tiles_path, int tile, plod_progress_fn progress,
                             void *user, char *message, size_t message_size);
/* Opens a tile file; cache_bytes (0 = default) bounds the tiles held in
 * memory (at least 16 tiles).  PLOD_ERR_IO / PLOD_ERR_BAD_IMAGE with a
 * message for a missing, truncated or foreign file; PLOD_ERR_NULL,
 * PLOD_ERR_NO_MEMORY.  *out is NULL on failure. */
plod_status plod_tiles_open(plod_tiles **out, const char *tiles_path, size_t cache_bytes,
                            char *message, size_t message_size);
void plod_tiles_destroy(plod_tiles *tiles);
/* Whether tiles_path is a complete tile file of `source` in its current
 * size and modification time (then no rebuild is needed). */
int plod_tiles_current(const char *tiles_path, const char *source);

int plod_tiles_width(const plod_tiles *tiles);
int plod_tiles_height(const plod_tiles *tiles);
plod_texel_type plod_tiles_type(const plod_tiles *tiles);
/* NaN texels in the map (counted when the file was built). */
size_t plod_tiles_nan_count(const plod_tiles *tiles);
/* Bytes of tiles in the cache now, and its bound. */
size_t plod_tiles_cached_bytes(const plod_tiles *tiles);
size_t plod_tiles_cache_limit(const plod_tiles *tiles);
/* Tile reads that failed since opening (file changed or vanished): their
 * samples were NaN. */
size_t plod_tiles_read_errors(const plod_tiles *tiles);

/* Bilinear sample at (u, v) = (lon / 180 deg, lat / 90 deg), clamped to
 * [-1, 1], with the conventions of a CAR cube map (wrap in longitude,
 * reflection across the poles); normalised as cube maps sample.  Safe from
 * several threads at once; the value never depends on what is cached. */
double plod_tiles_sample_uv(const plod_tiles *tiles, double u, double v);
/* Conservative bounds over the (u, v) box (every texel a bilinear tap in it
 * can read): exact for boxes within 2 x 2 tiles, per-tile bounds (and a
 * pyramid over them) for larger ones. */
void plod_tiles_range_uv(const plod_tiles *tiles, double u0, double v0, double u1, double v1,
                         double *lo, double *hi);
void plod_tiles_global_range(const plod_tiles *tiles, double *lo, double *hi);
/* The tiles as a height source (valid while `tiles` lives). */
plod_height_source plod_tiles_source(const plod_tiles *tiles);

/* ---- regional insets (insets.c) ------------------------------------------ */
/* A regional grid placed by longitude and latitude: samples at the corners
 * (pixel is point: sample (0, 0) at west/north, (width-1, height-1) at
 * east/south, as SRTM tiles), in metres, row 0 north, NaN = void. */
typedef struct plod_inset_desc {
    double west, south, east, north; /* degrees; west < east, no date-line crossing */
    int width, height;               /* >= 2 */
    const float *metres;             /* copied by plod_insets_create */
} plod_inset_desc;

typedef struct plod_insets plod_insets; /* opaque */

/* Copies the grids.  `feather`: the blend border's width as a fraction of
 * each inset's smaller side (0..0.5); edges shared with another inset are
 * not feathered.  Overlapping insets are refused (PLOD_ERR_BAD_PARAM, the
 * message names both), as are bad boxes, sizes or feathers
 * (PLOD_ERR_BAD_PARAM); PLOD_ERR_NULL, PLOD_ERR_NO_MEMORY. */
plod_status plod_insets_create(plod_insets **out, const plod_inset_desc *descs, size_t count,
                               double feather, char *message, size_t message_size);
void plod_insets_destroy(plod_insets *insets);
size_t plod_insets_count(const plod_insets *insets);
/* The height at a unit direction given the global data's `base_m`: inside
 * an inset base + w (inset - base), w the smoothstep of the distance to
 * its feathered edges; base_m outside every inset and over voids.
 * *texel_angle (may be NULL): the inset's sample spacing (radians) where it
 * counts, else 0. */
double plod_insets_blend(const plod_insets *insets, const double dir[3], double base_m,
                         double *texel_angle);
/* Where an inset counts at dir, for the detail field: the blend weight w
 * of plod_insets_blend (0 outside every inset and over voids) and the
 * coarsest sample spacing (radians) of its mosaic, the insets joined to it
 * by shared (unfeathered) edges, 0 where w is 0.  One spacing over a
 * mosaic: the detail that starts below it is continuous across the
 * mosaic's inner edges. */
typedef struct plod_inset_weight {
    double weight;
    double mosaic_texel_angle;
} plod_inset_weight;
/* plod_insets_blend, and *where (may be NULL) as above. */
double plod_insets_blend_weight(const plod_insets *insets, const double dir[3], double base_m,
                                double *texel_angle, plod_inset_weight *where);
/* The largest mosaic sample spacing (radians) of the insets meeting the
 * cap's lon/lat box, 0 when none does. */
double plod_insets_mosaic_texel_cap(const plod_insets *insets, const double axis[3],
                                    double angle);
/* How the insets under a cap vary: their sample spacing (radians, the
 * largest mosaic spacing there) and their mean height change per sample
 * over the pyramid blocks the range was read from (metres). */
typedef struct plod_insets_relief {
    double texel_angle;
    double per_sample;
} plod_insets_relief;
/* Metres bounds of the insets' samples under the cap's lon/lat box (from a
 * min/max pyramid: they tighten as the cap shrinks, down to blocks of 4
 * samples); 0 when no inset meets it (the blend lies between the global
 * height and these).  *relief (may be NULL): as above. */
int plod_insets_range_cap(const plod_insets *insets, const double axis[3], double angle,
                          double *lo, double *hi, plod_insets_relief *relief);
void plod_insets_global_range(const plod_insets *insets, double *lo, double *hi);

#ifdef __cplusplus
}
#endif
#endif /* PLOD_HEIGHTSOURCE_H */
