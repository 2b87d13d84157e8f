/* projection.c -- cube-sphere projections (TSC, CSC, QSC, spherified) and
 * plate carree (CAR), WCSLIB-style: one block per family with a face-local
 * forward (unit direction on a face -> (u, v)) and inverse ((u, v) -> unit
 * direction), shared face framing, and the cross-layout / lon-lat wrappers.
 *
 * Face frames (Calabretta & Greisen 2002, as WCSLIB): a direction d on face f
 * has zeta = d.c_f (>= |xi|, |eta|), xi = d.e_u, eta = d.e_v with
 *     face 0: c = +z, e_u = +y, e_v = -x        face 3: c = -x, e_u = -y, e_v = +z
 *     face 1: c = +x, e_u = +y, e_v = +z        face 4: c = -y, e_u = +x, e_v = +z
 *     face 2: c = +y, e_u = -x, e_v = +z        face 5: c = -z, e_u = +y, e_v = +x
 * Every frame vector is a signed unit axis, so the frame changes are exact
 * (sign flips and permutations); that is what makes edge points bit-identical
 * after canonicalisation.  Ties in face selection go to the lowest face.
 *
 * Cross layout [deg]: x = 45 (u + x0_f), y = 45 (v + y0_f) with
 *     (x0, y0) = (0, 2), (0, 0), (2, 0), (4, 0), (6, 0), (0, -2)
 * so face 4 spans x in [225, 315] (WCSLIB's s2x convention); the inverse also
 * accepts x in [-135, -45] for face 4 (WCSLIB's x2s wraps x < -45 by +360).
 *
 * Gasiński's thesis: K. Gasiński, "Porównanie metod wizualizacji terenu w
 * czasie rzeczywistym" (comparison of real-time terrain visualisation
 * methods), master's thesis, Gdańsk University of Technology, 2010, chapter
 * 3 (quad-sphere and cube-sphere formulas).
 */
#include "plod_projection.h"

#include <ctype.h>
#include <stdint.h>
#include <math.h>
#include <string.h>

#define PLOD__D2R (PLOD_PI / 180.0)
#define PLOD__R2D (180.0 / PLOD_PI)
#define PLOD__SQRT1_2 0.70710678118654752440

/* The per-point kernels are forced inline so that the vectorised loops,
 * instantiated once per projection below, fold the projection dispatch. */
#if defined(__GNUC__) || defined(__clang__)
#define PLOD__HOT static inline __attribute__((always_inline))
#else
#define PLOD__HOT static inline
#endif

static const char *const plod__projection_names[PLOD_PROJ_COUNT] = {
    "tsc", "csc", "qsc", "spherified", "car",
};

plod_status plod_projection_from_name(const char *name, plod_projection *out)
{
    if (!name || !out)
        return PLOD_ERR_NULL;
    for (int p = 0; p < PLOD_PROJ_COUNT; p++) {
        const char *candidate = plod__projection_names[p];
        size_t i = 0;
        while (candidate[i] && name[i] &&
               tolower((unsigned char)name[i]) == candidate[i])
            i++;
        if (!candidate[i] && !name[i]) {
            *out = (plod_projection)p;
            return PLOD_OK;
        }
    }
    return PLOD_ERR_BAD_PROJECTION;
}

const char *plod_projection_name(plod_projection projection)
{
    if ((unsigned)projection >= PLOD_PROJ_COUNT)
        return NULL;
    return plod__projection_names[projection];
}

int plod_projection_is_cube(plod_projection projection)
{
    return (unsigned)projection < PLOD_PROJ_CAR;
}

/* ======================================================================== */
/* Face frames                                                               */
/* ======================================================================== */

/* Frame tables: component index and sign of c, e_u, e_v per face, so the
 * frame changes are table lookups (branch-free for random faces). */
static const int plod__ic[PLOD_FACE_COUNT] = {2, 0, 1, 0, 1, 2};
static const int plod__iu[PLOD_FACE_COUNT] = {1, 1, 0, 1, 0, 1};
static const int plod__iv[PLOD_FACE_COUNT] = {0, 2, 2, 2, 2, 0};
static const double plod__sc[PLOD_FACE_COUNT] = {1.0, 1.0, 1.0, -1.0, -1.0, -1.0};
static const double plod__su[PLOD_FACE_COUNT] = {1.0, 1.0, -1.0, -1.0, 1.0, 1.0};
static const double plod__sv[PLOD_FACE_COUNT] = {-1.0, 1.0, 1.0, 1.0, 1.0, 1.0};

plod_status plod_face_frame(int face, int frame[3][3])
{
    if (face < 0 || face >= PLOD_FACE_COUNT)
        return PLOD_ERR_BAD_PARAM;
    const int index[3] = {plod__ic[face], plod__iu[face], plod__iv[face]};
    const double sign[3] = {plod__sc[face], plod__su[face], plod__sv[face]};
    for (int a = 0; a < 3; a++)
        for (int k = 0; k < 3; k++)
            frame[a][k] = k == index[a] ? (int)sign[a] : 0;
    return PLOD_OK;
}

PLOD__HOT double plod__maxd(double a, double b) { return a > b ? a : b; }

/* cond ? a : b on the bits (no branch for the compiler to thread: GCC
 * if-converts only small selects, and batch loops must stay branch-free) */
PLOD__HOT double plod__pick(int cond, double a, double b)
{
    uint64_t bits_a, bits_b, mask = (uint64_t)0 - (uint64_t)(cond != 0);
    memcpy(&bits_a, &a, sizeof a);
    memcpy(&bits_b, &b, sizeof b);
    uint64_t bits = (bits_a & mask) | (bits_b & ~mask);
    double out;
    memcpy(&out, &bits, sizeof out);
    return out;
}

