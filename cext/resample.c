/* resample.c -- the CubeResampler (equirectangular image -> cube map), the
 * cross layout, and pixel/channel conversions between images and cube maps.
 *
 * Source convention (CAR image, W x H, rows top to bottom): pixel (c, r) is
 * centred at lon = -180 + (c + 0.5) * 360 / W, lat = 90 - (r + 0.5) * 180 / H.
 * Taps wrap in longitude; a row beyond a pole reflects across it: row -1 is
 * row 0 at lon + 180 (column + W/2), row H is row H-1 at lon + 180.
 *
 * Filters: nearest; bilinear (default); bicubic = Catmull-Rom 4x4, its
 * result clamped per channel to the min/max of the central 2x2 taps so it
 * never overshoots (heights: no ringing below sea level or above peaks; a
 * texel whose 2x2 source taps are all 0 stays exactly 0).
 *
 * Speed: every cube projection maps faces 1..4 onto each other by a 90 deg
 * turn about +Z, and face 5 is face 0 mirrored in z (both checked on the
 * projection at run time); so only faces 1 and 0 get a face_to_dir and two
 * atan2 per texel, reused with a longitude shift of W/4 (faces 2..4) or a
 * latitude mirror (face 5).  Work is split into
 * chunks of rows taken by up to `threads` threads from one atomic counter;
 * each texel is written by exactly one thread from the same inputs, so the
 * output does not depend on the thread count.  Only the calling thread
 * invokes the progress callback.
 *
 * Cross layout (FITS, x = phi_c + 45 chi, y = theta_c + 45 psi): an image of
 * 4N x 3N; faces 1, 2, 3, 4 left to right in the middle band, face 0 above
 * face 1, face 5 below it; in each cell u runs right and v up.
 */
#include "plod_resample.h"

#include <assert.h>
#include <math.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define PLOD__CHUNK_ROWS 8

/* ======================================================================== */
/* names                                                                    */
/* ======================================================================== */

plod_status plod_filter_from_name(const char *name, plod_filter *out)
{
    static const char *const names[PLOD_FILTER_COUNT] = {"nearest", "bilinear", "bicubic"};
    if (!name || !out)
        return PLOD_ERR_NULL;
    for (int f = 0; f < PLOD_FILTER_COUNT; f++) {
        if (strcmp(name, names[f]) == 0) {
            *out = (plod_filter)f;
            return PLOD_OK;
        }
    }
    return PLOD_ERR_BAD_PARAM;
}

/* ======================================================================== */
/* pixel access                                                             */
/* ======================================================================== */

static double plod__read_norm(plod_texel_type type, const void *pixels, size_t index)
{
    switch (type) {
    case PLOD_TEXEL_U8: return ((const uint8_t *)pixels)[index] * (1.0 / 255.0);
    case PLOD_TEXEL_U16: return ((const uint16_t *)pixels)[index] * (1.0 / 65535.0);
    default: return ((const float *)pixels)[index];
    }
}

static void plod__write_norm(plod_texel_type type, void *pixels, size_t index, double value)
{
    switch (type) {
    case PLOD_TEXEL_U8: {
        double q = value * 255.0 + 0.5; /* NaN quantises to 0 (no UB cast) */
        ((uint8_t *)pixels)[index] = (uint8_t)(!(q > 0.0) ? 0.0 : q >= 255.0 ? 255.0 : q);
        break;
    }
    case PLOD_TEXEL_U16: {
        double q = value * 65535.0 + 0.5;
        ((uint16_t *)pixels)[index] = (uint16_t)(!(q > 0.0) ? 0.0 : q >= 65535.0 ? 65535.0 : q);
        break;
    }
    default:
        ((float *)pixels)[index] = (float)value;
        break;
    }
}

/* Channel map from `from` source channels to `to` destination channels:
 * map[c] is the source channel, or -1 for an opaque alpha (1.0).  Grey is
 * replicated into RGB, missing alpha is opaque, extra channels dropped. */
