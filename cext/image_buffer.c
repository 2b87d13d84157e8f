/* image_buffer.c -- images in memory: allocation, and taking in the typed
 * pixel buffers a caller decoded (plod_image.h).
 *
 * The buffer comes from outside the core (a decoder's array), so every
 * size is checked against the buffer's length before a byte is read, and a
 * texel count beyond max_pixels is refused before any allocation.
 */
#include "plod_image.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

size_t plod_image_texel_bytes(plod_texel_type type)
{
    switch (type) {
    case PLOD_TEXEL_U8: return 1;
    case PLOD_TEXEL_U16: return 2;
    case PLOD_TEXEL_F32: return 4;
    default: return 0;
    }
}

plod_status plod_image_alloc(plod_image *image, int width, int height, int channels,
                             plod_texel_type type)
{
    if (!image)
        return PLOD_ERR_NULL;
    image->pixels = NULL;
    image->borrowed = 0;
    if (width <= 0 || height <= 0 || channels < 1 || channels > 4 ||
        (unsigned)type >= PLOD_TEXEL_TYPE_COUNT)
        return PLOD_ERR_BAD_PARAM;
    uint64_t count = (uint64_t)width * (uint64_t)height;
    if (count > ((uint64_t)1 << 31))
        return PLOD_ERR_BAD_PARAM;
    uint64_t bytes = count * (uint64_t)channels * plod_image_texel_bytes(type);
    if (bytes > (uint64_t)SIZE_MAX)
        return PLOD_ERR_NO_MEMORY;
    void *pixels = calloc((size_t)bytes, 1);
    if (!pixels)
        return PLOD_ERR_NO_MEMORY;
    image->width = width;
    image->height = height;
    image->channels = channels;
    image->type = type;
    image->pixels = pixels;
    return PLOD_OK;
}

void plod_image_free(plod_image *image)
{
    if (!image)
        return;
    if (!image->borrowed)
        free(image->pixels);
    image->pixels = NULL;
    image->borrowed = 0;
}

plod_status plod_image_import(plod_image *image, const plod_image_buffer *buffer,
                              plod_import_mode mode, int writable, size_t max_pixels,
                              const char *name, char *message, size_t message_size)
{
    plod_status_format(message, message_size, "%s", "");
    if (!image || !buffer)
        return PLOD_ERR_NULL;
    image->pixels = NULL;
    image->borrowed = 0;
    if (!name)
        name = "image";
    if ((unsigned)buffer->type >= PLOD_RAW_TYPE_COUNT ||
        (mode != PLOD_IMPORT_TYPED && mode != PLOD_IMPORT_STORED)) {
        plod_status_format(message, message_size, "'%s': unknown sample type %d or mode %d",
                           name, (int)buffer->type, (int)mode);
        return PLOD_ERR_BAD_PARAM;
    }
    if (buffer->width <= 0 || buffer->height <= 0) {
        plod_status_format(message, message_size, "'%s' has an unsupported size (%dx%d)", name,
                           buffer->width, buffer->height);
        return PLOD_ERR_BAD_IMAGE;
    }
    if (buffer->channels < 1 || buffer->channels > 4) {
        plod_status_format(message, message_size, "'%s' has %d channels; 1 to 4 are supported",
                           name, buffer->channels);
        return PLOD_ERR_BAD_IMAGE;
    }
    if (max_pixels == 0)
        max_pixels = PLOD_IMAGE_DEFAULT_MAX_PIXELS;
    uint64_t texels = (uint64_t)buffer->width * (uint64_t)buffer->height;
    if (texels > (uint64_t)max_pixels) {
        plod_status_format(message, message_size,
                           "'%s' is %dx%d pixels, more than the limit of %zu", name,
                           buffer->width, buffer->height, max_pixels);
        return PLOD_ERR_BAD_IMAGE;
    }
    uint64_t count = texels * (uint64_t)buffer->channels;
    size_t sample = plod_raw_sample_bytes(buffer->type);
    if (!buffer->pixels || count * sample != (uint64_t)buffer->bytes) {
        plod_status_format(message, message_size,
                           "'%s': %zu bytes of pixels; %dx%d x %d samples of %zu bytes need "
                           "%llu",
                           name, buffer->bytes, buffer->width, buffer->height, buffer->channels,
                           sample, (unsigned long long)(count * sample));
        return PLOD_ERR_BAD_IMAGE;
    }
    plod_texel_type type = PLOD_TEXEL_F32;
    if (mode == PLOD_IMPORT_TYPED && buffer->type == PLOD_RAW_U8)
        type = PLOD_TEXEL_U8;
    else if (mode == PLOD_IMPORT_TYPED && buffer->type == PLOD_RAW_U16)
        type = PLOD_TEXEL_U16;
    int same = (type == PLOD_TEXEL_U8 && buffer->type == PLOD_RAW_U8) ||
               (type == PLOD_TEXEL_U16 && buffer->type == PLOD_RAW_U16) ||
               (type == PLOD_TEXEL_F32 && buffer->type == PLOD_RAW_F32);
    if (same && writable) {
        image->width = buffer->width;
        image->height = buffer->height;
        image->channels = buffer->channels;
        image->type = type;
        image->pixels = (void *)buffer->pixels;
        image->borrowed = 1;
        return PLOD_OK;
    }
    plod_image loaded = {0};
    plod_status status =
        plod_image_alloc(&loaded, buffer->width, buffer->height, buffer->channels, type);
    if (status != PLOD_OK) {
        plod_status_format(message, message_size, "cannot allocate %dx%d pixels for '%s'",
                           buffer->width, buffer->height, name);
        return status;
    }
    if (same) {
        memcpy(loaded.pixels, buffer->pixels, buffer->bytes);
    } else {
        const unsigned char *in = buffer->pixels;
        float *out = loaded.pixels;
        for (size_t i = 0; i < (size_t)count; i++) {
            switch (buffer->type) {
            case PLOD_RAW_U8: out[i] = (float)in[i]; break;
            case PLOD_RAW_U16: {
                uint16_t v;
                memcpy(&v, in + 2 * i, 2);
                out[i] = (float)v;
                break;
            }
            case PLOD_RAW_I16: {
                int16_t v;
                memcpy(&v, in + 2 * i, 2);
                out[i] = (float)v;
                break;
            }
            default: memcpy(out + i, in + 4 * i, 4);
            }
        }
    }
    *image = loaded;
    return PLOD_OK;
}
