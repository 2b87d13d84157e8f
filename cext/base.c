/* base.c -- the threads of plod_base.h: the fork-join loop, whose threads
 * are started per call (tens of microseconds: callers use it only for work
 * far above that, and keep below their own thresholds on one thread), and
 * the persistent workers, which wait between loops. */
#include "plod_base.h"
#include "plod_platform.h"

#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>

typedef struct plod__block {
    plod_range_fn range;
    void *context;
    size_t begin, end;
} plod__block;

static void plod__run_block(void *arg)
{
    const plod__block *b = arg;
    b->range(b->context, b->begin, b->end);
}

void plod_parallel_for(size_t count, int threads, plod_range_fn range, void *context)
{
    if (count == 0 || !range)
        return;
    size_t n = threads < 1 ? 1 : (size_t)threads;
    if (n > PLOD_MAX_THREADS)
        n = PLOD_MAX_THREADS;
    if (n > count)
        n = count;
    plod__block blocks[PLOD_MAX_THREADS];
    plod_thread ids[PLOD_MAX_THREADS];
    int started[PLOD_MAX_THREADS];
    for (size_t t = 0; t < n; t++)
        blocks[t] = (plod__block){range, context, count * t / n, count * (t + 1) / n};
    for (size_t t = 1; t < n; t++)
        started[t] = plod_thread_start(&ids[t], plod__run_block, &blocks[t]);
    plod__run_block(&blocks[0]);
    for (size_t t = 1; t < n; t++) {
        if (started[t])
            plod_thread_join(&ids[t]);
        else
            plod__run_block(&blocks[t]); /* no thread: do it here */
    }
}

/* ---- persistent workers ------------------------------------------------------ */

/* An idle worker looks for a loop every PLOD__POLL_NS; between
 * plod_workers_begin and plod_workers_end it spins instead (PLOD__SPIN_NS
 * at most).  Idle for PLOD__IDLE_NS, it sleeps on a condition variable
 * until plod_workers_begin or a loop.  Its own timer wakes a polling worker
 * on its own CPU: a wake through the condition variable, while the caller
 * keeps its CPU busy, took ~0.5-1 ms on a 2-CPU machine (the wakee waits
 * behind the caller), a polling worker answers plod_workers_begin within
 * ~0.15 ms.  Spinning only within begin..end and PLOD__LINGER_NS after
 * it: longer, a spinning thread slowed the caller's other work; the
 * linger covers the step from one call to the next of a frame (a refine,
 * then its emission), which a polling worker would join ~0.1 ms late, the
 * whole of a small emission. */
#define PLOD__SPIN_NS 2000000
#define PLOD__LINGER_NS 100000
#define PLOD__POLL_NS 100000
#define PLOD__IDLE_NS 100000000
#define PLOD__BACK_SHIFT 20
#define PLOD__GEN_SHIFT 40
#define PLOD__MAX_CHUNKS ((1u << 20) - 1)
#define PLOD__FIELD (((uint64_t)1 << 20) - 1)

struct plod_workers {
    int count;               /* workers started */
    plod_thread ids[PLOD_MAX_THREADS];
    unsigned long pid;       /* the creator's process: after fork() the
                                workers are gone */
    plod_mutex lock;
    plod_cond wake;
    atomic_int sleeping;     /* workers asleep or going to sleep */
    atomic_uint_fast64_t hint; /* bumped by plod_workers_begin */
    atomic_int spin;         /* 1 between plod_workers_begin and _end */
    atomic_uint_fast64_t linger_until; /* clock: spin on after _end until then */
    atomic_int quit;
    /* the loop: `next` holds its generation, its first unclaimed chunk and
     * one past its last (PLOD__GEN_SHIFT, PLOD__BACK_SHIFT), so a claim
     * from either end is one compare-exchange that fails for any other
     * loop */
    plod_range_fn range;
    void *context;
    size_t count_items, grain;
    atomic_uint_fast64_t next;
    atomic_size_t done;      /* chunks of the current loop that have run */
    uint64_t generation;     /* the caller's: the current loop's */
};

