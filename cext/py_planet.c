/* py_planet.c -- planetlod.Camera and planetlod.Planet: argument and status
 * translation over a plod_session (plod_session.h), which owns the planet's
 * per-frame state; mesh output is built in py_mesh.c.
 *
 * Bad input policy (documented in API.md):
 *   - Camera: NaN/inf anywhere, singular or projective matrix, lens <= 0,
 *     zero resolution, ortho_scale <= 0, clip_start >= clip_end ->
 *     InvalidArgument.
 *   - refine(): camera at the planet centre -> InvalidArgument; a camera
 *     below the surface refines by its true distance (terrain around it at
 *     full depth) with horizon culling off; budget 0 = unlimited;
 *     max_sectors caps memory (default 1 << 20 leaves).
 */
#include "pyplanetlod.h"

#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

/* ---- Camera ---------------------------------------------------------------- */

typedef struct {
    PyObject_HEAD
    plod_camera camera;
} plod_py_camera;

static PyTypeObject *plod__camera_type;

/* Item `index` of a sequence as a double; -1 with an exception on failure. */
static int plod__sequence_double(PyObject *seq, Py_ssize_t index, double *out)
{
    PyObject *item = PySequence_GetItem(seq, index);
    if (!item)
        return -1;
    *out = PyFloat_AsDouble(item);
    Py_DECREF(item);
    return (*out == -1.0 && PyErr_Occurred()) ? -1 : 0;
}

static int plod__matrix_arg(PyObject *obj, double out[16])
{
    PyObject *seq = PySequence_Fast(obj, "matrix_world must be a 4x4 matrix or 16 floats");
    if (!seq)
        return -1;
    Py_ssize_t n = PySequence_Size(seq);
    int ok = 0;
    if (n == 16) {
        ok = 1;
        for (Py_ssize_t i = 0; i < 16 && ok; i++)
            ok = plod__sequence_double(seq, i, &out[i]) == 0;
    } else if (n == 4) {
        ok = 1;
        for (Py_ssize_t r = 0; r < 4 && ok; r++) {
            PyObject *item = PySequence_GetItem(seq, r);
            PyObject *row = item ? PySequence_Fast(item, "matrix_world rows must be sequences")
                                 : NULL;
            Py_XDECREF(item);
            if (!row) {
                ok = 0;
                break;
            }
            if (PySequence_Size(row) != 4) {
                Py_DECREF(row);
                ok = 0;
                PyErr_SetString(PyExc_ValueError, "matrix_world rows need 4 values");
                break;
            }
            for (Py_ssize_t c = 0; c < 4 && ok; c++)
                ok = plod__sequence_double(row, c, &out[r * 4 + c]) == 0;
            Py_DECREF(row);
        }
    } else if (n >= 0) {
        PyErr_SetString(PyExc_ValueError, "matrix_world must be 4x4 or 16 floats");
    }
    Py_DECREF(seq);
    if (!ok) {
        /* re-raise as InvalidArgument, keeping the original message */
        PyObject *type, *value, *tb;
        PyErr_Fetch(&type, &value, &tb);
        PyObject *msg = value ? PyObject_Str(value) : NULL;
        const char *text = msg ? PyUnicode_AsUTF8AndSize(msg, NULL) : NULL;
        PyErr_Clear();
        plod_py_raise_detail(PLOD_ERR_BAD_CAMERA, "Camera matrix_world",
                             text ? text : "bad matrix");
        Py_XDECREF(msg);
        Py_XDECREF(type);
        Py_XDECREF(value);
        Py_XDECREF(tb);
        return -1;
    }
    return 0;
}

static int plod__camera_init(plod_py_camera *self, PyObject *args, PyObject *kwds)
{
    static char *kwlist[] = {"matrix_world", "type", "lens", "sensor_width",
                             "sensor_height", "sensor_fit", "ortho_scale",
                             "shift_x", "shift_y", "clip_start", "clip_end",
                             "resolution_x", "resolution_y", "pixel_aspect_x",
                             "pixel_aspect_y", NULL};
    plod_camera_desc d;
    plod_camera_desc_default(&d);
    PyObject *matrix = NULL;
    const char *type = "PERSP", *fit = "AUTO";
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "|Osdddsdddddiidd", kwlist, &matrix,
                                     &type, &d.lens, &d.sensor_width,
                                     &d.sensor_height, &fit, &d.ortho_scale,
                                     &d.shift_x, &d.shift_y, &d.clip_start,
                                     &d.clip_end, &d.resolution_x, &d.resolution_y,
                                     &d.pixel_aspect_x, &d.pixel_aspect_y))
        return -1;
    if (matrix && matrix != Py_None && plod__matrix_arg(matrix, d.matrix_world) < 0)
        return -1;
    if (!strcmp(type, "PERSP") || !strcmp(type, "PANO"))
        d.orthographic = 0;
    else if (!strcmp(type, "ORTHO"))
        d.orthographic = 1;
    else {
        plod_py_raise_detail(PLOD_ERR_BAD_CAMERA, "Camera",
                             "type must be 'PERSP' or 'ORTHO'");
        return -1;
    }
    if (!strcmp(fit, "AUTO"))
        d.sensor_fit = PLOD_SENSOR_AUTO;
    else if (!strcmp(fit, "HORIZONTAL"))
        d.sensor_fit = PLOD_SENSOR_HORIZONTAL;
    else if (!strcmp(fit, "VERTICAL"))
        d.sensor_fit = PLOD_SENSOR_VERTICAL;
    else {
        plod_py_raise_detail(PLOD_ERR_BAD_CAMERA, "Camera",
                             "sensor_fit must be 'AUTO', 'HORIZONTAL' or 'VERTICAL'");
        return -1;
    }
    plod_status st = plod_camera_init(&self->camera, &d);
    if (st != PLOD_OK) {
        plod_py_raise_detail(st, "Camera",
                             "non-finite value, singular matrix, lens/sensor/ortho_scale "
                             "<= 0, zero resolution or clip_start >= clip_end");
        return -1;
    }
    return 0;
}

static PyObject *plod__vec3(const double v[3])
{
    return Py_BuildValue("(ddd)", v[0], v[1], v[2]);
}

