/* test_mesh.c -- unit tests of the mesh stage core (cext/mesh.c) on
 * hand-made conforming sector sets: the 12 base sectors of a cube, uniform
 * and adaptive longest-edge bisections of them (forced splits).
 *
 * Built alone with mesh.c (tests/test_mesh_core.py compiles and runs it):
 * the emitter samples an analytic height field through its surface source,
 * so the test does not depend on other stages.
 */
#include <assert.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "plod.h"

/* ---- the surface: analytic heights ---------------------------------------------- */
static int g_height_kind = 1; /* 0: linear in x, 1: bumpy */

static double analytic_height(const plod_planet *planet, const double dir[3])
{
    if (g_height_kind == 0)
        return planet->height_scale * dir[0];
    return planet->height_scale *
           (sin(7.0 * dir[0]) * cos(5.0 * dir[1]) + 0.5 * sin(11.0 * dir[2] + dir[0]));
}

/* Normal by central differences of the analytic field (the core samples a
 * normal map; here only the mesh stage's use of it is under test). */
static double analytic_surface(const plod_planet *planet, const double dir[3], double normal[3])
{
    if (!planet->heightmap) {
        if (normal)
            memcpy(normal, dir, 3 * sizeof(double));
        return 0.0;
    }
    double height = analytic_height(planet, dir);
    if (!normal)
        return height;
    double axis[3] = {fabs(dir[0]) <= fabs(dir[1]) && fabs(dir[0]) <= fabs(dir[2]),
                      fabs(dir[0]) > fabs(dir[1]) && fabs(dir[1]) <= fabs(dir[2]), 0.0};
    if (axis[0] == 0.0 && axis[1] == 0.0)
        axis[2] = 1.0;
    double t1[3] = {axis[1] * dir[2] - axis[2] * dir[1], axis[2] * dir[0] - axis[0] * dir[2],
                    axis[0] * dir[1] - axis[1] * dir[0]};
    double l1 = sqrt(t1[0] * t1[0] + t1[1] * t1[1] + t1[2] * t1[2]);
    for (int c = 0; c < 3; c++)
        t1[c] /= l1;
    double t2[3] = {dir[1] * t1[2] - dir[2] * t1[1], dir[2] * t1[0] - dir[0] * t1[2],
                    dir[0] * t1[1] - dir[1] * t1[0]};
    const double step = 1e-5;
    double slope[2];
    const double *frame[2] = {t1, t2};
    for (int f = 0; f < 2; f++) {
        double h[2];
        for (int s = 0; s < 2; s++) {
            double p[3];
            for (int c = 0; c < 3; c++)
                p[c] = dir[c] + (s ? -step : step) * frame[f][c];
            double l = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
            for (int c = 0; c < 3; c++)
                p[c] /= l;
            h[s] = analytic_height(planet, p);
        }
        slope[f] = (h[0] - h[1]) / (2.0 * atan(step));
    }
    double r = planet->radius + height, len = 0.0;
    for (int c = 0; c < 3; c++) {
        normal[c] = r * dir[c] - slope[0] * t1[c] - slope[1] * t2[c];
        len += normal[c] * normal[c];
    }
    for (int c = 0; c < 3; c++)
        normal[c] /= sqrt(len);
    return height;
}

/* No detail field: every point keeps everything (octaves ignored). */
static void analytic_sample_n(const void *self, size_t n, const double *dirs,
                              const int *octaves, const int *normal_octaves, double *heights,
                              double *normals, double *detail)
{
    (void)octaves, (void)normal_octaves;
    for (size_t i = 0; i < n; i++) {
        heights[i] = analytic_surface(self, dirs + 3 * i, normals ? normals + 3 * i : NULL);
        if (detail)
            detail[i] = 0.0;
    }
}

static const plod_surface_ops analytic_ops = {analytic_sample_n, NULL, NULL};

/* The analytic field of `planet` (its radius, height_scale, and a non-NULL
 * heightmap token for relief). */
static plod_surface_source analytic_source(const plod_planet *planet)
{
    plod_surface_source source = {&analytic_ops, planet};
    return source;
}

static int g_failures = 0;
#define CHECK(cond, ...)                                                     \
    do {                                                                     \
        if (!(cond)) {                                                       \
            g_failures++;                                                    \
            fprintf(stderr, "FAIL %s:%d: ", __FILE__, __LINE__);             \
            fprintf(stderr, __VA_ARGS__);                                    \
            fprintf(stderr, "\n");                                           \
        }                                                                    \
    } while (0)

