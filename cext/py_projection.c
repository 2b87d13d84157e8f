/* py_projection.c -- Python bindings of the projection stage:
 * sphere_to_cube, cube_to_sphere (scalars or sequences/buffers -> array('d')),
 * dir_to_face, face_to_dir (scalars), dirs_to_faces, faces_to_dirs (batches),
 * and the PROJECTIONS tuple.
 */
#include "pyplanetlod.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* A Python number that is not a sequence (float, int, numpy scalars). */
static int plod__is_scalar(PyObject *obj)
{
    return PyFloat_Check(obj) || PyLong_Check(obj) ||
           (PyNumber_Check(obj) && !PySequence_Check(obj) && !PyObject_CheckBuffer(obj));
}

/* New array.array(typecode) of n zeros, with its storage exported into
 * *view (writable); the caller releases the view. */
static PyObject *plod__new_array(const char *typecode, size_t n, Py_buffer *view)
{
    if (n > (size_t)PY_SSIZE_T_MAX / 8)
        return PyErr_NoMemory();
    PyObject *array_module = PyImport_ImportModule("array");
    if (!array_module)
        return NULL;
    PyObject *proto = PyObject_CallMethod(array_module, "array", "s(i)", typecode, 0);
    Py_DECREF(array_module);
    if (!proto)
        return NULL;
    PyObject *result = PySequence_Repeat(proto, (Py_ssize_t)n);
    Py_DECREF(proto);
    if (!result)
        return NULL;
    if (PyObject_GetBuffer(result, view, PyBUF_WRITABLE | PyBUF_C_CONTIGUOUS) < 0) {
        Py_DECREF(result);
        return NULL;
    }
    return result;
}

/* Face numbers from an int32 buffer (array('i')) or any float sequence;
 * values that are not 0..5 become -1 (failing per point). */
