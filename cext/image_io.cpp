/* image_io.cpp -- the only C++ in the core: an extern "C" bridge from
 * plod_image.h to OpenImageIO 2.4.
 *
 * Rules of this file:
 *   - no C++ exception ever crosses into C: every entry point catches
 *     everything and returns a status with a message;
 *   - sizes are checked before any allocation (max_pixels guard), so a
 *     corrupt header that claims 10^6 x 10^6 pixels fails cleanly;
 *   - pixel memory is malloc'ed (plod_image_free is plain free()).
 */
#include "plod_image.h"

#include <OpenImageIO/imageio.h>

#include <sys/stat.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <new>
#include <string>

namespace {

const size_t plod__default_max_pixels = PLOD_IMAGE_DEFAULT_MAX_PIXELS;

void plod__set_message(char *message, size_t message_size, const std::string &text)
{
    if (!message || message_size == 0)
        return;
    size_t n = text.size() < message_size - 1 ? text.size() : message_size - 1;
    std::memcpy(message, text.data(), n);
    message[n] = '\0';
}

/* Lower-case extension without the dot ("" if none). */
std::string plod__extension(const char *path)
{
    const char *slash = std::strrchr(path, '/');
    const char *dot = std::strrchr(path, '.');
    if (!dot || (slash && dot < slash))
        return std::string();
    std::string ext(dot + 1);
    for (char &c : ext)
        c = (char)std::tolower((unsigned char)c);
    return ext;
}

const char *plod__type_name(plod_texel_type type)
{
    switch (type) {
    case PLOD_TEXEL_U8: return "8-bit";
    case PLOD_TEXEL_U16: return "16-bit";
    case PLOD_TEXEL_F32: return "float32";
    default: return "unknown";
    }
}

OIIO::TypeDesc plod__oiio_type(plod_texel_type type)
{
    switch (type) {
    case PLOD_TEXEL_U8: return OIIO::TypeDesc::UINT8;
    case PLOD_TEXEL_U16: return OIIO::TypeDesc::UINT16;
    default: return OIIO::TypeDesc::FLOAT;
    }
}

/* Whether a file type we know stores `type` without loss.  Unknown
 * extensions are left to OpenImageIO. */
bool plod__writer_holds(const std::string &ext, plod_texel_type type)
{
    if (ext == "png" || ext == "ppm" || ext == "pgm" || ext == "pnm")
        return type == PLOD_TEXEL_U8 || type == PLOD_TEXEL_U16;
    if (ext == "jpg" || ext == "jpeg" || ext == "bmp" || ext == "tga" || ext == "gif")
        return type == PLOD_TEXEL_U8;
    if (ext == "exr" || ext == "hdr" || ext == "pfm")
        return type == PLOD_TEXEL_F32;
    return true;
}

/* Reads the whole first subimage as `format`.  OIIO's converting
 * read_image allocates a fixed ~64 MB chunk per call whatever the image's
 * size (read_scanlines), which made every small read cost page faults for
 * 64 MB; a native read goes straight into `pixels`, and a conversion goes
 * through a buffer of the image's own size. */
bool plod__read_pixels(OIIO::ImageInput &input, OIIO::TypeDesc format, void *pixels)
{
    const OIIO::ImageSpec &spec = input.spec();
    if (!spec.channelformats.empty())
        return input.read_image(0, 0, 0, spec.nchannels, format, pixels);
    if (spec.format == format)
        return input.read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::UNKNOWN, pixels);
    std::unique_ptr<char[]> native(new (std::nothrow) char[spec.image_bytes(true)]);
    if (!native)
        return false;
    return input.read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::UNKNOWN, native.get()) &&
           OIIO::convert_image(spec.nchannels, spec.width, spec.height, 1, native.get(),
                               spec.format, OIIO::AutoStride, OIIO::AutoStride,
                               OIIO::AutoStride, pixels, format, OIIO::AutoStride,
                               OIIO::AutoStride, OIIO::AutoStride);
}

/* OpenEXR allocates each header attribute's declared size before reading
 * it, so a few hundred corrupt bytes can demand gigabytes (found by
 * fuzz_image: a 282-byte file made OpenEXR 3.1 allocate 1.9 GB).  Walks the
 * first header's attributes (name, type, int32 size, value) and refuses a
 * size larger than the file.  True: not an EXR, or a plausible header. */
