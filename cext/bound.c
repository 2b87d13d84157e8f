/* bound.c -- the bounding volumes of sectors and the only visibility and
 * error tests of the refinement.
 *
 * A sector's bound is a cap prism: every point r d with the unit direction
 * d within the cap angle of `axis` and r in [r_min, r_max] (metres from
 * the planet centre), r from the planet's height range over the sector.
 * Every test is exact or conservative for the prism, hence conservative
 * for the sector inside it:
 *   - horizon: a point at radius r >= rho is hidden by the ball of radius
 *     rho (the occluder, the lowest surface) from an eye at distance
 *     D > rho iff its angle from the eye direction exceeds
 *     acos(rho / D) + acos(rho / r); the largest r is the most visible,
 *     the smallest angle to the cap the most visible.
 *   - frustum: the max over the prism of n.x is the max over the cap of
 *     n.d (cos(max(0, angle(n, axis) - angle))) times r_max if positive,
 *     r_min otherwise; a bounding ball decides most planes first.
 *   - distance: the nearest direction is the eye direction clamped onto
 *     the cap; the nearest point of that ray segment closes it.
 * Angles are kept as cosines and sines, so a test costs a few dot
 * products (no trigonometry on the per-frame path).
 */
#include "plod_bound.h"
#include "plod_detail.h"

#include <math.h>
#include <string.h>

/* Cap angle inflation: slack against rounding in the corner angles. */
#define PLOD__CAP_INFLATE 1.0001
/* Height-range query box grows by this fraction of the sector's (u, v)
 * extent: mapped great-circle edges bulge out of the straight (u, v) ones
 * in the non-gnomonic projections. */
#define PLOD__RANGE_MARGIN 0.25
#define PLOD__ONE ((int32_t)1 << PLOD_COORD_BITS)

/* ---- construction ----------------------------------------------------------- */

void plod_bound_setup_init(plod_bound_setup *setup, const plod_planet *planet)
{
    double hmin, hmax;
    setup->planet = planet;
    setup->texels_per_unit =
        planet->heightmap ? 0.5 * plod_cubemap_size(planet->heightmap) : 0.0;
    plod_planet_height_range(planet, &hmin, &hmax);
    setup->occluder = planet->radius + hmin;
}

static double plod__memo_height(const plod_planet *planet, plod_bound_corners *memo, int k)
{
    if (!(memo->known & (1u << k))) {
        memo->height[k] = plod_planet_map_height(planet, memo->dir[k]);
        memo->known |= 1u << k;
    }
    return memo->height[k];
}

/* Below a texel the pyramid range (of the texels a sample can touch) stops
 * shrinking, so a camera a few metres over rough ground would sit inside
 * the prism of every sector under it at every level (distance 0: splits to
 * max_level, sectors of nanometres).  A sub-texel sector's bilinear surface
 * stays within lip * reach of its corner heights: the bilinear gradient is
 * at most sqrt(2) * (range of the touched texels) per texel, and a point of
 * the sector (edges bulge by < PLOD__RANGE_MARGIN of the box) is at most
 * sqrt(2) * (1 + 2 margin) * extent texels from a corner (CAR: texels of
 * the lon/lat box around the sector's cap). */
static void plod__tighten_subtexel(const plod_planet *planet, plod_bound_corners *memo,
                                   const int idx[3], double texels, double *hmin,
                                   double *hmax)
{
    if ((!planet->heightmap && !planet->source) || !(texels < 0.5) || !(*hmax > *hmin))
        return;
    double lo = INFINITY, hi = -INFINITY;
    for (int k = 0; k < 3; k++) {
        double h = plod__memo_height(planet, memo, idx[k]);
        lo = h < lo ? h : lo;
        hi = h > hi ? h : hi;
    }
    double reach = PLOD_SQRT2 * (1.0 + 2.0 * PLOD__RANGE_MARGIN) * texels;
    /* + the seam tolerance: across a face edge the two faces' samples
     * agree to ~1e-6 relative, not exactly */
    double deviation = 1.01 * PLOD_SQRT2 * (*hmax - *hmin) * reach +
                       2e-6 * fmax(fabs(*hmin), fabs(*hmax));
    double tight_min = lo - deviation, tight_max = hi + deviation;
    if (!(tight_min <= tight_max)) /* NaN corner heights: keep the range */
        return;
    *hmin = tight_min > *hmin ? tight_min : *hmin;
    *hmax = tight_max < *hmax ? tight_max : *hmax;
    if (*hmin > *hmax)
        *hmin = *hmax;
}

