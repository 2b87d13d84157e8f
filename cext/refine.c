/* refine.c -- HRTMR (Hybrid Real-Time Mesh Refinement) split/merge
 * refinement, leaves only, with implicit longest-edge-bisection ids.
 * K. Gasiński, "Porównanie metod wizualizacji terenu w czasie rzeczywistym"
 * (comparison of real-time terrain visualisation methods), master's thesis,
 * Gdańsk University of Technology, 2010, sections 5.2-5.3.
 *
 * Bit rules (libleb-style heap ids):
 *   id        = base << 56 | heap,  heap = 1 << level | path bits
 *   child(b)  = heap * 2 + b        parent = heap >> 1
 *   parent (c0, c1, c2), apex c1, hypotenuse c0-c2, m = (c0 + c2) / 2:
 *     child 0 = (c1, m, c0)         child 1 = (c2, m, c1)
 *   so every child keeps the counter-clockwise order and has its apex at m.
 * Base mesh: cube, per face the diagonal (-1,-1)-(1,1) splits the square
 * into two sectors that form the level-0 diamond; CAR, the octahedral
 * square's 8 octant triangles, each inner (northern) one paired with the
 * outer (southern) one across the equator line |u|+|v| = 1.
 *
 * Adjacency: every sector edge is keyed by the sum of its two endpoints'
 * canonical integer points on the cube (or octahedron) surface, which is
 * unique for the edges of a conforming mesh and equal from both faces of a
 * cube edge.  A hash table maps each key to the two leaves sharing it, so
 * forced splits and diamond lookups are O(1) and exact across faces.
 *
 * Determinism: the raw split predicate P of a node is a pure function of the
 * node and the camera (its own bounding cap prism; heights from range
 * queries).  Caps of children do not nest in their parents' (projection
 * distortion), so P alone is not monotone; the refinement uses
 * P*(node) = P(node) and P*(parent), which is.  The bounds of the internal
 * (split) nodes are kept in a dense array in creation order (removed ones
 * leave holes until the next compaction, which keeps the order), so a
 * parent always precedes its children; every leaf and node holds its
 * parent's index.  One sequential sweep per frame then gives P* of every
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
 * thresholds are decided by square-root-free bounds where they clear them);
 * a split costs one new projected point (leaves cache their corners'
 * directions, heights and canonical points) and two bounds.
 */
#include "plod_bound.h"
#include "plod_refine.h"

#include <assert.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define PLOD__ONE ((int32_t)1 << PLOD_COORD_BITS)
#define PLOD__BASE_SHIFT 56
#define PLOD__HEAP_MASK (((uint64_t)1 << PLOD__BASE_SHIFT) - 1)
/* ---- per-leaf bounds ------------------------------------------------------ */

typedef struct plod__geom {
    plod_bound self;
    uint32_t eval_frame;   /* frame of the cached evaluation below */
    uint8_t eval_split;    /* predicate result */
    uint8_t eval_flags;    /* PLOD_SECTOR_BACKFACING | OUTSIDE_FRUSTUM */
} plod__geom;

/* A leaf's corner directions and, once a bound needed them, heights: kept
 * so that a split computes only the new midpoint (the same calls on the
 * same corners, so the same bits as computing them again). */
typedef struct plod__corners {
    double dir[3][3];
    double height[3];
    int32_t canon[3][3]; /* canonical points (plod__canon): edge keys */
    unsigned known; /* bit k: height[k] computed */
} plod__corners;

typedef struct plod__edge {
    int32_t key[3];
    int32_t leaf[2]; /* -1 = none; both -1 = empty slot */
} plod__edge;

/* An internal (split) node: its bound and this frame's effective predicate
 * P*(node) = P(node) and P*(parent), memoised per frame. */
typedef struct plod__node {
    uint64_t id;        /* 0 = free slot */
    plod_bound bound;
} plod__node;

/* node_state bits, valid for the current frame (cleared by its pre-pass) */
enum {
    PLOD__P_KNOWN = 1, PLOD__P_TRUE = 2,        /* P(node) */
    PLOD__STAR_KNOWN = 4, PLOD__STAR_TRUE = 8   /* P*(node) */
};

struct plod_refiner {
    const plod_planet *planet;
    plod_sector *leaves;
    plod__geom *geom;
    plod__corners *corners;      /* apart from geom: only splits and merges
                                    read it, the per-frame sweeps do not */
    int32_t *leaf_parent;        /* parent's index in nodes[], -1 at level 0;
                                    apart from geom: the merge sweep reads
                                    it for every leaf */
    size_t count, capacity;
    plod__edge *edges;
    size_t edge_mask, edge_used; /* capacity - 1, live entries */
    size_t *pending;             /* split pass: in-place children to revisit */
    size_t pending_count, pending_capacity;
    plod__node *nodes;           /* internal nodes, dense, stable indices */
    int32_t *node_parent;        /* parent's index (< own), -1 at level 0 */
    uint8_t *node_state;         /* PLOD__P_* | PLOD__STAR_* this frame */
    uint8_t *node_planes;        /* this frame: bit i, the node's surface is
                                    inside frustum plane i (0 if unknown) */
    uint8_t *node_leaves;        /* how many of its 2 children are leaves */
    int32_t *node_partner;       /* the other parent of its diamond: both
                                    are made by one split, removed by one
                                    merge */
    size_t node_capacity, node_top, node_used; /* node_top: slots in use or
                                                  holes (id 0) */
    uint32_t frame;
    plod_bound_setup setup;
    int face_axes[PLOD_FACE_COUNT][3][3]; /* plod_face_frame of each face */
    /* per-update evaluation context */
    plod_bound_view view;
    const plod_refine_params *params;
    double merge_ratio;
    int coarsen_step;       /* the budget's step of the last update: where the
                               next update's search starts (never its result) */
    int budget_known;       /* coarsen_step is the answer for budget_camera and
                               budget_params (the same frame again) */
    plod_camera budget_camera;
    plod_refine_params budget_params;
    size_t max_sectors;
    int truncated;
    size_t splits, merges;
    /* this frame's visible sectors in canonical order (plod__order_visible) */
    uint32_t *order;
    size_t order_count, order_capacity;
    uint64_t *order_keys;        /* radix-sort scratch: 2 * order_capacity */
    uint32_t *order_scratch;     /* order_capacity */
};

/* ---- canonical points and edge keys -------------------------------------- */

static void plod__canon(const plod_refiner *r, int face, int32_t u, int32_t v,
                        int32_t out[3])
{
    if (plod_projection_is_cube(r->planet->projection)) {
        const int(*ax)[3] = r->face_axes[face];
        for (int i = 0; i < 3; i++)
            out[i] = ax[0][i] * PLOD__ONE + ax[1][i] * u + ax[2][i] * v;
        return;
    }
    /* octahedral square folded onto the octahedron |x|+|y|+|z| = ONE */
    int32_t au = u < 0 ? -u : u, av = v < 0 ? -v : v;
    int32_t z = PLOD__ONE - au - av;
    if (z >= 0) {
        out[0] = u;
        out[1] = v;
    } else {
        out[0] = (u < 0 ? -1 : 1) * (PLOD__ONE - av);
        out[1] = (v < 0 ? -1 : 1) * (PLOD__ONE - au);
    }
    out[2] = z;
}

/* Edge e joins corners e and (e + 1) % 3; edge 2 is the hypotenuse. */
static void plod__edge_key(const plod_refiner *r, const plod_sector *s, int e,
                           int32_t key[3])
{
    int a = e, b = (e + 1) % 3;
    int32_t pa[3], pb[3];
    plod__canon(r, s->face, s->cu[a], s->cv[a], pa);
    plod__canon(r, s->face, s->cu[b], s->cv[b], pb);
    for (int i = 0; i < 3; i++)
        key[i] = pa[i] + pb[i];
}

/* The key of edge e from cached canonical points (= plod__edge_key). */
static void plod__corners_key(const plod__corners *c, int e, int32_t key[3])
{
    const int32_t *pa = c->canon[e], *pb = c->canon[(e + 1) % 3];
    for (int i = 0; i < 3; i++)
        key[i] = pa[i] + pb[i];
}

static void plod__leaf_key(const plod_refiner *r, size_t at, int e, int32_t key[3])
{
    plod__corners_key(&r->corners[at], e, key);
}

static size_t plod__hash(const int32_t key[3])
{
    uint64_t h = (uint32_t)key[0];
    h = h * 0x9E3779B97F4A7C15ull ^ (uint32_t)key[1];
    h = h * 0xC2B2AE3D27D4EB4Full ^ (uint32_t)key[2];
    h ^= h >> 31;
    h *= 0x94D049BB133111EBull;
    h ^= h >> 29;
    return (size_t)h;
}

static int plod__key_eq(const int32_t a[3], const int32_t b[3])
{
    return a[0] == b[0] && a[1] == b[1] && a[2] == b[2];
}

static int plod__slot_empty(const plod__edge *e)
{
    return e->leaf[0] < 0 && e->leaf[1] < 0;
}

static size_t plod__edge_find(const plod_refiner *r, const int32_t key[3])
{
    size_t i = plod__hash(key) & r->edge_mask;
    for (;;) {
        const plod__edge *e = &r->edges[i];
        if (plod__slot_empty(e))
            return (size_t)-1;
        if (plod__key_eq(e->key, key))
            return i;
        i = (i + 1) & r->edge_mask;
    }
}

