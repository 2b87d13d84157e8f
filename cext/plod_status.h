/* plod_status.h -- status codes shared by every stage of the Planet LOD core.
 *
 * Every fallible C entry point returns a plod_status; PLOD_OK is 0.  The
 * Python module maps each code to one exception type in one place
 * (pymodule.c), so a new code needs a message here and a mapping there.
 */
#ifndef PLOD_STATUS_H
#define PLOD_STATUS_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef enum plod_status {
    PLOD_OK = 0,
    PLOD_ERR_NULL,            /* a required pointer argument was NULL */
    PLOD_ERR_BAD_PROJECTION,  /* unknown projection code or name */
    PLOD_ERR_BAD_COORD,       /* NaN/inf or out-of-domain coordinate */
    PLOD_ERR_BAD_PARAM,       /* an argument outside its documented range */
    PLOD_ERR_NO_MEMORY,       /* allocation failed or size would overflow */
    PLOD_ERR_IO,              /* file missing, unreadable or unwritable */
    PLOD_ERR_BAD_IMAGE,       /* corrupt image or unsupported pixel layout */
    PLOD_ERR_BAD_CAMERA,      /* singular/non-finite camera or bad intrinsics */
    PLOD_ERR_CANCELLED,       /* a progress callback asked to stop */
    PLOD_STATUS_COUNT
} plod_status;

/* Human-readable message for a status; never NULL (unknown codes get a
 * generic message). */
const char *plod_status_message(plod_status status);

/* An error record (as WCSLIB's wcserr): the status and the message written
 * where a check failed, which callers and bindings pass on instead of
 * checking again.  A zeroed record holds no error. */
typedef struct plod_error {
    plod_status status;
    char message[200];
} plod_error;

/* Records `status` and the printf-style message in *error (NULL: nothing
 * recorded); returns `status`, so a check can return what it records. */
plod_status plod_error_set(plod_error *error, plod_status status, const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

/* The explanation beside a returned status, printf-style, into `message`
 * of `size` bytes (truncated; nothing written when message is NULL or
 * size is 0): the messages of the readers and builders that take one. */
void plod_status_format(char *message, size_t size, const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

#ifdef __cplusplus
}
#endif
#endif /* PLOD_STATUS_H */
