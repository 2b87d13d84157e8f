/* plod_image.h -- plain 2-D images and file I/O through OpenImageIO
 * (image_io.cpp is the only C++ in the core: a thin extern "C" bridge).
 */
#ifndef PLOD_IMAGE_H
#define PLOD_IMAGE_H

#include <stddef.h>
#include "plod_cubemap.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Caller-visible image: rows top to bottom, channels interleaved.  Memory in
 * `pixels` is owned by whoever filled it; plod_image_free releases what
 * plod_image_alloc / plod_image_read allocated. */
#define PLOD_IMAGE_DEFAULT_MAX_PIXELS ((size_t)1 << 28)

typedef struct plod_image {
    int width;
    int height;
    int channels;            /* 1..4 */
    plod_texel_type type;
    void *pixels;
} plod_image;

/* Allocates zeroed pixels; rejects sizes over 2^31 texels per side product
 * limits (PLOD_ERR_NO_MEMORY / PLOD_ERR_BAD_PARAM). */
plod_status plod_image_alloc(plod_image *image, int width, int height,
                             int channels, plod_texel_type type);
void plod_image_free(plod_image *image);
size_t plod_image_texel_bytes(plod_texel_type type);

/* Reads any format OpenImageIO can (PNG 8/16, JPEG, TIFF incl. float, EXR).
 * Pixel type kept as u8/u16/f32 (other types converted to f32).
 * Errors: PLOD_ERR_IO (missing/unreadable), PLOD_ERR_BAD_IMAGE (corrupt,
 * zero size, > max_pixels; max_pixels 0 = PLOD_IMAGE_DEFAULT_MAX_PIXELS),
 * more than 4 channels).  Never throws.  `message` (may be NULL) receives a
 * NUL-terminated explanation of up to message_size bytes. */
plod_status plod_image_read(plod_image *image, const char *path,
                            size_t max_pixels, char *message,
                            size_t message_size);
/* Writes with the format chosen by the extension.  PLOD_ERR_IO on failure
 * (a partly written file is removed); PLOD_ERR_BAD_PARAM when a known file
 * type cannot hold the pixel type losslessly (.png: u8/u16; .jpg/.bmp/.tga:
 * u8; .exr/.hdr/.pfm: f32; .tif: all). */
plod_status plod_image_write(const plod_image *image, const char *path,
                             char *message, size_t message_size);

#ifdef __cplusplus
}
#endif
#endif /* PLOD_IMAGE_H */
