/* vh_skf.c - SKFMEC and plain EKF for tire lateral forces (seed 000), see vh_skf.h. */
#include <math.h>
#include <string.h>

#include "vh_kf.h"
#include "vh_mat.h"
#include "vh_skf.h"

#define NX VH_SKF_NX
#define NY VH_SKF_NY

/* Steps in INIT after a (re)start: 0.2 s at 2 kHz, long enough for P0 = O(1) to converge. */
#define INIT_STEPS 400u

/* vh_skf_run passes rows of VH_SKF_NU doubles as vh_skf_input_t: no padding allowed. */
typedef char input_layout_check[(sizeof(vh_skf_input_t) == VH_SKF_NU * sizeof(double)) ? 1 : -1];

void vh_skf_zeta_steady(const vh_skf_config_t *c, double *zeta1, double *zeta2)
{
    /* Steady cornering of the model itself: 2 Fyf + 2 Fyr = m ay, lf Fyf = lr Fyr (eq. 29,
     * small delta) and the roll equation kphi phi = ms e ay + hf 2 Fyf + hr 2 Fyr (eq. 30 with
     * p = p' = 0); zeta = Fy / phi (eq. 31-32). */
    const double l = c->lf + c->lr;
    const double phi_per_ay = (c->ms * c->e + c->hf * c->m * c->lr / l + c->hr * c->m * c->lf / l) /
                              (c->kphif + c->kphir);
    *zeta1 = c->m * c->lr / (2.0 * l) / phi_per_ay;
    *zeta2 = c->m * c->lf / (2.0 * l) / phi_per_ay;
}

void vh_skf_config_default(vh_skf_config_t *cfg, int variant)
{
    static const double s[NX] = {1e-1, 10.0, 10.0, 1e3, 1e2, 1e-3, 1e-3}; /* appendix */
    /* Tuning (docs/tireforce.md, "Tuning"): scaled coordinates, per 0.5 ms step. */
    static const double q[NX] = {1e-7, 1e-6, 1e-6, 1e-4, 1e-4, 1e-5, 1e-5};
    static const double p0[NX] = {1e-2, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0};
    static const double gp[NX] = {0.0, 0.0, 0.0, 0.0, 0.0, 3000.0, 3000.0};
    int i;
    memset(cfg, 0, sizeof *cfg);
    /* Ford FC/HVE (nomenclature) */
    cfg->m = 1814.0; cfg->ms = 1661.0; cfg->iz = 2560.0; cfg->ix = 580.0;
    cfg->lf = 1.076; cfg->lr = 1.617; cfg->h = 0.55; cfg->e = 0.48; cfg->hf = 0.114; cfg->hr = 0.004;
    cfg->kphif = 108205.8; cfg->kphir = 81436.7; cfg->cphif = 826.8; cfg->cphir = 658.9;
    cfg->rw = 0.305; cfg->iw = 2.0; cfg->tf = 0.784; cfg->tr = 0.760; cfg->g = 9.81;
    vh_skf_zeta_steady(cfg, &cfg->zeta1, &cfg->zeta2);
    cfg->lt_gain = 2.0; /* rigid-body lateral transfer with the half-tracks (docs/tireforce.md) */
    cfg->ts = 0.0005;
    cfg->tau_wdot = 0.02;
    for (i = 0; i < NX; ++i) {
        cfg->s[i] = s[i];
        cfg->q[i] = q[i];
        cfg->p0[i] = p0[i];
        cfg->gp[i] = gp[i];
    }
    cfg->r[0] = 2.5e-3; /* sensor noise: 0.05 m/s^2, 0.05 m/s^2, 0.002 rad/s, 0.003 rad/s */
    cfg->r[1] = 2.5e-3;
    cfg->r[2] = 4e-6;
    cfg->r[3] = 9e-6;
    cfg->gy[0] = 100.0;
    cfg->gy[1] = -100.0;
    cfg->p_cap = 8.0;
    cfg->p_max = 1e6;
    cfg->x_max = 1000.0; /* |x*|: the fixed-point state format holds 1024 */
    cfg->scaled = variant == VH_SKF_EKF ? 0 : 1;
    cfg->mec = variant == VH_SKF_EKF ? 0 : 1;
}

static int pos_finite(double v)
{
    return v > 0.0 && isfinite(v);
}

