/* lodupdate.c -- the LOD update policy of HRTMR (Hybrid Real-Time Mesh
 * Refinement; K. Gasiński, "Porównanie metod wizualizacji terenu w czasie
 * rzeczywistym" (comparison of real-time terrain visualisation methods),
 * master's thesis, Gdańsk University of Technology, 2010, sections
 * 5.2-5.3): one frame's passes over the LOD tree (lodtree.c) with the
 * tests of bound.c, and the public refiner of plod_refine.h.
 *
 * Determinism: the raw split predicate P of a node is a pure function of the
 * node and the camera (its own bounding cap prism; heights from range
 * queries).  Caps of children do not nest in their parents' (projection
 * distortion), so P alone is not monotone; the refinement uses
 * P*(node) = P(node) and P*(parent), which is.  The tree keeps internal
 * nodes parents first, so one sequential sweep per frame gives P* of every
 * node top-down, skipping P where the parent already fails P*, and hands
 * each node's frustum plane mask to its children.  Each frame merges every
 * diamond whose two parents fail P*, then splits every leaf that passes it
 * (with forced splits), until stable: the unique minimal conforming
 * refinement of {P* true}, whatever the previous frame was.  With
 * `hysteresis` the merge test uses the merge border instead and the result
 * depends on history.
 *
 * Per-frame cost is the predicate of every node and leaf, so it is kept to
 * a few dot products (bounds hold cosines and sines, not angles; distance
 * thresholds are decided by square-root-free bounds where they clear them).
 * The values the tests read live in a frame context built by each update,
 * not in the refiner.  The update's state across the passes of a frame
 * (each leaf's evaluation, the split limits and which of them stopped a
 * split) is the refiner's, not the tree's: the tree takes the limits with
 * each split and reports the moves of its leaf slots to the refiner, which
 * keeps the evaluations in an array parallel to the leaves.
 */
#include "plod_lodtree.h"
#include "plod_platform.h"

#include <assert.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* the canonical order's radix sort (plod__order_visible): 11-bit digits */
#define PLOD__ORDER_BITS 11
#define PLOD__ORDER_DIGITS ((64 + PLOD__ORDER_BITS - 1) / PLOD__ORDER_BITS)
#define PLOD__ORDER_RADIX (1u << PLOD__ORDER_BITS)

/* A leaf's evaluation, cached for the frame it names. */
typedef struct plod__leaf_eval {
    uint32_t frame;
    uint8_t split; /* P(leaf) */
} plod__leaf_eval;

struct plod_refiner {
    plod_lodtree tree;
    /* per leaf slot, kept in step with the tree's slots (its observer):
     * the evaluation of this frame where its frame is the tree's */
    plod__leaf_eval *leaf_eval;
    size_t leaf_eval_capacity;
    /* this update's limits on the splits, and which of them stopped one */
    plod_lodtree_limits limits;
    int truncated;          /* limits.max_sectors (or memory) stopped a split */
    int limited;            /* limits.max_splits stopped a split */
    /* the budget search, from one update to the next */
    int coarsen_step;       /* the budget's step of the last update: where the
                               next update's search starts (never its result) */
    int budget_known;       /* coarsen_step is the answer for budget_camera and
                               budget_params (the same frame again) */
    plod_camera budget_camera;
    plod_refine_params budget_params;
    /* the progressive refreshes' walk to the budget's step, a step a refresh */
    int progressive_next;   /* the step the next progressive refresh refines at
                               (-1: coarsen_step) */
    int step_pending;       /* this refresh moved that step: refresh again */
    int finer_failed;       /* the step below coarsen_step overflowed the
                               budget for finer_failed_camera: not tried again */
    plod_camera finer_failed_camera;
    /* this frame's visible sectors in canonical order (plod__order_visible)
     * and their keys, from which the next frame's order starts */
    uint32_t *order;
    uint64_t *order_keys;
    size_t order_count, order_capacity;
    size_t order_sorted;         /* entries of order/order_keys that the last
                                    ordering left sorted (0: none) */
    uint32_t *scratch_index;     /* 3 * order_capacity: the kept, the new */
    uint64_t *scratch_keys;      /* and the radix sort's scratch lists */
    uint8_t *order_kept;         /* order_capacity: the last order's entries kept */
    /* per leaf slot, its entry in the last order and that entry's key
     * (UINT32_MAX: none): the ordering then reads the leaves in slot order
     * and writes only the refiner's arrays, not leaves the workers have
     * just written */
    uint32_t *order_position;
    uint64_t *position_key;
    size_t position_capacity;
    uint32_t order_counts[PLOD__ORDER_DIGITS][PLOD__ORDER_RADIX]; /* digit counts */
    /* the memos of the distance tests (plod_bound_memo): the thresholds
     * memo_key names, and the eye's path since it was issued */
    uint32_t memo_key;
    int memo_current;            /* 0: the next threshold issues a new key */
    int memo_split_mode;
    double memo_split_scale, memo_error_scale;
    double travelled, memo_eye[3];
    /* bit i: leaf i passed P when the leaves were evaluated (or a split
     * wrote a new leaf into slot i ahead of the split pass); the split
     * pass visits only these slots.  NULL: it visits every slot */
    uint64_t *split_marks;
    size_t split_mark_words;
    /* the nodes the last sweep found with two leaf children and failing
     * P* (the merge pass's candidates; see plod__merge_pass) */
    int32_t *merge_nodes;
    size_t merge_count, merge_capacity;
    int merge_listed;            /* 0: the list is incomplete (no memory) */
    plod_workers *workers;       /* params.threads - 1 of them, or NULL */
    int workers_for;             /* the params.threads they were started for */
};

/* One update's context: the tree it refines, its parameters and the
 * camera-derived values and thresholds its tests read. */
typedef struct plod__frame {
    plod_refiner *refiner;
    plod_lodtree *tree;
    const plod_refine_params *params;
    plod_bound_view view;
    double merge_ratio;     /* merge_border / split_border (hysteresis) */
} plod__frame;

/* ---- the predicate ------------------------------------------------------------ */

/* Split predicate P of a node (level = its level), from its own bound. */
static int plod__wants_split(const plod__frame *f, plod_bound *b, int level,
                             unsigned *flags, unsigned parent_planes, unsigned *planes)
{
    *flags = plod_bound_cull(&f->view, b, parent_planes, planes);
    if (level >= f->params->max_level || *flags)
        return 0;
    return plod_bound_exceeds_memo(&f->view, b);
}

/* The frustum planes node `parent`'s surface is inside of, this frame
 * (final once the node sweep, or a lazy evaluation, has visited it). */
static unsigned plod__parent_planes(const plod_lodtree *t, int32_t parent)
{
    return parent >= 0 ? t->node_planes[parent] : 0u;
}

/* P(node) of an internal node, as PLOD_NODE_P_KNOWN | P_TRUE bits; stores its
 * plane mask. */
static unsigned plod__node_p(const plod__frame *f, int32_t k, unsigned parent_planes)
{
    plod_lodtree *t = f->tree;
    plod_lodtree_node *n = &t->nodes[k];
    unsigned flags, planes;
    int p = plod__wants_split(f, &n->bound, plod_lodtree_id_level(n->id), &flags,
                              parent_planes, &planes);
    t->node_planes[k] = (uint8_t)planes;
    return PLOD_NODE_P_KNOWN | (p ? PLOD_NODE_P_TRUE : 0u);
}

/* P*(node) = P(node) and P*(parent): monotone by construction, so the
 * refinement it defines has a unique minimal conforming closure.  For an
 * internal node, memoised per frame. */