static void plod__relax(void)
{
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#elif defined(__aarch64__)
    __asm__ __volatile__("yield");
#endif
}

/* Claims and runs chunks of generation `generation` until none is left:
 * the caller from the front, the workers from the back (after a
 * successful claim the loop's fields are its own: the caller changes them
 * only once every chunk has run).  From both ends, each thread keeps
 * mostly the same items from one loop to the next (a refine's leaves, frame
 * after frame): what it writes stays in its own core's cache instead of
 * moving to the other thread's. */
static void plod__run_chunks(plod_workers *w, uint64_t generation, int from_front)
{
    for (;;) {
        uint_fast64_t seen = atomic_load(&w->next);
        uint_fast64_t front = seen & PLOD__FIELD, back = seen >> PLOD__BACK_SHIFT & PLOD__FIELD;
        if ((seen >> PLOD__GEN_SHIFT) != generation || front >= back)
            return;
        uint_fast64_t claimed =
            from_front ? seen + 1 : seen - ((uint_fast64_t)1 << PLOD__BACK_SHIFT);
        if (!atomic_compare_exchange_weak(&w->next, &seen, claimed))
            continue;
        size_t chunk = (size_t)(from_front ? front : back - 1);
        size_t begin = chunk * w->grain;
        size_t end = begin + w->grain < w->count_items ? begin + w->grain : w->count_items;
        w->range(w->context, begin, end);
        atomic_fetch_add(&w->done, 1);
    }
}

static uint64_t plod__generation(plod_workers *w)
{
    return atomic_load(&w->next) >> PLOD__GEN_SHIFT;
}

static void plod__worker(void *arg)
{
    plod_workers *w = arg;
    uint64_t served = 0; /* the last generation it looked at */
    uint_fast64_t hint = atomic_load(&w->hint);
    int spinning = 0;
    uint64_t idle = plod_clock_ns();
    for (unsigned k = 1; !atomic_load(&w->quit); k++) {
        uint64_t generation = plod__generation(w);
        if (generation != served) {
            served = generation;
            plod__run_chunks(w, generation, 0);
            spinning = 1; /* for the next loop while the caller wants it (below) */
            idle = plod_clock_ns();
            continue;
        }
        if (atomic_load(&w->hint) != hint) {
            hint = atomic_load(&w->hint);
            spinning = 1;
            idle = plod_clock_ns();
        }
        if (spinning && (k & 255)) {
            plod__relax();
            continue;
        }
        uint64_t now = plod_clock_ns();
        int wanted = atomic_load(&w->spin) || now < atomic_load(&w->linger_until);
        if (spinning && (!wanted || now - idle > PLOD__SPIN_NS)) {
            spinning = 0; /* no loop came while spinning: poll */
            idle = now;
        }
        if (spinning)
            continue;
        if (now - idle <= PLOD__IDLE_NS) {
            plod_sleep_ns(PLOD__POLL_NS);
            continue;
        }
        plod_mutex_lock(&w->lock);
        atomic_fetch_add(&w->sleeping, 1);
        /* sleeping is raised before the last look, the caller publishes
         * before looking at sleeping: one of the two sees the other */
        while (!atomic_load(&w->quit) && plod__generation(w) == served &&
               atomic_load(&w->hint) == hint)
            plod_cond_wait(&w->wake, &w->lock);
        atomic_fetch_sub(&w->sleeping, 1);
        plod_mutex_unlock(&w->lock);
        idle = plod_clock_ns();
    }
}

static void plod__wake_sleepers(plod_workers *w)
{
    if (atomic_load(&w->sleeping) > 0) {
        plod_mutex_lock(&w->lock);
        plod_cond_broadcast(&w->wake);
        plod_mutex_unlock(&w->lock);
    }
}

