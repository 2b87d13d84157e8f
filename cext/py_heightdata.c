/* py_heightdata.c -- planetlod.TiledMap: an equirectangular height map of
 * any size sampled out of core (cext/heighttiles.c), for Planet(heightmap=).
 *
 * The tile file is written once next to the map (or where `tiles=` says)
 * and reused while the map's size and modification time are unchanged.
 */
#include "pyplanetlod.h"
#include "plod_platform.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PLOD__MESSAGE 512

typedef struct {
    PyObject_HEAD
    plod_tiles *tiles;
    PyObject *path;       /* str */
    PyObject *tiles_path; /* str */
} plod_py_tiled_map;

static PyTypeObject *plod__tiled_map_type;

const plod_tiles *plod_py_tiled_map_get(PyObject *obj)
{
    if (!plod__tiled_map_type || !PyObject_TypeCheck(obj, plod__tiled_map_type))
        return NULL;
    return ((plod_py_tiled_map *)obj)->tiles;
}

typedef struct plod__build_progress {
    PyObject *callable;
    int failed;
} plod__build_progress;

static int plod__build_progress_call(void *user, double fraction)
{
    plod__build_progress *p = user;
    if (!p->callable)
        return 0;
    PyGILState_STATE gil = PyGILState_Ensure();
    PyObject *result = PyObject_CallFunction(p->callable, "d", fraction);
    int cancel = 1;
    if (result) {
        cancel = PyObject_IsTrue(result);
        Py_DECREF(result);
    }
    if (cancel < 0 || !result) {
        p->failed = 1; /* the exception stays set and is raised afterwards */
        cancel = 1;
    }
    PyGILState_Release(gil);
    return cancel;
}

/* The tile file's path as bytes (a new reference, NULL with an exception
 * set): `tiles` when given, else the map's path + ".plodtiles". */
static PyObject *plod__tiles_path(const char *path, PyObject *tiles)
{
    if (tiles == Py_None)
        return PyBytes_FromFormat("%s.plodtiles", path);
    PyObject *bytes = NULL;
    return PyUnicode_FSConverter(tiles, &bytes) ? bytes : NULL;
}