/* cond ? a : b for small integers, arithmetically */
PLOD__HOT int plod__pick_int(int cond, int a, int b)
{
    return b ^ ((a ^ b) & -(cond != 0));
}

/* Lowest face whose centre axis is the largest component of d (ties -> the
 * lower face, as WCSLIB's strict '>' chain), branch-free (NaN: face 0). */
PLOD__HOT int plod__select_face(double x, double y, double z)
{
    double m = plod__maxd(plod__maxd(plod__maxd(z, x), plod__maxd(y, -x)),
                          plod__maxd(-y, -z));
    int face = 0; /* the first match wins: tested last */
    face = plod__pick_int(-z == m, 5, face);
    face = plod__pick_int(-y == m, 4, face);
    face = plod__pick_int(-x == m, 3, face);
    face = plod__pick_int(y == m, 2, face);
    face = plod__pick_int(x == m, 1, face);
    face = plod__pick_int(z == m, 0, face);
    return face;
}

/* The frame tables as selects (a batch loop cannot index a table per
 * lane): each coordinate is one component or its negation, exactly. */
PLOD__HOT void plod__to_local(int face, double x, double y, double z,
                                  double *xi, double *eta, double *zeta)
{
    double a = y, b = z, c = -z; /* face 5's, then the others' */
    a = plod__pick(face == 2, -x, a);
    a = plod__pick(face == 3, -y, a);
    a = plod__pick(face == 4, x, a);
    b = plod__pick(face == 0, -x, b);
    b = plod__pick(face == 5, x, b);
    c = plod__pick(face == 0, z, c);
    c = plod__pick(face == 1, x, c);
    c = plod__pick(face == 2, y, c);
    c = plod__pick(face == 3, -x, c);
    c = plod__pick(face == 4, -y, c);
    *xi = a;
    *eta = b;
    *zeta = c;
}

PLOD__HOT void plod__from_local(int face, double xi, double eta, double zeta,
                                    double d[3])
{
    d[plod__iu[face]] = plod__su[face] * xi;
    d[plod__iv[face]] = plod__sv[face] * eta;
    d[plod__ic[face]] = plod__sc[face] * zeta;
}

/* ======================================================================== */
/* TSC: tangential spherical cube (gnomonic per face)                        */
/*   forward  u = xi/zeta, v = eta/zeta                                      */
/*   inverse  (xi, eta, zeta) = (u, v, 1) / sqrt(1 + u^2 + v^2)              */
/* ======================================================================== */

PLOD__HOT void plod__tsc_fwd(double xi, double eta, double zeta, double r,
                                 double *u, double *v)
{
    (void)r;
    double inv = 1.0 / zeta;
    *u = xi * inv;
    *v = eta * inv;
}

PLOD__HOT void plod__tsc_inv(double u, double v, double *xi, double *eta,
                                 double *zeta)
{
    double r = 1.0 / sqrt(1.0 + u * u + v * v);
    *xi = u * r;
    *eta = v * r;
    *zeta = r;
}

/* ======================================================================== */
/* CSC: COBE quadrilateralized spherical cube (Chan & O'Neill 1975)          */
/*   forward  u = F(a, b), v = F(b, a) with (a, b) the TSC coordinates and   */
/*     F(a,b) = a gs + a^3 (1 - gs)                                          */
/*            + a b^2 (1 - a^2) [G + (M - G) a^2 + (1 - b^2) sum C_ij a^2i b^2j] */
/*            + a^3 (1 - a^2) [O1 - (1 - a^2) sum D_i a^2i]                  */
/*   inverse  chi = f(u, v), psi = f(v, u),                                  */
/*     f(X, Y) = X + X (1 - X^2) sum_{j<=6} sum_{i<=6-j} P_ij X^2i Y^2j,     */
/*   then the TSC inverse of (chi, psi).  Constants: Calabretta & Greisen    */
/*   2002 (Gasiński's thesis, 3.7.2, prints psi^2i where psi^2j is meant).   */
/*   The pair is an approximation: the sphere round trip errs by up to       */
/*   2.2e-4 rad (0.0125 deg, 2.9e-4 of a face unit; median 2.7e-5 rad),      */
/*   the same as WCSLIB's own cscs2x -> cscx2s (measured in the tests and    */
/*   the bench).  Evaluated in double precision.                             */
/* ======================================================================== */

PLOD__HOT double plod__csc_F(double a, double b)
{
    const double gstar = 1.37484847732, mm = 0.004869491981;
    const double gamma = -0.13161671474, omega1 = -0.159596235474;
    const double d0 = 0.0759196200467, d1 = -0.0217762490699;
    const double c00 = 0.141189631152, c10 = 0.0809701286525;
    const double c01 = -0.281528535557, c11 = 0.15384112876;
    const double c20 = -0.178251207466, c02 = 0.106959469314;
    double a2 = a * a, b2 = b * b, ca2 = 1.0 - a2, cb2 = 1.0 - b2;
    double sum_c = c00 + c10 * a2 + c01 * b2 + c11 * a2 * b2 + c20 * a2 * a2 +
                   c02 * b2 * b2;
    return a * (a2 + ca2 * (gstar + b2 * (gamma * ca2 + mm * a2 + cb2 * sum_c) +
                            a2 * (omega1 - ca2 * (d0 + d1 * a2))));
}

