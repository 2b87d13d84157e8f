/* cubemap.c -- cube maps: storage, seamless bilinear sampling, min/max
 * pyramid.
 *
 * Seams.  Each face has a frame (centre axis c, axis a_u along +u, axis a_v
 * along +v), read from the projection at creation: c = face_to_dir(f, 0, 0),
 * and the edge midpoint face_to_dir(f, 1, 0) = (c + a_u) / sqrt 2 in every
 * cube projection, likewise for a_v.  From the frames follows the exact edge
 * adjacency table: edge e of face f (0: u = -1, 1: u = +1, 2: v = -1,
 * 3: v = +1) touches face g whose centre is the edge's outward axis, at g's
 * edge whose outward axis is c_f; the along-edge coordinates agree or are
 * mirrored (`flip`).
 *
 * A bilinear tap one texel beyond a face edge ("ghost" texel) is the
 * neighbour's texel adjacent to the shared edge at the same along-edge
 * index.  The ghost diagonal to a face corner, where three faces meet, is
 * the average of the three corner texels A, B, C that meet there; the
 * exact corner then samples (A + B + C) / 3 from each of the three faces,
 * and along both edges near the corner the two faces use the same four
 * values with the same weights, so sampling is continuous everywhere.
 *
 * Pyramid.  Per face, level 0 holds channel 0 of each texel (raw value as
 * float: u8/u16 exact), level k the min and max of 2x2 cells of level k-1
 * (ceil sizes).  Range queries over-cover with the cells of a level chosen
 * so that at most 4x4 cells are read: conservative, O(1).
 */
#include "plod_cubemap.h"

#include <assert.h>
#include <float.h>
#include <stdint.h>
#include <math.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PLOD__MAX_LEVELS 20

typedef struct plod__edge_link {
    int face;  /* neighbour face */
    int edge;  /* neighbour's edge (0 u-, 1 u+, 2 v-, 3 v+) */
    int flip;  /* 1: along-edge index k maps to size-1-k */
} plod__edge_link;

struct plod_cubemap {
    plod_projection projection;
    int size;
    int width;   /* texels per face row: size, or 2*size for CAR */
    int height;  /* rows per face: size */
    int channels;
    int face_count;
    plod_texel_type type;
    size_t texel_bytes;
    size_t face_bytes;
    unsigned char *texels;
    int axes[PLOD_FACE_COUNT][3][3]; /* [face][c, a_u, a_v][xyz] in {-1,0,1} */
    plod__edge_link links[PLOD_FACE_COUNT][4];
    /* pyramid */
    int pyramid_valid;
    int levels;
    int level_width[PLOD__MAX_LEVELS];
    int level_height[PLOD__MAX_LEVELS];
    size_t level_offset[PLOD__MAX_LEVELS]; /* cells before the level, per face */
    size_t face_cells;                     /* cells of all levels, per face */
    float *pyramid_min;                    /* face_count * face_cells */
    float *pyramid_max;
    size_t nonfinite_texels;               /* NaN channel-0 texels (build_pyramid) */
};

/* ======================================================================== */
/* frames and adjacency                                                     */
/* ======================================================================== */

static int plod__axis_equal(const int a[3], const int b[3], int sign)
{
    return a[0] == sign * b[0] && a[1] == sign * b[1] && a[2] == sign * b[2];
}

/* The faces' frames (plod_face_frame) and, from them, which edge of which
 * face lies across each face edge. */
static plod_status plod__derive_frames(plod_cubemap *m)
{
    for (int f = 0; f < PLOD_FACE_COUNT; f++)
        plod_face_frame(f, m->axes[f]);
    for (int f = 0; f < PLOD_FACE_COUNT; f++) {
        for (int e = 0; e < 4; e++) {
            int sign = (e & 1) ? 1 : -1;
            const int *outward = m->axes[f][e < 2 ? 1 : 2];
            const int *along = m->axes[f][e < 2 ? 2 : 1];
            plod__edge_link link = {-1, -1, 0};
            for (int g = 0; g < PLOD_FACE_COUNT; g++)
                if (plod__axis_equal(m->axes[g][0], outward, sign))
                    link.face = g;
            if (link.face < 0)
                return PLOD_ERR_BAD_PROJECTION;
            int g = link.face;
            for (int e2 = 0; e2 < 4; e2++) {
                int sign2 = (e2 & 1) ? 1 : -1;
                if (plod__axis_equal(m->axes[g][e2 < 2 ? 1 : 2], m->axes[f][0], sign2))
                    link.edge = e2;
            }
            if (link.edge < 0)
                return PLOD_ERR_BAD_PROJECTION;
            const int *along2 = m->axes[g][link.edge < 2 ? 2 : 1];
            if (plod__axis_equal(along2, along, 1))
                link.flip = 0;
            else if (plod__axis_equal(along2, along, -1))
                link.flip = 1;
            else
                return PLOD_ERR_BAD_PROJECTION;
            m->links[f][e] = link;
        }
    }
    return PLOD_OK;
}

/* ======================================================================== */
/* create / destroy / queries                                               */
/* ======================================================================== */

plod_status plod_cubemap_create(plod_cubemap **out, plod_projection projection, int size,
                                int channels, plod_texel_type type)
{
    if (!out)
        return PLOD_ERR_NULL;
    *out = NULL;
    if ((unsigned)projection >= PLOD_PROJ_COUNT)
        return PLOD_ERR_BAD_PROJECTION;
    if (size < 1 || size > PLOD_CUBEMAP_MAX_SIZE || channels < 1 || channels > 4 ||
        (unsigned)type >= PLOD_TEXEL_TYPE_COUNT)
        return PLOD_ERR_BAD_PARAM;
    plod_cubemap *m = calloc(1, sizeof *m);
    if (!m)
        return PLOD_ERR_NO_MEMORY;
    m->projection = projection;
    m->size = size;
    m->channels = channels;
    m->type = type;
    m->face_count = plod_projection_is_cube(projection) ? PLOD_FACE_COUNT : 1;
    m->width = m->face_count == 1 ? 2 * size : size;
    m->height = size;
    m->texel_bytes = (type == PLOD_TEXEL_U8 ? 1 : type == PLOD_TEXEL_U16 ? 2 : 4) * (size_t)channels;
    m->face_bytes = (size_t)m->width * (size_t)m->height * m->texel_bytes;
    if (m->face_bytes / m->texel_bytes / (size_t)m->width != (size_t)m->height ||
        m->face_bytes > SIZE_MAX / (size_t)m->face_count) {
        free(m);
        return PLOD_ERR_NO_MEMORY;
    }
    if (m->face_count == PLOD_FACE_COUNT) {
        plod_status s = plod__derive_frames(m);
        if (s != PLOD_OK) {
            free(m);
            return s;
        }
    }
    m->texels = calloc((size_t)m->face_count, m->face_bytes);
    if (!m->texels) {
        free(m);
        return PLOD_ERR_NO_MEMORY;
    }
    *out = m;
    return PLOD_OK;
}

void plod_cubemap_destroy(plod_cubemap *m)
{
    if (!m)
        return;
    free(m->texels);
    free(m->pyramid_min);
    free(m->pyramid_max);
    free(m);
}