int vh_skf_config_check(const vh_skf_config_t *c)
{
    int i;
    const double pos[] = {c->m, c->ms, c->iz, c->ix, c->lf, c->lr, c->h, c->e, c->kphif, c->kphir,
                          c->rw, c->iw, c->tf, c->tr, c->g, c->zeta1, c->zeta2, c->ts, c->tau_wdot,
                          c->p_cap, c->p_max, c->x_max};
    const double any[] = {c->hf, c->hr, c->cphif, c->cphir, c->lt_gain, c->gy[0], c->gy[1]};
    for (i = 0; i < (int)(sizeof pos / sizeof pos[0]); ++i) {
        if (!pos_finite(pos[i])) {
            return 0;
        }
    }
    for (i = 0; i < (int)(sizeof any / sizeof any[0]); ++i) {
        if (!isfinite(any[i])) {
            return 0;
        }
    }
    for (i = 0; i < NX; ++i) {
        if (!pos_finite(c->s[i]) || !(c->q[i] >= 0.0) || !isfinite(c->q[i]) || !pos_finite(c->p0[i]) ||
            !isfinite(c->gp[i])) {
            return 0;
        }
    }
    for (i = 0; i < NY; ++i) {
        if (!pos_finite(c->r[i])) {
            return 0;
        }
    }
    /* m >= ms (the sprung mass is part of the vehicle) keeps E's 2x2 block invertible */
    return c->ms <= c->m && c->cphif >= 0.0 && c->cphir >= 0.0 && c->ts <= 0.1 && c->p_cap < c->p_max &&
           (c->scaled == 0 || c->scaled == 1) && (c->mec == 0 || c->mec == 1);
}

int vh_skf_init(vh_skf_t *f, const vh_skf_config_t *cfg)
{
    int i;
    if (!vh_skf_config_check(cfg)) {
        return VH_EINVAL;
    }
    memset(f, 0, sizeof *f);
    f->cfg = *cfg;
    for (i = 0; i < NX; ++i) {
        const double d = cfg->scaled ? cfg->s[i] : 1.0;
        const double sd = cfg->s[i] / d;
        f->d[i] = d;
        f->w[i] = sd * sd;
        f->qf[i] = cfg->q[i] / f->w[i];      /* P = S^-1 P* S^-T in the EKF's coordinates */
        f->gpf[i] = cfg->gp[i] / sd;
    }
    vh_skf_reset(f);
    return VH_OK;
}

static void restart(vh_skf_t *f)
{
    int i;
    memset(f->x, 0, sizeof f->x);
    memset(f->p, 0, sizeof f->p);
    memset(f->k, 0, sizeof f->k);
    memset(f->innov, 0, sizeof f->innov);
    memset(f->wdot, 0, sizeof f->wdot);
    memset(f->fx, 0, sizeof f->fx);
    memset(f->fz, 0, sizeof f->fz);
    memset(f->fy, 0, sizeof f->fy);
    f->cs_delta[0] = 1.0;
    f->cs_delta[1] = 0.0;
    for (i = 0; i < NX; ++i) {
        f->p[i * NX + i] = f->cfg.p0[i] / f->w[i];
    }
    f->nu_ay = 0.0;
    vh_kf_restart(&f->steps, &f->x_init, &f->health);
}

void vh_skf_reset(vh_skf_t *f)
{
    restart(f);
    f->resets = 0u;
    f->caps = 0u;
}

void vh_skf_state(const vh_skf_t *f, double x[VH_SKF_NX])
{
    int i;
    for (i = 0; i < NX; ++i) {
        x[i] = f->x[i] / f->d[i];
    }
}

/* What the model needs besides the state: this step's inputs and the eq. 30/39 terms. */
typedef struct {
    double c, s;   /* cos, sin of the steering angle */
    double fx[4];  /* eq. 30 */
    double ax, ay; /* measured accelerations (eq. 39) */
    double gy_nu[2]; /* Gy1, Gy2 times the a_y innovation, 0 without the MEC */
} ctx_t;