bool plod__exr_header_plausible(const char *path, long long file_size)
{
    std::FILE *f = std::fopen(path, "rb");
    if (!f)
        return true; /* let the reader report it */
    unsigned char head[8];
    bool plausible = true;
    if (std::fread(head, 1, 8, f) == 8 && head[0] == 0x76 && head[1] == 0x2f &&
        head[2] == 0x31 && head[3] == 0x01) {
        for (int attribute = 0; attribute < 1024; attribute++) {
            int c = std::fgetc(f), strings = 0;
            if (c == 0 || c == EOF)
                break; /* end of header (or truncated: OIIO reports it) */
            while (strings < 2 && c != EOF) /* attribute name, then type name */
                strings += (c = std::fgetc(f)) == 0;
            unsigned char le[4];
            if (c == EOF || std::fread(le, 1, 4, f) != 4)
                break;
            long long size = (long long)((uint32_t)le[0] | (uint32_t)le[1] << 8 |
                                         (uint32_t)le[2] << 16 | (uint32_t)le[3] << 24);
            if (size > file_size || std::fseek(f, (long)size, SEEK_CUR) != 0) {
                plausible = false;
                break;
            }
        }
    }
    std::fclose(f);
    return plausible;
}

/* Integer samples of a native buffer as f32 holding their values. */
bool plod__integers_to_float(OIIO::TypeDesc format, const void *native, size_t count,
                             float *out)
{
    switch (format.basetype) {
    case OIIO::TypeDesc::UINT8:
        for (size_t i = 0; i < count; i++) out[i] = (float)((const uint8_t *)native)[i];
        return true;
    case OIIO::TypeDesc::INT8:
        for (size_t i = 0; i < count; i++) out[i] = (float)((const int8_t *)native)[i];
        return true;
    case OIIO::TypeDesc::UINT16:
        for (size_t i = 0; i < count; i++) out[i] = (float)((const uint16_t *)native)[i];
        return true;
    case OIIO::TypeDesc::INT16:
        for (size_t i = 0; i < count; i++) out[i] = (float)((const int16_t *)native)[i];
        return true;
    case OIIO::TypeDesc::UINT32:
        for (size_t i = 0; i < count; i++) out[i] = (float)((const uint32_t *)native)[i];
        return true;
    case OIIO::TypeDesc::INT32:
        for (size_t i = 0; i < count; i++) out[i] = (float)((const int32_t *)native)[i];
        return true;
    default:
        return false;
    }
}

/* Reads the first subimage as f32 values as stored (integers not
 * normalised). */
bool plod__read_stored(OIIO::ImageInput &input, float *pixels)
{
    const OIIO::ImageSpec &spec = input.spec();
    unsigned char base = spec.format.basetype;
    bool integer = base == OIIO::TypeDesc::UINT8 || base == OIIO::TypeDesc::INT8 ||
                   base == OIIO::TypeDesc::UINT16 || base == OIIO::TypeDesc::INT16 ||
                   base == OIIO::TypeDesc::UINT32 || base == OIIO::TypeDesc::INT32;
    if (!spec.channelformats.empty() || !integer) /* floats keep their values anyway */
        return plod__read_pixels(input, OIIO::TypeDesc::FLOAT, pixels);
    std::unique_ptr<char[]> native(new (std::nothrow) char[spec.image_bytes(true)]);
    if (!native)
        return false;
    return input.read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::UNKNOWN, native.get()) &&
           plod__integers_to_float(spec.format, native.get(),
                                   (size_t)spec.image_pixels() * (size_t)spec.nchannels, pixels);
}

