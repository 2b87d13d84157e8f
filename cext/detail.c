/* detail.c -- the procedural detail field (see plod_detail.h).
 *
 * Octave i maps the unit direction d into its lattice by p = M_i d + o_i,
 * M_i = (radius / wavelength_i) R^i with R a fixed rotation (so no two
 * octaves share lattice axes and the grid never shows) and o_i a seeded
 * offset.  Lattice coordinates stay below 2^53, so floor() is exact and
 * integer corner hashes do not depend on the platform.  Gradients are
 * analytic (the quintic fade of Perlin's improved noise has continuous
 * second derivatives), mapped back by M_i^T.
 */
#include "plod_detail.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PLOD__DETAIL_PI PLOD_PI
/* error table over binades of the cell size: 2^e metres, e in [MIN, MAX] */
#define PLOD__ERR_EXP_MIN (-48)
#define PLOD__ERR_EXP_MAX 72
#define PLOD__ERR_COUNT (PLOD__ERR_EXP_MAX - PLOD__ERR_EXP_MIN + 1)
/* crater profile, in crater radii r: bowl floor -1 at 0, rim +RIM at 1,
 * ejecta to 0 at REACH; a crater's reach stays inside its lattice cell */
#define PLOD__CRATER_RIM 0.3
#define PLOD__CRATER_REACH 2.0
#define PLOD__CRATER_MAX_RADIUS 0.25
#define PLOD__CRATER_MIN_RADIUS 0.3 /* of the largest, inside one octave */
#define PLOD__CRATER_SMALLEST 0.04  /* lattice units: no smaller crater */
/* |grad n| of improved noise per lattice unit: per axis, the blend of the
 * corner gradients' components (<= 1) plus the fade derivative (<= 15/8)
 * times the difference of two corner values (each |g . (x - c)| <= 2):
 * 8.5, so |grad n| <= 8.5 sqrt 3 < 15 */
#define PLOD__NOISE_LIPSCHITZ 15.0
#define PLOD__CRATER_DEPTH 2.0 /* crater depth per unit of octave amplitude */
#define PLOD__RIDGE_GAIN 2.0
#define PLOD__CRATER_HILLS 0.35 /* the CRATERS style's hills, relative */

typedef struct plod__octave {
    double m[3][3];  /* direction -> lattice */
    double offset[3];
    double wavelength, amplitude;
    double frequency; /* radius / wavelength: the sphere's radius in the lattice */
    uint64_t seed, crater_seed;
    double noise_weight, crater_weight; /* metres per unit of each layer */
    double lo, hi;   /* the octave's term's bounds, metres (lo <= 0 <= hi) */
    double slope;    /* bound of |grad term|, metres per unit of direction */
} plod__octave;

struct plod_detail {
    plod_detail_params params;
    double radius;
    const plod_cubemap *source; /* the height map it was built for (identity only) */
    plod_cubemap *modulation;   /* owned, or NULL */
    int count;
    plod__octave octaves[PLOD_DETAIL_MAX_OCTAVES];
    double lo, hi;              /* bounds of N */
    double tail_lo[PLOD_DETAIL_MAX_OCTAVES + 1], tail_hi[PLOD_DETAIL_MAX_OCTAVES + 1];
                                /* bounds of the octaves from i on */
    double err[PLOD__ERR_COUNT];
    uint64_t stamp;
};

void plod_detail_params_init(plod_detail_params *params)
{
    memset(params, 0, sizeof *params);
    params->style = PLOD_DETAIL_MOUNTAINS;
    params->roughness = 0.5;
    params->smallest = 0.1;
    params->crater_density = 0.5;
    params->plains = 0.15;
}

/* ---- hashing ------------------------------------------------------------- */

static uint64_t plod__mix(uint64_t h)
{
    h ^= h >> 32;
    h *= 0xd6e8feb86659fd93ULL;
    h ^= h >> 32;
    h *= 0xd6e8feb86659fd93ULL;
    h ^= h >> 32;
    return h;
}

#define PLOD__HX 0x9E3779B97F4A7C15ULL
#define PLOD__HY 0xC2B2AE3D27D4EB4FULL
#define PLOD__HZ 0x165667B19E3779F9ULL

/* corner hash: one multiply (its top bits pick a gradient) */
static uint64_t plod__mix_fast(uint64_t h)
{
    h ^= h >> 31;
    h *= 0xd6e8feb86659fd93ULL;
    h ^= h >> 32;
    return h;
}

/* floor for |x| < 2^62 without a libm call (exact: the integer part of a
 * double this size is representable) */
static double plod__floor(double x)
{
    double t = (double)(int64_t)x;
    return t > x ? t - 1.0 : t;
}

