/* pymodule.c -- the `planetlod._native` module (re-exported by the `planetlod`
 * package): initialisation, the exported Buffer
 * type, and the single place where plod_status codes become exceptions.
 *
 * Module-level objects (exception classes, the Buffer type) are created once
 * in PyInit and never change afterwards; they hold no per-call state.
 */
#include "pyplanetlod.h"

#include <stdlib.h>
#include <string.h>

static PyObject *plod_py_base_error;
static PyObject *plod_py_invalid_argument;
static PyObject *plod_py_file_error;
static PyObject *plod_py_image_error;
static PyObject *plod_py_cancelled;
static PyTypeObject *plod_py_buffer_type;

/* ======================================================================== */
/* Buffer                                                                    */
/* ======================================================================== */

typedef struct {
    PyObject_HEAD
    void *data;
    Py_ssize_t count;
    Py_ssize_t itemsize;
    Py_ssize_t exports;
    char format[2];
    plod_py_pool *pool; /* a reference: data goes back to it (NULL: freed) */
    size_t capacity;    /* bytes of data */
} plod_py_buffer;

/* ---- storage pool ---------------------------------------------------------- */

/* Blocks below this size come from malloc's own free lists anyway. */
#define PLOD__POOL_MIN_BYTES ((size_t)64 << 10)
#define PLOD__POOL_BLOCKS 32

struct plod_py_pool {
    Py_ssize_t references;
    size_t keep_bytes;  /* the most it holds: 1.5 times the latest mesh's buffers */
    size_t kept_bytes;
    int count;          /* blocks held, oldest first */
    void *block[PLOD__POOL_BLOCKS];
    size_t bytes[PLOD__POOL_BLOCKS];
};

plod_py_pool *plod_py_pool_new(void)
{
    plod_py_pool *pool = calloc(1, sizeof *pool);
    if (pool)
        pool->references = 1;
    return pool;
}

/* Block k, no longer held (the caller's to use or free). */
static void *plod__pool_remove(plod_py_pool *pool, int k)
{
    void *block = pool->block[k];
    pool->kept_bytes -= pool->bytes[k];
    pool->count--;
    memmove(pool->block + k, pool->block + k + 1,
            (size_t)(pool->count - k) * sizeof pool->block[0]);
    memmove(pool->bytes + k, pool->bytes + k + 1,
            (size_t)(pool->count - k) * sizeof pool->bytes[0]);
    return block;
}

static void plod__pool_drop_oldest(plod_py_pool *pool)
{
    free(plod__pool_remove(pool, 0));
}

void plod_py_pool_release(plod_py_pool *pool)
{
    if (!pool || --pool->references > 0)
        return;
    while (pool->count > 0)
        plod__pool_drop_oldest(pool);
    free(pool);
}

void plod_py_pool_keep(plod_py_pool *pool, size_t bytes)
{
    if (!pool)
        return;
    pool->keep_bytes = bytes + bytes / 2; /* with the blocks' slack (below) */
    while (pool->count > 0 && pool->kept_bytes > pool->keep_bytes)
        plod__pool_drop_oldest(pool);
}

/* A held block of `need` to 2 `need` bytes (the smallest), or NULL. */
static void *plod__pool_take(plod_py_pool *pool, size_t need, size_t *bytes)
{
    int best = -1;
    for (int k = 0; k < pool->count; k++)
        if (pool->bytes[k] >= need && pool->bytes[k] / 2 <= need &&
            (best < 0 || pool->bytes[k] < pool->bytes[best]))
            best = k;
    if (best < 0)
        return NULL;
    *bytes = pool->bytes[best];
    return plod__pool_remove(pool, best);
}

/* A buffer's storage back to its pool (the newest block; the oldest go
 * while it holds too much), or freed. */
