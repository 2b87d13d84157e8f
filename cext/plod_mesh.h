/* plod_mesh.h -- sector templates (4^level triangles) and emission of the
 * visible sectors as flat float32 / int32 buffers (meshoptimizer-style:
 * caller-owned outputs, Bound() sizes, counts returned).
 *
 * The emission core knows neither the refiner nor the planet's data: a
 * sector is three unit corner directions (counter-clockwise seen from
 * outside), a level and a face, delivered by a sector source; heights,
 * normals and detail come from a surface source (plod_heightsource.h; the
 * planet's is plod_planet_surface_source, the refiner's leaves are
 * delivered by plod_session.h).  Each sector becomes one copy of the template:
 * vertex (i, j) of a template with n = 2^template_level segments per edge has
 * the integer weights (n-i-j, j, i) on corners (0, 1, 2), direction
 * normalise(sum of the non-zero terms w_c * corner_c, in corner order) and
 * position direction * (radius + height(direction)).  Weights k/n are exact
 * (n is a power of two) and a two-term sum is commutative, so a vertex on an
 * edge shared by two sectors is bit-identical from either side; with
 * -ffp-contract=off the whole position, normal and morph computation is a
 * function of that direction only, hence shared vertices weld exactly.
 * Vertices are NOT welded across sectors (each sector owns its copy).
 */
#ifndef PLOD_MESH_H
#define PLOD_MESH_H

#include "plod_planet.h"
#include "plod_surface.h"