/* Bounds of the detail field m N over a sector (plod_detail.h): the
 * region's modulation bounds [mlo, mhi] times N's bounds.  Small sectors
 * tighten both around corner 0: m as the map heights are (bilinear, below
 * half a texel), N by plod_detail_local_range over the cap's diameter
 * chord 2 sin(angle) (every point of the sector is within it of corner
 * 0), with the octaves a mesh of the sector drops counted by range;
 * over an inset widened by the range of the octaves the field keeps there.
 * *mod_max: the modulation bound (the error's scale); *band_max: the
 * hills' band's excess bound (its error's scale). */
static void plod__detail_bound(const plod_planet *planet, const plod_sector *s,
                               plod_bound_corners *memo, const int idx[3], const plod_bound *b,
                               double u0, double v0, double u1, double v1, double texels,
                               double *dmin, double *dmax, double *mod_max, double *band_max)
{
    double m[2];
    if (plod_projection_is_cube(planet->projection))
        plod_planet_detail_range_uv(planet, s->face, u0, v0, u1, v1, dmin, dmax, m);
    else
        plod_planet_detail_range_cap(planet, b->axis, atan2(b->sin_angle, b->cos_angle), dmin,
                                     dmax, m);
    *mod_max = m[1];
    *band_max = plod_detail_fine_excess_max(planet->detail, m[0], m[1]);
    if (!(m[1] > 0.0))
        return; /* sea: no detail */
    const double *corner = memo->dir[idx[0]];
    if (planet->heightmap && texels < 0.5 && m[1] > m[0]) {
        double mc = plod_planet_modulation(planet, corner);
        double reach = PLOD_SQRT2 * (1.0 + 2.0 * PLOD__RANGE_MARGIN) * texels;
        double deviation = 1.01 * PLOD_SQRT2 * (m[1] - m[0]) * reach + 2e-6;
        if (mc - deviation > m[0])
            m[0] = mc - deviation;
        if (mc + deviation < m[1])
            m[1] = mc + deviation;
        if (!(m[0] <= m[1])) /* NaN: keep the region's */
            return;
    }
    double chord = 2.0 * b->sin_angle * (b->cos_angle > 0.0 ? 1.0 : 0.0);
    if (!(chord > 0.0))
        return; /* a cap past a hemisphere: the region's bounds */
    /* the cap's angle only where insets may meet it */
    int first = planet->insets ? plod_planet_detail_first_octave_cap(
                                     planet, b->axis, atan2(b->sin_angle, b->cos_angle))
                               : plod_detail_octave_count(planet->detail);
    double excess = plod_detail_fine_excess_max(planet->detail, m[0], m[1]);
    int inset = first < plod_detail_octave_count(planet->detail);
    /* N's range and, over the band's excess, B's: one evaluation */
    double nlo, nhi, blo = 0.0, bhi = 0.0;
    plod_detail_local_ranges(planet->detail, corner, chord, b->size, &nlo, &nhi,
                             excess > 0.0 && !inset ? &blo : NULL, &bhi);
    if (inset) {
        /* an inset: there the field blends toward its fine octaves alone */
        double flo, fhi;
        plod_detail_tail_range(planet->detail, first, &flo, &fhi);
        nlo = flo < nlo ? flo : nlo;
        nhi = fhi > nhi ? fhi : nhi;
    }
    /* m in [m0, m1] >= 0 times N in [nlo, nhi], plus the hills' band's
     * excess (g(m) - m) B, B a partial sum of the band's octaves */
    double p[4] = {m[0] * nlo, m[0] * nhi, m[1] * nlo, m[1] * nhi};
    double lo = p[0], hi = p[0];
    for (int k = 1; k < 4; k++) {
        lo = p[k] < lo ? p[k] : lo;
        hi = p[k] > hi ? p[k] : hi;
    }
    if (excess > 0.0) {
        if (inset) /* an inset: B may start at its first octave, any partial sum */
            plod_detail_tail_range(planet->detail, plod_detail_fine_first(planet->detail), &blo,
                                   &bhi);
        /* (g - m) in [0, excess] */
        lo += excess * (blo < 0.0 ? blo : 0.0);
        hi += excess * (bhi > 0.0 ? bhi : 0.0);
    }
    *dmin = lo > *dmin ? lo : *dmin;
    *dmax = hi < *dmax ? hi : *dmax;
    if (*dmin > *dmax)
        *dmin = *dmax;
    *mod_max = m[1];
    *band_max = excess;
}