/* ---- sector sets -------------------------------------------------------------- */
typedef struct sector_set {
    plod_mesh_sector *s;
    size_t count, capacity;
} sector_set;

static void set_push(sector_set *set, const double a[3], const double b[3],
                     const double c[3], int level, int face)
{
    if (set->count == set->capacity) {
        set->capacity = set->capacity ? 2 * set->capacity : 64;
        set->s = realloc(set->s, set->capacity * sizeof *set->s);
        assert(set->s);
    }
    plod_mesh_sector *s = &set->s[set->count++];
    memcpy(s->corners[0], a, sizeof(double[3]));
    memcpy(s->corners[1], b, sizeof(double[3]));
    memcpy(s->corners[2], c, sizeof(double[3]));
    s->level = level;
    s->face = face;
    s->key = 0;
    s->split = NULL; /* no split morph: the distance geomorph */
}

static void normalise(double v[3])
{
    double l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    v[0] /= l; v[1] /= l; v[2] /= l;
}

/* 12 base sectors: per face two triangles on the diagonal p0-p2, corner 1
 * the apex, CCW seen from outside. */
static void cube_sectors(sector_set *set)
{
    set->count = 0;
    for (int face = 0; face < 6; face++) {
        int axis = face % 3;
        double sign = face < 3 ? 1.0 : -1.0;
        double n[3] = {0, 0, 0}, u[3] = {0, 0, 0}, v[3];
        n[axis] = sign;
        u[(axis + 1) % 3] = 1.0;
        v[0] = n[1] * u[2] - n[2] * u[1];
        v[1] = n[2] * u[0] - n[0] * u[2];
        v[2] = n[0] * u[1] - n[1] * u[0];
        static const double su[4] = {-1, 1, 1, -1}, sv[4] = {-1, -1, 1, 1};
        double p[4][3];
        for (int q = 0; q < 4; q++) {
            for (int c = 0; c < 3; c++)
                p[q][c] = n[c] + su[q] * u[c] + sv[q] * v[c];
            normalise(p[q]);
        }
        set_push(set, p[0], p[1], p[2], 0, face);
        set_push(set, p[2], p[3], p[0], 0, face);
    }
}

static int same(const double a[3], const double b[3])
{
    return memcmp(a, b, sizeof(double[3])) == 0;
}

/* Bisection of sector `index` at the midpoint of its edge 0-2; the children
 * keep the CCW order with the new right angle at corner 1. */
static void bisect(sector_set *set, size_t index)
{
    plod_mesh_sector t = set->s[index];
    double m[3];
    for (int c = 0; c < 3; c++)
        m[c] = t.corners[0][c] + t.corners[2][c];
    normalise(m);
    plod_mesh_sector *slot = &set->s[index];
    memcpy(slot->corners[0], t.corners[1], sizeof m);
    memcpy(slot->corners[1], m, sizeof m);
    memcpy(slot->corners[2], t.corners[0], sizeof m);
    slot->level = t.level + 1;
    set_push(set, t.corners[2], m, t.corners[1], t.level + 1, t.face);
}

/* The sector other than `self` with an edge p-q, or (size_t)-1. */
static size_t neighbour(const sector_set *set, size_t self, const double p[3],
                        const double q[3])
{
    for (size_t i = 0; i < set->count; i++) {
        if (i == self)
            continue;
        int hp = 0, hq = 0;
        for (int c = 0; c < 3; c++) {
            hp |= same(set->s[i].corners[c], p);
            hq |= same(set->s[i].corners[c], q);
        }
        if (hp && hq)
            return i;
    }
    return (size_t)-1;
}

/* Conforming split: the neighbour across the longest edge is split first
 * until it shares that edge as its own longest edge. */
static void forced_split(sector_set *set, size_t index)
{
    for (;;) {
        const plod_mesh_sector *t = &set->s[index];
        size_t nb = neighbour(set, index, t->corners[0], t->corners[2]);
        if (nb == (size_t)-1) {
            bisect(set, index);
            return;
        }
        const plod_mesh_sector *u = &set->s[nb];
        if (same(u->corners[0], t->corners[2]) && same(u->corners[2], t->corners[0])) {
            bisect(set, index);
            bisect(set, nb);
            return;
        }
        forced_split(set, nb);
    }
}

static void uniform(sector_set *set, int levels)
{
    cube_sectors(set);
    for (int l = 0; l < levels; l++) {
        size_t count = set->count;
        for (size_t i = 0; i < count; i++)
            bisect(set, i);
    }
}

