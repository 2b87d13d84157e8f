/* mesh.c -- sector templates and emission of sectors as flat buffers.
 *
 * Bit rules (see plod_mesh.h):
 *   n = 2^template_level; vertex (i, j) has integer weights
 *   k = (n-i-j, j, i) on corners (0, 1, 2) and weights k/n, exact in double.
 *   direction = normalise(sum over k_c != 0, in corner order, of (k_c/n)*C_c)
 *   A vertex on a shared edge has two non-zero terms, the same two products
 *   from either sector, and IEEE addition is commutative: identical sums.
 *   Everything after (height, normal, uv latitude, position, morph) is a
 *   function of that direction, the surface source and the parameters only.
 * Geomorph rule: n is even for level >= 1, so an odd vertex has exactly one
 *   even weight; its morph neighbours keep that weight and move the two odd
 *   ones by -+1 (both even vertices).  On a sector edge the even weight is
 *   the zero one, so the neighbours are the same two edge vertices from
 *   either side.  The morph pass reads only even vertices (never morphed), in
 *   float32 relative to the origin, so shared vertices morph identically.
 */
#include <assert.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "plod.h"


/* ---- templates ----------------------------------------------------------- */

static int plod__level_ok(int template_level)
{
    return template_level >= 0 && template_level <= PLOD_MAX_TEMPLATE_LEVEL;
}

size_t plod_template_vertex_count(int template_level)
{
    if (!plod__level_ok(template_level))
        return 0;
    size_t n = (size_t)1 << template_level;
    return (n + 1) * (n + 2) / 2;
}

size_t plod_template_triangle_count(int template_level)
{
    if (!plod__level_ok(template_level))
        return 0;
    size_t n = (size_t)1 << template_level;
    return n * n;
}

static size_t plod__vertex_index(int n, int i, int j)
{
    return (size_t)i * (size_t)(n + 1) - (size_t)i * (size_t)(i - 1) / 2 + (size_t)j;
}

plod_status plod_template_barycentrics(float *out, int template_level)
{
    if (!out)
        return PLOD_ERR_NULL;
    if (!plod__level_ok(template_level))
        return PLOD_ERR_BAD_PARAM;
    int n = 1 << template_level;
    float inv_n = 1.0f / (float)n;
    size_t v = 0;
    for (int i = 0; i <= n; i++)
        for (int j = 0; j <= n - i; j++, v++) {
            out[3 * v + 0] = (float)(n - i - j) * inv_n;
            out[3 * v + 1] = (float)j * inv_n;
            out[3 * v + 2] = (float)i * inv_n;
        }
    return PLOD_OK;
}

/* Triangles of one template copy whose first vertex has index `base`. */
static void plod__write_triangles(int32_t *out, int n, int32_t base)
{
    size_t t = 0;
    for (int i = 0; i < n; i++) {
        int32_t row = base + (int32_t)plod__vertex_index(n, i, 0);
        int32_t next = base + (int32_t)plod__vertex_index(n, i + 1, 0);
        for (int j = 0; j < n - i; j++, t++) {
            out[3 * t + 0] = row + j;
            out[3 * t + 1] = row + j + 1;
            out[3 * t + 2] = next + j;
        }
        for (int j = 0; j < n - i - 1; j++, t++) {
            out[3 * t + 0] = row + j + 1;
            out[3 * t + 1] = next + j + 1;
            out[3 * t + 2] = next + j;
        }
    }
    assert(t == (size_t)n * (size_t)n);
}

plod_status plod_template_triangles(int32_t *out, int template_level)
{
    if (!out)
        return PLOD_ERR_NULL;
    if (!plod__level_ok(template_level))
        return PLOD_ERR_BAD_PARAM;
    plod__write_triangles(out, 1 << template_level, 0);
    return PLOD_OK;
}

/* ---- parameters ------------------------------------------------------------ */

void plod_mesh_params_init(plod_mesh_params *params, const plod_planet *planet,
                           int template_level)
{
    memset(params, 0, sizeof *params);
    params->planet = planet;
    params->template_level = template_level;
    params->threads = 1;
    params->morph = 0;
    params->morph_lod_scale = planet ? planet->radius : 1.0;
    params->morph_ramp = 0.5;
    params->morph_level_rate = 2.0;
    params->detail_fade_cell = 0.0;
}

/* Height at one direction, every detail octave kept. */
static double plod__height(const plod_surface_source *surface, const double dir[3])
{
    double height;
    surface->ops->sample_n(surface->self, 1, dir, NULL, NULL, &height, NULL, NULL);
    return height;
}

void plod_mesh_origin(const plod_surface_source *surface, double radius,
                      const double eye[3], double origin[3])
{
    origin[0] = origin[1] = origin[2] = 0.0;
    if (!surface || !eye)
        return;
    double len = sqrt(eye[0] * eye[0] + eye[1] * eye[1] + eye[2] * eye[2]);
    if (!(len > 0.0) || !isfinite(len))
        return;
    double dir[3] = {eye[0] / len, eye[1] / len, eye[2] / len};
    double r = radius + plod__height(surface, dir);
    for (int c = 0; c < 3; c++)
        origin[c] = dir[c] * r;
}

/* A vertex's normal and detail (where given) moved the fraction m of the
 * way to the middle of the edge from a to b.  The shading follows the
 * geometry, so a split does not flash the normals.  Symmetric in a and b,
 * bit for bit. */
static void plod__blend_shading(float *v_nrm, float *v_det, const float *a_nrm,
                                const float *a_det, const float *b_nrm, const float *b_det,
                                double m)
{
    if (v_nrm) {
        double nv[3], len2 = 0.0;
        for (int c = 0; c < 3; c++) {
            double target = 0.5 * ((double)a_nrm[c] + (double)b_nrm[c]);
            nv[c] = (double)v_nrm[c] + m * (target - (double)v_nrm[c]);
            len2 += nv[c] * nv[c];
        }
        double len = sqrt(len2);
        if (len > 0.0)
            for (int c = 0; c < 3; c++)
                v_nrm[c] = (float)(nv[c] / len);
    }
    if (v_det) {
        double target = 0.5 * ((double)*a_det + (double)*b_det);
        *v_det = (float)((double)*v_det + m * (target - (double)*v_det));
    }
}

/* A vertex (position, and normal and detail where given) moved the
 * fraction m of the way to the middle of the edge from a to b: the coarser
 * grid's interpolation there.  Symmetric in a and b, bit for bit. */
static void plod__blend_toward(float *v_pos, float *v_nrm, float *v_det, const float *a_pos,
                               const float *a_nrm, const float *a_det, const float *b_pos,
                               const float *b_nrm, const float *b_det, double m)
{
    for (int c = 0; c < 3; c++) {
        double p = (double)v_pos[c];
        double target = 0.5 * ((double)a_pos[c] + (double)b_pos[c]);
        v_pos[c] = (float)(p + m * (target - p));
    }
    plod__blend_shading(v_nrm, v_det, a_nrm, a_det, b_nrm, b_det, m);
}

/* Vertex v of the arrays moved toward the middle of the edge from vertex a
 * to the point b (which may lie outside the arrays). */
static void plod__blend_to_edge(float *pos, float *nrm, float *det, size_t v, size_t a,
                                const float *b_pos, const float *b_nrm, const float *b_det,
                                double m)
{
    plod__blend_toward(pos + 3 * v, nrm ? nrm + 3 * v : NULL, det ? det + v : NULL,
                       pos + 3 * a, nrm ? nrm + 3 * a : NULL, det ? det + a : NULL, b_pos,
                       b_nrm, b_det, m);
}

/* The morph ramp with log2(scale) precomputed: level = rate * (log2(scale)
 * - log2(distance^2) / 2) avoids a square root per vertex. */
static double plod__morph_ramp(const double eye[3], double log2_scale, double rate,
                               double ramp, const double position[3])
{
    double dx = position[0] - eye[0];
    double dy = position[1] - eye[1];
    double dz = position[2] - eye[2];
    double distance2 = dx * dx + dy * dy + dz * dz;
    if (!(distance2 > 0.0))
        return 0.0;
    double level = rate * (log2_scale - 0.5 * log2(distance2));
    if (!isfinite(level))
        return 0.0;
    double fraction = level - floor(level);
    /* down from 1 after a whole level, and back up to 1 before the next:
     * a vertex crossing a level without its sector splitting there moves
     * on, it does not jump from full detail to the coarser grid */
    double down = (ramp - fraction) / ramp, up = (fraction - (1.0 - ramp)) / ramp;
    double m = up > down ? up : down;
    return m < 0.0 ? 0.0 : (m > 1.0 ? 1.0 : m);
}

double plod_mesh_morph_factor(const plod_mesh_params *params,
                              const double position[3])
{
    if (!params->morph || !(params->morph_lod_scale > 0.0))
        return 0.0;
    return plod__morph_ramp(params->eye, log2(params->morph_lod_scale),
                            params->morph_level_rate, params->morph_ramp, position);
}

static plod_status plod__check_params(const plod_mesh_params *params)
{
    if (!params || !params->planet)
        return PLOD_ERR_NULL;
    if (!plod__level_ok(params->template_level))
        return PLOD_ERR_BAD_PARAM;
    if (params->threads < 1 || params->threads > PLOD_MESH_MAX_THREADS)
        return PLOD_ERR_BAD_PARAM;
    if (!(params->planet->radius > 0.0) || !isfinite(params->planet->radius))
        return PLOD_ERR_BAD_PARAM;
    for (int c = 0; c < 3; c++)
        if (!isfinite(params->origin[c]) || !isfinite(params->eye[c]))
            return PLOD_ERR_BAD_COORD;
    if (params->changed_only && (params->morph || params->detail_fade_cell > 0.0))
        return PLOD_ERR_BAD_PARAM;
    if (!(params->detail_fade_cell >= 0.0) || !isfinite(params->detail_fade_cell))
        return PLOD_ERR_BAD_PARAM;
    if (params->morph) {
        if (!(params->morph_ramp > 0.0 && params->morph_ramp <= 1.0))
            return PLOD_ERR_BAD_PARAM;
        if (!(params->morph_lod_scale >= 0.0) || !isfinite(params->morph_lod_scale))
            return PLOD_ERR_BAD_PARAM;
        if (!(params->morph_level_rate > 0.0) || !isfinite(params->morph_level_rate))
            return PLOD_ERR_BAD_PARAM;
    }
    return PLOD_OK;
}

size_t plod_mesh_vertex_bound(size_t sector_count, int template_level)
{
    size_t per = plod_template_vertex_count(template_level);
    if (per == 0 || sector_count > (size_t)INT32_MAX / per)
        return 0;
    return sector_count * per;
}

size_t plod_mesh_triangle_bound(size_t sector_count, int template_level)
{
    size_t per = plod_template_triangle_count(template_level);
    if (per == 0 || plod_mesh_vertex_bound(sector_count, template_level) == 0)
        return 0;
    return sector_count * per;
}

/* ---- per-vertex geometry ---------------------------------------------------- */

/* atan2 to 1e-9 rad, 2-3x faster than libm's: the uv outputs are float32
 * (resolution 6e-8 of a turn), so libm's last bits are wasted there.
 * Octant reduction to a = lo/hi in [0, 1], then a near-minimax odd
 * polynomial of degree 19 (fitted offline; max error 9.1e-10 on [0, 1]). */
