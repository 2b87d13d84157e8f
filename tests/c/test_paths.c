/* Files named in UTF-8 beyond ASCII (an artist's home folder such as
 * C:\Users\José): the headerless grid reader, the raw-format guess and the
 * GeoTIFF tag reader open them through the platform layer, on POSIX and on
 * Windows (where the C runtime's narrow calls would read the name in the
 * ANSI code page and miss the file). */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "plod.h"
#include "plod_platform.h"

#define CHECK(cond)                                                                 \
    do {                                                                            \
        if (!(cond)) {                                                              \
            fprintf(stderr, "%s:%d: check failed: %s\n", __FILE__, __LINE__, #cond); \
            exit(1);                                                                \
        }                                                                           \
    } while (0)

static void write_file(const char *path, const void *data, size_t bytes)
{
    plod_file file;
    CHECK(plod_file_open(&file, path, PLOD_FILE_CREATE));
    CHECK(plod_file_write_at(file, data, bytes, 0));
    CHECK(plod_file_close(file));
}

int main(void)
{
    /* "Mont-Blanc é ñ 雪.r16": two- and three-byte UTF-8 sequences */
    const char *grid = "Mont-Blanc \xc3\xa9 \xc3\xb1 \xe9\x9b\xaa.r16";
    const char *tiff = "g\xc3\xa9otiff \xe9\x9b\xaa.tif";
    char message[512];

    /* a 4 x 4 u16 little-endian grid, texel i = 1000 + i */
    unsigned char bytes[32];
    for (int i = 0; i < 16; i++) {
        bytes[2 * i] = (unsigned char)((1000 + i) & 0xff);
        bytes[2 * i + 1] = (unsigned char)((1000 + i) >> 8);
    }
    write_file(grid, bytes, sizeof bytes);
    plod_path_info info;
    CHECK(plod_path_info_get(grid, &info) && info.regular && info.size == 32);

    plod_raw_format format;
    CHECK(plod_raw_guess(grid, &format, message, sizeof message) == PLOD_OK);
    CHECK(format.width == 4 && format.height == 4 && format.type == PLOD_RAW_U16);
    plod_image image = {0};
    CHECK(plod_image_read_raw(&image, grid, &format, 0, message, sizeof message) == PLOD_OK);
    CHECK(image.width == 4 && image.height == 4 && image.type == PLOD_TEXEL_U16);
    for (int i = 0; i < 16; i++)
        CHECK(((const uint16_t *)image.pixels)[i] == 1000 + i);
    plod_image_free(&image);

    /* a TIFF header without its directory: the reader opens the file and
     * says it is truncated (a file it could not open would be an I/O error) */
    write_file(tiff, "II*\0", 4);
    plod_georef geo;
    CHECK(plod_georef_read(&geo, tiff, message, sizeof message) == PLOD_ERR_BAD_IMAGE);
    CHECK(strstr(message, "truncated") != NULL);

    /* and a missing file with such a name is an I/O error naming it */
    CHECK(plod_path_remove(grid) && plod_path_remove(tiff));
    CHECK(plod_image_read_raw(&image, grid, &format, 0, message, sizeof message) == PLOD_ERR_IO);
    CHECK(strstr(message, grid) != NULL);
    CHECK(plod_georef_read(&geo, tiff, message, sizeof message) == PLOD_ERR_IO);

    printf("paths C tests passed\n");
    return 0;
}