plod_projection plod_cubemap_projection(const plod_cubemap *m) { return m->projection; }
int plod_cubemap_size(const plod_cubemap *m) { return m->size; }
int plod_cubemap_channels(const plod_cubemap *m) { return m->channels; }
int plod_cubemap_face_count(const plod_cubemap *m) { return m->face_count; }
int plod_cubemap_face_width(const plod_cubemap *m) { return m->width; }
int plod_cubemap_face_height(const plod_cubemap *m) { return m->height; }
plod_texel_type plod_cubemap_texel_type(const plod_cubemap *m) { return m->type; }
size_t plod_cubemap_face_bytes(const plod_cubemap *m) { return m->face_bytes; }

void *plod_cubemap_face_data(plod_cubemap *m, int face)
{
    assert(face >= 0 && face < m->face_count);
    m->pyramid_valid = 0; /* the caller may write texels */
    return m->texels + (size_t)face * m->face_bytes;
}

const void *plod_cubemap_face_data_const(const plod_cubemap *m, int face)
{
    assert(face >= 0 && face < m->face_count);
    return m->texels + (size_t)face * m->face_bytes;
}

/* ======================================================================== */
/* texel fetch                                                              */
/* ======================================================================== */

static double plod__scale(plod_texel_type type)
{
    return type == PLOD_TEXEL_U8 ? 1.0 / 255.0 : type == PLOD_TEXEL_U16 ? 1.0 / 65535.0 : 1.0;
}

/* Raw channel values of an in-face texel, normalised, into out[channels]. */
static void plod__texel(const plod_cubemap *m, int face, int i, int j, double *out)
{
    assert(i >= 0 && i < m->width && j >= 0 && j < m->height);
    size_t index = ((size_t)j * (size_t)m->width + (size_t)i) * (size_t)m->channels;
    const unsigned char *base = m->texels + (size_t)face * m->face_bytes;
    switch (m->type) {
    case PLOD_TEXEL_U8:
        for (int c = 0; c < m->channels; c++)
            out[c] = base[index + (size_t)c] * (1.0 / 255.0);
        break;
    case PLOD_TEXEL_U16:
        for (int c = 0; c < m->channels; c++)
            out[c] = ((const uint16_t *)base)[index + (size_t)c] * (1.0 / 65535.0);
        break;
    default:
        for (int c = 0; c < m->channels; c++)
            out[c] = ((const float *)base)[index + (size_t)c];
        break;
    }
}

/* Texel adjacent to edge `edge` of face f at along-edge index k, seen from
 * the neighbour: writes the neighbour's face and in-face indices. */
static void plod__across(const plod_cubemap *m, int f, int edge, int k, int *g, int *gi, int *gj)
{
    const plod__edge_link *link = &m->links[f][edge];
    int n = m->size;
    int along = link->flip ? n - 1 - k : k;
    *g = link->face;
    switch (link->edge) {
    case 0: *gi = 0; *gj = along; break;
    case 1: *gi = n - 1; *gj = along; break;
    case 2: *gi = along; *gj = 0; break;
    default: *gi = along; *gj = n - 1; break;
    }
}

/* Texel (i, j) of a cube face with i, j in [-1, size]: ghosts from the
 * neighbours, corner ghosts as the average of the three corner texels. */
static void plod__fetch_cube(const plod_cubemap *m, int f, int i, int j, double *out)
{
    int n = m->size;
    int out_i = i < 0 || i >= n;
    int out_j = j < 0 || j >= n;
    if (!out_i && !out_j) {
        plod__texel(m, f, i, j, out);
        return;
    }
    int g, gi, gj;
    if (out_i && !out_j) {
        plod__across(m, f, i < 0 ? 0 : 1, j, &g, &gi, &gj);
        plod__texel(m, g, gi, gj, out);
        return;
    }
    if (!out_i && out_j) {
        plod__across(m, f, j < 0 ? 2 : 3, i, &g, &gi, &gj);
        plod__texel(m, g, gi, gj, out);
        return;
    }
    int ic = i < 0 ? 0 : n - 1;
    int jc = j < 0 ? 0 : n - 1;
    double a[4], b[4], c[4];
    plod__texel(m, f, ic, jc, a);
    plod__across(m, f, i < 0 ? 0 : 1, jc, &g, &gi, &gj);
    plod__texel(m, g, gi, gj, b);
    plod__across(m, f, j < 0 ? 2 : 3, ic, &g, &gi, &gj);
    plod__texel(m, g, gi, gj, c);
    for (int k = 0; k < m->channels; k++)
        out[k] = (a[k] + b[k] + c[k]) / 3.0;
}

/* CAR texel indices with wrap in longitude and reflection across the
 * poles, into the map. */
static void plod__car_wrap(const plod_cubemap *m, int *i, int *j)
{
    int w = m->width, h = m->height;
    if (*j < 0 || *j >= h) {
        *j = *j < 0 ? -1 - *j : 2 * h - 1 - *j;
        *i += w / 2;
    }
    if (*j < 0)
        *j = 0;
    if (*j >= h)
        *j = h - 1;
    *i %= w;
    if (*i < 0)
        *i += w;
}

static void plod__fetch_car(const plod_cubemap *m, int i, int j, double *out)
{
    plod__car_wrap(m, &i, &j);
    plod__texel(m, 0, i, j, out);
}

/* ======================================================================== */
/* sampling                                                                 */
/* ======================================================================== */

static void plod__nan(const plod_cubemap *m, float *out)
{
    for (int c = 0; c < m->channels; c++)
        out[c] = NAN;
}

/* Lerps four taps (i0,j0), (i0+1,j0), (i0,j0+1), (i0+1,j0+1). */
static inline __attribute__((always_inline)) void
plod__lerp_taps(const double tap[4][4], double wu, double wv, int channels, double *acc)
{
    for (int c = 0; c < channels; c++) {
        double bottom = tap[0][c] + wu * (tap[1][c] - tap[0][c]);
        double top = tap[2][c] + wu * (tap[3][c] - tap[2][c]);
        acc[c] = bottom + wv * (top - bottom);
    }
}

static inline __attribute__((always_inline)) int plod__interior(const plod_cubemap *m, int i0,
                                                                int j0)
{
    return i0 >= 0 && j0 >= 0 && i0 + 1 < m->width && j0 + 1 < m->height;
}

/* Interior samples (nearly all): the four taps straight from the face,
 * converted exactly as plod__texel does.  Batch loops pass a constant type
 * and channel count, so the compiler drops the switch and unrolls the taps;
 * plod__bilinear passes the map's own. */
