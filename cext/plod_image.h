/* plod_image.h -- plain 2-D images in memory, the headerless height grids
 * and GeoTIFF georeferencing.  The core decodes no image format itself: the
 * caller decodes (the Python layer through OpenImageIO) and hands the core
 * typed pixel buffers (plod_image_import), and a band of rows at a time for
 * maps larger than memory (plod_image_rows_reader).
 */
#ifndef PLOD_IMAGE_H
#define PLOD_IMAGE_H

#include <stddef.h>
#include "plod_cubemap.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Caller-visible image: rows top to bottom, channels interleaved.
 * plod_image_free releases what plod_image_alloc, plod_image_import (when it
 * converted) or plod_image_read_raw allocated; `borrowed` non-zero: the
 * pixels belong to someone else (plod_image_import without a copy), and
 * plod_image_free only forgets them. */
#define PLOD_IMAGE_DEFAULT_MAX_PIXELS ((size_t)1 << 28)

typedef struct plod_image {
    int width;
    int height;
    int channels;            /* 1..4 */
    plod_texel_type type;
    void *pixels;
    int borrowed;
} plod_image;

/* Allocates zeroed pixels and sets the fields.  PLOD_ERR_NULL;
 * PLOD_ERR_BAD_PARAM for a non-positive size, channels outside 1..4, an
 * unknown type or more than 2^31 texels; PLOD_ERR_NO_MEMORY. */
plod_status plod_image_alloc(plod_image *image, int width, int height,
                             int channels, plod_texel_type type);
void plod_image_free(plod_image *image);
size_t plod_image_texel_bytes(plod_texel_type type);

/* ---- sample types: a headerless grid's or an imported buffer's ------------ */
typedef enum plod_raw_type {
    PLOD_RAW_U8 = 0,
    PLOD_RAW_U16,
    PLOD_RAW_I16,
    PLOD_RAW_F32,
    PLOD_RAW_TYPE_COUNT
} plod_raw_type;

size_t plod_raw_sample_bytes(plod_raw_type type);

/* ---- images decoded by the caller --------------------------------------- */
/* A decoded image as the caller holds it: width x height texels of
 * `channels` interleaved samples of `type` (native byte order), rows top to
 * bottom, `bytes` in all. */
typedef struct plod_image_buffer {
    int width;
    int height;
    int channels;
    plod_raw_type type;
    const void *pixels;
    size_t bytes;
} plod_image_buffer;

/* How samples become texels: PLOD_IMPORT_TYPED keeps u8/u16/f32 (normalised
 * on sampling, as every map) and takes i16 as f32 holding the integer
 * values; PLOD_IMPORT_STORED makes every integer type f32 holding its
 * values (a DEM's metres: never normalised). */
typedef enum plod_import_mode { PLOD_IMPORT_TYPED = 0, PLOD_IMPORT_STORED } plod_import_mode;

/* *image from a caller's buffer: borrowed without a copy when the texel type
 * is the sample type (u8/u16/f32, typed) and `writable` is non-zero (later
 * stages may turn voids into NaN in place), else converted into new memory.
 * `name` (the file, for messages; may be NULL).  PLOD_ERR_NULL;
 * PLOD_ERR_BAD_IMAGE for a zero size, channels outside 1..4, more than
 * max_pixels texels (0 = PLOD_IMAGE_DEFAULT_MAX_PIXELS) or `bytes` that do
 * not match; PLOD_ERR_BAD_PARAM for an unknown type or mode;
 * PLOD_ERR_NO_MEMORY.  `message` (may be NULL) receives a NUL-terminated
 * explanation of up to message_size bytes. */
plod_status plod_image_import(plod_image *image, const plod_image_buffer *buffer,
                              plod_import_mode mode, int writable, size_t max_pixels,
                              const char *name, char *message, size_t message_size);

/* ---- reading an image a band of rows at a time (maps over max_pixels) ----
 * The caller's decoder behind a small interface: open a file for channel 0
 * (u8/u16 kept, other types as f32, normalised as plod_image_import's typed
 * mode), read rows [y0, y1) top to bottom into width * (y1 - y0) texels of
 * the type open reported, close.  Statuses and messages as
 * plod_image_import's (PLOD_ERR_IO for a missing or unreadable file);
 * `context` is passed back unchanged. */
typedef struct plod_image_rows_reader {
    plod_status (*open)(void *context, const char *path, void **rows, int *width, int *height,
                        plod_texel_type *type, char *message, size_t message_size);
    plod_status (*read)(void *context, void *rows, int y0, int y1, void *pixels,
                        char *message, size_t message_size);
    void (*close)(void *context, void *rows);
    void *context;
} plod_image_rows_reader;

