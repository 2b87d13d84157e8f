/* clipmap.c -- geometry clipmaps on the cube faces (plod_clipmap.h). */
#include <math.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "plod_clipmap.h"
#include "plod_platform.h"
#include "plod_projection.h"

/* Cells (of the ring's level) inside the ring's outer edge where a coarse
 * leaf's corner can lie: a level l-1 cell's diagonal is at most ~3.7
 * level-l cells on every cube projection (its edges are up to 1.3 s_l
 * long), so every vertex on a ring's outer edge has phi >= ring_cells -
 * CM_MARGIN and gets alpha 1. */
#define CM_MARGIN 5.0
/* Cells beyond ring_cells / 2 where the finer ring's outer edge can lie
 * (its centre is up to ~2.8 cells from this ring's): alpha stays 0 there. */
#define CM_INNER 3.0
#define CM_LEVELS (PLOD_CLIPMAP_MAX_LEVEL + 1)

/* ---- cells ----------------------------------------------------------------
 * A cell is (face, i, j) at a level; its plain key face<<58 | i<<29 | j
 * sorts by face, then i, then j. */
static uint64_t cm__key(int face, uint32_t i, uint32_t j)
{
    return ((uint64_t)face << 58) | ((uint64_t)i << 29) | (uint64_t)j;
}

static void cm__unkey(uint64_t key, int *face, uint32_t *i, uint32_t *j)
{
    *face = (int)(key >> 58);
    *i = (uint32_t)((key >> 29) & 0x1FFFFFFFu);
    *j = (uint32_t)(key & 0x1FFFFFFFu);
}

/* Block-order key of a level-l cell with blocks of 2^b cells: face, block
 * (i >> b, j >> b), then the cell inside; the leaves of one block are then
 * contiguous.  Bits: 3 + 2 (29 - b) + 2 b = 61. */
static uint64_t cm__block_key(int face, uint32_t i, uint32_t j, int b)
{
    uint64_t m = ((uint64_t)1 << b) - 1, k = (uint64_t)face;
    k = (k << (29 - b)) | (i >> b);
    k = (k << (29 - b)) | (j >> b);
    k = (k << b) | (i & m);
    return (k << b) | (j & m);
}

static void cm__block_unkey(uint64_t k, int b, int *face, uint32_t *i, uint32_t *j)
{
    uint64_t m = ((uint64_t)1 << b) - 1, m29 = ((uint64_t)1 << (29 - b)) - 1;
    uint32_t lj = (uint32_t)(k & m), li = (uint32_t)((k >> b) & m);
    uint32_t bj = (uint32_t)((k >> (2 * b)) & m29), bi = (uint32_t)((k >> (2 * b + 29 - b)) & m29);
    *face = (int)(k >> (2 * b + 2 * (29 - b)));
    *i = (bi << b) | li;
    *j = (bj << b) | lj;
}

static int cm__compare_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

/* Face coordinate of grid line g at level l: exact (dyadic). */
static double cm__coord(uint32_t g, int level)
{
    return -1.0 + ldexp((double)g, 1 - level);
}

/* ---- state -------------------------------------------------------------------- */

typedef struct cm__stitch {
    int face;
    uint32_t ai, aj, bi, bj; /* coarse ends, in the leaf's level; b follows a
                                counter-clockwise around the leaf */
} cm__stitch;

typedef struct cm__block {
    int face;
    uint32_t bi, bj;        /* the block's cell at level l - shift */
    int shift;              /* cells per side: 2^shift */
    size_t leaf_begin, leaf_end, stitch_begin, stitch_end;
    uint32_t grid_vertices; /* grid points its leaves use */
    double axis[3], angle;  /* bounding cap */
    double r_min, r_max;    /* metres from the centre */
} cm__block;

typedef struct cm__level {
    int built;
    /* inputs the level was built from: C_{l+1} when it has a finer level */
    int has_next, next_face;
    uint32_t next_i, next_j;
    uint64_t *refined;      /* level-l cells split into level l+1, sorted */
    size_t n_refined, cap_refined;
    uint64_t *leaves;       /* level-l leaves, block-order keys, sorted */
    size_t n_leaves, cap_leaves;
    cm__stitch *stitches;
    size_t n_stitches, cap_stitches;
    cm__block *blocks;
    size_t n_blocks, cap_blocks;
} cm__level;

typedef struct cm__visible {
    int level;
    size_t block;
    size_t vertex_base, triangle_base;
} cm__visible;

struct plod_clipmap {
    /* what the levels were built for */
    const plod_planet *planet;
    double radius;
    plod_projection projection;
    int ring_cells, block_level, finest;
    uint64_t stamp;
    int handed[PLOD_FACE_COUNT]; /* e_u x e_v points outward */
    double centre[CM_LEVELS][3]; /* C_l (level 0: unused) */
    int centre_face[CM_LEVELS];
    uint32_t centre_i[CM_LEVELS], centre_j[CM_LEVELS];
    cm__level levels[CM_LEVELS];
    cm__visible *visible;
    size_t n_visible, cap_visible;
    size_t vertices, triangles;
    int updated;
};

static void cm__level_free(cm__level *level)
{
    free(level->refined);
    free(level->leaves);
    free(level->stitches);
    free(level->blocks);
    memset(level, 0, sizeof *level);
}

void plod_clipmap_params_default(plod_clipmap_params *params)
{
    if (!params)
        return;
    params->ring_cells = 32;
    params->max_pixel_error = 1.0;
    params->max_level = 24;
    params->block_level = 3;
    params->backface = 1;
    params->frustum = 1;
}

plod_status plod_clipmap_create(plod_clipmap **out)
{
    if (!out)
        return PLOD_ERR_NULL;
    *out = calloc(1, sizeof **out);
    return *out ? PLOD_OK : PLOD_ERR_NO_MEMORY;
}

void plod_clipmap_reset(plod_clipmap *clipmap)
{
    if (!clipmap)
        return;
    for (int l = 0; l < CM_LEVELS; l++)
        cm__level_free(&clipmap->levels[l]);
    free(clipmap->visible);
    memset(clipmap, 0, sizeof *clipmap);
}