/* Normal loads (eq. 39, front; the rear by the same load transfer without Gy) and dFz/dphi. */
static void loads(const vh_skf_config_t *c, const ctx_t *u, double phi, double fz[4], double dfz[4])
{
    const double l = c->lf + c->lr;
    const double kf = c->kphif / (c->kphif + c->kphir), kr = c->kphir / (c->kphif + c->kphir);
    const double half = 0.5 * c->m * c->g;
    const double roll = c->ms * c->e / (2.0 * c->m);
    const double sphi = sin(phi), cphi = cos(phi);
    const double lat_f = c->lt_gain * kf * (c->h * u->ay / (2.0 * c->tf * c->g) - roll / c->tf * sphi);
    const double lat_r = c->lt_gain * kr * (c->h * u->ay / (2.0 * c->tr * c->g) - roll / c->tr * sphi);
    const double base_f = c->lr / l - c->h * u->ax / (c->g * l);
    const double base_r = c->lf / l + c->h * u->ax / (c->g * l);
    const double dlat_f = -c->lt_gain * kf * roll / c->tf * cphi, dlat_r = -c->lt_gain * kr * roll / c->tr * cphi;
    fz[0] = half * (base_f - lat_f) + u->gy_nu[0]; /* eq. 39 */
    fz[1] = half * (base_f + lat_f) + u->gy_nu[1];
    fz[2] = half * (base_r - lat_r);
    fz[3] = half * (base_r + lat_r);
    dfz[0] = -half * dlat_f;
    dfz[1] = half * dlat_f;
    dfz[2] = -half * dlat_r;
    dfz[3] = half * dlat_r;
}

/* Static load of one front / one rear tire: Fzf, Fzr of eq. 33-34. */
static void static_loads(const vh_skf_config_t *c, double *fzf, double *fzr)
{
    const double l = c->lf + c->lr;
    *fzf = c->m * c->g * c->lr / (2.0 * l);
    *fzr = c->m * c->g * c->lf / (2.0 * l);
}

/* Force and moment sums of the appendix and their derivatives with respect to phi, Fyf, Fyr. */
typedef struct {
    double fx, fy_front, fy, mz, mx; /* sums (mx without the roll spring/damper) */
    double d_fx[3], d_fy_front[3], d_fy[3], d_mz[3], d_mx[3]; /* d/d(phi, Fyf, Fyr) */
} sums_t;

static void sums(const vh_skf_config_t *c, const ctx_t *u, const double x[NX], sums_t *sm)
{
    double fz[4], dfz[4], fzf, fzr, fy[4], dfy[3][4];
    int v;
    loads(c, u, x[VH_SKF_PHI], fz, dfz);
    static_loads(c, &fzf, &fzr);
    fy[0] = x[VH_SKF_FYF] * fz[0] / fzf; /* eq. 36 */
    fy[1] = x[VH_SKF_FYF] * fz[1] / fzf;
    fy[2] = x[VH_SKF_FYR] * fz[2] / fzr; /* eq. 37 */
    fy[3] = x[VH_SKF_FYR] * fz[3] / fzr;
    dfy[0][0] = x[VH_SKF_FYF] * dfz[0] / fzf; /* d/dphi through Fz(sin phi) */
    dfy[0][1] = x[VH_SKF_FYF] * dfz[1] / fzf;
    dfy[0][2] = x[VH_SKF_FYR] * dfz[2] / fzr;
    dfy[0][3] = x[VH_SKF_FYR] * dfz[3] / fzr;
    dfy[1][0] = fz[0] / fzf; /* d/dFyf */
    dfy[1][1] = fz[1] / fzf;
    dfy[1][2] = 0.0;
    dfy[1][3] = 0.0;
    dfy[2][0] = 0.0; /* d/dFyr */
    dfy[2][1] = 0.0;
    dfy[2][2] = fz[2] / fzr;
    dfy[2][3] = fz[3] / fzr;
    /* appendix */
    sm->fx = u->c * (u->fx[0] + u->fx[1]) - u->s * (fy[0] + fy[1]) + u->fx[2] + u->fx[3];
    sm->fy_front = u->s * (u->fx[0] + u->fx[1]) + u->c * (fy[0] + fy[1]);
    sm->fy = sm->fy_front + fy[2] + fy[3];
    sm->mz = c->lf * sm->fy_front - c->lr * (fy[2] + fy[3]) +
             c->tf * (u->c * (u->fx[1] - u->fx[0]) + u->s * (fy[0] - fy[1])) + c->tr * (u->fx[3] - u->fx[2]);
    sm->mx = c->hf * sm->fy_front + c->hr * (fy[2] + fy[3]);
    for (v = 0; v < 3; ++v) {
        const double *d = dfy[v];
        sm->d_fx[v] = -u->s * (d[0] + d[1]);
        sm->d_fy_front[v] = u->c * (d[0] + d[1]);
        sm->d_fy[v] = sm->d_fy_front[v] + d[2] + d[3];
        sm->d_mz[v] = c->lf * sm->d_fy_front[v] - c->lr * (d[2] + d[3]) + c->tf * u->s * (d[0] - d[1]);
        sm->d_mx[v] = c->hf * sm->d_fy_front[v] + c->hr * (d[2] + d[3]);
    }
}