PLOD_LANE_INLINE double plod__atan2(double y, double x)
{
    double ax = fabs(x), ay = fabs(y);
    double hi = ax > ay ? ax : ay, lo = ax > ay ? ay : ax;
    double a = lo / hi, a2 = a * a; /* branch-free: hi 0 is selected away */
    double p = -0.001508915608072453;
    p = p * a2 + 0.009565248310473062;
    p = p * a2 - 0.028485991375904976;
    p = p * a2 + 0.0550220670461883;
    p = p * a2 - 0.08213304635890722;
    p = p * a2 + 0.10877797708802883;
    p = p * a2 - 0.1424716367244522;
    p = p * a2 + 0.1999642767785636;
    p = p * a2 - 0.33333179705687827;
    p = p * a2 + 0.9999999804035231;
    double r = p * a;
    r = ay > ax ? PLOD_PI / 2 - r : r;
    r = x < 0.0 ? PLOD_PI - r : r;
    r = y < 0.0 ? -r : r;
    return hi == 0.0 ? 0.0 : r;
}

/* A row of sampled vertices into the float outputs (relative to the
 * origin; uv: longitude unwrapped around lon_ref, latitude) and the
 * positions in double, branch-free so that the loop vectorises.  Outputs
 * the caller does not want are NULL (normals and detail are then not
 * read). */
typedef struct plod__row {
    double *position;             /* 3 per vertex */
    float *positions, *normals;   /* 3 per vertex */
    float *uv;                    /* 2 per vertex */
    float *detail;
} plod__row;

PLOD_LANE_CLONES PLOD_LANE_LOOPS static void plod__row_outputs(
    size_t count, const double *dirs, const double *heights, const double *normals,
    const double *detail, double radius, const double origin[3], double lon_ref,
    const plod__row *out)
{
    /* the pointers read once: with -fno-strict-aliasing a float store
     * might otherwise change them, and the loops would not vectorise */
    double *position = out->position;
    float *positions = out->positions, *normals_f = out->normals, *uv = out->uv;
    float *detail_f = out->detail;
    for (size_t j = 0; j < count; j++) {
        const double *dir = dirs + 3 * j;
        double r = radius + heights[j];
        for (int c = 0; c < 3; c++) {
            double p = dir[c] * r;
            position[3 * j + c] = p;
            positions[3 * j + c] = (float)(p - origin[c]);
        }
    }
    if (normals_f)
        for (size_t j = 0; j < 3 * count; j++)
            normals_f[j] = (float)normals[j];
    if (uv)
        for (size_t j = 0; j < count; j++) {
            const double *dir = dirs + 3 * j;
            double horizontal = sqrt(dir[0] * dir[0] + dir[1] * dir[1]);
            double lon = plod__atan2(dir[1], dir[0]);
            lon = lon - lon_ref > PLOD_PI ? lon - 2 * PLOD_PI : lon;
            lon = lon - lon_ref < -PLOD_PI ? lon + 2 * PLOD_PI : lon;
            lon = horizontal > 1e-12 ? lon : lon_ref; /* at a pole: the sector's */
            double lat = plod__atan2(dir[2], horizontal);
            uv[2 * j] = (float)(lon / (2 * PLOD_PI) + 0.5);
            uv[2 * j + 1] = (float)(lat / PLOD_PI + 0.5);
        }
    if (detail_f)
        for (size_t j = 0; j < count; j++)
            detail_f[j] = (float)detail[j];
}

/* Corners finite, roughly unit, no two (nearly) antipodal: every weighted
 * sum is then safely away from zero. */
static int plod__sector_ok(const plod_mesh_sector *sector)
{
    for (int c = 0; c < 3; c++) {
        const double *p = sector->corners[c];
        if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
            return 0;
        double len2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
        if (!(len2 > 0.25 && len2 < 4.0))
            return 0;
    }
    for (int a = 0; a < 3; a++) {
        const double *p = sector->corners[a], *q = sector->corners[(a + 1) % 3];
        double dot = p[0] * q[0] + p[1] * q[1] + p[2] * q[2];
        if (!(dot > -0.5 * sqrt((p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) *
                                (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]))))
            return 0;
    }
    return 1;
}

/* The bit rule: non-zero terms only, in corner order. */
static void plod__vertex_direction(const double corners[3][3], const int k[3],
                                   double inv_n, double dir[3])
{
    double v[3] = {0.0, 0.0, 0.0};
    int first = 1;
    for (int c = 0; c < 3; c++) {
        if (k[c] == 0)
            continue;
        double w = (double)k[c] * inv_n;
        if (first) {
            v[0] = w * corners[c][0];
            v[1] = w * corners[c][1];
            v[2] = w * corners[c][2];
            first = 0;
        } else {
            v[0] = v[0] + w * corners[c][0];
            v[1] = v[1] + w * corners[c][1];
            v[2] = v[2] + w * corners[c][2];
        }
    }
    double inv_len = 1.0 / sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    dir[0] = v[0] * inv_len;
    dir[1] = v[1] * inv_len;
    dir[2] = v[2] * inv_len;
}

/* Template row i's directions, k = (n - i - j, j, i) for j = 0..n - i:
 * its two ends one by one, between them (k0 and k1 non-zero) the bit
 * rule's sums written out, in lanes. */
PLOD_LANE_CLONES PLOD_LANE_LOOPS static void plod__row_directions(const double corners[3][3],
                                                                 int n, int i, double inv_n,
                                                                 double *dirs)
{
    int last = n - i;
    plod__vertex_direction(corners, (const int[3]){last, 0, i}, inv_n, dirs);
    if (last == 0)
        return;
    plod__vertex_direction(corners, (const int[3]){0, last, i}, inv_n, dirs + 3 * last);
    /* the corners and the third term read once (the stores could alias
     * them as far as the compiler knows) */
    double a[3], b[3], t[3], w2 = (double)i * inv_n;
    for (int c = 0; c < 3; c++) {
        a[c] = corners[0][c];
        b[c] = corners[1][c];
        t[c] = w2 * corners[2][c];
    }
#define PLOD__ROW_LOOP(THIRD)                                                                 \
    for (int j = 1; j < last; j++) {                                                          \
        double w0 = (double)(last - j) * inv_n, w1 = (double)j * inv_n, v[3];                 \
        for (int c = 0; c < 3; c++)                                                           \
            v[c] = THIRD(w0 * a[c] + w1 * b[c], t[c]);                                        \
        double inv_len = 1.0 / sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);                 \
        for (int c = 0; c < 3; c++)                                                           \
            dirs[3 * j + c] = v[c] * inv_len;                                                 \
    }
#define PLOD__PLUS(sum, term) ((sum) + (term))
#define PLOD__ALONE(sum, term) (sum)
    if (i != 0)
        PLOD__ROW_LOOP(PLOD__PLUS)
    else
        PLOD__ROW_LOOP(PLOD__ALONE)
#undef PLOD__ALONE
#undef PLOD__PLUS
#undef PLOD__ROW_LOOP
}

/* ---- one sector ---------------------------------------------------------------- */

typedef struct plod__emitter {
    const plod_mesh_params *params;
    const plod_surface_source *surface;
    int banded; /* the surface limits detail per point (octaves_for_cell) */
    /* detail fade (params->detail_fade_cell > 0 on a banded surface):
     * log2 of the largest cell that keeps octave i, i < fade_octaves */
    int fade_octaves;
    double fade_log2_cell[PLOD_DETAIL_MAX_OCTAVES];
    double fade_ground_radius; /* metres from the centre to the ground below the eye */
    const plod_mesh_buffers *out;
    int n;
    size_t vertices_per_sector, triangles_per_sector;
} plod__emitter;

/* The fade's octave thresholds: for each octave the log2 cell where
 * octaves_for_cell stops keeping it (bisection over 2^-40..2^60 m: the
 * surface's answer is monotone in the cell). */
static void plod__fade_init(plod__emitter *e)
{
    const plod_surface_source *s = e->surface;
    int count = s->ops->octaves_for_cell(s->self, ldexp(1.0, -40));
    if (count > PLOD_DETAIL_MAX_OCTAVES)
        count = PLOD_DETAIL_MAX_OCTAVES;
    for (int i = 0; i < count; i++) {
        double lo = -40.0, hi = 60.0; /* keeps octave i at 2^lo, not at 2^hi */
        if (s->ops->octaves_for_cell(s->self, ldexp(1.0, 60)) > i) {
            e->fade_log2_cell[i] = 60.0;
            continue;
        }
        for (int it = 0; it < 60; it++) {
            double mid = 0.5 * (lo + hi);
            if (s->ops->octaves_for_cell(s->self, exp2(mid)) > i)
                lo = mid;
            else
                hi = mid;
        }
        e->fade_log2_cell[i] = lo;
    }
    e->fade_octaves = count;
    double ground[3];
    plod_mesh_origin(s, e->params->planet->radius, e->params->eye, ground);
    double r = sqrt(ground[0] * ground[0] + ground[1] * ground[1] + ground[2] * ground[2]);
    e->fade_ground_radius = r > 0.0 && isfinite(r) ? r : e->params->planet->radius;
}

/* The fade's band of the point at `radius` metres along the unit direction
 * `dir`: *whole octaves and the weight of the next (0 <= *fraction < 1). */
static void plod__fade_band(const plod__emitter *e, const double dir[3], double radius,
                            double log2_fade_cell, int *whole, double *fraction)
{
    const plod_mesh_params *params = e->params;
    double d2 = 0.0;
    for (int c = 0; c < 3; c++) {
        double x = dir[c] * radius - params->eye[c];
        d2 += x * x;
    }
    double log2_cell = 0.5 * log2(d2) + log2_fade_cell;
    double sum = 0.0;
    if (!isfinite(log2_cell)) /* at the eye: every octave */
        sum = (double)e->fade_octaves;
    else
        for (int i = 0; i < e->fade_octaves; i++) {
            double w = e->fade_log2_cell[i] - log2_cell + 0.5;
            sum += w <= 0.0 ? 0.0 : (w >= 1.0 ? 1.0 : w);
        }
    double f = floor(sum);
    *whole = (int)f;
    *fraction = sum - f;
    if (*whole >= e->fade_octaves) {
        *whole = e->fade_octaves;
        *fraction = 0.0;
    }
}

static void plod__emitter_init(plod__emitter *e, const plod_mesh_params *params,
                               const plod_surface_source *surface,
                               const plod_mesh_buffers *out)
{
    e->params = params;
    e->surface = surface;
    e->banded = surface->ops->octaves_for_cell != NULL;
    e->fade_octaves = 0;
    e->fade_ground_radius = params->planet->radius;
    if (e->banded && params->detail_fade_cell > 0.0)
        plod__fade_init(e);
    e->out = out;
    e->n = 1 << params->template_level;
    e->vertices_per_sector = plod_template_vertex_count(params->template_level);
    e->triangles_per_sector = plod_template_triangle_count(params->template_level);
}

