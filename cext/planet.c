/* planet.c -- planet description: validation, heights and height bounds.
 *
 * Heights are the height map's channel 0 (normalised as the cube map
 * samples it) times height_scale plus height_offset, in metres above
 * `radius`.  A negative scale swaps the bounds.  Without a map the planet
 * is a perfect sphere.
 * A detail field (plod_detail.h) adds m(d) N(d): m sampled from its
 * modulation map at the height map's location (1 without a map).
 */
#include "plod_planet.h"
#include "plod_detail.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#define PLOD__TERRAIN_RULE                                                                 \
    "the terrain (height_scale and height_offset over the height data's range) must "   \
    "stay above half the radius below it and within 10 radii above it"

/* The map's range [lo, hi] (map units) in metres must be finite, and the
 * terrain must stay outside the centre and within sane bounds. */
static plod_status plod__check_terrain(const plod_planet *planet, double lo, double hi,
                                       plod_status not_finite, const char *not_finite_message,
                                       plod_error *error)
{
    if (!isfinite(lo) || !isfinite(hi) || lo > hi)
        return plod_error_set(error, not_finite, "%s", not_finite_message);
    double a = lo * planet->height_scale + planet->height_offset,
           b = hi * planet->height_scale + planet->height_offset;
    double low = a < b ? a : b, high = a < b ? b : a;
    if (low <= -0.5 * planet->radius || high > 10.0 * planet->radius)
        return plod_error_set(error, PLOD_ERR_BAD_PARAM, PLOD__TERRAIN_RULE);
    return PLOD_OK;
}

plod_status plod_planet_check(const plod_planet *planet, plod_error *error)
{
    if (!planet)
        return plod_error_set(error, PLOD_ERR_NULL, "no planet");
    if (!isfinite(planet->radius) || planet->radius < 1.0 || planet->radius > 1e8)
        return plod_error_set(error, PLOD_ERR_BAD_PARAM,
                              "radius must be finite, in [1, 1e8] metres");
    if ((unsigned)planet->projection >= PLOD_PROJ_COUNT)
        return plod_error_set(error, PLOD_ERR_BAD_PROJECTION, "unknown projection");
    if (!isfinite(planet->height_scale) || !isfinite(planet->height_offset))
        return plod_error_set(error, PLOD_ERR_BAD_PARAM,
                              "height_scale and height_offset must be finite");
    if (planet->has_sea_level && !isfinite(planet->sea_level))
        return plod_error_set(error, PLOD_ERR_BAD_PARAM, "sea_level must be finite");
    if (planet->heightmap) {
        if (plod_cubemap_projection(planet->heightmap) != planet->projection)
            return plod_error_set(error, PLOD_ERR_BAD_PROJECTION,
                                  "heightmap projection differs from the planet's");
        if (plod_cubemap_nan_count(planet->heightmap) != 0)
            return plod_error_set(error, PLOD_ERR_BAD_IMAGE,
                                  "height map has NaN samples (no-data texels)");
        double lo, hi;
        plod_cubemap_global_range(planet->heightmap, &lo, &hi);
        plod_status st = plod__check_terrain(planet, lo, hi, PLOD_ERR_BAD_PARAM,
                                             "height map range is not finite", error);
        if (st != PLOD_OK)
            return st;
    }
    if (planet->source) {
        const plod_height_source *src = planet->source;
        if (planet->heightmap || !src->ops || !src->ops->sample || !src->ops->range_cap ||
            !src->ops->global_range || !src->ops->texel_angle)
            return plod_error_set(error, PLOD_ERR_BAD_PARAM,
                                  "a height source needs every operation, and no height map "
                                  "beside it");
        double lo, hi;
        src->ops->global_range(src->self, &lo, &hi);
        plod_status st = plod__check_terrain(planet, lo, hi, PLOD_ERR_BAD_IMAGE,
                                             "height source range is not finite", error);
        if (st != PLOD_OK)
            return st;
    }
    if (planet->normalmap) {
        const plod_cubemap *n = planet->normalmap;
        if (!planet->heightmap || plod_cubemap_projection(n) != planet->projection ||
            plod_cubemap_size(n) != plod_cubemap_size(planet->heightmap) ||
            plod_cubemap_channels(n) != 3)
            return plod_error_set(error, PLOD_ERR_BAD_PARAM,
                                  "the normal map is not made for this height map");
    }
    if (planet->detail) {
        if (!plod_detail_matches(planet->detail, planet))
            return plod_error_set(error, PLOD_ERR_BAD_PARAM,
                                  "the detail field is not made for this planet");
        double low, high; /* with the field too, the terrain stays as above */
        plod_planet_height_range(planet, &low, &high);
        if (!(low > -0.5 * planet->radius && high <= 10.0 * planet->radius))
            return plod_error_set(error, PLOD_ERR_BAD_PARAM,
                                  "the terrain with the detail field must stay above half "
                                  "the radius below it and within 10 radii above it");
    }
    return PLOD_OK;
}

plod_status plod_planet_build_normals(const plod_planet *planet, plod_cubemap **out,
                                      int threads)
{
    if (!out)
        return PLOD_ERR_NULL;
    *out = NULL;
    if (!planet || !planet->heightmap)
        return PLOD_ERR_NULL;
    /* the offset moves the whole surface: a sphere of radius + offset */
    return plod_cubemap_build_normals(out, planet->heightmap,
                                      planet->radius + planet->height_offset,
                                      planet->height_scale, threads);
}