static double plod__unit(uint64_t h) /* [0, 1) from the top 53 bits */
{
    return (double)(h >> 11) * (1.0 / 9007199254740992.0);
}

/* ---- gradient noise with its gradient -------------------------------------- */

/* the 12 cube-edge gradients of improved noise, 4 repeated to make 16 */
static const signed char plod__grad[16][3] = {
    {1, 1, 0}, {-1, 1, 0}, {1, -1, 0}, {-1, -1, 0}, {1, 0, 1}, {-1, 0, 1},
    {1, 0, -1}, {-1, 0, -1}, {0, 1, 1}, {0, -1, 1}, {0, 1, -1}, {0, -1, -1},
    {1, 1, 0}, {-1, 1, 0}, {0, -1, 1}, {0, -1, -1}};

/* Improved noise at lattice point p, clamped to [-1, 1] (its extremes are
 * within ~1 already; the clamp makes the bound exact); g: d n / d p. */
static double plod__gnoise(const double p[3], uint64_t seed, double g[3])
{
    double fx = plod__floor(p[0]), fy = plod__floor(p[1]), fz = plod__floor(p[2]);
    double x = p[0] - fx, y = p[1] - fy, z = p[2] - fz;
    uint64_t base = (uint64_t)(int64_t)fx * PLOD__HX + (uint64_t)(int64_t)fy * PLOD__HY +
                    (uint64_t)(int64_t)fz * PLOD__HZ + seed;
    double val[8], gr[8][3];
    for (int c = 0; c < 8; c++) {
        int cx = c & 1, cy = (c >> 1) & 1, cz = (c >> 2) & 1;
        uint64_t h = plod__mix_fast(base + (cx ? PLOD__HX : 0) + (cy ? PLOD__HY : 0) +
                                    (cz ? PLOD__HZ : 0));
        const signed char *q = plod__grad[h >> 60];
        gr[c][0] = q[0], gr[c][1] = q[1], gr[c][2] = q[2];
        val[c] = q[0] * (x - cx) + q[1] * (y - cy) + q[2] * (z - cz);
    }
    double ux = x * x * x * (x * (x * 6.0 - 15.0) + 10.0);
    double uy = y * y * y * (y * (y * 6.0 - 15.0) + 10.0);
    double uz = z * z * z * (z * (z * 6.0 - 15.0) + 10.0);
    double dx = 30.0 * x * x * (x * (x - 2.0) + 1.0);
    double dy = 30.0 * y * y * (y * (y - 2.0) + 1.0);
    double dz = 30.0 * z * z * (z * (z - 2.0) + 1.0);
    /* corners a..h = 000 100 010 110 001 101 011 111 */
    double k0 = val[0], k1 = val[1] - val[0], k2 = val[2] - val[0], k3 = val[4] - val[0];
    double k4 = val[0] - val[1] - val[2] + val[3];
    double k5 = val[0] - val[2] - val[4] + val[6];
    double k6 = val[0] - val[1] - val[4] + val[5];
    double k7 = -val[0] + val[1] + val[2] - val[3] + val[4] - val[5] - val[6] + val[7];
    double n = k0 + k1 * ux + k2 * uy + k3 * uz + k4 * ux * uy + k5 * uy * uz + k6 * uz * ux +
               k7 * ux * uy * uz;
    for (int a = 0; a < 3; a++) {
        double g0 = gr[0][a], g1 = gr[1][a] - gr[0][a], g2 = gr[2][a] - gr[0][a],
               g3 = gr[4][a] - gr[0][a];
        double g4 = gr[0][a] - gr[1][a] - gr[2][a] + gr[3][a];
        double g5 = gr[0][a] - gr[2][a] - gr[4][a] + gr[6][a];
        double g6 = gr[0][a] - gr[1][a] - gr[4][a] + gr[5][a];
        double g7 = -gr[0][a] + gr[1][a] + gr[2][a] - gr[3][a] + gr[4][a] - gr[5][a] -
                    gr[6][a] + gr[7][a];
        g[a] = g0 + g1 * ux + g2 * uy + g3 * uz + g4 * ux * uy + g5 * uy * uz + g6 * uz * ux +
               g7 * ux * uy * uz;
    }
    g[0] += dx * (k1 + k4 * uy + k6 * uz + k7 * uy * uz);
    g[1] += dy * (k2 + k5 * uz + k4 * ux + k7 * uz * ux);
    g[2] += dz * (k3 + k6 * ux + k5 * uy + k7 * ux * uy);
    if (n > 1.0 || n < -1.0) {
        g[0] = g[1] = g[2] = 0.0;
        n = n > 0.0 ? 1.0 : -1.0;
    }
    return n;
}