static inline __attribute__((always_inline)) void
plod__lerp_interior(const plod_cubemap *m, int face, int i0, int j0, double wu, double wv,
                    double *acc, plod_texel_type type, int channels)
{
    size_t row = (size_t)m->width * (size_t)channels;
    size_t at = ((size_t)j0 * (size_t)m->width + (size_t)i0) * (size_t)channels;
    const unsigned char *base = m->texels + (size_t)face * m->face_bytes;
    size_t offset[4] = {at, at + (size_t)channels, at + row, at + row + (size_t)channels};
    double tap[4][4];
    for (int k = 0; k < 4; k++)
        for (int c = 0; c < channels; c++) {
            size_t index = offset[k] + (size_t)c;
            switch (type) {
            case PLOD_TEXEL_U8: tap[k][c] = base[index] * (1.0 / 255.0); break;
            case PLOD_TEXEL_U16:
                tap[k][c] = ((const uint16_t *)base)[index] * (1.0 / 65535.0);
                break;
            default: tap[k][c] = ((const float *)base)[index]; break;
            }
        }
    plod__lerp_taps((const double (*)[4])tap, wu, wv, channels, acc);
}

static void plod__bilinear(const plod_cubemap *m, int face, double s, double t, double *acc)
{
    double fi = floor(s), fj = floor(t);
    double wu = s - fi, wv = t - fj;
    int i0 = (int)fi, j0 = (int)fj;
    if (plod__interior(m, i0, j0)) {
        plod__lerp_interior(m, face, i0, j0, wu, wv, acc, m->type, m->channels);
        return;
    }
    double tap[4][4];
    if (m->face_count == PLOD_FACE_COUNT) {
        plod__fetch_cube(m, face, i0, j0, tap[0]);
        plod__fetch_cube(m, face, i0 + 1, j0, tap[1]);
        plod__fetch_cube(m, face, i0, j0 + 1, tap[2]);
        plod__fetch_cube(m, face, i0 + 1, j0 + 1, tap[3]);
    } else {
        plod__fetch_car(m, i0, j0, tap[0]);
        plod__fetch_car(m, i0 + 1, j0, tap[1]);
        plod__fetch_car(m, i0, j0 + 1, tap[2]);
        plod__fetch_car(m, i0 + 1, j0 + 1, tap[3]);
    }
    plod__lerp_taps((const double (*)[4])tap, wu, wv, m->channels, acc);
}

static double plod__clamp_unit(double x)
{
    return x < -1.0 ? -1.0 : x > 1.0 ? 1.0 : x;
}

/* Texel coordinates (s, t) of face point (u, v), clamped to the face;
 * 0 for a bad face or non-finite u, v. */
static inline __attribute__((always_inline)) int
plod__face_point(const plod_cubemap *m, int face, double u, double v, double *s, double *t)
{
    if (!(isfinite(u) && isfinite(v)) || face < 0 || face >= m->face_count)
        return 0;
    u = plod__clamp_unit(u);
    v = plod__clamp_unit(v);
    *s = (u + 1.0) * 0.5 * m->width - 0.5;
    *t = (v + 1.0) * 0.5 * m->height - 0.5;
    return 1;
}

static int plod__sample_face_d(const plod_cubemap *m, int face, double u, double v, double *acc)
{
    double s, t;
    if (!plod__face_point(m, face, u, v, &s, &t))
        return 0;
    plod__bilinear(m, face, s, t, acc);
    return 1;
}

void plod_cubemap_sample_face(const plod_cubemap *m, int face, double u, double v, float *out)
{
    double acc[4];
    if (!plod__sample_face_d(m, face, u, v, acc)) {
        plod__nan(m, out);
        return;
    }
    for (int c = 0; c < m->channels; c++)
        out[c] = (float)acc[c];
}

int plod_cubemap_locate(const plod_cubemap *m, const double dir[3], int *face, double *u,
                        double *v)
{
    if (!(isfinite(dir[0]) && isfinite(dir[1]) && isfinite(dir[2])) ||
        (dir[0] == 0.0 && dir[1] == 0.0 && dir[2] == 0.0))
        return 0;
    if (m->face_count == 1) {
        double lon = atan2(dir[1], dir[0]);
        double lat = atan2(dir[2], hypot(dir[0], dir[1]));
        *face = 0;
        *u = lon / PLOD_PI;
        *v = lat / (0.5 * PLOD_PI);
        return 1;
    }
    return plod_dir_to_face(m->projection, dir, face, u, v) == PLOD_OK;
}

int plod_cubemap_sample_face_d(const plod_cubemap *m, int face, double u, double v,
                               double *out)
{
    return plod__sample_face_d(m, face, u, v, out);
}

void plod_cubemap_locate_n(const plod_cubemap *m, size_t n, const double *dirs, int *faces,
                           double *u, double *v)
{
    if (m->face_count == 1) {
        for (size_t i = 0; i < n; i++)
            if (!plod_cubemap_locate(m, dirs + 3 * i, faces + i, u + i, v + i))
                faces[i] = -1;
        return;
    }
    /* the projection's own batch loop: the same per-point kernel, inlined */
    (void)plod_dir_to_face_n(m->projection, n, dirs, faces, u, v, NULL);
}

/* Batches are sampled a block at a time in three passes: where each point
 * falls and its weights (a lane loop), the taps of the points inside a
 * face's texel grid (gathered), and their blend (a lane loop); points on
 * a face's last row or column go through plod__bilinear, unlocated ones
 * get NaN.  Every operation is plod__bilinear's, so the same bits. */
enum { PLOD__SAMPLE_BLOCK = 64 };

typedef struct plod__sample_plan {
    int64_t at[PLOD__SAMPLE_BLOCK]; /* texel of the first tap, from the map's start; -1: not interior */
    int valid[PLOD__SAMPLE_BLOCK];  /* located on a face */
    double s[PLOD__SAMPLE_BLOCK], t[PLOD__SAMPLE_BLOCK];   /* texel coordinates */
    double wu[PLOD__SAMPLE_BLOCK], wv[PLOD__SAMPLE_BLOCK]; /* weights */
} plod__sample_plan;

/* ghosts: 1 for a grid whose faces carry a ring of their neighbours'
 * texels (a bundle): `at` then counts in it and covers the faces' last
 * rows and columns too, all but the cells at a face's corners (whose
 * corner ghost is an average, plod__fetch_cube). */
PLOD_LANE_CLONES PLOD_LANE_LOOPS static void
plod__plan_samples(int width, int height, int face_count, int ghosts, size_t n,
                   const int *faces, const double *u, const double *v, plod__sample_plan *plan)
{
    int64_t stride = (int64_t)width + 2 * ghosts;
    int64_t face_texels = stride * ((int64_t)height + 2 * ghosts);
    for (size_t i = 0; i < n; i++) {
        double uu = u[i], vv = v[i];
        int face = faces[i];
        /* plod__face_point: finite, on a face, clamped */
        int valid = (fabs(uu) <= DBL_MAX) & (fabs(vv) <= DBL_MAX) & (face >= 0) &
                    (face < face_count);
        uu = uu < -1.0 ? -1.0 : (uu > 1.0 ? 1.0 : uu);
        vv = vv < -1.0 ? -1.0 : (vv > 1.0 ? 1.0 : vv);
        double s = valid ? (uu + 1.0) * 0.5 * width - 0.5 : 0.0;
        double t = valid ? (vv + 1.0) * 0.5 * height - 0.5 : 0.0;
        double fi = floor(s), fj = floor(t);
        int i0 = (int)fi, j0 = (int)fj;
        int edge_i = (i0 < 0) | (i0 + 1 >= width), edge_j = (j0 < 0) | (j0 + 1 >= height);
        int interior = (i0 >= -ghosts) & (j0 >= -ghosts) & (i0 + 1 < width + ghosts) &
                       (j0 + 1 < height + ghosts) & !(edge_i & edge_j & (ghosts > 0));
        plan->at[i] = valid & interior ? (int64_t)face * face_texels +
                                             (int64_t)(j0 + ghosts) * stride + (i0 + ghosts)
                                       : -1;
        plan->valid[i] = valid;
        plan->s[i] = s, plan->t[i] = t;
        plan->wu[i] = s - fi, plan->wv[i] = t - fj;
    }
}

