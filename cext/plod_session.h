/* plod_session.h -- the one object that owns a planet's per-frame state:
 * the planet, its refiner, its detail field and normal map, the emission
 * cache and the last frame's camera and parameters.  A frame is
 * plod_session_refine (camera -> LOD tree, culling) and then
 * plod_session_emit or plod_session_instances (the refiner's leaves ->
 * the emitter: the sector list in the canonical visible order, the origin
 * under the camera, the morph scale of the refine criterion, the cache).
 * Bindings, benchmarks and fuzzers drive a planet through a session; none
 * of them writes that glue again.
 *
 * The session, as WCSLIB documents a struct (it is opaque; these are what
 * the calls below give and return):
 *   Given, at plod_session_create:
 *     planet   copied; what its pointers reach (height map, height source,
 *              insets, a caller's detail field or normal map) is borrowed
 *              and must outlive the session.
 *     detail   optional detail parameters: the session builds the field
 *              and owns it (else planet->detail, borrowed, as given).
 *   Returned, per frame:
 *     the refiner's leaves and visible order (plod_session_refiner), the
 *     last refine's camera, parameters and statistics.
 *   Private, owned and released by plod_session_destroy:
 *     refiner, detail field (when built here), normal map (when built
 *     here), emission cache, lock.
 *
 * Thread safety: a session is not safe to call from two threads at once.
 * It holds a mutex for its callers to serialise themselves with
 * (plod_session_lock / _trylock / _unlock): a binding that lets several
 * threads reach one planet takes it around every call that reads or writes
 * the session (and around its use of the pointers those calls return).
 * The calls do not take it themselves, so a caller that owns the session
 * alone (a benchmark, a fuzzer) pays nothing.  Emission and refinement run
 * their own threads inside one call.  Every call but plod_session_destroy
 * needs a session (no NULL check).
 */
#ifndef PLOD_SESSION_H
#define PLOD_SESSION_H

#include "plod_chunked.h"
#include "plod_detail.h"
#include "plod_geomipmap.h"
#include "plod_mesh.h"
#include "plod_refine.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct plod_session plod_session; /* opaque */

/* ---- LOD methods ------------------------------------------------------------
 * How a refine selects the surface's patches.  Every method samples the
 * same surface through the same vertex evaluation (plod_mesh_sample:
 * heights, detail field and its fade, normals, uv, origin), culls against
 * the same camera and bounds, and emits plod_mesh_buffers (sector_level =
 * the method's level), so their meshes compare like with like. */
typedef enum plod_lod_method {
    PLOD_LOD_HRTMR = 0,     /* longest-edge bisection of the sectors (default) */
    PLOD_LOD_CHUNKED = 1,   /* chunked LOD on cube-face quadtrees (plod_chunked.h) */
    PLOD_LOD_GEOMIPMAP = 2, /* geomipmapping on cube-face tiles (plod_geomipmap.h) */
    PLOD_LOD_CLIPMAP = 3    /* geometry clipmaps (plod_clipmap.h) */
} plod_lod_method;
#define PLOD_LOD_METHOD_COUNT 4

typedef struct plod_method_params {
    plod_lod_method method;
    int chunked_skirts;  /* chunked: 1 skirts, 0 stitched edge variants */
    int geomipmap_tiles; /* geomipmapping: tiles per cube-face edge, a power
                            of two in 1..PLOD_GEOMIPMAP_MAX_TILES */
    int clipmap_ring_cells; /* clipmaps: a ring's outer radius in its own
                               cells, 24..1024 (plod_clipmap.h) */
} plod_method_params;

/* HRTMR, stitched chunks, 16 geomipmap tiles per face edge, clipmap rings
 * of 32 cells. */
void plod_method_params_default(plod_method_params *params);
/* "hrtmr", "chunked", "geomipmap", "clipmap"; NULL outside the enum. */
const char *plod_lod_method_name(int method);
/* The method named `name`, or -1. */
int plod_lod_method_from_name(const char *name);

