/* py_mesh.c -- Python bindings of the mesh stage: the planetlod.Mesh result
 * type, Planet.mesh() / Planet.instances() over the planet's session, and
 * a test-only entry point emitting explicit corner triangles.
 */
#include "pyplanetlod.h"

#include <assert.h>
#include <math.h>
#include <stddef.h>
#include <structmember.h>

/* ---- planetlod.Mesh ------------------------------------------------------ */

typedef struct plod_py_mesh {
    PyObject_HEAD
    PyObject *origin;        /* tuple of 3 floats */
    PyObject *positions, *normals, *uv, *triangles, *sector_level, *face, *morph, *detail;
    PyObject *sector_ids;
    Py_ssize_t vertex_count, triangle_count, sector_count;
    int template_level;
} plod_py_mesh;

static PyTypeObject *plod_py_mesh_type; /* created once at module init */

static int plod__mesh_traverse(plod_py_mesh *self, visitproc visit, void *arg)
{
    Py_VISIT(self->origin);
    Py_VISIT(self->positions);
    Py_VISIT(self->normals);
    Py_VISIT(self->uv);
    Py_VISIT(self->triangles);
    Py_VISIT(self->sector_level);
    Py_VISIT(self->face);
    Py_VISIT(self->morph);
    Py_VISIT(self->detail);
    Py_VISIT(self->sector_ids);
    Py_VISIT(Py_TYPE((PyObject *)self));
    return 0;
}

static int plod__mesh_clear(plod_py_mesh *self)
{
    Py_CLEAR(self->origin);
    Py_CLEAR(self->positions);
    Py_CLEAR(self->normals);
    Py_CLEAR(self->uv);
    Py_CLEAR(self->triangles);
    Py_CLEAR(self->sector_level);
    Py_CLEAR(self->face);
    Py_CLEAR(self->morph);
    Py_CLEAR(self->detail);
    Py_CLEAR(self->sector_ids);
    return 0;
}

static void plod__mesh_dealloc(plod_py_mesh *self)
{
    PyTypeObject *type = Py_TYPE((PyObject *)self);
    PyObject_GC_UnTrack(self);
    plod__mesh_clear(self);
    plod_py_free((PyObject *)self);
    Py_DECREF(type);
}

static PyObject *plod__mesh_repr(plod_py_mesh *self)
{
    return PyUnicode_FromFormat("<planetlod.Mesh %zd vertices, %zd triangles, %zd sectors, "
                                "template level %d>", self->vertex_count,
                                self->triangle_count, self->sector_count,
                                self->template_level);
}

static PyMemberDef plod__mesh_members[] = {
    {"origin", T_OBJECT_EX, offsetof(plod_py_mesh, origin), READONLY,
     "float64 surface point nearest the camera; positions are relative to it"},
    {"positions", T_OBJECT_EX, offsetof(plod_py_mesh, positions), READONLY,
     "Buffer('f', 3*V), relative to origin"},
    {"normals", T_OBJECT_EX, offsetof(plod_py_mesh, normals), READONLY,
     "Buffer('f', 3*V), unit, from the height field"},
    {"uv", T_OBJECT_EX, offsetof(plod_py_mesh, uv), READONLY,
     "Buffer('f', 2*V), equirectangular, unwrapped per sector"},
    {"triangles", T_OBJECT_EX, offsetof(plod_py_mesh, triangles), READONLY,
     "Buffer('i', 3*T), counter-clockwise seen from outside"},
    {"sector_level", T_OBJECT_EX, offsetof(plod_py_mesh, sector_level), READONLY,
     "Buffer('i', T): bisection level of each triangle's sector"},
    {"face", T_OBJECT_EX, offsetof(plod_py_mesh, face), READONLY,
     "Buffer('i', T): cube face of each triangle's sector"},
    {"morph", T_OBJECT_EX, offsetof(plod_py_mesh, morph), READONLY,
     "Buffer('f', V): applied geomorph factor (0 when off)"},
    {"detail", T_OBJECT_EX, offsetof(plod_py_mesh, detail), READONLY,
     "Buffer('f', V): the detail field's part of each vertex's height (metres; 0 "
     "without detail and on the sea)"},
    {"sector_ids", T_OBJECT_EX, offsetof(plod_py_mesh, sector_ids), READONLY,
     "Buffer('Q', S): each emitted sector's id (planet.sector_ids), in emission order"},
    {"vertex_count", T_PYSSIZET, offsetof(plod_py_mesh, vertex_count), READONLY, NULL},
    {"triangle_count", T_PYSSIZET, offsetof(plod_py_mesh, triangle_count), READONLY, NULL},
    {"sector_count", T_PYSSIZET, offsetof(plod_py_mesh, sector_count), READONLY, NULL},
    {"template_level", T_INT, offsetof(plod_py_mesh, template_level), READONLY, NULL},
    {NULL, 0, 0, 0, NULL}
};