/* The four taps of channel c at the planned interior points, tap[k][i]
 * (k: (i0, j0), (i0 + 1, j0), (i0, j0 + 1), (i0 + 1, j0 + 1)), converted
 * as plod__lerp_interior does; the other points get 0. */
static inline __attribute__((always_inline)) void
plod__gather_taps(const plod_cubemap *m, size_t n, const plod__sample_plan *plan, int c,
                  plod_texel_type type, int channels, double tap[4][PLOD__SAMPLE_BLOCK])
{
    size_t row = (size_t)m->width * (size_t)channels;
    for (size_t i = 0; i < n; i++) {
        if (plan->at[i] < 0) {
            tap[0][i] = tap[1][i] = tap[2][i] = tap[3][i] = 0.0;
            continue;
        }
        size_t at = (size_t)plan->at[i] * (size_t)channels + (size_t)c;
        size_t offset[4] = {at, at + (size_t)channels, at + row, at + row + (size_t)channels};
        for (int k = 0; k < 4; k++)
            switch (type) {
            case PLOD_TEXEL_U8: tap[k][i] = m->texels[offset[k]] * (1.0 / 255.0); break;
            case PLOD_TEXEL_U16:
                tap[k][i] = ((const uint16_t *)m->texels)[offset[k]] * (1.0 / 65535.0);
                break;
            default: tap[k][i] = ((const float *)m->texels)[offset[k]]; break;
            }
    }
}

/* plod__lerp_taps at every planned interior point, into out[i * stride] */
PLOD_LANE_CLONES PLOD_LANE_LOOPS static void
plod__blend_taps(size_t n, const plod__sample_plan *plan, const double tap[4][PLOD__SAMPLE_BLOCK],
                 double *out, size_t stride)
{
    for (size_t i = 0; i < n; i++) {
        double wu = plan->wu[i], wv = plan->wv[i];
        double bottom = tap[0][i] + wu * (tap[1][i] - tap[0][i]);
        double top = tap[2][i] + wu * (tap[3][i] - tap[2][i]);
        double value = bottom + wv * (top - bottom);
        out[i * stride] = plan->at[i] >= 0 ? value : out[i * stride];
    }
}

/* Points the blend leaves alone: NaN where unlocated, plod__bilinear on a
 * face's border. */
static void plod__sample_rest(const plod_cubemap *m, size_t n, const int *faces,
                              const plod__sample_plan *plan, double *out)
{
    for (size_t i = 0; i < n; i++) {
        if (plan->at[i] >= 0)
            continue;
        double *acc = out + i * (size_t)m->channels;
        if (!plan->valid[i])
            for (int c = 0; c < m->channels; c++)
                acc[c] = NAN;
        else
            plod__bilinear(m, faces[i], plan->s[i], plan->t[i], acc);
    }
}

/* One map's channels over a planned block. */
static inline __attribute__((always_inline)) void
plod__sample_block(const plod_cubemap *m, size_t n, const int *faces,
                   const plod__sample_plan *plan, plod_texel_type type, int channels,
                   double *out)
{
    double tap[4][PLOD__SAMPLE_BLOCK];
    plod__sample_rest(m, n, faces, plan, out);
    for (int c = 0; c < channels; c++) {
        plod__gather_taps(m, n, plan, c, type, channels, tap);
        plod__blend_taps(n, plan, (const double (*)[PLOD__SAMPLE_BLOCK])tap, out + c,
                         (size_t)channels);
    }
}

#define PLOD__SAMPLE_LOOP(TYPE, CHANNELS)                                                \
    for (size_t first = 0; first < n; first += PLOD__SAMPLE_BLOCK) {                     \
        size_t count = n - first < PLOD__SAMPLE_BLOCK ? n - first : PLOD__SAMPLE_BLOCK;   \
        plod__plan_samples(m->width, m->height, m->face_count, 0, count, faces + first,   \
                           u + first, v + first, &plan);                                  \
        plod__sample_block(m, count, faces + first, &plan, (TYPE), (CHANNELS),            \
                           out + first * (size_t)(CHANNELS));                             \
    }

void plod_cubemap_sample_face_n(const plod_cubemap *m, size_t n, const int *faces,
                                const double *u, const double *v, double *out)
{
    /* the layouts meshes sample per vertex (heights, u16x3 normals) get
     * their own loops; any other layout takes the generic one */
    plod__sample_plan plan;
    if (m->type == PLOD_TEXEL_U8 && m->channels == 1) {
        PLOD__SAMPLE_LOOP(PLOD_TEXEL_U8, 1)
    } else if (m->type == PLOD_TEXEL_U16 && m->channels == 1) {
        PLOD__SAMPLE_LOOP(PLOD_TEXEL_U16, 1)
    } else if (m->type == PLOD_TEXEL_F32 && m->channels == 1) {
        PLOD__SAMPLE_LOOP(PLOD_TEXEL_F32, 1)
    } else if (m->type == PLOD_TEXEL_U16 && m->channels == 3) {
        PLOD__SAMPLE_LOOP(PLOD_TEXEL_U16, 3)
    } else {
        PLOD__SAMPLE_LOOP(m->type, m->channels)
    }
}
#undef PLOD__SAMPLE_LOOP

/* A height map (1 channel) and its u16x3 normal map on one texel grid:
 * the location, weights and seam test are computed once for both. */
#define PLOD__PAIR_LOOP(TYPE)                                                            \
    for (size_t first = 0; first < n; first += PLOD__SAMPLE_BLOCK) {                     \
        size_t count = n - first < PLOD__SAMPLE_BLOCK ? n - first : PLOD__SAMPLE_BLOCK;   \
        plod__plan_samples(a->width, a->height, a->face_count, 0, count, faces + first,   \
                           u + first, v + first, &plan);                                  \
        plod__sample_block(a, count, faces + first, &plan, (TYPE), 1, out_a + first);     \
        plod__sample_block(b, count, faces + first, &plan, PLOD_TEXEL_U16, 3,             \
                           out_b + 3 * first);                                            \
    }

