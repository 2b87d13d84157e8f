/* plod_facetiles.h -- square tiles on the six cube faces: what the
 * quadtree-and-grid LOD methods (chunked LOD, geomipmapping) share.
 *
 * A tile (face, level, x, y) covers u in [-1 + 2 x / 2^level, -1 + 2 (x+1) /
 * 2^level] and likewise v in y, on the planet's cube projection; it is a
 * grid of N = 2^cells_log2 cells per side whose vertex (i, j) sits at the
 * dyadic face point u = -1 + 2 (x N + i) / (2^level N) (exact in double), so
 * a vertex two tiles share -- across a face edge too, where the projection
 * canonicalises the point -- has the same direction, and through the shared
 * vertex evaluation (plod_mesh_sample) the same position, bit for bit.
 *
 * Cracks where neighbours differ in spacing: either stitched (an edge whose
 * neighbour is 2^k times coarser keeps every 2^k-th boundary vertex and its
 * border strip is zipped to the inner row: the edge variants of chunked LOD
 * and geomipmapping, and any
 * difference up to the tile's cell count) or hidden by skirts (a strip down
 * from every edge, as deep as the tile's relief and curvature sag).
 *
 * Culling and the refinement error reuse the sector bounds of the HRTMR
 * refinement (plod_bound.h) over the tile's two triangle halves, so every
 * method is tested against the same camera, horizon, frustum, elevation
 * bounds and 1-pixel rule.  Internal to the core.
 */
#ifndef PLOD_FACETILES_H
#define PLOD_FACETILES_H

#include "plod_bound.h"
#include "plod_mesh.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Deepest tile level (fixed-point face coordinates of the bounds). */
#define PLOD_FACETILE_MAX_LEVEL 24

/* Edges: 0 v = v0, 1 u = u1, 2 v = v1, 3 u = u0 (counter-clockwise in uv). */
typedef struct plod_face_tile {
    uint64_t key;          /* plod_face_tile_key */
    int32_t x, y;          /* tile index on its face at its level */
    uint8_t face, level;   /* the tile covers 2^-level of the face edge */
    uint8_t cells_log2;    /* N = 2^cells_log2 cells per side, 0..8 */
    uint8_t coarser[4];    /* per edge: log2 of the neighbour's spacing over
                              this tile's (0: same or finer); <= cells_log2 */
    uint8_t finer;         /* bit e: a finer neighbour along edge e */
    uint8_t sea;           /* every height of the tile at or below the sea */
    int32_t method_level;  /* the sector_level attribute */
    float skirt;           /* skirt depth in metres (skirts only) */
} plod_face_tile;

uint64_t plod_face_tile_key(int face, int level, int32_t x, int32_t y);

/* One frame's view: the HRTMR refinement's bound tests, set up for a
 * camera and refinement parameters (thresholds, culling switches). */
typedef struct plod_facetiles_view {
    const plod_planet *planet;
    plod_bound_setup setup;
    plod_bound_view view;
    int mirrored[6];       /* face frame left-handed: triangles flipped */
} plod_facetiles_view;

/* The refinement parameters' and camera's rules (as the HRTMR update's),
 * and a cube projection (PLOD_ERR_BAD_PROJECTION for CAR: the methods
 * tile the cube faces); the rule that failed into *error (may be NULL). */
plod_status plod_facetiles_check(const plod_planet *planet, const plod_camera *camera,
                                 const plod_refine_params *params, plod_error *error);

/* PLOD_ERR_BAD_PROJECTION for CAR (the methods tile the cube faces). */
plod_status plod_facetiles_view_init(plod_facetiles_view *fv, const plod_planet *planet,
                                     const plod_camera *camera,
                                     const plod_refine_params *params);

/* The bounds of the tile's two triangle halves. */
void plod_facetiles_bounds(const plod_facetiles_view *fv, int face, int level, int32_t x,
                           int32_t y, plod_bound halves[2]);
/* 1 when both halves are culled (horizon, frustum, elevation bounds). */
int plod_facetiles_culled(const plod_facetiles_view *fv, const plod_bound halves[2]);
/* The refinement score (> 1 wants finer) of the tile's grid of 2^cells_log2
 * cells: the larger half's plod_bound_score at its distance. */
double plod_facetiles_score(plod_facetiles_view *fv, const plod_bound halves[2],
                            int cells_log2);
/* The nearest distance from the eye to the tile's bounds. */
double plod_facetiles_distance(const plod_facetiles_view *fv, const plod_bound halves[2]);

/* A face point just across edge `edge` of the tile, near its midpoint:
 * on the neighbouring tile of the same face, or of the next face. */
void plod_facetiles_across(int face, int level, int32_t x, int32_t y, int edge,
                           int *out_face, double *u, double *v);

/* ---- emission -------------------------------------------------------------------- */

typedef struct plod_facetiles_emission {
    plod_projection projection;
    int skirts;            /* 1: skirts, 0: stitched edges */
    int morph;             /* geomorph odd vertices (params->morph and scale) */
    int drop_sea;          /* lower-bound culling: leave out triangles whose
                              three vertices lie at or below sea_level */
    double sea_level;
    double ortho_cell;     /* detail band cell (metres) without a fade; 0: all */
} plod_facetiles_emission;

/* Upper bounds of the vertices and triangles of `count` tiles; 0, 0 when
 * they would not fit int32 indices. */
void plod_facetiles_bound(const plod_face_tile *tiles, size_t count, int skirts,
                          size_t *vertices, size_t *triangles);
/* Emits the tiles in order into `out` (plod_mesh_buffers; keys get the
 * tiles' keys) on params->threads threads, the same bits for any count.
 * Statuses as plod_mesh_emit. */
plod_status plod_facetiles_emit(const plod_mesh_params *params,
                                const plod_surface_source *surface,
                                const plod_facetiles_emission *options,
                                const plod_face_tile *tiles, size_t count,
                                const plod_mesh_buffers *out, size_t *vertex_count,
                                size_t *triangle_count);

#ifdef __cplusplus
}
#endif
#endif /* PLOD_FACETILES_H */
