/* vh_mat.h - small dense double matrices, row-major, sizes up to VH_MAT_MAX (TinyEKF style).
 *
 * Caller-owned storage; scratch on the stack, sized by VH_MAT_MAX. Output arguments may not
 * alias inputs unless stated.
 */
#ifndef VH_MAT_H
#define VH_MAT_H

#include <math.h>

#include "vh_types.h"

#define VH_MAT_MAX 8

/* The small products are static inline so that, called with constant sizes, the compiler
 * unrolls and vectorises them (a 4-state filter step is mostly these). */

/* c[n x p] = a[n x m] * B, B[k][j] = b[k * bk + j * bj]: the one product loop of vh_mat_mul and
 * vh_mat_mul_bt, which differ only in how b is laid out (inlined with constant strides). */
static inline void vh_mat_mul_strided(const double *a, const double *b, double *c, int n, int m, int p, int bk, int bj)
{
    int i, j, k;
    for (i = 0; i < n; ++i) {
        for (j = 0; j < p; ++j) {
            double s = 0.0;
            for (k = 0; k < m; ++k) {
                s += a[i * m + k] * b[k * bk + j * bj];
            }
            c[i * p + j] = s;
        }
    }
}

/* c[n x p] = a[n x m] * b[m x p] */
static inline void vh_mat_mul(const double *a, const double *b, double *c, int n, int m, int p)
{
    vh_mat_mul_strided(a, b, c, n, m, p, p, 1);
}

/* c[n x p] = a[n x m] * b[p x m]^T */
static inline void vh_mat_mul_bt(const double *a, const double *b, double *c, int n, int m, int p)
{
    vh_mat_mul_strided(a, b, c, n, m, p, 1, m);
}

static inline void vh_mat_identity(double *a, int n)
{
    int i;
    for (i = 0; i < n * n; ++i) {
        a[i] = 0.0;
    }
    for (i = 0; i < n; ++i) {
        a[i * n + i] = 1.0;
    }
}

/* a = diag(d) (n x n): a covariance's (re)start value */
static inline void vh_mat_diag(double *a, const double *d, int n)
{
    int i;
    for (i = 0; i < n * n; ++i) {
        a[i] = 0.0;
    }
    for (i = 0; i < n; ++i) {
        a[i * n + i] = d[i];
    }
}

/* a = (a + a^T) / 2, in place */
static inline void vh_mat_symmetrise(double *a, int n)
{
    int i, j;
    for (i = 0; i < n; ++i) {
        for (j = i + 1; j < n; ++j) {
            const double s = 0.5 * (a[i * n + j] + a[j * n + i]);
            a[i * n + j] = s;
            a[j * n + i] = s;
        }
    }
}

/* e = expm(a) for n <= VH_MAT_MAX: scaling and squaring with a 16-term Taylor series. */
void vh_mat_expm(const double *a, double *e, int n);
/* In-place Cholesky a = L L^T: the lower triangle is overwritten with L, and the diagonal's
 * reciprocals go to inv_diag[n] (the solve multiplies instead of dividing). 0, or -1 if a is not
 * positive definite (NaN included). */
static inline int vh_mat_chol(double *a, double *inv_diag, int n)
{
    int i, j, k;
    for (j = 0; j < n; ++j) {
        double d = a[j * n + j];
        for (k = 0; k < j; ++k) {
            d -= a[j * n + k] * a[j * n + k];
        }
        if (!(d > 0.0)) {
            return -1;
        }
        d = sqrt(d);
        a[j * n + j] = d;
        inv_diag[j] = 1.0 / d;
        for (i = j + 1; i < n; ++i) {
            double s = a[i * n + j];
            for (k = 0; k < j; ++k) {
                s -= a[i * n + k] * a[j * n + k];
            }
            a[i * n + j] = s * inv_diag[j];
        }
    }
    return 0;
}

/* Solve (L L^T) x = b for the m right-hand sides in the columns of b[n x m], in place. */
static inline void vh_mat_chol_solve(const double *l, const double *inv_diag, double *b, int n, int m)
{
    int c, i, k;
    for (c = 0; c < m; ++c) {
        for (i = 0; i < n; ++i) { /* forward: L y = b */
            double s = b[i * m + c];
            for (k = 0; k < i; ++k) {
                s -= l[i * n + k] * b[k * m + c];
            }
            b[i * m + c] = s * inv_diag[i];
        }
        for (i = n - 1; i >= 0; --i) { /* back: L^T x = y */
            double s = b[i * m + c];
            for (k = i + 1; k < n; ++k) {
                s -= l[k * n + i] * b[k * m + c];
            }
            b[i * m + c] = s * inv_diag[i];
        }
    }
}

/* 1 if every entry is finite. */
static inline int vh_mat_finite(const double *a, int count)
{
    int i;
    for (i = 0; i < count; ++i) {
        if (!isfinite(a[i])) {
            return 0;
        }
    }
    return 1;
}

#endif /* VH_MAT_H */