void plod_cubemap_sample_pair_n(const plod_cubemap *a, const plod_cubemap *b, size_t n,
                                const int *faces, const double *u, const double *v,
                                double *out_a, double *out_b)
{
    int paired = a->channels == 1 && b->channels == 3 && b->type == PLOD_TEXEL_U16 &&
                 a->width == b->width && a->height == b->height &&
                 a->face_count == b->face_count;
    plod__sample_plan plan;
    if (!paired) {
        plod_cubemap_sample_face_n(a, n, faces, u, v, out_a);
        plod_cubemap_sample_face_n(b, n, faces, u, v, out_b);
    } else if (a->type == PLOD_TEXEL_U8) {
        PLOD__PAIR_LOOP(PLOD_TEXEL_U8)
    } else if (a->type == PLOD_TEXEL_U16) {
        PLOD__PAIR_LOOP(PLOD_TEXEL_U16)
    } else {
        PLOD__PAIR_LOOP(PLOD_TEXEL_F32)
    }
}
#undef PLOD__PAIR_LOOP

/* ---- maps sampled together ------------------------------------------------- */

/* One texel of a bundle: the height's raw value (u8 and u16 values are
 * exact in a float, f32 is itself), the normal's three u16, the extra u8. */
typedef struct plod__bundle_texel {
    float height;
    uint16_t normal[3];
    uint8_t extra;
    uint8_t pad[5]; /* 16 bytes: a row's two taps share a cache line three times in four */
} plod__bundle_texel;

struct plod_cubemap_bundle {
    const plod_cubemap *heights, *normals, *extra;
    double height_scale; /* raw height -> the sampled value, as plod__gather_taps */
    int ghosts;          /* cube maps: 1, each face ringed by its neighbours' texels */
    size_t stride;       /* texels a row */
    plod__bundle_texel *texels;
};

static float plod__raw0(const plod_cubemap *m, const unsigned char *base, size_t texel);

/* Texel (i, j) of face f of the maps into x. */
static void plod__bundle_fill(const plod_cubemap_bundle *b, int f, int i, int j,
                              plod__bundle_texel *x)
{
    const plod_cubemap *h = b->heights;
    size_t t = (size_t)f * (size_t)h->width * (size_t)h->height + (size_t)j * (size_t)h->width +
               (size_t)i;
    x->height = plod__raw0(h, h->texels, t);
    const uint16_t *n16 = (const uint16_t *)b->normals->texels;
    for (int c = 0; c < 3; c++)
        x->normal[c] = n16[3 * t + (size_t)c];
    x->extra = b->extra ? b->extra->texels[t] : 0;
}

static int plod__same_grid(const plod_cubemap *a, const plod_cubemap *b)
{
    return a->projection == b->projection && a->width == b->width && a->height == b->height &&
           a->face_count == b->face_count;
}

plod_status plod_cubemap_bundle_create(plod_cubemap_bundle **out, const plod_cubemap *heights,
                                       const plod_cubemap *normals, const plod_cubemap *extra)
{
    if (!out || !heights || !normals)
        return PLOD_ERR_NULL;
    *out = NULL;
    if (heights->channels != 1 || normals->channels != 3 || normals->type != PLOD_TEXEL_U16 ||
        !plod__same_grid(heights, normals) ||
        (extra && (extra->channels != 1 || extra->type != PLOD_TEXEL_U8 ||
                   !plod__same_grid(heights, extra))))
        return PLOD_OK;
    int ghosts = heights->face_count == PLOD_FACE_COUNT ? 1 : 0;
    size_t stride = (size_t)heights->width + 2 * (size_t)ghosts;
    size_t rows = (size_t)heights->height + 2 * (size_t)ghosts;
    size_t count = (size_t)heights->face_count * stride * rows;
    if (count > PLOD_CUBEMAP_BUNDLE_MAX_BYTES / sizeof(plod__bundle_texel))
        return PLOD_OK;
    plod_cubemap_bundle *b = calloc(1, sizeof *b);
    plod__bundle_texel *texels = calloc(count, sizeof *texels);
    if (!b || !texels) {
        free(b);
        free(texels);
        return PLOD_ERR_NO_MEMORY;
    }
    b->heights = heights;
    b->normals = normals;
    b->extra = extra;
    b->height_scale = plod__scale(heights->type);
    b->ghosts = ghosts;
    b->stride = stride;
    b->texels = texels;
    int w = heights->width, h = heights->height;
    for (int f = 0; f < heights->face_count; f++) {
        plod__bundle_texel *face = texels + (size_t)f * stride * rows;
        for (int j = -ghosts; j < h + ghosts; j++)
            for (int i = -ghosts; i < w + ghosts; i++) {
                int out_i = i < 0 || i >= w, out_j = j < 0 || j >= h;
                if (out_i && out_j)
                    continue; /* a corner ghost: never read (plod__plan_samples) */
                int g = f, gi = i, gj = j;
                if (out_i) /* the neighbour's texel, as plod__fetch_cube */
                    plod__across(heights, f, i < 0 ? 0 : 1, j, &g, &gi, &gj);
                else if (out_j)
                    plod__across(heights, f, j < 0 ? 2 : 3, i, &g, &gi, &gj);
                plod__bundle_fill(b, g, gi, gj,
                                  face + (size_t)(j + ghosts) * stride + (size_t)(i + ghosts));
            }
    }
    *out = b;
    return PLOD_OK;
}

void plod_cubemap_bundle_destroy(plod_cubemap_bundle *bundle)
{
    if (!bundle)
        return;
    free(bundle->texels);
    free(bundle);
}

int plod_cubemap_bundle_holds(const plod_cubemap_bundle *bundle, const plod_cubemap *heights,
                              const plod_cubemap *normals, const plod_cubemap *extra)
{
    return bundle && bundle->heights == heights && bundle->normals == normals &&
           bundle->extra == extra;
}

/* The four taps of every channel at the planned interior points (as
 * plod__gather_taps: the same converted values), one pass over the
 * points: tap[channel][k][i], channels height, normal x, y, z, extra. */
static void plod__gather_bundle(const plod_cubemap_bundle *b, size_t n,
                                const plod__sample_plan *plan, int extra,
                                double tap[5][4][PLOD__SAMPLE_BLOCK])
{
    size_t row = b->stride;
    double hs = b->height_scale;
    for (size_t i = 0; i < n; i++) {
        if (plan->at[i] < 0) {
            for (int c = 0; c < 5; c++)
                tap[c][0][i] = tap[c][1][i] = tap[c][2][i] = tap[c][3][i] = 0.0;
            continue;
        }
        const plod__bundle_texel *x = b->texels + plan->at[i];
        const plod__bundle_texel *taps[4] = {x, x + 1, x + row, x + row + 1};
        for (int k = 0; k < 4; k++) {
            tap[0][k][i] = (double)taps[k]->height * hs;
            for (int c = 0; c < 3; c++)
                tap[1 + c][k][i] = taps[k]->normal[c] * (1.0 / 65535.0);
            tap[4][k][i] = extra ? taps[k]->extra * (1.0 / 255.0) : 0.0;
        }
    }
}