/* plod__gnoise's value alone: the same operations in the same order, so
 * the same bits (height-only callers: bounds, heights without normals). */
static double plod__gnoise_value(const double p[3], uint64_t seed)
{
    double fx = plod__floor(p[0]), fy = plod__floor(p[1]), fz = plod__floor(p[2]);
    double x = p[0] - fx, y = p[1] - fy, z = p[2] - fz;
    uint64_t base = (uint64_t)(int64_t)fx * PLOD__HX + (uint64_t)(int64_t)fy * PLOD__HY +
                    (uint64_t)(int64_t)fz * PLOD__HZ + seed;
    double val[8];
    for (int c = 0; c < 8; c++) {
        int cx = c & 1, cy = (c >> 1) & 1, cz = (c >> 2) & 1;
        uint64_t h = plod__mix_fast(base + (cx ? PLOD__HX : 0) + (cy ? PLOD__HY : 0) +
                                    (cz ? PLOD__HZ : 0));
        const signed char *q = plod__grad[h >> 60];
        val[c] = q[0] * (x - cx) + q[1] * (y - cy) + q[2] * (z - cz);
    }
    double ux = x * x * x * (x * (x * 6.0 - 15.0) + 10.0);
    double uy = y * y * y * (y * (y * 6.0 - 15.0) + 10.0);
    double uz = z * z * z * (z * (z * 6.0 - 15.0) + 10.0);
    double k0 = val[0], k1 = val[1] - val[0], k2 = val[2] - val[0], k3 = val[4] - val[0];
    double k4 = val[0] - val[1] - val[2] + val[3];
    double k5 = val[0] - val[2] - val[4] + val[6];
    double k6 = val[0] - val[1] - val[4] + val[5];
    double k7 = -val[0] + val[1] + val[2] - val[3] + val[4] - val[5] - val[6] + val[7];
    double n = k0 + k1 * ux + k2 * uy + k3 * uz + k4 * ux * uy + k5 * uy * uz + k6 * uz * ux +
               k7 * ux * uy * uz;
    if (n > 1.0 || n < -1.0)
        n = n > 0.0 ? 1.0 : -1.0;
    return n;
}

/* ---- craters --------------------------------------------------------------- */

/* Crater profile at x = distance / r, in units of depth; dprof: d/dx. */
static double plod__crater_profile(double x, double *dprof)
{
    if (x < 1.0) { /* parabolic bowl up to the rim */
        *dprof = 2.0 * (1.0 + PLOD__CRATER_RIM) * x;
        return -1.0 + (1.0 + PLOD__CRATER_RIM) * x * x;
    }
    if (x >= PLOD__CRATER_REACH) {
        *dprof = 0.0;
        return 0.0;
    }
    /* ejecta: rim * (1 - t)^3, flat where it meets the plain */
    double t = (x - 1.0) * (1.0 / (PLOD__CRATER_REACH - 1.0)), s = 1.0 - t;
    *dprof = -3.0 * PLOD__CRATER_RIM * s * s * (1.0 / (PLOD__CRATER_REACH - 1.0));
    return PLOD__CRATER_RIM * s * s * s;
}

/* The crater of the lattice cell holding p (lattice units; the sphere is
 * |p - centre| = radius there), in units of depth; 0 outside any crater.
 * The crater centre is a seeded point of the cell moved onto the sphere;
 * a crater whose reach would leave its cell is dropped, so every cell
 * boundary has height 0 and slope 0: seamless. */
