/* facetiles.c -- square cube-face tiles: bounds, neighbours, stitched or
 * skirted emission (plod_facetiles.h).
 */
#include "plod_facetiles.h"
#include "plod_projection.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

uint64_t plod_face_tile_key(int face, int level, int32_t x, int32_t y)
{
    return ((uint64_t)face << 56) | ((uint64_t)level << 50) | ((uint64_t)(uint32_t)y << 25) |
           (uint64_t)(uint32_t)x;
}

/* ---- the frame's view --------------------------------------------------------- */

plod_status plod_facetiles_check(const plod_planet *planet, const plod_camera *camera,
                                 const plod_refine_params *p, plod_error *error)
{
    if (!planet || !camera || !p)
        return plod_error_set(error, PLOD_ERR_NULL, "missing planet, camera or parameters");
    if (!plod_projection_is_cube(planet->projection))
        return plod_error_set(error, PLOD_ERR_BAD_PROJECTION,
                              "this LOD method tiles the cube faces: it needs a cube "
                              "projection (tsc, csc, qsc, spherified), not car");
    plod_status status = plod_refine_params_check(p, error);
    if (status != PLOD_OK)
        return status;
    double d = plod_norm3(camera->position);
    if (!isfinite(d) || !(d > 0.0))
        return plod_error_set(error, PLOD_ERR_BAD_COORD,
                              "camera position must be finite and off the centre");
    return PLOD_OK;
}

plod_status plod_facetiles_view_init(plod_facetiles_view *fv, const plod_planet *planet,
                                     const plod_camera *camera,
                                     const plod_refine_params *params)
{
    memset(fv, 0, sizeof *fv);
    if (!plod_projection_is_cube(planet->projection))
        return PLOD_ERR_BAD_PROJECTION;
    fv->planet = planet;
    plod_bound_setup_init(&fv->setup, planet);
    for (int f = 0; f < 6; f++) {
        int fr[3][3];
        plod_face_frame(f, fr);
        double c[3] = {fr[0][0], fr[0][1], fr[0][2]}, u[3] = {fr[1][0], fr[1][1], fr[1][2]},
               v[3] = {fr[2][0], fr[2][1], fr[2][2]}, x[3];
        plod_cross3(u, v, x);
        fv->mirrored[f] = plod_dot3(x, c) < 0.0;
    }
    /* as the HRTMR update sets its view (memos off: every test evaluated) */
    plod_bound_view *v = &fv->view;
    plod_bound_view_init(v, planet, fv->setup.occluder, camera, params,
                         plod_norm3(camera->position));
    v->coarsening = 1.0;
    if (params->criterion == PLOD_CRITERION_SIDE_DISTANCE) {
        v->split_mode = 0;
        v->split_scale = params->split_border;
    } else if (!camera->desc.orthographic) {
        v->split_mode = 1;
        v->split_scale = camera->pixels_per_radian / params->max_pixel_error;
    } else {
        v->split_mode = 2;
        v->split_scale = camera->pixels_per_metre / params->max_pixel_error;
    }
    v->memo_key = 0;
    return PLOD_OK;
}

/* ---- bounds ------------------------------------------------------------------- */

static double plod__tile_coord(int level, int32_t index)
{
    return ldexp((double)index, 1 - level) - 1.0;
}

void plod_facetiles_bounds(const plod_facetiles_view *fv, int face, int level, int32_t x,
                           int32_t y, plod_bound halves[2])
{
    /* the quad as two triangle sectors (corners 00, 10, 11 and 00, 11, 01) */
    const int32_t one = (int32_t)1 << PLOD_COORD_BITS;
    int32_t step = (int32_t)((int64_t)2 * one >> level);
    int32_t u0 = -one + x * step, v0 = -one + y * step;
    int32_t cu[4] = {u0, u0 + step, u0 + step, u0}, cv[4] = {v0, v0, v0 + step, v0 + step};
    plod_bound_corners corners;
    corners.known = 0;
    for (int k = 0; k < 4; k++)
        plod_face_to_dir(fv->planet->projection, face, ldexp((double)cu[k], -PLOD_COORD_BITS),
                         ldexp((double)cv[k], -PLOD_COORD_BITS), corners.dir[k]);
    static const int idx[2][3] = {{0, 1, 2}, {0, 2, 3}};
    for (int h = 0; h < 2; h++) {
        plod_sector s;
        memset(&s, 0, sizeof s);
        s.face = (uint8_t)face;
        for (int k = 0; k < 3; k++) {
            s.cu[k] = cu[idx[h][k]];
            s.cv[k] = cv[idx[h][k]];
        }
        plod_bound_build(&fv->setup, &s, &corners, idx[h], &halves[h]);
    }
}

