/* heighttiles.c -- tiled equirectangular height maps read out of core
 * (plod_heightsource.h): the tile file writer, a bounded tile cache with
 * second-chance (CLOCK) eviction, bilinear sampling with the CAR map's
 * conventions, and conservative bounds from per-tile min/max and a
 * pyramid over them.
 *
 * Memory: per-tile bounds (8 bytes per tile: 1.8 MB for an 86400 x 43200
 * map in 128-texel tiles) and the slot table, plus at most cache_bytes of
 * tiles.  Tiles are read at their offsets (plod_file_read_at), so the file
 * itself is never mapped.
 */
#include "plod_heightsource.h"
#include "plod_platform.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PLOD__TILES_MAGIC "PLODTIL1"
#define PLOD__TILES_HEADER 128
#define PLOD__TILES_ALIGN 512

typedef struct plod__tiles_header {
    char magic[8];
    uint32_t version, width, height, tile, type, reserved;
    int64_t source_size, source_mtime;
    uint64_t nan_count;
    uint64_t complete; /* 1 once every tile is written */
} plod__tiles_header;

struct plod_tiles {
    plod_file file;
    int width, height, tile, tiles_x, tiles_y;
    plod_texel_type type;
    size_t sample_bytes, tile_bytes;
    uint64_t data_offset;
    size_t nan_count;
    float *tile_min, *tile_max; /* per tile, stored units (NaN-free) */
    /* pyramid over tiles: level 0 is the tile grid */
    int levels;
    int level_w[32], level_h[32];
    float *level_min[32], *level_max[32];
    double global_lo, global_hi; /* normalised */
    /* the cache */
    plod_mutex lock;
    size_t slots, used, hand;
    unsigned char *slot_data;
    int32_t *slot_tile;
    unsigned char *slot_ref;
    int32_t *tile_slot; /* per tile: slot or -1 */
    size_t read_errors;
};

static size_t plod__tiles_sample_bytes(plod_texel_type type)
{
    return type == PLOD_TEXEL_U8 ? 1 : type == PLOD_TEXEL_U16 ? 2 : 4;
}

static double plod__tiles_scale(plod_texel_type type)
{
    return type == PLOD_TEXEL_U8 ? 1.0 / 255.0 : type == PLOD_TEXEL_U16 ? 1.0 / 65535.0 : 1.0;
}

static float plod__tiles_load(const unsigned char *p, plod_texel_type type)
{
    if (type == PLOD_TEXEL_U8)
        return (float)p[0];
    if (type == PLOD_TEXEL_U16) {
        uint16_t v;
        memcpy(&v, p, 2);
        return (float)v;
    }
    float f;
    memcpy(&f, p, 4);
    return f;
}

/* normalised exactly as plod_cubemap samples */
static double plod__tiles_value(const unsigned char *p, plod_texel_type type)
{
    if (type == PLOD_TEXEL_U8)
        return p[0] * (1.0 / 255.0);
    if (type == PLOD_TEXEL_U16) {
        uint16_t v;
        memcpy(&v, p, 2);
        return v * (1.0 / 65535.0);
    }
    float f;
    memcpy(&f, p, 4);
    return f;
}

static uint64_t plod__tiles_data_offset(size_t tile_count)
{
    size_t bounds = PLOD__TILES_HEADER + tile_count * 2 * sizeof(float);
    return (uint64_t)((bounds + PLOD__TILES_ALIGN - 1) / PLOD__TILES_ALIGN * PLOD__TILES_ALIGN);
}

/* ---- the source rows: a raw grid or the caller's image reader ----------------- */

typedef struct plod__row_reader {
    FILE *raw_file;
    plod_raw_format raw;
    int hgt_voids;
    unsigned char *raw_row;
    const plod_image_rows_reader *reader;
    void *image; /* the reader's rows, when open */
    int width, height;
    plod_texel_type type;
} plod__row_reader;

static int plod__host_big_endian(void)
{
    const uint16_t probe = 1;
    unsigned char first;
    memcpy(&first, &probe, 1);
    return first == 0;
}