static void plod__channel_map(int from, int to, int map[4])
{
    for (int c = 0; c < 4; c++)
        map[c] = c < from ? c : -1;
    if (to == from)
        return;
    int has_alpha_to = to == 2 || to == 4;
    int colour_from = (from == 1 || from == 2) ? 1 : 3;
    int colour_to = to - has_alpha_to;
    for (int c = 0; c < colour_to; c++)
        map[c] = colour_from == 1 ? 0 : (c < colour_from ? c : 0);
    if (has_alpha_to)
        map[to - 1] = (from == 2 || from == 4) ? from - 1 : -1;
}

/* ======================================================================== */
/* resampler                                                                */
/* ======================================================================== */

typedef struct plod__resample_job plod__resample_job;
typedef void (*plod__filter_fn)(const plod__resample_job *job, double x, double y, double *out);

struct plod__resample_job {
    plod_cubemap *cubemap;
    plod__filter_fn filter_fn;
    int channels; /* of the cube map */
    const plod_image *source;
    plod_filter filter;
    int channel_map[4];
    int rotated_equator; /* faces 1..4 are face 1 turned by 90 deg steps */
    int polar_mirror;    /* face 5 (u, v) is face 0 (u, -v) mirrored in z */
    int n;               /* face size */
    int rows_total;      /* rows in the job list */
    int chunks_total;
    double weight_total;
    atomic_int next_chunk;
    atomic_int cancel;
    atomic_int failed;
    atomic_long done_weight; /* in face rows */
    void *faces[PLOD_FACE_COUNT];
    plod_progress_fn progress; /* called by worker 0 (the caller's thread) */
    void *user;
};

/* Source tap rows/columns for one coordinate, wrapping/reflecting. */
static void plod__source_tap(const plod_image *src, long col, long row, long *out_col,
                             long *out_row)
{
    long w = src->width, h = src->height;
    if (row < 0 || row >= h) {
        row = row < 0 ? -1 - row : 2 * h - 1 - row;
        col += w / 2;
        if (row < 0)
            row = 0;
        if (row >= h)
            row = h - 1;
    }
    col %= w;
    if (col < 0)
        col += w;
    *out_col = col;
    *out_row = row;
}

/* Element offset (pixel index * channels) of the tap at (col, row). */
static size_t plod__tap_offset(const plod_image *src, long col, long row)
{
    long c, r;
    plod__source_tap(src, col, row, &c, &r);
    return ((size_t)r * (size_t)src->width + (size_t)c) * (size_t)src->channels;
}

static void plod__catmull_rom(double t, double w[4])
{
    double t2 = t * t, t3 = t2 * t;
    w[0] = 0.5 * (-t3 + 2.0 * t2 - t);
    w[1] = 0.5 * (3.0 * t3 - 5.0 * t2 + 2.0);
    w[2] = 0.5 * (-3.0 * t3 + 4.0 * t2 + t);
    w[3] = 0.5 * (t3 - t2);
}

/* Filtered source value at continuous pixel coordinates (x, y) (pixel
 * centres at integers), normalised, into out[channels].  One copy per
 * source pixel type; interpolation runs on raw values, scaled last, so an
 * all-zero footprint gives exactly 0. */
