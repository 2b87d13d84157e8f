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
/* ridged term w (s - CENTRE): s = (1 - |n|)^2 averages ~0.7 over gradient
 * noise, so a centre of 0.5 would lift every mountain by a fifth of the
 * field's amplitude sum; with the weights w, 0.63 leaves the field's mean
 * near 0 (the Earth preset: 28 m of a 12 km range over 200,000
 * directions); the unit range [-CENTRE, 1 - CENTRE] holds 0 */
#define PLOD__RIDGE_CENTRE 0.63
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
    int fine_first, fine_end;   /* the hills' band of octaves */
    double lo, hi;              /* bounds of N */
    double deepest;             /* N's lowest value over a fixed sample of
                                   directions (<= 0): how deep it digs in
                                   practice, far above lo for many octaves */
    double tail_lo[PLOD_DETAIL_MAX_OCTAVES + 1], tail_hi[PLOD_DETAIL_MAX_OCTAVES + 1];
                                /* bounds of the octaves from i on */
    /* err[v][e]: cell error at cells of 2^(e + PLOD__ERR_EXP_MIN) metres
     * counting the first v octaves (v = count: all of them) */
    double err[PLOD_DETAIL_MAX_OCTAVES + 1][PLOD__ERR_COUNT];
    double err_band[PLOD_DETAIL_MAX_OCTAVES + 1][PLOD__ERR_COUNT]; /* the band's alone */
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
    params->hills = 1.0;
    params->fine_roughness = 0.5;
    params->hills_fine = 1.0;
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

/* plod__grad per axis for the lanes: entry i's component + 1 in bits 2 i
 * and 2 i + 1 (test_detail.py holds the lanes to the point path) */
#define PLOD__GRAD_X 0x52552222u
#define PLOD__GRAD_Y 0x0a22550au
#define PLOD__GRAD_Z 0x250a0a55u

/* Improved noise at lattice point p, clamped to [-1, 1] (its extremes are
 * within ~1 already; the clamp makes the bound exact); g (when not NULL):
 * d n / d p.  Written for the compiler: the corners unrolled, the corner
 * gradients' blend coefficients in integers (small integers, so the same
 * values as in doubles), and inlined with g constant NULL for the
 * height-only callers (bounds, heights without normals): one expression
 * for n in both, so the same bits. */
