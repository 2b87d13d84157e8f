/* plod_lodtree.h -- the LOD tree of the refinement (lodtree.c): implicit
 * longest-edge-bisection ids, the leaf and internal-node stores with
 * their conforming neighbour links, split and merge, and the
 * invariants.  Mechanics only: when to split or merge, the limits on
 * splits and each frame's evaluation of the leaves are the LOD update's
 * (lodupdate.c), which drives the tree through these calls and keeps its
 * per-leaf state in arrays of its own (plod_lodtree_observer).  Internal
 * to the core: bindings use plod_refine.h.
 *
 * Bit rules (libleb-style heap ids):
 *   id        = base << 56 | heap,  heap = 1 << level | path bits
 *   child(b)  = heap * 2 + b        parent = heap >> 1
 *
 * Edge of the domain (documented no-ops, as in libleb): a split at
 * PLOD_MAX_LEVEL changes nothing and returns 1; a merge of a base sector
 * (level 0, no diamond parent) or of a diamond that is not whole (a
 * sibling or the partner is split further) changes nothing and returns 0.
 */
#ifndef PLOD_LODTREE_H
#define PLOD_LODTREE_H

#include <assert.h>
#include "plod_bound.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- ids ---------------------------------------------------------------------- */

#define PLOD_LODTREE_BASE_SHIFT 56
#define PLOD_LODTREE_HEAP_MASK (((uint64_t)1 << PLOD_LODTREE_BASE_SHIFT) - 1)

static inline int plod_lodtree_id_level(uint64_t id)
{
    assert(id & PLOD_LODTREE_HEAP_MASK);
    return 63 - __builtin_clzll(id & PLOD_LODTREE_HEAP_MASK);
}

static inline uint64_t plod_lodtree_parent_id(uint64_t id)
{
    return (id & ~PLOD_LODTREE_HEAP_MASK) | ((id & PLOD_LODTREE_HEAP_MASK) >> 1);
}

/* ---- the stores ----------------------------------------------------------------- */

/* A leaf's bound. */
typedef struct plod_lodtree_leaf {
    plod_bound self;
} plod_lodtree_leaf;

/* A leaf's corner directions and, once a bound needed them, heights: kept
 * so that a split computes only the new midpoint (the same calls on the
 * same corners, so the same bits as computing them again). */
typedef struct plod_lodtree_corners {
    double dir[3][3];
    double height[3];
    int32_t canon[3][3]; /* canonical points (shared corners compare equal) */
    unsigned known; /* bit k: height[k] computed */
} plod_lodtree_corners;

/* An internal (split) node and its bound. */
typedef struct plod_lodtree_node {
    uint64_t id;        /* 0 = free slot */
    plod_bound bound;
} plod_lodtree_node;

/* node_state bits: the LOD update's, valid for the current frame (cleared
 * by its sweep).  A split makes a node from a leaf that the update may
 * have evaluated this frame (plod_lodtree_observer.split): the node has
 * the leaf's bound, level and parent, so the same predicate. */
enum {
    PLOD_NODE_P_KNOWN = 1, PLOD_NODE_P_TRUE = 2,        /* P(node) */
    PLOD_NODE_STAR_KNOWN = 4, PLOD_NODE_STAR_TRUE = 8   /* P*(node) */
};

/* Whoever keeps per-leaf data in arrays parallel to the tree's (the LOD
 * update's evaluation of each leaf) follows the tree's changes of leaf
 * slots through these calls.  The tree makes them on the thread that
 * splits or merges, never from plod_lodtree_settle. */
typedef struct plod_lodtree_observer {
    void *context;
    /* room for slots [0, capacity); the tree grows only once it succeeds */
    plod_status (*reserve)(void *context, size_t capacity);
    /* the leaf at `slot` becomes internal node `node`; called before a
     * split writes the node's children (child 0 into `slot`) */
    void (*split)(void *context, size_t slot, int32_t node);
    /* `slot` holds a leaf made now (a split's child, a merge's parent, a
     * base sector of a reset) */
    void (*made)(void *context, size_t slot);
    /* the leaf at `from` moved to `to` (a merge filling a hole) */
    void (*moved)(void *context, size_t from, size_t to);
} plod_lodtree_observer;

/* Given: planet (borrowed).  Returned: everything else.  The arrays are
 * read directly by the LOD update; only these calls change their shape. */
typedef struct plod_lodtree {
    const plod_planet *planet;
    plod_bound_setup setup;
    int face_axes[PLOD_FACE_COUNT][3][3]; /* plod_face_frame of each face */
    plod_sector *leaves;
    plod_lodtree_leaf *geom;
    plod_lodtree_corners *corners; /* apart from geom: only splits and merges
                                      read it, the per-frame sweeps do not */
    int32_t *leaf_parent;        /* parent's index in nodes[], -1 at level 0;
                                    apart from geom: the merge sweep reads
                                    it for every leaf */
    size_t count, capacity;
    int32_t (*neighbours)[3];    /* the leaf across each edge (edge e joins
                                    corners e and e + 1 mod 3); apart from
                                    geom: only splits and merges read it */
    struct plod_lodtree_watch *watches; /* leaves merges will cascade from,
                                    kept up to date as leaves move */
    /* deferred splits: while `defer` is set, a split leaves its children's
     * bounds and corner caches to a job (plod_lodtree_settle) */
    int defer;
    struct plod_lodtree_job *jobs;
    size_t job_count, job_capacity;
    int32_t *leaf_job;           /* per leaf: the job that settles it, or -1 */
    size_t *pending;             /* leaves a split wrote children into in
                                    place (the split pass revisits them) */
    size_t pending_count, pending_capacity;
    plod_lodtree_node *nodes;    /* internal nodes, dense, parents first */
    int32_t *node_parent;        /* parent's index (< own), -1 at level 0 */
    uint8_t *node_state;         /* the LOD update's per-frame flags; 0 for
                                    a new node, not moved by compaction */
    uint8_t *node_planes;        /* the LOD update's per-frame plane mask;
                                    as node_state */
    uint8_t *node_leaves;        /* how many of its 2 children are leaves */
    int32_t *node_partner;       /* the other parent of its diamond: both
                                    are made by one split, removed by one
                                    merge */
    int32_t *node_child0;        /* the slot of its child 0 while that child
                                    is a leaf (kept as leaves move) */
    size_t node_capacity, node_top, node_used; /* node_top: slots in use or
                                                  holes (id 0) */
    uint32_t frame;              /* refine frame: the births of sectors */
    size_t splits, merges;       /* counted since the caller zeroed them */
    plod_lodtree_observer observer; /* all NULL: none */
} plod_lodtree;

