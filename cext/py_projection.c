/* py_projection.c -- Python bindings of the projection stage (placeholder until the stage lands). */
#include "pyplanetlod.h"

int plod_py_init_projection(PyObject *module)
{
    (void)module;
    return 0;
}