static void plod__morph_sector(const plod__emitter *e, size_t vbase)
{
    const plod_mesh_params *params = e->params;
    float *pos = e->out->positions + 3 * vbase;
    float *morph_out = e->out->morph ? e->out->morph + vbase : NULL;
    float *nrm = e->out->normals ? e->out->normals + 3 * vbase : NULL;
    float *det = e->out->detail ? e->out->detail + vbase : NULL;
    int n = e->n;
    if (!(params->morph_lod_scale > 0.0))
        return; /* factor 0 everywhere: nothing moves, morph already 0 */
    double log2_scale = log2(params->morph_lod_scale);
    size_t v = 0;
    for (int i = 0; i <= n; i++)
        for (int j = 0; j <= n - i; j++, v++) {
            int k0 = n - i - j;
            if (!(i & 1) && !(j & 1) && !(k0 & 1))
                continue; /* even vertex: on the coarser grid */
            size_t a, b;
            if (!(i & 1)) {        /* k2 even: move along the row */
                a = plod__vertex_index(n, i, j - 1);
                b = plod__vertex_index(n, i, j + 1);
            } else if (!(j & 1)) { /* k1 even */
                a = plod__vertex_index(n, i - 1, j);
                b = plod__vertex_index(n, i + 1, j);
            } else {               /* k0 even */
                a = plod__vertex_index(n, i - 1, j + 1);
                b = plod__vertex_index(n, i + 1, j - 1);
            }
            double p[3], world[3];
            for (int c = 0; c < 3; c++) {
                p[c] = (double)pos[3 * v + c];
                world[c] = p[c] + params->origin[c];
            }
            double m = plod__morph_ramp(params->eye, log2_scale, params->morph_level_rate,
                                        params->morph_ramp, world);
            if (morph_out)
                morph_out[v] = (float)m;
            if (m == 0.0)
                continue;
            plod__blend_to_edge(pos, nrm, det, v, a, pos + 3 * b, nrm ? nrm + 3 * b : NULL,
                                det ? det + b : NULL, m);
        }
}

/* ---- sector cache -------------------------------------------------------------- */

typedef struct plod__cache_entry {
    uint64_t key;
    unsigned char *data; /* plod__block layout, vertices_per_sector vertices */
} plod__cache_entry;

struct plod_mesh_cache {
    size_t max_bytes, bytes;
    /* what the entries were computed for */
    const plod_planet *planet;
    double radius, height_scale, height_offset;
    const void *heightmap, *normalmap, *source, *insets;
    const void *detail;
    const void *surface_ops, *surface_self;
    uint64_t surface_stamp;
    int template_level;
    size_t entry_bytes;
    plod__cache_entry *entries;
    size_t count, capacity;
    int32_t *table; /* open addressing over entries: index or -1 */
    size_t table_size; /* power of two, >= 2 * count, or 0 */
    size_t hits, misses;
    uint64_t emissions; /* emissions through the cache, never reset */
};

/* Per vertex: planet-space position (3 doubles), normal (3 floats), uv (2),
 * detail (1); per sector: the detail octaves each corner's normal was
 * computed with (-1 without detail; they depend on the origin). */
typedef struct plod__block {
    double *position;
    float *normal;
    float *uv;
    float *detail;
    int32_t *corner_band;
} plod__block;

#define PLOD__VERTEX_CACHE_BYTES (3 * sizeof(double) + 6 * sizeof(float))
#define PLOD__SECTOR_CACHE_BYTES (3 * sizeof(int32_t))

static void plod__block_view(unsigned char *data, size_t vertices, plod__block *b)
{
    b->position = (double *)data;
    b->normal = (float *)(data + 3 * sizeof(double) * vertices);
    b->uv = b->normal + 3 * vertices;
    b->detail = b->uv + 2 * vertices;
    b->corner_band = (int32_t *)(b->detail + vertices);
}

static size_t plod__key_hash(uint64_t key)
{
    key ^= key >> 33;
    key *= 0xff51afd7ed558ccdULL;
    key ^= key >> 33;
    return (size_t)key;
}

static int32_t plod__cache_find(const plod_mesh_cache *c, uint64_t key)
{
    if (!c->table_size || !key)
        return -1;
    size_t mask = c->table_size - 1;
    for (size_t h = plod__key_hash(key) & mask;; h = (h + 1) & mask) {
        int32_t e = c->table[h];
        if (e < 0 || c->entries[e].key == key)
            return e;
    }
}

/* Rebuilds the table over entries[0, count), sized for `expected` entries;
 * on allocation failure the cache is emptied (never wrong, only colder). */
static int plod__cache_rehash(plod_mesh_cache *c, size_t expected)
{
    size_t size = 16;
    while (size < 2 * expected)
        size *= 2;
    if (size != c->table_size) {
        int32_t *t = realloc(c->table, size * sizeof *t);
        if (!t)
            return 0;
        c->table = t;
        c->table_size = size;
    }
    memset(c->table, 0xff, c->table_size * sizeof *c->table);
    size_t mask = c->table_size - 1;
    for (size_t i = 0; i < c->count; i++) {
        size_t h = plod__key_hash(c->entries[i].key) & mask;
        while (c->table[h] >= 0)
            h = (h + 1) & mask;
        c->table[h] = (int32_t)i;
    }
    return 1;
}

plod_status plod_mesh_cache_create(plod_mesh_cache **out, size_t max_bytes)
{
    if (!out)
        return PLOD_ERR_NULL;
    *out = calloc(1, sizeof **out);
    if (!*out)
        return PLOD_ERR_NO_MEMORY;
    (*out)->max_bytes = max_bytes;
    (*out)->template_level = -1;
    return PLOD_OK;
}

void plod_mesh_cache_clear(plod_mesh_cache *cache)
{
    if (!cache)
        return;
    for (size_t i = 0; i < cache->count; i++)
        free(cache->entries[i].data);
    free(cache->entries);
    free(cache->table);
    cache->entries = NULL;
    cache->table = NULL;
    cache->count = cache->capacity = cache->table_size = 0;
    cache->bytes = 0;
    cache->planet = NULL;
    cache->template_level = -1;
}

void plod_mesh_cache_destroy(plod_mesh_cache *cache)
{
    plod_mesh_cache_clear(cache);
    free(cache);
}

void plod_mesh_cache_set_max_bytes(plod_mesh_cache *cache, size_t max_bytes)
{
    if (!cache)
        return;
    cache->max_bytes = max_bytes;
    if (cache->bytes > max_bytes)
        plod_mesh_cache_clear(cache);
}

void plod_mesh_cache_get_stats(const plod_mesh_cache *cache, plod_mesh_cache_stats *stats)
{
    memset(stats, 0, sizeof *stats);
    if (!cache)
        return;
    stats->sectors = cache->count;
    stats->bytes = cache->bytes;
    stats->max_bytes = cache->max_bytes;
    stats->hits = cache->hits;
    stats->misses = cache->misses;
    stats->emissions = cache->emissions;
}

/* Empties the cache unless its entries were computed for these parameters. */
static void plod__cache_bind(plod_mesh_cache *c, const plod_mesh_params *params,
                             const plod_surface_source *surface, size_t vertices_per_sector)
{
    const plod_planet *p = params->planet;
    uint64_t stamp = surface->ops->stamp ? surface->ops->stamp(surface->self) : 0;
    if (c->planet != p || c->template_level != params->template_level ||
        c->radius != p->radius || c->height_scale != p->height_scale ||
        c->height_offset != p->height_offset ||
        c->heightmap != (const void *)p->heightmap || c->normalmap != (const void *)p->normalmap ||
        c->source != (const void *)p->source || c->insets != (const void *)p->insets ||
        c->detail != (const void *)p->detail ||
        c->surface_ops != (const void *)surface->ops || c->surface_self != surface->self ||
        c->surface_stamp != stamp)
        plod_mesh_cache_clear(c);
    c->planet = p;
    c->radius = p->radius;
    c->height_scale = p->height_scale;
    c->height_offset = p->height_offset;
    c->heightmap = p->heightmap;
    c->source = p->source;
    c->insets = p->insets;
    c->normalmap = p->normalmap;
    c->detail = p->detail;
    c->surface_ops = surface->ops;
    c->surface_self = surface->self;
    c->surface_stamp = stamp;
    c->template_level = params->template_level;
    c->entry_bytes = vertices_per_sector * PLOD__VERTEX_CACHE_BYTES + PLOD__SECTOR_CACHE_BYTES;
}

/* ---- one sector ---------------------------------------------------------------- */

/* Where a sector's vertex data comes from and goes to, per output slot. */
typedef struct plod__slot_cache {
    int32_t hit;          /* entry to copy from, or -1 */
    unsigned char *fresh; /* new entry data to fill (a miss that fits), or NULL */
    uint64_t key;
    int corners_changed;  /* a hit whose corner normals were sampled again */
    int32_t corner_band[3]; /* ... with these bands (written back at commit) */
} plod__slot_cache;

/* Detail octaves per vertex.  A shared vertex must get the same octaves
 * from every sector holding it, so the band is a function of what the
 * vertex lies on: inside the sector, the octaves its template cells
 * resolve (cell = longest corner chord / n, as the refiner's error
 * counts); on an edge, those of the edge's own cells (the chord of its two
 * corners: the same bits from both sides); at a corner, shared by sectors
 * of several sizes, every octave for the height (the refiner keeps the
 * octaves a sector drops under the pixel error, so a corner stands out by
 * less than that) and, for the normal, the octaves of cells of
 * PLOD__CORNER_CELL times its distance to the eye, about a pixel there (a
 * function of the corner and the eye: the same from every sector; finer
 * octaves' slopes would speckle the shading: a corner's distance to the
 * origin, the ground below the eye, is ~0 under an orbiting camera).
 * Cached sectors get their corner normals again where the eye changed a
 * corner's band (plod__corner_normals).
 * band[0..2]: edge opposite corner k (weight k zero); band[3]: inside. */
