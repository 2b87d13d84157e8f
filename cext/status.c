/* status.c -- message table for plod_status, and the detail messages. */
#include "plod_status.h"

#include <stdarg.h>
#include <stdio.h>

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

plod_status plod_error_set(plod_error *error, plod_status status, const char *format, ...)
{
    if (!error)
        return status;
    error->status = status;
    va_list args;
    va_start(args, format);
    vsnprintf(error->message, sizeof error->message, format, args);
    va_end(args);
    return status;
}

void plod_status_format(char *message, size_t size, const char *format, ...)
{
    if (!message || !size)
        return;
    va_list args;
    va_start(args, format);
    vsnprintf(message, size, format, args);
    va_end(args);
}