void plod_clipmap_destroy(plod_clipmap *clipmap)
{
    plod_clipmap_reset(clipmap);
    free(clipmap);
}

size_t plod_clipmap_vertex_count(const plod_clipmap *clipmap)
{
    return clipmap && clipmap->updated ? clipmap->vertices : 0;
}

size_t plod_clipmap_triangle_count(const plod_clipmap *clipmap)
{
    return clipmap && clipmap->updated ? clipmap->triangles : 0;
}

size_t plod_clipmap_block_count(const plod_clipmap *clipmap)
{
    return clipmap && clipmap->updated ? clipmap->n_visible : 0;
}

size_t plod_clipmap_memory_bytes(const plod_clipmap *clipmap)
{
    if (!clipmap)
        return 0;
    size_t bytes = sizeof *clipmap + clipmap->cap_visible * sizeof *clipmap->visible;
    for (int l = 0; l < CM_LEVELS; l++) {
        const cm__level *L = &clipmap->levels[l];
        bytes += (L->cap_refined + L->cap_leaves) * sizeof(uint64_t) +
                 L->cap_stitches * sizeof *L->stitches + L->cap_blocks * sizeof *L->blocks;
    }
    return bytes;
}

/* ---- geometry helpers ------------------------------------------------------------ */

/* Nominal angular size of a level-l cell (a face spans pi/2). */
static double cm__cell_angle(int level)
{
    return ldexp(PLOD_PI / 2, -level);
}

static double cm__angle(const double a[3], const double b[3])
{
    double c[3];
    plod_cross3(a, b, c);
    return atan2(plod_norm3(c), plod_dot3(a, b));
}

static void cm__dir(const plod_clipmap *cm, int face, uint32_t gi, uint32_t gj, int level,
                    double dir[3])
{
    plod_face_to_dir(cm->projection, face, cm__coord(gi, level), cm__coord(gj, level), dir);
}

/* Corners of cell (i, j) counter-clockwise seen from outside, as grid
 * points: c[k] = (gi, gj). */
static void cm__corners(const plod_clipmap *cm, int face, uint32_t i, uint32_t j,
                        uint32_t c[4][2])
{
    uint32_t plain[4][2] = {{i, j}, {i + 1, j}, {i + 1, j + 1}, {i, j + 1}};
    for (int k = 0; k < 4; k++) {
        int from = cm->handed[face] ? k : (4 - k) % 4;
        c[k][0] = plain[from][0];
        c[k][1] = plain[from][1];
    }
}

/* Chord bound of the ring of level l+1: a level-l cell is refined when
 * every corner lies within ring_cells * s_{l+1} of C_{l+1} (chord
 * 2 sin(theta / 2)); *all: the ring covers the sphere. */
static double cm__ring_chord2(const plod_clipmap *cm, int level, int *all)
{
    double theta = cm->ring_cells * cm__cell_angle(level + 1);
    *all = theta >= PLOD_PI;
    double limit = 2.0 * sin((*all ? PLOD_PI : theta) / 2);
    return limit * limit;
}

static int cm__within(const double d[3], const double c[3], double chord2)
{
    double x = d[0] - c[0], y = d[1] - c[1], z = d[2] - c[2];
    return x * x + y * y + z * z <= chord2;
}

/* A binary search in a sorted array. */
static int cm__contains(const uint64_t *sorted, size_t n, uint64_t key)
{
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (sorted[mid] < key)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo < n && sorted[lo] == key;
}

/* ---- edge set: the edges of a level's refined cells --------------------------------- */

typedef struct cm__edge {
    double a[3], b[3]; /* ordered endpoints (memcmp order) */
    int used;
} cm__edge;

typedef struct cm__edges {
    cm__edge *slots;
    size_t mask;
} cm__edges;

static uint64_t cm__hash_doubles(const double *values, int n, uint64_t h)
{
    for (int k = 0; k < n; k++) {
        uint64_t x;
        memcpy(&x, values + k, sizeof x);
        h = (h ^ x) * 0x9e3779b97f4a7c15ull;
        h ^= h >> 31;
    }
    return h;
}

static void cm__edge_make(const double p[3], const double q[3], cm__edge *e)
{
    int swap = memcmp(p, q, 3 * sizeof(double)) > 0;
    memcpy(e->a, swap ? q : p, 3 * sizeof(double));
    memcpy(e->b, swap ? p : q, 3 * sizeof(double));
    e->used = 1;
}

static size_t cm__edge_slot(const cm__edges *set, const cm__edge *e)
{
    uint64_t h = cm__hash_doubles(e->a, 3, 0xcbf29ce484222325ull);
    h = cm__hash_doubles(e->b, 3, h);
    size_t s = (size_t)(h ^ (h >> 29)) & set->mask;
    while (set->slots[s].used && (memcmp(set->slots[s].a, e->a, sizeof e->a) != 0 ||
                                  memcmp(set->slots[s].b, e->b, sizeof e->b) != 0))
        s = (s + 1) & set->mask;
    return s;
}

/* ---- building a level --------------------------------------------------------------- */

static int cm__push_u64(uint64_t **array, size_t *n, size_t *cap, uint64_t value)
{
    if (*n == *cap) {
        uint64_t *grown = plod_grow(*array, cap, *n + 1, sizeof **array, 64);
        if (!grown)
            return 0;
        *array = grown;
    }
    (*array)[(*n)++] = value;
    return 1;
}

