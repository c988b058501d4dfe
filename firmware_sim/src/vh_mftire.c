/* vh_mftire.c - see vh_mftire.h. */
#include "vh_mftire.h"

#include <math.h>

#define PI 3.141592653589793
#define DEG_PER_RAD (180.0 / PI)
/* Curvature factors are kept below 1 (E = 1 flattens the curve to a plateau). The default
 * coefficients never come near it (E <= 0.71 at any load). */
#define E_MAX 0.999
/* Peak slips are kept where the theoretical slips stay finite: kappa_m < 1, alpha_m < pi/2. */
#define KAPPA_M_MAX 0.9
#define ALPHA_M_MAX 1.4
/* Below this normalised slip the linear limit F = (slip stiffness) sigma is used (no 0/0). */
#define S_LINEAR 1e-12
#define OPK_MIN 1e-6

void vh_mft_coef_default(vh_mft_coef_t *c)
{
    /* Bakker, Nyborg & Pacejka 1987 (SAE 870421), passenger-car tyre; Fz in kN, alpha in deg,
     * kappa in %, forces in N. Lateral a0..a8, longitudinal b0..b8. */
    static const double A[9] = {1.30, -22.1, 1011.0, 1078.0, 1.82, 0.208, 0.000, -0.354, 0.707};
    static const double B[9] = {1.65, -21.3, 1144.0, 49.6, 226.0, 0.069, -0.006, 0.056, 0.486};
    int i;
    for (i = 0; i < 9; ++i) {
        c->a[i] = A[i];
        c->b[i] = B[i];
    }
    c->fz_scale = 1.0;
    c->model = VH_MFT_MF87;
    for (i = 0; i < 8; ++i) {
        c->p[i] = 0.0;
    }
}

/* MF as a function of the slip x, with the factors B, C, D, E. */
static double mf(double b, double c, double d, double e, double x)
{
    const double bx = b * x;
    return d * sin(c * atan(bx - e * (bx - atan(bx))));
}

static double clamp_e(double e)
{
    return e < E_MAX ? e : E_MAX;
}

static int pac_check(const double *p)
{
    int i;
    for (i = 0; i < 8; ++i) {
        if (!isfinite(p[i])) {
            return 0;
        }
    }
    return p[0] > 1.0 && p[0] < 2.0 && p[4] > 1.0 && p[4] < 2.0 && p[1] > 0.0 && p[5] > 0.0 && p[3] != 0.0 &&
           p[7] > 0.0 && p[2] < 1.0 && p[6] < 1.0;
}

int vh_mft_check(const vh_mft_coef_t *c)
{
    int i, k;
    if (c->model == VH_MFT_PAC2002) {
        return pac_check(c->p);
    }
    if (c->model != VH_MFT_MF87) {
        return 0;
    }
    for (i = 0; i < 9; ++i) {
        if (!isfinite(c->a[i]) || !isfinite(c->b[i])) {
            return 0;
        }
    }
    if (!(c->a[0] > 1.0 && c->a[0] < 2.0 && c->b[0] > 1.0 && c->b[0] < 2.0 && c->a[2] > 0.0 && c->b[2] > 0.0 &&
          isfinite(c->fz_scale) && c->fz_scale >= 0.25 && c->fz_scale <= 4.0)) {
        return 0;
    }
    /* the polynomials are smooth: sample the load range finely (in the published tyre's loads) */
    for (k = 1; k <= 200; ++k) {
        const double f = VH_MFT_FZ_MAX * 1e-3 / c->fz_scale * (double)k / 200.0;
        const double dy = c->a[1] * f * f + c->a[2] * f;
        const double dx = c->b[1] * f * f + c->b[2] * f;
        const double ky = c->a[3] * sin(c->a[4] * atan(c->a[5] * f));
        const double kx = (c->b[3] * f * f + c->b[4] * f) * exp(-c->b[5] * f);
        const double ey = c->a[6] * f * f + c->a[7] * f + c->a[8];
        const double ex = c->b[6] * f * f + c->b[7] * f + c->b[8];
        if (!(dy > 0.0 && dx > 0.0 && ky > 0.0 && kx > 0.0 && ey < 1.0 && ex < 1.0)) {
            return 0;
        }
    }
    return 1;
}

double vh_mft_peak_u(double c, double e, double u0, int iters)
{
    /* dF/dx = 0 where C atan(.) = pi/2, i.e. (1 - E) u + E atan(u) = tan(pi / 2C) */
    const double t = tan(PI / (2.0 * c));
    double u = u0 > 0.0 ? u0 : t;
    int k, n = iters > 0 ? iters : 60;
    for (k = 0; k < n; ++k) {
        const double g = (1.0 - e) * u + e * atan(u) - t;
        const double dg = (1.0 - e) + e / (1.0 + u * u);
        double un = u - g / dg;
        if (!(un > 0.0)) {
            un = 0.5 * u; /* stay on the positive branch */
        }
        if (iters <= 0 && fabs(un - u) <= 1e-15 * un) {
            return un;
        }
        u = un;
    }
    return u;
}

