/* py_image.c -- image files for the binding: the core reads the headerless
 * grids itself; every other file is decoded and encoded by the Python module
 * planetlod.imageio (OpenImageIO's Python module), whose arrays the core
 * takes in without a copy where it can (plod_image_import).  The band-of-
 * rows reader that tiled maps need is planetlod.imageio.RowReader behind the
 * core's plod_image_rows_reader interface.
 *
 * Errors planetlod.imageio raises (FileError, ImageError, InvalidArgument,
 * MemoryError) carry a detail without context: they become statuses and are
 * raised again as every core error is ("context: what (detail)").  Anything
 * else (an ImportError naming what to install) propagates as it is.
 */
#include "pyplanetlod.h"

#define PLOD__IMAGE_MESSAGE 512

static const char *const plod__sample_names[PLOD_RAW_TYPE_COUNT] = {"u8", "u16", "i16", "f32"};

static int plod__sample_type(const char *name, plod_raw_type *type)
{
    for (int t = 0; t < PLOD_RAW_TYPE_COUNT; t++) {
        if (strcmp(name, plod__sample_names[t]) == 0) {
            *type = (plod_raw_type)t;
            return 0;
        }
    }
    return -1;
}

/* Calls planetlod.imageio.<name>(*args): a new reference or NULL. */
static PyObject *plod__imageio_call(const char *name, PyObject *args)
{
    if (!args)
        return NULL;
    PyObject *module = PyImport_ImportModule("planetlod.imageio");
    PyObject *function = module ? PyObject_GetAttrString(module, name) : NULL;
    PyObject *result = function ? PyObject_CallObject(function, args) : NULL;
    Py_XDECREF(function);
    Py_XDECREF(module);
    Py_DECREF(args);
    return result;
}

/* Raises the pending planetlod.imageio error again with `context`. */
static int plod__raise_with_context(const char *context)
{
    plod_status status;
    char message[PLOD__IMAGE_MESSAGE];
    if (plod_py_exception_status(&status, message, sizeof message) == 0)
        plod_py_raise_detail(status, context, message);
    return -1;
}

static int plod__read_grid(plod_py_image *out, const char *path, const plod_raw_format *raw,
                           const char *context)
{
    char message[PLOD__IMAGE_MESSAGE];
    plod_status s;
    Py_BEGIN_ALLOW_THREADS
    plod_raw_format guessed;
    s = raw ? PLOD_OK : plod_raw_guess(path, &guessed, message, sizeof message);
    if (s == PLOD_OK)
        s = plod_image_read_raw(&out->image, path, raw ? raw : &guessed, 0, message,
                                sizeof message);
    Py_END_ALLOW_THREADS
    if (s != PLOD_OK) {
        plod_py_raise_detail(s, context, message);
        return -1;
    }
    return 0;
}

static int plod__read_decoded(plod_py_image *out, const char *path, plod_import_mode mode,
                              const char *context)
{
    PyObject *result = plod__imageio_call(
        "read", Py_BuildValue("(NiK)", PyUnicode_DecodeFSDefault(path),
                              mode == PLOD_IMPORT_STORED,
                              (unsigned long long)PLOD_IMAGE_DEFAULT_MAX_PIXELS));
    if (!result)
        return plod__raise_with_context(context);
    int width, height, channels;
    const char *dtype = "?";
    PyObject *pixels;
    plod_raw_type type;
    if (!PyArg_ParseTuple(result, "iiisO", &width, &height, &channels, &dtype, &pixels) ||
        plod__sample_type(dtype, &type) < 0) {
        if (!PyErr_Occurred())
            PyErr_Format(PyExc_TypeError, "%s: planetlod.imageio.read gave sample type '%s'",
                         context, dtype);
        Py_DECREF(result);
        return -1;
    }
    int writable = 1;
    if (PyObject_GetBuffer(pixels, &out->view, PyBUF_C_CONTIGUOUS | PyBUF_WRITABLE) < 0) {
        PyErr_Clear();
        writable = 0;
        if (PyObject_GetBuffer(pixels, &out->view, PyBUF_C_CONTIGUOUS) < 0) {
            Py_DECREF(result);
            return -1;
        }
    }
    out->has_view = 1;
    Py_DECREF(result); /* the view holds the array */
    plod_image_buffer buffer = {width, height, channels, type, out->view.buf,
                                (size_t)out->view.len};
    char message[PLOD__IMAGE_MESSAGE];
    plod_status s = plod_image_import(&out->image, &buffer, mode, writable, 0, path, message,
                                      sizeof message);
    if (s == PLOD_OK && !out->image.borrowed) {
        PyBuffer_Release(&out->view);
        out->has_view = 0;
    }
    if (s != PLOD_OK) {
        plod_py_image_release(out);
        plod_py_raise_detail(s, context, message);
        return -1;
    }
    return 0;
}

