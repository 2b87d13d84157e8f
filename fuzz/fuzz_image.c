/* fuzz_image.c -- libFuzzer harness for what the core reads from outside:
 * headerless grids (cext/image_raw.c), GeoTIFF georeferencing
 * (cext/geotiff.c), decoded pixel buffers taken in (plod_image_import,
 * cext/image_buffer.c), tile files and their build through a rows reader
 * (cext/heighttiles.c), and the CubeResampler (cext/resample.c).
 *
 * Input layout: [kind][projection/filter][cube size][flags] bytes...
 * The first byte picks the kind: a file with a grid's or a TIFF's extension
 * (written to a private directory in /dev/shm and read as the core reads
 * it), a tile file, or a buffer as a decoder hands it over (the bytes are
 * the pixels; width, height, channels and sample type come from the tail,
 * usually not matching).  An image taken in is resampled into a tiny cube
 * map, optionally cancelled half-way through the progress callback, turned
 * into a cross image and back, sampled, and tiled out of core through a
 * rows reader that fails at a chosen band.
 *
 * The core decodes no compressed format (the Python layer does, through
 * OpenImageIO), so everything reached here is our code, instrumented.
 */
#include <errno.h>
#include <stdint.h>
#include <unistd.h>

#include "fuzz_input.h"
#include "plod_heightsource.h"
#include "plod_image.h"
#include "plod_resample.h"

static const char *const fuzz_extensions[] = {
    "tif", "hgt", "r16", "raw", /* GeoTIFF tags; headerless height grids */
    "plodtiles",                /* tile files (heighttiles.c) */
    "buf",                      /* a decoded buffer (plod_image_import) */
};
#define FUZZ_EXTENSIONS (sizeof fuzz_extensions / sizeof fuzz_extensions[0])

static char fuzz_dir[64];

static void fuzz__cleanup(void)
{
    for (size_t i = 0; i < FUZZ_EXTENSIONS; i++) {
        char path[128];
        snprintf(path, sizeof path, "%s/in.%s", fuzz_dir, fuzz_extensions[i]);
        unlink(path);
    }
    char built[128];
    snprintf(built, sizeof built, "%s/built.plodtiles", fuzz_dir);
    unlink(built);
    rmdir(fuzz_dir);
}

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    (void)argc;
    (void)argv;
    const char *base = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
    snprintf(fuzz_dir, sizeof fuzz_dir, "%s/plod-fuzz-XXXXXX", base);
    if (!mkdtemp(fuzz_dir)) {
        perror("mkdtemp");
        abort();
    }
    atexit(fuzz__cleanup);
    return 0;
}

typedef struct fuzz_progress {
    int calls;
    int cancel_at; /* 0: never */
    double last;
} fuzz_progress;

static int fuzz__progress(void *user, double fraction)
{
    fuzz_progress *p = user;
    FUZZ_CHECK(fraction >= 0.0 && fraction <= 1.0 && fraction >= p->last,
               "progress %g after %g", fraction, p->last);
    p->last = fraction;
    p->calls++;
    return p->cancel_at && p->calls >= p->cancel_at;
}

static void fuzz__check_image(const plod_image *image)
{
    FUZZ_CHECK(image->width > 0 && image->height > 0 && image->channels >= 1 &&
                   image->channels <= 4 && (unsigned)image->type < PLOD_TEXEL_TYPE_COUNT &&
                   image->pixels != NULL,
               "decoded image %dx%dx%d type %d", image->width, image->height,
               image->channels, image->type);
}