static PyObject *plod__camera_get(plod_py_camera *self, void *closure)
{
    const plod_camera *c = &self->camera;
    switch ((int)(intptr_t)closure) {
    case 0: return plod__vec3(c->position);
    case 1: return plod__vec3(c->forward);
    case 2: return plod__vec3(c->up);
    case 3: return plod__vec3(c->right);
    case 4: return PyFloat_FromDouble(c->pixels_per_radian);
    case 5: return PyFloat_FromDouble(c->pixels_per_metre);
    case 6: {
        PyObject *t = PyTuple_New(6);
        for (int i = 0; t && i < 6; i++)
            PyTuple_SetItem(t, i, Py_BuildValue("(dddd)", c->planes[i][0], c->planes[i][1],
                                                c->planes[i][2], c->planes[i][3]));
        return t;
    }
    case 7: return PyBool_FromLong(c->desc.orthographic);
    default: return Py_BuildValue("(dddd)", c->tan_left, c->tan_right, c->tan_bottom,
                                  c->tan_top);
    }
}

static PyObject *plod__camera_contains(plod_py_camera *self, PyObject *args)
{
    double p[3];
    if (!PyArg_ParseTuple(args, "ddd", &p[0], &p[1], &p[2]))
        return NULL;
    return PyBool_FromLong(plod_camera_contains(&self->camera, p));
}

static PyGetSetDef plod__camera_getset[] = {
    {"position", (getter)plod__camera_get, NULL, "planet-space position", (void *)0},
    {"forward", (getter)plod__camera_get, NULL, "unit view direction (-Z)", (void *)1},
    {"up", (getter)plod__camera_get, NULL, "unit up (+Y)", (void *)2},
    {"right", (getter)plod__camera_get, NULL, "unit right (+X)", (void *)3},
    {"pixels_per_radian", (getter)plod__camera_get, NULL, "perspective scale", (void *)4},
    {"pixels_per_metre", (getter)plod__camera_get, NULL, "orthographic scale", (void *)5},
    {"planes", (getter)plod__camera_get, NULL,
     "6 inward planes (nx, ny, nz, d): n.x + d >= 0 inside", (void *)6},
    {"orthographic", (getter)plod__camera_get, NULL, "bool", (void *)7},
    {"view_window", (getter)plod__camera_get, NULL,
     "(left, right, bottom, top) at unit depth (ortho: metres)", (void *)8},
    {NULL},
};

static PyMethodDef plod__camera_methods[] = {
    {"contains", (PyCFunction)plod__camera_contains, METH_VARARGS,
     "contains(x, y, z) -> bool: point inside the view frustum"},
    {NULL},
};

static PyType_Slot plod__camera_slots[] = {
    {Py_tp_doc, "Camera(matrix_world, type='PERSP'|'ORTHO', lens=50, sensor_width=36, "
                "sensor_height=24, sensor_fit='AUTO', ortho_scale=7, shift_x=0, shift_y=0, "
                "clip_start=0.1, clip_end=1000, resolution_x=1920, resolution_y=1080, "
                "pixel_aspect_x=1, pixel_aspect_y=1): Blender camera in planet space."},
    {Py_tp_init, plod__camera_init},
    {Py_tp_new, PyType_GenericNew},
    {Py_tp_getset, plod__camera_getset},
    {Py_tp_methods, plod__camera_methods},
    {0, NULL},
};

static PyType_Spec plod__camera_spec = {
    .name = "planetlod.Camera",
    .basicsize = sizeof(plod_py_camera),
    .flags = Py_TPFLAGS_DEFAULT,
    .slots = plod__camera_slots,
};

static const plod_camera *plod__camera_arg(PyObject *obj)
{
    if (!PyObject_TypeCheck(obj, plod__camera_type)) {
        PyErr_SetString(PyExc_TypeError, "expected a planetlod.Camera");
        return NULL;
    }
    return &((plod_py_camera *)obj)->camera;
}

/* ---- Planet ------------------------------------------------------------------ */

typedef struct {
    PyObject_HEAD
    /* Owned: the planet, its refiner, detail field, normal map, mesh cache,
     * last camera, and the lock that serialises every method reading or
     * writing them: refine() and mesh() run with the GIL released, so two
     * Python threads (a render job and the viewport) could otherwise be
     * inside one refiner at once.  Taken only through plod__planet_lock,
     * which never waits holding the GIL. */
    plod_session *session;
    PyObject *heightmap;  /* the CubeMap (or TiledMap) keeping the height data alive */
    plod_height_source source; /* the session planet's source for a TiledMap */
    plod_insets *insets;       /* owned; the session planet's insets */
    plod_py_pool *mesh_pool;   /* a reference: the storage of its meshes' buffers */
} plod_py_planet;

static void plod__planet_lock(plod_py_planet *self)
{
    if (plod_session_trylock(self->session))
        return;
    Py_BEGIN_ALLOW_THREADS
    plod_session_lock(self->session);
    Py_END_ALLOW_THREADS
}

static void plod__planet_unlock(plod_py_planet *self)
{
    plod_session_unlock(self->session);
}

static const char *const plod__detail_styles[PLOD_DETAIL_STYLE_COUNT] = {"hills", "mountains",
                                                                         "craters"};

/* A number from the detail dict, if the key is there. */
static int plod__detail_number(PyObject *dict, const char *key, double *out, int *used)
{
    PyObject *v = PyDict_GetItemString(dict, key); /* borrowed */
    if (!v)
        return 0;
    (*used)++;
    double x = PyFloat_AsDouble(v);
    if (x == -1.0 && PyErr_Occurred()) {
        PyErr_Clear();
        char msg[96];
        snprintf(msg, sizeof msg, "detail['%s'] must be a number", key);
        plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "Planet", msg);
        return -1;
    }
    *out = x;
    return 0;
}

/* Planet(detail=...): None or a dict (see API.md); *enabled 0 when None or
 * enabled=False. */