#define PLOD__DEFINE_FILTER(NAME, T, SCALE)                                                     \
    static void NAME(const plod__resample_job *job, double x, double y, double *out)            \
    {                                                                                           \
        const plod_image *src = job->source;                                                    \
        const T *px = (const T *)src->pixels;                                                   \
        const int *map = job->channel_map;                                                      \
        int channels = job->channels;                                                           \
        long w = src->width, h = src->height;                                                   \
        size_t sc = (size_t)src->channels;                                                      \
        if (job->filter == PLOD_FILTER_NEAREST) {                                               \
            size_t o = plod__tap_offset(src, (long)floor(x + 0.5), (long)floor(y + 0.5));       \
            for (int k = 0; k < channels; k++)                                                  \
                out[k] = map[k] < 0 ? 1.0 : px[o + (size_t)map[k]] * (SCALE);                   \
            return;                                                                             \
        }                                                                                       \
        double fx = floor(x), fy = floor(y);                                                    \
        long x0 = (long)fx, y0 = (long)fy;                                                      \
        double tx = x - fx, ty = y - fy;                                                        \
        if (job->filter == PLOD_FILTER_BILINEAR) {                                              \
            size_t o00, o10, o01, o11;                                                          \
            if (x0 >= 0 && y0 >= 0 && x0 + 1 < w && y0 + 1 < h) {                              \
                o00 = ((size_t)y0 * (size_t)w + (size_t)x0) * sc;                               \
                o10 = o00 + sc;                                                                 \
                o01 = o00 + (size_t)w * sc;                                                     \
                o11 = o01 + sc;                                                                 \
            } else {                                                                            \
                o00 = plod__tap_offset(src, x0, y0);                                            \
                o10 = plod__tap_offset(src, x0 + 1, y0);                                        \
                o01 = plod__tap_offset(src, x0, y0 + 1);                                        \
                o11 = plod__tap_offset(src, x0 + 1, y0 + 1);                                    \
            }                                                                                   \
            for (int k = 0; k < channels; k++) {                                                \
                int m = map[k];                                                                 \
                if (m < 0) {                                                                    \
                    out[k] = 1.0;                                                               \
                    continue;                                                                   \
                }                                                                               \
                double a = px[o00 + (size_t)m], b = px[o10 + (size_t)m];                        \
                double c = px[o01 + (size_t)m], d = px[o11 + (size_t)m];                        \
                double top = a + tx * (b - a), bottom = c + tx * (d - c);                       \
                out[k] = (top + ty * (bottom - top)) * (SCALE);                                 \
            }                                                                                   \
            return;                                                                             \
        }                                                                                       \
        size_t o[4][4];                                                                         \
        if (x0 >= 1 && y0 >= 1 && x0 + 2 < w && y0 + 2 < h) {                                  \
            size_t base = ((size_t)(y0 - 1) * (size_t)w + (size_t)(x0 - 1)) * sc;              \
            for (int dy = 0; dy < 4; dy++)                                                      \
                for (int dx = 0; dx < 4; dx++)                                                  \
                    o[dy][dx] = base + ((size_t)dy * (size_t)w + (size_t)dx) * sc;              \
        } else {                                                                                \
            for (int dy = 0; dy < 4; dy++)                                                      \
                for (int dx = 0; dx < 4; dx++)                                                  \
                    o[dy][dx] = plod__tap_offset(src, x0 - 1 + dx, y0 - 1 + dy);                \
        }                                                                                       \
        double wx[4], wy[4];                                                                    \
        plod__catmull_rom(tx, wx);                                                              \
        plod__catmull_rom(ty, wy);                                                              \
        for (int k = 0; k < channels; k++) {                                                    \
            int m = map[k];                                                                     \
            if (m < 0) {                                                                        \
                out[k] = 1.0;                                                                   \
                continue;                                                                       \
            }                                                                                   \
            double acc = 0.0;                                                                   \
            for (int dy = 0; dy < 4; dy++) {                                                    \
                double row = 0.0;                                                               \
                for (int dx = 0; dx < 4; dx++)                                                  \
                    row += wx[dx] * px[o[dy][dx] + (size_t)m];                                  \
                acc += wy[dy] * row;                                                            \
            }                                                                                   \
            double a = px[o[1][1] + (size_t)m], b = px[o[1][2] + (size_t)m];                    \
            double c = px[o[2][1] + (size_t)m], d = px[o[2][2] + (size_t)m];                    \
            double lo = fmin(fmin(a, b), fmin(c, d)), hi = fmax(fmax(a, b), fmax(c, d));        \
            out[k] = (acc < lo ? lo : acc > hi ? hi : acc) * (SCALE);                           \
        }                                                                                       \
    }

