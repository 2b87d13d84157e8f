/* session.c -- one planet's per-frame state and the refiner -> emitter glue
 * (plod_session.h).
 *
 * The glue: the emitter sees a sector as three corner directions, a level,
 * a face and a key; a refiner leaf gives them through plod_sector_corners,
 * its level and face, and its id as the cache key (ids are unique among the
 * leaves and stable while a leaf lives, which is what the cache needs).
 * Visible sectors are emitted in the refiner's canonical visible order, so
 * a mesh does not depend on the order splits and merges left the storage
 * in.  The origin is the surface point under the camera (float32 positions
 * relative to it keep millimetres at a planet's scale), and geomorphing
 * follows the refine criterion's split distance.
 */
#include "plod_clipmap.h"
#include "plod_session.h"
#include "plod_platform.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct plod_session {
    plod_planet planet;        /* copy; normalmap / detail may point below */
    plod_detail *detail;       /* owned, or NULL (planet.detail borrowed) */
    plod_cubemap *normalmap;   /* owned, or NULL */
    plod_cubemap_bundle *bundle; /* owned, or NULL: the maps the vertices sample */
    plod_refiner *refiner;     /* owned; reads &planet */
    plod_mesh_cache *mesh_cache; /* owned; created by the first cached emission */
    plod_workers *mesh_workers; /* owned; emissions' workers while the refiner has none */
    size_t mesh_cache_max_bytes;
    plod_camera camera;        /* last refine's */
    plod_refine_params params;
    int has_camera;
    plod_method_params method;
    plod_chunked *chunked;     /* owned; created by the first chunked refine */
    plod_geomipmap *geomipmap; /* owned; created by the first geomipmap refine */
    plod_clipmap *clipmap;     /* owned; created by the first clipmap refine */
    plod_split_morph *split_morphs; /* owned: the morphing emission's per sector */
    size_t split_morph_capacity;
    plod_mutex lock;
};

/* ---- LOD methods ------------------------------------------------------------------ */

static const char *const plod__method_names[PLOD_LOD_METHOD_COUNT] = {"hrtmr", "chunked",
                                                                      "geomipmap", "clipmap"};

void plod_method_params_default(plod_method_params *params)
{
    params->method = PLOD_LOD_HRTMR;
    params->chunked_skirts = 0;
    params->geomipmap_tiles = 16;
    params->clipmap_ring_cells = 32;
}

const char *plod_lod_method_name(int method)
{
    return method >= 0 && method < PLOD_LOD_METHOD_COUNT ? plod__method_names[method] : NULL;
}

int plod_lod_method_from_name(const char *name)
{
    for (int m = 0; name && m < PLOD_LOD_METHOD_COUNT; m++)
        if (!strcmp(name, plod__method_names[m]))
            return m;
    return -1;
}

static void plod__session_message(char *message, size_t size, const char *text)
{
    if (message && size)
        snprintf(message, size, "%s", text);
}

/* ---- create / destroy ------------------------------------------------------ */