static int plod__node_wants(const plod__frame *f, int32_t k)
{
    plod_lodtree *t = f->tree;
    unsigned st = t->node_state[k];
    if (st & PLOD_NODE_STAR_KNOWN)
        return (st & PLOD_NODE_STAR_TRUE) != 0;
    if (!(st & PLOD_NODE_P_KNOWN))
        st |= plod__node_p(f, k, plod__parent_planes(t, t->node_parent[k]));
    int wants = (st & PLOD_NODE_P_TRUE) != 0;
    int32_t parent = t->node_parent[k];
    if (wants && parent >= 0) {
        assert(t->nodes[parent].id == plod_lodtree_parent_id(t->nodes[k].id));
        wants = plod__node_wants(f, parent);
    }
    t->node_state[k] = (uint8_t)(st | PLOD_NODE_STAR_KNOWN | (wants ? PLOD_NODE_STAR_TRUE : 0u));
    return wants;
}

/* Whether an internal node may be merged back (its children removed): the
 * tree's merge policy (plod_lodtree_merge_fn). */
static int plod__allows_merge(void *context, int32_t k)
{
    const plod__frame *f = context;
    const plod_lodtree *t = f->tree;
    if (!f->params->hysteresis)
        return !plod__node_wants(f, k);
    const plod_lodtree_node *n = &t->nodes[k];
    int level = plod_lodtree_id_level(n->id);
    if (t->node_parent[k] >= 0 && !plod__node_wants(f, t->node_parent[k]))
        return 1;
    unsigned planes;
    unsigned flags = plod_bound_cull(&f->view, &n->bound, 0, &planes);
    return flags || level >= f->params->max_level ||
           plod_bound_score(&f->view, &n->bound, plod_bound_distance(&f->view, &n->bound)) <
               f->merge_ratio;
}

/* A leaf's flags from its culling flags: sea (every height at sea level),
 * visible (not culled, and not sea skipped). */
static uint16_t plod__leaf_flags(const plod__frame *f, const plod_sector *sec, unsigned cull)
{
    const plod_planet *planet = f->tree->planet;
    unsigned flags = cull;
    int sea = planet->has_sea_level && sec->height_max <= planet->sea_level;
    if (sea)
        flags |= PLOD_SECTOR_SEA;
    if (!cull && !(sea && f->params->skip_sea))
        flags |= PLOD_SECTOR_VISIBLE;
    return (uint16_t)flags;
}

/* P(leaf), cached for this frame, and the leaf's flags (culling, sea,
 * visible); returns P.  A pure function of the bound, the camera and the
 * parent's plane mask (whose bits change which planes are tested, not the
 * result). */
static int plod__eval_leaf(const plod__frame *f, size_t i)
{
    plod_lodtree *t = f->tree;
    plod__leaf_eval *e = &f->refiner->leaf_eval[i];
    unsigned flags, planes;
    e->split = (uint8_t)plod__wants_split(f, &t->geom[i].self, t->leaves[i].level, &flags,
                                          plod__parent_planes(t, t->leaf_parent[i]), &planes);
    e->frame = t->frame;
    t->leaves[i].flags = plod__leaf_flags(f, &t->leaves[i], flags);
    return e->split;
}

/* P*(leaf), caching P(leaf) and its cull flags for this frame. */
static int plod__leaf_wants_split(const plod__frame *f, size_t i)
{
    plod_lodtree *t = f->tree;
    const plod__leaf_eval *e = &f->refiner->leaf_eval[i];
    if (e->frame != t->frame)
        plod__eval_leaf(f, i);
    int32_t parent = t->leaf_parent[i];
    if (!e->split || parent < 0)
        return e->split;
    assert(t->nodes[parent].id == plod_lodtree_parent_id(t->leaves[i].id));
    return plod__node_wants(f, parent);
}

/* ---- the leaves' evaluation ----------------------------------------------------- */

/* P and flags of leaves [begin, end) (begin a multiple of 64), written to
 * their own slots, and their words of the split marks: pure functions
 * of the bounds, the camera and the parents' plane masks (final after the
 * node sweep), so any split of the work gives the bits of the lazy
 * single-threaded evaluation.  The node sweep itself stays sequential:
 * top-down, a node's plane mask spares its children most plane tests,
 * which a split by index range would lose. */
static void plod__eval_range(void *context, size_t begin, size_t end)
{
    const plod__frame *f = context;
    uint64_t *marks = f->refiner->split_marks;
    for (size_t first = begin; first < end; first += 64) {
        size_t last = end - first < 64 ? end : first + 64;
        uint64_t word = 0;
        for (size_t i = first; i < last; i++)
            word |= (uint64_t)(plod__eval_leaf(f, i) != 0) << (i - first);
        if (marks)
            marks[first / 64] = word;
    }
}

/* Room for the split marks of `count` leaves. */
static plod_status plod__marks_reserve(plod_refiner *r, size_t count)
{
    size_t words = count / 64 + 1;
    if (words <= r->split_mark_words)
        return PLOD_OK;
    uint64_t *fresh = plod_grow(r->split_marks, &r->split_mark_words, words, sizeof *fresh, 64);
    if (!fresh)
        return PLOD_ERR_NO_MEMORY;
    r->split_marks = fresh;
    return PLOD_OK;
}

/* Every leaf's P and flags, after the merges (the leaves they restored
 * included) and before the splits; on the refiner's workers from
 * PLOD__PARALLEL_LEAVES leaves (below, handing chunks over would eat the
 * gain), in chunks of whole mark words. */
#define PLOD__PARALLEL_LEAVES 2048
#define PLOD__PARALLEL_GRAIN 512

static void plod__eval_leaves(plod__frame *f)
{
    size_t count = f->tree->count;
    plod_refiner *r = f->refiner;
    if (plod__marks_reserve(r, count) != PLOD_OK) {
        /* without them the split pass visits every slot: the same result */
        free(r->split_marks);
        r->split_marks = NULL;
        r->split_mark_words = 0;
    }
    plod_workers_for(count >= PLOD__PARALLEL_LEAVES ? r->workers : NULL, count,
                     PLOD__PARALLEL_GRAIN, plod__eval_range, f);
}

/* Workers for params->threads, started once (and again when the count
 * changes); none when they cannot start: the result is the same. */
static void plod__ready_workers(plod_refiner *r, int threads)
{
    if (r->workers_for != threads) {
        plod_workers_destroy(r->workers);
        r->workers = NULL;
        r->workers_for = threads;
        if (threads >= 2 && plod_workers_create(&r->workers, threads) != PLOD_OK)
            r->workers = NULL;
    }
    plod_workers_begin(r->workers); /* until the classification: they spin */
}

/* ---- one refinement pass; the budget ---------------------------------------------- */

/* Drops every bound's memo (before the memo keys wrap around). */
static void plod__forget_memos(plod_lodtree *t)
{
    for (size_t i = 0; i < t->count; i++)
        t->geom[i].self.memo.key = 0;
    for (size_t k = 0; k < t->node_top; k++)
        t->nodes[k].bound.memo.key = 0;
}

/* The split thresholds of coarsening step `step`: the criterion's threshold
 * times 2^(step / 2) (pixel error, or split border). */
static void plod__view_threshold(plod_bound_view *v, const plod_refine_params *params,
                                 int step)
{
    v->coarsening = ldexp(step & 1 ? PLOD_SQRT2 : 1.0, step >> 1);
    if (params->criterion == PLOD_CRITERION_SIDE_DISTANCE) {
        v->split_mode = 0;
        v->split_scale = params->split_border * v->coarsening;
    } else if (!v->camera->desc.orthographic) {
        v->split_mode = 1;
        v->split_scale = v->camera->pixels_per_radian / (params->max_pixel_error * v->coarsening);
    } else {
        v->split_mode = 2;
        v->split_scale = v->camera->pixels_per_metre / (params->max_pixel_error * v->coarsening);
    }
}

static void plod__set_threshold(plod__frame *f, int step)
{
    const plod_refine_params *params = f->params;
    plod_bound_view *v = &f->view;
    plod__view_threshold(v, params, step);
    /* other thresholds than the memos were made under: a new key, whose
     * path starts here */
    plod_refiner *r = f->refiner;
    if (!r->memo_current || r->memo_split_mode != v->split_mode ||
        r->memo_split_scale != v->split_scale || r->memo_error_scale != v->error_scale) {
        if (r->memo_key == UINT32_MAX)
            plod__forget_memos(f->tree); /* the keys start again */
        r->memo_key = r->memo_key == UINT32_MAX ? 1 : r->memo_key + 1;
        r->memo_current = 1;
        r->memo_split_mode = v->split_mode;
        r->memo_split_scale = v->split_scale;
        r->memo_error_scale = v->error_scale;
        r->travelled = 0.0;
        memcpy(r->memo_eye, v->eye, sizeof r->memo_eye);
    }
    v->memo_key = r->memo_key;
    v->travelled = r->travelled;
}