static void plod__pool_give(plod_py_pool *pool, void *block, size_t bytes)
{
    if (bytes > pool->keep_bytes) {
        free(block);
        return;
    }
    if (pool->count == PLOD__POOL_BLOCKS)
        plod__pool_drop_oldest(pool);
    pool->block[pool->count] = block;
    pool->bytes[pool->count++] = bytes;
    pool->kept_bytes += bytes;
    while (pool->kept_bytes > pool->keep_bytes)
        plod__pool_drop_oldest(pool);
}

static Py_ssize_t plod__itemsize(char format)
{
    switch (format) {
    case 'f': return 4;
    case 'd': return 8;
    case 'i': return 4;
    case 'I': return 4;
    case 'B': return 1;
    case 'H': return 2;
    case 'Q': return 8;
    default: return 0;
    }
}

static PyObject *plod__buffer_alloc(char format, size_t count, void *data)
{
    Py_ssize_t itemsize = plod__itemsize(format);
    if (itemsize == 0) {
        free(data);
        PyErr_Format(PyExc_SystemError, "planetlod: bad buffer format '%c'", format);
        return NULL;
    }
    plod_py_buffer *self = PyObject_New(plod_py_buffer, plod_py_buffer_type);
    if (!self) {
        free(data);
        return NULL;
    }
    self->data = data;
    self->count = (Py_ssize_t)count;
    self->itemsize = itemsize;
    self->exports = 0;
    self->format[0] = format;
    self->format[1] = '\0';
    self->pool = NULL;
    self->capacity = 0;
    return (PyObject *)self;
}

/* Bytes of a buffer of `count` items of `format` (an empty one keeps one
 * item: malloc(0) may return NULL); -1 with an exception when there is no
 * such buffer. */
static int plod__storage_bytes(char format, size_t count, size_t *bytes)
{
    Py_ssize_t itemsize = plod__itemsize(format);
    if (itemsize == 0) {
        PyErr_Format(PyExc_SystemError, "planetlod: bad buffer format '%c'", format);
        return -1;
    }
    if (count > (size_t)PY_SSIZE_T_MAX / (size_t)itemsize) {
        PyErr_NoMemory();
        return -1;
    }
    *bytes = (count ? count : 1) * (size_t)itemsize;
    return 0;
}

PyObject *plod_py_buffer_new(char format, size_t count, void **data)
{
    size_t bytes;
    if (plod__storage_bytes(format, count, &bytes) < 0)
        return NULL;
    void *storage = calloc(bytes, 1);
    if (!storage)
        return PyErr_NoMemory();
    PyObject *buffer = plod__buffer_alloc(format, count, storage);
    if (buffer && data)
        *data = storage;
    return buffer;
}

PyObject *plod_py_buffer_pooled(plod_py_pool *pool, char format, size_t count, void **data)
{
    *data = NULL;
    size_t need;
    if (plod__storage_bytes(format, count, &need) < 0)
        return NULL;
    if (need < PLOD__POOL_MIN_BYTES)
        pool = NULL;
    size_t bytes = need;
    void *storage = pool ? plod__pool_take(pool, need, &bytes) : NULL;
    if (!storage && pool) {
        /* a quarter more: the next frames' meshes, a little larger, fit */
        bytes = need + need / 4;
        storage = malloc(bytes);
    }
    if (!storage)
        storage = malloc(bytes = need);
    if (!storage)
        return PyErr_NoMemory();
    PyObject *buffer = plod__buffer_alloc(format, count, storage);
    if (!buffer)
        return NULL; /* (storage freed) */
    if (pool) {
        plod_py_buffer *self = (plod_py_buffer *)buffer;
        self->pool = pool;
        self->capacity = bytes;
        pool->references++;
    }
    *data = storage;
    return buffer;
}