plod_status plod_session_create(plod_session **out, const plod_planet *planet,
                                const plod_detail_params *detail, char *message,
                                size_t message_size)
{
    plod__session_message(message, message_size, "");
    if (!out)
        return PLOD_ERR_NULL;
    *out = NULL;
    if (!planet)
        return PLOD_ERR_NULL;
    plod_session *s = calloc(1, sizeof *s);
    if (!s)
        return PLOD_ERR_NO_MEMORY;
    if (!plod_mutex_init(&s->lock)) {
        free(s);
        return PLOD_ERR_NO_MEMORY;
    }
    s->planet = *planet;
    plod_status st = PLOD_OK;
    size_t nan_texels = plod_planet_nan_count(&s->planet);
    if (nan_texels != 0) {
        if (message && message_size)
            snprintf(message, message_size,
                     "height map has %zu NaN samples (no-data texels); fill them before "
                     "using it as a height map",
                     nan_texels);
        plod_session_destroy(s);
        return PLOD_ERR_BAD_IMAGE;
    }
    /* the planet's checks say which rule failed; the refiner checks again */
    plod_error error = {PLOD_OK, ""};
    st = plod_planet_check(&s->planet, &error);
    if (st == PLOD_OK && detail) {
        st = plod_detail_create(&s->detail, detail, &s->planet);
        if (st == PLOD_ERR_BAD_PARAM)
            plod_error_set(&error, st,
                           "invalid detail (amplitude in [0, 1e6], roughness in [0, 1), "
                           "largest >= 0, smallest > 0, craters in [0, 4], crater_density "
                           "and plains in [0, 1], relief >= 0, hills in [plains, 1], "
                           "highlands >= 0, fine_roughness in [0, 1), fine_below >= 0)");
        else if (st != PLOD_OK)
            plod_error_set(&error, st, "detail field");
        if (st == PLOD_OK) {
            s->planet.detail = s->detail;
            st = plod_planet_check(&s->planet, &error);
        }
    }
    if (st == PLOD_OK) {
        st = plod_refiner_create(&s->refiner, &s->planet);
        if (st != PLOD_OK)
            plod_error_set(&error, st, "%s", plod_status_message(st));
    }
    if (st != PLOD_OK) {
        plod__session_message(message, message_size, error.message);
        plod_session_destroy(s);
        return st;
    }
    plod_refine_params_default(&s->params);
    plod_method_params_default(&s->method);
    s->mesh_cache_max_bytes = PLOD_MESH_CACHE_DEFAULT_BYTES;
    *out = s;
    return PLOD_OK;
}

void plod_session_destroy(plod_session *session)
{
    if (!session)
        return;
    plod_refiner_destroy(session->refiner);
    plod_chunked_destroy(session->chunked);
    plod_geomipmap_destroy(session->geomipmap);
    plod_clipmap_destroy(session->clipmap);
    plod_mesh_cache_destroy(session->mesh_cache);
    plod_workers_destroy(session->mesh_workers);
    plod_cubemap_bundle_destroy(session->bundle);
    plod_cubemap_destroy(session->normalmap);
    plod_detail_destroy(session->detail);
    free(session->split_morphs);
    plod_mutex_destroy(&session->lock);
    free(session);
}

/* ---- lock ---------------------------------------------------------------------- */

void plod_session_lock(plod_session *session)
{
    plod_mutex_lock(&session->lock);
}

int plod_session_trylock(plod_session *session)
{
    return plod_mutex_trylock(&session->lock);
}

void plod_session_unlock(plod_session *session)
{
    plod_mutex_unlock(&session->lock);
}

/* ---- queries ---------------------------------------------------------------------- */

const plod_planet *plod_session_planet(const plod_session *session)
{
    return &session->planet;
}

const plod_refiner *plod_session_refiner(const plod_session *session)
{
    return session->refiner;
}

const plod_camera *plod_session_camera(const plod_session *session)
{
    return session->has_camera ? &session->camera : NULL;
}

const plod_refine_params *plod_session_refine_params(const plod_session *session)
{
    return &session->params;
}

/* ---- per frame ---------------------------------------------------------------------- */

plod_status plod_session_set_method(plod_session *session, const plod_method_params *params,
                                    plod_error *error)
{
    if (!params)
        return plod_error_set(error, PLOD_ERR_NULL, "missing method parameters");
    if (!plod_lod_method_name((int)params->method))
        return plod_error_set(error, PLOD_ERR_BAD_PARAM,
                              "method must be hrtmr, chunked, geomipmap or clipmap");
    if (params->chunked_skirts != 0 && params->chunked_skirts != 1)
        return plod_error_set(error, PLOD_ERR_BAD_PARAM,
                              "chunked cracks must be stitched (0) or skirts (1)");
    int tiles = params->geomipmap_tiles;
    if (tiles < 1 || tiles > PLOD_GEOMIPMAP_MAX_TILES || (tiles & (tiles - 1)))
        return plod_error_set(error, PLOD_ERR_BAD_PARAM,
                              "geomipmap_tiles must be a power of two in 1..%d",
                              PLOD_GEOMIPMAP_MAX_TILES);
    /* ---- clipmap dispatch point: the clipmap module's parameters ---- */
    if (params->clipmap_ring_cells < 24 || params->clipmap_ring_cells > 1024)
        return plod_error_set(error, PLOD_ERR_BAD_PARAM,
                              "clipmap_ring_cells must be 24..1024 (got %d)",
                              params->clipmap_ring_cells);
    if (params->method != session->method.method ||
        params->chunked_skirts != session->method.chunked_skirts ||
        params->geomipmap_tiles != session->method.geomipmap_tiles ||
        params->clipmap_ring_cells != session->method.clipmap_ring_cells)
        session->has_camera = 0;
    session->method = *params;
    return PLOD_OK;
}

