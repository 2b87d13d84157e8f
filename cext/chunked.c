/* chunked.c -- chunked LOD on cube-face quadtrees (plod_chunked.h). */
#include "plod_chunked.h"
#include "plod_platform.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct plod__chunk {
    int32_t x, y;
    int32_t child; /* first of four, -1: a leaf */
    uint8_t face, level, culled, sea;
    float relief, size, sag; /* metres: for the skirt depth */
} plod__chunk;

struct plod_chunked {
    plod__chunk *nodes;
    size_t count, capacity;
    plod_face_tile *tiles;
    size_t tile_count, tile_capacity;
    uint32_t *stack;
    size_t stack_capacity;
};

plod_status plod_chunked_create(plod_chunked **out)
{
    if (!out)
        return PLOD_ERR_NULL;
    *out = calloc(1, sizeof **out);
    return *out ? PLOD_OK : PLOD_ERR_NO_MEMORY;
}

void plod_chunked_destroy(plod_chunked *c)
{
    if (!c)
        return;
    free(c->nodes);
    free(c->tiles);
    free(c->stack);
    free(c);
}

const plod_face_tile *plod_chunked_tiles(const plod_chunked *c, size_t *count)
{
    *count = c->tile_count;
    return c->tiles;
}

size_t plod_chunked_memory_bytes(const plod_chunked *c)
{
    return sizeof *c + c->capacity * sizeof *c->nodes + c->tile_capacity * sizeof *c->tiles +
           c->stack_capacity * sizeof *c->stack;
}

typedef struct plod__pass {
    plod_chunked *c;
    plod_facetiles_view fv;
    const plod_refine_params *params;
    const plod_planet *planet;
} plod__pass;

/* A new node (its bounds tested); -1 without memory. */
static int32_t plod__add(plod__pass *p, int face, int level, int32_t x, int32_t y)
{
    plod_chunked *c = p->c;
    if (c->count == c->capacity) {
        plod__chunk *grown = plod_grow(c->nodes, &c->capacity, c->count + 1, sizeof *grown, 64);
        if (!grown)
            return -1;
        c->nodes = grown;
    }
    plod_bound b[2];
    plod_facetiles_bounds(&p->fv, face, level, x, y, b);
    plod__chunk *n = &c->nodes[c->count];
    n->x = x, n->y = y, n->child = -1;
    n->face = (uint8_t)face, n->level = (uint8_t)level;
    n->culled = (uint8_t)plod_facetiles_culled(&p->fv, b);
    float hmin = b[0].hmin < b[1].hmin ? b[0].hmin : b[1].hmin;
    float hmax = b[0].hmax > b[1].hmax ? b[0].hmax : b[1].hmax;
    n->sea = p->planet->has_sea_level && (double)hmax <= p->planet->sea_level;
    n->relief = hmax - hmin;
    n->size = (float)(b[0].size > b[1].size ? b[0].size : b[1].size);
    n->sag = (float)(b[0].sag0 > b[1].sag0 ? b[0].sag0 : b[1].sag0);
    return (int32_t)c->count++;
}

static int plod__split(plod__pass *p, int32_t k)
{
    plod__chunk n = p->c->nodes[k];
    int32_t first = -1;
    for (int q = 0; q < 4; q++) {
        int32_t id = plod__add(p, n.face, n.level + 1, 2 * n.x + (q & 1), 2 * n.y + (q >> 1));
        if (id < 0)
            return -1;
        if (q == 0)
            first = id;
    }
    p->c->nodes[k].child = first;
    return 0;
}

/* The leaf containing face point (u, v). */
static int32_t plod__leaf_at(const plod_chunked *c, int face, double u, double v)
{
    int32_t k = face;
    while (c->nodes[k].child >= 0) {
        const plod__chunk *n = &c->nodes[k];
        double size = ldexp(1.0, -n->level); /* half the node's side */
        double mu = ldexp((double)n->x, 1 - n->level) - 1.0 + size;
        double mv = ldexp((double)n->y, 1 - n->level) - 1.0 + size;
        k = n->child + (u >= mu) + 2 * (v >= mv);
    }
    return k;
}

static int32_t plod__neighbour(const plod_chunked *c, const plod__chunk *n, int edge)
{
    int face;
    double u, v;
    plod_facetiles_across(n->face, n->level, n->x, n->y, edge, &face, &u, &v);
    return plod__leaf_at(c, face, u, v);
}

/* One selection at the view's threshold: the quadtree's splits by screen
 * error, then (stitched) the forced splits of the restricted tree.
 * PLOD_ERR_NO_MEMORY; *leaves, *splits, *truncated as found. */
static plod_status plod__select(plod__pass *p, int max_level, int t, int skirts,
                                size_t *leaves_out, size_t *splits_out, int *truncated_out)
{
    plod_chunked *c = p->c;
    const plod_refine_params *params = p->params;
    c->count = 0;
    for (int f = 0; f < 6; f++)
        if (plod__add(p, f, 0, 0, 0) < 0)
            return PLOD_ERR_NO_MEMORY;
    size_t splits = 0, leaves = 6;
    int truncated = 0;
    /* breadth first (nodes in creation order): splits by screen error */
    for (size_t k = 0; k < c->count; k++) {
        plod__chunk *n = &c->nodes[k];
        if (n->culled || n->level >= max_level)
            continue;
        plod_bound b[2];
        plod_facetiles_bounds(&p->fv, n->face, n->level, n->x, n->y, b);
        if (!(plod_facetiles_score(&p->fv, b, t) > 1.0))
            continue;
        if (leaves + 3 > params->max_sectors) {
            truncated = 1;
            break;
        }
        if (plod__split(p, (int32_t)k) < 0)
            return PLOD_ERR_NO_MEMORY;
        splits++;
        leaves += 3;
    }
    /* stitched edges: neighbours at most one level apart (forced splits) */
    for (int changed = !skirts; changed;) {
        changed = 0;
        for (size_t k = 0; k < c->count; k++) {
            if (c->nodes[k].child >= 0)
                continue;
            for (int e = 0; e < 4; e++) {
                int32_t m = plod__neighbour(c, &c->nodes[k], e);
                if (c->nodes[m].level + 1 >= c->nodes[k].level)
                    continue;
                if (plod__split(p, m) < 0)
                    return PLOD_ERR_NO_MEMORY;
                splits++;
                leaves += 3;
                changed = 1;
            }
        }
    }
    *leaves_out = leaves;
    *splits_out = splits;
    *truncated_out = truncated;
    return PLOD_OK;
}