PLOD__HOT double plod__csc_f(double xf, double yf)
{
    const double p00 = -0.27292696, p10 = -0.07629969, p20 = -0.22797056;
    const double p30 = 0.54852384, p40 = -0.62930065, p50 = 0.25795794;
    const double p60 = 0.02584375, p01 = -0.02819452, p11 = -0.01471565;
    const double p21 = 0.48051509, p31 = -1.74114454, p41 = 1.71547508;
    const double p51 = -0.53022337, p02 = 0.27058160, p12 = -0.56800938;
    const double p22 = 0.30803317, p32 = 0.98938102, p42 = -0.83180469;
    const double p03 = -0.60441560, p13 = 1.50880086, p23 = -0.93678576;
    const double p33 = 0.08693841, p04 = 0.93412077, p14 = -1.41601920;
    const double p24 = 0.33887446, p05 = -0.63915306, p15 = 0.52032238;
    const double p06 = 0.14381585;
    double xx = xf * xf, yy = yf * yf;
    double z0 = p00 + xx * (p10 + xx * (p20 + xx * (p30 + xx * (p40 + xx * (p50 + xx * p60)))));
    double z1 = p01 + xx * (p11 + xx * (p21 + xx * (p31 + xx * (p41 + xx * p51))));
    double z2 = p02 + xx * (p12 + xx * (p22 + xx * (p32 + xx * p42)));
    double z3 = p03 + xx * (p13 + xx * (p23 + xx * p33));
    double z4 = p04 + xx * (p14 + xx * p24);
    double z5 = p05 + xx * p15;
    double sum = z0 + yy * (z1 + yy * (z2 + yy * (z3 + yy * (z4 + yy * (z5 + yy * p06)))));
    return xf + xf * (1.0 - xx) * sum;
}

PLOD__HOT void plod__csc_fwd(double xi, double eta, double zeta, double r,
                                 double *u, double *v)
{
    (void)r;
    double a = xi / zeta, b = eta / zeta;
    *u = plod__csc_F(a, b);
    *v = plod__csc_F(b, a);
}

PLOD__HOT void plod__csc_inv(double u, double v, double *xi, double *eta,
                                 double *zeta)
{
    plod__tsc_inv(plod__csc_f(u, v), plod__csc_f(v, u), xi, eta, zeta);
}

/* ======================================================================== */
/* QSC: quadrilateralized spherical cube (O'Neill & Laubscher 1976), exact   */
/* and equal-area.  In the sector |xi| >= |eta| (the other is symmetric):    */
/*   omega = eta/xi, q = sqrt(2 + omega^2)                                   */
/*   u^2 = (1 - zeta) / (1 - 1/q),  v = u (12/pi) [atan omega - asin(omega/  */
/*         sqrt(2 + 2 omega^2))] = u (12/pi) atan(omega (q-1) / (q+omega^2)) */
/* Full double accuracy near the face centre: 1 - zeta is never formed by    */
/* subtraction (1 - zeta = (xi^2 + eta^2)/(1 + zeta), so                     */
/* u = xi sqrt((1 + omega^2) q / ((1 + zeta)(q - 1)))); the two arctangents  */
/* are merged with the subtraction formula (no cancellation, one atan).      */
/* Inverse, |u| >= |v|: t = (pi/12) v/u, omega = sin t / (cos t - 1/sqrt2)   */
/* (written with T = tan(t/2)), zeco = 1 - zeta = u^2 (q-1)/q,               */
/* xi = u sqrt(k (2 - zeco)/(1 + omega^2)) with k = (q-1)/q, eta = xi omega. */
/* ======================================================================== */

/* atan on |z| <= tan(15 deg) and tan on |t| <= pi/24, the only ranges QSC
 * needs: inline odd polynomials (Chebyshev fit for atan, 4.3e-16 relative;
 * Taylor to t^15 for tan, < 1e-17 truncation) instead of libm calls, so the
 * per-point kernels pipeline.  Accuracy is checked against WCSLIB in tests. */
PLOD__HOT double plod__qsc_atan(double z)
{
    /* Estrin's scheme: a short dependency chain, so points pipeline. */
    double s = z * z, s2 = s * s, s4 = s2 * s2, s8 = s4 * s4;
    double p01 = 0.9999999999999998 - 0.33333333333326276 * s;
    double p23 = 0.1999999999827801 - 0.14285714105900996 * s;
    double p45 = 0.11111101552317065 - 0.09090627784508971 * s;
    double p67 = 0.07687627787632645 - 0.06623679080877609 * s;
    double p89 = 0.05663496622387825 - 0.04312702159641274 * s;
    double p03 = p01 + p23 * s2, p47 = p45 + p67 * s2;
    return z * ((p03 + p47 * s4) + p89 * s8);
}

PLOD__HOT double plod__qsc_tan(double t)
{
    double s = t * t, s2 = s * s, s4 = s2 * s2;
    double q01 = 1.0 + (1.0 / 3.0) * s;
    double q23 = 2.0 / 15.0 + (17.0 / 315.0) * s;
    double q45 = 62.0 / 2835.0 + (1382.0 / 155925.0) * s;
    double q67 = 21844.0 / 6081075.0 + (929569.0 / 638512875.0) * s;
    return t * ((q01 + q23 * s2) + (q45 + q67 * s2) * s4);
}