static plod_status plod__edge_grow(plod_refiner *r, size_t capacity)
{
    plod__edge *fresh = malloc(capacity * sizeof *fresh);
    if (!fresh)
        return PLOD_ERR_NO_MEMORY;
    for (size_t i = 0; i < capacity; i++)
        fresh[i].leaf[0] = fresh[i].leaf[1] = -1;
    plod__edge *old = r->edges;
    size_t old_capacity = old ? r->edge_mask + 1 : 0;
    r->edges = fresh;
    r->edge_mask = capacity - 1;
    for (size_t i = 0; i < old_capacity; i++) {
        if (plod__slot_empty(&old[i]))
            continue;
        size_t j = plod__hash(old[i].key) & r->edge_mask;
        while (!plod__slot_empty(&fresh[j]))
            j = (j + 1) & r->edge_mask;
        fresh[j] = old[i];
    }
    free(old);
    return PLOD_OK;
}

/* Capacity is ensured by the caller (plod__reserve). */
static void plod__edge_add(plod_refiner *r, const int32_t key[3], int32_t leaf)
{
    size_t i = plod__hash(key) & r->edge_mask;
    for (;;) {
        plod__edge *e = &r->edges[i];
        if (plod__slot_empty(e)) {
            memcpy(e->key, key, sizeof e->key);
            e->leaf[0] = leaf;
            e->leaf[1] = -1;
            r->edge_used++;
            return;
        }
        if (plod__key_eq(e->key, key)) {
            assert(e->leaf[0] < 0 || e->leaf[1] < 0);
            e->leaf[e->leaf[0] < 0 ? 0 : 1] = leaf;
            return;
        }
        i = (i + 1) & r->edge_mask;
    }
}

/* A new edge shared by leaves a and b (key absent; capacity ensured). */
static void plod__edge_add_two(plod_refiner *r, const int32_t key[3], int32_t a, int32_t b)
{
    size_t i = plod__hash(key) & r->edge_mask;
    while (!plod__slot_empty(&r->edges[i])) {
        assert(!plod__key_eq(r->edges[i].key, key));
        i = (i + 1) & r->edge_mask;
    }
    plod__edge *e = &r->edges[i];
    memcpy(e->key, key, sizeof e->key);
    e->leaf[0] = a;
    e->leaf[1] = b;
    r->edge_used++;
}

static void plod__edge_remove(plod_refiner *r, const int32_t key[3], int32_t leaf)
{
    size_t i = plod__edge_find(r, key);
    assert(i != (size_t)-1);
    plod__edge *e = &r->edges[i];
    if (e->leaf[0] == leaf)
        e->leaf[0] = -1;
    else if (e->leaf[1] == leaf)
        e->leaf[1] = -1;
    else
        assert(!"leaf not on its edge");
    if (!plod__slot_empty(e))
        return;
    /* backward-shift deletion keeps linear probing chains intact */
    r->edge_used--;
    size_t hole = i, j = i;
    for (;;) {
        j = (j + 1) & r->edge_mask;
        plod__edge *n = &r->edges[j];
        if (plod__slot_empty(n))
            break;
        size_t home = plod__hash(n->key) & r->edge_mask;
        /* move n into the hole unless its home lies cyclically in (hole, j] */
        int stays = hole <= j ? (home > hole && home <= j) : (home > hole || home <= j);
        if (stays)
            continue;
        r->edges[hole] = *n;
        n->leaf[0] = n->leaf[1] = -1;
        hole = j;
    }
}

static void plod__edge_replace(plod_refiner *r, const int32_t key[3], int32_t from,
                               int32_t to)
{
    size_t i = plod__edge_find(r, key);
    assert(i != (size_t)-1);
    plod__edge *e = &r->edges[i];
    if (e->leaf[0] == from)
        e->leaf[0] = to;
    else {
        assert(e->leaf[1] == from);
        e->leaf[1] = to;
    }
}

/* The other leaf on edge `e` of leaf `index`, or -1. */
static int32_t plod__across(const plod_refiner *r, size_t index, int e)
{
    int32_t key[3];
    plod__leaf_key(r, index, e, key);
    size_t i = plod__edge_find(r, key);
    if (i == (size_t)-1)
        return -1;
    const plod__edge *edge = &r->edges[i];
    return edge->leaf[0] == (int32_t)index ? edge->leaf[1] : edge->leaf[0];
}

static void plod__leaf_link(plod_refiner *r, size_t index)
{
    for (int e = 0; e < 3; e++) {
        int32_t key[3];
        plod__leaf_key(r, index, e, key);
        plod__edge_add(r, key, (int32_t)index);
    }
}

/* Room for `extra` more leaves (and their edges). */
static plod_status plod__reserve(plod_refiner *r, size_t extra)
{
    size_t need = r->count + extra;
    if (need > r->capacity) {
        size_t capacity = r->capacity ? r->capacity : 64;
        while (capacity < need)
            capacity *= 2;
        plod_sector *leaves = realloc(r->leaves, capacity * sizeof *leaves);
        if (!leaves)
            return PLOD_ERR_NO_MEMORY;
        r->leaves = leaves;
        plod__geom *geom = realloc(r->geom, capacity * sizeof *geom);
        if (!geom)
            return PLOD_ERR_NO_MEMORY;
        r->geom = geom;
        plod__corners *corners = realloc(r->corners, capacity * sizeof *corners);
        if (!corners)
            return PLOD_ERR_NO_MEMORY;
        r->corners = corners;
        int32_t *parent = realloc(r->leaf_parent, capacity * sizeof *parent);
        if (!parent)
            return PLOD_ERR_NO_MEMORY;
        r->leaf_parent = parent;
        r->capacity = capacity;
    }
    /* every leaf has 3 edges, each shared by 2 leaves: 1.5 keys per leaf */
    size_t keys = r->edge_used + 3 * extra + 8;
    size_t edge_capacity = r->edges ? r->edge_mask + 1 : 0;
    if (keys * 2 > edge_capacity) {
        size_t capacity = edge_capacity ? edge_capacity : 256;
        while (keys * 2 > capacity)
            capacity *= 2;
        return plod__edge_grow(r, capacity);
    }
    return PLOD_OK;
}

/* ---- internal nodes ----------------------------------------------------------- */

static plod_status plod__node_reserve(plod_refiner *r, size_t extra)
{
    size_t need = r->node_top + extra;
    if (need <= r->node_capacity)
        return PLOD_OK;
    if (need > (size_t)INT32_MAX)
        return PLOD_ERR_NO_MEMORY;
    size_t capacity = r->node_capacity ? r->node_capacity : 64;
    while (capacity < need)
        capacity *= 2;
    plod__node *fresh = realloc(r->nodes, capacity * sizeof *fresh);
    if (!fresh)
        return PLOD_ERR_NO_MEMORY;
    r->nodes = fresh;
    int32_t *parent = realloc(r->node_parent, capacity * sizeof *parent);
    if (!parent)
        return PLOD_ERR_NO_MEMORY;
    r->node_parent = parent;
    uint8_t *state = realloc(r->node_state, capacity);
    if (!state)
        return PLOD_ERR_NO_MEMORY;
    r->node_state = state;
    uint8_t *planes = realloc(r->node_planes, capacity);
    if (!planes)
        return PLOD_ERR_NO_MEMORY;
    r->node_planes = planes;
    uint8_t *leaves = realloc(r->node_leaves, capacity);
    if (!leaves)
        return PLOD_ERR_NO_MEMORY;
    r->node_leaves = leaves;
    int32_t *partner = realloc(r->node_partner, capacity * sizeof *partner);
    if (!partner)
        return PLOD_ERR_NO_MEMORY;
    r->node_partner = partner;
    r->node_capacity = capacity; /* only once all four have grown */
    return PLOD_OK;
}

/* Capacity ensured by plod__node_reserve; returns the node's index. */
static int32_t plod__node_add(plod_refiner *r, uint64_t id, const plod_bound *bound,
                              int32_t parent)
{
    assert(r->node_top < r->node_capacity);
    assert(parent < (int32_t)r->node_top);
    int32_t at = (int32_t)r->node_top++; /* after its parent: creation order */
    plod__node *n = &r->nodes[at];
    n->id = id;
    n->bound = *bound;
    r->node_parent[at] = parent;
    r->node_state[at] = 0; /* evaluated on demand this frame */
    r->node_planes[at] = 0;
    r->node_leaves[at] = 2;
    r->node_used++;
    return at;
}

static void plod__node_remove(plod_refiner *r, int32_t at)
{
    assert(at >= 0 && (size_t)at < r->node_top && r->nodes[at].id);
    r->nodes[at].id = 0; /* a hole until plod__node_compact */
    r->node_used--;
}

/* Squeezes the holes out of the node arrays, keeping the order (parents
 * before children), and renumbers the parent indices of nodes and leaves.
 * Runs when holes outnumber live nodes: amortised O(1) per removal. */