/* The eye's path length since the memos' key was issued, rounded up (a
 * step below half a unit in the last place still advances it). */
static void plod__travel(plod_refiner *r, const double eye[3])
{
    double d[3] = {eye[0] - r->memo_eye[0], eye[1] - r->memo_eye[1], eye[2] - r->memo_eye[2]};
    double step = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (!(step < INFINITY))
        r->memo_current = 0; /* overflowed: a new key, a new path */
    else if (step > 0.0)
        r->travelled = nextafter(r->travelled + step * (1.0 + 1e-9), INFINITY);
    memcpy(r->memo_eye, eye, sizeof r->memo_eye);
}

/* Room for `count` merge candidates. */
static plod_status plod__merge_reserve(plod_refiner *r, size_t count)
{
    if (count <= r->merge_capacity)
        return PLOD_OK;
    int32_t *fresh = plod_grow(r->merge_nodes, &r->merge_capacity, count, sizeof *fresh, 256);
    if (!fresh)
        return PLOD_ERR_NO_MEMORY;
    r->merge_nodes = fresh;
    return PLOD_OK;
}

/* Appends node k to the merge candidates (or marks the list incomplete). */
static void plod__list_merge_node(plod_refiner *r, int32_t k)
{
    if (r->merge_count == r->merge_capacity &&
        plod__merge_reserve(r, r->merge_count + 1) != PLOD_OK) {
        r->merge_listed = 0;
        return;
    }
    r->merge_nodes[r->merge_count++] = k;
}

/* P* of every internal node in one sequential, top-down sweep (parents come
 * first); P is evaluated only where the parent passes P*.  Lists the nodes
 * with two leaf children that fail P*: without hysteresis the only merges
 * that can start. */
static void plod__sweep(plod__frame *f, int step)
{
    plod_lodtree *t = f->tree;
    plod_refiner *r = f->refiner;
    t->frame++;
    plod__set_threshold(f, step);
    plod_lodtree_compact(t);
    r->merge_count = 0;
    r->merge_listed = 1;
    for (size_t k = 0; k < t->node_top; k++) {
        if (!t->nodes[k].id) {
            t->node_state[k] = 0;
            continue;
        }
        int32_t parent = t->node_parent[k];
        if (parent >= 0 && !(t->node_state[parent] & PLOD_NODE_STAR_TRUE)) {
            t->node_state[k] = PLOD_NODE_STAR_KNOWN; /* P* false, P not needed */
            t->node_planes[k] = 0;
        } else {
            unsigned pk = plod__node_p(f, (int32_t)k, plod__parent_planes(t, parent));
            t->node_state[k] = (uint8_t)((pk & (PLOD_NODE_P_KNOWN | PLOD_NODE_P_TRUE)) |
                                         PLOD_NODE_STAR_KNOWN |
                                         ((pk & PLOD_NODE_P_TRUE) ? PLOD_NODE_STAR_TRUE : 0u));
        }
        if (t->node_leaves[k] == 2 && !(t->node_state[k] & PLOD_NODE_STAR_TRUE))
            plod__list_merge_node(r, (int32_t)k);
    }
}

/* The merge pass: every diamond whose parents fail the split predicate;
 * merges cascade upwards as subtrees collapse.  Without hysteresis it
 * starts from the sweep's candidates (a diamond can merge only if both its
 * parents have two leaf children and fail P*; the merges each one starts
 * try the diamonds above); the result does not depend on the order.  With
 * hysteresis (or no list) it goes down the leaves, so the leaves moved
 * into holes were already visited. */
static void plod__merge_pass(plod__frame *f)
{
    plod_lodtree *t = f->tree;
    plod_refiner *r = f->refiner;
    if (!f->params->hysteresis && r->merge_listed) {
        for (size_t c = r->merge_count; c-- > 0;) {
            int32_t pi = r->merge_nodes[c];
            if (!t->nodes[pi].id || t->node_leaves[pi] != 2)
                continue; /* merged, or split below, since it was listed */
            int32_t qi = t->node_partner[pi];
            if (t->node_leaves[qi] != 2 ||
                ((t->node_state[pi] | t->node_state[qi]) & PLOD_NODE_STAR_TRUE))
                continue;
            plod_lodtree_try_merge(t, (size_t)t->node_child0[pi], plod__allows_merge, f);
        }
        return;
    }
    for (size_t i = t->count; i-- > 0;) {
        if (i >= t->count)
            i = t->count - 1;
        /* plod_lodtree_try_merge's first tests, inline: most leaves fail them */
        int32_t pi = t->leaf_parent[i];
        if (pi < 0 || t->node_leaves[pi] != 2)
            continue;
        int32_t qi = t->node_partner[pi]; /* its diamond must merge too */
        if (t->node_leaves[qi] != 2)
            continue;
        if (!f->params->hysteresis &&
            ((t->node_state[pi] | t->node_state[qi]) & PLOD_NODE_STAR_TRUE))
            continue;
        plod_lodtree_try_merge(t, i, plod__allows_merge, f);
    }
}

/* plod_lodtree_split under this update's limits, noting which stopped it. */
static void plod__split(const plod__frame *f, size_t i)
{
    plod_refiner *r = f->refiner;
    int done = plod_lodtree_split(f->tree, i, &r->limits);
    if (done == PLOD_LODTREE_SPLIT_CAPPED)
        r->truncated = 1;
    else if (done == PLOD_LODTREE_SPLIT_LIMITED)
        r->limited = 1;
}

/* Deferred splits (plod_lodtree_defer) settled in parallel: a wave's jobs
 * from PLOD__PARALLEL_JOBS on, in chunks of PLOD__JOB_GRAIN (a job, two
 * bounds and their evaluation, takes about half a microsecond). */
#define PLOD__PARALLEL_JOBS 64
#define PLOD__JOB_GRAIN 32

typedef struct plod__wave {
    const plod__frame *frame;
    size_t first; /* the wave's first job */
} plod__wave;

/* Settles the wave's jobs [first + begin, first + end) and evaluates their
 * children: each writes only its own children's slots. */
static void plod__settle_range(void *context, size_t begin, size_t end)
{
    const plod__wave *wave = context;
    plod_lodtree *t = wave->frame->tree;
    for (size_t j = wave->first + begin; j < wave->first + end; j++) {
        if (!plod_lodtree_settle(t, j))
            continue; /* a split settled it on demand */
        plod__eval_leaf(wave->frame, plod_lodtree_job_child(t, j, 0));
        plod__eval_leaf(wave->frame, plod_lodtree_job_child(t, j, 1));
    }
}

/* Splits the leaf at slot i if it is settled and passes P*. */
static void plod__visit(const plod__frame *f, size_t i)
{
    plod_lodtree *t = f->tree;
    if (t->leaf_job[i] < 0 && plod__leaf_wants_split(f, i))
        plod__split(f, i);
}

/* The split pass in waves: the marked leaves that pass P* split, their
 * children's bounds are deferred; the wave's jobs are settled and their
 * children evaluated on the workers; the children that pass P* make the
 * next wave.  A slot whose leaf is unsettled when visited is visited again
 * as a child of its job.  Every leaf that passes P* splits (and the forced
 * splits a conforming tree needs), so the leaves are the same as the
 * depth-first pass's, in other slots. */