PLOD__DEFINE_FILTER(plod__filter_u8, uint8_t, 1.0 / 255.0)
PLOD__DEFINE_FILTER(plod__filter_u16, uint16_t, 1.0 / 65535.0)
PLOD__DEFINE_FILTER(plod__filter_f32, float, 1.0)

static void plod__filter_source(const plod__resample_job *job, double x, double y, double *out)
{
    job->filter_fn(job, x, y, out);
}

/* Source pixel coordinates of a direction. */
static void plod__dir_to_source(const plod_image *src, const double d[3], double *x, double *y)
{
    double lon = atan2(d[1], d[0]);
    double lat = atan2(d[2], hypot(d[0], d[1]));
    *x = (lon + PLOD_PI) * (src->width / (2.0 * PLOD_PI)) - 0.5;
    *y = (0.5 * PLOD_PI - lat) * (src->height / PLOD_PI) - 0.5;
}

static void plod__store(const plod__resample_job *job, int face, int i, int j,
                        const double *value)
{
    const plod_cubemap *m = job->cubemap;
    int channels = plod_cubemap_channels(m);
    size_t index = ((size_t)j * (size_t)plod_cubemap_face_width(m) + (size_t)i) * (size_t)channels;
    for (int k = 0; k < channels; k++)
        plod__write_norm(plod_cubemap_texel_type(m), job->faces[face], index + (size_t)k, value[k]);
}

/* Per-thread scratch for one face row. */
typedef struct plod__row_scratch {
    int *faces;
    double *u, *v, *dirs, *sx, *sy;
} plod__row_scratch;

static void plod__scratch_free(plod__row_scratch *rs)
{
    free(rs->faces);
    free(rs->u);
    free(rs->v);
    free(rs->dirs);
    free(rs->sx);
    free(rs->sy);
}

static int plod__scratch_alloc(plod__row_scratch *rs, size_t width)
{
    rs->faces = malloc(width * sizeof *rs->faces);
    rs->u = malloc(width * sizeof *rs->u);
    rs->v = malloc(width * sizeof *rs->v);
    rs->dirs = malloc(3 * width * sizeof *rs->dirs);
    rs->sx = malloc(width * sizeof *rs->sx);
    rs->sy = malloc(width * sizeof *rs->sy);
    if (rs->faces && rs->u && rs->v && rs->dirs && rs->sx && rs->sy)
        return 0;
    plod__scratch_free(rs);
    return -1;
}

/* Job row r: for a cube map with rotated_equator, rows [0, n) are the
 * equator band (faces 1..4, row r), then with polar_mirror [n, 2n) face 0
 * row j together with face 5 row n-1-j, else [n, 2n) face 0, [2n, 3n)
 * face 5; without rotated_equator rows [f*n, (f+1)*n) are face f.  CAR:
 * rows of face 0. */
static int plod__row_weight(const plod__resample_job *job, int r)
{
    if (!job->rotated_equator)
        return 1;
    return r < job->n ? 4 : job->polar_mirror ? 2 : 1;
}