PLOD__HOT void plod__qsc_fwd(double xi, double eta, double zeta, double r,
                                 double *u, double *v)
{
    int swap = fabs(eta) > fabs(xi); /* selects instead of branches */
    double major = swap ? eta : xi, minor = swap ? xi : eta;
    double omega = minor / major;
    double w2 = omega * omega;
    double q = sqrt(2.0 + w2);
    double along = major * sqrt((1.0 + w2) * q / ((r + zeta) * r * (q - 1.0)));
    double across = along * (12.0 / PLOD_PI) * plod__qsc_atan(omega * (q - 1.0) / (q + w2));
    int centre = major == 0.0; /* the face centre: no omega */
    *u = centre ? 0.0 : (swap ? across : along);
    *v = centre ? 0.0 : (swap ? along : across);
}

PLOD__HOT void plod__qsc_inv(double u, double v, double *xi, double *eta,
                                 double *zeta)
{
    const double in[2] = {u, v};
    int swap = fabs(v) > fabs(u);
    double major = in[swap], minor = in[1 - swap];
    if (major == 0.0) {
        *xi = 0.0;
        *eta = 0.0;
        *zeta = 1.0;
        return;
    }
    double tt = plod__qsc_tan((PLOD_PI / 24.0) * (minor / major));
    double omega = 2.0 * tt / ((1.0 - PLOD__SQRT1_2) - (1.0 + PLOD__SQRT1_2) * tt * tt);
    double w2 = omega * omega;
    double q = sqrt(2.0 + w2);
    double k = (q - 1.0) / q;
    double zeco = major * major * k;
    double out[2];
    out[swap] = major * sqrt(k * (2.0 - zeco) / (1.0 + w2));
    out[1 - swap] = out[swap] * omega;
    *zeta = 1.0 - zeco;
    *xi = out[0];
    *eta = out[1];
}

/* ======================================================================== */
/* Spherified cube: cube point (u, v, 1) -> sphere, per axis                 */
/*   xi = u sqrt(1/2 - v^2/6), eta = v sqrt(1/2 - u^2/6),                    */
/*   zeta = sqrt((1 - u^2/2)(1 - v^2/2) + u^2 v^2 / 12)   (exactly unit).    */
/* Inverse in closed form: with U = u^2, V = v^2, d = xi^2 - eta^2,          */
/*   U^2 - (3 + 2d) U + 6 xi^2 = 0, smaller root in the stable form          */
/*   U = 12 xi^2 / ((3 + 2d) + sqrt((3 + 2d)^2 - 24 xi^2)), V likewise with   */
/*   -d and eta; then one Newton step on the 2x2 system polishes to ~1 ulp.  */
/* ======================================================================== */

PLOD__HOT void plod__sph_inv(double u, double v, double *xi, double *eta,
                                 double *zeta)
{
    double u2 = u * u, v2 = v * v;
    *xi = u * sqrt(0.5 - v2 * (1.0 / 6.0));
    *eta = v * sqrt(0.5 - u2 * (1.0 / 6.0));
    *zeta = sqrt((1.0 - 0.5 * u2) * (1.0 - 0.5 * v2) + u2 * v2 * (1.0 / 12.0));
}

PLOD__HOT double plod__sph_root(double s2, double d)
{
    double p = 3.0 + 2.0 * d;
    double disc = p * p - 24.0 * s2;
    if (disc < 0.0)
        disc = 0.0;
    return 12.0 * s2 / (p + sqrt(disc));
}

PLOD__HOT void plod__sph_fwd(double xi, double eta, double zeta, double r,
                                 double *u, double *v)
{
    (void)zeta;
    if (r != 1.0) {
        double inv = 1.0 / r;
        xi *= inv;
        eta *= inv;
    }
    double x2 = xi * xi, y2 = eta * eta, d = x2 - y2;
    double a = copysign(sqrt(plod__sph_root(x2, d)), xi);
    double b = copysign(sqrt(plod__sph_root(y2, -d)), eta);
    /* Newton polish: F = (a s(b) - xi, b s(a) - eta), s(t) = sqrt(1/2 - t^2/6). */
    double sa = sqrt(0.5 - a * a * (1.0 / 6.0)), sb = sqrt(0.5 - b * b * (1.0 / 6.0));
    double f1 = a * sb - xi, f2 = b * sa - eta;
    double j11 = sb, j12 = -a * b / (6.0 * sb);
    double j21 = -a * b / (6.0 * sa), j22 = sa;
    double det = j11 * j22 - j12 * j21;
    if (det != 0.0) {
        a -= (f1 * j22 - f2 * j12) / det;
        b -= (j11 * f2 - j21 * f1) / det;
    }
    *u = a;
    *v = b;
}

/* ======================================================================== */
/* Face-local dispatch (cube projections)                                    */
/* ======================================================================== */

/* (xi, eta, zeta) of length r (r = 1 for unit input), on the face
 * (zeta >= |xi|, |eta|) -> (u, v) in [-1, 1]; exactly +-1 when the
 * direction is exactly on an edge.  Taking r instead of normalising first
 * keeps a sqrt and a division off each point's dependency chain. */
PLOD__HOT void plod__local_fwd(plod_projection projection, double xi,
                                   double eta, double zeta, double r, double *u,
                                   double *v)
{
    double a, b;
    switch (projection) {
    case PLOD_PROJ_TSC: plod__tsc_fwd(xi, eta, zeta, r, &a, &b); break;
    case PLOD_PROJ_CSC: plod__csc_fwd(xi, eta, zeta, r, &a, &b); break;
    case PLOD_PROJ_QSC: plod__qsc_fwd(xi, eta, zeta, r, &a, &b); break;
    default: plod__sph_fwd(xi, eta, zeta, r, &a, &b); break;
    }
    if (fabs(xi) >= zeta)
        a = copysign(1.0, xi);
    if (fabs(eta) >= zeta)
        b = copysign(1.0, eta);
    *u = a < -1.0 ? -1.0 : (a > 1.0 ? 1.0 : a);
    *v = b < -1.0 ? -1.0 : (b > 1.0 ? 1.0 : b);
}

