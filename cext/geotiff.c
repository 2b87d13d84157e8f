/* geotiff.c -- the georeferencing of a GeoTIFF: the few tags that place a
 * raster on the globe, read from the first image file directory (IFD) of a
 * classic or BigTIFF file in either byte order, and the lon/lat box of the
 * raster's sample centres they give.
 *
 * Tags (Ritter, Ruth et al., GeoTIFF Format Specification, revision 1.0,
 * 2000; OGC GeoTIFF Standard 1.1, 2019): ModelPixelScale (33550),
 * ModelTiepoint (33922), ModelTransformation (34264), GeoKeyDirectory
 * (34735, read for GTModelType 1024, GTRasterType 1025, GeographicType
 * 2048, GeogAngularUnits 2054, ProjectedCSType 3072) and GDAL's no-data
 * value (42113, ASCII).  The pixels themselves are OpenImageIO's business
 * (image_io.cpp); this reader only walks the directory, every count and
 * offset checked against the file's size before it is read, so a truncated
 * or hostile file is an error with a message, never a wild read.
 *
 * Raster space: with PixelIsArea (the default) raster point (i, j) is the
 * north-west corner of pixel (i, j), whose sample lies half a pixel further
 * east and south; with PixelIsPoint (i, j) is the sample itself.
 */
#include "plod_image.h"
#include "plod_platform.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum {
    PLOD__TAG_MODEL_PIXEL_SCALE = 33550,
    PLOD__TAG_MODEL_TIEPOINT = 33922,
    PLOD__TAG_MODEL_TRANSFORMATION = 34264,
    PLOD__TAG_GEO_KEY_DIRECTORY = 34735,
    PLOD__TAG_GDAL_NODATA = 42113,

    PLOD__KEY_MODEL_TYPE = 1024,
    PLOD__KEY_RASTER_TYPE = 1025,
    PLOD__KEY_GEOGRAPHIC_TYPE = 2048,
    PLOD__KEY_ANGULAR_UNITS = 2054,
    PLOD__KEY_PROJECTED_TYPE = 3072,

    PLOD__MAX_ENTRIES = 4096,  /* directory entries; real files have ~20 */
    PLOD__MAX_GEO_KEYS = 1024,
};

typedef struct plod__tiff {
    plod_file file;
    unsigned long long size;
    int big_endian;
    int big_tiff; /* 8-byte offsets and counts, 20-byte entries */
} plod__tiff;

static unsigned long long plod__tiff_uint(const plod__tiff *t, const unsigned char *p, int bytes)
{
    unsigned long long v = 0;
    for (int i = 0; i < bytes; i++)
        v |= (unsigned long long)p[t->big_endian ? bytes - 1 - i : i] << (8 * i);
    return v;
}

/* Reads `bytes` at `offset`; 0 when they lie (partly) beyond the file. */
static int plod__tiff_read(const plod__tiff *t, unsigned long long offset, void *out, size_t bytes)
{
    if (offset > t->size || bytes > t->size - offset)
        return 0;
    return plod_file_read_at(t->file, out, bytes, offset);
}

static size_t plod__tiff_type_bytes(unsigned type)
{
    switch (type) {
    case 1: case 2: case 6: case 7: return 1; /* BYTE ASCII SBYTE UNDEFINED */
    case 3: case 8: return 2;                 /* SHORT SSHORT */
    case 4: case 9: case 11: case 13: return 4; /* LONG SLONG FLOAT IFD */
    case 5: case 10: case 12: case 16: case 17: case 18: return 8;
    default: return 0;
    }
}

/* An entry's values: `count` items of `type` inline in `field` or at the
 * offset it holds.  Returns a malloc'ed copy in file byte order, NULL with
 * *corrupt set when it does not fit the file. */
