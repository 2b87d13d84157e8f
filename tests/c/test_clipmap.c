/* test_clipmap.c -- the geometry clipmap through the C core: a closed
 * surface (welded by position, every edge in exactly two triangles) from
 * orbit to 2 m on every cube projection, the same output for any thread
 * count, an incremental update equal to a build from scratch, culled
 * output whose open edges all lie out of view, and bad parameters
 * refused.  Prints per-frame counts and "passed". */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "plod.h"
#include "plod_clipmap.h"
#include "plod_session.h"
#include "test_support.h"

#define FRAMES 24
#define MAP_SIZE 128
#define RADIUS 6371000.0

static int failures = 0;
#define CHECK(cond, ...)                                                  \
    do {                                                                  \
        if (!(cond)) {                                                    \
            failures++;                                                   \
            printf("FAIL %s:%d: ", __FILE__, __LINE__);                   \
            printf(__VA_ARGS__);                                          \
            printf("\n");                                                 \
        }                                                                 \
    } while (0)

static plod_cubemap *make_heightmap(void)
{
    plod_cubemap *map = NULL;
    if (plod_cubemap_create(&map, PLOD_PROJ_QSC, MAP_SIZE, 1, PLOD_TEXEL_U16) != PLOD_OK)
        return NULL;
    for (int face = 0; face < 6; face++) {
        uint16_t *texels = plod_cubemap_face_data(map, face);
        for (int j = 0; j < MAP_SIZE; j++)
            for (int i = 0; i < MAP_SIZE; i++) {
                uint32_t a = test_mix32((uint32_t)(face * 7919 + (i >> 3) * 131 + (j >> 3)));
                uint32_t b = test_mix32((uint32_t)(face * 104729 + i * 31 + j));
                texels[(size_t)j * MAP_SIZE + (size_t)i] =
                    (uint16_t)((a >> 17) + (b >> 20));
            }
    }
    if (plod_cubemap_build_pyramid(map) != PLOD_OK) {
        plod_cubemap_destroy(map);
        return NULL;
    }
    return map;
}

/* Frame k of a descent from 20,000 km to 2 m above the highest terrain,
 * pitching up from straight down to 10 degrees below the horizon, near a
 * cube corner and edge (lat 34, lon 44) so rings cross faces. */
static void descent(int k, double top, double lon_shift, plod_camera *camera,
                    const plod_planet *planet)
{
    const double pi = 3.14159265358979323846;
    double lat = 34.0 * pi / 180.0, lon0 = (44.0 + lon_shift) * pi / 180.0;
    double t = (double)k / (FRAMES - 1);
    double alt = exp(log(2e7) * (1 - t) + log(2.0) * t);
    double lon = lon0 + 0.002 * t;
    double d[3] = {cos(lat) * cos(lon), cos(lat) * sin(lon), sin(lat)};
    double east[3] = {-sin(lon), cos(lon), 0.0};
    double pitch = (-90.0 + 80.0 * (t * 1.25 < 1.0 ? t * 1.25 : 1.0)) * pi / 180.0;
    double eye[3], target[3], m[16];
    for (int i = 0; i < 3; i++) {
        double view = east[i] * cos(pitch) + d[i] * sin(pitch);
        eye[i] = d[i] * (RADIUS + top + alt);
        target[i] = eye[i] + view;
    }
    double north[3] = {-sin(lat) * cos(lon), -sin(lat) * sin(lon), cos(lat)};
    test_look_at(eye, target, fabs(pitch) < 89.0 * pi / 180.0 ? d : north, m);
    plod_camera_desc desc;
    plod_camera_desc_default(&desc);
    memcpy(desc.matrix_world, m, sizeof m);
    desc.clip_start = 0.1;
    desc.clip_end = 1e12;
    plod_camera_init(camera, &desc);
    plod_recommended_clip(planet, camera, &desc.clip_start, &desc.clip_end);
    plod_camera_init(camera, &desc);
}

