/* bench_mesh_c.c -- C-level mesh emission throughput (no Python, buffers
 * allocated once and reused, as a renderer streaming frames would).
 * Built (the core's C files, as setup.py compiles them) and run by
 * `bench_mesh.py --c`, which hands the map over decoded, as a headerless
 * grid.  Scene as bench_mesh.py: an
 * Earth-radius planet, perfect sphere and the Earth topology map as a 1024^2
 * QSC cube map with its normal map, camera 10 km up, refined without
 * culling; then the session's emission of every sector with every output,
 * at template levels 4..7 on 1 and 2 threads, best of 5 (wall clock).
 *     bench_mesh_c [GRID WIDTH HEIGHT u8|u16|f32]
 */
#include "plod.h"
#include "plod_image.h"
#include "plod_resample.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static double bench__now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* Blender-style camera matrix looking from eye at target, +Z up. */
static void bench__look_at(const double eye[3], const double target[3], double m[16])
{
    double back[3], right[3], up[3], z[3] = {0.0, 0.0, 1.0};
    double n = 0.0;
    for (int k = 0; k < 3; k++) {
        back[k] = eye[k] - target[k];
        n += back[k] * back[k];
    }
    for (int k = 0; k < 3; k++)
        back[k] /= sqrt(n);
    right[0] = z[1] * back[2] - z[2] * back[1];
    right[1] = z[2] * back[0] - z[0] * back[2];
    right[2] = z[0] * back[1] - z[1] * back[0];
    n = sqrt(right[0] * right[0] + right[1] * right[1] + right[2] * right[2]);
    for (int k = 0; k < 3; k++)
        right[k] /= n;
    up[0] = back[1] * right[2] - back[2] * right[1];
    up[1] = back[2] * right[0] - back[0] * right[2];
    up[2] = back[0] * right[1] - back[1] * right[0];
    for (int k = 0; k < 3; k++) {
        m[4 * k + 0] = right[k];
        m[4 * k + 1] = up[k];
        m[4 * k + 2] = back[k];
        m[4 * k + 3] = eye[k];
    }
    m[12] = m[13] = m[14] = 0.0;
    m[15] = 1.0;
}

static int bench__run(const char *name, const plod_planet *planet, const plod_camera *camera)
{
    plod_session *session = NULL;
    plod_refine_params rp;
    plod_refine_params_default(&rp);
    rp.backface_culling = 0;
    rp.frustum_culling = 0;
    if (plod_session_create(&session, planet, NULL, NULL, 0) != PLOD_OK ||
        plod_session_refine(session, camera, &rp, NULL, NULL) != PLOD_OK) {
        fprintf(stderr, "bench_mesh_c: refine failed\n");
        return 1;
    }
    size_t count = plod_session_sector_count(session, 0);
    for (int level = 4; level <= 7; level++) {
        size_t vb = plod_mesh_vertex_bound(count, level), tb = plod_mesh_triangle_bound(count, level);
        plod_mesh_buffers out = {
            malloc(3 * vb * sizeof(float)), malloc(3 * vb * sizeof(float)),
            malloc(2 * vb * sizeof(float)), malloc(vb * sizeof(float)),
            malloc(3 * tb * sizeof(int32_t)), malloc(tb * sizeof(int32_t)),
            malloc(tb * sizeof(int32_t)),
        };
        if (!out.positions || !out.normals || !out.uv || !out.morph || !out.triangles ||
            !out.sector_level || !out.face) {
            fprintf(stderr, "bench_mesh_c: out of memory\n");
            return 1;
        }
        for (int threads = 1; threads <= 2; threads++) {
            plod_mesh_params mp;
            plod_session_mesh_params(session, level, 0, threads, &mp);
            double best = INFINITY;
            size_t vertices = 0;
            for (int run = 0; run < 6; run++) { /* the first run warms the buffers */
                double t0 = bench__now();
                if (plod_session_emit(session, &mp, 0, 0, &out, &vertices, NULL) != PLOD_OK) {
                    fprintf(stderr, "bench_mesh_c: emission failed\n");
                    return 1;
                }
                double dt = bench__now() - t0;
                if (run > 0 && dt < best)
                    best = dt;
            }
            printf("%15s %3d %8zu %10zu %4d %8.2f %8.1f\n", name, level, count, vertices,
                   threads, 1e3 * best, (double)vertices / best / 1e6);
        }
        free(out.positions), free(out.normals), free(out.uv), free(out.morph);
        free(out.triangles), free(out.sector_level), free(out.face);
    }
    plod_session_destroy(session);
    return 0;
}

