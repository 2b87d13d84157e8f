/* planet.c -- planet description: validation, heights and height bounds.
 *
 * Heights are the height map's channel 0 (normalised as the cube map
 * samples it) times height_scale, in metres above `radius`.  A negative
 * scale swaps the bounds.  Without a map the planet is a perfect sphere.
 */
#include "plod_planet.h"

#include <math.h>

plod_status plod_planet_check(const plod_planet *planet)
{
    if (!planet)
        return PLOD_ERR_NULL;
    if (!isfinite(planet->radius) || planet->radius < 1.0 || planet->radius > 1e8)
        return PLOD_ERR_BAD_PARAM;
    if ((unsigned)planet->projection >= PLOD_PROJ_COUNT)
        return PLOD_ERR_BAD_PROJECTION;
    if (!isfinite(planet->height_scale))
        return PLOD_ERR_BAD_PARAM;
    if (planet->has_sea_level && !isfinite(planet->sea_level))
        return PLOD_ERR_BAD_PARAM;
    if (planet->heightmap) {
        if (plod_cubemap_projection(planet->heightmap) != planet->projection)
            return PLOD_ERR_BAD_PROJECTION;
        if (plod_cubemap_nan_count(planet->heightmap) != 0)
            return PLOD_ERR_BAD_IMAGE;
        double lo, hi;
        plod_cubemap_global_range(planet->heightmap, &lo, &hi);
        if (!isfinite(lo) || !isfinite(hi) || lo > hi)
            return PLOD_ERR_BAD_PARAM;
        /* the terrain must stay outside the centre and within sane bounds */
        double a = lo * planet->height_scale, b = hi * planet->height_scale;
        double low = a < b ? a : b, high = a < b ? b : a;
        if (low <= -0.5 * planet->radius || high > 10.0 * planet->radius)
            return PLOD_ERR_BAD_PARAM;
    }
    return PLOD_OK;
}

double plod_planet_height(const plod_planet *planet, const double dir[3])
{
    if (!planet->heightmap)
        return 0.0;
    return plod_cubemap_sample_height(planet->heightmap, dir) * planet->height_scale;
}

#define PLOD__PLANET_PI 3.141592653589793

static void plod__scaled(const plod_planet *planet, double lo, double hi,
                         double *min_m, double *max_m)
{
    double a = lo * planet->height_scale, b = hi * planet->height_scale;
    *min_m = a < b ? a : b;
    *max_m = a < b ? b : a;
}

void plod_planet_height_range(const plod_planet *planet, double *min_m,
                              double *max_m)
{
    if (!planet->heightmap) {
        *min_m = *max_m = 0.0;
        return;
    }
    double lo, hi;
    plod_cubemap_global_range(planet->heightmap, &lo, &hi);
    plod__scaled(planet, lo, hi, min_m, max_m);
}

void plod_planet_height_range_uv(const plod_planet *planet, int face, double u0,
                                 double v0, double u1, double v1, double *min_m,
                                 double *max_m)
{
    if (!planet->heightmap) {
        *min_m = *max_m = 0.0;
        return;
    }
    if (!plod_projection_is_cube(planet->projection)) {
        /* the CAR map is addressed by lon/lat, not by the octahedral square */
        plod_planet_height_range(planet, min_m, max_m);
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
    plod_planet_height_range(planet, min_m, max_m);
    if (!planet->heightmap || plod_cubemap_face_count(planet->heightmap) != 1 ||
        !(angle >= 0.0) || angle >= 0.5 * PLOD__PLANET_PI)
        return;
    const double deg = 180.0 / PLOD__PLANET_PI;
    double lat = asin(fmax(-1.0, fmin(1.0, axis[2])));
    double lon = atan2(axis[1], axis[0]);
    double lat0 = lat - angle, lat1 = lat + angle, half_lon;
    if (lat1 >= 0.5 * PLOD__PLANET_PI || lat0 <= -0.5 * PLOD__PLANET_PI) {
        half_lon = PLOD__PLANET_PI; /* a pole inside: every longitude */
        lat0 = fmax(lat0, -0.5 * PLOD__PLANET_PI);
        lat1 = fmin(lat1, 0.5 * PLOD__PLANET_PI);
    } else {
        /* longitude half-width of a cap not holding a pole */
        half_lon = asin(fmin(1.0, sin(angle) / cos(lat)));
    }
    double v0 = lat0 * deg / 90.0, v1 = lat1 * deg / 90.0;
    double lo, hi, lo2, hi2;
    if (half_lon >= PLOD__PLANET_PI) {
        plod_cubemap_range(planet->heightmap, 0, -1.0, v0, 1.0, v1, &lo, &hi);
    } else {
        double u0 = (lon - half_lon) * deg / 180.0, u1 = (lon + half_lon) * deg / 180.0;
        if (u0 < -1.0) { /* across the +-180 deg seam: two boxes */
            plod_cubemap_range(planet->heightmap, 0, -1.0, v0, u1, v1, &lo, &hi);
            plod_cubemap_range(planet->heightmap, 0, u0 + 2.0, v0, 1.0, v1, &lo2, &hi2);
            lo = fmin(lo, lo2);
            hi = fmax(hi, hi2);
        } else if (u1 > 1.0) {
            plod_cubemap_range(planet->heightmap, 0, u0, v0, 1.0, v1, &lo, &hi);
            plod_cubemap_range(planet->heightmap, 0, -1.0, v0, u1 - 2.0, v1, &lo2, &hi2);
            lo = fmin(lo, lo2);
            hi = fmax(hi, hi2);
        } else {
            plod_cubemap_range(planet->heightmap, 0, u0, v0, u1, v1, &lo, &hi);
        }
    }
    plod__scaled(planet, lo, hi, min_m, max_m);
    int size = plod_cubemap_size(planet->heightmap); /* rows; 2 * size columns */
    *texels = fmax(2.0 * half_lon * deg / 360.0 * 2.0 * size, (lat1 - lat0) * deg / 180.0 * size);
}