/* Metres for a sampled map value.  Without an offset exactly value * scale
 * (no "+ 0.0", which would turn a -0.0 height into +0.0). */
static inline double plod__metres(const plod_planet *planet, double value)
{
    double height = value * planet->height_scale;
    return planet->height_offset != 0.0 ? height + planet->height_offset : height;
}

/* The data's texel as an angle (radians) at dir; 0 without data.  An
 * inset's where it counts (finer data). */
static double plod__texel_angle(const plod_planet *planet, const double dir[3])
{
    if (planet->insets) {
        double angle;
        plod_insets_blend(planet->insets, dir, 0.0, &angle);
        if (angle > 0.0)
            return angle;
    }
    if (planet->heightmap) {
        int size = plod_cubemap_size(planet->heightmap);
        return 1.5707963267948966 / (double)(size < 1 ? 1 : size);
    }
    if (planet->source)
        return planet->source->ops->texel_angle(planet->source->self, dir);
    return 0.0;
}

double plod_planet_texel_size(const plod_planet *planet, const double dir[3])
{
    double angle = plod__texel_angle(planet, dir);
    return angle > 0.0 ? angle * planet->radius : INFINITY;
}

/* Unit normal of the displaced surface d*(R+h(d)) from central differences
 * of h along a tangent frame chosen from d alone, one texel apart:
 * n ~ r d - h1 t1 - h2 t2 with h1, h2 in metres per radian. */
static void plod__difference_normal(const plod_planet *planet, const double dir[3],
                                    double r, double normal[3])
{
    double step = tan(plod__texel_angle(planet, dir));
    double inv_2angle = 0.5 / atan(step);
    double ax = fabs(dir[0]), ay = fabs(dir[1]), az = fabs(dir[2]);
    double axis[3] = {0.0, 0.0, 0.0};
    if (ax <= ay && ax <= az)
        axis[0] = 1.0;
    else if (ay <= az)
        axis[1] = 1.0;
    else
        axis[2] = 1.0;
    double t1[3] = {axis[1] * dir[2] - axis[2] * dir[1], axis[2] * dir[0] - axis[0] * dir[2],
                    axis[0] * dir[1] - axis[1] * dir[0]};
    double inv_l1 = 1.0 / sqrt(t1[0] * t1[0] + t1[1] * t1[1] + t1[2] * t1[2]);
    t1[0] *= inv_l1, t1[1] *= inv_l1, t1[2] *= inv_l1;
    double t2[3] = {dir[1] * t1[2] - dir[2] * t1[1], dir[2] * t1[0] - dir[0] * t1[2],
                    dir[0] * t1[1] - dir[1] * t1[0]};
    const double *frame[2] = {t1, t2};
    double slope[2];
    for (int f = 0; f < 2; f++) {
        double h[2];
        for (int s = 0; s < 2; s++) {
            double sign = s ? -step : step;
            double p[3] = {dir[0] + sign * frame[f][0], dir[1] + sign * frame[f][1],
                           dir[2] + sign * frame[f][2]};
            double inv_lp = 1.0 / sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
            p[0] *= inv_lp, p[1] *= inv_lp, p[2] *= inv_lp;
            h[s] = plod_planet_map_height(planet, p);
        }
        slope[f] = (h[0] - h[1]) * inv_2angle;
    }
    double v[3];
    for (int c = 0; c < 3; c++)
        v[c] = r * dir[c] - slope[0] * t1[c] - slope[1] * t2[c];
    double inv_len = 1.0 / sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int c = 0; c < 3; c++)
        normal[c] = v[c] * inv_len;
}

/* The field's directions are unit: callers' directions (unit by
 * contract, any length from Python) are renormalised, one rounding. */
PLOD_LANE_INLINE void plod__unit_dir(const double dir[3], double unit[3])
{
    double len2 = dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2];
    double inv = 1.0 / sqrt(len2);
    unit[0] = dir[0] * inv, unit[1] = dir[1] * inv, unit[2] = dir[2] * inv;
}

/* The detail term m N (N evaluated at the unit direction dir, g its
 * gradient) on top of the map's height and normal: height += m N; the
 * normal, if wanted, is rebuilt from the map normal's slope plus N's
 * analytic slope: n ~ (R + h) d - grad_t h_map - m grad_t N (kept where
 * that is zero or not finite).  Branch-free but for the outputs asked
 * for, so that batch loops vectorise. */
PLOD_LANE_INLINE void plod__apply_detail(double radius, const double dir[3], double m,
                                         double noise, const double g[3], double *height,
                                         double *normal, double *detail)
{
    double h_map = *height;
    *height = h_map + m * noise;
    if (detail)
        *detail = m * noise;
    if (!normal)
        return;
    double nd = normal[0] * dir[0] + normal[1] * dir[1] + normal[2] * dir[2];
    double k = nd > 1e-3 ? (radius + h_map) / nd : 0.0; /* map slope, per radian */
    double gd = g[0] * dir[0] + g[1] * dir[1] + g[2] * dir[2];
    double r = radius + *height, v[3];
    for (int c = 0; c < 3; c++)
        v[c] = r * dir[c] + k * (normal[c] - nd * dir[c]) - m * (g[c] - gd * dir[c]);
    double vlen2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    int keep = !((vlen2 > 0.0) & (vlen2 <= DBL_MAX)); /* zero, infinite or NaN */
    double inv_len = 1.0 / sqrt(vlen2);
    for (int c = 0; c < 3; c++)
        normal[c] = keep ? normal[c] : v[c] * inv_len;
}

