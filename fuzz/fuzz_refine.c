/* fuzz_refine.c -- libFuzzer harness for camera construction, HRTMR
 * refinement + culling and mesh emission through a session (cext/session.c
 * over camera.c, bound.c, lodtree.c, lodupdate.c, planet.c, mesh.c, with
 * cubemap.c/projection.c
 * underneath).
 *
 * Each input builds a planet (any projection; radius, height scale and sea
 * level from a table of edge cases or raw doubles; no height map or a tiny
 * 1..4 texel-per-side cube map whose texels come from the input, float maps
 * included NaN/inf), one to three cameras (structured: anywhere from the
 * centre to far away, looking anywhere, or 16 raw matrix doubles; any
 * intrinsics), refines incrementally with random parameters, then emits the
 * mesh and the instanced form.  Work per input is bounded by max_sectors
 * (16..512), template levels 0..2 and a small budget, so that an execution
 * costs tens of microseconds.  Checks besides ASan/UBSan: bad planets and
 * cameras are refused with a status; without hysteresis every frame equals
 * a fresh refiner's at its camera (leaves, flags, visible order), whatever
 * frames came before; statistics are monotone (total >=
 * backface >= frustum >= budget), the budget and max_level hold, the sector
 * list matches the statistics, corners are finite unit vectors, emitted
 * counts equal the bounds, triangle indices are in range, and with finite
 * heights every emitted float is finite.
 */
#include <math.h>
#include <stdint.h>

#include "fuzz_input.h"
#include "plod_detail.h"
#include "plod_mesh.h"
#include "plod_refine.h"
#include "plod_session.h"

#define MAX_CAMERAS 3

/* FUZZ_DUMP=1 prints each input's planet, parameters and cameras as C
 * initialisers (for writing reproducers). */
static int fuzz__dump(void)
{
    static int dump = -1;
    if (dump < 0)
        dump = getenv("FUZZ_DUMP") != NULL;
    return dump;
}

static double fuzz__pick(fuzz_input *in, const double *table, size_t n)
{
    uint8_t b = fuzz_u8(in);
    if (b >= 240)
        return fuzz_double(in);
    return table[b % n];
}

static void fuzz__normalise(double v[3])
{
    double n = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (!(n > 0) || !isfinite(n)) {
        v[0] = 0, v[1] = 0, v[2] = 1;
        return;
    }
    v[0] /= n, v[1] /= n, v[2] /= n;
}

static void fuzz__cross(const double a[3], const double b[3], double out[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

/* Camera matrix: structured (position at a distance from the centre, looking
 * roughly at it or anywhere, rolled), or raw doubles. */
static void fuzz__camera_matrix(fuzz_input *in, double radius, double m[16])
{
    uint8_t mode = fuzz_u8(in);
    if ((mode & 7) == 7) {
        for (int i = 0; i < 16; i++)
            m[i] = (mode & 8) && (i >= 12) ? (i == 15 ? 1.0 : 0.0) : fuzz_double(in);
        return;
    }
    static const double altitude[] = {0.0, 0.5, 0.999, 1.0, 1.0 + 1e-12, 1.000001, 1.0001,
                                      1.001, 1.01, 1.1, 1.5, 2.0, 4.0, 30.0, 1e4, 1e12};
    double dist = radius * fuzz__pick(in, altitude, sizeof altitude / sizeof altitude[0]);
    double pos[3] = {fuzz_double_in(in, -1, 1), fuzz_double_in(in, -1, 1),
                     fuzz_double_in(in, -1, 1)};
    fuzz__normalise(pos);
    for (int i = 0; i < 3; i++)
        pos[i] *= dist;
    double forward[3];
    if (mode & 8) { /* anywhere */
        forward[0] = fuzz_double_in(in, -1, 1);
        forward[1] = fuzz_double_in(in, -1, 1);
        forward[2] = fuzz_double_in(in, -1, 1);
    } else { /* towards the centre, perturbed */
        double jitter = (mode & 16) ? 0.5 : 0.01;
        for (int i = 0; i < 3; i++)
            forward[i] = -pos[i] / (dist != 0 && isfinite(dist) ? dist : 1.0) +
                         jitter * fuzz_double_in(in, -1, 1);
    }
    fuzz__normalise(forward);
    double up_hint[3] = {fuzz_double_in(in, -1, 1), fuzz_double_in(in, -1, 1),
                         fuzz_double_in(in, -1, 1)};
    double right[3], up[3];
    fuzz__cross(forward, up_hint, right);
    fuzz__normalise(right);
    fuzz__cross(right, forward, up);
    fuzz__normalise(up);
    double scale = (mode & 32) ? fuzz_double(in) : 1.0; /* scaled/singular matrices */
    for (int r = 0; r < 3; r++) {
        m[r * 4 + 0] = right[r] * scale;
        m[r * 4 + 1] = up[r] * scale;
        m[r * 4 + 2] = -forward[r] * scale; /* camera looks down -Z */
        m[r * 4 + 3] = pos[r];
    }
    m[12] = m[13] = m[14] = 0.0;
    m[15] = 1.0;
}

static void fuzz__camera_desc(fuzz_input *in, double radius, plod_camera_desc *d)
{
    memset(d, 0, sizeof *d);
    fuzz__camera_matrix(in, radius, d->matrix_world);
    uint8_t flags = fuzz_u8(in);
    static const double lens[] = {50.0, 18.0, 200.0, 1.0, 1e-6, 0.0, -50.0, 1e6};
    static const double sensor[] = {36.0, 24.0, 1.0, 0.0, -1.0, 1e-9};
    static const double ortho[] = {7.0, 1e-3, 0.0, -1.0, 1e7, 1.0};
    static const double shift[] = {0.0, 0.1, -0.5, 2.0};
    static const double clip_start[] = {0.1, 1.0, 1e-6, 0.0, -1.0, 1e5};
    static const double clip_end[] = {1000.0, 1e8, 1e12, 0.05, 0.1};
    static const double aspect[] = {1.0, 2.0, 0.5, 0.0, -1.0};
    d->orthographic = flags & 1;
    d->lens = fuzz__pick(in, lens, 8);
    d->sensor_width = fuzz__pick(in, sensor, 6);
    d->sensor_height = fuzz__pick(in, sensor, 6);
    d->sensor_fit = (plod_sensor_fit)((flags >> 1) % 4); /* 3 is invalid */
    d->ortho_scale = fuzz__pick(in, ortho, 6) * ((flags & 8) ? radius : 1.0);
    d->shift_x = fuzz__pick(in, shift, 4);
    d->shift_y = fuzz__pick(in, shift, 4);
    d->clip_start = fuzz__pick(in, clip_start, 6);
    d->clip_end = fuzz__pick(in, clip_end, 5) * ((flags & 16) ? radius : 1.0);
    d->resolution_x = (flags & 32) ? (int)fuzz_u32(in) : fuzz_range(in, 1, 96);
    d->resolution_y = (flags & 64) ? (int)fuzz_u32(in) : fuzz_range(in, 1, 64);
    d->pixel_aspect_x = fuzz__pick(in, aspect, 5);
    d->pixel_aspect_y = fuzz__pick(in, aspect, 5);
}

static int fuzz__finite3(const double v[3])
{
    return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]);
}