/* Block bounds: a cap around the block's cell and its heights. */
static void cm__block_bounds(const plod_clipmap *cm, cm__block *b, int level)
{
    int lb = level - b->shift;
    uint32_t gi = b->bi, gj = b->bj;
    double u0 = cm__coord(gi, lb), u1 = cm__coord(gi + 1, lb);
    double v0 = cm__coord(gj, lb), v1 = cm__coord(gj + 1, lb);
    plod_face_to_dir(cm->projection, b->face, 0.5 * (u0 + u1), 0.5 * (v0 + v1), b->axis);
    double angle = 0.0;
    for (int k = 0; k < 9; k++) {
        if (k == 4)
            continue;
        double u = k % 3 == 0 ? u0 : (k % 3 == 1 ? 0.5 * (u0 + u1) : u1);
        double v = k / 3 == 0 ? v0 : (k / 3 == 1 ? 0.5 * (v0 + v1) : v1);
        double d[3];
        plod_face_to_dir(cm->projection, b->face, u, v, d);
        double a = cm__angle(b->axis, d);
        angle = a > angle ? a : angle;
    }
    /* the edges between the samples bulge a little beyond them */
    b->angle = angle * (lb <= 2 ? 1.1 : 1.02) + 1e-12;
    double hmin, hmax, dmin, dmax, imin, imax;
    plod_planet_height_range_uv(cm->planet, b->face, u0, v0, u1, v1, &hmin, &hmax);
    plod_planet_detail_range_uv(cm->planet, b->face, u0, v0, u1, v1, &dmin, &dmax, NULL);
    hmin += dmin;
    hmax += dmax;
    if (plod_planet_insets_range_cap(cm->planet, b->axis, b->angle, &imin, &imax, NULL)) {
        hmin = imin + dmin < hmin ? imin + dmin : hmin;
        hmax = imax + dmax > hmax ? imax + dmax : hmax;
    }
    b->r_min = cm->radius + hmin;
    b->r_max = cm->radius + hmax;
}

/* Builds level l from level l-1's refined cells (all six faces at level
 * 0) and C_{l+1}.  0 without memory. */
static int cm__build_level(plod_clipmap *cm, int level, int has_next)
{
    cm__level *L = &cm->levels[level];
    L->built = 0;
    L->n_refined = L->n_leaves = L->n_stitches = L->n_blocks = 0;
    L->has_next = has_next;
    L->next_face = has_next ? cm->centre_face[level + 1] : -1;
    L->next_i = has_next ? cm->centre_i[level + 1] : 0;
    L->next_j = has_next ? cm->centre_j[level + 1] : 0;
    int b = cm->block_level < level ? cm->block_level : level;

    size_t parents = level == 0 ? PLOD_FACE_COUNT : cm->levels[level - 1].n_refined;
    int all = 0;
    double chord2 = has_next ? cm__ring_chord2(cm, level, &all) : 0.0;
    const double *centre = has_next ? cm->centre[level + 1] : NULL;
    for (size_t p = 0; p < parents; p++) {
        int face;
        uint32_t pi = 0, pj = 0;
        if (level == 0)
            face = (int)p;
        else
            cm__unkey(cm->levels[level - 1].refined[p], &face, &pi, &pj);
        /* the children's corners: the parent's 3 x 3 grid points (2 x 2 at
         * level 0), each tested once */
        int side = level == 0 ? 2 : 3, inside[3][3];
        for (int a = 0; a < side && has_next && !all; a++)
            for (int c = 0; c < side; c++) {
                double d[3];
                cm__dir(cm, face, 2 * pi + (uint32_t)a, 2 * pj + (uint32_t)c, level, d);
                inside[a][c] = cm__within(d, centre, chord2);
            }
        for (int c = 0; c < (level == 0 ? 1 : 4); c++) {
            int ci = level == 0 ? 0 : c >> 1, cj = level == 0 ? 0 : c & 1;
            uint32_t i = 2 * pi + (uint32_t)ci, j = 2 * pj + (uint32_t)cj;
            int refines = has_next && (all || (inside[ci][cj] && inside[ci + 1][cj] &&
                                               inside[ci][cj + 1] && inside[ci + 1][cj + 1]));
            int ok = refines
                         ? cm__push_u64(&L->refined, &L->n_refined, &L->cap_refined,
                                        cm__key(face, i, j))
                         : cm__push_u64(&L->leaves, &L->n_leaves, &L->cap_leaves,
                                        cm__block_key(face, i, j, b));
            if (!ok)
                return 0;
        }
    }
    if (L->n_refined)
        qsort(L->refined, L->n_refined, sizeof *L->refined, cm__compare_u64);
    if (L->n_leaves)
        qsort(L->leaves, L->n_leaves, sizeof *L->leaves, cm__compare_u64);

    /* stitches: leaf edges that a refined cell of this level shares */
    cm__edges set = {NULL, 0};
    if (L->n_refined) {
        size_t slots = 16;
        while (slots < 8 * L->n_refined)
            slots *= 2;
        set.slots = calloc(slots, sizeof *set.slots);
        if (!set.slots)
            return 0;
        set.mask = slots - 1;
        uint32_t last = (uint32_t)1 << level; /* cells per face side */
        for (size_t r = 0; r < L->n_refined; r++) {
            int face;
            uint32_t i, j, c[4][2];
            cm__unkey(L->refined[r], &face, &i, &j);
            if (i != 0 && j != 0 && i + 1 != last && j + 1 != last)
                continue; /* its edges meet cells of its own face only */
            cm__corners(cm, face, i, j, c);
            double d[4][3];
            for (int k = 0; k < 4; k++)
                cm__dir(cm, face, c[k][0], c[k][1], level, d[k]);
            for (int k = 0; k < 4; k++) {
                cm__edge e;
                cm__edge_make(d[k], d[(k + 1) % 4], &e);
                set.slots[cm__edge_slot(&set, &e)] = e;
            }
        }
    }

    /* blocks: runs of leaves with the same block */
    for (size_t f = 0; f < L->n_leaves;) {
        int face;
        uint32_t i, j;
        cm__block_unkey(L->leaves[f], b, &face, &i, &j);
        cm__block blk;
        memset(&blk, 0, sizeof blk);
        blk.face = face;
        blk.bi = i >> b;
        blk.bj = j >> b;
        blk.shift = b;
        blk.leaf_begin = f;
        blk.stitch_begin = L->n_stitches;
        int n = 1 << b;
        unsigned char *used = calloc((size_t)(n + 1) * (size_t)(n + 1), 1);
        if (!used) {
            free(set.slots);
            return 0;
        }
        size_t g = f;
        for (; g < L->n_leaves; g++) {
            int gf;
            uint32_t gi, gj;
            cm__block_unkey(L->leaves[g], b, &gf, &gi, &gj);
            if (gf != face || (gi >> b) != blk.bi || (gj >> b) != blk.bj)
                break;
            uint32_t li = gi & (uint32_t)(n - 1), lj = gj & (uint32_t)(n - 1);
            used[li * (uint32_t)(n + 1) + lj] = used[(li + 1) * (uint32_t)(n + 1) + lj] = 1;
            used[li * (uint32_t)(n + 1) + lj + 1] = used[(li + 1) * (uint32_t)(n + 1) + lj + 1] = 1;
            if (!set.slots)
                continue;
            uint32_t c[4][2], last = (uint32_t)1 << level;
            cm__corners(cm, gf, gi, gj, c);
            int border = gi == 0 || gj == 0 || gi + 1 == last || gj + 1 == last;
            double d[4][3];
            for (int k = 0; k < 4 && border; k++)
                cm__dir(cm, gf, c[k][0], c[k][1], level, d[k]);
            for (int k = 0; k < 4; k++) {
                /* the cell across edge k: on this face, an integer look-up;
                 * across a face edge, by the edge's directions */
                uint32_t a0 = c[k][0], a1 = c[k][1], b0 = c[(k + 1) % 4][0],
                         b1 = c[(k + 1) % 4][1];
                int shared;
                if (a0 == b0 && (a0 == 0 || a0 == last)) {
                    cm__edge e;
                    cm__edge_make(d[k], d[(k + 1) % 4], &e);
                    shared = set.slots[cm__edge_slot(&set, &e)].used;
                } else if (a1 == b1 && (a1 == 0 || a1 == last)) {
                    cm__edge e;
                    cm__edge_make(d[k], d[(k + 1) % 4], &e);
                    shared = set.slots[cm__edge_slot(&set, &e)].used;
                } else {
                    /* the neighbour is the cell on the far side of the edge */
                    uint32_t ni = a0 == b0 ? (a0 == gi ? gi - 1 : gi + 1) : gi;
                    uint32_t nj = a1 == b1 ? (a1 == gj ? gj - 1 : gj + 1) : gj;
                    shared = cm__contains(L->refined, L->n_refined, cm__key(gf, ni, nj));
                }
                if (!shared)
                    continue;
                if (L->n_stitches == L->cap_stitches) {
                    cm__stitch *grown = plod_grow(L->stitches, &L->cap_stitches,
                                                  L->n_stitches + 1, sizeof *grown, 64);
                    if (!grown) {
                        free(used);
                        free(set.slots);
                        return 0;
                    }
                    L->stitches = grown;
                }
                cm__stitch s = {gf, c[k][0], c[k][1], c[(k + 1) % 4][0], c[(k + 1) % 4][1]};
                L->stitches[L->n_stitches++] = s;
            }
        }
        for (size_t k = 0; k < (size_t)(n + 1) * (size_t)(n + 1); k++)
            blk.grid_vertices += used[k];
        free(used);
        blk.leaf_end = g;
        blk.stitch_end = L->n_stitches;
        cm__block_bounds(cm, &blk, level);
        if (L->n_blocks == L->cap_blocks) {
            cm__block *grown = plod_grow(L->blocks, &L->cap_blocks, L->n_blocks + 1,
                                         sizeof *grown, 16);
            if (!grown) {
                free(set.slots);
                return 0;
            }
            L->blocks = grown;
        }
        L->blocks[L->n_blocks++] = blk;
        f = g;
    }
    free(set.slots);
    L->built = 1;
    return 1;
}