plod_status plod_workers_create(plod_workers **out, int threads)
{
    if (!out)
        return PLOD_ERR_NULL;
    *out = NULL;
    if (threads < 2 || threads > PLOD_MAX_THREADS)
        return PLOD_ERR_BAD_PARAM;
    plod_workers *w = calloc(1, sizeof *w);
    if (!w)
        return PLOD_ERR_NO_MEMORY;
    if (!plod_mutex_init(&w->lock)) {
        free(w);
        return PLOD_ERR_NO_MEMORY;
    }
    if (!plod_cond_init(&w->wake)) {
        plod_mutex_destroy(&w->lock);
        free(w);
        return PLOD_ERR_NO_MEMORY;
    }
    atomic_init(&w->sleeping, 0);
    atomic_init(&w->hint, 0);
    atomic_init(&w->spin, 0);
    atomic_init(&w->linger_until, 0);
    atomic_init(&w->quit, 0);
    atomic_init(&w->next, 0);
    atomic_init(&w->done, 0);
    w->pid = plod_process_id();
    for (int t = 1; t < threads; t++) {
        if (!plod_thread_start(&w->ids[w->count], plod__worker, w))
            break;
        w->count++;
    }
    if (w->count == 0) {
        plod_workers_destroy(w);
        return PLOD_ERR_NO_MEMORY;
    }
    *out = w;
    return PLOD_OK;
}

void plod_workers_destroy(plod_workers *w)
{
    if (!w)
        return;
    if (w->pid == plod_process_id()) { /* a forked child has no workers to join */
        atomic_store(&w->quit, 1);
        plod_mutex_lock(&w->lock);
        plod_cond_broadcast(&w->wake);
        plod_mutex_unlock(&w->lock);
        for (int t = 0; t < w->count; t++)
            plod_thread_join(&w->ids[t]);
        plod_cond_destroy(&w->wake);
        plod_mutex_destroy(&w->lock);
    }
    free(w);
}

int plod_workers_threads(const plod_workers *w)
{
    return w && w->pid == plod_process_id() ? 1 + w->count : 1;
}

void plod_workers_begin(plod_workers *w)
{
    if (!w || w->pid != plod_process_id())
        return;
    atomic_store(&w->spin, 1);
    atomic_fetch_add(&w->hint, 1);
    plod__wake_sleepers(w);
}

void plod_workers_end(plod_workers *w)
{
    if (!w)
        return;
    atomic_store(&w->linger_until, plod_clock_ns() + PLOD__LINGER_NS);
    atomic_store(&w->spin, 0);
}

void *plod_grow(void *array, size_t *capacity, size_t need, size_t size, size_t first)
{
    size_t grown = *capacity ? *capacity : (first ? first : 1);
    while (grown < need) {
        if (grown > SIZE_MAX / 2)
            return NULL;
        grown *= 2;
    }
    if (size && grown > SIZE_MAX / size)
        return NULL;
    void *fresh = realloc(array, grown * size);
    if (!fresh)
        return NULL;
    *capacity = grown;
    return fresh;
}

void plod_workers_for(plod_workers *w, size_t count, size_t grain, plod_range_fn range,
                      void *context)
{
    if (count == 0 || !range)
        return;
    if (grain == 0)
        grain = 1;
    if ((count - 1) / grain + 1 > PLOD__MAX_CHUNKS)
        grain = (count - 1) / PLOD__MAX_CHUNKS + 1;
    size_t chunks = (count - 1) / grain + 1;
    if (!w || w->pid != plod_process_id() || chunks < 2) {
        range(context, 0, count);
        return;
    }
    w->range = range;
    w->context = context;
    w->count_items = count;
    w->grain = grain;
    atomic_store(&w->done, 0);
    w->generation = (w->generation + 1) & 0xFFFFFFu;
    if (w->generation == 0)
        w->generation = 1; /* 0 is the pool's first, empty generation */
    atomic_store(&w->next, (uint_fast64_t)w->generation << PLOD__GEN_SHIFT |
                               (uint_fast64_t)chunks << PLOD__BACK_SHIFT); /* publishes it */
    plod__wake_sleepers(w);
    plod__run_chunks(w, w->generation, 1);
    while (atomic_load(&w->done) < chunks) /* chunks the workers claimed */
        plod__relax();
}
