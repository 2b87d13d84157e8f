/* py_mesh.c -- Python bindings of the mesh stage (placeholder until the stage lands). */
#include "pyplanetlod.h"

int plod_py_init_mesh(PyObject *module)
{
    (void)module;
    return 0;
}