static void plod__split_waves(plod__frame *f)
{
    plod_lodtree *t = f->tree;
    const plod_refiner *r = f->refiner;
    const uint64_t *marks = r->split_marks;
    plod_lodtree_defer(t, 1);
    size_t swept = t->count;
    for (size_t w = 0; w * 64 < swept && !r->truncated; w++)
        for (uint64_t bits = marks[w]; bits && !r->truncated; bits &= bits - 1)
            plod__visit(f, w * 64 + (size_t)__builtin_ctzll(bits));
    for (size_t first = 0; first < t->job_count;) {
        size_t last = t->job_count;
        plod__wave wave = {f, first};
        plod_workers_for(last - first >= PLOD__PARALLEL_JOBS ? f->refiner->workers : NULL,
                         last - first, PLOD__JOB_GRAIN, plod__settle_range, &wave);
        for (size_t j = first; j < last && !r->truncated; j++) {
            plod__visit(f, plod_lodtree_job_child(t, j, 0));
            if (!r->truncated)
                plod__visit(f, plod_lodtree_job_child(t, j, 1));
        }
        first = last;
    }
    plod_lodtree_defer(t, 0);
    t->pending_count = 0;
}

/* Splits leaf i while it passes P* (and the split happens). */
static void plod__split_leaf(const plod__frame *f, size_t i)
{
    plod_lodtree *t = f->tree;
    const plod_refiner *r = f->refiner;
    while (!r->truncated && !r->limited && plod__leaf_wants_split(f, i)) {
        size_t before = t->splits;
        plod__split(f, i);
        if (t->splits == before)
            break; /* at PLOD_MAX_LEVEL or truncated */
    }
}

/* The split pass: one sweep (children appended at the end are swept too);
 * children written in place of earlier leaves are revisited after.  The
 * sweep visits only the slots the evaluation marked, and those a split
 * wrote a child into ahead of it: at every other slot a sweep over all of
 * them would find a leaf that fails P, so the splits are the same, in the
 * same order. */
static void plod__split_pass(plod__frame *f)
{
    plod_lodtree *t = f->tree;
    const plod_refiner *r = f->refiner;
    t->pending_count = 0;
    /* waves, unless a cap may stop the pass where the order of the splits
     * decides which were made and hysteresis carries that to later frames */
    if (!r->limits.max_splits && r->split_marks &&
        (!f->params->hysteresis || r->limits.max_sectors >= f->params->max_sectors)) {
        plod__split_waves(f);
        return;
    }
    if (r->limits.max_splits) { /* progressive: breadth first (plod_refine_params) */
        for (int again = 1; again && !r->truncated && !r->limited;) {
            again = 0;
            size_t swept = t->count; /* children appended now wait for the next sweep */
            for (size_t i = 0; i < swept && !r->truncated && !r->limited; i++) {
                if (!plod__leaf_wants_split(f, i))
                    continue;
                size_t before = t->splits;
                plod__split(f, i);
                again |= t->splits != before;
            }
        }
        t->pending_count = 0;
        return;
    }
    uint64_t *marks = r->split_marks;
    size_t swept = 0;
    if (marks) {
        swept = t->count;
        for (size_t w = 0; w * 64 < swept && !r->truncated; w++) {
            while (marks[w] && !r->truncated) {
                size_t i = w * 64 + (size_t)__builtin_ctzll(marks[w]);
                marks[w] &= marks[w] - 1;
                size_t queued = t->pending_count;
                plod__split_leaf(f, i);
                for (size_t k = queued; k < t->pending_count; k++) {
                    size_t at = t->pending[k];
                    if (at > i && at < swept)
                        marks[at / 64] |= (uint64_t)1 << (at % 64);
                }
            }
        }
    }
    for (size_t i = swept; i < t->count && !r->truncated; i++)
        plod__split_leaf(f, i);
    while (t->pending_count && !r->truncated)
        plod__split_leaf(f, t->pending[--t->pending_count]);
}

/* One pass at coarsening step `step`: merges every diamond whose parents fail
 * P*, then splits every leaf that passes it, stopping (truncated) before the
 * leaves would exceed `cap`.  Untruncated, the result is the unique minimal
 * conforming refinement of {P* true} whatever the refinement was before. */
static void plod__refine_pass(plod__frame *f, int step, size_t cap)
{
    plod__sweep(f, step);
    f->refiner->limits.max_sectors = cap;
    f->refiner->truncated = 0;
    plod__merge_pass(f);
    plod__eval_leaves(f);
    plod__split_pass(f);
}

/* Coarsening steps the budget may take: 2^(64 / 2) times the threshold
 * leaves nothing but the base mesh split. */
#define PLOD__MAX_COARSEN_STEP 64

/* Whether step `step`'s refinement keeps at most `budget` sectors (visible
 * or not); leaves the refiner at it (truncated when it does not fit). */
static int plod__fits(plod__frame *f, int step)
{
    const plod_refine_params *params = f->params;
    size_t cap = params->budget < params->max_sectors ? params->budget + 1 : params->max_sectors;
    plod__refine_pass(f, step, cap);
    return !f->refiner->truncated && f->tree->count <= params->budget;
}

/* A lower bound of the sectors step `step` keeps, from the current
 * refinement of a coarser step (a subset of step's, the thresholds being
 * monotone): every leaf that step splits adds at least one sector. */
static size_t plod__sectors_at_least(plod__frame *f, int step)
{
    plod__sweep(f, step);
    size_t n = f->tree->count;
    for (size_t i = 0; i < f->tree->count; i++)
        n += plod__leaf_wants_split(f, i) != 0;
    return n;
}

/* The budget coarsens the whole refinement instead of dropping sectors: the
 * result is the refinement of the smallest coarsening step (threshold times
 * 2^(step / 2)) that keeps at most `budget` sectors.  The sector count only
 * falls as the step grows (thresholds only rise, P* sets only shrink), so
 * that step is unique: a function of the camera and the parameters alone,
 * not of the step the search starts from (the last update's, for speed).
 * Visible sectors are a subset, so they fit too; only when even the coarsest
 * step keeps more sectors than the budget does the nearest-first cut after
 * culling apply. */
static void plod__fit_budget(plod_refiner *r, plod__frame *f)
{
    const plod_refine_params *params = f->params;
    const plod_camera *camera = f->view.camera;
    int step = r->coarsen_step;
    if (step < 0 || step > PLOD__MAX_COARSEN_STEP)
        step = 0;
    if (r->budget_known && memcmp(&r->budget_camera, camera, sizeof *camera) == 0 &&
        memcmp(&r->budget_params, params, sizeof *params) == 0) {
        /* the same camera and parameters again: the same (unique) step */
        plod__refine_pass(f, step, params->max_sectors);
        return;
    }
    if (plod__fits(f, step)) {
        while (step > 0) {
            if (plod__sectors_at_least(f, step - 1) > params->budget)
                break; /* the finer step cannot fit: no need to build it */
            if (!plod__fits(f, step - 1)) {
                plod__fits(f, step); /* back to the result */
                break;
            }
            step--;
        }
    } else {
        while (step < PLOD__MAX_COARSEN_STEP && !plod__fits(f, ++step))
            ;
        if (r->truncated) /* even the coarsest step does not fit: complete it */
            plod__refine_pass(f, step, params->max_sectors);
    }
    r->coarsen_step = step;
    r->budget_camera = *camera;
    r->budget_params = *params;
    r->budget_known = 1;
}

/* ---- visible ordering ---------------------------------------------------------- */

/* Depth-first key of a sector: its base, then its bisection path
 * left-aligned (the heap's leading 1 at bit 55), so leaves, which never
 * nest, sort in depth-first order: a spatially coherent order that depends
 * on the leaf set alone, not on the order in which splits and merges left
 * them in the leaf array. */
static uint64_t plod__order_key(uint64_t id)
{
    uint64_t heap = id & PLOD_LODTREE_HEAP_MASK;
    int level = plod_lodtree_id_level(id);
    return (id & ~PLOD_LODTREE_HEAP_MASK) | heap << (PLOD_LODTREE_BASE_SHIFT - 1 - level);
}