static plod_status plod__resample_row(plod__resample_job *job, int r, void *scratch)
{
    plod_cubemap *m = job->cubemap;
    const plod_image *src = job->source;
    int n = job->n;
    double value[4];
    if (plod_cubemap_face_count(m) == 1) {
        /* CAR target: separable lon per column, lat per row. */
        int w = plod_cubemap_face_width(m);
        double lat = -0.5 * PLOD_PI + (r + 0.5) * PLOD_PI / n;
        double y = (0.5 * PLOD_PI - lat) * (src->height / PLOD_PI) - 0.5;
        for (int i = 0; i < w; i++) {
            double lon = -PLOD_PI + (i + 0.5) * 2.0 * PLOD_PI / w;
            double x = (lon + PLOD_PI) * (src->width / (2.0 * PLOD_PI)) - 0.5;
            plod__filter_source(job, x, y, value);
            plod__store(job, 0, i, r, value);
        }
        return PLOD_OK;
    }
    int face, j;
    if (job->rotated_equator) {
        face = r < n ? 1 : r < 2 * n ? 0 : 5;
        j = r % n;
    } else {
        face = r / n;
        j = r % n;
    }
    plod__row_scratch *rs = scratch;
    double v = -1.0 + (j + 0.5) * 2.0 / n;
    for (int i = 0; i < n; i++) {
        rs->faces[i] = face;
        rs->u[i] = -1.0 + (i + 0.5) * 2.0 / n;
        rs->v[i] = v;
    }
    plod_status s = plod_face_to_dir_n(plod_cubemap_projection(m), (size_t)n, rs->faces, rs->u,
                                       rs->v, rs->dirs, NULL);
    if (s != PLOD_OK)
        return s;
    double *sx = rs->sx, *sy = rs->sy;
    for (int i = 0; i < n; i++)
        plod__dir_to_source(src, rs->dirs + 3 * i, &sx[i], &sy[i]);
    int copies = (job->rotated_equator && face == 1) ? 4 : 1;
    for (int k = 0; k < copies; k++) {
        double shift = k * (src->width / 4.0);
        for (int i = 0; i < n; i++) {
            plod__filter_source(job, sx[i] + shift, sy[i], value);
            plod__store(job, face + k, i, j, value);
        }
    }
    if (face == 0 && job->polar_mirror) {
        /* lat -> -lat: source row y -> H - 1 - y */
        for (int i = 0; i < n; i++) {
            plod__filter_source(job, sx[i], src->height - 1.0 - sy[i], value);
            plod__store(job, 5, i, n - 1 - j, value);
        }
    }
    return PLOD_OK;
}

/* Takes chunks until none is left; the caller thread (report != 0) calls
 * the progress callback. */
static void plod__resample_work(plod__resample_job *job, int report, plod_progress_fn progress,
                                void *user)
{
    size_t width = (size_t)plod_cubemap_face_width(job->cubemap);
    plod__row_scratch scratch;
    if (plod__scratch_alloc(&scratch, width) < 0) {
        atomic_store(&job->failed, PLOD_ERR_NO_MEMORY);
        atomic_store(&job->cancel, 1);
        return;
    }
    double last_reported = 0.0;
    for (;;) {
        if (atomic_load(&job->cancel))
            break;
        int chunk = atomic_fetch_add(&job->next_chunk, 1);
        if (chunk >= job->chunks_total)
            break;
        int r0 = chunk * PLOD__CHUNK_ROWS;
        int r1 = r0 + PLOD__CHUNK_ROWS < job->rows_total ? r0 + PLOD__CHUNK_ROWS : job->rows_total;
        long weight = 0;
        for (int r = r0; r < r1; r++) {
            plod_status s = plod__resample_row(job, r, &scratch);
            if (s != PLOD_OK) {
                atomic_store(&job->failed, s);
                atomic_store(&job->cancel, 1);
                break;
            }
            weight += plod__row_weight(job, r);
        }
        long done = atomic_fetch_add(&job->done_weight, weight) + weight;
        if (report && progress) {
            double fraction = done / job->weight_total;
            if (fraction - last_reported >= 0.02 && fraction < 1.0) {
                last_reported = fraction;
                if (progress(user, fraction))
                    atomic_store(&job->cancel, 1);
            }
        }
    }
    plod__scratch_free(&scratch);
}

/* plod_parallel_for's range over workers; worker 0 runs on the caller's
 * thread, the one that may call the progress callback. */
static void plod__resample_workers(void *context, size_t begin, size_t end)
{
    plod__resample_job *job = context;
    for (size_t w = begin; w < end; w++)
        plod__resample_work(job, w == 0, job->progress, job->user);
}

