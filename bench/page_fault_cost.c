/* page_fault_cost.c -- what a first touch of memory costs here: anonymous
 * memory mapped and written one byte a 4 KB page, three ways, the median
 * of a few runs in microseconds per 4 KB page:
 *   touch     pages faulted in one by one as they are first written
 *   populate  MAP_POPULATE (the kernel fills the mapping in one call)
 *   huge      a 2 MB-aligned mapping with MADV_HUGEPAGE (transparent huge
 *             pages where the kernel allows them; fresh guest memory on a
 *             VM can cost far more than memory the guest has used before)
 * A planet's first descent grows its meshes and sector cache by hundreds
 * of megabytes, and every new page is one of these (bench/README.md,
 * "Detail field").
 *
 *     page_fault_cost [megabytes]      (default 64)
 */
#define _GNU_SOURCE
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/mman.h>
#include <time.h>

enum { RUNS = 5, PAGE = 4096 };
#define HUGE_PAGE ((size_t)2 << 20)

static double now_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e6 + (double)ts.tv_nsec * 1e-3;
}

static void touch(volatile char *p, size_t bytes)
{
    for (size_t at = 0; at < bytes; at += PAGE)
        p[at] = 1;
}

/* microseconds per 4 KB page of mapping `bytes` and writing every page */
static double touch_cost(size_t bytes)
{
    char *p = mmap(NULL, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED)
        return -1.0;
    double t0 = now_us();
    touch(p, bytes);
    double t = now_us() - t0;
    munmap(p, bytes);
    return t / (double)(bytes / PAGE);
}

static double populate_cost(size_t bytes)
{
    double t0 = now_us();
    char *p = mmap(NULL, bytes, PROT_READ | PROT_WRITE,
                   MAP_PRIVATE | MAP_ANONYMOUS | MAP_POPULATE, -1, 0);
    if (p == MAP_FAILED)
        return -1.0;
    touch(p, bytes);
    double t = now_us() - t0;
    munmap(p, bytes);
    return t / (double)(bytes / PAGE);
}

static double huge_cost(size_t bytes)
{
    size_t mapped = bytes + HUGE_PAGE;
    char *p = mmap(NULL, mapped, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED)
        return -1.0;
    char *aligned = (char *)(((uintptr_t)p + HUGE_PAGE - 1) & ~(uintptr_t)(HUGE_PAGE - 1));
    madvise(aligned, bytes, MADV_HUGEPAGE); /* a hint: refused, it is 4 KB pages */
    double t0 = now_us();
    touch(aligned, bytes);
    double t = now_us() - t0;
    munmap(p, mapped);
    return t / (double)(bytes / PAGE);
}

static int compare(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double median_of(double (*cost)(size_t), size_t bytes)
{
    double runs[RUNS];
    for (int r = 0; r < RUNS; r++)
        runs[r] = cost(bytes);
    qsort(runs, RUNS, sizeof runs[0], compare);
    return runs[RUNS / 2];
}

int main(int argc, char **argv)
{
    long megabytes = argc > 1 ? strtol(argv[1], NULL, 10) : 64;
    if (megabytes < 2 || megabytes > 4096) {
        fprintf(stderr, "page_fault_cost: megabytes in [2, 4096]\n");
        return 1;
    }
    size_t bytes = (size_t)megabytes << 20;
    double touched = median_of(touch_cost, bytes), populated = median_of(populate_cost, bytes),
           huge = median_of(huge_cost, bytes);
    if (touched < 0.0 || populated < 0.0 || huge < 0.0) {
        fprintf(stderr, "page_fault_cost: mmap failed\n");
        return 1;
    }
    printf("first touch per 4 KB page: touch %.2f us, populate %.2f us, huge %.2f us\n", touched,
           populated, huge);
    return 0;
}
