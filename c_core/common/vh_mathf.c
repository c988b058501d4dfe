/* vh_mathf.c - float32 sin, cos, atan, atan2 from + - * / only (method and sources: vh_mathf.h). */
#include "vh_mathf.h"

#include <math.h>
#include <stdint.h>

/* single precision only, on every build */
#pragma GCC diagnostic error "-Wdouble-promotion"

static const float FOPI = 1.27323954473516f; /* 4/pi */
/* pi/4 = DP1 + DP2 + DP3, DP1 and DP2 with few enough bits that j*DP1 and j*DP2 are exact for
 * j < 2^13 (Cody & Waite; Cephes sinf.c's 24-bit split) */
static const float DP1 = 0.78515625f;
static const float DP2 = 2.4187564849853515625e-4f;
static const float DP3 = 3.77489497744594108e-8f;
static const float T24 = 16777216.0f;

/* pi/2, pi/4, pi rounded to float (hi) and the rest (lo = value - hi, to float) */
static const float PIO2_HI = 1.57079637050628662109375f, PIO2_LO = -4.37113900018624283e-8f;
static const float PIO4_HI = 0.785398185253143310546875f, PIO4_LO = -2.18556950009312141e-8f;
static const float PI_HI = 3.1415927410125732421875f, PI_LO = -8.74227800037248566e-8f;

/* sin r and cos r for |r| <= pi/4 (Cephes sinf.c: relative error 3.8e-9 and 7.8e-8 theoretical) */
static float sin_poly(float r)
{
    const float z = r * r;
    return ((-1.9515295891e-4f * z + 8.3321608736e-3f) * z - 1.6666654611e-1f) * z * r + r;
}

static float cos_poly(float r)
{
    const float z = r * r;
    float y = (2.443315711809948e-5f * z - 1.388731625493765e-3f) * z + 4.166664568298827e-2f;
    y *= z * z;
    y -= 0.5f * z;
    return y + 1.0f;
}

/* |x| = j pi/4 + r, j even (zeros to the origin), |r| <= pi/4; the octant j mod 8 in *oct.
 * ax < 2^24, so the conversion is defined. */
static float reduce(float ax, uint32_t *oct)
{
    uint32_t j = (uint32_t)(ax * FOPI);
    float y;
    j += j & 1u;
    y = (float)j;
    *oct = j & 7u;
    return ((ax - y * DP1) - y * DP2) - y * DP3;
}

/* A NaN's bits are not IEEE's to fix: an invalid operation gives the FPU's default NaN, negative on
 * x86-64, positive on ARM. So a NaN argument is returned as it is and the others get the constant NAN. */
static float not_placed(float x)
{
    return x != x ? x : NAN;
}

float vh_sinf(float x)
{
    const int neg = x < 0.0f;
    const float ax = neg ? -x : x;
    uint32_t oct;
    float r, y;
    if (!(ax < T24)) {
        return not_placed(x);
    }
    r = reduce(ax, &oct);
    y = (oct == 2u || oct == 6u) ? cos_poly(r) : sin_poly(r);
    return (neg ^ (oct > 3u)) ? -y : y;
}

float vh_cosf(float x)
{
    const float ax = x < 0.0f ? -x : x;
    uint32_t oct;
    float r, y;
    if (!(ax < T24)) {
        return not_placed(x);
    }
    r = reduce(ax, &oct);
    y = (oct == 2u || oct == 6u) ? sin_poly(r) : cos_poly(r);
    return (oct == 2u || oct == 4u) ? -y : y;
}

/* atan on [0, inf]: by tan(3pi/8) and tan(pi/8) to |t| <= tan(pi/8) (Cephes atanf.c; relative error
 * 1.9e-7 over +-10 there), the offset added in two parts */
static float atan_pos(float ax)
{
    float t, hi, lo, z;
    if (ax > 2.414213562373095f) {
        t = -1.0f / ax;
        hi = PIO2_HI;
        lo = PIO2_LO;
    } else if (ax > 0.4142135623730950f) {
        t = (ax - 1.0f) / (ax + 1.0f);
        hi = PIO4_HI;
        lo = PIO4_LO;
    } else {
        t = ax;
        hi = 0.0f;
        lo = 0.0f;
    }
    z = t * t;
    return hi + ((((8.05374449538e-2f * z - 1.38776856032e-1f) * z + 1.99777106478e-1f) * z
                  - 3.33329491539e-1f) * z * t + t + lo);
}

float vh_atanf(float x)
{
    if (x < 0.0f) {
        return -atan_pos(-x);
    }
    return atan_pos(x); /* NaN stays NaN: every comparison is false */
}

float vh_atan2f(float y, float x)
{
    static const float BIG = 3.40282347e+38f; /* FLT_MAX */
    float z;
    if ((y > BIG || y < -BIG) && (x > BIG || x < -BIG)) {
        y = y < 0.0f ? -1.0f : 1.0f; /* both infinite: +-pi/4, +-3pi/4 (C99 F.9.1.4), not inf/inf's NaN */
        x = x < 0.0f ? -1.0f : 1.0f;
    }
    if (x == 0.0f) {
        return y < 0.0f ? -PIO2_HI : (y > 0.0f ? PIO2_HI : (y == 0.0f ? 0.0f : y));
    }
    if (y == 0.0f) {
        return x < 0.0f ? PI_HI : (x > 0.0f ? 0.0f : x);
    }
    z = vh_atanf(y / x);
    if (x > 0.0f || x != x) {
        return z;
    }
    return y < 0.0f ? -PI_HI + (z - PI_LO) : PI_HI + (z + PI_LO);
}