static unsigned char *plod__tiff_values(const plod__tiff *t, const unsigned char *field,
                                        unsigned type, unsigned long long count,
                                        unsigned long long max_count, int *corrupt)
{
    size_t item = plod__tiff_type_bytes(type);
    size_t inline_bytes = t->big_tiff ? 8 : 4;
    if (!item || count == 0 || count > max_count) {
        *corrupt = 1;
        return NULL;
    }
    size_t bytes = (size_t)count * item;
    unsigned char *out = malloc(bytes + 1);
    if (!out)
        return NULL;
    if (bytes <= inline_bytes) {
        memcpy(out, field, bytes);
    } else if (!plod__tiff_read(t, plod__tiff_uint(t, field, (int)inline_bytes), out, bytes)) {
        free(out);
        *corrupt = 1;
        return NULL;
    }
    out[bytes] = 0;
    return out;
}

/* Item `i` of DOUBLE or FLOAT values as a double. */
static double plod__tiff_real(const plod__tiff *t, const unsigned char *values, unsigned type,
                              size_t i)
{
    if (type == 12) {
        uint64_t bits = plod__tiff_uint(t, values + 8 * i, 8);
        double v;
        memcpy(&v, &bits, sizeof v);
        return v;
    }
    uint32_t bits = (uint32_t)plod__tiff_uint(t, values + 4 * i, 4);
    float v;
    memcpy(&v, &bits, sizeof v);
    return v;
}

static void plod__geo_keys(plod_georef *geo, const plod__tiff *t, const unsigned char *shorts,
                           size_t count)
{
    size_t keys = (size_t)plod__tiff_uint(t, shorts + 6, 2);
    for (size_t k = 0; k < keys && 4 * (k + 2) <= count; k++) {
        const unsigned char *e = shorts + 8 * (k + 1);
        unsigned id = (unsigned)plod__tiff_uint(t, e, 2);
        unsigned location = (unsigned)plod__tiff_uint(t, e + 2, 2);
        int value = (int)plod__tiff_uint(t, e + 6, 2);
        if (location != 0)
            continue; /* a double or ASCII parameter: none of the keys read here */
        switch (id) {
        case PLOD__KEY_MODEL_TYPE: geo->model_type = value; break;
        case PLOD__KEY_RASTER_TYPE: geo->raster_type = value; break;
        case PLOD__KEY_GEOGRAPHIC_TYPE: geo->geographic_type = value; break;
        case PLOD__KEY_ANGULAR_UNITS: geo->angular_units = value; break;
        case PLOD__KEY_PROJECTED_TYPE: geo->projected_type = value; break;
        default: break;
        }
    }
}

