/* py_cubemap.c -- Python bindings of the cubemap stage (placeholder until the stage lands). */
#include "pyplanetlod.h"

int plod_py_init_cubemap(PyObject *module)
{
    (void)module;
    return 0;
}
