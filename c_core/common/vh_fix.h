/* vh_fix.h - fixed-point helpers: int32 storage, int64 accumulators, round-half-up, saturation
 * that is counted (CMSIS-DSP / libfixmath conventions).
 *
 * A value v in format Qi.f is the int32 round(v 2^f) with i + f = 31 (i integer bits besides the
 * sign). Functions take the fractional bits of their operands and result, so one helper serves
 * every format; the formats of the estimator live in vh_skfq.h.
 *
 * Rounding: every right shift is round-half-up, floor(x / 2^s + 1/2), i.e. (x + 2^(s-1)) >> s with
 * an arithmetic (flooring) shift that is written out portably (C99 leaves >> of negative values
 * implementation-defined) and compiles to one sar/asr.
 * Saturation: a result outside int32 is clipped to INT32_MIN / INT32_MAX and `*sat` is incremented
 * (itself saturating at UINT32_MAX). `sat` is never NULL. No function has undefined behaviour
 * for any int32 input: left shifts are multiplications of int64 values known not to overflow.
 *
 * Integer only: this header and vh_fix.c use no floating point (checked by tests/test_skfmec.py).
 */
#ifndef VH_FIX_H
#define VH_FIX_H

#include <stdint.h>

#include "vh_types.h" /* vh_sat_add_u32 */

/* A constant of any magnitude with full 31-bit precision: value = m * 2^-e, |m| in [2^30, 2^31)
 * (or m = 0). Made off-line (vh_skfq_params_from_config); the ECU only multiplies by it. */
typedef struct {
    int32_t m;
    int32_t e;
} vh_fix_k_t;

static inline void vh_fix_count(uint32_t *sat)
{
    *sat = vh_sat_add_u32(*sat, 1u);
}

/* floor(x / 2^s) for 0 <= s <= 62, portable arithmetic shift. */
static inline int64_t vh_fix_asr64(int64_t x, int s)
{
    return x >= 0 ? (x >> s) : ~((~x) >> s);
}

/* Clip an int64 to int32, counting a saturation. */
static inline int32_t vh_fix_sat32(int64_t x, uint32_t *sat)
{
    if (x > INT32_MAX) {
        vh_fix_count(sat);
        return INT32_MAX;
    }
    if (x < INT32_MIN) {
        vh_fix_count(sat);
        return INT32_MIN;
    }
    return (int32_t)x;
}

/* round_half_up(x / 2^s), s in [0, 62]; saturated to int32. Precondition |x| < 2^62 (every caller's
 * accumulator is bounded so: products of two int32 are < 2^62). s >= 63 gives 0. */
static inline int32_t vh_fix_rshift_rnd(int64_t x, int s, uint32_t *sat)
{
    if (s <= 0) {
        return vh_fix_sat32(x, sat);
    }
    if (s >= 63) {
        return 0;
    }
    return vh_fix_sat32(vh_fix_asr64(x + ((int64_t)1 << (s - 1)), s), sat);
}

/* x * 2^s for s in [0, 31], saturated (the int64 product of an int32 and 2^31 cannot overflow).
 * Outside that range, still defined: s < 0 is vh_fix_rshift_rnd(x, -s); s > 31 saturates any
 * x != 0 (counted), as the exact result would. */
static inline int32_t vh_fix_lshift_sat(int32_t x, int s, uint32_t *sat)
{
    if (s < 0) {
        return vh_fix_rshift_rnd(x, -s, sat);
    }
    if (s > 31) {
        if (x == 0) {
            return 0;
        }
        vh_fix_count(sat);
        return x > 0 ? INT32_MAX : INT32_MIN;
    }
    return vh_fix_sat32((int64_t)x * ((int64_t)1 << s), sat);
}

/* Convert between formats: from fin to fout fractional bits (round-half-up down, saturating up). */
static inline int32_t vh_fix_convert(int32_t x, int fin, int fout, uint32_t *sat)
{
    return fout >= fin ? vh_fix_lshift_sat(x, fout - fin, sat) : vh_fix_rshift_rnd(x, fin - fout, sat);
}

/* Saturating a + b, a - b (same format). */
static inline int32_t vh_fix_add(int32_t a, int32_t b, uint32_t *sat)
{
    return vh_fix_sat32((int64_t)a + b, sat);
}

static inline int32_t vh_fix_sub(int32_t a, int32_t b, uint32_t *sat)
{
    return vh_fix_sat32((int64_t)a - b, sat);
}