void plod_cubemap_bundle_sample_n(const plod_cubemap_bundle *b, size_t n, const int *faces,
                                  const double *u, const double *v, double *heights_out,
                                  double *normals_out, double *extra_out)
{
    const plod_cubemap *m = b->heights;
    int extra = b->extra && extra_out;
    enum { AHEAD = 4 };
    plod__sample_plan plans[AHEAD];
    double tap[5][4][PLOD__SAMPLE_BLOCK];
    for (size_t first = 0; first < n; first += PLOD__SAMPLE_BLOCK) {
        size_t count = n - first < PLOD__SAMPLE_BLOCK ? n - first : PLOD__SAMPLE_BLOCK;
        size_t block = first / PLOD__SAMPLE_BLOCK % AHEAD;
        if (block == 0) /* the next blocks planned and their taps' lines requested */
            for (size_t a = 0; a < AHEAD && first + a * PLOD__SAMPLE_BLOCK < n; a++) {
                size_t at = first + a * PLOD__SAMPLE_BLOCK;
                size_t c = n - at < PLOD__SAMPLE_BLOCK ? n - at : PLOD__SAMPLE_BLOCK;
                plod__plan_samples(m->width, m->height, m->face_count, b->ghosts, c,
                                   faces + at, u + at, v + at, &plans[a]);
                for (size_t i = 0; i < c; i++)
                    if (plans[a].at[i] >= 0) {
                        const plod__bundle_texel *x = b->texels + plans[a].at[i];
                        __builtin_prefetch(x);
                        __builtin_prefetch(x + 1);
                        __builtin_prefetch(x + b->stride);
                        __builtin_prefetch(x + b->stride + 1);
                    }
            }
        const plod__sample_plan *plan = &plans[block];
        /* the cells at the faces' corners (CAR: the last rows and columns)
         * from the maps themselves */
        plod__sample_rest(b->heights, count, faces + first, plan, heights_out + first);
        plod__sample_rest(b->normals, count, faces + first, plan, normals_out + 3 * first);
        if (extra)
            plod__sample_rest(b->extra, count, faces + first, plan, extra_out + first);
        plod__gather_bundle(b, count, plan, extra, tap);
        plod__blend_taps(count, plan, (const double (*)[PLOD__SAMPLE_BLOCK])tap[0],
                         heights_out + first, 1);
        for (int c = 0; c < 3; c++)
            plod__blend_taps(count, plan, (const double (*)[PLOD__SAMPLE_BLOCK])tap[1 + c],
                             normals_out + 3 * first + c, 3);
        if (extra)
            plod__blend_taps(count, plan, (const double (*)[PLOD__SAMPLE_BLOCK])tap[4],
                             extra_out + first, 1);
    }
}

static int plod__sample_dir_d(const plod_cubemap *m, const double dir[3], double *acc)
{
    int face;
    double u, v;
    return plod_cubemap_locate(m, dir, &face, &u, &v) && plod__sample_face_d(m, face, u, v, acc);
}

void plod_cubemap_sample(const plod_cubemap *m, const double dir[3], float *out)
{
    double acc[4];
    if (!plod__sample_dir_d(m, dir, acc)) {
        plod__nan(m, out);
        return;
    }
    for (int c = 0; c < m->channels; c++)
        out[c] = (float)acc[c];
}

double plod_cubemap_sample_height(const plod_cubemap *m, const double dir[3])
{
    double acc[4];
    if (!plod__sample_dir_d(m, dir, acc))
        return NAN;
    return acc[0];
}

/* ======================================================================== */
/* normal maps                                                              */
/* ======================================================================== */

/* Unit direction and height (metres) of texel (i, j) of face f, where i
 * or j may be one step outside the face (not both): the neighbour face's
 * texel there, or the CAR wrap.  point = {x, y, z, height}. */
static void plod__texel_point(const plod_cubemap *m, int f, int i, int j, double height_scale,
                              double point[4])
{
    int n = m->size;
    if (m->face_count == PLOD_FACE_COUNT) {
        if (i < 0 || i >= n)
            plod__across(m, f, i < 0 ? 0 : 1, j, &f, &i, &j);
        else if (j < 0 || j >= n)
            plod__across(m, f, j < 0 ? 2 : 3, i, &f, &i, &j);
        (void)plod_face_to_dir(m->projection, f, (i + 0.5) * 2.0 / n - 1.0,
                               (j + 0.5) * 2.0 / n - 1.0, point);
    } else {
        plod__car_wrap(m, &i, &j);
        double lon = ((i + 0.5) * 2.0 / m->width - 1.0) * PLOD_PI;
        double lat = ((j + 0.5) * 2.0 / m->height - 1.0) * 0.5 * PLOD_PI;
        point[0] = cos(lat) * cos(lon);
        point[1] = cos(lat) * sin(lon);
        point[2] = sin(lat);
    }
    double texel[4];
    plod__texel(m, f, i, j, texel);
    point[3] = height_scale * texel[0];
}

/* Gnomonic offset of unit direction q seen from unit direction d: a
 * tangent vector at d, in radians to first order. */
static void plod__gnomonic(const double d[3], const double q[3], double g[3])
{
    double inv = 1.0 / (q[0] * d[0] + q[1] * d[1] + q[2] * d[2]);
    for (int k = 0; k < 3; k++)
        g[k] = q[k] * inv - d[k];
}

/* Normal at the centre point from its four grid neighbours: the height
 * gradient G in the tangent plane solves G . (g+ - g-) = h+ - h- along
 * both grid directions (g: gnomonic offsets, so uneven texel spacing and
 * the sphere's curvature do not bias it), then n ~ r d - G. */
static void plod__grid_normal(const double *c, const double *left, const double *right,
                              const double *down, const double *up, double radius,
                              double normal[3])
{
    double gl[3], gr[3], gd[3], gu[3];
    plod__gnomonic(c, left, gl);
    plod__gnomonic(c, right, gr);
    plod__gnomonic(c, down, gd);
    plod__gnomonic(c, up, gu);
    double a[3] = {gr[0] - gl[0], gr[1] - gl[1], gr[2] - gl[2]};
    double b[3] = {gu[0] - gd[0], gu[1] - gd[1], gu[2] - gd[2]};
    double aa = a[0] * a[0] + a[1] * a[1] + a[2] * a[2];
    double bb = b[0] * b[0] + b[1] * b[1] + b[2] * b[2];
    double ab = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    double det = aa * bb - ab * ab;
    double dh_a = right[3] - left[3], dh_b = up[3] - down[3];
    normal[0] = c[0], normal[1] = c[1], normal[2] = c[2];
    if (!(det > 1e-9 * aa * bb) || !isfinite(det))
        return; /* grid directions (nearly) parallel: keep radial */
    double x = (dh_a * bb - dh_b * ab) / det, y = (dh_b * aa - dh_a * ab) / det;
    double r = radius + c[3], v[3], len2 = 0.0;
    for (int k = 0; k < 3; k++) {
        v[k] = r * c[k] - (x * a[k] + y * b[k]);
        len2 += v[k] * v[k];
    }
    if (!(len2 > 0.0) || !isfinite(len2))
        return;
    double inv = (v[0] * c[0] + v[1] * c[1] + v[2] * c[2] < 0.0 ? -1.0 : 1.0) / sqrt(len2);
    for (int k = 0; k < 3; k++)
        normal[k] = v[k] * inv;
}