static plod_status plod__rows_open(plod__row_reader *r, const char *source,
                                   const plod_raw_format *raw,
                                   const plod_image_rows_reader *reader, char *message,
                                   size_t message_size)
{
    memset(r, 0, sizeof *r);
    plod_raw_format guessed;
    if (!raw && plod_raw_is_raw_path(source)) {
        plod_status s = plod_raw_guess(source, &guessed, message, message_size);
        if (s != PLOD_OK)
            return s;
        raw = &guessed;
    }
    if (!raw) {
        if (!reader || !reader->open || !reader->read || !reader->close) {
            plod_status_format(message, message_size,
                                "no image reader for '%s' (only .hgt, .r16 and .raw grids "
                                "are read without one)",
                                source);
            return PLOD_ERR_BAD_PARAM;
        }
        plod_status s = reader->open(reader->context, source, &r->image, &r->width, &r->height,
                                     &r->type, message, message_size);
        if (s != PLOD_OK) {
            r->image = NULL;
            return s;
        }
        if (!r->image || r->width <= 0 || r->height <= 0 ||
            (unsigned)r->type >= PLOD_TEXEL_TYPE_COUNT) {
            if (r->image)
                reader->close(reader->context, r->image);
            r->image = NULL;
            plod_status_format(message, message_size, "'%s' has an unsupported format or layout",
                                source);
            return PLOD_ERR_BAD_IMAGE;
        }
        r->reader = reader;
        return PLOD_OK;
    }
    if (raw->width <= 0 || raw->height <= 0 || (unsigned)raw->type >= PLOD_RAW_TYPE_COUNT) {
        plod_status_format(message, message_size, "bad raw grid layout %dx%d type %d",
                            raw->width, raw->height, (int)raw->type);
        return PLOD_ERR_BAD_PARAM;
    }
    plod_path_info info;
    if (!plod_path_info_get(source, &info) || !info.regular) {
        plod_status_format(message, message_size, "cannot open '%s': %s", source,
                            strerror(errno));
        return PLOD_ERR_IO;
    }
    unsigned long long expected = (unsigned long long)raw->width *
                                  (unsigned long long)raw->height *
                                  plod_raw_sample_bytes(raw->type);
    if ((unsigned long long)info.size != expected) {
        plod_status_format(message, message_size,
                            "'%s' is %lld bytes; %dx%d samples of %zu bytes need %llu", source,
                            (long long)info.size, raw->width, raw->height,
                            plod_raw_sample_bytes(raw->type), expected);
        return PLOD_ERR_BAD_IMAGE;
    }
    r->raw = *raw;
    r->raw_file = plod_fopen(source, "rb");
    r->raw_row = malloc((size_t)raw->width * plod_raw_sample_bytes(raw->type));
    if (!r->raw_file || !r->raw_row) {
        if (r->raw_file)
            fclose(r->raw_file);
        free(r->raw_row);
        r->raw_file = NULL;
        r->raw_row = NULL;
        plod_status_format(message, message_size, "cannot read '%s'", source);
        return PLOD_ERR_IO;
    }
    size_t length = strlen(source);
    r->hgt_voids = length > 4 && (strcmp(source + length - 4, ".hgt") == 0 ||
                                  strcmp(source + length - 4, ".HGT") == 0);
    r->width = raw->width;
    r->height = raw->height;
    r->type = raw->type == PLOD_RAW_U8    ? PLOD_TEXEL_U8
              : raw->type == PLOD_RAW_U16 ? PLOD_TEXEL_U16
                                          : PLOD_TEXEL_F32;
    return PLOD_OK;
}

static void plod__rows_close(plod__row_reader *r)
{
    if (r->raw_file)
        fclose(r->raw_file);
    free(r->raw_row);
    if (r->image)
        r->reader->close(r->reader->context, r->image);
    memset(r, 0, sizeof *r);
}

/* Rows [y0, y1) in r->type into out (width per row). */
static plod_status plod__rows_read(plod__row_reader *r, int y0, int y1, void *out,
                                   char *message, size_t message_size)
{
    if (r->image)
        return r->reader->read(r->reader->context, r->image, y0, y1, out, message, message_size);
    size_t sample = plod_raw_sample_bytes(r->raw.type), count = (size_t)r->width;
    size_t out_row = count * plod__tiles_sample_bytes(r->type);
    int swap = r->raw.big_endian != plod__host_big_endian();
    for (int y = y0; y < y1; y++) {
        if (fread(r->raw_row, sample, count, r->raw_file) != count) {
            plod_status_format(message, message_size, "the grid is truncated at row %d", y);
            return PLOD_ERR_BAD_IMAGE;
        }
        unsigned char *dst = (unsigned char *)out + (size_t)(y - y0) * out_row;
        const unsigned char *in = r->raw_row;
        for (size_t i = 0; i < count; i++) {
            switch (r->raw.type) {
            case PLOD_RAW_U8: dst[i] = in[i]; break;
            case PLOD_RAW_U16: {
                uint16_t v;
                memcpy(&v, in + 2 * i, 2);
                if (swap)
                    v = (uint16_t)(v >> 8 | v << 8);
                memcpy(dst + 2 * i, &v, 2);
                break;
            }
            case PLOD_RAW_I16: {
                uint16_t v;
                memcpy(&v, in + 2 * i, 2);
                if (swap)
                    v = (uint16_t)(v >> 8 | v << 8);
                int32_t s = v >= 0x8000u ? (int32_t)v - 65536 : (int32_t)v;
                float f = r->hgt_voids && s == -32768 ? NAN : (float)s;
                memcpy(dst + 4 * i, &f, 4);
                break;
            }
            default: {
                uint32_t v;
                memcpy(&v, in + 4 * i, 4);
                if (swap)
                    v = v >> 24 | (v >> 8 & 0xff00u) | (v << 8 & 0xff0000u) | v << 24;
                memcpy(dst + 4 * i, &v, 4);
            }
            }
        }
    }
    return PLOD_OK;
}

/* u8/u16 rows read as two's complement, into f32 */
static void plod__rows_to_signed(const void *in, plod_texel_type type, size_t count, float *out)
{
    for (size_t i = count; i-- > 0;) { /* backwards: in and out may overlap */
        int v = type == PLOD_TEXEL_U8 ? (int)((const uint8_t *)in)[i]
                                      : (int)((const uint16_t *)in)[i];
        if (type == PLOD_TEXEL_U8)
            v = v >= 0x80 ? v - 256 : v;
        else
            v = v >= 0x8000 ? v - 65536 : v;
        out[i] = (float)v;
    }
}