/* A normal map sample (3 channels in [0, 1]) decoded into the unit normal
 * when `sampled`; the normal is left as it is otherwise, or where the
 * sample is too short to be a normal (interpolated across a fold: it
 * stays radial).  Branch-free, for the batch loop. */
PLOD_LANE_INLINE void plod__decode_normal(const double s[3], int sampled, double normal[3])
{
    double m[3] = {2.0 * s[0] - 1.0, 2.0 * s[1] - 1.0, 2.0 * s[2] - 1.0};
    double len2 = m[0] * m[0] + m[1] * m[1] + m[2] * m[2];
    int use = sampled & (len2 > 0.25);
    double inv_len = 1.0 / sqrt(len2);
    for (int c = 0; c < 3; c++)
        normal[c] = use ? m[c] * inv_len : normal[c];
}

/* plod__decode_normal over a batch: the samples of points on faces[i] (-1:
 * not sampled) */
PLOD_LANE_CLONES PLOD_LANE_LOOPS static void plod__decode_normals(size_t n, const int *faces,
                                                                 const double *samples,
                                                                 double *normals)
{
    for (size_t i = 0; i < n; i++)
        plod__decode_normal(samples + 3 * i, faces[i] >= 0, normals + 3 * i);
}

/* plod__unit_dir over a batch, in place */
PLOD_LANE_CLONES PLOD_LANE_LOOPS static void plod__unit_dirs(size_t n, double *dirs)
{
    for (size_t i = 0; i < n; i++)
        plod__unit_dir(dirs + 3 * i, dirs + 3 * i);
}

/* plod__apply_detail over a batch (heights, normals and detail of the
 * batch's points, in order) */
PLOD_LANE_CLONES PLOD_LANE_LOOPS static void plod__apply_detail_n(
    double radius, size_t n, const double *unit, const double *scale, const double *noise,
    const double *gradient, double *heights, double *normals, double *detail)
{
    if (normals && detail)
        for (size_t i = 0; i < n; i++)
            plod__apply_detail(radius, unit + 3 * i, scale[i], noise[i], gradient + 3 * i,
                               heights + i, normals + 3 * i, detail + i);
    else if (normals)
        for (size_t i = 0; i < n; i++)
            plod__apply_detail(radius, unit + 3 * i, scale[i], noise[i], gradient + 3 * i,
                               heights + i, normals + 3 * i, NULL);
    else
        for (size_t i = 0; i < n; i++)
            plod__apply_detail(radius, unit + 3 * i, scale[i], noise[i], NULL, heights + i,
                               NULL, detail ? detail + i : NULL);
}

/* The detail field on top of the map's height and normal at dir (first
 * `octaves` octaves for the height, `normal_octaves` for the normal's
 * slope); nothing where m is 0 (sea) or NaN.  Where an inset counts
 * (inset->weight w > 0) the field starts below its data: N = (1 - w) N_all
 * + w N_from, N_from the octaves from the first one of wavelength <= two
 * of the mosaic's samples, started fresh (plod_detail_noise_from); the
 * same w as the heights' blend, so the field fades in across the
 * feathered border as the inset's heights fade out.  The normal's slope
 * blends the same way (w's own slope is left out, as the modulation's). */
/* The octave the field starts at where an inset counts (plod__add_detail). */
static int plod__inset_first_octave(const plod_planet *planet, const plod_inset_weight *inset)
{
    return plod_detail_first_octave_below(planet->detail,
                                          2.0 * inset->mosaic_texel_angle * planet->radius);
}

/* N = (1 - w) N_all + w N_from (and its gradient when normal) applied at
 * the unit direction: the one sequence of operations for the point and
 * the batched paths.  noise/g: N_all (unused when w >= 1); from/g_from:
 * N_from (unused when w is 0). */
static void plod__blend_apply(const plod_planet *planet, const double unit[3], double m,
                              double w, double noise, const double g_all[3], double from,
                              const double g_from[3], double *height, double *normal,
                              double *detail)
{
    double g[3] = {0.0, 0.0, 0.0};
    if (normal)
        memcpy(g, w >= 1.0 ? g_from : g_all, sizeof g);
    if (w >= 1.0) {
        noise = from;
    } else if (w > 0.0) {
        noise += w * (from - noise);
        if (normal)
            for (int c = 0; c < 3; c++)
                g[c] += w * (g_from[c] - g[c]);
    }
    plod__apply_detail(planet->radius, unit, m, noise, g, height, normal, detail);
}

/* The hills' band (plod_detail.h): the field applied as m N' with
 * N' = N + ((g(m) - m) / m) B, B the band's part of N (band, band_g:
 * plod_detail_noise_band_n's, from N's own pass), so that the detail is
 * m N + (g - m) B; the gradient alike.  The same operations on the point
 * and the batched paths. */
static void plod__fine_gain_n(const plod_planet *planet, size_t n, const double *modulation,
                              const double *band, const double *band_g, double *sums,
                              double *gradients)
{
    const plod_detail *d = planet->detail;
    if (plod_detail_fine_first(d) >= plod_detail_fine_end(d))
        return;
    for (size_t i = 0; i < n; i++) {
        double m = modulation[i];
        double g = plod_detail_fine_modulation(d, m);
        if (!(g > m) || !(m > 0.0))
            continue;
        double excess = (g - m) / m;
        sums[i] += excess * band[i];
        if (gradients)
            for (int c = 0; c < 3; c++)
                gradients[3 * i + c] += excess * band_g[3 * i + c];
    }
}

