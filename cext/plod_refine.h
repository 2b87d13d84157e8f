/* plod_refine.h -- HRTMR (Hybrid Real-Time Mesh Refinement) split/merge
 * refinement of spherical triangle sectors, leaves only, implicit ids
 * (K. Gasiński, master's thesis, Gdańsk University of Technology, 2010,
 * sections 5.2-5.3).
 *
 * Cube-sphere: 12 base sectors, two per face, on the 8 cube corners; CAR:
 * 8 octahedron sectors in the octahedral square.  Split = longest-edge
 * bisection with forced splits across the split edge (conforming); merge =
 * a diamond of 4 sectors back into 2.  Incremental from frame to frame.
 * Implemented by lodtree.c (the tree: ids, stores, split and merge,
 * invariants; plod_sector_corners) and lodupdate.c (one frame's passes),
 * over the bounds and tests of bound.c (also plod_recommended_clip).
 */
#ifndef PLOD_REFINE_H
#define PLOD_REFINE_H

#include <stdint.h>
#include "plod_camera.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- sectors ------------------------------------------------------------ */

#define PLOD_MAX_LEVEL 52   /* deepest bisection level supported */

/* Value-type sector (<= 64 bytes).  Corners are dyadic face coordinates
 * u = cu / 2^PLOD_COORD_BITS on `face` (octahedral square for CAR), in
 * counter-clockwise order seen from outside the planet; corner 1 is the
 * right-angle apex, edge 0-2 the longest edge. */
#define PLOD_COORD_BITS 28
typedef struct plod_sector {
    uint64_t id;          /* base index (4 bits) << 56 | bisection path */
    int32_t cu[3], cv[3]; /* corner face coordinates, fixed point */
    float height_min;     /* metres, over the sector (conservative) */
    float height_max;
    uint32_t birth;       /* refine frame in which it was created */
    uint16_t flags;       /* PLOD_SECTOR_* */
    uint8_t face;
    uint8_t level;        /* bisection depth, 0 = base sector */
} plod_sector;

enum {
    PLOD_SECTOR_VISIBLE = 1u << 0,   /* passed every enabled test */
    PLOD_SECTOR_BACKFACING = 1u << 1,
    PLOD_SECTOR_OUTSIDE_FRUSTUM = 1u << 2,
    PLOD_SECTOR_OVER_BUDGET = 1u << 3,
    PLOD_SECTOR_SEA = 1u << 4        /* all heights at sea level */
};

/* ---- parameters and statistics --------------------------------------------- */

typedef enum plod_criterion {
    PLOD_CRITERION_PIXEL_ERROR = 0, /* screen-space error in pixels */
    PLOD_CRITERION_SIDE_DISTANCE    /* Gasiński: side / distance borders */
} plod_criterion;

typedef struct plod_refine_params {
    plod_criterion criterion;
    double max_pixel_error;  /* pixels, default 1 */
    double split_border;     /* side/distance, default 0.5 */
    double merge_border;     /* default 0.25, in (0, split_border]; used
                                only with hysteresis */
    int hysteresis;          /* 0 (renders): the result is a function of the
                                camera and parameters alone, whatever frames
                                came before.  1 (viewport): a split node
                                whose parent still wants its split, that is
                                not culled and below max_level, keeps its
                                children while its score (pixel error /
                                max_pixel_error, or size / distance /
                                split_border) stays at or above
                                merge_border / split_border, together with
                                the forced splits those children need; all
                                else equals the result without hysteresis */
    int template_level;      /* 0..7: 4^level triangles per sector */
    int max_level;           /* <= PLOD_MAX_LEVEL */
    size_t budget;           /* max sectors kept (visible or not), 0 =
                                unlimited: over it the split threshold
                                rises in steps of sqrt 2 until the whole
                                refinement fits (the smallest such step:
                                unique, so without hysteresis still a
                                function of the camera alone); only if even
                                the coarsest step does not fit are the
                                farthest visible sectors flagged
                                PLOD_SECTOR_OVER_BUDGET */
    int backface_culling;
    int frustum_culling;
    int skip_sea;            /* drop PLOD_SECTOR_SEA sectors from visible */
    size_t max_sectors;      /* hard cap on leaves (memory bound), >= 12;
                                default PLOD_DEFAULT_MAX_SECTORS; when
                                reached the split pass stops
                                (stats.truncated) */
    int threads;             /* 1..PLOD_REFINE_MAX_THREADS, default 1: threads
                                that evaluate the leaves' predicates and
                                flags of large sector sets (>= 2048 leaves;
                                the node sweep stays sequential), the
                                refiner's persistent workers; result
                                identical to 1 */
    size_t max_splits;       /* 0 (default): unlimited.  Progressive
                                refinement (the viewport): an update makes at
                                most this many splits (stats.splits: 2 per
                                diamond, forced ones included; at least one
                                diamond, so updates always progress),
                                and splits breadth first (every leaf that
                                wants it once per sweep, so the whole view
                                gains a level before any part gains two);
                                where the limit stops it, stats.pending is
                                set and later updates carry on from there.
                                The budget then caps the pass at a
                                coarsening step that later updates walk, a
                                step each, to the one that fits (coarser
                                where the budget binds, finer where it may
                                fit), pending while it moves.  The result
                                depends on the updates before: the
                                viewport's, never a render's */
} plod_refine_params;