/* Refines around a point until sectors near it reach `depth`. */
static void adaptive(sector_set *set, const double focus[3], int depth)
{
    cube_sectors(set);
    for (int pass = 0; pass < depth; pass++) {
        for (size_t i = 0; i < set->count; i++) {
            const plod_mesh_sector *t = &set->s[i];
            double c[3] = {0, 0, 0};
            for (int k = 0; k < 3; k++)
                for (int x = 0; x < 3; x++)
                    c[x] += t->corners[k][x];
            normalise(c);
            double d = acos(fmin(1.0, c[0] * focus[0] + c[1] * focus[1] + c[2] * focus[2]));
            double size = 1.2 * pow(0.5, t->level / 2.0);
            if (t->level < depth && d < 2.0 * size) {
                forced_split(set, i);
                i = (size_t)-1; /* restart: indices moved */
                if (set->count > 4000)
                    return;
            }
        }
    }
}

/* ---- welding and edge checks ------------------------------------------------ */
typedef struct keyed {
    float p[3];
    size_t index;
} keyed;

static int cmp_keyed(const void *a, const void *b)
{
    const keyed *x = a, *y = b;
    int c = memcmp(x->p, y->p, sizeof x->p);
    if (c)
        return c;
    return x->index < y->index ? -1 : x->index > y->index;
}

static size_t weld(const float *positions, size_t vertex_count, size_t *remap)
{
    keyed *k = malloc(vertex_count * sizeof *k);
    assert(k);
    for (size_t v = 0; v < vertex_count; v++) {
        memcpy(k[v].p, positions + 3 * v, sizeof k[v].p);
        for (int c = 0; c < 3; c++)
            if (k[v].p[c] == 0.0f)
                k[v].p[c] = 0.0f; /* -0 and +0 weld */
        k[v].index = v;
    }
    qsort(k, vertex_count, sizeof *k, cmp_keyed);
    size_t unique = 0;
    for (size_t v = 0; v < vertex_count; v++) {
        if (v > 0 && memcmp(k[v].p, k[v - 1].p, sizeof k[v].p) != 0)
            unique++;
        remap[k[v].index] = unique;
    }
    free(k);
    return vertex_count ? unique + 1 : 0;
}

typedef struct edge {
    size_t a, b;
} edge;

static int cmp_edge(const void *x, const void *y)
{
    const edge *e = x, *f = y;
    if (e->a != f->a)
        return e->a < f->a ? -1 : 1;
    return e->b < f->b ? -1 : e->b > f->b;
}

/* Counts edges used by one triangle (boundary), by more than two or twice in
 * the same direction (non-manifold / flipped), degenerate triangles; checks
 * Euler's V - E + F = 2. */
static void check_closed(const char *what, const float *positions, size_t vertex_count,
                         const int32_t *triangles, size_t triangle_count)
{
    size_t *remap = malloc(vertex_count * sizeof *remap);
    edge *edges = malloc(3 * triangle_count * sizeof *edges);
    assert(remap && edges);
    size_t welded = weld(positions, vertex_count, remap);
    size_t degenerate = 0;
    for (size_t t = 0; t < triangle_count; t++)
        for (int e = 0; e < 3; e++) {
            size_t a = remap[triangles[3 * t + e]], b = remap[triangles[3 * t + (e + 1) % 3]];
            degenerate += a == b;
            edges[3 * t + e].a = a;
            edges[3 * t + e].b = b;
        }
    qsort(edges, 3 * triangle_count, sizeof *edges, cmp_edge);
    size_t undirected = 0, bad = 0;
    for (size_t i = 0; i < 3 * triangle_count; i++) {
        if (i > 0 && cmp_edge(&edges[i], &edges[i - 1]) == 0) {
            bad++; /* same directed edge twice */
            continue;
        }
        edge rev = {edges[i].b, edges[i].a};
        if (!bsearch(&rev, edges, 3 * triangle_count, sizeof *edges, cmp_edge))
            bad++; /* boundary */
        if (edges[i].a < edges[i].b)
            undirected++;
    }
    long euler = (long)welded - (long)undirected + (long)triangle_count;
    CHECK(bad == 0 && degenerate == 0 && euler == 2,
          "%s: %zu bad edges, %zu degenerate, V-E+F = %ld (V %zu of %zu)", what, bad,
          degenerate, euler, welded, vertex_count);
    free(remap);
    free(edges);
}