static int plod__tiled_map_init(plod_py_tiled_map *self, PyObject *args, PyObject *kwds)
{
    static char *kwlist[] = {"path", "raw", "signed", "tiles", "cache_bytes", "tile", "progress",
                             NULL};
    const char *context = "planetlod.TiledMap";
    PyObject *path_bytes = NULL, *raw = Py_None, *tiles_obj = Py_None, *progress = Py_None;
    int is_signed = 0, tile = PLOD_TILES_DEFAULT_TILE;
    Py_ssize_t cache_bytes = 0;
    if (self->tiles) {
        PyErr_SetString(PyExc_RuntimeError, "TiledMap already initialised");
        return -1;
    }
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "O&|OpOniO", kwlist, PyUnicode_FSConverter,
                                     &path_bytes, &raw, &is_signed, &tiles_obj, &cache_bytes,
                                     &tile, &progress))
        return -1;
    int result = -1;
    PyObject *tiles_bytes = NULL;
    plod_py_read_options options;
    if (plod_py_read_options_arg(raw, is_signed, &options, context) < 0)
        goto done;
    if (cache_bytes < 0) {
        plod_py_raise_detail(PLOD_ERR_BAD_PARAM, context, "cache_bytes must be >= 0 (0: 128 MiB)");
        goto done;
    }
    if (progress != Py_None && !PyCallable_Check(progress)) {
        plod_py_raise_detail(PLOD_ERR_BAD_PARAM, context, "progress must be callable or None");
        goto done;
    }
    const char *path = PyBytes_AsString(path_bytes);
    if (!(tiles_bytes = plod__tiles_path(path, tiles_obj)))
        goto done;
    const char *tiles_path = PyBytes_AsString(tiles_bytes);
    if (!plod_path_readable(path)) {
        char detail[PLOD__MESSAGE];
        snprintf(detail, sizeof detail, "cannot read '%s'", path);
        plod_py_raise_detail(PLOD_ERR_IO, context, detail);
        goto done;
    }
    char message[PLOD__MESSAGE];
    plod_status s = PLOD_OK;
    if (!plod_tiles_current(tiles_path, path)) {
        plod__build_progress p = {progress == Py_None ? NULL : progress, 0};
        plod_py_rows_context rows_context;
        plod_image_rows_reader reader = plod_py_rows_reader(&rows_context);
        Py_BEGIN_ALLOW_THREADS
        s = plod_tiles_build(path, options.has_raw ? &options.raw : NULL, &reader,
                             options.is_signed, tiles_path, tile, plod__build_progress_call, &p,
                             message, sizeof message);
        Py_END_ALLOW_THREADS
        if (plod_py_rows_reader_raise(&rows_context) < 0) {
            PyErr_Clear(); /* keep the reader's error over any progress one */
            goto done;
        }
        if (p.failed)
            goto done;
        if (s != PLOD_OK) {
            plod_py_raise_detail(s, context, message);
            goto done;
        }
    }
    plod_tiles *tiles = NULL;
    Py_BEGIN_ALLOW_THREADS
    s = plod_tiles_open(&tiles, tiles_path, (size_t)cache_bytes, message, sizeof message);
    Py_END_ALLOW_THREADS
    if (s != PLOD_OK) {
        plod_py_raise_detail(s, context, message);
        goto done;
    }
    self->tiles = tiles;
    self->path = PyUnicode_DecodeFSDefault(path);
    self->tiles_path = PyUnicode_DecodeFSDefault(tiles_path);
    result = self->path && self->tiles_path ? 0 : -1;
done:
    Py_XDECREF(tiles_bytes);
    Py_XDECREF(path_bytes);
    return result;
}

static void plod__tiled_map_dealloc(plod_py_tiled_map *self)
{
    plod_tiles_destroy(self->tiles);
    self->tiles = NULL;
    Py_CLEAR(self->path);
    Py_CLEAR(self->tiles_path);
    PyTypeObject *tp = Py_TYPE((PyObject *)self);
    freefunc release = (freefunc)PyType_GetSlot(tp, Py_tp_free);
    release(self);
    Py_DECREF(tp);
}

static int plod__tiled_map_ready(plod_py_tiled_map *self)
{
    if (!self->tiles) {
        PyErr_SetString(PyExc_RuntimeError, "TiledMap not initialised");
        return 0;
    }
    return 1;
}

static PyObject *plod__tiled_map_sample(plod_py_tiled_map *self, PyObject *args)
{
    double lon, lat;
    if (!plod__tiled_map_ready(self) || !PyArg_ParseTuple(args, "dd", &lon, &lat))
        return NULL;
    if (!isfinite(lon) || !isfinite(lat))
        return plod_py_raise_detail(PLOD_ERR_BAD_COORD, "TiledMap.sample",
                                    "longitude and latitude must be finite");
    double value;
    Py_BEGIN_ALLOW_THREADS
    value = plod_tiles_sample_uv(self->tiles, lon / 180.0, lat / 90.0);
    Py_END_ALLOW_THREADS
    return PyFloat_FromDouble(value);
}

static PyObject *plod__tiled_map_range(plod_py_tiled_map *self, PyObject *args)
{
    double lon0 = -180.0, lat0 = -90.0, lon1 = 180.0, lat1 = 90.0;
    if (!plod__tiled_map_ready(self) ||
        !PyArg_ParseTuple(args, "|dddd", &lon0, &lat0, &lon1, &lat1))
        return NULL;
    double lo, hi;
    if (PyTuple_Size(args) == 0) {
        plod_tiles_global_range(self->tiles, &lo, &hi);
    } else {
        Py_BEGIN_ALLOW_THREADS
        plod_tiles_range_uv(self->tiles, lon0 / 180.0, lat0 / 90.0, lon1 / 180.0, lat1 / 90.0,
                            &lo, &hi);
        Py_END_ALLOW_THREADS
    }
    return Py_BuildValue("(dd)", lo, hi);
}