/* Reads the first directory's georeferencing; 1 on success, 0 corrupt. */
static int plod__tiff_georef(plod_georef *geo, const plod__tiff *t, unsigned long long ifd)
{
    size_t count_bytes = t->big_tiff ? 8 : 2, entry_bytes = t->big_tiff ? 20 : 12;
    unsigned char head[8];
    if (!plod__tiff_read(t, ifd, head, count_bytes))
        return 0;
    unsigned long long entries = plod__tiff_uint(t, head, (int)count_bytes);
    if (entries == 0 || entries > PLOD__MAX_ENTRIES)
        return 0;
    unsigned char *table = malloc((size_t)entries * entry_bytes);
    if (!table || !plod__tiff_read(t, ifd + count_bytes, table, (size_t)entries * entry_bytes)) {
        free(table);
        return 0;
    }
    int corrupt = 0;
    /* strip or tile offsets and byte counts: the pixel data must lie inside
     * the file (OpenImageIO 2.4 reads a truncated strip as zeros) */
    unsigned char *data_at[2] = {NULL, NULL}, *data_bytes[2] = {NULL, NULL};
    unsigned data_type[2][2] = {{0, 0}, {0, 0}};
    unsigned long long data_count[2][2] = {{0, 0}, {0, 0}};
    for (size_t e = 0; e < entries && !corrupt; e++) {
        const unsigned char *entry = table + e * entry_bytes;
        unsigned tag = (unsigned)plod__tiff_uint(t, entry, 2);
        unsigned type = (unsigned)plod__tiff_uint(t, entry + 2, 2);
        unsigned long long count = plod__tiff_uint(t, entry + 4, t->big_tiff ? 8 : 4);
        const unsigned char *field = entry + (t->big_tiff ? 12 : 8);
        int real = type == 11 || type == 12;
        unsigned char *values = NULL;
        switch (tag) {
        case PLOD__TAG_MODEL_PIXEL_SCALE:
            if (!real || count < 2) {
                corrupt = 1;
                break;
            }
            if (!(values = plod__tiff_values(t, field, type, count, 3, &corrupt)))
                break;
            for (size_t i = 0; i < 3; i++)
                geo->scale[i] = i < count ? plod__tiff_real(t, values, type, i) : 0.0;
            geo->has_scale = 1;
            break;
        case PLOD__TAG_MODEL_TIEPOINT:
            if (!real || count < 6) {
                corrupt = 1;
                break;
            }
            if (!(values = plod__tiff_values(t, field, type, count, 6 * 65536, &corrupt)))
                break;
            for (size_t i = 0; i < 6; i++)
                geo->tiepoint[i] = plod__tiff_real(t, values, type, i);
            geo->tiepoint_count = (int)(count / 6);
            break;
        case PLOD__TAG_MODEL_TRANSFORMATION:
            if (!real || count != 16) {
                corrupt = 1;
                break;
            }
            if (!(values = plod__tiff_values(t, field, type, count, 16, &corrupt)))
                break;
            for (size_t i = 0; i < 16; i++)
                geo->transform[i] = plod__tiff_real(t, values, type, i);
            geo->has_transform = 1;
            break;
        case PLOD__TAG_GEO_KEY_DIRECTORY:
            if (type != 3 || count < 4) {
                corrupt = 1;
                break;
            }
            if (!(values = plod__tiff_values(t, field, type, count, 4 * (PLOD__MAX_GEO_KEYS + 1),
                                             &corrupt)))
                break;
            plod__geo_keys(geo, t, values, (size_t)count);
            geo->has_keys = 1;
            break;
        case PLOD__TAG_GDAL_NODATA:
            if (type != 2 || !(values = plod__tiff_values(t, field, type, count, 256, &corrupt)))
                break;
            {
                char *end;
                double v = strtod((const char *)values, &end);
                if (end != (const char *)values) {
                    geo->nodata = v;
                    geo->has_nodata = 1;
                }
            }
            break;
        case 273: case 279: case 324: case 325: { /* Strip/Tile Offsets/ByteCounts */
            int tiles = tag >= 324, counts = tag == 279 || tag == 325;
            unsigned char **slot = counts ? &data_bytes[tiles] : &data_at[tiles];
            if ((type != 3 && type != 4 && type != 16) || *slot) {
                corrupt = 1;
                break;
            }
            *slot = plod__tiff_values(t, field, type, count, (unsigned long long)1 << 24, &corrupt);
            data_type[tiles][counts] = type;
            data_count[tiles][counts] = count;
            break;
        }
        default:
            break;
        }
        free(values);
    }
    for (int k = 0; k < 2 && !corrupt; k++) {
        if (!data_at[k] && !data_bytes[k])
            continue;
        if (!data_at[k] || !data_bytes[k] || data_count[k][0] != data_count[k][1]) {
            corrupt = 1;
            break;
        }
        int at_size = (int)plod__tiff_type_bytes(data_type[k][0]);
        int bytes_size = (int)plod__tiff_type_bytes(data_type[k][1]);
        for (unsigned long long i = 0; i < data_count[k][0] && !corrupt; i++) {
            unsigned long long at = plod__tiff_uint(t, data_at[k] + i * at_size, at_size);
            unsigned long long bytes =
                plod__tiff_uint(t, data_bytes[k] + i * bytes_size, bytes_size);
            corrupt = at > t->size || bytes > t->size - at;
        }
    }
    for (int k = 0; k < 2; k++)
        free(data_at[k]), free(data_bytes[k]);
    free(table);
    geo->present = geo->has_scale || geo->tiepoint_count || geo->has_transform || geo->has_keys;
    return !corrupt;
}