static double plod__crater(const double p[3], const double centre[3], double radius,
                           uint64_t seed, double density, double g[3])
{
    g[0] = g[1] = g[2] = 0.0;
    double fx = plod__floor(p[0]), fy = plod__floor(p[1]), fz = plod__floor(p[2]);
    uint64_t h = plod__mix((uint64_t)(int64_t)fx * PLOD__HX + (uint64_t)(int64_t)fy * PLOD__HY +
                           (uint64_t)(int64_t)fz * PLOD__HZ + seed);
    if (plod__unit(h) >= density)
        return 0.0;
    double c[3] = {fx + plod__unit(plod__mix(h + 1)), fy + plod__unit(plod__mix(h + 2)),
                   fz + plod__unit(plod__mix(h + 3))};
    double w[3] = {c[0] - centre[0], c[1] - centre[1], c[2] - centre[2]};
    double len = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
    if (!(len > 0.0))
        return 0.0;
    double s = radius / len;
    c[0] = centre[0] + w[0] * s, c[1] = centre[1] + w[1] * s, c[2] = centre[2] + w[2] * s;
    /* many small craters, few large ones inside a class: r^-2; a crater
     * shrinks to the room its cell leaves around the centre, and one
     * with too little room is dropped (its slope stays bounded) */
    double q = plod__unit(plod__mix(h + 4));
    double r = PLOD__CRATER_MAX_RADIUS *
               (PLOD__CRATER_MIN_RADIUS + (1.0 - PLOD__CRATER_MIN_RADIUS) * q * q);
    double room = 0.5;
    for (int a = 0; a < 3; a++) {
        double lo = c[a] - (a == 0 ? fx : (a == 1 ? fy : fz)), hi = 1.0 - lo;
        room = lo < room ? lo : room;
        room = hi < room ? hi : room;
    }
    if (r * PLOD__CRATER_REACH > room)
        r = room * (1.0 / PLOD__CRATER_REACH);
    if (!(r >= PLOD__CRATER_SMALLEST))
        return 0.0;
    double reach = PLOD__CRATER_REACH * r;
    double d[3] = {p[0] - c[0], p[1] - c[1], p[2] - c[2]};
    double dist2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    if (dist2 >= reach * reach)
        return 0.0;
    double dist = sqrt(dist2), dprof;
    double value = plod__crater_profile(dist / r, &dprof);
    if (dist > 0.0) {
        double k = dprof / (r * dist);
        g[0] = k * d[0], g[1] = k * d[1], g[2] = k * d[2];
    }
    return value;
}

/* ---- the field ------------------------------------------------------------- */

static void plod__lattice(const plod__octave *o, const double dir[3], double p[3])
{
    for (int a = 0; a < 3; a++)
        p[a] = o->m[a][0] * dir[0] + o->m[a][1] * dir[1] + o->m[a][2] * dir[2] + o->offset[a];
}

/* lattice gradient -> direction gradient (M^T g), scaled, added to acc */
static void plod__add_gradient(const plod__octave *o, const double g[3], double scale,
                               double acc[3])
{
    for (int a = 0; a < 3; a++)
        acc[a] += scale * (o->m[0][a] * g[0] + o->m[1][a] * g[1] + o->m[2][a] * g[2]);
}

/* plod_detail_noise without the gradient: the same sum, bit for bit. */
static double plod__noise_value(const plod_detail *detail, const double dir[3], int octaves)
{
    double sum = 0.0;
    int ridged = detail->params.style == PLOD_DETAIL_MOUNTAINS;
    double weight = 1.0;
    for (int i = 0; i < octaves; i++) {
        const plod__octave *o = &detail->octaves[i];
        double p[3], g[3];
        plod__lattice(o, dir, p);
        if (o->noise_weight != 0.0) {
            double n = plod__gnoise_value(p, o->seed);
            if (!ridged) {
                sum += o->noise_weight * n;
            } else {
                double an = n < 0.0 ? -n : n;
                double s = (1.0 - an) * (1.0 - an);
                sum += o->noise_weight * weight * (s - 0.5);
                double next = PLOD__RIDGE_GAIN * s;
                weight = next >= 1.0 ? 1.0 : next;
            }
        }
        if (o->crater_weight != 0.0) {
            double cp[3] = {p[0] + 0.5, p[1] + 0.5, p[2] + 0.5};
            double centre[3] = {o->offset[0] + 0.5, o->offset[1] + 0.5, o->offset[2] + 0.5};
            double value = plod__crater(cp, centre, o->frequency, o->crater_seed,
                                        detail->params.crater_density, g);
            if (value != 0.0)
                sum += o->crater_weight * value;
        }
    }
    return sum;
}