static PyObject *plod__tiled_map_get(plod_py_tiled_map *self, void *closure)
{
    if (!plod__tiled_map_ready(self))
        return NULL;
    static const char *const dtypes[] = {"u8", "u16", "f32"};
    switch ((int)(intptr_t)closure) {
    case 0: return PyLong_FromLong(plod_tiles_width(self->tiles));
    case 1: return PyLong_FromLong(plod_tiles_height(self->tiles));
    case 2: return PyUnicode_FromString(dtypes[plod_tiles_type(self->tiles)]);
    case 3: Py_INCREF(self->path); return self->path;
    case 4: Py_INCREF(self->tiles_path); return self->tiles_path;
    case 5: return PyLong_FromSize_t(plod_tiles_cache_limit(self->tiles));
    case 6: return PyLong_FromSize_t(plod_tiles_cached_bytes(self->tiles));
    case 7: return PyLong_FromSize_t(plod_tiles_read_errors(self->tiles));
    default: return PyLong_FromSize_t(plod_tiles_nan_count(self->tiles));
    }
}

static PyGetSetDef plod__tiled_map_getset[] = {
    {"width", (getter)plod__tiled_map_get, NULL, "texels per row (360 degrees)", (void *)0},
    {"height", (getter)plod__tiled_map_get, NULL, "rows (180 degrees)", (void *)1},
    {"dtype", (getter)plod__tiled_map_get, NULL, "'u8', 'u16' or 'f32'", (void *)2},
    {"path", (getter)plod__tiled_map_get, NULL, "the map", (void *)3},
    {"tiles_path", (getter)plod__tiled_map_get, NULL, "its tile file", (void *)4},
    {"cache_bytes", (getter)plod__tiled_map_get, NULL, "bound of the tile cache", (void *)5},
    {"cached_bytes", (getter)plod__tiled_map_get, NULL, "bytes of tiles cached now", (void *)6},
    {"read_errors", (getter)plod__tiled_map_get, NULL,
     "tile reads that failed (file changed or vanished): NaN samples", (void *)7},
    {"nan_count", (getter)plod__tiled_map_get, NULL, "NaN texels (no-data)", (void *)8},
    {NULL},
};

/* TiledMap.is_written(path, tiles=None): whether the tile file is complete
 * and current for the map (then TiledMap(path) opens it without writing). */
static PyObject *plod__tiled_map_is_written(PyObject *Py_UNUSED(cls), PyObject *args,
                                            PyObject *kwds)
{
    static char *kwlist[] = {"path", "tiles", NULL};
    PyObject *path_bytes = NULL, *tiles_obj = Py_None, *tiles_bytes = NULL, *result = NULL;
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "O&|O", kwlist, PyUnicode_FSConverter,
                                     &path_bytes, &tiles_obj))
        return NULL;
    if (!(tiles_bytes = plod__tiles_path(PyBytes_AsString(path_bytes), tiles_obj)))
        goto done;
    const char *path = PyBytes_AsString(path_bytes), *tiles_path = PyBytes_AsString(tiles_bytes);
    int current;
    Py_BEGIN_ALLOW_THREADS
    current = plod_tiles_current(tiles_path, path);
    Py_END_ALLOW_THREADS
    result = PyBool_FromLong(current);
done:
    Py_XDECREF(tiles_bytes);
    Py_DECREF(path_bytes);
    return result;
}

