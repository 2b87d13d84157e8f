/* fuzz_projection.c -- libFuzzer harness for cext/projection.c.
 *
 * Every projection, both directions (sphere <-> cross layout, direction <->
 * face/u/v, scalar and vectorised), with doubles that include NaN payloads,
 * infinities, signed zeros, denormals, DBL_MAX and values a few ulps off
 * face edges, poles and lon = +-180.  Besides ASan/UBSan it checks the
 * documented contract:
 *   - non-finite input never returns PLOD_OK; PLOD_OK output is finite;
 *   - lat of cube_to_sphere lies in [-90, 90]; dir_to_face gives a face in
 *     [0, 5] and u, v in [-1, 1]; face_to_dir gives a unit vector;
 *   - a successful forward result maps back (inverse succeeds and lands
 *     on the same direction within the projection's accuracy);
 *   - the vectorised forms agree bit for bit with the scalar ones.
 */
#include <math.h>
#include <stdint.h>

#include "fuzz_input.h"
#include "plod_projection.h"

#define MAX_POINTS 8
#define DEG (3.14159265358979323846 / 180.0)

/* Round-trip angular tolerance [rad].  CSC's inverse is an approximation
 * (published polynomials): WCSLIB's own cscs2x -> cscx2s round trip is off
 * by up to 2.19e-4 rad (0.0125 deg, e.g. at lon -104.52, lat 0). */
static double fuzz__tolerance(plod_projection p)
{
    return p == PLOD_PROJ_CSC ? 3e-4 : 1e-9;
}

static void fuzz__lonlat_dir(double lon_deg, double lat_deg, double d[3])
{
    double lon = lon_deg * DEG, lat = lat_deg * DEG;
    d[0] = cos(lat) * cos(lon);
    d[1] = cos(lat) * sin(lon);
    d[2] = sin(lat);
}

static double fuzz__angle(const double a_in[3], const double b_in[3])
{
    /* Scale by the largest component first: |DBL_MAX|^2 would overflow. */
    double a[3], b[3];
    double ma = fmax(fabs(a_in[0]), fmax(fabs(a_in[1]), fabs(a_in[2])));
    double mb = fmax(fabs(b_in[0]), fmax(fabs(b_in[1]), fabs(b_in[2])));
    for (int i = 0; i < 3; i++) {
        a[i] = a_in[i] / ma;
        b[i] = b_in[i] / mb;
    }
    double c[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                   a[0] * b[1] - a[1] * b[0]};
    double s = sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
    double dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    return atan2(s, dot);
}

static int fuzz__same_bits(double a, double b)
{
    return memcmp(&a, &b, sizeof a) == 0;
}

static void fuzz__sphere_to_cube(plod_projection p, double lon, double lat)
{
    double x = 0, y = 0;
    plod_status s = plod_sphere_to_cube(p, lon, lat, &x, &y);
    if (!isfinite(lon) || !isfinite(lat))
        FUZZ_CHECK(s != PLOD_OK, "p=%d lon=%g lat=%g accepted", p, lon, lat);
    if (s != PLOD_OK)
        return;
    FUZZ_CHECK(isfinite(x) && isfinite(y), "p=%d (%.17g, %.17g) -> (%g, %g)",
               p, lon, lat, x, y);
    FUZZ_CHECK(lat >= -90.0 && lat <= 90.0, "p=%d lat=%.17g accepted", p, lat);
    double lon2 = 0, lat2 = 0;
    s = plod_cube_to_sphere(p, x, y, &lon2, &lat2);
    FUZZ_CHECK(s == PLOD_OK, "p=%d (%.17g, %.17g) -> (%.17g, %.17g) not invertible (%d)",
               p, lon, lat, x, y, s);
    FUZZ_CHECK(isfinite(lon2) && lat2 >= -90.0 && lat2 <= 90.0,
               "p=%d inverse gave (%g, %g)", p, lon2, lat2);
    if (fabs(lon) < 1e6) { /* beyond, lon_deg*DEG itself loses the answer */
        double a[3], b[3];
        fuzz__lonlat_dir(lon, lat, a);
        fuzz__lonlat_dir(lon2, lat2, b);
        FUZZ_CHECK(fuzz__angle(a, b) <= fuzz__tolerance(p),
                   "p=%d (%.17g, %.17g) -> (%.17g, %.17g) -> (%.17g, %.17g): %g rad",
                   p, lon, lat, x, y, lon2, lat2, fuzz__angle(a, b));
    }
}