/* ---- emission helpers ------------------------------------------------------------ */
typedef struct mesh {
    float *positions, *normals, *uv, *morph;
    int32_t *triangles, *level, *face;
    size_t vertices, triangles_count;
} mesh;

static plod_status emit(const plod_mesh_params *params, const sector_set *set, mesh *m)
{
    size_t vb = plod_mesh_vertex_bound(set->count, params->template_level);
    size_t tb = plod_mesh_triangle_bound(set->count, params->template_level);
    memset(m, 0, sizeof *m);
    m->positions = malloc(3 * vb * sizeof(float));
    m->normals = malloc(3 * vb * sizeof(float));
    m->uv = malloc(2 * vb * sizeof(float));
    m->morph = malloc(vb * sizeof(float));
    m->triangles = malloc(3 * tb * sizeof(int32_t));
    m->level = malloc(tb * sizeof(int32_t));
    m->face = malloc(tb * sizeof(int32_t));
    assert(m->positions && m->normals && m->uv && m->morph && m->triangles && m->level && m->face);
    plod_mesh_buffers out = {m->positions, m->normals, m->uv, m->morph,
                             m->triangles, m->level, m->face};
    plod_surface_source surface = analytic_source(params->planet);
    return plod_mesh_emit_array(params, set->s, set->count, &surface, &out, &m->vertices,
                                &m->triangles_count);
}

static void mesh_free(mesh *m)
{
    free(m->positions); free(m->normals); free(m->uv); free(m->morph);
    free(m->triangles); free(m->level); free(m->face);
}

static int mesh_equal(const mesh *a, const mesh *b)
{
    return a->vertices == b->vertices && a->triangles_count == b->triangles_count &&
           !memcmp(a->positions, b->positions, 12 * a->vertices) &&
           !memcmp(a->normals, b->normals, 12 * a->vertices) &&
           !memcmp(a->uv, b->uv, 8 * a->vertices) &&
           !memcmp(a->morph, b->morph, 4 * a->vertices) &&
           !memcmp(a->triangles, b->triangles, 12 * a->triangles_count) &&
           !memcmp(a->level, b->level, 4 * a->triangles_count) &&
           !memcmp(a->face, b->face, 4 * a->triangles_count);
}

/* Welded vertices must carry bit-identical normals (shared edge rule). */
static void check_shared_normals(const char *what, const mesh *m)
{
    size_t *remap = malloc(m->vertices * sizeof *remap);
    assert(remap);
    size_t welded = weld(m->positions, m->vertices, remap);
    size_t *first = malloc(welded * sizeof *first);
    assert(first);
    for (size_t w = 0; w < welded; w++)
        first[w] = (size_t)-1;
    size_t mismatch = 0;
    for (size_t v = 0; v < m->vertices; v++) {
        size_t w = remap[v];
        if (first[w] == (size_t)-1)
            first[w] = v;
        else
            mismatch += memcmp(m->normals + 3 * v, m->normals + 3 * first[w], 12) != 0;
    }
    CHECK(mismatch == 0, "%s: %zu shared vertices with different normals", what, mismatch);
    free(first);
    free(remap);
}

/* ---- tests ---------------------------------------------------------------------- */
static plod_planet test_planet(double radius, double height_scale, int with_map)
{
    plod_planet p;
    memset(&p, 0, sizeof p);
    p.radius = radius;
    p.projection = PLOD_PROJ_QSC;
    p.heightmap = with_map ? (const plod_cubemap *)&p : NULL; /* non-NULL token */
    p.height_scale = height_scale;
    return p;
}

static void test_templates(void)
{
    for (int level = 0; level <= PLOD_MAX_TEMPLATE_LEVEL; level++) {
        size_t n = (size_t)1 << level;
        size_t vc = plod_template_vertex_count(level), tc = plod_template_triangle_count(level);
        CHECK(tc == n * n && vc == (n + 1) * (n + 2) / 2, "template %d counts", level);
        float *bary = malloc(3 * vc * sizeof(float));
        int32_t *tri = malloc(3 * tc * sizeof(int32_t));
        CHECK(plod_template_barycentrics(bary, level) == PLOD_OK, "bary");
        CHECK(plod_template_triangles(tri, level) == PLOD_OK, "tri");
        for (size_t v = 0; v < vc; v++)
            CHECK(bary[3 * v] + bary[3 * v + 1] + bary[3 * v + 2] == 1.0f, "weights sum");
        double area = 0.0;
        int in_range = 1;
        for (size_t t = 0; t < tc; t++) {
            const float *a = bary + 3 * tri[3 * t], *b = bary + 3 * tri[3 * t + 1],
                        *c = bary + 3 * tri[3 * t + 2];
            for (int e = 0; e < 3; e++)
                in_range &= tri[3 * t + e] >= 0 && (size_t)tri[3 * t + e] < vc;
            /* signed area in the (w1, w2) plane: CCW => positive */
            double s = (b[1] - a[1]) * (c[2] - a[2]) - (b[2] - a[2]) * (c[1] - a[1]);
            CHECK(s > 0, "template %d triangle %zu not CCW", level, t);
            area += 0.5 * s;
        }
        CHECK(in_range, "indices in range");
        CHECK(fabs(area - 0.5) < 1e-9, "template %d area %g", level, area);
        free(bary);
        free(tri);
    }
    CHECK(plod_template_vertex_count(8) == 0 && plod_template_vertex_count(-1) == 0, "bad level");
    float dummy[3];
    CHECK(plod_template_barycentrics(dummy, 8) == PLOD_ERR_BAD_PARAM, "bad level status");
}