/* Emission along bench_refine.py's descent (20,000 km to 2 m over Everest,
 * 240 frames, 1 px at 1920x1080, template level 4): each frame's visible
 * sectors emitted with the sector cache and without it, interleaved, into
 * buffers grown once and reused.  Reports vertices/s over the whole path
 * and the cache's hit rate. */
static int bench__flyby(const char *name, const plod_planet *planet, double terrain_top)
{
    const double pi = 3.14159265358979323846, radius = planet->radius;
    const int frames = 240;
    plod_refine_params rp;
    plod_refine_params_default(&rp);
    rp.max_level = 24;
    plod_mesh_buffers out = {0};
    size_t capacity = 0;
    for (int threads = 1; threads <= 2; threads++) {
        double t_cached = 0.0, t_plain = 0.0;
        size_t vertices_total = 0, hits = 0, misses = 0;
        plod_session *session = NULL; /* fresh: base sectors, empty cache */
        if (plod_session_create(&session, planet, NULL, NULL, 0) != PLOD_OK)
            return 1;
        for (int k = 0; k < frames; k++) {
            double t = (double)k / (frames - 1);
            double alt = exp(log(2e7) * (1 - t) + log(2.0) * t);
            double lat = 27.9 * pi / 180, lon = 86.9 * pi / 180 + 0.002 * t;
            double d[3] = {cos(lat) * cos(lon), cos(lat) * sin(lon), sin(lat)};
            double east[3] = {-sin(lon), cos(lon), 0.0};
            double pitch = (-90.0 + 80.0 * fmin(1.0, t * 1.25)) * pi / 180;
            double eye[3], target[3];
            for (int c = 0; c < 3; c++) {
                eye[c] = d[c] * (radius + terrain_top + alt);
                target[c] = eye[c] + east[c] * cos(pitch) + d[c] * sin(pitch);
            }
            plod_camera_desc desc;
            plod_camera_desc_default(&desc);
            bench__look_at(eye, target, desc.matrix_world); /* +Z up: pole-safe here */
            desc.resolution_x = 1920;
            desc.resolution_y = 1080;
            desc.clip_start = 0.1;
            desc.clip_end = 1e9;
            plod_camera camera;
            if (plod_camera_init(&camera, &desc) != PLOD_OK ||
                plod_session_refine(session, &camera, &rp, NULL, NULL) != PLOD_OK)
                return 1;
            size_t emitted = plod_session_sector_count(session, 1);
            if (emitted > capacity) {
                capacity = emitted + emitted / 2;
                size_t vb = plod_mesh_vertex_bound(capacity, rp.template_level);
                size_t tb = plod_mesh_triangle_bound(capacity, rp.template_level);
                free(out.positions), free(out.normals), free(out.uv), free(out.morph);
                free(out.triangles), free(out.sector_level), free(out.face);
                out = (plod_mesh_buffers){
                    calloc(3 * vb, sizeof(float)), calloc(3 * vb, sizeof(float)),
                    calloc(2 * vb, sizeof(float)), calloc(vb, sizeof(float)),
                    calloc(3 * tb, sizeof(int32_t)), calloc(tb, sizeof(int32_t)),
                    calloc(tb, sizeof(int32_t))};
                if (!out.positions || !out.normals || !out.uv || !out.morph ||
                    !out.triangles || !out.sector_level || !out.face)
                    return 1;
                /* touch every page once, as a reused buffer would be */
                plod_mesh_params warm;
                plod_session_mesh_params(session, rp.template_level, 0, 1, &warm);
                plod_session_emit(session, &warm, 1, 0, &out, NULL, NULL);
            }
            plod_mesh_params mp;
            plod_session_mesh_params(session, rp.template_level, 0, threads, &mp);
            size_t vertices = 0;
            double t0 = bench__now();
            if (plod_session_emit(session, &mp, 1, 0, &out, &vertices, NULL) != PLOD_OK)
                return 1;
            double t1 = bench__now();
            if (plod_session_emit(session, &mp, 1, 1, &out, NULL, NULL) != PLOD_OK)
                return 1;
            double t2 = bench__now();
            plod_mesh_cache_stats cs;
            plod_session_cache_stats(session, &cs);
            hits += cs.hits;
            misses += cs.misses;
            t_plain += t1 - t0;
            t_cached += t2 - t1;
            vertices_total += vertices;
        }
        plod_session_destroy(session);
        printf("%15s %4d %10zu %10.1f %10.1f %7.2fx %8.1f%%\n", name, threads, vertices_total,
               vertices_total / t_plain / 1e6, vertices_total / t_cached / 1e6,
               t_plain / t_cached, 100.0 * (double)hits / (double)(hits + misses));
    }
    free(out.positions), free(out.normals), free(out.uv), free(out.morph);
    free(out.triangles), free(out.sector_level), free(out.face);
    return 0;
}

