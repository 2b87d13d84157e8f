/* lodtree.c -- the LOD tree of HRTMR (Hybrid Real-Time Mesh Refinement):
 * leaves only, with implicit longest-edge-bisection ids.
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
 * Adjacency: every leaf links to the leaf across each of its edges (a
 * conforming mesh: always exactly one), so forced splits and diamond
 * lookups are one read, across faces too.  Splits and merges keep the links
 * as ROAM's triangle bintree keeps its base, left and right neighbours
 * (M. Duchaineau et al., "ROAMing Terrain: Real-time Optimally Adapting
 * Meshes", IEEE Visualization, 1997): a child inherits its parent's leg,
 * the ring around the split point links the four children, and the outer
 * neighbours are relinked.  Corners keep
 * canonical integer points on the cube (or octahedron) surface, equal from
 * both faces of a cube edge, which the checks compare.
 *
 * Nodes: the bounds of the internal (split) nodes are kept in a dense
 * array in creation order (removed ones leave holes until the next
 * compaction, which keeps the order), so a parent always precedes its
 * children; every leaf and node holds its parent's index.
 *
 * Edge of the domain: a split at PLOD_MAX_LEVEL and a merge without a
 * whole diamond are no-ops (plod_lodtree.h), not errors.
 *
 * A split costs one new projected point (leaves cache their corners'
 * directions, heights and canonical points) and two bounds.
 */
#include "plod_lodtree.h"

#include <assert.h>
#include <stdlib.h>
#include <string.h>

#define PLOD__ONE ((int32_t)1 << PLOD_COORD_BITS)

/* ---- canonical points and neighbour links -------------------------------- */