static void fuzz__use_cubemap(plod_cubemap *cubemap, fuzz_input *in)
{
    int channels = plod_cubemap_channels(cubemap);
    if (plod_cubemap_build_pyramid(cubemap) != PLOD_OK)
        return;
    double lo, hi;
    plod_cubemap_global_range(cubemap, &lo, &hi);
    for (int i = 0; i < 3; i++) {
        double dir[3] = {fuzz_double_in(in, -1, 1), fuzz_double_in(in, -1, 1),
                         fuzz_double_in(in, -1, 1)};
        if (dir[0] == 0 && dir[1] == 0 && dir[2] == 0)
            dir[2] = 1;
        float out[4] = {0, 0, 0, 0};
        plod_cubemap_sample(cubemap, dir, out);
        (void)plod_cubemap_sample_height(cubemap, dir);
        (void)channels;
        if (plod_cubemap_face_count(cubemap) == 6) {
            int face = fuzz_range(in, 0, 5);
            plod_cubemap_range(cubemap, face, fuzz_double(in), fuzz_double(in),
                               fuzz_double(in), fuzz_double(in), &lo, &hi);
        }
    }
    plod_image cross = {0};
    if (plod_cubemap_to_cross(&cross, cubemap) == PLOD_OK) {
        fuzz__check_image(&cross);
        plod_cubemap *back = NULL;
        if (plod_cubemap_from_cross(&back, &cross, plod_cubemap_projection(cubemap)) == PLOD_OK) {
            FUZZ_CHECK(plod_cubemap_size(back) == plod_cubemap_size(cubemap),
                       "cross round trip size %d vs %d", plod_cubemap_size(back),
                       plod_cubemap_size(cubemap));
            FUZZ_CHECK(memcmp(plod_cubemap_face_data_const(back, 3),
                              plod_cubemap_face_data_const(cubemap, 3),
                              plod_cubemap_face_bytes(cubemap)) == 0,
                       "cross round trip changed texels");
            plod_cubemap_destroy(back);
        }
        plod_image_free(&cross);
    }
    plod_image face = {0};
    if (plod_cubemap_face_to_image(&face, cubemap, fuzz_range(in, -1, 6)) == PLOD_OK) {
        fuzz__check_image(&face);
        plod_image_free(&face);
    }
}

/* A rows reader over an image in memory (channel 0), as the binding's reader
 * over a decoder: it fails at band `fail_at` (0: never). */
typedef struct fuzz_rows {
    const plod_image *image;
    int fail_at, reads, open;
} fuzz_rows;

static plod_status fuzz__rows_open(void *context, const char *path, void **rows, int *width,
                                   int *height, plod_texel_type *type, char *message,
                                   size_t message_size)
{
    (void)path;
    fuzz_rows *r = context;
    if (r->fail_at == 1) {
        plod_status_format(message, message_size, "%s", "not a readable image");
        return PLOD_ERR_BAD_IMAGE;
    }
    r->open++;
    *rows = r;
    *width = r->image->width;
    *height = r->image->height;
    *type = r->image->type;
    return PLOD_OK;
}

static plod_status fuzz__rows_read(void *context, void *rows, int y0, int y1, void *pixels,
                                   char *message, size_t message_size)
{
    fuzz_rows *r = context;
    FUZZ_CHECK(rows == r && r->open == 1, "read on a reader not open");
    FUZZ_CHECK(y0 >= 0 && y0 < y1 && y1 <= r->image->height, "rows %d..%d of %d", y0, y1,
               r->image->height);
    if (r->fail_at > 1 && ++r->reads >= r->fail_at - 1) {
        plod_status_format(message, message_size, "rows %d..%d are corrupt", y0, y1);
        return PLOD_ERR_BAD_IMAGE;
    }
    size_t texel = plod_image_texel_bytes(r->image->type);
    const unsigned char *in = r->image->pixels;
    unsigned char *out = pixels;
    for (int y = y0; y < y1; y++)
        for (int x = 0; x < r->image->width; x++)
            memcpy(out + ((size_t)(y - y0) * (size_t)r->image->width + (size_t)x) * texel,
                   in + (((size_t)y * (size_t)r->image->width + (size_t)x) *
                         (size_t)r->image->channels) * texel,
                   texel);
    return PLOD_OK;
}

static void fuzz__rows_close(void *context, void *rows)
{
    fuzz_rows *r = context;
    FUZZ_CHECK(rows == r && r->open == 1, "close of a reader not open");
    r->open--;
}

/* Samples and bounds of a tile file: every sample inside the global range
 * (or NaN where the map has voids), every box's bounds inside it too. */