static int plod__detail_arg(PyObject *obj, plod_detail_params *p, int *enabled)
{
    plod_detail_params_init(p);
    *enabled = 0;
    if (obj == Py_None)
        return 0;
    if (!PyDict_Check(obj)) {
        plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "Planet", "detail must be a dict or None");
        return -1;
    }
    int used = 0;
    *enabled = 1;
    PyObject *v = PyDict_GetItemString(obj, "enabled");
    if (v) {
        used++;
        int t = PyObject_IsTrue(v);
        if (t < 0)
            return -1;
        *enabled = t;
    }
    v = PyDict_GetItemString(obj, "style");
    if (v) {
        used++;
        const char *name = PyUnicode_Check(v) ? PyUnicode_AsUTF8AndSize(v, NULL) : NULL;
        int found = -1;
        for (int i = 0; name && i < PLOD_DETAIL_STYLE_COUNT; i++)
            if (!strcmp(name, plod__detail_styles[i]))
                found = i;
        if (found < 0) {
            PyErr_Clear();
            plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "Planet",
                                 "detail['style'] must be 'hills', 'mountains' or 'craters'");
            return -1;
        }
        p->style = (plod_detail_style)found;
    }
    v = PyDict_GetItemString(obj, "seed");
    if (v) {
        used++;
        unsigned long long seed = PyLong_Check(v) ? PyLong_AsUnsignedLongLongMask(v) : 0;
        if (!PyLong_Check(v) || PyErr_Occurred()) {
            PyErr_Clear();
            plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "Planet", "detail['seed'] must be an int");
            return -1;
        }
        p->seed = (uint64_t)seed;
    }
    if (plod__detail_number(obj, "amplitude", &p->amplitude, &used) < 0 ||
        plod__detail_number(obj, "roughness", &p->roughness, &used) < 0 ||
        plod__detail_number(obj, "largest", &p->largest, &used) < 0 ||
        plod__detail_number(obj, "smallest", &p->smallest, &used) < 0 ||
        plod__detail_number(obj, "craters", &p->craters, &used) < 0 ||
        plod__detail_number(obj, "crater_density", &p->crater_density, &used) < 0 ||
        plod__detail_number(obj, "plains", &p->plains, &used) < 0 ||
        plod__detail_number(obj, "relief", &p->relief, &used) < 0 ||
        plod__detail_number(obj, "hills", &p->hills, &used) < 0 ||
        plod__detail_number(obj, "highlands", &p->highlands, &used) < 0 ||
        plod__detail_number(obj, "fine_roughness", &p->fine_roughness, &used) < 0 ||
        plod__detail_number(obj, "fine_below", &p->fine_below, &used) < 0 ||
        plod__detail_number(obj, "hills_fine", &p->hills_fine, &used) < 0 ||
        plod__detail_number(obj, "hills_fine_below", &p->hills_fine_below, &used) < 0 ||
        plod__detail_number(obj, "hills_fine_to", &p->hills_fine_to, &used) < 0)
        return -1;
    if (used != (int)PyDict_Size(obj)) {
        plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "Planet",
                             "detail keys: enabled, style, amplitude, roughness, largest, "
                             "smallest, seed, craters, crater_density, plains, relief, hills, "
                             "highlands, fine_roughness, fine_below, hills_fine, hills_fine_below, "
                             "hills_fine_to");
        return -1;
    }
    return 0;
}

static int plod__planet_init(plod_py_planet *self, PyObject *args, PyObject *kwds)
{
    static char *kwlist[] = {"radius", "projection", "heightmap", "height_scale",
                             "sea_level", "heightmap_size", "detail", "height_offset",
                             "height_signed", "heightmap_raw", "insets", "inset_feather",
                             NULL};
    double radius;
    PyObject *proj = NULL, *heightmap = Py_None, *sea = Py_None, *detail = Py_None;
    PyObject *raw = Py_None, *insets = Py_None;
    double scale = 1.0, offset = 0.0, feather = 0.1;
    int size = 0, is_signed = 0;
    if (self->session) {
        PyErr_SetString(PyExc_RuntimeError, "Planet already initialised");
        return -1;
    }
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "d|OOdOiOdpOOd", kwlist, &radius, &proj,
                                     &heightmap, &scale, &sea, &size, &detail, &offset,
                                     &is_signed, &raw, &insets, &feather))
        return -1;
    plod_detail_params detail_params;
    int detail_on = 0;
    if (plod__detail_arg(detail, &detail_params, &detail_on) < 0)
        return -1;
    plod_py_read_options read_options;
    if (plod_py_read_options_arg(raw, is_signed, &read_options, "Planet") < 0)
        return -1;
    plod_planet planet;
    memset(&planet, 0, sizeof planet);
    planet.radius = radius;
    planet.height_scale = scale;
    planet.height_offset = offset;
    char message[256];
    if (plod_planet_check_numbers(&planet, message, sizeof message) != PLOD_OK) {
        plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "Planet", message);
        return -1;
    }
    plod_insets_destroy(self->insets);
    self->insets = NULL;
    if (plod_py_insets_arg(insets, feather, &self->insets) < 0)
        return -1;
    planet.insets = self->insets;
    planet.projection = PLOD_PROJ_QSC;
    if (proj && proj != Py_None && plod_py_projection_arg(proj, &planet.projection) < 0)
        return -1;
    if (sea != Py_None) {
        double s = PyFloat_AsDouble(sea);
        if (s == -1.0 && PyErr_Occurred())
            return -1;
        planet.has_sea_level = 1;
        planet.sea_level = s;
    }
    if (size < 0 || size > PLOD_CUBEMAP_MAX_MAP_SIZE) {
        snprintf(message, sizeof message, "heightmap_size in [0, %d]", PLOD_CUBEMAP_MAX_MAP_SIZE);
        plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "Planet", message);
        return -1;
    }
    PyObject *map = NULL;
    const plod_tiles *tiles = heightmap != Py_None ? plod_py_tiled_map_get(heightmap) : NULL;
    if (tiles) { /* out of core: sampled through the height source interface */
        if (read_options.is_signed || read_options.has_raw) {
            plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "Planet",
                                 "height_signed and heightmap_raw apply to a height map read "
                                 "from a file; give them to TiledMap");
            return -1;
        }
        self->source = plod_tiles_source(tiles);
        planet.source = &self->source;
        Py_INCREF(heightmap);
        map = heightmap;
    } else if (heightmap != Py_None) {
        if (PyUnicode_Check(heightmap) || PyBytes_Check(heightmap) ||
            PyObject_HasAttrString(heightmap, "__fspath__")) {
            PyObject *path = NULL;
            if (!PyUnicode_FSConverter(heightmap, &path))
                return -1;
            map = plod_py_cubemap_from_image(PyBytes_AsString(path),
                                             planet.projection, size, 1, &read_options);
            Py_DECREF(path);
            if (!map)
                return -1;
        } else {
            if (read_options.is_signed || read_options.has_raw) {
                plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "Planet",
                                     "height_signed and heightmap_raw apply to a height map "
                                     "read from a file, not to a CubeMap");
                return -1;
            }
            Py_INCREF(heightmap);
            map = heightmap;
        }
        plod_cubemap *cm = plod_py_cubemap_get(map);
        if (!cm) {
            Py_DECREF(map);
            return -1;
        }
        if (plod_cubemap_build_pyramid(cm) != PLOD_OK) {
            Py_DECREF(map);
            PyErr_NoMemory();
            return -1;
        }
        planet.heightmap = cm;
    }
    self->heightmap = map;
    plod_session *session = NULL;
    plod_status st;
    Py_BEGIN_ALLOW_THREADS
    st = plod_session_create(&session, &planet, detail_on ? &detail_params : NULL, message,
                             sizeof message);
    Py_END_ALLOW_THREADS
    if (st != PLOD_OK) {
        Py_CLEAR(self->heightmap);
        plod_py_raise_detail(st, "Planet", message);
        return -1;
    }
    self->session = session;
    if (!self->mesh_pool)
        self->mesh_pool = plod_py_pool_new(); /* none: meshes use malloc */
    return 0;
}