static PyType_Slot plod__mesh_slots[] = {
    {Py_tp_dealloc, plod__mesh_dealloc},
    {Py_tp_traverse, plod__mesh_traverse},
    {Py_tp_clear, plod__mesh_clear},
    {Py_tp_repr, plod__mesh_repr},
    {Py_tp_members, plod__mesh_members},
    {Py_tp_doc, "Visible sectors emitted as flat buffers (see planet.mesh())."},
    {0, NULL}
};

static PyType_Spec plod__mesh_spec = {
    "planetlod.Mesh", sizeof(plod_py_mesh), 0,
    Py_TPFLAGS_DEFAULT | Py_TPFLAGS_HAVE_GC, plod__mesh_slots
};

static PyObject *plod__origin_tuple(const double origin[3])
{
    return Py_BuildValue("(ddd)", origin[0], origin[1], origin[2]);
}

/* One emission into caller-sized buffers (plod_mesh_emit's contract). */
typedef plod_status (*plod__emit_fn)(const void *context, const plod_mesh_buffers *out,
                                     size_t *vertex_count, size_t *triangle_count);
/* One instanced emission (plod_mesh_instances' contract). */
typedef plod_status (*plod__instances_fn)(const void *context, float *corners, float *levels,
                                          float *morph, size_t *instance_count);

/* Emits at most `sectors` sectors through `emit` into a new Mesh (its
 * buffers cut to what was emitted, their storage from `pool`); the GIL is
 * released meanwhile. */