static PyMethodDef plod__tiled_map_methods[] = {
    {"is_written", (PyCFunction)(void (*)(void))plod__tiled_map_is_written,
     METH_VARARGS | METH_KEYWORDS | METH_STATIC,
     "is_written(path, tiles=None) -> bool: the tile file (default path + '.plodtiles') is "
     "complete and current for the map, so TiledMap(path) opens it without writing"},
    {"sample", (PyCFunction)plod__tiled_map_sample, METH_VARARGS,
     "sample(lon_deg, lat_deg) -> float: bilinear value (normalised as CubeMap samples)"},
    {"range", (PyCFunction)plod__tiled_map_range, METH_VARARGS,
     "range([lon0, lat0, lon1, lat1]) -> (min, max): conservative bounds of the box (or the "
     "whole map)"},
    {NULL},
};

static PyType_Slot plod__tiled_map_slots[] = {
    {Py_tp_doc, "TiledMap(path, raw=None, signed=False, tiles=None, cache_bytes=0, tile=128, "
                "progress=None): an equirectangular height map of any size, read out of core "
                "through a tile file written once (default: path + '.plodtiles') and a tile "
                "cache of at most cache_bytes (0: 128 MiB).  Planet(heightmap=TiledMap(...))."},
    {Py_tp_init, plod__tiled_map_init},
    {Py_tp_new, PyType_GenericNew},
    {Py_tp_dealloc, plod__tiled_map_dealloc},
    {Py_tp_getset, plod__tiled_map_getset},
    {Py_tp_methods, plod__tiled_map_methods},
    {0, NULL},
};

static PyType_Spec plod__tiled_map_spec = {
    .name = "planetlod.TiledMap",
    .basicsize = sizeof(plod_py_tiled_map),
    .flags = Py_TPFLAGS_DEFAULT,
    .slots = plod__tiled_map_slots,
};

int plod_py_init_heightdata(PyObject *module)
{
    PyObject *type = PyType_FromSpec(&plod__tiled_map_spec);
    if (!type)
        return -1;
    plod__tiled_map_type = (PyTypeObject *)type;
    Py_INCREF(type); /* ours, beside the module's */
    if (PyModule_AddObject(module, "TiledMap", type) < 0) {
        Py_DECREF(type);
        Py_DECREF(type);
        plod__tiled_map_type = NULL;
        return -1;
    }
    return 0;
}

/* ======================================================================== */
/* insets for Planet(insets=[...])                                          */
/* ======================================================================== */

/* Channel 0 of an image as metres: value * scale + offset (u8/u16
 * normalised as maps sample; f32 as stored; NaN stays a void). */
static float *plod__image_metres(const plod_image *image, double scale, double offset)
{
    size_t n = (size_t)image->width * (size_t)image->height;
    float *out = malloc(n * sizeof *out);
    if (!out)
        return NULL;
    for (size_t i = 0; i < n; i++) {
        size_t at = i * (size_t)image->channels;
        double v;
        switch (image->type) {
        case PLOD_TEXEL_U8: v = ((const uint8_t *)image->pixels)[at] * (1.0 / 255.0); break;
        case PLOD_TEXEL_U16: v = ((const uint16_t *)image->pixels)[at] * (1.0 / 65535.0); break;
        default: v = ((const float *)image->pixels)[at];
        }
        out[i] = (float)(v * scale + offset);
    }
    return out;
}

static int plod__number_item(PyObject *dict, const char *key, double *out, int required)
{
    PyObject *item = PyMapping_HasKeyString(dict, key) ? PyMapping_GetItemString(dict, key) : NULL;
    PyErr_Clear();
    if (!item)
        return required ? -1 : 0;
    double v = PyFloat_AsDouble(item);
    Py_DECREF(item);
    if (v == -1.0 && PyErr_Occurred()) {
        PyErr_Clear();
        return -1;
    }
    *out = v;
    return isfinite(v) ? 0 : -1;
}

/* A GeoTIFF inset's box from its tags into `box`, and its no-data samples
 * (channel 0) made voids.  A `given` box must agree with the tags to 1 %
 * of a sample spacing on every side (it is then used as given); otherwise
 * PLOD_ERR_BAD_PARAM names both. */
