/* geomipmap.c -- geomipmapping on cube-face tiles (plod_geomipmap.h). */
#include "plod_geomipmap.h"
#include "plod_platform.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct plod_geomipmap {
    int tiles, cells_log2;   /* the d-value table's grid */
    float *dvalues;          /* 6 tiles^2 (cells_log2 + 1): metres, NaN = not yet */
    signed char *chosen;     /* per tile this refine: mip level, -1 not drawn */
    plod_face_tile *list;
    size_t list_count, list_capacity;
};

plod_status plod_geomipmap_create(plod_geomipmap **out)
{
    if (!out)
        return PLOD_ERR_NULL;
    *out = calloc(1, sizeof **out);
    return *out ? PLOD_OK : PLOD_ERR_NO_MEMORY;
}

void plod_geomipmap_destroy(plod_geomipmap *g)
{
    if (!g)
        return;
    free(g->dvalues);
    free(g->chosen);
    free(g->list);
    free(g);
}

const plod_face_tile *plod_geomipmap_tiles(const plod_geomipmap *g, size_t *count)
{
    *count = g->list_count;
    return g->list;
}

size_t plod_geomipmap_memory_bytes(const plod_geomipmap *g)
{
    size_t tiles = 6 * (size_t)g->tiles * (size_t)g->tiles;
    return sizeof *g + tiles * ((size_t)(g->cells_log2 + 1) * sizeof(float) + 1) +
           g->list_capacity * sizeof *g->list;
}

static int plod__log2(int v)
{
    int l = 0;
    while ((1 << l) < v)
        l++;
    return l;
}

/* The tile's d-values: for each mip level m, the largest distance between
 * a full-resolution vertex on the real surface (every detail octave) and
 * the level-m mesh there (its cells split along the (0,0)-(1,1) diagonal,
 * as the emitter splits them), made non-decreasing in m. */
static void plod__dvalues(const plod_planet *planet, int face, int level, int32_t x, int32_t y,
                          int n_log2, float *out, double *work)
{
    int n = 1 << n_log2, row = n + 1;
    size_t count = (size_t)row * (size_t)row;
    double *dirs = work, *p = work + 3 * count, *heights = work + 6 * count;
    int shift = 1 - level - n_log2;
    for (int j = 0; j <= n; j++)
        for (int i = 0; i <= n; i++) {
            double u = ldexp((double)((int64_t)x * n + i), shift) - 1.0;
            double v = ldexp((double)((int64_t)y * n + j), shift) - 1.0;
            plod_face_to_dir(planet->projection, face, u, v, dirs + 3 * ((size_t)j * row + i));
        }
    plod_surface_source surface = plod_planet_surface_source(planet);
    surface.ops->sample_n(surface.self, count, dirs, NULL, NULL, heights, NULL, NULL);
    for (size_t k = 0; k < count; k++)
        for (int c = 0; c < 3; c++)
            p[3 * k + c] = dirs[3 * k + c] * (planet->radius + heights[k]);
    double worst = 0.0;
    out[0] = 0.0f;
    for (int m = 1; m <= n_log2; m++) {
        int s = 1 << m;
        double d = 0.0;
        for (int j = 0; j <= n; j++)
            for (int i = 0; i <= n; i++) {
                int ci = i / s, cj = j / s;
                if (ci * s == n)
                    ci--;
                if (cj * s == n)
                    cj--;
                double a = (double)(i - ci * s) / s, b = (double)(j - cj * s) / s;
                const double *p00 = p + 3 * ((size_t)(cj * s) * row + (size_t)(ci * s));
                const double *p10 = p00 + 3 * s, *p01 = p00 + 3 * (size_t)s * row;
                const double *p11 = p01 + 3 * s;
                double e2 = 0.0;
                for (int c = 0; c < 3; c++) {
                    double q = a >= b ? p00[c] + a * (p10[c] - p00[c]) + b * (p11[c] - p10[c])
                                      : p00[c] + b * (p01[c] - p00[c]) + a * (p11[c] - p01[c]);
                    double diff = p[3 * ((size_t)j * row + i) + c] - q;
                    e2 += diff * diff;
                }
                d = e2 > d ? e2 : d;
            }
        d = sqrt(d);
        worst = d > worst ? d : worst;
        /* rounded up to float: a d-value never understates */
        float f = (float)worst;
        if ((double)f < worst)
            f = nextafterf(f, INFINITY);
        out[m] = f;
    }
}