static int fuzz__same(const void *a, const void *b, size_t bytes)
{
    return bytes == 0 || memcmp(a, b, bytes) == 0;
}

/* The session's cache persists over the execution's frames: with flag 0x20
 * the emission goes through it (budget: everything, or half the sectors
 * with 0x40) and, for small meshes, must equal an uncached emission bit for
 * bit. */
static void fuzz__emit(fuzz_input *in, plod_session *session, int finite_heights)
{
    const plod_camera *camera = plod_session_camera(session);
    const plod_refine_params *rp = plod_session_refine_params(session);
    uint8_t flags = fuzz_u8(in);
    int level = (flags & 0x80) ? fuzz_range(in, -2, 9) : fuzz_range(in, 0, 2);
    int visible_only = !(flags & 1);
    size_t count = 0;
    plod_refiner_sectors(plod_session_refiner(session), &count);
    size_t emitted = plod_session_sector_count(session, visible_only);
    FUZZ_CHECK(emitted <= count, "counted %zu of %zu", emitted, count);
    if (emitted > 256)
        return; /* keep an execution cheap */
    plod_mesh_params mp;
    plod_session_mesh_params(session, level, 0, (flags & 2) ? 2 : 1, &mp);
    if (finite_heights) /* non-finite maps are refused by plod_planet_check (NaN count, range) */
        FUZZ_CHECK(fuzz__finite3(mp.origin), "origin not finite");
    if (flags & 4) {
        mp.morph = 1;
        plod_session_set_morph_scale(&mp, camera, rp);
        if (flags & 8) {
            mp.morph_lod_scale = fuzz_double(in);
            mp.morph_level_rate = fuzz_double(in);
        }
        mp.morph_ramp = (flags & 16) ? fuzz_double(in) : 0.5;
    }
    size_t vbound = plod_mesh_vertex_bound(emitted, level);
    size_t tbound = plod_mesh_triangle_bound(emitted, level);
    int level_ok = level >= 0 && level <= PLOD_MAX_TEMPLATE_LEVEL;
    if (!level_ok)
        FUZZ_CHECK(vbound == 0 && tbound == 0, "bounds for level %d", level);
    if (vbound > 8385u)
        return; /* one level-7 sector (8385 vertices) fits; under ASan a vertex
                   costs ~1 us, and bigger meshes only repeat the same paths */
    size_t vcap = vbound ? vbound : 1, tcap = tbound ? tbound : 1;
    plod_mesh_buffers b = {
        malloc(3 * vcap * sizeof(float)), malloc(3 * vcap * sizeof(float)),
        malloc(2 * vcap * sizeof(float)), malloc(vcap * sizeof(float)),
        malloc(3 * tcap * sizeof(int32_t)), malloc(tcap * sizeof(int32_t)),
        malloc(tcap * sizeof(int32_t)),
    };
    FUZZ_CHECK(b.positions && b.normals && b.uv && b.morph && b.triangles &&
                   b.sector_level && b.face, "out of memory");
    size_t nv = 0, nt = 0, cached_before = 0;
    int use_cache = (flags & 0x20) != 0;
    if (use_cache) {
        plod_session_set_cache_max_bytes(session, (flags & 0x40) ? vbound * 22
                                                                 : PLOD_MESH_CACHE_DEFAULT_BYTES);
        plod_mesh_cache_stats before;
        plod_session_cache_stats(session, &before);
        cached_before = before.sectors;
    }
    plod_status s = plod_session_emit(session, &mp, visible_only, use_cache, &b, &nv, &nt);
    if (!level_ok)
        FUZZ_CHECK(s != PLOD_OK, "template level %d accepted", level);
    if (use_cache) {
        plod_mesh_cache_stats cst;
        plod_session_cache_stats(session, &cst);
        FUZZ_CHECK(cst.bytes <= cst.max_bytes, "cache holds %zu bytes, budget %zu", cst.bytes,
                   cst.max_bytes);
        if (s == PLOD_OK)
            FUZZ_CHECK(cst.hits + cst.misses == emitted && cst.sectors <= emitted,
                       "cache: %zu hits %zu misses %zu entries, %zu sectors", cst.hits,
                       cst.misses, cst.sectors, emitted);
        else /* refused parameters leave it alone; a failed sector empties it */
            FUZZ_CHECK(cst.sectors == 0 || cst.sectors == cached_before,
                       "failed emission left %zu cache entries (%zu before)", cst.sectors,
                       cached_before);
    }
    if (use_cache && s == PLOD_OK && vbound <= 1024) { /* 16 level-3 sectors */
        plod_mesh_buffers u = {
            malloc(3 * vcap * sizeof(float)), malloc(3 * vcap * sizeof(float)),
            malloc(2 * vcap * sizeof(float)), malloc(vcap * sizeof(float)),
            malloc(3 * tcap * sizeof(int32_t)), malloc(tcap * sizeof(int32_t)),
            malloc(tcap * sizeof(int32_t)),
        };
        FUZZ_CHECK(u.positions && u.normals && u.uv && u.morph && u.triangles &&
                       u.sector_level && u.face, "out of memory");
        size_t unv = 0, unt = 0;
        FUZZ_CHECK(plod_session_emit(session, &mp, visible_only, 0, &u, &unv, &unt) == PLOD_OK &&
                       unv == nv && unt == nt,
                   "uncached emission disagrees on status or counts");
        FUZZ_CHECK(fuzz__same(u.positions, b.positions, 12 * nv) &&
                       fuzz__same(u.normals, b.normals, 12 * nv) &&
                       fuzz__same(u.uv, b.uv, 8 * nv) && fuzz__same(u.morph, b.morph, 4 * nv) &&
                       fuzz__same(u.triangles, b.triangles, 12 * nt) &&
                       fuzz__same(u.sector_level, b.sector_level, 4 * nt) &&
                       fuzz__same(u.face, b.face, 4 * nt),
                   "cached emission differs from uncached (%zu vertices)", nv);
        free(u.positions), free(u.normals), free(u.uv), free(u.morph);
        free(u.triangles), free(u.sector_level), free(u.face);
    }
    if (use_cache && s == PLOD_OK) {
        /* again for the same eye, changed only: what the cache held was
         * just emitted, so only the sectors that did not fit come again */
        plod_mesh_cache_stats held, after;
        plod_session_cache_stats(session, &held);
        plod_mesh_params again = mp;
        again.changed_only = 1;
        size_t cnv = 0, cnt = 0;
        plod_status cs = plod_session_emit(session, &again, visible_only, 1, &b, &cnv, &cnt);
        plod_session_cache_stats(session, &after);
        FUZZ_CHECK(after.emissions == held.emissions + (cs != PLOD_ERR_BAD_PARAM),
                   "emissions %llu after %llu (status %d)", (unsigned long long)after.emissions,
                   (unsigned long long)held.emissions, cs);
        if (mp.morph) {
            FUZZ_CHECK(cs == PLOD_ERR_BAD_PARAM, "changed_only with morph: status %d", cs);
        } else {
            size_t per = plod_template_vertex_count(level);
            FUZZ_CHECK(cs == PLOD_OK && cnv == (emitted - held.sectors) * per &&
                           after.hits == held.sectors,
                       "changed_only emitted %zu vertices, %zu of %zu sectors were cached",
                       cnv, held.sectors, emitted);
        }
        s = plod_session_emit(session, &mp, visible_only, 1, &b, &nv, &nt); /* restore b */
        FUZZ_CHECK(s == PLOD_OK, "cached emission failed the second time");
    }
    if (s == PLOD_OK) {
        FUZZ_CHECK(nv == vbound && nt == tbound, "emitted %zu/%zu, bounds %zu/%zu", nv, nt,
                   vbound, tbound);
        for (size_t i = 0; i < 3 * nt; i++)
            FUZZ_CHECK(b.triangles[i] >= 0 && (size_t)b.triangles[i] < nv,
                       "triangle index %d of %zu", b.triangles[i], nv);
        if (finite_heights) {
            for (size_t i = 0; i < 3 * nv; i++)
                FUZZ_CHECK(isfinite(b.positions[i]) && isfinite(b.normals[i]),
                           "vertex value %zu not finite (%g, %g)", i, b.positions[i],
                           b.normals[i]);
            for (size_t i = 0; i < nv; i++)
                FUZZ_CHECK(isfinite(b.uv[2 * i]) && isfinite(b.uv[2 * i + 1]) &&
                               b.morph[i] >= 0 && b.morph[i] <= 1,
                           "uv/morph %zu: %g %g %g", i, b.uv[2 * i], b.uv[2 * i + 1],
                           b.morph[i]);
        }
        for (size_t i = 0; i < nt; i++)
            FUZZ_CHECK(b.face[i] >= 0 && b.face[i] < 6 && b.sector_level[i] >= 0 &&
                           b.sector_level[i] <= PLOD_MAX_LEVEL,
                       "face %d level %d", b.face[i], b.sector_level[i]);
    }
    free(b.positions), free(b.normals), free(b.uv), free(b.morph);
    free(b.triangles), free(b.sector_level), free(b.face);

    /* Instanced form over the visible sectors. */
    size_t visible = plod_session_sector_count(session, 1);
    float *corners = malloc(9 * (visible ? visible : 1) * sizeof(float));
    float *levels = malloc((visible ? visible : 1) * sizeof(float));
    float *morph = malloc((visible ? visible : 1) * sizeof(float));
    FUZZ_CHECK(corners && levels && morph, "out of memory");
    size_t instances = 0;
    s = plod_session_instances(session, &mp, corners, levels, morph, &instances);
    if (s == PLOD_OK) {
        FUZZ_CHECK(instances == visible, "%zu instances, %zu sectors", instances, visible);
        for (size_t i = 0; i < 9 * instances; i++)
            FUZZ_CHECK(isfinite(corners[i]) && fabsf(corners[i]) <= 1.0f, "corner %g", corners[i]);
    }
    free(corners), free(levels), free(morph);
}