int plod_py_buffer_truncate(PyObject *obj, size_t count)
{
    if (!PyObject_TypeCheck(obj, plod_py_buffer_type)) {
        PyErr_SetString(PyExc_TypeError, "expected a planetlod.Buffer");
        return -1;
    }
    plod_py_buffer *self = (plod_py_buffer *)obj;
    if (self->exports > 0 || count > (size_t)self->count) {
        PyErr_SetString(PyExc_SystemError, "planetlod: buffer cannot be truncated");
        return -1;
    }
    self->count = (Py_ssize_t)count;
    return 0;
}

void *plod_py_buffer_data(PyObject *obj, size_t *count, char *format)
{
    if (!PyObject_TypeCheck(obj, plod_py_buffer_type)) {
        PyErr_SetString(PyExc_TypeError, "expected a planetlod.Buffer");
        return NULL;
    }
    plod_py_buffer *self = (plod_py_buffer *)obj;
    if (count)
        *count = (size_t)self->count;
    if (format)
        *format = self->format[0];
    return self->data;
}

static void plod__buffer_dealloc(plod_py_buffer *self)
{
    PyTypeObject *type = Py_TYPE((PyObject *)self);
    if (self->pool) {
        plod__pool_give(self->pool, self->data, self->capacity);
        plod_py_pool_release(self->pool);
    } else {
        free(self->data);
    }
    PyObject_Free(self);
    Py_DECREF(type);
}

static int plod__buffer_getbuffer(plod_py_buffer *self, Py_buffer *view, int flags)
{
    /* Shapes are filled only when asked for, as CPython's array does: a
     * PyBUF_SIMPLE|PyBUF_FORMAT consumer (Blender's foreach_set) gets a flat
     * byte run plus the item format. */
    view->buf = self->data;
    view->obj = Py_NewRef((PyObject *)self);
    view->len = self->count * self->itemsize;
    view->readonly = 0;
    view->itemsize = self->itemsize;
    view->format = (flags & PyBUF_FORMAT) ? self->format : NULL;
    view->ndim = 1;
    view->shape = (flags & PyBUF_ND) ? &self->count : NULL;
    view->strides = ((flags & PyBUF_STRIDES) == PyBUF_STRIDES) ? &self->itemsize : NULL;
    view->suboffsets = NULL;
    view->internal = NULL;
    self->exports++;
    return 0;
}

static void plod__buffer_releasebuffer(plod_py_buffer *self, Py_buffer *view)
{
    (void)view;
    self->exports--;
}

static Py_ssize_t plod__buffer_length(plod_py_buffer *self)
{
    return self->count;
}

static PyObject *plod__buffer_item(plod_py_buffer *self, Py_ssize_t index)
{
    if (index < 0 || index >= self->count) {
        PyErr_SetString(PyExc_IndexError, "planetlod.Buffer index out of range");
        return NULL;
    }
    const char *p = (const char *)self->data + index * self->itemsize;
    switch (self->format[0]) {
    case 'f': { float x; memcpy(&x, p, 4); return PyFloat_FromDouble(x); }
    case 'd': { double x; memcpy(&x, p, 8); return PyFloat_FromDouble(x); }
    case 'i': { int32_t x; memcpy(&x, p, 4); return PyLong_FromLong(x); }
    case 'I': { uint32_t x; memcpy(&x, p, 4); return PyLong_FromUnsignedLong(x); }
    case 'B': return PyLong_FromLong(*(const uint8_t *)p);
    case 'H': { uint16_t x; memcpy(&x, p, 2); return PyLong_FromLong(x); }
    case 'Q': { uint64_t x; memcpy(&x, p, 8); return PyLong_FromUnsignedLongLong(x); }
    default: break;
    }
    PyErr_SetString(PyExc_SystemError, "planetlod.Buffer: bad format");
    return NULL;
}

static PyObject *plod__buffer_tolist(plod_py_buffer *self, PyObject *unused)
{
    (void)unused;
    PyObject *list = PyList_New(self->count);
    if (!list)
        return NULL;
    for (Py_ssize_t i = 0; i < self->count; i++) {
        PyObject *item = plod__buffer_item(self, i);
        if (!item) {
            Py_DECREF(list);
            return NULL;
        }
        PyList_SetItem(list, i, item);
    }
    return list;
}

