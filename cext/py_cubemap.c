/* py_cubemap.c -- planetlod.CubeMap, planetlod.resample and the cube map
 * glue used by Planet (plod_py_cubemap_get, plod_py_cubemap_from_image).
 *
 * Long C work (image reading, resampling, writing) runs with the GIL
 * released; a Python progress callback is called back under the GIL from
 * the calling thread only (the resampler guarantees that).  An exception
 * raised by the callback cancels the work and is re-raised afterwards.
 */
#include "pyplanetlod.h"
#include "plod_platform.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PLOD__MESSAGE_SIZE 512

static PyTypeObject *plod_py_cubemap_type;

typedef struct {
    PyObject_HEAD
    plod_cubemap *map;
} plod_py_cubemap;

/* ======================================================================== */
/* argument helpers                                                         */
/* ======================================================================== */

static const char *const plod__dtype_names[PLOD_TEXEL_TYPE_COUNT] = {"u8", "u16", "f32"};

static int plod__dtype_arg(PyObject *obj, plod_texel_type *out)
{
    const char *text = PyUnicode_Check(obj) ? PyUnicode_AsUTF8AndSize(obj, NULL) : NULL;
    if (text) {
        for (int t = 0; t < PLOD_TEXEL_TYPE_COUNT; t++) {
            if (strcmp(text, plod__dtype_names[t]) == 0) {
                *out = (plod_texel_type)t;
                return 0;
            }
        }
    }
    PyErr_Clear();
    plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "planetlod.CubeMap",
                         "dtype must be 'u8', 'u16' or 'f32'");
    return -1;
}

static int plod__filter_arg(PyObject *obj, plod_filter *out, const char *context)
{
    const char *text = PyUnicode_Check(obj) ? PyUnicode_AsUTF8AndSize(obj, NULL) : NULL;
    if (text && plod_filter_from_name(text, out) == PLOD_OK)
        return 0;
    PyErr_Clear();
    char detail[160];
    snprintf(detail, sizeof detail, "unknown filter '%.40s'; expected 'nearest', 'bilinear' or 'bicubic'",
             text ? text : "(not a str)");
    plod_py_raise_detail(PLOD_ERR_BAD_PARAM, context, detail);
    return -1;
}

static int plod__size_arg(long size, const char *context)
{
    if (size < 1 || size > PLOD_CUBEMAP_MAX_MAP_SIZE) {
        char detail[120];
        snprintf(detail, sizeof detail, "size %ld outside 1..%d", size, PLOD_CUBEMAP_MAX_MAP_SIZE);
        plod_py_raise_detail(PLOD_ERR_BAD_PARAM, context, detail);
        return -1;
    }
    return 0;
}

/* Output formats: channels 0 = keep the source's. */
typedef struct plod__format {
    const char *name;
    int channels;
    plod_texel_type type;
} plod__format;

static const plod__format plod__formats[] = {
    {"rgba8", 4, PLOD_TEXEL_U8}, {"rgb8", 3, PLOD_TEXEL_U8}, {"r16", 1, PLOD_TEXEL_U16},
    {"f32", 0, PLOD_TEXEL_F32},  {"r8", 1, PLOD_TEXEL_U8},
};

static const plod__format *plod__format_arg(PyObject *obj, const char *context)
{
    const char *text = PyUnicode_Check(obj) ? PyUnicode_AsUTF8AndSize(obj, NULL) : NULL;
    if (text)
        for (size_t k = 0; k < sizeof plod__formats / sizeof plod__formats[0]; k++)
            if (strcmp(text, plod__formats[k].name) == 0)
                return &plod__formats[k];
    PyErr_Clear();
    char detail[160];
    snprintf(detail, sizeof detail,
             "unknown format '%.40s'; expected 'rgba8', 'rgb8', 'r16', 'f32' or 'r8'",
             text ? text : "(not a str)");
    plod_py_raise_detail(PLOD_ERR_BAD_PARAM, context, detail);
    return NULL;
}

/* Channel count written for `format` from a source of `channels`; -1 with
 * InvalidArgument when the source cannot be expressed in that format
 * (colour into a single-channel format). */
static int plod__format_channels(const plod__format *format, int channels, const char *context)
{
    if (format->channels == 0)
        return channels;
    if (format->channels == 1 && channels > 2) {
        char detail[200];
        snprintf(detail, sizeof detail,
                 "format '%s' is single-channel but the input has %d channels (colour); use "
                 "'rgb8', 'rgba8' or 'f32'",
                 format->name, channels);
        plod_py_raise_detail(PLOD_ERR_BAD_PARAM, context, detail);
        return -1;
    }
    return format->channels;
}