static int *plod__faces_arg(PyObject *obj, size_t *count)
{
    if (PyObject_CheckBuffer(obj)) {
        Py_buffer view;
        if (PyObject_GetBuffer(obj, &view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0)
            return NULL;
        const char *fmt = view.format ? view.format : "B";
        if ((fmt[0] == 'i' || fmt[0] == 'l') && fmt[1] == 0 && view.itemsize == 4) {
            size_t n = (size_t)(view.len / 4);
            int *faces = malloc((n ? n : 1) * sizeof(int));
            if (faces)
                memcpy(faces, view.buf, n * sizeof(int));
            PyBuffer_Release(&view);
            if (!faces)
                return (int *)PyErr_NoMemory();
            *count = n;
            return faces;
        }
        PyBuffer_Release(&view);
    }
    size_t n = 0;
    double *values = plod_py_doubles(obj, &n, "faces_to_dirs: faces");
    if (!values)
        return NULL;
    int *faces = malloc((n ? n : 1) * sizeof(int));
    if (!faces) {
        free(values);
        return (int *)PyErr_NoMemory();
    }
    for (size_t i = 0; i < n; i++)
        faces[i] = (values[i] >= 0.0 && values[i] <= 5.0 && values[i] == floor(values[i]))
                       ? (int)values[i] : -1;
    free(values);
    *count = n;
    return faces;
}

/* float64 input: a C-contiguous 'd' buffer is used in place (no copy);
 * anything else is converted by plod_py_doubles into owned storage. */
typedef struct {
    const double *data;
    size_t count;
    double *owned;
    Py_buffer view;
    int has_view;
} plod__doubles_in;

static int plod__doubles_get(PyObject *obj, plod__doubles_in *in, const char *what)
{
    in->owned = NULL;
    in->has_view = 0;
    if (PyObject_CheckBuffer(obj) &&
        PyObject_GetBuffer(obj, &in->view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) == 0) {
        const char *fmt = in->view.format ? in->view.format : "B";
        if ((fmt[0] == '<' || fmt[0] == '=' || fmt[0] == '@') && fmt[1] == 'd')
            fmt++;
        if (fmt[0] == 'd' && fmt[1] == 0 && in->view.itemsize == 8) {
            in->data = in->view.buf;
            in->count = (size_t)(in->view.len / 8);
            in->has_view = 1;
            return 0;
        }
        PyBuffer_Release(&in->view);
    }
    PyErr_Clear(); /* plod_py_doubles reports its own, clearer errors */
    in->owned = plod_py_doubles(obj, &in->count, what);
    in->data = in->owned;
    return in->owned ? 0 : -1;
}

static void plod__doubles_release(plod__doubles_in *in)
{
    if (in->has_view)
        PyBuffer_Release(&in->view);
    in->has_view = 0;
    free(in->owned);
    in->owned = NULL;
}

typedef plod_status (*plod__pair_fn)(plod_projection, double, double, double *, double *);
typedef plod_status (*plod__pair_n_fn)(plod_projection, size_t, const double *,
                                       const double *, double *, double *, int *);

/* Shared body of sphere_to_cube / cube_to_sphere. */
static PyObject *plod__pair_call(PyObject *args, const char *name, plod__pair_fn one,
                                 plod__pair_n_fn many)
{
    PyObject *proj_obj, *a_obj, *b_obj;
    if (!PyArg_ParseTuple(args, "OOO", &proj_obj, &a_obj, &b_obj))
        return NULL;
    plod_projection projection;
    if (plod_py_projection_arg(proj_obj, &projection) < 0)
        return NULL;
    int a_scalar = plod__is_scalar(a_obj), b_scalar = plod__is_scalar(b_obj);
    if (a_scalar != b_scalar)
        return plod_py_raise_detail(PLOD_ERR_BAD_PARAM, name,
                                    "give two numbers or two sequences of equal length");
    if (a_scalar) {
        double a = PyFloat_AsDouble(a_obj);
        if (a == -1.0 && PyErr_Occurred())
            return NULL;
        double b = PyFloat_AsDouble(b_obj);
        if (b == -1.0 && PyErr_Occurred())
            return NULL;
        double out_a, out_b;
        plod_status st = one(projection, a, b, &out_a, &out_b);
        if (st != PLOD_OK) {
            char detail[96];
            PyOS_snprintf(detail, sizeof detail, "%.17g, %.17g", a, b);
            return plod_py_raise_detail(st, name, detail);
        }
        return Py_BuildValue("(dd)", out_a, out_b);
    }
    plod__doubles_in in_a, in_b;
    if (plod__doubles_get(a_obj, &in_a, name) < 0)
        return NULL;
    if (plod__doubles_get(b_obj, &in_b, name) < 0) {
        plod__doubles_release(&in_a);
        return NULL;
    }
    size_t na = in_a.count, nb = in_b.count;
    const double *a = in_a.data, *b = in_b.data;
    PyObject *result = NULL, *out_a = NULL, *out_b = NULL;
    Py_buffer view_a, view_b;
    if (na != nb) {
        char detail[96];
        PyOS_snprintf(detail, sizeof detail, "lengths differ: %zu and %zu", na, nb);
        plod_py_raise_detail(PLOD_ERR_BAD_PARAM, name, detail);
        goto done;
    }
    out_a = plod__new_array("d", na, &view_a);
    if (!out_a)
        goto done;
    out_b = plod__new_array("d", na, &view_b);
    if (!out_b) {
        PyBuffer_Release(&view_a);
        goto done;
    }
    Py_BEGIN_ALLOW_THREADS
    /* Failed points are NaN; the status is not an error for sequences. */
    (void)many(projection, na, a, b, view_a.buf, view_b.buf, NULL);
    Py_END_ALLOW_THREADS
    PyBuffer_Release(&view_a);
    PyBuffer_Release(&view_b);
    result = PyTuple_Pack(2, out_a, out_b);
done:
    Py_XDECREF(out_a);
    Py_XDECREF(out_b);
    plod__doubles_release(&in_a);
    plod__doubles_release(&in_b);
    return result;
}

static PyObject *plod__py_sphere_to_cube(PyObject *self, PyObject *args)
{
    (void)self;
    return plod__pair_call(args, "sphere_to_cube", plod_sphere_to_cube,
                           plod_sphere_to_cube_n);
}

static PyObject *plod__py_cube_to_sphere(PyObject *self, PyObject *args)
{
    (void)self;
    return plod__pair_call(args, "cube_to_sphere", plod_cube_to_sphere,
                           plod_cube_to_sphere_n);
}

static PyObject *plod__py_dir_to_face(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *proj_obj;
    double dir[3];
    if (!PyArg_ParseTuple(args, "Oddd", &proj_obj, &dir[0], &dir[1], &dir[2]))
        return NULL;
    plod_projection projection;
    if (plod_py_projection_arg(proj_obj, &projection) < 0)
        return NULL;
    int face;
    double u, v;
    plod_status st = plod_dir_to_face(projection, dir, &face, &u, &v);
    if (st != PLOD_OK)
        return plod_py_raise_detail(st, "dir_to_face",
                                    "direction must be finite and non-zero");
    return Py_BuildValue("(idd)", face, u, v);
}

static PyObject *plod__py_face_to_dir(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *proj_obj;
    int face;
    double u, v;
    if (!PyArg_ParseTuple(args, "Oidd", &proj_obj, &face, &u, &v))
        return NULL;
    plod_projection projection;
    if (plod_py_projection_arg(proj_obj, &projection) < 0)
        return NULL;
    double dir[3];
    plod_status st = plod_face_to_dir(projection, face, u, v, dir);
    if (st != PLOD_OK)
        return plod_py_raise_detail(st, "face_to_dir",
                                    projection == PLOD_PROJ_CAR
                                        ? "car needs face 0 and u, v in [-1, 1]"
                                        : "face must be 0..5 and u, v in [-1, 1]");
    return Py_BuildValue("(ddd)", dir[0], dir[1], dir[2]);
}

static PyObject *plod__py_dirs_to_faces(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *proj_obj, *dirs_obj;
    if (!PyArg_ParseTuple(args, "OO", &proj_obj, &dirs_obj))
        return NULL;
    plod_projection projection;
    if (plod_py_projection_arg(proj_obj, &projection) < 0)
        return NULL;
    plod__doubles_in in;
    if (plod__doubles_get(dirs_obj, &in, "dirs_to_faces") < 0)
        return NULL;
    size_t n3 = in.count;
    const double *dirs = in.data;
    if (n3 % 3 != 0) {
        plod__doubles_release(&in);
        return plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "dirs_to_faces",
                                    "dirs must hold 3 floats per direction");
    }
    size_t n = n3 / 3;
    PyObject *faces = NULL, *u = NULL, *v = NULL, *result = NULL;
    Py_buffer vf, vu, vv;
    faces = plod__new_array("i", n, &vf);
    if (!faces)
        goto done;
    u = plod__new_array("d", n, &vu);
    if (!u) {
        PyBuffer_Release(&vf);
        goto done;
    }
    v = plod__new_array("d", n, &vv);
    if (!v) {
        PyBuffer_Release(&vf);
        PyBuffer_Release(&vu);
        goto done;
    }
    Py_BEGIN_ALLOW_THREADS
    (void)plod_dir_to_face_n(projection, n, dirs, vf.buf, vu.buf, vv.buf, NULL);
    Py_END_ALLOW_THREADS
    PyBuffer_Release(&vf);
    PyBuffer_Release(&vu);
    PyBuffer_Release(&vv);
    result = PyTuple_Pack(3, faces, u, v);
done:
    Py_XDECREF(faces);
    Py_XDECREF(u);
    Py_XDECREF(v);
    plod__doubles_release(&in);
    return result;
}

