/* plod_detail.h -- procedural detail below the height map's resolution.
 *
 * The planet's surface is the height map plus a deterministic detail field
 * D(d) = m(d) * N(d) of the unit direction d:
 *   - N is a sum of band-limited octaves i = 0..count-1 of wavelength
 *     largest * 2^-i (down to `smallest`) and amplitude amplitude *
 *     roughness^i (fine_roughness per octave below `fine_below`), each a 3-D lattice function of the direction (gradient
 *     noise, ridged noise, impact craters) evaluated on the unit sphere in
 *     double precision: no seams at cube faces, poles or the date line.
 *     Lattice points are hashed with the seed (64-bit integer hash); only
 *     + - * / floor sqrt are used, so the field is the same bits on every
 *     machine and thread count (with -ffp-contract=off).
 *   - m in [0, 1] is the modulation map, built once from the height map: 0
 *     on texels at or below sea level, `plains` on flat land (local
 *     relief r, the largest height step to the 8 neighbouring texels, up to
 *     a third of `relief` metres) rising to `hills` where r reaches
 *     `relief`; with `highlands` > 0
 *     it rises on from `hills` towards 1 with the height above the sea
 *     (1 at `highlands` metres), gated by the map's steepness (none below
 *     r = relief, all from r = 5 relief): high, steep ranges get the
 *     strongest relief, high plateaus stay hills.  Real relief follows
 *     that pattern: local relief in ~10 km windows grows with elevation
 *     where the land is steep (E. H. Hammond, "Analysis of properties of
 *     land form geography", Annals of the AAG, 1964; D. R. Montgomery and
 *     M. T. Brandon, "Topographic controls on erosion rates in
 *     tectonically active mountain ranges", EPSL, 2002); bench/
 *     bench_relief.py compares the Earth preset with real DEMs.  On low
 *     coasts m is at most twice the height above the sea over the deepest
 *     value of N at 4,096 fixed directions (lowlands are not pushed under
 *     the sea; the bound of many octaves' sum is far deeper than the field
 *     ever reaches, and would flatten every lowland hill); sampled
 *     bilinearly at the height map's location, bounded over regions by its
 *     min/max pyramid.  Without a height map m = 1.
 * Styles (the octaves' shape):
 *   HILLS      gradient-noise fBm (K. Perlin, "Improving Noise", SIGGRAPH
 *              2002): rolling relief.
 *   MOUNTAINS  ridged multifractal (F. K. Musgrave, "Texturing and
 *              Modeling: A Procedural Approach", 1994/2003): each octave
 *              (1 - |n|)^2 weighted by the previous octave's signal, so
 *              ridges carry fine detail and valleys stay smooth, as on
 *              eroded ranges; centred on the signal's mean (~0.7), so
 *              the field does not lift the ranges it roughens.
 *   CRATERS    low hills plus impact craters: one lattice cell per octave
 *              holds at most one crater (bowl, raised rim, ejecta blanket
 *              falling off to zero inside the cell, so cells join
 *              seamlessly); a fixed chance per cell at every octave gives
 *              the power-law size-frequency distribution N(>D) ~ D^-2
 *              of crater populations in equilibrium.
 * `craters` adds the crater layer (weight) to any style.
 * Where finer data than the height map counts (an inset), the planet
 * starts the field there at a later octave (plod_detail_noise_from),
 * blended with the full field by the inset's weight (plod_planet.h).
 *
 * Every octave's unit range holds 0, so partial sums (the meshes'
 * band-limited octaves) stay inside the bounds of the full sum.
 */
#ifndef PLOD_DETAIL_H
#define PLOD_DETAIL_H

#include <stddef.h>
#include <stdint.h>

#include "plod_planet.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum plod_detail_style {
    PLOD_DETAIL_HILLS = 0,
    PLOD_DETAIL_MOUNTAINS,
    PLOD_DETAIL_CRATERS,
    PLOD_DETAIL_STYLE_COUNT
} plod_detail_style;

#define PLOD_DETAIL_MAX_OCTAVES 40