static void fuzz__cube_to_sphere(plod_projection p, double x, double y)
{
    double lon = 0, lat = 0;
    plod_status s = plod_cube_to_sphere(p, x, y, &lon, &lat);
    if (!isfinite(x) || !isfinite(y))
        FUZZ_CHECK(s != PLOD_OK, "p=%d x=%g y=%g accepted", p, x, y);
    if (s != PLOD_OK)
        return;
    FUZZ_CHECK(isfinite(lon) && isfinite(lat) && lat >= -90.0 && lat <= 90.0,
               "p=%d (%.17g, %.17g) -> (%g, %g)", p, x, y, lon, lat);
    double x2 = 0, y2 = 0;
    s = plod_sphere_to_cube(p, lon, lat, &x2, &y2);
    FUZZ_CHECK(s == PLOD_OK && isfinite(x2) && isfinite(y2),
               "p=%d (%.17g, %.17g) -> (%.17g, %.17g) -> status %d", p, x, y,
               lon, lat, s);
    double lon3 = 0, lat3 = 0;
    s = plod_cube_to_sphere(p, x2, y2, &lon3, &lat3);
    FUZZ_CHECK(s == PLOD_OK, "p=%d forward result (%.17g, %.17g) rejected", p, x2, y2);
    double a[3], b[3];
    fuzz__lonlat_dir(lon, lat, a);
    fuzz__lonlat_dir(lon3, lat3, b);
    FUZZ_CHECK(fuzz__angle(a, b) <= fuzz__tolerance(p),
               "p=%d (%.17g, %.17g) -> (%.17g, %.17g) -> (%.17g, %.17g) -> (%.17g, %.17g): %g rad",
               p, x, y, lon, lat, x2, y2, lon3, lat3, fuzz__angle(a, b));
}

static void fuzz__dir_to_face(plod_projection p, const double dir[3])
{
    int face = -7;
    double u = 0, v = 0;
    plod_status s = plod_dir_to_face(p, dir, &face, &u, &v);
    int finite = isfinite(dir[0]) && isfinite(dir[1]) && isfinite(dir[2]);
    int zero = dir[0] == 0 && dir[1] == 0 && dir[2] == 0;
    if (!finite || zero)
        FUZZ_CHECK(s != PLOD_OK, "p=%d dir (%g, %g, %g) accepted", p, dir[0],
                   dir[1], dir[2]);
    if (s != PLOD_OK)
        return;
    FUZZ_CHECK(face >= 0 && face < PLOD_FACE_COUNT && isfinite(u) && isfinite(v) &&
                   fabs(u) <= 1.0 && fabs(v) <= 1.0,
               "p=%d dir (%.17g, %.17g, %.17g) -> face %d (%.17g, %.17g)", p,
               dir[0], dir[1], dir[2], face, u, v);
    if (p == PLOD_PROJ_CAR)
        FUZZ_CHECK(face == 0, "CAR face %d", face);
    double back[3] = {0, 0, 0};
    s = plod_face_to_dir(p, face, u, v, back);
    FUZZ_CHECK(s == PLOD_OK, "p=%d face %d (%.17g, %.17g) from dir rejected (%d)",
               p, face, u, v, s);
    double len = sqrt(back[0] * back[0] + back[1] * back[1] + back[2] * back[2]);
    FUZZ_CHECK(fabs(len - 1.0) <= 1e-12, "p=%d |dir| = %.17g", p, len);
    FUZZ_CHECK(fuzz__angle(dir, back) <= fuzz__tolerance(p),
               "p=%d dir (%.17g, %.17g, %.17g) -> face %d (%.17g, %.17g) -> "
               "(%.17g, %.17g, %.17g): %g rad",
               p, dir[0], dir[1], dir[2], face, u, v, back[0], back[1], back[2],
               fuzz__angle(dir, back));
}