static PyObject *plod__buffer_get_format(plod_py_buffer *self, void *closure)
{
    (void)closure;
    return PyUnicode_FromString(self->format);
}

static PyObject *plod__buffer_get_itemsize(plod_py_buffer *self, void *closure)
{
    (void)closure;
    return PyLong_FromSsize_t(self->itemsize);
}

static PyObject *plod__buffer_get_nbytes(plod_py_buffer *self, void *closure)
{
    (void)closure;
    return PyLong_FromSsize_t(self->count * self->itemsize);
}

static PyObject *plod__buffer_repr(plod_py_buffer *self)
{
    return PyUnicode_FromFormat("<planetlod.Buffer format='%s' len=%zd>",
                                self->format, self->count);
}

static PyMethodDef plod__buffer_methods[] = {
    {"tolist", (PyCFunction)plod__buffer_tolist, METH_NOARGS,
     "tolist() -> list\n\nThe items as Python numbers."},
    {NULL, NULL, 0, NULL},
};

static PyGetSetDef plod__buffer_getset[] = {
    {"format", (getter)plod__buffer_get_format, NULL, "struct format character", NULL},
    {"itemsize", (getter)plod__buffer_get_itemsize, NULL, "bytes per item", NULL},
    {"nbytes", (getter)plod__buffer_get_nbytes, NULL, "total bytes", NULL},
    {NULL, NULL, NULL, NULL, NULL},
};

static PyType_Slot plod__buffer_slots[] = {
    {Py_tp_dealloc, plod__buffer_dealloc},
    {Py_tp_repr, plod__buffer_repr},
    {Py_tp_methods, plod__buffer_methods},
    {Py_tp_getset, plod__buffer_getset},
    {Py_bf_getbuffer, plod__buffer_getbuffer},
    {Py_bf_releasebuffer, plod__buffer_releasebuffer},
    {Py_sq_length, plod__buffer_length},
    {Py_sq_item, plod__buffer_item},
    {Py_tp_doc, (void *)"Flat typed buffer exported by planetlod (buffer protocol, "
                "accepted by Blender's foreach_set)."},
    {0, NULL},
};

static PyType_Spec plod__buffer_spec = {
    .name = "planetlod.Buffer",
    .basicsize = sizeof(plod_py_buffer),
    .itemsize = 0,
    .flags = Py_TPFLAGS_DEFAULT,
    .slots = plod__buffer_slots,
};

/* ======================================================================== */
/* Errors                                                                    */
/* ======================================================================== */

PyObject *plod_py_raise_detail(plod_status status, const char *context,
                               const char *detail)
{
    PyObject *type;
    switch (status) {
    case PLOD_ERR_NO_MEMORY:
        type = PyExc_MemoryError;
        break;
    case PLOD_ERR_IO:
        type = plod_py_file_error;
        break;
    case PLOD_ERR_BAD_IMAGE:
        type = plod_py_image_error;
        break;
    case PLOD_ERR_CANCELLED:
        type = plod_py_cancelled;
        break;
    case PLOD_OK:
        type = PyExc_SystemError; /* a caller bug: raising on success */
        break;
    default:
        type = plod_py_invalid_argument;
        break;
    }
    const char *message = plod_status_message(status);
    if (detail && detail[0])
        PyErr_Format(type, "%s: %s (%s)", context ? context : "planetlod", message, detail);
    else
        PyErr_Format(type, "%s: %s", context ? context : "planetlod", message);
    return NULL;
}