/* ---- culling ------------------------------------------------------------------------ */

typedef struct cm__view {
    const plod_camera *camera;
    double eye[3], eye_unit[3], eye_dist;
    int horizon;                 /* the eye is above the occluder */
    double occluder, eye_horizon; /* radius; the eye's horizon angle */
    int backface, frustum;
} cm__view;

static int cm__block_visible(const cm__view *view, const cm__block *b)
{
    double theta = b->angle < PLOD_PI ? b->angle : PLOD_PI;
    if (view->backface && view->horizon) {
        double gamma = cm__angle(view->eye_unit, b->axis);
        double peek = b->r_max > view->occluder ? acos(view->occluder / b->r_max) : 0.0;
        if (gamma - theta > view->eye_horizon + peek)
            return 0;
    }
    if (view->frustum && theta < PLOD_PI / 2) {
        /* the ball around the cap prism's section: its farthest points from
         * an axis point are the section's four corners */
        double c = cos(theta), s = sin(theta);
        double z0 = 0.5 * (b->r_min * c + b->r_max);
        double pts[4][2] = {{b->r_max, 0.0}, {b->r_max * c, b->r_max * s},
                            {b->r_min * c, b->r_min * s}, {b->r_min, 0.0}};
        double radius2 = 0.0;
        for (int k = 0; k < 4; k++) {
            double dz = pts[k][0] - z0, dx = pts[k][1];
            double d2 = dz * dz + dx * dx;
            radius2 = d2 > radius2 ? d2 : radius2;
        }
        double radius = sqrt(radius2) * (1.0 + 1e-9);
        double centre[3] = {b->axis[0] * z0, b->axis[1] * z0, b->axis[2] * z0};
        for (int p = 0; p < 6; p++) {
            const double *pl = view->camera->planes[p];
            if (pl[0] * centre[0] + pl[1] * centre[1] + pl[2] * centre[2] + pl[3] < -radius)
                return 0;
        }
    }
    return 1;
}

/* ---- update --------------------------------------------------------------------------- */

