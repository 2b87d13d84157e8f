/* plod_clipmap.h -- geometry clipmaps on the cube faces: nested rings of
 * regular grids centred under the viewer (F. Losasso, H. Hoppe, "Geometry
 * Clipmaps: Terrain Rendering Using Nested Regular Grids", SIGGRAPH 2004;
 * A. Asirvatham, H. Hoppe, "Terrain Rendering Using GPU-Based Geometry
 * Clipmaps", GPU Gems 2, 2005), laid on the sphere as one grid per level
 * on each cube face.
 *
 * Why rings on the cube faces rather than a polar grid around the nadir
 * (M. Clasen, H.-C. Hege, "Terrain Rendering using Spherical Clipmaps",
 * EuroVis 2006): a polar grid turns with the viewer, so its vertices slide
 * over the terrain every frame; the cube-face grids are fixed on the
 * planet, so a level's vertices stay put while its ring moves in whole
 * coarse cells, the mesh is a function of the camera alone and the
 * vertices the planet's projection already addresses (height map texels,
 * bounds per face rectangle) are reused.  The rings are round (angular
 * distance on the sphere), as Clasen and Hege's, so they cross face edges
 * and cube corners without special cases.
 *
 * Levels: level l divides each cube face into 2^l x 2^l cells (nominal
 * angular size s_l = (pi/2) 2^-l).  Level l's centre C_l is the centre of
 * the level l-1 cell holding the nadir (so the ring moves in whole coarse
 * cells, 2 of its own).  A level l-1 cell is refined into its four level-l
 * children when its parent is refined, l <= the finest level, and all its
 * corners lie within ring_cells * s_l of C_l.  The leaves (cells not
 * refined whose parent is) are the mesh: each ring l is the level-l leaves,
 * an annulus about ring_cells/2 .. ring_cells of its cells wide.  Coarse
 * levels whose ring covers the sphere are refined everywhere, so the
 * coarsest ring reaches the horizon from any height.  The finest level is
 * the coarsest whose cells, seen from the eye's height above the nadir's
 * surface, span at most max_pixel_error pixels, up to max_level.
 *
 * Transition regions (Losasso and Hoppe's blend): in ring l a vertex at
 * phi = (angle to C_l) / s_l cells gets alpha = clamp((phi - (ring_cells -
 * margin - w)) / w, 0, 1), w = ring_cells / 5 (their w = n/10), margin the
 * cells a coarse leaf's corner can lie inside the ring; its position,
 * normal and detail move toward the coarser level's (the midpoint of its
 * two level l-1 neighbours on the coarse triangulation, sampled with the
 * coarser level's detail band), so the ring's outer vertices (alpha 1) sit
 * exactly on the coarser ring's edges.  With morph off alpha is 0 or 1 (1
 * only in that outer margin), so the rings still meet.  T-junctions are
 * closed by one stitch triangle per coarse edge that borders the finer
 * ring: (fine midpoint, coarse ends), of zero area when the midpoint's
 * alpha is 1 (Losasso and Hoppe's zero-area triangles), so the emitted
 * surface is closed: welded by position, every edge has two triangles.
 *
 * Vertices go through the shared vertex evaluation (plod_mesh_sample):
 * heights, normals and detail from the surface source, positions computed
 * in double and written relative to the origin as float32.  Each level
 * samples the detail band its cells resolve (a level is a filtered
 * terrain, as a clipmap level is), or, with the emission's detail fade,
 * the fade's band (a function of the direction and the eye).  Culling (horizon against
 * the lowest surface's ball, frustum) is per block of 2^block_level x
 * 2^block_level cells, with the block's elevation bounds.
 *
 * Incremental update: the object keeps each level's refined cells,
 * leaves, stitches and blocks (with their bounds).  A new camera whose
 * nadir stays in the same level l-1 cell keeps every level up to l - 1
 * (their inputs are unchanged); only the finer levels are rebuilt.  The
 * result equals a new object's for the same camera and parameters, bit for
 * bit.  Emission runs on `threads` threads, one block at a time per
 * thread, identical for any count.
 */
#ifndef PLOD_CLIPMAP_H
#define PLOD_CLIPMAP_H

#include "plod_camera.h"
#include "plod_mesh.h"