/* (u, v) in [-1, 1] -> unit (xi, eta, zeta); on an edge (|u| == 1) the
 * result has |xi| == zeta exactly, so the direction is exactly on the edge. */
PLOD__HOT void plod__local_inv(plod_projection projection, double u,
                                   double v, double *xi, double *eta, double *zeta)
{
    double a, b, c;
    switch (projection) {
    case PLOD_PROJ_TSC: plod__tsc_inv(u, v, &a, &b, &c); break;
    case PLOD_PROJ_CSC: plod__csc_inv(u, v, &a, &b, &c); break;
    case PLOD_PROJ_QSC: plod__qsc_inv(u, v, &a, &b, &c); break;
    default: plod__sph_inv(u, v, &a, &b, &c); break;
    }
    if (fabs(u) == 1.0)
        a = copysign(c, u);
    if (fabs(v) == 1.0)
        b = copysign(c, v);
    *xi = a;
    *eta = b;
    *zeta = c;
}

/* Unit vector, -0 turned into +0 so equal points have equal bits. */
PLOD__HOT void plod__normalise(double d[3])
{
    double r = 1.0 / sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    d[0] = d[0] * r + 0.0;
    d[1] = d[1] * r + 0.0;
    d[2] = d[2] * r + 0.0;
}

/* Cube projections: (face, u, v) valid -> unit direction, evaluated on the
 * lowest face containing the cube point c_f + u e_u + v e_v. */
PLOD__HOT void plod__cube_face_to_dir(plod_projection projection, int face,
                                          double u, double v, double d[3])
{
    u += 0.0;
    v += 0.0;
    if (fabs(u) == 1.0 || fabs(v) == 1.0) {
        double p[3];
        plod__from_local(face, u, v, 1.0, p);
        int canonical = plod__select_face(p[0], p[1], p[2]);
        double zeta;
        plod__to_local(canonical, p[0], p[1], p[2], &u, &v, &zeta);
        face = canonical;
    }
    double xi, eta, zeta;
    plod__local_inv(projection, u, v, &xi, &eta, &zeta);
    /* The inverses are unit to rounding (|d| - 1 < 5e-16, tested); only
     * -0 is turned into +0 so that equal points have equal bits. */
    plod__from_local(face, xi + 0.0, eta + 0.0, zeta, d);
    d[0] += 0.0;
    d[1] += 0.0;
    d[2] += 0.0;
}

/* ======================================================================== */
/* CAR: plate carree; its refinement domain is the octahedral square.        */
/* Face 0, (u, v) in [-1, 1]^2, h = pi/2, a = |u|, b = |v|, s = a + b:       */
/*   lat = h (1 - s)                     (linear in |u| + |v|; s <= 1 north) */
/*   north (s <= 1): lon = h b / s within the quadrant                      */
/*   south (s > 1): fold a' = 1 - b, b' = 1 - a (s' = a' + b' = 2 - s) and   */
/*                  lon = h b' / s'                                          */
/*   quadrant by the signs: x takes the sign of u, y the sign of v, so       */
/*   (1, 0) -> lon 0, (0, 1) -> lon 90, (-1, 0) -> lon 180, (0, -1) -> -90;  */
/*   the square's border folds onto the meridians 0/90/180/-90 south of the */
/*   equator, its corners onto the south pole.                              */
/* Evaluated as x = sin(h s) sin(h a/s), y = sin(h s) sin(h b/s),           */
/* z = cos(h s) (south: with a', b', s' and z = -cos(h s')), then signed    */
/* and normalised: the octant edges (u = 0, v = 0, the border) come out     */
/* bit-identical from either side.  Rows of constant s are latitude circles */
/* of 4s (or 4s') unit lengths, so geometry crowds towards the poles like   */
/* the CAR quad-sphere of Gasiński's thesis.                                */
/* ======================================================================== */

PLOD__HOT void plod__car_face_to_dir(double u, double v, double d[3])
{
    const double h = 0.5 * PLOD_PI;
    double a = fabs(u), b = fabs(v);
    double s = a + b, z_sign = 1.0;
    if (s > 1.0) {
        double a2 = 1.0 - b, b2 = 1.0 - a;
        a = a2;
        b = b2;
        s = a + b;
        z_sign = -1.0;
    }
    if (s == 0.0) {
        d[0] = 0.0;
        d[1] = 0.0;
        d[2] = z_sign;
        return;
    }
    double r = sin(h * s);
    d[0] = r * sin(h * (a / s));
    d[1] = r * sin(h * (b / s));
    d[2] = z_sign * cos(h * s);
    if (u < 0.0)
        d[0] = -d[0];
    if (v < 0.0)
        d[1] = -d[1];
    plod__normalise(d);
}

PLOD__HOT void plod__car_dir_to_face(const double d[3], double *u, double *v)
{
    const double h = 0.5 * PLOD_PI;
    double ax = fabs(d[0]), ay = fabs(d[1]);
    double rho = hypot(ax, ay);
    double t = atan2(ay, ax) / h; /* fraction of the quadrant, 0 at lon 0 */
    double a, b;
    if (d[2] >= 0.0) {
        double s = atan2(rho, d[2]) / h;
        b = s * t;
        a = s - b;
    } else {
        double s = atan2(rho, -d[2]) / h;
        double b2 = s * t, a2 = s - b2;
        a = 1.0 - b2;
        b = 1.0 - a2;
    }
    a = a > 1.0 ? 1.0 : a;
    b = b > 1.0 ? 1.0 : b;
    *u = (d[0] < 0.0 ? -a : a) + 0.0;
    *v = (d[1] < 0.0 ? -b : b) + 0.0;
}