typedef struct mesh {
    plod_mesh_buffers b;
    size_t nv, nt;
    uint64_t hash;
} mesh;

static void mesh_free(mesh *m)
{
    free(m->b.positions), free(m->b.normals), free(m->b.uv), free(m->b.morph);
    free(m->b.triangles), free(m->b.sector_level), free(m->b.face), free(m->b.detail);
    memset(m, 0, sizeof *m);
}

/* Emission options as a session gives them: morph, and the detail fade
 * (cells of one pixel) or the rings' own bands. */
static int morph_on = 1, fade_on = 1;

static int emit(const plod_clipmap *cm, const plod_planet *planet,
                const plod_surface_source *surface, const plod_camera *camera,
                const double origin[3], int threads, mesh *m)
{
    plod_mesh_params mp;
    plod_mesh_params_init(&mp, planet, 0);
    memcpy(mp.origin, origin, sizeof mp.origin);
    memcpy(mp.eye, camera->position, sizeof mp.eye);
    mp.threads = threads;
    mp.morph = morph_on;
    mp.detail_fade_cell = fade_on ? 1.0 / camera->pixels_per_radian : 0.0;
    memset(m, 0, sizeof *m);
    size_t v = plod_clipmap_vertex_count(cm), t = plod_clipmap_triangle_count(cm);
    size_t vc = v ? v : 1, tc = t ? t : 1;
    m->b.positions = malloc(12 * vc), m->b.normals = malloc(12 * vc), m->b.uv = malloc(8 * vc);
    m->b.morph = malloc(4 * vc), m->b.triangles = malloc(12 * tc);
    m->b.sector_level = malloc(4 * tc), m->b.face = malloc(4 * tc), m->b.detail = malloc(4 * vc);
    if (plod_clipmap_emit(cm, &mp, surface, &m->b, &m->nv, &m->nt) != PLOD_OK)
        return 0;
    uint64_t h = TEST_FNV_OFFSET;
    h = test_fnv1a(m->b.positions, 12 * m->nv, h);
    h = test_fnv1a(m->b.normals, 12 * m->nv, h);
    h = test_fnv1a(m->b.uv, 8 * m->nv, h);
    h = test_fnv1a(m->b.morph, 4 * m->nv, h);
    h = test_fnv1a(m->b.detail, 4 * m->nv, h);
    h = test_fnv1a(m->b.triangles, 12 * m->nt, h);
    h = test_fnv1a(m->b.sector_level, 4 * m->nt, h);
    h = test_fnv1a(m->b.face, 4 * m->nt, h);
    m->hash = h;
    return 1;
}

/* ---- welding ---------------------------------------------------------------- */

static int compare_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

typedef struct weld {
    uint32_t *id;   /* welded id per vertex */
    uint64_t *open; /* open edges (id pairs), n_open of them */
    size_t n_open, n_over; /* edges in one triangle; edges in three or more */
} weld;

static void weld_free(weld *w)
{
    free(w->id), free(w->open);
    memset(w, 0, sizeof *w);
}

