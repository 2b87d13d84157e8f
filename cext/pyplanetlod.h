/* pyplanetlod.h -- shared internals of the Python module `planetlod`.
 * Only the py_*.c files include this; the core (plod_*.h) never sees Python.
 */
#ifndef PYPLANETLOD_H
#define PYPLANETLOD_H

/* The stable ABI of Python 3.11: one planetlod/_native.abi3.so loads in every
 * CPython from 3.11 on (Blender 3.4 with Debian's 3.11, 4.2 .. 5.0 with
 * 3.11, 5.1 with 3.13).  setup.py builds with py_limited_api.  Code here
 * uses only the limited API: no struct access to type objects (tp_alloc and
 * tp_free through PyType_GetSlot), no *_GET_ITEM / *_SET_ITEM macros. */
#ifndef Py_LIMITED_API
#define Py_LIMITED_API 0x030B0000
#endif
#define PY_SSIZE_T_CLEAN
#include <Python.h>
/* Python.h under the limited API does not bring these in. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "plod.h"

/* A new instance of heap type `type` through its tp_alloc slot. */
static inline PyObject *plod_py_alloc(PyTypeObject *type)
{
    allocfunc alloc = (allocfunc)PyType_GetSlot(type, Py_tp_alloc);
    return alloc(type, 0);
}

/* Frees `self` through its type's tp_free slot (the caller then drops its
 * reference to the heap type, as every heap type's dealloc must). */
static inline void plod_py_free(PyObject *self)
{
    freefunc free_slot = (freefunc)PyType_GetSlot(Py_TYPE(self), Py_tp_free);
    free_slot(self);
}

/* ---- exported buffers (pymodule.c) ---------------------------------------
 * planetlod.Buffer: a 1-D, C-contiguous, read-write buffer that honours
 * PyBUF_SIMPLE|PyBUF_FORMAT (Blender's foreach_set accepts it, a memoryview
 * does not), supports len(), indexing and .tolist().  format is one struct
 * character: 'f' float32, 'd' float64, 'i' int32, 'I' uint32, 'B' uint8,
 * 'H' uint16, 'Q' uint64. */

/* New zero-filled buffer of `count` items; *data receives its storage. */
PyObject *plod_py_buffer_new(char format, size_t count, void **data);
/* Shortens a buffer nothing has exported yet to its first `count` items
 * (a result filled below its bound); -1 with an exception otherwise. */
int plod_py_buffer_truncate(PyObject *buffer, size_t count);
/* Storage pointer of a planetlod.Buffer (NULL + TypeError otherwise). */
void *plod_py_buffer_data(PyObject *buffer, size_t *count, char *format);

/* A pool of buffer storage, so that one frame's mesh buffers reuse the
 * memory of a mesh freed before instead of new pages, which the kernel
 * faults in and zeroes (up to half of a cached frame's emission).  It
 * holds at most 1.5 times plod_py_pool_keep's bytes (a mesh's buffers with
 * their slack), oldest blocks going first.  Reference counted (under the
 * GIL): the owner's and one per buffer. */
typedef struct plod_py_pool plod_py_pool;
plod_py_pool *plod_py_pool_new(void); /* NULL: no memory */
void plod_py_pool_release(plod_py_pool *pool); /* NULL: nothing */
void plod_py_pool_keep(plod_py_pool *pool, size_t bytes);
/* A buffer of `count` uninitialised items from a held block of its size
 * (up to twice it) or malloc; its storage returns to `pool` when it goes
 * (is freed where pool is NULL or the buffer below 64 KB, which malloc
 * serves from its own free lists). */
PyObject *plod_py_buffer_pooled(plod_py_pool *pool, char format, size_t count, void **data);

/* ---- errors (pymodule.c) -------------------------------------------------
 * Raises the exception for `status` ("context: message") and returns NULL.
 * Mapping: argument errors -> planetlod.InvalidArgument (a ValueError),
 * PLOD_ERR_IO -> planetlod.FileError (an OSError), PLOD_ERR_BAD_IMAGE ->
 * planetlod.ImageError (a ValueError), PLOD_ERR_NO_MEMORY -> MemoryError,
 * PLOD_ERR_CANCELLED -> planetlod.Cancelled (PLOD_OK: SystemError, a
 * caller bug).  All but MemoryError derive from planetlod.PlanetLODError. */
PyObject *plod_py_raise(plod_status status, const char *context);
PyObject *plod_py_raise_detail(plod_status status, const char *context,
                               const char *detail);
/* The pending exception as a status and its text, when it is one of the
 * classes above or MemoryError (then cleared): 0.  -1 leaves any other
 * exception set (and returns -1 with none pending). */
int plod_py_exception_status(plod_status *status, char *message, size_t message_size);

/* ---- argument helpers (pymodule.c) ----------------------------------------- */
/* Projection from a Python str; InvalidArgument listing valid names. */
int plod_py_projection_arg(PyObject *name, plod_projection *out);
/* Reads a float64 sequence or buffer into a new malloc'ed array. */
double *plod_py_doubles(PyObject *obj, size_t *count, const char *what);