static void test_watertight(void)
{
    plod_planet planet = test_planet(6371000.0, 8000.0, 1);
    sector_set set = {0};
    char what[128];
    for (int bis = 0; bis <= 4; bis++) {
        uniform(&set, bis);
        for (int tl = 0; tl <= 4; tl++) {
            plod_mesh_params params;
            plod_mesh_params_init(&params, &planet, tl);
            params.threads = 2;
            mesh m;
            CHECK(emit(&params, &set, &m) == PLOD_OK, "emit");
            snprintf(what, sizeof what, "uniform %d template %d", bis, tl);
            check_closed(what, m.positions, m.vertices, m.triangles, m.triangles_count);
            if (tl == 3)
                check_shared_normals(what, &m);
            mesh_free(&m);
        }
    }
    double focus[3] = {0.3, -0.5, 0.8};
    normalise(focus);
    adaptive(&set, focus, 10);
    int lo = 99, hi = 0;
    for (size_t i = 0; i < set.count; i++) {
        lo = set.s[i].level < lo ? set.s[i].level : lo;
        hi = set.s[i].level > hi ? set.s[i].level : hi;
    }
    CHECK(hi - lo >= 5, "adaptive set spans levels %d..%d", lo, hi);
    for (int tl = 0; tl <= 4; tl++) {
        plod_mesh_params params;
        plod_mesh_params_init(&params, &planet, tl);
        params.threads = 2;
        params.origin[0] = focus[0] * planet.radius;
        params.origin[1] = focus[1] * planet.radius;
        params.origin[2] = focus[2] * planet.radius;
        mesh m;
        CHECK(emit(&params, &set, &m) == PLOD_OK, "emit");
        snprintf(what, sizeof what, "adaptive (%zu sectors) template %d", set.count, tl);
        check_closed(what, m.positions, m.vertices, m.triangles, m.triangles_count);
        check_shared_normals(what, &m);
        /* and with geomorphing on, camera just above the focus */
        params.morph = 1;
        for (int c = 0; c < 3; c++)
            params.eye[c] = focus[c] * (planet.radius + 20000.0);
        params.morph_lod_scale = 1.5e6;
        mesh mm;
        CHECK(emit(&params, &set, &mm) == PLOD_OK, "emit morph");
        snprintf(what, sizeof what, "adaptive morphed template %d", tl);
        check_closed(what, mm.positions, mm.vertices, mm.triangles, mm.triangles_count);
        /* morph: even vertices unmoved, odd ones at p + m (mid - p) */
        size_t n = (size_t)1 << tl, moved = 0, wrong = 0;
        size_t per = plod_template_vertex_count(tl);
        for (size_t s = 0; s < set.count && tl > 0; s++) {
            size_t base = s * per, v = 0;
            for (size_t i = 0; i <= n; i++)
                for (size_t j = 0; j <= n - i; j++, v++) {
                    size_t k0 = n - i - j, g = base + v;
                    float mf = mm.morph[g];
                    if (!(i & 1) && !(j & 1) && !(k0 & 1)) {
                        wrong += mf != 0.0f || memcmp(m.positions + 3 * g, mm.positions + 3 * g, 12);
                        continue;
                    }
                    wrong += !(mf >= 0.0f && mf <= 1.0f);
                    size_t a, b;
                    #define IDX(ii, jj) (base + (ii) * (n + 1) - (ii) * ((ii) - 1) / 2 + (jj))
                    if (!(i & 1)) { a = IDX(i, j - 1); b = IDX(i, j + 1); }
                    else if (!(j & 1)) { a = IDX(i - 1, j); b = IDX(i + 1, j); }
                    else { a = IDX(i - 1, j + 1); b = IDX(i + 1, j - 1); }
                    #undef IDX
                    for (int c = 0; c < 3; c++) {
                        double p = m.positions[3 * g + c];
                        double mid = 0.5 * ((double)m.positions[3 * a + c] + m.positions[3 * b + c]);
                        double expect = p + mf * (mid - p);
                        double tol = 1e-6 * (fabs(p) + fabs(mid)) + 1e-3;
                        wrong += fabs(mm.positions[3 * g + c] - expect) > tol;
                    }
                    moved += mf > 0.0f;
                }
        }
        CHECK(wrong == 0, "template %d: %zu morph mismatches", tl, wrong);
        CHECK(tl == 0 || moved > 0, "template %d: no vertex morphed", tl);
        mesh_free(&mm);
        mesh_free(&m);
    }
    free(set.s);
}

