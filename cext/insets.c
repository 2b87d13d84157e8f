/* insets.c -- regional high-resolution height grids placed by longitude and
 * latitude over the planet's global data (plod_heightsource.h): bilinear
 * samples in metres, blended into the global height across a feathered
 * border (a smoothstep of the distance to the inset's edge), with voids
 * (NaN) falling back to the global data.  Edges shared with a neighbouring
 * inset are not feathered, so a mosaic of tiles (SRTM 1 deg x 1 deg) is one
 * surface; its outer border blends into the global map.
 */
#include "plod_heightsource.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Min/max pyramid of the samples: blocks of 4, 8, 16 and 32 samples. */
#define PLOD__INSET_LEVELS 4
#define PLOD__INSET_FINEST 4

typedef struct plod__inset {
    double west, south, east, north; /* degrees: the corner samples */
    int width, height;
    float *metres;                   /* row 0 north */
    int shared[4];                   /* west, east, south, north edge shared */
    double feather;                  /* degrees */
    double texel_angle;              /* radians: the north-south sample spacing */
    double mosaic_texel_angle;       /* radians: the coarsest over its mosaic */
    double lo, hi;                   /* metres, NaN-free */
    int blocks_x[PLOD__INSET_LEVELS], blocks_y[PLOD__INSET_LEVELS];
    float *block_lo[PLOD__INSET_LEVELS], *block_hi[PLOD__INSET_LEVELS]; /* voids left out:
                                        +inf / -inf for a block of voids */
} plod__inset;

struct plod_insets {
    plod__inset *items;
    size_t count;
    double lo, hi;
};

void plod_insets_destroy(plod_insets *insets)
{
    if (!insets)
        return;
    for (size_t i = 0; i < insets->count; i++) {
        free(insets->items[i].metres);
        for (int l = 0; l < PLOD__INSET_LEVELS; l++) {
            free(insets->items[i].block_lo[l]);
            free(insets->items[i].block_hi[l]);
        }
    }
    free(insets->items);
    free(insets);
}

/* Whether edge `side` of a is covered by b along its whole length. */
static int plod__edge_shared(const plod__inset *a, const plod__inset *b, int side)
{
    const double eps = 1e-9;
    switch (side) {
    case 0: return fabs(b->east - a->west) < eps && b->south <= a->south + eps && b->north >= a->north - eps;
    case 1: return fabs(b->west - a->east) < eps && b->south <= a->south + eps && b->north >= a->north - eps;
    case 2: return fabs(b->north - a->south) < eps && b->west <= a->west + eps && b->east >= a->east - eps;
    default: return fabs(b->south - a->north) < eps && b->west <= a->west + eps && b->east >= a->east - eps;
    }
}