#define PLOD__CORNER_CELL 1e-3
static double plod__chord2(const double a[3], const double b[3])
{
    double d[3] = {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
    return d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
}

static void plod__detail_bands(const plod__emitter *e, const double corners[3][3], int n,
                               int band[4])
{
    const plod_surface_source *surface = e->surface;
    double radius = e->params->planet->radius;
    double longest = 0.0;
    for (int k = 0; k < 3; k++) {
        double c2 = plod__chord2(corners[(k + 1) % 3], corners[(k + 2) % 3]);
        double cell = sqrt(c2) * radius / (double)n;
        band[k] = surface->ops->octaves_for_cell(surface->self, cell);
        longest = c2 > longest ? c2 : longest;
    }
    band[3] = surface->ops->octaves_for_cell(surface->self, sqrt(longest) * radius / (double)n);
}

static int plod__corner_band(const plod__emitter *e, const double dir[3])
{
    const plod_mesh_params *params = e->params;
    double radius = params->planet->radius;
    double d2 = 0.0;
    for (int c = 0; c < 3; c++) {
        double x = dir[c] * radius - params->eye[c];
        d2 += x * x;
    }
    return e->surface->ops->octaves_for_cell(e->surface->self, sqrt(d2) * PLOD__CORNER_CELL);
}

static int plod__vertex_band(const plod__emitter *e, const int k[3], const int band[4],
                             const double dir[3], int *normal_band)
{
    int zeros = (k[0] == 0) + (k[1] == 0) + (k[2] == 0);
    if (zeros == 2) { /* a corner */
        *normal_band = plod__corner_band(e, dir);
        return PLOD_DETAIL_MAX_OCTAVES;
    }
    int b = zeros == 1 ? band[k[0] == 0 ? 0 : (k[1] == 0 ? 1 : 2)] : band[3];
    *normal_band = b;
    return b;
}

/* Fading vertices: the band one octave up sampled too, and heights,
 * normals and detail moved toward it by each vertex's fraction (the
 * fraction 0 ones unchanged, bit for bit; only the fading ones sampled
 * again, a point's sample being a function of its direction and band). */
static void plod__fade_blend(const plod__emitter *e, size_t count, const double *dirs,
                             const int *octaves, const double *fade, double *heights,
                             double *normals, double *detail)
{
    enum { ROW = (1 << PLOD_MAX_TEMPLATE_LEVEL) + 1, GROUP = ROW + 160 };
    double up_dirs[3 * GROUP], up_heights[GROUP], up_normals[3 * GROUP], up_detail[GROUP];
    int up_octaves[GROUP];
    size_t fading[GROUP], m = 0;
    assert(count <= GROUP);
    for (size_t v = 0; v < count; v++) {
        if (!(fade[v] > 0.0))
            continue;
        memcpy(up_dirs + 3 * m, dirs + 3 * v, 3 * sizeof *dirs);
        up_octaves[m] = octaves[v] + 1;
        fading[m++] = v;
    }
    if (m == 0)
        return;
    e->surface->ops->sample_n(e->surface->self, m, up_dirs, up_octaves, up_octaves,
                              up_heights, normals ? up_normals : NULL,
                              detail ? up_detail : NULL);
    for (size_t j = 0; j < m; j++) {
        size_t v = fading[j];
        double f = fade[v];
        heights[v] += f * (up_heights[j] - heights[v]);
        if (detail)
            detail[v] += f * (up_detail[j] - detail[v]);
        if (normals) {
            double *nv = normals + 3 * v, len2 = 0.0;
            for (int c = 0; c < 3; c++) {
                nv[c] += f * (up_normals[3 * j + c] - nv[c]);
                len2 += nv[c] * nv[c];
            }
            double len = sqrt(len2);
            if (len > 0.0)
                for (int c = 0; c < 3; c++)
                    nv[c] /= len;
        }
    }
}

/* The first height of the fade's distance keeps the octaves of cells of at
 * least this fraction of the distance: the finer ones move the point by
 * about their slope times their cell, a few per cent of the distance. */
#define PLOD__FADE_FIRST_CELL (1.0 / 16.0)

/* The fade's bands of `count` unit directions (count <= the emitter's row
 * groups): the band follows each vertex's distance from the eye, and that
 * distance its height, which the band shapes.  So the height is taken
 * first from the surface faded for the distance to the point at the ground
 * radius below the eye (right near the eye, where the ground lies within a
 * few metres of that sphere while the planet's radius may be kilometres
 * away), at cells of at least PLOD__FADE_FIRST_CELL of it, then the band
 * from the distance to that height: continuous in the direction and the
 * eye, and within what the first height's missing octaves move it of the
 * true distance.  Returns whether any vertex fades. */
static int plod__fade_bands(const plod__emitter *e, size_t count, const double *dirs,
                            int *octaves, double *fade)
{
    enum { GROUP = (1 << PLOD_MAX_TEMPLATE_LEVEL) + 161 };
    double heights[GROUP];
    int any_fade = 0;
    assert(count <= GROUP);
    double log2_rate = log2(e->params->detail_fade_cell);
    double log2_first = log2_rate > log2(PLOD__FADE_FIRST_CELL) ? log2_rate
                                                                : log2(PLOD__FADE_FIRST_CELL);
    for (size_t v = 0; v < count; v++) {
        plod__fade_band(e, dirs + 3 * v, e->fade_ground_radius, log2_first, octaves + v,
                        fade + v);
        any_fade |= fade[v] > 0.0;
    }
    e->surface->ops->sample_n(e->surface->self, count, dirs, octaves, octaves, heights, NULL,
                              NULL);
    if (any_fade)
        plod__fade_blend(e, count, dirs, octaves, fade, heights, NULL, NULL);
    any_fade = 0;
    double radius = e->params->planet->radius;
    for (size_t v = 0; v < count; v++) {
        plod__fade_band(e, dirs + 3 * v, radius + heights[v], log2_rate, octaves + v, fade + v);
        any_fade |= fade[v] > 0.0;
    }
    return any_fade;
}

/* Computes the sector's vertices into the outputs and, when `block` is not
 * NULL, into it (every field). */
static void plod__compute_vertices(const plod__emitter *e, const plod_mesh_sector *sector,
                                   size_t vbase, const plod__block *block)
{
    const plod_mesh_params *params = e->params;
    const plod_planet *planet = params->planet;
    const plod_mesh_buffers *out = e->out;
    const double (*corners)[3] = (const double (*)[3])sector->corners;
    int n = e->n;
    double inv_n = 1.0 / (double)n;
    int want_normal = out->normals || block, want_uv = out->uv || block;
    int want_detail = out->detail || block;

    double lon_ref = 0.0;
    if (want_uv) {
        double cx = corners[0][0] + corners[1][0] + corners[2][0];
        double cy = corners[0][1] + corners[1][1] + corners[2][1];
        if (cx != 0.0 || cy != 0.0)
            lon_ref = plod__atan2(cy, cx);
    }

    /* rows are sampled in groups of up to GROUP vertices (a whole sector at
     * the usual template levels): the surface's batched sampling and the
     * detail field's SIMD lanes want long batches */
    enum { ROW = (1 << PLOD_MAX_TEMPLATE_LEVEL) + 1, GROUP = ROW + 160 };
    double dirs[3 * GROUP], heights[GROUP], normals[3 * GROUP], detail[GROUP];
    double position_scratch[3 * GROUP];
    float positions_scratch[3 * GROUP];
    int octaves[GROUP], normal_octaves[GROUP], band[4];
    int fading = e->banded && params->detail_fade_cell > 0.0;
    double fade[GROUP]; /* the next octave's weight per vertex when fading */
    if (e->banded && !fading)
        plod__detail_bands(e, corners, n, band);
    if (block)
        for (int c = 0; c < 3; c++)
            block->corner_band[c] = -1;
    size_t v = vbase, b = 0;
    for (int i = 0; i <= n;) {
        /* whole rows at a time: directions, then the surface's batched sampling */
        int row = 0, any_fade = 0;
        for (; i <= n && row + (n - i + 1) <= GROUP; i++) {
            plod__row_directions(corners, n, i, inv_n, dirs + 3 * row);
            for (int j = 0; j <= n - i && e->banded && !fading; j++) {
                int k[3] = {n - i - j, j, i};
                octaves[row + j] = plod__vertex_band(e, k, band, dirs + 3 * (row + j),
                                                     normal_octaves + row + j);
                if (block && (k[0] == n || k[1] == n || k[2] == n)) /* a corner */
                    block->corner_band[k[0] == n ? 0 : (k[1] == n ? 1 : 2)] =
                        normal_octaves[row + j];
            }
            row += n - i + 1;
        }
        if (fading) {
            any_fade = plod__fade_bands(e, (size_t)row, dirs, octaves, fade);
            memcpy(normal_octaves, octaves, (size_t)row * sizeof *octaves);
        }
        e->surface->ops->sample_n(e->surface->self, (size_t)row, dirs,
                                  e->banded ? octaves : NULL,
                                  e->banded ? normal_octaves : NULL, heights,
                                  want_normal ? normals : NULL, want_detail ? detail : NULL);
        if (any_fade)
            plod__fade_blend(e, (size_t)row, dirs, octaves, fade, heights,
                             want_normal ? normals : NULL, want_detail ? detail : NULL);
        /* the outputs written in place where they are wanted, the block's
         * copied from them (positions in double only into the block) */
        plod__row row_out = {
            block ? block->position + 3 * b : position_scratch,
            out->positions ? out->positions + 3 * v : positions_scratch,
            !want_normal ? NULL : (out->normals ? out->normals + 3 * v : block->normal + 3 * b),
            !want_uv ? NULL : (out->uv ? out->uv + 2 * v : block->uv + 2 * b),
            !want_detail ? NULL : (out->detail ? out->detail + v : block->detail + b)};
        plod__row_outputs((size_t)row, dirs, heights, normals, detail, planet->radius,
                          params->origin, lon_ref, &row_out);
        if (block && out->normals)
            memcpy(block->normal + 3 * b, row_out.normals, 3 * (size_t)row * sizeof(float));
        if (block && out->uv)
            memcpy(block->uv + 2 * b, row_out.uv, 2 * (size_t)row * sizeof(float));
        if (block && out->detail)
            memcpy(block->detail + b, row_out.detail, (size_t)row * sizeof(float));
        v += (size_t)row;
        b += (size_t)row;
    }
}

/* Vertices (weights k on `corners`, template of e->n segments) evaluated
 * as plod__compute_vertices evaluates them in a sector with those corners:
 * the same direction sums, detail bands, samples and casts, so the same
 * bits.  Outputs: positions 3 per vertex (relative to the origin), normals
 * 3 and detail 1 where not NULL. */
static void plod__sample_vertices(const plod__emitter *e, const double corners[3][3],
                                  size_t count, const int (*k)[3], float *positions,
                                  float *normals_f, float *detail_f)
{
    enum { MAX = 1 << (PLOD_MAX_TEMPLATE_LEVEL - 1) };
    const plod_mesh_params *params = e->params;
    double inv_n = 1.0 / (double)e->n;
    double dirs[3 * MAX], heights[MAX], normals[3 * MAX], detail[MAX], fade[MAX];
    double position[3 * MAX];
    int octaves[MAX], normal_octaves[MAX], band[4];
    assert(count <= MAX);
    int fading = e->banded && params->detail_fade_cell > 0.0, any_fade = 0;
    if (e->banded && !fading)
        plod__detail_bands(e, corners, e->n, band);
    for (size_t v = 0; v < count; v++) {
        plod__vertex_direction(corners, k[v], inv_n, dirs + 3 * v);
        if (e->banded && !fading)
            octaves[v] = plod__vertex_band(e, k[v], band, dirs + 3 * v, normal_octaves + v);
    }
    if (fading) {
        any_fade = plod__fade_bands(e, count, dirs, octaves, fade);
        memcpy(normal_octaves, octaves, count * sizeof *octaves);
    }
    e->surface->ops->sample_n(e->surface->self, count, dirs, e->banded ? octaves : NULL,
                              e->banded ? normal_octaves : NULL, heights,
                              normals_f ? normals : NULL, detail_f ? detail : NULL);
    if (any_fade)
        plod__fade_blend(e, count, dirs, octaves, fade, heights, normals_f ? normals : NULL,
                         detail_f ? detail : NULL);
    plod__row row_out = {position, positions, normals_f, NULL, detail_f};
    plod__row_outputs(count, dirs, heights, normals, detail, params->planet->radius,
                      params->origin, 0.0, &row_out);
}

/* ---- the split morph (plod_mesh_sector.split) ------------------------------------
 * Weights: a sector's vertex k = (k0, k1, k2) on its corners.  Its parent
 * P = (p0, p1, p2) has child 0 = (p1, m, p0) and child 1 = (p2, m, p1), m
 * the middle of p0 p2; a child's vertex with k1 even is P's vertex
 * plod__to_parent.  A vertex with k1 odd lies off P's grid and blends
 * toward the middle of P's edge through it that keeps the weight on P's
 * right-angle corner p1 (child 0: k0; child 1: k2); that edge's far end may
 * lie in the sibling (plod__to_sibling).  The same a level further up for
 * every ancestor in the chain, each vertex with its weights in each. */

static void plod__to_parent(int child, const int k[3], int out[3])
{
    if (!child) {
        out[0] = k[2] + k[1] / 2, out[1] = k[0], out[2] = k[1] / 2;
    } else {
        out[0] = k[1] / 2, out[1] = k[2], out[2] = k[0] + k[1] / 2;
    }
}

/* The two ends of the parent's edge through a vertex k (k1 odd) of a
 * `child`, in the child's weights; they may leave the child (a negative
 * weight: in the sibling, plod__to_sibling). */
static void plod__edge_ends(int child, const int k[3], int ends[2][3])
{
    for (int s = 0; s < 2; s++) {
        int d = s ? 1 : -1;
        ends[s][1] = k[1] + d;
        if (!child) { /* k0 kept */
            ends[s][0] = k[0];
            ends[s][2] = k[2] - d;
        } else {      /* k2 kept */
            ends[s][2] = k[2];
            ends[s][0] = k[0] - d;
        }
    }
}

/* A point of the parent's plane past a child's edge through the midpoint
 * (child 0: k2 < 0; child 1: k0 < 0) in the sibling's weights. */
static void plod__to_sibling(int child, const int k[3], int out[3])
{
    if (!child) { /* sibling child 1 = (p2, m, p1) */
        out[0] = -k[2], out[1] = k[1] + 2 * k[2], out[2] = k[0];
    } else {      /* sibling child 0 = (p1, m, p0) */
        out[0] = k[2], out[1] = k[1] + 2 * k[0], out[2] = -k[0];
    }
}

/* The parent's corners from a child's and the parent's corner it lacks,
 * and the sibling's. */
static void plod__family_corners(const double corners[3][3], const double third[3], int child,
                                 double parent[3][3], double sibling[3][3])
{
    for (int c = 0; c < 3; c++) {
        parent[0][c] = child ? third[c] : corners[2][c];
        parent[1][c] = corners[child ? 2 : 0][c];
        parent[2][c] = child ? corners[0][c] : third[c];
        sibling[0][c] = child ? corners[2][c] : third[c];
        sibling[1][c] = corners[1][c];
        sibling[2][c] = child ? third[c] : corners[0][c];
    }
}

/* A vertex's outputs: where they are, or NULL. */
typedef struct plod__vertex_ref {
    float *pos, *nrm, *det;
} plod__vertex_ref;

/* The split morph's scratch for one sector: the points it blends or
 * blends toward, each once per stage.  Stage j's points are evaluated from
 * the corners of the sector's ancestor j levels up (tri 0) or of that
 * ancestor's sibling (tri 1), in their weights; stage 0's first `grid`
 * points are the sector's own vertices.  A point born at stage s (an odd
 * weight on corner 1 of the ancestor s levels up) has an arrival there:
 * the two ends of that ancestor's edge through it, stage s points. */
typedef struct plod__chain_point {
    int k[3];
    int tri;
    int birth;       /* its arrival's stage, or -1: not blended */
    int32_t arrival;
} plod__chain_point;

typedef struct plod__chain_arrival {
    int k[3];        /* in the stage's ancestor's weights */
    int stage;
    int32_t end[2];  /* points */
} plod__chain_arrival;

typedef struct plod__chain {
    const plod_split_morph *morph;
    int n, stages;
    size_t grid;
    uint32_t *keys; /* (stage, kind, grid index) + 1; 0: empty */
    int32_t *values;
    size_t capacity, used;
    plod__chain_point *points;
    size_t point_count, point_capacity;
    plod__chain_arrival *arrivals;
    size_t arrival_count, arrival_capacity;
    float *pos, *nrm, *det; /* per point past the sector's own */
    int with_nrm, with_det;
    float *own_pos, *own_nrm, *own_det; /* the sector's arrays */
    const double *origin;
} plod__chain;

static int plod__chain_rehash(plod__chain *c, size_t capacity)
{
    uint32_t *keys = calloc(capacity, sizeof *keys);
    int32_t *values = malloc(capacity * sizeof *values);
    if (!keys || !values) {
        free(keys);
        free(values);
        return 0;
    }
    for (size_t i = 0; i < c->capacity; i++) {
        if (!c->keys[i])
            continue;
        size_t at = (c->keys[i] * 2654435761u) & (capacity - 1);
        while (keys[at])
            at = (at + 1) & (capacity - 1);
        keys[at] = c->keys[i];
        values[at] = c->values[i];
    }
    free(c->keys);
    free(c->values);
    c->keys = keys;
    c->values = values;
    c->capacity = capacity;
    return 1;
}

/* The slot of key (stage, kind 0/1: a point of tri 0/1, 2: an arrival, k);
 * *found whether it holds a value.  NULL: no memory. */
static int32_t *plod__chain_slot(plod__chain *c, int stage, int kind, const int k[3],
                                 int *found)
{
    if (2 * (c->used + 1) > c->capacity && !plod__chain_rehash(c, 2 * c->capacity))
        return NULL;
    uint32_t key = (uint32_t)(((size_t)stage * 3 + (size_t)kind) * c->grid +
                              plod__vertex_index(c->n, k[2], k[1])) + 1u;
    size_t at = (key * 2654435761u) & (c->capacity - 1);
    while (c->keys[at] && c->keys[at] != key)
        at = (at + 1) & (c->capacity - 1);
    *found = c->keys[at] != 0;
    if (!*found) {
        c->keys[at] = key;
        c->used++;
    }
    return &c->values[at];
}

static int plod__chain_grow(void **array, size_t *capacity, size_t need, size_t size)
{
    if (need <= *capacity)
        return 1;
    size_t grown = *capacity ? 2 * *capacity : 64;
    while (grown < need)
        grown *= 2;
    void *p = realloc(*array, grown * size);
    if (!p)
        return 0;
    *array = p;
    *capacity = grown;
    return 1;
}

/* Where a point of stage b (tri, weights k) is born: the stage whose
 * ancestor has it off its parent's grid, with its weights there in x; -1
 * past the stages or where that stage's factor is 0 (it keeps its own
 * position). */
static int plod__chain_birth(const plod__chain *c, int b, int tri, const int k[3], int x[3])
{
    const plod_split_morph_stage *st = c->morph->stage;
    if (k[1] & 1) {
        assert(!tri);
        memcpy(x, k, sizeof(int[3]));
        return st[b].factor > 0.0 ? b : -1;
    }
    int up[3];
    plod__to_parent(tri ? !st[b].child : st[b].child, k, up);
    for (int s = b + 1; s < c->stages; s++) {
        if (up[1] & 1) {
            memcpy(x, up, sizeof(int[3]));
            return st[s].factor > 0.0 ? s : -1;
        }
        int next[3];
        plod__to_parent(st[s].child, up, next);
        memcpy(up, next, sizeof up);
    }
    return -1;
}

/* Notes point p's birth and its arrival (new ones are listed). */
static int plod__chain_born(plod__chain *c, int b, int32_t p)
{
    plod__chain_point *pt = &c->points[p];
    int x[3];
    pt->birth = plod__chain_birth(c, b, pt->tri, pt->k, x);
    pt->arrival = -1;
    if (pt->birth < 0)
        return 1;
    int found;
    int32_t *slot = plod__chain_slot(c, pt->birth, 2, x, &found);
    if (!slot)
        return 0;
    if (!found) {
        if (!plod__chain_grow((void **)&c->arrivals, &c->arrival_capacity,
                              c->arrival_count + 1, sizeof *c->arrivals))
            return 0;
        plod__chain_arrival *a = &c->arrivals[c->arrival_count];
        memcpy(a->k, x, sizeof a->k);
        a->stage = pt->birth;
        a->end[0] = a->end[1] = -1;
        *slot = (int32_t)c->arrival_count++;
    }
    c->points[p].arrival = *slot;
    return 1;
}

/* The point of stage b at (tri, k), listed if new; -1: no memory. */
static int32_t plod__chain_point_at(plod__chain *c, int b, int tri, const int k[3])
{
    assert(k[0] >= 0 && k[1] >= 0 && k[2] >= 0 && k[0] + k[1] + k[2] == c->n);
    int found;
    int32_t *slot = plod__chain_slot(c, b, tri, k, &found);
    if (!slot)
        return -1;
    if (found)
        return *slot;
    if (!plod__chain_grow((void **)&c->points, &c->point_capacity, c->point_count + 1,
                          sizeof *c->points))
        return -1;
    int32_t p = (int32_t)c->point_count++;
    *slot = p;
    memcpy(c->points[p].k, k, sizeof(int[3]));
    c->points[p].tri = tri;
    if (!plod__chain_born(c, b, p))
        return -1;
    return p;
}

static plod__vertex_ref plod__chain_ref(const plod__chain *c, int32_t p)
{
    plod__vertex_ref r;
    if ((size_t)p < c->grid) {
        r.pos = c->own_pos + 3 * (size_t)p;
        r.nrm = c->own_nrm ? c->own_nrm + 3 * (size_t)p : NULL;
        r.det = c->own_det ? c->own_det + p : NULL;
    } else {
        size_t q = (size_t)p - c->grid;
        r.pos = c->pos + 3 * q;
        r.nrm = c->with_nrm ? c->nrm + 3 * q : NULL;
        r.det = c->with_det ? c->det + q : NULL;
    }
    return r;
}

/* Point p blended by its birth stage's factor toward its arrival's edge
 * middle, along its own direction and in height: its distance from the
 * centre moves toward the mean of the edge ends'.  Not where it stands: the
 * grids of a sector's ancestors (their corners' bit rule) do not nest on
 * the sphere, so an ancestor's edge middle lies beside the vertex, the
 * more the larger the ancestor, and a whole-position blend slides the
 * vertex sideways by that gap as the factor changes.  Not to the chord:
 * an ancestor's long edges sag kilometres below the ground (an edge of
 * 700 km by 10 km), which would read as valleys and, below sea level, as
 * sea; at the sector's own split the chord and the mean differ by its own
 * cells' sag, a fraction of a pixel. */
static void plod__chain_blend(const plod__chain *c, int32_t p)
{
    const plod__chain_point *pt = &c->points[p];
    const plod__chain_arrival *a = &c->arrivals[pt->arrival];
    plod__vertex_ref v = plod__chain_ref(c, p), e0 = plod__chain_ref(c, a->end[0]),
                     e1 = plod__chain_ref(c, a->end[1]);
    double m = c->morph->stage[pt->birth].factor;
    m = m > 1.0 ? 1.0 : m;
    /* planet-centred, in double */
    double at[3], r2 = 0.0, r2a = 0.0, r2b = 0.0;
    for (int k = 0; k < 3; k++) {
        at[k] = (double)v.pos[k] + c->origin[k];
        double pa = (double)e0.pos[k] + c->origin[k], pb = (double)e1.pos[k] + c->origin[k];
        r2 += at[k] * at[k];
        r2a += pa * pa;
        r2b += pb * pb;
    }
    double r = sqrt(r2), target = 0.5 * (sqrt(r2a) + sqrt(r2b));
    double scale = (r + m * (target - r)) / r;
    for (int k = 0; k < 3; k++)
        v.pos[k] = (float)(at[k] * scale - c->origin[k]);
    plod__blend_shading(v.nrm, v.det, e0.nrm, e0.det, e1.nrm, e1.det, m);
}

static void plod__chain_free(plod__chain *c)
{
    free(c->keys);
    free(c->values);
    free(c->points);
    free(c->arrivals);
    free(c->pos);
    free(c->nrm);
    free(c->det);
}

/* Evaluates the points [first, last) past the sector's own, from the
 * corners of the stage's ancestor (tri 0) and of its sibling (tri 1), in
 * batches the sampler takes. */
static void plod__chain_evaluate(const plod__emitter *e, plod__chain *c,
                                 const double ancestor[3][3], const double sibling[3][3],
                                 size_t first, size_t last)
{
    enum { MAX = 1 << (PLOD_MAX_TEMPLATE_LEVEL - 1) };
    int k[MAX][3];
    int32_t which[MAX];
    float pos[3 * MAX], nrm[3 * MAX], det[MAX];
    if (first < c->grid)
        first = c->grid;
    for (int tri = 0; tri < 2; tri++)
        for (size_t p = first; p < last;) {
            size_t count = 0;
            for (; p < last && count < MAX; p++)
                if (c->points[p].tri == tri) {
                    memcpy(k[count], c->points[p].k, sizeof k[count]);
                    which[count++] = (int32_t)p;
                }
            if (!count)
                continue;
            plod__sample_vertices(e, tri ? sibling : ancestor, count, (const int (*)[3])k, pos,
                                  c->with_nrm ? nrm : NULL, c->with_det ? det : NULL);
            for (size_t i = 0; i < count; i++) {
                plod__vertex_ref r = plod__chain_ref(c, which[i]);
                memcpy(r.pos, pos + 3 * i, 3 * sizeof(float));
                if (r.nrm)
                    memcpy(r.nrm, nrm + 3 * i, 3 * sizeof(float));
                if (r.det)
                    *r.det = det[i];
            }
        }
}

/* The split morph of a sector (plod_mesh_sector.split): the points of every
 * stage found from the sector's vertices up (each arrival's edge ends, then
 * theirs), then evaluated and blended from the top stage down, so each
 * edge's ends have their final positions before a point blends toward
 * them; the sector's own vertices last. */
static plod_status plod__split_morph_sector(const plod__emitter *e,
                                            const plod_mesh_sector *sector, size_t vbase)
{
    const plod_split_morph *morph = sector->split;
    int stages = morph->stages < PLOD_SPLIT_MORPH_STAGES ? morph->stages
                                                         : PLOD_SPLIT_MORPH_STAGES;
    if (stages <= 0)
        return PLOD_OK; /* morph output already 0 */
    const plod_mesh_buffers *out = e->out;
    int n = e->n;
    plod__chain c;
    memset(&c, 0, sizeof c);
    c.morph = morph;
    c.origin = e->params->origin;
    c.n = n;
    c.stages = stages;
    c.grid = e->vertices_per_sector;
    c.own_pos = out->positions + 3 * vbase;
    c.own_nrm = out->normals ? out->normals + 3 * vbase : NULL;
    c.own_det = out->detail ? out->detail + vbase : NULL;
    c.with_nrm = c.own_nrm != NULL;
    c.with_det = c.own_det != NULL;
    float *morph_out = out->morph ? out->morph + vbase : NULL;
    plod_status status = PLOD_ERR_NO_MEMORY;
    size_t first[PLOD_SPLIT_MORPH_STAGES + 1];
    size_t capacity = 64;
    while (capacity < 8 * c.grid)
        capacity *= 2;
    c.keys = calloc(capacity, sizeof *c.keys);
    c.values = malloc(capacity * sizeof *c.values);
    if (!c.keys || !c.values)
        goto done;
    c.capacity = capacity;

    /* the sector's own vertices: stage 0's first points */
    for (int i = 0; i <= n; i++)
        for (int j = 0; j <= n - i; j++) {
            int k[3] = {n - i - j, j, i};
            if (plod__chain_point_at(&c, 0, 0, k) < 0)
                goto done;
        }
    /* each stage's arrivals add their ends to it; an end's own arrival is
     * further up */
    for (int b = 0; b < stages; b++) {
        first[b] = b ? c.point_count : 0;
        int child = morph->stage[b].child;
        for (size_t a = 0; a < c.arrival_count; a++) {
            if (c.arrivals[a].stage != b)
                continue;
            int ends[2][3];
            plod__edge_ends(child, c.arrivals[a].k, ends);
            for (int s = 0; s < 2; s++) {
                int past = child ? ends[s][0] < 0 : ends[s][2] < 0, q[3];
                if (past)
                    plod__to_sibling(child, ends[s], q);
                int32_t p = plod__chain_point_at(&c, b, past, past ? q : ends[s]);
                if (p < 0)
                    goto done;
                c.arrivals[a].end[s] = p;
            }
        }
    }
    first[stages] = c.point_count;
    size_t extra = c.point_count - c.grid;
    if (extra) {
        c.pos = malloc(3 * extra * sizeof *c.pos);
        c.nrm = c.with_nrm ? malloc(3 * extra * sizeof *c.nrm) : NULL;
        c.det = c.with_det ? malloc(extra * sizeof *c.det) : NULL;
        if (!c.pos || (c.with_nrm && !c.nrm) || (c.with_det && !c.det))
            goto done;
    }

    /* the ancestors' and their siblings' corners */
    double ancestor[PLOD_SPLIT_MORPH_STAGES + 1][3][3], sibling[PLOD_SPLIT_MORPH_STAGES][3][3];
    memcpy(ancestor[0], sector->corners, sizeof ancestor[0]);
    for (int b = 0; b < stages; b++)
        plod__family_corners((const double (*)[3])ancestor[b], morph->stage[b].third_corner,
                             morph->stage[b].child, ancestor[b + 1], sibling[b]);

    for (int b = stages - 1; b >= 0; b--) {
        plod__chain_evaluate(e, &c, (const double (*)[3])ancestor[b],
                             (const double (*)[3])sibling[b], first[b], first[b + 1]);
        for (size_t p = first[b]; p < first[b + 1]; p++)
            if (c.points[p].birth > b)
                plod__chain_blend(&c, (int32_t)p);
    }
    /* the sector's vertices born at stage 0, toward their blended ends */
    for (size_t p = 0; p < c.grid; p++) {
        int birth = c.points[p].birth;
        if (birth == 0)
            plod__chain_blend(&c, (int32_t)p);
        if (morph_out && birth >= 0)
            morph_out[p] = (float)morph->stage[birth].factor;
    }
    status = PLOD_OK;
done:
    plod__chain_free(&c);
    return status;
}

/* A cached sector's corner normals for this emission's eye (they depend
 * on it, plod__vertex_band): as plod__compute_vertices computes them,
 * evaluated again only for corners whose band the eye changed (the cached
 * normal of an unchanged band is that evaluation's result). */
static void plod__corner_positions(int n, size_t at[3])
{
    at[0] = plod__vertex_index(n, 0, 0);
    at[1] = plod__vertex_index(n, 0, n);
    at[2] = plod__vertex_index(n, n, 0);
}

/* The normal band of each of a sector's corners for this emission's eye. */
static void plod__corner_bands(const plod__emitter *e, const plod_mesh_sector *sector,
                               double dirs[9], int32_t bands[3])
{
    int n = e->n;
    double inv_n = 1.0 / (double)n;
    const int ks[3][3] = {{n, 0, 0}, {0, n, 0}, {0, 0, n}};
    for (int c = 0; c < 3; c++) {
        plod__vertex_direction((const double (*)[3])sector->corners, ks[c], inv_n,
                               dirs + 3 * c);
        bands[c] = plod__corner_band(e, dirs + 3 * c);
    }
}

/* Whether a cached sector's corner normals hold for this emission's eye. */
static int plod__corners_current(const plod__emitter *e, const plod_mesh_sector *sector,
                                 const plod__block *block)
{
    if (!e->banded || !e->out->normals)
        return 1;
    double dirs[9];
    int32_t bands[3];
    plod__corner_bands(e, sector, dirs, bands);
    return bands[0] == block->corner_band[0] && bands[1] == block->corner_band[1] &&
           bands[2] == block->corner_band[2];
}

/* Corners of cached sectors whose normals this emission samples again,
 * gathered over a chunk's sectors so that the surface samples them in
 * full batches (a sector has at most three). */
enum { PLOD__CORNER_BATCH = 192 };
typedef struct plod__corner_batch {
    size_t count;
    double dirs[3 * PLOD__CORNER_BATCH];
    int octaves[PLOD__CORNER_BATCH], normal_octaves[PLOD__CORNER_BATCH];
    size_t vertex[PLOD__CORNER_BATCH]; /* output vertex */
} plod__corner_batch;

static void plod__flush_corners(const plod__emitter *e, plod__corner_batch *batch)
{
    if (!batch->count)
        return;
    double heights[PLOD__CORNER_BATCH], normals[3 * PLOD__CORNER_BATCH];
    e->surface->ops->sample_n(e->surface->self, batch->count, batch->dirs, batch->octaves,
                              batch->normal_octaves, heights, normals, NULL);
    for (size_t c = 0; c < batch->count; c++)
        for (int k = 0; k < 3; k++)
            e->out->normals[3 * batch->vertex[c] + k] = (float)normals[3 * c + k];
    batch->count = 0;
}

static void plod__corner_normals(const plod__emitter *e, const plod_mesh_sector *sector,
                                 size_t vbase, const plod__block *block,
                                 plod__slot_cache *sc, plod__corner_batch *batch)
{
    size_t at[3];
    plod__corner_positions(e->n, at);
    double dirs[9];
    int32_t bands[3];
    plod__corner_bands(e, sector, dirs, bands);
    int changed = 0;
    for (int c = 0; c < 3; c++) { /* the corners whose band changed */
        if (bands[c] == block->corner_band[c])
            continue;
        if (batch->count == PLOD__CORNER_BATCH)
            plod__flush_corners(e, batch);
        size_t i = batch->count++;
        memcpy(batch->dirs + 3 * i, dirs + 3 * c, 3 * sizeof(double));
        batch->octaves[i] = PLOD_DETAIL_MAX_OCTAVES;
        batch->normal_octaves[i] = bands[c];
        batch->vertex[i] = vbase + at[c];
        changed = 1;
    }
    if (!changed)
        return;
    sc->corners_changed = 1;
    for (int c = 0; c < 3; c++)
        sc->corner_band[c] = bands[c];
}

/* The same outputs from a cache entry: (float)(p - origin) as computed. */
static void plod__copy_vertices(const plod__emitter *e, size_t vbase, const plod__block *block)
{
    const plod_mesh_buffers *out = e->out;
    const double *origin = e->params->origin;
    size_t count = e->vertices_per_sector;
    if (out->positions) {
        float *dst = out->positions + 3 * vbase;
        const double *src = block->position;
        for (size_t k = 0; k < 3 * count; k += 3) {
            dst[k + 0] = (float)(src[k + 0] - origin[0]);
            dst[k + 1] = (float)(src[k + 1] - origin[1]);
            dst[k + 2] = (float)(src[k + 2] - origin[2]);
        }
    }
    if (out->normals)
        memcpy(out->normals + 3 * vbase, block->normal, 3 * count * sizeof(float));
    if (out->uv)
        memcpy(out->uv + 2 * vbase, block->uv, 2 * count * sizeof(float));
    if (out->detail) /* (corners keep every octave: independent of the origin) */
        memcpy(out->detail + vbase, block->detail, count * sizeof(float));
}

static plod_status plod__emit_sector(const plod__emitter *e, const plod_mesh_sector *sector,
                                     size_t slot, const plod_mesh_cache *cache,
                                     plod__slot_cache *sc, plod__corner_batch *corners)
{
    if (!plod__sector_ok(sector))
        return PLOD_ERR_BAD_COORD;
    const plod_mesh_params *params = e->params;
    const plod_mesh_buffers *out = e->out;
    int n = e->n;
    size_t vbase = slot * e->vertices_per_sector;
    size_t tbase = slot * e->triangles_per_sector;

    plod__block block;
    if (sc && sc->hit >= 0) {
        plod__block_view(cache->entries[sc->hit].data, e->vertices_per_sector, &block);
        plod__copy_vertices(e, vbase, &block);
        if (e->banded && out->normals)
            plod__corner_normals(e, sector, vbase, &block, sc, corners);
    } else if (sc && sc->fresh) {
        plod__block_view(sc->fresh, e->vertices_per_sector, &block);
        plod__compute_vertices(e, sector, vbase, &block);
    } else {
        plod__compute_vertices(e, sector, vbase, NULL);
    }
    if (out->morph)
        memset(out->morph + vbase, 0, e->vertices_per_sector * sizeof(float));
    if (out->keys)
        out->keys[slot] = sector->key;

    if (out->triangles)
        plod__write_triangles(out->triangles + 3 * tbase, n, (int32_t)vbase);
    if (out->sector_level) /* tests outside the loops: plain fills */
        for (size_t t = 0; t < e->triangles_per_sector; t++)
            out->sector_level[tbase + t] = sector->level;
    if (out->face)
        for (size_t t = 0; t < e->triangles_per_sector; t++)
            out->face[tbase + t] = sector->face;
    if (params->morph && n > 1 && out->positions) {
        if (sector->split)
            return plod__split_morph_sector(e, sector, vbase);
        plod__morph_sector(e, vbase);
    }
    return PLOD_OK;
}

/* ---- threads ----------------------------------------------------------------- */

typedef struct plod__chunk {
    const plod__emitter *emitter;
    plod_mesh_sector_fn source;
    const void *context;
    size_t begin, end;   /* sector index range */
    size_t first_slot;   /* output slot of its first emitted sector */
    size_t emitted;      /* sectors it emits (counting pass) */
    /* cache: read-only here; misses get fresh blocks within `budget` bytes */
    const plod_mesh_cache *cache;
    plod__slot_cache *slots; /* indexed by output slot */
    size_t budget;
    plod_status status;
} plod__chunk;

static void plod__run_chunk(plod__chunk *chunk)
{
    const plod__emitter *e = chunk->emitter;
    const plod_mesh_cache *cache = chunk->cache;
    size_t slot = chunk->first_slot;
    plod_mesh_sector sector;
    plod__corner_batch corners;
    corners.count = 0;
    chunk->status = PLOD_OK;
    for (size_t s = chunk->begin; s < chunk->end; s++) {
        sector.key = 0;
        sector.split = NULL;
        if (!chunk->source(chunk->context, s, &sector))
            continue;
        plod__slot_cache *sc = NULL;
        if (cache && sector.key) {
            sc = &chunk->slots[slot];
            sc->key = sector.key;
            sc->hit = plod__cache_find(cache, sector.key);
            sc->fresh = NULL;
            sc->corners_changed = 0;
            size_t need = cache->entry_bytes;
            if (sc->hit < 0 && need <= chunk->budget) {
                sc->fresh = malloc(need);
                if (sc->fresh)
                    chunk->budget -= need;
            }
        }
        plod_status st = plod__emit_sector(e, &sector, slot, cache, sc, &corners);
        slot++;
        if (st != PLOD_OK) {
            chunk->status = st;
            break;
        }
    }
    plod__flush_corners(e, &corners);
}

/* plod_parallel_for's range: chunks [begin, end). */
static void plod__run_chunks(void *context, size_t begin, size_t end)
{
    plod__chunk *chunks = context;
    for (size_t t = begin; t < end; t++)
        plod__run_chunk(&chunks[t]);
}

/* A hit's corner normals sampled again for this eye go back into its
 * entry with their bands, so the entry holds what this emission wrote
 * (changed_only compares with it). */
static void plod__write_back_corners(plod_mesh_cache *c, const plod__emitter *e,
                                     const plod__slot_cache *sc, size_t slot)
{
    plod__block block;
    plod__block_view(c->entries[sc->hit].data, e->vertices_per_sector, &block);
    size_t at[3];
    plod__corner_positions(e->n, at);
    const float *normals = e->out->normals + 3 * slot * e->vertices_per_sector;
    for (int k = 0; k < 3; k++) {
        memcpy(block.normal + 3 * at[k], normals + 3 * at[k], 3 * sizeof(float));
        block.corner_band[k] = sc->corner_band[k];
    }
}

/* After the threads: keep the entries this emission used (and those a
 * changed_only emission left out: unchanged[0, count), an entry or -1),
 * add its fresh blocks (a key seen twice keeps its first), free the rest.
 * Any failure empties the cache: it is never wrong, only colder. */
static void plod__cache_commit(plod_mesh_cache *c, const plod__emitter *e,
                               plod__slot_cache *slots, size_t total,
                               const int32_t *unchanged, size_t count, int ok)
{
    c->emissions++;
    c->hits = c->misses = 0;
    for (size_t i = 0; i < count; i++)
        c->hits += unchanged[i] >= 0;
    size_t fresh = 0;
    for (size_t i = 0; i < total; i++) {
        if (!slots[i].key)
            continue;
        c->hits += slots[i].hit >= 0;
        c->misses += slots[i].hit < 0;
        fresh += slots[i].fresh != NULL;
    }
    unsigned char *used = ok ? calloc(c->count ? c->count : 1, 1) : NULL;
    size_t need = c->count + fresh;
    if (used && need > c->capacity) {
        size_t cap = c->capacity ? c->capacity : 64;
        while (cap < need)
            cap *= 2;
        plod__cache_entry *grown = realloc(c->entries, cap * sizeof *grown);
        if (grown) {
            c->entries = grown;
            c->capacity = cap;
        } else {
            free(used);
            used = NULL;
        }
    }
    if (!used) {
        for (size_t i = 0; i < total; i++)
            free(slots[i].fresh);
        plod_mesh_cache_clear(c);
        return;
    }
    for (size_t i = 0; i < total; i++)
        if (slots[i].key && slots[i].hit >= 0) {
            used[slots[i].hit] = 1;
            if (slots[i].corners_changed)
                plod__write_back_corners(c, e, &slots[i], i);
        }
    for (size_t i = 0; i < count; i++)
        if (unchanged[i] >= 0)
            used[unchanged[i]] = 1;
    size_t kept = 0;
    for (size_t i = 0; i < c->count; i++) {
        if (used[i]) {
            c->entries[kept++] = c->entries[i];
        } else {
            free(c->entries[i].data);
            c->bytes -= c->entry_bytes;
        }
    }
    free(used);
    c->count = kept;
    if (!plod__cache_rehash(c, need)) {
        for (size_t i = 0; i < total; i++)
            free(slots[i].fresh);
        plod_mesh_cache_clear(c);
        return;
    }
    size_t mask = c->table_size - 1;
    for (size_t i = 0; i < total; i++) {
        if (!slots[i].fresh)
            continue;
        size_t h = plod__key_hash(slots[i].key) & mask;
        while (c->table[h] >= 0 && c->entries[c->table[h]].key != slots[i].key)
            h = (h + 1) & mask;
        if (c->table[h] >= 0) { /* the key came twice */
            free(slots[i].fresh);
            continue;
        }
        c->table[h] = (int32_t)c->count;
        c->entries[c->count++] = (plod__cache_entry){slots[i].key, slots[i].fresh};
        c->bytes += c->entry_bytes;
    }
}

/* changed_only: the source without the sectors whose cached output holds. */
typedef struct plod__changed_source {
    plod_mesh_sector_fn source;
    const void *context;
    const size_t *index; /* the source's indices of the changed sectors */
} plod__changed_source;

static int plod__changed_sector(const void *context, size_t k, plod_mesh_sector *sector)
{
    const plod__changed_source *src = context;
    return src->source(src->context, src->index[k], sector);
}

/* Per sector index, the entry of a sector a changed_only emission leaves
 * out (a hit whose corner normals hold), else -1 (plod_parallel_for's
 * range). */
typedef struct plod__unchanged_search {
    const plod__emitter *emitter;
    const plod_mesh_cache *cache;
    plod_mesh_sector_fn source;
    const void *context;
    int32_t *entry;
} plod__unchanged_search;

static void plod__find_unchanged(void *context, size_t begin, size_t end)
{
    const plod__unchanged_search *u = context;
    plod_mesh_sector sector;
    for (size_t s = begin; s < end; s++) {
        u->entry[s] = -1;
        sector.key = 0;
        sector.split = NULL;
        if (!u->source(u->context, s, &sector) || !sector.key)
            continue;
        int32_t hit = plod__cache_find(u->cache, sector.key);
        if (hit < 0)
            continue;
        plod__block block;
        plod__block_view(u->cache->entries[hit].data, u->emitter->vertices_per_sector, &block);
        if (plod__corners_current(u->emitter, &sector, &block))
            u->entry[s] = hit;
    }
}

/* With a cache a hit costs a copy and a miss the whole evaluation, and the
 * misses cluster (the new sectors near the eye): the threads' chunks are
 * cut at equal estimated work, a miss counting PLOD__MISS_WEIGHT hits.
 * (Where the chunks are cut never changes the output: slots follow the
 * index order.) */
#define PLOD__MISS_WEIGHT 16

typedef struct plod__weighing {
    plod_mesh_sector_fn source;
    const void *context;
    const plod_mesh_cache *cache;
    unsigned char *weight; /* per index: 0 not emitted, 1 a hit, else a miss */
} plod__weighing;

static void plod__weigh(void *context, size_t begin, size_t end)
{
    const plod__weighing *w = context;
    plod_mesh_sector sector;
    for (size_t s = begin; s < end; s++) {
        sector.key = 0;
        sector.split = NULL;
        if (!w->source(w->context, s, &sector))
            w->weight[s] = 0;
        else if (sector.key && plod__cache_find(w->cache, sector.key) >= 0)
            w->weight[s] = 1;
        else
            w->weight[s] = PLOD__MISS_WEIGHT;
    }
}

/* plod_parallel_for on the caller's persistent workers when it lends
 * them (chunks of `grain`), else on threads started for the loop. */
static void plod__parallel(const plod_mesh_params *params, size_t count, int threads,
                           size_t grain, plod_range_fn range, void *context)
{
    if (params->workers && threads > 1)
        plod_workers_for(params->workers, count, grain, range, context);
    else
        plod_parallel_for(count, threads, range, context);
}

/* Each sector's work (plod__weigh) into weight[0, count), on one thread
 * below PLOD__PARALLEL_WEIGHING sectors (a cache lookup each: a thread
 * would cost more); returns the total. */
#define PLOD__PARALLEL_WEIGHING 4096
static uint64_t plod__weigh_all(const plod_mesh_params *params, plod_mesh_sector_fn source,
                                const void *context, size_t count, unsigned char *weight)
{
    plod__weighing w = {source, context,
                        params->detail_fade_cell > 0.0 ? NULL : params->cache, weight};
    plod__parallel(params, count, count < PLOD__PARALLEL_WEIGHING ? 1 : params->threads, 1024,
                   plod__weigh, &w);
    uint64_t total = 0;
    for (size_t s = 0; s < count; s++)
        total += weight[s];
    return total;
}

/* Chunk t = [cut[t], cut[t + 1]) of [0, count): equal work by the
 * weights. */
static void plod__cut_by_work(const unsigned char *weight, uint64_t total, size_t count,
                              int threads, size_t *cut)
{
    uint64_t done = 0;
    int t = 1;
    cut[0] = 0;
    for (size_t s = 0; s < count && t < threads; s++) {
        done += weight[s];
        while (t < threads && done * (uint64_t)threads >= total * (uint64_t)t)
            cut[t++] = s + 1;
    }
    while (t <= threads)
        cut[t++] = count;
}

/* A thread takes tens of microseconds to start, a persistent worker a few
 * to wake: each must have at least this much work (in hits, a miss
 * counting PLOD__MISS_WEIGHT; a hit is about a microsecond), or the
 * emission runs on fewer. */
#define PLOD__MIN_WORK_PER_THREAD 96
#define PLOD__MIN_WORK_PER_WORKER 16

plod_status plod_mesh_emit(const plod_mesh_params *params,
                           const plod_mesh_sector_source *sectors,
                           const plod_surface_source *surface, const plod_mesh_buffers *out,
                           size_t *vertex_count, size_t *triangle_count)
{
    if (vertex_count)
        *vertex_count = 0;
    if (triangle_count)
        *triangle_count = 0;
    if (!sectors || !sectors->sector || !surface || !surface->ops || !surface->ops->sample_n ||
        !out)
        return PLOD_ERR_NULL;
    plod_status st = plod__check_params(params);
    if (st != PLOD_OK)
        return st;
    plod_mesh_sector_fn source = sectors->sector;
    const void *context = sectors->context;
    size_t count = sectors->count;

    plod__emitter emitter;
    plod__emitter_init(&emitter, params, surface, out);

    /* a fading band follows the eye: nothing cached holds */
    plod_mesh_cache *cache = params->detail_fade_cell > 0.0 ? NULL : params->cache;
    if (cache)
        plod__cache_bind(cache, params, surface, emitter.vertices_per_sector);
    int32_t *unchanged = NULL; /* changed_only: per index, the entry left out or -1 */
    size_t *changed_index = NULL, source_count = count;
    plod__changed_source changed;
    if (cache && params->changed_only && count) {
        unchanged = malloc(count * sizeof *unchanged);
        changed_index = malloc(count * sizeof *changed_index);
        if (unchanged && changed_index) {
            plod__unchanged_search search = {&emitter, cache, source, context, unchanged};
            /* ~0.1 us a sector: a thread (tens of us to start) pays from
             * about a thousand */
            int search_threads = count < 1024 ? 1 : params->threads;
            plod__parallel(params, count, search_threads, 256, plod__find_unchanged, &search);
            /* the changed sectors as a source of their own, so that the
             * threads' chunks share them evenly (they cluster near the eye) */
            size_t n = 0;
            for (size_t i = 0; i < count; i++)
                if (unchanged[i] < 0)
                    changed_index[n++] = i;
            changed = (plod__changed_source){source, context, changed_index};
            source = plod__changed_sector;
            context = &changed;
            count = n;
        } else { /* every sector is emitted */
            free(unchanged);
            free(changed_index);
            unchanged = NULL;
            changed_index = NULL;
        }
    }

    /* the work: with a cache each sector weighed (hits copy, misses
     * compute), without one every sector a miss */
    unsigned char *weight = cache && count > 0 ? malloc(count) : NULL;
    uint64_t work = weight ? plod__weigh_all(params, source, context, count, weight)
                           : (uint64_t)count * PLOD__MISS_WEIGHT;
    uint64_t min_work = params->workers ? PLOD__MIN_WORK_PER_WORKER : PLOD__MIN_WORK_PER_THREAD;
    int threads = params->threads;
    if ((uint64_t)threads * min_work > work)
        threads = (int)(work / min_work);
    if (threads < 1)
        threads = 1;

    /* the chunks: one a thread, or with workers sixteen a thread, claimed
     * in turn: a worker that wakes late still finds some, and the sectors
     * near the eye (more octaves than a miss's weight says) do not leave
     * one thread finishing alone */
    int parts = threads;
    if (params->workers && threads > 1) {
        uint64_t most = work / PLOD__MIN_WORK_PER_WORKER;
        parts = 16 * threads < PLOD_MESH_MAX_THREADS ? 16 * threads : PLOD_MESH_MAX_THREADS;
        parts = (uint64_t)parts > most ? (int)most : parts;
        parts = parts < threads ? threads : parts;
    }
    plod__chunk chunks[PLOD_MESH_MAX_THREADS];
    size_t cut[PLOD_MESH_MAX_THREADS + 1];
    int by_work = weight && parts > 1;
    if (by_work)
        plod__cut_by_work(weight, work, count, parts, cut);
    free(weight);
    size_t total = 0;
    /* Contiguous split of [0, count): by work with a cache, else by count. */
    for (int t = 0; t < parts; t++) {
        chunks[t].emitter = &emitter;
        chunks[t].source = source;
        chunks[t].context = context;
        chunks[t].begin = by_work ? cut[t] : count * (size_t)t / (size_t)parts;
        chunks[t].end = by_work ? cut[t + 1] : count * (size_t)(t + 1) / (size_t)parts;
        chunks[t].emitted = 0;
        for (size_t s = chunks[t].begin; s < chunks[t].end; s++)
            chunks[t].emitted += source(context, s, NULL) ? 1 : 0;
        chunks[t].first_slot = total;
        total += chunks[t].emitted;
        chunks[t].status = PLOD_OK;
        chunks[t].cache = NULL;
        chunks[t].slots = NULL;
        chunks[t].budget = 0;
    }
    if (total > 0 && plod_mesh_vertex_bound(total, params->template_level) == 0) {
        free(unchanged);
        free(changed_index);
        return PLOD_ERR_BAD_PARAM; /* indices would overflow int32 */
    }

    plod__slot_cache *slots = NULL;
    if (cache) {
        slots = total ? calloc(total, sizeof *slots) : NULL;
        if (total && !slots) {
            plod_mesh_cache_clear(cache); /* emit uncached */
            cache = NULL; /* (what changed_only left out stays the caller's) */
        }
    }
    if (slots) {
        /* the entries held now may all be evicted at the end, but they
         * count until then: each chunk gets an equal share of the rest */
        size_t room = cache->max_bytes > cache->bytes ? cache->max_bytes - cache->bytes : 0;
        for (int t = 0; t < parts; t++) {
            chunks[t].cache = cache;
            chunks[t].slots = slots;
            chunks[t].budget = room / (size_t)parts;
        }
    }

    /* the chunks, not the threads, decide the slots */
    plod__parallel(params, (size_t)parts, threads, 1, plod__run_chunks, chunks);
    st = PLOD_OK;
    for (int t = 0; t < parts; t++)
        if (chunks[t].status != PLOD_OK && st == PLOD_OK)
            st = chunks[t].status;
    if (cache) { /* an emission of nothing leaves nothing cached */
        plod__cache_commit(cache, &emitter, slots, total, unchanged,
                           unchanged ? source_count : 0, st == PLOD_OK);
        free(slots);
    }
    free(unchanged);
    free(changed_index);
    if (st != PLOD_OK)
        return st;

    if (vertex_count)
        *vertex_count = total * emitter.vertices_per_sector;
    if (triangle_count)
        *triangle_count = total * emitter.triangles_per_sector;
    return PLOD_OK;
}

static int plod__array_source(const void *context, size_t index,
                              plod_mesh_sector *sector)
{
    if (sector)
        *sector = ((const plod_mesh_sector *)context)[index];
    return 1;
}

plod_status plod_mesh_emit_array(const plod_mesh_params *params,
                                 const plod_mesh_sector *sectors, size_t count,
                                 const plod_surface_source *surface,
                                 const plod_mesh_buffers *out,
                                 size_t *vertex_count, size_t *triangle_count)
{
    if (!sectors && count > 0)
        return PLOD_ERR_NULL;
    plod_mesh_sector_source source = {plod__array_source, sectors, count};
    return plod_mesh_emit(params, &source, surface, out, vertex_count, triangle_count);
}

/* ---- instanced form ---------------------------------------------------------- */

plod_status plod_mesh_instances(const plod_mesh_params *params,
                                const plod_mesh_sector_source *sectors,
                                const plod_surface_source *surface, float *corners,
                                float *levels, float *morph, size_t *instance_count)
{
    if (instance_count)
        *instance_count = 0;
    if (!sectors || !sectors->sector || !surface || !surface->ops || !surface->ops->sample_n)
        return PLOD_ERR_NULL;
    plod_status st = plod__check_params(params);
    if (st != PLOD_OK)
        return st;
    size_t slot = 0;
    plod_mesh_sector sector;
    for (size_t s = 0; s < sectors->count; s++) {
        if (!sectors->sector(sectors->context, s, &sector))
            continue;
        if (!plod__sector_ok(&sector))
            return PLOD_ERR_BAD_COORD;
        if (corners)
            for (int c = 0; c < 3; c++)
                for (int x = 0; x < 3; x++)
                    corners[9 * slot + 3 * c + x] = (float)sector.corners[c][x];
        if (levels)
            levels[slot] = (float)sector.level;
        if (morph) {
            double centroid[3];
            int k[3] = {1, 1, 1};
            plod__vertex_direction((const double (*)[3])sector.corners, k, 1.0, centroid);
            double r = params->planet->radius + plod__height(surface, centroid);
            for (int c = 0; c < 3; c++)
                centroid[c] *= r;
            morph[slot] = (float)plod_mesh_morph_factor(params, centroid);
        }
        slot++;
    }
    if (instance_count)
        *instance_count = slot;
    return PLOD_OK;
}

/* ---- the shared vertex evaluation (plod_mesh_sampler) --------------------------- */

_Static_assert(PLOD_MESH_SAMPLER_OCTAVES == PLOD_DETAIL_MAX_OCTAVES,
               "the sampler keeps one fade threshold per detail octave");

void plod_mesh_sampler_init(plod_mesh_sampler *sampler, const plod_mesh_params *params,
                            const plod_surface_source *surface)
{
    plod__emitter e;
    memset(&e, 0, sizeof e);
    e.params = params;
    e.surface = surface;
    e.banded = surface->ops->octaves_for_cell != NULL;
    if (e.banded && params->detail_fade_cell > 0.0)
        plod__fade_init(&e);
    sampler->params = params;
    sampler->surface = surface;
    sampler->banded = e.banded;
    sampler->fade_octaves = e.fade_octaves;
    memcpy(sampler->fade_log2_cell, e.fade_log2_cell, sizeof sampler->fade_log2_cell);
    sampler->fade_ground_radius = e.fade_ground_radius;
}

double plod_mesh_atan2(double y, double x)
{
    return plod__atan2(y, x);
}

void plod_mesh_sample(const plod_mesh_sampler *sampler, size_t count, const double *dirs,
                      const double *cells, double lon_ref, float *positions, float *normals,
                      float *uv, float *detail, double *world)
{
    enum { GROUP = (1 << PLOD_MAX_TEMPLATE_LEVEL) + 161 };
    plod__emitter e;
    memset(&e, 0, sizeof e);
    e.params = sampler->params;
    e.surface = sampler->surface;
    e.banded = sampler->banded;
    e.fade_octaves = sampler->fade_octaves;
    memcpy(e.fade_log2_cell, sampler->fade_log2_cell, sizeof e.fade_log2_cell);
    e.fade_ground_radius = sampler->fade_ground_radius;
    const plod_mesh_params *params = sampler->params;
    int fading = e.banded && params->detail_fade_cell > 0.0;
    double heights[GROUP], normals_d[3 * GROUP], detail_d[GROUP], fade[GROUP];
    double position_scratch[3 * GROUP];
    float positions_scratch[3 * GROUP];
    int octaves[GROUP];
    for (size_t at = 0; at < count; at += GROUP) {
        size_t n = count - at < GROUP ? count - at : GROUP;
        const double *d = dirs + 3 * at;
        int any_fade = fading ? plod__fade_bands(&e, n, d, octaves, fade) : 0;
        for (size_t j = 0; j < n && e.banded && !fading; j++)
            octaves[j] = cells ? e.surface->ops->octaves_for_cell(e.surface->self,
                                                                  cells[at + j])
                               : PLOD_DETAIL_MAX_OCTAVES;
        e.surface->ops->sample_n(e.surface->self, n, d, e.banded ? octaves : NULL,
                                 e.banded ? octaves : NULL, heights,
                                 normals ? normals_d : NULL, detail ? detail_d : NULL);
        if (any_fade)
            plod__fade_blend(&e, n, d, octaves, fade, heights, normals ? normals_d : NULL,
                             detail ? detail_d : NULL);
        plod__row row = {world ? world + 3 * at : position_scratch,
                         positions ? positions + 3 * at : positions_scratch,
                         normals ? normals + 3 * at : NULL, uv ? uv + 2 * at : NULL,
                         detail ? detail + at : NULL};
        plod__row_outputs(n, d, heights, normals_d, detail_d, params->planet->radius,
                          params->origin, lon_ref, &row);
    }
}