static plod_status plod__order_reserve(plod_refiner *r, size_t need)
{
    if (need <= r->order_capacity)
        return PLOD_OK;
    size_t capacity = r->order_capacity ? r->order_capacity : 256;
    while (capacity < need)
        capacity *= 2;
    /* realloc keeps the sorted entries the next ordering starts from */
    uint32_t *order = realloc(r->order, capacity * sizeof *order);
    if (!order)
        return PLOD_ERR_NO_MEMORY;
    r->order = order;
    uint64_t *keys = realloc(r->order_keys, capacity * sizeof *keys);
    if (!keys)
        return PLOD_ERR_NO_MEMORY;
    r->order_keys = keys;
    uint32_t *scratch_index = realloc(r->scratch_index, 3 * capacity * sizeof *scratch_index);
    if (!scratch_index)
        return PLOD_ERR_NO_MEMORY;
    r->scratch_index = scratch_index;
    uint64_t *scratch_keys = realloc(r->scratch_keys, 3 * capacity * sizeof *scratch_keys);
    if (!scratch_keys)
        return PLOD_ERR_NO_MEMORY;
    r->scratch_keys = scratch_keys;
    uint8_t *kept = realloc(r->order_kept, capacity * sizeof *kept);
    if (!kept)
        return PLOD_ERR_NO_MEMORY;
    r->order_kept = kept;
    r->order_capacity = capacity; /* only once all five have grown */
    return PLOD_OK;
}

/* Sorts n (key, index) pairs by key: an LSD radix sort, 11 bits a pass
 * (one read of the keys counts every digit), skipping the passes in which
 * every key has the same digit (the high bits of a frame's keys mostly
 * agree).  The result is in keys/index; tmp_*: scratch for n. */
static void plod__radix_sort(uint64_t *keys, uint32_t *index, size_t n, uint64_t *tmp_keys,
                             uint32_t *tmp_index, uint32_t (*count)[PLOD__ORDER_RADIX])
{
    if (n < 2)
        return;
    const uint64_t mask = PLOD__ORDER_RADIX - 1;
    memset(count, 0, PLOD__ORDER_DIGITS * sizeof *count);
    for (size_t k = 0; k < n; k++)
        for (int d = 0; d < PLOD__ORDER_DIGITS; d++)
            count[d][keys[k] >> (d * PLOD__ORDER_BITS) & mask]++;
    uint64_t *in_keys = keys, *out_keys = tmp_keys;
    uint32_t *in_index = index, *out_index = tmp_index;
    for (int d = 0; d < PLOD__ORDER_DIGITS; d++) {
        int shift = d * PLOD__ORDER_BITS;
        uint32_t *start = count[d];
        if (start[in_keys[0] >> shift & mask] == n)
            continue; /* one digit for all: this pass keeps the order */
        uint32_t sum = 0;
        for (unsigned b = 0; b < PLOD__ORDER_RADIX; b++) {
            uint32_t c = start[b];
            start[b] = sum;
            sum += c;
        }
        for (size_t k = 0; k < n; k++) {
            uint32_t to = start[in_keys[k] >> shift & mask]++;
            out_keys[to] = in_keys[k];
            out_index[to] = in_index[k];
        }
        uint64_t *tk = in_keys; in_keys = out_keys; out_keys = tk;
        uint32_t *ti = in_index; in_index = out_index; out_index = ti;
    }
    if (in_keys != keys) { /* an odd number of passes ran */
        memcpy(keys, in_keys, n * sizeof *keys);
        memcpy(index, in_index, n * sizeof *index);
    }
}

/* The visible leaves' indices sorted by plod__order_key.  From one frame
 * to the next most of them stay: the last frame's sorted entries whose
 * leaf is still there and visible are kept in their order, only the others
 * are sorted, and the two lists are merged (the same order as sorting
 * them all: the keys are unique). */
static plod_status plod__order_visible(plod_refiner *r, size_t visible)
{
    size_t previous = r->order_sorted;
    r->order_sorted = 0;
    r->order_count = 0;
    if (visible == 0)
        return PLOD_OK; /* the arrays may not exist yet (NULL + 0 is undefined) */
    plod_status st = plod__order_reserve(r, visible);
    if (st != PLOD_OK)
        return st;
    plod_lodtree *t = &r->tree;
    if (t->count > r->position_capacity) {
        size_t was = r->position_capacity, capacity = was;
        uint32_t *position = plod_grow(r->order_position, &capacity, t->count,
                                       sizeof *position, 256);
        if (!position)
            return PLOD_ERR_NO_MEMORY;
        r->order_position = position;
        uint64_t *key = realloc(r->position_key, capacity * sizeof *key);
        if (!key)
            return PLOD_ERR_NO_MEMORY;
        r->position_key = key;
        for (size_t i = was; i < capacity; i++)
            position[i] = UINT32_MAX;
        r->position_capacity = capacity; /* only once both have grown */
    }
    size_t capacity = r->order_capacity;
    uint64_t *kept_keys = r->scratch_keys, *new_keys = r->scratch_keys + capacity;
    uint32_t *kept_index = r->scratch_index, *new_index = r->scratch_index + capacity;
    if (previous == 0) /* no last order (a reset, a failure): no entry to point at */
        memset(r->order_position, 0xFF, r->position_capacity * sizeof *r->order_position);
    memset(r->order_kept, 0, previous);
    size_t added = 0;
    for (size_t i = 0; i < t->count; i++) {
        const plod_sector *sec = &t->leaves[i];
        if (!(sec->flags & PLOD_SECTOR_VISIBLE))
            continue;
        uint64_t key = plod__order_key(sec->id);
        uint32_t j = r->order_position[i];
        if (j != UINT32_MAX && r->position_key[i] == key) {
            assert(j < previous && r->order[j] == i);
            r->order_kept[j] = 1;
            continue;
        }
        new_keys[added] = key;
        new_index[added++] = (uint32_t)i;
    }
    size_t kept = 0;
    for (size_t j = 0; j < previous; j++) {
        if (!r->order_kept[j]) {
            r->order_position[r->order[j]] = UINT32_MAX; /* gone from the order */
            continue;
        }
        kept_keys[kept] = r->order_keys[j];
        kept_index[kept++] = r->order[j];
    }
    assert(kept + added == visible);
    plod__radix_sort(new_keys, new_index, added, r->scratch_keys + 2 * capacity,
                     r->scratch_index + 2 * capacity, r->order_counts);
    size_t a = 0, b = 0, n = 0;
    while (a < kept && b < added) {
        int take_kept = kept_keys[a] < new_keys[b];
        r->order_keys[n] = take_kept ? kept_keys[a] : new_keys[b];
        r->order[n++] = take_kept ? kept_index[a++] : new_index[b++];
    }
    for (; a < kept; a++, n++) {
        r->order_keys[n] = kept_keys[a];
        r->order[n] = kept_index[a];
    }
    for (; b < added; b++, n++) {
        r->order_keys[n] = new_keys[b];
        r->order[n] = new_index[b];
    }
    r->order_count = r->order_sorted = n;
    for (size_t k = 0; k < n; k++) {
        r->order_position[r->order[k]] = (uint32_t)k;
        r->position_key[r->order[k]] = r->order_keys[k];
    }
    return PLOD_OK;
}

/* ---- one update ------------------------------------------------------------------ */

plod_status plod_refine_params_check(const plod_refine_params *p, plod_error *error)
{
    const plod_status bad = PLOD_ERR_BAD_PARAM;
    if ((unsigned)p->criterion > PLOD_CRITERION_SIDE_DISTANCE)
        return plod_error_set(error, bad, "unknown criterion");
    if (!(isfinite(p->max_pixel_error) && p->max_pixel_error > 0))
        return plod_error_set(error, bad, "max_pixel_error must be finite and > 0");
    if (!(isfinite(p->split_border) && p->split_border > 0 &&
          isfinite(p->merge_border) && p->merge_border > 0 &&
          p->merge_border <= p->split_border))
        return plod_error_set(error, bad, "borders must be finite, 0 < merge_border <= "
                                          "split_border");
    if (p->template_level < 0 || p->template_level > 7)
        return plod_error_set(error, bad, "template_level must be 0..7");
    if (p->max_level < 0 || p->max_level > PLOD_MAX_LEVEL)
        return plod_error_set(error, bad, "max_level must be 0..%d", PLOD_MAX_LEVEL);
    if (p->max_sectors < 12)
        return plod_error_set(error, bad, "max_sectors must be >= 12");
    if (p->threads < 1 || p->threads > PLOD_REFINE_MAX_THREADS)
        return plod_error_set(error, bad, "threads must be 1..%d", PLOD_REFINE_MAX_THREADS);
    return PLOD_OK;
}