/* Instantiates PLOD__LOOP(PROJ) once per projection, so each vectorised
 * loop runs with a compile-time projection (no per-point dispatch). */
#define PLOD__PER_PROJECTION(projection)                                          \
    switch (projection) {                                                         \
    case PLOD_PROJ_TSC: PLOD__LOOP(PLOD_PROJ_TSC) break;                          \
    case PLOD_PROJ_CSC: PLOD__LOOP(PLOD_PROJ_CSC) break;                          \
    case PLOD_PROJ_QSC: PLOD__LOOP(PLOD_PROJ_QSC) break;                          \
    case PLOD_PROJ_SPHERIFIED: PLOD__LOOP(PLOD_PROJ_SPHERIFIED) break;            \
    default: PLOD__LOOP(PLOD_PROJ_CAR) break;                                     \
    }

/* ======================================================================== */
/* Direction <-> face                                                        */
/* ======================================================================== */

PLOD__HOT int plod__finite3(const double d[3])
{
    return isfinite(d[0]) && isfinite(d[1]) && isfinite(d[2]);
}

/* Unchecked core: d finite and non-zero. */
PLOD__HOT void plod__dir_to_face(plod_projection projection, const double dir[3],
                                     int *face, double *u, double *v)
{
    double d[3] = {dir[0], dir[1], dir[2]};
    double r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    if (!(r2 > 1e-290 && r2 < 1e290)) {
        /* Scale by the largest component first so huge/tiny inputs normalise. */
        double m = plod__maxd(fabs(d[0]), plod__maxd(fabs(d[1]), fabs(d[2])));
        d[0] /= m;
        d[1] /= m;
        d[2] /= m;
    }
    if (projection == PLOD_PROJ_CAR) { /* scale-invariant */
        *face = 0;
        plod__car_dir_to_face(d, u, v);
        return;
    }
    double r = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    int f = plod__select_face(d[0], d[1], d[2]);
    double xi, eta, zeta;
    plod__to_local(f, d[0], d[1], d[2], &xi, &eta, &zeta);
    plod__local_fwd(projection, xi, eta, zeta, r, u, v);
    *u += 0.0;
    *v += 0.0;
    *face = f;
}

plod_status plod_dir_to_face(plod_projection projection, const double dir[3],
                             int *face, double *u, double *v)
{
    if (!dir || !face || !u || !v)
        return PLOD_ERR_NULL;
    if ((unsigned)projection >= PLOD_PROJ_COUNT)
        return PLOD_ERR_BAD_PROJECTION;
    if (!plod__finite3(dir) || (dir[0] == 0.0 && dir[1] == 0.0 && dir[2] == 0.0))
        return PLOD_ERR_BAD_COORD;
    plod__dir_to_face(projection, dir, face, u, v);
    return PLOD_OK;
}

PLOD__HOT plod_status plod__face_to_dir(plod_projection projection, int face,
                                        double u, double v, double dir[3])
{
    int max_face = projection == PLOD_PROJ_CAR ? 0 : PLOD_FACE_COUNT - 1;
    if (face < 0 || face > max_face)
        return PLOD_ERR_BAD_PARAM;
    if (!(fabs(u) <= 1.0 && fabs(v) <= 1.0)) /* also rejects NaN */
        return PLOD_ERR_BAD_COORD;
    if (projection == PLOD_PROJ_CAR)
        plod__car_face_to_dir(u, v, dir);
    else
        plod__cube_face_to_dir(projection, face, u, v, dir);
    return PLOD_OK;
}

plod_status plod_face_to_dir(plod_projection projection, int face, double u,
                             double v, double dir[3])
{
    if (!dir)
        return PLOD_ERR_NULL;
    if ((unsigned)projection >= PLOD_PROJ_COUNT)
        return PLOD_ERR_BAD_PROJECTION;
    return plod__face_to_dir(projection, face, u, v, dir);
}

/* The batch, lane by lane as if every direction were finite and of
 * moderate length (those are exactly plod__dir_to_face's operations: no
 * rescaling): branch-free, so the loop vectorises.  redo[i] marks the
 * others, for the caller to take one by one. */
PLOD_LANE_CLONES PLOD_LANE_LOOPS static void plod__dir_to_face_lanes(
    plod_projection projection, size_t n, const double *dirs, int *faces, double *u, double *v,
    unsigned char *redo)
{
#define PLOD__LOOP(PROJ)                                                                  \
    for (size_t i = 0; i < n; i++) {                                                      \
        double x = dirs[3 * i], y = dirs[3 * i + 1], z = dirs[3 * i + 2];                 \
        double r2 = x * x + y * y + z * z;                                                \
        redo[i] = !((r2 > 1e-290) & (r2 < 1e290)); /* also NaN and infinities */          \
        double r = sqrt(x * x + y * y + z * z), xi, eta, zeta, a, b;                      \
        int f = plod__select_face(x, y, z);                                               \
        plod__to_local(f, x, y, z, &xi, &eta, &zeta);                                     \
        plod__local_fwd(PROJ, xi, eta, zeta, r, &a, &b);                                  \
        faces[i] = f;                                                                     \
        u[i] = a + 0.0;                                                                   \
        v[i] = b + 0.0;                                                                   \
    }
    switch (projection) {
    case PLOD_PROJ_TSC: PLOD__LOOP(PLOD_PROJ_TSC) break;
    case PLOD_PROJ_CSC: PLOD__LOOP(PLOD_PROJ_CSC) break;
    case PLOD_PROJ_QSC: PLOD__LOOP(PLOD_PROJ_QSC) break;
    default: PLOD__LOOP(PLOD_PROJ_SPHERIFIED) break;
    }
#undef PLOD__LOOP
}