/* Welds vertices with bit-equal positions; counts edges by triangles. */
static void weld_mesh(const mesh *m, weld *w)
{
    memset(w, 0, sizeof *w);
    size_t slots = 16;
    while (slots < 2 * m->nv)
        slots *= 2;
    int64_t *table = malloc(slots * sizeof *table);
    for (size_t s = 0; s < slots; s++)
        table[s] = -1;
    w->id = malloc((m->nv ? m->nv : 1) * sizeof *w->id);
    uint32_t next = 0;
    uint32_t *first = malloc((m->nv ? m->nv : 1) * sizeof *first); /* id -> vertex */
    for (size_t v = 0; v < m->nv; v++) {
        const float *p = m->b.positions + 3 * v;
        size_t s = (size_t)test_fnv1a(p, 12, TEST_FNV_OFFSET) & (slots - 1);
        while (table[s] >= 0 && memcmp(m->b.positions + 3 * first[table[s]], p, 12) != 0)
            s = (s + 1) & (slots - 1);
        if (table[s] < 0) {
            first[next] = (uint32_t)v;
            table[s] = next++;
        }
        w->id[v] = (uint32_t)table[s];
    }
    uint64_t *edges = malloc((m->nt ? 3 * m->nt : 1) * sizeof *edges);
    size_t ne = 0;
    for (size_t t = 0; t < m->nt; t++)
        for (int k = 0; k < 3; k++) {
            uint32_t a = w->id[m->b.triangles[3 * t + k]];
            uint32_t b = w->id[m->b.triangles[3 * t + (k + 1) % 3]];
            if (a == b)
                continue;
            uint32_t lo = a < b ? a : b, hi = a < b ? b : a;
            edges[ne++] = ((uint64_t)lo << 32) | hi;
        }
    qsort(edges, ne, sizeof *edges, compare_u64);
    w->open = malloc((ne ? ne : 1) * sizeof *w->open);
    for (size_t e = 0; e < ne;) {
        size_t f = e;
        while (f < ne && edges[f] == edges[e])
            f++;
        if (f - e == 1)
            w->open[w->n_open++] = edges[e];
        else if (f - e > 2)
            w->n_over++;
        e = f;
    }
    free(edges), free(table), free(first);
}

/* ---- the checks ---------------------------------------------------------------- */

static plod_session *make_session(plod_projection projection, const plod_cubemap *map)
{
    plod_planet planet;
    memset(&planet, 0, sizeof planet);
    planet.radius = RADIUS;
    planet.projection = projection;
    planet.heightmap = map;
    planet.height_scale = 8848.0;
    plod_detail_params detail;
    plod_detail_params_init(&detail);
    detail.style = PLOD_DETAIL_MOUNTAINS;
    detail.amplitude = map ? 400.0 : 2000.0;
    detail.plains = 0.45;
    detail.seed = 11;
    char message[256];
    plod_session *session = NULL;
    if (plod_session_create(&session, &planet, &detail, message, sizeof message) != PLOD_OK) {
        printf("session: %s\n", message);
        return NULL;
    }
    if (plod_session_build_normals(session, 2) != PLOD_OK) {
        plod_session_destroy(session);
        return NULL;
    }
    return session;
}

/* Whole planet, culling off: closed at every frame of the descent. */
static void check_closed(plod_projection projection, const plod_cubemap *map, int morph,
                         int fade, int frames_step)
{
    plod_session *session = make_session(projection, map);
    CHECK(session != NULL, "session");
    if (!session)
        return;
    const plod_planet *planet = plod_session_planet(session);
    plod_surface_source surface = plod_planet_surface_source(planet);
    double bottom, top;
    plod_planet_height_range(planet, &bottom, &top);
    plod_clipmap *cm = NULL;
    plod_clipmap_create(&cm);
    plod_clipmap_params params;
    plod_clipmap_params_default(&params);
    params.backface = params.frustum = 0;
    morph_on = morph;
    fade_on = fade;
    for (int k = 0; k < FRAMES; k += frames_step) {
        plod_camera camera;
        descent(k, top, 0.0, &camera, planet);
        plod_clipmap_stats stats;
        plod_error error = {0};
        plod_status st = plod_clipmap_update(cm, planet, &surface, &camera, &params, &stats, &error);
        CHECK(st == PLOD_OK, "update: %s", error.message);
        double origin[3];
        plod_mesh_origin(&surface, RADIUS, camera.position, origin);
        mesh m;
        CHECK(emit(cm, planet, &surface, &camera, origin, 2, &m), "emit");
        weld w;
        weld_mesh(&m, &w);
        CHECK(w.n_open == 0 && w.n_over == 0,
              "%s morph=%d fade=%d frame %d: %zu open edges, %zu edges in 3+ triangles",
              plod_projection_name(projection), morph, fade, k, w.n_open, w.n_over);
        CHECK(stats.stitches_open == 0, "%s frame %d: %zu stitches not closed",
              plod_projection_name(projection), k, stats.stitches_open);
        printf("closed %s morph=%d fade=%d frame %2d finest %2d cells %7zu stitches %5zu "
               "triangles %8zu vertices %8zu open %zu\n",
               plod_projection_name(projection), morph, fade, k, stats.finest_level, stats.cells,
               stats.stitches, m.nt, m.nv, w.n_open);
        weld_free(&w);
        mesh_free(&m);
    }
    plod_clipmap_destroy(cm);
    plod_session_destroy(session);
}