int plod_py_exception_status(plod_status *status, char *message, size_t message_size)
{
    PyObject *type, *value, *traceback;
    PyErr_Fetch(&type, &value, &traceback);
    if (!type)
        return -1;
    if (PyErr_GivenExceptionMatches(type, plod_py_image_error))
        *status = PLOD_ERR_BAD_IMAGE;
    else if (PyErr_GivenExceptionMatches(type, plod_py_file_error))
        *status = PLOD_ERR_IO;
    else if (PyErr_GivenExceptionMatches(type, plod_py_invalid_argument))
        *status = PLOD_ERR_BAD_PARAM;
    else if (PyErr_GivenExceptionMatches(type, PyExc_MemoryError))
        *status = PLOD_ERR_NO_MEMORY;
    else {
        PyErr_Restore(type, value, traceback);
        return -1;
    }
    PyObject *text = value ? PyObject_Str(value) : NULL;
    const char *utf8 = text ? PyUnicode_AsUTF8AndSize(text, NULL) : NULL;
    PyErr_Clear();
    plod_status_format(message, message_size, "%s", utf8 ? utf8 : "");
    Py_XDECREF(text);
    Py_XDECREF(type);
    Py_XDECREF(value);
    Py_XDECREF(traceback);
    return 0;
}

PyObject *plod_py_raise(plod_status status, const char *context)
{
    return plod_py_raise_detail(status, context, NULL);
}

/* ======================================================================== */
/* Argument helpers                                                          */
/* ======================================================================== */

/* "'tsc', 'csc', ... or 'car'": the names in plod_projection_name's table. */
static void plod__projection_choices(char *out, size_t size)
{
    size_t used = 0;
    out[0] = '\0';
    for (int p = 0; p < PLOD_PROJ_COUNT; p++) {
        const char *sep = p == 0 ? "" : p + 1 < PLOD_PROJ_COUNT ? ", " : " or ";
        int n = snprintf(out + used, size - used, "%s'%s'", sep,
                         plod_projection_name((plod_projection)p));
        if (n < 0 || (size_t)n >= size - used)
            break;
        used += (size_t)n;
    }
}

int plod_py_projection_arg(PyObject *name, plod_projection *out)
{
    char choices[128];
    plod__projection_choices(choices, sizeof choices);
    if (!PyUnicode_Check(name)) {
        PyErr_Format(plod_py_invalid_argument, "projection must be a str: %s", choices);
        return -1;
    }
    const char *text = PyUnicode_AsUTF8AndSize(name, NULL);
    if (!text)
        return -1;
    if (plod_projection_from_name(text, out) != PLOD_OK) {
        PyErr_Format(plod_py_invalid_argument, "unknown projection '%s' (expected %s)", text,
                     choices);
        return -1;
    }
    return 0;
}