/* cos and sin of a cap angle (given by its cosine and sine) grown by the
 * rounding slack PLOD__CAP_INFLATE: by delta >= (INFLATE - 1) * angle,
 * from angle <= pi/2 * sine below 90 degrees and <= pi above. */
static void plod__inflate_cap(double sine, double cosine, double *sin_out, double *cos_out)
{
    double s = sine, c = cosine; /* of unit vectors: s^2 + c^2 = 1 within rounding */
    double bound = c > 0.0 ? (PLOD_PI / 2) * s : PLOD_PI;
    double delta = (PLOD__CAP_INFLATE - 1.0) * bound + 1e-15;
    double cd = 1.0 - 0.5 * delta * delta, sd = delta - delta * delta * delta * (1.0 / 6.0);
    double cos_ = c * cd - s * sd, sin_ = s * cd + c * sd;
    if (sin_ < 0.0) { /* past pi: the whole sphere */
        cos_ = -1.0;
        sin_ = 0.0;
    }
    *cos_out = cos_;
    *sin_out = sin_;
}

/* Whether every bilinear tap in the face box [u0,u1] x [v0,v1] reads the
 * same 2 x 2 texels of one face (cube maps, away from face edges, where the
 * height map is one bilinear patch: the range query then returns exactly
 * those 4 texels' range). */
static int plod__inside_one_cell(const plod_bound_setup *setup, double u0, double v0, double u1,
                                 double v1)
{
    if (!setup->planet->heightmap || !plod_projection_is_cube(setup->planet->projection))
        return 0;
    double size = 2.0 * setup->texels_per_unit;
    double i0 = floor((u0 + 1.0) * 0.5 * size - 0.5), i1 = floor((u1 + 1.0) * 0.5 * size - 0.5);
    double j0 = floor((v0 + 1.0) * 0.5 * size - 0.5), j1 = floor((v1 + 1.0) * 0.5 * size - 0.5);
    return i0 == i1 && j0 == j1 && i0 >= 0.0 && j0 >= 0.0 && i1 + 1.0 <= size - 1.0 &&
           j1 + 1.0 <= size - 1.0;
}

