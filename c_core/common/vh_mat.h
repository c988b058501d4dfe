/* vh_mat.h - small dense double matrices, row-major, sizes up to VH_MAT_MAX (TinyEKF style).
 *
 * Caller-owned storage; scratch on the stack, sized by VH_MAT_MAX. Output arguments may not
 * alias inputs unless stated.
 */
#ifndef VH_MAT_H
#define VH_MAT_H

#ifndef VH_MAT_CDEF
#include <math.h>

#include "vh_types.h"
#endif

#define VH_MAT_MAX 8

/* The small products are static inline so that, called with constant sizes, the compiler
 * unrolls and vectorises them (a 4-state filter step is mostly these); one source for double
 * (here) and float (the ECU's driveline filter, vh_dkf_f32.c): vh_mat_ops.inc. */
#ifndef VH_MAT_CDEF /* cffi's declarations (c_core/cbuild.py) need none of the inline ones */
#define VH_MAT_REAL double
#define VH_MAT_FN(n) vh_mat_##n
#define VH_MAT_SQRT sqrt
#include "vh_mat_ops.inc"
#undef VH_MAT_REAL
#undef VH_MAT_FN
#undef VH_MAT_SQRT
#endif

/* e = expm(a) for n <= VH_MAT_MAX: scaling and squaring with a 16-term Taylor series. */
void vh_mat_expm(const double *a, double *e, int n);

#endif /* VH_MAT_H */