static double plod__now_us(void)
{
    return (double)plod_clock_ns() * 1e-3;
}

/* The frame context of an update at `camera` (eye_dist: its distance from
 * the centre, checked by the caller). */
static void plod__frame_init(plod__frame *f, plod_refiner *r, const plod_camera *camera,
                             const plod_refine_params *params, double eye_dist)
{
    const plod_planet *planet = r->tree.planet;
    f->refiner = r;
    f->tree = &r->tree;
    f->params = params;
    plod_bound_view_init(&f->view, planet, r->tree.setup.occluder, camera, params, eye_dist);
    f->merge_ratio = params->merge_border / params->split_border;
}

/* The refinement of this frame: one pass, or the budget's search. */
static void plod__refine(plod_refiner *r, plod__frame *f)
{
    r->tree.splits = r->tree.merges = 0;
    r->limits.max_splits = f->params->max_splits;
    r->limited = 0;
    if (f->params->max_splits) {
        /* progressive: the breadth-first pass, the budget as its cap, at the
         * budget's coarsening step.  Capped alone at one step, the splits a
         * view kept from an earlier place would crowd out the ones the new
         * place needs (a jump down to the ground would end short of it, the
         * coarse surface above the eye), so where the budget binds the next
         * refresh refines the whole view a step coarser, and where a finer
         * step may fit (and has not overflowed for this camera) a step
         * finer: the refreshes walk to the step a camera-only update finds,
         * each within its split limit */
        size_t budget = f->params->budget, cap = f->params->max_sectors;
        const plod_camera *camera = f->view.camera;
        int step = r->progressive_next >= 0 ? r->progressive_next : r->coarsen_step;
        if (!budget || step < 0 || step > PLOD__MAX_COARSEN_STEP)
            step = 0;
        plod__refine_pass(f, step, budget && budget < cap ? budget : cap);
        int next = step;
        if (budget && !r->limited) {
            int same = r->finer_failed &&
                       memcmp(&r->finer_failed_camera, camera, sizeof *camera) == 0;
            if (r->truncated && step < PLOD__MAX_COARSEN_STEP) {
                next = step + 1;
                r->finer_failed = 1;
                r->finer_failed_camera = *camera;
            } else if (!r->truncated && step > 0 && !same &&
                       plod__sectors_at_least(f, step - 1) <= budget) {
                next = step - 1;
                plod__sweep(f, step); /* back to the refined step's thresholds */
            }
        }
        r->coarsen_step = step;
        r->progressive_next = next;
        r->step_pending = next != step;
        r->budget_known = 0;
    } else if (f->params->budget == 0) {
        plod__refine_pass(f, 0, f->params->max_sectors);
        r->coarsen_step = 0;
        r->budget_known = 0;
        r->progressive_next = -1;
        r->step_pending = 0;
    } else {
        plod__fit_budget(r, f);
        r->progressive_next = -1;
        r->step_pending = 0;
    }
}

/* The counts of plod__classify over a range of leaves. */
typedef struct plod__class_counts {
    size_t after_backface, after_frustum, sea_skipped, visible;
    int deepest;
} plod__class_counts;

/* plod__classify's chunks: at most PLOD__CLASS_CHUNKS, each with its counts */
#define PLOD__CLASS_CHUNKS 64

typedef struct plod__class_job {
    const plod__frame *frame;
    int evaluated; /* every leaf was evaluated this frame (no cap stopped a pass) */
    size_t grain;
    plod__class_counts counts[PLOD__CLASS_CHUNKS];
} plod__class_job;

/* The counts of leaves [begin, end), to the chunk's own entry, from the
 * flags their evaluation wrote (evaluating those a stopped pass left). */
static void plod__classify_range(void *context, size_t begin, size_t end)
{
    plod__class_job *job = context;
    const plod__frame *f = job->frame;
    plod_lodtree *t = f->tree;
    plod__class_counts c = {0, 0, 0, 0, 0};
    for (size_t i = begin; i < end; i++) {
        const plod_sector *sec = &t->leaves[i];
        if (!job->evaluated && f->refiner->leaf_eval[i].frame != t->frame)
            plod__eval_leaf(f, i); /* not visited (a pass stopped by a cap) */
        unsigned flags = sec->flags;
        c.deepest = sec->level > c.deepest ? sec->level : c.deepest;
        if (flags & PLOD_SECTOR_BACKFACING)
            continue;
        c.after_backface++;
        if (flags & PLOD_SECTOR_OUTSIDE_FRUSTUM)
            continue;
        c.after_frustum++;
        if (!(flags & PLOD_SECTOR_VISIBLE)) {
            c.sea_skipped++; /* neither culled nor visible */
            continue;
        }
        c.visible++;
    }
    job->counts[begin / job->grain] = c;
}

/* The culling counts of `stats` over every leaf's flags (culling, sea,
 * visible: written when the leaf was evaluated), on the refiner's workers
 * when there are many leaves (the counts are sums: the same for any
 * chunking); returns the visible count. */
static size_t plod__classify(const plod__frame *f, plod_refine_stats *s)
{
    size_t count = f->tree->count;
    plod__class_job job;
    job.frame = f;
    job.evaluated = !f->refiner->truncated && !f->refiner->limited;
    job.grain = count / PLOD__CLASS_CHUNKS + 1;
    if (job.grain < PLOD__PARALLEL_GRAIN)
        job.grain = PLOD__PARALLEL_GRAIN;
    size_t chunks = count ? (count - 1) / job.grain + 1 : 0;
    /* a single call on the caller writes entry 0 only */
    memset(job.counts, 0, chunks * sizeof job.counts[0]);
    plod_workers_for(count >= PLOD__PARALLEL_LEAVES ? f->refiner->workers : NULL, count,
                     job.grain, plod__classify_range, &job);
    size_t visible = 0;
    int deepest = 0;
    for (size_t k = 0; k < chunks; k++) {
        const plod__class_counts *c = &job.counts[k];
        s->sectors_after_backface += c->after_backface;
        s->sectors_after_frustum += c->after_frustum;
        s->sectors_sea_skipped += c->sea_skipped;
        visible += c->visible;
        deepest = c->deepest > deepest ? c->deepest : deepest;
    }
    s->max_level_reached = deepest;
    return visible;
}

typedef struct plod__rank {
    double distance;
    uint64_t id;
    size_t index;
} plod__rank;

static int plod__rank_cmp(const void *pa, const void *pb)
{
    const plod__rank *a = pa, *b = pb;
    if (a->distance != b->distance)
        return a->distance < b->distance ? -1 : 1;
    return a->id < b->id ? -1 : (a->id > b->id);
}

/* When even the coarsest step keeps more visible sectors than the budget:
 * the farthest lose PLOD_SECTOR_VISIBLE for PLOD_SECTOR_OVER_BUDGET
 * (nearest first, ties by id). */
static plod_status plod__cut_to_budget(const plod__frame *f, size_t *visible)
{
    plod_lodtree *t = f->tree;
    size_t budget = f->params->budget;
    if (budget == 0 || *visible <= budget)
        return PLOD_OK;
    plod__rank *ranks = malloc(*visible * sizeof *ranks);
    if (!ranks)
        return PLOD_ERR_NO_MEMORY;
    size_t k = 0;
    for (size_t i = 0; i < t->count; i++)
        if (t->leaves[i].flags & PLOD_SECTOR_VISIBLE)
            ranks[k++] = (plod__rank){plod_bound_distance(&f->view, &t->geom[i].self),
                                      t->leaves[i].id, i};
    qsort(ranks, *visible, sizeof *ranks, plod__rank_cmp);
    for (size_t j = budget; j < *visible; j++) {
        plod_sector *sec = &t->leaves[ranks[j].index];
        sec->flags = (uint16_t)((sec->flags & ~PLOD_SECTOR_VISIBLE) | PLOD_SECTOR_OVER_BUDGET);
    }
    free(ranks);
    *visible = budget;
    return PLOD_OK;
}