static uint16_t plod__unorm16(double x)
{
    double q = (x + 1.0) * 0.5 * 65535.0 + 0.5;
    return (uint16_t)(q < 0.0 ? 0.0 : q > 65535.0 ? 65535.0 : q);
}

/* The normal map in bands of rows, each with its own three rolling rows of
 * points (a ghost column at both ends): a band's texels depend on the
 * height map alone, so any split into bands and threads writes the same
 * map. */
#define PLOD__NORMAL_BANDS 8 /* per face */

typedef struct plod__normal_job {
    const plod_cubemap *heights;
    plod_cubemap *normals;
    double radius, height_scale;
    atomic_int failed; /* a band found no memory for its rows */
} plod__normal_job;

static void plod__normal_bands(void *context, size_t begin, size_t end)
{
    plod__normal_job *job = context;
    const plod_cubemap *heights = job->heights;
    int w = heights->width, h = heights->height;
    size_t row_doubles = (size_t)(w + 2) * 4;
    double *rows = malloc(3 * row_doubles * sizeof *rows);
    if (!rows) {
        atomic_store(&job->failed, 1);
        return;
    }
    for (size_t band = begin; band < end; band++) {
        int f = (int)(band / PLOD__NORMAL_BANDS), b = (int)(band % PLOD__NORMAL_BANDS);
        int first = (int)((int64_t)h * b / PLOD__NORMAL_BANDS);
        int last = (int)((int64_t)h * (b + 1) / PLOD__NORMAL_BANDS); /* rows [first, last) */
        uint16_t *texels = (uint16_t *)(job->normals->texels + (size_t)f * job->normals->face_bytes);
        for (int j = first - 1; j <= last && first < last; j++) {
            double *row = rows + (size_t)((j + 3) % 3) * row_doubles;
            int ghost_row = j < 0 || j >= h;
            for (int i = ghost_row ? 0 : -1; i <= (ghost_row ? w - 1 : w); i++)
                plod__texel_point(heights, f, i, j, job->height_scale, row + 4 * (i + 1));
            if (j < first + 1)
                continue;
            int jc = j - 1; /* complete now: its row and both neighbours */
            const double *below = rows + (size_t)((jc + 2) % 3) * row_doubles;
            const double *centre = rows + (size_t)((jc + 3) % 3) * row_doubles;
            for (int i = 0; i < w; i++) {
                const double *c = centre + 4 * (i + 1);
                double normal[3];
                plod__grid_normal(c, c - 4, c + 4, below + 4 * (i + 1), row + 4 * (i + 1),
                                  job->radius, normal);
                uint16_t *texel = texels + 3 * ((size_t)jc * (size_t)w + (size_t)i);
                for (int k = 0; k < 3; k++)
                    texel[k] = plod__unorm16(isfinite(normal[k]) ? normal[k] : 0.0);
            }
        }
    }
    free(rows);
}

plod_status plod_cubemap_build_normals(plod_cubemap **out, const plod_cubemap *heights,
                                       double radius, double height_scale, int threads)
{
    if (!out || !heights)
        return PLOD_ERR_NULL;
    *out = NULL;
    if (!(radius > 0.0) || !isfinite(radius) || !isfinite(height_scale))
        return PLOD_ERR_BAD_PARAM;
    plod_cubemap *normals = NULL;
    plod_status st = plod_cubemap_create(&normals, heights->projection, heights->size, 3,
                                         PLOD_TEXEL_U16);
    if (st != PLOD_OK)
        return st;
    plod__normal_job job = {heights, normals, radius, height_scale};
    atomic_init(&job.failed, 0);
    plod_parallel_for((size_t)heights->face_count * PLOD__NORMAL_BANDS, threads,
                      plod__normal_bands, &job);
    if (atomic_load(&job.failed)) {
        plod_cubemap_destroy(normals);
        return PLOD_ERR_NO_MEMORY;
    }
    *out = normals;
    return PLOD_OK;
}

/* ======================================================================== */
/* min/max pyramid                                                          */
/* ======================================================================== */

static float plod__raw0(const plod_cubemap *m, const unsigned char *base, size_t texel)
{
    size_t index = texel * (size_t)m->channels;
    switch (m->type) {
    case PLOD_TEXEL_U8: return base[index];
    case PLOD_TEXEL_U16: return ((const uint16_t *)base)[index];
    default: return ((const float *)base)[index];
    }
}

plod_status plod_cubemap_build_pyramid(plod_cubemap *m)
{
    if (!m)
        return PLOD_ERR_NULL;
    int w = m->width, h = m->height, levels = 0;
    size_t cells = 0;
    for (;;) {
        assert(levels < PLOD__MAX_LEVELS);
        m->level_width[levels] = w;
        m->level_height[levels] = h;
        m->level_offset[levels] = cells;
        cells += (size_t)w * (size_t)h;
        levels++;
        if (w == 1 && h == 1)
            break;
        w = (w + 1) / 2;
        h = (h + 1) / 2;
    }
    if (!m->pyramid_min) {
        m->pyramid_min = malloc(cells * (size_t)m->face_count * sizeof(float));
        m->pyramid_max = malloc(cells * (size_t)m->face_count * sizeof(float));
        if (!m->pyramid_min || !m->pyramid_max) {
            free(m->pyramid_min);
            free(m->pyramid_max);
            m->pyramid_min = m->pyramid_max = NULL;
            return PLOD_ERR_NO_MEMORY;
        }
    }
    m->levels = levels;
    m->face_cells = cells;
    m->nonfinite_texels = 0;
    for (int f = 0; f < m->face_count; f++) {
        float *lo = m->pyramid_min + (size_t)f * cells;
        float *hi = m->pyramid_max + (size_t)f * cells;
        const unsigned char *base = m->texels + (size_t)f * m->face_bytes;
        size_t count = (size_t)m->width * (size_t)m->height;
        for (size_t t = 0; t < count; t++) {
            float value = plod__raw0(m, base, t);
            if (value != value) { /* NaN texels do not bound anything */
                value = 0.0f;
                m->nonfinite_texels++;
            }
            lo[t] = hi[t] = value;
        }
        for (int L = 1; L < levels; L++) {
            int pw = m->level_width[L - 1], ph = m->level_height[L - 1];
            const float *plo = lo + m->level_offset[L - 1], *phi = hi + m->level_offset[L - 1];
            float *clo = lo + m->level_offset[L], *chi = hi + m->level_offset[L];
            for (int y = 0; y < m->level_height[L]; y++) {
                for (int x = 0; x < m->level_width[L]; x++) {
                    float a = INFINITY, b = -INFINITY;
                    for (int dy = 0; dy < 2; dy++) {
                        int py = 2 * y + dy;
                        if (py >= ph)
                            continue;
                        for (int dx = 0; dx < 2; dx++) {
                            int px = 2 * x + dx;
                            if (px >= pw)
                                continue;
                            size_t p = (size_t)py * (size_t)pw + (size_t)px;
                            if (plo[p] < a)
                                a = plo[p];
                            if (phi[p] > b)
                                b = phi[p];
                        }
                    }
                    size_t c = (size_t)y * (size_t)m->level_width[L] + (size_t)x;
                    clo[c] = a;
                    chi[c] = b;
                }
            }
        }
    }
    m->pyramid_valid = 1;
    return PLOD_OK;
}