static void plod__node_compact(plod_refiner *r)
{
    if (r->node_top < 64 || r->node_top < 2 * r->node_used)
        return;
    int32_t *map = malloc(r->node_top * sizeof *map);
    if (!map)
        return; /* the holes stay: only memory, never correctness */
    size_t next = 0;
    for (size_t k = 0; k < r->node_top; k++) {
        if (!r->nodes[k].id) {
            map[k] = -1;
            continue;
        }
        int32_t parent = r->node_parent[k];
        assert(parent < (int32_t)k);
        map[k] = (int32_t)next;
        r->nodes[next] = r->nodes[k]; /* next <= k: in place */
        r->node_parent[next] = parent >= 0 ? map[parent] : -1;
        r->node_leaves[next] = r->node_leaves[k];
        r->node_partner[next] = r->node_partner[k]; /* renumbered below */
        next++;
    }
    for (size_t k = 0; k < next; k++)
        r->node_partner[k] = map[r->node_partner[k]];
    for (size_t i = 0; i < r->count; i++)
        if (r->leaf_parent[i] >= 0)
            r->leaf_parent[i] = map[r->leaf_parent[i]];
    assert(next == r->node_used);
    r->node_top = next;
    free(map);
}

/* ---- geometry of a node ---------------------------------------------------- */

void plod_sector_corners(const plod_planet *planet, const plod_sector *sector,
                         double corners[3][3])
{
    const double scale = 1.0 / (double)PLOD__ONE;
    for (int k = 0; k < 3; k++) {
        plod_status st = plod_face_to_dir(planet->projection, sector->face,
                                          sector->cu[k] * scale,
                                          sector->cv[k] * scale, corners[k]);
        (void)st;
        assert(st == PLOD_OK);
    }
}

/* The corner points of a split (plod_bound_corners) with their canonical
 * points. */
typedef struct plod__corner_memo {
    plod_bound_corners points;
    int32_t canon[4][3];
} plod__corner_memo;

/* memo entries idx[0..2] become the corners of the leaf at `at` */
static void plod__store_corners(plod_refiner *r, size_t at, const plod__corner_memo *memo,
                                const int idx[3])
{
    plod__corners *c = &r->corners[at];
    c->known = 0;
    for (int k = 0; k < 3; k++) {
        memcpy(c->dir[k], memo->points.dir[idx[k]], sizeof c->dir[k]);
        memcpy(c->canon[k], memo->canon[idx[k]], sizeof c->canon[k]);
        c->height[k] = memo->points.height[idx[k]];
        if (memo->points.known & (1u << idx[k]))
            c->known |= 1u << k;
    }
}

static void plod__load_corners(const plod_refiner *r, size_t at, plod__corner_memo *memo)
{
    const plod__corners *c = &r->corners[at];
    memcpy(memo->points.dir, c->dir, sizeof c->dir);
    memcpy(memo->canon, c->canon, sizeof c->canon);
    memcpy(memo->points.height, c->height, sizeof c->height);
    memo->points.known = c->known & 7u;
}

/* Bound of the leaf at `at` from scratch; fills its corner cache. */
static void plod__compute_bound(plod_refiner *r, size_t at, plod_bound *b)
{
    plod__corner_memo memo;
    memo.points.known = 0;
    const plod_sector *s = &r->leaves[at];
    plod_sector_corners(r->planet, s, memo.points.dir);
    for (int k = 0; k < 3; k++)
        plod__canon(r, s->face, s->cu[k], s->cv[k], memo.canon[k]);
    static const int idx[3] = {0, 1, 2};
    plod_bound_build(&r->setup, s, &memo.points, idx, b);
    plod__store_corners(r, at, &memo, idx);
}

/* Split predicate P of a node (level = its level), from its own bound. */
static int plod__wants_split(const plod_refiner *r, const plod_bound *b, int level,
                             unsigned *flags, unsigned parent_planes, unsigned *planes)
{
    *flags = plod_bound_cull(&r->view, b, parent_planes, planes);
    if (level >= r->params->max_level || *flags)
        return 0;
    return plod_bound_exceeds_at_prism(&r->view, b);
}

static int plod__id_level(uint64_t id)
{
    uint64_t heap = id & PLOD__HEAP_MASK;
    assert(heap);
    return 63 - __builtin_clzll(heap);
}

static uint64_t plod__parent_id(uint64_t id)
{
    return (id & ~PLOD__HEAP_MASK) | ((id & PLOD__HEAP_MASK) >> 1);
}

/* The frustum planes node `parent`'s surface is inside of, this frame
 * (final once the node sweep, or a lazy evaluation, has visited it). */
static unsigned plod__parent_planes(const plod_refiner *r, int32_t parent)
{
    return parent >= 0 ? r->node_planes[parent] : 0u;
}

/* P(node) of an internal node, as PLOD__P_KNOWN | P_TRUE bits; stores its
 * plane mask. */
static unsigned plod__node_p(plod_refiner *r, int32_t k, unsigned parent_planes)
{
    const plod__node *n = &r->nodes[k];
    unsigned flags, planes;
    int p = plod__wants_split(r, &n->bound, plod__id_level(n->id), &flags, parent_planes,
                              &planes);
    r->node_planes[k] = (uint8_t)planes;
    return PLOD__P_KNOWN | (p ? PLOD__P_TRUE : 0u);
}

/* P*(node) = P(node) and P*(parent): monotone by construction, so the
 * refinement it defines has a unique minimal conforming closure.  For an
 * internal node, memoised per frame. */
static int plod__node_wants(plod_refiner *r, int32_t k)
{
    unsigned st = r->node_state[k];
    if (st & PLOD__STAR_KNOWN)
        return (st & PLOD__STAR_TRUE) != 0;
    if (!(st & PLOD__P_KNOWN))
        st |= plod__node_p(r, k, plod__parent_planes(r, r->node_parent[k]));
    int wants = (st & PLOD__P_TRUE) != 0;
    int32_t parent = r->node_parent[k];
    if (wants && parent >= 0) {
        assert(r->nodes[parent].id == plod__parent_id(r->nodes[k].id));
        wants = plod__node_wants(r, parent);
    }
    r->node_state[k] = (uint8_t)(st | PLOD__STAR_KNOWN | (wants ? PLOD__STAR_TRUE : 0u));
    return wants;
}

/* Whether an internal node may be merged back (its children removed). */
static int plod__allows_merge(plod_refiner *r, int32_t k)
{
    if (!r->params->hysteresis)
        return !plod__node_wants(r, k);
    const plod__node *n = &r->nodes[k];
    int level = plod__id_level(n->id);
    if (r->node_parent[k] >= 0 && !plod__node_wants(r, r->node_parent[k]))
        return 1;
    unsigned planes;
    unsigned flags = plod_bound_cull(&r->view, &n->bound, 0, &planes);
    return flags || level >= r->params->max_level ||
           plod_bound_score(&r->view, &n->bound, plod_bound_distance(&r->view, &n->bound)) < r->merge_ratio;
}

/* P*(leaf), caching P(leaf) and its cull flags for this frame. */
static int plod__leaf_wants_split(plod_refiner *r, size_t i)
{
    plod__geom *g = &r->geom[i];
    if (g->eval_frame != r->frame) {
        unsigned flags;
        unsigned planes;
        g->eval_split = (uint8_t)plod__wants_split(r, &g->self, r->leaves[i].level,
                                                   &flags,
                                                   plod__parent_planes(r, r->leaf_parent[i]),
                                                   &planes);
        g->eval_flags = (uint8_t)flags;
        g->eval_frame = r->frame;
    }
    int32_t parent = r->leaf_parent[i];
    if (!g->eval_split || parent < 0)
        return g->eval_split;
    assert(r->nodes[parent].id == plod__parent_id(r->leaves[i].id));
    return plod__node_wants(r, parent);
}

/* ---- node algebra ---------------------------------------------------------- */

static void plod__child(const plod_sector *p, int bit, uint32_t frame,
                        plod_sector *c)
{
    int32_t mu = (int32_t)(((int64_t)p->cu[0] + p->cu[2]) / 2);
    int32_t mv = (int32_t)(((int64_t)p->cv[0] + p->cv[2]) / 2);
    memset(c, 0, sizeof *c);
    int a = bit ? 2 : 1, b = bit ? 1 : 0; /* corners 0 and 2 of the child */
    c->cu[0] = p->cu[a];
    c->cv[0] = p->cv[a];
    c->cu[1] = mu;
    c->cv[1] = mv;
    c->cu[2] = p->cu[b];
    c->cv[2] = p->cv[b];
    uint64_t base = p->id >> PLOD__BASE_SHIFT, heap = p->id & PLOD__HEAP_MASK;
    c->id = base << PLOD__BASE_SHIFT | (heap * 2 + (uint64_t)bit);
    c->face = p->face;
    c->level = (uint8_t)(p->level + 1);
    c->birth = frame;
}