/* Template level 3, origin on the surface, morphing for an eye 5 km up. */
static void morph_params(plod_mesh_params *params, const plod_planet *planet)
{
    plod_mesh_params_init(params, planet, 3);
    params->origin[2] = planet->radius;
    params->morph = 1;
    params->eye[2] = planet->radius + 5000.0;
    params->morph_lod_scale = 4e5;
}

static void test_threads_identical(void)
{
    plod_planet planet = test_planet(1737400.0, 3000.0, 1);
    sector_set set = {0};
    uniform(&set, 5);
    plod_mesh_params params;
    morph_params(&params, &planet);
    mesh ref;
    CHECK(emit(&params, &set, &ref) == PLOD_OK, "emit 1 thread");
    for (int threads = 2; threads <= 5; threads++) {
        params.threads = threads;
        mesh m;
        CHECK(emit(&params, &set, &m) == PLOD_OK, "emit threads");
        CHECK(mesh_equal(&ref, &m), "%d threads differ from 1", threads);
        mesh_free(&m);
    }
    mesh_free(&ref);
    free(set.s);
}

/* The sector cache: output bit-identical to uncached emission whatever the
 * hits, entries = the last emission's keyed sectors, budget held, a failed
 * emission empties it, duplicate keys and unkeyed sectors handled. */
