/* projection.c -- cube-sphere projections (placeholder: names only). */
#include "plod_projection.h"

#include <ctype.h>
#include <string.h>

static const char *const plod__projection_names[PLOD_PROJ_COUNT] = {
    "tsc", "csc", "qsc", "spherified", "car",
};

plod_status plod_projection_from_name(const char *name, plod_projection *out)
{
    if (!name || !out)
        return PLOD_ERR_NULL;
    for (int p = 0; p < PLOD_PROJ_COUNT; p++) {
        const char *candidate = plod__projection_names[p];
        size_t i = 0;
        while (candidate[i] && name[i] &&
               tolower((unsigned char)name[i]) == candidate[i])
            i++;
        if (!candidate[i] && !name[i]) {
            *out = (plod_projection)p;
            return PLOD_OK;
        }
    }
    return PLOD_ERR_BAD_PROJECTION;
}

const char *plod_projection_name(plod_projection projection)
{
    if ((unsigned)projection >= PLOD_PROJ_COUNT)
        return NULL;
    return plod__projection_names[projection];
}