static void plod__parent(const plod_sector *c, plod_sector *p)
{
    uint64_t base = c->id >> PLOD__BASE_SHIFT, heap = c->id & PLOD__HEAP_MASK;
    int bit = (int)(heap & 1);
    memset(p, 0, sizeof *p);
    if (!bit) { /* c = (c1, m, c0) */
        p->cu[0] = c->cu[2];
        p->cv[0] = c->cv[2];
        p->cu[1] = c->cu[0];
        p->cv[1] = c->cv[0];
        p->cu[2] = 2 * c->cu[1] - c->cu[2];
        p->cv[2] = 2 * c->cv[1] - c->cv[2];
    } else { /* c = (c2, m, c1) */
        p->cu[0] = 2 * c->cu[1] - c->cu[0];
        p->cv[0] = 2 * c->cv[1] - c->cv[0];
        p->cu[1] = c->cu[2];
        p->cv[1] = c->cv[2];
        p->cu[2] = c->cu[0];
        p->cv[2] = c->cv[0];
    }
    p->id = base << PLOD__BASE_SHIFT | (heap >> 1);
    p->face = c->face;
    p->level = (uint8_t)(c->level - 1);
}

static void plod__apply_bound(plod_sector *s, const plod_bound *b)
{
    s->height_min = b->hmin;
    s->height_max = b->hmax;
}

/* ---- split ----------------------------------------------------------------- */

/* Both leaves share their hypotenuse and have the same level. */
static void plod__split_diamond(plod_refiner *r, size_t i, size_t n)
{
    size_t pair[2] = {i, n};
    plod_sector parents[2] = {r->leaves[i], r->leaves[n]};
    /* edge table, incrementally: the shared hypotenuse goes; a child's own
     * hypotenuse is one of its parent's legs (child 0 keeps the parent's
     * slot, so only child 1's leg is relinked); the children's other two
     * edges are new, four keys each shared by two of the four children */
    int32_t hyp[3];
    plod__leaf_key(r, i, 2, hyp);
    plod__edge_remove(r, hyp, (int32_t)i);
    plod__edge_remove(r, hyp, (int32_t)n);
    int32_t node[2] = {plod__node_add(r, parents[0].id, &r->geom[i].self, r->leaf_parent[i]),
                       plod__node_add(r, parents[1].id, &r->geom[n].self, r->leaf_parent[n])};
    r->node_partner[node[0]] = node[1];
    r->node_partner[node[1]] = node[0];
    for (int k = 0; k < 2; k++) {
        int32_t up = r->node_parent[node[k]];
        if (up >= 0)
            r->node_leaves[up]--; /* that child is a node now */
    }
    size_t child[2][2]; /* [parent][bit] */
    for (int k = 0; k < 2; k++) {
        /* the parent's corners 0..2 and the midpoint 3 of its hypotenuse */
        plod__corner_memo memo;
        plod__load_corners(r, pair[k], &memo);
        for (int bit = 0; bit < 2; bit++) {
            size_t at = bit ? r->count++ : pair[k];
            child[k][bit] = at;
            plod_sector *c = &r->leaves[at];
            plod__child(&parents[k], bit, r->frame, c);
            if (bit == 0) {
                const double scale = 1.0 / (double)PLOD__ONE;
                plod_status st = plod_face_to_dir(r->planet->projection, c->face,
                                                  c->cu[1] * scale, c->cv[1] * scale,
                                                  memo.points.dir[3]);
                (void)st;
                assert(st == PLOD_OK);
                plod__canon(r, c->face, c->cu[1], c->cv[1], memo.canon[3]);
            }
            /* plod__child: corners (parent a, midpoint, parent b) */
            const int idx[3] = {bit ? 2 : 1, 3, bit ? 1 : 0};
            plod__geom *g = &r->geom[at];
            plod_bound_build(&r->setup, c, &memo.points, idx, &g->self);
            plod__store_corners(r, at, &memo, idx);
            g->eval_frame = r->frame - 1;
            r->leaf_parent[at] = node[k];
            plod__apply_bound(c, &g->self);
            if (at != pair[k]) {
                int32_t key[3];
                plod__leaf_key(r, at, 2, key);
                plod__edge_replace(r, key, (int32_t)pair[k], (int32_t)at);
            }
        }
    }
    /* p's children (p1, m, p0), (p2, m, p1); q's (q1, m, p2), (p0, m, q1):
     * edge 0 of each child is edge 1 of the next one around m */
    static const int ring[4][2] = {{0, 0}, {0, 1}, {1, 0}, {1, 1}}; /* [parent, bit] */
    for (int k = 0; k < 4; k++) {
        size_t a = child[ring[k][0]][ring[k][1]];
        size_t b = child[ring[(k + 1) % 4][0]][ring[(k + 1) % 4][1]];
        int32_t key[3];
        plod__leaf_key(r, a, 0, key);
        plod__edge_add_two(r, key, (int32_t)a, (int32_t)b);
    }
    r->splits += 2;
    r->pending[r->pending_count++] = i;
    r->pending[r->pending_count++] = n;
}

static plod_status plod__pending_reserve(plod_refiner *r, size_t extra)
{
    if (r->pending_count + extra <= r->pending_capacity)
        return PLOD_OK;
    size_t capacity = r->pending_capacity ? 2 * r->pending_capacity : 256;
    while (capacity < r->pending_count + extra)
        capacity *= 2;
    size_t *fresh = realloc(r->pending, capacity * sizeof *fresh);
    if (!fresh)
        return PLOD_ERR_NO_MEMORY;
    r->pending = fresh;
    r->pending_capacity = capacity;
    return PLOD_OK;
}

/* Splits leaf i, first splitting the coarser neighbour across its
 * hypotenuse when needed.  Returns 0 when the sector cap stopped it. */
static int plod__split(plod_refiner *r, size_t i)
{
    if (r->leaves[i].level >= PLOD_MAX_LEVEL)
        return 1; /* edge of domain: a no-op */
    for (int attempt = 0; attempt < 2; attempt++) {
        int32_t n = plod__across(r, i, 2);
        assert(n >= 0);
        if (n < 0)
            return 1;
        if (r->leaves[n].level == r->leaves[i].level) {
            if (r->count + 2 > r->max_sectors || plod__reserve(r, 2) != PLOD_OK ||
                plod__node_reserve(r, 2) != PLOD_OK || plod__pending_reserve(r, 2) != PLOD_OK) {
                r->truncated = 1;
                return 0;
            }
            plod__split_diamond(r, i, (size_t)n);
            return 1;
        }
        assert(r->leaves[n].level + 1 == r->leaves[i].level);
        if (!plod__split(r, (size_t)n))
            return 0;
    }
    assert(!"forced split did not produce a diamond");
    return 1;
}

/* ---- merge ----------------------------------------------------------------- */

/* Drops leaf x, already unlinked, moving the last leaf into its slot. */
static void plod__drop_unlinked(plod_refiner *r, size_t x)
{
    size_t last = r->count - 1;
    if (x != last) {
        for (int e = 0; e < 3; e++) {
            int32_t key[3];
            plod__leaf_key(r, last, e, key);
            plod__edge_replace(r, key, (int32_t)last, (int32_t)x);
        }
        r->leaves[x] = r->leaves[last];
        r->geom[x] = r->geom[last];
        r->corners[x] = r->corners[last];
        r->leaf_parent[x] = r->leaf_parent[last];
    }
    r->count--;
}

/* A parent's corners from its child 0 (p1, m, p0) and child 1 (p2, m, p1). */
static plod__corners plod__parent_corners(const plod__corners *c0, const plod__corners *c1)
{
    plod__corners p;
    const plod__corners *from[3] = {c0, c0, c1};
    static const int which[3] = {2, 0, 0};
    p.known = 0;
    for (int k = 0; k < 3; k++) {
        memcpy(p.dir[k], from[k]->dir[which[k]], sizeof p.dir[k]);
        memcpy(p.canon[k], from[k]->canon[which[k]], sizeof p.canon[k]);
        p.height[k] = from[k]->height[which[k]];
        if (from[k]->known & (1u << which[k]))
            p.known |= 1u << k;
    }
    return p;
}

static int plod__same_point(const plod_refiner *r, size_t a, int ka, size_t b, int kb)
{
    return plod__key_eq(r->corners[a].canon[ka], r->corners[b].canon[kb]);
}

/* Tries to merge the diamond whose child-0 leaf is at index ia.  Returns 1
 * if merged (leaves[ia] then holds the restored parent). */
static int plod__try_merge(plod_refiner *r, size_t ia);

/* After a merge restored a leaf at `index`, tries its own diamond (a merge
 * can only become possible when one of its four subtrees collapses). */
static void plod__cascade(plod_refiner *r, size_t index)
{
    const plod_sector *s = &r->leaves[index];
    if (s->level == 0)
        return;
    if (!(s->id & 1)) {
        plod__try_merge(r, index);
        return;
    }
    int32_t sibling = plod__across(r, index, 1); /* child 1's edge (m, c1) */
    if (sibling >= 0 && (r->leaves[sibling].id ^ s->id) == 1)
        plod__try_merge(r, (size_t)sibling);
}

static int plod__merge_diamond(plod_refiner *r, size_t ia, int32_t pi);

static int plod__try_merge(plod_refiner *r, size_t ia)
{
    const plod_sector *a = &r->leaves[ia];
    if (a->level == 0 || (a->id & 1))
        return 0;
    /* necessary conditions that need no edge lookup come first (leaf-child
     * counts, the memoised predicate); every condition is pure, so the
     * order does not change which diamonds merge */
    int32_t pi = r->leaf_parent[ia];
    assert(pi >= 0 && r->nodes[pi].id == plod__parent_id(a->id));
    if (r->node_leaves[pi] != 2 || !plod__allows_merge(r, pi))
        return 0; /* a's sibling is split, or p still wants its split */
    return plod__merge_diamond(r, ia, pi);
}

