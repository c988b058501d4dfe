/* vh_roll_params.c - default parameters of the roll UKF and its sliding-mode controller.
 * Vehicle: the project's 14-DOF plant (firmware_sim vh_v14_params_default; seed 000's Ford
 * FC/HVE car plus the documented chosen values); docs/roll.md has every figure and why. */
#include <stddef.h>

#include "vh_roll.h"

void vh_roll_params_default(vh_roll_params_t *prm)
{
    int i;
    if (prm == NULL) {
        return;
    }
    prm->ms = 1661.0; prm->ix = 580.0; prm->iy = 2450.0; prm->iz = 2560.0;
    prm->lf = 1.076; prm->lr = 1.617; prm->tf = 0.784; prm->tr = 0.760;
    prm->h = 0.55; prm->hf = 0.114; prm->hr = 0.004;
    prm->kphi_f = 108205.8; prm->kphi_r = 81436.7; prm->cphi_f = 826.8; prm->cphi_r = 658.9;
    prm->m_uf = 153.0 / 2.0 * 1.617 / (1.076 + 1.617);
    prm->m_ur = 153.0 / 2.0 * 1.076 / (1.076 + 1.617);
    prm->k_f = 30000.0; prm->k_r = 25000.0; prm->kt = 250000.0; prm->ct = 100.0;
    /* cornering stiffness per unit load of the plant's tyre at the static loads (docs/roll.md) */
    prm->calpha_f = 17.34; prm->calpha_r = 20.22;
    prm->mf_c = 1.30; prm->mu = 1.0; prm->mu_load = 0.94; prm->v_low = 1.0;
    prm->dt = 0.001; prm->kappa = 1.0;
    /* Q per step: random-walk acceleration noise on the velocity states (model error: the
     * simplified tyre above all), small on the positions */
    for (i = 0; i < VH_ROLL_NX; ++i) {
        prm->q[i] = 1e-12;
    }
    prm->q[VH_ROLL_X_VY] = 1e-5;
    prm->q[VH_ROLL_X_R] = 1e-6;
    prm->q[VH_ROLL_X_VZ] = 1e-6;
    prm->q[VH_ROLL_X_P] = 1e-8;  /* the roll balance is well known: small */
    prm->q[VH_ROLL_X_Q] = 1e-6;
    for (i = 0; i < VH_ROLL_NW; ++i) {
        prm->q[VH_ROLL_X_VZU + i] = 1e-4;
    }
    /* robust variant: the roll-moment disturbance's random walk per step [kN m]^2 (docs/roll.md) */
    prm->q[VH_ROLL_X_D] = 1e-5;
    for (i = 0; i < VH_ROLL_NW; ++i) {
        prm->q[VH_ROLL_X_DFZ + i] = 1e-3; /* [kN]^2 */
    }
    /* R: the sensor noise of docs/roll.md */
    prm->r[VH_ROLL_Z_AY] = 0.05 * 0.05;
    for (i = 0; i < VH_ROLL_NW; ++i) {
        prm->r[VH_ROLL_Z_AZU + i] = 0.2 * 0.2;
        prm->r[VH_ROLL_Z_DT + i] = 0.0002 * 0.0002;
        prm->r[VH_ROLL_Z_DS + i] = 0.0005 * 0.0005;
    }
    prm->r[VH_ROLL_Z_R] = 0.005 * 0.005;
    prm->p0[VH_ROLL_X_VY] = 0.5 * 0.5;
    prm->p0[VH_ROLL_X_R] = 0.05 * 0.05;
    prm->p0[VH_ROLL_X_Z] = 0.01 * 0.01;
    prm->p0[VH_ROLL_X_VZ] = 0.05 * 0.05;
    prm->p0[VH_ROLL_X_PHI] = 0.02 * 0.02;
    prm->p0[VH_ROLL_X_P] = 0.05 * 0.05;
    prm->p0[VH_ROLL_X_THETA] = 0.01 * 0.01;
    prm->p0[VH_ROLL_X_Q] = 0.05 * 0.05;
    for (i = 0; i < VH_ROLL_NW; ++i) {
        prm->p0[VH_ROLL_X_ZU + i] = 0.005 * 0.005;
        prm->p0[VH_ROLL_X_VZU + i] = 0.05 * 0.05;
    }
    prm->p0[VH_ROLL_X_D] = 1.0; /* 1 kN m */
    for (i = 0; i < VH_ROLL_NW; ++i) {
        prm->p0[VH_ROLL_X_DFZ + i] = 0.25; /* 0.5 kN */
    }
    prm->reg_eps = 1e-6;
    prm->nis_max = 1000.0;
    prm->phi_max = 0.3;
    /* converged: roll within 0.02 deg, roll rate within 0.2 deg/s (1 sigma of P). From P0 that takes
     * 6 steps at 5 ms; the steady state is 0.0015 deg / 0.026 deg/s (docs/roll.md) */
    prm->conv_sd_phi = 3.5e-4;
    prm->conv_sd_p = 3.5e-3;
    /* the robust variant's adaptive roll-rate noise: 0.1 s, q_p at most 1e4 times its own (docs/roll.md) */
    prm->qp_adapt_tau = 0.1;
    prm->qp_adapt_max = 100.0;
    /* the paper's UKF with a kinematic a_y; the ECU's app runs the robust variant on a body-fixed
     * accelerometer (vh_roll_app_config_default) */
    prm->variant = VH_ROLL_V_PAPER;
    prm->ay_gravity = 0u;
}