/* Bound of sector s whose corners are memo->dir[idx[0..2]]. */
void plod_bound_build(const plod_bound_setup *setup, const plod_sector *s,
                      plod_bound_corners *memo, const int idx[3], plod_bound *b)
{
    const plod_planet *planet = setup->planet;
    const double *c[3] = {memo->dir[idx[0]], memo->dir[idx[1]], memo->dir[idx[2]]};
    b->memo = (plod_bound_memo){0};
    double axis[3] = {c[0][0] + c[1][0] + c[2][0], c[0][1] + c[1][1] + c[2][1],
                      c[0][2] + c[1][2] + c[2][2]};
    double len = plod_norm3(axis);
    double inv_len = 1.0 / len;
    for (int k = 0; k < 3; k++)
        b->axis[k] = axis[k] * inv_len;
    /* the cap angle: the largest corner angle from the axis (largest sine
     * below 90 degrees, where the sine resolves small angles; smallest
     * cosine above), kept as its cosine and sine: no trigonometry.  Sines
     * and chords are compared squared: one square root each */
    double cap_sin2 = 0.0, cap_cos = 1.0, chord2 = 0.0;
    int acute = 1;
    for (int k = 0; k < 3; k++) {
        const double *a = b->axis, *v = c[k];
        double x[3];
        plod_cross3(a, v, x);
        double sine2 = plod_dot3(x, x);
        double cosine = plod_dot3(a, v);
        if (cosine <= 0.0 && acute) {
            acute = 0;
            cap_sin2 = sine2, cap_cos = cosine;
        } else if (acute ? sine2 > cap_sin2 : cosine < cap_cos) {
            cap_sin2 = sine2, cap_cos = cosine;
        }
        const double *p = c[k], *q = c[(k + 1) % 3];
        double d[3] = {p[0] - q[0], p[1] - q[1], p[2] - q[2]};
        double ch2 = plod_dot3(d, d);
        chord2 = ch2 > chord2 ? ch2 : chord2;
    }
    plod__inflate_cap(sqrt(cap_sin2), cap_cos, &b->sin_angle, &b->cos_angle);
    b->size = sqrt(chord2) * planet->radius;

    const double scale = 1.0 / (double)PLOD__ONE;
    double u0 = 2, u1 = -2, v0 = 2, v1 = -2;
    for (int k = 0; k < 3; k++) {
        double u = s->cu[k] * scale, v = s->cv[k] * scale;
        u0 = u < u0 ? u : u0;
        u1 = u > u1 ? u : u1;
        v0 = v < v0 ? v : v0;
        v1 = v > v1 ? v : v1;
    }
    double extent = fmax(u1 - u0, v1 - v0);
    double mu = (u1 - u0) * PLOD__RANGE_MARGIN, mv = (v1 - v0) * PLOD__RANGE_MARGIN;
    u0 = fmax(-1.0, u0 - mu);
    u1 = fmin(1.0, u1 + mu);
    v0 = fmax(-1.0, v0 - mv);
    v1 = fmin(1.0, v1 + mv);
    double hmin, hmax, texels;
    if (plod_projection_is_cube(planet->projection) && !planet->source) {
        plod_planet_height_range_uv(planet, s->face, u0, v0, u1, v1, &hmin, &hmax);
        texels = extent * setup->texels_per_unit;
    } else {
        /* CAR, or a height source: the octahedral square / the face is
         * not the data's lon/lat grid */
        plod_planet_height_range_cap(planet, b->axis, atan2(b->sin_angle, b->cos_angle),
                                     &hmin, &hmax, &texels);
    }
    double inset_lo, inset_hi, cap_angle = 0.0;
    plod_insets_relief inset;
    int insets = 0;
    if (planet->insets) { /* the cap's angle only where insets may meet it */
        cap_angle = atan2(b->sin_angle, b->cos_angle);
        insets = plod_planet_insets_range_cap(planet, b->axis, cap_angle, &inset_lo, &inset_hi,
                                              &inset);
    }
    double inset_relief = 0.0;
    if (insets) { /* the blend lies between the global data and the insets */
        hmin = inset_lo < hmin ? inset_lo : hmin;
        hmax = inset_hi > hmax ? inset_hi : hmax;
        /* the insets' own relief at their spacing, as the map's below: over
         * a sector e samples across, the pyramid's mean change per sample
         * times the e + 1 samples it touches (no more than the range),
         * shrinking with e below one sample as the map's relief of the
         * 2 x 2 texels around does */
        double e = inset.texel_angle > 0.0 ? 2.0 * cap_angle / inset.texel_angle : 1.0;
        double range = inset_hi - inset_lo;
        double across = inset.per_sample * (e < 1.0 ? 1.0 : e + 1.0);
        inset_relief = (across < range ? across : range) * (e < 1.0 ? e : 1.0);
    }
    double relief_range = hmax - hmin;
    if (!insets) /* corner heights are blends there, not the map's bilinear patch */
        plod__tighten_subtexel(planet, memo, idx, texels, &hmin, &hmax);
    b->detail0 = b->band0 = 0.0;
    if (planet->detail) { /* the map's bounds (tightened on map heights) + the field's */
        double dmin, dmax;
        plod__detail_bound(planet, s, memo, idx, b, u0, v0, u1, v1, texels, &dmin, &dmax,
                           &b->detail0, &b->band0);
        hmin += dmin;
        hmax += dmax;
    }
    float fmin_ = (float)hmin, fmax_ = (float)hmax;
    if ((double)fmin_ > hmin)
        fmin_ = nextafterf(fmin_, -INFINITY);
    if ((double)fmax_ < hmax)
        fmax_ = nextafterf(fmax_, INFINITY);
    b->hmin = fmin_;
    b->hmax = fmax_;
    b->r_min = planet->radius + fmin_;
    b->r_max = planet->radius + fmax_;
    /* Ground below the sea is drawn at the sea's surface (the lifted mesh
     * of the add-on and the preview): the shell of a sector under the sea
     * reaches up to it, so that culling, the horizon and the distance see
     * the water, not only the sea floor.  hmin / hmax stay the ground's
     * (the sector's heights, its sea flag). */
    if (planet->has_sea_level && b->r_max < planet->radius + planet->sea_level)
        b->r_max = planet->radius + planet->sea_level;
    b->sag0 = b->size * b->size / (8.0 * b->r_min);
    b->relief0 = relief_range * (texels < 1.0 ? texels : 1.0) + inset_relief;
    b->twist0 = !insets && plod__inside_one_cell(setup, u0, v0, u1, v1)
                    ? 3.0 * relief_range * texels * texels
                    : INFINITY;
    double rho = setup->occluder;
    b->horizon = b->r_max >= rho;
    if (b->horizon) { /* cap angle + beta, cos beta = rho / r_max */
        double inv_r = 1.0 / b->r_max;
        double cb = rho * inv_r, sb = sqrt((b->r_max - rho) * (b->r_max + rho)) * inv_r;
        b->horizon_cos = b->cos_angle * cb - b->sin_angle * sb;
        b->horizon_sin = b->sin_angle * cb + b->cos_angle * sb;
    }
    if (b->cos_angle > 0.0) {
        double z0 = b->r_min * b->cos_angle, lateral = b->r_max * b->sin_angle;
        b->sphere_z = 0.5 * (z0 + b->r_max);
        double half = 0.5 * (b->r_max - z0);
        b->sphere_radius = sqrt(half * half + lateral * lateral) * (1.0 + 1e-12);
    } else {
        b->sphere_z = 0.0;
        b->sphere_radius = b->r_max;
    }
}