static void test_cache(void)
{
    plod_planet planet = test_planet(1737400.0, 3000.0, 1);
    sector_set set = {0};
    uniform(&set, 4);
    for (size_t i = 0; i < set.count; i++)
        set.s[i].key = 1000 + i;
    plod_mesh_cache *cache = NULL;
    CHECK(plod_mesh_cache_create(&cache, PLOD_MESH_CACHE_DEFAULT_BYTES) == PLOD_OK, "create");
    plod_mesh_params params;
    morph_params(&params, &planet);
    mesh ref;
    CHECK(emit(&params, &set, &ref) == PLOD_OK, "uncached");
    params.cache = cache;
    plod_mesh_cache_stats st;
    for (int round = 0; round < 3; round++) {
        params.threads = 1 + round;
        mesh m;
        CHECK(emit(&params, &set, &m) == PLOD_OK, "cached round %d", round);
        CHECK(mesh_equal(&ref, &m), "cached round %d differs from uncached", round);
        plod_mesh_cache_get_stats(cache, &st);
        CHECK(st.sectors == set.count, "entries %zu of %zu", st.sectors, set.count);
        CHECK(st.hits == (round ? set.count : 0) && st.misses == (round ? 0 : set.count),
              "round %d: %zu hits %zu misses", round, st.hits, st.misses);
        mesh_free(&m);
    }
    size_t vertices = plod_template_vertex_count(3);
    CHECK(st.bytes == set.count * (vertices * 48 + 12), "bytes %zu", st.bytes);

    /* another origin: hits re-offset exactly */
    params.origin[0] = 12345.678;
    params.cache = NULL;
    mesh ref2, m2;
    CHECK(emit(&params, &set, &ref2) == PLOD_OK, "uncached, moved origin");
    params.cache = cache;
    CHECK(emit(&params, &set, &m2) == PLOD_OK && mesh_equal(&ref2, &m2), "moved origin");
    mesh_free(&ref2);
    mesh_free(&m2);

    /* half the sectors: the other half is evicted; unkeyed ones never cached */
    sector_set half = {set.s, set.count / 2, set.count / 2};
    half.s[0].key = 0;
    mesh m3;
    CHECK(emit(&params, &half, &m3) == PLOD_OK, "half");
    plod_mesh_cache_get_stats(cache, &st);
    CHECK(st.sectors == half.count - 1 && st.hits == half.count - 1 && st.misses == 0,
          "half: %zu entries, %zu hits, %zu misses", st.sectors, st.hits, st.misses);
    mesh_free(&m3);
    half.s[0].key = 1000;

    /* template level change empties it */
    params.template_level = 2;
    mesh m4;
    CHECK(emit(&params, &set, &m4) == PLOD_OK, "level 2");
    plod_mesh_cache_get_stats(cache, &st);
    CHECK(st.hits == 0 && st.misses == set.count, "level change: %zu hits", st.hits);
    mesh_free(&m4);

    /* budget: room for 10 sectors (split over 2 threads: 5 each) */
    plod_mesh_cache_clear(cache);
    plod_mesh_cache_set_max_bytes(cache, 10 * (plod_template_vertex_count(2) * 48 + 12));
    params.threads = 2;
    mesh m5;
    CHECK(emit(&params, &set, &m5) == PLOD_OK, "budget");
    plod_mesh_cache_get_stats(cache, &st);
    CHECK(st.sectors == 10 && st.bytes <= st.max_bytes, "budget: %zu entries %zu bytes",
          st.sectors, st.bytes);
    mesh_free(&m5);
    plod_mesh_cache_set_max_bytes(cache, PLOD_MESH_CACHE_DEFAULT_BYTES);

    /* duplicate keys (a caller error): no crash, no leak, first one kept */
    set.s[1].key = set.s[0].key;
    mesh m6;
    CHECK(emit(&params, &set, &m6) == PLOD_OK, "duplicate keys");
    plod_mesh_cache_get_stats(cache, &st);
    CHECK(st.sectors == set.count - 1, "duplicates: %zu entries", st.sectors);
    mesh_free(&m6);

    /* a bad sector fails the emission and empties the cache */
    set.s[set.count - 1].corners[0][0] = NAN;
    mesh m7;
    CHECK(emit(&params, &set, &m7) == PLOD_ERR_BAD_COORD, "bad sector");
    plod_mesh_cache_get_stats(cache, &st);
    CHECK(st.sectors == 0 && st.bytes == 0, "failed emission left %zu entries", st.sectors);
    mesh_free(&m7);

    plod_mesh_cache_destroy(cache);
    plod_mesh_cache_destroy(NULL);
    mesh_free(&ref);
    free(set.s);
}

static void test_normals_and_uv(void)
{
    /* h = H * x: exact normal ~ r d - H (e_x - x d) */
    g_height_kind = 0;
    plod_planet planet = test_planet(1000.0, 50.0, 1);
    sector_set set = {0};
    uniform(&set, 2);
    plod_mesh_params params;
    plod_mesh_params_init(&params, &planet, 3);
    mesh m;
    CHECK(emit(&params, &set, &m) == PLOD_OK, "emit");
    double worst = 0.0;
    for (size_t v = 0; v < m.vertices; v++) {
        double p[3] = {m.positions[3 * v], m.positions[3 * v + 1], m.positions[3 * v + 2]};
        double d[3] = {p[0], p[1], p[2]};
        normalise(d);
        double r = planet.radius + planet.height_scale * d[0];
        double n[3];
        for (int c = 0; c < 3; c++)
            n[c] = r * d[c] - planet.height_scale * ((c == 0) - d[0] * d[c]);
        normalise(n);
        double dot = n[0] * m.normals[3 * v] + n[1] * m.normals[3 * v + 1] + n[2] * m.normals[3 * v + 2];
        double len = sqrt(m.normals[3 * v] * m.normals[3 * v] + m.normals[3 * v + 1] * m.normals[3 * v + 1] +
                          m.normals[3 * v + 2] * m.normals[3 * v + 2]);
        (void)dot;
        for (int c = 0; c < 3; c++)
            worst = fmax(worst, fabs(n[c] - m.normals[3 * v + c]));
        CHECK(fabs(len - 1.0) < 1e-6, "normal not unit");
    }
    CHECK(worst < 2e-6, "normal error %g", worst);
    /* uv: in range (up to the per-sector unwrap), no triangle across the seam */
    double max_span = 0.0;
    for (size_t t = 0; t < m.triangles_count; t++) {
        float lo = 9, hi = -9;
        for (int e = 0; e < 3; e++) {
            float u = m.uv[2 * m.triangles[3 * t + e]];
            lo = u < lo ? u : lo;
            hi = u > hi ? u : hi;
        }
        max_span = fmax(max_span, hi - lo);
    }
    CHECK(max_span < 0.3, "a triangle spans %g in u (seam)", max_span);
    for (size_t v = 0; v < m.vertices; v++) {
        CHECK(m.uv[2 * v + 1] >= 0.0f && m.uv[2 * v + 1] <= 1.0f, "v out of range");
        CHECK(m.uv[2 * v] >= -0.5f && m.uv[2 * v] <= 1.5f, "u far out of range");
    }
    mesh_free(&m);
    /* no map: normals are the directions, positions on the sphere */
    planet = test_planet(1000.0, 50.0, 0);
    CHECK(emit(&params, &set, &m) == PLOD_OK, "emit sphere");
    for (size_t v = 0; v < m.vertices; v++) {
        double p[3] = {m.positions[3 * v], m.positions[3 * v + 1], m.positions[3 * v + 2]};
        double len = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
        CHECK(fabs(len - 1000.0) < 1e-3, "sphere radius %g", len);
        double dot = (p[0] * m.normals[3 * v] + p[1] * m.normals[3 * v + 1] + p[2] * m.normals[3 * v + 2]) / len;
        CHECK(dot > 1.0 - 1e-6, "sphere normal");
    }
    mesh_free(&m);
    free(set.s);
    g_height_kind = 1;
}