static void plod__add_detail(const plod_planet *planet, const double dir[3], double m,
                             int octaves, int normal_octaves, const plod_inset_weight *inset,
                             double *height, double *normal, double *detail)
{
    if (!(m != 0.0) || octaves <= 0)
        return; /* sea (m = 0) or NaN map: unchanged (and *detail 0) */
    double unit[3], g[3], noise;
    plod__unit_dir(dir, unit);
    double w = inset && inset->weight > 0.0 ? inset->weight : 0.0;
    double band, band_g[3];
    if (!(w > 0.0)) {
        plod_detail_noise_band_n(planet->detail, 1, unit, NULL, &octaves, &normal_octaves,
                                 &noise, normal ? g : NULL, &band, band_g);
        plod__fine_gain_n(planet, 1, &m, &band, band_g, &noise, normal ? g : NULL);
        plod__apply_detail(planet->radius, unit, m, noise, g, height, normal, detail);
        return;
    }
    double from, g_from[3] = {0.0, 0.0, 0.0};
    int first = plod__inset_first_octave(planet, inset);
    noise = 0.0, g[0] = g[1] = g[2] = 0.0;
    if (w < 1.0) {
        plod_detail_noise_band_n(planet->detail, 1, unit, NULL, &octaves, &normal_octaves,
                                 &noise, normal ? g : NULL, &band, band_g);
        plod__fine_gain_n(planet, 1, &m, &band, band_g, &noise, normal ? g : NULL);
    }
    plod_detail_noise_band_n(planet->detail, 1, unit, &first, &octaves, &normal_octaves, &from,
                             normal ? g_from : NULL, &band, band_g);
    plod__fine_gain_n(planet, 1, &m, &band, band_g, &from, normal ? g_from : NULL);
    plod__blend_apply(planet, unit, m, w, noise, g, from, g_from, height, normal, detail);
}

/* Points sampled together: a sector's vertices at the usual template
 * levels, so that the detail field's batches see its corners together. */
#define PLOD__SURFACE_CHUNK 256

/* plod__add_detail at a run of points (count <= PLOD__SURFACE_CHUNK) whose map heights,
 * normals, modulations and inset weights are known: the field in batches
 * (all octaves where w < 1, the inset's from its first where w > 0), the
 * same bits per point. */
static void plod__add_detail_run(const plod_planet *planet, size_t count, const double *dirs,
                                 const double *modulation, const int *octaves,
                                 const int *normal_octaves, const plod_inset_weight *insets,
                                 double *heights, double *normals, double *detail)
{
    enum { RUN = PLOD__SURFACE_CHUNK };
    double unit[3 * RUN], all_unit[3 * RUN], from_unit[3 * RUN];
    double noise[RUN], g[3 * RUN], from[RUN], g_from[3 * RUN], band[RUN], band_g[3 * RUN];
    int all_oct[RUN], all_noct[RUN], from_first[RUN], from_oct[RUN], from_noct[RUN];
    double all_m[RUN], from_m[RUN];
    size_t all_at[RUN], from_at[RUN], live_at[RUN];
    size_t live = 0, n_all = 0, n_from = 0;
    for (size_t i = 0; i < count; i++) {
        if (!(modulation[i] != 0.0) || octaves[i] <= 0)
            continue;
        plod__unit_dir(dirs + 3 * i, unit + 3 * live);
        double w = insets[i].weight > 0.0 ? insets[i].weight : 0.0;
        if (w < 1.0) {
            memcpy(all_unit + 3 * n_all, unit + 3 * live, 3 * sizeof(double));
            all_oct[n_all] = octaves[i], all_noct[n_all] = normal_octaves[i];
            all_m[n_all] = modulation[i];
            all_at[live] = n_all++;
        }
        if (w > 0.0) {
            memcpy(from_unit + 3 * n_from, unit + 3 * live, 3 * sizeof(double));
            from_first[n_from] = plod__inset_first_octave(planet, &insets[i]);
            from_oct[n_from] = octaves[i], from_noct[n_from] = normal_octaves[i];
            from_m[n_from] = modulation[i];
            from_at[live] = n_from++;
        }
        live_at[live++] = i;
    }
    plod_detail_noise_band_n(planet->detail, n_all, all_unit, NULL, all_oct, all_noct, noise,
                             normals ? g : NULL, band, band_g);
    plod__fine_gain_n(planet, n_all, all_m, band, band_g, noise, normals ? g : NULL);
    plod_detail_noise_band_n(planet->detail, n_from, from_unit, from_first, from_oct, from_noct,
                             from, normals ? g_from : NULL, band, band_g);
    plod__fine_gain_n(planet, n_from, from_m, band, band_g, from, normals ? g_from : NULL);
    for (size_t j = 0; j < live; j++) {
        size_t i = live_at[j];
        double w = insets[i].weight > 0.0 ? insets[i].weight : 0.0;
        double *normal = normals ? normals + 3 * i : NULL;
        double *d = detail ? detail + i : NULL;
        if (!(w > 0.0)) {
            plod__apply_detail(planet->radius, unit + 3 * j, modulation[i], noise[all_at[j]],
                               g + 3 * all_at[j], heights + i, normal, d);
            continue;
        }
        static const double zero[3] = {0.0, 0.0, 0.0};
        double n_all_value = w < 1.0 ? noise[all_at[j]] : 0.0;
        const double *g_all = w < 1.0 && normals ? g + 3 * all_at[j] : zero;
        plod__blend_apply(planet, unit + 3 * j, modulation[i], w, n_all_value, g_all,
                          from[from_at[j]], normals ? g_from + 3 * from_at[j] : zero,
                          heights + i, normal, d);
    }
}