static void fuzz__check_frame(const plod_refiner *refiner, const plod_planet *planet,
                              const plod_refine_params *rp, const plod_refine_stats *st)
{
    FUZZ_CHECK(st->sectors_after_backface <= st->sectors_total &&
                   st->sectors_after_frustum <= st->sectors_after_backface &&
                   st->sectors_after_budget <= st->sectors_after_frustum,
               "stats %zu %zu %zu %zu", st->sectors_total, st->sectors_after_backface,
               st->sectors_after_frustum, st->sectors_after_budget);
    if (rp->budget)
        FUZZ_CHECK(st->sectors_after_budget <= rp->budget, "%zu visible, budget %zu",
                   st->sectors_after_budget, rp->budget);
    if (rp->max_splits) /* one diamond (2 splits) always may */
        FUZZ_CHECK(st->splits <= (rp->max_splits > 2 ? rp->max_splits : 2),
                   "%zu splits, limit %zu", st->splits, rp->max_splits);
    else
        FUZZ_CHECK(!st->pending, "pending without a split limit");
    size_t count = 0;
    const plod_sector *sectors = plod_refiner_sectors(refiner, &count);
    FUZZ_CHECK(count == st->sectors_total, "%zu sectors, stats %zu", count, st->sectors_total);
    FUZZ_CHECK(count <= rp->max_sectors + 2, "%zu sectors over max_sectors %zu", count,
               rp->max_sectors);
    FUZZ_CHECK(st->max_level_reached <= rp->max_level, "level %d over max %d",
               st->max_level_reached, rp->max_level);
    size_t visible = 0;
    for (size_t i = 0; i < count; i++) {
        const plod_sector *s = &sectors[i];
        visible += (s->flags & PLOD_SECTOR_VISIBLE) != 0;
        FUZZ_CHECK(s->level <= rp->max_level && s->face < 6, "sector level %d face %d",
                   s->level, s->face);
        double c[3][3];
        plod_sector_corners(planet, s, c);
        for (int k = 0; k < 3; k++) {
            double len = sqrt(c[k][0] * c[k][0] + c[k][1] * c[k][1] + c[k][2] * c[k][2]);
            FUZZ_CHECK(fuzz__finite3(c[k]) && fabs(len - 1.0) < 1e-9,
                       "sector %zu corner %d length %g", i, k, len);
        }
    }
    FUZZ_CHECK(visible == st->sectors_after_budget, "%zu flagged visible, stats %zu", visible,
               st->sectors_after_budget);
}