static PyObject *plod__mesh_build(const plod_mesh_params *params, size_t sectors, size_t vb,
                                  size_t tb, int whole_patches, plod__emit_fn emit,
                                  const void *context, plod_py_pool *pool)
{
    if (sectors > 0 && (vb == 0 || tb == 0))
        return plod_py_raise_detail(PLOD_ERR_NO_MEMORY, "mesh",
                                    "too many vertices for int32 indices; lower "
                                    "template_level or the sector count");
    plod_py_mesh *mesh = PyObject_GC_New(plod_py_mesh, plod_py_mesh_type);
    if (!mesh)
        return NULL;
    mesh->origin = mesh->positions = mesh->normals = mesh->uv = NULL;
    mesh->triangles = mesh->sector_level = mesh->face = mesh->morph = mesh->detail = NULL;
    mesh->sector_ids = NULL;
    mesh->vertex_count = mesh->triangle_count = 0;
    mesh->sector_count = (Py_ssize_t)sectors;
    mesh->template_level = params->template_level;
    PyObject_GC_Track(mesh);

    /* Every item gets written by the emitter: no zero fill.  The pool then
     * holds as much as this mesh takes, for the next: the buffers below, 10
     * floats a vertex (positions 3, normals 3, uv 2, morph, detail), 5 ints
     * a triangle (3 indices, level, face) and an id a sector. */
    plod_mesh_buffers out;
    plod_py_pool_keep(pool, 4 * (10 * vb + 5 * tb) + 8 * sectors);
    mesh->positions = plod_py_buffer_pooled(pool, 'f', 3 * vb, (void **)&out.positions);
    mesh->normals = plod_py_buffer_pooled(pool, 'f', 3 * vb, (void **)&out.normals);
    mesh->uv = plod_py_buffer_pooled(pool, 'f', 2 * vb, (void **)&out.uv);
    mesh->morph = plod_py_buffer_pooled(pool, 'f', vb, (void **)&out.morph);
    mesh->triangles = plod_py_buffer_pooled(pool, 'i', 3 * tb, (void **)&out.triangles);
    mesh->sector_level = plod_py_buffer_pooled(pool, 'i', tb, (void **)&out.sector_level);
    mesh->face = plod_py_buffer_pooled(pool, 'i', tb, (void **)&out.face);
    mesh->detail = plod_py_buffer_pooled(pool, 'f', vb, (void **)&out.detail);
    mesh->sector_ids = plod_py_buffer_pooled(pool, 'Q', sectors, (void **)&out.keys);
    mesh->origin = plod__origin_tuple(params->origin);
    if (!mesh->positions || !mesh->normals || !mesh->uv || !mesh->morph ||
        !mesh->triangles || !mesh->sector_level || !mesh->face || !mesh->detail ||
        !mesh->sector_ids || !mesh->origin) {
        Py_DECREF(mesh);
        return NULL;
    }
    size_t vertices = 0, triangles = 0;
    plod_status st;
    Py_BEGIN_ALLOW_THREADS
    st = emit(context, &out, &vertices, &triangles);
    Py_END_ALLOW_THREADS
    if (st != PLOD_OK) {
        Py_DECREF(mesh);
        return plod_py_raise(st, "mesh");
    }
    mesh->vertex_count = (Py_ssize_t)vertices;
    mesh->triangle_count = (Py_ssize_t)triangles;
    /* whole_patches: every patch emitted, with as many vertices as it uses */
    size_t emitted = whole_patches
                         ? sectors
                         : vertices / plod_template_vertex_count(params->template_level);
    mesh->sector_count = (Py_ssize_t)emitted;
    if ((emitted < sectors || vertices < vb || triangles < tb) &&
        (plod_py_buffer_truncate(mesh->positions, 3 * vertices) < 0 ||
         plod_py_buffer_truncate(mesh->normals, 3 * vertices) < 0 ||
         plod_py_buffer_truncate(mesh->uv, 2 * vertices) < 0 ||
         plod_py_buffer_truncate(mesh->morph, vertices) < 0 ||
         plod_py_buffer_truncate(mesh->detail, vertices) < 0 ||
         plod_py_buffer_truncate(mesh->triangles, 3 * triangles) < 0 ||
         plod_py_buffer_truncate(mesh->sector_level, triangles) < 0 ||
         plod_py_buffer_truncate(mesh->face, triangles) < 0 ||
         plod_py_buffer_truncate(mesh->sector_ids, emitted) < 0)) {
        Py_DECREF(mesh);
        return NULL;
    }
    return (PyObject *)mesh;
}

