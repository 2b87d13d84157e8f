/* base.c -- the fork-join loop of plod_base.h.  Threads are started per
 * call (tens of microseconds): callers use it only for work far above
 * that, and keep below their own thresholds on one thread. */
#include "plod_base.h"

#include <pthread.h>

typedef struct plod__block {
    plod_range_fn range;
    void *context;
    size_t begin, end;
} plod__block;

static void *plod__run_block(void *arg)
{
    const plod__block *b = arg;
    b->range(b->context, b->begin, b->end);
    return NULL;
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
    pthread_t ids[PLOD_MAX_THREADS];
    int started[PLOD_MAX_THREADS];
    for (size_t t = 0; t < n; t++)
        blocks[t] = (plod__block){range, context, count * t / n, count * (t + 1) / n};
    for (size_t t = 1; t < n; t++)
        started[t] = pthread_create(&ids[t], NULL, plod__run_block, &blocks[t]) == 0;
    plod__run_block(&blocks[0]);
    for (size_t t = 1; t < n; t++) {
        if (started[t])
            pthread_join(ids[t], NULL);
        else
            plod__run_block(&blocks[t]); /* no thread: do it here */
    }
}