static int fuzz__id_flags_cmp(const void *pa, const void *pb)
{
    const uint64_t *a = pa, *b = pb;
    return a[0] != b[0] ? (a[0] < b[0] ? -1 : 1) : (a[1] > b[1]) - (a[1] < b[1]);
}

/* (id, flags) of every leaf, sorted: the leaf set a frame decided. */
static uint64_t *fuzz__leaf_set(const plod_refiner *refiner, size_t *count)
{
    const plod_sector *sectors = plod_refiner_sectors(refiner, count);
    uint64_t *set = malloc(2 * (*count ? *count : 1) * sizeof *set);
    FUZZ_CHECK(set != NULL, "out of memory");
    for (size_t i = 0; i < *count; i++) {
        set[2 * i] = sectors[i].id;
        set[2 * i + 1] = sectors[i].flags;
    }
    qsort(set, *count, 2 * sizeof *set, fuzz__id_flags_cmp);
    return set;
}

/* Without hysteresis a frame depends on its camera alone: the incremental
 * result equals a fresh refiner's at the same camera (leaves, flags and the
 * canonical visible order), unless max_sectors truncated either or a split
 * limit (progressive refinement, history-dependent by design) is set. */
static void fuzz__check_history_free(const plod_refiner *incremental, const plod_planet *planet,
                                     const plod_camera *camera, const plod_refine_params *rp,
                                     const plod_refine_stats *st)
{
    if (rp->hysteresis || st->truncated || rp->max_splits)
        return;
    plod_refiner *fresh = NULL;
    FUZZ_CHECK(plod_refiner_create(&fresh, planet) == PLOD_OK, "fresh refiner");
    plod_refine_stats fst;
    FUZZ_CHECK(plod_refiner_update(fresh, camera, rp, &fst, NULL) == PLOD_OK,
               "a fresh refiner refused what the incremental one accepted");
    if (!fst.truncated) {
        size_t n = 0, m = 0;
        uint64_t *a = fuzz__leaf_set(incremental, &n), *b = fuzz__leaf_set(fresh, &m);
        FUZZ_CHECK(n == m && memcmp(a, b, 2 * n * sizeof *a) == 0,
                   "incremental refinement (%zu leaves) differs from a fresh one (%zu)", n, m);
        free(a), free(b);
        size_t va = 0, vb = 0;
        const uint32_t *oa = plod_refiner_visible(incremental, &va);
        const uint32_t *ob = plod_refiner_visible(fresh, &vb);
        const plod_sector *sa = plod_refiner_sectors(incremental, NULL);
        const plod_sector *sb = plod_refiner_sectors(fresh, NULL);
        FUZZ_CHECK(va == vb && va == st->sectors_after_budget, "visible %zu vs %zu", va, vb);
        for (size_t k = 0; k < va; k++)
            FUZZ_CHECK(sa[oa[k]].id == sb[ob[k]].id, "visible order differs at %zu", k);
    }
    plod_refiner_destroy(fresh);
}