plod_status plod__read(plod_image *image, const char *path, size_t max_pixels, bool stored,
                       char *message, size_t message_size)
{
    struct stat info;
    if (stat(path, &info) != 0) {
        plod__set_message(message, message_size,
                          std::string("cannot open '") + path + "': " + std::strerror(errno));
        return PLOD_ERR_IO;
    }
    if (!S_ISREG(info.st_mode)) {
        plod__set_message(message, message_size,
                          std::string("'") + path + "' is not a regular file");
        return PLOD_ERR_IO;
    }
    FILE *probe = std::fopen(path, "rb");
    if (!probe) {
        plod__set_message(message, message_size,
                          std::string("cannot read '") + path + "': " + std::strerror(errno));
        return PLOD_ERR_IO;
    }
    std::fclose(probe);
    if (info.st_size == 0) {
        plod__set_message(message, message_size,
                          std::string("'") + path + "' is empty (0 bytes)");
        return PLOD_ERR_BAD_IMAGE;
    }

    if (!plod__exr_header_plausible(path, (long long)info.st_size)) {
        plod__set_message(message, message_size,
                          std::string("'") + path +
                              "' is a corrupt OpenEXR file (a header attribute is larger than the file)");
        return PLOD_ERR_BAD_IMAGE;
    }
    auto input = OIIO::ImageInput::open(path);
    if (!input) {
        std::string why = OIIO::geterror();
        plod__set_message(message, message_size,
                          std::string("'") + path + "' is not a readable image" +
                              (why.empty() ? "" : ": " + why));
        return PLOD_ERR_BAD_IMAGE;
    }
    /* OpenImageIO 2.4's SGI reader writes past the caller's buffer on
     * corrupt RLE data (fuzz_image: fuzz/repro/sgi-rle-overflow.sgi) and
     * news negative sizes; heightmaps do not come as SGI, so it is refused
     * rather than trusted with Blender's heap. */
    if (std::strcmp(input->format_name(), "sgi") == 0) {
        plod__set_message(message, message_size,
                          std::string("'") + path +
                              "' is an SGI image; SGI is not supported (use PNG, TIFF or EXR)");
        return PLOD_ERR_BAD_IMAGE;
    }
    const OIIO::ImageSpec &spec = input->spec();
    if (spec.width <= 0 || spec.height <= 0 || spec.depth != 1 || spec.deep) {
        plod__set_message(message, message_size,
                          std::string("'") + path + "' has an unsupported size or layout (" +
                              std::to_string(spec.width) + "x" + std::to_string(spec.height) +
                              "x" + std::to_string(spec.depth) + (spec.deep ? ", deep" : "") + ")");
        return PLOD_ERR_BAD_IMAGE;
    }
    if (spec.nchannels < 1 || spec.nchannels > 4) {
        plod__set_message(message, message_size,
                          std::string("'") + path + "' has " + std::to_string(spec.nchannels) +
                              " channels; 1 to 4 are supported");
        return PLOD_ERR_BAD_IMAGE;
    }
    if (max_pixels == 0)
        max_pixels = plod__default_max_pixels;
    uint64_t pixels = (uint64_t)spec.width * (uint64_t)spec.height;
    if (pixels > (uint64_t)max_pixels) {
        plod__set_message(message, message_size,
                          std::string("'") + path + "' is " + std::to_string(spec.width) + "x" +
                              std::to_string(spec.height) + " pixels, more than the limit of " +
                              std::to_string(max_pixels));
        return PLOD_ERR_BAD_IMAGE;
    }

    plod_texel_type type = PLOD_TEXEL_F32;
    if (stored)
        type = PLOD_TEXEL_F32;
    else if (spec.format == OIIO::TypeDesc::UINT8)
        type = PLOD_TEXEL_U8;
    else if (spec.format == OIIO::TypeDesc::UINT16)
        type = PLOD_TEXEL_U16;

    plod_image loaded = {};
    plod_status status = plod_image_alloc(&loaded, spec.width, spec.height, spec.nchannels, type);
    if (status != PLOD_OK) {
        plod__set_message(message, message_size,
                          std::string("cannot allocate ") + std::to_string(spec.width) + "x" +
                              std::to_string(spec.height) + " pixels for '" + path + "'");
        return status;
    }
    bool ok;
    try { /* decoders throw (OpenEXR, bad_alloc): never leak the pixels */
        ok = stored ? plod__read_stored(*input, (float *)loaded.pixels)
                    : plod__read_pixels(*input, plod__oiio_type(type), loaded.pixels);
    } catch (...) {
        plod_image_free(&loaded);
        throw;
    }
    if (!ok) {
        std::string why = input->geterror();
        plod_image_free(&loaded);
        plod__set_message(message, message_size,
                          std::string("'") + path + "' is corrupt or truncated" +
                              (why.empty() ? "" : ": " + why));
        return PLOD_ERR_BAD_IMAGE;
    }
    input->close();
    *image = loaded;
    return PLOD_OK;
}

