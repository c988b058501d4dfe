/* vh_mat.c - see vh_mat.h. */
#include <math.h>

#include "vh_mat.h"

void vh_mat_mul(const double *a, const double *b, double *c, int n, int m, int p)
{
    int i, j, k;
    for (i = 0; i < n; ++i) {
        for (j = 0; j < p; ++j) {
            double s = 0.0;
            for (k = 0; k < m; ++k) {
                s += a[i * m + k] * b[k * p + j];
            }
            c[i * p + j] = s;
        }
    }
}

void vh_mat_mul_bt(const double *a, const double *b, double *c, int n, int m, int p)
{
    int i, j, k;
    for (i = 0; i < n; ++i) {
        for (j = 0; j < p; ++j) {
            double s = 0.0;
            for (k = 0; k < m; ++k) {
                s += a[i * m + k] * b[j * m + k];
            }
            c[i * p + j] = s;
        }
    }
}

void vh_mat_identity(double *a, int n)
{
    int i;
    for (i = 0; i < n * n; ++i) {
        a[i] = 0.0;
    }
    for (i = 0; i < n; ++i) {
        a[i * n + i] = 1.0;
    }
}

void vh_mat_symmetrise(double *a, int n)
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

void vh_mat_expm(const double *a, double *e, int n)
{
    double as[VH_MAT_MAX * VH_MAT_MAX];
    double term[VH_MAT_MAX * VH_MAT_MAX];
    double tmp[VH_MAT_MAX * VH_MAT_MAX];
    double norm = 0.0, scale = 1.0;
    int i, j, k, squarings = 0;

    /* infinity norm, then halve until <= 0.5 so the Taylor tail is below 1e-19 */
    for (i = 0; i < n; ++i) {
        double row = 0.0;
        for (j = 0; j < n; ++j) {
            row += fabs(a[i * n + j]);
        }
        norm = row > norm ? row : norm;
    }
    while (norm * scale > 0.5 && squarings < 60) {
        scale *= 0.5;
        ++squarings;
    }
    for (i = 0; i < n * n; ++i) {
        as[i] = a[i] * scale;
    }
    vh_mat_identity(e, n);
    vh_mat_identity(term, n);
    for (k = 1; k <= 16; ++k) {
        vh_mat_mul(term, as, tmp, n, n, n);
        for (i = 0; i < n * n; ++i) {
            term[i] = tmp[i] / (double)k;
            e[i] += term[i];
        }
    }
    for (k = 0; k < squarings; ++k) {
        vh_mat_mul(e, e, tmp, n, n, n);
        for (i = 0; i < n * n; ++i) {
            e[i] = tmp[i];
        }
    }
}

int vh_mat_chol(double *a, int n)
{
    int i, j, k;
    for (j = 0; j < n; ++j) {
        double d = a[j * n + j];
        for (k = 0; k < j; ++k) {
            d -= a[j * n + k] * a[j * n + k];
        }
        if (!(d > 0.0)) { /* also catches NaN */
            return -1;
        }
        d = sqrt(d);
        a[j * n + j] = d;
        for (i = j + 1; i < n; ++i) {
            double s = a[i * n + j];
            for (k = 0; k < j; ++k) {
                s -= a[i * n + k] * a[j * n + k];
            }
            a[i * n + j] = s / d;
        }
    }
    return 0;
}

void vh_mat_chol_solve(const double *l, double *b, int n, int m)
{
    int c, i, k;
    for (c = 0; c < m; ++c) {
        for (i = 0; i < n; ++i) { /* forward: L y = b */
            double s = b[i * m + c];
            for (k = 0; k < i; ++k) {
                s -= l[i * n + k] * b[k * m + c];
            }
            b[i * m + c] = s / l[i * n + i];
        }
        for (i = n - 1; i >= 0; --i) { /* back: L^T x = y */
            double s = b[i * m + c];
            for (k = i + 1; k < n; ++k) {
                s -= l[k * n + i] * b[k * m + c];
            }
            b[i * m + c] = s / l[i * n + i];
        }
    }
}

int vh_mat_finite(const double *a, int count)
{
    int i;
    for (i = 0; i < count; ++i) {
        if (!isfinite(a[i])) {
            return 0;
        }
    }
    return 1;
}
