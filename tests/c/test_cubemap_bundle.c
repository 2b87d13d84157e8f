/* test_cubemap_bundle.c -- a bundle of a height map, its normal map and an
 * 8-bit map (plod_cubemap_bundle_sample_n) against the maps sampled one by
 * one (plod_cubemap_sample_pair_n, plod_cubemap_sample_face_n), bit for bit.
 *
 * Every projection (CAR included: no ghost ring there), every height texel
 * type, with and without the 8-bit map; points inside faces, on and next
 * to their edges (the ghost ring the bundle copies from the neighbours),
 * in the cells at their corners (left to the maps), beyond [-1, 1]
 * (clamped), unlocated (face -1) and non-finite.  Grids that differ give no
 * bundle.  Built by tests/test_cubemap_bundle.py with the core's C sources.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "plod_cubemap.h"

static unsigned long long rng_state = 0x2545f4914f6cdd1dULL;

static double uniform(void) /* [0, 1) */
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return (double)(rng_state >> 11) * (1.0 / 9007199254740992.0);
}

static int same(double a, double b)
{
    return (isnan(a) && isnan(b)) || memcmp(&a, &b, sizeof a) == 0;
}

static void fill_random(plod_cubemap *m)
{
    plod_texel_type type = plod_cubemap_texel_type(m);
    size_t bytes = plod_cubemap_face_bytes(m);
    for (int f = 0; f < plod_cubemap_face_count(m); f++) {
        unsigned char *data = plod_cubemap_face_data(m, f);
        if (type == PLOD_TEXEL_U8) {
            for (size_t i = 0; i < bytes; i++)
                data[i] = (unsigned char)(uniform() * 256.0);
        } else if (type == PLOD_TEXEL_U16) {
            uint16_t *d = (uint16_t *)data;
            for (size_t i = 0; i < bytes / 2; i++)
                d[i] = (uint16_t)(uniform() * 65536.0);
        } else {
            float *d = (float *)data;
            for (size_t i = 0; i < bytes / 4; i++)
                d[i] = (float)(uniform() * 3.0 - 1.0);
        }
    }
}

enum { POINTS = 4000 };

/* A face coordinate on the grid's interesting places: texel centres and
 * the cells between them, the last half texel, the edge itself, beyond. */
static double coordinate(int width)
{
    double r = uniform();
    if (r < 0.25) /* at or near an edge */
        return (uniform() < 0.5 ? -1.0 : 1.0) * (1.0 - (uniform() < 0.5 ? 0.0 : uniform() / width));
    if (r < 0.3)
        return uniform() < 0.5 ? -1.0 : 1.0;
    if (r < 0.35) /* clamped */
        return (uniform() < 0.5 ? -1.0 : 1.0) * (1.0 + uniform());
    if (r < 0.45) /* a texel centre */
        return ((int)(uniform() * width) + 0.5) * 2.0 / width - 1.0;
    return 2.0 * uniform() - 1.0;
}