size_t plod_cubemap_nan_count(const plod_cubemap *m)
{
    return m && m->pyramid_valid ? m->nonfinite_texels : 0;
}

/* Raw min/max over in-face texels [i0,i1]x[j0,j1] (inclusive, clamped). */
static void plod__rect_range(const plod_cubemap *m, int face, int i0, int j0, int i1, int j1,
                             float *lo_out, float *hi_out)
{
    if (i0 < 0) i0 = 0;
    if (j0 < 0) j0 = 0;
    if (i1 > m->width - 1) i1 = m->width - 1;
    if (j1 > m->height - 1) j1 = m->height - 1;
    int L = 0;
    while (L + 1 < m->levels && ((i1 >> L) - (i0 >> L) > 3 || (j1 >> L) - (j0 >> L) > 3))
        L++;
    const float *lo = m->pyramid_min + (size_t)face * m->face_cells + m->level_offset[L];
    const float *hi = m->pyramid_max + (size_t)face * m->face_cells + m->level_offset[L];
    int lw = m->level_width[L];
    float a = *lo_out, b = *hi_out;
    for (int y = j0 >> L; y <= (j1 >> L); y++) {
        for (int x = i0 >> L; x <= (i1 >> L); x++) {
            size_t c = (size_t)y * (size_t)lw + (size_t)x;
            if (lo[c] < a)
                a = lo[c];
            if (hi[c] > b)
                b = hi[c];
        }
    }
    *lo_out = a;
    *hi_out = b;
}

/* Ghost strip beyond edge `edge` of face f over along-edge indices [k0,k1]. */
static void plod__strip_range(const plod_cubemap *m, int f, int edge, int k0, int k1, float *lo,
                              float *hi)
{
    int g, gi0, gj0, gi1, gj1;
    if (k0 < 0) k0 = 0;
    if (k1 > m->size - 1) k1 = m->size - 1;
    plod__across(m, f, edge, k0, &g, &gi0, &gj0);
    plod__across(m, f, edge, k1, &g, &gi1, &gj1);
    plod__rect_range(m, g, gi0 < gi1 ? gi0 : gi1, gj0 < gj1 ? gj0 : gj1, gi0 > gi1 ? gi0 : gi1,
                     gj0 > gj1 ? gj0 : gj1, lo, hi);
}

void plod_cubemap_range(const plod_cubemap *m, int face, double u0, double v0, double u1,
                        double v1, double *min_value, double *max_value)
{
    assert(m->pyramid_valid);
    if (!m->pyramid_valid || face < 0 || face >= m->face_count || !(u0 == u0) || !(u1 == u1) ||
        !(v0 == v0) || !(v1 == v1)) {
        plod_cubemap_global_range(m, min_value, max_value);
        return;
    }
    if (u0 > u1) { double t = u0; u0 = u1; u1 = t; }
    if (v0 > v1) { double t = v0; v0 = v1; v1 = t; }
    u0 = plod__clamp_unit(u0);
    u1 = plod__clamp_unit(u1);
    v0 = plod__clamp_unit(v0);
    v1 = plod__clamp_unit(v1);
    /* Every texel a bilinear tap at a point of the rectangle can read. */
    int i0 = (int)floor((u0 + 1.0) * 0.5 * m->width - 0.5);
    int i1 = (int)floor((u1 + 1.0) * 0.5 * m->width - 0.5) + 1;
    int j0 = (int)floor((v0 + 1.0) * 0.5 * m->height - 0.5);
    int j1 = (int)floor((v1 + 1.0) * 0.5 * m->height - 0.5) + 1;
    float lo = INFINITY, hi = -INFINITY;
    plod__rect_range(m, face, i0, j0, i1, j1, &lo, &hi);
    if (m->face_count == PLOD_FACE_COUNT) {
        if (i0 < 0) plod__strip_range(m, face, 0, j0, j1, &lo, &hi);
        if (i1 >= m->size) plod__strip_range(m, face, 1, j0, j1, &lo, &hi);
        if (j0 < 0) plod__strip_range(m, face, 2, i0, i1, &lo, &hi);
        if (j1 >= m->size) plod__strip_range(m, face, 3, i0, i1, &lo, &hi);
    } else {
        /* CAR: wrap in longitude; across a pole the taps are from the same
         * edge row at other longitudes, so take the whole row. */
        if (i0 < 0) plod__rect_range(m, 0, m->width - 1, j0, m->width - 1, j1, &lo, &hi);
        if (i1 >= m->width) plod__rect_range(m, 0, 0, j0, 0, j1, &lo, &hi);
        if (j0 < 0) plod__rect_range(m, 0, 0, 0, m->width - 1, 0, &lo, &hi);
        if (j1 >= m->height)
            plod__rect_range(m, 0, 0, m->height - 1, m->width - 1, m->height - 1, &lo, &hi);
    }
    double scale = plod__scale(m->type);
    *min_value = lo * scale;
    *max_value = hi * scale;
}

void plod_cubemap_global_range(const plod_cubemap *m, double *min_value, double *max_value)
{
    assert(m->pyramid_valid);
    if (!m->pyramid_valid) {
        *min_value = -INFINITY;
        *max_value = INFINITY;
        return;
    }
    float lo = INFINITY, hi = -INFINITY;
    size_t top = m->level_offset[m->levels - 1];
    for (int f = 0; f < m->face_count; f++) {
        float a = m->pyramid_min[(size_t)f * m->face_cells + top];
        float b = m->pyramid_max[(size_t)f * m->face_cells + top];
        if (a < lo) lo = a;
        if (b > hi) hi = b;
    }
    double scale = plod__scale(m->type);
    *min_value = lo * scale;
    *max_value = hi * scale;
}

/* ---- image layouts ---------------------------------------------------------- */

int plod_cubemap_is_cross_layout(int width, int height)
{
    return width % 4 == 0 && width / 4 * 3 == height;
}

int plod_cubemap_is_equirectangular(int width, int height)
{
    return width == 2 * height;
}

int plod_cubemap_size_for_width(int width)
{
    int size = width / 4 > 0 ? width / 4 : 1;
    return size > PLOD_CUBEMAP_MAX_MAP_SIZE ? PLOD_CUBEMAP_MAX_MAP_SIZE : size;
}

int plod_cubemap_face_path(char *out, size_t size, const char *path, int face)
{
    const char *mark = strstr(path, "{face}");
    int n;
    if (mark) {
        n = snprintf(out, size, "%.*s%d%s", (int)(mark - path), path, face, mark + 6);
    } else {
        const char *slash = strrchr(path, '/');
        const char *dot = strrchr(path, '.');
        if (!dot || (slash && dot < slash))
            dot = path + strlen(path);
        n = snprintf(out, size, "%.*s_face%d%s", (int)(dot - path), path, face, dot);
    }
    return n > 0 && (size_t)n < size ? 0 : -1;
}