/* The load-polynomial part shared by vh_mft_load and vh_mft_load_near: D, C, E at the
 * published tyre's load f [kN] for the scale sc; B from the stiffnesses ky, kx. */
static void finish_load(vh_mft_state_t *s, const vh_mft_coef_t *c, double fz, double f, double mu, double ky,
                        double kx)
{
    const double sc = c->fz_scale;
    s->fz = fz > 0.0 ? fz : 0.0;
    if (c->model == VH_MFT_PAC2002) { /* D = mu p_d*1 Fz, C and E constant */
        s->cy = c->p[0];
        s->cx = c->p[4];
        s->dy = mu > 0.0 ? mu * c->p[1] * s->fz : 0.0;
        s->dx = mu > 0.0 ? mu * c->p[5] * s->fz : 0.0;
        s->ey = clamp_e(c->p[2]);
        s->ex = clamp_e(c->p[6]);
    } else {
        const double lam_y = mu > 0.0 ? mu / (c->a[2] * 1e-3) : 0.0;
        const double lam_x = mu > 0.0 ? mu / (c->b[2] * 1e-3) : 0.0;
        s->cy = c->a[0];
        s->cx = c->b[0];
        s->dy = sc * lam_y * (c->a[1] * f * f + c->a[2] * f);
        s->dx = sc * lam_x * (c->b[1] * f * f + c->b[2] * f);
        s->ey = clamp_e(c->a[6] * f * f + c->a[7] * f + c->a[8]);
        s->ex = clamp_e(c->b[6] * f * f + c->b[7] * f + c->b[8]);
    }
    if (s->dy > 0.0 && s->dx > 0.0 && ky > 0.0 && kx > 0.0) {
        s->by = ky / (s->cy * s->dy);
        s->bx = kx / (s->cx * s->dx);
    } else {
        s->dx = s->dy = s->bx = s->by = 0.0; /* no load or no friction: no force */
    }
}

void vh_mft_load(vh_mft_state_t *s, const vh_mft_coef_t *c, double fz, double mu)
{
    const double sc = c->fz_scale;
    if (c->model == VH_MFT_PAC2002) { /* slip stiffnesses proportional to the load */
        s->dky = fabs(c->p[3]);
        s->dkx = c->p[7];
        s->ky = s->dky * (fz > 0.0 ? fz : 0.0);
        s->kx = s->dkx * (fz > 0.0 ? fz : 0.0);
        finish_load(s, c, fz, 0.0, mu, s->ky, s->kx);
        return;
    }
    const double f = fz > 0.0 ? fz * 1e-3 / sc : 0.0; /* kN of the published tyre */
    const double th = c->a[4] * atan(c->a[5] * f);
    const double sin_th = sin(th);
    const double cos_th = th < PI / 2.0 ? sqrt(1.0 - sin_th * sin_th) : -sqrt(1.0 - sin_th * sin_th);
    const double ex = exp(-c->b[5] * f);
    const double px = c->b[3] * f * f + c->b[4] * f;
    s->ky = sc * c->a[3] * sin_th * DEG_PER_RAD; /* N/rad */
    s->kx = sc * px * ex * 100.0;                /* N per unit slip */
    /* d/dFz = (1 / (1000 sc)) d/df, and the sc in front cancels */
    s->dky = c->a[3] * cos_th * c->a[4] * c->a[5] / (1.0 + c->a[5] * f * c->a[5] * f) * DEG_PER_RAD * 1e-3;
    s->dkx = ((2.0 * c->b[3] * f + c->b[4]) - c->b[5] * px) * ex * 100.0 * 1e-3;
    finish_load(s, c, fz, f, mu, s->ky, s->kx);
}

void vh_mft_load_near(vh_mft_state_t *s, const vh_mft_state_t *near, const vh_mft_coef_t *c, double fz, double mu)
{
    const double f = fz > 0.0 ? fz * 1e-3 / c->fz_scale : 0.0;
    const double dfz = (fz > 0.0 ? fz : 0.0) - near->fz;
    s->ky = near->ky + near->dky * dfz;
    s->kx = near->kx + near->dkx * dfz;
    s->dky = near->dky;
    s->dkx = near->dkx;
    finish_load(s, c, fz, f, mu, s->ky, s->kx);
}