static PyObject *plod__py_faces_to_dirs(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *proj_obj, *faces_obj, *u_obj, *v_obj;
    if (!PyArg_ParseTuple(args, "OOOO", &proj_obj, &faces_obj, &u_obj, &v_obj))
        return NULL;
    plod_projection projection;
    if (plod_py_projection_arg(proj_obj, &projection) < 0)
        return NULL;
    size_t nf = 0, nu = 0, nv = 0;
    plod__doubles_in in_u = {0}, in_v = {0};
    int *faces = NULL;
    PyObject *out = NULL, *result = NULL;
    faces = plod__faces_arg(faces_obj, &nf);
    if (!faces)
        goto done;
    if (plod__doubles_get(u_obj, &in_u, "faces_to_dirs") < 0)
        goto done;
    nu = in_u.count;
    if (plod__doubles_get(v_obj, &in_v, "faces_to_dirs") < 0)
        goto done;
    nv = in_v.count;
    const double *u = in_u.data, *v = in_v.data;
    if (nf != nu || nu != nv) {
        plod_py_raise_detail(PLOD_ERR_BAD_PARAM, "faces_to_dirs",
                             "faces, u and v must have equal lengths");
        goto done;
    }
    Py_buffer vd;
    out = plod__new_array("d", 3 * nf, &vd);
    if (!out)
        goto done;
    Py_BEGIN_ALLOW_THREADS
    (void)plod_face_to_dir_n(projection, nf, faces, u, v, vd.buf, NULL);
    Py_END_ALLOW_THREADS
    PyBuffer_Release(&vd);
    result = out;
    out = NULL;
done:
    Py_XDECREF(out);
    plod__doubles_release(&in_u);
    plod__doubles_release(&in_v);
    free(faces);
    return result;
}

