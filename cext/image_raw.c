/* image_raw.c -- headerless height grids: RAW/R16 as terrain tools export
 * them (width, height, sample type and byte order given) and SRTM .hgt
 * tiles (big-endian int16, 1201 or 3601 samples a side, -32768 = void).
 *
 * Unsigned samples keep their type (u8, u16: normalised on sampling as
 * every other map); signed int16 samples become float32 holding their
 * integer values (SRTM: metres), voids NaN; float32 samples stay as they
 * are.  The file size must equal width * height * sample size exactly: a
 * guessed or mistyped size is an error, never a garbled map.
 */
#include "plod_image.h"
#include "plod_platform.h"

#include <errno.h>
#include <stdint.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

size_t plod_raw_sample_bytes(plod_raw_type type)
{
    switch (type) {
    case PLOD_RAW_U8: return 1;
    case PLOD_RAW_U16:
    case PLOD_RAW_I16: return 2;
    case PLOD_RAW_F32: return 4;
    default: return 0;
    }
}

static const char *plod__raw_type_name(plod_raw_type type)
{
    static const char *const names[] = {"u8", "u16", "i16", "f32"};
    return (unsigned)type < PLOD_RAW_TYPE_COUNT ? names[type] : "?";
}

/* Lower-case extension without the dot ("" if none), at most 7 bytes. */
static void plod__raw_extension(const char *path, char ext[8])
{
    ext[0] = '\0';
    const char *slash = strrchr(path, '/');
    const char *dot = strrchr(path, '.');
    if (!dot || (slash && dot < slash) || strlen(dot + 1) > 7)
        return;
    size_t i = 0;
    for (const char *c = dot + 1; *c; c++)
        ext[i++] = (char)(*c >= 'A' && *c <= 'Z' ? *c - 'A' + 'a' : *c);
    ext[i] = '\0';
}

int plod_raw_is_raw_path(const char *path)
{
    char ext[8];
    plod__raw_extension(path, ext);
    return strcmp(ext, "hgt") == 0 || strcmp(ext, "r16") == 0 || strcmp(ext, "raw") == 0;
}

int plod_hgt_origin(const char *path, int *lon, int *lat)
{
    const char *slash = strrchr(path, '/');
    const char *name = slash ? slash + 1 : path;
    /* N45E006.hgt: latitude of the south edge, longitude of the west edge */
    char ns = name[0], ew = name[3];
    if (!(ns == 'N' || ns == 'S' || ns == 'n' || ns == 's') ||
        !(ew == 'E' || ew == 'W' || ew == 'e' || ew == 'w'))
        return 0;
    int digits[5];
    const int at[5] = {1, 2, 4, 5, 6};
    for (int k = 0; k < 5; k++) {
        char c = name[at[k]];
        if (c < '0' || c > '9')
            return 0;
        digits[k] = c - '0';
    }
    int la = digits[0] * 10 + digits[1], lo = digits[2] * 100 + digits[3] * 10 + digits[4];
    if (ns == 'S' || ns == 's')
        la = -la;
    if (ew == 'W' || ew == 'w')
        lo = -lo;
    if (la < -90 || la > 89 || lo < -180 || lo > 179)
        return 0;
    *lat = la;
    *lon = lo;
    return 1;
}

static int plod__file_size(const char *path, long long *size, char *message, size_t message_size,
                           plod_status *status)
{
    plod_path_info info;
    if (!plod_path_info_get(path, &info)) {
        plod_status_format(message, message_size, "cannot open '%s': %s", path, strerror(errno));
        *status = PLOD_ERR_IO;
        return 0;
    }
    if (!info.regular) {
        plod_status_format(message, message_size, "'%s' is not a regular file", path);
        *status = PLOD_ERR_IO;
        return 0;
    }
    *size = (long long)info.size;
    return 1;
}

/* The largest n with n * n <= value (value < 2^62). */
static long long plod__isqrt(long long value)
{
    long long n = (long long)sqrt((double)value);
    while (n > 0 && n * n > value)
        n--;
    while ((n + 1) * (n + 1) <= value)
        n++;
    return n;
}