/* ---- tests ------------------------------------------------------------------ */

/* Culling flags of a bound (PLOD_SECTOR_BACKFACING or OUTSIDE_FRUSTUM:
 * culled or not, the same whichever test finds it).  Angles are compared
 * through cosines with per-node constants, so a test costs a few dot
 * products (no trigonometry).
 * Plane masks: bit i of parent_planes says the parent's surface is inside
 * frustum plane i, so this sector's surface (part of it) is too; its
 * bound, which contains that surface, then has a point inside plane i and
 * plane i cannot cull it: the test is skipped, with the same result.
 * *planes: parent_planes plus the planes this bound is inside of. */
unsigned plod_bound_cull(const plod_bound_view *v, const plod_bound *b, unsigned parent_planes,
                         unsigned *planes)
{
    *planes = parent_planes;
    const plod_camera *cam = v->camera;
    const double *e = v->eye_unit;
    double cphi = plod_dot3(b->axis, e);
    /* both angles are in [0, pi): their sum is below pi iff its sine is
     * positive (rounding near pi only skips the test: conservative) */
    if (v->horizon_on && b->horizon &&
        b->horizon_sin * v->eye_horizon_cos + b->horizon_cos * v->eye_horizon_sin > 0.0) {
        /* hidden iff phi > horizon angle + eye angle */
        double limit = b->horizon_cos * v->eye_horizon_cos - b->horizon_sin * v->eye_horizon_sin;
        if (cphi < limit - 1e-12)
            return PLOD_SECTOR_BACKFACING;
    }
    if (v->frustum_culling && parent_planes != PLOD_BOUND_ALL_PLANES) {
        for (int i = 0; i < 6; i++) {
            if (parent_planes & (1u << i))
                continue;
            const double *pl = cam->planes[i];
            double c = plod_dot3(pl, b->axis);
            double centre = c * b->sphere_z + pl[3];
            double margin = 1e-9 * (b->r_max + fabs(pl[3]));
            if (centre >= b->sphere_radius) {
                *planes |= 1u << i; /* the bounding ball is inside this plane */
                continue;
            }
            if (centre < -b->sphere_radius - margin)
                return PLOD_SECTOR_OUTSIDE_FRUSTUM;
            double best;
            if (c >= b->cos_angle) {
                best = 1.0;
            } else {
                double s2 = 1.0 - c * c; /* fmax(0, x) without the libm call */
                double s = sqrt(s2 > 0.0 ? s2 : 0.0);
                best = c * b->cos_angle + s * b->sin_angle;
            }
            double reach = best * (best >= 0.0 ? b->r_max : b->r_min);
            if (reach + pl[3] < -margin)
                return PLOD_SECTOR_OUTSIDE_FRUSTUM;
        }
    }
    return 0;
}

/* Eye distance of a bound's prism: to its nearest point. */
double plod_bound_distance(const plod_bound_view *v, const plod_bound *b)
{
    const double *e = v->eye_unit;
    double cphi = plod_dot3(b->axis, e);
    double dist = v->eye_dist;
    if (cphi >= b->cos_angle)
        return dist > b->r_max ? dist - b->r_max : (dist < b->r_min ? b->r_min - dist : 0.0);
    double cr[3];
    plod_cross3(b->axis, e, cr);
    double sphi = plod_norm3(cr);
    /* delta = phi - angle > 0: the eye direction's angle beyond the cap */
    double cdelta = cphi * b->cos_angle + sphi * b->sin_angle;
    double sdelta = sphi * b->cos_angle - cphi * b->sin_angle;
    double one_minus = cdelta > 0.0 ? sdelta * sdelta / (1.0 + cdelta) : 1.0 - cdelta;
    double t = dist * cdelta;
    t = t < b->r_min ? b->r_min : (t > b->r_max ? b->r_max : t);
    double radial = dist - t;
    return sqrt(radial * radial + 2.0 * dist * t * one_minus);
}