static plod_status cm__check(const plod_planet *planet, const plod_camera *camera,
                             const plod_clipmap_params *p, plod_error *error)
{
    if (!plod_projection_is_cube(planet->projection))
        return plod_error_set(error, PLOD_ERR_BAD_PARAM,
                              "the clipmap needs a cube projection (tsc, csc, qsc, spherified)");
    if (!(planet->radius > 0.0) || !isfinite(planet->radius))
        return plod_error_set(error, PLOD_ERR_BAD_PARAM, "radius must be positive and finite");
    if (p->ring_cells < 24 || p->ring_cells > 1024)
        return plod_error_set(error, PLOD_ERR_BAD_PARAM, "ring_cells must be 24..1024 (got %d)",
                              p->ring_cells);
    if (!(p->max_pixel_error > 0.0) || !isfinite(p->max_pixel_error))
        return plod_error_set(error, PLOD_ERR_BAD_PARAM,
                              "max_pixel_error must be positive and finite");
    if (p->max_level < 1 || p->max_level > PLOD_CLIPMAP_MAX_LEVEL)
        return plod_error_set(error, PLOD_ERR_BAD_PARAM, "max_level must be 1..%d (got %d)",
                              PLOD_CLIPMAP_MAX_LEVEL, p->max_level);
    if (p->block_level < 0 || p->block_level > PLOD_CLIPMAP_MAX_BLOCK_LEVEL)
        return plod_error_set(error, PLOD_ERR_BAD_PARAM, "block_level must be 0..%d (got %d)",
                              PLOD_CLIPMAP_MAX_BLOCK_LEVEL, p->block_level);
    const double *e = camera->position;
    if (!isfinite(e[0]) || !isfinite(e[1]) || !isfinite(e[2]) || plod_norm3(e) == 0.0)
        return plod_error_set(error, PLOD_ERR_BAD_COORD,
                              "the camera must not be at the planet's centre");
    return PLOD_OK;
}

plod_status plod_clipmap_update(plod_clipmap *cm, const plod_planet *planet,
                                const plod_surface_source *surface,
                                const plod_camera *camera,
                                const plod_clipmap_params *params,
                                plod_clipmap_stats *stats, plod_error *error)
{
    if (!cm || !planet || !surface || !surface->ops || !camera || !params)
        return plod_error_set(error, PLOD_ERR_NULL, "clipmap update: a required argument is NULL");
    plod_status st = cm__check(planet, camera, params, error);
    if (st != PLOD_OK)
        return st;
    uint64_t start = plod_clock_ns();
    uint64_t stamp = surface->ops->stamp ? surface->ops->stamp(surface->self) : 0;
    if (cm->planet != planet || cm->radius != planet->radius ||
        cm->projection != planet->projection || cm->ring_cells != params->ring_cells ||
        cm->block_level != params->block_level || cm->stamp != stamp) {
        plod_clipmap_reset(cm);
        cm->planet = planet;
        cm->radius = planet->radius;
        cm->projection = planet->projection;
        cm->ring_cells = params->ring_cells;
        cm->block_level = params->block_level;
        cm->stamp = stamp;
        for (int f = 0; f < PLOD_FACE_COUNT; f++) {
            int frame[3][3];
            plod_face_frame(f, frame);
            double c[3], eu[3], ev[3], n[3];
            for (int k = 0; k < 3; k++) {
                c[k] = frame[0][k];
                eu[k] = frame[1][k];
                ev[k] = frame[2][k];
            }
            plod_cross3(eu, ev, n);
            cm->handed[f] = plod_dot3(n, c) > 0.0;
        }
    }
    cm->updated = 0;

    /* the finest level: cells of max_pixel_error pixels at the eye's height */
    const double *eye = camera->position;
    double eye_dist = plod_norm3(eye), unit[3] = {eye[0] / eye_dist, eye[1] / eye_dist,
                                                  eye[2] / eye_dist};
    double ground;
    surface->ops->sample_n(surface->self, 1, unit, NULL, NULL, &ground, NULL, NULL);
    double height = eye_dist - (planet->radius + ground);
    double target = camera->desc.orthographic
                        ? params->max_pixel_error / camera->pixels_per_metre
                        : params->max_pixel_error * (height > 0.0 ? height : 0.0) /
                              camera->pixels_per_radian;
    int finest = params->max_level;
    if (target > 0.0 && isfinite(target)) {
        double levels = ceil(log2(planet->radius * (PLOD_PI / 2) / target));
        finest = levels < 1.0 ? 1 : (levels < params->max_level ? (int)levels : params->max_level);
    }

    /* the centres C_l, l = 1..finest: the level l-1 cell holding the nadir */
    int nface;
    double nu, nv;
    if (plod_dir_to_face(planet->projection, unit, &nface, &nu, &nv) != PLOD_OK)
        return plod_error_set(error, PLOD_ERR_BAD_COORD, "the camera's nadir has no face");
    for (int l = 1; l <= finest; l++) {
        double cells = ldexp(1.0, l - 1);
        double fi = floor((nu + 1.0) * 0.5 * cells), fj = floor((nv + 1.0) * 0.5 * cells);
        uint32_t ci = (uint32_t)(fi < cells - 1 ? fi : cells - 1);
        uint32_t cj = (uint32_t)(fj < cells - 1 ? fj : cells - 1);
        cm->centre_face[l] = nface;
        cm->centre_i[l] = ci;
        cm->centre_j[l] = cj;
        plod_face_to_dir(planet->projection, nface, cm__coord(2 * ci + 1, l),
                         cm__coord(2 * cj + 1, l), cm->centre[l]);
    }

    /* rebuild from the first level whose inputs changed */
    size_t refreshed = 0, cells = 0, blocks = 0, stitches = 0;
    int first_rebuilt = finest + 1, parents_changed = 0;
    for (int l = 0; l <= finest; l++) {
        cm__level *L = &cm->levels[l];
        int has_next = l < finest;
        int same = L->built && !parents_changed && L->has_next == has_next &&
                   (!has_next || (L->next_face == cm->centre_face[l + 1] &&
                                  L->next_i == cm->centre_i[l + 1] &&
                                  L->next_j == cm->centre_j[l + 1]));
        if (!same) {
            uint64_t *old_leaves = NULL, *old_refined = NULL;
            size_t n_old = L->n_leaves, n_old_refined = L->n_refined;
            if (L->built) {
                old_leaves = malloc((n_old ? n_old : 1) * sizeof *old_leaves);
                old_refined = malloc((n_old_refined ? n_old_refined : 1) * sizeof *old_refined);
                if (old_leaves && n_old)
                    memcpy(old_leaves, L->leaves, n_old * sizeof *old_leaves);
                if (old_refined && n_old_refined)
                    memcpy(old_refined, L->refined, n_old_refined * sizeof *old_refined);
            }
            if (l < first_rebuilt)
                first_rebuilt = l;
            if (!cm__build_level(cm, l, has_next)) {
                free(old_leaves);
                free(old_refined);
                plod_clipmap_reset(cm);
                return plod_error_set(error, PLOD_ERR_NO_MEMORY, "clipmap: out of memory");
            }
            /* leaves new this frame: a merge of the two sorted lists */
            size_t a = 0;
            for (size_t k = 0; k < L->n_leaves; k++) {
                while (old_leaves && a < n_old && old_leaves[a] < L->leaves[k])
                    a++;
                refreshed += !(old_leaves && a < n_old && old_leaves[a] == L->leaves[k]);
            }
            parents_changed = !old_refined || n_old_refined != L->n_refined ||
                              (n_old_refined &&
                               memcmp(old_refined, L->refined,
                                      n_old_refined * sizeof *old_refined) != 0);
            free(old_leaves);
            free(old_refined);
        } else {
            parents_changed = 0;
        }
        cells += L->n_leaves;
        blocks += L->n_blocks;
        stitches += L->n_stitches;
    }
    for (int l = finest + 1; l < CM_LEVELS; l++)
        cm__level_free(&cm->levels[l]);
    cm->finest = finest;

    /* culling, per block */
    cm__view view;
    memset(&view, 0, sizeof view);
    view.camera = camera;
    memcpy(view.eye, eye, sizeof view.eye);
    memcpy(view.eye_unit, unit, sizeof view.eye_unit);
    view.eye_dist = eye_dist;
    double hmin, hmax;
    plod_planet_height_range(planet, &hmin, &hmax);
    view.occluder = planet->radius + (hmin < 0.0 ? hmin : 0.0);
    view.horizon = eye_dist > view.occluder;
    view.eye_horizon = view.horizon ? acos(view.occluder / eye_dist) : PLOD_PI;
    view.backface = params->backface != 0;
    view.frustum = params->frustum != 0;
    cm->n_visible = 0;
    cm->vertices = cm->triangles = 0;
    size_t open = 0;
    for (int l = 0; l <= finest; l++) {
        cm__level *L = &cm->levels[l];
        for (size_t k = 0; k < L->n_blocks; k++) {
            const cm__block *b = &L->blocks[k];
            if (!cm__block_visible(&view, b))
                continue;
            if (cm->n_visible == cm->cap_visible) {
                cm__visible *grown = plod_grow(cm->visible, &cm->cap_visible,
                                               cm->n_visible + 1, sizeof *grown, 256);
                if (!grown) {
                    plod_clipmap_reset(cm);
                    return plod_error_set(error, PLOD_ERR_NO_MEMORY, "clipmap: out of memory");
                }
                cm->visible = grown;
            }
            cm__visible vis = {l, k, cm->vertices, cm->triangles};
            cm->visible[cm->n_visible++] = vis;
            size_t ns = b->stitch_end - b->stitch_begin;
            cm->vertices += b->grid_vertices + 3 * ns;
            cm->triangles += 2 * (b->leaf_end - b->leaf_begin) + ns;
        }
    }
    if (cm->vertices > (size_t)INT32_MAX) {
        plod_clipmap_reset(cm);
        return plod_error_set(error, PLOD_ERR_NO_MEMORY, "clipmap: too many vertices");
    }
    cm->updated = 1;
    if (stats) {
        /* stitches whose midpoint does not reach alpha 1 (see CM_MARGIN) */
        for (int l = 1; l <= finest; l++) {
            const cm__level *C = &cm->levels[l - 1];
            double s = cm__cell_angle(l), edge = cm->ring_cells - CM_MARGIN;
            for (size_t k = 0; k < C->n_stitches; k++) {
                const cm__stitch *t = &C->stitches[k];
                double d[3];
                cm__dir(cm, t->face, t->ai + t->bi, t->aj + t->bj, l, d);
                open += cm__angle(d, cm->centre[l]) / s < edge;
            }
        }
        memset(stats, 0, sizeof *stats);
        stats->finest_level = finest;
        stats->first_rebuilt = first_rebuilt;
        stats->cells = cells;
        stats->cells_refreshed = refreshed;
        stats->blocks = blocks;
        stats->blocks_visible = cm->n_visible;
        stats->stitches = stitches;
        stats->stitches_open = open;
        stats->update_us = (double)(plod_clock_ns() - start) / 1e3;
    }
    return PLOD_OK;
}

