/* plod_surface.h -- the finished surface the mesh emitter samples: heights
 * in metres, unit normals and the detail field's part, per direction.
 */
#ifndef PLOD_SURFACE_H
#define PLOD_SURFACE_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* plod_height_source (plod_heightsource.h) is raw data: map values and
 * their bounds, which the planet scales, blends and bounds.  A surface
 * source is the other end: heights in metres, unit normals and the detail
 * field's part, with the detail band chosen per point, as mesh vertices
 * need them.  The planet is one (plod_planet_surface_source); tests and
 * other surfaces plug in the same way. */
typedef struct plod_surface_ops {
    /* At n unit directions (dirs: 3 n doubles): heights[i] in metres above
     * the radius, normals[3 i..] unit outward (NULL: not wanted), detail[i]
     * the detail field's part of the height (NULL: not wanted).  octaves /
     * normal_octaves (NULL: all): per point, the detail octaves the height
     * and the normal keep.  A point's results depend on its direction and
     * band only (not on n or its neighbours), bit for bit.  Called from
     * several threads at once. */
    void (*sample_n)(const void *self, size_t n, const double *dirs, const int *octaves,
                     const int *normal_octaves, double *heights, double *normals,
                     double *detail);
    /* Detail octaves that cells of `cell` metres resolve.  NULL when the
     * surface has no band-limited detail: every point keeps everything. */
    int (*octaves_for_cell)(const void *self, double cell);
    /* A value that changes whenever the surface's samples would (caches
     * compare it); NULL: they never change while `self` lives. */
    uint64_t (*stamp)(const void *self);
} plod_surface_ops;

typedef struct plod_surface_source {
    const plod_surface_ops *ops;
    const void *self;
} plod_surface_source;

#ifdef __cplusplus
}
#endif
#endif /* PLOD_SURFACE_H */