const plod_method_params *plod_session_method(const plod_session *session)
{
    return &session->method;
}

size_t plod_session_method_bytes(const plod_session *session)
{
    switch (session->method.method) {
    case PLOD_LOD_CHUNKED:
        return session->chunked ? plod_chunked_memory_bytes(session->chunked) : 0;
    case PLOD_LOD_GEOMIPMAP:
        return session->geomipmap ? plod_geomipmap_memory_bytes(session->geomipmap) : 0;
    case PLOD_LOD_CLIPMAP:
        return plod_clipmap_memory_bytes(session->clipmap);
    default:
        return plod_refiner_memory_bytes(session->refiner);
    }
}

plod_status plod_session_refine(plod_session *session, const plod_camera *camera,
                                const plod_refine_params *params, plod_refine_stats *stats,
                                plod_error *error)
{
    plod_refine_stats frame;
    plod_status st;
    switch (session->method.method) {
    case PLOD_LOD_CHUNKED:
        if (!session->chunked && plod_chunked_create(&session->chunked) != PLOD_OK)
            return plod_error_set(error, PLOD_ERR_NO_MEMORY, "chunked: out of memory");
        st = plod_chunked_refine(session->chunked, &session->planet, camera, params,
                                 session->method.chunked_skirts, &frame, error);
        break;
    case PLOD_LOD_GEOMIPMAP:
        if (!session->geomipmap && plod_geomipmap_create(&session->geomipmap) != PLOD_OK)
            return plod_error_set(error, PLOD_ERR_NO_MEMORY, "geomipmap: out of memory");
        st = plod_geomipmap_refine(session->geomipmap, &session->planet, camera, params,
                                   session->method.geomipmap_tiles, &frame, error);
        break;
    case PLOD_LOD_CLIPMAP: {
        /* ---- clipmap dispatch point (plod_clipmap.h): the refine's pixel
         * error, culling and level limit (one clipmap level per two
         * bisection levels), template_level as the culling blocks ---- */
        if (params->template_level > PLOD_CLIPMAP_MAX_BLOCK_LEVEL)
            return plod_error_set(error, PLOD_ERR_BAD_PARAM,
                                  "the clipmap's culling blocks (2^template_level cells a "
                                  "side) take template_level 0..%d",
                                  PLOD_CLIPMAP_MAX_BLOCK_LEVEL);
        if (!session->clipmap && plod_clipmap_create(&session->clipmap) != PLOD_OK)
            return plod_error_set(error, PLOD_ERR_NO_MEMORY, "clipmap: out of memory");
        plod_clipmap_params cp;
        plod_clipmap_params_default(&cp);
        cp.ring_cells = session->method.clipmap_ring_cells;
        cp.max_pixel_error = params->max_pixel_error;
        cp.max_level = params->max_level / 2 < PLOD_CLIPMAP_MAX_LEVEL ? params->max_level / 2
                                                                       : PLOD_CLIPMAP_MAX_LEVEL;
        cp.block_level = params->template_level;
        cp.backface = params->backface_culling;
        cp.frustum = params->frustum_culling;
        plod_surface_source surface = plod_planet_surface_source(&session->planet);
        plod_clipmap_stats cs;
        st = plod_clipmap_update(session->clipmap, &session->planet, &surface, camera, &cp, &cs,
                                 error);
        if (st == PLOD_OK) {
            memset(&frame, 0, sizeof frame);
            frame.sectors_total = cs.blocks;
            frame.sectors_after_backface = frame.sectors_after_frustum = cs.blocks_visible;
            frame.sectors_after_budget = cs.blocks_visible;
            frame.splits = cs.cells_refreshed; /* leaf cells new this frame */
            frame.max_level_reached = cs.finest_level;
            frame.refine_us = cs.update_us;
        }
        break;
    }
    default:
        st = plod_refiner_update(session->refiner, camera, params, &frame, error);
        break;
    }
    if (st != PLOD_OK) {
        if (session->method.method != PLOD_LOD_HRTMR)
            session->has_camera = 0; /* the patches are not this camera's */
        return st;
    }
    session->camera = *camera;
    session->params = *params;
    session->has_camera = 1;
    if (stats)
        *stats = frame;
    return PLOD_OK;
}