/* Refinement score of a bound: > 1 wants a split (ignoring culling).
 * Pixel criterion: the geometric error of the sector drawn with a template
 * of 2^t cells per edge, projected at the bound's distance:
 *   curvature sag of a cell   (size / 2^t)^2 / (8 r_min)
 * + relief left between cells (hmax - hmin) * min(1, extent / texel) / 2^t
 * (below one texel the bilinear surface varies ~linearly between its
 * creases, so the relief of the texel footprint shrinks with the sector;
 * plus, where insets meet the sector, their relief at their own spacing),
 * or, for a sector inside one bilinear cell of the map and no inset, the smaller
 *   twist of the cell        3 (hmax - hmin) (extent / texel / 2^t)^2:
 * there h = a + b x + c y + d x y with |d| <= 2 (hmax - hmin) per texel^2,
 * and linear interpolation over a template cell of diameter
 * sqrt 2 extent / 2^t leaves at most |d| diameter^2 / 2; times 1.5 for
 * the projection's curvature inside the cell.
 * + the detail field's modulation maximum times its expected error at the
 * template's cells (and the hills' band's excess times its octaves' own),
 * counting only the octaves of at least
 * PLOD_DETAIL_VISIBLE_WAVE_PIXELS pixels' wavelength at the distance
 * (plod_detail.h): the error shrinks with the distance, never grows.
 * Each term only decreases from a parent to its children. */
static double plod__error_m(const plod_bound_view *v, const plod_bound *b, int visible)
{
    double relief = b->relief0 * v->error_scale, twist = b->twist0 * v->error_scale2;
    double error = b->sag0 * v->error_scale2 + (twist < relief ? twist : relief);
    if (b->detail0 > 0.0) /* the detail a template cell does not resolve */
        error += b->detail0 * plod_detail_cell_error_visible(v->detail, b->size * v->error_scale,
                                                             visible);
    if (b->band0 > 0.0) /* the hills' band's excess: its own octaves' error */
        error += b->band0 * plod_detail_cell_error_band(v->detail, b->size * v->error_scale,
                                                        visible);
    return error;
}

/* The detail octaves that count at `distance` (already floored): those of
 * wavelength >= PLOD_DETAIL_VISIBLE_WAVE_PIXELS pixels there.  A finer
 * octave is roughness below the pixel at that distance: no mesh can draw
 * it, and refining for it would cut cells of a pixel wherever the field's
 * fine octaves are steep (the mesh still draws every octave its cells
 * resolve). */
static double plod__visible_wave(const plod_bound_view *v, double distance)
{
    const plod_camera *camera = v->camera;
    return camera->desc.orthographic
               ? PLOD_DETAIL_VISIBLE_WAVE_PIXELS / camera->pixels_per_metre
               : PLOD_DETAIL_VISIBLE_WAVE_PIXELS * distance / camera->pixels_per_radian;
}

static int plod__visible_octaves(const plod_bound_view *v, const plod_bound *b,
                                 double distance)
{
    if (!v->detail || !(b->detail0 > 0.0))
        return 0;
    return plod_detail_octaves_at_least(v->detail, plod__visible_wave(v, distance));
}

double plod_bound_score(const plod_bound_view *v, const plod_bound *b, double distance)
{
    double d = distance > v->distance_floor ? distance : v->distance_floor;
    if (v->criterion == PLOD_CRITERION_SIDE_DISTANCE)
        return b->size / d / v->split_border / v->coarsening;
    double per = v->camera->desc.orthographic ? v->camera->pixels_per_metre
                                              : v->camera->pixels_per_radian / d;
    double px = plod__error_m(v, b, plod__visible_octaves(v, b, d)) * per;
    return px / v->max_pixel_error / v->coarsening;
}

/* score > 1 without divisions (hot path: every node, every frame):
 * side / distance: size > split_border * d; pixel, perspective:
 * error * pixels_per_radian / max_pixel_error > d; orthographic:
 * error * pixels_per_metre / max_pixel_error > 1. */