/* Model at the physical state x: xd = x' (eq. 35) and fj = dx'/dx when non-NULL; y = [ax ay r p]
 * (eq. 29) and hj = dy/dx when non-NULL. E^-1 is applied in closed form: E is diagonal but for
 * the vy-p block [[m, -ms e], [-ms e, Ix + ms e^2]]. */
static void model(const vh_skf_config_t *c, const ctx_t *u, const double x[NX], double xd[NX], double fj[NX * NX],
                  double y[NY], double hj[NY * NX])
{
    const double m = c->m, mse = c->ms * c->e, ixx = c->ix + c->ms * c->e * c->e;
    const double det = m * ixx - mse * mse;
    const double kphi = c->kphif + c->kphir, cphi = c->cphif + c->cphir;
    const double vx = x[VH_SKF_VX], vy = x[VH_SKF_VY], r = x[VH_SKF_R], phi = x[VH_SKF_PHI], p = x[VH_SKF_P];
    sums_t sm;
    sums(c, u, x, &sm);
    if (xd != NULL) {
        const double g1 = sm.fy - m * r * vx;                                /* eq. 35, row 2 */
        const double g4 = sm.mx - kphi * phi - cphi * p + mse * r * vx;      /* row 5 */
        xd[VH_SKF_VX] = (sm.fx + m * r * vy - mse * p * r) / m;
        xd[VH_SKF_VY] = (ixx * g1 + mse * g4) / det;
        xd[VH_SKF_R] = sm.mz / c->iz;
        xd[VH_SKF_PHI] = p;
        xd[VH_SKF_P] = (mse * g1 + m * g4) / det;
        xd[VH_SKF_FYF] = c->zeta1 * p;
        xd[VH_SKF_FYR] = c->zeta2 * p;
    }
    if (fj != NULL) {
        double dg1[NX], dg4[NX];
        int j;
        memset(fj, 0, NX * NX * sizeof fj[0]);
        memset(dg1, 0, sizeof dg1);
        memset(dg4, 0, sizeof dg4);
        /* row vx */
        fj[VH_SKF_VX * NX + VH_SKF_VY] = r;
        fj[VH_SKF_VX * NX + VH_SKF_R] = vy - mse * p / m;
        fj[VH_SKF_VX * NX + VH_SKF_P] = -mse * r / m;
        /* vy and p rows through g1, g4 */
        dg1[VH_SKF_VX] = -m * r;
        dg1[VH_SKF_R] = -m * vx;
        dg4[VH_SKF_VX] = mse * r;
        dg4[VH_SKF_R] = mse * vx;
        dg4[VH_SKF_PHI] = -kphi;
        dg4[VH_SKF_P] = -cphi;
        for (j = 0; j < 3; ++j) { /* phi, Fyf, Fyr */
            const int col = j == 0 ? VH_SKF_PHI : VH_SKF_FYF + j - 1;
            fj[VH_SKF_VX * NX + col] = sm.d_fx[j] / m;
            fj[VH_SKF_R * NX + col] = sm.d_mz[j] / c->iz;
            dg1[col] += sm.d_fy[j];
            dg4[col] += sm.d_mx[j];
        }
        for (j = 0; j < NX; ++j) {
            fj[VH_SKF_VY * NX + j] = (ixx * dg1[j] + mse * dg4[j]) / det;
            fj[VH_SKF_P * NX + j] = (mse * dg1[j] + m * dg4[j]) / det;
        }
        fj[VH_SKF_PHI * NX + VH_SKF_P] = 1.0;
        fj[VH_SKF_FYF * NX + VH_SKF_P] = c->zeta1;
        fj[VH_SKF_FYR * NX + VH_SKF_P] = c->zeta2;
    }
    if (y != NULL) {
        /* ax = vx' - r vy = (SFx - ms e p r) / m; ay = vy' + r vx = (Ixx SFy + ms e SMx) / det:
         * the r vx terms cancel, so neither output depends on vx or vy. */
        const double mx = sm.mx - kphi * phi - cphi * p;
        y[VH_SKF_AX] = (sm.fx - mse * p * r) / m;
        y[VH_SKF_AY] = (ixx * sm.fy + mse * mx) / det;
        y[VH_SKF_YR] = r;
        y[VH_SKF_YP] = p;
    }
    if (hj != NULL) {
        int j;
        memset(hj, 0, NY * NX * sizeof hj[0]);
        hj[VH_SKF_AX * NX + VH_SKF_R] = -mse * p / m;
        hj[VH_SKF_AX * NX + VH_SKF_P] = -mse * r / m;
        for (j = 0; j < 3; ++j) {
            const int col = j == 0 ? VH_SKF_PHI : VH_SKF_FYF + j - 1;
            hj[VH_SKF_AX * NX + col] = sm.d_fx[j] / m;
            hj[VH_SKF_AY * NX + col] = (ixx * sm.d_fy[j] + mse * sm.d_mx[j]) / det;
        }
        hj[VH_SKF_AY * NX + VH_SKF_PHI] -= mse * kphi / det;
        hj[VH_SKF_AY * NX + VH_SKF_P] = -mse * cphi / det;
        hj[VH_SKF_YR * NX + VH_SKF_R] = 1.0;
        hj[VH_SKF_YP * NX + VH_SKF_P] = 1.0;
    }
}