/* Faces 1..4 = face 1 turned by (f - 1) * 90 deg about +Z? */
static int plod__equator_rotates(const plod_cubemap *m)
{
    plod_projection p = plod_cubemap_projection(m);
    const double probes[3][2] = {{0.3, -0.7}, {-0.9, 0.2}, {1.0, 1.0}};
    for (int q = 0; q < 3; q++) {
        double d1[3];
        if (plod_face_to_dir(p, 1, probes[q][0], probes[q][1], d1) != PLOD_OK)
            return 0;
        double x = d1[0], y = d1[1];
        for (int k = 1; k < 4; k++) {
            double d[3];
            if (plod_face_to_dir(p, 1 + k, probes[q][0], probes[q][1], d) != PLOD_OK)
                return 0;
            double rx = x, ry = y; /* rotate (x, y) by k * 90 deg */
            for (int t = 0; t < k; t++) {
                double nx = -ry;
                ry = rx;
                rx = nx;
            }
            if (fabs(d[0] - rx) > 1e-12 || fabs(d[1] - ry) > 1e-12 || fabs(d[2] - d1[2]) > 1e-12)
                return 0;
        }
    }
    return 1;
}

/* Face 5 at (u, v) = face 0 at (u, -v) with z negated? */
static int plod__poles_mirror(const plod_cubemap *m)
{
    plod_projection p = plod_cubemap_projection(m);
    const double probes[3][2] = {{0.3, -0.7}, {-0.9, 0.2}, {1.0, 1.0}};
    for (int q = 0; q < 3; q++) {
        double d0[3], d5[3];
        if (plod_face_to_dir(p, 0, probes[q][0], -probes[q][1], d0) != PLOD_OK ||
            plod_face_to_dir(p, 5, probes[q][0], probes[q][1], d5) != PLOD_OK)
            return 0;
        if (fabs(d0[0] - d5[0]) > 1e-12 || fabs(d0[1] - d5[1]) > 1e-12 ||
            fabs(d0[2] + d5[2]) > 1e-12)
            return 0;
    }
    return 1;
}

plod_status plod_resample_car_to_cube_threads(plod_cubemap *cubemap, const plod_image *source,
                                              plod_filter filter, int threads,
                                              plod_progress_fn progress, void *user)
{
    if (!cubemap || !source || !source->pixels)
        return PLOD_ERR_NULL;
    if ((unsigned)filter >= PLOD_FILTER_COUNT || source->width < 1 || source->height < 1 ||
        source->channels < 1 || source->channels > 4 ||
        (unsigned)source->type >= PLOD_TEXEL_TYPE_COUNT)
        return PLOD_ERR_BAD_PARAM;
    if (threads < 1)
        threads = 1;
    if (threads > 16)
        threads = 16;
    plod__resample_job *job = calloc(1, sizeof *job);
    if (!job)
        return PLOD_ERR_NO_MEMORY;
    job->cubemap = cubemap;
    job->source = source;
    job->filter = filter;
    job->n = plod_cubemap_size(cubemap);
    job->channels = plod_cubemap_channels(cubemap);
    job->filter_fn = source->type == PLOD_TEXEL_U8    ? plod__filter_u8
                     : source->type == PLOD_TEXEL_U16 ? plod__filter_u16
                                                      : plod__filter_f32;
    for (int f = 0; f < plod_cubemap_face_count(cubemap); f++)
        job->faces[f] = plod_cubemap_face_data(cubemap, f);
    plod__channel_map(source->channels, plod_cubemap_channels(cubemap), job->channel_map);
    if (plod_cubemap_face_count(cubemap) == 1) {
        job->rows_total = job->n;
        job->weight_total = job->n;
    } else {
        job->rotated_equator = plod__equator_rotates(cubemap);
        job->polar_mirror = job->rotated_equator && plod__poles_mirror(cubemap);
        job->rows_total = !job->rotated_equator ? 6 * job->n : job->polar_mirror ? 2 * job->n
                                                                                : 3 * job->n;
        job->weight_total = 6.0 * job->n;
    }
    job->chunks_total = (job->rows_total + PLOD__CHUNK_ROWS - 1) / PLOD__CHUNK_ROWS;
    atomic_init(&job->next_chunk, 0);
    atomic_init(&job->cancel, 0);
    atomic_init(&job->failed, PLOD_OK);
    atomic_init(&job->done_weight, 0);

    job->progress = progress;
    job->user = user;
    /* workers take chunks from one queue: any number of them (a worker
     * whose thread cannot start finds it empty) gives the same output */
    int workers = threads < job->chunks_total ? threads : job->chunks_total;
    plod_parallel_for((size_t)(workers > 1 ? workers : 1), workers, plod__resample_workers, job);

    plod_status status = (plod_status)atomic_load(&job->failed);
    if (status == PLOD_OK && atomic_load(&job->cancel))
        status = PLOD_ERR_CANCELLED;
    if (status == PLOD_OK && progress && progress(user, 1.0))
        status = PLOD_ERR_CANCELLED;
    free(job);
    if (status == PLOD_OK)
        status = plod_cubemap_build_pyramid(cubemap);
    return status;
}