plod_status plod_refiner_update(plod_refiner *r, const plod_camera *camera,
                                const plod_refine_params *params,
                                plod_refine_stats *stats, plod_error *error)
{
    if (!r || !camera || !params)
        return plod_error_set(error, PLOD_ERR_NULL, "no refiner, camera or parameters");
    plod_status st = plod_refine_params_check(params, error);
    if (st != PLOD_OK)
        return st;
    double eye_dist = sqrt(camera->position[0] * camera->position[0] +
                           camera->position[1] * camera->position[1] +
                           camera->position[2] * camera->position[2]);
    if (!isfinite(eye_dist) || !(eye_dist > 1e-6 * r->tree.planet->radius))
        return plod_error_set(error, PLOD_ERR_BAD_CAMERA, "camera at the planet centre");

    double t0 = plod__now_us();
    r->tree.frame++;
    r->order_count = 0; /* a failure below leaves no stale visible list */
    plod__frame f;
    plod__frame_init(&f, r, camera, params, eye_dist);
    plod__travel(r, camera->position);
    plod__ready_workers(r, params->threads);
    plod__refine(r, &f);
    double t1 = plod__now_us();
    plod_refine_stats s;
    memset(&s, 0, sizeof s);
    size_t visible = plod__classify(&f, &s);
    plod_workers_end(r->workers);
    st = plod__cut_to_budget(&f, &visible);
    if (st == PLOD_OK)
        st = plod__order_visible(r, visible);
    if (st != PLOD_OK)
        return plod_error_set(error, st, "out of memory for the visible order");
    double t2 = plod__now_us();
    s.sectors_total = r->tree.count;
    s.sectors_after_budget = visible;
    s.splits = r->tree.splits;
    s.merges = r->tree.merges;
    s.refine_us = t1 - t0;
    s.cull_us = t2 - t1;
    s.truncated = r->truncated;
    s.pending = r->limited || r->step_pending;
    s.frame = r->tree.frame;
    if (stats)
        *stats = s;
    return PLOD_OK;
}

/* ---- the refiner ------------------------------------------------------------------ */

/* The tree's observer: the leaves' evaluations follow their slots; a leaf
 * made now has none yet (the frame before the tree's). */
static plod_status plod__leaf_eval_reserve(void *context, size_t capacity)
{
    plod_refiner *r = context;
    if (capacity <= r->leaf_eval_capacity)
        return PLOD_OK;
    plod__leaf_eval *fresh = realloc(r->leaf_eval, capacity * sizeof *fresh);
    if (!fresh)
        return PLOD_ERR_NO_MEMORY;
    r->leaf_eval = fresh;
    r->leaf_eval_capacity = capacity;
    return PLOD_OK;
}

/* A split makes the leaf's node with P known when the leaf was evaluated
 * this frame. */
static void plod__leaf_eval_split(void *context, size_t slot, int32_t node)
{
    plod_refiner *r = context;
    const plod__leaf_eval *e = &r->leaf_eval[slot];
    if (e->frame == r->tree.frame)
        r->tree.node_state[node] =
            (uint8_t)(PLOD_NODE_P_KNOWN | (e->split ? PLOD_NODE_P_TRUE : 0u));
}

static void plod__leaf_eval_made(void *context, size_t slot)
{
    plod_refiner *r = context;
    r->leaf_eval[slot].frame = r->tree.frame - 1;
}

static void plod__leaf_eval_moved(void *context, size_t from, size_t to)
{
    plod_refiner *r = context;
    r->leaf_eval[to] = r->leaf_eval[from];
}

plod_status plod_refiner_create(plod_refiner **out, const plod_planet *planet)
{
    if (!out)
        return PLOD_ERR_NULL;
    *out = NULL;
    plod_status st = plod_planet_check(planet, NULL);
    if (st != PLOD_OK)
        return st;
    plod_refiner *r = calloc(1, sizeof *r);
    if (!r)
        return PLOD_ERR_NO_MEMORY;
    st = plod_lodtree_init(&r->tree, planet);
    if (st != PLOD_OK) {
        free(r);
        return st;
    }
    /* the base sectors: not evaluated (frame 0, the tree's starts at 1) */
    r->leaf_eval = calloc(r->tree.capacity, sizeof *r->leaf_eval);
    if (!r->leaf_eval) {
        plod_lodtree_free(&r->tree);
        free(r);
        return PLOD_ERR_NO_MEMORY;
    }
    r->leaf_eval_capacity = r->tree.capacity;
    r->tree.observer = (plod_lodtree_observer){r, plod__leaf_eval_reserve, plod__leaf_eval_split,
                                               plod__leaf_eval_made, plod__leaf_eval_moved};
    *out = r;
    return PLOD_OK;
}

void plod_refiner_destroy(plod_refiner *refiner)
{
    if (!refiner)
        return;
    plod_workers_destroy(refiner->workers);
    plod_lodtree_free(&refiner->tree);
    free(refiner->leaf_eval);
    free(refiner->order);
    free(refiner->order_keys);
    free(refiner->scratch_index);
    free(refiner->scratch_keys);
    free(refiner->order_kept);
    free(refiner->order_position);
    free(refiner->position_key);
    free(refiner->split_marks);
    free(refiner->merge_nodes);
    free(refiner);
}

plod_status plod_refiner_reserve(plod_refiner *refiner, size_t sectors)
{
    if (!refiner)
        return PLOD_ERR_NULL;
    if (sectors > PLOD_REFINER_MAX_RESERVE)
        return PLOD_ERR_BAD_PARAM;
    size_t old_evals = refiner->leaf_eval_capacity;
    plod_status st = plod_lodtree_reserve(&refiner->tree, sectors);
    if (st == PLOD_OK && refiner->leaf_eval_capacity > old_evals) /* touched now, as the tree's */
        memset(refiner->leaf_eval + old_evals, 0,
               (refiner->leaf_eval_capacity - old_evals) * sizeof *refiner->leaf_eval);
    if (st == PLOD_OK)
        st = plod__order_reserve(refiner, sectors);
    if (st == PLOD_OK)
        st = plod__marks_reserve(refiner, sectors);
    if (st == PLOD_OK) /* at most half the nodes have two leaf children */
        st = plod__merge_reserve(refiner, sectors / 2 + 1);
    return st;
}

void plod_refiner_reset(plod_refiner *refiner)
{
    if (!refiner)
        return;
    refiner->order_count = refiner->order_sorted = 0;
    plod_lodtree_reset(&refiner->tree);
}

plod_workers *plod_refiner_workers(const plod_refiner *refiner)
{
    return refiner ? refiner->workers : NULL;
}

const plod_sector *plod_refiner_sectors(const plod_refiner *refiner, size_t *count)
{
    if (count)
        *count = refiner ? refiner->tree.count : 0;
    return refiner ? refiner->tree.leaves : NULL;
}

const uint32_t *plod_refiner_visible(const plod_refiner *refiner, size_t *count)
{
    if (count)
        *count = refiner ? refiner->order_count : 0;
    return refiner ? refiner->order : NULL;
}

void plod_refine_params_default(plod_refine_params *params)
{
    memset(params, 0, sizeof *params);
    params->criterion = PLOD_CRITERION_PIXEL_ERROR;
    params->max_pixel_error = 1.0;
    params->split_border = 0.5;
    params->merge_border = 0.25;
    params->hysteresis = 0;
    params->template_level = 4;
    params->max_level = 48;
    params->budget = 0;
    params->backface_culling = 1;
    params->frustum_culling = 1;
    params->skip_sea = 0;
    params->max_sectors = PLOD_DEFAULT_MAX_SECTORS;
    params->threads = 1;
}