/* ---- writing ------------------------------------------------------------------- */

static int plod__stat_source(const char *source, int64_t *size, int64_t *mtime)
{
    plod_path_info info;
    if (!plod_path_info_get(source, &info))
        return 0;
    *size = info.size;
    *mtime = info.mtime;
    return 1;
}

plod_status plod_tiles_build(const char *source, const plod_raw_format *raw,
                             const plod_image_rows_reader *rows_reader, int is_signed,
                             const char *tiles_path, int tile, plod_progress_fn progress,
                             void *user, char *message, size_t message_size)
{
    plod_status_format(message, message_size, "%s", "");
    if (!source || !tiles_path)
        return PLOD_ERR_NULL;
    if (tile == 0)
        tile = PLOD_TILES_DEFAULT_TILE;
    if (tile < 16 || tile > 4096 || (tile & (tile - 1)) != 0) {
        plod_status_format(message, message_size, "tile size %d: a power of two in 16..4096",
                            tile);
        return PLOD_ERR_BAD_PARAM;
    }
    plod__row_reader reader;
    plod_status s = plod__rows_open(&reader, source, raw, rows_reader, message, message_size);
    if (s != PLOD_OK)
        return s;
    plod_texel_type type = reader.type;
    if (is_signed && type != PLOD_TEXEL_F32)
        type = PLOD_TEXEL_F32;
    int width = reader.width, height = reader.height;
    int tiles_x = (width + tile - 1) / tile, tiles_y = (height + tile - 1) / tile;
    size_t tile_count = (size_t)tiles_x * (size_t)tiles_y;
    size_t sample = plod__tiles_sample_bytes(type);
    size_t read_sample = plod__tiles_sample_bytes(reader.type);
    size_t tile_bytes = (size_t)tile * (size_t)tile * sample;
    uint64_t data_offset = plod__tiles_data_offset(tile_count);
    /* a band of `tile` rows in the stored type (reads of reader.type fit:
     * never wider than the stored type) */
    size_t band_bytes = (size_t)width * (size_t)tile * (sample > read_sample ? sample : read_sample);
    unsigned char *band = malloc(band_bytes);
    unsigned char *tile_buffer = malloc(tile_bytes);
    float *bounds = malloc(tile_count * 2 * sizeof(float));
    size_t path_length = strlen(tiles_path);
    char *temporary = malloc(path_length + 16);
    if (!band || !tile_buffer || !bounds || !temporary) {
        free(band), free(tile_buffer), free(bounds), free(temporary);
        plod__rows_close(&reader);
        plod_status_format(message, message_size, "cannot allocate a %dx%d band", width, tile);
        return PLOD_ERR_NO_MEMORY;
    }
    snprintf(temporary, path_length + 16, "%s.partial", tiles_path);
    plod_file file;
    if (!plod_file_open(&file, temporary, PLOD_FILE_CREATE)) {
        plod_status_format(message, message_size, "cannot write '%s': %s", temporary,
                            strerror(errno));
        s = PLOD_ERR_IO;
        goto done;
    }
    plod__tiles_header header;
    memset(&header, 0, sizeof header);
    memcpy(header.magic, PLOD__TILES_MAGIC, 8);
    header.version = 1;
    header.width = (uint32_t)width;
    header.height = (uint32_t)height;
    header.tile = (uint32_t)tile;
    header.type = (uint32_t)type;
    if (!plod__stat_source(source, &header.source_size, &header.source_mtime))
        header.source_size = header.source_mtime = -1;
    uint64_t nan_count = 0;
    for (int ty = 0; ty < tiles_y && s == PLOD_OK; ty++) {
        int y0 = ty * tile, rows = height - y0 < tile ? height - y0 : tile;
        s = plod__rows_read(&reader, y0, y0 + rows, band, message, message_size);
        if (s != PLOD_OK)
            break;
        if (type != reader.type)
            plod__rows_to_signed(band, reader.type, (size_t)width * (size_t)rows, (float *)band);
        for (int tx = 0; tx < tiles_x; tx++) {
            int x0 = tx * tile;
            float lo = INFINITY, hi = -INFINITY;
            for (int j = 0; j < tile; j++) {
                int y = j < rows ? j : rows - 1; /* pad by repeating the edge */
                for (int i = 0; i < tile; i++) {
                    int x = x0 + i < width ? x0 + i : width - 1;
                    const unsigned char *from = band + ((size_t)y * (size_t)width + (size_t)x) * sample;
                    memcpy(tile_buffer + ((size_t)j * (size_t)tile + (size_t)i) * sample, from, sample);
                    if (j < rows && x0 + i < width) {
                        float v = plod__tiles_load(from, type);
                        if (v != v) {
                            nan_count++;
                            continue;
                        }
                        lo = v < lo ? v : lo;
                        hi = v > hi ? v : hi;
                    }
                }
            }
            size_t index = (size_t)ty * (size_t)tiles_x + (size_t)tx;
            bounds[2 * index] = lo;
            bounds[2 * index + 1] = hi;
            if (!plod_file_write_at(file, tile_buffer, tile_bytes,
                                    data_offset + (uint64_t)index * tile_bytes)) {
                plod_status_format(message, message_size, "writing '%s' failed: %s", temporary,
                                    strerror(errno));
                s = PLOD_ERR_IO;
                break;
            }
        }
        if (s == PLOD_OK && progress && progress(user, (double)(ty + 1) / tiles_y)) {
            s = PLOD_ERR_CANCELLED;
            plod_status_format(message, message_size, "cancelled");
        }
    }
    if (s == PLOD_OK) {
        header.nan_count = nan_count;
        header.complete = 1;
        unsigned char head[PLOD__TILES_HEADER];
        memset(head, 0, sizeof head);
        memcpy(head, &header, sizeof header);
        if (!plod_file_write_at(file, bounds, tile_count * 2 * sizeof(float),
                                PLOD__TILES_HEADER) ||
            !plod_file_write_at(file, head, sizeof head, 0) || !plod_file_sync(file)) {
            plod_status_format(message, message_size, "writing '%s' failed: %s", temporary,
                                strerror(errno));
            s = PLOD_ERR_IO;
        }
    }
    if (!plod_file_close(file) && s == PLOD_OK) {
        plod_status_format(message, message_size, "writing '%s' failed", temporary);
        s = PLOD_ERR_IO;
    }
    if (s == PLOD_OK && !plod_path_replace(temporary, tiles_path)) {
        plod_status_format(message, message_size, "cannot rename to '%s': %s", tiles_path,
                            strerror(errno));
        s = PLOD_ERR_IO;
    }
    if (s != PLOD_OK)
        plod_path_remove(temporary);
done:
    free(band), free(tile_buffer), free(bounds), free(temporary);
    plod__rows_close(&reader);
    return s;
}

