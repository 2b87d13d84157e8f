/* plod_geomipmap.h -- geomipmapping on the cube faces (W. H. de Boer,
 * "Fast Terrain Rendering Using Geometrical MipMapping", 2000).
 *
 * Each cube face is a fixed grid of tiles x tiles tiles of (2^n + 1)^2
 * vertices, n = the refinement's template_level (plod_facetiles.h).  Each
 * tile is drawn at one mip level m (every 2^m-th vertex, m = 0..n): the
 * coarsest whose d-value -- the largest distance between the tile's
 * full-resolution vertices and the level-m mesh, measured on the real
 * surface (the detail the finest grid resolves included), computed once
 * per tile when it is first seen -- projects to at most max_pixel_error
 * pixels at the tile's distance (orthographic: pixels_per_metre; the
 * side_distance criterion: the level whose cells are the split border's
 * fraction of the distance).  A level's error is the larger of its d-value
 * and the one below, so levels never get finer with distance.  Cracks:
 * every edge keeps its coarser neighbour's vertices and is zipped to the
 * tile's inner row (index variants for any level difference).  Culling:
 * the HRTMR bounds (horizon, elevation, frustum); with skip_sea, the
 * lower-bound culling of D. Jankauskas ("Fast Terrain Rendering:
 * Geomipmap Optimization", master's thesis, Vilnius University, 2009):
 * tiles whose heights all lie at or below sea_level are left out, and so are the triangles of the others whose three
 * vertices do; the sea sphere is the gap plane that covers them.  The
 * finest detail is the grid's: 2 tiles x 2^n cells per face edge; nearer
 * than that resolves, the error exceeds the threshold.  Internal to the
 * core; the session drives it.
 */
#ifndef PLOD_GEOMIPMAP_H
#define PLOD_GEOMIPMAP_H

#include "plod_facetiles.h"

#ifdef __cplusplus
extern "C" {
#endif

#define PLOD_GEOMIPMAP_MAX_TILES 256

typedef struct plod_geomipmap plod_geomipmap; /* opaque */

plod_status plod_geomipmap_create(plod_geomipmap **out);
void plod_geomipmap_destroy(plod_geomipmap *geomipmap);

/* Chooses the visible tiles and their levels for `camera`; the d-value
 * table is rebuilt when `tiles` or template_level change.
 * plod_facetiles_check's rules, tiles a power of two in
 * 1..PLOD_GEOMIPMAP_MAX_TILES
 * (PLOD_ERR_BAD_PARAM), PLOD_ERR_NO_MEMORY.  stats (may be NULL):
 * sectors_total the tiles, after_backface / after_frustum the tiles not
 * culled, after_budget the visible ones, sea_skipped those lower-bound
 * culling left out, max_level_reached the finest level used (n - m),
 * refine_us. */
plod_status plod_geomipmap_refine(plod_geomipmap *geomipmap, const plod_planet *planet,
                                  const plod_camera *camera, const plod_refine_params *params,
                                  int tiles, plod_refine_stats *stats, plod_error *error);
const plod_face_tile *plod_geomipmap_tiles(const plod_geomipmap *geomipmap, size_t *count);
size_t plod_geomipmap_memory_bytes(const plod_geomipmap *geomipmap);

#ifdef __cplusplus
}
#endif
#endif /* PLOD_GEOMIPMAP_H */