plod_status plod_chunked_refine(plod_chunked *c, const plod_planet *planet,
                                const plod_camera *camera, const plod_refine_params *params,
                                int skirts, plod_refine_stats *stats, plod_error *error)
{
    uint64_t start = plod_clock_ns();
    plod_status st = plod_facetiles_check(planet, camera, params, error);
    if (st != PLOD_OK)
        return st;
    if (!skirts && params->template_level < 1)
        return plod_error_set(error, PLOD_ERR_BAD_PARAM,
                              "chunked LOD with stitched edges needs template_level >= 1 "
                              "(an edge must have a midpoint to stitch to)");
    plod__pass p = {c, {0}, params, planet};
    plod_facetiles_view_init(&p.fv, planet, camera, params);
    int max_level = params->max_level / 2;
    int t = params->template_level;
    if (max_level > PLOD_FACETILE_MAX_LEVEL)
        max_level = PLOD_FACETILE_MAX_LEVEL;
    /* a budget of chunks: the threshold rises in steps of sqrt 2 to the
     * first whose selection fits (as HRTMR's budget; still a function of
     * the camera alone) */
    size_t splits = 0, leaves = 0, all_splits = 0;
    int truncated = 0;
    for (int step = 0;; step++) {
        p.fv.view.coarsening = ldexp(step & 1 ? sqrt(2.0) : 1.0, step >> 1);
        if (plod__select(&p, max_level, t, skirts, &leaves, &splits, &truncated) != PLOD_OK)
            return plod_error_set(error, PLOD_ERR_NO_MEMORY, "chunked: out of memory");
        all_splits += splits;
        if (!params->budget || leaves <= params->budget || step >= 128)
            break;
    }
    splits = all_splits;
    /* the visible leaves, depth first (the stack never holds more than
     * the nodes and the six roots) */
    c->tile_count = 0;
    size_t top = 0, visible = 0, sea_skipped = 0;
    int deepest = 0;
    if (c->count + 6 > c->stack_capacity) {
        uint32_t *grown = plod_grow(c->stack, &c->stack_capacity, c->count + 6, 4, 64);
        if (!grown)
            return plod_error_set(error, PLOD_ERR_NO_MEMORY, "chunked: out of memory");
        c->stack = grown;
    }
    for (int f = 5; f >= 0; f--)
        c->stack[top++] = (uint32_t)f;
    while (top) {
        const plod__chunk *n = &c->nodes[c->stack[--top]];
        if (n->child >= 0) {
            for (int q = 3; q >= 0; q--)
                c->stack[top++] = (uint32_t)(n->child + q);
            continue;
        }
        if (n->culled)
            continue;
        if (n->sea && params->skip_sea) {
            sea_skipped++;
            continue;
        }
        if (c->tile_count == c->tile_capacity) {
            plod_face_tile *grown =
                plod_grow(c->tiles, &c->tile_capacity, c->tile_count + 1, sizeof *grown, 64);
            if (!grown)
                return plod_error_set(error, PLOD_ERR_NO_MEMORY, "chunked: out of memory");
            c->tiles = grown;
        }
        plod_face_tile *tile = &c->tiles[c->tile_count++];
        memset(tile, 0, sizeof *tile);
        tile->face = n->face, tile->level = n->level, tile->x = n->x, tile->y = n->y;
        tile->key = plod_face_tile_key(n->face, n->level, n->x, n->y);
        tile->cells_log2 = (uint8_t)t;
        tile->method_level = n->level;
        tile->sea = n->sea;
        for (int e = 0; e < 4; e++) {
            const plod__chunk *m = &c->nodes[plod__neighbour(c, n, e)];
            if (m->level < n->level && !skirts) {
                int d = n->level - m->level;
                tile->coarser[e] = (uint8_t)(d < t ? d : t);
            }
            if (m->level != n->level)
                tile->finer |= (uint8_t)((m->level > n->level) << e);
        }
        /* a coarser neighbour's edge leaves this chunk by at most its relief
         * and the curvature sag over its side */
        tile->skirt = n->relief + n->sag + 1e-3f * n->size;
        deepest = n->level > deepest ? n->level : deepest;
        visible++;
    }
    if (stats) {
        memset(stats, 0, sizeof *stats);
        stats->sectors_total = leaves;
        stats->sectors_after_backface = stats->sectors_after_frustum = visible + sea_skipped;
        stats->sectors_after_budget = visible;
        stats->sectors_sea_skipped = sea_skipped;
        stats->splits = splits;
        stats->max_level_reached = deepest;
        stats->truncated = truncated;
        stats->refine_us = (double)(plod_clock_ns() - start) * 1e-3;
    }
    return PLOD_OK;
}