static void fuzz__use_tiles(plod_tiles *tiles, fuzz_input *in)
{
    double lo, hi;
    plod_tiles_global_range(tiles, &lo, &hi);
    for (int i = 0; i < 4; i++) {
        double u = fuzz_double_in(in, -1.2, 1.2), v = fuzz_double_in(in, -1.2, 1.2);
        double value = plod_tiles_sample_uv(tiles, u, v);
        if (plod_tiles_nan_count(tiles) == 0 && plod_tiles_read_errors(tiles) == 0 &&
            isfinite(lo) && isfinite(hi)) /* +-inf texels: NaN lerps, refused by planets */
            FUZZ_CHECK(value >= lo - 1e-9 * fabs(lo) && value <= hi + 1e-9 * fabs(hi),
                       "sample %g outside %g..%g", value, lo, hi);
        double a, b;
        plod_tiles_range_uv(tiles, u, v, fuzz_double_in(in, -1.2, 1.2),
                            fuzz_double_in(in, -1.2, 1.2), &a, &b);
        if (lo <= hi && a == a)
            FUZZ_CHECK(a >= lo && b <= hi, "box %g..%g outside %g..%g", a, b, lo, hi);
    }
    plod_height_source source = plod_tiles_source(tiles);
    double axis[3] = {fuzz_double_in(in, -1, 1), fuzz_double_in(in, -1, 1), 1.0};
    double n = sqrt(axis[0] * axis[0] + axis[1] * axis[1] + 1.0);
    axis[0] /= n, axis[1] /= n, axis[2] /= n;
    double texels;
    source.ops->range_cap(source.self, axis, fuzz_double_in(in, 0, 3.2), &lo, &hi, &texels);
    (void)source.ops->sample(source.self, axis);
}

/* A TIFF's georeferencing (geotiff.c): a status and a terminated message
 * for any bytes; a box, when one comes, ordered and finite. */