void plod_session_reset(plod_session *session)
{
    plod_refiner_reset(session->refiner);
    plod_clipmap_reset(session->clipmap);
    session->has_camera = 0;
}

plod_status plod_session_reserve(plod_session *session, size_t sectors)
{
    return plod_refiner_reserve(session->refiner, sectors);
}

plod_status plod_session_build_normals(plod_session *session, int threads)
{
    if (!session->planet.heightmap || session->planet.normalmap)
        return PLOD_OK;
    plod_status st = plod_planet_build_normals(&session->planet, &session->normalmap, threads);
    if (st != PLOD_OK)
        return st;
    session->planet.normalmap = session->normalmap;
    /* the height, normal and modulation maps interleaved for the vertices:
     * where it cannot be made, they are sampled map by map */
    const plod_cubemap *modulation =
        session->planet.detail ? plod_detail_modulation(session->planet.detail) : NULL;
    if (plod_cubemap_bundle_create(&session->bundle, session->planet.heightmap,
                                   session->normalmap, modulation) == PLOD_OK)
        session->planet.bundle = session->bundle;
    return PLOD_OK;
}

/* ---- emission ------------------------------------------------------------------------ */

/* The refiner's leaves as the emitter's sector source. */
typedef struct plod__leaf_source {
    const plod_planet *planet;
    const plod_sector *sectors;
    const uint32_t *order; /* NULL: storage order */
    const plod_split_morph *split; /* per index, or NULL: no split morph */
} plod__leaf_source;

static int plod__leaf_sector(const void *context, size_t index, plod_mesh_sector *out)
{
    const plod__leaf_source *src = context;
    const plod_sector *s = &src->sectors[src->order ? src->order[index] : index];
    if (out) {
        plod_sector_corners(src->planet, s, out->corners);
        out->level = s->level;
        out->face = s->face;
        out->key = s->id;
        out->split = src->split ? &src->split[index] : NULL;
    }
    return 1;
}

/* The sector source over `leaves` (which it points into). */
static plod_mesh_sector_source plod__leaf_source_init(const plod_session *session,
                                                      int visible_only,
                                                      plod__leaf_source *leaves)
{
    size_t count, visible;
    leaves->planet = &session->planet;
    leaves->sectors = plod_refiner_sectors(session->refiner, &count);
    leaves->order = plod_refiner_visible(session->refiner, &visible);
    leaves->split = NULL;
    if (!visible_only)
        leaves->order = NULL;
    plod_mesh_sector_source source = {plod__leaf_sector, leaves,
                                      visible_only ? visible : count};
    return source;
}

static int plod__template_level_ok(int template_level)
{
    return template_level >= 0 && template_level <= PLOD_MAX_TEMPLATE_LEVEL;
}

/* Size of a level-0 sector as the refiner measures it (the longest corner
 * chord), extrapolated back from deep levels where it halves every two
 * bisections: the hypotenuse in face units times the equal-area scale of
 * the face domain (cube: 2 sqrt 2 units, 4 units^2 per 4 pi/6 sr;
 * octahedral square: sqrt 2 units, 1/2 unit^2 per 4 pi/8 sr). */
static double plod__base_side(const plod_planet *planet)
{
    double size = planet->projection == PLOD_PROJ_CAR
                      ? sqrt(2.0) * sqrt(PLOD_PI)
                      : 2.0 * sqrt(2.0) * sqrt(PLOD_PI / 6.0);
    return planet->radius * size;
}

