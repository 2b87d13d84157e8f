/* bench_projection_c.c -- C-level throughput of the vectorised projection
 * kernels (no Python in the loop).  Built and run by bench_projection.py:
 *     cc -O2 -ffp-contract=off -Icext bench/bench_projection_c.c cext/projection.c -lm
 * Prints one line per projection: ns/point for dir->face, face->dir,
 * lon/lat->cross, cross->lon/lat (thread CPU time, best of 5). */
#include "plod_projection.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static double plod__cpu_seconds(void)
{
    struct timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* xorshift64*: a deterministic, seedable uniform in [-1, 1). */
static double plod__uniform(unsigned long long *state)
{
    *state ^= *state >> 12;
    *state ^= *state << 25;
    *state ^= *state >> 27;
    return (double)((*state * 2685821657736338717ULL) >> 11) * (2.0 / 9007199254740992.0) - 1.0;
}

int main(int argc, char **argv)
{
    size_t n = argc > 1 ? (size_t)strtoull(argv[1], NULL, 10) : 2000000;
    double *dirs = malloc(3 * n * sizeof *dirs), *dirs2 = malloc(3 * n * sizeof *dirs2);
    double *u = malloc(n * sizeof *u), *v = malloc(n * sizeof *v);
    double *lon = malloc(n * sizeof *lon), *lat = malloc(n * sizeof *lat);
    double *x = malloc(n * sizeof *x), *y = malloc(n * sizeof *y);
    int *faces = malloc(n * sizeof *faces);
    if (!dirs || !dirs2 || !u || !v || !lon || !lat || !x || !y || !faces) {
        fprintf(stderr, "out of memory\n");
        return 1;
    }
    unsigned long long state = 88172645463325252ULL;
    for (size_t i = 0; i < n; i++) {
        double a, b, c, r2;
        do {
            a = plod__uniform(&state);
            b = plod__uniform(&state);
            c = plod__uniform(&state);
            r2 = a * a + b * b + c * c;
        } while (r2 > 1.0 || r2 < 1e-6);
        double r = sqrt(r2);
        dirs[3 * i] = a / r;
        dirs[3 * i + 1] = b / r;
        dirs[3 * i + 2] = c / r;
        lon[i] = atan2(b, a) * (180.0 / 3.14159265358979323846);
        lat[i] = asin(c / r) * (180.0 / 3.14159265358979323846);
    }
    printf("| mapping | dir->face ns | face->dir ns | lon/lat->cross ns | cross->lon/lat ns | dir fwd+inv M points/s | lon/lat fwd+inv M points/s |\n");
    printf("|---|---|---|---|---|---|---|\n");
    for (int p = 0; p < PLOD_PROJ_COUNT; p++) {
        double best[4] = {1e30, 1e30, 1e30, 1e30};
        for (int rep = 0; rep < 5; rep++) {
            double t0 = plod__cpu_seconds();
            plod_dir_to_face_n((plod_projection)p, n, dirs, faces, u, v, NULL);
            double t1 = plod__cpu_seconds();
            plod_face_to_dir_n((plod_projection)p, n, faces, u, v, dirs2, NULL);
            double t2 = plod__cpu_seconds();
            plod_sphere_to_cube_n((plod_projection)p, n, lon, lat, x, y, NULL);
            double t3 = plod__cpu_seconds();
            plod_cube_to_sphere_n((plod_projection)p, n, x, y, lon, lat, NULL);
            double t4 = plod__cpu_seconds();
            double t[4] = {t1 - t0, t2 - t1, t3 - t2, t4 - t3};
            for (int k = 0; k < 4; k++)
                best[k] = t[k] < best[k] ? t[k] : best[k];
        }
        double ns[4];
        for (int k = 0; k < 4; k++)
            ns[k] = best[k] / (double)n * 1e9;
        printf("| %s | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f |\n",
               plod_projection_name((plod_projection)p), ns[0], ns[1], ns[2], ns[3],
               1e3 / (ns[0] + ns[1]), 1e3 / (ns[2] + ns[3]));
    }
    free(dirs);
    free(dirs2);
    free(u);
    free(v);
    free(lon);
    free(lat);
    free(x);
    free(y);
    free(faces);
    return 0;
}