plod_status plod_resample_car_to_cube(plod_cubemap *cubemap, const plod_image *source,
                                      plod_filter filter, plod_progress_fn progress, void *user)
{
    return plod_resample_car_to_cube_threads(cubemap, source, filter, 2, progress, user);
}

/* ======================================================================== */
/* conversions and the cross layout                                         */
/* ======================================================================== */

/* Copies a w x h block of texels, converting type and channels; rows of the
 * destination are taken bottom-up from the source when `flip`. */
static void plod__copy_block(plod_texel_type src_type, const void *src, int src_channels,
                             size_t src_stride, plod_texel_type dst_type, void *dst,
                             int dst_channels, size_t dst_stride, int w, int h, int flip)
{
    int map[4];
    plod__channel_map(src_channels, dst_channels, map);
    for (int y = 0; y < h; y++) {
        size_t src_row = (size_t)(flip ? h - 1 - y : y) * src_stride;
        size_t dst_row = (size_t)y * dst_stride;
        if (src_type == dst_type && src_channels == dst_channels) {
            size_t bytes = (size_t)w * (size_t)src_channels * plod_image_texel_bytes(src_type);
            memcpy((char *)dst + dst_row * plod_image_texel_bytes(dst_type),
                   (const char *)src + src_row * plod_image_texel_bytes(src_type), bytes);
            continue;
        }
        for (int x = 0; x < w; x++) {
            for (int k = 0; k < dst_channels; k++) {
                double value = map[k] < 0 ? 1.0
                                          : plod__read_norm(src_type, src,
                                                            src_row + (size_t)x * src_channels +
                                                                (size_t)map[k]);
                plod__write_norm(dst_type, dst, dst_row + (size_t)x * dst_channels + (size_t)k,
                                 value);
            }
        }
    }
}

plod_status plod_image_convert(plod_image *out, const plod_image *image, int channels,
                               plod_texel_type type)
{
    if (!out || !image || !image->pixels)
        return PLOD_ERR_NULL;
    plod_status s = plod_image_alloc(out, image->width, image->height, channels, type);
    if (s != PLOD_OK)
        return s;
    plod__copy_block(image->type, image->pixels, image->channels,
                     (size_t)image->width * (size_t)image->channels, type, out->pixels, channels,
                     (size_t)image->width * (size_t)channels, image->width, image->height, 0);
    return PLOD_OK;
}

/* Cross cell (column, row from the top) of each face. */
static const int plod__cross_cell[PLOD_FACE_COUNT][2] = {
    {0, 0}, {0, 1}, {1, 1}, {2, 1}, {3, 1}, {0, 2},
};