plod_status plod_georef_read(plod_georef *geo, const char *path, char *message,
                             size_t message_size)
{
    plod_status_format(message, message_size, "%s", "");
    if (!geo || !path)
        return PLOD_ERR_NULL;
    memset(geo, 0, sizeof *geo);
    plod_path_info info;
    plod__tiff t = {0};
    errno = 0;
    if (!plod_path_info_get(path, &info) || !info.regular ||
        !plod_file_open(&t.file, path, PLOD_FILE_READ)) {
        plod_status_format(message, message_size, "cannot open '%s': %s", path,
                          errno ? strerror(errno) : "not a regular file");
        return PLOD_ERR_IO;
    }
    t.size = (unsigned long long)info.size;
    unsigned char head[16];
    plod_status status = PLOD_OK;
    size_t got = t.size < sizeof head ? (size_t)t.size : sizeof head;
    if (!plod_file_read_at(t.file, head, got, 0))
        got = 0;
    int tiff = got >= 4 && ((head[0] == 'I' && head[1] == 'I') ||
                            (head[0] == 'M' && head[1] == 'M'));
    if (tiff) {
        t.big_endian = head[0] == 'M';
        unsigned magic = (unsigned)plod__tiff_uint(&t, head + 2, 2);
        t.big_tiff = magic == 43;
        tiff = magic == 42 || magic == 43;
    }
    if (tiff) {
        int whole_header = got >= (t.big_tiff ? 16u : 8u);
        unsigned long long ifd = !whole_header ? 0
                                 : t.big_tiff  ? plod__tiff_uint(&t, head + 8, 8)
                                               : plod__tiff_uint(&t, head + 4, 4);
        if (!whole_header || !plod__tiff_georef(geo, &t, ifd)) {
            memset(geo, 0, sizeof *geo);
            plod_status_format(message, message_size,
                              "'%s' is a corrupt or truncated TIFF file (its first image "
                              "directory or pixel data lie beyond the file's %llu bytes, or "
                              "the directory is malformed)",
                              path, t.size);
            status = PLOD_ERR_BAD_IMAGE;
        }
    }
    plod_file_close(t.file);
    return status;
}

/* 1e-9 degrees (0.1 mm): the rounding of the boxes, so that tags written
 * with the usual decimal rounding give the box a caller would type and
 * tiles meet exactly at shared edges. */
static double plod__nanodegrees(double degrees) { return round(degrees * 1e9) / 1e9; }

static const char *plod__geographic_name(int code)
{
    switch (code) {
    case 4326: return "WGS 84";
    case 4269: return "NAD83";
    case 4258: return "ETRS89";
    default: return NULL;
    }
}