#ifdef __cplusplus
extern "C" {
#endif

#define PLOD_MAX_TEMPLATE_LEVEL 7  /* 16384 triangles */
#define PLOD_MESH_MAX_THREADS 64

/* ---- templates ----------------------------------------------------------
 * Vertex order: rows i = 0..n, inside a row j = 0..n-i; index of (i, j) is
 * i*(n+1) - i*(i-1)/2 + j.  Triangles per row: "up" (i,j) (i,j+1) (i+1,j)
 * for j < n-i, then "down" (i,j+1) (i+1,j+1) (i+1,j) for j < n-i-1;
 * counter-clockwise when the corners are. */

/* (n+1)(n+2)/2 and n*n for n = 2^template_level; 0 outside 0..7. */
size_t plod_template_vertex_count(int template_level);
size_t plod_template_triangle_count(int template_level);
/* Barycentric weights (corner 0, 1, 2) per template vertex into `out`
 * (3 * vertex_count floats, exact).  PLOD_ERR_BAD_PARAM for a bad level. */
plod_status plod_template_barycentrics(float *out, int template_level);
/* Template triangles into `out` (3 * triangle_count int32 indices).  Both:
 * PLOD_ERR_NULL, PLOD_ERR_BAD_PARAM for a bad level. */
plod_status plod_template_triangles(int32_t *out, int template_level);

/* ---- sectors as the emitter sees them ----------------------------------- */
struct plod_split_morph; /* plod_refine.h */

typedef struct plod_mesh_sector {
    double corners[3][3]; /* unit directions, CCW seen from outside */
    int level;            /* written to the sector_level attribute */
    int face;             /* written to the face attribute */
    uint64_t key;         /* identity for plod_mesh_cache (the refiner's
                             sector id); 0 = never cached.  plod_mesh_emit
                             sets it to 0 before each source call;
                             plod_mesh_instances neither sets nor reads it. */
    /* Split morph (plod_split_morph in plod_refine.h): with `split` set and
     * params.morph, each vertex on the grid of the sector's ancestor j
     * levels up but off the grid of the one above it (j = 0: the sector's
     * own vertices off its parent's grid) blends by stage j's factor toward
     * the middle of that next ancestor's edge through it, whose ends blend
     * the same way first, as far up as the stages reach.  It moves along
     * its own direction, in height, toward the mean of the edge ends'
     * distances from the centre: the ancestors' grids do not nest on the
     * sphere, so a whole-position blend would slide it sideways by the gap,
     * and the chords of an ancestor's long edges sag kilometres below the
     * ground.  Normals and detail blend toward the edge middle's.  An
     * edge's ends are evaluated from the corners of the triangle of the
     * ancestor's level that holds them (the ancestor or its sibling), as
     * that triangle's sector evaluates them, so every sector holding a
     * vertex computes the same bits.  Sectors whose factors are all 0 do
     * not move.  NULL: the distance geomorph below (params.morph_*).
     * plod_mesh_emit sets it to NULL before each source call. */
    const struct plod_split_morph *split;
} plod_mesh_sector;

/* Returns 1 if sector `index` (0..count-1) is emitted and then fills
 * *sector unless it is NULL (the counting pass, on the calling thread,
 * passes NULL), 0 to skip it.  Called concurrently from several threads:
 * must be reentrant. */
typedef int (*plod_mesh_sector_fn)(const void *context, size_t index,
                                   plod_mesh_sector *sector);

/* Sector source: `sector` over indices 0..count-1 with its `context`. */
typedef struct plod_mesh_sector_source {
    plod_mesh_sector_fn sector;
    const void *context;
    size_t count;
} plod_mesh_sector_source;

/* ---- sector cache ----------------------------------------------------------
 * Sectors persist from frame to frame (a flyby splits or merges a few percent
 * of them per frame), and a persistent sector's vertices differ between
 * frames only by the origin they are written relative to.  A cache keeps, per
 * sector key, the planet-space positions (double), normals, uv and detail of the
 * sectors emitted by the last plod_mesh_emit that used it; a sector found
 * there is copied (positions re-offset in double, then cast; with a detail
 * field, corner normals whose band depends on the eye sampled again)
 * instead of recomputed, so the output is bit-identical to an uncached
 * emission.
 * Entries not used by an emission are freed at its end: the cache holds one
 * frame's sectors, at most max_bytes (48 bytes per vertex and 12 per
 * sector; sectors that do not fit are emitted uncached).  One cache serves
 * one planet, surface source and template level: emitting another planet
 * (pointer, radius, height scale and offset, maps, source, insets, detail),
 * another surface source (ops, self, stamp) or level through it empties it
 * first.  Not thread-safe: one emission at a time per cache (the emission's
 * own threads are handled inside). */
typedef struct plod_mesh_cache plod_mesh_cache; /* opaque */

typedef struct plod_mesh_cache_stats {
    size_t sectors;   /* entries held */
    size_t bytes;     /* their vertex data */
    size_t max_bytes;
    size_t hits;      /* last emission: sectors copied from the cache */
    size_t misses;    /* last emission: keyed sectors computed */
    uint64_t emissions; /* emissions through the cache so far: a caller
                           holding the output of emission k knows, seeing
                           k here, that no other emission changed what a
                           changed_only emission leaves out */
} plod_mesh_cache_stats;

#define PLOD_MESH_CACHE_DEFAULT_BYTES ((size_t)256 << 20)

/* An empty cache; PLOD_ERR_NULL or PLOD_ERR_NO_MEMORY (*out NULL then).
 * The other calls accept NULL (no-op; statistics zero). */
plod_status plod_mesh_cache_create(plod_mesh_cache **out, size_t max_bytes);
void plod_mesh_cache_destroy(plod_mesh_cache *cache);
void plod_mesh_cache_clear(plod_mesh_cache *cache);
/* Lowers or raises the budget; entries over it are dropped at once. */
void plod_mesh_cache_set_max_bytes(plod_mesh_cache *cache, size_t max_bytes);
void plod_mesh_cache_get_stats(const plod_mesh_cache *cache,
                               plod_mesh_cache_stats *stats);

/* ---- parameters ---------------------------------------------------------- */
typedef struct plod_mesh_params {
    const plod_planet *planet;  /* borrowed: radius, projection (morph
                                   scale) and the cache's identity; heights
                                   come from the emission's surface source */
    int template_level;         /* 0..PLOD_MAX_TEMPLATE_LEVEL */
    double origin[3];           /* positions are written relative to it
                                   (subtracted in double, then cast) */
    int threads;                /* 1..PLOD_MESH_MAX_THREADS; output is
                                   identical for any value */
    plod_workers *workers;      /* NULL: threads started for the emission;
                                   else persistent workers to run them on
                                   (borrowed, called from this thread only
                                   while the emission runs; plod_base.h) */
    /* Geomorphing: odd template vertices blend toward the midpoint of their
     * two even neighbours along the template line on which their even weight
     * is constant (for an edge vertex: along the sector edge).  The factor
     * is a function of the vertex's unmorphed position and `eye` only, so a
     * shared vertex morphs identically from both sides: continuous level
     * L = morph_level_rate * log2(morph_lod_scale / distance), f = L -
     * floor(L), morph = clamp(max(morph_ramp - f, f - (1 - morph_ramp)) /
     * morph_ramp, 0, 1): 1 at whole levels, near the refiner's split
     * distance for a level (looks like the coarser grid), down to 0 over
     * morph_ramp of a level (full detail) and back up over the level's last
     * morph_ramp: continuous in the distance. */
    int morph;                  /* 0 off (morph output all 0) */
    double eye[3];              /* camera position, planet space (metres):
                                   the morph factor and the corner normals'
                                   detail band (plod_detail.h) */
    double morph_lod_scale;     /* metres, >= 0 (0: factor 0 everywhere) */
    double morph_level_rate;    /* levels per halving of distance, > 0 */
    double morph_ramp;          /* (0, 1] */
    /* Detail fade: > 0 makes every vertex's detail band a continuous
     * function of its distance d to `eye` instead of its sector's cells,
     * so the surface changes continuously as the eye moves (no band
     * switching when a sector splits or merges).  d is measured to the
     * vertex on the ground (its height from a first, coarser fade for the
     * distance to the sphere through the ground below the eye), not to the
     * planet's sphere, which lies kilometres below high ground.  A cell of
     * detail_fade_cell * d metres is assumed at the vertex; octave i gets
     * the weight clamp(log2(c_i / cell) + 0.5, 0, 1), c_i the largest cell
     * that keeps it (the surface's octaves_for_cell), i.e. it fades in over
     * one halving of the distance around where a mesh of such cells starts
     * to resolve it.  Heights, normals and detail are the blend of the two
     * whole bands around the weights' sum (a convex mix of partial sums, so
     * inside the field's bounds).  The band depends on the eye: the cache
     * is not used and changed_only is refused.  0: bands by the sector's
     * template cells (see plod__detail_bands in mesh.c). */
    double detail_fade_cell;    /* radians (cell metres per metre), >= 0 */
    plod_mesh_cache *cache;     /* NULL: none (borrowed; see above) */
    /* With a cache: leave out the sectors whose output the cache's last
     * emission already gave (a hit whose corner normals keep their band),
     * so a caller that keeps what that emission wrote updates only what
     * changed (new sectors, and sectors whose corner normals the eye
     * changed); left-out sectors stay cached.  Positions are still
     * relative to this emission's origin.  Needs morph off (the morph
     * moves every vertex with the eye): PLOD_ERR_BAD_PARAM.  Without a
     * cache every sector is emitted. */
    int changed_only;
} plod_mesh_params;

/* Defaults: origin 0, threads 1, no workers, morph off, ramp 0.5, scale =
 * radius, rate 2, no detail fade, no cache. */
void plod_mesh_params_init(plod_mesh_params *params, const plod_planet *planet,
                           int template_level);
/* Surface point nearest the eye: d = eye/|eye|, d * (radius + height(d)),
 * the height from `surface` (every detail octave).  Zero vector when the
 * eye is at the centre or not finite, or surface is NULL. */
void plod_mesh_origin(const plod_surface_source *surface, double radius,
                      const double eye[3], double origin[3]);
/* Morph factor of an (unmorphed) planet-space position; 0 when morph is off
 * or the scale is 0. */
double plod_mesh_morph_factor(const plod_mesh_params *params,
                              const double position[3]);

/* ---- emission ------------------------------------------------------------ */
/* Output buffers, caller-owned; any may be NULL (not written).  Sizes for S
 * emitted sectors (V = plod_mesh_vertex_bound, T = plod_mesh_triangle_bound):
 * positions 3V floats (relative to params.origin), normals 3V (unit, the
 * surface source's at each vertex's direction: for the planet, sampled from
 * its normal map when it has one, else from height differences; see
 * plod_planet_surface), uv
 * 2V (equirectangular: u = lon/2pi + 0.5, v = lat/pi + 0.5, lon unwrapped to
 * within pi of the sector centroid's; vertices at a pole take the centroid's
 * longitude), morph V (applied factor, 0 for even vertices), triangles 3T
 * int32 (indices into this output), sector_level T, face T, detail V (the
 * detail field's part of the vertex's height in metres, over the octaves
 * the vertex keeps: modulation times noise; 0 without detail and on the
 * sea), keys S (each emitted sector's key, plod_mesh_sector.key). */
typedef struct plod_mesh_buffers {
    float *positions;
    float *normals;
    float *uv;
    float *morph;
    int32_t *triangles;
    int32_t *sector_level;
    int32_t *face;
    float *detail;
    uint64_t *keys;
} plod_mesh_buffers;

/* Vertices / triangles for `sector_count` sectors; 0 on a bad level or when
 * the count would not fit int32 indices. */
size_t plod_mesh_vertex_bound(size_t sector_count, int template_level);
size_t plod_mesh_triangle_bound(size_t sector_count, int template_level);

/* Emits every sector `sectors` accepts, in index order, with heights,
 * normals and detail sampled from `surface`, splitting the index
 * range into contiguous chunks over params->threads threads (each writes its
 * own slice).  Allocation: none but the threads without a cache; with
 * params->cache, a slot per emitted sector, the new entries and the
 * cache's table (a failed allocation emits uncached or empties the cache,
 * never fails the emission).  Buffers must hold the bounds for the emitted
 * sector count.  Returns PLOD_ERR_NULL, PLOD_ERR_BAD_PARAM (level, threads,
 * the planet's radius, morph parameters, too many vertices),
 * PLOD_ERR_BAD_COORD (a non-finite origin or eye, or a sector with
 * non-finite or degenerate corners; output then partial).  Counts may be
 * NULL; they are 0 on failure. */
plod_status plod_mesh_emit(const plod_mesh_params *params,
                           const plod_mesh_sector_source *sectors,
                           const plod_surface_source *surface, const plod_mesh_buffers *out,
                           size_t *vertex_count, size_t *triangle_count);
/* Same over a plain array (every sector emitted, each as given: its split
 * fields too, so zero `split` where there is no split morph). */
plod_status plod_mesh_emit_array(const plod_mesh_params *params,
                                 const plod_mesh_sector *sectors, size_t count,
                                 const plod_surface_source *surface,
                                 const plod_mesh_buffers *out,
                                 size_t *vertex_count, size_t *triangle_count);

/* ---- instanced form (GPU path) ---------------------------------------------
 * Per emitted sector: corners 9 floats (unit directions), level 1 float,
 * morph 1 float (the morph factor at the sector's centroid on the surface,
 * its height from `surface`).  Any output may be NULL; no allocation; one
 * thread.  *instance_count (may be NULL) gets the number written.  Statuses
 * as plod_mesh_emit (PLOD_ERR_BAD_COORD stops at the bad sector, earlier
 * instances written). */
plod_status plod_mesh_instances(const plod_mesh_params *params,
                                const plod_mesh_sector_source *sectors,
                                const plod_surface_source *surface, float *corners,
                                float *levels, float *morph, size_t *instance_count);

/* ---- the shared vertex evaluation ------------------------------------------
 * What every LOD method's vertices go through, so that they sample the same
 * surface as the sector emission: heights, normals and detail from the
 * surface source (its sea and detail field included), the detail band of
 * each vertex, positions in double relative to the origin then cast, the
 * equirectangular uv.  A vertex's results are a function of its direction,
 * its cell and the params (origin, eye, detail fade) alone, so a vertex two
 * patches share is bit-identical from both. */
#define PLOD_MESH_SAMPLER_OCTAVES 40 /* = PLOD_DETAIL_MAX_OCTAVES */
typedef struct plod_mesh_sampler {
    const plod_mesh_params *params;   /* borrowed */
    const plod_surface_source *surface; /* borrowed */
    int banded;                       /* the surface limits detail per point */
    int fade_octaves;                 /* detail fade thresholds (see params) */
    double fade_log2_cell[PLOD_MESH_SAMPLER_OCTAVES];
    double fade_ground_radius;        /* metres to the ground below the eye */
} plod_mesh_sampler;

/* Prepares a sampler for `params` (origin, eye, detail_fade_cell read) and
 * `surface`; both must outlive it. */
void plod_mesh_sampler_init(plod_mesh_sampler *sampler, const plod_mesh_params *params,
                            const plod_surface_source *surface);
/* `count` unit directions (3 count doubles) into the outputs (any may be
 * NULL; sizes as plod_mesh_buffers: positions and normals 3 per vertex, uv
 * 2, detail 1; `world` 3 doubles per vertex, the planet-space positions).
 * Detail band per vertex: with params->detail_fade_cell > 0 the fade's
 * (a function of the direction and the eye); else the octaves that cells
 * of cells[i] metres resolve (cells NULL: every octave).  uv longitudes are
 * unwrapped to within pi of lon_ref (radians).  Thread-safe for distinct
 * outputs. */
void plod_mesh_sample(const plod_mesh_sampler *sampler, size_t count, const double *dirs,
                      const double *cells, double lon_ref, float *positions, float *normals,
                      float *uv, float *detail, double *world);
/* atan2(y, x) as the emission's uv computes it (1e-9 rad). */
double plod_mesh_atan2(double y, double x);

#ifdef __cplusplus
}
#endif
#endif /* PLOD_MESH_H */