double *plod_py_doubles(PyObject *obj, size_t *count, const char *what)
{
    if (PyObject_CheckBuffer(obj)) {
        Py_buffer view;
        if (PyObject_GetBuffer(obj, &view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0)
            return NULL;
        const char *fmt = view.format ? view.format : "B";
        if (fmt[0] == '<' || fmt[0] == '=' || fmt[0] == '@')
            fmt++;
        double *values = NULL;
        size_t n = 0;
        if (strcmp(fmt, "d") == 0) {
            n = (size_t)(view.len / 8);
            values = malloc((n ? n : 1) * sizeof(double));
            if (values)
                memcpy(values, view.buf, n * sizeof(double));
        } else if (strcmp(fmt, "f") == 0) {
            n = (size_t)(view.len / 4);
            values = malloc((n ? n : 1) * sizeof(double));
            for (size_t i = 0; values && i < n; i++)
                values[i] = ((const float *)view.buf)[i];
        } else {
            PyBuffer_Release(&view);
            PyErr_Format(PyExc_TypeError, "%s: buffer must hold float64 or float32, not '%s'",
                         what, fmt);
            return NULL;
        }
        PyBuffer_Release(&view);
        if (!values)
            return (double *)PyErr_NoMemory();
        *count = n;
        return values;
    }
    PyObject *seq = PySequence_Fast(obj, "expected a sequence or buffer of floats");
    if (!seq)
        return NULL;
    Py_ssize_t n = PySequence_Size(seq);
    if (n < 0) {
        Py_DECREF(seq);
        return NULL;
    }
    double *values = malloc((size_t)(n ? n : 1) * sizeof(double));
    if (!values) {
        Py_DECREF(seq);
        return (double *)PyErr_NoMemory();
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        PyObject *item = PySequence_GetItem(seq, i);
        values[i] = item ? PyFloat_AsDouble(item) : -1.0;
        Py_XDECREF(item);
        if (values[i] == -1.0 && PyErr_Occurred()) {
            free(values);
            Py_DECREF(seq);
            PyErr_Format(PyExc_TypeError, "%s: item %zd is not a number", what, i);
            return NULL;
        }
    }
    Py_DECREF(seq);
    *count = (size_t)n;
    return values;
}

/* ======================================================================== */
/* Module                                                                    */
/* ======================================================================== */

static PyObject *plod__new_exception(PyObject *module, const char *name,
                                     PyObject *bases, const char *doc)
{
    char qualified[64];
    snprintf(qualified, sizeof qualified, "planetlod.%s", name);
    PyObject *type = PyErr_NewExceptionWithDoc(qualified, doc, bases, NULL);
    if (!type)
        return NULL;
    if (PyModule_AddObjectRef(module, name, type) < 0) {
        Py_DECREF(type);
        return NULL;
    }
    return type;
}

static int plod__add_exceptions(PyObject *module)
{
    plod_py_base_error = plod__new_exception(module, "PlanetLODError", NULL,
                                             "Base class of planetlod errors.");
    if (!plod_py_base_error)
        return -1;
    PyObject *bases = PyTuple_Pack(2, plod_py_base_error, PyExc_ValueError);
    if (!bases)
        return -1;
    plod_py_invalid_argument = plod__new_exception(
        module, "InvalidArgument", bases, "An argument outside its valid range.");
    plod_py_image_error = plod__new_exception(
        module, "ImageError", bases, "A corrupt, empty or unsupported image.");
    Py_DECREF(bases);
    if (!plod_py_invalid_argument || !plod_py_image_error)
        return -1;
    bases = PyTuple_Pack(2, plod_py_base_error, PyExc_OSError);
    if (!bases)
        return -1;
    plod_py_file_error = plod__new_exception(module, "FileError", bases,
                                             "A file that cannot be read or written.");
    Py_DECREF(bases);
    if (!plod_py_file_error)
        return -1;
    plod_py_cancelled = plod__new_exception(module, "Cancelled", plod_py_base_error,
                                            "A long operation was cancelled.");
    return plod_py_cancelled ? 0 : -1;
}

static struct PyModuleDef plod__module_def = {
    PyModuleDef_HEAD_INIT,
    .m_name = "planetlod._native",
    .m_doc = "Planet LOD core: cube-sphere projections, cube maps, HRTMR "
             "refinement, culling and sector mesh emission.",
    .m_size = -1,
};

PyMODINIT_FUNC PyInit__native(void)
{
    PyObject *module = PyModule_Create(&plod__module_def);
    if (!module)
        return NULL;
    plod_py_buffer_type = (PyTypeObject *)PyType_FromSpec(&plod__buffer_spec);
    if (!plod_py_buffer_type || PyModule_AddObjectRef(module, "Buffer",
                                                      (PyObject *)plod_py_buffer_type) < 0)
        goto fail;
    if (plod__add_exceptions(module) < 0)
        goto fail;
    if (PyModule_AddStringConstant(module, "__version__", "0.1.0") < 0)
        goto fail;
    if (plod_py_init_projection(module) < 0 || plod_py_init_cubemap(module) < 0 ||
        plod_py_init_planet(module) < 0 || plod_py_init_mesh(module) < 0 ||
        plod_py_init_heightdata(module) < 0)
        goto fail;
    return module;
fail:
    Py_DECREF(module);
    return NULL;
}