plod_status plod_insets_create(plod_insets **out, const plod_inset_desc *descs, size_t count,
                               double feather, char *message, size_t message_size)
{
    plod_status_format(message, message_size, "%s", "");
    if (!out || (!descs && count))
        return PLOD_ERR_NULL;
    *out = NULL;
    if (!(feather >= 0.0 && feather <= 0.5)) {
        plod_status_format(message, message_size, "feather %g outside 0..0.5", feather);
        return PLOD_ERR_BAD_PARAM;
    }
    for (size_t i = 0; i < count; i++) {
        const plod_inset_desc *d = &descs[i];
        if (!d->metres || d->width < 2 || d->height < 2 || !(d->west < d->east) ||
            !(d->south < d->north) || d->west < -180.0 || d->east > 180.0 ||
            d->south < -90.0 || d->north > 90.0) {
            plod_status_format(message, message_size,
                                "inset %zu: %dx%d samples over lon %g..%g, lat %g..%g: needs 2x2 "
                                "samples or more, west < east within -180..180 (none across "
                                "the date line), south < north within -90..90",
                                i, d->width, d->height, d->west, d->east, d->south, d->north);
            return PLOD_ERR_BAD_PARAM;
        }
        for (size_t j = 0; j < i; j++) {
            const plod_inset_desc *e = &descs[j];
            if (d->west < e->east && e->west < d->east && d->south < e->north &&
                e->south < d->north) {
                plod_status_format(message, message_size,
                                    "insets %zu and %zu overlap (lon %g..%g, lat %g..%g and lon "
                                    "%g..%g, lat %g..%g); give each area once",
                                    j, i, e->west, e->east, e->south, e->north, d->west, d->east,
                                    d->south, d->north);
                return PLOD_ERR_BAD_PARAM;
            }
        }
    }
    plod_insets *s = calloc(1, sizeof *s);
    if (!s || !(s->items = calloc(count ? count : 1, sizeof *s->items))) {
        free(s);
        return PLOD_ERR_NO_MEMORY;
    }
    s->count = count;
    s->lo = INFINITY, s->hi = -INFINITY;
    for (size_t i = 0; i < count; i++) {
        const plod_inset_desc *d = &descs[i];
        plod__inset *t = &s->items[i];
        t->west = d->west, t->south = d->south, t->east = d->east, t->north = d->north;
        t->width = d->width, t->height = d->height;
        size_t n = (size_t)d->width * (size_t)d->height;
        t->metres = malloc(n * sizeof *t->metres);
        int ok = t->metres != NULL;
        for (int l = 0; l < PLOD__INSET_LEVELS; l++) {
            int size = PLOD__INSET_FINEST << l;
            t->blocks_x[l] = (d->width + size - 1) / size;
            t->blocks_y[l] = (d->height + size - 1) / size;
            size_t blocks = (size_t)t->blocks_x[l] * (size_t)t->blocks_y[l];
            t->block_lo[l] = malloc(blocks * sizeof(float));
            t->block_hi[l] = malloc(blocks * sizeof(float));
            ok = ok && t->block_lo[l] && t->block_hi[l];
            for (size_t b = 0; ok && b < blocks; b++)
                t->block_lo[l][b] = INFINITY, t->block_hi[l][b] = -INFINITY;
        }
        if (!ok) {
            plod_insets_destroy(s);
            return PLOD_ERR_NO_MEMORY;
        }
        memcpy(t->metres, d->metres, n * sizeof *t->metres);
        t->lo = INFINITY, t->hi = -INFINITY;
        for (int y = 0; y < d->height; y++)
            for (int x = 0; x < d->width; x++) {
                float v = t->metres[(size_t)y * (size_t)d->width + (size_t)x];
                if (!isfinite(v)) {
                    t->metres[(size_t)y * (size_t)d->width + (size_t)x] = NAN; /* a void */
                    continue;
                }
                size_t b = (size_t)(y / PLOD__INSET_FINEST) * (size_t)t->blocks_x[0] +
                           (size_t)(x / PLOD__INSET_FINEST);
                t->block_lo[0][b] = v < t->block_lo[0][b] ? v : t->block_lo[0][b];
                t->block_hi[0][b] = v > t->block_hi[0][b] ? v : t->block_hi[0][b];
                t->lo = v < t->lo ? v : t->lo;
                t->hi = v > t->hi ? v : t->hi;
            }
        for (int l = 1; l < PLOD__INSET_LEVELS; l++) /* each block: its 2 x 2 finer ones */
            for (int y = 0; y < t->blocks_y[l - 1]; y++)
                for (int x = 0; x < t->blocks_x[l - 1]; x++) {
                    size_t f = (size_t)y * (size_t)t->blocks_x[l - 1] + (size_t)x;
                    size_t b = (size_t)(y / 2) * (size_t)t->blocks_x[l] + (size_t)(x / 2);
                    float lo = t->block_lo[l - 1][f], hi = t->block_hi[l - 1][f];
                    t->block_lo[l][b] = lo < t->block_lo[l][b] ? lo : t->block_lo[l][b];
                    t->block_hi[l][b] = hi > t->block_hi[l][b] ? hi : t->block_hi[l][b];
                }
        double span = fmin(d->east - d->west, d->north - d->south);
        t->feather = feather * span;
        if (t->lo <= t->hi) {
            s->lo = t->lo < s->lo ? t->lo : s->lo;
            s->hi = t->hi > s->hi ? t->hi : s->hi;
        }
    }
    for (size_t i = 0; i < count; i++) {
        plod__inset *t = &s->items[i];
        t->texel_angle = (t->north - t->south) / (t->height - 1) * PLOD_PI / 180.0;
        t->mosaic_texel_angle = t->texel_angle;
    }
    for (size_t i = 0; i < count; i++)
        for (int side = 0; side < 4; side++)
            for (size_t j = 0; j < count; j++)
                if (j != i && plod__edge_shared(&s->items[i], &s->items[j], side))
                    s->items[i].shared[side] = 1;
    /* the coarsest spacing over each mosaic: spread along shared edges
     * (either side's) until nothing changes; at most count rounds */
    for (int changed = 1; changed;) {
        changed = 0;
        for (size_t i = 0; i < count; i++)
            for (size_t j = 0; j < count; j++) {
                plod__inset *a = &s->items[i], *b = &s->items[j];
                if (j == i || !(b->mosaic_texel_angle > a->mosaic_texel_angle))
                    continue;
                for (int side = 0; side < 4; side++)
                    if (plod__edge_shared(a, b, side) || plod__edge_shared(b, a, side)) {
                        a->mosaic_texel_angle = b->mosaic_texel_angle;
                        changed = 1;
                        break;
                    }
            }
    }
    *out = s;
    return PLOD_OK;
}