static void fuzz__face_to_dir(plod_projection p, int face, double u, double v)
{
    double dir[3] = {0, 0, 0};
    plod_status s = plod_face_to_dir(p, face, u, v, dir);
    if (!isfinite(u) || !isfinite(v) || face < 0 || face >= PLOD_FACE_COUNT ||
        (p == PLOD_PROJ_CAR && face != 0))
        FUZZ_CHECK(s != PLOD_OK, "p=%d face %d (%g, %g) accepted", p, face, u, v);
    if (s != PLOD_OK)
        return;
    double len = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
    FUZZ_CHECK(isfinite(len) && fabs(len - 1.0) <= 1e-12,
               "p=%d face %d (%.17g, %.17g) -> |dir| %.17g", p, face, u, v, len);
    int face2 = -7;
    double u2, v2;
    s = plod_dir_to_face(p, dir, &face2, &u2, &v2);
    FUZZ_CHECK(s == PLOD_OK, "p=%d face_to_dir output rejected (%d)", p, s);
    double again[3];
    s = plod_face_to_dir(p, face2, u2, v2, again);
    FUZZ_CHECK(s == PLOD_OK && fuzz__angle(dir, again) <= fuzz__tolerance(p),
               "p=%d face %d (%.17g, %.17g) -> face %d (%.17g, %.17g): %g rad", p,
               face, u, v, face2, u2, v2, fuzz__angle(dir, again));
}

