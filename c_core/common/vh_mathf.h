/* vh_mathf.h - the float32 sin, cos, atan and atan2 the firmware calls, the same bits on every build.
 *
 * libm's float functions are not correctly rounded, and each C library rounds its own way (newlib on
 * the Cortex-M4F, glibc on the host, which even picks an FMA variant by CPU), so a float32 estimator
 * calling them gives different bits on the ECU and the host. These are written with + - * / only
 * (each IEEE-754 correctly rounded on both sides, with -ffp-contract=off and no double), so the
 * result is a function of the argument alone.
 *
 * Method and coefficients: Cephes Math Library (S. L. Moshier), single precision sinf.c, cosf.c,
 * atanf.c, atan2f.c (Release 2.2, 1995; "may be used freely", the licence SciPy and Go take it
 * under): Cody-Waite reduction by pi/4 in three parts, minimax polynomials on [-pi/4, pi/4] and on
 * [0, tan(pi/8)]. Added: the low part of pi/2, pi/4 and pi in atan's and atan2's final sum (as
 * FreeBSD msun's s_atanf.c does with atanlo[]). Accuracy against double libm, measured by
 * tests/test_c_mathf.py over the ranges the firmware uses (sin/cos |x| <= 8192, atan all of R):
 * see that test. A NaN argument comes back as it is (its bits too).
 *
 * vh_sinf/vh_cosf: |x| < 2^24 (beyond, and for +-inf, a float cannot place x within pi/4: NAN). */
#ifndef VH_MATHF_H
#define VH_MATHF_H

float vh_sinf(float x);
float vh_cosf(float x);
float vh_atanf(float x);
/* atan2(y, x) in [-pi, pi]; +0 for y = 0 and x > 0, pi for y = 0 and x < 0 (the sign of a zero y
 * is not used). */
float vh_atan2f(float y, float x);

#endif /* VH_MATHF_H */