static void plod__planet_dealloc(plod_py_planet *self)
{
    plod_session_destroy(self->session);
    self->session = NULL;
    plod_insets_destroy(self->insets);
    self->insets = NULL;
    plod_py_pool_release(self->mesh_pool);
    self->mesh_pool = NULL;
    Py_CLEAR(self->heightmap);
    PyTypeObject *tp = Py_TYPE((PyObject *)self);
    plod_py_free((PyObject *)self);
    Py_DECREF(tp);
}

static int plod__planet_ready(plod_py_planet *self)
{
    if (!self->session) {
        PyErr_SetString(PyExc_RuntimeError, "Planet not initialised");
        return 0;
    }
    return 1;
}

static PyObject *plod__planet_refine(plod_py_planet *self, PyObject *args, PyObject *kwds)
{
    static char *kwlist[] = {"camera", "criterion", "max_pixel_error", "split_border",
                             "merge_border", "hysteresis", "template_level", "max_level",
                             "budget", "backface", "frustum", "skip_sea", "max_sectors",
                             "threads", "max_splits", "method", "chunk_cracks",
                             "geomipmap_tiles", "clipmap_ring_cells", NULL};
    PyObject *cam_obj;
    const char *criterion = "pixel", *method = NULL, *cracks = NULL;
    plod_method_params mp;
    plod_method_params_default(&mp);
    plod_refine_params p;
    plod_refine_params_default(&p);
    Py_ssize_t budget = 0, max_sectors = (Py_ssize_t)PLOD_DEFAULT_MAX_SECTORS, max_splits = 0;
    if (!plod__planet_ready(self))
        return NULL;
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "O|sdddpiinpppninzzii", kwlist, &cam_obj,
                                     &criterion, &p.max_pixel_error, &p.split_border,
                                     &p.merge_border, &p.hysteresis, &p.template_level,
                                     &p.max_level, &budget, &p.backface_culling,
                                     &p.frustum_culling, &p.skip_sea, &max_sectors,
                                     &p.threads, &max_splits, &method, &cracks,
                                     &mp.geomipmap_tiles, &mp.clipmap_ring_cells))
        return NULL;
    /* the LOD method: named here, checked and kept by the session */
    mp.method = method ? (plod_lod_method)plod_lod_method_from_name(method) : PLOD_LOD_HRTMR;
    if (method && (int)mp.method < 0)
        return plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "refine",
                                    "method must be 'hrtmr', 'chunked', 'geomipmap' or "
                                    "'clipmap'");
    if (cracks && strcmp(cracks, "stitch") && strcmp(cracks, "skirts"))
        return plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "refine",
                                    "chunk_cracks must be 'stitch' or 'skirts'");
    if (cracks)
        mp.chunked_skirts = !strcmp(cracks, "skirts");
    const plod_camera *cam = plod__camera_arg(cam_obj);
    if (!cam)
        return NULL;
    if (!strcmp(criterion, "pixel"))
        p.criterion = PLOD_CRITERION_PIXEL_ERROR;
    else if (!strcmp(criterion, "side_distance"))
        p.criterion = PLOD_CRITERION_SIDE_DISTANCE;
    else
        return plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "refine",
                                    "criterion must be 'pixel' or 'side_distance'");
    if (budget < 0)
        return plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "refine",
                                    "budget must be >= 0 (0 = unlimited)");
    if (max_splits < 0)
        return plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "refine",
                                    "max_splits must be >= 0 (0 = unlimited)");
    if (max_sectors < 0)
        return plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "refine", "max_sectors must be >= 12");
    p.budget = (size_t)budget;
    p.max_sectors = (size_t)max_sectors;
    p.max_splits = (size_t)max_splits;
    plod_refine_stats s;
    plod_error error = {PLOD_OK, ""};
    plod_status st;
    st = plod_session_set_method(self->session, &mp, &error);
    if (st != PLOD_OK)
        return plod_py_raise_detail(st, "refine", error.message);
    Py_BEGIN_ALLOW_THREADS
    st = plod_session_refine(self->session, cam, &p, &s, &error);
    Py_END_ALLOW_THREADS
    if (st != PLOD_OK)
        return plod_py_raise_detail(st, "refine", error.message);
    size_t vertices, triangles;
    if (mp.method == PLOD_LOD_HRTMR) {
        /* what planet.mesh(template_level) would emit for the visible sectors */
        vertices = s.sectors_after_budget * plod_template_vertex_count(p.template_level);
        triangles = s.sectors_after_budget * plod_template_triangle_count(p.template_level);
    } else {
        size_t emitted;
        plod_session_emit_bounds(self->session, p.template_level, 1, &vertices, &triangles,
                                 &emitted);
    }
    PyObject *stats = Py_BuildValue(
        "{s:n,s:n,s:n,s:n,s:n,s:n,s:n,s:d,s:d,s:i,s:O,s:O,s:I,s:K,s:K}",
        "sectors_total", (Py_ssize_t)s.sectors_total, "sectors_after_backface",
        (Py_ssize_t)s.sectors_after_backface, "sectors_after_frustum",
        (Py_ssize_t)s.sectors_after_frustum, "sectors_after_budget",
        (Py_ssize_t)s.sectors_after_budget, "sectors_sea_skipped",
        (Py_ssize_t)s.sectors_sea_skipped, "splits", (Py_ssize_t)s.splits, "merges",
        (Py_ssize_t)s.merges, "refine_us", s.refine_us, "cull_us", s.cull_us, "max_level",
        s.max_level_reached, "truncated", s.truncated ? Py_True : Py_False, "pending",
        s.pending ? Py_True : Py_False, "frame", s.frame, "vertices",
        (unsigned long long)vertices, "triangles", (unsigned long long)triangles);
    if (!stats || mp.method == PLOD_LOD_HRTMR)
        return stats;
    /* the other methods also name themselves and the state they keep */
    PyObject *name = PyUnicode_FromString(plod_lod_method_name((int)mp.method));
    PyObject *state = PyLong_FromSize_t(plod_session_method_bytes(self->session));
    int failed = !name || !state || PyDict_SetItemString(stats, "method", name) < 0 ||
                 PyDict_SetItemString(stats, "state_bytes", state) < 0;
    Py_XDECREF(name);
    Py_XDECREF(state);
    if (failed)
        Py_CLEAR(stats);
    return stats;
}