/* ---- emission ------------------------------------------------------------------------- */

typedef struct cm__request {
    int level, face;
    uint32_t gi, gj;
} cm__request;

/* The ring's blend weight of a vertex (Losasso and Hoppe's alpha over the
 * angular distance to the ring's centre, in its cells); morph off: 1 in
 * the ring's outer margin, else 0. */
static double cm__alpha(const plod_clipmap *cm, int morph, int level, const double dir[3])
{
    if (level == 0)
        return 0.0;
    double phi = cm__angle(dir, cm->centre[level]) / cm__cell_angle(level);
    double k = cm->ring_cells, end = k - CM_MARGIN;
    if (!morph)
        return phi >= end ? 1.0 : 0.0;
    double begin = end - k / 5.0;
    begin = begin > k / 2.0 + CM_INNER ? begin : k / 2.0 + CM_INNER;
    double a = (phi - begin) / (end - begin);
    return a <= 0.0 ? 0.0 : (a >= 1.0 ? 1.0 : a);
}

typedef struct cm__emit {
    const plod_clipmap *cm;
    const plod_mesh_params *params;
    plod_mesh_sampler sampler;
    const plod_mesh_buffers *out;
    int morph;
    atomic_int failed;
} cm__emit;

/* Per vertex: 3 dirs, 1 cell, 3 world, 1 alpha, 3 target dirs, 1 target
 * cell, 3 target world, 3 target sum (doubles); 3 normals, 1 detail, 3
 * target normals, 1 target detail (floats). */