size_t plod_insets_count(const plod_insets *insets) { return insets ? insets->count : 0; }

void plod_insets_global_range(const plod_insets *insets, double *lo, double *hi)
{
    *lo = insets->lo;
    *hi = insets->hi;
}

static void plod__inset_lonlat(const double dir[3], double *lon, double *lat)
{
    const double deg = 180.0 / PLOD_PI;
    *lon = atan2(dir[1], dir[0]) * deg;
    *lat = atan2(dir[2], hypot(dir[0], dir[1])) * deg;
}

static double plod__smoothstep(double x)
{
    x = x < 0.0 ? 0.0 : x > 1.0 ? 1.0 : x;
    return x * x * (3.0 - 2.0 * x);
}

double plod_insets_blend(const plod_insets *insets, const double dir[3], double base_m,
                         double *texel_angle)
{
    return plod_insets_blend_weight(insets, dir, base_m, texel_angle, NULL);
}

double plod_insets_blend_weight(const plod_insets *insets, const double dir[3], double base_m,
                                double *texel_angle, plod_inset_weight *where)
{
    if (texel_angle)
        *texel_angle = 0.0;
    if (where)
        where->weight = where->mosaic_texel_angle = 0.0;
    if (!insets || !insets->count)
        return base_m;
    double lon, lat;
    plod__inset_lonlat(dir, &lon, &lat);
    for (size_t i = 0; i < insets->count; i++) {
        const plod__inset *t = &insets->items[i];
        if (lon < t->west || lon > t->east || lat < t->south || lat > t->north)
            continue;
        double d = INFINITY;
        if (!t->shared[0]) d = fmin(d, lon - t->west);
        if (!t->shared[1]) d = fmin(d, t->east - lon);
        if (!t->shared[2]) d = fmin(d, lat - t->south);
        if (!t->shared[3]) d = fmin(d, t->north - lat);
        double w = t->feather > 0.0 ? plod__smoothstep(d / t->feather) : (d >= 0.0 ? 1.0 : 0.0);
        if (!(w > 0.0))
            return base_m;
        /* corner samples: pixel is point */
        double s = (lon - t->west) / (t->east - t->west) * (t->width - 1);
        double r = (t->north - lat) / (t->north - t->south) * (t->height - 1);
        double fi = floor(s), fj = floor(r);
        int i0 = (int)fi, j0 = (int)fj;
        if (i0 >= t->width - 1) i0 = t->width - 2;
        if (j0 >= t->height - 1) j0 = t->height - 2;
        if (i0 < 0) i0 = 0;
        if (j0 < 0) j0 = 0;
        double wu = s - i0, wv = r - j0;
        const float *p = t->metres + (size_t)j0 * (size_t)t->width + (size_t)i0;
        double a = p[0], b = p[1], c = p[t->width], e = p[t->width + 1];
        double top = a + wu * (b - a), bottom = c + wu * (e - c);
        double value = top + wv * (bottom - top);
        if (!(value == value))
            return base_m; /* a void: the global data */
        if (texel_angle)
            *texel_angle = t->texel_angle;
        if (where) {
            where->weight = w < 1.0 ? w : 1.0;
            where->mosaic_texel_angle = t->mosaic_texel_angle;
        }
        return w >= 1.0 ? value : base_m + w * (value - base_m);
    }
    return base_m;
}

/* The lon/lat box around a spherical cap (degrees): latitudes lat0..lat1,
 * longitudes lon +- half_lon (180: all). */
typedef struct plod__cap_box {
    double lat0, lat1, lon, half_lon;
} plod__cap_box;

static plod__cap_box plod__cap_box_of(const double axis[3], double angle)
{
    const double deg = 180.0 / PLOD_PI;
    plod__cap_box box;
    double lat = asin(fmax(-1.0, fmin(1.0, axis[2]))) * deg;
    box.lon = atan2(axis[1], axis[0]) * deg;
    double a = angle * deg;
    box.lat0 = lat - a, box.lat1 = lat + a;
    if (!(angle >= 0.0) || angle >= 0.5 * PLOD_PI || box.lat1 >= 90.0 || box.lat0 <= -90.0)
        box.half_lon = 180.0;
    else
        box.half_lon = asin(fmin(1.0, sin(angle) / cos(lat / deg))) * deg;
    return box;
}