static void plod__canon(const plod_lodtree *t, int face, int32_t u, int32_t v,
                        int32_t out[3])
{
    if (plod_projection_is_cube(t->planet->projection)) {
        const int(*ax)[3] = t->face_axes[face];
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

static int plod__key_eq(const int32_t a[3], const int32_t b[3])
{
    return a[0] == b[0] && a[1] == b[1] && a[2] == b[2];
}

/* Whether edge ea of leaf a and edge eb of leaf b join the same two
 * points, in opposite directions (as two counter-clockwise neighbours'). */
static int plod__same_edge(const plod_lodtree *t, size_t a, int ea, size_t b, int eb)
{
    const int32_t(*pa)[3] = t->corners[a].canon, (*pb)[3] = t->corners[b].canon;
    return plod__key_eq(pa[ea], pb[(eb + 1) % 3]) && plod__key_eq(pa[(ea + 1) % 3], pb[eb]);
}

/* The other leaf on edge `e` of leaf `index`. */
static int32_t plod__across(const plod_lodtree *t, size_t index, int e)
{
    return t->neighbours[index][e];
}

/* Leaf `leaf`'s link that pointed at `from` points at `to` instead (two
 * sectors of a conforming mesh share at most one edge, so the link is
 * found by value). */
static void plod__relink(plod_lodtree *t, int32_t leaf, int32_t from, int32_t to)
{
    assert(leaf >= 0 && (size_t)leaf < t->count);
    int32_t *link = t->neighbours[leaf];
    for (int e = 0; e < 3; e++) {
        if (link[e] == from) {
            link[e] = to;
            return;
        }
    }
    assert(!"leaf not linked to its neighbour");
}

/* A merge's watch on a leaf it will cascade from: plod__drop_unlinked
 * updates `index` when it moves that leaf. */
typedef struct plod_lodtree_watch {
    size_t index;
    struct plod_lodtree_watch *outer;
} plod_lodtree_watch;

/* Room for `extra` more leaves. */
static plod_status plod__reserve(plod_lodtree *t, size_t extra)
{
    size_t need = t->count + extra;
    if (need > t->capacity) {
        size_t capacity = t->capacity ? t->capacity : 64;
        while (capacity < need)
            capacity *= 2;
        plod_sector *leaves = realloc(t->leaves, capacity * sizeof *leaves);
        if (!leaves)
            return PLOD_ERR_NO_MEMORY;
        t->leaves = leaves;
        plod_lodtree_leaf *geom = realloc(t->geom, capacity * sizeof *geom);
        if (!geom)
            return PLOD_ERR_NO_MEMORY;
        t->geom = geom;
        plod_lodtree_corners *corners = realloc(t->corners, capacity * sizeof *corners);
        if (!corners)
            return PLOD_ERR_NO_MEMORY;
        t->corners = corners;
        int32_t *parent = realloc(t->leaf_parent, capacity * sizeof *parent);
        if (!parent)
            return PLOD_ERR_NO_MEMORY;
        t->leaf_parent = parent;
        int32_t(*neighbours)[3] = realloc(t->neighbours, capacity * sizeof *neighbours);
        if (!neighbours)
            return PLOD_ERR_NO_MEMORY;
        t->neighbours = neighbours;
        int32_t *job = realloc(t->leaf_job, capacity * sizeof *job);
        if (!job)
            return PLOD_ERR_NO_MEMORY;
        t->leaf_job = job;
        if (t->observer.reserve && t->observer.reserve(t->observer.context, capacity) != PLOD_OK)
            return PLOD_ERR_NO_MEMORY;
        t->capacity = capacity; /* only once all six (and the observer's) have grown */
    }
    return PLOD_OK;
}

/* ---- internal nodes ----------------------------------------------------------- */

static plod_status plod__node_reserve(plod_lodtree *t, size_t extra)
{
    size_t need = t->node_top + extra;
    if (need <= t->node_capacity)
        return PLOD_OK;
    if (need > (size_t)INT32_MAX)
        return PLOD_ERR_NO_MEMORY;
    size_t capacity = t->node_capacity ? t->node_capacity : 64;
    while (capacity < need)
        capacity *= 2;
    plod_lodtree_node *fresh = realloc(t->nodes, capacity * sizeof *fresh);
    if (!fresh)
        return PLOD_ERR_NO_MEMORY;
    t->nodes = fresh;
    int32_t *parent = realloc(t->node_parent, capacity * sizeof *parent);
    if (!parent)
        return PLOD_ERR_NO_MEMORY;
    t->node_parent = parent;
    uint8_t *state = realloc(t->node_state, capacity);
    if (!state)
        return PLOD_ERR_NO_MEMORY;
    t->node_state = state;
    uint8_t *planes = realloc(t->node_planes, capacity);
    if (!planes)
        return PLOD_ERR_NO_MEMORY;
    t->node_planes = planes;
    uint8_t *leaves = realloc(t->node_leaves, capacity);
    if (!leaves)
        return PLOD_ERR_NO_MEMORY;
    t->node_leaves = leaves;
    int32_t *partner = realloc(t->node_partner, capacity * sizeof *partner);
    if (!partner)
        return PLOD_ERR_NO_MEMORY;
    t->node_partner = partner;
    int32_t *child0 = realloc(t->node_child0, capacity * sizeof *child0);
    if (!child0)
        return PLOD_ERR_NO_MEMORY;
    t->node_child0 = child0;
    t->node_capacity = capacity; /* only once all have grown */
    return PLOD_OK;
}

/* Capacity ensured by plod__node_reserve; returns the node's index. */
static int32_t plod__node_add(plod_lodtree *t, uint64_t id, const plod_bound *bound,
                              int32_t parent)
{
    assert(t->node_top < t->node_capacity);
    assert(parent < (int32_t)t->node_top);
    int32_t at = (int32_t)t->node_top++; /* after its parent: creation order */
    plod_lodtree_node *n = &t->nodes[at];
    n->id = id;
    n->bound = *bound;
    t->node_parent[at] = parent;
    t->node_state[at] = 0; /* evaluated on demand this frame */
    t->node_planes[at] = 0;
    t->node_leaves[at] = 2;
    t->node_used++;
    return at;
}

static void plod__node_remove(plod_lodtree *t, int32_t at)
{
    assert(at >= 0 && (size_t)at < t->node_top && t->nodes[at].id);
    t->nodes[at].id = 0; /* a hole until plod_lodtree_compact */
    t->node_used--;
}

/* Squeezes the holes out of the node arrays, keeping the order (parents
 * before children), and renumbers the parent indices of nodes and leaves.
 * Runs when holes outnumber live nodes: amortised O(1) per removal. */
void plod_lodtree_compact(plod_lodtree *t)
{
    if (t->node_top < 64 || t->node_top < 2 * t->node_used)
        return;
    int32_t *map = malloc(t->node_top * sizeof *map);
    if (!map)
        return; /* the holes stay: only memory, never correctness */
    size_t next = 0;
    for (size_t k = 0; k < t->node_top; k++) {
        if (!t->nodes[k].id) {
            map[k] = -1;
            continue;
        }
        int32_t parent = t->node_parent[k];
        assert(parent < (int32_t)k);
        map[k] = (int32_t)next;
        t->nodes[next] = t->nodes[k]; /* next <= k: in place */
        t->node_parent[next] = parent >= 0 ? map[parent] : -1;
        t->node_leaves[next] = t->node_leaves[k];
        t->node_partner[next] = t->node_partner[k]; /* renumbered below */
        t->node_child0[next] = t->node_child0[k];
        next++;
    }
    for (size_t k = 0; k < next; k++)
        t->node_partner[k] = map[t->node_partner[k]];
    for (size_t i = 0; i < t->count; i++)
        if (t->leaf_parent[i] >= 0)
            t->leaf_parent[i] = map[t->leaf_parent[i]];
    assert(next == t->node_used);
    t->node_top = next;
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
static void plod__store_corners(plod_lodtree *t, size_t at, const plod__corner_memo *memo,
                                const int idx[3])
{
    plod_lodtree_corners *c = &t->corners[at];
    c->known = 0;
    for (int k = 0; k < 3; k++) {
        memcpy(c->dir[k], memo->points.dir[idx[k]], sizeof c->dir[k]);
        memcpy(c->canon[k], memo->canon[idx[k]], sizeof c->canon[k]);
        c->height[k] = memo->points.height[idx[k]];
        if (memo->points.known & (1u << idx[k]))
            c->known |= 1u << k;
    }
}

static void plod__load_corners(const plod_lodtree *t, size_t at, plod__corner_memo *memo)
{
    const plod_lodtree_corners *c = &t->corners[at];
    memcpy(memo->points.dir, c->dir, sizeof c->dir);
    memcpy(memo->canon, c->canon, sizeof c->canon);
    memcpy(memo->points.height, c->height, sizeof c->height);
    memo->points.known = c->known & 7u;
}

/* A deferred split of one parent (plod_lodtree_defer): the parent's
 * corners, and the slots of the children that wait for their bounds. */
typedef struct plod_lodtree_job {
    plod__corner_memo memo;
    size_t child[2];
    int settled;
} plod_lodtree_job;

static plod_status plod__job_reserve(plod_lodtree *t, size_t extra)
{
    if (t->job_count + extra <= t->job_capacity)
        return PLOD_OK;
    plod_lodtree_job *fresh =
        plod_grow(t->jobs, &t->job_capacity, t->job_count + extra, sizeof *fresh, 256);
    if (!fresh)
        return PLOD_ERR_NO_MEMORY;
    t->jobs = fresh;
    return PLOD_OK;
}

/* Bound of the leaf at `at` from scratch; fills its corner cache. */
static void plod__compute_bound(plod_lodtree *t, size_t at, plod_bound *b)
{
    plod__corner_memo memo;
    memo.points.known = 0;
    const plod_sector *s = &t->leaves[at];
    plod_sector_corners(t->planet, s, memo.points.dir);
    for (int k = 0; k < 3; k++)
        plod__canon(t, s->face, s->cu[k], s->cv[k], memo.canon[k]);
    static const int idx[3] = {0, 1, 2};
    plod_bound_build(&t->setup, s, &memo.points, idx, b);
    plod__store_corners(t, at, &memo, idx);
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
    uint64_t base = p->id >> PLOD_LODTREE_BASE_SHIFT, heap = p->id & PLOD_LODTREE_HEAP_MASK;
    c->id = base << PLOD_LODTREE_BASE_SHIFT | (heap * 2 + (uint64_t)bit);
    c->face = p->face;
    c->level = (uint8_t)(p->level + 1);
    c->birth = frame;
}

static void plod__parent(const plod_sector *c, plod_sector *p)
{
    uint64_t base = c->id >> PLOD_LODTREE_BASE_SHIFT, heap = c->id & PLOD_LODTREE_HEAP_MASK;
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
    p->id = base << PLOD_LODTREE_BASE_SHIFT | (heap >> 1);
    p->face = c->face;
    p->level = (uint8_t)(c->level - 1);
}

static void plod__apply_bound(plod_sector *s, const plod_bound *b)
{
    s->height_min = b->hmin;
    s->height_max = b->hmax;
}

/* ---- split ----------------------------------------------------------------- */

/* What a split computes for the two children of one parent, made at slots
 * at[0] and at[1] (memo: the parent's corners): the midpoint of the
 * parent's hypotenuse, the children's bounds, corner caches and height
 * ranges.  Writes only the children's slots. */
static void plod__settle_children(plod_lodtree *t, plod__corner_memo *memo, const size_t at[2])
{
    const plod_sector *c0 = &t->leaves[at[0]];
    const double scale = 1.0 / (double)PLOD__ONE;
    plod_status st = plod_face_to_dir(t->planet->projection, c0->face, c0->cu[1] * scale,
                                      c0->cv[1] * scale, memo->points.dir[3]);
    (void)st;
    assert(st == PLOD_OK);
    plod__canon(t, c0->face, c0->cu[1], c0->cv[1], memo->canon[3]);
    for (int bit = 0; bit < 2; bit++) {
        /* plod__child: corners (parent a, midpoint, parent b) */
        const int idx[3] = {bit ? 2 : 1, 3, bit ? 1 : 0};
        plod_sector *c = &t->leaves[at[bit]];
        plod_lodtree_leaf *g = &t->geom[at[bit]];
        plod_bound_build(&t->setup, c, &memo->points, idx, &g->self);
        plod__store_corners(t, at[bit], memo, idx);
        plod__apply_bound(c, &g->self);
    }
}

int plod_lodtree_settle(plod_lodtree *t, size_t job)
{
    assert(job < t->job_count);
    plod_lodtree_job *j = &t->jobs[job];
    if (j->settled)
        return 0;
    plod__settle_children(t, &j->memo, j->child);
    t->leaf_job[j->child[0]] = t->leaf_job[j->child[1]] = -1;
    j->settled = 1;
    return 1;
}

size_t plod_lodtree_job_child(const plod_lodtree *t, size_t job, int bit)
{
    assert(job < t->job_count && (bit == 0 || bit == 1));
    return t->jobs[job].child[bit];
}

void plod_lodtree_defer(plod_lodtree *t, int on)
{
    if (!on) {
        for (size_t j = 0; j < t->job_count; j++)
            plod_lodtree_settle(t, j);
    }
    t->job_count = 0;
    t->defer = on;
}

/* A leaf about to be split (or to give its bound to a node) is settled. */
static void plod__settle_leaf(plod_lodtree *t, size_t i)
{
    if (t->leaf_job[i] >= 0)
        plod_lodtree_settle(t, (size_t)t->leaf_job[i]);
}

/* Both leaves share their hypotenuse and have the same level. */
static void plod__split_diamond(plod_lodtree *t, size_t i, size_t n)
{
    size_t pair[2] = {i, n};
    plod_sector parents[2] = {t->leaves[i], t->leaves[n]};
    /* links: a child's hypotenuse is one of its parent's legs (child 0
     * keeps the parent's slot, so only child 1's neighbour is relinked);
     * the children's other two edges join them around the midpoint */
    int32_t legs[2][2] = {{t->neighbours[i][0], t->neighbours[i][1]},
                          {t->neighbours[n][0], t->neighbours[n][1]}};
    int32_t node[2] = {plod__node_add(t, parents[0].id, &t->geom[i].self, t->leaf_parent[i]),
                       plod__node_add(t, parents[1].id, &t->geom[n].self, t->leaf_parent[n])};
    t->node_partner[node[0]] = node[1];
    t->node_partner[node[1]] = node[0];
    t->node_child0[node[0]] = (int32_t)i; /* child 0 keeps its parent's slot */
    t->node_child0[node[1]] = (int32_t)n;
    if (t->observer.split)
        for (int k = 0; k < 2; k++)
            t->observer.split(t->observer.context, pair[k], node[k]);
    for (int k = 0; k < 2; k++) {
        int32_t up = t->node_parent[node[k]];
        if (up >= 0)
            t->node_leaves[up]--; /* that child is a node now */
    }
    size_t child[2][2]; /* [parent][bit] */
    for (int k = 0; k < 2; k++) {
        /* the parent's corners 0..2 and the midpoint 3 of its hypotenuse */
        plod__corner_memo memo;
        plod__load_corners(t, pair[k], &memo);
        for (int bit = 0; bit < 2; bit++) {
            size_t at = bit ? t->count++ : pair[k];
            child[k][bit] = at;
            plod__child(&parents[k], bit, t->frame, &t->leaves[at]);
            t->leaf_parent[at] = node[k];
            t->neighbours[at][2] = legs[k][bit];
            if (at != pair[k])
                plod__relink(t, legs[k][bit], (int32_t)pair[k], (int32_t)at);
            if (t->observer.made)
                t->observer.made(t->observer.context, at);
        }
        if (t->defer) {
            plod_lodtree_job *job = &t->jobs[t->job_count];
            job->memo = memo;
            job->child[0] = child[k][0];
            job->child[1] = child[k][1];
            job->settled = 0;
            t->leaf_job[child[k][0]] = t->leaf_job[child[k][1]] = (int32_t)t->job_count++;
        } else {
            plod__settle_children(t, &memo, child[k]);
            t->leaf_job[child[k][0]] = t->leaf_job[child[k][1]] = -1;
        }
    }
    /* p's children (p1, m, p0), (p2, m, p1); q's (q1, m, p2), (p0, m, q1):
     * edge 0 of each child is edge 1 of the next one around m */
    static const int ring[4][2] = {{0, 0}, {0, 1}, {1, 0}, {1, 1}}; /* [parent, bit] */
    for (int k = 0; k < 4; k++) {
        size_t a = child[ring[k][0]][ring[k][1]];
        size_t b = child[ring[(k + 1) % 4][0]][ring[(k + 1) % 4][1]];
        t->neighbours[a][0] = (int32_t)b;
        t->neighbours[b][1] = (int32_t)a;
    }
    t->splits += 2;
    t->pending[t->pending_count++] = i;
    t->pending[t->pending_count++] = n;
}

static plod_status plod__pending_reserve(plod_lodtree *t, size_t extra)
{
    if (t->pending_count + extra <= t->pending_capacity)
        return PLOD_OK;
    size_t *fresh = plod_grow(t->pending, &t->pending_capacity, t->pending_count + extra,
                              sizeof *fresh, 256);
    if (!fresh)
        return PLOD_ERR_NO_MEMORY;
    t->pending = fresh;
    return PLOD_OK;
}

/* Splits leaf i, first splitting the coarser neighbour across its
 * hypotenuse when needed. */
int plod_lodtree_split(plod_lodtree *t, size_t i, const plod_lodtree_limits *limits)
{
    if (t->leaves[i].level >= PLOD_MAX_LEVEL)
        return PLOD_LODTREE_SPLIT_DONE; /* edge of domain: a no-op */
    plod__settle_leaf(t, i);
    for (int attempt = 0; attempt < 2; attempt++) {
        int32_t n = plod__across(t, i, 2);
        assert(n >= 0);
        if (n < 0)
            return PLOD_LODTREE_SPLIT_DONE;
        plod__settle_leaf(t, (size_t)n);
        if (t->leaves[n].level == t->leaves[i].level) {
            /* a diamond splits two sectors; the first of an update always
             * may (progress whatever the limit) */
            if (limits->max_splits && t->splits > 0 && t->splits + 2 > limits->max_splits)
                return PLOD_LODTREE_SPLIT_LIMITED;
            if (t->count + 2 > limits->max_sectors || plod__reserve(t, 2) != PLOD_OK ||
                plod__node_reserve(t, 2) != PLOD_OK || plod__pending_reserve(t, 2) != PLOD_OK ||
                (t->defer && plod__job_reserve(t, 2) != PLOD_OK))
                return PLOD_LODTREE_SPLIT_CAPPED;
            plod__split_diamond(t, i, (size_t)n);
            return PLOD_LODTREE_SPLIT_DONE;
        }
        assert(t->leaves[n].level + 1 == t->leaves[i].level);
        int forced = plod_lodtree_split(t, (size_t)n, limits);
        if (forced != PLOD_LODTREE_SPLIT_DONE)
            return forced;
    }
    assert(!"forced split did not produce a diamond");
    return PLOD_LODTREE_SPLIT_DONE;
}

/* ---- merge ----------------------------------------------------------------- */

/* Drops leaf x, which no leaf links to any more, moving the last leaf
 * into its slot. */
static void plod__drop_unlinked(plod_lodtree *t, size_t x)
{
    size_t last = t->count - 1;
    if (x != last) {
        for (int e = 0; e < 3; e++)
            plod__relink(t, t->neighbours[last][e], (int32_t)last, (int32_t)x);
        memcpy(t->neighbours[x], t->neighbours[last], sizeof t->neighbours[x]);
        t->leaves[x] = t->leaves[last];
        t->geom[x] = t->geom[last];
        if (t->observer.moved)
            t->observer.moved(t->observer.context, last, x);
        t->corners[x] = t->corners[last];
        t->leaf_parent[x] = t->leaf_parent[last];
        t->leaf_job[x] = t->leaf_job[last];
        if (t->leaf_parent[x] >= 0 && !(t->leaves[x].id & 1))
            t->node_child0[t->leaf_parent[x]] = (int32_t)x;
        for (plod_lodtree_watch *w = t->watches; w; w = w->outer)
            if (w->index == last)
                w->index = x;
    }
    t->count--;
}

/* A parent's corners from its child 0 (p1, m, p0) and child 1 (p2, m, p1). */
static plod_lodtree_corners plod__parent_corners(const plod_lodtree_corners *c0, const plod_lodtree_corners *c1)
{
    plod_lodtree_corners p;
    const plod_lodtree_corners *from[3] = {c0, c0, c1};
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

static int plod__same_point(const plod_lodtree *t, size_t a, int ka, size_t b, int kb)
{
    return plod__key_eq(t->corners[a].canon[ka], t->corners[b].canon[kb]);
}

/* Tries to merge the diamond whose child-0 leaf is at index ia.  Returns 1
 * if merged (leaves[ia] then holds the restored parent). */
/* The LOD update's merge policy, handed down through a cascade. */
typedef struct plod__merge_policy {
    plod_lodtree_merge_fn allows;
    void *context;
} plod__merge_policy;

static int plod__try_merge(plod_lodtree *t, size_t ia, const plod__merge_policy *m);

/* After a merge restored a leaf at `index`, tries its own diamond (a merge
 * can only become possible when one of its four subtrees collapses). */
static void plod__cascade(plod_lodtree *t, size_t index, const plod__merge_policy *m)
{
    const plod_sector *s = &t->leaves[index];
    if (s->level == 0)
        return;
    if (!(s->id & 1)) {
        plod__try_merge(t, index, m);
        return;
    }
    int32_t sibling = plod__across(t, index, 1); /* child 1's edge (m, c1) */
    if (sibling >= 0 && (t->leaves[sibling].id ^ s->id) == 1)
        plod__try_merge(t, (size_t)sibling, m);
}

static int plod__merge_diamond(plod_lodtree *t, size_t ia, int32_t pi,
                               const plod__merge_policy *m);

static int plod__try_merge(plod_lodtree *t, size_t ia, const plod__merge_policy *m)
{
    const plod_sector *a = &t->leaves[ia];
    if (a->level == 0 || (a->id & 1))
        return 0;
    /* necessary conditions that need no edge lookup come first (leaf-child
     * counts, the memoised predicate); every condition is pure, so the
     * order does not change which diamonds merge */
    int32_t pi = t->leaf_parent[ia];
    assert(pi >= 0 && t->nodes[pi].id == plod_lodtree_parent_id(a->id));
    if (t->node_leaves[pi] != 2 || !m->allows(m->context, pi))
        return 0; /* a's sibling is split, or p still wants its split */
    return plod__merge_diamond(t, ia, pi, m);
}

/* The rest of try_merge: the partner half, then the merge itself. */
static int plod__merge_diamond(plod_lodtree *t, size_t ia, int32_t pi,
                               const plod__merge_policy *m)
{
    const plod_sector *a = &t->leaves[ia];
    int level = a->level;
    int32_t ic = plod__across(t, ia, 1);
    if (ic < 0)
        return 0;
    const plod_sector *c = &t->leaves[ic];
    if (c->level != level || !plod__same_point(t, ia, 1, (size_t)ic, 1))
        return 0; /* c is not the partner parent's child (it is split) */
    int32_t qi = t->leaf_parent[ic];
    assert(qi >= 0 && t->nodes[qi].id == plod_lodtree_parent_id(c->id));
    if (t->node_leaves[qi] != 2 || !m->allows(m->context, qi))
        return 0;
    int32_t ib = plod__across(t, ia, 0);
    if (ib < 0)
        return 0;
    const plod_sector *b = &t->leaves[ib];
    if (b->level != level || (a->id ^ b->id) != 1)
        return 0;
    int32_t id_ = plod__across(t, (size_t)ib, 0);
    if (id_ < 0)
        return 0;
    const plod_sector *d = &t->leaves[id_];
    if (d->level != level || (c->id ^ d->id) != 1 || !plod__same_point(t, ia, 1, (size_t)id_, 1))
        return 0;
    const plod_lodtree_node *pn = &t->nodes[pi], *qn = &t->nodes[qi];

    plod_sector p, q;
    plod__parent(a, &p);
    plod__parent(c, &q);
    plod_lodtree_leaf gp = {.self = pn->bound};
    plod_lodtree_leaf gq = {.self = qn->bound};
    p.birth = q.birth = t->frame;
    plod__apply_bound(&p, &gp.self);
    plod__apply_bound(&q, &gq.self);
    int32_t gp_gq_parent[2] = {t->node_parent[pi], t->node_parent[qi]};
    plod__node_remove(t, pi);
    plod__node_remove(t, qi);
    size_t ib_ = (size_t)ib, ic_ = (size_t)ic, id2 = (size_t)id_;
    /* a is child 0 of p; c may be either child of q */
    int c_first = !(t->leaves[ic_].id & 1);
    /* links (the reverse of plod__split_diamond): each child's hypotenuse
     * is a leg of its parent, whose neighbour is relinked to the parent's
     * slot; the parents share their hypotenuse again */
    const size_t child_at[2][2] = {{ia, ib_}, {c_first ? ic_ : id2, c_first ? id2 : ic_}};
    const size_t parent_at[2] = {ia, ic_};
    for (int k = 0; k < 2; k++) {
        int32_t legs[2] = {t->neighbours[child_at[k][0]][2], t->neighbours[child_at[k][1]][2]};
        for (int bit = 0; bit < 2; bit++)
            if (child_at[k][bit] != parent_at[k])
                plod__relink(t, legs[bit], (int32_t)child_at[k][bit], (int32_t)parent_at[k]);
        t->neighbours[parent_at[k]][0] = legs[0];
        t->neighbours[parent_at[k]][1] = legs[1];
        t->neighbours[parent_at[k]][2] = (int32_t)parent_at[1 - k];
    }
    plod_lodtree_corners cp = plod__parent_corners(&t->corners[ia], &t->corners[ib_]);
    plod_lodtree_corners cq = plod__parent_corners(&t->corners[c_first ? ic_ : id2],
                                            &t->corners[c_first ? id2 : ic_]);
    t->corners[ia] = cp;
    t->corners[ic_] = cq;
    t->leaves[ia] = p;
    t->geom[ia] = gp;
    t->leaf_parent[ia] = gp_gq_parent[0];
    t->leaf_job[ia] = -1;
    if (gp_gq_parent[0] >= 0 && !(p.id & 1))
        t->node_child0[gp_gq_parent[0]] = (int32_t)ia;
    t->leaves[ic_] = q;
    t->geom[ic_] = gq;
    if (t->observer.made) {
        t->observer.made(t->observer.context, ia);
        t->observer.made(t->observer.context, ic_);
    }
    t->leaf_parent[ic_] = gp_gq_parent[1];
    t->leaf_job[ic_] = -1;
    if (gp_gq_parent[1] >= 0 && !(q.id & 1))
        t->node_child0[gp_gq_parent[1]] = (int32_t)ic_;
    size_t hi = ib_ > id2 ? ib_ : id2, lo = ib_ > id2 ? id2 : ib_;
    size_t at[2] = {ia, ic_};
    for (int k = 0; k < 2; k++) {
        size_t hole = k ? lo : hi, last = t->count - 1;
        for (int j = 0; j < 2; j++)
            if (at[j] == last)
                at[j] = hole;
        plod__drop_unlinked(t, hole);
    }
    for (int k = 0; k < 2; k++) {
        int32_t up = gp_gq_parent[k];
        if (up >= 0)
            t->node_leaves[up]++; /* its child is a leaf again */
    }
    t->merges += 2;
    /* the first cascade may move q into a hole: a watch follows it */
    uint64_t q_id = t->leaves[at[1]].id;
    plod_lodtree_watch q_watch = {at[1], t->watches};
    t->watches = &q_watch;
    plod__cascade(t, at[0], m);
    t->watches = q_watch.outer;
    if (q_watch.index < t->count && t->leaves[q_watch.index].id == q_id)
        plod__cascade(t, q_watch.index, m);
    return 1;
}

/* ---- create / reset ---------------------------------------------------------- */

static void plod__add_base(plod_lodtree *t, unsigned base, int face,
                           const int32_t cu[3], const int32_t cv[3])
{
    size_t at = t->count++;
    plod_sector *s = &t->leaves[at];
    memset(s, 0, sizeof *s);
    s->id = (uint64_t)base << PLOD_LODTREE_BASE_SHIFT | 1u;
    s->face = (uint8_t)face;
    s->level = 0;
    s->birth = t->frame;
    for (int k = 0; k < 3; k++) {
        s->cu[k] = cu[k];
        s->cv[k] = cv[k];
    }
    plod_lodtree_leaf *g = &t->geom[at];
    memset(g, 0, sizeof *g);
    plod__compute_bound(t, at, &g->self);
    if (t->observer.made)
        t->observer.made(t->observer.context, at);
    t->leaf_parent[at] = -1;
    t->leaf_job[at] = -1;
    plod__apply_bound(s, &g->self);
}

/* Links the base sectors: each edge to the one other base edge joining the
 * same two points (a dozen sectors: by comparison). */
static void plod__link_base(plod_lodtree *t)
{
    for (size_t i = 0; i < t->count; i++) {
        for (int e = 0; e < 3; e++) {
            t->neighbours[i][e] = -1;
            for (size_t j = 0; j < t->count && t->neighbours[i][e] < 0; j++)
                for (int f = 0; f < 3; f++)
                    if (j != i && plod__same_edge(t, i, e, j, f))
                        t->neighbours[i][e] = (int32_t)j;
            assert(t->neighbours[i][e] >= 0);
        }
    }
}

static plod_status plod__build_base(plod_lodtree *t)
{
    t->count = 0;
    t->node_used = 0;
    t->node_top = 0;
    t->watches = NULL;
    plod_status st = plod__reserve(t, 12);
    if (st != PLOD_OK)
        return st;
    const int32_t O = PLOD__ONE;
    if (plod_projection_is_cube(t->planet->projection)) {
        for (int f = 0; f < 6; f++) {
            const int32_t au[3] = {-O, O, O}, av[3] = {-O, -O, O};
            const int32_t bu[3] = {O, -O, -O}, bv[3] = {O, O, -O};
            plod__add_base(t, (unsigned)(2 * f), f, au, av);
            plod__add_base(t, (unsigned)(2 * f + 1), f, bu, bv);
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
            plod__add_base(t, base++, 0, iu, iv);
            plod__add_base(t, base++, 0, ou, ov);
        }
    }
    plod__link_base(t);
    return PLOD_OK;
}

/* ---- create / destroy ----------------------------------------------------------- */

plod_status plod_lodtree_init(plod_lodtree *t, const plod_planet *planet)
{
    memset(t, 0, sizeof *t);
    t->planet = planet;
    t->frame = 1;
    plod_bound_setup_init(&t->setup, planet);
    for (int f = 0; f < PLOD_FACE_COUNT; f++)
        plod_face_frame(f, t->face_axes[f]);
    plod_status st = plod__build_base(t);
    if (st != PLOD_OK)
        plod_lodtree_free(t);
    return st;
}

void plod_lodtree_free(plod_lodtree *t)
{
    free(t->leaves);
    free(t->geom);
    free(t->corners);
    free(t->leaf_parent);
    free(t->neighbours);
    free(t->leaf_job);
    free(t->jobs);
    free(t->nodes);
    free(t->node_parent);
    free(t->node_state);
    free(t->node_planes);
    free(t->node_leaves);
    free(t->node_partner);
    free(t->node_child0);
    free(t->pending);
    memset(t, 0, sizeof *t);
}

void plod_lodtree_reset(plod_lodtree *t)
{
    t->frame++;
    plod_status st = plod__build_base(t);
    (void)st; /* capacity for 12 leaves exists since init */
}

plod_status plod_lodtree_reserve(plod_lodtree *t, size_t sectors)
{
    size_t old_leaves = t->capacity, old_nodes = t->node_capacity;
    size_t old_pending = t->pending_capacity;
    /* a binary forest over 12 roots: internal nodes = leaves - 12 */
    plod_status st = plod__reserve(t, sectors > t->count ? sectors - t->count : 0);
    if (st == PLOD_OK)
        st = plod__node_reserve(t, sectors > t->node_top ? sectors - t->node_top : 0);
    if (st == PLOD_OK)
        st = plod__pending_reserve(t, sectors > t->pending_count ? sectors - t->pending_count : 0);
    size_t old_jobs = t->job_capacity;
    if (st == PLOD_OK) /* a frame's deferred splits: a quarter of the sectors covers most */
        st = plod__job_reserve(t, sectors / 4 > t->job_count ? sectors / 4 - t->job_count : 0);
    if (st != PLOD_OK)
        return st;
    if (t->job_capacity > old_jobs)
        memset(t->jobs + old_jobs, 0, (t->job_capacity - old_jobs) * sizeof *t->jobs);
    /* Touch the new tails now: the first faults on fresh pages are what
     * made growth frames slow, and this moves them out of the update. */
    size_t grown = t->capacity - old_leaves;
    if (grown) {
        memset(t->leaves + old_leaves, 0, grown * sizeof *t->leaves);
        memset(t->geom + old_leaves, 0, grown * sizeof *t->geom);
        memset(t->corners + old_leaves, 0, grown * sizeof *t->corners);
        memset(t->leaf_parent + old_leaves, 0, grown * sizeof *t->leaf_parent);
        memset(t->neighbours + old_leaves, 0, grown * sizeof *t->neighbours);
        memset(t->leaf_job + old_leaves, 0xff, grown * sizeof *t->leaf_job); /* -1 */
    }
    grown = t->node_capacity - old_nodes;
    if (grown) {
        memset(t->nodes + old_nodes, 0, grown * sizeof *t->nodes);
        memset(t->node_parent + old_nodes, 0, grown * sizeof *t->node_parent);
        memset(t->node_state + old_nodes, 0, grown);
        memset(t->node_planes + old_nodes, 0, grown);
        memset(t->node_leaves + old_nodes, 0, grown);
        memset(t->node_partner + old_nodes, 0, grown * sizeof *t->node_partner);
        memset(t->node_child0 + old_nodes, 0, grown * sizeof *t->node_child0);
    }
    grown = t->pending_capacity - old_pending;
    if (grown) /* the split queue may not exist yet (NULL + 0 is undefined) */
        memset(t->pending + old_pending, 0, grown * sizeof *t->pending);
    return PLOD_OK;
}

size_t plod_lodtree_memory_bytes(const plod_lodtree *t)
{
    size_t bytes = t->capacity * (sizeof(plod_sector) + sizeof(plod_lodtree_leaf) +
                                  sizeof(int32_t) + sizeof *t->neighbours);
    bytes += t->capacity * sizeof(plod_lodtree_corners);
    bytes += t->node_capacity * (sizeof(plod_lodtree_node) + 3 * sizeof(int32_t) + 3);
    bytes += t->pending_capacity * sizeof(size_t);
    bytes += t->capacity * sizeof *t->leaf_job + t->job_capacity * sizeof(plod_lodtree_job);
    return bytes;
}

/* ---- merge, the public entry ------------------------------------------------------ */

int plod_lodtree_try_merge(plod_lodtree *t, size_t leaf, plod_lodtree_merge_fn allows_merge,
                           void *context)
{
    const plod__merge_policy m = {allows_merge, context};
    return plod__try_merge(t, leaf, &m);
}

/* ---- invariants ---------------------------------------------------------------- */

plod_status plod_lodtree_check(const plod_lodtree *t)
{
    if (t->defer || t->job_count)
        return PLOD_ERR_BAD_PARAM; /* deferred splits left unsettled */
    for (size_t i = 0; i < t->count; i++) {
        const plod_sector *s = &t->leaves[i];
        if (t->leaf_job[i] != -1)
            return PLOD_ERR_BAD_PARAM;
        /* the corner cache first: the links are checked on its points */
        double fresh[3][3];
        plod_sector_corners(t->planet, s, fresh);
        const plod_lodtree_corners *cc = &t->corners[i];
        if (memcmp(fresh, cc->dir, sizeof fresh) != 0)
            return PLOD_ERR_BAD_PARAM;
        for (int k = 0; k < 3; k++) {
            int32_t point[3];
            plod__canon(t, s->face, s->cu[k], s->cv[k], point);
            if (!plod__key_eq(point, cc->canon[k]))
                return PLOD_ERR_BAD_PARAM;
        }
    }
    for (size_t i = 0; i < t->count; i++) {
        const plod_sector *s = &t->leaves[i];
        /* closed sphere: every edge has a leaf across, joining the same two
         * points and linked back over that edge alone */
        for (int e = 0; e < 3; e++) {
            int32_t other = t->neighbours[i][e];
            if (other < 0 || (size_t)other >= t->count || other == (int32_t)i)
                return PLOD_ERR_BAD_PARAM;
            int back = 0, f_back = -1;
            for (int f = 0; f < 3; f++)
                if (t->neighbours[other][f] == (int32_t)i)
                    back++, f_back = f;
            if (back != 1 || !plod__same_edge(t, i, e, (size_t)other, f_back))
                return PLOD_ERR_BAD_PARAM;
            int dl = (int)t->leaves[other].level - (int)s->level;
            if (dl < -1 || dl > 1)
                return PLOD_ERR_BAD_PARAM;
        }
        /* the corner cache holds the bits a fresh computation gives */
        const plod_lodtree_corners *cc = &t->corners[i];
        for (int k = 0; k < 3; k++) {
            double h = plod_planet_map_height(t->planet, cc->dir[k]);
            if ((cc->known & (1u << k)) && memcmp(&h, &cc->height[k], sizeof h) != 0)
                return PLOD_ERR_BAD_PARAM;
        }
        int32_t parent = t->leaf_parent[i];
        if ((s->level > 0) != (parent >= 0))
            return PLOD_ERR_BAD_PARAM;
        if (parent >= 0 && ((size_t)parent >= t->node_top ||
                            t->nodes[parent].id != plod_lodtree_parent_id(s->id)))
            return PLOD_ERR_BAD_PARAM;
    }
    /* a binary forest with count leaves over the base sectors */
    size_t bases = plod_projection_is_cube(t->planet->projection) ? 12 : 8;
    if (t->node_used + bases != t->count)
        return PLOD_ERR_BAD_PARAM;
    size_t live = 0;
    for (size_t k = 0; k < t->node_top; k++) {
        const plod_lodtree_node *n = &t->nodes[k];
        if (!n->id)
            continue;
        live++;
        int top = plod_lodtree_id_level(n->id) == 0;
        int32_t parent = t->node_parent[k];
        if (top != (parent < 0))
            return PLOD_ERR_BAD_PARAM;
        if (!top && ((size_t)parent >= k ||
                     t->nodes[parent].id != plod_lodtree_parent_id(n->id)))
            return PLOD_ERR_BAD_PARAM;
        int32_t partner = t->node_partner[k];
        if (partner < 0 || (size_t)partner >= t->node_top || !t->nodes[partner].id ||
            t->node_partner[partner] != (int32_t)k || partner == (int32_t)k ||
            plod_lodtree_id_level(t->nodes[partner].id) != plod_lodtree_id_level(n->id))
            return PLOD_ERR_BAD_PARAM;
    }
    if (live != t->node_used)
        return PLOD_ERR_BAD_PARAM;
    /* leaf-child counts: every node's children, leaves or nodes, add to 2 */
    uint8_t *count = calloc(t->node_top ? t->node_top : 1, 1);
    if (!count)
        return PLOD_ERR_NO_MEMORY;
    for (size_t i = 0; i < t->count; i++) {
        int32_t parent = t->leaf_parent[i];
        if (parent < 0)
            continue;
        count[parent]++;
        /* a child-0 leaf is where its parent says */
        if (!(t->leaves[i].id & 1) && t->node_child0[parent] != (int32_t)i) {
            free(count);
            return PLOD_ERR_BAD_PARAM;
        }
    }
    plod_status st = PLOD_OK;
    for (size_t k = 0; k < t->node_top; k++)
        if (t->nodes[k].id && count[k] != t->node_leaves[k])
            st = PLOD_ERR_BAD_PARAM;
    free(count);
    if (st != PLOD_OK)
        return st;
    return PLOD_OK;
}