double plod_detail_noise(const plod_detail *detail, const double dir[3], int octaves,
                         double gradient[3])
{
    double acc[3] = {0.0, 0.0, 0.0};
    double sum = 0.0;
    if (octaves > detail->count)
        octaves = detail->count;
    if (!(fabs(dir[0]) <= 2.0 && fabs(dir[1]) <= 2.0 && fabs(dir[2]) <= 2.0)) {
        if (gradient) /* not a unit direction (NaN): no lattice to read */
            gradient[0] = gradient[1] = gradient[2] = NAN;
        return NAN;
    }
    if (!gradient)
        return plod__noise_value(detail, dir, octaves);
    int ridged = detail->params.style == PLOD_DETAIL_MOUNTAINS;
    double weight = 1.0, dweight[3] = {0.0, 0.0, 0.0}; /* ridged: previous signal */
    for (int i = 0; i < octaves; i++) {
        const plod__octave *o = &detail->octaves[i];
        double p[3], g[3];
        plod__lattice(o, dir, p);
        if (o->noise_weight != 0.0) {
            double n = plod__gnoise(p, o->seed, g);
            if (!ridged) {
                sum += o->noise_weight * n;
                plod__add_gradient(o, g, o->noise_weight, acc);
            } else {
                /* signal s = (1 - |n|)^2 in [0, 1]; term w (s - 1/2) */
                double an = n < 0.0 ? -n : n, sign = n < 0.0 ? -1.0 : 1.0;
                double s = (1.0 - an) * (1.0 - an);
                double ds = -2.0 * (1.0 - an) * sign; /* per unit of n */
                double a = o->noise_weight;
                sum += a * weight * (s - 0.5);
                double dl[3] = {a * weight * ds * g[0], a * weight * ds * g[1],
                                a * weight * ds * g[2]}; /* lattice units */
                plod__add_gradient(o, dl, 1.0, acc);
                for (int k = 0; k < 3; k++) /* dweight is per unit of direction */
                    acc[k] += a * (s - 0.5) * dweight[k];
                /* next weight: clamp(gain s, 0, 1) */
                double next = PLOD__RIDGE_GAIN * s;
                if (next >= 1.0) {
                    weight = 1.0;
                    dweight[0] = dweight[1] = dweight[2] = 0.0;
                } else {
                    weight = next;
                    double dd[3] = {0.0, 0.0, 0.0};
                    double dsg[3] = {PLOD__RIDGE_GAIN * ds * g[0], PLOD__RIDGE_GAIN * ds * g[1],
                                     PLOD__RIDGE_GAIN * ds * g[2]};
                    plod__add_gradient(o, dsg, 1.0, dd);
                    memcpy(dweight, dd, sizeof dd);
                }
            }
        }
        if (o->crater_weight != 0.0) {
            double cp[3] = {p[0] + 0.5, p[1] + 0.5, p[2] + 0.5}; /* its own cells */
            double centre[3] = {o->offset[0] + 0.5, o->offset[1] + 0.5, o->offset[2] + 0.5};
            double value = plod__crater(cp, centre, o->frequency, o->crater_seed,
                                        detail->params.crater_density, g);
            if (value != 0.0) {
                sum += o->crater_weight * value;
                plod__add_gradient(o, g, o->crater_weight, acc);
            }
        }
    }
    if (gradient)
        memcpy(gradient, acc, sizeof acc);
    return sum;
}

int plod_detail_octaves_for_cell(const plod_detail *detail, double cell)
{
    double need = PLOD_DETAIL_CELLS_PER_WAVE * cell;
    int k = 0;
    while (k < detail->count && detail->octaves[k].wavelength >= need)
        k++;
    return k;
}

void plod_detail_noise_range(const plod_detail *detail, double *lo, double *hi)
{
    *lo = detail->lo;
    *hi = detail->hi;
}

void plod_detail_local_range(const plod_detail *detail, const double dir[3], double reach,
                             double cell, double *lo, double *hi)
{
    *lo = detail->lo;
    *hi = detail->hi;
    int coarse = plod_detail_octaves_for_cell(detail, cell);
    double change = 0.0;
    for (int i = 0; i < coarse; i++) {
        const plod__octave *o = &detail->octaves[i];
        double width = o->hi - o->lo, step = o->slope * reach;
        change += step < width ? step : width;
    }
    double fine = detail->tail_hi[coarse] - detail->tail_lo[coarse];
    if (!(2.0 * change + fine < 0.75 * (detail->hi - detail->lo)))
        return; /* not worth the evaluation */
    double centre = plod_detail_noise(detail, dir, coarse, NULL);
    double a = centre - change + detail->tail_lo[coarse];
    double b = centre + change + detail->tail_hi[coarse];
    /* the sum's rounding: far below any octave's range, but say so */
    double slack = 1e-12 * (detail->hi - detail->lo);
    a -= slack, b += slack;
    *lo = a > *lo ? a : *lo;
    *hi = b < *hi ? b : *hi;
    if (*lo > *hi)
        *lo = *hi;
}

/* half the unit range of octave i's layers, metres */
static double plod__half_range(const plod_detail *d, int i)
{
    const plod__octave *o = &d->octaves[i];
    double noise = o->noise_weight * (d->params.style == PLOD_DETAIL_MOUNTAINS ? 0.5 : 1.0);
    return noise + o->crater_weight * 0.5 * (1.0 + PLOD__CRATER_RIM);
}