static int plod__layout_arg(PyObject *obj, int *cross, const char *context)
{
    const char *text = PyUnicode_Check(obj) ? PyUnicode_AsUTF8AndSize(obj, NULL) : NULL;
    if (text && strcmp(text, "cross") == 0) {
        *cross = 1;
        return 0;
    }
    if (text && strcmp(text, "faces") == 0) {
        *cross = 0;
        return 0;
    }
    PyErr_Clear();
    plod_py_raise_detail(PLOD_ERR_BAD_PARAM, context, "layout must be 'cross' or 'faces'");
    return -1;
}

/* ======================================================================== */
/* progress trampoline                                                      */
/* ======================================================================== */

typedef struct plod__py_progress {
    PyObject *callable; /* borrowed; NULL = none */
    double offset, scale;
    PyObject *error_type, *error_value, *error_tb;
} plod__py_progress;

static int plod__progress_call(plod__py_progress *p, double fraction)
{
    if (!p->callable)
        return 0;
    PyGILState_STATE gil = PyGILState_Ensure();
    int cancel = 0;
    PyObject *result = PyObject_CallFunction(p->callable, "d", p->offset + p->scale * fraction);
    if (!result) {
        PyErr_Fetch(&p->error_type, &p->error_value, &p->error_tb);
        cancel = 1;
    } else {
        cancel = PyObject_IsTrue(result);
        Py_DECREF(result);
        if (cancel < 0) {
            PyErr_Fetch(&p->error_type, &p->error_value, &p->error_tb);
            cancel = 1;
        }
    }
    PyGILState_Release(gil);
    return cancel;
}

static int plod__progress_trampoline(void *user, double fraction)
{
    return plod__progress_call((plod__py_progress *)user, fraction);
}

/* After a cancelled run: re-raise the callback's exception, else Cancelled. */
static PyObject *plod__progress_raise(plod__py_progress *p, plod_status status, const char *context,
                                      const char *detail)
{
    if (p->error_type) {
        PyErr_Restore(p->error_type, p->error_value, p->error_tb);
        p->error_type = p->error_value = p->error_tb = NULL;
        return NULL;
    }
    return plod_py_raise_detail(status, context, detail);
}

static void plod__progress_clear(plod__py_progress *p)
{
    Py_XDECREF(p->error_type);
    Py_XDECREF(p->error_value);
    Py_XDECREF(p->error_tb);
    p->error_type = p->error_value = p->error_tb = NULL;
}

/* ======================================================================== */
/* loading                                                                  */
/* ======================================================================== */

static PyObject *plod__wrap(plod_cubemap *map)
{
    plod_py_cubemap *self = PyObject_New(plod_py_cubemap, plod_py_cubemap_type);
    if (!self) {
        plod_cubemap_destroy(map);
        return NULL;
    }
    self->map = map;
    return (PyObject *)self;
}

int plod_py_read_options_arg(PyObject *raw, int is_signed, plod_py_read_options *out,
                             const char *context)
{
    memset(out, 0, sizeof *out);
    out->is_signed = is_signed != 0;
    if (!raw || raw == Py_None)
        return 0;
    static const char *const types[] = {"u8", "u16", "i16", "f32"};
    const char *problem = NULL;
    if (!PyMapping_Check(raw) || !PyObject_HasAttrString(raw, "keys")) {
        problem = "raw must be a mapping: width, height, dtype, byteorder";
        goto fail;
    }
    static const char *const keys[] = {"width", "height", "dtype", "byteorder"};
    PyObject *items[4] = {NULL, NULL, NULL, NULL};
    for (int k = 0; k < 4; k++) {
        items[k] = PyMapping_HasKeyString(raw, keys[k]) ? PyMapping_GetItemString(raw, keys[k])
                                                        : NULL;
        PyErr_Clear();
    }
    out->has_raw = 1;
    out->raw.type = PLOD_RAW_U16;
    long width = items[0] ? PyLong_AsLong(items[0]) : -1;
    long height = items[1] ? PyLong_AsLong(items[1]) : -1;
    PyErr_Clear();
    const char *dtype =
        items[2] && PyUnicode_Check(items[2]) ? PyUnicode_AsUTF8AndSize(items[2], NULL) : "u16";
    const char *order =
        items[3] && PyUnicode_Check(items[3]) ? PyUnicode_AsUTF8AndSize(items[3], NULL) : "little";
    int type = -1;
    for (int t = 0; dtype && t < PLOD_RAW_TYPE_COUNT; t++)
        if (strcmp(dtype, types[t]) == 0)
            type = t;
    if (width < 1 || width > (1L << 30) || height < 1 || height > (1L << 30))
        problem = "raw width and height must be integers >= 1";
    else if (type < 0 || (items[2] && !PyUnicode_Check(items[2])))
        problem = "raw dtype must be 'u8', 'u16', 'i16' or 'f32'";
    else if (!order || (strcmp(order, "little") != 0 && strcmp(order, "big") != 0) ||
             (items[3] && !PyUnicode_Check(items[3])))
        problem = "raw byteorder must be 'little' or 'big'";
    for (int k = 0; k < 4; k++)
        Py_XDECREF(items[k]);
    PyErr_Clear();
    if (problem)
        goto fail;
    out->raw.width = (int)width;
    out->raw.height = (int)height;
    out->raw.type = (plod_raw_type)type;
    out->raw.big_endian = strcmp(order, "big") == 0;
    return 0;
fail:
    plod_py_raise_detail(PLOD_ERR_BAD_PARAM, context, problem);
    return -1;
}