static int plod__all_octaves(const plod_planet *planet)
{
    return planet->detail ? plod_detail_octave_count(planet->detail) : 0;
}

/* Height (and normal, from differences one texel apart) of a height
 * source at dir; the caller set normal to dir. */
static double plod__source_surface(const plod_planet *planet, const double dir[3],
                                   double normal[3])
{
    const plod_height_source *src = planet->source;
    double height = plod__metres(planet, src->ops->sample(src->self, dir));
    if (normal && height == height)
        plod__difference_normal(planet, dir, planet->radius + height, normal);
    return height;
}

static double plod__global_surface(const plod_planet *planet, const double dir[3],
                                   double normal[3], int *face, double *u, double *v);

/* The map's height and normal at dir (no detail), insets blended in;
 * *face, *u, *v: where the global map sampled (face -1 without a map);
 * *inset (may be NULL): where an inset counts (weight 0 elsewhere). */
static double plod__map_surface(const plod_planet *planet, const double dir[3], double normal[3],
                                int *face, double *u, double *v, plod_inset_weight *inset)
{
    if (inset)
        inset->weight = inset->mosaic_texel_angle = 0.0;
    if (!planet->insets)
        return plod__global_surface(planet, dir, normal, face, u, v);
    double base = plod__global_surface(planet, dir, NULL, face, u, v);
    double texel;
    double height = plod_insets_blend_weight(planet->insets, dir, base, &texel, inset);
    if (normal) {
        normal[0] = dir[0], normal[1] = dir[1], normal[2] = dir[2];
        if (height == height && (planet->heightmap || planet->source || texel > 0.0))
            plod__difference_normal(planet, dir, planet->radius + height, normal);
    }
    return height;
}

/* The global data's height and normal at dir (no insets, no detail). */
static double plod__global_surface(const plod_planet *planet, const double dir[3], double normal[3],
                                int *face, double *u, double *v)
{
    *face = -1;
    if (normal)
        normal[0] = dir[0], normal[1] = dir[1], normal[2] = dir[2];
    if (!planet->heightmap)
        return planet->source ? plod__source_surface(planet, dir, normal) : 0.0;
    double sample[4] = {0.0, 0.0, 0.0, 0.0};
    if (!plod_cubemap_locate(planet->heightmap, dir, face, u, v) ||
        !plod_cubemap_sample_face_d(planet->heightmap, *face, *u, *v, sample)) {
        *face = -1;
        return NAN;
    }
    double height = plod__metres(planet, sample[0]);
    if (!normal)
        return height;
    if (!planet->normalmap) {
        plod__difference_normal(planet, dir, planet->radius + height, normal);
        return height;
    }
    if (plod_cubemap_sample_face_d(planet->normalmap, *face, *u, *v, sample))
        plod__decode_normal(sample, 1, normal);
    return height;
}

/* modulation at a located map point (1 without a map, NaN if unlocated) */
static double plod__modulation_at(const plod_planet *planet, int face, double u, double v)
{
    const plod_cubemap *mod = plod_detail_modulation(planet->detail);
    if (!planet->heightmap || !mod)
        return 1.0;
    double sample[4];
    if (face < 0 || !plod_cubemap_sample_face_d(mod, face, u, v, sample))
        return NAN;
    return sample[0];
}

double plod_planet_map_height(const plod_planet *planet, const double dir[3])
{
    int face;
    double u, v;
    return plod__map_surface(planet, dir, NULL, &face, &u, &v, NULL);
}

double plod_planet_surface(const plod_planet *planet, const double dir[3], double normal[3])
{
    int face;
    double u, v;
    plod_inset_weight inset;
    double height = plod__map_surface(planet, dir, normal, &face, &u, &v, &inset);
    if (planet->detail)
        plod__add_detail(planet, dir, plod__modulation_at(planet, face, u, v),
                         plod__all_octaves(planet), plod__all_octaves(planet), &inset, &height,
                         normal, NULL);
    return height;
}

/* plod_planet_surface over a row of directions: one projection loop and
 * one bilinear loop per map instead of two calls per point, so the per-point
 * kernels pipeline; bit for bit the single-point results. */
void plod_planet_surface_band_n(const plod_planet *planet, size_t n, const double *dirs,
                                const int *octaves, const int *normal_octaves,
                                double *heights, double *normals)
{
    plod_planet_surface_detail_n(planet, n, dirs, octaves, normal_octaves, heights, normals,
                                 NULL);
}