/* ---- opening --------------------------------------------------------------------- */

static int plod__read_header(plod_file file, plod__tiles_header *header)
{
    unsigned char head[PLOD__TILES_HEADER];
    if (!plod_file_read_at(file, head, sizeof head, 0))
        return 0;
    memcpy(header, head, sizeof *header);
    return memcmp(header->magic, PLOD__TILES_MAGIC, 8) == 0 && header->version == 1;
}

int plod_tiles_current(const char *tiles_path, const char *source)
{
    plod_file file;
    if (!plod_file_open(&file, tiles_path, PLOD_FILE_READ))
        return 0;
    plod__tiles_header header;
    int ok = plod__read_header(file, &header) && header.complete == 1;
    plod_file_close(file);
    int64_t size, mtime;
    return ok && plod__stat_source(source, &size, &mtime) && size == header.source_size &&
           mtime == header.source_mtime;
}

plod_status plod_tiles_open(plod_tiles **out, const char *tiles_path, size_t cache_bytes,
                            char *message, size_t message_size)
{
    plod_status_format(message, message_size, "%s", "");
    if (!out || !tiles_path)
        return PLOD_ERR_NULL;
    *out = NULL;
    plod_file file;
    if (!plod_file_open(&file, tiles_path, PLOD_FILE_READ)) {
        plod_status_format(message, message_size, "cannot open '%s': %s", tiles_path,
                            strerror(errno));
        return PLOD_ERR_IO;
    }
    plod__tiles_header h;
    int64_t file_size;
    if (!plod__read_header(file, &h) || h.complete != 1 || !plod_file_size(file, &file_size)) {
        plod_file_close(file);
        plod_status_format(message, message_size, "'%s' is not a complete tile file",
                            tiles_path);
        return PLOD_ERR_BAD_IMAGE;
    }
    if (h.width < 2 || h.height < 1 || h.width > (1u << 24) || h.height > (1u << 24) ||
        h.tile < 16 || h.tile > 4096 || (h.tile & (h.tile - 1)) || h.type >= PLOD_TEXEL_TYPE_COUNT) {
        plod_file_close(file);
        plod_status_format(message, message_size, "'%s' has a corrupt header", tiles_path);
        return PLOD_ERR_BAD_IMAGE;
    }
    plod_tiles *t = calloc(1, sizeof *t);
    if (!t) {
        plod_file_close(file);
        return PLOD_ERR_NO_MEMORY;
    }
    t->file = file;
    t->width = (int)h.width;
    t->height = (int)h.height;
    t->tile = (int)h.tile;
    t->type = (plod_texel_type)h.type;
    t->tiles_x = (t->width + t->tile - 1) / t->tile;
    t->tiles_y = (t->height + t->tile - 1) / t->tile;
    t->sample_bytes = plod__tiles_sample_bytes(t->type);
    t->tile_bytes = (size_t)t->tile * (size_t)t->tile * t->sample_bytes;
    t->nan_count = (size_t)h.nan_count;
    size_t count = (size_t)t->tiles_x * (size_t)t->tiles_y;
    t->data_offset = plod__tiles_data_offset(count);
    plod_status s = PLOD_OK;
    if ((unsigned long long)file_size <
        (unsigned long long)t->data_offset + (unsigned long long)count * t->tile_bytes) {
        plod_status_format(message, message_size, "'%s' is truncated (%lld bytes)", tiles_path,
                            (long long)file_size);
        s = PLOD_ERR_BAD_IMAGE;
        goto fail;
    }
    float *bounds = malloc(count * 2 * sizeof(float));
    t->tile_min = malloc(count * sizeof(float));
    t->tile_max = malloc(count * sizeof(float));
    if (!bounds || !t->tile_min || !t->tile_max) {
        free(bounds);
        s = PLOD_ERR_NO_MEMORY;
        goto fail;
    }
    if (!plod_file_read_at(file, bounds, count * 2 * sizeof(float), PLOD__TILES_HEADER)) {
        free(bounds);
        plod_status_format(message, message_size, "'%s' is truncated", tiles_path);
        s = PLOD_ERR_BAD_IMAGE;
        goto fail;
    }
    float lo = INFINITY, hi = -INFINITY;
    for (size_t i = 0; i < count; i++) {
        t->tile_min[i] = bounds[2 * i];
        t->tile_max[i] = bounds[2 * i + 1];
        if (t->tile_min[i] < lo)
            lo = t->tile_min[i];
        if (t->tile_max[i] > hi)
            hi = t->tile_max[i];
    }
    free(bounds);
    if (!(lo <= hi)) { /* every texel NaN */
        lo = hi = NAN;
    }
    double scale = plod__tiles_scale(t->type);
    t->global_lo = lo * scale;
    t->global_hi = hi * scale;
    /* the pyramid: 2 x 2 cells per coarser cell, to one cell */
    t->level_w[0] = t->tiles_x, t->level_h[0] = t->tiles_y;
    t->level_min[0] = t->tile_min, t->level_max[0] = t->tile_max;
    t->levels = 1;
    while ((t->level_w[t->levels - 1] > 1 || t->level_h[t->levels - 1] > 1) && t->levels < 32) {
        int l = t->levels, w = (t->level_w[l - 1] + 1) / 2, hgt = (t->level_h[l - 1] + 1) / 2;
        t->level_w[l] = w, t->level_h[l] = hgt;
        t->level_min[l] = malloc((size_t)w * (size_t)hgt * sizeof(float));
        t->level_max[l] = malloc((size_t)w * (size_t)hgt * sizeof(float));
        t->levels++;
        if (!t->level_min[l] || !t->level_max[l]) {
            s = PLOD_ERR_NO_MEMORY;
            goto fail;
        }
        for (int y = 0; y < hgt; y++)
            for (int x = 0; x < w; x++) {
                float a = INFINITY, b = -INFINITY;
                for (int dy = 0; dy < 2; dy++)
                    for (int dx = 0; dx < 2; dx++) {
                        int sx = 2 * x + dx, sy = 2 * y + dy;
                        if (sx >= t->level_w[l - 1] || sy >= t->level_h[l - 1])
                            continue;
                        size_t k = (size_t)sy * (size_t)t->level_w[l - 1] + (size_t)sx;
                        a = t->level_min[l - 1][k] < a ? t->level_min[l - 1][k] : a;
                        b = t->level_max[l - 1][k] > b ? t->level_max[l - 1][k] : b;
                    }
                t->level_min[l][(size_t)y * (size_t)w + (size_t)x] = a;
                t->level_max[l][(size_t)y * (size_t)w + (size_t)x] = b;
            }
    }
    if (cache_bytes == 0)
        cache_bytes = PLOD_TILES_DEFAULT_CACHE_BYTES;
    t->slots = cache_bytes / t->tile_bytes;
    if (t->slots < 16)
        t->slots = 16;
    if (t->slots > count)
        t->slots = count;
    t->slot_data = malloc(t->slots * t->tile_bytes); /* pages are touched as tiles arrive */
    t->slot_tile = malloc(t->slots * sizeof(int32_t));
    t->slot_ref = calloc(t->slots, 1);
    t->tile_slot = malloc(count * sizeof(int32_t));
    if (!t->slot_data || !t->slot_tile || !t->slot_ref || !t->tile_slot || count > INT32_MAX) {
        s = PLOD_ERR_NO_MEMORY;
        goto fail;
    }
    for (size_t i = 0; i < count; i++)
        t->tile_slot[i] = -1;
    if (!plod_mutex_init(&t->lock)) {
        s = PLOD_ERR_NO_MEMORY;
        goto fail;
    }
    *out = t;
    return PLOD_OK;
fail:
    for (int l = 1; l < t->levels; l++)
        free(t->level_min[l]), free(t->level_max[l]);
    free(t->tile_min), free(t->tile_max), free(t->slot_data), free(t->slot_tile);
    free(t->slot_ref), free(t->tile_slot);
    plod_file_close(file);
    free(t);
    if (s == PLOD_ERR_NO_MEMORY)
        plod_status_format(message, message_size, "out of memory opening '%s'", tiles_path);
    return s;
}