int plod_facetiles_culled(const plod_facetiles_view *fv, const plod_bound halves[2])
{
    unsigned planes;
    return plod_bound_cull(&fv->view, &halves[0], 0, &planes) &&
           plod_bound_cull(&fv->view, &halves[1], 0, &planes);
}

double plod_facetiles_distance(const plod_facetiles_view *fv, const plod_bound halves[2])
{
    double a = plod_bound_distance(&fv->view, &halves[0]);
    double b = plod_bound_distance(&fv->view, &halves[1]);
    return a < b ? a : b;
}

double plod_facetiles_score(plod_facetiles_view *fv, const plod_bound halves[2],
                            int cells_log2)
{
    fv->view.error_scale = ldexp(1.0, -cells_log2);
    fv->view.error_scale2 = fv->view.error_scale * fv->view.error_scale;
    double best = 0.0;
    for (int h = 0; h < 2; h++) {
        double s = plod_bound_score(&fv->view, &halves[h],
                                    plod_bound_distance(&fv->view, &halves[h]));
        best = s > best ? s : best;
    }
    return best;
}

/* ---- neighbours ------------------------------------------------------------------ */

void plod_facetiles_across(int face, int level, int32_t x, int32_t y, int edge,
                           int *out_face, double *u, double *v)
{
    /* the edge midpoint, nudged a quarter tile across */
    double size = ldexp(1.0, 1 - level), nudge = 0.25 * size;
    double mu = plod__tile_coord(level, x) + 0.5 * size;
    double mv = plod__tile_coord(level, y) + 0.5 * size;
    double pu = mu, pv = mv;
    switch (edge) {
    case 0: pv = plod__tile_coord(level, y) - nudge; break;
    case 1: pu = plod__tile_coord(level, x + 1) + nudge; break;
    case 2: pv = plod__tile_coord(level, y + 1) + nudge; break;
    default: pu = plod__tile_coord(level, x) - nudge; break;
    }
    if (pu >= -1.0 && pu <= 1.0 && pv >= -1.0 && pv <= 1.0) {
        *out_face = face, *u = pu, *v = pv;
        return;
    }
    /* onto the next face: the cube point on the edge, in that face's frame */
    int fr[3][3];
    plod_face_frame(face, fr);
    double eu = edge == 1 ? 1.0 : (edge == 3 ? -1.0 : mu);
    double ev = edge == 2 ? 1.0 : (edge == 0 ? -1.0 : mv);
    double p[3], exit_axis[3];
    for (int k = 0; k < 3; k++) {
        p[k] = fr[0][k] + eu * fr[1][k] + ev * fr[2][k];
        exit_axis[k] = edge == 1 ? fr[1][k] : edge == 3 ? -fr[1][k]
                     : edge == 2 ? fr[2][k] : -fr[2][k];
    }
    for (int g = 0; g < 6; g++) {
        int gf[3][3];
        plod_face_frame(g, gf);
        if (gf[0][0] != exit_axis[0] || gf[0][1] != exit_axis[1] || gf[0][2] != exit_axis[2])
            continue;
        double gu = 0.0, gv = 0.0;
        for (int k = 0; k < 3; k++) {
            gu += p[k] * gf[1][k];
            gv += p[k] * gf[2][k];
        }
        /* the coordinate on the edge is +-1: move it inwards */
        if (fabs(gu) == 1.0)
            gu -= copysign(nudge, gu);
        else
            gv -= copysign(nudge, gv);
        *out_face = g, *u = gu, *v = gv;
        return;
    }
    *out_face = face, *u = mu, *v = mv; /* not reached: every edge has a face */
}

/* ---- emission ---------------------------------------------------------------------- */

static size_t plod__tile_vertex_bound(const plod_face_tile *t, int skirts)
{
    size_t n = (size_t)1 << t->cells_log2;
    return (n + 1) * (n + 1) + (skirts ? 4 * n : 0);
}

static size_t plod__tile_triangle_bound(const plod_face_tile *t, int skirts)
{
    size_t n = (size_t)1 << t->cells_log2;
    return 2 * n * n + (skirts ? 8 * n : 0);
}

