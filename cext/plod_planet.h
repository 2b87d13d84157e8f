/* plod_planet.h -- the planet being refined: radius, mapping, heights.
 * A plain value struct; the height map is borrowed (caller keeps it alive).
 */
#ifndef PLOD_PLANET_H
#define PLOD_PLANET_H

#include "plod_cubemap.h"
#include "plod_heightsource.h"
#include "plod_surface.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct plod_detail plod_detail; /* plod_detail.h */

typedef struct plod_planet {
    double radius;              /* metres, [1, 1e8] */
    plod_projection projection; /* mapping used for sectors */
    const plod_cubemap *heightmap; /* borrowed; NULL = perfect sphere.  Its
                                      projection equals `projection` (CAR:
                                      an equirectangular map) and its
                                      pyramid is built
                                      (plod_cubemap_build_pyramid; bounds
                                      and NaN count come from it). */
    double height_scale;        /* metres per unit of sampled height */
    double height_offset;       /* metres added to every height (a datum:
                                   terrain below the radius, sea floor);
                                   height = sample * height_scale +
                                   height_offset */
    const plod_cubemap *normalmap; /* borrowed, optional: the normals of
                                      heightmap for this radius and
                                      height_scale (plod_planet_build_normals);
                                      NULL: normals from height differences
                                      (slower) */
    const plod_cubemap_bundle *bundle; /* borrowed, optional: heightmap,
                                      normalmap and the detail's modulation
                                      interleaved (plod_cubemap_bundle_create)
                                      for the vertices' samples; used only
                                      while it holds exactly those maps; the
                                      same values as the maps apart */
    int has_sea_level;          /* non-zero: sea_level is set */
    double sea_level;           /* metres; sectors whose heights are all
                                   <= sea_level may be skipped */
    const plod_detail *detail;  /* borrowed, optional: the detail field added
                                   to the map (plod_detail_create for this
                                   planet); NULL: the map alone */
    const plod_height_source *source; /* borrowed, optional, only without a
                                   heightmap: height data sampled out of
                                   core (plod_heightsource.h; a tiled map).
                                   Heights = value * height_scale +
                                   height_offset; normals from differences;
                                   sector bounds through spherical caps */
    const plod_insets *insets;  /* borrowed, optional: regional grids in
                                   metres blended over the global data
                                   (the map or the source) across feathered
                                   borders; normals there from differences
                                   one inset sample apart */
} plod_planet;

/* ---- validation and set-up -------------------------------------------------- */

/* Validates fields: finite numbers, radius range, projection
 * (PLOD_ERR_BAD_PROJECTION, also for a height map in another one), no NaN
 * texels in the height map and a finite global range of the height source
 * (PLOD_ERR_BAD_IMAGE), height ranges that keep the terrain outside the
 * centre, a complete height source, a normal map and detail field made for
 * this planet.  PLOD_ERR_NULL for NULL, PLOD_ERR_BAD_PARAM otherwise; the
 * rule that failed goes into *error (may be NULL).
 * The height map's pyramid is not checked (see `heightmap`). */
plod_status plod_planet_check(const plod_planet *planet, plod_error *error);
/* The planet's own numbers, checkable before any height data is read:
 * height_offset finite, radius finite in [1, 1e8] metres.
 * PLOD_ERR_BAD_PARAM with `message` (may be NULL) naming the rule. */
plod_status plod_planet_check_numbers(const plod_planet *planet, char *message,
                                      size_t message_size);
/* No-data (NaN) texels in the planet's height data: the height map's, or
 * the height source's when it counts them; 0 without data.  A planet with
 * any is refused (plod_planet_check, plod_session_create): NaN heights
 * would reach the emitted vertices. */
size_t plod_planet_nan_count(const plod_planet *planet);
/* The normal map of planet's height map (plod_cubemap_build_normals for
 * the sphere of radius + height_offset and height_scale, on `threads`
 * threads), for planet->normalmap; caller owns *out.  PLOD_ERR_NULL
 * without a height map; else plod_cubemap_build_normals' statuses. */
plod_status plod_planet_build_normals(const plod_planet *planet, plod_cubemap **out,
                                      int threads);

/* ---- heights and normals ---------------------------------------------------- */

/* Metres per texel of the planet's height data at a unit direction (a
 * cube map: its texel at the face centre; a height source: its
 * texel_angle there; an inset's sample spacing where it counts), INFINITY
 * without data.  Detail starts below it: over an inset the field is
 * (1 - w) N_all + w N_from, w the inset's blend weight and N_from the
 * octaves from the first of wavelength <= two of its mosaic's samples
 * (plod_detail_noise_from), in heights, normals and sector bounds. */
double plod_planet_texel_size(const plod_planet *planet, const double dir[3]);
/* Height in metres above `radius` at a unit direction: the map's plus the
 * detail field's (every octave). */
double plod_planet_height(const plod_planet *planet, const double dir[3]);
/* The height map's part alone (0 without a map). */
double plod_planet_map_height(const plod_planet *planet, const double dir[3]);
/* Height as plod_planet_height (bit for bit) and, if `normal` is not NULL,
 * the unit outward surface normal at a unit direction: with a height map,
 * sampled from normalmap at the same map location (one projection for
 * both), or without a normal map from central differences of four more
 * heights (4x slower); with a height source, and inside insets, from
 * differences; without data, the direction; tilted by the detail field's
 * analytic slope when there is one. */