static PyObject *plod__planet_reset(plod_py_planet *self, PyObject *unused)
{
    (void)unused;
    if (!plod__planet_ready(self))
        return NULL;
    plod_session_reset(self->session);
    Py_RETURN_NONE;
}

static PyObject *plod__planet_reserve(plod_py_planet *self, PyObject *args, PyObject *kwds)
{
    static char *kwlist[] = {"sectors", NULL};
    Py_ssize_t sectors;
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "n", kwlist, &sectors))
        return NULL;
    if (sectors < 0 || (size_t)sectors > PLOD_REFINER_MAX_RESERVE)
        return plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "reserve",
                                    "sectors must be in 0..2**26");
    plod_status st;
    Py_BEGIN_ALLOW_THREADS
    st = plod_session_reserve(self->session, (size_t)sectors);
    Py_END_ALLOW_THREADS
    if (st != PLOD_OK)
        return plod_py_raise(st, "reserve");
    Py_RETURN_NONE;
}

static int plod__visible_only_arg(PyObject *args, PyObject *kwds, int *visible_only)
{
    static char *kwlist[] = {"visible_only", NULL};
    *visible_only = 1;
    return PyArg_ParseTupleAndKeywords(args, kwds, "|p", kwlist, visible_only);
}

/* kind: 0 ids, 1 levels, 2 corner directions, 3 flags, 4 height bounds;
 * visible sectors in the canonical order meshes are emitted in, all
 * sectors in storage order */
static PyObject *plod__planet_export(plod_py_planet *self, PyObject *args, PyObject *kwds,
                                     int kind)
{
    int visible_only;
    if (!plod__planet_ready(self) || !plod__visible_only_arg(args, kwds, &visible_only))
        return NULL;
    size_t count, visible;
    const plod_sector *sec = plod_refiner_sectors(plod_session_refiner(self->session), &count);
    const uint32_t *order = plod_refiner_visible(plod_session_refiner(self->session), &visible);
    size_t n = visible_only ? visible : count;
    static const char formats[] = {'Q', 'i', 'd', 'i', 'f'};
    static const size_t per[] = {1, 1, 9, 1, 2};
    void *data;
    PyObject *buf = plod_py_buffer_new(formats[kind], n * per[kind], &data);
    if (!buf)
        return NULL;
    for (size_t k = 0; k < n; k++) {
        size_t i = visible_only ? order[k] : k;
        switch (kind) {
        case 0: ((uint64_t *)data)[k] = sec[i].id; break;
        case 1: ((int32_t *)data)[k] = sec[i].level; break;
        case 2: plod_sector_corners(plod_session_planet(self->session), &sec[i], (double(*)[3])((double *)data + 9 * k)); break;
        case 3: ((int32_t *)data)[k] = sec[i].flags; break;
        default:
            ((float *)data)[2 * k] = sec[i].height_min;
            ((float *)data)[2 * k + 1] = sec[i].height_max;
        }
    }
    return buf;
}

static PyObject *plod__planet_sector_ids(plod_py_planet *self, PyObject *a, PyObject *k)
{
    return plod__planet_export(self, a, k, 0);
}
static PyObject *plod__planet_sector_levels(plod_py_planet *self, PyObject *a, PyObject *k)
{
    return plod__planet_export(self, a, k, 1);
}
static PyObject *plod__planet_sector_corners(plod_py_planet *self, PyObject *a, PyObject *k)
{
    return plod__planet_export(self, a, k, 2);
}
static PyObject *plod__planet_sector_flags(plod_py_planet *self, PyObject *a, PyObject *k)
{
    return plod__planet_export(self, a, k, 3);
}
static PyObject *plod__planet_sector_heights(plod_py_planet *self, PyObject *a, PyObject *k)
{
    return plod__planet_export(self, a, k, 4);
}

static PyObject *plod__planet_check(plod_py_planet *self, PyObject *unused)
{
    (void)unused;
    if (!plod__planet_ready(self))
        return NULL;
    return PyBool_FromLong(plod_refiner_check(plod_session_refiner(self->session)) == PLOD_OK);
}

static PyObject *plod__planet_sectors(plod_py_planet *self, PyObject *unused)
{
    (void)unused;
    if (!plod__planet_ready(self))
        return NULL;
    size_t count;
    const plod_sector *sec = plod_refiner_sectors(plod_session_refiner(self->session), &count);
    void *data;
    PyObject *buf = plod_py_buffer_new('B', count * sizeof *sec, &data);
    if (buf && count)
        memcpy(data, sec, count * sizeof *sec);
    return buf;
}

static PyObject *plod__planet_recommended_clip(plod_py_planet *self, PyObject *args)
{
    PyObject *cam_obj;
    if (!plod__planet_ready(self) || !PyArg_ParseTuple(args, "O", &cam_obj))
        return NULL;
    const plod_camera *cam = plod__camera_arg(cam_obj);
    if (!cam)
        return NULL;
    double a, b;
    plod_recommended_clip(plod_session_planet(self->session), cam, &a, &b);
    return Py_BuildValue("(dd)", a, b);
}

static PyObject *plod__planet_height(plod_py_planet *self, PyObject *args)
{
    double d[3];
    if (!plod__planet_ready(self) || !PyArg_ParseTuple(args, "ddd", &d[0], &d[1], &d[2]))
        return NULL;
    double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (!isfinite(len) || !(len > 0))
        return plod_py_raise_detail(PLOD_ERR_BAD_COORD, "height",
                                    "direction must be finite and non-zero");
    return PyFloat_FromDouble(plod_planet_height(plod_session_planet(self->session), d));
}

static PyObject *plod__planet_texel_size(plod_py_planet *self, PyObject *args)
{
    double d[3];
    if (!plod__planet_ready(self) || !PyArg_ParseTuple(args, "ddd", &d[0], &d[1], &d[2]))
        return NULL;
    double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (!isfinite(len) || !(len > 0))
        return plod_py_raise_detail(PLOD_ERR_BAD_COORD, "texel_size",
                                    "direction must be finite and non-zero");
    d[0] /= len, d[1] /= len, d[2] /= len;
    return PyFloat_FromDouble(plod_planet_texel_size(plod_session_planet(self->session), d));
}

