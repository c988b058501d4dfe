/* vh_fix.c - fixed-point helpers that are too big to inline, see vh_fix.h. Integer only. */
#include "vh_fix.h"

void vh_fix_row_pack(const int32_t *a, int n, vh_fix_row_t *row)
{
    int i;
    row->n = 0;
    if (n < 0 || n > VH_FIX_DOT_MAX) {
        return; /* precondition: more terms could overflow the accumulator */
    }
    for (i = 0; i < n; ++i) {
        if (a[i] != 0) {
            row->v[row->n] = a[i];
            row->at[row->n] = (uint8_t)i;
            ++row->n;
        }
    }
}

int64_t vh_fix_row_dot(const vh_fix_row_t *row, const int32_t *b, int sb)
{
    int64_t acc = 0;
    int k;
    for (k = 0; k < row->n; ++k) {
        acc += vh_fix_asr64((int64_t)row->v[k] * b[row->at[k] * sb], VH_FIX_GUARD);
    }
    return acc;
}

int32_t vh_fix_div(int32_t num, int32_t den, int s, uint32_t *sat)
{
    int64_t n2, d2, q;
    if (den <= 0) {
        if (num == 0) {
            return 0;
        }
        vh_fix_count(sat);
        return num > 0 ? INT32_MAX : INT32_MIN;
    }
    if (s < 0 || s > 30) { /* 2 num 2^s would not fit int64: clamp, and say so */
        vh_fix_count(sat);
        s = s < 0 ? 0 : 30;
    }
    /* floor((2 num 2^s + den) / (2 den)): |2 num 2^s| <= 2^62 */
    n2 = (int64_t)num * ((int64_t)1 << (s + 1)) + den;
    d2 = 2 * (int64_t)den;
    q = n2 / d2;
    if (n2 % d2 != 0 && n2 < 0) {
        --q; /* C division truncates; floor for negatives */
    }
    return vh_fix_sat32(q, sat);
}

/* floor(n / d) for d > 0 (C division truncates toward zero). */
static int64_t floor_div(int64_t n, int64_t d)
{
    const int64_t q = n / d;
    return (n % d != 0 && n < 0) ? q - 1 : q;
}

int32_t vh_fix_from_raw(int32_t raw, int32_t num, int32_t den, int frac, uint32_t *sat)
{
    if (raw > 65536 || raw < -65536 || num <= 0 || num > 32768 || den <= 0 || frac < 0 || frac > 30) {
        vh_fix_count(sat);
        return 0;
    }
    /* floor(raw num 2^frac / den + 1/2) = floor((2 raw num 2^frac + den) / (2 den)); |.| < 2^63 */
    return vh_fix_sat32(floor_div(2 * (int64_t)raw * num * ((int64_t)1 << frac) + den, 2 * (int64_t)den), sat);
}

int64_t vh_fix_to_raw(int32_t v, int frac, int32_t num, int32_t den)
{
    int64_t d;
    if (num <= 0 || den <= 0 || den > 1073741824 || frac < 0 || frac > 30) {
        return 0;
    }
    /* floor(v den / (num 2^frac) + 1/2) = floor((2 v den + num 2^frac) / (2 num 2^frac)):
     * |2 v den| < 2^63, 2 num 2^frac < 2^62 */
    d = (int64_t)num * ((int64_t)1 << frac);
    return floor_div(2 * (int64_t)v * den + d, 2 * d);
}

#define ONE_Q30 1073741824 /* 1.0 in Q1.30 */

/* 1 - x2 * inv * p, Q1.30 throughout: one Horner step of the Taylor series. */
static int32_t horner(int32_t x2, int32_t inv, int32_t p, uint32_t *sat)
{
    const int32_t t = vh_fix_mul(x2, 30, inv, 30, 30, sat);
    return vh_fix_sub(ONE_Q30, vh_fix_mul(t, 30, p, 30, 30, sat), sat);
}

void vh_fix_sincos(int32_t angle, int32_t *s_out, int32_t *c_out, uint32_t *sat)
{
    /* round(2^30 / k) for the Taylor denominators */
    static const int32_t inv_sin[4] = {14913081, 25565282, 53687091, 178956971};        /* 72 42 20 6 */
    static const int32_t inv_cos[5] = {11930465, 19173961, 35791394, 89478485, 536870912}; /* 90 56 30 12 2 */
    int32_t x2, ps = ONE_Q30, pc = ONE_Q30;
    int i;
    if (angle > ONE_Q30) {
        angle = ONE_Q30;
        vh_fix_count(sat);
    } else if (angle < -ONE_Q30) {
        angle = -ONE_Q30;
        vh_fix_count(sat);
    }
    x2 = vh_fix_mul(angle, 30, angle, 30, 30, sat);
    for (i = 0; i < 4; ++i) {
        ps = horner(x2, inv_sin[i], ps, sat);
    }
    for (i = 0; i < 5; ++i) {
        pc = horner(x2, inv_cos[i], pc, sat);
    }
    *s_out = vh_fix_mul(angle, 30, ps, 30, 30, sat);
    *c_out = pc;
}