plod_status plod_geomipmap_refine(plod_geomipmap *g, const plod_planet *planet,
                                  const plod_camera *camera, const plod_refine_params *params,
                                  int tiles, plod_refine_stats *stats, plod_error *error)
{
    uint64_t start = plod_clock_ns();
    plod_status st = plod_facetiles_check(planet, camera, params, error);
    if (st != PLOD_OK)
        return st;
    if (tiles < 1 || tiles > PLOD_GEOMIPMAP_MAX_TILES || (tiles & (tiles - 1)))
        return plod_error_set(error, PLOD_ERR_BAD_PARAM,
                              "geomipmap_tiles must be a power of two in 1..%d",
                              PLOD_GEOMIPMAP_MAX_TILES);
    int n = params->template_level, level = plod__log2(tiles);
    size_t count = 6 * (size_t)tiles * (size_t)tiles;
    if (!g->dvalues || g->tiles != tiles || g->cells_log2 != n) {
        float *d = malloc(count * (size_t)(n + 1) * sizeof *d);
        signed char *chosen = malloc(count);
        if (!d || !chosen) {
            free(d);
            free(chosen);
            return plod_error_set(error, PLOD_ERR_NO_MEMORY, "geomipmap: out of memory");
        }
        for (size_t k = 0; k < count * (size_t)(n + 1); k++)
            d[k] = NAN;
        free(g->dvalues);
        free(g->chosen);
        g->dvalues = d, g->chosen = chosen;
        g->tiles = tiles, g->cells_log2 = n;
    }
    size_t row = (size_t)(1 << n) + 1;
    double *work = malloc(7 * row * row * sizeof *work);
    if (!work)
        return plod_error_set(error, PLOD_ERR_NO_MEMORY, "geomipmap: out of memory");
    plod_facetiles_view fv;
    plod_facetiles_view_init(&fv, planet, camera, params);
    const plod_bound_view *view = &fv.view;
    size_t unculled = 0, sea_skipped = 0;
    int finest = 0;
    g->list_count = 0;
    /* each tile's level from its d-values at its distance */
    for (int f = 0; f < 6; f++)
        for (int32_t y = 0; y < tiles; y++)
            for (int32_t x = 0; x < tiles; x++) {
                size_t k = ((size_t)f * tiles + (size_t)y) * tiles + (size_t)x;
                g->chosen[k] = -1;
                plod_bound b[2];
                plod_facetiles_bounds(&fv, f, level, x, y, b);
                if (plod_facetiles_culled(&fv, b))
                    continue;
                unculled++;
                float hmax = b[0].hmax > b[1].hmax ? b[0].hmax : b[1].hmax;
                if (params->skip_sea && planet->has_sea_level &&
                    (double)hmax <= planet->sea_level) { /* on the lower bound */
                    sea_skipped++;
                    continue;
                }
                float *d = g->dvalues + k * (size_t)(n + 1);
                if (isnan(d[0]))
                    plod__dvalues(planet, f, level, x, y, n, d, work);
                double distance = plod_facetiles_distance(&fv, b);
                if (distance < view->distance_floor)
                    distance = view->distance_floor;
                int m = n;
                for (; m > 0; m--) { /* the coarsest level within the threshold */
                    double ok;
                    if (params->criterion == PLOD_CRITERION_SIDE_DISTANCE) {
                        double cell = b[0].size / ldexp(1.0, n - m); /* diagonal */
                        ok = cell * ldexp(1.0, params->template_level) / distance <=
                             params->split_border;
                    } else if (camera->desc.orthographic) {
                        ok = (double)d[m] * camera->pixels_per_metre <= params->max_pixel_error;
                    } else {
                        ok = (double)d[m] * camera->pixels_per_radian / distance <=
                             params->max_pixel_error;
                    }
                    if (ok)
                        break;
                }
                g->chosen[k] = (signed char)m;
                finest = n - m > finest ? n - m : finest;
                if (g->list_count == g->list_capacity) {
                    plod_face_tile *grown = plod_grow(g->list, &g->list_capacity,
                                                      g->list_count + 1, sizeof *grown, 64);
                    if (!grown) {
                        free(work);
                        g->list_count = 0;
                        return plod_error_set(error, PLOD_ERR_NO_MEMORY,
                                              "geomipmap: out of memory");
                    }
                    g->list = grown;
                }
                plod_face_tile *t = &g->list[g->list_count++];
                memset(t, 0, sizeof *t);
                t->face = (uint8_t)f, t->level = (uint8_t)level, t->x = x, t->y = y;
                t->key = plod_face_tile_key(f, level, x, y);
                t->cells_log2 = (uint8_t)(n - m);
                t->method_level = m;
            }
    free(work);
    /* stitching: each edge keeps its coarser neighbour's vertices */
    for (size_t i = 0; i < g->list_count; i++) {
        plod_face_tile *t = &g->list[i];
        int m = n - t->cells_log2;
        for (int e = 0; e < 4; e++) {
            int face;
            double u, v;
            plod_facetiles_across(t->face, level, t->x, t->y, e, &face, &u, &v);
            int32_t nx = (int32_t)floor((u + 1.0) * 0.5 * tiles);
            int32_t ny = (int32_t)floor((v + 1.0) * 0.5 * tiles);
            nx = nx < 0 ? 0 : (nx >= tiles ? tiles - 1 : nx);
            ny = ny < 0 ? 0 : (ny >= tiles ? tiles - 1 : ny);
            int other = g->chosen[((size_t)face * tiles + (size_t)ny) * tiles + (size_t)nx];
            if (other > m)
                t->coarser[e] = (uint8_t)(other - m);
            else if (other >= 0 && other < m)
                t->finer |= (uint8_t)(1u << e);
        }
    }
    if (stats) {
        memset(stats, 0, sizeof *stats);
        stats->sectors_total = count;
        stats->sectors_after_backface = stats->sectors_after_frustum = unculled;
        stats->sectors_after_budget = g->list_count;
        stats->sectors_sea_skipped = sea_skipped;
        stats->max_level_reached = finest;
        stats->refine_us = (double)(plod_clock_ns() - start) * 1e-3;
    }
    return PLOD_OK;
}