plod_status plod__write(const plod_image *image, const char *path, char *message,
                        size_t message_size)
{
    std::string ext = plod__extension(path);
    if (!plod__writer_holds(ext, image->type)) {
        plod__set_message(message, message_size,
                          std::string("a .") + ext + " file cannot hold " +
                              plod__type_name(image->type) + " pixels ('" + path + "')");
        return PLOD_ERR_BAD_PARAM;
    }
    auto output = OIIO::ImageOutput::create(path);
    if (!output) {
        std::string why = OIIO::geterror();
        plod__set_message(message, message_size,
                          std::string("no image writer for '") + path + "'" +
                              (why.empty() ? "" : ": " + why));
        return PLOD_ERR_IO;
    }
    OIIO::ImageSpec spec(image->width, image->height, image->channels,
                         plod__oiio_type(image->type));
    if (!output->open(path, spec)) {
        std::string why = output->geterror();
        plod__set_message(message, message_size,
                          std::string("cannot write '") + path + "'" +
                              (why.empty() ? "" : ": " + why));
        return PLOD_ERR_IO;
    }
    bool ok = output->write_image(plod__oiio_type(image->type), image->pixels);
    std::string why = ok ? std::string() : output->geterror();
    ok = output->close() && ok;
    if (!ok) {
        if (why.empty())
            why = output->geterror();
        std::remove(path);
        plod__set_message(message, message_size,
                          std::string("writing '") + path + "' failed" +
                              (why.empty() ? "" : ": " + why));
        return PLOD_ERR_IO;
    }
    return PLOD_OK;
}

} // namespace

extern "C" {

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
    image->pixels = nullptr;
    if (width <= 0 || height <= 0 || channels < 1 || channels > 4 ||
        (unsigned)type >= PLOD_TEXEL_TYPE_COUNT)
        return PLOD_ERR_BAD_PARAM;
    uint64_t count = (uint64_t)width * (uint64_t)height;
    if (count > ((uint64_t)1 << 31))
        return PLOD_ERR_BAD_PARAM;
    uint64_t bytes = count * (uint64_t)channels * plod_image_texel_bytes(type);
    if (bytes > (uint64_t)SIZE_MAX)
        return PLOD_ERR_NO_MEMORY;
    void *pixels = std::calloc((size_t)bytes, 1);
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
    std::free(image->pixels);
    image->pixels = nullptr;
}

static plod_status plod__read_entry(plod_image *image, const char *path, size_t max_pixels,
                                    bool stored, char *message, size_t message_size)
{
    plod__set_message(message, message_size, "");
    if (!image || !path)
        return PLOD_ERR_NULL;
    image->pixels = nullptr;
    if (plod_raw_is_raw_path(path)) {
        plod_raw_format format;
        plod_status status = plod_raw_guess(path, &format, message, message_size);
        if (status != PLOD_OK)
            return status;
        return plod_image_read_raw(image, path, &format, max_pixels, message, message_size);
    }
    try {
        return plod__read(image, path, max_pixels, stored, message, message_size);
    } catch (const std::bad_alloc &) {
        plod__set_message(message, message_size, std::string("out of memory reading '") + path + "'");
        return PLOD_ERR_NO_MEMORY;
    } catch (const std::exception &e) {
        plod__set_message(message, message_size,
                          std::string("reading '") + path + "' failed: " + e.what());
        return PLOD_ERR_BAD_IMAGE;
    } catch (...) {
        plod__set_message(message, message_size, std::string("reading '") + path + "' failed");
        return PLOD_ERR_BAD_IMAGE;
    }
}

plod_status plod_image_read(plod_image *image, const char *path, size_t max_pixels,
                            char *message, size_t message_size)
{
    return plod__read_entry(image, path, max_pixels, false, message, message_size);
}

plod_status plod_image_read_stored(plod_image *image, const char *path, size_t max_pixels,
                                   char *message, size_t message_size)
{
    return plod__read_entry(image, path, max_pixels, true, message, message_size);
}