static inline double plod__gnoise_kernel(const double p[3], uint64_t seed, double g[3])
{
    double fx = plod__floor(p[0]), fy = plod__floor(p[1]), fz = plod__floor(p[2]);
    double x = p[0] - fx, y = p[1] - fy, z = p[2] - fz;
    uint64_t base = (uint64_t)(int64_t)fx * PLOD__HX + (uint64_t)(int64_t)fy * PLOD__HY +
                    (uint64_t)(int64_t)fz * PLOD__HZ + seed;
    /* corners a..h = 000 100 010 110 001 101 011 111 */
    const signed char *q0 = plod__grad[plod__mix_fast(base) >> 60];
    const signed char *q1 = plod__grad[plod__mix_fast(base + PLOD__HX) >> 60];
    const signed char *q2 = plod__grad[plod__mix_fast(base + PLOD__HY) >> 60];
    const signed char *q3 = plod__grad[plod__mix_fast(base + PLOD__HX + PLOD__HY) >> 60];
    const signed char *q4 = plod__grad[plod__mix_fast(base + PLOD__HZ) >> 60];
    const signed char *q5 = plod__grad[plod__mix_fast(base + PLOD__HX + PLOD__HZ) >> 60];
    const signed char *q6 = plod__grad[plod__mix_fast(base + PLOD__HY + PLOD__HZ) >> 60];
    const signed char *q7 =
        plod__grad[plod__mix_fast(base + PLOD__HX + PLOD__HY + PLOD__HZ) >> 60];
    double x1 = x - 1, y1 = y - 1, z1 = z - 1;
    double val0 = q0[0] * x + q0[1] * y + q0[2] * z;
    double val1 = q1[0] * x1 + q1[1] * y + q1[2] * z;
    double val2 = q2[0] * x + q2[1] * y1 + q2[2] * z;
    double val3 = q3[0] * x1 + q3[1] * y1 + q3[2] * z;
    double val4 = q4[0] * x + q4[1] * y + q4[2] * z1;
    double val5 = q5[0] * x1 + q5[1] * y + q5[2] * z1;
    double val6 = q6[0] * x + q6[1] * y1 + q6[2] * z1;
    double val7 = q7[0] * x1 + q7[1] * y1 + q7[2] * z1;
    double ux = x * x * x * (x * (x * 6.0 - 15.0) + 10.0);
    double uy = y * y * y * (y * (y * 6.0 - 15.0) + 10.0);
    double uz = z * z * z * (z * (z * 6.0 - 15.0) + 10.0);
    double k0 = val0, k1 = val1 - val0, k2 = val2 - val0, k3 = val4 - val0;
    double k4 = val0 - val1 - val2 + val3;
    double k5 = val0 - val2 - val4 + val6;
    double k6 = val0 - val1 - val4 + val5;
    double k7 = -val0 + val1 + val2 - val3 + val4 - val5 - val6 + val7;
    double n = k0 + k1 * ux + k2 * uy + k3 * uz + k4 * ux * uy + k5 * uy * uz + k6 * uz * ux +
               k7 * ux * uy * uz;
    if (g) {
        double dx = 30.0 * x * x * (x * (x - 2.0) + 1.0);
        double dy = 30.0 * y * y * (y * (y - 2.0) + 1.0);
        double dz = 30.0 * z * z * (z * (z - 2.0) + 1.0);
        for (int a = 0; a < 3; a++) {
            int g0 = q0[a], g1 = q1[a] - q0[a], g2 = q2[a] - q0[a], g3 = q4[a] - q0[a];
            int g4 = q0[a] - q1[a] - q2[a] + q3[a];
            int g5 = q0[a] - q2[a] - q4[a] + q6[a];
            int g6 = q0[a] - q1[a] - q4[a] + q5[a];
            int g7 = -q0[a] + q1[a] + q2[a] - q3[a] + q4[a] - q5[a] - q6[a] + q7[a];
            g[a] = (double)g0 + (double)g1 * ux + (double)g2 * uy + (double)g3 * uz +
                   (double)g4 * ux * uy + (double)g5 * uy * uz + (double)g6 * uz * ux +
                   (double)g7 * ux * uy * uz;
        }
        g[0] += dx * (k1 + k4 * uy + k6 * uz + k7 * uy * uz);
        g[1] += dy * (k2 + k5 * uz + k4 * ux + k7 * uz * ux);
        g[2] += dz * (k3 + k6 * ux + k5 * uy + k7 * ux * uy);
    }
    if (n > 1.0 || n < -1.0) {
        if (g)
            g[0] = g[1] = g[2] = 0.0;
        n = n > 0.0 ? 1.0 : -1.0;
    }
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

/* The crater of one lattice cell (its integer corner fx, fy, fz): none,
 * or its centre and radius in lattice units.  The crater centre is a
 * seeded point of the cell moved onto the sphere |p - centre| = radius;
 * a crater whose reach would leave its cell is dropped, so every cell
 * boundary has height 0 and slope 0: seamless. */
typedef struct plod__crater_cell {
    double fx, fy, fz;
    int present;
    double c[3], r;
} plod__crater_cell;

static void plod__crater_cell_of(double fx, double fy, double fz, const double centre[3],
                                 double radius, uint64_t seed, double density,
                                 plod__crater_cell *cell)
{
    cell->fx = fx, cell->fy = fy, cell->fz = fz;
    cell->present = 0;
    uint64_t h = plod__mix((uint64_t)(int64_t)fx * PLOD__HX + (uint64_t)(int64_t)fy * PLOD__HY +
                           (uint64_t)(int64_t)fz * PLOD__HZ + seed);
    if (plod__unit(h) >= density)
        return;
    double c[3] = {fx + plod__unit(plod__mix(h + 1)), fy + plod__unit(plod__mix(h + 2)),
                   fz + plod__unit(plod__mix(h + 3))};
    double w[3] = {c[0] - centre[0], c[1] - centre[1], c[2] - centre[2]};
    double len = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
    if (!(len > 0.0))
        return;
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
        return;
    cell->present = 1;
    memcpy(cell->c, c, sizeof c);
    cell->r = r;
}

/* The crater of `cell` at p (in it), in units of depth; 0 outside it. */
static double plod__crater_at(const double p[3], const plod__crater_cell *cell, double g[3])
{
    g[0] = g[1] = g[2] = 0.0;
    if (!cell->present)
        return 0.0;
    const double *c = cell->c;
    double r = cell->r, reach = PLOD__CRATER_REACH * r;
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

/* The crater of the lattice cell holding p (lattice units), in units of
 * depth; 0 outside any crater; g: its gradient. */
static double plod__crater(const double p[3], const double centre[3], double radius,
                           uint64_t seed, double density, double g[3])
{
    plod__crater_cell cell;
    plod__crater_cell_of(plod__floor(p[0]), plod__floor(p[1]), plod__floor(p[2]), centre, radius,
                         seed, density, &cell);
    return plod__crater_at(p, &cell, g);
}

/* ---- the field ------------------------------------------------------------- */

static inline void plod__lattice(const plod__octave *o, const double dir[3], double p[3])
{
    for (int a = 0; a < 3; a++)
        p[a] = o->m[a][0] * dir[0] + o->m[a][1] * dir[1] + o->m[a][2] * dir[2] + o->offset[a];
}

/* lattice gradient -> direction gradient (M^T g), scaled, added to acc */
static inline void plod__add_gradient(const plod__octave *o, const double g[3], double scale,
                               double acc[3])
{
    for (int a = 0; a < 3; a++)
        acc[a] += scale * (o->m[0][a] * g[0] + o->m[1][a] * g[1] + o->m[2][a] * g[2]);
}

/* The running state of N and its gradient along the octaves at one
 * direction. */
typedef struct plod__noise_state {
    double sum;
    double weight;     /* ridged: the previous octave's signal, clamped */
    double acc[3];     /* gradient, metres per unit of direction */
    double dweight[3]; /* gradient of weight, per unit of direction */
} plod__noise_state;

static inline void plod__noise_start(plod__noise_state *st)
{
    st->sum = 0.0;
    st->weight = 1.0;
    for (int a = 0; a < 3; a++)
        st->acc[a] = st->dweight[a] = 0.0;
}

/* Octave o's term at dir into st: its value into the sum when add_sum,
 * its gradient when gradient (dweight kept only then).  Every caller
 * (one point or a batch, with or without the gradient) runs this one
 * sequence of operations per octave, so they agree bit for bit. */
static inline void plod__octave_step(const plod_detail *detail, const plod__octave *o,
                                     int ridged, const double dir[3], int add_sum,
                                     int gradient, int crater_gradient, plod__noise_state *st)
{
    double p[3], g[3];
    plod__lattice(o, dir, p);
    if (o->noise_weight != 0.0) {
        double n = plod__gnoise_kernel(p, o->seed, gradient ? g : NULL);
        if (!ridged) {
            if (add_sum)
                st->sum += o->noise_weight * n;
            if (gradient)
                plod__add_gradient(o, g, o->noise_weight, st->acc);
        } else if (!gradient) {
            double an = n < 0.0 ? -n : n;
            double s = (1.0 - an) * (1.0 - an);
            if (add_sum)
                st->sum += o->noise_weight * st->weight * (s - PLOD__RIDGE_CENTRE);
            double next = PLOD__RIDGE_GAIN * s;
            st->weight = next >= 1.0 ? 1.0 : next;
        } else {
            /* signal s = (1 - |n|)^2 in [0, 1]; term w (s - 1/2) */
            double an = n < 0.0 ? -n : n, sign = n < 0.0 ? -1.0 : 1.0;
            double s = (1.0 - an) * (1.0 - an);
            double ds = -2.0 * (1.0 - an) * sign; /* per unit of n */
            double a = o->noise_weight, weight = st->weight;
            if (add_sum)
                st->sum += a * weight * (s - PLOD__RIDGE_CENTRE);
            double dl[3] = {a * weight * ds * g[0], a * weight * ds * g[1],
                            a * weight * ds * g[2]}; /* lattice units */
            plod__add_gradient(o, dl, 1.0, st->acc);
            for (int k = 0; k < 3; k++) /* dweight is per unit of direction */
                st->acc[k] += a * (s - PLOD__RIDGE_CENTRE) * st->dweight[k];
            /* next weight: clamp(gain s, 0, 1) */
            double next = PLOD__RIDGE_GAIN * s;
            if (next >= 1.0) {
                st->weight = 1.0;
                st->dweight[0] = st->dweight[1] = st->dweight[2] = 0.0;
            } else {
                st->weight = next;
                double dd[3] = {0.0, 0.0, 0.0};
                double dsg[3] = {PLOD__RIDGE_GAIN * ds * g[0], PLOD__RIDGE_GAIN * ds * g[1],
                                 PLOD__RIDGE_GAIN * ds * g[2]};
                plod__add_gradient(o, dsg, 1.0, dd);
                memcpy(st->dweight, dd, sizeof dd);
            }
        }
    }
    if (o->crater_weight != 0.0) {
        double cp[3] = {p[0] + 0.5, p[1] + 0.5, p[2] + 0.5}; /* its own cells */
        double centre[3] = {o->offset[0] + 0.5, o->offset[1] + 0.5, o->offset[2] + 0.5};
        double value = plod__crater(cp, centre, o->frequency, o->crater_seed,
                                    detail->params.crater_density, g);
        if (value != 0.0) {
            if (add_sum)
                st->sum += o->crater_weight * value;
            if (gradient && crater_gradient)
                plod__add_gradient(o, g, o->crater_weight, st->acc);
        }
    }
}

/* plod_detail_noise_from without the gradient: the same sum, bit for bit. */
static double plod__noise_value(const plod_detail *detail, const double dir[3], int first,
                                int octaves)
{
    int ridged = detail->params.style == PLOD_DETAIL_MOUNTAINS;
    plod__noise_state st;
    plod__noise_start(&st);
    for (int i = first; i < octaves; i++)
        plod__octave_step(detail, &detail->octaves[i], ridged, dir, 1, 0, 0, &st);
    return st.sum;
}

static int plod__unit_range(const double dir[3])
{
    return fabs(dir[0]) <= 2.0 && fabs(dir[1]) <= 2.0 && fabs(dir[2]) <= 2.0;
}

double plod_detail_noise(const plod_detail *detail, const double dir[3], int octaves,
                         double gradient[3])
{
    return plod_detail_noise_from(detail, dir, 0, octaves, gradient);
}

double plod_detail_noise_from(const plod_detail *detail, const double dir[3], int first,
                              int octaves, double gradient[3])
{
    if (octaves > detail->count)
        octaves = detail->count;
    first = first > 0 ? first : 0;
    if (!plod__unit_range(dir)) {
        if (gradient) /* not a unit direction (NaN): no lattice to read */
            gradient[0] = gradient[1] = gradient[2] = NAN;
        return NAN;
    }
    if (!gradient)
        return plod__noise_value(detail, dir, first, octaves);
    int ridged = detail->params.style == PLOD_DETAIL_MOUNTAINS;
    plod__noise_state st;
    plod__noise_start(&st);
    for (int i = first; i < octaves; i++)
        plod__octave_step(detail, &detail->octaves[i], ridged, dir, 1, 1,
                          i + PLOD_DETAIL_CRATER_NORMAL_LAG < octaves, &st);
    memcpy(gradient, st.acc, sizeof st.acc);
    return st.sum;
}

/* ---- the field at a batch of directions ------------------------------------ */

/* Octave by octave across a batch of directions, each step a loop over the
 * batch's lanes in structure-of-arrays form: the arithmetic (lattice
 * point, fade, blend, gradient, ridged weights) compiles to SIMD, the
 * lattice hashes stay scalar.  Per lane the operations are those of
 * plod__octave_step in its order (lanes past their octave count are
 * masked, not computed differently), so every lane is bit for bit
 * plod_detail_noise. */
#define PLOD__LANES 64
/* lanes are run in whole vectors of up to 8 doubles (AVX-512): a partial
 * vector would fall to the loops' scalar remainder */
#define PLOD__LANE_ROUND(count) (((count) + 7) & ~7)
/* points sorted by depth together, then run PLOD__LANES at a time */
#define PLOD__SORT_SPAN 256

typedef struct plod__lanes {
    int count; /* lanes in use, PLOD__LANE_ROUNDed (idle ones masked) */
    double dir[3][PLOD__LANES];
    double value_count[PLOD__LANES], gradient_count[PLOD__LANES]; /* octaves */
    double first[PLOD__LANES]; /* the lane's first octave (those before it idle) */
    double p[3][PLOD__LANES];    /* lattice point */
    double frac[3][PLOD__LANES]; /* position inside the lattice cell */
    double n[PLOD__LANES], g[3][PLOD__LANES];
    double sum[PLOD__LANES], weight[PLOD__LANES];
    double acc[3][PLOD__LANES], dweight[3][PLOD__LANES];
} plod__lanes;

/* floor() of |x| < 2^51, exact, branch-free: round to an integer by
 * adding and removing 2^52, step down where that rounded up */
PLOD_LANE_INLINE double plod__floor_exact(double x)
{
    double big = x < 0.0 ? -4503599627370496.0 : 4503599627370496.0;
    double r = (x + big) - big;
    return r > x ? r - 1.0 : r;
}

/* lane k of octave o's gradient noise (n, and g when gradient): the
 * arithmetic of plod__gnoise_kernel after the hashes, with q[c][a] corner
 * c's gradient component a (the lane's own, or one set for all lanes where
 * they share a lattice cell: the same values, so the same bits) */
PLOD_LANE_INLINE void plod__lane_blend(plod__lanes *l, int k, int gradient,
                                        const double q[8][3])
{
#define PLOD__Q(c, a) q[c][a]
    double x = l->frac[0][k], y = l->frac[1][k], z = l->frac[2][k];
    double x1 = x - 1, y1 = y - 1, z1 = z - 1;
    double val0 = PLOD__Q(0, 0) * x + PLOD__Q(0, 1) * y + PLOD__Q(0, 2) * z;
    double val1 = PLOD__Q(1, 0) * x1 + PLOD__Q(1, 1) * y + PLOD__Q(1, 2) * z;
    double val2 = PLOD__Q(2, 0) * x + PLOD__Q(2, 1) * y1 + PLOD__Q(2, 2) * z;
    double val3 = PLOD__Q(3, 0) * x1 + PLOD__Q(3, 1) * y1 + PLOD__Q(3, 2) * z;
    double val4 = PLOD__Q(4, 0) * x + PLOD__Q(4, 1) * y + PLOD__Q(4, 2) * z1;
    double val5 = PLOD__Q(5, 0) * x1 + PLOD__Q(5, 1) * y + PLOD__Q(5, 2) * z1;
    double val6 = PLOD__Q(6, 0) * x + PLOD__Q(6, 1) * y1 + PLOD__Q(6, 2) * z1;
    double val7 = PLOD__Q(7, 0) * x1 + PLOD__Q(7, 1) * y1 + PLOD__Q(7, 2) * z1;
    double ux = x * x * x * (x * (x * 6.0 - 15.0) + 10.0);
    double uy = y * y * y * (y * (y * 6.0 - 15.0) + 10.0);
    double uz = z * z * z * (z * (z * 6.0 - 15.0) + 10.0);
    double k0 = val0, k1 = val1 - val0, k2 = val2 - val0, k3 = val4 - val0;
    double k4 = val0 - val1 - val2 + val3;
    double k5 = val0 - val2 - val4 + val6;
    double k6 = val0 - val1 - val4 + val5;
    double k7 = -val0 + val1 + val2 - val3 + val4 - val5 - val6 + val7;
    double n = k0 + k1 * ux + k2 * uy + k3 * uz + k4 * ux * uy + k5 * uy * uz + k6 * uz * ux +
               k7 * ux * uy * uz;
    int clamp = (n > 1.0) | (n < -1.0);
    l->n[k] = clamp ? (n > 0.0 ? 1.0 : -1.0) : n;
    if (!gradient)
        return;
    double dx = 30.0 * x * x * (x * (x - 2.0) + 1.0);
    double dy = 30.0 * y * y * (y * (y - 2.0) + 1.0);
    double dz = 30.0 * z * z * (z * (z - 2.0) + 1.0);
#define PLOD__AXIS_GRADIENT(a)                                                                  \
    double q0##a = PLOD__Q(0, a), q1##a = PLOD__Q(1, a), q2##a = PLOD__Q(2, a),                \
           q3##a = PLOD__Q(3, a), q4##a = PLOD__Q(4, a), q5##a = PLOD__Q(5, a),                \
           q6##a = PLOD__Q(6, a), q7##a = PLOD__Q(7, a);                                       \
    double g##a = q0##a + (q1##a - q0##a) * ux + (q2##a - q0##a) * uy + (q4##a - q0##a) * uz + \
                  (q0##a - q1##a - q2##a + q3##a) * ux * uy +                                  \
                  (q0##a - q2##a - q4##a + q6##a) * uy * uz +                                  \
                  (q0##a - q1##a - q4##a + q5##a) * uz * ux +                                  \
                  (-q0##a + q1##a + q2##a - q3##a + q4##a - q5##a - q6##a + q7##a) * ux * uy * uz;
    PLOD__AXIS_GRADIENT(0)
    PLOD__AXIS_GRADIENT(1)
    PLOD__AXIS_GRADIENT(2)
#undef PLOD__AXIS_GRADIENT
#undef PLOD__Q
    g0 += dx * (k1 + k4 * uy + k6 * uz + k7 * uy * uz);
    g1 += dy * (k2 + k5 * uz + k4 * ux + k7 * uz * ux);
    g2 += dz * (k3 + k6 * ux + k5 * uy + k7 * ux * uy);
    l->g[0][k] = clamp ? 0.0 : g0;
    l->g[1][k] = clamp ? 0.0 : g1;
    l->g[2][k] = clamp ? 0.0 : g2;
}

/* corner gradient component from a lattice hash: plod__grad[h >> 60][axis]
 * (the table packed per axis) */
PLOD_LANE_INLINE double plod__grad_component(uint32_t packed, uint64_t hash)
{
    uint32_t shift = (uint32_t)(hash >> 59) & 30u;
    return (double)((int32_t)((packed >> shift) & 3u) - 1);
}

/* the 8 corners' gradients of the lattice cell hashed to `base`, from
 * plod__grad packed per axis (shifts and masks instead of table gathers:
 * the same values) */
PLOD_LANE_INLINE void plod__lane_corners(uint64_t base, double q[8][3])
{
    for (int c = 0; c < 8; c++) {
        uint64_t hash = plod__mix_fast(base + ((c & 1) ? PLOD__HX : 0) +
                                       ((c & 2) ? PLOD__HY : 0) + ((c & 4) ? PLOD__HZ : 0));
        q[c][0] = plod__grad_component(PLOD__GRAD_X, hash);
        q[c][1] = plod__grad_component(PLOD__GRAD_Y, hash);
        q[c][2] = plod__grad_component(PLOD__GRAD_Z, hash);
    }
}

/* octave o's gradient noise at every lane (n, and g when gradient) */
PLOD_LANE_CLONES PLOD_LANE_LOOPS static void plod__lanes_noise(plod__lanes *l, const plod__octave *o,
                                                           int gradient)
{
    double m00 = o->m[0][0], m01 = o->m[0][1], m02 = o->m[0][2], m10 = o->m[1][0],
           m11 = o->m[1][1], m12 = o->m[1][2], m20 = o->m[2][0], m21 = o->m[2][1],
           m22 = o->m[2][2], o0 = o->offset[0], o1 = o->offset[1], o2 = o->offset[2];
    for (int k = 0; k < l->count; k++) {
        double d0 = l->dir[0][k], d1 = l->dir[1][k], d2 = l->dir[2][k];
        double p0 = m00 * d0 + m01 * d1 + m02 * d2 + o0;
        double p1 = m10 * d0 + m11 * d1 + m12 * d2 + o1;
        double p2 = m20 * d0 + m21 * d1 + m22 * d2 + o2;
        l->p[0][k] = p0, l->p[1][k] = p1, l->p[2][k] = p2;
        l->frac[0][k] = p0 - plod__floor_exact(p0);
        l->frac[1][k] = p1 - plod__floor_exact(p1);
        l->frac[2][k] = p2 - plod__floor_exact(p2);
    }
    /* the cell's integer corner, p - frac (the floor, exactly), as an
     * integer: the bits of floor + 1.5 * 2^52 less those of 1.5 * 2^52 are
     * its two's complement for |floor| < 2^51 (the cast, in SIMD) */
    uint64_t base[PLOD__LANES], differ = 0, seed = o->seed;
    for (int k = 0; k < l->count; k++) {
        uint64_t xyz[3];
        for (int a = 0; a < 3; a++) {
            double shifted = (l->p[a][k] - l->frac[a][k]) + 6755399441055744.0;
            memcpy(&xyz[a], &shifted, sizeof shifted);
            xyz[a] -= 0x4338000000000000ULL;
        }
        base[k] = xyz[0] * PLOD__HX + xyz[1] * PLOD__HY + xyz[2] * PLOD__HZ + seed;
    }
    for (int k = 0; k < l->count; k++) /* apart: base[0] read while written kept it scalar */
        differ |= base[k] ^ base[0];
    if (l->count > 0 && !differ) {
        /* every lane in one lattice cell (the coarse octaves of a sector):
         * its corners hashed once */
        double q[8][3];
        plod__lane_corners(base[0], q);
        if (gradient)
            for (int k = 0; k < l->count; k++)
                plod__lane_blend(l, k, 1, q);
        else
            for (int k = 0; k < l->count; k++)
                plod__lane_blend(l, k, 0, q);
        return;
    }
    /* each lane's corners hashed inside the blend's loop: kept in registers */
    if (gradient)
        for (int k = 0; k < l->count; k++) {
            double q[8][3];
            plod__lane_corners(base[k], q);
            plod__lane_blend(l, k, 1, q);
        }
    else
        for (int k = 0; k < l->count; k++) {
            double q[8][3];
            plod__lane_corners(base[k], q);
            plod__lane_blend(l, k, 0, q);
        }
}

/* An octave's weight and rotation, copied out of the octave: the lane
 * loops' stores then provably leave them alone, which the vectoriser
 * needs under -fno-strict-aliasing. */
typedef struct plod__octave_terms {
    double a;
    double m[3][3];
} plod__octave_terms;

/* lane k: octave i's noise term into the sum (i < its value count) and
 * gradient (i < its gradient count): plod__octave_step's operations, as
 * selects */
PLOD_LANE_INLINE void plod__lane_accumulate(plod__lanes *l, int k, const plod__octave_terms *o,
                                            double at, int ridged, int gradient)
{
    double a = o->a;
    int started = at >= l->first[k];
    int add_sum = started & (at < l->value_count[k]);
    int add_gradient = gradient ? started & (at < l->gradient_count[k]) : 0;
    double n = l->n[k];
    double g0 = l->g[0][k], g1 = l->g[1][k], g2 = l->g[2][k];
    if (!ridged) {
        l->sum[k] = add_sum ? l->sum[k] + a * n : l->sum[k];
        if (!gradient)
            return;
        double d0 = a * (o->m[0][0] * g0 + o->m[1][0] * g1 + o->m[2][0] * g2);
        double d1 = a * (o->m[0][1] * g0 + o->m[1][1] * g1 + o->m[2][1] * g2);
        double d2 = a * (o->m[0][2] * g0 + o->m[1][2] * g1 + o->m[2][2] * g2);
        l->acc[0][k] = add_gradient ? l->acc[0][k] + d0 : l->acc[0][k];
        l->acc[1][k] = add_gradient ? l->acc[1][k] + d1 : l->acc[1][k];
        l->acc[2][k] = add_gradient ? l->acc[2][k] + d2 : l->acc[2][k];
        return;
    }
    int active = add_sum | add_gradient;
    double an = n < 0.0 ? -n : n, sign = n < 0.0 ? -1.0 : 1.0;
    double s = (1.0 - an) * (1.0 - an);
    double weight = l->weight[k];
    l->sum[k] = add_sum ? l->sum[k] + a * weight * (s - PLOD__RIDGE_CENTRE) : l->sum[k];
    double next = PLOD__RIDGE_GAIN * s;
    int saturated = next >= 1.0;
    l->weight[k] = active ? (saturated ? 1.0 : next) : weight;
    if (!gradient)
        return;
    double ds = -2.0 * (1.0 - an) * sign;
    double t0 = a * weight * ds * g0, t1 = a * weight * ds * g1, t2 = a * weight * ds * g2;
    double s0 = PLOD__RIDGE_GAIN * ds * g0, s1 = PLOD__RIDGE_GAIN * ds * g1,
           s2 = PLOD__RIDGE_GAIN * ds * g2;
    double term = a * (s - PLOD__RIDGE_CENTRE);
#define PLOD__RIDGED_AXIS(c)                                                                    \
    {                                                                                          \
        double acc = l->acc[c][k] +                                                            \
                     1.0 * (o->m[0][c] * t0 + o->m[1][c] * t1 + o->m[2][c] * t2);              \
        acc += term * l->dweight[c][k];                                                        \
        double dd = 0.0 + 1.0 * (o->m[0][c] * s0 + o->m[1][c] * s1 + o->m[2][c] * s2);        \
        l->acc[c][k] = add_gradient ? acc : l->acc[c][k];                                      \
        l->dweight[c][k] = add_gradient ? (saturated ? 0.0 : dd) : l->dweight[c][k];           \
    }
    PLOD__RIDGED_AXIS(0)
    PLOD__RIDGED_AXIS(1)
    PLOD__RIDGED_AXIS(2)
#undef PLOD__RIDGED_AXIS
}

PLOD_LANE_CLONES PLOD_LANE_LOOPS static void
plod__lanes_accumulate(plod__lanes *l, const plod__octave *o, int ridged, int i, int gradient)
{
    double at = (double)i;
    plod__octave_terms terms = {o->noise_weight, {{0.0}}};
    memcpy(terms.m, o->m, sizeof terms.m);
    if (ridged && gradient)
        for (int k = 0; k < l->count; k++)
            plod__lane_accumulate(l, k, &terms, at, 1, 1);
    else if (ridged)
        for (int k = 0; k < l->count; k++)
            plod__lane_accumulate(l, k, &terms, at, 1, 0);
    else if (gradient)
        for (int k = 0; k < l->count; k++)
            plod__lane_accumulate(l, k, &terms, at, 0, 1);
    else
        for (int k = 0; k < l->count; k++)
            plod__lane_accumulate(l, k, &terms, at, 0, 0);
}

static const double plod__idle_dir[3] = {1.0, 0.0, 0.0};

/* One batch of up to PLOD__LANES lanes: lane k is point lane_of[k] (deepest
 * first), depth_of[] the octaves each point evaluates. */
/* The running sums and gradients of the lanes (k < count) into `sum`
 * and `acc`: the hills' band's prefix sums. */
static void plod__lanes_snapshot(const plod__lanes *l, int count, double *sum,
                                 double (*acc)[PLOD__LANES])
{
    memcpy(sum, l->sum, (size_t)count * sizeof *sum);
    for (int a = 0; a < 3; a++)
        memcpy(acc[a], l->acc[a], (size_t)count * sizeof **acc);
}

/* band_sums (may be NULL): per point, the part of its sum from the hills'
 * band's octaves (and band_gradients that of its gradient): the running
 * sum after the band less the one before it, from the same pass. */
static void plod__noise_batch(const plod_detail *detail, int ridged, plod__lanes *l,
                              const double *dirs, const int *first_octaves,
                              const int *octaves, const int *gradient_octaves,
                              const int *lane_of, const int *depth_of, int count,
                              double *sums, double *gradients, double *band_sums,
                              double *band_gradients)
{
    double before_sum[PLOD__LANES], before_acc[3][PLOD__LANES];
    double after_sum[PLOD__LANES], after_acc[3][PLOD__LANES];
    int band_first = band_sums ? detail->fine_first : detail->count + 1;
    int band_end = band_sums ? detail->fine_end : detail->count + 1;
    int took_before = 0, took_after = 0;
    int deepest = 0, deepest_gradient = 0, depth[PLOD__LANES];
    int padded = PLOD__LANE_ROUND(count), earliest = detail->count;
    /* idle lanes are masked and may read any lattice point: the batch's
     * first direction keeps them in its cells (plod__lanes_noise's
     * one-cell octaves) */
    const double *idle_dir = plod__idle_dir;
    for (int k = 0; k < count; k++)
        if (plod__unit_range(dirs + 3 * (size_t)lane_of[k])) {
            idle_dir = dirs + 3 * (size_t)lane_of[k];
            break;
        }
    for (int k = 0; k < padded; k++) {
        int v = 0, g = 0, f = 0;
        const double *dir = idle_dir;
        if (k < count) {
            size_t at = (size_t)lane_of[k];
            v = octaves[at] < detail->count ? octaves[at] : detail->count;
            g = !gradients ? 0
                           : (gradient_octaves[at] < detail->count ? gradient_octaves[at]
                                                                   : detail->count);
            if (plod__unit_range(dirs + 3 * at))
                dir = dirs + 3 * at;
            else
                v = g = 0;
            f = first_octaves && first_octaves[at] > 0 ? first_octaves[at] : 0;
            earliest = f < earliest ? f : earliest;
        }
        l->first[k] = f;
        for (int a = 0; a < 3; a++)
            l->dir[a][k] = dir[a];
        l->value_count[k] = v;
        l->gradient_count[k] = g;
        depth[k] = k < count ? depth_of[lane_of[k]] : 0;
        deepest = depth[k] > deepest ? depth[k] : deepest;
        deepest_gradient = g > deepest_gradient ? g : deepest_gradient;
        l->sum[k] = 0.0;
        l->weight[k] = 1.0;
        for (int a = 0; a < 3; a++)
            l->acc[a][k] = l->dweight[a][k] = 0.0;
    }
    int active = count;
    for (int i = 0; i < deepest; i++) {
        if (i == band_first)
            plod__lanes_snapshot(l, count, before_sum, before_acc), took_before = 1;
        if (i == band_end)
            plod__lanes_snapshot(l, count, after_sum, after_acc), took_after = 1;
        if (i < earliest)
            continue; /* no lane has started (lanes only ever drop out below) */
        while (active > 0 && depth[active - 1] <= i)
            active--;
        l->count = PLOD__LANE_ROUND(active);
        const plod__octave *o = &detail->octaves[i];
        int gradient = i < deepest_gradient; /* a lane wants it */
        if (o->noise_weight != 0.0) {
            plod__lanes_noise(l, o, gradient);
            plod__lanes_accumulate(l, o, ridged, i, gradient);
        }
        if (o->crater_weight == 0.0)
            continue;
        /* craters: lane by lane, neighbouring lanes mostly in one cell */
        plod__crater_cell cell = {NAN, NAN, NAN, 0, {0.0, 0.0, 0.0}, 0.0};
        for (int k = 0; k < active; k++) {
            int started = i >= l->first[k];
            int add_sum = started && i < l->value_count[k];
            int add_gradient = started && i + PLOD_DETAIL_CRATER_NORMAL_LAG <
                                              l->gradient_count[k];
            if (!add_sum && !add_gradient)
                continue;
            double cp[3] = {l->p[0][k] + 0.5, l->p[1][k] + 0.5, l->p[2][k] + 0.5}, g[3];
            if (o->noise_weight == 0.0) /* the lattice point was not computed */
                for (int a = 0; a < 3; a++)
                    cp[a] = o->m[a][0] * l->dir[0][k] + o->m[a][1] * l->dir[1][k] +
                            o->m[a][2] * l->dir[2][k] + o->offset[a] + 0.5;
            double centre[3] = {o->offset[0] + 0.5, o->offset[1] + 0.5,
                                o->offset[2] + 0.5};
            double fx = plod__floor(cp[0]), fy = plod__floor(cp[1]), fz = plod__floor(cp[2]);
            if (fx != cell.fx || fy != cell.fy || fz != cell.fz)
                plod__crater_cell_of(fx, fy, fz, centre, o->frequency, o->crater_seed,
                                     detail->params.crater_density, &cell);
            double value = plod__crater_at(cp, &cell, g);
            if (value == 0.0)
                continue;
            if (add_sum)
                l->sum[k] += o->crater_weight * value;
            if (add_gradient) {
                double acc[3] = {l->acc[0][k], l->acc[1][k], l->acc[2][k]};
                plod__add_gradient(o, g, o->crater_weight, acc);
                for (int a = 0; a < 3; a++)
                    l->acc[a][k] = acc[a];
            }
        }
    }
    for (int k = 0; k < count; k++) {
        size_t at = (size_t)lane_of[k];
        int unit = plod__unit_range(dirs + 3 * at);
        sums[at] = unit ? l->sum[k] : NAN;
        if (gradients)
            for (int a = 0; a < 3; a++)
                gradients[3 * at + a] = unit ? l->acc[a][k] : NAN;
    }
    if (!band_sums)
        return;
    /* a band the batch did not reach ends (or starts) at the last sums */
    if (!took_before)
        plod__lanes_snapshot(l, count, before_sum, before_acc);
    if (!took_after)
        plod__lanes_snapshot(l, count, after_sum, after_acc);
    for (int k = 0; k < count; k++) {
        size_t at = (size_t)lane_of[k];
        int unit = plod__unit_range(dirs + 3 * at);
        band_sums[at] = unit ? after_sum[k] - before_sum[k] : NAN;
        if (gradients)
            for (int a = 0; a < 3; a++)
                band_gradients[3 * at + a] = unit ? after_acc[a][k] - before_acc[a][k] : NAN;
    }
}

void plod_detail_noise_n(const plod_detail *detail, size_t n, const double *dirs,
                         const int *octaves, const int *gradient_octaves, double *sums,
                         double *gradients)
{
    plod_detail_noise_from_n(detail, n, dirs, NULL, octaves, gradient_octaves, sums, gradients);
}

void plod_detail_noise_from_n(const plod_detail *detail, size_t n, const double *dirs,
                              const int *first_octaves, const int *octaves,
                              const int *gradient_octaves, double *sums, double *gradients)
{
    plod_detail_noise_band_n(detail, n, dirs, first_octaves, octaves, gradient_octaves, sums,
                             gradients, NULL, NULL);
}

void plod_detail_noise_band_n(const plod_detail *detail, size_t n, const double *dirs,
                              const int *first_octaves, const int *octaves,
                              const int *gradient_octaves, double *sums, double *gradients,
                              double *band_sums, double *band_gradients)
{
    int ridged = detail->params.style == PLOD_DETAIL_MOUNTAINS;
    plod__lanes lanes, *l = &lanes;
    int depth_of[PLOD__SORT_SPAN], order[PLOD__SORT_SPAN];
    int per_depth[PLOD_DETAIL_MAX_OCTAVES + 2];
    for (size_t first = 0; first < n; first += PLOD__SORT_SPAN) {
        int span = (int)(n - first < PLOD__SORT_SPAN ? n - first : PLOD__SORT_SPAN);
        /* the span's lanes deepest first (a stable counting sort on the
         * octaves to evaluate): in each batch the lanes still going at an
         * octave are a prefix, and the few deep ones (a sector's corners)
         * share a batch */
        memset(per_depth, 0, sizeof per_depth);
        for (int k = 0; k < span; k++) {
            size_t at = first + (size_t)k;
            int v = octaves[at] < detail->count ? octaves[at] : detail->count;
            int g = !gradients ? 0
                               : (gradient_octaves[at] < detail->count ? gradient_octaves[at]
                                                                       : detail->count);
            v = v > 0 ? v : 0;
            g = g > 0 ? g : 0;
            if (!plod__unit_range(dirs + 3 * at))
                v = g = 0; /* NaN below */
            depth_of[k] = v > g ? v : g;
            per_depth[depth_of[k]]++;
        }
        for (int d = detail->count, start = 0; d >= 0; d--) {
            int here = per_depth[d];
            per_depth[d] = start;
            start += here;
        }
        for (int k = 0; k < span; k++)
            order[per_depth[depth_of[k]]++] = k;
        for (int batch = 0; batch < span; batch += PLOD__LANES)
            plod__noise_batch(detail, ridged, l, dirs + 3 * first,
                              first_octaves ? first_octaves + first : NULL, octaves + first,
                              gradients ? gradient_octaves + first : NULL, order + batch,
                              depth_of, span - batch < PLOD__LANES ? span - batch : PLOD__LANES,
                              sums + first, gradients ? gradients + 3 * first : NULL,
                              band_sums ? band_sums + first : NULL,
                              band_sums && gradients ? band_gradients + 3 * first : NULL);
    }
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

int plod_detail_first_octave_below(const plod_detail *detail, double wavelength)
{
    /* a hair of tolerance: data of exactly the map's resolution drops nothing */
    double limit = wavelength * (1.0 + 1e-9);
    int k = 0;
    while (k < detail->count && detail->octaves[k].wavelength > limit)
        k++;
    return k;
}

void plod_detail_tail_range(const plod_detail *detail, int first, double *lo, double *hi)
{
    first = first < 0 ? 0 : (first > detail->count ? detail->count : first);
    *lo = detail->tail_lo[first];
    *hi = detail->tail_hi[first];
}

/* The ranges' centre: N's first `octaves` octaves at dir, and *band the
 * hills' band's part of them, in one pass (N's sum bit for bit
 * plod_detail_noise's). */
static double plod__prefix_value(const plod_detail *detail, const double dir[3], int octaves,
                                 double *band)
{
    int ridged = detail->params.style == PLOD_DETAIL_MOUNTAINS;
    plod__noise_state st;
    plod__noise_start(&st);
    double before = 0.0, after = 0.0;
    int took_before = 0, took_after = 0;
    for (int i = 0; i < octaves; i++) {
        if (i == detail->fine_first)
            before = st.sum, took_before = 1;
        if (i == detail->fine_end)
            after = st.sum, took_after = 1;
        plod__octave_step(detail, &detail->octaves[i], ridged, dir, 1, 0, 0, &st);
    }
    *band = (took_after ? after : st.sum) - (took_before ? before : st.sum);
    return st.sum;
}

void plod_detail_local_ranges(const plod_detail *detail, const double dir[3], double reach,
                              double cell, double *lo, double *hi, double *band_lo,
                              double *band_hi)
{
    *lo = detail->lo;
    *hi = detail->hi;
    int coarse = plod_detail_octaves_for_cell(detail, cell);
    double change = 0.0, band_change = 0.0;
    int first = detail->fine_first, end = detail->fine_end;
    for (int i = 0; i < coarse; i++) {
        const plod__octave *o = &detail->octaves[i];
        double width = o->hi - o->lo, step = o->slope * reach;
        change += step < width ? step : width;
        if (i >= first && i < end)
            band_change += step < width ? step : width;
    }
    /* the sum's rounding: far below any octave's range, but say so */
    double slack = 1e-12 * (detail->hi - detail->lo);
    double fine = detail->tail_hi[coarse] - detail->tail_lo[coarse];
    int want = 2.0 * change + fine < 0.75 * (detail->hi - detail->lo);
    /* the band's octaves alone: tail sums from `first` less those from `end` */
    int band_coarse = coarse < end ? coarse : end, want_band = 0;
    double fine_lo = 0.0, fine_hi = 0.0;
    if (band_lo) {
        *band_lo = *band_hi = 0.0;
        if (first < end) {
            *band_lo = detail->tail_lo[first] - detail->tail_lo[end] - slack;
            *band_hi = detail->tail_hi[first] - detail->tail_hi[end] + slack;
            fine_lo = detail->tail_lo[band_coarse] - detail->tail_lo[end];
            fine_hi = detail->tail_hi[band_coarse] - detail->tail_hi[end];
            want_band = band_coarse > first &&
                        2.0 * band_change + (fine_hi - fine_lo) < 0.75 * (*band_hi - *band_lo);
        }
    }
    if (!want && !want_band)
        return; /* not worth the evaluation */
    double band;
    double centre = plod__prefix_value(detail, dir, want ? coarse : band_coarse, &band);
    if (want) {
        double a = centre - change + detail->tail_lo[coarse] - slack;
        double b = centre + change + detail->tail_hi[coarse] + slack;
        *lo = a > *lo ? a : *lo;
        *hi = b < *hi ? b : *hi;
        if (*lo > *hi)
            *lo = *hi;
    }
    if (want_band) {
        double a = band - band_change + fine_lo - slack, b = band + band_change + fine_hi + slack;
        *band_lo = a > *band_lo ? a : *band_lo;
        *band_hi = b < *band_hi ? b : *band_hi;
        if (*band_lo > *band_hi)
            *band_lo = *band_hi;
    }
}

void plod_detail_local_range(const plod_detail *detail, const double dir[3], double reach,
                             double cell, double *lo, double *hi)
{
    plod_detail_local_ranges(detail, dir, reach, cell, lo, hi, NULL, NULL);
}

void plod_detail_band_local_range(const plod_detail *detail, const double dir[3],
                                  double reach, double cell, double *lo, double *hi)
{
    double nlo, nhi;
    plod_detail_local_ranges(detail, dir, reach, cell, &nlo, &nhi, lo, hi);
}

/* half the unit range of octave i's layers, metres */
static double plod__half_range(const plod_detail *d, int i)
{
    const plod__octave *o = &d->octaves[i];
    double noise = o->noise_weight * (d->params.style == PLOD_DETAIL_MOUNTAINS ? 0.5 : 1.0);
    return noise + o->crater_weight * 0.5 * (1.0 + PLOD__CRATER_RIM);
}

/* octaves first..visible-1 */
static double plod__cell_error_exact(const plod_detail *d, double cell, int first, int visible)
{
    int keep = plod_detail_octaves_for_cell(d, cell);
    double e2 = 0.0;
    for (int i = first; i < visible; i++) {
        double half = plod__half_range(d, i), term = half;
        if (i < keep) {
            /* linear interpolation over a cell: ~ a (pi cell / wavelength)^2 / 2 */
            double x = cell / d->octaves[i].wavelength;
            double f = 0.5 * PLOD_PI * PLOD_PI * x * x;
            term = half * (f < 1.0 ? f : 1.0);
        }
        e2 += term * term;
    }
    return sqrt(e2);
}

static double plod__cell_error_table(const plod_detail *detail,
                                     const double (*table)[PLOD__ERR_COUNT], double cell,
                                     int visible)
{
    if (!(cell > 0.0) || visible <= 0)
        return 0.0;
    const double *err = table[visible < detail->count ? visible : detail->count];
    int e;
    double mant = frexp(cell, &e); /* cell = mant 2^e, mant in [0.5, 1) */
    if (e <= PLOD__ERR_EXP_MIN)
        return err[0];
    if (e > PLOD__ERR_EXP_MAX)
        return err[PLOD__ERR_COUNT - 1];
    double hi = err[e - PLOD__ERR_EXP_MIN], lo = err[e - 1 - PLOD__ERR_EXP_MIN];
    return lo + (hi - lo) * (2.0 * mant - 1.0);
}

double plod_detail_cell_error_visible(const plod_detail *detail, double cell, int visible)
{
    return plod__cell_error_table(detail, detail->err, cell, visible);
}

double plod_detail_cell_error_band(const plod_detail *detail, double cell, int visible)
{
    if (detail->fine_first >= detail->fine_end)
        return 0.0;
    return plod__cell_error_table(detail, detail->err_band, cell, visible);
}

double plod_detail_cell_error(const plod_detail *detail, double cell)
{
    return plod_detail_cell_error_visible(detail, cell, detail->count);
}

int plod_detail_octaves_at_least(const plod_detail *detail, double wavelength)
{
    int k = 0;
    while (k < detail->count && detail->octaves[k].wavelength >= wavelength)
        k++;
    return k;
}

int plod_detail_fine_first(const plod_detail *detail)
{
    return detail->fine_first;
}

int plod_detail_fine_end(const plod_detail *detail)
{
    return detail->fine_end;
}

double plod_detail_fine_modulation(const plod_detail *detail, double m)
{
    const plod_detail_params *p = &detail->params;
    if (detail->fine_first >= detail->count || !(p->hills < 1.0) || !(m > p->plains))
        return m; /* no band, no hills below the top, plains, sea or NaN */
    double top = p->hills_fine * p->hills;
    top = top < 1.0 ? top : 1.0;
    if (m < p->hills)
        return p->plains + (top - p->plains) * ((m - p->plains) / (p->hills - p->plains));
    if (m < 1.0)
        return top + (1.0 - top) * ((m - p->hills) / (1.0 - p->hills));
    return m;
}

double plod_detail_fine_excess_max(const plod_detail *detail, double m0, double m1)
{
    if (detail->fine_first >= detail->count || m0 != m0 || m1 != m1)
        return 0.0;
    if (m0 > m1) {
        double t = m0;
        m0 = m1, m1 = t;
    }
    double best = plod_detail_fine_modulation(detail, m0) - m0;
    double e1 = plod_detail_fine_modulation(detail, m1) - m1;
    best = e1 > best ? e1 : best;
    double h = detail->params.hills; /* g - m is piecewise linear: its knot */
    if (m0 < h && h < m1) {
        double eh = plod_detail_fine_modulation(detail, h) - h;
        best = eh > best ? eh : best;
    }
    /* the division's rounding in g, far below any height's */
    return best > 0.0 ? best * (1.0 + 1e-9) + 1e-12 : 0.0;
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

/* N's lowest value at PLOD__DEPTH_SAMPLES directions drawn from the seed's
 * hash (uniform in the cube, normalised: + - * / sqrt only, so the same
 * bits everywhere). */
#define PLOD__DEPTH_SAMPLES 4096
static double plod__deepest(const plod_detail *d)
{
    double deepest = 0.0;
    uint64_t h = plod__mix(d->params.seed ^ 0xdee9ULL);
    for (int k = 0; k < PLOD__DEPTH_SAMPLES; k++) {
        double v[3], len2 = 0.0;
        for (int a = 0; a < 3; a++) {
            h = plod__mix(h + 0x9E3779B97F4A7C15ULL);
            v[a] = 2.0 * plod__unit(h) - 1.0;
            len2 += v[a] * v[a];
        }
        if (!(len2 > 1e-6 && len2 <= 1.0))
            continue; /* inside the unit ball: uniform directions */
        double len = sqrt(len2);
        double dir[3] = {v[0] / len, v[1] / len, v[2] / len};
        double n = plod__noise_value(d, dir, 0, d->count);
        deepest = n < deepest ? n : deepest;
    }
    return deepest;
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
    double plains = d->params.plains, hills = d->params.hills;
    double highlands = d->params.highlands;
    for (int f = 0; f < faces; f++) {
        uint8_t *out = plod_cubemap_face_data(d->modulation, f);
        for (size_t t = 0; t < texels; t++) {
            double r = relief[(size_t)f * texels + t];
            double m = 0.0;
            if (r >= 0.0) {
                /* plains up to a third of the reference: one quantum of
                 * an 8-bit map's steps is no hill */
                double x = 1.5 * r / reference - 0.5;
                x = x > 0.0 ? (x < 1.0 ? x : 1.0) : 0.0; /* inf / inf (NaN): 0 */
                m = plains + (hills - plains) * x * x * (3.0 - 2.0 * x);
                if (highlands > 0.0) {
                    /* steepness gate: from r = reference to 5 reference */
                    double g = (r - reference) / (4.0 * reference);
                    g = g > 0.0 ? (g < 1.0 ? g : 1.0) : 0.0; /* NaN: 0 */
                    double e = above[(size_t)f * texels + t] / highlands;
                    e = e > 0.0 ? (e < 1.0 ? e : 1.0) : 0.0; /* no sea level: 1 */
                    m += (1.0 - hills) * g * g * (3.0 - 2.0 * g) * e;
                    m = m < 1.0 ? m : 1.0;
                }
                /* low coasts: the field's deepest half-range stays above the sea */
                if (d->deepest < 0.0) {
                    double limit = 2.0 * above[(size_t)f * texels + t] / -d->deepest;
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
           p->plains >= 0.0 && p->plains <= 1.0 && isfinite(p->relief) && p->relief >= 0.0 &&
           p->hills >= p->plains && p->hills <= 1.0 && isfinite(p->highlands) &&
           p->highlands >= 0.0 && p->fine_roughness >= 0.0 && p->fine_roughness < 1.0 &&
           isfinite(p->fine_below) && p->fine_below >= 0.0 && isfinite(p->hills_fine) &&
           p->hills_fine >= 1.0 && p->hills_fine <= 16.0 && isfinite(p->hills_fine_below) &&
           p->hills_fine_below >= 0.0 && isfinite(p->hills_fine_to) && p->hills_fine_to >= 0.0;
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
                                     ? 0.5 * PLOD_PI / size
                                     : PLOD_PI / size;
            largest = 2.0 * texel_angle * planet->radius;
        } else if (planet->source) { /* an out-of-core map: its texel at the equator */
            static const double equator[3] = {1.0, 0.0, 0.0};
            double texel_angle = planet->source->ops->texel_angle(planet->source->self, equator);
            largest = texel_angle > 0.0 && isfinite(texel_angle)
                          ? 2.0 * texel_angle * planet->radius
                          : planet->radius / 50.0;
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
            d->lo -= PLOD__RIDGE_CENTRE * o->noise_weight;
            d->hi += (1.0 - PLOD__RIDGE_CENTRE) * o->noise_weight;
        } else {
            d->lo -= o->noise_weight;
            d->hi += o->noise_weight;
        }
        d->lo -= o->crater_weight;
        d->hi += o->crater_weight * PLOD__CRATER_RIM;
        o->lo = -(params->style == PLOD_DETAIL_MOUNTAINS ? PLOD__RIDGE_CENTRE : 1.0) *
                    o->noise_weight -
                o->crater_weight;
        o->hi = (params->style == PLOD_DETAIL_MOUNTAINS ? 1.0 - PLOD__RIDGE_CENTRE : 1.0) *
                    o->noise_weight +
                o->crater_weight * PLOD__CRATER_RIM;
        /* slopes per lattice unit: noise PLOD__NOISE_LIPSCHITZ; ridged term
         * a (w ds + (s - CENTRE) dw) with |ds| <= 2 L, |dw| <= gain 2 L at the
         * previous octave's half frequency; crater profile slope / r_min */
        double noise_slope = PLOD__NOISE_LIPSCHITZ * freq;
        if (params->style == PLOD_DETAIL_MOUNTAINS)
            noise_slope = 2.0 * PLOD__NOISE_LIPSCHITZ * freq +
                          PLOD__RIDGE_CENTRE * PLOD__RIDGE_GAIN * 2.0 *
                              PLOD__NOISE_LIPSCHITZ * 0.5 * freq;
        double crater_slope = 2.0 * (1.0 + PLOD__CRATER_RIM) / PLOD__CRATER_SMALLEST * freq;
        o->slope = o->noise_weight * noise_slope + o->crater_weight * crater_slope;
        plod__matmul(rot, acc, acc);
        wavelength *= 0.5;
        amplitude *= wavelength < params->fine_below ? params->fine_roughness
                                                      : params->roughness;
        count++;
    }
    d->count = count;
    d->fine_first = d->fine_end = count;
    if (params->hills_fine > 1.0 && params->hills_fine_below > 0.0) {
        d->fine_first = plod_detail_octaves_at_least(d, params->hills_fine_below);
        d->fine_end = params->hills_fine_to > 0.0
                          ? plod_detail_octaves_at_least(d, params->hills_fine_to)
                          : count;
        if (d->fine_end <= d->fine_first)
            d->fine_first = d->fine_end = count; /* an empty band */
    }
    d->tail_lo[count] = d->tail_hi[count] = 0.0;
    for (int i = count - 1; i >= 0; i--) {
        d->tail_lo[i] = d->tail_lo[i + 1] + d->octaves[i].lo;
        d->tail_hi[i] = d->tail_hi[i + 1] + d->octaves[i].hi;
    }
    for (int v = 0; v <= count; v++)
        for (int e = 0; e < PLOD__ERR_COUNT; e++) {
            double cell = ldexp(1.0, e + PLOD__ERR_EXP_MIN);
            d->err[v][e] = plod__cell_error_exact(d, cell, 0, v);
            int band_end = v < d->fine_end ? v : d->fine_end;
            d->err_band[v][e] = PLOD_DETAIL_BAND_ERROR_SHARE *
                                plod__cell_error_exact(d, cell, d->fine_first, band_end);
        }
    d->deepest = plod__deepest(d);
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
                           (double)params->style, params->hills, params->highlands,
                           params->fine_roughness, params->fine_below, params->hills_fine,
                           params->hills_fine_below, params->hills_fine_to};
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