typedef struct plod_detail_params {
    plod_detail_style style;
    double amplitude;  /* metres: the first octave's amplitude at m = 1, >= 0 */
    double roughness;  /* amplitude ratio from one octave to the next, [0, 1) */
    double largest;    /* metres: first octave's wavelength; 0 = two height
                          map (or out-of-core map) texels, radius / 50
                          without a map */
    double smallest;   /* metres: no octave finer than this, > 0 */
    uint64_t seed;
    double craters;    /* crater layer weight, [0, 4] (CRATERS: >= 1 applies) */
    double crater_density; /* chance of a crater per lattice cell, [0, 1] */
    double plains;     /* modulation on flat land, [0, 1] */
    double relief;     /* metres of local map relief for modulation `hills`
                          (1 when highlands is 0); 0 = the 90th percentile
                          over land texels */
    double hills;      /* modulation of hills (local relief >= relief), [plains, 1] */
    double highlands;  /* metres above the sea at which steep highlands reach
                          modulation 1; 0 = no elevation term (hills is then
                          the top) */
    double fine_roughness; /* amplitude ratio to octaves of wavelength below
                              fine_below, [0, 1) */
    double fine_below; /* metres; 0 = roughness everywhere.  Relief of
                          kilometres needs a slow fall-off (roughness ~0.6),
                          but octaves much finer than a mesh cell add to the
                          pixel criterion's error: a fall-off of 0.5 or
                          faster there keeps the error proportional to the
                          cell, so refinement near the ground stays
                          bounded */
    double hills_fine; /* gain, >= 1, of the hills' band of octaves (wavelength
                          below hills_fine_below, down to hills_fine_to) where
                          the modulation is `hills` (1: none).  Real hills
                          are rougher at a kilometre for their relief over
                          ten than ranges are (the Jacksboro fault DEM: std
                          50 m in 1 km windows against 114 m in 10 km), so
                          one modulation of every octave cannot fit both */
    double hills_fine_below; /* metres; 0 = no band */
    double hills_fine_to;    /* metres: the band's octaves are of wavelength
                                >= this (0: down to the finest) */
} plod_detail_params;

/* Defaults: MOUNTAINS, amplitude 0 (set it), roughness 0.5, largest 0,
 * smallest 0.1 m, seed 0, craters 0, density 0.5, plains 0.15, relief 0,
 * hills 1, highlands 0, fine_roughness 0.5, fine_below 0, hills_fine 1,
 * hills_fine_below 0, hills_fine_to 0. */
void plod_detail_params_init(plod_detail_params *params);

/* Builds the field for `planet` (radius, projection, height map, height
 * scale and sea level are read now; the planet's own `detail` is ignored):
 * octave tables and the modulation map.  PLOD_ERR_NULL, PLOD_ERR_BAD_PARAM
 * for bad parameters, PLOD_ERR_NO_MEMORY; *out is NULL on failure.
 * Release with plod_detail_destroy (NULL: no-op). */
plod_status plod_detail_create(plod_detail **out, const plod_detail_params *params,
                               const plod_planet *planet);
void plod_detail_destroy(plod_detail *detail);

const plod_detail_params *plod_detail_get_params(const plod_detail *detail);
int plod_detail_octave_count(const plod_detail *detail);
double plod_detail_wavelength(const plod_detail *detail, int octave); /* metres */
/* The modulation map (NULL without a height map); same projection and
 * size as the height map, 1 channel u8. */
const plod_cubemap *plod_detail_modulation(const plod_detail *detail);
/* Non-zero when detail was built for this radius and height map. */
int plod_detail_matches(const plod_detail *detail, const plod_planet *planet);
/* A hash of everything the field depends on (for caches). */
uint64_t plod_detail_stamp(const plod_detail *detail);

/* N(d) summed over the first `octaves` octaves (clamped to the count) at
 * a unit direction, in metres before modulation; `gradient` (may be NULL)
 * gets its gradient in metres per unit of direction (3-D; project onto
 * the tangent plane for the slope per radian).  The crater layer's part of
 * the gradient leaves out the last PLOD_DETAIL_CRATER_NORMAL_LAG of those
 * octaves: a band kept for cells of a third of its finest wavelength holds
 * craters down to 0.08 wavelengths across, smaller than a cell, whose
 * walls' slopes sampled at single vertices speckle the shading; four
 * octaves on, the smallest span ~4 cells (their heights stay). */