/* Is a planet-space point in view: inside the frustum (with a tolerance)
 * and above the horizon of the occluder? */
static int in_view(const plod_camera *camera, const double p[3], double occluder)
{
    for (int k = 0; k < 6; k++) {
        const double *pl = camera->planes[k];
        double scale = sqrt(pl[0] * pl[0] + pl[1] * pl[1] + pl[2] * pl[2]);
        if (pl[0] * p[0] + pl[1] * p[1] + pl[2] * p[2] + pl[3] < -1e-6 * scale * RADIUS)
            return 0;
    }
    /* hidden behind the occluder ball: the segment eye-p passes through it */
    const double *e = camera->position;
    double d[3] = {p[0] - e[0], p[1] - e[1], p[2] - e[2]};
    double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    double t = -(e[0] * d[0] + e[1] * d[1] + e[2] * d[2]) / dd;
    if (t > 0.0 && t < 1.0) {
        double q[3] = {e[0] + t * d[0], e[1] + t * d[1], e[2] + t * d[2]};
        if (sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]) < occluder * (1 - 1e-9))
            return 0;
    }
    return 1;
}

/* The flight with culling on, incrementally, against a fresh clipmap per
 * frame, on 1 and 3 threads; the open edges of the culled surface lie out
 * of view. */
static void check_flight(const plod_cubemap *map)
{
    plod_session *session = make_session(PLOD_PROJ_QSC, map);
    CHECK(session != NULL, "session");
    if (!session)
        return;
    const plod_planet *planet = plod_session_planet(session);
    plod_surface_source surface = plod_planet_surface_source(planet);
    double bottom, top;
    plod_planet_height_range(planet, &bottom, &top);
    plod_clipmap *kept = NULL;
    plod_clipmap_create(&kept);
    plod_clipmap_params params;
    plod_clipmap_params_default(&params);
    uint64_t all = TEST_FNV_OFFSET;
    size_t rebuilt_levels = 0, kept_levels = 0;
    for (int k = 0; k < 2 * FRAMES; k++) {
        plod_camera camera;
        /* the second half flies sideways at the bottom: the nadir crosses
         * cells, so the fine rings move while the coarse ones stay */
        if (k < FRAMES)
            descent(k, top, 0.0, &camera, planet);
        else
            descent(FRAMES - 1, top, 1e-6 * (k - FRAMES + 1) * (k - FRAMES + 1), &camera, planet);
        plod_clipmap_stats stats, fresh_stats;
        plod_error error = {0};
        CHECK(plod_clipmap_update(kept, planet, &surface, &camera, &params, &stats, &error) ==
                  PLOD_OK, "update: %s", error.message);
        plod_clipmap *fresh = NULL;
        plod_clipmap_create(&fresh);
        CHECK(plod_clipmap_update(fresh, planet, &surface, &camera, &params, &fresh_stats, NULL) ==
                  PLOD_OK, "fresh update");
        double origin[3];
        plod_mesh_origin(&surface, RADIUS, camera.position, origin);
        mesh a, b, c;
        CHECK(emit(kept, planet, &surface, &camera, origin, 1, &a), "emit");
        CHECK(emit(fresh, planet, &surface, &camera, origin, 3, &b), "emit fresh");
        CHECK(emit(kept, planet, &surface, &camera, origin, 3, &c), "emit threads");
        CHECK(a.nv == b.nv && a.nt == b.nt && a.hash == b.hash,
              "frame %d: incremental %016llx != fresh %016llx", k, (unsigned long long)a.hash,
              (unsigned long long)b.hash);
        CHECK(a.hash == c.hash, "frame %d: 1 thread %016llx != 3 threads %016llx", k,
              (unsigned long long)a.hash, (unsigned long long)c.hash);
        CHECK(stats.cells == fresh_stats.cells && stats.stitches == fresh_stats.stitches,
              "frame %d: stats differ", k);
        weld w;
        weld_mesh(&a, &w);
        size_t seen = 0;
        double occluder = RADIUS + (bottom < 0 ? bottom : 0);
        /* every open edge's midpoint lies out of view */
        uint32_t *by_id = malloc((a.nv ? a.nv : 1) * sizeof *by_id);
        for (size_t v = 0; v < a.nv; v++)
            by_id[w.id[v]] = (uint32_t)v;
        for (size_t e = 0; e < w.n_open; e++) {
            uint32_t ids[2] = {(uint32_t)(w.open[e] >> 32), (uint32_t)(w.open[e] & 0xffffffffu)};
            double mid[3];
            for (int c3 = 0; c3 < 3; c3++)
                mid[c3] = origin[c3] + 0.5 * ((double)a.b.positions[3 * by_id[ids[0]] + c3] +
                                              (double)a.b.positions[3 * by_id[ids[1]] + c3]);
            seen += in_view(&camera, mid, occluder);
        }
        CHECK(seen == 0 && w.n_over == 0, "frame %d: %zu open edges in view", k, seen);
        free(by_id);
        all = test_fnv1a(&a.hash, sizeof a.hash, all);
        if (stats.first_rebuilt > stats.finest_level)
            kept_levels += (size_t)stats.finest_level + 1;
        else {
            rebuilt_levels += (size_t)(stats.finest_level + 1 - stats.first_rebuilt);
            kept_levels += (size_t)stats.first_rebuilt;
        }
        printf("flight frame %2d finest %2d first_rebuilt %2d cells %6zu refreshed %6zu "
               "blocks %5zu/%5zu triangles %7zu vertices %7zu open %5zu update_us %.0f\n",
               k, stats.finest_level, stats.first_rebuilt, stats.cells, stats.cells_refreshed,
               stats.blocks_visible, stats.blocks, a.nt, a.nv, w.n_open, stats.update_us);
        weld_free(&w);
        mesh_free(&a), mesh_free(&b), mesh_free(&c);
        plod_clipmap_destroy(fresh);
    }
    CHECK(kept_levels > 0, "the incremental update never kept a level");
    printf("flight levels kept %zu rebuilt %zu hash %016llx\n", kept_levels, rebuilt_levels,
           (unsigned long long)all);
    plod_clipmap_destroy(kept);
    plod_session_destroy(session);
}