void plod_tiles_destroy(plod_tiles *t)
{
    if (!t)
        return;
    for (int l = 1; l < t->levels; l++)
        free(t->level_min[l]), free(t->level_max[l]);
    free(t->tile_min), free(t->tile_max), free(t->slot_data), free(t->slot_tile);
    free(t->slot_ref), free(t->tile_slot);
    plod_mutex_destroy(&t->lock);
    plod_file_close(t->file);
    free(t);
}

int plod_tiles_width(const plod_tiles *t) { return t->width; }
int plod_tiles_height(const plod_tiles *t) { return t->height; }
plod_texel_type plod_tiles_type(const plod_tiles *t) { return t->type; }
size_t plod_tiles_nan_count(const plod_tiles *t) { return t->nan_count; }
size_t plod_tiles_cache_limit(const plod_tiles *t) { return t->slots * t->tile_bytes; }

size_t plod_tiles_cached_bytes(const plod_tiles *t)
{
    plod_tiles *m = (plod_tiles *)t;
    plod_mutex_lock(&m->lock);
    size_t bytes = m->used * m->tile_bytes;
    plod_mutex_unlock(&m->lock);
    return bytes;
}

size_t plod_tiles_read_errors(const plod_tiles *t)
{
    plod_tiles *m = (plod_tiles *)t;
    plod_mutex_lock(&m->lock);
    size_t errors = m->read_errors;
    plod_mutex_unlock(&m->lock);
    return errors;
}