#define PLOD_DETAIL_CRATER_NORMAL_LAG 4
double plod_detail_noise(const plod_detail *detail, const double dir[3], int octaves,
                         double gradient[3]);
/* plod_detail_noise at n directions (dirs: 3 n doubles): sums[k] bit for
 * bit plod_detail_noise(dirs + 3 k, octaves[k], NULL) and, when gradients
 * is not NULL, gradients + 3 k that of plod_detail_noise(dirs + 3 k,
 * gradient_octaves[k], gradient); one pass over the octaves for both. */
void plod_detail_noise_n(const plod_detail *detail, size_t n, const double *dirs,
                         const int *octaves, const int *gradient_octaves, double *sums,
                         double *gradients);
/* The field where height data resolves the first `first` octaves (an
 * inset finer than the global map): octaves first..octaves-1 alone, their
 * running state starting at `first` as at octave 0 (the ridged weights
 * unset), so nothing of the coarse octaves' pattern remains; 0 when
 * octaves <= first.  first 0: plod_detail_noise bit for bit. */
double plod_detail_noise_from(const plod_detail *detail, const double dir[3], int first,
                              int octaves, double gradient[3]);
/* plod_detail_noise_from at n directions, bit for bit per point (as
 * plod_detail_noise_n; first_octaves NULL: 0 everywhere, which is
 * plod_detail_noise_n). */
void plod_detail_noise_from_n(const plod_detail *detail, size_t n, const double *dirs,
                              const int *first_octaves, const int *octaves,
                              const int *gradient_octaves, double *sums, double *gradients);
/* plod_detail_noise_from_n, and when band_sums is not NULL per point the
 * hills' band's part of its sum (the running sum after the band's octaves
 * less the one before them, from the same pass: N's band octaves with
 * N's own ridged weights, nothing to evaluate again) and, with
 * gradients, band_gradients that of its gradient.  sums and gradients
 * bit for bit plod_detail_noise_from_n's. */
void plod_detail_noise_band_n(const plod_detail *detail, size_t n, const double *dirs,
                              const int *first_octaves, const int *octaves,
                              const int *gradient_octaves, double *sums, double *gradients,
                              double *band_sums, double *band_gradients);
/* The first octave of wavelength <= `wavelength` metres (the octave count
 * if none): where data of half that wavelength's texels leaves the field
 * to start. */
int plod_detail_first_octave_below(const plod_detail *detail, double wavelength);
/* Bounds of any partial sum of the octaves from `first` on, started fresh
 * there or not (plod_detail_noise_from): lo <= 0 <= hi, inside
 * plod_detail_noise_range. */
void plod_detail_tail_range(const plod_detail *detail, int first, double *lo, double *hi);
/* Octaves a mesh with cells of `cell` metres resolves: those of
 * wavelength >= PLOD_DETAIL_CELLS_PER_WAVE * cell. */
#define PLOD_DETAIL_CELLS_PER_WAVE 3.0
int plod_detail_octaves_for_cell(const plod_detail *detail, double cell);
/* Bounds of N over all octaves (any partial sum lies inside): lo <= 0 <= hi. */
void plod_detail_noise_range(const plod_detail *detail, double *lo, double *hi);
/* Bounds of N_k (any band limit k >= the octaves a cell of `cell` metres
 * keeps, the full field included) over the points within unit chord
 * `reach` of the unit direction `dir`: N of the coarse octaves at dir, +-
 * their largest change over the reach (per-octave slope bounds, each
 * capped by its range), plus the finer octaves' range; clamped to
 * plod_detail_noise_range.  Evaluates the coarse octaves at dir only when
 * that can beat the global range. */
void plod_detail_local_range(const plod_detail *detail, const double dir[3], double reach,
                             double cell, double *lo, double *hi);
/* Expected height error, per unit of modulation, of a mesh with cells of
 * `cell` metres against the field: the octaves it drops, and the
 * interpolation error of the ones it keeps, summed as independent errors
 * (root of the sum of squares: the octaves' phases are independent, and
 * the ridged octaves are weighted by the coarser ones, so their full
 * ranges never add up in one place).  Monotone in cell. */