/* The vectorised forms must equal the scalar ones, point by point. */
static void fuzz__vectorised(plod_projection p, fuzz_input *in)
{
    size_t n = (size_t)fuzz_range(in, 0, MAX_POINTS);
    double a[MAX_POINTS], b[MAX_POINTS], c[MAX_POINTS], o1[MAX_POINTS],
        o2[MAX_POINTS], dirs[3 * MAX_POINTS];
    int stat[MAX_POINTS], faces[MAX_POINTS];
    for (size_t i = 0; i < n; i++) {
        a[i] = fuzz_double(in);
        b[i] = fuzz_double(in);
        c[i] = fuzz_double(in);
        faces[i] = fuzz_range(in, -1, 6);
    }
    int use_stat = fuzz_u8(in) & 1;
    for (int direction = 0; direction < 2; direction++) {
        plod_status all = direction == 0
            ? plod_sphere_to_cube_n(p, n, a, b, o1, o2, use_stat ? stat : NULL)
            : plod_cube_to_sphere_n(p, n, a, b, o1, o2, use_stat ? stat : NULL);
        plod_status first = PLOD_OK;
        for (size_t i = 0; i < n; i++) {
            double s1 = 0, s2 = 0;
            plod_status s = direction == 0 ? plod_sphere_to_cube(p, a[i], b[i], &s1, &s2)
                                           : plod_cube_to_sphere(p, a[i], b[i], &s1, &s2);
            if (s != PLOD_OK && first == PLOD_OK)
                first = s;
            if (use_stat)
                FUZZ_CHECK(stat[i] == (int)s, "p=%d dir %d point %zu: stat %d vs %d",
                           p, direction, i, stat[i], s);
            if (s == PLOD_OK)
                FUZZ_CHECK(fuzz__same_bits(s1, o1[i]) && fuzz__same_bits(s2, o2[i]),
                           "p=%d dir %d point %zu: vector (%.17g, %.17g) scalar (%.17g, %.17g)",
                           p, direction, i, o1[i], o2[i], s1, s2);
            else
                FUZZ_CHECK(isnan(o1[i]) && isnan(o2[i]), "failed point not NaN");
        }
        FUZZ_CHECK(all == first, "p=%d n-form status %d, first failure %d", p, all, first);
    }
    {
        for (size_t i = 0; i < n; i++) {
            dirs[3 * i] = a[i];
            dirs[3 * i + 1] = b[i];
            dirs[3 * i + 2] = c[i];
        }
        int out_faces[MAX_POINTS];
        plod_dir_to_face_n(p, n, dirs, out_faces, o1, o2, use_stat ? stat : NULL);
        for (size_t i = 0; i < n; i++) {
            int f = -1;
            double u = 0, v = 0;
            plod_status s = plod_dir_to_face(p, dirs + 3 * i, &f, &u, &v);
            if (use_stat)
                FUZZ_CHECK(stat[i] == (int)s, "dir_to_face_n stat");
            if (s == PLOD_OK)
                FUZZ_CHECK(out_faces[i] == f && fuzz__same_bits(u, o1[i]) &&
                               fuzz__same_bits(v, o2[i]),
                           "dir_to_face_n differs from scalar at %zu", i);
        }
    }
    {
        plod_face_to_dir_n(p, n, faces, a, b, dirs, use_stat ? stat : NULL);
        for (size_t i = 0; i < n; i++) {
            double d[3];
            plod_status s = plod_face_to_dir(p, faces[i], a[i], b[i], d);
            if (use_stat)
                FUZZ_CHECK(stat[i] == (int)s, "face_to_dir_n stat");
            if (s == PLOD_OK)
                FUZZ_CHECK(fuzz__same_bits(d[0], dirs[3 * i]) &&
                               fuzz__same_bits(d[1], dirs[3 * i + 1]) &&
                               fuzz__same_bits(d[2], dirs[3 * i + 2]),
                           "face_to_dir_n differs from scalar at %zu", i);
        }
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_input in = {data, size};
    uint8_t op = fuzz_u8(&in);
    /* Mostly valid codes, sometimes a bad one (must be rejected, not used). */
    int code = (op & 0x80) ? (int)(int8_t)fuzz_u8(&in) : (op >> 4) % PLOD_PROJ_COUNT;
    plod_projection p = (plod_projection)code;
    int valid = code >= 0 && code < PLOD_PROJ_COUNT;

    if (!valid) {
        double x, y, d[3] = {1, 0, 0};
        int f;
        FUZZ_CHECK(plod_projection_name(p) == NULL, "name of code %d", code);
        FUZZ_CHECK(plod_sphere_to_cube(p, 0, 0, &x, &y) != PLOD_OK, "bad code %d", code);
        FUZZ_CHECK(plod_cube_to_sphere(p, 0, 0, &x, &y) != PLOD_OK, "bad code %d", code);
        FUZZ_CHECK(plod_dir_to_face(p, d, &f, &x, &y) != PLOD_OK, "bad code %d", code);
        FUZZ_CHECK(plod_face_to_dir(p, 1, 0, 0, d) != PLOD_OK, "bad code %d", code);
        (void)plod_projection_is_cube(p);
        return 0;
    }

    switch (op & 7) {
    case 0: {
        double lon = fuzz_double(&in), lat = fuzz_double(&in);
        fuzz__sphere_to_cube(p, lon, lat);
        break;
    }
    case 1: {
        double x = fuzz_double(&in), y = fuzz_double(&in);
        fuzz__cube_to_sphere(p, x, y);
        break;
    }
    case 2: {
        double dir[3] = {fuzz_double(&in), fuzz_double(&in), fuzz_double(&in)};
        fuzz__dir_to_face(p, dir);
        break;
    }
    case 3: {
        int face = (op & 8) ? fuzz_range(&in, -3, 9) : fuzz_range(&in, 0, 5);
        double u = fuzz_double(&in), v = fuzz_double(&in);
        fuzz__face_to_dir(p, face, u, v);
        break;
    }
    case 4:
        fuzz__vectorised(p, &in);
        break;
    case 5: {
        /* Names: arbitrary bytes, NUL-terminated. */
        char name[24];
        size_t n = in.size < sizeof name - 1 ? in.size : sizeof name - 1;
        memcpy(name, in.data, n);
        name[n] = '\0';
        plod_projection out = PLOD_PROJ_COUNT;
        plod_status s = plod_projection_from_name(name, &out);
        if (s == PLOD_OK)
            FUZZ_CHECK((unsigned)out < PLOD_PROJ_COUNT &&
                           plod_projection_name(out) != NULL,
                       "name '%s' -> %d", name, out);
        FUZZ_CHECK(plod_projection_from_name(NULL, &out) != PLOD_OK, "NULL name");
        break;
    }
    default: {
        /* Points near faces: a face centre plus a small, possibly denormal,
         * offset, both directions through every entry point. */
        double lon = 45.0 * fuzz_range(&in, -8, 8) + fuzz_double(&in) * 1e-12;
        double lat = 45.0 * fuzz_range(&in, -2, 2) + fuzz_double(&in) * 1e-12;
        fuzz__sphere_to_cube(p, lon, lat);
        double dir[3];
        fuzz__lonlat_dir(lon, lat, dir);
        fuzz__dir_to_face(p, dir);
        break;
    }
    }
    return 0;
}