static void test_bad_input(void)
{
    plod_planet planet = test_planet(1000.0, 1.0, 0);
    sector_set set = {0};
    cube_sectors(&set);
    plod_surface_source surface = analytic_source(&planet);
    plod_mesh_params params;
    plod_mesh_params_init(&params, &planet, 2);
    float buf[3 * 200];
    plod_mesh_buffers out = {0};
    out.positions = buf;
    size_t vc = 1;
    params.template_level = 9;
    CHECK(plod_mesh_emit_array(&params, set.s, 1, &surface, &out, &vc, NULL) == PLOD_ERR_BAD_PARAM, "level");
    CHECK(vc == 0, "count reset on error");
    params.template_level = 2;
    params.threads = 0;
    CHECK(plod_mesh_emit_array(&params, set.s, 1, &surface, &out, &vc, NULL) == PLOD_ERR_BAD_PARAM, "threads");
    params.threads = 1;
    CHECK(plod_mesh_emit_array(NULL, set.s, 1, &surface, &out, &vc, NULL) == PLOD_ERR_NULL, "null params");
    set.s[0].corners[1][2] = NAN;
    CHECK(plod_mesh_emit_array(&params, set.s, 1, &surface, &out, &vc, NULL) == PLOD_ERR_BAD_COORD, "nan corner");
    memcpy(set.s[0].corners[1], set.s[0].corners[0], sizeof(double[3]));
    for (int c = 0; c < 3; c++)
        set.s[0].corners[1][c] = -set.s[0].corners[0][c];
    CHECK(plod_mesh_emit_array(&params, set.s, 1, &surface, &out, &vc, NULL) == PLOD_ERR_BAD_COORD, "antipodal");
    params.origin[0] = INFINITY;
    CHECK(plod_mesh_emit_array(&params, set.s + 1, 1, &surface, &out, &vc, NULL) == PLOD_ERR_BAD_COORD, "origin");
    params.origin[0] = 0;
    params.morph = 1;
    params.morph_ramp = 0.0;
    CHECK(plod_mesh_emit_array(&params, set.s + 1, 1, &surface, &out, &vc, NULL) == PLOD_ERR_BAD_PARAM, "ramp");
    CHECK(plod_mesh_vertex_bound((size_t)1 << 40, 7) == 0, "bound overflow");
    double origin[3] = {1, 2, 3}, zero[3] = {0, 0, 0};
    plod_mesh_origin(&surface, planet.radius, zero, origin);
    CHECK(origin[0] == 0 && origin[1] == 0 && origin[2] == 0, "origin at centre");
    double eye[3] = {0, 3000, 0};
    plod_mesh_origin(&surface, planet.radius, eye, origin);
    CHECK(origin[1] == 1000.0 && origin[0] == 0.0, "origin under eye");
    free(set.s);
}

int main(void)
{
    test_templates();
    test_watertight();
    test_threads_identical();
    test_cache();
    test_normals_and_uv();
    test_bad_input();
    if (g_failures) {
        fprintf(stderr, "%d failures\n", g_failures);
        return 1;
    }
    printf("mesh C tests passed\n");
    return 0;
}