/* ---- create / destroy ---------------------------------------------------- */

/* Checks the planet (plod_planet_check), builds the detail field when
 * `detail` is not NULL, and the refiner at the base sectors.  On failure
 * *out is NULL and `message` (may be NULL) says which part was refused:
 * PLOD_ERR_NULL for a NULL out or planet, PLOD_ERR_BAD_IMAGE for height
 * data with NaN texels (plod_planet_nan_count), plod_planet_check's
 * statuses for a bad planet, PLOD_ERR_BAD_PARAM for bad detail parameters,
 * PLOD_ERR_NO_MEMORY.  The mesh cache budget starts at
 * PLOD_MESH_CACHE_DEFAULT_BYTES. */
plod_status plod_session_create(plod_session **out, const plod_planet *planet,
                                const plod_detail_params *detail, char *message,
                                size_t message_size);
/* Releases everything the session owns; NULL is a no-op.  The lock must
 * not be held. */
void plod_session_destroy(plod_session *session);

/* ---- lock (see above) ------------------------------------------------------ */
void plod_session_lock(plod_session *session);
/* 1 when taken, 0 when another thread holds it. */
int plod_session_trylock(plod_session *session);
void plod_session_unlock(plod_session *session);

/* ---- queries (valid until the next call that changes the session) -------- */
/* The session's planet (its normal map and detail field included). */
const plod_planet *plod_session_planet(const plod_session *session);
/* The refiner: its leaves (plod_refiner_sectors) and visible order. */
const plod_refiner *plod_session_refiner(const plod_session *session);
/* The last successful refine's camera; NULL before one and after a reset. */
const plod_camera *plod_session_camera(const plod_session *session);
/* The last successful refine's parameters (plod_refine_params_default
 * before one). */
const plod_refine_params *plod_session_refine_params(const plod_session *session);

/* ---- per frame --------------------------------------------------------------- */

/* plod_refiner_update (stats and error may be NULL); on success the camera
 * and parameters become the session's last.  On failure they stay the
 * previous frame's, *error says why, and the refiner's leaves are as
 * plod_refiner_update leaves them. */
plod_status plod_session_refine(plod_session *session, const plod_camera *camera,
                                const plod_refine_params *params, plod_refine_stats *stats,
                                plod_error *error);
/* The LOD method of the next refines.  PLOD_ERR_BAD_PARAM (with *error,
 * may be NULL) for an unknown method or bad method parameters.  A change of
 * method forgets the last camera (emit then emits nothing until the next
 * refine). */
plod_status plod_session_set_method(plod_session *session, const plod_method_params *params,
                                    plod_error *error);
const plod_method_params *plod_session_method(const plod_session *session);
/* Vertices and triangles an emission of the last refine can write at
 * most (buffer sizes), and the sectors (HRTMR) or patches it emits; 0, 0
 * when they would not fit int32 indices. */
void plod_session_emit_bounds(const plod_session *session, int template_level,
                              int visible_only, size_t *vertices, size_t *triangles,
                              size_t *sectors);

/* Bytes of the LOD method's own state (HRTMR: plod_refiner_memory_bytes;
 * the others: their trees, tables and patch lists), capacities included. */
size_t plod_session_method_bytes(const plod_session *session);

/* Back to the base sectors; forgets the last camera. */
void plod_session_reset(plod_session *session);
/* plod_refiner_reserve. */
plod_status plod_session_reserve(plod_session *session, size_t sectors);

/* Builds the normal map of the planet's height map once, on `threads`
 * threads (a no-op without a height map or with one already, the caller's
 * included), and the bundle of the maps the vertices sample
 * (plod_cubemap_bundle; none where it cannot be made); emissions and
 * plod_planet_surface on the session's planet then sample normals instead
 * of differencing heights.  PLOD_ERR_NO_MEMORY, or
 * plod_cubemap_build_normals' PLOD_ERR_BAD_PARAM for a radius + height
 * offset that is not positive. */
plod_status plod_session_build_normals(plod_session *session, int threads);