/* ---- the cache (callers hold the lock) -------------------------------------------- */

/* Whether a tile read from disk agrees with the bounds its file declares:
 * bounds drive culling and refinement, so texels outside them (or NaN in a
 * file that declares no voids) mean a damaged file, and the tile is refused
 * as a read error rather than shown with wrong bounds. */
static int plod__tile_matches_bounds(const plod_tiles *t, size_t index, const unsigned char *data)
{
    float lo = t->tile_min[index], hi = t->tile_max[index];
    size_t count = (size_t)t->tile * (size_t)t->tile;
    for (size_t k = 0; k < count; k++) {
        float value = plod__tiles_load(data + k * t->sample_bytes, t->type);
        if (value != value) {
            if (t->nan_count == 0)
                return 0;
        } else if (!(value >= lo && value <= hi)) {
            return 0;
        }
    }
    return 1;
}

/* The cached texels of tile `index`, reading it if needed; NULL if the
 * read failed or the tile contradicts its declared bounds. */
static const unsigned char *plod__tile(plod_tiles *t, size_t index)
{
    int32_t slot = t->tile_slot[index];
    if (slot >= 0) {
        t->slot_ref[slot] = 1;
        return t->slot_data + (size_t)slot * t->tile_bytes;
    }
    size_t victim;
    if (t->used < t->slots) {
        victim = t->used++;
    } else {
        for (;;) { /* second chance */
            victim = t->hand;
            t->hand = (t->hand + 1) % t->slots;
            if (!t->slot_ref[victim])
                break;
            t->slot_ref[victim] = 0;
        }
        if (t->slot_tile[victim] >= 0)
            t->tile_slot[t->slot_tile[victim]] = -1;
    }
    t->slot_tile[victim] = -1;
    unsigned char *data = t->slot_data + victim * t->tile_bytes;
    if (!plod_file_read_at(t->file, data, t->tile_bytes,
                           t->data_offset + (uint64_t)index * t->tile_bytes) ||
        !plod__tile_matches_bounds(t, index, data)) {
        t->read_errors++; /* the slot stays empty (reused first by the clock) */
        t->slot_ref[victim] = 0;
        return NULL;
    }
    t->slot_tile[victim] = (int32_t)index;
    t->slot_ref[victim] = 1;
    t->tile_slot[index] = (int32_t)victim;
    return data;
}

/* Wrapped texel indices, as plod__car_wrap: (i, j) with j = 0 south. */
static void plod__tiles_wrap(const plod_tiles *t, int *i, int *j)
{
    int w = t->width, h = t->height;
    if (*j < 0 || *j >= h) {
        *j = *j < 0 ? -1 - *j : 2 * h - 1 - *j;
        *i += w / 2;
    }
    if (*j < 0)
        *j = 0;
    if (*j >= h)
        *j = h - 1;
    *i %= w;
    if (*i < 0)
        *i += w;
}

/* Texel (i, j), j = 0 south, already wrapped; lock held. */
static double plod__texel(plod_tiles *t, int i, int j)
{
    int row = t->height - 1 - j; /* the file is north first */
    size_t index = (size_t)(row / t->tile) * (size_t)t->tiles_x + (size_t)(i / t->tile);
    const unsigned char *data = plod__tile(t, index);
    if (!data)
        return NAN;
    size_t at = (size_t)(row % t->tile) * (size_t)t->tile + (size_t)(i % t->tile);
    return plod__tiles_value(data + at * t->sample_bytes, t->type);
}

double plod_tiles_sample_uv(const plod_tiles *tiles, double u, double v)
{
    if (!(u == u) || !(v == v) || !isfinite(u) || !isfinite(v))
        return NAN;
    u = u < -1.0 ? -1.0 : u > 1.0 ? 1.0 : u;
    v = v < -1.0 ? -1.0 : v > 1.0 ? 1.0 : v;
    plod_tiles *t = (plod_tiles *)tiles; /* the cache changes; the map does not */
    double s = (u + 1.0) * 0.5 * t->width - 0.5, r = (v + 1.0) * 0.5 * t->height - 0.5;
    double fi = floor(s), fj = floor(r);
    double wu = s - fi, wv = r - fj;
    int ii[4] = {(int)fi, (int)fi + 1, (int)fi, (int)fi + 1};
    int jj[4] = {(int)fj, (int)fj, (int)fj + 1, (int)fj + 1};
    double tap[4];
    plod_mutex_lock(&t->lock);
    for (int k = 0; k < 4; k++) {
        plod__tiles_wrap(t, &ii[k], &jj[k]);
        tap[k] = plod__texel(t, ii[k], jj[k]);
    }
    plod_mutex_unlock(&t->lock);
    /* as plod__lerp_taps */
    double bottom = tap[0] + wu * (tap[1] - tap[0]);
    double top = tap[2] + wu * (tap[3] - tap[2]);
    return bottom + wv * (top - bottom);
}