void plod_facetiles_bound(const plod_face_tile *tiles, size_t count, int skirts,
                          size_t *vertices, size_t *triangles)
{
    size_t v = 0, t = 0;
    for (size_t i = 0; i < count; i++) {
        v += plod__tile_vertex_bound(&tiles[i], skirts);
        t += plod__tile_triangle_bound(&tiles[i], skirts);
    }
    if (v > (size_t)INT32_MAX || t > (size_t)INT32_MAX / 3)
        v = t = 0;
    *vertices = v;
    *triangles = t;
}

/* Grid point of the border strip of edge e: position p along the edge
 * (0..n, counter-clockwise) on the outer row (inner 0) or the next
 * (inner 1), as (i, j). */
static void plod__edge_point(int e, int n, int p, int inner, int *i, int *j)
{
    switch (e) {
    case 0: *i = p, *j = inner; break;
    case 1: *i = n - inner, *j = p; break;
    case 2: *i = n - p, *j = n - inner; break;
    default: *i = inner, *j = n - p; break;
    }
}

typedef struct plod__tile_job {
    const plod_mesh_params *params;
    const plod_facetiles_emission *options;
    const plod_mesh_sampler *sampler;
    const plod_face_tile *tiles;
    const size_t *vbase, *tbase;   /* planned slices (bounds) */
    size_t *vcount, *tcount;       /* what each tile wrote */
    const plod_mesh_buffers *out;
    int mirrored[6];
    atomic_int failed;
} plod__tile_job;

static void plod__add_triangle(int32_t *tri, size_t *t, int32_t a, int32_t b, int32_t c,
                               int mirrored)
{
    tri[3 * *t] = a;
    tri[3 * *t + 1] = mirrored ? c : b;
    tri[3 * *t + 2] = mirrored ? b : c;
    (*t)++;
}

/* One tile into its slice: vertices (grid, then skirt bottoms), triangles
 * (tile-local indices), then the unused vertices removed. */