/* The rest of try_merge: the partner half, then the merge itself. */
static int plod__merge_diamond(plod_refiner *r, size_t ia, int32_t pi)
{
    const plod_sector *a = &r->leaves[ia];
    int level = a->level;
    int32_t ic = plod__across(r, ia, 1);
    if (ic < 0)
        return 0;
    const plod_sector *c = &r->leaves[ic];
    if (c->level != level || !plod__same_point(r, ia, 1, (size_t)ic, 1))
        return 0; /* c is not the partner parent's child (it is split) */
    int32_t qi = r->leaf_parent[ic];
    assert(qi >= 0 && r->nodes[qi].id == plod__parent_id(c->id));
    if (r->node_leaves[qi] != 2 || !plod__allows_merge(r, qi))
        return 0;
    int32_t ib = plod__across(r, ia, 0);
    if (ib < 0)
        return 0;
    const plod_sector *b = &r->leaves[ib];
    if (b->level != level || (a->id ^ b->id) != 1)
        return 0;
    int32_t id_ = plod__across(r, (size_t)ib, 0);
    if (id_ < 0)
        return 0;
    const plod_sector *d = &r->leaves[id_];
    if (d->level != level || (c->id ^ d->id) != 1 || !plod__same_point(r, ia, 1, (size_t)id_, 1))
        return 0;
    const plod__node *pn = &r->nodes[pi], *qn = &r->nodes[qi];

    plod_sector p, q;
    plod__parent(a, &p);
    plod__parent(c, &q);
    plod__geom gp = {.self = pn->bound, .eval_frame = r->frame - 1};
    plod__geom gq = {.self = qn->bound, .eval_frame = r->frame - 1};
    p.birth = q.birth = r->frame;
    plod__apply_bound(&p, &gp.self);
    plod__apply_bound(&q, &gq.self);
    int32_t gp_gq_parent[2] = {r->node_parent[pi], r->node_parent[qi]};
    plod__node_remove(r, pi);
    plod__node_remove(r, qi);
    size_t ib_ = (size_t)ib, ic_ = (size_t)ic, id2 = (size_t)id_;
    /* edge table, incrementally (the reverse of plod__split_diamond): each
     * child's hypotenuse is a leg of its parent, relinked to the parent's
     * slot; the children's other edges go; the parents' shared hypotenuse
     * comes back */
    const size_t child_at[4] = {ia, ib_, ic_, id2};
    for (int x = 0; x < 4; x++) {
        size_t to = x < 2 ? ia : ic_;
        int32_t key[3];
        if (child_at[x] != to) {
            plod__leaf_key(r, child_at[x], 2, key);
            plod__edge_replace(r, key, (int32_t)child_at[x], (int32_t)to);
        }
        for (int e = 0; e < 2; e++) {
            plod__leaf_key(r, child_at[x], e, key);
            plod__edge_remove(r, key, (int32_t)child_at[x]);
        }
    }
    plod__corners cp = plod__parent_corners(&r->corners[ia], &r->corners[ib_]);
    /* a is child 0 of p; c may be either child of q */
    int c_first = !(r->leaves[ic_].id & 1);
    plod__corners cq = plod__parent_corners(&r->corners[c_first ? ic_ : id2],
                                            &r->corners[c_first ? id2 : ic_]);
    r->corners[ia] = cp;
    r->corners[ic_] = cq;
    r->leaves[ia] = p;
    r->geom[ia] = gp;
    r->leaf_parent[ia] = gp_gq_parent[0];
    r->leaves[ic_] = q;
    r->geom[ic_] = gq;
    r->leaf_parent[ic_] = gp_gq_parent[1];
    int32_t hyp[3];
    plod__leaf_key(r, ia, 2, hyp);
    plod__edge_add(r, hyp, (int32_t)ia);
    plod__edge_add(r, hyp, (int32_t)ic_);
    size_t hi = ib_ > id2 ? ib_ : id2, lo = ib_ > id2 ? id2 : ib_;
    size_t at[2] = {ia, ic_};
    for (int k = 0; k < 2; k++) {
        size_t hole = k ? lo : hi, last = r->count - 1;
        for (int j = 0; j < 2; j++)
            if (at[j] == last)
                at[j] = hole;
        plod__drop_unlinked(r, hole);
    }
    for (int k = 0; k < 2; k++) {
        int32_t up = gp_gq_parent[k];
        if (up >= 0)
            r->node_leaves[up]++; /* its child is a leaf again */
    }
    r->merges += 2;
    uint64_t q_id = r->leaves[at[1]].id;
    int32_t q_hyp[3];
    plod__leaf_key(r, at[1], 2, q_hyp);
    plod__cascade(r, at[0]);
    /* the first cascade may have moved q into a hole (or merged p away):
     * q is still on its own hypotenuse edge, found by key */
    size_t slot = plod__edge_find(r, q_hyp);
    assert(slot != (size_t)-1);
    for (int k = 0; k < 2; k++) {
        int32_t leaf = r->edges[slot].leaf[k];
        if (leaf >= 0 && r->leaves[leaf].id == q_id) {
            plod__cascade(r, (size_t)leaf);
            break;
        }
    }
    return 1;
}

/* ---- create / reset ---------------------------------------------------------- */

static void plod__add_base(plod_refiner *r, unsigned base, int face,
                           const int32_t cu[3], const int32_t cv[3])
{
    size_t at = r->count++;
    plod_sector *s = &r->leaves[at];
    memset(s, 0, sizeof *s);
    s->id = (uint64_t)base << PLOD__BASE_SHIFT | 1u;
    s->face = (uint8_t)face;
    s->level = 0;
    s->birth = r->frame;
    for (int k = 0; k < 3; k++) {
        s->cu[k] = cu[k];
        s->cv[k] = cv[k];
    }
    plod__geom *g = &r->geom[at];
    memset(g, 0, sizeof *g);
    plod__compute_bound(r, at, &g->self);
    g->eval_frame = r->frame - 1;
    r->leaf_parent[at] = -1;
    plod__apply_bound(s, &g->self);
    plod__leaf_link(r, at);
}


static plod_status plod__build_base(plod_refiner *r)
{
    r->count = 0;
    r->edge_used = 0;
    r->node_used = 0;
    r->node_top = 0;
    if (r->edges)
        for (size_t i = 0; i <= r->edge_mask; i++)
            r->edges[i].leaf[0] = r->edges[i].leaf[1] = -1;
    plod_status st = plod__reserve(r, 12);
    if (st != PLOD_OK)
        return st;
    const int32_t O = PLOD__ONE;
    if (plod_projection_is_cube(r->planet->projection)) {
        for (int f = 0; f < 6; f++) {
            const int32_t au[3] = {-O, O, O}, av[3] = {-O, -O, O};
            const int32_t bu[3] = {O, -O, -O}, bv[3] = {O, O, -O};
            plod__add_base(r, (unsigned)(2 * f), f, au, av);
            plod__add_base(r, (unsigned)(2 * f + 1), f, bu, bv);
        }
    } else {
        unsigned base = 0;
        for (int q = 0; q < 4; q++) {
            int32_t su = (q & 1) ? -O : O, sv = (q & 2) ? -O : O;
            /* counter-clockwise when su * sv > 0; else swap the ends */
            int flip = (su > 0) != (sv > 0);
            int32_t iu[3] = {0, 0, su}, iv[3] = {sv, 0, 0};
            int32_t ou[3] = {su, su, 0}, ov[3] = {0, sv, sv};
            if (flip) {
                int32_t t;
                t = iu[0]; iu[0] = iu[2]; iu[2] = t;
                t = iv[0]; iv[0] = iv[2]; iv[2] = t;
                t = ou[0]; ou[0] = ou[2]; ou[2] = t;
                t = ov[0]; ov[0] = ov[2]; ov[2] = t;
            }
            plod__add_base(r, base++, 0, iu, iv);
            plod__add_base(r, base++, 0, ou, ov);
        }
    }
    return PLOD_OK;
}

plod_status plod_refiner_create(plod_refiner **out, const plod_planet *planet)
{
    if (!out)
        return PLOD_ERR_NULL;
    *out = NULL;
    plod_status st = plod_planet_check(planet);
    if (st != PLOD_OK)
        return st;
    plod_refiner *r = calloc(1, sizeof *r);
    if (!r)
        return PLOD_ERR_NO_MEMORY;
    r->planet = planet;
    r->frame = 1;
    plod_bound_setup_init(&r->setup, planet);
    for (int f = 0; f < PLOD_FACE_COUNT; f++)
        plod_face_frame(f, r->face_axes[f]);
    st = plod__build_base(r);
    if (st != PLOD_OK) {
        plod_refiner_destroy(r);
        return st;
    }
    *out = r;
    return PLOD_OK;
}

static plod_status plod__order_reserve(plod_refiner *r, size_t need);