double plod_session_set_morph_scale(plod_mesh_params *params,
                                    const plod_camera *camera,
                                    const plod_refine_params *refine_params)
{
    if (!params)
        return 0.0;
    params->morph_lod_scale = 0.0;
    params->morph_level_rate = 2.0;
    const plod_planet *planet = params->planet;
    if (!planet || !camera || !refine_params || !plod__template_level_ok(params->template_level))
        return 0.0;
    if (camera->desc.orthographic)
        return 0.0;
    double side = plod__base_side(planet);
    double scale;
    if (refine_params->criterion == PLOD_CRITERION_SIDE_DISTANCE) {
        if (!(refine_params->split_border > 0.0))
            return 0.0;
        scale = side / refine_params->split_border;
    } else {
        if (!(refine_params->max_pixel_error > 0.0))
            return 0.0;
        double cells = (double)(1 << params->template_level);
        scale = side * side * camera->pixels_per_radian /
                (8.0 * planet->radius * cells * cells * refine_params->max_pixel_error);
        params->morph_level_rate = 1.0;
    }
    /* The refiner measures distance to a bounding cap (nearer than the
     * vertices) and forced splits refine further: measured on an Earth-size
     * sphere, median(sector level - L) was 1.3 levels (cube) and 1.8 (CAR)
     * for both criteria; shift L so that the median is 0.5, mid-ramp. */
    double bias = planet->projection == PLOD_PROJ_CAR ? 1.3 : 0.8;
    scale *= exp2(bias / params->morph_level_rate);
    params->morph_lod_scale = isfinite(scale) && scale > 0.0 ? scale : 0.0;
    return params->morph_lod_scale;
}

/* The fade keeps the octaves cells of one pixel per pixel of allowed error
 * resolve: what it drops then stands out by less than that error (finer
 * than the refiner's cells, whose choice assumed the octaves they keep). */
#define PLOD__FADE_CELL_PIXELS 1.0

void plod_session_mesh_params(const plod_session *session, int template_level, int morph,
                              int threads, plod_mesh_params *params)
{
    plod_mesh_params_init(params, &session->planet, template_level);
    params->threads = threads;
    if (session->has_camera) {
        const plod_camera *camera = &session->camera;
        plod_surface_source surface = plod_planet_surface_source(&session->planet);
        plod_mesh_origin(&surface, session->planet.radius, camera->position, params->origin);
        for (int c = 0; c < 3; c++)
            params->eye[c] = camera->position[c];
        int patches = session->method.method != PLOD_LOD_HRTMR;
        if (patches && !camera->desc.orthographic && camera->pixels_per_radian > 0.0 &&
            session->params.max_pixel_error > 0.0)
            /* the patch methods' vertices take their detail band from the
             * fade (a function of the direction and the eye), so that
             * patches of any level agree where they meet */
            params->detail_fade_cell = PLOD__FADE_CELL_PIXELS *
                                       session->params.max_pixel_error /
                                       camera->pixels_per_radian;
        if (morph) {
            params->morph =
                plod_session_set_morph_scale(params, camera, &session->params) > 0.0;
            if (patches) /* one quadtree level per two bisection levels */
                params->morph_level_rate *= 0.5;
            /* detail fades with distance (perspective cameras) */
            if (!camera->desc.orthographic && camera->pixels_per_radian > 0.0 &&
                session->params.max_pixel_error > 0.0)
                params->detail_fade_cell = PLOD__FADE_CELL_PIXELS *
                                           session->params.max_pixel_error /
                                           camera->pixels_per_radian;
        }
    }
}

/* The last refine's patches of a patch method (NULL, 0 for HRTMR). */
static const plod_face_tile *plod__method_tiles(const plod_session *session, size_t *count)
{
    *count = 0;
    if (!session->has_camera)
        return NULL;
    switch (session->method.method) {
    case PLOD_LOD_CHUNKED:
        return session->chunked ? plod_chunked_tiles(session->chunked, count) : NULL;
    case PLOD_LOD_GEOMIPMAP:
        return session->geomipmap ? plod_geomipmap_tiles(session->geomipmap, count) : NULL;
    /* ---- clipmap dispatch point: its patch count (sector_count),
     * bounds (plod_session_emit_bounds) and emission (plod_session_emit)
     * go beside the tile methods' (plod_clipmap.h) ---- */
    default:
        return NULL;
    }
}

