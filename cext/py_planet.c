/* py_planet.c -- Python bindings of the planet stage (placeholder until the stage lands). */
#include "pyplanetlod.h"

int plod_py_init_planet(PyObject *module)
{
    (void)module;
    return 0;
}
