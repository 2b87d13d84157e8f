/* status.c -- message table for plod_status. */
#include "plod_status.h"

static const char *const plod__status_messages[PLOD_STATUS_COUNT] = {
    [PLOD_OK] = "success",
    [PLOD_ERR_NULL] = "null pointer argument",
    [PLOD_ERR_BAD_PROJECTION] = "unknown projection",
    [PLOD_ERR_BAD_COORD] = "coordinate is not finite or outside its domain",
    [PLOD_ERR_BAD_PARAM] = "parameter outside its valid range",
    [PLOD_ERR_NO_MEMORY] = "out of memory (or size too large)",
    [PLOD_ERR_IO] = "file could not be read or written",
    [PLOD_ERR_BAD_IMAGE] = "corrupt or unsupported image",
    [PLOD_ERR_BAD_CAMERA] = "invalid camera",
    [PLOD_ERR_CANCELLED] = "cancelled",
};

const char *plod_status_message(plod_status status)
{
    if ((unsigned)status >= PLOD_STATUS_COUNT || !plod__status_messages[status])
        return "unknown error";
    return plod__status_messages[status];
}