plod_status plod_raw_guess(const char *path, plod_raw_format *format, char *message,
                           size_t message_size)
{
    if (message && message_size)
        message[0] = '\0';
    if (!path || !format)
        return PLOD_ERR_NULL;
    char ext[8];
    plod__raw_extension(path, ext);
    long long bytes;
    plod_status status = PLOD_OK;
    if (!plod__file_size(path, &bytes, message, message_size, &status))
        return status;
    memset(format, 0, sizeof *format);
    if (strcmp(ext, "hgt") == 0) {
        format->type = PLOD_RAW_I16;
        format->big_endian = 1;
        if (bytes == 1201LL * 1201 * 2)
            format->width = format->height = 1201; /* SRTM3, 3 arc-seconds */
        else if (bytes == 3601LL * 3601 * 2)
            format->width = format->height = 3601; /* SRTM1, 1 arc-second */
        else {
            plod_status_format(message, message_size,
                              "'%s' is %lld bytes; an SRTM .hgt tile has 2884802 (1201 x 1201) "
                              "or 25934402 (3601 x 3601)",
                              path, bytes);
            return PLOD_ERR_BAD_IMAGE;
        }
        return PLOD_OK;
    }
    if (strcmp(ext, "r16") != 0 && strcmp(ext, "raw") != 0) {
        plod_status_format(message, message_size,
                          "'%s' is not a .hgt, .r16 or .raw height grid", path);
        return PLOD_ERR_BAD_PARAM;
    }
    /* terrain tools' default: unsigned 16-bit little-endian, square or 2:1 */
    format->type = PLOD_RAW_U16;
    format->big_endian = 0;
    long long samples = bytes / 2, side = plod__isqrt(samples), half = plod__isqrt(samples / 2);
    if (bytes % 2 == 0 && side > 0 && side * side == samples) {
        format->width = format->height = (int)(side < 1 << 30 ? side : 0);
    } else if (bytes % 2 == 0 && half > 0 && 2 * half * half == samples) {
        format->width = (int)(2 * half < 1 << 30 ? 2 * half : 0);
        format->height = (int)(half < 1 << 30 ? half : 0);
    }
    if (format->width <= 0 || format->height <= 0) {
        plod_status_format(message, message_size,
                          "'%s' is %lld bytes, not a square or 2:1 grid of 16-bit samples; "
                          "give its width, height, sample type and byte order",
                          path, bytes);
        return PLOD_ERR_BAD_IMAGE;
    }
    return PLOD_OK;
}

static int plod__host_big_endian(void)
{
    const uint16_t probe = 1;
    unsigned char first;
    memcpy(&first, &probe, 1);
    return first == 0;
}

/* Converts one row of raw samples in place of `out` (row-major texels). */
static void plod__raw_row(const unsigned char *in, size_t count, const plod_raw_format *format,
                          int hgt_voids, void *out)
{
    int swap = format->big_endian != plod__host_big_endian();
    switch (format->type) {
    case PLOD_RAW_U8:
        memcpy(out, in, count);
        break;
    case PLOD_RAW_U16:
        for (size_t i = 0; i < count; i++) {
            uint16_t v;
            memcpy(&v, in + 2 * i, 2);
            ((uint16_t *)out)[i] = swap ? (uint16_t)(v >> 8 | v << 8) : v;
        }
        break;
    case PLOD_RAW_I16:
        for (size_t i = 0; i < count; i++) {
            uint16_t v;
            memcpy(&v, in + 2 * i, 2);
            if (swap)
                v = (uint16_t)(v >> 8 | v << 8);
            int32_t s = v >= 0x8000u ? (int32_t)v - 65536 : (int32_t)v;
            ((float *)out)[i] = hgt_voids && s == -32768 ? NAN : (float)s;
        }
        break;
    default:
        for (size_t i = 0; i < count; i++) {
            uint32_t v;
            memcpy(&v, in + 4 * i, 4);
            if (swap)
                v = v >> 24 | (v >> 8 & 0xff00u) | (v << 8 & 0xff0000u) | v << 24;
            memcpy((float *)out + i, &v, 4);
        }
    }
}

