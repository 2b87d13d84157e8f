/* test_detail_lanes.c -- the detail field's batches (SIMD lanes) against its
 * point path, bit for bit.
 *
 * plod_detail_noise_from_n sorts its points by the octaves they evaluate
 * and runs them in batches of lanes; whatever a point's batch-mates, its
 * sum and gradient must be plod_detail_noise_from's at that point alone.
 * Checked for every style and the crater layer, with every point's own
 * value band, gradient band and first octave (out of range ones included),
 * on runs of nearby directions (a sector's vertices: whole batches in one
 * lattice cell of the coarse octaves), scattered ones and non-finite ones.
 * Built by tests/test_detail_lanes.py with the core's C sources.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "plod_detail.h"

static unsigned long long rng_state = 0x9e3779b97f4a7c15ULL;

static double uniform(void) /* [0, 1) */
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return (double)(rng_state >> 11) * (1.0 / 9007199254740992.0);
}

static int pick(int lo, int hi) /* [lo, hi] */
{
    return lo + (int)(uniform() * (double)(hi - lo + 1));
}

static void random_direction(double d[3])
{
    double len;
    do {
        for (int a = 0; a < 3; a++)
            d[a] = 2.0 * uniform() - 1.0;
        len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    } while (!(len > 0.1 && len <= 1.0));
    for (int a = 0; a < 3; a++)
        d[a] /= len;
}

static int same(double a, double b)
{
    return (isnan(a) && isnan(b)) || memcmp(&a, &b, sizeof a) == 0;
}

enum { POINTS = 1100 };

static int check(const plod_detail *detail, const char *label, int with_first)
{
    static double dirs[3 * POINTS], sums[POINTS], gradients[3 * POINTS];
    static int firsts[POINTS], octaves[POINTS], gradient_octaves[POINTS];
    int count = plod_detail_octave_count(detail);
    for (int k = 0; k < POINTS;) {
        double centre[3];
        random_direction(centre);
        int run = pick(1, 200);
        double spread = pow(10.0, -(double)pick(2, 9));
        for (int j = 0; j < run && k < POINTS; j++, k++) {
            double *d = dirs + 3 * k;
            for (int a = 0; a < 3; a++)
                d[a] = centre[a] + spread * (2.0 * uniform() - 1.0);
            double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
            for (int a = 0; a < 3; a++)
                d[a] /= len;
            int band = pick(-2, count + 3);
            /* a sector's vertices: most share a band, its corners take every octave */
            octaves[k] = pick(0, 9) == 0 ? PLOD_DETAIL_MAX_OCTAVES : band;
            gradient_octaves[k] = pick(0, 3) == 0 ? pick(-1, count + 1) : octaves[k];
            firsts[k] = with_first ? pick(-1, count + 1) : 0;
            if (pick(0, 60) == 0)
                d[pick(0, 2)] = pick(0, 1) ? NAN : INFINITY;
        }
    }
    int failures = 0;
    for (int pass = 0; pass < 2; pass++) {
        double *g = pass ? gradients : NULL;
        plod_detail_noise_from_n(detail, POINTS, dirs, with_first ? firsts : NULL, octaves,
                                 gradient_octaves, sums, g);
        for (int k = 0; k < POINTS && failures < 5; k++) {
            double point_g[3];
            double sum = plod_detail_noise_from(detail, dirs + 3 * k, firsts[k], octaves[k], NULL);
            int ok = same(sums[k], sum);
            if (g) {
                (void)plod_detail_noise_from(detail, dirs + 3 * k, firsts[k],
                                             gradient_octaves[k], point_g);
                for (int a = 0; a < 3; a++)
                    ok = ok && same(g[3 * k + a], point_g[a]);
            }
            if (!ok) {
                printf("%s%s: point %d (first %d, octaves %d, gradient octaves %d) differs: "
                       "%.17g against %.17g\n",
                       label, g ? " with gradients" : "", k, firsts[k], octaves[k],
                       gradient_octaves[k], sums[k], sum);
                failures++;
            }
        }
    }
    return failures;
}

int main(void)
{
    plod_planet planet;
    memset(&planet, 0, sizeof planet);
    planet.radius = 6371000.0;
    planet.projection = PLOD_PROJ_QSC;
    struct {
        const char *label;
        plod_detail_style style;
        double craters;
    } cases[] = {{"hills", PLOD_DETAIL_HILLS, 0.0},
                 {"mountains", PLOD_DETAIL_MOUNTAINS, 0.0},
                 {"craters", PLOD_DETAIL_CRATERS, 0.0},
                 {"mountains and craters", PLOD_DETAIL_MOUNTAINS, 1.0}};
    int failures = 0;
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        plod_detail_params params;
        plod_detail_params_init(&params);
        params.style = cases[c].style;
        params.craters = cases[c].craters;
        params.amplitude = 900.0;
        params.largest = 40000.0;
        params.smallest = 0.1;
        plod_detail *detail = NULL;
        if (plod_detail_create(&detail, &params, &planet) != PLOD_OK) {
            printf("%s: plod_detail_create failed\n", cases[c].label);
            return 1;
        }
        if (plod_detail_octave_count(detail) < 15) {
            printf("%s: only %d octaves\n", cases[c].label, plod_detail_octave_count(detail));
            return 1;
        }
        failures += check(detail, cases[c].label, 0);
        failures += check(detail, cases[c].label, 1);
        plod_detail_destroy(detail);
    }
    if (failures)
        return 1;
    printf("detail lanes C tests passed\n");
    return 0;
}