/* ---- headerless height grids (image_raw.c) ------------------------------ */
/* A headerless grid: rows top to bottom, one sample per texel. */
typedef struct plod_raw_format {
    int width;
    int height;
    plod_raw_type type;
    int big_endian; /* non-zero: most significant byte first */
} plod_raw_format;

/* Reads a headerless grid as a 1-channel image: u8 and u16 keep their type
 * (normalised on sampling as other maps), i16 becomes f32 holding the
 * integer values (in a .hgt file -32768 is a void: NaN), f32 stays.  The
 * file size must be exactly width * height * sample bytes
 * (PLOD_ERR_BAD_IMAGE otherwise); PLOD_ERR_IO for a missing or unreadable
 * file, PLOD_ERR_BAD_IMAGE beyond max_pixels (0 = the default). */
plod_status plod_image_read_raw(plod_image *image, const char *path,
                                const plod_raw_format *format, size_t max_pixels,
                                char *message, size_t message_size);
/* The format of a .hgt (big-endian i16, 1201 or 3601 a side, from the file
 * size), .r16 or .raw file (u16 little-endian, square or 2:1 from the file
 * size).  PLOD_ERR_BAD_IMAGE when the size fits none; PLOD_ERR_BAD_PARAM
 * for another extension; PLOD_ERR_IO for a missing file. */
plod_status plod_raw_guess(const char *path, plod_raw_format *format, char *message,
                           size_t message_size);
/* Non-zero for a path ending in .hgt, .r16 or .raw (any case). */
int plod_raw_is_raw_path(const char *path);
/* South-west corner of an SRTM tile from its file name (N45E006.hgt: lat 45,
 * lon 6; S and W negative); 0 when the name does not follow the scheme. */
int plod_hgt_origin(const char *path, int *lon, int *lat);
/* Reinterprets u8/u16 texels as two's complement (int8/int16 data stored
 * in an unsigned file): the image becomes f32 holding the signed integer
 * values.  f32 images are left as they are. */
plod_status plod_image_reinterpret_signed(plod_image *image);

/* ---- GeoTIFF georeferencing (geotiff.c) -------------------------------- */
/* What the first image directory of a TIFF says about its placement.
 * Returned by plod_georef_read; zero members: the tag or key is absent. */
typedef struct plod_georef {
    int present;          /* any georeferencing tag or GeoKeyDirectory */
    int has_scale;        /* ModelPixelScale: scale[0..2] (x, y, z per pixel) */
    double scale[3];
    int tiepoint_count;   /* ModelTiepoint: the first in tiepoint (I, J, K, X, Y, Z) */
    double tiepoint[6];
    int has_transform;    /* ModelTransformation: row-major 4 x 4 */
    double transform[16];
    int has_keys;         /* a GeoKeyDirectory; its keys below */
    int model_type;       /* GTModelTypeGeoKey: 1 projected, 2 geographic, 3 geocentric */
    int raster_type;      /* GTRasterTypeGeoKey: 1 PixelIsArea (also when 0), 2 PixelIsPoint */
    int geographic_type;  /* GeographicTypeGeoKey: EPSG code (4326 WGS 84) */
    int angular_units;    /* GeogAngularUnitsGeoKey: EPSG code (9102 degree) */
    int projected_type;   /* ProjectedCSTypeGeoKey: EPSG code */
    int has_nodata;       /* GDAL_NODATA: samples equal to nodata are voids */
    double nodata;
} plod_georef;

/* Reads the georeferencing of a classic or BigTIFF file (either byte
 * order).  A file that is not a TIFF, or a TIFF without these tags: PLOD_OK
 * with geo->present 0.  PLOD_ERR_IO for a missing file, PLOD_ERR_BAD_IMAGE
 * for a TIFF whose directory or tag values lie beyond its end or have the
 * wrong type (a truncated or corrupt file); never reads past the file. */
plod_status plod_georef_read(plod_georef *geo, const char *path, char *message,
                             size_t message_size);
/* The box {west, south, east, north} in degrees of the sample centres of a
 * width x height raster (the corner samples, pixel is point, as
 * plod_inset_desc wants it): PixelIsArea shifts the tiepoint half a pixel
 * east and south, PixelIsPoint does not.  Rounded to 1e-9 degrees.
 * Supported: geographic lon/lat in degrees, WGS 84 (EPSG:4326; NAD83 4269
 * and ETRS89 4258 taken as WGS 84), one tiepoint with ModelPixelScale or a
 * ModelTransformation without rotation, north up.  Anything else (a
 * projected or geocentric CRS, no CRS named, a rotated transform, several
 * tiepoints, south-up): PLOD_ERR_BAD_IMAGE naming what is unsupported;
 * PLOD_ERR_BAD_PARAM when geo->present is 0. */
plod_status plod_georef_box(const plod_georef *geo, int width, int height, double box[4],
                            char *message, size_t message_size);

#ifdef __cplusplus
}
#endif
#endif /* PLOD_IMAGE_H */