static int plod__cap_box_meets(const plod__cap_box *box, const plod__inset *t)
{
    if (box->lat1 < t->south || box->lat0 > t->north)
        return 0;
    double w0 = box->lon - box->half_lon, w1 = box->lon + box->half_lon;
    int hit = box->half_lon >= 180.0;
    for (int k = -1; k <= 1 && !hit; k++) /* the box, also shifted across the date line */
        hit = w0 + 360.0 * k <= t->east && w1 + 360.0 * k >= t->west;
    return hit;
}

double plod_insets_mosaic_texel_cap(const plod_insets *insets, const double axis[3],
                                    double angle)
{
    if (!insets || !insets->count)
        return 0.0;
    plod__cap_box box = plod__cap_box_of(axis, angle);
    double widest = 0.0;
    for (size_t i = 0; i < insets->count; i++) {
        const plod__inset *t = &insets->items[i];
        if (plod__cap_box_meets(&box, t) && t->mosaic_texel_angle > widest)
            widest = t->mosaic_texel_angle;
    }
    return widest;
}

int plod_insets_range_cap(const plod_insets *insets, const double axis[3], double angle,
                          double *lo_out, double *hi_out, plod_insets_relief *relief)
{
    if (!insets || !insets->count)
        return 0;
    plod__cap_box box = plod__cap_box_of(axis, angle);
    double lon = box.lon, half_lon = box.half_lon, lat0 = box.lat0, lat1 = box.lat1;
    double lo = INFINITY, hi = -INFINITY, texel_angle = 0.0, per_sample = 0.0;
    int any = 0;
    for (size_t i = 0; i < insets->count; i++) {
        const plod__inset *t = &insets->items[i];
        if (!plod__cap_box_meets(&box, t))
            continue;
        double w0 = lon - half_lon, w1 = lon + half_lon;
        any = 1;
        texel_angle = t->mosaic_texel_angle > texel_angle ? t->mosaic_texel_angle : texel_angle;
        /* the samples under the box (clamped to the inset), whole inset when wide */
        double x0 = half_lon >= 180.0 ? t->west : fmax(t->west, w0), x1 = half_lon >= 180.0 ? t->east : fmin(t->east, w1);
        if (!(x0 <= x1)) /* hit through the date line shift: the whole inset */
            x0 = t->west, x1 = t->east;
        double y0 = fmax(t->south, lat0), y1 = fmin(t->north, lat1);
        int c0 = (int)floor((x0 - t->west) / (t->east - t->west) * (t->width - 1)) - 1;
        int c1 = (int)floor((x1 - t->west) / (t->east - t->west) * (t->width - 1)) + 2;
        int r0 = (int)floor((t->north - y1) / (t->north - t->south) * (t->height - 1)) - 1;
        int r1 = (int)floor((t->north - y0) / (t->north - t->south) * (t->height - 1)) + 2;
        c0 = c0 < 0 ? 0 : c0, r0 = r0 < 0 ? 0 : r0;
        c1 = c1 >= t->width ? t->width - 1 : c1, r1 = r1 >= t->height ? t->height - 1 : r1;
        /* the finest pyramid level with at most 8 x 8 blocks there */
        int l = 0;
        while (l + 1 < PLOD__INSET_LEVELS &&
               ((c1 - c0) / (PLOD__INSET_FINEST << l) > 7 ||
                (r1 - r0) / (PLOD__INSET_FINEST << l) > 7))
            l++;
        int size = PLOD__INSET_FINEST << l;
        double ilo = INFINITY, ihi = -INFINITY;
        for (int by = r0 / size; by <= r1 / size; by++)
            for (int bx = c0 / size; bx <= c1 / size; bx++) {
                size_t b = (size_t)by * (size_t)t->blocks_x[l] + (size_t)bx;
                if (t->block_lo[l][b] < ilo) ilo = t->block_lo[l][b];
                if (t->block_hi[l][b] > ihi) ihi = t->block_hi[l][b];
            }
        int across = (c1 / size - c0 / size) > (r1 / size - r0 / size) ? (c1 / size - c0 / size)
                                                                       : (r1 / size - r0 / size);
        if (ilo <= ihi) {
            lo = ilo < lo ? ilo : lo;
            hi = ihi > hi ? ihi : hi;
            double slope = (ihi - ilo) / ((double)(across + 1) * size);
            per_sample = slope > per_sample ? slope : per_sample;
        }
    }
    if (!any)
        return 0;
    *lo_out = lo;
    *hi_out = hi;
    if (relief) {
        relief->texel_angle = texel_angle;
        relief->per_sample = per_sample;
    }
    return 1;
}