/* Warns (UserWarning) unless the equirectangular input is 2:1. */
static int plod__warn_aspect(const plod_image *image, const char *path)
{
    if (plod_cubemap_is_equirectangular(image->width, image->height))
        return 0;
    return PyErr_WarnFormat(PyExc_UserWarning, 1,
                            "planetlod: '%s' is %dx%d, not 2:1; resampling it as an "
                            "equirectangular (lon -180..180, lat 90..-90) map anyway",
                            path, image->width, image->height);
}

/* Resamples `image` into a new cube map: NULL with an exception on error. */
static plod_cubemap *plod__resample_image(const plod_image *image, plod_projection projection,
                                          int size, int channels, plod_texel_type type,
                                          plod_filter filter, plod__py_progress *progress,
                                          const char *context)
{
    plod_cubemap *map;
    plod_status s = plod_cubemap_create(&map, projection, size, channels, type);
    if (s != PLOD_OK) {
        plod_py_raise(s, context);
        return NULL;
    }
    Py_BEGIN_ALLOW_THREADS
    s = plod_resample_car_to_cube(map, image, filter,
                                  progress && progress->callable ? plod__progress_trampoline : NULL,
                                  progress);
    Py_END_ALLOW_THREADS
    if (s != PLOD_OK) {
        plod_cubemap_destroy(map);
        if (progress)
            plod__progress_raise(progress, s, context, "cancelled by the progress callback");
        else
            plod_py_raise(s, context);
        return NULL;
    }
    return map;
}

/* The shared loader of CubeMap.from_image and plod_py_cubemap_from_image. */
static PyObject *plod__cubemap_from_image(const char *path, plod_projection projection, int size,
                                          int channels, plod_filter filter, PyObject *progress,
                                          const plod_py_read_options *options)
{
    const char *context = "planetlod.CubeMap.from_image";
    if (size < 0 || size > PLOD_CUBEMAP_MAX_MAP_SIZE) {
        plod__size_arg(size, context);
        return NULL;
    }
    if (channels < 0 || channels > 4)
        return plod_py_raise_detail(PLOD_ERR_BAD_PARAM, context, "channels must be 1..4 (or None)");
    plod_py_image read;
    if (plod_py_image_read(&read, path, PLOD_IMPORT_TYPED, options, context) < 0) {
        plod_py_image_release(&read);
        return NULL;
    }
    const plod_image image = read.image;
    if (channels == 0)
        channels = image.channels;
    plod_cubemap *map = NULL;
    if (plod_cubemap_is_cross_layout(image.width, image.height) &&
        plod_projection_is_cube(projection)) {
        plod_image converted = {0};
        const plod_image *cross = &image;
        plod_status s = PLOD_OK;
        if (channels != image.channels) {
            s = plod_image_convert(&converted, &image, channels, image.type);
            cross = &converted;
        }
        if (s == PLOD_OK)
            s = plod_cubemap_from_cross(&map, cross, projection);
        plod_image_free(&converted);
        plod_py_image_release(&read);
        if (s != PLOD_OK)
            return plod_py_raise(s, context);
        return plod__wrap(map);
    }
    if (plod__warn_aspect(&image, path) < 0) {
        plod_py_image_release(&read);
        return NULL;
    }
    if (size == 0)
        size = plod_cubemap_size_for_width(image.width);
    plod__py_progress p = {progress == Py_None ? NULL : progress, 0.0, 1.0, NULL, NULL, NULL};
    map = plod__resample_image(&image, projection, size, channels, image.type, filter, &p, context);
    plod_py_image_release(&read);
    plod__progress_clear(&p);
    return map ? plod__wrap(map) : NULL;
}

/* ======================================================================== */
/* glue for Planet                                                          */
/* ======================================================================== */

plod_cubemap *plod_py_cubemap_get(PyObject *obj)
{
    if (!plod_py_cubemap_type || !PyObject_TypeCheck(obj, plod_py_cubemap_type)) {
        PyErr_SetString(PyExc_TypeError, "expected a planetlod.CubeMap");
        return NULL;
    }
    return ((plod_py_cubemap *)obj)->map;
}

PyObject *plod_py_cubemap_from_image(const char *path, plod_projection projection, int size,
                                     int channels, const plod_py_read_options *options)
{
    return plod__cubemap_from_image(path, projection, size, channels, PLOD_FILTER_BILINEAR,
                                    Py_None, options);
}

/* ======================================================================== */
/* CubeMap                                                                  */
/* ======================================================================== */