plod_status plod_dir_to_face_n(plod_projection projection, size_t n,
                               const double *dirs, int *faces, double *u,
                               double *v, int *stat)
{
    if (n && (!dirs || !faces || !u || !v))
        return PLOD_ERR_NULL;
    if ((unsigned)projection >= PLOD_PROJ_COUNT)
        return PLOD_ERR_BAD_PROJECTION;
    plod_status first = PLOD_OK;
    enum { BLOCK = 256 };
    unsigned char redo[BLOCK];
    for (size_t begin = 0; begin < n; begin += BLOCK) {
        size_t count = n - begin < BLOCK ? n - begin : BLOCK;
        const double *block_dirs = dirs + 3 * begin;
        if (projection == PLOD_PROJ_CAR)
            memset(redo, 1, count);
        else
            plod__dir_to_face_lanes(projection, count, block_dirs, faces + begin, u + begin,
                                    v + begin, redo);
        for (size_t k = 0; k < count; k++) {
            size_t i = begin + k;
            plod_status st = PLOD_OK;
            if (redo[k]) {
                const double *d = dirs + 3 * i;
                if (!plod__finite3(d) || (d[0] == 0.0 && d[1] == 0.0 && d[2] == 0.0)) {
                    st = PLOD_ERR_BAD_COORD;
                    faces[i] = -1;
                    u[i] = v[i] = NAN;
                } else {
                    plod__dir_to_face(projection, d, faces + i, u + i, v + i);
                }
            }
            if (stat)
                stat[i] = (int)st;
            if (st != PLOD_OK && first == PLOD_OK)
                first = st;
        }
    }
    return first;
}

plod_status plod_face_to_dir_n(plod_projection projection, size_t n,
                               const int *faces, const double *u,
                               const double *v, double *dirs, int *stat)
{
    if (n && (!faces || !u || !v || !dirs))
        return PLOD_ERR_NULL;
    if ((unsigned)projection >= PLOD_PROJ_COUNT)
        return PLOD_ERR_BAD_PROJECTION;
    plod_status first = PLOD_OK;
#define PLOD__LOOP(PROJ)                                                          \
    for (size_t i = 0; i < n; i++) {                                              \
        plod_status st = plod__face_to_dir(PROJ, faces[i], u[i], v[i], dirs + 3 * i); \
        if (st != PLOD_OK) {                                                      \
            dirs[3 * i] = dirs[3 * i + 1] = dirs[3 * i + 2] = NAN;                \
            if (first == PLOD_OK)                                                 \
                first = st;                                                       \
        }                                                                         \
        if (stat)                                                                 \
            stat[i] = (int)st;                                                    \
    }
    PLOD__PER_PROJECTION(projection)
#undef PLOD__LOOP
    return first;
}

/* ======================================================================== */
/* Spherical [deg] <-> cross layout [deg]                                    */
/* ======================================================================== */

static const double plod__face_x0[PLOD_FACE_COUNT] = {0.0, 0.0, 2.0, 4.0, 6.0, 0.0};
static const double plod__face_y0[PLOD_FACE_COUNT] = {2.0, 0.0, 0.0, 0.0, 0.0, -2.0};

/* Wraps a finite longitude into [-180, 180] exactly. */
PLOD__HOT double plod__wrap_lon(double lon)
{
    if (fabs(lon) <= 180.0) /* the common case skips the libm call */
        return lon;
    lon = fmod(lon, 360.0);
    if (lon > 180.0)
        lon -= 360.0;
    else if (lon < -180.0)
        lon += 360.0;
    return lon;
}

/* sin and cos of an angle in [-180, 180] degrees, reduced exactly to
 * [-45, 45] first: multiples of 90 give exact 0/+-1. */
PLOD__HOT void plod__sincosd(double deg, double *s, double *c)
{
    static const double sign_s[4] = {1.0, 1.0, -1.0, -1.0};
    static const double sign_c[4] = {1.0, -1.0, -1.0, 1.0};
    int q = (int)(deg / 90.0 + 2.5) - 2; /* floor(deg/90 + 1/2), deg >= -180 */
    double r = (deg - 90.0 * q) * PLOD__D2R;
    const double sc[2] = {sin(r), cos(r)};
    int odd = q & 1;
    *s = sign_s[q & 3] * sc[odd];
    *c = sign_c[q & 3] * sc[1 - odd];
}

PLOD__HOT plod_status plod__sphere_to_cube(plod_projection projection,
                                               double lon, double lat,
                                               double *x, double *y)
{
    if (!isfinite(lon) || !(fabs(lat) <= 90.0))
        return PLOD_ERR_BAD_COORD;
    lon = plod__wrap_lon(lon);
    if (projection == PLOD_PROJ_CAR) {
        *x = lon;
        *y = lat;
        return PLOD_OK;
    }
    double slon, clon, slat, clat;
    plod__sincosd(lon, &slon, &clon);
    plod__sincosd(lat, &slat, &clat);
    double dx = clat * clon, dy = clat * slon, dz = slat;
    int f = plod__select_face(dx, dy, dz);
    double xi, eta, zeta, u, v;
    plod__to_local(f, dx, dy, dz, &xi, &eta, &zeta);
    plod__local_fwd(projection, xi, eta, zeta, 1.0, &u, &v);
    *x = 45.0 * (u + plod__face_x0[f]);
    *y = 45.0 * (v + plod__face_y0[f]);
    return PLOD_OK;
}