/* min/max of stored values over texel rows [r0, r1] (north-first file
 * rows) and columns [c0, c1], all inside the map: exact within 2 x 2
 * tiles, else from the coarsest pyramid level whose cells still resolve
 * the box into at most 4 x 4 cells. */
static void plod__rect(plod_tiles *t, int c0, int r0, int c1, int r1, float *lo, float *hi)
{
    int tx0 = c0 / t->tile, tx1 = c1 / t->tile, ty0 = r0 / t->tile, ty1 = r1 / t->tile;
    if ((tx1 - tx0 + 1) * (ty1 - ty0 + 1) <= 4) {
        plod_mutex_lock(&t->lock);
        for (int ty = ty0; ty <= ty1; ty++)
            for (int tx = tx0; tx <= tx1; tx++) {
                size_t index = (size_t)ty * (size_t)t->tiles_x + (size_t)tx;
                const unsigned char *data = plod__tile(t, index);
                if (!data) { /* unreadable: the tile's stored bounds */
                    *lo = t->tile_min[index] < *lo ? t->tile_min[index] : *lo;
                    *hi = t->tile_max[index] > *hi ? t->tile_max[index] : *hi;
                    continue;
                }
                int a0 = tx == tx0 ? c0 % t->tile : 0, a1 = tx == tx1 ? c1 % t->tile : t->tile - 1;
                int b0 = ty == ty0 ? r0 % t->tile : 0, b1 = ty == ty1 ? r1 % t->tile : t->tile - 1;
                for (int b = b0; b <= b1; b++)
                    for (int a = a0; a <= a1; a++) {
                        float v = plod__tiles_load(
                            data + ((size_t)b * (size_t)t->tile + (size_t)a) * t->sample_bytes,
                            t->type);
                        if (v < *lo)
                            *lo = v;
                        if (v > *hi)
                            *hi = v;
                    }
            }
        plod_mutex_unlock(&t->lock);
        return;
    }
    int l = 0;
    while (l + 1 < t->levels && ((tx1 >> l) - (tx0 >> l) + 1) * ((ty1 >> l) - (ty0 >> l) + 1) > 16)
        l++;
    for (int y = ty0 >> l; y <= ty1 >> l; y++)
        for (int x = tx0 >> l; x <= tx1 >> l; x++) {
            size_t k = (size_t)y * (size_t)t->level_w[l] + (size_t)x;
            if (t->level_min[l][k] < *lo)
                *lo = t->level_min[l][k];
            if (t->level_max[l][k] > *hi)
                *hi = t->level_max[l][k];
        }
}

void plod_tiles_range_uv(const plod_tiles *tiles, double u0, double v0, double u1, double v1,
                         double *lo_out, double *hi_out)
{
    plod_tiles *t = (plod_tiles *)tiles;
    if (!(isfinite(u0) && isfinite(u1) && isfinite(v0) && isfinite(v1))) {
        plod_tiles_global_range(tiles, lo_out, hi_out);
        return;
    }
    if (u0 > u1) { double s = u0; u0 = u1; u1 = s; }
    if (v0 > v1) { double s = v0; v0 = v1; v1 = s; }
    u0 = u0 < -1.0 ? -1.0 : u0 > 1.0 ? 1.0 : u0;
    u1 = u1 < -1.0 ? -1.0 : u1 > 1.0 ? 1.0 : u1;
    v0 = v0 < -1.0 ? -1.0 : v0 > 1.0 ? 1.0 : v0;
    v1 = v1 < -1.0 ? -1.0 : v1 > 1.0 ? 1.0 : v1;
    /* every texel a bilinear tap in the box can read (as plod_cubemap_range) */
    int i0 = (int)floor((u0 + 1.0) * 0.5 * t->width - 0.5);
    int i1 = (int)floor((u1 + 1.0) * 0.5 * t->width - 0.5) + 1;
    int j0 = (int)floor((v0 + 1.0) * 0.5 * t->height - 0.5);
    int j1 = (int)floor((v1 + 1.0) * 0.5 * t->height - 0.5) + 1;
    float lo = INFINITY, hi = -INFINITY;
    int ci0 = i0 < 0 ? 0 : i0, ci1 = i1 >= t->width ? t->width - 1 : i1;
    int cj0 = j0 < 0 ? 0 : j0, cj1 = j1 >= t->height ? t->height - 1 : j1;
    /* rows: j = 0 south is file row height - 1 */
    plod__rect(t, ci0, t->height - 1 - cj1, ci1, t->height - 1 - cj0, &lo, &hi);
    if (i0 < 0) /* wrap in longitude */
        plod__rect(t, t->width - 1, t->height - 1 - cj1, t->width - 1, t->height - 1 - cj0, &lo,
                   &hi);
    if (i1 >= t->width)
        plod__rect(t, 0, t->height - 1 - cj1, 0, t->height - 1 - cj0, &lo, &hi);
    if (j0 < 0) /* across a pole: the whole edge row */
        plod__rect(t, 0, t->height - 1, t->width - 1, t->height - 1, &lo, &hi);
    if (j1 >= t->height)
        plod__rect(t, 0, 0, t->width - 1, 0, &lo, &hi);
    double scale = plod__tiles_scale(t->type);
    if (!(lo <= hi)) { /* nothing but NaN */
        *lo_out = t->global_lo;
        *hi_out = t->global_hi;
        return;
    }
    *lo_out = lo * scale;
    *hi_out = hi * scale;
}