#ifdef __cplusplus
extern "C" {
#endif

#define PLOD_CLIPMAP_MAX_LEVEL 28
#define PLOD_CLIPMAP_MAX_BLOCK_LEVEL 6

typedef struct plod_clipmap plod_clipmap; /* opaque */

typedef struct plod_clipmap_params {
    int ring_cells;         /* ring's outer radius in its own cells, 16..1024 */
    double max_pixel_error; /* finest level: cells of at most this many
                               pixels under the eye; > 0, finite */
    int max_level;          /* finest level allowed, 1..PLOD_CLIPMAP_MAX_LEVEL */
    int block_level;        /* culling blocks of 2^b x 2^b cells, 0..6 */
    int backface;           /* cull blocks beyond the horizon */
    int frustum;            /* cull blocks outside the view frustum */
} plod_clipmap_params;

/* ring_cells 32, max_pixel_error 1, max_level 24, block_level 3, morph 1,
 * backface 1, frustum 1. */
void plod_clipmap_params_default(plod_clipmap_params *params);

typedef struct plod_clipmap_stats {
    int finest_level;       /* the finest level this frame */
    int first_rebuilt;      /* first level rebuilt (finest_level + 1: none) */
    size_t cells;           /* leaf cells (every ring, culled or not) */
    size_t cells_refreshed; /* leaf cells that were not leaves last frame */
    size_t blocks, blocks_visible;
    size_t stitches;        /* stitch triangles (every ring) */
    size_t stitches_open;   /* stitches whose midpoint's alpha is not 1
                               (cracks filled by a thin triangle; 0 when
                               the margins hold) */
    double update_us;       /* wall time of the update */
} plod_clipmap_stats;

/* An empty clipmap (no levels).  PLOD_ERR_NULL, PLOD_ERR_NO_MEMORY. */
plod_status plod_clipmap_create(plod_clipmap **out);
void plod_clipmap_destroy(plod_clipmap *clipmap);
/* Forgets every level: the next update builds from scratch. */
void plod_clipmap_reset(plod_clipmap *clipmap);

/* The rings for `camera` over `planet` (radius, projection and the bounds
 * of its heights and detail; a cube projection) and `surface` (the
 * nadir's height).  PLOD_ERR_NULL; PLOD_ERR_BAD_PARAM (a parameter out of
 * range, a CAR planet: *error names it); PLOD_ERR_BAD_COORD (the eye at
 * the planet's centre); PLOD_ERR_NO_MEMORY (the clipmap is then reset).
 * stats and error may be NULL. */
plod_status plod_clipmap_update(plod_clipmap *clipmap, const plod_planet *planet,
                                const plod_surface_source *surface,
                                const plod_camera *camera,
                                const plod_clipmap_params *params,
                                plod_clipmap_stats *stats, plod_error *error);

/* Vertices and triangles the last update's visible blocks emit (0 before
 * an update). */
size_t plod_clipmap_vertex_count(const plod_clipmap *clipmap);
size_t plod_clipmap_triangle_count(const plod_clipmap *clipmap);
/* Visible blocks the last update emits (0 before an update). */
size_t plod_clipmap_block_count(const plod_clipmap *clipmap);
/* Bytes the clipmap holds (every level's cells, stitches and blocks, and
 * the visible list; capacities included; 0 for NULL). */
size_t plod_clipmap_memory_bytes(const plod_clipmap *clipmap);

/* Emits the last update's visible blocks (ring by ring, coarsest first;
 * blocks in cell order) into `out` (plod_mesh_buffers; sizes from the
 * counts above; keys: plod_clipmap_block_count) through the shared vertex evaluation
 * (plod_mesh_sample with params: origin, eye, detail fade; without the
 * fade each ring samples the detail band its cells resolve): positions
 * relative to params->origin, normals, uv (longitude unwrapped per
 * block), morph (alpha), triangles (counter-clockwise from outside),
 * sector_level (the ring's level), face, detail, keys (per visible block:
 * face << 56 | level << 50 | block row << 25 | block column, the block's
 * cell at level - min(block_level, level)).  params->morph on: the
 * transition regions blend (alpha ramps); off: hard rings (alpha 0 or 1).
 * params->threads 1..PLOD_MESH_MAX_THREADS (identical output; on
 * params->workers when given).  PLOD_ERR_NULL; PLOD_ERR_BAD_PARAM
 * (threads, no update yet, another planet radius); PLOD_ERR_BAD_COORD (a
 * non-finite origin or eye); PLOD_ERR_NO_MEMORY. */
plod_status plod_clipmap_emit(const plod_clipmap *clipmap, const plod_mesh_params *params,
                              const plod_surface_source *surface, const plod_mesh_buffers *out,
                              size_t *vertex_count, size_t *triangle_count);

#ifdef __cplusplus
}
#endif
#endif /* PLOD_CLIPMAP_H */