static void fuzz__use_georef(const char *path, fuzz_input *in)
{
    plod_georef geo;
    char why[256];
    plod_status s = plod_georef_read(&geo, path, why, sizeof why);
    FUZZ_CHECK(memchr(why, '\0', sizeof why) != NULL, "georef message not terminated");
    FUZZ_CHECK(s == PLOD_OK || s == PLOD_ERR_BAD_IMAGE || s == PLOD_ERR_NO_MEMORY,
               "georef status %d (%s)", s, why);
    if (s != PLOD_OK || !geo.present)
        return;
    int width = fuzz_range(in, 1, 5000), height = fuzz_range(in, 1, 5000);
    double box[4];
    s = plod_georef_box(&geo, width, height, box, why, sizeof why);
    FUZZ_CHECK(memchr(why, '\0', sizeof why) != NULL, "georef box message not terminated");
    FUZZ_CHECK(s == PLOD_OK || s == PLOD_ERR_BAD_IMAGE, "georef box status %d (%s)", s, why);
    if (s == PLOD_OK)
        FUZZ_CHECK(!(box[0] > box[2]) && !(box[1] > box[3]),
                   "georef box %g %g %g %g not ordered", box[0], box[1], box[2], box[3]);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_input in = {data, size};
    const char *ext = fuzz_extensions[fuzz_u8(&in) % FUZZ_EXTENSIONS];
    uint8_t mode = fuzz_u8(&in);
    int size_code = fuzz_u8(&in);
    uint8_t flags = fuzz_u8(&in);
    /* The rest is the file; parameters for later steps come from a copy of
     * the file's tail so the decoder sees the whole input. */
    fuzz_input tail = {in.data + in.size / 2, in.size - in.size / 2};

    char path[128];
    snprintf(path, sizeof path, "%s/in.%s", fuzz_dir, ext);
    FILE *f = fopen(path, "wb");
    FUZZ_CHECK(f != NULL, "cannot create %s: %s", path, strerror(errno));
    if (in.size)
        FUZZ_CHECK(fwrite(in.data, 1, in.size, f) == in.size, "short write");
    fclose(f);

    if (strcmp(ext, "plodtiles") == 0) { /* a tile file as it lies on disk */
        plod_tiles *tiles = NULL;
        char why[256];
        plod_status ts = plod_tiles_open(&tiles, path, 1, why, sizeof why);
        FUZZ_CHECK(memchr(why, '\0', sizeof why) != NULL, "message not terminated");
        FUZZ_CHECK((ts == PLOD_OK) == (tiles != NULL), "open status %d, tiles %p", ts,
                   (void *)tiles);
        if (tiles) {
            fuzz__use_tiles(tiles, &tail);
            plod_tiles_destroy(tiles);
        }
        return 0;
    }

    plod_image image = {0};
    char message[256];
    if (strcmp(ext, "tif") == 0) { /* the tags the core reads itself */
        fuzz__use_georef(path, &tail);
        return 0;
    }

    /* A small pixel cap keeps each execution cheap; absurd sizes must be
     * refused by the cap before any allocation. */
    size_t max_pixels = (flags & 1) ? 4096 : 1u << 18;
    plod_status s;
    int imported = strcmp(ext, "buf") == 0;
    /* the buffer outlives the borrowed image: a copy the harness owns */
    unsigned char *copy = NULL;
    if (imported) {
        plod_image_buffer buffer = {fuzz_range(&tail, -1, 70), fuzz_range(&tail, -1, 70),
                                    fuzz_range(&tail, 0, 5),
                                    (plod_raw_type)fuzz_range(&tail, 0, PLOD_RAW_TYPE_COUNT),
                                    NULL, in.size};
        size_t sample = plod_raw_sample_bytes(buffer.type);
        if ((flags & 0x80) && buffer.width > 0 && buffer.channels > 0 && sample) /* fit */
            buffer.height = (int)(in.size / ((size_t)buffer.width * (size_t)buffer.channels *
                                             sample));
        copy = malloc(in.size ? in.size : 1);
        FUZZ_CHECK(copy != NULL, "no memory for %zu bytes", in.size);
        memcpy(copy, in.data, in.size);
        buffer.pixels = copy;
        plod_import_mode import_mode = (size_code & 0x80) ? PLOD_IMPORT_STORED : PLOD_IMPORT_TYPED;
        s = plod_image_import(&image, &buffer, import_mode, flags & 0x08 ? 0 : 1, max_pixels,
                              "fuzz", message, sizeof message);
        if (s == PLOD_OK) {
            FUZZ_CHECK(image.width == buffer.width && image.height == buffer.height &&
                           image.channels == buffer.channels &&
                           (size_t)buffer.width * (size_t)buffer.height *
                                   (size_t)buffer.channels * sample == in.size,
                       "imported %dx%dx%d from %zu bytes", image.width, image.height,
                       image.channels, in.size);
            FUZZ_CHECK(import_mode == PLOD_IMPORT_TYPED || image.type == PLOD_TEXEL_F32,
                       "stored import gave type %d", image.type);
            FUZZ_CHECK(!image.borrowed || image.pixels == copy, "borrowed other pixels");
        }
    } else if (flags & 0x80) {
        /* an explicit headerless format, usually not matching the size */
        plod_raw_format raw = {fuzz_range(&tail, -2, 70), fuzz_range(&tail, -2, 70),
                               (plod_raw_type)fuzz_range(&tail, 0, PLOD_RAW_TYPE_COUNT),
                               fuzz_range(&tail, 0, 1)};
        s = plod_image_read_raw(&image, path, &raw, max_pixels, message, sizeof message);
        FUZZ_CHECK(s != PLOD_OK || (image.width == raw.width && image.height == raw.height &&
                                    (size_t)raw.width * (size_t)raw.height *
                                            plod_raw_sample_bytes(raw.type) == in.size),
                   "raw %dx%d type %d read from %zu bytes", raw.width, raw.height, raw.type,
                   in.size);
    } else { /* by the extension's rules and the file's size */
        plod_raw_format raw;
        s = plod_raw_guess(path, &raw, message, sizeof message);
        if (s == PLOD_OK)
            s = plod_image_read_raw(&image, path, &raw, max_pixels, message, sizeof message);
    }
    if (s == PLOD_OK && (flags & 0x20) && image.type != PLOD_TEXEL_F32) {
        int was_u16 = image.type == PLOD_TEXEL_U16;
        uint16_t first = was_u16 ? ((const uint16_t *)image.pixels)[0]
                                 : ((const uint8_t *)image.pixels)[0];
        FUZZ_CHECK(plod_image_reinterpret_signed(&image) == PLOD_OK, "reinterpret failed");
        float value = ((const float *)image.pixels)[0];
        FUZZ_CHECK(image.type == PLOD_TEXEL_F32 &&
                       value == (was_u16 ? (float)(int16_t)first : (float)(int8_t)first),
                   "signed %u read as %g", first, value);
    }
    FUZZ_CHECK(memchr(message, '\0', sizeof message) != NULL, "message not terminated");
    if (s != PLOD_OK) {
        FUZZ_CHECK(s == PLOD_ERR_IO || s == PLOD_ERR_BAD_IMAGE || s == PLOD_ERR_NO_MEMORY ||
                       ((flags & 0x80 || imported) && s == PLOD_ERR_BAD_PARAM), /* bad layout */
                   "read status %d (%s)", s, message);
        FUZZ_CHECK(image.pixels == NULL, "failed read left pixels");
        free(copy);
        return 0;
    }
    fuzz__check_image(&image);
    if ((flags & 0x10) && image.width * image.height <= 4096) {
        /* the same image tiled out of core: a grid file as it lies, an
         * imported one through a rows reader (failing at a chosen band: the
         * build then leaves nothing) */
        char built[128];
        snprintf(built, sizeof built, "%s/built.plodtiles", fuzz_dir);
        plod_tiles *tiles = NULL;
        fuzz_rows rows = {&image, (mode >> 4) & 3, 0, 0};
        plod_image_rows_reader reader = {fuzz__rows_open, fuzz__rows_read, fuzz__rows_close,
                                         &rows};
        plod_status ts = plod_tiles_build(path, NULL, imported ? &reader : NULL, 0, built, 16, NULL, NULL,
                                          message, sizeof message);
        FUZZ_CHECK(rows.open == 0, "the build left the reader open");
        FUZZ_CHECK(ts == PLOD_OK || access(built, F_OK) != 0, "a failed build left %s", built);
        if (ts == PLOD_OK && plod_tiles_open(&tiles, built, 1, message, sizeof message) == PLOD_OK) {
            FUZZ_CHECK(plod_tiles_width(tiles) >= 1 && plod_tiles_height(tiles) >= 1,
                       "tiled %dx%d", plod_tiles_width(tiles), plod_tiles_height(tiles));
            fuzz__use_tiles(tiles, &tail);
            plod_tiles_destroy(tiles);
        }
        unlink(built);
    }
    FUZZ_CHECK((size_t)image.width * (size_t)image.height <= max_pixels,
               "%dx%d over the cap %zu", image.width, image.height, max_pixels);

    static const plod_projection cube[] = {PLOD_PROJ_TSC, PLOD_PROJ_CSC, PLOD_PROJ_QSC,
                                           PLOD_PROJ_SPHERIFIED};
    plod_projection projection = cube[mode & 3];
    plod_filter filter = (plod_filter)((mode >> 2) % PLOD_FILTER_COUNT);
    int cube_size = 1 + size_code % 8;
    plod_texel_type type = (flags & 2) ? image.type
                                       : (plod_texel_type)((flags >> 2) % PLOD_TEXEL_TYPE_COUNT);
    plod_cubemap *cubemap = NULL;
    if (plod_cubemap_create(&cubemap, projection, cube_size, image.channels, type) == PLOD_OK) {
        fuzz_progress progress = {0, (flags >> 4) & 3, 0.0};
        s = plod_resample_car_to_cube(cubemap, &image, filter,
                                      (flags & 0x40) ? fuzz__progress : NULL, &progress);
        FUZZ_CHECK(s == PLOD_OK || s == PLOD_ERR_CANCELLED || s == PLOD_ERR_BAD_PARAM ||
                       s == PLOD_ERR_BAD_IMAGE,
                   "resample status %d", s);
        if (s == PLOD_OK)
            fuzz__use_cubemap(cubemap, &tail);
        plod_cubemap_destroy(cubemap);
    }
    /* A 4:3 image may be a cross-layout cube map. */
    if (image.width * 3 == image.height * 4) {
        plod_cubemap *cross_map = NULL;
        if (plod_cubemap_from_cross(&cross_map, &image, projection) == PLOD_OK) {
            fuzz__use_cubemap(cross_map, &tail);
            plod_cubemap_destroy(cross_map);
        }
    }
    plod_image_free(&image);
    FUZZ_CHECK(image.pixels == NULL, "plod_image_free left pixels");
    free(copy);
    return 0;
}