static PyObject *plod__planet_height_range(plod_py_planet *self, PyObject *unused)
{
    (void)unused;
    if (!plod__planet_ready(self))
        return NULL;
    double a, b;
    plod_planet_height_range(plod_session_planet(self->session), &a, &b);
    return Py_BuildValue("(dd)", a, b);
}

/* template_level=None means the level of the last refine. */
static int plod__template_level_arg(const plod_py_planet *self, PyObject *level_obj, int *level)
{
    *level = plod_session_refine_params(self->session)->template_level;
    if (level_obj == Py_None)
        return 0;
    long value = PyLong_AsLong(level_obj);
    if (value == -1 && PyErr_Occurred())
        return -1;
    *level = value < INT_MIN ? INT_MIN : value > INT_MAX ? INT_MAX : (int)value;
    return 0;
}

/* Once per planet (the map and the planet never change); then each vertex
 * samples its normal instead of differencing four heights. */
static int plod__ensure_normalmap(plod_py_planet *self, const char *context, int threads)
{
    plod_status st;
    Py_BEGIN_ALLOW_THREADS
    st = plod_session_build_normals(self->session, threads);
    Py_END_ALLOW_THREADS
    if (st != PLOD_OK) {
        plod_py_raise(st, context);
        return -1;
    }
    return 0;
}

static PyObject *plod__planet_surface(plod_py_planet *self, PyObject *args, PyObject *kwds)
{
    static char *kwlist[] = {"directions", NULL};
    PyObject *obj;
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "O", kwlist, &obj))
        return NULL;
    size_t count;
    double *dirs = plod_py_doubles(obj, &count, "directions");
    if (!dirs)
        return NULL;
    if (count % 3) {
        free(dirs);
        return plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "surface",
                                    "directions must hold 3 floats per point");
    }
    size_t n = count / 3;
    for (size_t i = 0; i < n; i++) {
        double *d = dirs + 3 * i;
        double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        if (!isfinite(len) || !(len > 0)) {
            free(dirs);
            return plod_py_raise_detail(PLOD_ERR_BAD_COORD, "surface",
                                        "every direction must be finite and non-zero");
        }
        d[0] /= len, d[1] /= len, d[2] /= len;
    }
    if (plod__ensure_normalmap(self, "surface (normal map)", 1) < 0) {
        free(dirs);
        return NULL;
    }
    double *heights, *normals;
    PyObject *h = plod_py_buffer_new('d', n, (void **)&heights);
    PyObject *nb = h ? plod_py_buffer_new('d', 3 * n, (void **)&normals) : NULL;
    if (!nb) {
        Py_XDECREF(h);
        free(dirs);
        return NULL;
    }
    Py_BEGIN_ALLOW_THREADS
    plod_planet_surface_n(plod_session_planet(self->session), n, dirs, heights, normals);
    Py_END_ALLOW_THREADS
    free(dirs);
    return Py_BuildValue("(NN)", h, nb);
}

static PyObject *plod__planet_mesh(plod_py_planet *self, PyObject *args, PyObject *kwds)
{
    static char *kwlist[] = {"template_level", "morph", "threads", "visible_only", "cache",
                             "changed_only", NULL};
    PyObject *level_obj = Py_None, *morph_obj = Py_False;
    int morph, threads = 2, visible_only = 1, use_cache = 1, changed_only = 0;
    if (!plod__planet_ready(self))
        return NULL;
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "|OOippp", kwlist, &level_obj, &morph_obj,
                                     &threads, &visible_only, &use_cache, &changed_only))
        return NULL;
    if ((morph = PyObject_IsTrue(morph_obj)) < 0)
        return NULL;
    int level;
    if (plod__template_level_arg(self, level_obj, &level) < 0)
        return NULL;
    if (threads >= 1 && threads <= PLOD_MESH_MAX_THREADS &&
        plod__ensure_normalmap(self, "mesh (normal map)", threads) < 0)
        return NULL; /* (a bad thread count is reported by the emission) */
    return plod_py_mesh_emit(self->session, self->mesh_pool, level, morph, threads,
                             visible_only, use_cache, changed_only);
}

static PyObject *plod__planet_instances(plod_py_planet *self, PyObject *args, PyObject *kwds)
{
    static char *kwlist[] = {"template_level", NULL};
    PyObject *level_obj = Py_None;
    if (!plod__planet_ready(self))
        return NULL;
    if (!PyArg_ParseTupleAndKeywords(args, kwds, "|O", kwlist, &level_obj))
        return NULL;
    int level;
    if (plod__template_level_arg(self, level_obj, &level) < 0)
        return NULL;
    if (plod_session_method(self->session)->method != PLOD_LOD_HRTMR)
        return plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "instances",
                                    "instances() draws HRTMR's sectors: refine with "
                                    "method='hrtmr' first");
    return plod_py_instances(self->session, level);
}

static PyObject *plod__planet_get(plod_py_planet *self, void *closure)
{
    if (!plod__planet_ready(self))
        return NULL;
    size_t count;
    const plod_planet *planet = plod_session_planet(self->session);
    const plod_sector *sec = plod_refiner_sectors(plod_session_refiner(self->session), &count);
    switch ((int)(intptr_t)closure) {
    case 0: return PyLong_FromSize_t(count);
    case 7: return PyLong_FromSize_t(plod_refiner_memory_bytes(plod_session_refiner(self->session)));
    case 8: {
        plod_mesh_cache_stats st;
        plod_session_cache_stats(self->session, &st);
        return Py_BuildValue("{s:n,s:n,s:n,s:n,s:n,s:K}", "sectors", (Py_ssize_t)st.sectors,
                             "bytes", (Py_ssize_t)st.bytes, "max_bytes",
                             (Py_ssize_t)st.max_bytes, "hits",
                             (Py_ssize_t)st.hits, "misses", (Py_ssize_t)st.misses,
                             "emissions", (unsigned long long)st.emissions);
    }
    case 1: {
        size_t n = 0;
        for (size_t i = 0; i < count; i++)
            n += (sec[i].flags & PLOD_SECTOR_VISIBLE) != 0;
        return PyLong_FromSize_t(n);
    }
    case 2: return PyFloat_FromDouble(planet->radius);
    case 3: return PyUnicode_FromString(plod_projection_name(planet->projection));
    case 4: return PyFloat_FromDouble(planet->height_scale);
    case 10: return PyFloat_FromDouble(planet->height_offset);
    case 5:
        if (!planet->has_sea_level)
            Py_RETURN_NONE;
        return PyFloat_FromDouble(planet->sea_level);
    case 9: {
        if (!planet->detail)
            Py_RETURN_NONE;
        const plod_detail_params *p = plod_detail_get_params(planet->detail);
        int octaves = plod_detail_octave_count(planet->detail);
        return Py_BuildValue("{s:O,s:s,s:d,s:d,s:d,s:d,s:K,s:d,s:d,s:d,s:d,s:d,s:d,s:d,s:d,"
                             "s:d,s:d,s:d,s:i,s:d}",
                             "enabled", Py_True, "style", plod__detail_styles[p->style],
                             "amplitude", p->amplitude, "roughness", p->roughness, "largest",
                             p->largest, "smallest", p->smallest, "seed",
                             (unsigned long long)p->seed, "craters", p->craters,
                             "crater_density", p->crater_density, "plains", p->plains,
                             "relief", p->relief, "hills", p->hills, "highlands", p->highlands,
                             "fine_roughness", p->fine_roughness, "fine_below", p->fine_below,
                             "hills_fine", p->hills_fine, "hills_fine_below",
                             p->hills_fine_below, "hills_fine_to", p->hills_fine_to, "octaves",
                             octaves, "finest_wavelength",
                             octaves ? plod_detail_wavelength(planet->detail, octaves - 1) : 0.0);
    }
    case 6:
    default:
        if (!self->heightmap)
            Py_RETURN_NONE;
        Py_INCREF(self->heightmap);
        return self->heightmap;
    }
}