#define CM_DOUBLES 18
#define CM_FLOATS 8

/* Vertex values for n requests into the outputs at `vbase`: the shared
 * vertex evaluation (plod_mesh_sample) at the vertex and, where alpha > 0,
 * at its coarse neighbours, blended in double. */
static void cm__vertices(const cm__emit *e, const cm__request *req, size_t n, double lon_ref,
                         size_t vbase, double *scratch, float *fscratch)
{
    const plod_clipmap *cm = e->cm;
    const plod_mesh_buffers *out = e->out;
    const double *origin = e->params->origin;
    double *dirs = scratch, *cells = dirs + 3 * n, *world = cells + n, *alpha = world + 3 * n;
    double *tdirs = alpha + n, *tcells = tdirs + 3 * n, *tworld = tcells + n, *tsum = tworld + 3 * n;
    float *normals = fscratch, *detail = normals + 3 * n, *tnormals = detail + n,
          *tdetail = tnormals + 3 * n;
    for (size_t v = 0; v < n; v++) {
        cm__dir(cm, req[v].face, req[v].gi, req[v].gj, req[v].level, dirs + 3 * v);
        alpha[v] = cm__alpha(cm, e->morph, req[v].level, dirs + 3 * v);
        cells[v] = cm->radius * cm__cell_angle(req[v].level);
        tcells[v] = cm->radius * cm__cell_angle(req[v].level > 0 ? req[v].level - 1 : 0);
    }
    plod_mesh_sample(&e->sampler, n, dirs, cells, lon_ref, NULL, normals,
                     out->uv ? out->uv + 2 * vbase : NULL, detail, world);
    /* coarse targets: the midpoint of the two level l-1 neighbours on the
     * coarse triangulation (diagonal (i, j)-(i+1, j+1)), or, for a point of
     * the coarse grid, the point itself, sampled as the coarser level
     * samples it; one pass per end */
    double *tn = malloc(4 * n * sizeof *tn); /* normal sums and detail sums */
    if (!tn) {
        atomic_store((atomic_int *)&e->failed, 1);
        return;
    }
    for (int end = 0; end < 2; end++) {
        for (size_t v = 0; v < n; v++) {
            uint32_t oi = req[v].gi & 1u, oj = req[v].gj & 1u;
            uint32_t gi = end == 0 ? req[v].gi - oi : req[v].gi + oi;
            uint32_t gj = end == 0 ? req[v].gj - oj : req[v].gj + oj;
            if (alpha[v] > 0.0)
                cm__dir(cm, req[v].face, gi, gj, req[v].level, tdirs + 3 * v);
            else
                memcpy(tdirs + 3 * v, dirs + 3 * v, 3 * sizeof(double));
        }
        plod_mesh_sample(&e->sampler, n, tdirs, tcells, lon_ref, NULL, tnormals, NULL, tdetail,
                         tworld);
        for (size_t v = 0; v < n; v++) {
            if (!(alpha[v] > 0.0))
                continue;
            int even = !(req[v].gi & 1u) && !(req[v].gj & 1u);
            if (end == 1 && even)
                continue;
            for (int c = 0; c < 3; c++) {
                tsum[3 * v + c] = end == 0 ? tworld[3 * v + c]
                                           : (tsum[3 * v + c] + tworld[3 * v + c]) * 0.5;
                tn[4 * v + c] = end == 0 ? (double)tnormals[3 * v + c]
                                         : tn[4 * v + c] + (double)tnormals[3 * v + c];
            }
            tn[4 * v + 3] = end == 0 ? (double)tdetail[v]
                                     : (tn[4 * v + 3] + (double)tdetail[v]) * 0.5;
            if (end == 1) {
                double len = plod_norm3(tn + 4 * v);
                for (int c = 0; c < 3; c++)
                    tn[4 * v + c] = len > 0.0 ? tn[4 * v + c] / len : (double)normals[3 * v + c];
            }
        }
    }
    for (size_t v = 0; v < n; v++) {
        size_t o = vbase + v;
        double a = alpha[v], p[3], nrm[3], det = detail[v];
        for (int c = 0; c < 3; c++) {
            p[c] = world[3 * v + c];
            nrm[c] = normals[3 * v + c];
        }
        if (a >= 1.0) {
            for (int c = 0; c < 3; c++) {
                p[c] = tsum[3 * v + c];
                nrm[c] = tn[4 * v + c];
            }
            det = tn[4 * v + 3];
        } else if (a > 0.0) {
            for (int c = 0; c < 3; c++) {
                p[c] = (1.0 - a) * p[c] + a * tsum[3 * v + c];
                nrm[c] = (1.0 - a) * nrm[c] + a * tn[4 * v + c];
            }
            double len = plod_norm3(nrm);
            if (len > 0.0)
                for (int c = 0; c < 3; c++)
                    nrm[c] /= len;
            det = (1.0 - a) * det + a * tn[4 * v + 3];
        }
        if (out->positions)
            for (int c = 0; c < 3; c++)
                out->positions[3 * o + c] = (float)(p[c] - origin[c]);
        if (out->normals)
            for (int c = 0; c < 3; c++)
                out->normals[3 * o + c] = (float)nrm[c];
        if (out->morph)
            out->morph[o] = (float)a;
        if (out->detail)
            out->detail[o] = (float)det;
    }
    free(tn);
}