static PyObject *plod__cubemap_new(PyTypeObject *type, PyObject *args, PyObject *kwargs)
{
    static char *keywords[] = {"projection", "size", "channels", "dtype", NULL};
    PyObject *projection_obj = NULL, *dtype_obj = NULL;
    long size = 256;
    int channels = 1;
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "|OliO:CubeMap", keywords, &projection_obj,
                                     &size, &channels, &dtype_obj))
        return NULL;
    plod_projection projection = PLOD_PROJ_QSC;
    plod_texel_type dtype = PLOD_TEXEL_U8;
    if (projection_obj && plod_py_projection_arg(projection_obj, &projection) < 0)
        return NULL;
    if (dtype_obj && plod__dtype_arg(dtype_obj, &dtype) < 0)
        return NULL;
    if (plod__size_arg(size, "planetlod.CubeMap") < 0)
        return NULL;
    if (channels < 1 || channels > 4)
        return plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "planetlod.CubeMap", "channels must be 1..4");
    plod_cubemap *map;
    plod_status s = plod_cubemap_create(&map, projection, (int)size, channels, dtype);
    if (s == PLOD_OK)
        s = plod_cubemap_build_pyramid(map);
    if (s != PLOD_OK) {
        plod_cubemap_destroy(map);
        return plod_py_raise(s, "planetlod.CubeMap");
    }
    plod_py_cubemap *self = (plod_py_cubemap *)plod_py_alloc(type);
    if (!self) {
        plod_cubemap_destroy(map);
        return NULL;
    }
    self->map = map;
    return (PyObject *)self;
}

static void plod__cubemap_dealloc(plod_py_cubemap *self)
{
    PyTypeObject *type = Py_TYPE((PyObject *)self);
    plod_cubemap_destroy(self->map);
    plod_py_free((PyObject *)self);
    Py_DECREF(type);
}

static PyObject *plod__cubemap_from_image_method(PyObject *cls, PyObject *args, PyObject *kwargs)
{
    (void)cls;
    static char *keywords[] = {"path", "projection", "size", "filter", "channels", "progress",
                               "raw", "signed", NULL};
    PyObject *path_obj, *projection_obj = NULL, *size_obj = Py_None, *filter_obj = NULL;
    PyObject *channels_obj = Py_None, *progress = Py_None, *raw = Py_None;
    int is_signed = 0;
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "O&|OOOOOOp:from_image", keywords,
                                     PyUnicode_FSConverter, &path_obj, &projection_obj, &size_obj,
                                     &filter_obj, &channels_obj, &progress, &raw, &is_signed))
        return NULL;
    plod_py_read_options options;
    const char *context = "planetlod.CubeMap.from_image";
    plod_projection projection = PLOD_PROJ_QSC;
    plod_filter filter = PLOD_FILTER_BILINEAR;
    long size = 1024, channels = 0;
    PyObject *result = NULL;
    if (projection_obj && plod_py_projection_arg(projection_obj, &projection) < 0)
        goto done;
    if (filter_obj && plod__filter_arg(filter_obj, &filter, context) < 0)
        goto done;
    if (size_obj != Py_None) {
        size = PyLong_AsLong(size_obj);
        if (size == -1 && PyErr_Occurred())
            goto done;
        if (plod__size_arg(size, context) < 0)
            goto done;
    } else {
        size = 0;
    }
    if (channels_obj != Py_None) {
        channels = PyLong_AsLong(channels_obj);
        if (channels == -1 && PyErr_Occurred())
            goto done;
        if (channels < 1 || channels > 4) {
            plod_py_raise_detail(PLOD_ERR_BAD_PARAM, context, "channels must be 1..4 (or None)");
            goto done;
        }
    }
    if (progress != Py_None && !PyCallable_Check(progress)) {
        plod_py_raise_detail(PLOD_ERR_BAD_PARAM, context, "progress must be callable or None");
        goto done;
    }
    if (plod_py_read_options_arg(raw, is_signed, &options, context) < 0)
        goto done;
    result = plod__cubemap_from_image(PyBytes_AsString(path_obj), projection, (int)size,
                                      (int)channels, filter, progress, &options);
done:
    Py_DECREF(path_obj);
    return result;
}

static int plod__direction_args(PyObject *args, double dir[3], const char *context)
{
    if (!PyArg_ParseTuple(args, "ddd", &dir[0], &dir[1], &dir[2]))
        return -1;
    if (!(isfinite(dir[0]) && isfinite(dir[1]) && isfinite(dir[2])) ||
        (dir[0] == 0.0 && dir[1] == 0.0 && dir[2] == 0.0)) {
        plod_py_raise_detail(PLOD_ERR_BAD_COORD, context, "direction must be finite and non-zero");
        return -1;
    }
    return 0;
}

static PyObject *plod__floats_tuple(const float *values, int count)
{
    PyObject *tuple = PyTuple_New(count);
    if (!tuple)
        return NULL;
    for (int c = 0; c < count; c++) {
        PyObject *item = PyFloat_FromDouble(values[c]);
        if (!item) {
            Py_DECREF(tuple);
            return NULL;
        }
        PyTuple_SetItem(tuple, c, item);
    }
    return tuple;
}