/* a * b: a in Q.fa, b in Q.fb, result in Q.fo (fo <= fa + fb). The 64-bit product is exact,
 * then one round-half-up shift by fa + fb - fo and saturation: error <= 1/2 LSB of the result. */
static inline int32_t vh_fix_mul(int32_t a, int fa, int32_t b, int fb, int fo, uint32_t *sat)
{
    return vh_fix_rshift_rnd((int64_t)a * b, fa + fb - fo, sat);
}

/* k * v: v in Q.fin, result in Q.fout; shift e + fin - fout (a left shift when negative, saturated).
 * Exact 64-bit product, one rounding: error <= 1/2 LSB of the result plus k's own 2^-31 relative. */
static inline int32_t vh_fix_kmul(vh_fix_k_t k, int32_t v, int fin, int fout, uint32_t *sat)
{
    const int s = k.e + fin - fout;
    const int64_t prod = (int64_t)k.m * v;
    if (s >= 0) {
        return vh_fix_rshift_rnd(prod, s, sat);
    }
    if (s < -31 || prod > (INT64_MAX >> -s) || prod < -(INT64_MAX >> -s)) {
        if (prod == 0) {
            return 0;
        }
        vh_fix_count(sat);
        return prod > 0 ? INT32_MAX : INT32_MIN;
    }
    return vh_fix_sat32(prod * ((int64_t)1 << -s), sat);
}

/* Guarded dot product of a packed row and b: sum_k row.v[k] * b[row.at[k] * sb], returned in
 * Q.(fa + fb - 3): each exact product is floored by the 3 guard bits before accumulation, so 8
 * products of two int32 cannot overflow the int64 accumulator (8 * 2^62 / 2^3 = 2^62). The result
 * differs from the exact sum by less than n LSB of Q.(fa+fb-3), far below the final rounding
 * (vh_fix_rshift_rnd to the output).
 * A row a[0..n) is packed once (vh_fix_row_pack: its nonzero entries, value and column) and then
 * multiplied by as many b as needed: the SKFMEC's Phi and H are structurally sparse, and a zero term
 * adds exactly 0 to the guarded sum, so the products cost the nonzeros only and give the dense sum's
 * bits. An n outside [0, 8] is refused: the packed row is empty (a longer sum could overflow; callers
 * size n at compile time, see vh_skfq.c). */
#define VH_FIX_GUARD 3
#define VH_FIX_DOT_MAX 8
typedef struct {
    int32_t n;
    int32_t v[VH_FIX_DOT_MAX];
    uint8_t at[VH_FIX_DOT_MAX];
} vh_fix_row_t;
void vh_fix_row_pack(const int32_t *a, int n, vh_fix_row_t *row);
int64_t vh_fix_row_dot(const vh_fix_row_t *row, const int32_t *b, int sb);

/* round_half_up(num * 2^s / den) with den > 0, saturated; s in [0, 30] so that the numerator
 * 2 num 2^s fits int64. An s outside [0, 30] is clamped to it and counted as a saturation (the
 * result is then not num 2^s / den). den <= 0 saturates towards the sign of num (counted). */
int32_t vh_fix_div(int32_t num, int32_t den, int s, uint32_t *sat);

/* A raw CAN signal times its DBC scale num/den, in Q.frac: round_half_up(raw num 2^frac / den),
 * saturated (counted). Exact (one rounding of the exact rational), so for the DBC's decimal
 * scales it equals rounding the double decode (tests/test_c_integer_path.py checks every raw
 * value). Preconditions, checked (result 0, counted): |raw| <= 2^16, 0 < num <= 2^15, den > 0,
 * 0 <= frac <= 30, so that 2 raw num 2^frac fits int64. */
int32_t vh_fix_from_raw(int32_t raw, int32_t num, int32_t den, int frac, uint32_t *sat);
/* The inverse: a value in Q.frac to raw units of scale num/den, round_half_up(v den / (num 2^frac)),
 * as int64 (the caller clamps to the signal's range). Exact; 0 < den <= 2^30, num > 0, 0 <= frac <= 30
 * (outside: 0). */
int64_t vh_fix_to_raw(int32_t v, int frac, int32_t num, int32_t den);

/* sin and cos of an angle in Q1.30 [rad], |angle| <= 1 (larger is clipped to +-1 and counted),
 * results in Q1.30: Horner-form Taylor polynomials to x^9 and x^10 (truncation < 3e-8 at 1 rad),
 * each step rounded half-up. */
void vh_fix_sincos(int32_t angle_q30, int32_t *sin_q30, int32_t *cos_q30, uint32_t *sat);

#endif /* VH_FIX_H */