#define PLOD_REFINE_MAX_THREADS 16

#define PLOD_DEFAULT_MAX_SECTORS ((size_t)1 << 20)

void plod_refine_params_default(plod_refine_params *params);
/* PLOD_OK, or PLOD_ERR_BAD_PARAM with *error (may be NULL) naming the rule
 * a parameter breaks (criterion, pixel error, borders, template and tree
 * levels, sector limit, threads): what plod_refiner_update and the other
 * LOD methods refuse. */
plod_status plod_refine_params_check(const plod_refine_params *params, plod_error *error);

typedef struct plod_refine_stats {
    size_t sectors_total;
    size_t sectors_after_backface;
    size_t sectors_after_frustum;
    size_t sectors_after_budget;  /* = visible (after sea skipping) */
    size_t sectors_sea_skipped;
    size_t splits, merges;
    double refine_us, cull_us;
    int max_level_reached;
    int truncated;                /* 1: max_sectors stopped the split pass */
    int pending;                  /* 1: max_splits stopped it, or the
                                     budget's step moved: refine again */
    unsigned frame;               /* refine frame counter (sector.birth) */
} plod_refine_stats;

/* ---- the refiner: create / destroy, one frame, queries ---------------------- */

typedef struct plod_refiner plod_refiner; /* opaque */

/* The planet (and its height map) is borrowed and must outlive the refiner.
 * *out is NULL on failure: PLOD_ERR_NULL, plod_planet_check's statuses,
 * PLOD_ERR_NO_MEMORY.  Destroy with plod_refiner_destroy (NULL: no-op). */
plod_status plod_refiner_create(plod_refiner **out, const plod_planet *planet);
void plod_refiner_destroy(plod_refiner *refiner);
/* Room for `sectors` leaf sectors (the leaves with their neighbour links,
 * the internal nodes, the pending and deferred splits, the merge
 * candidates and the visible order) allocated now, and all but the visible order
 * touched, so that plod_refiner_update does not grow its arrays, or fault
 * in fresh pages, until the set exceeds it: a planet's first descent then
 * runs at steady-state cost.  Never shrinks (reset
 * keeps the capacity).  PLOD_ERR_BAD_PARAM above PLOD_REFINER_MAX_RESERVE,
 * PLOD_ERR_NO_MEMORY (the leaves unchanged, the refiner usable) if it
 * cannot; PLOD_ERR_NULL for a NULL refiner. */
#define PLOD_REFINER_MAX_RESERVE ((size_t)1 << 26)
plod_status plod_refiner_reserve(plod_refiner *refiner, size_t sectors);
/* Back to the base sectors. */
void plod_refiner_reset(plod_refiner *refiner);
/* One frame: merge pass, split pass, culling; fills stats (may be NULL).
 * Without hysteresis the leaves, their flags and plod_refiner_visible()
 * equal those of a fresh refiner's first update at this camera, unless
 * max_sectors truncated either (stats.truncated).  Returns PLOD_ERR_NULL,
 * PLOD_ERR_BAD_PARAM (a parameter outside the ranges above; nothing
 * changed), PLOD_ERR_BAD_CAMERA (eye not finite or at the planet's centre;
 * nothing changed) or PLOD_ERR_NO_MEMORY (the visible order or the budget
 * cut could not be allocated: the leaves are this frame's, stats are not
 * written and the visible list is empty until a successful update).  The split pass itself never fails: when memory runs out it
 * stops as at max_sectors.  *error (may be NULL) gets the status and the rule
 * or reason of a failure. */
plod_status plod_refiner_update(plod_refiner *refiner, const plod_camera *camera,
                                const plod_refine_params *params,
                                plod_refine_stats *stats, plod_error *error);
/* The refiner's persistent workers (NULL with one thread): the refiner's
 * owner may lend them to other stages between updates, from the thread
 * that updates. */
plod_workers *plod_refiner_workers(const plod_refiner *refiner);
/* Every leaf sector (visible or not), valid until the next update/reset. */
const plod_sector *plod_refiner_sectors(const plod_refiner *refiner,
                                        size_t *count);