static PyObject *plod__cubemap_sample(plod_py_cubemap *self, PyObject *args)
{
    double dir[3];
    if (plod__direction_args(args, dir, "planetlod.CubeMap.sample") < 0)
        return NULL;
    float out[4];
    plod_cubemap_sample(self->map, dir, out);
    return plod__floats_tuple(out, plod_cubemap_channels(self->map));
}

static PyObject *plod__cubemap_sample_face(plod_py_cubemap *self, PyObject *args)
{
    int face;
    double u, v;
    if (!PyArg_ParseTuple(args, "idd:sample_face", &face, &u, &v))
        return NULL;
    if (face < 0 || face >= plod_cubemap_face_count(self->map))
        return plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "planetlod.CubeMap.sample_face",
                                    "face out of range");
    if (!(isfinite(u) && isfinite(v)))
        return plod_py_raise_detail(PLOD_ERR_BAD_COORD, "planetlod.CubeMap.sample_face",
                                    "u, v must be finite");
    float out[4];
    plod_cubemap_sample_face(self->map, face, u, v, out);
    return plod__floats_tuple(out, plod_cubemap_channels(self->map));
}

static PyObject *plod__cubemap_face(plod_py_cubemap *self, PyObject *args)
{
    int face;
    if (!PyArg_ParseTuple(args, "i:face", &face))
        return NULL;
    if (face < 0 || face >= plod_cubemap_face_count(self->map))
        return plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "planetlod.CubeMap.face",
                                    "face out of range");
    plod_texel_type type = plod_cubemap_texel_type(self->map);
    char format = type == PLOD_TEXEL_U8 ? 'B' : type == PLOD_TEXEL_U16 ? 'H' : 'f';
    size_t bytes = plod_cubemap_face_bytes(self->map);
    void *data;
    PyObject *buffer = plod_py_buffer_new(format, bytes / plod_image_texel_bytes(type), &data);
    if (!buffer)
        return NULL;
    memcpy(data, plod_cubemap_face_data_const(self->map, face), bytes);
    return buffer;
}

static PyObject *plod__cubemap_set_face(plod_py_cubemap *self, PyObject *args)
{
    int face;
    Py_buffer view;
    if (!PyArg_ParseTuple(args, "iy*:set_face", &face, &view))
        return NULL;
    PyObject *result = NULL;
    size_t bytes = plod_cubemap_face_bytes(self->map);
    if (face < 0 || face >= plod_cubemap_face_count(self->map)) {
        plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "planetlod.CubeMap.set_face", "face out of range");
    } else if ((size_t)view.len != bytes) {
        char detail[120];
        snprintf(detail, sizeof detail, "expected %zu bytes, got %zd", bytes, view.len);
        plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "planetlod.CubeMap.set_face", detail);
    } else {
        memcpy(plod_cubemap_face_data(self->map, face), view.buf, bytes);
        plod_status s = plod_cubemap_build_pyramid(self->map);
        result = s == PLOD_OK ? Py_NewRef(Py_None) : plod_py_raise(s, "planetlod.CubeMap.set_face");
    }
    PyBuffer_Release(&view);
    return result;
}

static PyObject *plod__cubemap_range(plod_py_cubemap *self, PyObject *args, PyObject *kwargs)
{
    static char *keywords[] = {"face", "u0", "v0", "u1", "v1", NULL};
    PyObject *face_obj = Py_None;
    double u0 = -1.0, v0 = -1.0, u1 = 1.0, v1 = 1.0;
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "|Odddd:range", keywords, &face_obj, &u0, &v0,
                                     &u1, &v1))
        return NULL;
    double lo, hi;
    if (face_obj == Py_None) {
        plod_cubemap_global_range(self->map, &lo, &hi);
    } else {
        long face = PyLong_AsLong(face_obj);
        if (face == -1 && PyErr_Occurred())
            return NULL;
        if (face < 0 || face >= plod_cubemap_face_count(self->map))
            return plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "planetlod.CubeMap.range",
                                        "face out of range");
        if (!(isfinite(u0) && isfinite(v0) && isfinite(u1) && isfinite(v1)))
            return plod_py_raise_detail(PLOD_ERR_BAD_COORD, "planetlod.CubeMap.range",
                                        "u0, v0, u1, v1 must be finite");
        plod_cubemap_range(self->map, (int)face, u0, v0, u1, v1, &lo, &hi);
    }
    return Py_BuildValue("(dd)", lo, hi);
}

/* Writes a cube map (cross or six faces) converted to channels/type.
 * GIL released around the writes. */