/* ---- reading height data (py_cubemap.c) ----------------------------------
 * How an image file is read: `raw` (a mapping width, height, dtype 'u8' |
 * 'u16' | 'i16' | 'f32', byteorder 'little' | 'big'; None = by the file's
 * extension) and `signed` (u8/u16 samples are two's complement). */
typedef struct plod_py_read_options {
    int is_signed;
    int has_raw;
    plod_raw_format raw;
} plod_py_read_options;
/* Fills *out from the Python arguments; -1 with InvalidArgument. */
int plod_py_read_options_arg(PyObject *raw, int is_signed, plod_py_read_options *out,
                             const char *context);

/* ---- image files (py_image.c) ---------------------------------------------
 * .hgt/.r16/.raw grids (and `raw` layouts) are read by the core; every other
 * file through planetlod.imageio (OpenImageIO's Python module), whose array
 * the image borrows while `view` is held. */
typedef struct plod_py_image {
    plod_image image;
    Py_buffer view;
    int has_view;
} plod_py_image;
/* Reads `path` (options may be NULL: by the extension, unsigned) with the
 * GIL held; mode PLOD_IMPORT_STORED: samples as stored (GeoTIFF DEMs).  -1
 * with FileError / ImageError / InvalidArgument / MemoryError ("context:
 * ...") or ImportError (no OpenImageIO).  Release with
 * plod_py_image_release (also after a failure). */
int plod_py_image_read(plod_py_image *out, const char *path, plod_import_mode mode,
                       const plod_py_read_options *options, const char *context);
void plod_py_image_release(plod_py_image *image);
/* Writes `image` to `path` (the type chosen by its extension) with the GIL
 * held; -1 with an exception as plod_py_image_read's. */
int plod_py_image_write(const plod_image *image, const char *path, const char *context);
/* planetlod.imageio.RowReader as the core's rows reader, for calls made
 * with the GIL released.  An exception that is not a planetlod error is
 * kept in the context: raise it with plod_py_rows_reader_raise (-1) after
 * the core returns (0 when there is none). */
typedef struct plod_py_rows_context {
    PyObject *error_type, *error_value, *error_traceback;
} plod_py_rows_context;
plod_image_rows_reader plod_py_rows_reader(plod_py_rows_context *context);
int plod_py_rows_reader_raise(plod_py_rows_context *context);

/* ---- tiled maps (py_heightdata.c; used by Planet) ------------------------
 * The tiles inside a planetlod.TiledMap, or NULL (no exception) for any
 * other object. */
const plod_tiles *plod_py_tiled_map_get(PyObject *obj);
int plod_py_init_heightdata(PyObject *module);
/* Planet(insets=...): a list of .hgt or GeoTIFF paths or dicts(path, west, south, east,
 * north[, raw, scale, offset]); *out NULL for None.  -1 with an exception. */
int plod_py_insets_arg(PyObject *list, double feather, plod_insets **out);

/* ---- cube map glue (py_cubemap.c; used by Planet) ----------------------
 * planetlod.CubeMap wraps an owned plod_cubemap with its pyramid built. */
/* Borrowed pointer to the cube map inside a planetlod.CubeMap, or NULL with
 * TypeError if `obj` is not one. */
plod_cubemap *plod_py_cubemap_get(PyObject *obj);
/* New planetlod.CubeMap from an image file: an equirectangular (2:1) image
 * is resampled into `projection` at `size` (0 = chosen from the image), a
 * cross-layout (4:3) image is taken as a cube map already.  channels 0 =
 * keep the image's.  Raises FileError/ImageError/InvalidArgument. */
PyObject *plod_py_cubemap_from_image(const char *path, plod_projection projection,
                                     int size, int channels,
                                     const plod_py_read_options *options);

/* ---- emission (py_mesh.c; called by Planet.mesh / Planet.instances) -----
 * New planetlod.Mesh / instances dict from the planet's session (its lock
 * held by the caller): the visible sectors (every leaf unless
 * visible_only) at `template_level`, origin and geomorphing from the last
 * refine (plod_session_mesh_params), through the session's cache when
 * use_cache.  InvalidArgument for a template level outside 0..7 or
 * threads outside 1..64. */
/* pool: where the mesh's buffers take and return their storage (NULL: malloc) */
PyObject *plod_py_mesh_emit(plod_session *session, plod_py_pool *pool, int template_level,
                            int morph, int threads, int visible_only, int use_cache,
                            int changed_only);
PyObject *plod_py_instances(plod_session *session, int template_level);

/* ---- per-stage registration (each py_*.c defines one) --------------------- */
int plod_py_init_projection(PyObject *module);
int plod_py_init_cubemap(PyObject *module);
int plod_py_init_planet(PyObject *module);
int plod_py_init_mesh(PyObject *module);

#endif /* PYPLANETLOD_H */