static PyMethodDef plod__projection_methods[] = {
    {"sphere_to_cube", plod__py_sphere_to_cube, METH_VARARGS,
     "sphere_to_cube(projection, lon_deg, lat_deg) -> (x_deg, y_deg)\n\n"
     "Sphere -> cross layout [deg] (x = phi_c + 45 chi, y = theta_c + 45 psi;\n"
     "face 4 has x in [225, 315]).  Two numbers give a tuple of floats;\n"
     "non-finite input or |lat| > 90 raises InvalidArgument.  Two equal-length\n"
     "sequences/buffers of float64 give two array('d'); failed points are NaN.\n"
     "For 'car', x = lon wrapped to [-180, 180], y = lat."},
    {"cube_to_sphere", plod__py_cube_to_sphere, METH_VARARGS,
     "cube_to_sphere(projection, x_deg, y_deg) -> (lon_deg, lat_deg)\n\n"
     "Cross layout [deg] -> sphere; lon in [-180, 180].  (x, y) must lie on a\n"
     "face of the cross (face 4 also as x in [-135, -45]).  Two numbers give\n"
     "a tuple (bad input raises InvalidArgument); two equal-length sequences\n"
     "give two array('d') with NaN at failed points."},
    {"dir_to_face", plod__py_dir_to_face, METH_VARARGS,
     "dir_to_face(projection, x, y, z) -> (face, u, v)\n\n"
     "Direction (finite, non-zero; need not be unit) -> face 0..5 and u, v in\n"
     "[-1, 1].  Directions exactly on an edge go to the lowest face.  For\n"
     "'car' the face is 0 and (u, v) is the octahedral square."},
    {"face_to_dir", plod__py_face_to_dir, METH_VARARGS,
     "face_to_dir(projection, face, u, v) -> (x, y, z)\n\n"
     "Face coordinates -> unit direction.  Points on face edges are evaluated\n"
     "on their lowest face, so the result is bit-identical from either side."},
    {"dirs_to_faces", plod__py_dirs_to_faces, METH_VARARGS,
     "dirs_to_faces(projection, dirs) -> (faces array('i'), u array('d'), v array('d'))\n\n"
     "Batch dir_to_face over a flat float64 sequence/buffer of 3n values;\n"
     "failed points give face -1 and NaN."},
    {"faces_to_dirs", plod__py_faces_to_dirs, METH_VARARGS,
     "faces_to_dirs(projection, faces, u, v) -> array('d') of 3n values\n\n"
     "Batch face_to_dir; failed points give NaN directions."},
    {NULL, NULL, 0, NULL},
};

int plod_py_init_projection(PyObject *module)
{
    if (PyModule_AddFunctions(module, plod__projection_methods) < 0)
        return -1;
    PyObject *names = PyTuple_New(PLOD_PROJ_COUNT);
    if (!names)
        return -1;
    for (int p = 0; p < PLOD_PROJ_COUNT; p++) {
        PyObject *name = PyUnicode_FromString(plod_projection_name((plod_projection)p));
        if (!name) {
            Py_DECREF(names);
            return -1;
        }
        PyTuple_SetItem(names, p, name);
    }
    if (PyModule_AddObject(module, "PROJECTIONS", names) < 0) {
        Py_DECREF(names);
        return -1;
    }
    return 0;
}