/* ---- locked entry points (see plod_py_planet.lock) ---------------------------- */

typedef PyObject *(*plod__kw_method)(plod_py_planet *, PyObject *, PyObject *);
typedef PyObject *(*plod__no_arg_method)(plod_py_planet *, PyObject *);

static PyObject *plod__locked_kw(plod__kw_method fn, plod_py_planet *self, PyObject *args,
                                 PyObject *kwds)
{
    if (!plod__planet_ready(self))
        return NULL;
    plod__planet_lock(self);
    PyObject *result = fn(self, args, kwds);
    plod__planet_unlock(self);
    return result;
}

static PyObject *plod__locked_no_arg(plod__no_arg_method fn, plod_py_planet *self,
                                     PyObject *unused)
{
    if (!plod__planet_ready(self))
        return NULL;
    plod__planet_lock(self);
    PyObject *result = fn(self, unused);
    plod__planet_unlock(self);
    return result;
}

#define PLOD__LOCKED_KW(name)                                                         \
    static PyObject *name##_locked(plod_py_planet *self, PyObject *a, PyObject *k)   \
    {                                                                                 \
        return plod__locked_kw(name, self, a, k);                                     \
    }
#define PLOD__LOCKED_NO_ARG(name)                                                     \
    static PyObject *name##_locked(plod_py_planet *self, PyObject *unused)           \
    {                                                                                 \
        return plod__locked_no_arg(name, self, unused);                               \
    }

PLOD__LOCKED_KW(plod__planet_refine)
PLOD__LOCKED_KW(plod__planet_sector_ids)
PLOD__LOCKED_KW(plod__planet_sector_levels)
PLOD__LOCKED_KW(plod__planet_sector_corners)
PLOD__LOCKED_KW(plod__planet_sector_flags)
PLOD__LOCKED_KW(plod__planet_sector_heights)
PLOD__LOCKED_KW(plod__planet_mesh)
PLOD__LOCKED_KW(plod__planet_surface)
PLOD__LOCKED_KW(plod__planet_reserve)
PLOD__LOCKED_KW(plod__planet_instances)
PLOD__LOCKED_NO_ARG(plod__planet_reset)
PLOD__LOCKED_NO_ARG(plod__planet_check)
PLOD__LOCKED_NO_ARG(plod__planet_sectors)

static PyObject *plod__planet_get_locked(plod_py_planet *self, void *closure)
{
    if (!plod__planet_ready(self))
        return NULL;
    plod__planet_lock(self);
    PyObject *result = plod__planet_get(self, closure);
    plod__planet_unlock(self);
    return result;
}

static PyObject *plod__planet_cache_bytes_get_locked(plod_py_planet *self, void *closure)
{
    (void)closure;
    if (!plod__planet_ready(self))
        return NULL;
    plod__planet_lock(self);
    size_t bytes = plod_session_cache_max_bytes(self->session);
    plod__planet_unlock(self);
    return PyLong_FromSize_t(bytes);
}

static int plod__planet_cache_bytes_set_locked(plod_py_planet *self, PyObject *value,
                                               void *closure)
{
    (void)closure;
    if (!plod__planet_ready(self))
        return -1;
    if (!value) {
        PyErr_SetString(PyExc_AttributeError, "mesh_cache_max_bytes cannot be deleted");
        return -1;
    }
    size_t bytes = PyLong_AsSize_t(value);
    if (bytes == (size_t)-1 && PyErr_Occurred()) {
        PyErr_Clear();
        plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "mesh_cache_max_bytes",
                             "must be an integer >= 0");
        return -1;
    }
    plod__planet_lock(self);
    plod_session_set_cache_max_bytes(self->session, bytes);
    plod__planet_unlock(self);
    return 0;
}

static PyGetSetDef plod__planet_getset[] = {
    {"sector_count", (getter)plod__planet_get_locked, NULL, "leaf sectors", (void *)0},
    {"visible_count", (getter)plod__planet_get_locked, NULL, "visible leaf sectors", (void *)1},
    {"radius", (getter)plod__planet_get_locked, NULL, "metres", (void *)2},
    {"projection", (getter)plod__planet_get_locked, NULL, "projection name", (void *)3},
    {"height_scale", (getter)plod__planet_get_locked, NULL, "metres per height unit", (void *)4},
    {"sea_level", (getter)plod__planet_get_locked, NULL, "metres or None", (void *)5},
    {"height_offset", (getter)plod__planet_get_locked, NULL,
     "metres added to every map height (datum)", (void *)10},
    {"heightmap", (getter)plod__planet_get_locked, NULL, "CubeMap or None", (void *)6},
    {"detail", (getter)plod__planet_get_locked, NULL,
     "the detail field's parameters (dict, with its octave count and finest wavelength) "
     "or None", (void *)9},
    {"memory_bytes", (getter)plod__planet_get_locked, NULL,
     "bytes held by the refiner (sectors, bounds, adjacency, internal nodes)", (void *)7},
    {"mesh_cache_info", (getter)plod__planet_get_locked, NULL,
     "mesh() sector cache: dict(sectors, bytes, max_bytes, hits, misses, emissions); hits "
     "and misses of the last cached mesh(), emissions: cached mesh() calls so far", (void *)8},
    {"mesh_cache_max_bytes", (getter)plod__planet_cache_bytes_get_locked,
     (setter)plod__planet_cache_bytes_set_locked,
     "budget of mesh()'s sector cache (bytes, default 256 MiB; 0 disables it)", NULL},
    {NULL},
};

