/* test_descent.c -- the reference descent through the C core alone, hashed:
 * one number that two builds (two compilers, two C libraries, two operating
 * systems) print alike only if they compute the same bits.
 *
 * The flight is tools/descent_hash.py's (20,000 km to 2 m over 48 frames,
 * 1920x1080, lens 50 mm, the recommended clip planes, 1 px error, template
 * level 4, budget 8,000 sectors, with and without hysteresis; each frame's
 * mesh at template level 3 with morphing on 2 threads through the sector
 * cache, and its instances at level 2) over an Earth-sized planet whose
 * height map is made here from integers (no image file: a 256-texel QSC
 * cube map of 16-bit heights), with the MOUNTAINS detail field on and off
 * and the normal map built on 2 threads.  Hashed per frame: the refine
 * statistics that are results, the visible sectors' ids and levels, every
 * mesh buffer, the instances' corners, levels and morph factors (FNV-1a,
 * 64 bits).  Prints one hash per configuration and one over all.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "plod.h"
#include "plod_session.h"
#include "test_support.h"

#define FRAMES 48
#define MAP_SIZE 256
#define RADIUS 6371000.0

/* ---- the hash ------------------------------------------------------------ */

typedef struct hash64 { uint64_t h; } hash64;

static void hash_bytes(hash64 *hash, const void *data, size_t bytes)
{
    hash->h = test_fnv1a(data, bytes, hash->h);
}

static void hash_u64(hash64 *hash, uint64_t v)
{
    unsigned char b[8]; /* little-endian on every host */
    for (int i = 0; i < 8; i++)
        b[i] = (unsigned char)(v >> (8 * i));
    hash_bytes(hash, b, 8);
}

/* ---- the height map: integer value noise ----------------------------------- */

/* Lattice value noise at cell size 2^shift, bilinear in integers. */
static uint32_t value_noise(int face, int i, int j, int shift, uint32_t seed)
{
    int ci = i >> shift, cj = j >> shift, cell = 1 << shift;
    uint32_t fi = (uint32_t)(i & (cell - 1)), fj = (uint32_t)(j & (cell - 1));
    uint32_t v[4];
    for (int k = 0; k < 4; k++)
        v[k] = test_mix32(seed ^ test_mix32((uint32_t)face * 0x9e3779b9u ^
                                            test_mix32((uint32_t)(ci + (k & 1)) ^
                                                       test_mix32((uint32_t)(cj + (k >> 1)))))) >>
               16;
    uint32_t bottom = v[0] * ((uint32_t)cell - fi) + v[1] * fi;
    uint32_t top = v[2] * ((uint32_t)cell - fi) + v[3] * fi;
    return (uint32_t)(((uint64_t)bottom * ((uint32_t)cell - fj) + (uint64_t)top * fj) >>
                      (2 * shift));
}

static plod_cubemap *make_heightmap(void)
{
    plod_cubemap *map = NULL;
    if (plod_cubemap_create(&map, PLOD_PROJ_QSC, MAP_SIZE, 1, PLOD_TEXEL_U16) != PLOD_OK)
        return NULL;
    for (int face = 0; face < 6; face++) {
        uint16_t *texels = plod_cubemap_face_data(map, face);
        for (int j = 0; j < MAP_SIZE; j++)
            for (int i = 0; i < MAP_SIZE; i++) {
                /* octaves of halving amplitude; the sum stays below 65536 */
                uint32_t h = value_noise(face, i, j, 6, 1u) / 2 + value_noise(face, i, j, 4, 2u) / 4 +
                             value_noise(face, i, j, 2, 3u) / 8 + value_noise(face, i, j, 1, 4u) / 16;
                texels[(size_t)j * MAP_SIZE + (size_t)i] = (uint16_t)h;
            }
    }
    if (plod_cubemap_build_pyramid(map) != PLOD_OK) {
        plod_cubemap_destroy(map);
        return NULL;
    }
    return map;
}

/* ---- the flight ---------------------------------------------------------------- */

