/* vh_mat.h - small dense double matrices, row-major, sizes up to VH_MAT_MAX (TinyEKF style).
 *
 * Caller-owned storage; scratch on the stack, sized by VH_MAT_MAX. Output arguments may not
 * alias inputs unless stated.
 */
#ifndef VH_MAT_H
#define VH_MAT_H

#include "vh_types.h"

#define VH_MAT_MAX 8

/* c[n x p] = a[n x m] * b[m x p] */
void vh_mat_mul(const double *a, const double *b, double *c, int n, int m, int p);
/* c[n x p] = a[n x m] * b[p x m]^T */
void vh_mat_mul_bt(const double *a, const double *b, double *c, int n, int m, int p);
void vh_mat_identity(double *a, int n);
/* a = (a + a^T) / 2, in place */
void vh_mat_symmetrise(double *a, int n);
/* e = expm(a) for n <= VH_MAT_MAX: scaling and squaring with a 16-term Taylor series. */
void vh_mat_expm(const double *a, double *e, int n);
/* In-place Cholesky a = L L^T (lower triangle overwritten with L). 0, or -1 if not positive definite. */
int vh_mat_chol(double *a, int n);
/* Solve (L L^T) x = b for the m right-hand sides in the columns of b[n x m], in place. */
void vh_mat_chol_solve(const double *l, double *b, int n, int m);
/* 1 if every entry is finite. */
int vh_mat_finite(const double *a, int count);

#endif /* VH_MAT_H */