plod_status plod_refiner_reserve(plod_refiner *refiner, size_t sectors)
{
    if (!refiner)
        return PLOD_ERR_NULL;
    if (sectors > PLOD_REFINER_MAX_RESERVE)
        return PLOD_ERR_BAD_PARAM;
    plod_refiner *r = refiner;
    size_t old_leaves = r->capacity, old_nodes = r->node_capacity;
    size_t old_pending = r->pending_capacity;
    /* a binary forest over 12 roots: internal nodes = leaves - 12 */
    plod_status st = plod__reserve(r, sectors > r->count ? sectors - r->count : 0);
    if (st == PLOD_OK)
        st = plod__node_reserve(r, sectors > r->node_top ? sectors - r->node_top : 0);
    if (st == PLOD_OK)
        st = plod__pending_reserve(r, sectors > r->pending_count ? sectors - r->pending_count : 0);
    if (st == PLOD_OK)
        st = plod__order_reserve(r, sectors);
    if (st != PLOD_OK)
        return st;
    /* Touch the new tails now: the first faults on fresh pages are what
     * made growth frames slow, and this moves them out of refine(). */
    size_t grown = r->capacity - old_leaves;
    if (grown) {
        memset(r->leaves + old_leaves, 0, grown * sizeof *r->leaves);
        memset(r->geom + old_leaves, 0, grown * sizeof *r->geom);
        memset(r->corners + old_leaves, 0, grown * sizeof *r->corners);
        memset(r->leaf_parent + old_leaves, 0, grown * sizeof *r->leaf_parent);
    }
    grown = r->node_capacity - old_nodes;
    if (grown) {
        memset(r->nodes + old_nodes, 0, grown * sizeof *r->nodes);
        memset(r->node_parent + old_nodes, 0, grown * sizeof *r->node_parent);
        memset(r->node_state + old_nodes, 0, grown);
        memset(r->node_planes + old_nodes, 0, grown);
        memset(r->node_leaves + old_nodes, 0, grown);
        memset(r->node_partner + old_nodes, 0, grown * sizeof *r->node_partner);
    }
    grown = r->pending_capacity - old_pending;
    if (grown) /* the split queue may not exist yet (NULL + 0 is undefined) */
        memset(r->pending + old_pending, 0, grown * sizeof *r->pending);
    return PLOD_OK;
}

void plod_refiner_destroy(plod_refiner *refiner)
{
    if (!refiner)
        return;
    free(refiner->leaves);
    free(refiner->geom);
    free(refiner->corners);
    free(refiner->leaf_parent);
    free(refiner->edges);
    free(refiner->nodes);
    free(refiner->node_parent);
    free(refiner->node_state);
    free(refiner->node_planes);
    free(refiner->node_leaves);
    free(refiner->node_partner);
    free(refiner->pending);
    free(refiner->order);
    free(refiner->order_keys);
    free(refiner->order_scratch);
    free(refiner);
}

void plod_refiner_reset(plod_refiner *refiner)
{
    if (!refiner)
        return;
    refiner->frame++;
    refiner->order_count = 0;
    plod_status st = plod__build_base(refiner);
    (void)st; /* capacity for 12 leaves exists since create */
}

