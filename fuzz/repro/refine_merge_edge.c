/* refine_merge_edge.c -- reproducer found by fuzz/fuzz_refine.c:
 * after a frame whose split pass was stopped by max_sectors, the next
 * frame's merge pass links a leaf to an edge that already has two leaves
 * (lodtree.c plod__edge_add assertion; with NDEBUG the adjacency is silently
 * overwritten).  Build and run: bash fuzz/repro/run.sh refine_merge_edge
 */
#include <assert.h>
#include <stdio.h>
#include <stdlib.h>
#include "plod_refine.h"

static plod_camera camera_at(const double m[16])
{
    plod_camera_desc d = {0};
    for (int i = 0; i < 16; i++)
        d.matrix_world[i] = m[i];
    d.lens = 50, d.sensor_width = 36, d.sensor_height = 36;
    d.sensor_fit = PLOD_SENSOR_AUTO, d.ortho_scale = 7;
    d.clip_start = 0.1, d.clip_end = 1000;
    d.resolution_x = 1, d.resolution_y = 1;
    d.pixel_aspect_x = 1, d.pixel_aspect_y = 1;
    plod_camera c;
    if (plod_camera_init(&c, &d) != PLOD_OK)
        abort();
    return c;
}

int main(int argc, char **argv)
{
    size_t max_sectors = argc > 1 ? (size_t)atol(argv[1]) : 173;
    plod_planet planet = {.radius = 1737400, .projection = PLOD_PROJ_CSC,
                          .height_scale = 8848, .has_sea_level = 1,
                          .sea_level = 9.6925098676211405e-217};
    plod_refiner *r;
    if (plod_refiner_create(&r, &planet) != PLOD_OK)
        abort();
    plod_refine_params p;
    plod_refine_params_default(&p);
    p.criterion = PLOD_CRITERION_SIDE_DISTANCE;
    p.max_pixel_error = 4, p.split_border = 1, p.merge_border = 0.25;
    p.hysteresis = 0, p.backface_culling = 1, p.frustum_culling = 0;
    p.template_level = 1, p.max_level = 9, p.budget = 55;
    p.max_sectors = max_sectors;
    const double m0[16] = {0, 0.70710678118654757, 0.57735026918962584, -1003170.4780998051,
                           0, -0.70710678118654757, 0.57735026918962584, -1003197.760615173,
                           1, 0, 0.57735026918962584, -1003197.760615173, 0, 0, 0, 1};
    const double m1[16] = {0.70097623505624451, 0.039156902249895896, 0.71210887853794147,
                           1124542.5061580243, -0.71308188252523219, 0.021532595121975744,
                           0.70075000974783008, 1092724.9769538317, 0.012105647468987681,
                           -0.99900104321942784, 0.043015915029805285, -748278.74064790516,
                           0, 0, 0, 1};
    plod_camera c0 = camera_at(m0), c1 = camera_at(m1);
    plod_refine_stats st;
    plod_status s = plod_refiner_update(r, &c0, &p, &st, NULL);
    printf("frame 1: status %d, %zu sectors, truncated %d\n", s, st.sectors_total, st.truncated);
    s = plod_refiner_update(r, &c1, &p, &st, NULL);
    printf("frame 2: status %d, %zu sectors, truncated %d, merges %zu\n", s, st.sectors_total,
           st.truncated, st.merges);
    plod_refiner_destroy(r);
    return 0;
}