void vh_mft_peaks(vh_mft_state_t *s, double ux, double uy, int iters)
{
    s->uy = uy > 0.0 ? vh_mft_peak_u(s->cy, s->ey, uy, iters) : vh_mft_peak_u(s->cy, s->ey, 0.0, 0);
    s->ux = ux > 0.0 ? vh_mft_peak_u(s->cx, s->ex, ux, iters) : vh_mft_peak_u(s->cx, s->ex, 0.0, 0);
    if (s->by > 0.0 && s->bx > 0.0) {
        s->alpha_m = s->uy / s->by;
        s->kappa_m = s->ux / s->bx;
        s->alpha_m = s->alpha_m < ALPHA_M_MAX ? s->alpha_m : ALPHA_M_MAX;
        s->kappa_m = s->kappa_m < KAPPA_M_MAX ? s->kappa_m : KAPPA_M_MAX;
    } else {
        s->kappa_m = 0.1; /* finite peaks keep the normalisation defined; the forces are zero */
        s->alpha_m = 0.1;
    }
    s->tan_alpha_m = tan(s->alpha_m);
    s->sxm_drive = s->kappa_m / (1.0 + s->kappa_m); /* sigma_x = kappa / (1 + kappa) at +-kappa_m */
    s->sxm_brake = s->kappa_m / (1.0 - s->kappa_m);
    s->inv_sxm_drive = 1.0 / s->sxm_drive;
    s->inv_sxm_brake = 1.0 / s->sxm_brake;
    s->inv_sym = 1.0 / s->tan_alpha_m;
}

void vh_mft_hold_peaks(vh_mft_state_t *s, const vh_mft_state_t *from)
{
    s->ux = from->ux;
    s->uy = from->uy;
    s->kappa_m = from->kappa_m;
    s->alpha_m = from->alpha_m;
    s->tan_alpha_m = from->tan_alpha_m;
    s->sxm_drive = from->sxm_drive;
    s->sxm_brake = from->sxm_brake;
    s->inv_sxm_drive = from->inv_sxm_drive;
    s->inv_sxm_brake = from->inv_sxm_brake;
    s->inv_sym = from->inv_sym;
}

double vh_mft_fx0(const vh_mft_state_t *s, double kappa)
{
    return mf(s->bx, s->cx, s->dx, s->ex, kappa);
}

double vh_mft_fy0(const vh_mft_state_t *s, double alpha)
{
    return mf(s->by, s->cy, s->dy, s->ey, alpha);
}

void vh_mft_forces(const vh_mft_state_t *s, double kappa, double tan_alpha, double *fx, double *fy)
{
    double opk = 1.0 + kappa, inv, sx, sy, sxm, nx, ny, sn, se, keq;

    opk = opk > OPK_MIN ? opk : OPK_MIN;
    inv = 1.0 / opk;
    sx = kappa * inv; /* theoretical slips */
    sy = tan_alpha * inv;
    /* normalised by the peak's theoretical slips; sigma_xm on the side of sigma_x */
    if (sx >= 0.0) {
        sxm = s->sxm_drive;
        nx = sx * s->inv_sxm_drive;
    } else {
        sxm = s->sxm_brake;
        nx = sx * s->inv_sxm_brake;
    }
    ny = sy * s->inv_sym;
    sn = sqrt(nx * nx + ny * ny);
    if (!(sn > S_LINEAR)) {
        *fx = s->bx * s->cx * s->dx * sx; /* limit s -> 0: slip stiffness times theoretical slip */
        *fy = s->by * s->cy * s->dy * sy;
        return;
    }
    /* equivalent pure slips whose theoretical slips are s sigma_xm, s sigma_ym */
    se = sn * sxm;
    if (sx >= 0.0) {
        keq = se < 1.0 - 1e-12 ? se / (1.0 - se) : 1e12; /* sigma_x -> 1 is kappa -> infinity */
    } else {
        keq = se / (1.0 + se);
    }
    inv = 1.0 / sn;
    *fx = nx == 0.0 ? 0.0 : nx * inv * mf(s->bx, s->cx, s->dx, s->ex, keq);
    *fy = ny == 0.0 ? 0.0 : ny * inv * mf(s->by, s->cy, s->dy, s->ey, atan(sn * s->tan_alpha_m));
}

void vh_mft_eval(const vh_mft_coef_t *c, double fz, double mu, double kappa, double tan_alpha, double *fx,
                 double *fy)
{
    vh_mft_state_t s;
    vh_mft_load(&s, c, fz, mu);
    vh_mft_peaks(&s, 0.0, 0.0, 0);
    vh_mft_forces(&s, kappa, tan_alpha, fx, fy);
}