/* Frame k of the descent over a planet whose heights reach `top` metres. */
static void descent_matrix(int k, double top, double m[16])
{
    const double pi = 3.14159265358979323846;
    double lat = 27.9 * pi / 180.0, lon0 = 86.9 * pi / 180.0;
    double start = 2e7 < 3.0 * RADIUS ? 2e7 : 3.0 * RADIUS;
    double t = (double)k / (FRAMES - 1);
    double alt = exp(log(start) * (1 - t) + log(2.0) * t);
    double lon = lon0 + 0.002 * t;
    double d[3] = {cos(lat) * cos(lon), cos(lat) * sin(lon), sin(lat)};
    double east[3] = {-sin(lon), cos(lon), 0.0};
    double pitch = (-90.0 + 80.0 * (t * 1.25 < 1.0 ? t * 1.25 : 1.0)) * pi / 180.0;
    double eye[3], target[3];
    for (int i = 0; i < 3; i++) {
        double view = east[i] * cos(pitch) + d[i] * sin(pitch);
        eye[i] = d[i] * (RADIUS + top + alt);
        target[i] = eye[i] + view;
    }
    double north[3] = {-sin(lat) * cos(lon), -sin(lat) * sin(lon), cos(lat)};
    test_look_at(eye, target, fabs(pitch) < 89.0 * pi / 180.0 ? d : north, m);
}

static int make_camera(const plod_planet *planet, const double matrix[16], plod_camera *camera)
{
    plod_camera_desc desc;
    plod_camera_desc_default(&desc);
    memcpy(desc.matrix_world, matrix, sizeof desc.matrix_world);
    desc.clip_start = 0.1;
    desc.clip_end = 1e12;
    if (plod_camera_init(camera, &desc) != PLOD_OK)
        return 0;
    plod_recommended_clip(planet, camera, &desc.clip_start, &desc.clip_end);
    return plod_camera_init(camera, &desc) == PLOD_OK;
}

static void hash_stats(hash64 *hash, const plod_refine_stats *s)
{
    uint64_t values[] = {s->sectors_total, s->sectors_after_backface, s->sectors_after_frustum,
                         s->sectors_after_budget, s->sectors_sea_skipped, s->splits, s->merges,
                         (uint64_t)s->max_level_reached, (uint64_t)s->truncated,
                         (uint64_t)s->pending, s->frame};
    for (size_t i = 0; i < sizeof values / sizeof values[0]; i++)
        hash_u64(hash, values[i]);
}

static int hash_mesh(hash64 *hash, plod_session *session)
{
    size_t sectors = plod_session_sector_count(session, 1);
    size_t vb = plod_mesh_vertex_bound(sectors, 3), tb = plod_mesh_triangle_bound(sectors, 3);
    size_t vcap = vb ? vb : 1, tcap = tb ? tb : 1, scap = sectors ? sectors : 1;
    plod_mesh_buffers out = {
        malloc(12 * vcap), malloc(12 * vcap), malloc(8 * vcap), malloc(4 * vcap),
        malloc(12 * tcap), malloc(4 * tcap), malloc(4 * tcap), malloc(4 * vcap),
        malloc(8 * scap)};
    int ok = out.positions && out.normals && out.uv && out.morph && out.triangles &&
             out.sector_level && out.face && out.detail && out.keys;
    plod_mesh_params params;
    plod_session_mesh_params(session, 3, 1, 2, &params);
    size_t nv = 0, nt = 0;
    if (ok)
        ok = plod_session_emit(session, &params, 1, 1, &out, &nv, &nt) == PLOD_OK;
    if (ok) {
        hash_bytes(hash, params.origin, sizeof params.origin);
        hash_bytes(hash, out.positions, 12 * nv);
        hash_bytes(hash, out.normals, 12 * nv);
        hash_bytes(hash, out.uv, 8 * nv);
        hash_bytes(hash, out.morph, 4 * nv);
        hash_bytes(hash, out.detail, 4 * nv);
        hash_bytes(hash, out.triangles, 12 * nt);
        hash_bytes(hash, out.sector_level, 4 * nt);
        hash_bytes(hash, out.face, 4 * nt);
    }
    free(out.positions), free(out.normals), free(out.uv), free(out.morph);
    free(out.triangles), free(out.sector_level), free(out.face), free(out.detail);
    free(out.keys);
    if (!ok)
        return 0;

    float *corners = malloc(36 * scap), *levels = malloc(4 * scap), *morph = malloc(4 * scap);
    size_t instances = 0;
    plod_session_mesh_params(session, 2, 1, 1, &params);
    ok = corners && levels && morph &&
         plod_session_instances(session, &params, corners, levels, morph, &instances) == PLOD_OK;
    if (ok) {
        hash_bytes(hash, corners, 36 * instances);
        hash_bytes(hash, levels, 4 * instances);
        hash_bytes(hash, morph, 4 * instances);
    }
    free(corners), free(levels), free(morph);
    return ok;
}

