/* test_support.h -- pieces the C core's test programs share: the FNV-1a
 * hash that their outputs are compared by, an integer mixer for made-up
 * height maps, and a camera matrix that looks from an eye at a target.
 * Header-only (static functions), so each test stays one translation unit
 * that builds alike for Linux and for Windows. */
#ifndef PLOD_TEST_SUPPORT_H
#define PLOD_TEST_SUPPORT_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

#define TEST_FNV_OFFSET 0xcbf29ce484222325ull

/* FNV-1a over bytes, continuing from h (TEST_FNV_OFFSET to start). */
static uint64_t test_fnv1a(const void *data, size_t bytes, uint64_t h)
{
    const unsigned char *p = data;
    for (size_t i = 0; i < bytes; i++) {
        h ^= p[i];
        h *= 0x100000001b3ull;
    }
    return h;
}

static uint32_t test_mix32(uint32_t x)
{
    x ^= x >> 16;
    x *= 0x7feb352du;
    x ^= x >> 15;
    x *= 0x846ca68bu;
    x ^= x >> 16;
    return x;
}

/* Blender's camera convention: the columns of the 4x4 row-major matrix are
 * right, up and back (the view looks down -Z), then the eye. */
static void test_look_at(const double eye[3], const double target[3], const double up[3],
                         double m[16])
{
    double back[3], right[3], upv[3];
    for (int i = 0; i < 3; i++)
        back[i] = eye[i] - target[i];
    double n = sqrt(back[0] * back[0] + back[1] * back[1] + back[2] * back[2]);
    for (int i = 0; i < 3; i++)
        back[i] /= n;
    right[0] = up[1] * back[2] - up[2] * back[1];
    right[1] = up[2] * back[0] - up[0] * back[2];
    right[2] = up[0] * back[1] - up[1] * back[0];
    n = sqrt(right[0] * right[0] + right[1] * right[1] + right[2] * right[2]);
    for (int i = 0; i < 3; i++)
        right[i] /= n;
    upv[0] = back[1] * right[2] - back[2] * right[1];
    upv[1] = back[2] * right[0] - back[0] * right[2];
    upv[2] = back[0] * right[1] - back[1] * right[0];
    for (int r = 0; r < 3; r++) {
        m[4 * r + 0] = right[r];
        m[4 * r + 1] = upv[r];
        m[4 * r + 2] = back[r];
        m[4 * r + 3] = eye[r];
    }
    m[12] = m[13] = m[14] = 0.0;
    m[15] = 1.0;
}

#endif