static PyObject *plod__write_cubemap(const plod_cubemap *map, const char *path, int cross,
                                     int channels, plod_texel_type type, const char *context)
{
    int faces = cross || plod_cubemap_face_count(map) == 1 ? 1 : PLOD_FACE_COUNT;
    size_t path_size = strlen(path) + 32;
    char *face_path = malloc(path_size);
    if (!face_path)
        return PyErr_NoMemory();
    plod_status s = PLOD_OK;
    for (int f = 0; f < faces; f++) {
        const char *target = path;
        if (faces > 1) {
            if (plod_cubemap_face_path(face_path, path_size, path, f) < 0) {
                free(face_path);
                return plod_py_raise_detail(PLOD_ERR_BAD_PARAM, context, "bad output path");
            }
            target = face_path;
        }
        plod_image image = {0};
        Py_BEGIN_ALLOW_THREADS
        s = plod_cubemap_to_image(&image, map, faces == 1, f, channels, type);
        Py_END_ALLOW_THREADS
        int written = s == PLOD_OK ? plod_py_image_write(&image, target, context) : -1;
        plod_image_free(&image);
        if (s != PLOD_OK) {
            free(face_path);
            return plod_py_raise(s, context);
        }
        if (written < 0) {
            free(face_path);
            return NULL;
        }
    }
    free(face_path);
    Py_RETURN_NONE;
}

static PyObject *plod__cubemap_save(plod_py_cubemap *self, PyObject *args, PyObject *kwargs)
{
    static char *keywords[] = {"path", "layout", "format", NULL};
    const char *context = "planetlod.CubeMap.save";
    PyObject *path_obj, *layout_obj = NULL, *format_obj = Py_None;
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "O&|OO:save", keywords, PyUnicode_FSConverter,
                                     &path_obj, &layout_obj, &format_obj))
        return NULL;
    PyObject *result = NULL;
    int cross = 1;
    int channels = plod_cubemap_channels(self->map);
    plod_texel_type type = plod_cubemap_texel_type(self->map);
    if (layout_obj && plod__layout_arg(layout_obj, &cross, context) < 0)
        goto done;
    if (format_obj != Py_None) {
        const plod__format *format = plod__format_arg(format_obj, context);
        if (!format)
            goto done;
        channels = plod__format_channels(format, channels, context);
        if (channels < 0)
            goto done;
        type = format->type;
    }
    result = plod__write_cubemap(self->map, PyBytes_AsString(path_obj), cross, channels, type,
                                 context);
done:
    Py_DECREF(path_obj);
    return result;
}

static PyObject *plod__cubemap_get_projection(plod_py_cubemap *self, void *closure)
{
    (void)closure;
    return PyUnicode_FromString(plod_projection_name(plod_cubemap_projection(self->map)));
}

static PyObject *plod__cubemap_get_size(plod_py_cubemap *self, void *closure)
{
    (void)closure;
    return PyLong_FromLong(plod_cubemap_size(self->map));
}

static PyObject *plod__cubemap_get_channels(plod_py_cubemap *self, void *closure)
{
    (void)closure;
    return PyLong_FromLong(plod_cubemap_channels(self->map));
}

static PyObject *plod__cubemap_get_dtype(plod_py_cubemap *self, void *closure)
{
    (void)closure;
    return PyUnicode_FromString(plod__dtype_names[plod_cubemap_texel_type(self->map)]);
}

static PyObject *plod__cubemap_get_face_count(plod_py_cubemap *self, void *closure)
{
    (void)closure;
    return PyLong_FromLong(plod_cubemap_face_count(self->map));
}

static PyObject *plod__cubemap_get_face_shape(plod_py_cubemap *self, void *closure)
{
    (void)closure;
    return Py_BuildValue("(ii)", plod_cubemap_face_width(self->map),
                         plod_cubemap_face_height(self->map));
}

static PyObject *plod__cubemap_repr(plod_py_cubemap *self)
{
    return PyUnicode_FromFormat("<planetlod.CubeMap %s size=%d channels=%d dtype=%s>",
                                plod_projection_name(plod_cubemap_projection(self->map)),
                                plod_cubemap_size(self->map), plod_cubemap_channels(self->map),
                                plod__dtype_names[plod_cubemap_texel_type(self->map)]);
}