static int cm__emit_block(cm__emit *e, const cm__visible *vis)
{
    const plod_clipmap *cm = e->cm;
    const cm__level *L = &cm->levels[vis->level];
    const cm__block *b = &L->blocks[vis->block];
    const plod_mesh_buffers *out = e->out;
    int level = vis->level, n = 1 << b->shift;
    if (out->keys)
        out->keys[vis - cm->visible] = ((uint64_t)b->face << 56) | ((uint64_t)level << 50) |
                                       ((uint64_t)b->bj << 25) | (uint64_t)b->bi;
    size_t grid = (size_t)(n + 1) * (size_t)(n + 1);
    size_t ns = b->stitch_end - b->stitch_begin;
    size_t nreq = b->grid_vertices + 3 * ns;
    int32_t *index = malloc(grid * sizeof *index);
    cm__request *req = malloc(nreq * sizeof *req);
    double *scratch = malloc(CM_DOUBLES * nreq * sizeof *scratch);
    float *fscratch = malloc(CM_FLOATS * nreq * sizeof *fscratch);
    if (!index || !req || !scratch || !fscratch) {
        free(index), free(req), free(scratch), free(fscratch);
        return 0;
    }
    for (size_t k = 0; k < grid; k++)
        index[k] = -1;
    uint32_t mask = (uint32_t)(n - 1), i0 = b->bi << b->shift, j0 = b->bj << b->shift;
    for (size_t f = b->leaf_begin; f < b->leaf_end; f++) {
        int face;
        uint32_t i, j;
        cm__block_unkey(L->leaves[f], b->shift, &face, &i, &j);
        uint32_t li = i & mask, lj = j & mask;
        for (int c = 0; c < 4; c++)
            index[(li + (uint32_t)(c & 1)) * (uint32_t)(n + 1) + lj + (uint32_t)(c >> 1)] = 0;
    }
    int32_t next = 0;
    for (uint32_t li = 0; li <= (uint32_t)n; li++)
        for (uint32_t lj = 0; lj <= (uint32_t)n; lj++) {
            size_t k = li * (uint32_t)(n + 1) + lj;
            if (index[k] < 0)
                continue;
            index[k] = next;
            cm__request r = {level, b->face, i0 + li, j0 + lj};
            req[next++] = r;
        }
    for (size_t s = 0; s < ns; s++) {
        const cm__stitch *t = &L->stitches[b->stitch_begin + s];
        cm__request m = {level + 1, t->face, t->ai + t->bi, t->aj + t->bj};
        cm__request bq = {level, t->face, t->bi, t->bj};
        cm__request aq = {level, t->face, t->ai, t->aj};
        req[next + 3 * s] = m;
        req[next + 3 * s + 1] = bq;
        req[next + 3 * s + 2] = aq;
    }
    double lon_ref = plod_mesh_atan2(b->axis[1], b->axis[0]);
    cm__vertices(e, req, nreq, lon_ref, vis->vertex_base, scratch, fscratch);

    size_t t = vis->triangle_base;
    int32_t base = (int32_t)vis->vertex_base;
    for (size_t f = b->leaf_begin; f < b->leaf_end; f++, t += 2) {
        int face;
        uint32_t i, j, c[4][2];
        cm__block_unkey(L->leaves[f], b->shift, &face, &i, &j);
        cm__corners(cm, face, i, j, c);
        int32_t idx[4];
        for (int k = 0; k < 4; k++)
            idx[k] = base + index[(c[k][0] - i0) * (uint32_t)(n + 1) + (c[k][1] - j0)];
        if (out->triangles) {
            int32_t *tri = out->triangles + 3 * t;
            tri[0] = idx[0], tri[1] = idx[1], tri[2] = idx[2];
            tri[3] = idx[0], tri[4] = idx[2], tri[5] = idx[3];
        }
        if (out->sector_level)
            out->sector_level[t] = out->sector_level[t + 1] = level;
        if (out->face)
            out->face[t] = out->face[t + 1] = face;
    }
    for (size_t s = 0; s < ns; s++, t++) {
        int32_t v0 = base + next + (int32_t)(3 * s);
        if (out->triangles) {
            int32_t *tri = out->triangles + 3 * t;
            tri[0] = v0, tri[1] = v0 + 1, tri[2] = v0 + 2;
        }
        if (out->sector_level)
            out->sector_level[t] = level;
        if (out->face)
            out->face[t] = L->stitches[b->stitch_begin + s].face;
    }
    free(index), free(req), free(scratch), free(fscratch);
    return 1;
}

static void cm__run(void *context, size_t begin, size_t end)
{
    cm__emit *e = context;
    for (size_t k = begin; k < end; k++)
        if (!cm__emit_block(e, &e->cm->visible[k]))
            atomic_store(&e->failed, 1);
}

plod_status plod_clipmap_emit(const plod_clipmap *clipmap, const plod_mesh_params *params,
                              const plod_surface_source *surface, const plod_mesh_buffers *out,
                              size_t *vertex_count, size_t *triangle_count)
{
    if (vertex_count)
        *vertex_count = 0;
    if (triangle_count)
        *triangle_count = 0;
    if (!clipmap || !params || !params->planet || !surface || !surface->ops || !out)
        return PLOD_ERR_NULL;
    if (!clipmap->updated || params->threads < 1 || params->threads > PLOD_MESH_MAX_THREADS ||
        params->planet->radius != clipmap->radius || !(params->detail_fade_cell >= 0.0))
        return PLOD_ERR_BAD_PARAM;
    const double *o = params->origin, *eye = params->eye;
    if (!isfinite(o[0]) || !isfinite(o[1]) || !isfinite(o[2]) || !isfinite(eye[0]) ||
        !isfinite(eye[1]) || !isfinite(eye[2]))
        return PLOD_ERR_BAD_COORD;
    cm__emit *e = malloc(sizeof *e);
    if (!e)
        return PLOD_ERR_NO_MEMORY;
    memset(e, 0, sizeof *e);
    atomic_init(&e->failed, 0);
    e->cm = clipmap;
    e->params = params;
    e->out = out;
    e->morph = params->morph != 0;
    plod_mesh_sampler_init(&e->sampler, params, surface);
    /* blocks of a few hundred vertices: a handful per chunk */
    if (params->workers && params->threads > 1)
        plod_workers_for(params->workers, clipmap->n_visible, 4, cm__run, e);
    else
        plod_parallel_for(clipmap->n_visible, params->threads, cm__run, e);
    int failed = atomic_load(&e->failed);
    free(e);
    if (failed)
        return PLOD_ERR_NO_MEMORY;
    if (vertex_count)
        *vertex_count = clipmap->vertices;
    if (triangle_count)
        *triangle_count = clipmap->triangles;
    return PLOD_OK;
}