int plod_py_image_read(plod_py_image *out, const char *path, plod_import_mode mode,
                       const plod_py_read_options *options, const char *context)
{
    memset(out, 0, sizeof *out);
    int result;
    if (options && options->has_raw)
        result = plod__read_grid(out, path, &options->raw, context);
    else if (plod_raw_is_raw_path(path))
        result = plod__read_grid(out, path, NULL, context);
    else
        result = plod__read_decoded(out, path, mode, context);
    if (result == 0 && options && options->is_signed) {
        plod_status s = plod_image_reinterpret_signed(&out->image);
        if (s != PLOD_OK) {
            char message[PLOD__IMAGE_MESSAGE];
            snprintf(message, sizeof message, "reinterpreting '%s' as signed", path);
            plod_py_image_release(out);
            plod_py_raise_detail(s, context, message);
            return -1;
        }
    }
    return result;
}

void plod_py_image_release(plod_py_image *image)
{
    plod_image_free(&image->image);
    if (image->has_view)
        PyBuffer_Release(&image->view);
    image->has_view = 0;
}

int plod_py_image_write(const plod_image *image, const char *path, const char *context)
{
    size_t bytes = (size_t)image->width * (size_t)image->height * (size_t)image->channels *
                   plod_image_texel_bytes(image->type);
    const char *dtype = image->type == PLOD_TEXEL_U8    ? "u8"
                        : image->type == PLOD_TEXEL_U16 ? "u16"
                                                        : "f32";
    if (!image->pixels || bytes == 0 || bytes > (size_t)PY_SSIZE_T_MAX) {
        plod_py_raise_detail(PLOD_ERR_BAD_PARAM, context, "no pixels to write");
        return -1;
    }
    PyObject *view = PyMemoryView_FromMemory(image->pixels, (Py_ssize_t)bytes, PyBUF_READ);
    if (!view)
        return -1;
    PyObject *result = plod__imageio_call(
        "write", Py_BuildValue("(NNiiis)", PyUnicode_DecodeFSDefault(path), view, image->width,
                               image->height, image->channels, dtype));
    if (!result)
        return plod__raise_with_context(context);
    Py_DECREF(result);
    return 0;
}

/* ---- rows a band at a time (plod_image_rows_reader) ----------------------
 * Called by the core with the GIL released (a tiled map's build): each call
 * takes the GIL.  An error that is not one of imageio's is kept in the
 * context, the core sees PLOD_ERR_BAD_IMAGE, and the binding raises it
 * afterwards (plod_py_rows_reader_raise). */

typedef struct plod__rows {
    PyObject *reader; /* planetlod.imageio.RowReader */
    int width;
    plod_texel_type type;
} plod__rows;

static plod_status plod__rows_failed(plod_py_rows_context *context, char *message,
                                     size_t message_size)
{
    plod_status status;
    if (plod_py_exception_status(&status, message, message_size) == 0)
        return status;
    if (!context->error_type)
        PyErr_Fetch(&context->error_type, &context->error_value, &context->error_traceback);
    else
        PyErr_Clear();
    plod_status_format(message, message_size, "%s", "the image reader failed");
    return PLOD_ERR_BAD_IMAGE;
}