/* Heights at points spread over sectors (corners, edge midpoints, centre)
 * lie inside the sectors' bounds (detail planets: the field's bounds). */
static void fuzz__check_bounds(const plod_refiner *refiner, const plod_planet *planet)
{
    size_t count = 0;
    const plod_sector *sectors = plod_refiner_sectors(refiner, &count);
    static const double w[7][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {.5, .5, 0},
                                   {0, .5, .5}, {.5, 0, .5}, {1 / 3., 1 / 3., 1 / 3.}};
    for (size_t i = 0; i < count && i < 24; i++) {
        const plod_sector *s = &sectors[i * (count / 24 + 1) % count];
        double c[3][3];
        plod_sector_corners(planet, s, c);
        for (int k = 0; k < 7; k++) {
            double p[3];
            for (int a = 0; a < 3; a++)
                p[a] = w[k][0] * c[0][a] + w[k][1] * c[1][a] + w[k][2] * c[2][a];
            double len = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
            for (int a = 0; a < 3; a++)
                p[a] /= len;
            double h = plod_planet_height(planet, p);
            if (!isfinite(h))
                continue;
            FUZZ_CHECK(h >= s->height_min && h <= s->height_max,
                       "height %.17g outside the sector's bounds [%.9g, %.9g] (level %d)", h,
                       (double)s->height_min, (double)s->height_max, s->level);
        }
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_input in = {data, size};
    uint8_t head = fuzz_u8(&in);

    /* ---- planet ---- */
    static const double radii[] = {6371000.0, 1737400.0, 1.0, 1e8, 100.0, 0.0, -1.0,
                                   0.999, 1e12, 1e8 + 1};
    static const double scales[] = {1.0, 8848.0, 0.0, 1e5, -1.0, 1e-3, 1e9};
    plod_planet planet;
    memset(&planet, 0, sizeof planet);
    planet.projection = (plod_projection)((head & 7) % (PLOD_PROJ_COUNT + 1)); /* 5 invalid */
    planet.radius = fuzz__pick(&in, radii, sizeof radii / sizeof radii[0]);
    planet.height_scale = fuzz__pick(&in, scales, sizeof scales / sizeof scales[0]);
    planet.has_sea_level = (head >> 3) & 1;
    planet.sea_level = fuzz_double(&in);
    int finite_heights = 1;
    plod_cubemap *map = NULL;
    if (head & 0x10) {
        uint8_t m = fuzz_u8(&in);
        int map_size = 1 + (m & 3);
        plod_texel_type type = (plod_texel_type)((m >> 2) % 3);
        plod_projection mp = (m & 0x20) ? (plod_projection)((m >> 6) % PLOD_PROJ_COUNT)
                                        : planet.projection;
        if (plod_cubemap_create(&map, mp, map_size, 1, type) == PLOD_OK) {
            for (int f = 0; f < plod_cubemap_face_count(map); f++) {
                uint8_t *texels = plod_cubemap_face_data(map, f);
                size_t bytes = plod_cubemap_face_bytes(map);
                for (size_t i = 0; i < bytes; i++)
                    texels[i] = fuzz_u8(&in);
                if (type == PLOD_TEXEL_F32)
                    for (size_t i = 0; i < bytes / 4; i++)
                        if (!isfinite(((float *)texels)[i]))
                            finite_heights = 0;
            }
            /* plod_planet requires the pyramid (plod_planet.h contract) */
            if (plod_cubemap_build_pyramid(map) == PLOD_OK)
                planet.heightmap = map;
        }
    }
    if (head & 0x20) { /* a datum: terrain below the radius, or absurd */
        static const double offsets[] = {-11000.0, 2500.0, -3.2e6, 1e9, -0.0, INFINITY, NAN};
        planet.height_offset = fuzz__pick(&in, offsets, sizeof offsets / sizeof offsets[0]);
    }
    if (!isfinite(planet.height_scale) || !isfinite(planet.height_offset))
        finite_heights = 0;
    plod_detail *detail = NULL;
    if (head & 0x20) { /* a detail field with random parameters */
        static const double amplitude[] = {300.0, 0.0, 1.0, 1e6, -1.0, 2e6};
        static const double roughness[] = {0.5, 0.0, 0.99, 1.0, -0.1};
        static const double largest[] = {0.0, 1.0, 1e4, -1.0};
        static const double smallest[] = {0.1, 1e-3, 10.0, 0.0, 1e9};
        static const double unit[] = {0.5, 0.0, 1.0, 2.0, -0.5};
        static const double craters[] = {0.0, 1.0, 4.0, 5.0};
        plod_detail_params dp;
        plod_detail_params_init(&dp);
        uint8_t b = fuzz_u8(&in);
        dp.style = (plod_detail_style)(b % (PLOD_DETAIL_STYLE_COUNT + 1)); /* one invalid */
        dp.amplitude = fuzz__pick(&in, amplitude, 6);
        dp.roughness = fuzz__pick(&in, roughness, 5);
        dp.largest = fuzz__pick(&in, largest, 4);
        dp.smallest = fuzz__pick(&in, smallest, 5);
        dp.seed = fuzz_u8(&in);
        dp.craters = fuzz__pick(&in, craters, 4);
        dp.crater_density = fuzz__pick(&in, unit, 5);
        dp.plains = fuzz__pick(&in, unit, 5);
        dp.relief = (b & 0x80) ? fuzz__pick(&in, largest, 4) : 0.0;
        int valid = (unsigned)dp.style < PLOD_DETAIL_STYLE_COUNT && dp.amplitude >= 0.0 &&
                    dp.amplitude <= 1e6 && dp.roughness >= 0.0 && dp.roughness < 1.0 &&
                    isfinite(dp.largest) && dp.largest >= 0.0 && isfinite(dp.smallest) &&
                    dp.smallest > 0.0 && dp.craters >= 0.0 && dp.craters <= 4.0 &&
                    dp.crater_density >= 0.0 && dp.crater_density <= 1.0 && dp.plains >= 0.0 &&
                    dp.plains <= 1.0 && isfinite(dp.relief) && dp.relief >= 0.0 &&
                    planet.radius >= 1.0 && isfinite(planet.radius);
        plod_status ds = plod_detail_create(&detail, &dp, &planet);
        FUZZ_CHECK(valid ? (ds == PLOD_OK || ds == PLOD_ERR_NO_MEMORY) : ds != PLOD_OK,
                   "detail parameters %s (%d): style %d amplitude %g roughness %g largest %g "
                   "smallest %g craters %g density %g plains %g relief %g radius %g",
                   valid ? "refused" : "accepted", ds, dp.style, dp.amplitude, dp.roughness,
                   dp.largest, dp.smallest, dp.craters, dp.crater_density, dp.plains, dp.relief,
                   planet.radius);
        if (ds == PLOD_OK) {
            FUZZ_CHECK(plod_detail_octave_count(detail) <= PLOD_DETAIL_MAX_OCTAVES, "octaves");
            planet.detail = detail;
        }
    }
    plod_status s = plod_planet_check(&planet, NULL);
    if (!isfinite(planet.height_offset))
        FUZZ_CHECK(s != PLOD_OK, "non-finite height offset accepted");
    if (!(planet.radius >= 1.0 && planet.radius <= 1e8) ||
        (unsigned)planet.projection >= PLOD_PROJ_COUNT)
        FUZZ_CHECK(s != PLOD_OK, "planet radius %g projection %d accepted", planet.radius,
                   planet.projection);
    plod_session *session = NULL;
    plod_status cs = plod_session_create(&session, &planet, NULL, NULL, 0);
    if (s != PLOD_OK) {
        FUZZ_CHECK(cs != PLOD_OK, "session accepted a planet plod_planet_check refused (%d)", s);
        plod_detail_destroy(detail);
        plod_cubemap_destroy(map);
        return 0;
    }
    if (cs != PLOD_OK) {
        plod_detail_destroy(detail);
        plod_cubemap_destroy(map);
        return 0;
    }
    const plod_refiner *refiner = plod_session_refiner(session);
    if (planet.heightmap && (fuzz_u8(&in) & 1)) {
        FUZZ_CHECK(plod_session_build_normals(session, 2) == PLOD_OK,
                   "normal map of a valid planet refused");
        planet = *plod_session_planet(session); /* the session's normal map */
        const plod_cubemap *normals = planet.normalmap;
        FUZZ_CHECK(normals != NULL, "no normal map built");
        FUZZ_CHECK(plod_cubemap_channels(normals) == 3 &&
                       plod_cubemap_size(normals) == plod_cubemap_size(planet.heightmap),
                   "normal map shape");
        for (int f = 0; f < plod_cubemap_face_count(normals); f++) {
            const uint16_t *t = plod_cubemap_face_data_const(normals, f);
            size_t n = plod_cubemap_face_bytes(normals) / 6;
            for (size_t i = 0; i < n && finite_heights; i++) {
                double x = t[3 * i] / 32767.5 - 1, y = t[3 * i + 1] / 32767.5 - 1,
                       z = t[3 * i + 2] / 32767.5 - 1;
                FUZZ_CHECK(fabs(x * x + y * y + z * z - 1.0) < 1e-3, "normal texel not unit");
            }
        }
        FUZZ_CHECK(plod_planet_check(&planet, NULL) == PLOD_OK,
                   "planet with its normal map refused");
    }
    if (fuzz__dump())
        fprintf(stderr, "planet: radius %.17g projection %d height_scale %.17g sea %d %.17g map %s\n",
                planet.radius, planet.projection, planet.height_scale, planet.has_sea_level,
                planet.sea_level, planet.heightmap ? "yes" : "no");
    double hmin = 0, hmax = 0;
    plod_planet_height_range(&planet, &hmin, &hmax);
    (void)plod_planet_height(&planet, (const double[3]){0, 0, 1});
    {
        /* the batched surface path (mesh rows) is the point path, bit for bit */
        double dirs[3 * 5], heights[5], normals[3 * 5];
        for (int i = 0; i < 5; i++) {
            double *d = dirs + 3 * i;
            for (int c = 0; c < 3; c++)
                d[c] = (double)(int8_t)fuzz_u8(&in) + (i == 4 ? 0.0 : 0.5);
            double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
            for (int c = 0; c < 3; c++)
                d[c] /= len;
        }
        plod_planet_surface_n(&planet, 5, dirs, heights, normals);
        for (int i = 0; i < 5; i++) {
            double normal[3];
            double h = plod_planet_surface(&planet, dirs + 3 * i, normal);
            FUZZ_CHECK(memcmp(&h, heights + i, sizeof h) == 0 &&
                           memcmp(normal, normals + 3 * i, sizeof normal) == 0,
                       "batched surface differs from the point path at %d", i);
        }
    }

    /* ---- refinement parameters ---- */
    plod_refine_params rp;
    plod_refine_params_default(&rp);
    uint8_t pf = fuzz_u8(&in);
    static const double pixel_error[] = {1.0, 0.5, 4.0, 64.0, 0.0, -1.0, 1e-9};
    static const double borders[] = {0.5, 0.25, 0.1, 1.0, 0.0, -0.5, 10.0};
    rp.criterion = (pf & 1) ? PLOD_CRITERION_SIDE_DISTANCE : PLOD_CRITERION_PIXEL_ERROR;
    rp.max_pixel_error = fuzz__pick(&in, pixel_error, 7);
    rp.split_border = fuzz__pick(&in, borders, 7);
    rp.merge_border = fuzz__pick(&in, borders, 7);
    rp.hysteresis = (pf >> 1) & 1;
    rp.backface_culling = (pf >> 2) & 1;
    rp.frustum_culling = (pf >> 3) & 1;
    rp.skip_sea = (pf >> 4) & 1;
    rp.template_level = fuzz_range(&in, 0, 2);
    rp.max_level = (pf & 0x20) ? fuzz_range(&in, -1, PLOD_MAX_LEVEL + 1) : fuzz_range(&in, 0, 10);
    rp.budget = (size_t)fuzz_range(&in, 0, 64);
    rp.max_sectors = (size_t)fuzz_range(&in, 8, 512);
    uint8_t progressive = fuzz_u8(&in); /* half the inputs: 1..64 splits a frame */
    rp.max_splits = (progressive & 0x80) ? 1 + (size_t)(progressive & 63) : 0;
    int frames = 1 + (pf >> 6) % MAX_CAMERAS;
    if (fuzz__dump())
        fprintf(stderr, "params: criterion %d pixel_error %.17g split %.17g merge %.17g "
                "hysteresis %d backface %d frustum %d skip_sea %d template %d max_level %d "
                "budget %zu max_sectors %zu max_splits %zu frames %d\n", rp.criterion,
                rp.max_pixel_error, rp.split_border, rp.merge_border, rp.hysteresis,
                rp.backface_culling, rp.frustum_culling, rp.skip_sea, rp.template_level,
                rp.max_level, rp.budget, rp.max_sectors, rp.max_splits, frames);

    for (int f = 0; f < frames; f++) {
        plod_camera_desc desc;
        fuzz__camera_desc(&in, planet.radius, &desc);
        plod_camera camera;
        s = plod_camera_init(&camera, &desc);
        if (fuzz__dump()) {
            fprintf(stderr, "camera %d (init %d): matrix {", f, s);
            for (int i = 0; i < 16; i++)
                fprintf(stderr, "%.17g%s", desc.matrix_world[i], i < 15 ? ", " : "}\n");
            fprintf(stderr, "  ortho %d lens %.17g sensor %.17g x %.17g fit %d ortho_scale %.17g "
                    "shift %.17g %.17g clip %.17g %.17g res %d x %d aspect %.17g %.17g\n",
                    desc.orthographic, desc.lens, desc.sensor_width, desc.sensor_height,
                    desc.sensor_fit, desc.ortho_scale, desc.shift_x, desc.shift_y,
                    desc.clip_start, desc.clip_end, desc.resolution_x, desc.resolution_y,
                    desc.pixel_aspect_x, desc.pixel_aspect_y);
        }
        int finite_desc = 1;
        for (int i = 0; i < 16; i++)
            finite_desc &= isfinite(desc.matrix_world[i]) != 0;
        if (!finite_desc || desc.resolution_x <= 0 || desc.resolution_y <= 0 ||
            !(desc.clip_start < desc.clip_end))
            FUZZ_CHECK(s != PLOD_OK, "bad camera accepted");
        if (s != PLOD_OK)
            continue;
        FUZZ_CHECK(fuzz__finite3(camera.position) && fuzz__finite3(camera.forward),
                   "camera derived values not finite");
        double clip0 = 0, clip1 = 0;
        plod_recommended_clip(&planet, &camera, &clip0, &clip1);
        /* Beyond ~1e150 m the horizon distance sqrt(2Rh + h^2) overflows to
         * inf (reported; the camera is accepted there). */
        double dist = sqrt(camera.position[0] * camera.position[0] +
                           camera.position[1] * camera.position[1] +
                           camera.position[2] * camera.position[2]);
        if (finite_heights)
            FUZZ_CHECK(!isnan(clip0) && !isnan(clip1) && clip0 > 0 && clip0 <= clip1 &&
                           (dist > 1e150 || (isfinite(clip1) && clip0 < clip1)),
                       "recommended clip %g %g at distance %g", clip0, clip1, dist);
        plod_refine_stats st;
        s = plod_session_refine(session, &camera, &rp, &st, NULL);
        int params_ok = rp.max_level >= 0 && rp.max_level <= PLOD_MAX_LEVEL;
        if (!params_ok)
            FUZZ_CHECK(s != PLOD_OK, "max_level %d accepted", rp.max_level);
        if (s != PLOD_OK)
            continue;
        fuzz__check_frame(refiner, &planet, &rp, &st);
        fuzz__check_history_free(refiner, &planet, &camera, &rp, &st);
        if (planet.detail && finite_heights)
            fuzz__check_bounds(refiner, &planet);
        if (f == frames - 1 || (fuzz_u8(&in) & 1))
            fuzz__emit(&in, session, finite_heights);
        uint8_t op = fuzz_u8(&in);
        if (op == 0xff) {
            plod_session_reset(session);
        } else if (op == 0xfe) { /* capacity ahead: results must not change */
            size_t want = (size_t)fuzz_u8(&in) * 64;
            FUZZ_CHECK(plod_session_reserve(session, want) == PLOD_OK, "reserve(%zu)", want);
            FUZZ_CHECK(plod_session_reserve(session, PLOD_REFINER_MAX_RESERVE + 1) ==
                           PLOD_ERR_BAD_PARAM, "reserve above the cap accepted");
            FUZZ_CHECK(plod_refiner_check(refiner) == PLOD_OK, "invariants after reserve");
        }
    }
    plod_session_destroy(session);
    plod_detail_destroy(detail);
    plod_cubemap_destroy(map);
    return 0;
}