size_t plod_session_sector_count(const plod_session *session, int visible_only)
{
    if (session->method.method == PLOD_LOD_CLIPMAP)
        return session->has_camera ? plod_clipmap_block_count(session->clipmap) : 0;
    if (session->method.method != PLOD_LOD_HRTMR) {
        size_t count;
        plod__method_tiles(session, &count);
        return count;
    }
    plod__leaf_source leaves;
    return plod__leaf_source_init(session, visible_only, &leaves).count;
}

void plod_session_emit_bounds(const plod_session *session, int template_level,
                              int visible_only, size_t *vertices, size_t *triangles,
                              size_t *sectors)
{
    size_t count = plod_session_sector_count(session, visible_only);
    *sectors = count;
    if (session->method.method == PLOD_LOD_CLIPMAP) {
        *vertices = session->has_camera ? plod_clipmap_vertex_count(session->clipmap) : 0;
        *triangles = session->has_camera ? plod_clipmap_triangle_count(session->clipmap) : 0;
        return;
    }
    if (session->method.method != PLOD_LOD_HRTMR) {
        size_t n;
        const plod_face_tile *tiles = plod__method_tiles(session, &n);
        plod_facetiles_bound(tiles, n,
                             session->method.method == PLOD_LOD_CHUNKED &&
                                 session->method.chunked_skirts,
                             vertices, triangles);
        return;
    }
    *vertices = plod_mesh_vertex_bound(count, template_level);
    *triangles = plod_mesh_triangle_bound(count, template_level);
}

/* Persistent workers for an emission on `threads` threads, as many as
 * that (called under the session's lock): the refiner's, else the
 * session's own, started by the first such emission and kept until the
 * count changes; NULL for one thread or when none can start (the
 * emission then starts threads of its own). */
static plod_workers *plod__emission_workers(plod_session *session, int threads)
{
    if (threads < 2)
        return NULL;
    plod_workers *refiner_workers = plod_refiner_workers(session->refiner);
    if (refiner_workers && plod_workers_threads(refiner_workers) == threads)
        return refiner_workers;
    if (session->mesh_workers && plod_workers_threads(session->mesh_workers) != threads) {
        plod_workers_destroy(session->mesh_workers);
        session->mesh_workers = NULL;
    }
    if (!session->mesh_workers && threads <= PLOD_MAX_THREADS &&
        plod_workers_create(&session->mesh_workers, threads) != PLOD_OK)
        session->mesh_workers = NULL;
    return session->mesh_workers;
}

/* A patch method's emission: its tiles through the shared tile emitter. */
static plod_status plod__emit_patches(plod_session *session, plod_mesh_params *mp,
                                      const plod_mesh_buffers *out, size_t *vertex_count,
                                      size_t *triangle_count)
{
    if (vertex_count)
        *vertex_count = 0;
    if (triangle_count)
        *triangle_count = 0;
    /* the patches' grids are the refine's: another level, or an emission
     * of changes only (no cache), cannot be honoured */
    if (mp->changed_only ||
        (session->has_camera && mp->template_level != session->params.template_level))
        return PLOD_ERR_BAD_PARAM;
    if (session->method.method == PLOD_LOD_CLIPMAP) {
        /* ---- clipmap dispatch point (plod_clipmap.h) ---- */
        if (!session->has_camera)
            return PLOD_OK;
        mp->workers = plod__emission_workers(session, mp->threads);
        plod_surface_source surface = plod_planet_surface_source(&session->planet);
        plod_workers_begin(mp->workers);
        plod_status st = plod_clipmap_emit(session->clipmap, mp, &surface, out, vertex_count,
                                           triangle_count);
        plod_workers_end(mp->workers);
        return st;
    }
    size_t count;
    const plod_face_tile *tiles = plod__method_tiles(session, &count);
    const plod_camera *camera = session->has_camera ? &session->camera : NULL;
    plod_facetiles_emission options;
    memset(&options, 0, sizeof options);
    options.projection = session->planet.projection;
    options.skirts =
        session->method.method == PLOD_LOD_CHUNKED && session->method.chunked_skirts;
    options.morph = mp->morph && session->method.method == PLOD_LOD_CHUNKED;
    options.drop_sea = session->method.method == PLOD_LOD_GEOMIPMAP &&
                       session->params.skip_sea && session->planet.has_sea_level;
    options.sea_level = session->planet.sea_level;
    if (camera && camera->desc.orthographic && camera->pixels_per_metre > 0.0)
        options.ortho_cell = session->params.max_pixel_error / camera->pixels_per_metre;
    mp->workers = plod__emission_workers(session, mp->threads);
    plod_surface_source surface = plod_planet_surface_source(&session->planet);
    plod_workers_begin(mp->workers);
    plod_status st = plod_facetiles_emit(mp, &surface, &options, tiles, count, out,
                                         vertex_count, triangle_count);
    plod_workers_end(mp->workers);
    return st;
}