static PyMethodDef plod__cubemap_methods[] = {
    {"from_image", (PyCFunction)(void (*)(void))plod__cubemap_from_image_method,
     METH_VARARGS | METH_KEYWORDS | METH_CLASS,
     "from_image(path, projection='qsc', size=1024, filter='bilinear', channels=None, "
     "progress=None, raw=None, signed=False) -> CubeMap\n\nAn equirectangular image is "
     "resampled (size None: width/4); a 4:3 cross-layout image is loaded as a cube map in "
     "`projection` as is.  raw: dict(width, height, dtype='u8'|'u16'|'i16'|'f32', "
     "byteorder='little'|'big') for a headerless grid; signed: 8/16-bit samples are two's "
     "complement (read as float32 integer values)."},
    {"sample", (PyCFunction)plod__cubemap_sample, METH_VARARGS,
     "sample(x, y, z) -> tuple\n\nSeamless bilinear sample at a direction (normalised values)."},
    {"sample_face", (PyCFunction)plod__cubemap_sample_face, METH_VARARGS,
     "sample_face(face, u, v) -> tuple\n\nBilinear sample at face coordinates in [-1, 1]."},
    {"face", (PyCFunction)plod__cubemap_face, METH_VARARGS,
     "face(face) -> Buffer\n\nCopy of the raw texels of a face (rows along +v)."},
    {"set_face", (PyCFunction)plod__cubemap_set_face, METH_VARARGS,
     "set_face(face, data)\n\nReplaces a face's raw texels (bytes-like, exact size)."},
    {"range", (PyCFunction)(void (*)(void))plod__cubemap_range, METH_VARARGS | METH_KEYWORDS,
     "range(face=None, u0=-1, v0=-1, u1=1, v1=1) -> (min, max)\n\nConservative channel-0 bounds "
     "over a face rectangle including the bilinear footprint; the whole map without face."},
    {"save", (PyCFunction)(void (*)(void))plod__cubemap_save, METH_VARARGS | METH_KEYWORDS,
     "save(path, layout='cross', format=None)\n\nWrites the cross image or six face images "
     "('{face}' in path, else '_face<N>' before the extension)."},
    {NULL, NULL, 0, NULL},
};

static PyGetSetDef plod__cubemap_getset[] = {
    {"projection", (getter)plod__cubemap_get_projection, NULL, "projection name", NULL},
    {"size", (getter)plod__cubemap_get_size, NULL, "face size N (texels)", NULL},
    {"channels", (getter)plod__cubemap_get_channels, NULL, "channels per texel", NULL},
    {"dtype", (getter)plod__cubemap_get_dtype, NULL, "'u8', 'u16' or 'f32'", NULL},
    {"face_count", (getter)plod__cubemap_get_face_count, NULL, "6, or 1 for CAR", NULL},
    {"face_shape", (getter)plod__cubemap_get_face_shape, NULL, "(width, height) of a face", NULL},
    {NULL, NULL, NULL, NULL, NULL},
};

static PyType_Slot plod__cubemap_slots[] = {
    {Py_tp_new, plod__cubemap_new},
    {Py_tp_dealloc, plod__cubemap_dealloc},
    {Py_tp_repr, plod__cubemap_repr},
    {Py_tp_methods, plod__cubemap_methods},
    {Py_tp_getset, plod__cubemap_getset},
    {Py_tp_doc, (void *)"CubeMap(projection='qsc', size=256, channels=1, dtype='u8')\n\n"
                "Six size x size faces (CAR: one 2*size x size map) with seamless bilinear "
                "sampling and a min/max pyramid."},
    {0, NULL},
};

static PyType_Spec plod__cubemap_spec = {
    .name = "planetlod.CubeMap",
    .basicsize = sizeof(plod_py_cubemap),
    .itemsize = 0,
    .flags = Py_TPFLAGS_DEFAULT,
    .slots = plod__cubemap_slots,
};

/* ======================================================================== */
/* resample()                                                               */
/* ======================================================================== */

static double plod__seconds(void)
{
    return 1e-9 * (double)plod_clock_ns();
}

/* CPU time of the calling thread: with threads=1 the whole resampling cost,
 * undisturbed by other processes on a busy machine. */
static double plod__thread_cpu_seconds(void)
{
    return 1e-9 * (double)plod_thread_cpu_ns();
}