static int fly(const plod_cubemap *map, int detail_on, int hysteresis, uint64_t *digest)
{
    plod_planet planet;
    memset(&planet, 0, sizeof planet);
    planet.radius = RADIUS;
    planet.projection = PLOD_PROJ_QSC;
    planet.heightmap = map;
    planet.height_scale = 8848.0;
    planet.has_sea_level = 1;
    planet.sea_level = 2000.0;
    plod_detail_params detail;
    plod_detail_params_init(&detail);
    detail.style = PLOD_DETAIL_MOUNTAINS;
    detail.amplitude = 1000.0;
    detail.plains = 0.45;
    detail.seed = 7;
    char message[256];
    plod_session *session = NULL;
    if (plod_session_create(&session, &planet, detail_on ? &detail : NULL, message,
                            sizeof message) != PLOD_OK) {
        fprintf(stderr, "session: %s\n", message);
        return 0;
    }
    int ok = plod_session_build_normals(session, 2) == PLOD_OK;
    double bottom, top;
    plod_planet_height_range(plod_session_planet(session), &bottom, &top);
    hash64 hash = {TEST_FNV_OFFSET};
    for (int k = 0; ok && k < FRAMES; k++) {
        double matrix[16];
        descent_matrix(k, top, matrix);
        plod_camera camera;
        ok = make_camera(plod_session_planet(session), matrix, &camera);
        plod_refine_params params;
        plod_refine_params_default(&params);
        params.max_pixel_error = 1.0;
        params.template_level = 4;
        params.hysteresis = hysteresis;
        params.max_level = 48;
        params.budget = 8000;
        params.threads = 2; /* the refiner's workers; the same result as 1 */
        plod_refine_stats stats;
        if (ok)
            ok = plod_session_refine(session, &camera, &params, &stats, NULL) == PLOD_OK;
        if (!ok)
            break;
        hash_stats(&hash, &stats);
        size_t count = 0, visible = 0;
        const plod_sector *sectors = plod_refiner_sectors(plod_session_refiner(session), &count);
        const uint32_t *order = plod_refiner_visible(plod_session_refiner(session), &visible);
        for (size_t i = 0; i < visible; i++) {
            hash_u64(&hash, sectors[order[i]].id);
            hash_u64(&hash, sectors[order[i]].level);
        }
        ok = hash_mesh(&hash, session);
    }
    plod_session_destroy(session);
    *digest = hash.h;
    return ok;
}

int main(void)
{
    plod_cubemap *map = make_heightmap();
    if (!map) {
        fprintf(stderr, "no memory for the height map\n");
        return 1;
    }
    hash64 all = {TEST_FNV_OFFSET};
    int ok = 1;
    for (int detail_on = 1; ok && detail_on >= 0; detail_on--)
        for (int hysteresis = 1; ok && hysteresis >= 0; hysteresis--) {
            uint64_t digest = 0;
            ok = fly(map, detail_on, hysteresis, &digest);
            hash_u64(&all, digest);
            printf("detail=%s hysteresis=%s %016llx\n", detail_on ? "on " : "off",
                   hysteresis ? "on " : "off", (unsigned long long)digest);
        }
    plod_cubemap_destroy(map);
    if (!ok) {
        fprintf(stderr, "the descent failed\n");
        return 1;
    }
    printf("descent %016llx\n", (unsigned long long)all.h);
    return 0;
}