void vh_roll_smc_params_default(vh_roll_smc_params_t *c, const vh_roll_params_t *prm)
{
    double l, h_ra, e;
    if (c == NULL || prm == NULL) {
        return;
    }
    l = prm->lf + prm->lr;
    h_ra = prm->hf + (prm->hr - prm->hf) * prm->lf / l;
    e = prm->h - h_ra;
    c->lambda = 10.0; c->k = 5.0; c->p = 0.1;
    c->ref_frac = 0.3; c->ref_tau = 0.05; c->ay_tau = 0.02;
    c->front_share = prm->kphi_f / (prm->kphi_f + prm->kphi_r);
    /* 48 V electromechanical stabiliser, ~1.2 kNm at the bar per axle; through the bar's lever
     * arms and links that is ~4.8 kNm of roll moment on the body (docs/roll.md) */
    c->m_max_f = 4800.0; c->m_max_r = 4800.0;
    c->rate_max_f = 16000.0; c->rate_max_r = 16000.0;
    c->fade_time = 0.3; /* = m_max / rate_max: the fastest the rate limit allows */
    c->recover_time = 0.5;
    /* ride-through: a not-OK estimate (frames missing, every input timed out, the actuators holding)
     * for up to 60 ms = 12 sensor frames holds the fade and keeps acting on the UKF's prediction, so a
     * host stall of a few tens of ms does not drop the actuators; a real fault trips 60 ms after it is
     * detected and is faded out 0.36 s after (within the fault tests' 0.5 s; docs/roll.md) */
    c->not_ok_debounce = 0.06;
    c->dt = prm->dt;
    c->i_roll = prm->ix + prm->ms * e * e;
    c->ms_e = prm->ms * e;
    c->kphi = prm->kphi_f + prm->kphi_r;
    c->cphi = prm->cphi_f + prm->cphi_r;
    /* the robust variant's disturbance estimate enters eq. 27 whole; the paper's has none */
    c->dist_gain = prm->variant == VH_ROLL_V_ROBUST ? 1.0 : 0.0;
    /* the actuator acts between body and axle, so a steady moment turns the body against the
     * suspension alone (the tyres carry no net moment): per axle k_phi,i / k_susp,i of what eq. 27
     * says (docs/roll.md, "The robust law") */
    {
        const double ksf = 1.0 / (1.0 / prm->kphi_f - 1.0 / (2.0 * prm->kt * prm->tf * prm->tf));
        const double ksr = 1.0 / (1.0 / prm->kphi_r - 1.0 / (2.0 * prm->kt * prm->tr * prm->tr));
        c->eta = c->front_share * prm->kphi_f / ksf + (1.0 - c->front_share) * prm->kphi_r / ksr;
    }
    c->ki = 0.0;
    c->i_frac = 0.25;
    c->law = VH_ROLL_L_PAPER;
    if (prm->variant == VH_ROLL_V_ROBUST) {
        vh_roll_smc_law_robust(c);
    }
}

void vh_roll_smc_law_robust(vh_roll_smc_params_t *c)
{
    /* chosen on the design cases (roll_paper_{36,72}kph_active and control_table.DESIGN, both plants;
     * docs/roll.md, "The robust law") */
    c->law = VH_ROLL_L_ROBUST;
    c->lambda = 1.0;  /* the surface's corner far below the roll mode (~14 rad/s): the layer damps */
    c->k = 5.0;
    c->p = 0.75;      /* slope k/p = 6.7 /s, a fifth of the actuator's bandwidth 1/(30 ms): the
                       * estimated rate lags ~40 ms on MB, and the layer's damping through that lag,
                       * the actuator's and its rate limit must not turn into negative damping */
    c->ki = 200.0;
    c->ay_tau = 0.05; /* the feedforward's a_y: the estimate carries a plant's roll mode (MB) */
    c->ref_tau = 0.1; /* the reference lags a_y: the feedforward leads in a transient */
    /* no disturbance feedforward: on a foreign plant d carries the plant's unmodelled roll dynamics
     * and closes a second loop through the UKF (docs/roll.md); the integral takes the steady part */
    c->dist_gain = 0.0;
}