plod_status plod_cubemap_to_image(plod_image *image, const plod_cubemap *cubemap, int layout_cross,
                                  int face, int channels, plod_texel_type type)
{
    if (!image || !cubemap)
        return PLOD_ERR_NULL;
    image->pixels = NULL;
    int n = plod_cubemap_size(cubemap);
    int fw = plod_cubemap_face_width(cubemap);
    int cube = plod_cubemap_face_count(cubemap) == PLOD_FACE_COUNT;
    if (channels < 1 || channels > 4 || (unsigned)type >= PLOD_TEXEL_TYPE_COUNT)
        return PLOD_ERR_BAD_PARAM;
    if (layout_cross && !cube)
        layout_cross = 0, face = 0; /* a CAR map is its own layout */
    if (!layout_cross && (face < 0 || face >= plod_cubemap_face_count(cubemap)))
        return PLOD_ERR_BAD_PARAM;
    if ((size_t)n > (size_t)INT32_MAX / 4)
        return PLOD_ERR_BAD_PARAM;
    plod_status s = layout_cross ? plod_image_alloc(image, 4 * n, 3 * n, channels, type)
                                 : plod_image_alloc(image, fw, n, channels, type);
    if (s != PLOD_OK)
        return s;
    int src_channels = plod_cubemap_channels(cubemap);
    size_t dst_stride = (size_t)image->width * (size_t)channels;
    int first = layout_cross ? 0 : face;
    int last = layout_cross ? PLOD_FACE_COUNT - 1 : face;
    for (int f = first; f <= last; f++) {
        size_t offset = 0;
        if (layout_cross)
            offset = (size_t)plod__cross_cell[f][1] * (size_t)n * dst_stride +
                     (size_t)plod__cross_cell[f][0] * (size_t)n * (size_t)channels;
        /* face rows run along +v, image rows top-down: flip */
        plod__copy_block(plod_cubemap_texel_type(cubemap), plod_cubemap_face_data_const(cubemap, f),
                         src_channels, (size_t)fw * (size_t)src_channels, type,
                         (char *)image->pixels + offset * plod_image_texel_bytes(type), channels,
                         dst_stride, fw, n, 1);
    }
    return PLOD_OK;
}

plod_status plod_cubemap_to_cross(plod_image *image, const plod_cubemap *cubemap)
{
    if (!cubemap)
        return PLOD_ERR_NULL;
    return plod_cubemap_to_image(image, cubemap, 1, 0, plod_cubemap_channels(cubemap),
                                 plod_cubemap_texel_type(cubemap));
}

plod_status plod_cubemap_face_to_image(plod_image *image, const plod_cubemap *cubemap, int face)
{
    if (!cubemap)
        return PLOD_ERR_NULL;
    return plod_cubemap_to_image(image, cubemap, 0, face, plod_cubemap_channels(cubemap),
                                 plod_cubemap_texel_type(cubemap));
}

plod_status plod_cubemap_from_cross(plod_cubemap **out, const plod_image *cross,
                                    plod_projection projection)
{
    if (!out || !cross || !cross->pixels)
        return PLOD_ERR_NULL;
    *out = NULL;
    if (!plod_projection_is_cube(projection))
        return PLOD_ERR_BAD_PROJECTION;
    if (cross->width < 4 || cross->width % 4 != 0 || cross->width / 4 * 3 != cross->height)
        return PLOD_ERR_BAD_IMAGE;
    int n = cross->width / 4;
    plod_cubemap *m;
    plod_status s = plod_cubemap_create(&m, projection, n, cross->channels, cross->type);
    if (s != PLOD_OK)
        return s;
    size_t stride = (size_t)cross->width * (size_t)cross->channels;
    for (int f = 0; f < PLOD_FACE_COUNT; f++) {
        size_t offset = (size_t)plod__cross_cell[f][1] * (size_t)n * stride +
                        (size_t)plod__cross_cell[f][0] * (size_t)n * (size_t)cross->channels;
        plod__copy_block(cross->type, (const char *)cross->pixels + offset * plod_image_texel_bytes(cross->type),
                         cross->channels, stride, cross->type, plod_cubemap_face_data(m, f),
                         cross->channels, (size_t)n * (size_t)cross->channels, n, n, 1);
    }
    s = plod_cubemap_build_pyramid(m);
    if (s != PLOD_OK) {
        plod_cubemap_destroy(m);
        return s;
    }
    *out = m;
    return PLOD_OK;
}