plod_status plod_image_write(const plod_image *image, const char *path, char *message,
                             size_t message_size)
{
    plod__set_message(message, message_size, "");
    if (!image || !path || !image->pixels)
        return PLOD_ERR_NULL;
    if (image->width <= 0 || image->height <= 0 || image->channels < 1 || image->channels > 4 ||
        (unsigned)image->type >= PLOD_TEXEL_TYPE_COUNT)
        return PLOD_ERR_BAD_PARAM;
    try {
        return plod__write(image, path, message, message_size);
    } catch (const std::bad_alloc &) {
        plod__set_message(message, message_size, std::string("out of memory writing '") + path + "'");
        return PLOD_ERR_NO_MEMORY;
    } catch (const std::exception &e) {
        plod__set_message(message, message_size,
                          std::string("writing '") + path + "' failed: " + e.what());
        return PLOD_ERR_IO;
    } catch (...) {
        plod__set_message(message, message_size, std::string("writing '") + path + "' failed");
        return PLOD_ERR_IO;
    }
}

struct plod_image_rows {
    std::unique_ptr<OIIO::ImageInput> input;
    OIIO::TypeDesc format;
    int width, height;
};

plod_status plod_image_rows_open(plod_image_rows **out, const char *path, int *width,
                                 int *height, plod_texel_type *type, char *message,
                                 size_t message_size)
{
    plod__set_message(message, message_size, "");
    if (!out || !path || !width || !height || !type)
        return PLOD_ERR_NULL;
    *out = nullptr;
    try {
        struct stat info;
        if (stat(path, &info) != 0 || !S_ISREG(info.st_mode)) {
            plod__set_message(message, message_size,
                              std::string("cannot open '") + path + "'");
            return PLOD_ERR_IO;
        }
        if (!plod__exr_header_plausible(path, (long long)info.st_size)) {
            plod__set_message(message, message_size,
                              std::string("'") + path + "' is a corrupt OpenEXR file");
            return PLOD_ERR_BAD_IMAGE;
        }
        auto input = OIIO::ImageInput::open(path);
        if (!input) {
            std::string why = OIIO::geterror();
            plod__set_message(message, message_size,
                              std::string("'") + path + "' is not a readable image" +
                                  (why.empty() ? "" : ": " + why));
            return PLOD_ERR_BAD_IMAGE;
        }
        const OIIO::ImageSpec &spec = input->spec();
        if (std::strcmp(input->format_name(), "sgi") == 0 || spec.width <= 0 ||
            spec.height <= 0 || spec.depth != 1 || spec.deep || spec.nchannels < 1) {
            plod__set_message(message, message_size,
                              std::string("'") + path + "' has an unsupported format or layout");
            return PLOD_ERR_BAD_IMAGE;
        }
        std::unique_ptr<plod_image_rows> rows(new plod_image_rows);
        *type = spec.format == OIIO::TypeDesc::UINT8    ? PLOD_TEXEL_U8
                : spec.format == OIIO::TypeDesc::UINT16 ? PLOD_TEXEL_U16
                                                        : PLOD_TEXEL_F32;
        rows->format = plod__oiio_type(*type);
        rows->width = *width = spec.width;
        rows->height = *height = spec.height;
        rows->input = std::move(input);
        *out = rows.release();
        return PLOD_OK;
    } catch (const std::bad_alloc &) {
        return PLOD_ERR_NO_MEMORY;
    } catch (...) {
        plod__set_message(message, message_size, std::string("reading '") + path + "' failed");
        return PLOD_ERR_BAD_IMAGE;
    }
}

plod_status plod_image_rows_read(plod_image_rows *rows, int y0, int y1, void *pixels,
                                 char *message, size_t message_size)
{
    plod__set_message(message, message_size, "");
    if (!rows || !pixels)
        return PLOD_ERR_NULL;
    if (y0 < 0 || y1 > rows->height || y0 >= y1)
        return PLOD_ERR_BAD_PARAM;
    try {
        if (!rows->input->read_scanlines(0, 0, y0, y1, 0, 0, 1, rows->format, pixels)) {
            std::string why = rows->input->geterror();
            plod__set_message(message, message_size,
                              std::string("rows ") + std::to_string(y0) + ".." +
                                  std::to_string(y1) + " are corrupt or truncated" +
                                  (why.empty() ? "" : ": " + why));
            return PLOD_ERR_BAD_IMAGE;
        }
        return PLOD_OK;
    } catch (const std::bad_alloc &) {
        return PLOD_ERR_NO_MEMORY;
    } catch (...) {
        plod__set_message(message, message_size, "reading rows failed");
        return PLOD_ERR_BAD_IMAGE;
    }
}

void plod_image_rows_close(plod_image_rows *rows)
{
    try {
        delete rows;
    } catch (...) {
    }
}

} // extern "C"
