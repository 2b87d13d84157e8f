/* plod_base.h -- what every stage of the Planet LOD core shares: status
 * codes (plod_status.h), constants, small double[3] vector helpers, one
 * fork-join loop over threads and a pool of persistent workers.
 */
#ifndef PLOD_BASE_H
#define PLOD_BASE_H

#include <math.h>
#include <stddef.h>
#include "plod_status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- constants ------------------------------------------------------------
 * Written with more digits than a double holds: each rounds to the nearest
 * double (pi/2 and pi/4 are then exact scalings of PLOD_PI). */
#define PLOD_PI 3.14159265358979323846
#define PLOD_SQRT2 1.41421356237309504880

/* ---- vectors --------------------------------------------------------------
 * Sums in index order (0 + 1) + 2: with -ffp-contract=off a caller gets the
 * bits of the same expression written out. */
static inline double plod_dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static inline double plod_norm3(const double a[3])
{
    return sqrt(plod_dot3(a, a));
}

/* out = a x b; out may not alias a or b. */
static inline void plod_cross3(const double a[3], const double b[3], double out[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

/* ---- lane loops ------------------------------------------------------------
 * Loops over a batch of points written for SIMD (structure of arrays, the
 * branches as selects) ask GCC for what its -O2 lacks: vectorised loops,
 * and selects if-converted, which needs leave to evaluate both arms of a
 * floating-point select (no traps; the values are the same either way).
 * fp-contract stays off: no fused multiply-adds, the roundings of the
 * point path.  On x86-64 Linux, GCC also builds a PLOD_LANE_CLONES
 * function for AVX2 (4 lanes) and for x86-64-v4 (AVX-512: 8 lanes, 64-bit
 * integer multiplies for the lattice hashes), the one the processor has
 * chosen at load time; every version gives the same bits (IEEE double
 * arithmetic, no FMA: test_cpu_paths.py).  PLOD_NO_CLONES builds the
 * plain version alone.  PLOD_LANE_INLINE: helpers inlined into them. */
#if defined(__GNUC__) && !defined(__clang__)
#define PLOD_LANE_LOOPS __attribute__((optimize("O3", "no-trapping-math", "fp-contract=off")))
#define PLOD_LANE_INLINE static inline __attribute__((always_inline))
#if defined(__x86_64__) && defined(__linux__) && !defined(PLOD_NO_CLONES)
#if __GNUC__ >= 12
#define PLOD_LANE_CLONES __attribute__((target_clones("arch=x86-64-v4", "avx2", "default")))
#else
#define PLOD_LANE_CLONES __attribute__((target_clones("avx2", "default")))
#endif
#endif
#endif
#ifndef PLOD_LANE_LOOPS
#define PLOD_LANE_LOOPS
#define PLOD_LANE_INLINE static inline
#endif
#ifndef PLOD_LANE_CLONES
#define PLOD_LANE_CLONES
#endif

/* ---- threads --------------------------------------------------------------- */

#define PLOD_MAX_THREADS 64

/* Runs indices [begin, end) of a loop. */
typedef void (*plod_range_fn)(void *context, size_t begin, size_t end);

/* Fork-join: splits [0, count) into n = min(threads, count,
 * PLOD_MAX_THREADS) contiguous blocks, block t = [count t / n,
 * count (t + 1) / n), and calls range(context, begin, end) once per block:
 * block 0 on the calling thread, the others on threads started for them
 * (a block whose thread cannot start runs on the calling thread after
 * block 0).  Returns when every block has run.  threads < 1 counts as 1;
 * count 0 calls nothing.  Blocks run concurrently: they must write
 * disjoint memory, and the output is the same for every thread count only
 * if it does not depend on the blocking. */
void plod_parallel_for(size_t count, int threads, plod_range_fn range, void *context);

/* Grows an array of `size`-byte elements whose capacity *capacity is below
 * `need`: the capacity doubles (from `first` when 0) until it holds `need`.
 * Returns the moved array, or NULL without memory (the array and
 * *capacity as they were). */
void *plod_grow(void *array, size_t *capacity, size_t need, size_t size, size_t first);

/* Persistent workers, for loops of a few hundred microseconds, where
 * starting threads (tens of microseconds each) would eat the gain.  A loop
 * is cut into chunks that the caller claims from the front and the workers
 * from the back (so each keeps mostly the same items from one loop to the
 * next); the caller never waits for a worker to start, only for the
 * chunks a worker has claimed, so a worker that is slow to be scheduled
 * (or gone: after fork()) costs nothing but its share.  Between
 * plod_workers_begin and plod_workers_end (and ~0.1 ms after it) idle
 * workers spin for the next loop; otherwise they look for one every
 * ~0.1 ms for a while, then sleep.  The pool belongs to its creator, who
 * calls it from one thread at a time. */
typedef struct plod_workers plod_workers;

/* `threads` - 1 workers (threads counts the caller).  PLOD_ERR_BAD_PARAM
 * for threads < 2 or above PLOD_MAX_THREADS; PLOD_ERR_NO_MEMORY when no
 * thread could start (with fewer it succeeds; plod_workers_threads says). */
plod_status plod_workers_create(plod_workers **out, int threads);
void plod_workers_destroy(plod_workers *workers);
/* The caller plus the workers that started. */
int plod_workers_threads(const plod_workers *workers);
/* Loops are coming: idle workers wake (if asleep) and spin until
 * plod_workers_end (or a few milliseconds), so the loops start on all
 * threads at once. */
void plod_workers_begin(plod_workers *workers);
void plod_workers_end(plod_workers *workers);
/* Calls range(context, begin, end) over [0, count) in chunks of `grain`
 * (0 counts as 1), on the caller and the workers; returns when every chunk
 * has run.  workers NULL: one call on the caller.  As plod_parallel_for:
 * chunks must write disjoint memory, and the output is the same for every
 * thread count only if it does not depend on the chunking. */
void plod_workers_for(plod_workers *workers, size_t count, size_t grain, plod_range_fn range,
                      void *context);

#ifdef __cplusplus
}
#endif
#endif /* PLOD_BASE_H */