double plod_planet_surface(const plod_planet *planet, const double dir[3],
                           double normal[3]);
/* plod_planet_surface at n unit directions (dirs: 3 n doubles), bit for
 * bit: heights[i], and normals[3 i..] when `normals` is not NULL. */
void plod_planet_surface_n(const plod_planet *planet, size_t n, const double *dirs,
                           double *heights, double *normals);
/* plod_planet_surface_n with the detail field band-limited per point:
 * heights keep its first octaves[i] octaves, normals the slope of its
 * first normal_octaves[i] (<= octaves[i]; NULL: the same); octaves NULL:
 * all, = plod_planet_surface_n bit for bit.  Normals: the map's normal
 * tilted by those octaves' analytic slope (the modulation's own slope is
 * left out: it varies over map texels, ~1e-3 of the octaves' slopes). */
void plod_planet_surface_band_n(const plod_planet *planet, size_t n, const double *dirs,
                                const int *octaves, const int *normal_octaves,
                                double *heights, double *normals);
/* plod_planet_surface_band_n, and when `detail` is not NULL the detail
 * field's part of each height (metres: modulation times the kept octaves;
 * 0 without detail, on the sea and where the map has no value).  Same
 * heights and normals bit for bit. */
void plod_planet_surface_detail_n(const plod_planet *planet, size_t n, const double *dirs,
                                  const int *octaves, const int *normal_octaves,
                                  double *heights, double *normals, double *detail);
/* The planet as a surface source (plod_heightsource.h) for the mesh
 * emitter: sample_n is plod_planet_surface_detail_n; octaves_for_cell and
 * stamp are the detail field's (both NULL without one).  Valid while
 * `planet` lives; reads its fields at each call. */
plod_surface_source plod_planet_surface_source(const plod_planet *planet);

/* ---- height bounds ---------------------------------------------------------- */

/* Global height bounds in metres: the height map's or the height
 * source's, widened by the insets' and the detail field's (0, 0 without
 * any of them). */
void plod_planet_height_range(const plod_planet *planet, double *min_m,
                              double *max_m);
/* Conservative bounds of the height MAP's part in metres over the face
 * rectangle [u0,u1]x[v0,v1] (clamped to the face).  Without a cube map
 * (a height source or no data) and for CAR (the octahedral square is not
 * how the map is addressed): the global range of the map or source and
 * the insets (0, 0 without any).  The detail field's part:
 * plod_planet_detail_range_uv. */
void plod_planet_height_range_uv(const plod_planet *planet, int face, double u0,
                                 double v0, double u1, double v1, double *min_m,
                                 double *max_m);
/* Conservative bounds of the height data's part in metres (map or
 * source; not the insets, not the detail field) over the spherical cap of
 * unit centre `axis` and angular radius `angle` (radians).  A CAR map:
 * through the cap's longitude/latitude box (the whole longitude range
 * when the cap holds a pole), *texels the box's larger side in map texels
 * (for sub-texel refinements).  A height source: its range_cap (and its
 * *texels).  A cube map: the map's global range; no data: 0, 0; both
 * with *texels = INFINITY. */
void plod_planet_height_range_cap(const plod_planet *planet, const double axis[3],
                                  double angle, double *min_m, double *max_m,
                                  double *texels);
/* Conservative bounds of the detail field (any band limit) in metres over
 * the same regions as plod_planet_height_range_uv / _cap: the noise's
 * bounds times the modulation map's maximum there.  0, 0 without detail.
 * modulation (may be NULL) gets the modulation map's bounds there. */
void plod_planet_detail_range_uv(const plod_planet *planet, int face, double u0, double v0,
                                 double u1, double v1, double *min_m, double *max_m,
                                 double modulation[2]);
void plod_planet_detail_range_cap(const plod_planet *planet, const double axis[3],
                                  double angle, double *min_m, double *max_m,
                                  double modulation[2]);
/* The earliest octave the detail field starts at, where an inset counts,
 * over the spherical cap: the octaves before it have weight 1 - w there
 * (plod_planet_surface); the octave count where no inset meets the cap (0
 * without detail).  The field over the cap lies within the union of its
 * all-octave bounds and plod_detail_tail_range from this octave. */
int plod_planet_detail_first_octave_cap(const plod_planet *planet, const double axis[3],
                                        double angle);
/* Metres bounds of the planet's insets under a spherical cap (the blended
 * heights lie between the global data's and these; they tighten as the cap
 * shrinks) and, when relief is not NULL, how they vary there
 * (plod_insets_range_cap); 0 when none meets it. */
int plod_planet_insets_range_cap(const plod_planet *planet, const double axis[3],
                                 double angle, double *min_m, double *max_m,
                                 plod_insets_relief *relief);
/* The detail field's modulation at a unit direction (sampled where the
 * height map samples; 1 without a map, 0 without detail). */
double plod_planet_modulation(const plod_planet *planet, const double dir[3]);

#ifdef __cplusplus
}
#endif
#endif /* PLOD_PLANET_H */