static int check(plod_projection projection, plod_texel_type type, int with_extra)
{
    const int size = 7;
    plod_cubemap *heights = NULL, *normals = NULL, *extra = NULL, *other = NULL;
    plod_cubemap_bundle *bundle = NULL;
    int failures = 0;
    if (plod_cubemap_create(&heights, projection, size, 1, type) != PLOD_OK)
        return 1;
    fill_random(heights);
    if (plod_cubemap_build_normals(&normals, heights, 1000.0, 50.0, 1) != PLOD_OK)
        return 1;
    /* the normal map is the same on any number of threads */
    plod_cubemap *threaded = NULL;
    if (plod_cubemap_build_normals(&threaded, heights, 1000.0, 50.0, 3) != PLOD_OK)
        return 1;
    for (int f = 0; f < plod_cubemap_face_count(normals); f++)
        if (memcmp(plod_cubemap_face_data_const(normals, f),
                   plod_cubemap_face_data_const(threaded, f),
                   plod_cubemap_face_bytes(normals)) != 0) {
            printf("FAIL projection %d type %d: normal map on 3 threads\n", (int)projection,
                   (int)type);
            failures++;
        }
    plod_cubemap_destroy(threaded);
    if (with_extra) {
        if (plod_cubemap_create(&extra, projection, size, 1, PLOD_TEXEL_U8) != PLOD_OK)
            return 1;
        fill_random(extra);
    }
    if (plod_cubemap_bundle_create(&bundle, heights, normals, extra) != PLOD_OK || !bundle) {
        printf("FAIL projection %d type %d: no bundle\n", (int)projection, (int)type);
        return 1;
    }
    if (!plod_cubemap_bundle_holds(bundle, heights, normals, extra) ||
        plod_cubemap_bundle_holds(bundle, heights, normals, with_extra ? NULL : normals)) {
        printf("FAIL projection %d type %d: holds\n", (int)projection, (int)type);
        failures++;
    }
    static int faces[POINTS];
    static double u[POINTS], v[POINTS];
    static double h_bundle[POINTS], n_bundle[3 * POINTS], e_bundle[POINTS];
    static double h_maps[POINTS], n_maps[3 * POINTS], e_maps[POINTS];
    int face_count = plod_cubemap_face_count(heights);
    int width = plod_cubemap_face_width(heights);
    for (int k = 0; k < POINTS; k++) {
        faces[k] = (int)(uniform() * face_count);
        u[k] = coordinate(width);
        v[k] = coordinate(size);
        double r = uniform();
        if (r < 0.01)
            faces[k] = -1;
        else if (r < 0.02)
            faces[k] = face_count;
        else if (r < 0.03)
            u[k] = NAN;
        else if (r < 0.04)
            v[k] = INFINITY;
    }
    plod_cubemap_bundle_sample_n(bundle, POINTS, faces, u, v, h_bundle, n_bundle,
                                 with_extra ? e_bundle : NULL);
    plod_cubemap_sample_pair_n(heights, normals, POINTS, faces, u, v, h_maps, n_maps);
    if (with_extra)
        plod_cubemap_sample_face_n(extra, POINTS, faces, u, v, e_maps);
    for (int k = 0; k < POINTS && failures < 5; k++) {
        int ok = same(h_bundle[k], h_maps[k]);
        for (int c = 0; c < 3; c++)
            ok &= same(n_bundle[3 * k + c], n_maps[3 * k + c]);
        if (with_extra)
            ok &= same(e_bundle[k], e_maps[k]);
        if (!ok) {
            printf("FAIL projection %d type %d extra %d: point %d face %d (%.17g, %.17g): "
                   "height %.17g against %.17g\n",
                   (int)projection, (int)type, with_extra, k, faces[k], u[k], v[k],
                   h_bundle[k], h_maps[k]);
            failures++;
        }
    }
    /* maps on another grid: no bundle */
    if (plod_cubemap_create(&other, projection, size + 1, 1, PLOD_TEXEL_U8) == PLOD_OK) {
        plod_cubemap_bundle *none = NULL;
        if (plod_cubemap_bundle_create(&none, heights, normals, other) != PLOD_OK || none) {
            printf("FAIL projection %d: a bundle of two grids\n", (int)projection);
            failures++;
        }
        plod_cubemap_bundle_destroy(none);
    }
    plod_cubemap_destroy(other);
    plod_cubemap_bundle_destroy(bundle);
    plod_cubemap_destroy(extra);
    plod_cubemap_destroy(normals);
    plod_cubemap_destroy(heights);
    return failures;
}

int main(void)
{
    const plod_projection projections[] = {PLOD_PROJ_TSC, PLOD_PROJ_CSC, PLOD_PROJ_QSC,
                                           PLOD_PROJ_SPHERIFIED, PLOD_PROJ_CAR};
    const plod_texel_type types[] = {PLOD_TEXEL_U8, PLOD_TEXEL_U16, PLOD_TEXEL_F32};
    int failures = 0;
    for (size_t p = 0; p < sizeof projections / sizeof *projections; p++)
        for (size_t t = 0; t < sizeof types / sizeof *types; t++)
            for (int extra = 0; extra <= 1; extra++)
                failures += check(projections[p], types[t], extra);
    if (failures) {
        printf("%d failures\n", failures);
        return 1;
    }
    printf("cubemap bundle C tests passed\n");
    return 0;
}