const plod_sector *plod_refiner_sectors(const plod_refiner *refiner, size_t *count)
{
    if (count)
        *count = refiner ? refiner->count : 0;
    return refiner ? refiner->leaves : NULL;
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

/* ---- parallel evaluation ------------------------------------------------------- */

/* P and cull flags of leaves [begin, end), written to their own slots only:
 * pure functions of the bounds, the camera and the parents' plane masks
 * (final after the node sweep), so any split of the work gives the bits of
 * the lazy single-threaded evaluation.  The node sweep itself stays
 * sequential: top-down, a node's plane mask spares its children most plane
 * tests, which a split by index range would lose. */
static void plod__eval_range(void *context, size_t begin, size_t end)
{
    plod_refiner *r = context;
    for (size_t i = begin; i < end; i++) {
        plod__geom *g = &r->geom[i];
        unsigned flags, planes;
        g->eval_split = (uint8_t)plod__wants_split(r, &g->self, r->leaves[i].level, &flags,
                                                   plod__parent_planes(r, r->leaf_parent[i]),
                                                   &planes);
        g->eval_flags = (uint8_t)flags;
        g->eval_frame = r->frame;
    }
}

/* Evaluates every leaf's P and flags on `threads` threads, after the node
 * sweep; below PLOD__PARALLEL_LEAVES leaves (thread start-up, ~10-50 us,
 * would eat the gain) or when no thread can be started the split pass
 * evaluates them as usual. */
#define PLOD__PARALLEL_LEAVES 8192

static void plod__eval_parallel(plod_refiner *r, int threads)
{
    if (threads < 2 || r->count < PLOD__PARALLEL_LEAVES)
        return;
    plod_parallel_for(r->count, threads, plod__eval_range, r);
}

/* ---- update ------------------------------------------------------------------ */

static double plod__now_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e6 + ts.tv_nsec * 1e-3;
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

/* Depth-first key of a sector: its base, then its bisection path
 * left-aligned (the heap's leading 1 at bit 55), so leaves, which never
 * nest, sort in depth-first order: a spatially coherent order that depends
 * on the leaf set alone, not on the order in which splits and merges left
 * them in the leaf array. */
static uint64_t plod__order_key(uint64_t id)
{
    uint64_t heap = id & PLOD__HEAP_MASK;
    int level = plod__id_level(id);
    return (id & ~PLOD__HEAP_MASK) | heap << (PLOD__BASE_SHIFT - 1 - level);
}

static plod_status plod__order_reserve(plod_refiner *r, size_t need)
{
    if (need <= r->order_capacity)
        return PLOD_OK;
    size_t capacity = r->order_capacity ? r->order_capacity : 256;
    while (capacity < need)
        capacity *= 2;
    uint32_t *order = realloc(r->order, capacity * sizeof *order);
    if (!order)
        return PLOD_ERR_NO_MEMORY;
    r->order = order;
    uint32_t *scratch = realloc(r->order_scratch, capacity * sizeof *scratch);
    if (!scratch)
        return PLOD_ERR_NO_MEMORY;
    r->order_scratch = scratch;
    uint64_t *keys = realloc(r->order_keys, 2 * capacity * sizeof *keys);
    if (!keys)
        return PLOD_ERR_NO_MEMORY;
    r->order_keys = keys;
    r->order_capacity = capacity; /* only once all three have grown */
    return PLOD_OK;
}

/* The visible leaves' indices sorted by plod__order_key: an LSD radix sort,
 * 8 bits a pass, skipping the passes in which every key has the same digit
 * (the high bits of a frame's keys mostly agree). */
static plod_status plod__order_visible(plod_refiner *r, size_t visible)
{
    r->order_count = 0;
    if (visible == 0)
        return PLOD_OK; /* the arrays may not exist yet (NULL + 0 is undefined) */
    plod_status st = plod__order_reserve(r, visible);
    if (st != PLOD_OK)
        return st;
    uint64_t *keys = r->order_keys, *keys_out = r->order_keys + r->order_capacity;
    uint32_t *index = r->order, *index_out = r->order_scratch;
    size_t n = 0;
    for (size_t i = 0; i < r->count; i++) {
        if (!(r->leaves[i].flags & PLOD_SECTOR_VISIBLE))
            continue;
        keys[n] = plod__order_key(r->leaves[i].id);
        index[n++] = (uint32_t)i;
    }
    assert(n == visible);
    for (int shift = 0; shift < 64; shift += 8) {
        size_t start[257] = {0};
        for (size_t k = 0; k < n; k++)
            start[(keys[k] >> shift & 0xFF) + 1]++;
        if (start[(keys[0] >> shift & 0xFF) + 1] == n)
            continue; /* one digit for all: this pass keeps the order */
        for (int d = 0; d < 256; d++)
            start[d + 1] += start[d];
        for (size_t k = 0; k < n; k++) {
            size_t to = start[keys[k] >> shift & 0xFF]++;
            keys_out[to] = keys[k];
            index_out[to] = index[k];
        }
        uint64_t *tk = keys; keys = keys_out; keys_out = tk;
        uint32_t *ti = index; index = index_out; index_out = ti;
    }
    if (index != r->order) /* an odd number of passes ran */
        memcpy(r->order, index, n * sizeof *index);
    r->order_count = n;
    return PLOD_OK;
}

static plod_status plod__check_params(const plod_refine_params *p)
{
    if ((unsigned)p->criterion > PLOD_CRITERION_SIDE_DISTANCE)
        return PLOD_ERR_BAD_PARAM;
    if (!(isfinite(p->max_pixel_error) && p->max_pixel_error > 0))
        return PLOD_ERR_BAD_PARAM;
    if (!(isfinite(p->split_border) && p->split_border > 0 &&
          isfinite(p->merge_border) && p->merge_border > 0 &&
          p->merge_border <= p->split_border))
        return PLOD_ERR_BAD_PARAM;
    if (p->template_level < 0 || p->template_level > 7)
        return PLOD_ERR_BAD_PARAM;
    if (p->max_level < 0 || p->max_level > PLOD_MAX_LEVEL)
        return PLOD_ERR_BAD_PARAM;
    if (p->max_sectors < 12)
        return PLOD_ERR_BAD_PARAM;
    if (p->threads < 1 || p->threads > PLOD_REFINE_MAX_THREADS)
        return PLOD_ERR_BAD_PARAM;
    return PLOD_OK;
}

/* ---- one refinement pass; the budget ---------------------------------------------- */

/* The split thresholds of coarsening step `step`: the criterion's threshold
 * times 2^(step / 2) (pixel error, or split border). */
static void plod__set_threshold(plod_refiner *r, const plod_refine_params *params, int step)
{
    plod_bound_view *v = &r->view;
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

/* P* of every internal node in one sequential, top-down sweep (parents come
 * first); P is evaluated only where the parent passes P*.  Then the leaves'
 * P, on threads when there are many. */
static void plod__sweep(plod_refiner *r, const plod_refine_params *params, int step)
{
    r->frame++;
    plod__set_threshold(r, params, step);
    plod__node_compact(r);
    for (size_t k = 0; k < r->node_top; k++) {
        if (!r->nodes[k].id) {
            r->node_state[k] = 0;
            continue;
        }
        int32_t parent = r->node_parent[k];
        if (parent >= 0 && !(r->node_state[parent] & PLOD__STAR_TRUE)) {
            r->node_state[k] = PLOD__STAR_KNOWN; /* P* false, P not needed */
            r->node_planes[k] = 0;
            continue;
        }
        unsigned pk = plod__node_p(r, (int32_t)k, plod__parent_planes(r, parent));
        r->node_state[k] = (uint8_t)((pk & (PLOD__P_KNOWN | PLOD__P_TRUE)) |
                                     PLOD__STAR_KNOWN |
                                     ((pk & PLOD__P_TRUE) ? PLOD__STAR_TRUE : 0u));
    }
    plod__eval_parallel(r, params->threads);
}

/* One pass at coarsening step `step`: merges every diamond whose parents fail
 * P*, then splits every leaf that passes it, stopping (truncated) before the
 * leaves would exceed `cap`.  Untruncated, the result is the unique minimal
 * conforming refinement of {P* true} whatever the refinement was before. */
static void plod__refine_pass(plod_refiner *r, const plod_refine_params *params, int step,
                              size_t cap)
{
    plod__sweep(r, params, step);
    r->max_sectors = cap;
    r->truncated = 0;
    /* merge pass: every diamond whose parents fail the split predicate;
     * downwards, so the leaves moved into holes were already visited, and
     * merges cascade upwards as subtrees collapse */
    for (size_t i = r->count; i-- > 0;) {
        if (i >= r->count)
            i = r->count - 1;
        /* plod__try_merge's first tests, inline: most leaves fail them */
        int32_t pi = r->leaf_parent[i];
        if (pi < 0 || r->node_leaves[pi] != 2)
            continue;
        int32_t qi = r->node_partner[pi]; /* its diamond must merge too */
        if (r->node_leaves[qi] != 2)
            continue;
        if (!params->hysteresis && ((r->node_state[pi] | r->node_state[qi]) & PLOD__STAR_TRUE))
            continue;
        plod__try_merge(r, i);
    }
    /* split pass: one sweep (children appended at the end are swept too);
     * children written in place of earlier leaves are revisited after */
    r->pending_count = 0;
    for (size_t i = 0; i < r->count && !r->truncated; i++) {
        while (!r->truncated && plod__leaf_wants_split(r, i)) {
            size_t before = r->splits;
            plod__split(r, i);
            if (r->splits == before)
                break; /* at PLOD_MAX_LEVEL or truncated */
        }
    }
    while (r->pending_count && !r->truncated) {
        size_t i = r->pending[--r->pending_count];
        while (!r->truncated && plod__leaf_wants_split(r, i)) {
            size_t before = r->splits;
            plod__split(r, i);
            if (r->splits == before)
                break;
        }
    }
}

/* Coarsening steps the budget may take: 2^(64 / 2) times the threshold
 * leaves nothing but the base mesh split. */
#define PLOD__MAX_COARSEN_STEP 64

/* Whether step `step`'s refinement keeps at most `budget` sectors (visible
 * or not); leaves the refiner at it (truncated when it does not fit). */
static int plod__fits(plod_refiner *r, const plod_refine_params *params, int step)
{
    size_t cap = params->budget < params->max_sectors ? params->budget + 1 : params->max_sectors;
    plod__refine_pass(r, params, step, cap);
    return !r->truncated && r->count <= params->budget;
}

/* A lower bound of the sectors step `step` keeps, from the current
 * refinement of a coarser step (a subset of step's, the thresholds being
 * monotone): every leaf that step splits adds at least one sector. */
static size_t plod__sectors_at_least(plod_refiner *r, const plod_refine_params *params,
                                     int step)
{
    plod__sweep(r, params, step);
    size_t n = r->count;
    for (size_t i = 0; i < r->count; i++)
        n += plod__leaf_wants_split(r, i) != 0;
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
static void plod__fit_budget(plod_refiner *r, const plod_refine_params *params)
{
    int step = r->coarsen_step;
    if (step < 0 || step > PLOD__MAX_COARSEN_STEP)
        step = 0;
    const plod_camera *camera = r->view.camera;
    if (r->budget_known && memcmp(&r->budget_camera, camera, sizeof *camera) == 0 &&
        memcmp(&r->budget_params, params, sizeof *params) == 0) {
        /* the same camera and parameters again: the same (unique) step */
        plod__refine_pass(r, params, step, params->max_sectors);
        return;
    }
    if (plod__fits(r, params, step)) {
        while (step > 0) {
            if (plod__sectors_at_least(r, params, step - 1) > params->budget)
                break; /* the finer step cannot fit: no need to build it */
            if (!plod__fits(r, params, step - 1)) {
                plod__fits(r, params, step); /* back to the result */
                break;
            }
            step--;
        }
    } else {
        while (step < PLOD__MAX_COARSEN_STEP && !plod__fits(r, params, ++step))
            ;
        if (r->truncated) /* even the coarsest step does not fit: complete it */
            plod__refine_pass(r, params, step, params->max_sectors);
    }
    r->coarsen_step = step;
    r->budget_camera = *camera;
    r->budget_params = *params;
    r->budget_known = 1;
}

plod_status plod_refiner_update(plod_refiner *r, const plod_camera *camera,
                                const plod_refine_params *params,
                                plod_refine_stats *stats)
{
    if (!r || !camera || !params)
        return PLOD_ERR_NULL;
    plod_status st = plod__check_params(params);
    if (st != PLOD_OK)
        return st;
    double eye_dist = sqrt(camera->position[0] * camera->position[0] +
                           camera->position[1] * camera->position[1] +
                           camera->position[2] * camera->position[2]);
    if (!isfinite(eye_dist) || !(eye_dist > 1e-6 * r->planet->radius))
        return PLOD_ERR_BAD_CAMERA; /* at (or numerically at) the centre */

    double t0 = plod__now_us();
    r->frame++;
    r->params = params;
    plod_bound_view *v = &r->view;
    v->camera = camera;
    v->detail = r->planet->detail;
    memcpy(v->eye, camera->position, sizeof v->eye);
    v->eye_dist = eye_dist;
    for (int k = 0; k < 3; k++)
        v->eye_unit[k] = camera->position[k] / eye_dist;
    double rho = r->setup.occluder;
    v->horizon_on = params->backface_culling && !camera->desc.orthographic && eye_dist > rho;
    double eye_horizon_angle =
        v->horizon_on ? atan2(sqrt((eye_dist - rho) * (eye_dist + rho)), rho) : 0.0;
    v->eye_horizon_cos = cos(eye_horizon_angle);
    v->eye_horizon_sin = sin(eye_horizon_angle);
    v->frustum_culling = params->frustum_culling;
    v->criterion = params->criterion;
    v->split_border = params->split_border;
    v->max_pixel_error = params->max_pixel_error;
    r->merge_ratio = params->merge_border / params->split_border;
    v->error_scale = ldexp(1.0, -params->template_level);
    v->error_scale2 = v->error_scale * v->error_scale;
    v->distance_floor = 1e-9 * r->planet->radius;
    r->splits = r->merges = 0;
    if (params->budget == 0) {
        plod__refine_pass(r, params, 0, params->max_sectors);
        r->coarsen_step = 0;
        r->budget_known = 0;
    } else {
        plod__fit_budget(r, params);
    }
    double t1 = plod__now_us();

    /* culling and statistics */
    plod_refine_stats s;
    memset(&s, 0, sizeof s);
    size_t visible = 0;
    int deepest = 0;
    for (size_t i = 0; i < r->count; i++) {
        plod_sector *sec = &r->leaves[i];
        plod__geom *g = &r->geom[i];
        if (g->eval_frame != r->frame) { /* not visited (truncated pass) */
            unsigned cull_flags;
            unsigned planes;
            g->eval_split = (uint8_t)plod__wants_split(r, &g->self, sec->level,
                                                       &cull_flags, 0, &planes);
            g->eval_flags = (uint8_t)cull_flags;
            g->eval_frame = r->frame;
        }
        unsigned flags = g->eval_flags;
        int sea = r->planet->has_sea_level && sec->height_max <= r->planet->sea_level;
        if (sea)
            flags |= PLOD_SECTOR_SEA;
        deepest = sec->level > deepest ? sec->level : deepest;
        if (flags & PLOD_SECTOR_BACKFACING) {
            sec->flags = (uint16_t)flags;
            continue;
        }
        s.sectors_after_backface++;
        if (flags & PLOD_SECTOR_OUTSIDE_FRUSTUM) {
            sec->flags = (uint16_t)flags;
            continue;
        }
        s.sectors_after_frustum++;
        if (sea) {
            if (params->skip_sea) {
                s.sectors_sea_skipped++;
                sec->flags = (uint16_t)flags;
                continue;
            }
        }
        sec->flags = (uint16_t)(flags | PLOD_SECTOR_VISIBLE);
        visible++;
    }
    if (params->budget > 0 && visible > params->budget) {
        plod__rank *ranks = malloc(visible * sizeof *ranks);
        if (!ranks)
            return PLOD_ERR_NO_MEMORY;
        size_t k = 0;
        for (size_t i = 0; i < r->count; i++)
            if (r->leaves[i].flags & PLOD_SECTOR_VISIBLE)
                ranks[k++] = (plod__rank){plod_bound_distance(&r->view, &r->geom[i].self),
                                          r->leaves[i].id, i};
        qsort(ranks, visible, sizeof *ranks, plod__rank_cmp);
        for (size_t j = params->budget; j < visible; j++) {
            plod_sector *sec = &r->leaves[ranks[j].index];
            sec->flags = (uint16_t)((sec->flags & ~PLOD_SECTOR_VISIBLE) |
                                    PLOD_SECTOR_OVER_BUDGET);
        }
        free(ranks);
        visible = params->budget;
    }
    st = plod__order_visible(r, visible);
    if (st != PLOD_OK)
        return st;
    double t2 = plod__now_us();
    s.sectors_total = r->count;
    s.sectors_after_budget = visible;
    s.splits = r->splits;
    s.merges = r->merges;
    s.refine_us = t1 - t0;
    s.cull_us = t2 - t1;
    s.max_level_reached = deepest;
    s.truncated = r->truncated;
    s.frame = r->frame;
    r->view.camera = NULL;
    r->params = NULL;
    if (stats)
        *stats = s;
    return PLOD_OK;
}

size_t plod_refiner_memory_bytes(const plod_refiner *r)
{
    if (!r)
        return 0;
    size_t bytes = sizeof *r + r->capacity * (sizeof(plod_sector) + sizeof(plod__geom) +
                                              sizeof(int32_t));
    if (r->edges)
        bytes += (r->edge_mask + 1) * sizeof(plod__edge);
    bytes += r->capacity * sizeof(plod__corners);
    bytes += r->node_capacity * (sizeof(plod__node) + 2 * sizeof(int32_t) + 3);
    bytes += r->pending_capacity * sizeof(size_t);
    bytes += r->order_capacity * (2 * sizeof(uint32_t) + 2 * sizeof(uint64_t));
    return bytes;
}

/* ---- invariants ---------------------------------------------------------------- */

plod_status plod_refiner_check(const plod_refiner *r)
{
    if (!r)
        return PLOD_ERR_NULL;
    size_t links = 0;
    for (size_t i = 0; i < r->count; i++) {
        const plod_sector *s = &r->leaves[i];
        for (int e = 0; e < 3; e++) {
            int32_t key[3];
            plod__edge_key(r, s, e, key);
            size_t slot = plod__edge_find(r, key);
            if (slot == (size_t)-1)
                return PLOD_ERR_BAD_PARAM;
            const plod__edge *edge = &r->edges[slot];
            if (edge->leaf[0] != (int32_t)i && edge->leaf[1] != (int32_t)i)
                return PLOD_ERR_BAD_PARAM;
            int32_t other = edge->leaf[0] == (int32_t)i ? edge->leaf[1] : edge->leaf[0];
            if (other < 0 || (size_t)other >= r->count)
                return PLOD_ERR_BAD_PARAM; /* closed sphere: always two */
            int dl = (int)r->leaves[other].level - (int)s->level;
            if (dl < -1 || dl > 1)
                return PLOD_ERR_BAD_PARAM;
        }
        /* the corner cache holds the bits a fresh computation gives */
        double fresh[3][3];
        plod_sector_corners(r->planet, s, fresh);
        const plod__corners *cc = &r->corners[i];
        if (memcmp(fresh, cc->dir, sizeof fresh) != 0)
            return PLOD_ERR_BAD_PARAM;
        for (int k = 0; k < 3; k++) {
            int32_t point[3];
            plod__canon(r, s->face, s->cu[k], s->cv[k], point);
            if (!plod__key_eq(point, cc->canon[k]))
                return PLOD_ERR_BAD_PARAM;
        }
        for (int k = 0; k < 3; k++) {
            double h = plod_planet_map_height(r->planet, cc->dir[k]);
            if ((cc->known & (1u << k)) && memcmp(&h, &cc->height[k], sizeof h) != 0)
                return PLOD_ERR_BAD_PARAM;
        }
        int32_t parent = r->leaf_parent[i];
        if ((s->level > 0) != (parent >= 0))
            return PLOD_ERR_BAD_PARAM;
        if (parent >= 0 && ((size_t)parent >= r->node_top ||
                            r->nodes[parent].id != plod__parent_id(s->id)))
            return PLOD_ERR_BAD_PARAM;
        links += 3;
    }
    size_t used = 0;
    for (size_t i = 0; i <= r->edge_mask; i++)
        if (!plod__slot_empty(&r->edges[i]))
            used++;
    if (used != r->edge_used || 2 * used != links)
        return PLOD_ERR_BAD_PARAM;
    /* a binary forest with count leaves over the base sectors */
    size_t bases = plod_projection_is_cube(r->planet->projection) ? 12 : 8;
    if (r->node_used + bases != r->count)
        return PLOD_ERR_BAD_PARAM;
    size_t live = 0;
    for (size_t k = 0; k < r->node_top; k++) {
        const plod__node *n = &r->nodes[k];
        if (!n->id)
            continue;
        live++;
        int top = plod__id_level(n->id) == 0;
        int32_t parent = r->node_parent[k];
        if (top != (parent < 0))
            return PLOD_ERR_BAD_PARAM;
        if (!top && ((size_t)parent >= k ||
                     r->nodes[parent].id != plod__parent_id(n->id)))
            return PLOD_ERR_BAD_PARAM;
        int32_t partner = r->node_partner[k];
        if (partner < 0 || (size_t)partner >= r->node_top || !r->nodes[partner].id ||
            r->node_partner[partner] != (int32_t)k || partner == (int32_t)k ||
            plod__id_level(r->nodes[partner].id) != plod__id_level(n->id))
            return PLOD_ERR_BAD_PARAM;
    }
    if (live != r->node_used)
        return PLOD_ERR_BAD_PARAM;
    /* leaf-child counts: every node's children, leaves or nodes, add to 2 */
    uint8_t *count = calloc(r->node_top ? r->node_top : 1, 1);
    if (!count)
        return PLOD_ERR_NO_MEMORY;
    for (size_t i = 0; i < r->count; i++)
        if (r->leaf_parent[i] >= 0)
            count[r->leaf_parent[i]]++;
    plod_status st = PLOD_OK;
    for (size_t k = 0; k < r->node_top; k++)
        if (r->nodes[k].id && count[k] != r->node_leaves[k])
            st = PLOD_ERR_BAD_PARAM;
    free(count);
    if (st != PLOD_OK)
        return st;
    return PLOD_OK;
}

/* ---- horizon-distance correction ---------------------------------------------- */

void plod_recommended_clip(const plod_planet *planet, const plod_camera *camera,
                           double *clip_start, double *clip_end)
{
    double hmin, hmax;
    plod_planet_height_range(planet, &hmin, &hmax);
    const double *p = camera->position;
    double dist = hypot(hypot(p[0], p[1]), p[2]); /* no overflow below ~1e308 */
    double top = planet->radius + hmax, rho = planet->radius + hmin;
    double corner = 1.0;
    if (!camera->desc.orthographic) {
        double tx = fmax(fabs(camera->tan_left), fabs(camera->tan_right));
        double ty = fmax(fabs(camera->tan_bottom), fabs(camera->tan_top));
        corner = 1.0 / sqrt(1.0 + tx * tx + ty * ty);
    }
    /* nearest terrain is at least (dist - top) away; depth >= distance *
     * cos(corner angle) inside the frustum */
    double clearance = dist - top;
    double near_ = clearance > 0 ? 0.9 * clearance * corner : 0.0;
    double floor_ = fmax(1e-3, 1e-7 * planet->radius);
    if (clearance <= 0)
        floor_ = 1e-3;
    if (!(near_ >= floor_)) /* also NaN: infinite clearance times a zero corner */
        near_ = floor_;
    /* farthest visible terrain: the horizon of the occluder ball plus the
     * distance at which the highest peak still rises above it */
    double far_;
    if (dist > rho) {
        double horizon = sqrt((dist - rho) * (dist + rho));
        double beyond = sqrt((top - rho) * (top + rho));
        far_ = (horizon + beyond) * 1.01;
    } else {
        far_ = (dist + top) * 1.01;
    }
    if (far_ <= near_)
        far_ = near_ * 2.0;
    *clip_start = near_;
    *clip_end = far_;
}