plod_status plod_session_emit(plod_session *session, const plod_mesh_params *params,
                              int visible_only, int use_cache,
                              const plod_mesh_buffers *out, size_t *vertex_count,
                              size_t *triangle_count)
{
    if (!params)
        return PLOD_ERR_NULL;
    plod_mesh_params mp = *params;
    mp.planet = &session->planet;
    mp.cache = NULL;
    if (session->method.method != PLOD_LOD_HRTMR)
        return plod__emit_patches(session, &mp, out, vertex_count, triangle_count);
    mp.workers = plod__emission_workers(session, mp.threads);
    if (use_cache) {
        if (!session->mesh_cache &&
            plod_mesh_cache_create(&session->mesh_cache, session->mesh_cache_max_bytes) !=
                PLOD_OK)
            return PLOD_ERR_NO_MEMORY;
        mp.cache = session->mesh_cache;
    }
    plod__leaf_source leaves;
    plod_mesh_sector_source sectors = plod__leaf_source_init(session, visible_only, &leaves);
    if (mp.morph && session->has_camera && !session->camera.desc.orthographic) {
        /* the split morph, from the last refine's split test (plod_refine.h) */
        if (sectors.count > session->split_morph_capacity) {
            plod_split_morph *grown =
                realloc(session->split_morphs, sectors.count * sizeof *grown);
            if (!grown)
                return PLOD_ERR_NO_MEMORY;
            session->split_morphs = grown;
            session->split_morph_capacity = sectors.count;
        }
        plod_status st = plod_refiner_split_morphs(session->refiner, &session->camera,
                                                   &session->params, leaves.order,
                                                   sectors.count, session->split_morphs);
        if (st != PLOD_OK)
            return st;
        leaves.split = session->split_morphs;
    }
    plod_surface_source surface = plod_planet_surface_source(&session->planet);
    /* the workers spin from here (the emission's setup) to its loops, and
     * linger after it for the next call */
    plod_workers_begin(mp.workers);
    plod_status st = plod_mesh_emit(&mp, &sectors, &surface, out, vertex_count, triangle_count);
    plod_workers_end(mp.workers);
    return st;
}

plod_status plod_session_instances(plod_session *session, const plod_mesh_params *params,
                                   float *corners, float *levels, float *morph,
                                   size_t *instance_count)
{
    if (!params)
        return PLOD_ERR_NULL;
    if (session->method.method != PLOD_LOD_HRTMR)
        return PLOD_ERR_BAD_PARAM; /* the instanced form is HRTMR's sectors */
    plod_mesh_params mp = *params;
    mp.planet = &session->planet;
    mp.cache = NULL;
    plod__leaf_source leaves;
    plod_mesh_sector_source sectors = plod__leaf_source_init(session, 1, &leaves);
    plod_surface_source surface = plod_planet_surface_source(&session->planet);
    return plod_mesh_instances(&mp, &sectors, &surface, corners, levels, morph,
                               instance_count);
}

/* ---- emission cache ----------------------------------------------------------------------- */

void plod_session_set_cache_max_bytes(plod_session *session, size_t max_bytes)
{
    session->mesh_cache_max_bytes = max_bytes;
    plod_mesh_cache_set_max_bytes(session->mesh_cache, max_bytes);
}

size_t plod_session_cache_max_bytes(const plod_session *session)
{
    return session->mesh_cache_max_bytes;
}

void plod_session_cache_stats(const plod_session *session, plod_mesh_cache_stats *stats)
{
    plod_mesh_cache_get_stats(session->mesh_cache, stats);
    stats->max_bytes = session->mesh_cache_max_bytes;
}