/* Template barycentrics/triangles and per-sector instance data as a dict. */
static PyObject *plod__instances_build(const plod_mesh_params *params, size_t sectors,
                                       plod__instances_fn emit, const void *context)
{
    int level = params->template_level;
    float *bary, *corners, *levels, *morph;
    int32_t *tris;
    PyObject *dict = PyDict_New();
    if (!dict)
        return NULL;
    PyObject *items[7] = {
        plod_py_buffer_new('f', 3 * plod_template_vertex_count(level), (void **)&bary),
        plod_py_buffer_new('i', 3 * plod_template_triangle_count(level), (void **)&tris),
        plod_py_buffer_new('f', 9 * sectors, (void **)&corners),
        plod_py_buffer_new('f', sectors, (void **)&levels),
        plod_py_buffer_new('f', sectors, (void **)&morph),
        plod__origin_tuple(params->origin),
        PyLong_FromLong(level)};
    static const char *names[7] = {"template_barycentrics", "template_triangles",
                                   "corners", "levels", "morph", "origin",
                                   "template_level"};
    int failed = 0;
    for (int i = 0; i < 7; i++) {
        if (!items[i] || PyDict_SetItemString(dict, names[i], items[i]) < 0)
            failed = 1;
        Py_XDECREF(items[i]);
    }
    if (failed) {
        Py_DECREF(dict);
        return NULL;
    }
    plod_status st = plod_template_barycentrics(bary, level);
    if (st == PLOD_OK)
        st = plod_template_triangles(tris, level);
    size_t written = 0;
    if (st == PLOD_OK)
        st = emit(context, corners, levels, morph, &written);
    if (st != PLOD_OK) {
        Py_DECREF(dict);
        return plod_py_raise(st, "instances");
    }
    assert(written == sectors);
    return dict;
}

/* ---- Planet.mesh() / Planet.instances(): through the planet's session ------ */

typedef struct plod__session_emission {
    plod_session *session;
    plod_mesh_params params;
    int visible_only, use_cache;
} plod__session_emission;

static plod_status plod__session_emit(const void *context, const plod_mesh_buffers *out,
                                      size_t *vertex_count, size_t *triangle_count)
{
    const plod__session_emission *e = context;
    return plod_session_emit(e->session, &e->params, e->visible_only, e->use_cache, out,
                             vertex_count, triangle_count);
}

static plod_status plod__session_instances(const void *context, float *corners,
                                           float *levels, float *morph,
                                           size_t *instance_count)
{
    const plod__session_emission *e = context;
    return plod_session_instances(e->session, &e->params, corners, levels, morph,
                                  instance_count);
}

static int plod__emission_args(int template_level, int threads)
{
    if (template_level < 0 || template_level > PLOD_MAX_TEMPLATE_LEVEL) {
        plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "mesh",
                             "template_level must be in 0..7");
        return -1;
    }
    if (threads < 1 || threads > PLOD_MESH_MAX_THREADS) {
        plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "mesh", "threads must be in 1..64");
        return -1;
    }
    return 0;
}

PyObject *plod_py_mesh_emit(plod_session *session, plod_py_pool *pool, int template_level,
                            int morph, int threads, int visible_only, int use_cache,
                            int changed_only)
{
    if (plod__emission_args(template_level, threads) < 0)
        return NULL;
    if (changed_only && (morph || !use_cache))
        return plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "mesh",
                                    "changed_only needs cache=True and morph=False");
    plod__session_emission e = {session, {0}, visible_only, use_cache};
    plod_session_mesh_params(session, template_level, morph, threads, &e.params);
    e.params.changed_only = changed_only;
    size_t vb, tb, sectors;
    plod_session_emit_bounds(session, template_level, visible_only, &vb, &tb, &sectors);
    int patches = plod_session_method(session)->method != PLOD_LOD_HRTMR;
    if (patches && changed_only)
        return plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "mesh",
                                    "changed_only needs the hrtmr method (the other methods "
                                    "keep no cache)");
    if (patches && template_level != plod_session_refine_params(session)->template_level)
        return plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "mesh",
                                    "with this LOD method template_level must be the "
                                    "refine's (its patches' grids are chosen by the refine)");
    return plod__mesh_build(&e.params, sectors, vb, tb, patches, plod__session_emit, &e, pool);
}

PyObject *plod_py_instances(plod_session *session, int template_level)
{
    if (plod__emission_args(template_level, 1) < 0)
        return NULL;
    plod__session_emission e = {session, {0}, 1, 0};
    plod_session_mesh_params(session, template_level, 1, 1, &e.params);
    return plod__instances_build(&e.params, plod_session_sector_count(session, 1),
                                 plod__session_instances, &e);
}

/* ---- test entry point: explicit corner triangles -------------------------- */

