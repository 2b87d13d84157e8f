/* plod_chunked.h -- chunked LOD on six cube-face quadtrees (T. Ulrich,
 * "Rendering Massive Terrains using Chunked Level of Detail Control",
 * SIGGRAPH course notes, 2002).
 *
 * Each cube face is the root of a quadtree of chunks: fixed-size grids of
 * 2^template_level cells per side (plod_facetiles.h).  A chunk splits while
 * its screen-space error exceeds the refinement's threshold (the HRTMR
 * refinement's bounds and 1-pixel rule over the chunk's two triangle
 * halves), unless it is culled (horizon and elevation bounds, frustum) or
 * at max_level / 2 (quadtree levels halve the size where bisection levels
 * halve the area).  Cracks: skirts (any level difference), or stitched edge
 * variants over a restricted quadtree (neighbours differ by at most one
 * level; forced splits keep it so), the 16 variants of an edge set.  Over
 * params->budget leaves the threshold rises in steps of sqrt 2 until the
 * selection fits.  The selection is a function of the camera and
 * parameters alone (no state between refines).  Internal to the core; the session drives it.
 */
#ifndef PLOD_CHUNKED_H
#define PLOD_CHUNKED_H

#include "plod_facetiles.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct plod_chunked plod_chunked; /* opaque */

plod_status plod_chunked_create(plod_chunked **out);
void plod_chunked_destroy(plod_chunked *chunked);

/* Selects the visible chunks for `camera`: plod_facetiles_check's rules,
 * PLOD_ERR_NO_MEMORY.  skirts: 1 skirts, 0 stitched (restricted tree).
 * stats (may be NULL): sectors_total the quadtree's leaves, after_backface
 * / after_frustum / after_budget the visible chunks, splits, truncated
 * (max_sectors leaves reached), max_level_reached, refine_us. */
plod_status plod_chunked_refine(plod_chunked *chunked, const plod_planet *planet,
                                const plod_camera *camera, const plod_refine_params *params,
                                int skirts, plod_refine_stats *stats, plod_error *error);
/* The last refine's visible chunks, in depth-first order (faces 0..5). */
const plod_face_tile *plod_chunked_tiles(const plod_chunked *chunked, size_t *count);
size_t plod_chunked_memory_bytes(const plod_chunked *chunked);

#ifdef __cplusplus
}
#endif
#endif /* PLOD_CHUNKED_H */