void plod_planet_surface_detail_n(const plod_planet *planet, size_t n, const double *dirs,
                                  const int *octaves, const int *normal_octaves,
                                  double *heights, double *normals, double *detail)
{
    if (!normal_octaves)
        normal_octaves = octaves;
    enum { CHUNK = PLOD__SURFACE_CHUNK };
    if (normals)
        memcpy(normals, dirs, 3 * n * sizeof *normals);
    if (detail)
        memset(detail, 0, n * sizeof *detail);
    int all = plod__all_octaves(planet);
    if (planet->insets) { /* blends and difference normals point by point, detail in runs */
        plod_inset_weight inset[CHUNK];
        double modulation[CHUNK];
        int band[CHUNK], normal_band[CHUNK];
        for (size_t first = 0; first < n; first += CHUNK) {
            size_t count = n - first < CHUNK ? n - first : CHUNK;
            for (size_t k = 0; k < count; k++) {
                size_t i = first + k;
                int face;
                double u, v;
                double *normal = normals ? normals + 3 * i : NULL;
                heights[i] =
                    plod__map_surface(planet, dirs + 3 * i, normal, &face, &u, &v, inset + k);
                if (!planet->detail)
                    continue;
                modulation[k] = plod__modulation_at(planet, face, u, v);
                band[k] = octaves ? octaves[i] : all;
                normal_band[k] = normal_octaves ? normal_octaves[i] : all;
            }
            if (planet->detail)
                plod__add_detail_run(planet, count, dirs + 3 * first, modulation, band,
                                     normal_band, inset, heights + first,
                                     normals ? normals + 3 * first : NULL,
                                     detail ? detail + first : NULL);
        }
        return;
    }
    if (!planet->heightmap) {
        for (size_t i = 0; i < n; i++) {
            heights[i] = planet->source ? plod__source_surface(planet, dirs + 3 * i,
                                                               normals ? normals + 3 * i : NULL)
                                        : 0.0;
            if (planet->detail)
                plod__add_detail(planet, dirs + 3 * i, 1.0, octaves ? octaves[i] : all,
                                 normal_octaves ? normal_octaves[i] : all, NULL, heights + i,
                                 normals ? normals + 3 * i : NULL, detail ? detail + i : NULL);
        }
        return;
    }
    if (normals && (!planet->normalmap || plod_cubemap_channels(planet->normalmap) != 3)) {
        for (size_t i = 0; i < n; i++) { /* rare (C callers only): point by point */
            int face;
            double u, v;
            heights[i] =
                plod__map_surface(planet, dirs + 3 * i, normals + 3 * i, &face, &u, &v, NULL);
            if (planet->detail)
                plod__add_detail(planet, dirs + 3 * i, plod__modulation_at(planet, face, u, v),
                                 octaves ? octaves[i] : all,
                                 normal_octaves ? normal_octaves[i] : all, NULL, heights + i,
                                 normals + 3 * i, detail ? detail + i : NULL);
        }
        return;
    }
    const plod_cubemap *mod = planet->detail ? plod_detail_modulation(planet->detail) : NULL;
    const plod_cubemap_bundle *bundle =
        normals && plod_cubemap_bundle_holds(planet->bundle, planet->heightmap,
                                             planet->normalmap, mod)
            ? planet->bundle
            : NULL;
    int faces[CHUNK];
    double u[CHUNK], v[CHUNK], modulation[CHUNK];
    double unit[3 * CHUNK], scale[CHUNK], noise[CHUNK], gradient[3 * CHUNK];
    double fine[CHUNK], fine_gradient[3 * CHUNK]; /* the hills' band's part */
    double height_live[CHUNK], normal_live[3 * CHUNK], detail_live[CHUNK];
    size_t index[CHUNK];
    int band_live[CHUNK], normal_band_live[CHUNK];
    double sample[4 * CHUNK], normal_sample[3 * CHUNK]; /* maps have 1..4 channels */
    size_t height_channels = (size_t)plod_cubemap_channels(planet->heightmap);
    for (size_t first = 0; first < n; first += CHUNK) {
        size_t count = n - first < CHUNK ? n - first : CHUNK;
        plod_cubemap_locate_n(planet->heightmap, count, dirs + 3 * first, faces, u, v);
        if (bundle) /* the three maps in one pass (modulation's values used below) */
            plod_cubemap_bundle_sample_n(bundle, count, faces, u, v, sample, normal_sample,
                                         mod ? modulation : NULL);
        else if (normals)
            plod_cubemap_sample_pair_n(planet->heightmap, planet->normalmap, count, faces, u, v,
                                       sample, normal_sample);
        else
            plod_cubemap_sample_face_n(planet->heightmap, count, faces, u, v, sample);
        for (size_t i = 0; i < count; i++)
            heights[first + i] =
                faces[i] < 0 ? NAN : plod__metres(planet, sample[i * height_channels]);
        if (normals) {
            plod__decode_normals(count, faces, normal_sample, normals + 3 * first);
        }
        if (!planet->detail)
            continue;
        if (mod && !bundle)
            plod_cubemap_sample_face_n(mod, count, faces, u, v, modulation);
        /* the points with detail (land), their field in one batch */
        size_t live = 0;
        for (size_t i = 0; i < count; i++) {
            size_t at = first + i;
            double m = !mod ? 1.0 : (faces[i] < 0 ? NAN : modulation[i]);
            int band = octaves ? octaves[at] : all;
            if (!(m != 0.0) || band <= 0)
                continue; /* sea (m = 0) or NaN map: unchanged (and detail 0) */
            memcpy(unit + 3 * live, dirs + 3 * at, 3 * sizeof *unit);
            height_live[live] = heights[at];
            if (normals)
                memcpy(normal_live + 3 * live, normals + 3 * at, 3 * sizeof *normal_live);
            index[live] = at;
            scale[live] = m;
            band_live[live] = band;
            normal_band_live[live] = normal_octaves ? normal_octaves[at] : all;
            live++;
        }
        plod__unit_dirs(live, unit);
        plod_detail_noise_band_n(planet->detail, live, unit, NULL, band_live, normal_band_live,
                                 noise, normals ? gradient : NULL, fine, fine_gradient);
        plod__fine_gain_n(planet, live, scale, fine, fine_gradient, noise,
                          normals ? gradient : NULL);
        plod__apply_detail_n(planet->radius, live, unit, scale, noise, gradient, height_live,
                             normals ? normal_live : NULL, detail ? detail_live : NULL);
        for (size_t j = 0; j < live; j++) {
            size_t at = index[j];
            heights[at] = height_live[j];
            if (normals)
                memcpy(normals + 3 * at, normal_live + 3 * j, 3 * sizeof *normals);
            if (detail)
                detail[at] = detail_live[j];
        }
    }
}