static void plod__emit_tile(plod__tile_job *job, size_t index, double *dirs, double *world,
                            double *cells, int32_t *tri, int32_t *remap)
{
    const plod_face_tile *t = &job->tiles[index];
    const plod_facetiles_emission *opt = job->options;
    const plod_mesh_params *params = job->params;
    const plod_mesh_buffers *out = job->out;
    int n = 1 << t->cells_log2, row = n + 1, mirrored = job->mirrored[t->face];
    size_t grid = (size_t)row * (size_t)row;
    size_t nv = grid + (opt->skirts ? 4 * (size_t)n : 0);
    size_t v0 = job->vbase[index];
    int shift = 1 - t->level - t->cells_log2;
    for (int j = 0; j <= n; j++)
        for (int i = 0; i <= n; i++) {
            double u = ldexp((double)((int64_t)t->x * n + i), shift) - 1.0;
            double v = ldexp((double)((int64_t)t->y * n + j), shift) - 1.0;
            plod_face_to_dir(opt->projection, t->face, u, v, dirs + 3 * ((size_t)j * row + i));
        }
    /* skirt bottoms: the boundary's directions, counter-clockwise from (0, 0) */
    size_t s = grid;
    if (opt->skirts)
        for (int e = 0; e < 4; e++)
            for (int p = 0; p < n; p++, s++) {
                int i, j;
                plod__edge_point(e, n, p, 0, &i, &j);
                memcpy(dirs + 3 * s, dirs + 3 * ((size_t)j * row + i), 3 * sizeof(double));
            }
    for (size_t k = 0; k < nv; k++)
        cells[k] = opt->ortho_cell;
    double c[3] = {0.0, 0.0, 0.0};
    for (int k = 0; k < 3; k++)
        c[k] = dirs[k] + dirs[3 * (size_t)n + k] + dirs[3 * (grid - 1) + k] +
               dirs[3 * (grid - 1 - (size_t)n) + k];
    double lon_ref = c[0] != 0.0 || c[1] != 0.0 ? plod_mesh_atan2(c[1], c[0]) : 0.0;
    plod_mesh_sample(job->sampler, nv, dirs, opt->ortho_cell > 0.0 ? cells : NULL, lon_ref,
                     out->positions ? out->positions + 3 * v0 : NULL,
                     out->normals ? out->normals + 3 * v0 : NULL,
                     out->uv ? out->uv + 2 * v0 : NULL, out->detail ? out->detail + v0 : NULL,
                     world);
    float *pos = out->positions ? out->positions + 3 * v0 : NULL;
    if (opt->skirts && pos)
        for (size_t k = grid; k < nv; k++) { /* lowered along the direction */
            double r = plod_norm3(world + 3 * k), lowered = r - (double)t->skirt;
            for (int a = 0; a < 3; a++) {
                double p = dirs[3 * k + a] * lowered;
                world[3 * k + a] = p;
                pos[3 * k + a] = (float)(p - params->origin[a]);
            }
        }
    float *morph = out->morph ? out->morph + v0 : NULL;
    if (morph)
        for (size_t k = 0; k < nv; k++)
            morph[k] = 0.0f;
    if (opt->morph && pos && n >= 2) {
        /* odd vertices toward the coarser grid (Ulrich's vertex morph); held
         * on edges whose neighbour has another spacing */
        for (int j = 0; j <= n; j++)
            for (int i = 0; i <= n; i++) {
                if (!(i & 1) && !(j & 1))
                    continue;
                int on_edge = (j == 0 && (t->finer & 1 || t->coarser[0])) ||
                              (i == n && (t->finer & 2 || t->coarser[1])) ||
                              (j == n && (t->finer & 4 || t->coarser[2])) ||
                              (i == 0 && (t->finer & 8 || t->coarser[3]));
                if (on_edge)
                    continue;
                size_t k = (size_t)j * row + i, a, b;
                if ((i & 1) && !(j & 1))
                    a = k - 1, b = k + 1;
                else if (!(i & 1))
                    a = k - (size_t)row, b = k + (size_t)row;
                else
                    a = k - (size_t)row - 1, b = k + (size_t)row + 1;
                double m = plod_mesh_morph_factor(params, world + 3 * k);
                if (morph)
                    morph[k] = (float)m;
                if (m == 0.0)
                    continue;
                for (int q = 0; q < 3; q++) {
                    double p = (double)pos[3 * k + q];
                    double target = 0.5 * ((double)pos[3 * a + q] + (double)pos[3 * b + q]);
                    pos[3 * k + q] = (float)(p + m * (target - p));
                }
                if (out->normals) {
                    float *nr = out->normals + 3 * v0;
                    double nv3[3], len2 = 0.0;
                    for (int q = 0; q < 3; q++) {
                        double target = 0.5 * ((double)nr[3 * a + q] + (double)nr[3 * b + q]);
                        nv3[q] = (double)nr[3 * k + q] + m * (target - (double)nr[3 * k + q]);
                        len2 += nv3[q] * nv3[q];
                    }
                    double len = sqrt(len2);
                    if (len > 0.0)
                        for (int q = 0; q < 3; q++)
                            nr[3 * k + q] = (float)(nv3[q] / len);
                }
                if (out->detail) {
                    float *d = out->detail + v0;
                    double target = 0.5 * ((double)d[a] + (double)d[b]);
                    d[k] = (float)((double)d[k] + m * (target - (double)d[k]));
                }
            }
    }

    /* triangles, tile-local */
    size_t nt = 0;
#define PLOD__V(i, j) ((int32_t)((size_t)(j) * (size_t)row + (size_t)(i)))
    if (n == 1) {
        plod__add_triangle(tri, &nt, PLOD__V(0, 0), PLOD__V(1, 0), PLOD__V(1, 1), mirrored);
        plod__add_triangle(tri, &nt, PLOD__V(0, 0), PLOD__V(1, 1), PLOD__V(0, 1), mirrored);
    } else {
        for (int j = 1; j < n - 1; j++)
            for (int i = 1; i < n - 1; i++) {
                plod__add_triangle(tri, &nt, PLOD__V(i, j), PLOD__V(i + 1, j),
                                   PLOD__V(i + 1, j + 1), mirrored);
                plod__add_triangle(tri, &nt, PLOD__V(i, j), PLOD__V(i + 1, j + 1),
                                   PLOD__V(i, j + 1), mirrored);
            }
        for (int e = 0; e < 4; e++) {
            int k = opt->skirts ? 1 : 1 << t->coarser[e];
            int a = 0, b = 1; /* outer position a*k, inner position b */
            while (a * k < n || b < n - 1) {
                int oi, oj, ii, ij, pi, pj;
                plod__edge_point(e, n, a * k, 0, &oi, &oj);
                plod__edge_point(e, n, b, 1, &ii, &ij);
                if (a * k < n && (b == n - 1 || (a + 1) * k <= b)) {
                    plod__edge_point(e, n, (a + 1) * k, 0, &pi, &pj);
                    plod__add_triangle(tri, &nt, PLOD__V(oi, oj), PLOD__V(pi, pj),
                                       PLOD__V(ii, ij), mirrored);
                    a++;
                } else {
                    plod__edge_point(e, n, b + 1, 1, &pi, &pj);
                    plod__add_triangle(tri, &nt, PLOD__V(oi, oj), PLOD__V(pi, pj),
                                       PLOD__V(ii, ij), mirrored);
                    b++;
                }
            }
        }
    }
    if (opt->skirts) { /* a strip down from every boundary segment */
        for (int e = 0; e < 4; e++)
            for (int p = 0; p < n; p++) {
                int ai, aj, bi, bj;
                plod__edge_point(e, n, p, 0, &ai, &aj);
                plod__edge_point(e, n, p + 1, 0, &bi, &bj);
                int32_t da = (int32_t)(grid + (size_t)e * (size_t)n + (size_t)p);
                int32_t db = (int32_t)(grid + ((size_t)e * (size_t)n + (size_t)p + 1) %
                                                  (4 * (size_t)n));
                plod__add_triangle(tri, &nt, PLOD__V(ai, aj), da, PLOD__V(bi, bj), mirrored);
                plod__add_triangle(tri, &nt, PLOD__V(bi, bj), da, db, mirrored);
            }
    }
#undef PLOD__V
    /* lower-bound culling: triangles on the lower bound (the sea) left out */
    if (opt->drop_sea) {
        size_t kept = 0;
        double floor_r = params->planet->radius + opt->sea_level;
        for (size_t q = 0; q < nt; q++) {
            int low = 1;
            for (int c3 = 0; c3 < 3 && low; c3++)
                low = plod_norm3(world + 3 * (size_t)tri[3 * q + c3]) <= floor_r;
            if (low)
                continue;
            memmove(tri + 3 * kept, tri + 3 * q, 3 * sizeof(int32_t));
            kept++;
        }
        nt = kept;
    }
    /* unused vertices out (stitched edges, dropped triangles) */
    for (size_t k = 0; k < nv; k++)
        remap[k] = -1;
    for (size_t q = 0; q < 3 * nt; q++)
        remap[tri[q]] = 0;
    size_t used = 0;
    for (size_t k = 0; k < nv; k++) {
        if (remap[k] < 0)
            continue;
        remap[k] = (int32_t)used;
        if (used != k) {
            if (out->positions)
                memcpy(out->positions + 3 * (v0 + used), out->positions + 3 * (v0 + k),
                       3 * sizeof(float));
            if (out->normals)
                memcpy(out->normals + 3 * (v0 + used), out->normals + 3 * (v0 + k),
                       3 * sizeof(float));
            if (out->uv)
                memcpy(out->uv + 2 * (v0 + used), out->uv + 2 * (v0 + k), 2 * sizeof(float));
            if (out->detail)
                out->detail[v0 + used] = out->detail[v0 + k];
            if (out->morph)
                out->morph[v0 + used] = out->morph[v0 + k];
        }
        used++;
    }
    size_t t0 = job->tbase[index];
    if (out->triangles)
        for (size_t q = 0; q < 3 * nt; q++)
            out->triangles[3 * t0 + q] = remap[tri[q]];
    for (size_t q = 0; q < nt; q++) {
        if (out->sector_level)
            out->sector_level[t0 + q] = t->method_level;
        if (out->face)
            out->face[t0 + q] = t->face;
    }
    if (out->keys)
        out->keys[index] = t->key;
    job->vcount[index] = used;
    job->tcount[index] = nt;
}