static plod_status plod__georef_place(const plod_georef *geo, plod_image *image,
                                      const double *given, double box[4], const char *path,
                                      Py_ssize_t i, char *message, size_t message_size)
{
    double tagged[4];
    char why[PLOD__MESSAGE];
    plod_status s = plod_georef_box(geo, image->width, image->height, tagged, why, sizeof why);
    if (s != PLOD_OK) {
        snprintf(message, message_size, "inset %zd ('%.200s'): %s", i, path, why);
        return s;
    }
    if (given) {
        double dx = (tagged[2] - tagged[0]) / (image->width > 1 ? image->width - 1 : 1);
        double dy = (tagged[3] - tagged[1]) / (image->height > 1 ? image->height - 1 : 1);
        for (int k = 0; k < 4; k++)
            if (!(fabs(given[k] - tagged[k]) <= 0.01 * (k % 2 ? dy : dx))) {
                snprintf(message, message_size,
                         "inset %zd ('%.200s'): the box given (west %.9g, south %.9g, east "
                         "%.9g, north %.9g) disagrees with the file's GeoTIFF placement of its "
                         "sample centres (%.9g, %.9g, %.9g, %.9g, Pixel%s); leave the box out "
                         "to place it by its tags",
                         i, path, given[0], given[1], given[2], given[3], tagged[0], tagged[1],
                         tagged[2], tagged[3], geo->raster_type == 2 ? "IsPoint" : "IsArea");
                return PLOD_ERR_BAD_PARAM;
            }
    } else {
        memcpy(box, tagged, sizeof tagged);
    }
    if (geo->has_nodata && image->type == PLOD_TEXEL_F32) {
        float nodata = (float)geo->nodata;
        float *v = image->pixels;
        size_t n = (size_t)image->width * (size_t)image->height;
        for (size_t t = 0; t < n; t++)
            if (v[t * (size_t)image->channels] == nodata)
                v[t * (size_t)image->channels] = NAN;
    }
    return PLOD_OK;
}