void plod_planet_surface_n(const plod_planet *planet, size_t n, const double *dirs,
                           double *heights, double *normals)
{
    plod_planet_surface_band_n(planet, n, dirs, NULL, NULL, heights, normals);
}

/* One sampling path for heights, so that mesh vertices (through
 * plod_planet_surface) and every other caller agree bit for bit. */
double plod_planet_height(const plod_planet *planet, const double dir[3])
{
    return plod_planet_surface(planet, dir, NULL);
}

static void plod__scaled(const plod_planet *planet, double lo, double hi,
                         double *min_m, double *max_m)
{
    double a = plod__metres(planet, lo), b = plod__metres(planet, hi);
    *min_m = a < b ? a : b;
    *max_m = a < b ? b : a;
}

static void plod__cubemap_range_uv(const void *map, double u0, double v0, double u1,
                                   double v1, double *lo, double *hi)
{
    plod_cubemap_range(map, 0, u0, v0, u1, v1, lo, hi);
}

/* Bounds of map channel 0 (raw, as sampled) over the spherical cap
 * (axis, angle) through its lon/lat box, for a CAR map (face count 1);
 * else, or for a cap not inside a hemisphere, the global range.  *texels:
 * the box's larger side in map texels (INFINITY for the global range). */
static void plod__cap_range(const plod_cubemap *map, const double axis[3], double angle,
                            double *lo_out, double *hi_out, double *texels)
{
    *texels = INFINITY;
    plod_cubemap_global_range(map, lo_out, hi_out);
    if (plod_cubemap_face_count(map) != 1)
        return;
    int size = plod_cubemap_size(map); /* rows; 2 * size columns */
    plod_lonlat_cap_range(axis, angle, 2 * size, size, plod__cubemap_range_uv, map, lo_out,
                          hi_out, texels);
}

/* detail bounds given the modulation maximum m */
static void plod__detail_scaled(const plod_planet *planet, double mlo, double m,
                                double *min_m, double *max_m, double *modulation)
{
    double lo, hi;
    plod_detail_noise_range(planet->detail, &lo, &hi);
    m = m > 1.0 ? 1.0 : (m > 0.0 ? m : 0.0); /* NaN-free maps: m in [0, 1] */
    mlo = mlo > m ? m : (mlo > 0.0 ? mlo : 0.0);
    /* m P + g T inside g (P + T)'s bounds: both ranges hold 0, g >= m */
    double g = plod_detail_fine_modulation(planet->detail, m);
    *min_m = lo * g;
    *max_m = hi * g;
    if (modulation)
        modulation[0] = mlo, modulation[1] = m;
}

double plod_planet_modulation(const plod_planet *planet, const double dir[3])
{
    if (!planet->detail)
        return 0.0;
    const plod_cubemap *mod = plod_detail_modulation(planet->detail);
    if (!planet->heightmap || !mod)
        return 1.0;
    int face;
    double u, v;
    if (!plod_cubemap_locate(planet->heightmap, dir, &face, &u, &v))
        return NAN;
    return plod__modulation_at(planet, face, u, v);
}

static void plod__global_height_range(const plod_planet *planet, double *min_m,
                                      double *max_m);

static void plod__map_height_range(const plod_planet *planet, double *min_m, double *max_m)
{
    plod__global_height_range(planet, min_m, max_m);
    if (planet->insets && plod_insets_count(planet->insets)) {
        double lo, hi;
        plod_insets_global_range(planet->insets, &lo, &hi);
        if (lo <= hi) {
            *min_m = lo < *min_m ? lo : *min_m;
            *max_m = hi > *max_m ? hi : *max_m;
        }
    }
}

int plod_planet_detail_first_octave_cap(const plod_planet *planet, const double axis[3],
                                        double angle)
{
    if (!planet->detail)
        return 0;
    int count = plod_detail_octave_count(planet->detail);
    if (!planet->insets)
        return count;
    double texel = plod_insets_mosaic_texel_cap(planet->insets, axis, angle);
    if (!(texel > 0.0))
        return count;
    return plod_detail_first_octave_below(planet->detail, 2.0 * texel * planet->radius);
}

int plod_planet_insets_range_cap(const plod_planet *planet, const double axis[3],
                                 double angle, double *min_m, double *max_m,
                                 plod_insets_relief *relief)
{
    return planet->insets &&
           plod_insets_range_cap(planet->insets, axis, angle, min_m, max_m, relief);
}

static void plod__global_height_range(const plod_planet *planet, double *min_m, double *max_m)
{
    if (!planet->heightmap && planet->source) {
        double lo, hi;
        planet->source->ops->global_range(planet->source->self, &lo, &hi);
        plod__scaled(planet, lo, hi, min_m, max_m);
        return;
    }
    if (!planet->heightmap) {
        *min_m = *max_m = 0.0;
        return;
    }
    double lo, hi;
    plod_cubemap_global_range(planet->heightmap, &lo, &hi);
    plod__scaled(planet, lo, hi, min_m, max_m);
}