/* ---- emission ------------------------------------------------------------------ */

/* Sets the emission's params->morph_lod_scale and morph_level_rate so that the continuous
 * level tracks the refine criterion's split distance of a level-L sector
 * (side = longest corner chord ~ base chord * 2^(-L/2)).  side_distance: split when side/d >
 * split_border, so scale = base side / split_border, rate 2.  pixel: the
 * curvature-sag term of the refiner's error, (side/2^t)^2 / (8 R) *
 * pixels_per_radian / d > max_pixel_error, so scale = base side^2 *
 * pixels_per_radian / (8 R 4^t max_pixel_error), rate 1 (relief makes the
 * refiner split earlier than this predicts; the ramp is an approximation).
 * Either scale is then multiplied by 2^(bias / rate), bias 0.8 levels on
 * the cube and 1.3 for CAR: the refiner measures distance to a bounding
 * cap and forced splits refine further, and the shift puts the measured
 * median sector level mid-ramp.  Base side: the longest corner chord of a
 * level-0 sector extrapolated back from deep levels (radius * 2 sqrt 2
 * sqrt(pi / 6) on the cube, radius * sqrt 2 sqrt pi for CAR).
 * Orthographic cameras, NULL arguments, a bad template level or a
 * non-positive split_border / max_pixel_error: scale 0 (no morph).
 * Returns the scale. */
double plod_session_set_morph_scale(plod_mesh_params *params,
                                    const plod_camera *camera,
                                    const plod_refine_params *refine_params);
/* Returned: emission parameters for the last refine: plod_mesh_params_init
 * for the session's planet, `threads`, and with a last camera the origin
 * on the surface point nearest it, the eye at it, and when `morph` the
 * morph scale of the refine criterion (plod_session_set_morph_scale; morph
 * stays off where that scale is 0) and, for a perspective camera, the detail
 * fade (plod_mesh_params.detail_fade_cell: cells of max_pixel_error
 * pixels), so the surface is a continuous function of the eye.  Values are not checked here:
 * plod_session_emit refuses bad ones.  The caller may adjust the result. */
void plod_session_mesh_params(const plod_session *session, int template_level, int morph,
                              int threads, plod_mesh_params *params);
/* Sectors an emission emits: the visible ones, or every leaf. */
size_t plod_session_sector_count(const plod_session *session, int visible_only);

/* Emits the visible sectors in the canonical visible order (plod_refiner_
 * visible), or every leaf in storage order, through plod_mesh_emit with
 * `params` (params->planet and params->cache are replaced by the session's
 * planet and, when use_cache, its cache, created on first use).  Buffers
 * and counts as plod_mesh_emit; size them with plod_session_sector_count.
 * PLOD_ERR_NULL for NULL params, PLOD_ERR_NO_MEMORY when the cache cannot
 * be created; else plod_mesh_emit's statuses. */
plod_status plod_session_emit(plod_session *session, const plod_mesh_params *params,
                              int visible_only, int use_cache,
                              const plod_mesh_buffers *out, size_t *vertex_count,
                              size_t *triangle_count);
/* plod_mesh_instances over the visible sectors, in the same order (never
 * cached); PLOD_ERR_NULL for NULL params, else its statuses. */
plod_status plod_session_instances(plod_session *session, const plod_mesh_params *params,
                                   float *corners, float *levels, float *morph,
                                   size_t *instance_count);

/* ---- emission cache ------------------------------------------------------------- */
/* The cache's budget (bytes; 0 disables it): kept for the cache's
 * creation, applied at once to an existing one. */
void plod_session_set_cache_max_bytes(plod_session *session, size_t max_bytes);
size_t plod_session_cache_max_bytes(const plod_session *session);
/* The cache's statistics (zero before its first use); max_bytes is the
 * session's budget. */
void plod_session_cache_stats(const plod_session *session, plod_mesh_cache_stats *stats);

#ifdef __cplusplus
}
#endif
#endif /* PLOD_SESSION_H */