static PyMethodDef plod__planet_methods[] = {
    {"refine", (PyCFunction)(void (*)(void))plod__planet_refine_locked, METH_VARARGS | METH_KEYWORDS,
     "refine(camera, criterion='pixel', max_pixel_error=1.0, split_border=0.5, "
     "merge_border=0.25, hysteresis=False, template_level=4, max_level=48, budget=0, "
     "backface=True, frustum=True, skip_sea=False, max_sectors=1<<20, threads=1) -> dict"},
    {"reset", (PyCFunction)(void (*)(void))plod__planet_reset_locked, METH_NOARGS, "back to the base sectors"},
    {"check_invariants", (PyCFunction)(void (*)(void))plod__planet_check_locked, METH_NOARGS,
     "check_invariants() -> bool: internal adjacency/tree invariants hold (tests)"},
    {"sectors", (PyCFunction)(void (*)(void))plod__planet_sectors_locked, METH_NOARGS,
     "raw plod_sector records (SECTOR_SIZE bytes each), all leaves"},
    {"sector_ids", (PyCFunction)(void (*)(void))plod__planet_sector_ids_locked,
     METH_VARARGS | METH_KEYWORDS, "sector_ids(visible_only=True) -> Buffer('Q')"},
    {"sector_levels", (PyCFunction)(void (*)(void))plod__planet_sector_levels_locked,
     METH_VARARGS | METH_KEYWORDS, "sector_levels(visible_only=True) -> Buffer('i')"},
    {"sector_corners", (PyCFunction)(void (*)(void))plod__planet_sector_corners_locked,
     METH_VARARGS | METH_KEYWORDS,
     "sector_corners(visible_only=True) -> Buffer('d'), 9 per sector: unit corner "
     "directions, counter-clockwise from outside, corner 1 the right-angle apex"},
    {"sector_flags", (PyCFunction)(void (*)(void))plod__planet_sector_flags_locked,
     METH_VARARGS | METH_KEYWORDS,
     "sector_flags(visible_only=False) -> Buffer('i'): 1 visible, 2 beyond horizon, "
     "4 outside frustum, 8 over budget, 16 sea"},
    {"sector_heights", (PyCFunction)(void (*)(void))plod__planet_sector_heights_locked,
     METH_VARARGS | METH_KEYWORDS,
     "sector_heights(visible_only=True) -> Buffer('f'), (min, max) metres per sector"},
    {"recommended_clip", (PyCFunction)plod__planet_recommended_clip, METH_VARARGS,
     "recommended_clip(camera) -> (clip_start, clip_end)"},
    {"height", (PyCFunction)plod__planet_height, METH_VARARGS, "height(x, y, z) -> metres"},
    {"texel_size", (PyCFunction)plod__planet_texel_size, METH_VARARGS,
     "texel_size(x, y, z) -> metres per texel of the height data at a direction (inf "
     "without data)"},
    {"height_range", (PyCFunction)plod__planet_height_range, METH_NOARGS,
     "height_range() -> (min, max) metres"},
    {"mesh", (PyCFunction)(void (*)(void))plod__planet_mesh_locked, METH_VARARGS | METH_KEYWORDS,
     "mesh(template_level=None, morph=False, threads=2, visible_only=True, cache=True, "
     "changed_only=False) -> Mesh; with cache, sectors kept from the previous mesh() are "
     "copied, not recomputed (identical output); changed_only leaves out the sectors whose "
     "output the previous mesh() already gave (mesh.sector_ids names those emitted)"},
    {"reserve", (PyCFunction)(void (*)(void))plod__planet_reserve_locked,
     METH_VARARGS | METH_KEYWORDS,
     "reserve(sectors): allocate (and touch) room for this many sectors now, so that "
     "refine() does not grow its arrays mid-flight; never shrinks"},
    {"surface", (PyCFunction)(void (*)(void))plod__planet_surface_locked,
     METH_VARARGS | METH_KEYWORDS,
     "surface(directions) -> (heights, normals): for 3 n floats (any lengths), n heights in "
     "metres ('d') and n unit surface normals (3 n 'd'), as the mesh vertices sample them"},
    {"instances", (PyCFunction)(void (*)(void))plod__planet_instances_locked,
     METH_VARARGS | METH_KEYWORDS, "instances(template_level=None) -> dict"},
    {NULL},
};

static PyType_Slot plod__planet_slots[] = {
    {Py_tp_doc, "Planet(radius, projection='qsc', heightmap=None, height_scale=1.0, "
                "sea_level=None, heightmap_size=0, height_offset=0.0, height_signed=False, "
                "heightmap_raw=None): a planet refined with HRTMR; heights = map value * "
                "height_scale + height_offset."},
    {Py_tp_init, plod__planet_init},
    {Py_tp_new, PyType_GenericNew},
    {Py_tp_dealloc, plod__planet_dealloc},
    {Py_tp_getset, plod__planet_getset},
    {Py_tp_methods, plod__planet_methods},
    {0, NULL},
};

static PyType_Spec plod__planet_spec = {
    .name = "planetlod.Planet",
    .basicsize = sizeof(plod_py_planet),
    .flags = Py_TPFLAGS_DEFAULT,
    .slots = plod__planet_slots,
};

int plod_py_init_planet(PyObject *module)
{
    PyObject *cam = PyType_FromSpec(&plod__camera_spec);
    if (!cam)
        return -1;
    plod__camera_type = (PyTypeObject *)cam;
    if (PyModule_AddObject(module, "Camera", cam) < 0) {
        Py_DECREF(cam);
        return -1;
    }
    Py_INCREF(cam); /* the module's reference plus ours */
    PyObject *planet = PyType_FromSpec(&plod__planet_spec);
    if (!planet)
        return -1;
    PyObject *size = PyLong_FromSize_t(sizeof(plod_sector));
    if (!size || PyObject_SetAttrString(planet, "SECTOR_SIZE", size) < 0) {
        Py_XDECREF(size);
        Py_DECREF(planet);
        return -1;
    }
    Py_DECREF(size);
    if (PyModule_AddObject(module, "Planet", planet) < 0) {
        Py_DECREF(planet);
        return -1;
    }
    return 0;
}
