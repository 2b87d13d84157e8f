/* fuzz_input.h -- a tiny FuzzedDataProvider for the C harnesses: consumes
 * the libFuzzer input front to back and returns zeros once it runs out, so
 * every input (even an empty one) is a valid program.
 */
#ifndef PLOD_FUZZ_INPUT_H
#define PLOD_FUZZ_INPUT_H

#include <float.h>
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct fuzz_input {
    const uint8_t *data;
    size_t size;
} fuzz_input;

/* A violated invariant: print why and abort, so libFuzzer saves the input. */
#define FUZZ_CHECK(cond, ...)                                                \
    do {                                                                     \
        if (!(cond)) {                                                       \
            fprintf(stderr, "fuzz invariant failed: %s (%s:%d): ", #cond,    \
                    __FILE__, __LINE__);                                     \
            fprintf(stderr, __VA_ARGS__);                                    \
            fputc('\n', stderr);                                             \
            abort();                                                         \
        }                                                                    \
    } while (0)

static inline uint8_t fuzz_u8(fuzz_input *in)
{
    if (in->size == 0)
        return 0;
    uint8_t b = in->data[0];
    in->data++;
    in->size--;
    return b;
}

static inline uint32_t fuzz_u32(fuzz_input *in)
{
    uint32_t v = 0;
    for (int i = 0; i < 4; i++)
        v |= (uint32_t)fuzz_u8(in) << (8 * i);
    return v;
}

static inline uint64_t fuzz_u64(fuzz_input *in)
{
    return (uint64_t)fuzz_u32(in) | (uint64_t)fuzz_u32(in) << 32;
}

/* Integer in [lo, hi] (hi >= lo, span < 2^32). */
static inline int fuzz_range(fuzz_input *in, int lo, int hi)
{
    uint32_t span = (uint32_t)(hi - lo) + 1u;
    uint32_t raw = span <= 256 ? fuzz_u8(in) : fuzz_u32(in);
    return lo + (int)(raw % span);
}

/* Values that break numerical code: signed zeros, denormals, extremes,
 * non-finite values, cube edges/corners and face-boundary angles. */
static const double fuzz_special_values[] = {
    0.0, -0.0, 1.0, -1.0, 0.5, -0.5, 2.0, 1e-300, -1e-300, 4.9e-324,
    -4.9e-324, 2.2250738585072014e-308, DBL_MIN / 2, DBL_MAX, -DBL_MAX,
    DBL_EPSILON, 1.0 - DBL_EPSILON / 2, 1.0 + DBL_EPSILON, -1.0 - DBL_EPSILON,
    45.0, -45.0, 90.0, -90.0, 135.0, 180.0, -180.0, 225.0, 270.0, 315.0,
    360.0, -360.0, 720.0, 35.26438968275465, -35.26438968275465,
    0.5773502691896258, 0.7071067811865476, 1e9, -1e9, 1e18, 1e300,
    INFINITY, -INFINITY, NAN, -NAN, 89.99999999999999, 90.00000000000001,
    179.99999999999997, 6371000.0, 1e8, 1e-9, 3.0, 4.0, 8.0, 0.1,
};

/* A double: raw IEEE bits (any NaN payload, denormals, infinities), a
 * special value, a small integer, or a value in [-2, 2] / [-400, 400]. */
static inline double fuzz_double(fuzz_input *in)
{
    uint8_t mode = fuzz_u8(in);
    switch (mode & 7) {
    case 0: {
        uint64_t bits = fuzz_u64(in);
        double d;
        memcpy(&d, &bits, sizeof d);
        return d;
    }
    case 1:
    case 2: {
        size_t n = sizeof fuzz_special_values / sizeof fuzz_special_values[0];
        double d = fuzz_special_values[fuzz_u8(in) % n];
        /* nudge by a few ulps either side */
        int ulps = (int)(mode >> 3) - 16;
        for (; ulps > 0; ulps--)
            d = nextafter(d, INFINITY);
        for (; ulps < 0; ulps++)
            d = nextafter(d, -INFINITY);
        return d;
    }
    case 3:
        return (double)(int8_t)fuzz_u8(in);
    case 4:
    case 5:
        return -2.0 + 4.0 * (double)fuzz_u32(in) / 4294967295.0;
    default:
        return -400.0 + 800.0 * (double)fuzz_u32(in) / 4294967295.0;
    }
}

static inline double fuzz_double_in(fuzz_input *in, double lo, double hi)
{
    return lo + (hi - lo) * (double)fuzz_u32(in) / 4294967295.0;
}

#endif /* PLOD_FUZZ_INPUT_H */
