/* vh_mat.c - see vh_mat.h. */
#include <math.h>

#include "vh_mat.h"

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