static void bench__flyby_header(void)
{
    printf("\nflyby: bench_refine.py's descent, 240 frames, visible sectors, template level 4,\n"
           "uncached vs sector cache, interleaved per frame (Mvert/s over the whole path)\n");
    printf("%15s %4s %10s %10s %10s %8s %9s\n", "planet", "thr", "vertices", "uncached",
           "cached", "ratio", "hit rate");
}

int main(int argc, char **argv)
{
    const double radius = 6371e3;
    double eye[3] = {radius + 10e3, 0.0, 0.0}, target[3] = {radius, 50e3, 20e3};
    plod_camera_desc desc;
    plod_camera_desc_default(&desc);
    bench__look_at(eye, target, desc.matrix_world);
    desc.clip_start = 0.1;
    desc.clip_end = 1e9;
    plod_camera camera;
    if (plod_camera_init(&camera, &desc) != PLOD_OK) {
        fprintf(stderr, "bench_mesh_c: bad camera\n");
        return 1;
    }
    printf("%15s %3s %8s %10s %4s %8s %8s\n", "planet", "tl", "sectors", "vertices", "thr",
           "ms", "Mvert/s");
    plod_planet sphere = {0};
    sphere.radius = radius;
    sphere.projection = PLOD_PROJ_QSC;
    sphere.height_scale = 1.0;
    if (bench__run("sphere", &sphere, &camera))
        return 1;
    if (argc < 2) {
        bench__flyby_header();
        return bench__flyby("sphere", &sphere, 0.0);
    }
    plod_image image = {0};
    char message[256];
    plod_cubemap *heights = NULL, *normals = NULL;
    plod_raw_format grid = {argc > 3 ? atoi(argv[2]) : 0, argc > 3 ? atoi(argv[3]) : 0,
                            argc < 5                      ? PLOD_RAW_U16
                            : strcmp(argv[4], "u8") == 0  ? PLOD_RAW_U8
                            : strcmp(argv[4], "f32") == 0 ? PLOD_RAW_F32
                                                          : PLOD_RAW_U16,
                            0};
    snprintf(message, sizeof message, "usage: bench_mesh_c [GRID WIDTH HEIGHT u8|u16|f32]");
    if (argc < 5 ||
        plod_image_read_raw(&image, argv[1], &grid, 0, message, sizeof message) != PLOD_OK ||
        plod_cubemap_create(&heights, PLOD_PROJ_QSC, 1024, 1, image.type) != PLOD_OK ||
        plod_resample_car_to_cube(heights, &image, PLOD_FILTER_BILINEAR, NULL, NULL) != PLOD_OK ||
        plod_cubemap_build_pyramid(heights) != PLOD_OK) {
        fprintf(stderr, "bench_mesh_c: cannot load %s: %s\n", argv[1], message);
        return 1;
    }
    plod_image_free(&image);
    plod_planet earth = sphere;
    earth.heightmap = heights;
    earth.height_scale = 8848.0;
    double t0 = bench__now();
    if (plod_planet_build_normals(&earth, &normals, 1) != PLOD_OK)
        return 1;
    printf("(normal map 6 x 1024^2 built in %.1f ms, once per planet)\n", 1e3 * (bench__now() - t0));
    earth.normalmap = normals;
    int failed = bench__run("earth-topology", &earth, &camera);
    double lo, hi;
    plod_planet_height_range(&earth, &lo, &hi);
    bench__flyby_header();
    failed = failed || bench__flyby("sphere", &sphere, 0.0) ||
             bench__flyby("earth-topology", &earth, hi);
    plod_cubemap_destroy(normals);
    plod_cubemap_destroy(heights);
    return failed;
}