/* ---- split morph ------------------------------------------------------------------ */

/* The split test's score of a bound (plod_bound_score at its distance). */
static double plod__score(const plod_bound_view *v, const plod_bound *b)
{
    return plod_bound_score(v, b, plod_bound_distance(v, b));
}

/* The split morph's factors of every diamond (plod_refine.h), per node
 * (both parents of a diamond get the same value).  Scratch of one call. */
typedef struct plod__morph_factors {
    double *reach;  /* the node's own capped score, then the diamond's reach */
    double *factor; /* m of the node's diamond */
    int32_t *by_level; /* the live nodes, deepest level first */
} plod__morph_factors;

static double plod__max(double a, double b)
{
    return b > a ? b : a;
}

static double plod__min(double a, double b)
{
    return b < a ? b : a;
}

static plod_status plod__morph_factors_compute(const plod_lodtree *t, const plod_bound_view *v,
                                               plod__morph_factors *mf)
{
    size_t nodes = t->node_top ? t->node_top : 1;
    mf->reach = malloc(nodes * sizeof *mf->reach);
    mf->factor = malloc(nodes * sizeof *mf->factor);
    mf->by_level = malloc(nodes * sizeof *mf->by_level);
    if (!mf->reach || !mf->factor || !mf->by_level)
        return PLOD_ERR_NO_MEMORY;
    /* the scores P* acts on: capped by the ancestors' (nodes come parents
     * first), and the nodes counted by level */
    size_t per_level[PLOD_MAX_LEVEL + 2] = {0};
    for (size_t k = 0; k < t->node_top; k++) {
        mf->factor[k] = 0.0;
        if (!t->nodes[k].id) {
            mf->reach[k] = 0.0;
            continue;
        }
        double s = plod__score(v, &t->nodes[k].bound);
        int32_t parent = t->node_parent[k];
        mf->reach[k] = parent >= 0 ? plod__min(s, mf->reach[parent]) : s;
        per_level[PLOD_MAX_LEVEL - plod_lodtree_id_level(t->nodes[k].id) + 1]++;
    }
    for (size_t l = 1; l <= PLOD_MAX_LEVEL + 1; l++)
        per_level[l] += per_level[l - 1];
    for (size_t k = 0; k < t->node_top; k++)
        if (t->nodes[k].id)
            mf->by_level[per_level[PLOD_MAX_LEVEL - plod_lodtree_id_level(t->nodes[k].id)]++] =
                (int32_t)k;
    size_t live = per_level[PLOD_MAX_LEVEL];
    /* reaches bottom-up, a level at a time: a node's is complete once every
     * diamond below it is, and its partner's too */
    double log_range = log(PLOD_SPLIT_MORPH_RANGE);
    for (size_t first = 0; first < live;) {
        int level = plod_lodtree_id_level(t->nodes[mf->by_level[first]].id);
        size_t last = first;
        while (last < live && plod_lodtree_id_level(t->nodes[mf->by_level[last]].id) == level)
            last++;
        for (size_t at = first; at < last; at++) {
            int32_t k = mf->by_level[at], q = t->node_partner[k];
            double e = q >= 0 ? plod__max(mf->reach[k], mf->reach[q]) : mf->reach[k];
            double m = e > 1.0 ? 1.0 - log(e) / log_range : 1.0;
            mf->factor[k] = m < 0.0 ? 0.0 : (m > 1.0 ? 1.0 : m);
            /* the parent is split for this diamond: it reaches as far */
            int32_t parent = t->node_parent[k];
            if (parent >= 0)
                mf->reach[parent] = plod__max(mf->reach[parent], e);
        }
        first = last;
    }
    return PLOD_OK;
}

static void plod__morph_factors_free(plod__morph_factors *mf)
{
    free(mf->reach);
    free(mf->factor);
    free(mf->by_level);
}

/* The parent of a sector (its bisection's inverse): child 0 is (p1, m, p0),
 * child 1 is (p2, m, p1).  Returns which child s is. */
static int plod__parent_sector(const plod_sector *s, plod_sector *p)
{
    int bit = (int)(s->id & 1u);
    *p = *s;
    if (bit == 0) {
        p->cu[0] = s->cu[2], p->cv[0] = s->cv[2];
        p->cu[1] = s->cu[0], p->cv[1] = s->cv[0];
        p->cu[2] = 2 * s->cu[1] - s->cu[2], p->cv[2] = 2 * s->cv[1] - s->cv[2];
    } else {
        p->cu[0] = 2 * s->cu[1] - s->cu[0], p->cv[0] = 2 * s->cv[1] - s->cv[0];
        p->cu[1] = s->cu[2], p->cv[1] = s->cv[2];
        p->cu[2] = s->cu[0], p->cv[2] = s->cv[0];
    }
    p->id = plod_lodtree_parent_id(s->id);
    p->level = (uint8_t)(s->level - 1);
    return bit;
}

/* The split morph of leaf i (plod_refine.h): its ancestors' factors up to
 * the last above 0, then their corners. */
static void plod__split_morph(const plod_lodtree *t, const plod__morph_factors *mf, size_t i,
                              plod_split_morph *out)
{
    out->stages = 0;
    int stages = 0;
    int32_t node = t->leaf_parent[i];
    for (int j = 0; j < PLOD_SPLIT_MORPH_STAGES && node >= 0; j++) {
        out->stage[j].factor = mf->factor[node];
        if (mf->factor[node] > 0.0)
            stages = j + 1;
        node = t->node_parent[node];
    }
    plod_sector below = t->leaves[i], above;
    double corners[3][3];
    for (int j = 0; j < stages; j++) {
        int child = plod__parent_sector(&below, &above);
        plod_sector_corners(t->planet, &above, corners);
        out->stage[j].child = child;
        memcpy(out->stage[j].third_corner, corners[child ? 0 : 2],
               sizeof out->stage[j].third_corner);
        below = above;
    }
    out->stages = stages;
}

plod_status plod_refiner_split_morphs(const plod_refiner *r, const plod_camera *camera,
                                      const plod_refine_params *params,
                                      const uint32_t *leaves, size_t count,
                                      plod_split_morph *out)
{
    if (!r || !camera || !params || (count && !out))
        return PLOD_ERR_NULL;
    const plod_lodtree *t = &r->tree;
    double eye_dist = sqrt(camera->position[0] * camera->position[0] +
                           camera->position[1] * camera->position[1] +
                           camera->position[2] * camera->position[2]);
    if (!isfinite(eye_dist) || !(eye_dist > 1e-6 * t->planet->radius))
        return PLOD_ERR_BAD_COORD;
    for (size_t k = 0; k < count; k++)
        if ((leaves ? leaves[k] : k) >= t->count)
            return PLOD_ERR_BAD_PARAM;
    plod_bound_view view;
    plod_bound_view_init(&view, t->planet, t->setup.occluder, camera, params, eye_dist);
    /* the last update's coarsening step (0 without a budget) */
    plod__view_threshold(&view, params, params->budget ? r->coarsen_step : 0);
    plod__morph_factors mf;
    plod_status st = plod__morph_factors_compute(t, &view, &mf);
    if (st == PLOD_OK)
        for (size_t k = 0; k < count; k++)
            plod__split_morph(t, &mf, leaves ? leaves[k] : k, &out[k]);
    plod__morph_factors_free(&mf);
    return st;
}

size_t plod_refiner_memory_bytes(const plod_refiner *r)
{
    if (!r)
        return 0;
    return sizeof *r + plod_lodtree_memory_bytes(&r->tree) +
           r->leaf_eval_capacity * sizeof *r->leaf_eval +
           r->order_capacity * 4 * (sizeof(uint32_t) + sizeof(uint64_t)) +
           r->split_mark_words * sizeof(uint64_t) + r->merge_capacity * sizeof(int32_t);
}

plod_status plod_refiner_check(const plod_refiner *r)
{
    if (!r)
        return PLOD_ERR_NULL;
    return plod_lodtree_check(&r->tree);
}