static PyObject *plod__resample(PyObject *module, PyObject *args, PyObject *kwargs)
{
    (void)module;
    static char *keywords[] = {"input_path", "output_path", "projection", "size", "filter",
                               "format", "layout", "progress", "threads", NULL};
    const char *context = "planetlod.resample";
    PyObject *input_obj, *output_obj, *projection_obj = NULL, *filter_obj = NULL;
    PyObject *format_obj = NULL, *layout_obj = NULL, *progress = Py_None;
    long size = 1024;
    int threads = 2;
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "O&O&|OlOOOOi:resample", keywords,
                                     PyUnicode_FSConverter, &input_obj, PyUnicode_FSConverter,
                                     &output_obj, &projection_obj, &size, &filter_obj, &format_obj,
                                     &layout_obj, &progress, &threads))
        return NULL;
    PyObject *result = NULL;
    plod_projection projection = PLOD_PROJ_QSC;
    plod_filter filter = PLOD_FILTER_BILINEAR;
    const plod__format *format = &plod__formats[2]; /* r16 */
    int cross = 1;
    plod_py_image read = {0};
    const plod_image *image = &read.image;
    plod_cubemap *map = NULL;
    plod__py_progress p = {progress == Py_None ? NULL : progress, 0.05, 0.85, NULL, NULL, NULL};
    const char *input = PyBytes_AsString(input_obj);

    if (projection_obj && plod_py_projection_arg(projection_obj, &projection) < 0)
        goto done;
    if (plod__size_arg(size, context) < 0)
        goto done;
    if (filter_obj && plod__filter_arg(filter_obj, &filter, context) < 0)
        goto done;
    if (format_obj && !(format = plod__format_arg(format_obj, context)))
        goto done;
    if (layout_obj && plod__layout_arg(layout_obj, &cross, context) < 0)
        goto done;
    if (threads < 1 || threads > 16) {
        plod_py_raise_detail(PLOD_ERR_BAD_PARAM, context, "threads must be 1..16");
        goto done;
    }
    if (progress != Py_None && !PyCallable_Check(progress)) {
        plod_py_raise_detail(PLOD_ERR_BAD_PARAM, context, "progress must be callable or None");
        goto done;
    }
    if (plod__progress_call(&p, -p.offset / p.scale)) /* 0.0 */
        goto cancelled;
    double t0 = plod__seconds();
    if (plod_py_image_read(&read, input, PLOD_IMPORT_TYPED, NULL, context) < 0)
        goto done;
    double t1 = plod__seconds();
    int channels = plod__format_channels(format, image->channels, context);
    if (channels < 0)
        goto done;
    if (plod__warn_aspect(image, input) < 0)
        goto done;
    plod_status s = plod_cubemap_create(&map, projection, (int)size, channels, format->type);
    if (s != PLOD_OK) {
        plod_py_raise(s, context);
        goto done;
    }
    double cpu0 = plod__thread_cpu_seconds();
    Py_BEGIN_ALLOW_THREADS
    s = plod_resample_car_to_cube_threads(map, image, filter, threads,
                                          p.callable ? plod__progress_trampoline : NULL, &p);
    Py_END_ALLOW_THREADS
    double t2 = plod__seconds();
    double cpu1 = plod__thread_cpu_seconds();
    plod_py_image_release(&read);
    if (s == PLOD_ERR_CANCELLED)
        goto cancelled;
    if (s != PLOD_OK) {
        plod_py_raise(s, context);
        goto done;
    }
    PyObject *written = plod__write_cubemap(map, PyBytes_AsString(output_obj), cross, channels,
                                            format->type, context);
    if (!written)
        goto done;
    Py_DECREF(written);
    double t3 = plod__seconds();
    /* cancelling after the write cannot unwrite: the answer is ignored */
    plod__progress_call(&p, (1.0 - p.offset) / p.scale);
    plod__progress_clear(&p);
    result = Py_BuildValue("{s:d,s:d,s:d,s:d}", "read_s", t1 - t0, "resample_s", t2 - t1,
                           "write_s", t3 - t2, "resample_thread_cpu_s", cpu1 - cpu0);
    goto done;
cancelled:
    plod__progress_raise(&p, PLOD_ERR_CANCELLED, context, "cancelled by the progress callback");
done:
    plod_py_image_release(&read);
    plod_cubemap_destroy(map);
    plod__progress_clear(&p);
    Py_DECREF(input_obj);
    Py_DECREF(output_obj);
    return result;
}

static PyMethodDef plod__cubemap_functions[] = {
    {"resample", (PyCFunction)(void (*)(void))plod__resample, METH_VARARGS | METH_KEYWORDS,
     "resample(input_path, output_path, projection='qsc', size=1024, filter='bilinear', "
     "format='r16', layout='cross', progress=None, threads=2) -> dict\n\n"
     "Equirectangular image -> cube map image(s).  formats: 'rgba8', 'rgb8', 'r16', 'f32' "
     "(keeps the channels), 'r8'.  layout 'faces' writes six images ('{face}' in the path, "
     "else '_face<N>' before the extension).  progress(fraction) returning True cancels "
     "(planetlod.Cancelled, nothing written).  Returns the seconds spent: "
     "{'read_s', 'resample_s', 'write_s', 'resample_thread_cpu_s'} (the last: CPU "
     "time of the calling thread, all of it with threads=1)."},
    {NULL, NULL, 0, NULL},
};

int plod_py_init_cubemap(PyObject *module)
{
    plod_py_cubemap_type = (PyTypeObject *)PyType_FromSpec(&plod__cubemap_spec);
    if (!plod_py_cubemap_type)
        return -1;
    if (PyModule_AddObjectRef(module, "CubeMap", (PyObject *)plod_py_cubemap_type) < 0)
        return -1;
    if (PyModule_AddFunctions(module, plod__cubemap_functions) < 0)
        return -1;
    PyObject *formats = Py_BuildValue("(sssss)", "rgba8", "rgb8", "r16", "f32", "r8");
    if (!formats || PyModule_AddObject(module, "RESAMPLE_FORMATS", formats) < 0) {
        Py_XDECREF(formats);
        return -1;
    }
    PyObject *filters = Py_BuildValue("(sss)", "nearest", "bilinear", "bicubic");
    if (!filters || PyModule_AddObject(module, "FILTERS", filters) < 0) {
        Py_XDECREF(filters);
        return -1;
    }
    return 0;
}