static double plod__cell_error_exact(const plod_detail *d, double cell)
{
    int keep = plod_detail_octaves_for_cell(d, cell);
    double e = 0.0;
    for (int i = 0; i < d->count; i++) {
        double half = plod__half_range(d, i);
        if (i >= keep) {
            e += half;
        } else {
            /* linear interpolation over a cell: ~ a (pi cell / wavelength)^2 / 2 */
            double x = cell / d->octaves[i].wavelength;
            double f = 0.5 * PLOD__DETAIL_PI * PLOD__DETAIL_PI * x * x;
            e += half * (f < 1.0 ? f : 1.0);
        }
    }
    return e;
}

double plod_detail_cell_error(const plod_detail *detail, double cell)
{
    if (!(cell > 0.0))
        return 0.0;
    int e;
    double mant = frexp(cell, &e); /* cell = mant 2^e, mant in [0.5, 1) */
    if (e <= PLOD__ERR_EXP_MIN)
        return detail->err[0];
    if (e > PLOD__ERR_EXP_MAX)
        return detail->err[PLOD__ERR_COUNT - 1];
    double hi = detail->err[e - PLOD__ERR_EXP_MIN], lo = detail->err[e - 1 - PLOD__ERR_EXP_MIN];
    return lo + (hi - lo) * (2.0 * mant - 1.0);
}

/* ---- construction ------------------------------------------------------------ */