int plod_py_insets_arg(PyObject *list, double feather, plod_insets **out)
{
    const char *context = "Planet insets";
    *out = NULL;
    if (!list || list == Py_None)
        return 0;
    PyObject *seq = PySequence_List(list);
    if (!seq) {
        PyErr_Clear();
        plod_py_raise_detail(PLOD_ERR_BAD_PARAM, context,
                             "insets must be a list of .hgt or GeoTIFF paths or dicts(path, "
                             "west, south, east, north[, raw, scale, offset])");
        return -1;
    }
    Py_ssize_t count = PyList_Size(seq);
    plod_inset_desc *descs = calloc(count ? (size_t)count : 1, sizeof *descs);
    float **grids = calloc(count ? (size_t)count : 1, sizeof *grids);
    int result = -1;
    char message[2 * PLOD__MESSAGE]; /* room for a path and the reason */
    if (!descs || !grids) {
        PyErr_NoMemory();
        goto done;
    }
    for (Py_ssize_t i = 0; i < count; i++) {
        PyObject *item = PyList_GetItem(seq, i); /* borrowed */
        PyObject *path_obj = item, *raw = Py_None, *owned = NULL;
        double box[4] = {0, 0, 0, 0}, scale = 1.0, offset = 0.0; /* west south east north */
        int is_dict = PyDict_Check(item), box_keys = 0;
        if (is_dict) {
            static const char *const sides[4] = {"west", "south", "east", "north"};
            path_obj = PyDict_GetItemString(item, "path");
            raw = PyDict_GetItemString(item, "raw");
            if (!raw)
                raw = Py_None;
            int bad = !path_obj || plod__number_item(item, "scale", &scale, 0) < 0 ||
                      plod__number_item(item, "offset", &offset, 0) < 0;
            for (int k = 0; k < 4 && !bad; k++) {
                int has = PyMapping_HasKeyString(item, sides[k]);
                box_keys += has;
                bad = has && plod__number_item(item, sides[k], &box[k], 1) < 0;
            }
            if (bad || (box_keys != 0 && box_keys != 4)) {
                snprintf(message, sizeof message,
                         "inset %zd: a dict needs path and finite west, south, east, north "
                         "(degrees; all four, or none for a GeoTIFF placed by its tags; "
                         "optional raw, scale, offset)", i);
                plod_py_raise_detail(PLOD_ERR_BAD_PARAM, context, message);
                goto done;
            }
        }
        if (!PyUnicode_FSConverter(path_obj, &owned)) {
            PyErr_Clear();
            snprintf(message, sizeof message, "inset %zd: not a path or dict", i);
            plod_py_raise_detail(PLOD_ERR_BAD_PARAM, context, message);
            goto done;
        }
        const char *path = PyBytes_AsString(owned);
        plod_py_read_options options;
        if (plod_py_read_options_arg(raw, 0, &options, context) < 0) {
            Py_DECREF(owned);
            goto done;
        }
        plod_georef geo = {0};
        plod_status s = PLOD_OK;
        if (!options.has_raw && !plod_raw_is_raw_path(path)) {
            Py_BEGIN_ALLOW_THREADS
            s = plod_georef_read(&geo, path, message, sizeof message);
            Py_END_ALLOW_THREADS
        }
        int lon, lat, hgt_name = !is_dict && plod_hgt_origin(path, &lon, &lat);
        if (s == PLOD_OK && !hgt_name && !box_keys && !geo.present) {
            snprintf(message, sizeof message,
                     "inset %zd ('%.200s'): %s; give other grids as dict(path, west, south, "
                     "east, north)",
                     i, path,
                     options.has_raw ? "a raw grid carries no placement"
                     : is_dict ? "not a GeoTIFF with georeferencing"
                               : "a bare path must be an SRTM tile named like N45E006.hgt or a "
                                 "GeoTIFF with georeferencing");
            s = PLOD_ERR_BAD_PARAM;
        }
        if (hgt_name)
            box[0] = lon, box[1] = lat, box[2] = lon + 1.0, box[3] = lat + 1.0;
        plod_py_image read = {0};
        plod_image *image = &read.image;
        if (s != PLOD_OK) {
            Py_DECREF(owned);
            plod_py_raise_detail(s, context, message);
            goto done;
        }
        if (plod_py_image_read(&read, path, geo.present ? PLOD_IMPORT_STORED : PLOD_IMPORT_TYPED,
                               &options, context) < 0) {
            Py_DECREF(owned);
            plod_py_image_release(&read);
            goto done;
        }
        if (geo.present)
            s = plod__georef_place(&geo, image, box_keys ? box : NULL, box, path, i, message,
                                   sizeof message);
        Py_DECREF(owned);
        if (s != PLOD_OK) {
            plod_py_image_release(&read);
            plod_py_raise_detail(s, context, message);
            goto done;
        }
        grids[i] = plod__image_metres(image, scale, offset);
        descs[i].width = image->width;
        descs[i].height = image->height;
        plod_py_image_release(&read);
        if (!grids[i]) {
            PyErr_NoMemory();
            goto done;
        }
        descs[i].west = box[0], descs[i].south = box[1], descs[i].east = box[2];
        descs[i].north = box[3];
        descs[i].metres = grids[i];
    }
    plod_status s = plod_insets_create(out, descs, (size_t)count, feather, message,
                                       sizeof message);
    if (s != PLOD_OK) {
        plod_py_raise_detail(s, context, message);
        goto done;
    }
    result = 0;
done:
    for (Py_ssize_t i = 0; grids && i < count; i++)
        free(grids[i]);
    free(grids);
    free(descs);
    Py_DECREF(seq);
    return result;
}