typedef struct plod__corner_source {
    const double *corners; /* 9 per sector */
    const double *levels, *faces; /* may be NULL */
} plod__corner_source;

static int plod__corner_sector(const void *context, size_t index,
                               plod_mesh_sector *out)
{
    const plod__corner_source *src = context;
    if (out) {
        for (int c = 0; c < 3; c++)
            for (int x = 0; x < 3; x++)
                out->corners[c][x] = src->corners[9 * index + 3 * c + x];
        out->level = src->levels ? (int)src->levels[index] : 0;
        out->face = src->faces ? (int)src->faces[index] : 0;
    }
    return 1;
}

typedef struct plod__corner_emission {
    const plod_mesh_params *params;
    plod_mesh_sector_source sectors;
    plod_surface_source surface;
} plod__corner_emission;

static plod_status plod__corner_emit(const void *context, const plod_mesh_buffers *out,
                                     size_t *vertex_count, size_t *triangle_count)
{
    const plod__corner_emission *e = context;
    return plod_mesh_emit(e->params, &e->sectors, &e->surface, out, vertex_count,
                          triangle_count);
}

static plod_status plod__corner_instances(const void *context, float *corners,
                                          float *levels, float *morph,
                                          size_t *instance_count)
{
    const plod__corner_emission *e = context;
    return plod_mesh_instances(e->params, &e->sectors, &e->surface, corners, levels, morph,
                               instance_count);
}

static int plod__vec3_arg(PyObject *obj, double out[3], const char *what)
{
    if (!obj || obj == Py_None)
        return 0;
    size_t n = 0;
    double *v = plod_py_doubles(obj, &n, what);
    if (!v)
        return -1;
    if (n != 3) {
        free(v);
        plod_py_raise_detail(PLOD_ERR_BAD_PARAM, what, "expected 3 numbers");
        return -1;
    }
    out[0] = v[0]; out[1] = v[1]; out[2] = v[2];
    free(v);
    return 0;
}