static void plod__matmul(const double a[3][3], const double b[3][3], double out[3][3])
{
    double t[3][3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            t[i][j] = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
    memcpy(out, t, sizeof t);
}

/* Height of texel t (channel 0, normalised as sampling). */
static double plod__texel(const void *data, plod_texel_type type, int channels, size_t t)
{
    switch (type) {
    case PLOD_TEXEL_U8:
        return ((const uint8_t *)data)[t * (size_t)channels] * (1.0 / 255.0);
    case PLOD_TEXEL_U16:
        return ((const uint16_t *)data)[t * (size_t)channels] * (1.0 / 65535.0);
    default:
        return ((const float *)data)[t * (size_t)channels];
    }
}

static int plod__compare(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

/* The modulation map of planet's height map (see plod_detail.h). */
static plod_status plod__build_modulation(plod_detail *d, const plod_planet *planet)
{
    const plod_cubemap *map = planet->heightmap;
    int faces = plod_cubemap_face_count(map);
    int w = plod_cubemap_face_width(map), hgt = plod_cubemap_face_height(map);
    int channels = plod_cubemap_channels(map);
    plod_texel_type type = plod_cubemap_texel_type(map);
    size_t texels = (size_t)w * (size_t)hgt;
    float *relief = malloc(2 * texels * (size_t)faces * sizeof *relief);
    if (!relief)
        return PLOD_ERR_NO_MEMORY;
    float *above = relief + texels * (size_t)faces; /* metres above the sea */
    double scale = planet->height_scale;
    size_t land = 0;
    for (int f = 0; f < faces; f++) {
        const void *data = plod_cubemap_face_data_const(map, f);
        for (int y = 0; y < hgt; y++)
            for (int x = 0; x < w; x++) {
                double h = plod__texel(data, type, channels, (size_t)y * w + x) * scale +
                           planet->height_offset; /* for the sea test; steps cancel it */
                double r = 0.0;
                for (int dy = -1; dy <= 1; dy++)
                    for (int dx = -1; dx <= 1; dx++) {
                        int xx = x + dx, yy = y + dy;
                        xx = xx < 0 ? 0 : (xx >= w ? w - 1 : xx);
                        yy = yy < 0 ? 0 : (yy >= hgt ? hgt - 1 : yy);
                        double hn = plod__texel(data, type, channels, (size_t)yy * w + xx) *
                                        scale + planet->height_offset;
                        double step = fabs(hn - h);
                        r = step > r ? step : r;
                    }
                int sea = planet->has_sea_level && h <= planet->sea_level;
                relief[(size_t)f * texels + (size_t)y * w + x] = sea ? -1.0f : (float)r;
                above[(size_t)f * texels + (size_t)y * w + x] =
                    planet->has_sea_level ? (float)(h - planet->sea_level) : INFINITY;
                land += !sea;
            }
    }
    double reference = d->params.relief;
    if (!(reference > 0.0)) {
        float *sorted = malloc((land ? land : 1) * sizeof *sorted);
        if (!sorted) {
            free(relief);
            return PLOD_ERR_NO_MEMORY;
        }
        size_t k = 0;
        for (size_t t = 0; t < texels * (size_t)faces; t++)
            if (relief[t] >= 0.0f)
                sorted[k++] = relief[t];
        reference = 0.0;
        if (k) {
            qsort(sorted, k, sizeof *sorted, plod__compare);
            reference = sorted[(size_t)(0.9 * (double)(k - 1))];
        }
        free(sorted);
        if (!(reference > 0.0))
            reference = 1.0; /* flat land: plains everywhere */
    }
    plod_status st = plod_cubemap_create(&d->modulation, plod_cubemap_projection(map),
                                         plod_cubemap_size(map), 1, PLOD_TEXEL_U8);
    if (st != PLOD_OK) {
        free(relief);
        return st;
    }
    double plains = d->params.plains;
    for (int f = 0; f < faces; f++) {
        uint8_t *out = plod_cubemap_face_data(d->modulation, f);
        for (size_t t = 0; t < texels; t++) {
            double r = relief[(size_t)f * texels + t];
            double m = 0.0;
            if (r >= 0.0) {
                double x = r / reference;
                x = x < 1.0 ? x : 1.0; /* inf / inf (NaN) too */
                m = plains + (1.0 - plains) * x * x * (3.0 - 2.0 * x);
                /* low coasts: the field's deepest half-range stays above the sea */
                if (d->lo < 0.0) {
                    double limit = 2.0 * above[(size_t)f * texels + t] / -d->lo;
                    m = limit < m ? (limit > 0.0 ? limit : 0.0) : m;
                }
            }
            out[t] = (uint8_t)(m * 255.0 + 0.5);
        }
    }
    free(relief);
    return plod_cubemap_build_pyramid(d->modulation);
}

static int plod__params_ok(const plod_detail_params *p)
{
    return (unsigned)p->style < PLOD_DETAIL_STYLE_COUNT && isfinite(p->amplitude) &&
           p->amplitude >= 0.0 && p->amplitude <= 1e6 && p->roughness >= 0.0 &&
           p->roughness < 1.0 && isfinite(p->largest) && p->largest >= 0.0 &&
           isfinite(p->smallest) && p->smallest > 0.0 && p->craters >= 0.0 &&
           p->craters <= 4.0 && p->crater_density >= 0.0 && p->crater_density <= 1.0 &&
           p->plains >= 0.0 && p->plains <= 1.0 && isfinite(p->relief) && p->relief >= 0.0;
}

plod_status plod_detail_create(plod_detail **out, const plod_detail_params *params,
                               const plod_planet *planet)
{
    if (!out)
        return PLOD_ERR_NULL;
    *out = NULL;
    if (!params || !planet)
        return PLOD_ERR_NULL;
    if (!plod__params_ok(params) || !isfinite(planet->radius) || !(planet->radius >= 1.0))
        return PLOD_ERR_BAD_PARAM;
    plod_detail *d = calloc(1, sizeof *d);
    if (!d)
        return PLOD_ERR_NO_MEMORY;
    d->params = *params;
    d->radius = planet->radius;
    d->source = planet->heightmap;
    double largest = params->largest;
    if (!(largest > 0.0)) {
        if (planet->heightmap) {
            int size = plod_cubemap_size(planet->heightmap);
            double texel_angle = plod_projection_is_cube(planet->projection)
                                     ? 0.5 * PLOD__DETAIL_PI / size
                                     : PLOD__DETAIL_PI / size;
            largest = 2.0 * texel_angle * planet->radius;
        } else {
            largest = planet->radius / 50.0;
        }
    }
    /* fixed rotation between octaves: unit quaternion (0.8, 0.3, 0.4, 0.34)
     * normalised; any generic rotation does */
    double qw = 0.8, qx = 0.3, qy = 0.4, qz = 0.34;
    double ql = sqrt(qw * qw + qx * qx + qy * qy + qz * qz);
    qw /= ql, qx /= ql, qy /= ql, qz /= ql;
    double rot[3][3] = {
        {1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)},
        {2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)},
        {2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)}};
    double acc[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    double wavelength = largest, amplitude = params->amplitude;
    int craters_style = params->style == PLOD_DETAIL_CRATERS;
    double crater_layer = craters_style ? (params->craters > 1.0 ? params->craters : 1.0)
                                        : params->craters;
    double noise_layer = craters_style ? PLOD__CRATER_HILLS : 1.0;
    uint64_t seed = plod__mix(params->seed ^ 0x5eedULL);
    d->lo = d->hi = 0.0;
    int count = 0;
    /* lattice coordinates stay below 2^50: exact floors and integer casts */
    while (count < PLOD_DETAIL_MAX_OCTAVES && wavelength >= params->smallest &&
           amplitude > 0.0 && planet->radius / wavelength < 1e15) {
        plod__octave *o = &d->octaves[count];
        double freq = planet->radius / wavelength;
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++)
                o->m[i][j] = freq * acc[i][j];
        uint64_t h = plod__mix(seed + (uint64_t)count * 0x632BE59BD9B4E019ULL);
        for (int a = 0; a < 3; a++)
            o->offset[a] = 1024.0 * plod__unit(plod__mix(h + (uint64_t)a + 1));
        o->seed = plod__mix(h + 7);
        o->crater_seed = plod__mix(h + 11);
        o->wavelength = wavelength;
        o->frequency = freq;
        o->amplitude = amplitude;
        o->noise_weight = noise_layer * amplitude;
        o->crater_weight = crater_layer * PLOD__CRATER_DEPTH * amplitude;
        if (params->style == PLOD_DETAIL_MOUNTAINS) {
            d->lo -= 0.5 * o->noise_weight;
            d->hi += 0.5 * o->noise_weight;
        } else {
            d->lo -= o->noise_weight;
            d->hi += o->noise_weight;
        }
        d->lo -= o->crater_weight;
        d->hi += o->crater_weight * PLOD__CRATER_RIM;
        o->lo = -(params->style == PLOD_DETAIL_MOUNTAINS ? 0.5 : 1.0) * o->noise_weight -
                o->crater_weight;
        o->hi = (params->style == PLOD_DETAIL_MOUNTAINS ? 0.5 : 1.0) * o->noise_weight +
                o->crater_weight * PLOD__CRATER_RIM;
        /* slopes per lattice unit: noise PLOD__NOISE_LIPSCHITZ; ridged term
         * a (w ds + (s - 1/2) dw) with |ds| <= 2 L, |dw| <= gain 2 L at the
         * previous octave's half frequency; crater profile slope / r_min */
        double noise_slope = PLOD__NOISE_LIPSCHITZ * freq;
        if (params->style == PLOD_DETAIL_MOUNTAINS)
            noise_slope = 2.0 * PLOD__NOISE_LIPSCHITZ * freq +
                          0.5 * PLOD__RIDGE_GAIN * 2.0 * PLOD__NOISE_LIPSCHITZ * 0.5 * freq;
        double crater_slope = 2.0 * (1.0 + PLOD__CRATER_RIM) / PLOD__CRATER_SMALLEST * freq;
        o->slope = o->noise_weight * noise_slope + o->crater_weight * crater_slope;
        plod__matmul(rot, acc, acc);
        wavelength *= 0.5;
        amplitude *= params->roughness;
        count++;
    }
    d->count = count;
    d->tail_lo[count] = d->tail_hi[count] = 0.0;
    for (int i = count - 1; i >= 0; i--) {
        d->tail_lo[i] = d->tail_lo[i + 1] + d->octaves[i].lo;
        d->tail_hi[i] = d->tail_hi[i + 1] + d->octaves[i].hi;
    }
    for (int e = 0; e < PLOD__ERR_COUNT; e++)
        d->err[e] = plod__cell_error_exact(d, ldexp(1.0, e + PLOD__ERR_EXP_MIN));
    if (planet->heightmap) {
        plod_status st = plod__build_modulation(d, planet);
        if (st != PLOD_OK) {
            plod_detail_destroy(d);
            return st;
        }
    }
    /* stamp: the parameters and the planet it was built for */
    uint64_t s = plod__mix(params->seed + 0x9E37ULL);
    const double vals[] = {params->amplitude, params->roughness, largest, params->smallest,
                           params->craters, params->crater_density, params->plains,
                           params->relief, planet->radius, planet->height_scale,
                           (double)params->style};
    for (size_t i = 0; i < sizeof vals / sizeof vals[0]; i++) {
        uint64_t bits;
        memcpy(&bits, &vals[i], sizeof bits);
        s = plod__mix(s ^ bits);
    }
    d->stamp = s;
    *out = d;
    return PLOD_OK;
}

void plod_detail_destroy(plod_detail *detail)
{
    if (!detail)
        return;
    plod_cubemap_destroy(detail->modulation);
    free(detail);
}

const plod_detail_params *plod_detail_get_params(const plod_detail *detail)
{
    return &detail->params;
}

int plod_detail_octave_count(const plod_detail *detail)
{
    return detail->count;
}

double plod_detail_wavelength(const plod_detail *detail, int octave)
{
    return octave >= 0 && octave < detail->count ? detail->octaves[octave].wavelength : 0.0;
}

const plod_cubemap *plod_detail_modulation(const plod_detail *detail)
{
    return detail->modulation;
}

int plod_detail_matches(const plod_detail *detail, const plod_planet *planet)
{
    return detail->radius == planet->radius && detail->source == planet->heightmap;
}

uint64_t plod_detail_stamp(const plod_detail *detail)
{
    return detail->stamp;
}