/* First usable sample: vx from the wheel speeds, the axle forces of quasi-steady cornering at the
 * measured a_y (the same split as vh_skf_zeta_steady) and the roll angle of eq. 31. */
static void seed_state(vh_skf_t *f, const vh_skf_input_t *in, unsigned mask)
{
    const vh_skf_config_t *c = &f->cfg;
    const double l = c->lf + c->lr;
    double x[NX];
    int i;
    x[VH_SKF_VX] = c->rw * 0.25 * (in->omega[0] + in->omega[1] + in->omega[2] + in->omega[3]);
    x[VH_SKF_VY] = 0.0;
    x[VH_SKF_R] = in->r;
    x[VH_SKF_FYF] = c->m * in->ay * c->lr / (2.0 * l);
    x[VH_SKF_FYR] = c->m * in->ay * c->lf / (2.0 * l);
    x[VH_SKF_PHI] = x[VH_SKF_FYF] / c->zeta1;
    x[VH_SKF_P] = (mask & VH_SKF_Y_P) ? in->p : 0.0;
    for (i = 0; i < NX; ++i) {
        f->x[i] = f->d[i] * x[i];
    }
    for (i = 0; i < 4; ++i) {
        f->w_prev[i] = in->omega[i];
        f->wdot[i] = 0.0;
    }
    f->x_init = 1u;
}

static int sane(const vh_skf_t *f)
{
    int i;
    for (i = 0; i < NX * NX; ++i) {
        if (!isfinite(f->p[i])) {
            return 0;
        }
    }
    for (i = 0; i < NX; ++i) {
        const double d = f->p[i * NX + i] * f->w[i];
        const int observable = i != VH_SKF_VX && i != VH_SKF_VY; /* vx, vy are clamped instead */
        if (!isfinite(f->x[i]) || !(d > 0.0) || d > f->cfg.p_max ||
            (observable && fabs(f->x[i] * f->cfg.s[i] / f->d[i]) > f->cfg.x_max)) {
            return 0;
        }
    }
    return 1;
}