plod_status plod_image_read_raw(plod_image *image, const char *path,
                                const plod_raw_format *format, size_t max_pixels,
                                char *message, size_t message_size)
{
    if (message && message_size)
        message[0] = '\0';
    if (!image || !path || !format)
        return PLOD_ERR_NULL;
    image->pixels = NULL;
    if (format->width <= 0 || format->height <= 0 ||
        (unsigned)format->type >= PLOD_RAW_TYPE_COUNT) {
        plod_status_format(message, message_size,
                          "raw grid of %dx%d %s samples: width and height must be positive, "
                          "the type u8, u16, i16 or f32",
                          format->width, format->height, plod__raw_type_name(format->type));
        return PLOD_ERR_BAD_PARAM;
    }
    long long bytes;
    plod_status status = PLOD_OK;
    if (!plod__file_size(path, &bytes, message, message_size, &status))
        return status;
    size_t sample = plod_raw_sample_bytes(format->type);
    unsigned long long expected =
        (unsigned long long)format->width * (unsigned long long)format->height * sample;
    if ((unsigned long long)bytes != expected) {
        plod_status_format(message, message_size,
                          "'%s' is %lld bytes; %dx%d %s samples need %llu", path, bytes,
                          format->width, format->height, plod__raw_type_name(format->type),
                          expected);
        return PLOD_ERR_BAD_IMAGE;
    }
    if (max_pixels == 0)
        max_pixels = PLOD_IMAGE_DEFAULT_MAX_PIXELS;
    if ((unsigned long long)format->width * (unsigned long long)format->height > max_pixels) {
        plod_status_format(message, message_size,
                          "'%s' is %dx%d samples, more than the limit of %zu", path,
                          format->width, format->height, max_pixels);
        return PLOD_ERR_BAD_IMAGE;
    }
    plod_texel_type type = format->type == PLOD_RAW_U8    ? PLOD_TEXEL_U8
                           : format->type == PLOD_RAW_U16 ? PLOD_TEXEL_U16
                                                          : PLOD_TEXEL_F32;
    plod_image loaded = {0};
    status = plod_image_alloc(&loaded, format->width, format->height, 1, type);
    if (status != PLOD_OK) {
        plod_status_format(message, message_size, "cannot allocate %dx%d samples for '%s'",
                          format->width, format->height, path);
        return status;
    }
    FILE *file = plod_fopen(path, "rb");
    size_t row_bytes = (size_t)format->width * sample;
    unsigned char *row = file ? malloc(row_bytes) : NULL;
    if (!file || !row) {
        plod_status_format(message, message_size, file ? "out of memory reading '%s'"
                                                      : "cannot read '%s'",
                          path);
        if (file)
            fclose(file);
        plod_image_free(&loaded);
        return file ? PLOD_ERR_NO_MEMORY : PLOD_ERR_IO;
    }
    char ext[8];
    plod__raw_extension(path, ext);
    int hgt_voids = strcmp(ext, "hgt") == 0;
    size_t texel_row = (size_t)format->width * plod_image_texel_bytes(type);
    for (int y = 0; y < format->height; y++) {
        if (fread(row, 1, row_bytes, file) != row_bytes) {
            plod_status_format(message, message_size, "'%s' is truncated (row %d of %d)", path,
                              y, format->height);
            free(row);
            fclose(file);
            plod_image_free(&loaded);
            return PLOD_ERR_BAD_IMAGE;
        }
        plod__raw_row(row, (size_t)format->width, format, hgt_voids,
                      (char *)loaded.pixels + (size_t)y * texel_row);
    }
    free(row);
    fclose(file);
    *image = loaded;
    return PLOD_OK;
}

plod_status plod_image_reinterpret_signed(plod_image *image)
{
    if (!image || !image->pixels)
        return PLOD_ERR_NULL;
    if (image->type == PLOD_TEXEL_F32)
        return PLOD_OK; /* already signed */
    size_t count = (size_t)image->width * (size_t)image->height * (size_t)image->channels;
    float *values = malloc(count * sizeof *values);
    if (!values)
        return PLOD_ERR_NO_MEMORY;
    for (size_t i = 0; i < count; i++) {
        if (image->type == PLOD_TEXEL_U8) {
            uint8_t v = ((const uint8_t *)image->pixels)[i];
            values[i] = (float)(v >= 0x80u ? (int)v - 256 : (int)v);
        } else {
            uint16_t v = ((const uint16_t *)image->pixels)[i];
            values[i] = (float)(v >= 0x8000u ? (int32_t)v - 65536 : (int32_t)v);
        }
    }
    plod_image_free(image);
    image->pixels = values;
    image->type = PLOD_TEXEL_F32;
    return PLOD_OK;
}