/* Every value in (0, 1e12): a parameter that must be positive, and not absurd. */
static int all_positive(const double *v, size_t n)
{
    size_t i;
    int ok = 1;
    for (i = 0; i < n; ++i) {
        ok = ok && v[i] > 0.0 && v[i] < 1e12;
    }
    return ok;
}
/* all_positive over the arguments (a C99 compound literal: the count cannot go stale) */
#define POSITIVE(...) \
    all_positive((const double[]){__VA_ARGS__}, sizeof((const double[]){__VA_ARGS__}) / sizeof(double))

int vh_roll_params_check(const vh_roll_params_t *prm)
{
    int i, ok;
    if (prm == NULL) {
        return -1;
    }
    /* ct may be 0: ct + 1 */
    ok = POSITIVE(prm->ms, prm->ix, prm->iy, prm->iz, prm->lf, prm->lr, prm->tf, prm->tr, prm->h, prm->kphi_f,
                  prm->kphi_r, prm->cphi_f, prm->cphi_r, prm->m_uf, prm->m_ur, prm->k_f, prm->k_r, prm->kt,
                  prm->calpha_f, prm->calpha_r, prm->mf_c, prm->mu, prm->mu_load, prm->v_low, prm->dt, prm->ct + 1.0);
    for (i = 0; i < VH_ROLL_NX; ++i) {
        ok = ok && prm->q[i] >= 0.0 && prm->q[i] < 1e12 && prm->p0[i] > 0.0 && prm->p0[i] < 1e12;
    }
    for (i = 0; i < VH_ROLL_NZ; ++i) {
        ok = ok && prm->r[i] > 0.0 && prm->r[i] < 1e12;
    }
    ok = ok && prm->kappa >= 0.0 && prm->kappa < 1e6 && prm->hf < prm->h && prm->hr < prm->h &&
         prm->hf >= 0.0 && prm->hr >= 0.0 && prm->cphi_f >= 0.0 && prm->cphi_r >= 0.0 &&
         prm->reg_eps > 0.0 && prm->reg_eps < 1.0 && prm->nis_max >= 0.0 && prm->phi_max > 0.0 &&
         prm->conv_sd_phi > 0.0 && prm->conv_sd_phi < 1e3 && prm->conv_sd_p > 0.0 && prm->conv_sd_p < 1e3 &&
         prm->qp_adapt_tau >= 0.0 && prm->qp_adapt_tau < 1e3 && prm->qp_adapt_max >= 1.0 && prm->qp_adapt_max <= 1e3 &&
         (prm->variant == VH_ROLL_V_PAPER || prm->variant == VH_ROLL_V_ROBUST) && prm->ay_gravity <= 1u;
    if (ok) {
        /* suspension roll stiffness with the tyres in series removed (as the plant,
         * docs/chassis_plant.md): positive. The bar, what the springs leave of it, may be negative */
        const double ksf = 1.0 / (1.0 / prm->kphi_f - 1.0 / (2.0 * prm->kt * prm->tf * prm->tf));
        const double ksr = 1.0 / (1.0 / prm->kphi_r - 1.0 / (2.0 * prm->kt * prm->tr * prm->tr));
        ok = ksf > 0.0 && ksr > 0.0;
    }
    return ok ? 0 : -1;
}

int vh_roll_smc_params_check(const vh_roll_smc_params_t *prm)
{
    int ok;
    if (prm == NULL) {
        return -1;
    }
    /* recover_time and cphi may be 0: + 1 */
    ok = POSITIVE(prm->lambda, prm->k, prm->p, prm->ref_tau, prm->m_max_f, prm->m_max_r, prm->rate_max_f,
                  prm->rate_max_r, prm->fade_time, prm->dt, prm->i_roll, prm->ms_e, prm->kphi,
                  prm->recover_time + 1.0, prm->cphi + 1.0, prm->ay_tau);
    ok = ok && prm->ref_frac >= 0.0 && prm->ref_frac <= 1.0 && prm->front_share >= 0.0 &&
         prm->front_share <= 1.0 && prm->recover_time >= 0.0 && prm->not_ok_debounce >= 0.0 &&
         prm->not_ok_debounce < 1e3 && prm->cphi >= 0.0 && prm->dist_gain >= 0.0 && prm->dist_gain <= 1.0 &&
         prm->fade_time * prm->rate_max_f >= prm->m_max_f * (1.0 - 1e-9) &&
         prm->fade_time * prm->rate_max_r >= prm->m_max_r * (1.0 - 1e-9) && /* the rate limit can follow the fade */
         (prm->law == VH_ROLL_L_PAPER || prm->law == VH_ROLL_L_ROBUST) && prm->eta > 0.0 && prm->eta <= 1.0 &&
         prm->ki >= 0.0 && prm->ki < 1e6 && prm->i_frac >= 0.0 && prm->i_frac <= 1.0;
    return ok ? 0 : -1;
}