int vh_skf_step(vh_skf_t *f, const vh_skf_input_t *in, unsigned mask)
{
    const vh_skf_config_t *c = &f->cfg;
    const double ts = c->ts;
    const double ymeas[NY] = {in->ax, in->ay, in->r, in->p};
    double x[NX], xd[NX], fj[NX * NX], phi[NX * NX], tmp[NX * NX], yhat[NY], hj[NY * NX];
    double xprior[NX], hrow[NX], u[NX], kcol[NX];
    ctx_t ctx;
    int i, j, l;

    if (!vh_mat_finite(&in->ax, VH_SKF_NU)) {
        mask = 0u; /* nothing of this sample is usable: predict only with held inputs */
    }
    if (!f->x_init) {
        if ((mask & VH_SKF_SEED_VALID) != VH_SKF_SEED_VALID) {
            return 0; /* wait for a usable first sample */
        }
        seed_state(f, in, mask);
    }

    /* wheel accelerations: first-order filtered difference; longitudinal forces by eq. 30 */
    if (mask & VH_SKF_U_VALID) {
        const double alpha = ts / (c->tau_wdot + ts);
        for (i = 0; i < 4; ++i) {
            f->wdot[i] += alpha * ((in->omega[i] - f->w_prev[i]) / ts - f->wdot[i]);
            f->w_prev[i] = in->omega[i];
            f->fx[i] = (in->torque[i] - c->iw * f->wdot[i]) / c->rw;
        }
        f->cs_delta[0] = cos(in->delta);
        f->cs_delta[1] = sin(in->delta);
    } /* else held: the last forces and steering angle */
    ctx.c = f->cs_delta[0];
    ctx.s = f->cs_delta[1];
    memcpy(ctx.fx, f->fx, sizeof ctx.fx);
    ctx.ax = (mask & VH_SKF_Y_AX) ? in->ax : 0.0;
    ctx.ay = (mask & VH_SKF_Y_AY) ? in->ay : 0.0;
    ctx.gy_nu[0] = c->mec ? c->gy[0] * f->nu_ay : 0.0;
    ctx.gy_nu[1] = c->mec ? c->gy[1] * f->nu_ay : 0.0;

    /* predict. eq. 38 discretised: S x+ = S x + Ts (S f(x) + Gp (r - r^)) */
    vh_skf_state(f, x);
    model(c, &ctx, x, xd, fj, NULL, NULL);
    {
        const double nu_r = (c->mec && (mask & VH_SKF_Y_R)) ? in->r - x[VH_SKF_R] : 0.0;
        for (i = 0; i < NX; ++i) {
            f->x[i] += ts * (f->d[i] * xd[i] + f->gpf[i] * nu_r);
        }
    }
    /* Phi = I + Ts F_f, F_f = D F D^-1 (eq. 28 when D = S); P- = Phi P Phi^T + Q */
    for (i = 0; i < NX; ++i) {
        for (j = 0; j < NX; ++j) {
            phi[i * NX + j] = ts * fj[i * NX + j] * f->d[i] / f->d[j] + (i == j ? 1.0 : 0.0);
        }
    }
    for (i = 0; i < NX; ++i) { /* tmp = Phi P */
        for (j = 0; j < NX; ++j) {
            double s = 0.0;
            for (l = 0; l < NX; ++l) {
                s += phi[i * NX + l] * f->p[l * NX + j];
            }
            tmp[i * NX + j] = s;
        }
    }
    for (i = 0; i < NX; ++i) { /* P = tmp Phi^T, upper triangle mirrored */
        for (j = i; j < NX; ++j) {
            double s = 0.0;
            for (l = 0; l < NX; ++l) {
                s += tmp[i * NX + l] * phi[j * NX + l];
            }
            f->p[i * NX + j] = s;
            f->p[j * NX + i] = s;
        }
        f->p[i * NX + i] += f->qf[i];
    }

    /* update: outputs and H at the prior (H_f = H D^-1), one scalar update per valid row */
    vh_skf_state(f, x);
    model(c, &ctx, x, NULL, NULL, yhat, hj);
    memcpy(xprior, f->x, sizeof xprior);
    memset(f->k, 0, sizeof f->k);
    for (i = 0; i < NY; ++i) {
        double e, s;
        f->innov[i] = (mask & (1u << i)) ? ymeas[i] - yhat[i] : 0.0;
        if (!(mask & (1u << i))) {
            continue;
        }
        /* innovation of this row after the previous rows' corrections (linearised at the prior),
         * so the sequence equals the batch update with a diagonal R */
        e = f->innov[i];
        for (j = 0; j < NX; ++j) {
            hrow[j] = hj[i * NX + j] / f->d[j];
            e -= hrow[j] * (f->x[j] - xprior[j]);
        }
        for (j = 0; j < NX; ++j) { /* u = P h^T */
            double a = 0.0;
            for (l = 0; l < NX; ++l) {
                a += f->p[j * NX + l] * hrow[l];
            }
            u[j] = a;
        }
        s = c->r[i];
        for (j = 0; j < NX; ++j) {
            s += hrow[j] * u[j];
        }
        if (!(s > 0.0) || !isfinite(s)) {
            goto diverged;
        }
        for (j = 0; j < NX; ++j) { /* K = P H^T R^-1 (eq. 27), discrete: u / s */
            kcol[j] = u[j] / s;
            f->k[j * NY + i] = kcol[j];
            f->x[j] += kcol[j] * e;
        }
        /* Joseph form (I - k h) P (I - k h)^T + k r k^T, expanded: P - k u^T - u k^T + s k k^T.
         * Symmetric by construction (upper triangle mirrored), first-order insensitive to k. */
        for (j = 0; j < NX; ++j) {
            for (l = j; l < NX; ++l) {
                const double v = f->p[j * NX + l] - kcol[j] * u[l] - u[j] * kcol[l] + s * kcol[j] * kcol[l];
                f->p[j * NX + l] = v;
                f->p[l * NX + j] = v;
            }
        }
    }
    f->nu_ay = f->innov[VH_SKF_AY];

    /* variance cap: P <- D P D, D = I with 1/2 at i, while the scaled variance exceeds p_cap */
    for (i = 0; i < NX; ++i) {
        if (f->p[i * NX + i] * f->w[i] > c->p_cap && isfinite(f->p[i * NX + i])) {
            for (j = 0; j < NX; ++j) {
                f->p[i * NX + j] *= 0.5;
                f->p[j * NX + i] *= 0.5;
            }
            ++f->caps;
        }
    }
    /* vx, vy: no output sees them, so sensor bias makes them drift open loop; they are held in
     * |x*| <= x_max like a saturating integrator instead of resetting the whole filter */
    for (i = VH_SKF_VX; i <= VH_SKF_VY; ++i) {
        const double lim = c->x_max * f->d[i] / c->s[i];
        f->x[i] = f->x[i] > lim ? lim : (f->x[i] < -lim ? -lim : f->x[i]);
    }
    if (!sane(f)) {
        goto diverged;
    }

    /* outputs at the estimate: eq. 39 with the new a_y innovation, eq. 36-37 */
    {
        double dfz[4], fzf, fzr;
        vh_skf_state(f, x);
        ctx.gy_nu[0] = c->mec ? c->gy[0] * f->nu_ay : 0.0;
        ctx.gy_nu[1] = c->mec ? c->gy[1] * f->nu_ay : 0.0;
        loads(c, &ctx, x[VH_SKF_PHI], f->fz, dfz);
        static_loads(c, &fzf, &fzr);
        f->fy[0] = x[VH_SKF_FYF] * f->fz[0] / fzf;
        f->fy[1] = x[VH_SKF_FYF] * f->fz[1] / fzf;
        f->fy[2] = x[VH_SKF_FYR] * f->fz[2] / fzr;
        f->fy[3] = x[VH_SKF_FYR] * f->fz[3] / fzr;
    }
    f->health = vh_kf_step_health(&f->steps, (mask & VH_SKF_ALL_VALID) != VH_SKF_ALL_VALID, INIT_STEPS);
    return 0;

diverged:
    restart(f);
    return vh_kf_fault(&f->resets, &f->health);
}

uint32_t vh_skf_run(vh_skf_t *f, size_t n, const double *u, const uint8_t *mask, double *x_out,
                    double *fy_out, double *fz_out, double *p_out, uint8_t *health_out)
{
    size_t t;
    uint32_t resets = 0u;
    for (t = 0; t < n; ++t) {
        vh_skf_input_t in;
        memcpy(&in, u + t * VH_SKF_NU, sizeof in);
        resets += (uint32_t)vh_skf_step(f, &in, mask ? mask[t] : VH_SKF_ALL_VALID);
        vh_skf_state(f, x_out + t * NX);
        memcpy(fy_out + t * 4, f->fy, sizeof f->fy);
        memcpy(fz_out + t * 4, f->fz, sizeof f->fz);
        if (p_out) {
            memcpy(p_out + t * NX * NX, f->p, sizeof f->p);
        }
        if (health_out) {
            health_out[t] = f->health;
        }
    }
    return resets;
}
