/* plod_mesh.h -- sector templates (4^level triangles) and emission of the
 * visible sectors as flat float32 / int32 buffers (meshoptimizer-style:
 * caller-owned outputs, Bound() sizes, counts returned).
 */
#ifndef PLOD_MESH_H
#define PLOD_MESH_H

#include "plod_refine.h"

#ifdef __cplusplus
extern "C" {
#endif

#define PLOD_MAX_TEMPLATE_LEVEL 7  /* 16384 triangles */

size_t plod_template_vertex_count(int template_level);
size_t plod_template_triangle_count(int template_level);

/* See mesh.c for the full contract; filled in by the mesh stage. */

#ifdef __cplusplus
}
#endif
#endif /* PLOD_MESH_H */