static int plod__exceeds(const plod_bound_view *v, const plod_bound *b, double distance)
{
    double d = distance > v->distance_floor ? distance : v->distance_floor;
    switch (v->split_mode) {
    case 0:
        return b->size > v->split_scale * d;
    case 1:
        return plod__error_m(v, b, plod__visible_octaves(v, b, d)) * v->split_scale > d;
    default:
        return plod__error_m(v, b, plod__visible_octaves(v, b, d)) * v->split_scale > 1.0;
    }
}

/* plod__exceeds at the prism's distance.  Most nodes are far from the
 * threshold: two bounds without square roots or divisions decide them, the
 * bounding ball (no nearer than the prism) and the prism point axis * r_min
 * (no nearer than the prism's nearest point), each only when it clears the
 * threshold by a margin far above the rounding of the exact distance; so
 * the result is the exact test's.  With `slack` (may be NULL): how far the
 * eye may move before the exact test could decide otherwise (the prism's
 * distance changes no faster than the eye; the margins cover the rounding
 * at both ends), or <= 0. */
static int plod__exceeds_slack(const plod_bound_view *v, const plod_bound *b, double *slack)
{
    double reach; /* the distance threshold, metres (pixel: its largest) */
    double reach_near; /* pixel: the threshold for distances <= reach */
    switch (v->split_mode) {
    case 0:
        reach = reach_near = b->size / v->split_scale;
        break;
    case 1: {
        /* the error only shrinks with the distance (fewer octaves count):
         * every octave's counted bounds it beyond reach, and those that
         * count at reach bound it from below inside reach */
        int all = v->detail ? plod_detail_octave_count(v->detail) : 0;
        reach = plod__error_m(v, b, all) * v->split_scale;
        reach_near = reach;
        if (b->detail0 > 0.0 && reach > v->distance_floor) {
            int at_reach = plod__visible_octaves(v, b, reach);
            if (at_reach < all)
                reach_near = plod__error_m(v, b, at_reach) * v->split_scale;
        }
        break;
    }
    default:
        if (slack)
            *slack = INFINITY; /* orthographic: no distance */
        return plod__exceeds(v, b, 0.0);
    }
    /* false at the distance floor: false at any distance (as plod__exceeds) */
    if (!(v->split_mode ? reach > v->distance_floor
                        : b->size > v->split_scale * v->distance_floor)) {
        if (slack)
            *slack = INFINITY;
        return 0;
    }
    const double *eye = v->eye;
    double margin = 1e-9 * (reach + b->sphere_radius) + 1e-12 * v->eye_dist;
    double g[3] = {eye[0] - b->axis[0] * b->sphere_z, eye[1] - b->axis[1] * b->sphere_z,
                   eye[2] - b->axis[2] * b->sphere_z};
    double far_ = reach + b->sphere_radius + margin;
    double gg = plod_dot3(g, g);
    if (gg >= far_ * far_) {
        if (slack)
            *slack = sqrt(gg) - far_ - 2.0 * margin;
        return 0;
    }
    double near_ = reach_near - margin;
    if (near_ > (v->split_mode ? v->distance_floor : 0.0)) {
        double q[3] = {eye[0] - b->axis[0] * b->r_min, eye[1] - b->axis[1] * b->r_min,
                       eye[2] - b->axis[2] * b->r_min};
        double qq = plod_dot3(q, q);
        if (qq <= near_ * near_) {
            /* distance below reach (above the floor): the exact test is true */
            if (slack)
                *slack = near_ - sqrt(qq) - 2.0 * margin;
            return 1;
        }
    }
    double distance = plod_bound_distance(v, b);
    int exceeds = plod__exceeds(v, b, distance);
    if (slack) {
        if (v->split_mode == 0 || !(b->detail0 > 0.0)) {
            *slack = fabs(distance - reach) - 3.0 * margin;
        } else {
            /* the decision holds while the distance stays on its side of
             * the threshold at the octaves counted now, and those stay */
            double d = distance > v->distance_floor ? distance : v->distance_floor;
            int visible = plod__visible_octaves(v, b, d);
            double threshold = plod__error_m(v, b, visible) * v->split_scale;
            double per_wave = v->camera->pixels_per_radian / PLOD_DETAIL_VISIBLE_WAVE_PIXELS;
            if (exceeds) {
                double until = visible > 0 ? plod_detail_wavelength(v->detail, visible - 1) *
                                                 per_wave * (1.0 - 1e-9)
                                           : INFINITY;
                until = until < threshold ? until : threshold;
                *slack = until - distance - 3.0 * margin;
            } else {
                double from = visible < plod_detail_octave_count(v->detail)
                                  ? plod_detail_wavelength(v->detail, visible) * per_wave *
                                        (1.0 + 1e-9)
                                  : 0.0;
                from = from > threshold ? from : threshold;
                from = from > v->distance_floor ? from : v->distance_floor;
                *slack = distance - from - 3.0 * margin;
            }
        }
    }
    return exceeds;
}