static void check_bad_parameters(const plod_cubemap *map)
{
    plod_session *session = make_session(PLOD_PROJ_QSC, map);
    if (!session)
        return;
    const plod_planet *planet = plod_session_planet(session);
    plod_surface_source surface = plod_planet_surface_source(planet);
    plod_camera camera;
    descent(3, 9000.0, 0.0, &camera, planet);
    plod_clipmap *cm = NULL;
    plod_clipmap_create(&cm);
    plod_clipmap_params good, p;
    plod_clipmap_params_default(&good);
    struct {
        const char *what;
        int field;
        double value;
    } cases[] = {{"ring_cells", 0, 23}, {"ring_cells", 0, 1025}, {"max_pixel_error", 1, 0.0},
                 {"max_pixel_error", 1, NAN}, {"max_level", 2, 0}, {"max_level", 2, 29},
                 {"block_level", 3, -1}, {"block_level", 3, 7}};
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        p = good;
        if (cases[k].field == 0)
            p.ring_cells = (int)cases[k].value;
        else if (cases[k].field == 1)
            p.max_pixel_error = cases[k].value;
        else if (cases[k].field == 2)
            p.max_level = (int)cases[k].value;
        else
            p.block_level = (int)cases[k].value;
        plod_error error = {0};
        plod_status st = plod_clipmap_update(cm, planet, &surface, &camera, &p, NULL, &error);
        CHECK(st == PLOD_ERR_BAD_PARAM && strstr(error.message, cases[k].what),
              "%s = %g: status %d, message '%s'", cases[k].what, cases[k].value, (int)st,
              error.message);
    }
    plod_planet car = *planet;
    car.projection = PLOD_PROJ_CAR;
    car.heightmap = NULL;
    plod_error error = {0};
    CHECK(plod_clipmap_update(cm, &car, &surface, &camera, &good, NULL, &error) ==
                  PLOD_ERR_BAD_PARAM && strstr(error.message, "cube projection"),
          "CAR: '%s'", error.message);
    plod_camera centre = camera;
    centre.position[0] = centre.position[1] = centre.position[2] = 0.0;
    CHECK(plod_clipmap_update(cm, planet, &surface, &centre, &good, NULL, NULL) ==
              PLOD_ERR_BAD_COORD, "eye at the centre");
    CHECK(plod_clipmap_update(cm, planet, NULL, &camera, &good, NULL, NULL) == PLOD_ERR_NULL,
          "NULL surface");
    plod_mesh_params mp;
    plod_mesh_params_init(&mp, planet, 0);
    plod_mesh_buffers none;
    memset(&none, 0, sizeof none);
    plod_clipmap *empty = NULL;
    plod_clipmap_create(&empty);
    CHECK(plod_clipmap_emit(empty, &mp, &surface, &none, NULL, NULL) == PLOD_ERR_BAD_PARAM,
          "emit before an update");
    CHECK(plod_clipmap_update(cm, planet, &surface, &camera, &good, NULL, NULL) == PLOD_OK,
          "good update");
    mp.threads = 0;
    CHECK(plod_clipmap_emit(cm, &mp, &surface, &none, NULL, NULL) == PLOD_ERR_BAD_PARAM,
          "threads 0");
    mp.threads = 65;
    CHECK(plod_clipmap_emit(cm, &mp, &surface, &none, NULL, NULL) == PLOD_ERR_BAD_PARAM,
          "threads 65");
    mp.threads = 1;
    mp.origin[0] = NAN;
    CHECK(plod_clipmap_emit(cm, &mp, &surface, &none, NULL, NULL) == PLOD_ERR_BAD_COORD,
          "NaN origin");
    plod_clipmap_destroy(empty);
    plod_clipmap_destroy(cm);
    plod_session_destroy(session);
}

/* CLIPMAP_PART picks one part (1 closed, 2 flight, 3 bad parameters);
 * undefined: all of them. */
int main(void)
{
#ifdef CLIPMAP_PART
    int part = CLIPMAP_PART;
#else
    int part = 0;
#endif
    plod_cubemap *map = make_heightmap();
    if (!map) {
        printf("no memory for the height map\n");
        return 1;
    }
    if (part == 0 || part == 1) {
        check_closed(PLOD_PROJ_QSC, map, 1, 1, 3);
        check_closed(PLOD_PROJ_QSC, map, 1, 0, 7);
        check_closed(PLOD_PROJ_QSC, map, 0, 1, 7);
        check_closed(PLOD_PROJ_TSC, NULL, 1, 1, 7);
        check_closed(PLOD_PROJ_CSC, NULL, 1, 0, 7);
        check_closed(PLOD_PROJ_SPHERIFIED, NULL, 1, 1, 7);
    }
    if (part == 0 || part == 2)
        check_flight(map);
    if (part == 0 || part == 3)
        check_bad_parameters(map);
    plod_cubemap_destroy(map);
    if (failures) {
        printf("%d failures\n", failures);
        return 1;
    }
    printf("passed\n");
    return 0;
}