void plod_tiles_global_range(const plod_tiles *t, double *lo, double *hi)
{
    *lo = t->global_lo;
    *hi = t->global_hi;
}

/* ---- as a height source ------------------------------------------------------------ */

static void plod__tiles_lonlat(const double dir[3], double *u, double *v)
{
    /* exactly as plod_cubemap_locate for CAR maps: the same bits */
    *u = atan2(dir[1], dir[0]) / PLOD_PI;
    *v = atan2(dir[2], hypot(dir[0], dir[1])) / (0.5 * PLOD_PI);
}

static double plod__tiles_source_sample(const void *self, const double dir[3])
{
    double u, v;
    plod__tiles_lonlat(dir, &u, &v);
    return plod_tiles_sample_uv(self, u, v);
}

void plod_lonlat_cap_range(const double axis[3], double angle, int width, int height,
                           plod_range_uv_fn range_uv, const void *context, double *lo_out,
                           double *hi_out, double *texels)
{
    *texels = INFINITY;
    if (!(angle >= 0.0) || angle >= 0.5 * PLOD_PI)
        return;
    const double deg = 180.0 / PLOD_PI;
    double lat = asin(fmax(-1.0, fmin(1.0, axis[2])));
    double lon = atan2(axis[1], axis[0]);
    double lat0 = lat - angle, lat1 = lat + angle, half_lon;
    if (lat1 >= 0.5 * PLOD_PI || lat0 <= -0.5 * PLOD_PI) {
        half_lon = PLOD_PI; /* a pole inside: every longitude */
        lat0 = fmax(lat0, -0.5 * PLOD_PI);
        lat1 = fmin(lat1, 0.5 * PLOD_PI);
    } else {
        /* longitude half-width of a cap not holding a pole */
        half_lon = asin(fmin(1.0, sin(angle) / cos(lat)));
    }
    double v0 = lat0 * deg / 90.0, v1 = lat1 * deg / 90.0;
    double lo, hi, lo2, hi2;
    if (half_lon >= PLOD_PI) {
        range_uv(context, -1.0, v0, 1.0, v1, &lo, &hi);
    } else {
        double u0 = (lon - half_lon) * deg / 180.0, u1 = (lon + half_lon) * deg / 180.0;
        if (u0 < -1.0) { /* across the +-180 deg seam: two boxes */
            range_uv(context, -1.0, v0, u1, v1, &lo, &hi);
            range_uv(context, u0 + 2.0, v0, 1.0, v1, &lo2, &hi2);
            lo = fmin(lo, lo2);
            hi = fmax(hi, hi2);
        } else if (u1 > 1.0) {
            range_uv(context, u0, v0, 1.0, v1, &lo, &hi);
            range_uv(context, -1.0, v0, u1 - 2.0, v1, &lo2, &hi2);
            lo = fmin(lo, lo2);
            hi = fmax(hi, hi2);
        } else {
            range_uv(context, u0, v0, u1, v1, &lo, &hi);
        }
    }
    *lo_out = lo;
    *hi_out = hi;
    *texels = fmax(2.0 * half_lon * deg / 360.0 * width, (lat1 - lat0) * deg / 180.0 * height);
}

static void plod__tiles_range_uv_fn(const void *tiles, double u0, double v0, double u1,
                                    double v1, double *lo, double *hi)
{
    plod_tiles_range_uv(tiles, u0, v0, u1, v1, lo, hi);
}

static void plod__tiles_source_range_cap(const void *self, const double axis[3], double angle,
                                         double *lo_out, double *hi_out, double *texels)
{
    const plod_tiles *t = self;
    plod_tiles_global_range(t, lo_out, hi_out);
    plod_lonlat_cap_range(axis, angle, t->width, t->height, plod__tiles_range_uv_fn, t, lo_out,
                          hi_out, texels);
}

static void plod__tiles_source_global(const void *self, double *lo, double *hi)
{
    plod_tiles_global_range(self, lo, hi);
}

static double plod__tiles_source_texel(const void *self, const double dir[3])
{
    (void)dir;
    const plod_tiles *t = self;
    return PLOD_PI / t->height; /* along a meridian; narrower east-west near the poles */
}

static size_t plod__tiles_source_nan_count(const void *self)
{
    return plod_tiles_nan_count(self);
}

static const plod_height_source_ops plod__tiles_ops = {
    plod__tiles_source_sample,
    plod__tiles_source_range_cap,
    plod__tiles_source_global,
    plod__tiles_source_texel,
    plod__tiles_source_nan_count,
};

plod_height_source plod_tiles_source(const plod_tiles *tiles)
{
    plod_height_source source = {&plod__tiles_ops, tiles};
    return source;
}