PLOD__HOT plod_status plod__cube_to_sphere(plod_projection projection,
                                               double x, double y,
                                               double *lon, double *lat)
{
    if (!isfinite(x) || !isfinite(y))
        return PLOD_ERR_BAD_COORD;
    if (projection == PLOD_PROJ_CAR) {
        if (!(fabs(x) <= 180.0 && fabs(y) <= 90.0))
            return PLOD_ERR_BAD_COORD;
        *lon = x;
        *lat = y;
        return PLOD_OK;
    }
    double xf = x / 45.0, yf = y / 45.0;
    /* WCSLIB's bounds: the cross's column |x| <= 45 or its equatorial row. */
    if (fabs(xf) <= 1.0) {
        if (fabs(yf) > 3.0)
            return PLOD_ERR_BAD_COORD;
    } else if (fabs(xf) > 7.0 || fabs(yf) > 1.0) {
        return PLOD_ERR_BAD_COORD;
    }
    if (xf < -1.0)
        xf += 8.0;
    int f;
    if (xf > 5.0) { f = 4; xf -= 6.0; }
    else if (xf > 3.0) { f = 3; xf -= 4.0; }
    else if (xf > 1.0) { f = 2; xf -= 2.0; }
    else if (yf > 1.0) { f = 0; yf -= 2.0; }
    else if (yf < -1.0) { f = 5; yf += 2.0; }
    else { f = 1; }
    xf = xf < -1.0 ? -1.0 : (xf > 1.0 ? 1.0 : xf);
    yf = yf < -1.0 ? -1.0 : (yf > 1.0 ? 1.0 : yf);
    double d[3];
    plod__cube_face_to_dir(projection, f, xf, yf, d);
    double rho = sqrt(d[0] * d[0] + d[1] * d[1]);
    *lon = rho == 0.0 ? 0.0 : atan2(d[1], d[0]) * PLOD__R2D;
    *lat = atan(d[2] / rho) * PLOD__R2D; /* rho == 0: z/0 = +-inf, lat +-90 */
    return PLOD_OK;
}

plod_status plod_sphere_to_cube(plod_projection projection, double lon_deg,
                                double lat_deg, double *x_deg, double *y_deg)
{
    if (!x_deg || !y_deg)
        return PLOD_ERR_NULL;
    if ((unsigned)projection >= PLOD_PROJ_COUNT)
        return PLOD_ERR_BAD_PROJECTION;
    return plod__sphere_to_cube(projection, lon_deg, lat_deg, x_deg, y_deg);
}

plod_status plod_cube_to_sphere(plod_projection projection, double x_deg,
                                double y_deg, double *lon_deg, double *lat_deg)
{
    if (!lon_deg || !lat_deg)
        return PLOD_ERR_NULL;
    if ((unsigned)projection >= PLOD_PROJ_COUNT)
        return PLOD_ERR_BAD_PROJECTION;
    return plod__cube_to_sphere(projection, x_deg, y_deg, lon_deg, lat_deg);
}

/* One specialised loop per projection (PLOD__PER_PROJECTION): a failed
 * point gives NaN outputs and its status; the first failure is returned. */
#define PLOD__POINT_LOOP(FN, PROJ, IN_A, IN_B, OUT_A, OUT_B)                      \
    for (size_t i = 0; i < n; i++) {                                              \
        plod_status st = FN(PROJ, IN_A[i], IN_B[i], OUT_A + i, OUT_B + i);        \
        if (st != PLOD_OK) {                                                      \
            OUT_A[i] = OUT_B[i] = NAN;                                            \
            if (first == PLOD_OK)                                                 \
                first = st;                                                       \
        }                                                                         \
        if (stat)                                                                 \
            stat[i] = (int)st;                                                    \
    }

plod_status plod_sphere_to_cube_n(plod_projection projection, size_t n,
                                  const double *lon_deg, const double *lat_deg,
                                  double *x_deg, double *y_deg, int *stat)
{
    if (n && (!lon_deg || !lat_deg || !x_deg || !y_deg))
        return PLOD_ERR_NULL;
    if ((unsigned)projection >= PLOD_PROJ_COUNT)
        return PLOD_ERR_BAD_PROJECTION;
    plod_status first = PLOD_OK;
#define PLOD__LOOP(PROJ) PLOD__POINT_LOOP(plod__sphere_to_cube, PROJ, lon_deg, lat_deg, x_deg, y_deg)
    PLOD__PER_PROJECTION(projection)
#undef PLOD__LOOP
    return first;
}

plod_status plod_cube_to_sphere_n(plod_projection projection, size_t n,
                                  const double *x_deg, const double *y_deg,
                                  double *lon_deg, double *lat_deg, int *stat)
{
    if (n && (!x_deg || !y_deg || !lon_deg || !lat_deg))
        return PLOD_ERR_NULL;
    if ((unsigned)projection >= PLOD_PROJ_COUNT)
        return PLOD_ERR_BAD_PROJECTION;
    plod_status first = PLOD_OK;
#define PLOD__LOOP(PROJ) PLOD__POINT_LOOP(plod__cube_to_sphere, PROJ, x_deg, y_deg, lon_deg, lat_deg)
    PLOD__PER_PROJECTION(projection)
#undef PLOD__LOOP
    return first;
}