void plod_planet_height_range(const plod_planet *planet, double *min_m,
                              double *max_m)
{
    plod__map_height_range(planet, min_m, max_m);
    if (planet->detail) {
        double lo, hi, mlo = 0.0, mhi = 1.0;
        const plod_cubemap *mod = plod_detail_modulation(planet->detail);
        if (planet->heightmap && mod)
            plod_cubemap_global_range(mod, &mlo, &mhi);
        plod__detail_scaled(planet, mlo, mhi, &lo, &hi, NULL);
        *min_m += lo;
        *max_m += hi;
    }
}

void plod_planet_height_range_uv(const plod_planet *planet, int face, double u0,
                                 double v0, double u1, double v1, double *min_m,
                                 double *max_m)
{
    if (!planet->heightmap) { /* a source's bounds come through caps */
        plod__map_height_range(planet, min_m, max_m);
        return;
    }
    if (!plod_projection_is_cube(planet->projection)) {
        /* the CAR map is addressed by lon/lat, not by the octahedral square */
        plod__map_height_range(planet, min_m, max_m);
        return;
    }
    double lo, hi;
    plod_cubemap_range(planet->heightmap, face, u0, v0, u1, v1, &lo, &hi);
    plod__scaled(planet, lo, hi, min_m, max_m);
}

void plod_planet_height_range_cap(const plod_planet *planet, const double axis[3],
                                  double angle, double *min_m, double *max_m,
                                  double *texels)
{
    *texels = INFINITY;
    if (!planet->heightmap && planet->source) {
        double lo, hi;
        planet->source->ops->range_cap(planet->source->self, axis, angle, &lo, &hi, texels);
        plod__scaled(planet, lo, hi, min_m, max_m);
        return;
    }
    if (!planet->heightmap) {
        *min_m = *max_m = 0.0;
        return;
    }
    double lo, hi;
    plod__cap_range(planet->heightmap, axis, angle, &lo, &hi, texels);
    plod__scaled(planet, lo, hi, min_m, max_m);
}

void plod_planet_detail_range_uv(const plod_planet *planet, int face, double u0, double v0,
                                 double u1, double v1, double *min_m, double *max_m,
                                 double modulation[2])
{
    if (!planet->detail) {
        *min_m = *max_m = 0.0;
        if (modulation)
            modulation[0] = modulation[1] = 0.0;
        return;
    }
    const plod_cubemap *mod = plod_detail_modulation(planet->detail);
    double mlo = 0.0, mhi = 1.0;
    if (planet->heightmap && mod) {
        if (plod_projection_is_cube(planet->projection))
            plod_cubemap_range(mod, face, u0, v0, u1, v1, &mlo, &mhi);
        else
            plod_cubemap_global_range(mod, &mlo, &mhi);
    }
    plod__detail_scaled(planet, mlo, mhi, min_m, max_m, modulation);
}

void plod_planet_detail_range_cap(const plod_planet *planet, const double axis[3],
                                  double angle, double *min_m, double *max_m,
                                  double modulation[2])
{
    if (!planet->detail) {
        *min_m = *max_m = 0.0;
        if (modulation)
            modulation[0] = modulation[1] = 0.0;
        return;
    }
    const plod_cubemap *mod = plod_detail_modulation(planet->detail);
    double mlo = 0.0, mhi = 1.0, texels;
    if (planet->heightmap && mod)
        plod__cap_range(mod, axis, angle, &mlo, &mhi, &texels);
    plod__detail_scaled(planet, mlo, mhi, min_m, max_m, modulation);
}

/* ---- the planet as a surface source --------------------------------------- */

static void plod__surface_sample_n(const void *self, size_t n, const double *dirs,
                                   const int *octaves, const int *normal_octaves,
                                   double *heights, double *normals, double *detail)
{
    plod_planet_surface_detail_n(self, n, dirs, octaves, normal_octaves, heights, normals,
                                 detail);
}

static int plod__surface_octaves_for_cell(const void *self, double cell)
{
    return plod_detail_octaves_for_cell(((const plod_planet *)self)->detail, cell);
}

static uint64_t plod__surface_stamp(const void *self)
{
    return plod_detail_stamp(((const plod_planet *)self)->detail);
}

static const plod_surface_ops plod__planet_surface_ops = {plod__surface_sample_n, NULL, NULL};
static const plod_surface_ops plod__detail_surface_ops = {
    plod__surface_sample_n, plod__surface_octaves_for_cell, plod__surface_stamp};

plod_surface_source plod_planet_surface_source(const plod_planet *planet)
{
    plod_surface_source source = {
        planet && planet->detail ? &plod__detail_surface_ops : &plod__planet_surface_ops,
        planet};
    return source;
}

/* ---- checks with messages ------------------------------------------------------ */

plod_status plod_planet_check_numbers(const plod_planet *planet, char *message,
                                      size_t message_size)
{
    const char *rule = NULL;
    if (!planet)
        return PLOD_ERR_NULL;
    if (!isfinite(planet->height_offset))
        rule = "height_offset must be finite";
    else if (!isfinite(planet->radius) || planet->radius < 1.0 || planet->radius > 1e8)
        rule = "radius must be finite, in [1, 1e8] metres";
    if (message && message_size)
        snprintf(message, message_size, "%s", rule ? rule : "");
    return rule ? PLOD_ERR_BAD_PARAM : PLOD_OK;
}

size_t plod_planet_nan_count(const plod_planet *planet)
{
    if (planet->heightmap)
        return plod_cubemap_nan_count(planet->heightmap);
    if (planet->source && planet->source->ops && planet->source->ops->nan_count)
        return planet->source->ops->nan_count(planet->source->self);
    return 0;
}