double plod_detail_cell_error(const plod_detail *detail, double cell);
/* The same counting only the first `visible` octaves (clamped to the
 * count; <= 0: 0): neither the drop nor the interpolation error of the
 * finer ones.  Monotone in cell and in visible; plod_detail_cell_error at
 * visible >= the count. */
double plod_detail_cell_error_visible(const plod_detail *detail, double cell, int visible);
/* Octaves of wavelength >= `wavelength` metres (the first ones). */
int plod_detail_octaves_at_least(const plod_detail *detail, double wavelength);
/* The hills' band: octaves fine_first..fine_end-1 (wavelength below
 * hills_fine_below, down to hills_fine_to; none when hills_fine is 1).
 * Where the modulation is m the surface's detail is
 *   m N + (g(m) - m) B,
 * B N's own octaves of the band below the point's band limit (their
 * ridged weights N's: plod_detail_noise_band_n takes B from N's pass,
 * at no cost of its own), so the band's relief follows g(m) and the rest
 * m.  g is piecewise linear through (plains,
 * plains), (hills, min(1, hills_fine * hills)) and (1, 1), and m
 * elsewhere (below plains,
 * or with hills 1): g >= m, monotone, 1 at m = 1, so plains and the
 * steepest ranges keep their relief and hills get the band's gain.
 * After F. K. Musgrave's multifractals ("Texturing and Modeling: A
 * Procedural Approach", 2003), whose octaves' amplitudes follow the
 * local character of the terrain rather than one spectrum. */
int plod_detail_fine_first(const plod_detail *detail);
int plod_detail_fine_end(const plod_detail *detail);
double plod_detail_fine_modulation(const plod_detail *detail, double m);
/* max of g(m) - m over m in [m0, m1] (>= 0; 0 without a band), for
 * bounds and the refinement error. */
double plod_detail_fine_excess_max(const plod_detail *detail, double m0, double m1);
/* Bounds of B (any band limit >= the octaves a cell of `cell` metres
 * keeps) over the points within unit chord `reach` of `dir`, as
 * plod_detail_local_range (lo <= 0 <= hi is not promised); 0, 0 without a
 * band. */
void plod_detail_band_local_range(const plod_detail *detail, const double dir[3],
                                  double reach, double cell, double *lo, double *hi);
/* plod_detail_local_range and, when band_lo is not NULL, into band_lo,
 * band_hi plod_detail_band_local_range, both from one evaluation of the
 * coarse octaves (the same bounds, bit for bit). */
void plod_detail_local_ranges(const plod_detail *detail, const double dir[3], double reach,
                              double cell, double *lo, double *hi, double *band_lo,
                              double *band_hi);
/* PLOD_DETAIL_BAND_ERROR_SHARE times plod_detail_cell_error_visible
 * counting only the band's octaves (per unit of g - m): the error term of
 * the band's excess.  Monotone in cell and in visible. */
double plod_detail_cell_error_band(const plod_detail *detail, double cell, int visible);

/* The share of the hills' band's excess that the pixel criterion counts.
 * Over hills the band's relief of a kilometre shows as shading: light and
 * shadow on slopes that every vertex's normal carries exactly (the
 * analytic slope of the octaves its cell keeps), while the positions
 * between vertices only need to hold the silhouette.  Counted in full,
 * the band's four times stronger octaves asked for cells about half as
 * large across the view (2-3 times the sectors over hills, for the same
 * shading); a quarter asks for about 1.4 times (bench/RESULTS.md), and
 * every octave the cells keep still lies in the mesh's heights and
 * normals.  Bounds count the whole excess. */
#define PLOD_DETAIL_BAND_ERROR_SHARE 0.25

/* Pixels of wavelength below which an octave counts in no refinement
 * error (plod_bound.h): relief finer than that at its distance is below
 * the pixel, which no mesh draws (its triangles would alias it), and
 * steep fine octaves would otherwise cut cells of a pixel everywhere. */
#define PLOD_DETAIL_VISIBLE_WAVE_PIXELS 2.0

#ifdef __cplusplus
}
#endif
#endif /* PLOD_DETAIL_H */