/* ---- create / destroy ----------------------------------------------------------- */

/* The base sectors of the planet's projection (12 on the cube, 8 for CAR).
 * tree is zeroed first; on failure it holds nothing to free. */
plod_status plod_lodtree_init(plod_lodtree *tree, const plod_planet *planet);
void plod_lodtree_free(plod_lodtree *tree);
/* Back to the base sectors (the frame counter advances); keeps capacity. */
void plod_lodtree_reset(plod_lodtree *tree);
/* Room for `sectors` leaves, their links, nodes and split queue, allocated
 * and touched now.  PLOD_ERR_NO_MEMORY leaves the tree usable. */
plod_status plod_lodtree_reserve(plod_lodtree *tree, size_t sectors);
size_t plod_lodtree_memory_bytes(const plod_lodtree *tree);

/* ---- split / merge ------------------------------------------------------------- */

/* The caller's limits on a split (its budget policy). */
typedef struct plod_lodtree_limits {
    size_t max_sectors;          /* a split that would exceed it stops */
    size_t max_splits;           /* 0, or: a diamond split that would take
                                    `splits` over it stops (the first one of
                                    a count from 0 never does) */
} plod_lodtree_limits;

enum {
    PLOD_LODTREE_SPLIT_LIMITED = -1, /* max_splits stopped it */
    PLOD_LODTREE_SPLIT_CAPPED = 0,   /* max_sectors (or memory) stopped it */
    PLOD_LODTREE_SPLIT_DONE = 1
};

/* Splits leaf i and, first, the coarser neighbours across its hypotenuse
 * (forced splits: the result conforms).  Leaf i's slot receives child 0 of
 * its split, its index is pushed on `pending`, new leaves are appended.
 * Returns a PLOD_LODTREE_SPLIT_* value; at PLOD_MAX_LEVEL a no-op returning
 * PLOD_LODTREE_SPLIT_DONE.  A stop leaves the forced splits made before it. */
int plod_lodtree_split(plod_lodtree *tree, size_t i, const plod_lodtree_limits *limits);

/* Deferred splits (as many threads can compute the bounds of the children
 * as there are jobs).  plod_lodtree_defer(tree, 1) starts them: each split
 * records a job for each of its two parents whose children it makes in
 * place (ids, corners, links) without their bounds, leaf_job[] naming the
 * job; a split of an unsettled leaf settles it first.  Settling a job
 * computes what an immediate split would have (the same calls on the same
 * corners: the same bits).  plod_lodtree_defer(tree, 0) settles the jobs
 * left and ends.  Jobs write only their own children: distinct jobs may be
 * settled on distinct threads while nothing else changes the tree. */
void plod_lodtree_defer(plod_lodtree *tree, int on);
/* Settles job `job`; returns 0 if it was settled before. */
int plod_lodtree_settle(plod_lodtree *tree, size_t job);
/* The slot that job `job` made child `bit` (0, 1) in. */
size_t plod_lodtree_job_child(const plod_lodtree *tree, size_t job, int bit);

/* Whether internal node `node` may lose its children (the LOD update's
 * policy, asked by the merge below). */
typedef int (*plod_lodtree_merge_fn)(void *context, int32_t node);
/* Merges the diamond whose child-0 leaf is at `leaf` back into its two
 * parents if it is whole and allows_merge agrees for both, then tries the
 * parents' own diamonds (cascade).  Returns 1 if it merged (leaves moved
 * to fill the holes: indices above the merged ones may change), 0
 * otherwise, a no-op (child 1 or level 0 given, a diamond not whole, or
 * refused). */
int plod_lodtree_try_merge(plod_lodtree *tree, size_t leaf, plod_lodtree_merge_fn allows_merge,
                           void *context);
/* Squeezes the holes of removed nodes out of the node arrays (keeping
 * parents before children) when they outnumber the live nodes.  node_state
 * and node_planes are not carried: call before the frame's evaluation. */
void plod_lodtree_compact(plod_lodtree *tree);

/* ---- invariants ------------------------------------------------------------------ */

/* plod_refiner_check's tests (plod_refine.h); PLOD_OK, PLOD_ERR_BAD_PARAM
 * when one fails, or PLOD_ERR_NO_MEMORY (its scratch array). */
plod_status plod_lodtree_check(const plod_lodtree *tree);

#ifdef __cplusplus
}
#endif
#endif /* PLOD_LODTREE_H */