static plod_status plod__rows_open(void *user, const char *path, void **out, int *width,
                                   int *height, plod_texel_type *type, char *message,
                                   size_t message_size)
{
    plod_py_rows_context *context = user;
    PyGILState_STATE gil = PyGILState_Ensure();
    plod_status s = PLOD_OK;
    *out = NULL;
    plod__rows *rows = calloc(1, sizeof *rows);
    PyObject *dtype = NULL;
    long w = 0, h = 0;
    plod_raw_type sample = PLOD_RAW_F32;
    if (!rows) {
        s = PLOD_ERR_NO_MEMORY;
        goto done;
    }
    rows->reader =
        plod__imageio_call("RowReader", Py_BuildValue("(N)", PyUnicode_DecodeFSDefault(path)));
    PyObject *w_obj = rows->reader ? PyObject_GetAttrString(rows->reader, "width") : NULL;
    PyObject *h_obj = w_obj ? PyObject_GetAttrString(rows->reader, "height") : NULL;
    dtype = h_obj ? PyObject_GetAttrString(rows->reader, "dtype") : NULL;
    w = w_obj ? PyLong_AsLong(w_obj) : -1;
    h = h_obj ? PyLong_AsLong(h_obj) : -1;
    Py_XDECREF(w_obj);
    Py_XDECREF(h_obj);
    const char *name = dtype && PyUnicode_Check(dtype) ? PyUnicode_AsUTF8AndSize(dtype, NULL) : NULL;
    if (PyErr_Occurred()) {
        s = plod__rows_failed(context, message, message_size);
        goto done;
    }
    if (!name || plod__sample_type(name, &sample) < 0 || sample == PLOD_RAW_I16 || w < 1 ||
        h < 1 || w > (1L << 30) || h > (1L << 30)) {
        plod_status_format(message, message_size, "'%s' has an unsupported format or layout",
                           path);
        s = PLOD_ERR_BAD_IMAGE;
        goto done;
    }
    rows->width = *width = (int)w;
    *height = (int)h;
    rows->type = *type = sample == PLOD_RAW_U8    ? PLOD_TEXEL_U8
                         : sample == PLOD_RAW_U16 ? PLOD_TEXEL_U16
                                                  : PLOD_TEXEL_F32;
    *out = rows;
done:
    Py_XDECREF(dtype);
    if (s != PLOD_OK && rows) {
        Py_XDECREF(rows->reader);
        free(rows);
    }
    PyGILState_Release(gil);
    return s;
}

static plod_status plod__rows_read(void *user, void *handle, int y0, int y1, void *pixels,
                                   char *message, size_t message_size)
{
    plod_py_rows_context *context = user;
    plod__rows *rows = handle;
    PyGILState_STATE gil = PyGILState_Ensure();
    plod_status s = PLOD_OK;
    PyObject *band = PyObject_CallMethod(rows->reader, "read", "ii", y0, y1);
    Py_buffer view;
    if (!band || PyObject_GetBuffer(band, &view, PyBUF_C_CONTIGUOUS) < 0) {
        s = plod__rows_failed(context, message, message_size);
    } else {
        size_t bytes = (size_t)rows->width * (size_t)(y1 - y0) *
                       plod_image_texel_bytes(rows->type);
        if ((size_t)view.len != bytes) {
            plod_status_format(message, message_size,
                               "rows %d..%d: %zd bytes where %zu were expected", y0, y1,
                               view.len, bytes);
            s = PLOD_ERR_BAD_IMAGE;
        } else {
            memcpy(pixels, view.buf, bytes);
        }
        PyBuffer_Release(&view);
    }
    Py_XDECREF(band);
    PyGILState_Release(gil);
    return s;
}

static void plod__rows_close(void *user, void *handle)
{
    (void)user;
    plod__rows *rows = handle;
    PyGILState_STATE gil = PyGILState_Ensure();
    PyObject *type, *value, *traceback;
    PyErr_Fetch(&type, &value, &traceback);
    PyObject *result = PyObject_CallMethod(rows->reader, "close", NULL);
    Py_XDECREF(result);
    PyErr_Clear(); /* closing after a read cannot fail the read */
    PyErr_Restore(type, value, traceback);
    Py_DECREF(rows->reader);
    free(rows);
    PyGILState_Release(gil);
}

plod_image_rows_reader plod_py_rows_reader(plod_py_rows_context *context)
{
    memset(context, 0, sizeof *context);
    plod_image_rows_reader reader = {plod__rows_open, plod__rows_read, plod__rows_close,
                                     context};
    return reader;
}

int plod_py_rows_reader_raise(plod_py_rows_context *context)
{
    if (!context->error_type)
        return 0;
    PyErr_Restore(context->error_type, context->error_value, context->error_traceback);
    context->error_type = context->error_value = context->error_traceback = NULL;
    return -1;
}