static void plod__emit_range(void *context, size_t begin, size_t end)
{
    plod__tile_job *job = context;
    size_t need = 0, tris = 0;
    for (size_t i = begin; i < end; i++) {
        size_t v = plod__tile_vertex_bound(&job->tiles[i], job->options->skirts);
        size_t t = plod__tile_triangle_bound(&job->tiles[i], job->options->skirts);
        need = v > need ? v : need;
        tris = t > tris ? t : tris;
    }
    double *dirs = malloc(need * 7 * sizeof(double));
    int32_t *tri = malloc((3 * tris + need) * sizeof(int32_t));
    if (!dirs || !tri) {
        free(dirs);
        free(tri);
        atomic_store(&job->failed, 1);
        return;
    }
    for (size_t i = begin; i < end; i++)
        plod__emit_tile(job, i, dirs, dirs + 3 * need, dirs + 6 * need, tri, tri + 3 * tris);
    free(dirs);
    free(tri);
}

plod_status plod_facetiles_emit(const plod_mesh_params *params,
                                const plod_surface_source *surface,
                                const plod_facetiles_emission *options,
                                const plod_face_tile *tiles, size_t count,
                                const plod_mesh_buffers *out, size_t *vertex_count,
                                size_t *triangle_count)
{
    if (vertex_count)
        *vertex_count = 0;
    if (triangle_count)
        *triangle_count = 0;
    if (!params || !params->planet || !surface || !options || !out || (count && !tiles))
        return PLOD_ERR_NULL;
    if (params->threads < 1 || params->threads > PLOD_MESH_MAX_THREADS)
        return PLOD_ERR_BAD_PARAM;
    for (int c = 0; c < 3; c++)
        if (!isfinite(params->origin[c]) || !isfinite(params->eye[c]))
            return PLOD_ERR_BAD_COORD;
    size_t vb, tb;
    plod_facetiles_bound(tiles, count, options->skirts, &vb, &tb);
    if (count && (vb == 0 || tb == 0))
        return PLOD_ERR_BAD_PARAM;
    if (count == 0)
        return PLOD_OK;
    size_t *slots = malloc(4 * count * sizeof(size_t));
    if (!slots)
        return PLOD_ERR_NO_MEMORY;
    size_t *vbase = slots, *tbase = slots + count, *vcount = slots + 2 * count,
           *tcount = slots + 3 * count;
    size_t v = 0, t = 0;
    for (size_t i = 0; i < count; i++) {
        vbase[i] = v, tbase[i] = t;
        v += plod__tile_vertex_bound(&tiles[i], options->skirts);
        t += plod__tile_triangle_bound(&tiles[i], options->skirts);
    }
    plod_mesh_sampler sampler;
    plod_mesh_sampler_init(&sampler, params, surface);
    plod__tile_job job = {params, options, &sampler, tiles, vbase, tbase, vcount, tcount,
                          out, {0}, 0};
    atomic_init(&job.failed, 0);
    for (int f = 0; f < 6; f++) {
        int fr[3][3];
        plod_face_frame(f, fr);
        double c[3] = {fr[0][0], fr[0][1], fr[0][2]}, u[3] = {fr[1][0], fr[1][1], fr[1][2]},
               w[3] = {fr[2][0], fr[2][1], fr[2][2]}, x[3];
        plod_cross3(u, w, x);
        job.mirrored[f] = plod_dot3(x, c) < 0.0;
    }
    int threads = params->threads;
    if ((size_t)threads > count)
        threads = (int)count;
    if (params->workers)
        plod_workers_for(params->workers, count, 1, plod__emit_range, &job);
    else
        plod_parallel_for(count, threads, plod__emit_range, &job);
    if (atomic_load(&job.failed)) {
        free(slots);
        return PLOD_ERR_NO_MEMORY;
    }
    /* the slices packed in order, indices shifted with their vertices */
    size_t vw = 0, tw = 0;
    for (size_t i = 0; i < count; i++) {
        size_t vs = vbase[i], ts = tbase[i], vn = vcount[i], tn = tcount[i];
        if (vs != vw) {
            if (out->positions)
                memmove(out->positions + 3 * vw, out->positions + 3 * vs, 3 * vn * sizeof(float));
            if (out->normals)
                memmove(out->normals + 3 * vw, out->normals + 3 * vs, 3 * vn * sizeof(float));
            if (out->uv)
                memmove(out->uv + 2 * vw, out->uv + 2 * vs, 2 * vn * sizeof(float));
            if (out->morph)
                memmove(out->morph + vw, out->morph + vs, vn * sizeof(float));
            if (out->detail)
                memmove(out->detail + vw, out->detail + vs, vn * sizeof(float));
        }
        if (out->triangles)
            for (size_t q = 0; q < 3 * tn; q++)
                out->triangles[3 * tw + q] = out->triangles[3 * ts + q] + (int32_t)vw;
        if (ts != tw) {
            if (out->sector_level)
                memmove(out->sector_level + tw, out->sector_level + ts, tn * sizeof(int32_t));
            if (out->face)
                memmove(out->face + tw, out->face + ts, tn * sizeof(int32_t));
        }
        vw += vn;
        tw += tn;
    }
    free(slots);
    if (vertex_count)
        *vertex_count = vw;
    if (triangle_count)
        *triangle_count = tw;
    return PLOD_OK;
}