/* This frame's visible sectors as indices into plod_refiner_sectors(), in
 * canonical (depth-first) order: the same list for the same leaf set and
 * camera, whatever frames came before, so meshes emitted in this order are
 * byte-identical however the planet got there.  Valid until the next
 * update/reset. */
const uint32_t *plod_refiner_visible(const plod_refiner *refiner, size_t *count);
/* Unit directions of a sector's corners, bit-identical wherever two sectors
 * share a corner. */
void plod_sector_corners(const plod_planet *planet, const plod_sector *sector,
                         double corners[3][3]);

/* ---- memory, invariants ------------------------------------------------------ */

/* Bytes held by the refiner (sector records, per-leaf bounds, corners and
 * neighbour links, internal-node table, split queue, deferred splits and
 * split marks, visible order), capacities included; 0 for NULL. */
size_t plod_refiner_memory_bytes(const plod_refiner *refiner);

/* ---- split morph (F. Strugar, "Continuous Distance-Dependent Level of
 * Detail for Rendering Heightmaps", 2009, carried to longest-edge
 * bisection and composed over every level still morphing) ---------------
 * A diamond D (two parents split together) gives its four children one
 * factor m_D: 1 where the children look exactly like their parents, 0
 * where they are their own surface.  m_D follows D's reach e_D, the larger
 * of D's split score and the reach of every split diamond below that needs
 * D split (a forced split takes its forcer's): e_D crosses 1 exactly where
 * D splits or merges, and m_D = 1 - log(e_D) / log(PLOD_SPLIT_MORPH_RANGE),
 * clamped to [0, 1].  A split's scores are those of the refinement's P*
 * (plod_bound_score at the bound's distance, capped by the ancestors').  So
 * each diamond morphs over the same ratio of distance whatever its children
 * do, and where the scores fall slowly with the level, many levels morph at
 * once: a leaf's vertex on the grid of its ancestor j levels up but off
 * the grid of the next one blends by the factor of that next ancestor's
 * diamond toward the middle of its edge through the vertex, whose ends
 * blend in turn (plod_mesh_sector.split).  A leaf lists
 * PLOD_SPLIT_MORPH_STAGES ancestors at most; a diamond further up does not
 * blend its vertices (its reach under the range means the scores fell by
 * less than 2.2 % a level, 1.7^(1/24), over all the levels between).  A
 * function of the tree, the camera and the parameters alone. */
#define PLOD_SPLIT_MORPH_RANGE 1.7
#define PLOD_SPLIT_MORPH_STAGES 24 /* ancestors a leaf blends through */

typedef struct plod_split_morph_stage {
    double factor;          /* m of this ancestor's diamond in [0, 1] */
    double third_corner[3]; /* unit direction of the ancestor's corner the
                               one below it lacks (plod_sector_corners) */
    int child;              /* which child of this ancestor the one below it
                               is: 0 = corners (corner 1, midpoint, corner
                               0), 1 = (corner 2, midpoint, corner 1) */
} plod_split_morph_stage;

typedef struct plod_split_morph {
    int stages; /* ancestors listed, parent first: up to the last whose
                   factor is above 0 (0 for a base sector or where none is) */
    plod_split_morph_stage stage[PLOD_SPLIT_MORPH_STAGES];
} plod_split_morph;

/* The split morph of `count` leaves (indices into plod_refiner_sectors, or
 * 0..count-1 when `leaves` is NULL) for `camera` and `params` (those of the
 * last update: the tree is theirs) into out[0..count-1].  Scores every
 * node and leaf once.  PLOD_ERR_NULL, PLOD_ERR_BAD_COORD for a camera at
 * the planet's centre or not finite, PLOD_ERR_BAD_PARAM for an index out of
 * range, PLOD_ERR_NO_MEMORY. */
plod_status plod_refiner_split_morphs(const plod_refiner *refiner, const plod_camera *camera,
                                      const plod_refine_params *params,
                                      const uint32_t *leaves, size_t count,
                                      plod_split_morph *out);

/* Verifies the internal invariants (neighbour links match the leaves'
 * edges both ways, every edge shared by two leaves within one level,
 * internal nodes = leaves - base sectors, parent and diamond-partner
 * links, cached corners and heights equal to fresh ones, no split left
 * waiting for its children's bounds).  PLOD_OK, PLOD_ERR_BAD_PARAM when one
 * fails, PLOD_ERR_NULL, or PLOD_ERR_NO_MEMORY (its scratch array); O(leaves
 * + nodes).  For tests. */
plod_status plod_refiner_check(const plod_refiner *refiner);

/* ---- clip range (bound.c) ----------------------------------------------------- */

/* Horizon-distance correction: recommended clip range for a camera. */
void plod_recommended_clip(const plod_planet *planet, const plod_camera *camera,
                           double *clip_start, double *clip_end);

#ifdef __cplusplus
}
#endif
#endif /* PLOD_REFINE_H */