int plod_bound_exceeds_memo(const plod_bound_view *v, plod_bound *b)
{
    plod_bound_memo *m = &b->memo;
    if (!v->memo_key)
        return plod__exceeds_slack(v, b, NULL);
    if (m->key == v->memo_key && v->travelled < m->until)
        return m->exceeds;
    double slack;
    int exceeds = plod__exceeds_slack(v, b, &slack);
    m->key = v->memo_key;
    m->exceeds = (uint8_t)exceeds;
    /* rounded down (until <= travelled: tested again next time) */
    m->until = slack > 0.0 ? nextafter(v->travelled + slack * (1.0 - 1e-9), -INFINITY)
                           : -INFINITY;
    return exceeds;
}
/* ---- horizon-distance correction ---------------------------------------------- */

void plod_recommended_clip(const plod_planet *planet, const plod_camera *camera,
                           double *clip_start, double *clip_end)
{
    double hmin, hmax;
    plod_planet_height_range(planet, &hmin, &hmax);
    const double *p = camera->position;
    double dist = hypot(hypot(p[0], p[1]), p[2]); /* no overflow below ~1e308 */
    double top = planet->radius + hmax, rho = planet->radius + hmin;
    double corner = 1.0;
    if (!camera->desc.orthographic) {
        double tx = fmax(fabs(camera->tan_left), fabs(camera->tan_right));
        double ty = fmax(fabs(camera->tan_bottom), fabs(camera->tan_top));
        corner = 1.0 / sqrt(1.0 + tx * tx + ty * ty);
    }
    /* nearest terrain is at least (dist - top) away; depth >= distance *
     * cos(corner angle) inside the frustum */
    double clearance = dist - top;
    double near_ = clearance > 0 ? 0.9 * clearance * corner : 0.0;
    double floor_ = fmax(1e-3, 1e-7 * planet->radius);
    if (clearance <= 0)
        floor_ = 1e-3;
    if (!(near_ >= floor_)) /* also NaN: infinite clearance times a zero corner */
        near_ = floor_;
    /* farthest visible terrain: the horizon of the occluder ball plus the
     * distance at which the highest peak still rises above it */
    double far_;
    if (dist > rho) {
        double horizon = sqrt((dist - rho) * (dist + rho));
        double beyond = sqrt((top - rho) * (top + rho));
        far_ = (horizon + beyond) * 1.01;
    } else {
        far_ = (dist + top) * 1.01;
    }
    if (far_ <= near_)
        far_ = near_ * 2.0;
    *clip_start = near_;
    *clip_end = far_;
}

void plod_bound_view_init(plod_bound_view *v, const plod_planet *planet, double occluder,
                          const plod_camera *camera, const plod_refine_params *params,
                          double eye_dist)
{
    memset(v, 0, sizeof *v);
    v->camera = camera;
    v->detail = planet->detail;
    memcpy(v->eye, camera->position, sizeof v->eye);
    v->eye_dist = eye_dist;
    for (int k = 0; k < 3; k++)
        v->eye_unit[k] = camera->position[k] / eye_dist;
    double rho = occluder;
    v->horizon_on = params->backface_culling && !camera->desc.orthographic && eye_dist > rho;
    double eye_horizon_angle =
        v->horizon_on ? atan2(sqrt((eye_dist - rho) * (eye_dist + rho)), rho) : 0.0;
    v->eye_horizon_cos = cos(eye_horizon_angle);
    v->eye_horizon_sin = sin(eye_horizon_angle);
    v->frustum_culling = params->frustum_culling;
    v->criterion = params->criterion;
    v->split_border = params->split_border;
    v->max_pixel_error = params->max_pixel_error;
    v->error_scale = ldexp(1.0, -params->template_level);
    v->error_scale2 = v->error_scale * v->error_scale;
    v->distance_floor = 1e-9 * planet->radius;
}