static PyObject *plod__mesh_from_corners(PyObject *module, PyObject *args, PyObject *kwargs)
{
    (void)module;
    static char *keywords[] = {"corners", "radius", "template_level", "levels", "faces",
                               "threads", "heightmap", "height_scale", "projection",
                               "origin", "eye", "morph_lod_scale", "morph_ramp",
                               "instances", "normal_map", NULL};
    PyObject *corners_obj, *levels_obj = Py_None, *faces_obj = Py_None;
    PyObject *heightmap_obj = Py_None, *projection_obj = NULL;
    PyObject *origin_obj = Py_None, *eye_obj = Py_None;
    double radius = 1.0, height_scale = 1.0, morph_lod_scale = 0.0, morph_ramp = 0.5;
    int template_level = 2, threads = 1, instances = 0, normal_map = 1;
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "Od|iOOiOdOOOddpp", keywords,
                                     &corners_obj, &radius, &template_level,
                                     &levels_obj, &faces_obj, &threads, &heightmap_obj,
                                     &height_scale, &projection_obj, &origin_obj,
                                     &eye_obj, &morph_lod_scale, &morph_ramp,
                                     &instances, &normal_map))
        return NULL;
    plod_planet planet = {0};
    planet.radius = radius;
    planet.projection = PLOD_PROJ_QSC;
    planet.height_scale = height_scale;
    if (projection_obj && plod_py_projection_arg(projection_obj, &planet.projection) < 0)
        return NULL;
    if (heightmap_obj != Py_None) {
        planet.heightmap = plod_py_cubemap_get(heightmap_obj);
        if (!planet.heightmap)
            return NULL;
    }
    plod_mesh_params params;
    plod_mesh_params_init(&params, &planet, template_level);
    params.threads = threads;
    params.morph_ramp = morph_ramp;
    if (plod__vec3_arg(origin_obj, params.origin, "origin") < 0 ||
        plod__vec3_arg(eye_obj, params.eye, "eye") < 0)
        return NULL;
    params.morph = eye_obj != Py_None && morph_lod_scale > 0.0;
    params.morph_lod_scale = morph_lod_scale;

    size_t n_corners = 0, n_levels = 0, n_faces = 0;
    plod__corner_source src = {NULL, NULL, NULL};
    PyObject *result = NULL;
    double *corners = plod_py_doubles(corners_obj, &n_corners, "corners");
    double *levels = NULL, *faces = NULL;
    if (!corners)
        goto done;
    if (n_corners % 9) {
        plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "corners", "9 numbers per sector");
        goto done;
    }
    size_t count = n_corners / 9;
    if (levels_obj != Py_None) {
        levels = plod_py_doubles(levels_obj, &n_levels, "levels");
        if (!levels)
            goto done;
    }
    if (faces_obj != Py_None) {
        faces = plod_py_doubles(faces_obj, &n_faces, "faces");
        if (!faces)
            goto done;
    }
    if ((levels && n_levels != count) || (faces && n_faces != count)) {
        plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "levels/faces", "one per sector");
        goto done;
    }
    src.corners = corners;
    src.levels = levels;
    src.faces = faces;
    if (!(template_level >= 0 && template_level <= PLOD_MAX_TEMPLATE_LEVEL)) {
        plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "mesh", "template_level must be in 0..7");
        goto done;
    }
    if (!(radius > 0.0) || !isfinite(radius)) {
        plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "mesh", "radius must be > 0");
        goto done;
    }
    plod_cubemap *normals = NULL;
    if (planet.heightmap && normal_map && !instances) {
        plod_status st = plod_planet_build_normals(&planet, &normals, params.threads);
        if (st != PLOD_OK) {
            plod_py_raise(st, "mesh (normal map)");
            goto done;
        }
        planet.normalmap = normals;
    }
    plod__corner_emission emission = {&params, {plod__corner_sector, &src, count},
                                      plod_planet_surface_source(&planet)};
    result = instances
                 ? plod__instances_build(&params, count, plod__corner_instances, &emission)
                 : plod__mesh_build(&params, count,
                                    plod_mesh_vertex_bound(count, template_level),
                                    plod_mesh_triangle_bound(count, template_level), 0,
                                    plod__corner_emit, &emission, NULL);
    plod_cubemap_destroy(normals);
done:
    free(corners);
    free(levels);
    free(faces);
    return result;
}

static PyMethodDef plod__mesh_methods[] = {
    {"_mesh_from_corners", (PyCFunction)(void (*)(void))plod__mesh_from_corners,
     METH_VARARGS | METH_KEYWORDS,
     "_mesh_from_corners(corners, radius, template_level=2, levels=None, faces=None, "
     "threads=1, heightmap=None, height_scale=1.0, projection='qsc', origin=None, "
     "eye=None, morph_lod_scale=0.0, morph_ramp=0.5, instances=False, normal_map=True) "
     "-> Mesh | dict\n"
     "Test/diagnostic entry: emits explicit sectors (9 corner floats each, unit "
     "directions CCW from outside) without a refiner."},
    {NULL, NULL, 0, NULL}
};

int plod_py_init_mesh(PyObject *module)
{
    plod_py_mesh_type = (PyTypeObject *)PyType_FromSpec(&plod__mesh_spec);
    if (!plod_py_mesh_type)
        return -1;
    if (PyModule_AddObject(module, "Mesh", (PyObject *)plod_py_mesh_type) < 0) {
        Py_DECREF(plod_py_mesh_type);
        return -1;
    }
    Py_INCREF((PyObject *)plod_py_mesh_type); /* the module's reference was stolen */
    if (PyModule_AddFunctions(module, plod__mesh_methods) < 0)
        return -1;
    if (PyModule_AddIntConstant(module, "MAX_TEMPLATE_LEVEL", PLOD_MAX_TEMPLATE_LEVEL) < 0)
        return -1;
    return 0;
}