plod_status plod_georef_box(const plod_georef *geo, int width, int height, double box[4],
                            char *message, size_t message_size)
{
    plod_status_format(message, message_size, "%s", "");
    if (!geo || !box)
        return PLOD_ERR_NULL;
    if (!geo->present) {
        plod_status_format(message, message_size, "no GeoTIFF georeferencing");
        return PLOD_ERR_BAD_PARAM;
    }
    if (geo->model_type == 1 || (geo->model_type == 0 && geo->projected_type)) {
        plod_status_format(message, message_size,
                          "a projected CRS (GTModelTypeGeoKey 1, ProjectedCSTypeGeoKey %d%s) "
                          "is not supported: insets need geographic longitude/latitude "
                          "(EPSG:4326); reproject the file, e.g. gdalwarp -t_srs EPSG:4326",
                          geo->projected_type,
                          geo->projected_type >= 32601 && geo->projected_type <= 32760 ? ", UTM"
                                                                                        : "");
        return PLOD_ERR_BAD_IMAGE;
    }
    if (geo->model_type == 3 || (geo->model_type && geo->model_type != 2)) {
        plod_status_format(message, message_size,
                          "GTModelTypeGeoKey %d (%s) is not supported: insets need geographic "
                          "longitude/latitude (EPSG:4326)",
                          geo->model_type, geo->model_type == 3 ? "geocentric" : "unknown");
        return PLOD_ERR_BAD_IMAGE;
    }
    if (!geo->geographic_type) {
        plod_status_format(message, message_size,
                          "the GeoTIFF names no geographic CRS (GeographicTypeGeoKey missing): "
                          "its placement is unknown; give the box (west, south, east, north)");
        return PLOD_ERR_BAD_IMAGE;
    }
    if (!plod__geographic_name(geo->geographic_type)) {
        plod_status_format(message, message_size,
                          "geographic CRS EPSG:%d is not supported (WGS 84, EPSG:4326, is; "
                          "NAD83 4269 and ETRS89 4258 are taken as WGS 84)",
                          geo->geographic_type);
        return PLOD_ERR_BAD_IMAGE;
    }
    if (geo->angular_units && geo->angular_units != 9102) {
        plod_status_format(message, message_size,
                          "angular unit EPSG:%d is not supported (degrees, 9102, are)",
                          geo->angular_units);
        return PLOD_ERR_BAD_IMAGE;
    }
    if (geo->raster_type && geo->raster_type != 1 && geo->raster_type != 2) {
        plod_status_format(message, message_size,
                          "GTRasterTypeGeoKey %d is neither PixelIsArea (1) nor PixelIsPoint (2)",
                          geo->raster_type);
        return PLOD_ERR_BAD_IMAGE;
    }
    double scale_x, scale_y, x0, y0; /* degrees per pixel; raster point (0, 0) */
    if (geo->has_transform) {
        const double *m = geo->transform;
        if (m[1] != 0.0 || m[4] != 0.0) {
            plod_status_format(message, message_size,
                              "a rotated or sheared ModelTransformation (%g, %g off the "
                              "diagonal) is not supported: only north-up grids are",
                              m[1], m[4]);
            return PLOD_ERR_BAD_IMAGE;
        }
        scale_x = m[0], scale_y = -m[5], x0 = m[3], y0 = m[7];
    } else if (geo->has_scale && geo->tiepoint_count == 1) {
        const double *tp = geo->tiepoint;
        scale_x = geo->scale[0], scale_y = geo->scale[1];
        x0 = tp[3] - tp[0] * scale_x, y0 = tp[4] + tp[1] * scale_y;
    } else {
        plod_status_format(message, message_size,
                          geo->tiepoint_count > 1
                              ? "%d tiepoints (a warped grid) are not supported: one tiepoint "
                                "and ModelPixelScale, or ModelTransformation, are"
                              : "the GeoTIFF has %d tiepoints and %s ModelPixelScale, and no "
                                "ModelTransformation: its placement is incomplete",
                          geo->tiepoint_count, geo->has_scale ? "a" : "no");
        return PLOD_ERR_BAD_IMAGE;
    }
    if (!(scale_x > 0.0 && scale_y > 0.0) || !isfinite(scale_x) || !isfinite(scale_y) ||
        !isfinite(x0) || !isfinite(y0)) {
        plod_status_format(message, message_size,
                          "pixel size %g x %g degrees at (%g, %g): only north-up, west-to-east "
                          "grids with positive, finite pixel sizes are supported",
                          scale_x, -scale_y, x0, y0);
        return PLOD_ERR_BAD_IMAGE;
    }
    double half = geo->raster_type == 2 ? 0.0 : 0.5; /* PixelIsArea: centre of pixel 0 */
    double west = x0 + half * scale_x, north = y0 - half * scale_y;
    box[0] = plod__nanodegrees(west);
    box[1] = plod__nanodegrees(north - (height - 1) * scale_y);
    box[2] = plod__nanodegrees(west + (width - 1) * scale_x);
    box[3] = plod__nanodegrees(north);
    return PLOD_OK;
}
