/* core_latency.c -- how far apart two CPUs are: one cache line passed back
 * and forth between a thread pinned to each, the median round trip of a
 * few runs in nanoseconds.  On a shared VM the same two vCPUs are
 * sometimes close (tens of ns) and sometimes far apart (hundreds), and
 * threaded figures differ with it; bench_detail_builds.py prints it before
 * and after its measures.
 *
 *     core_latency [cpu_a cpu_b]      (default 0 1)
 *
 * Prints "round trip N ns", or a line saying why it could not measure
 * (exit status 1).
 */
#define _GNU_SOURCE
#include <pthread.h>
#include <sched.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

enum { ROUND_TRIPS = 100000, RUNS = 5 };

typedef struct {
    _Alignas(64) atomic_int turn; /* 1: the partner's, 0: the caller's */
    _Alignas(64) atomic_int ready; /* the partner's: 1 pinned, -1 not */
    int cpu;
} line_state;

static int pin_to(int cpu)
{
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(cpu, &set);
    return pthread_setaffinity_np(pthread_self(), sizeof set, &set) == 0;
}

static void *partner(void *arg)
{
    line_state *s = arg;
    int pinned = pin_to(s->cpu);
    atomic_store(&s->ready, pinned ? 1 : -1);
    if (!pinned)
        return NULL;
    for (int k = 0; k < RUNS * ROUND_TRIPS; k++) {
        while (atomic_load_explicit(&s->turn, memory_order_acquire) != 1)
            ;
        atomic_store_explicit(&s->turn, 0, memory_order_release);
    }
    return NULL;
}

static double now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e9 + (double)ts.tv_nsec;
}

static int compare(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int main(int argc, char **argv)
{
    int cpu_a = argc > 2 ? atoi(argv[1]) : 0, cpu_b = argc > 2 ? atoi(argv[2]) : 1;
    if (!pin_to(cpu_a)) {
        printf("cannot pin a thread to CPU %d\n", cpu_a);
        return 1;
    }
    line_state s = {.cpu = cpu_b};
    atomic_init(&s.turn, 0);
    atomic_init(&s.ready, 0);
    pthread_t thread;
    if (pthread_create(&thread, NULL, partner, &s) != 0) {
        printf("cannot start a thread\n");
        return 1;
    }
    while (atomic_load(&s.ready) == 0)
        sched_yield(); /* (one CPU: the partner needs this one to start) */
    if (atomic_load(&s.ready) < 0) {
        pthread_join(thread, NULL);
        printf("cannot pin a thread to CPU %d\n", cpu_b);
        return 1;
    }
    double runs[RUNS];
    for (int r = 0; r < RUNS; r++) {
        double t0 = now_ns();
        for (int k = 0; k < ROUND_TRIPS; k++) {
            atomic_store_explicit(&s.turn, 1, memory_order_release);
            while (atomic_load_explicit(&s.turn, memory_order_acquire) != 0)
                ;
        }
        runs[r] = (now_ns() - t0) / ROUND_TRIPS;
    }
    pthread_join(thread, NULL);
    qsort(runs, RUNS, sizeof runs[0], compare);
    printf("round trip %.0f ns\n", runs[RUNS / 2]);
    return 0;
}
