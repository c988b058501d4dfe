/* vh_dlplant.c - see vh_dlplant.h. Equation numbers refer to seed 001 (Kim 2011). */
#include "vh_dlplant.h"
#include "vh_mat.h"
#include "vh_tc.h"

#include <math.h>

#define TWO_PI 6.283185307179586
/* Largest rate (1/s) times the sub-step allowed; RK4's real-axis stability limit is 2.78. */
#define MAX_LAMBDA_H 1.0
/* Engine speed beyond which the full-load curve is zero (fuel cut) [rad/s]. */
#define WE_CUT 733.0382858376184 /* 7000 rpm */

/* Full-load torque shape of a ~2 L naturally aspirated petrol engine, as a fraction of the peak,
 * every 500 rpm from 0 to the 7000 rpm fuel cut: 110 Nm at 500-1000 rpm, peak at 4000 rpm. A
 * uniform grid makes the lookup one multiplication. */
#define N_BP 15
#define BP_STEP (WE_CUT / (N_BP - 1))
static const double TE_SHAPE[N_BP] = {0.55, 0.55, 0.70, 0.80, 0.86, 0.90, 0.925, 0.965,
                                      1.0, 0.99, 0.975, 0.94, 0.895, 0.815, 0.0};

/* Steepest slope of the converter capacity (near coupling), for sub-step sizing. */
#define BLEND_A (vh_tc_max_slope())

void vh_dlp_params_default(vh_dlp_params_t *prm)
{
    prm->jo = 0.016;
    prm->jv = 160.0;
    prm->rd = 0.255;
    /* the ECU's table (c_core vh_ecu.c): a typical 5-speed transaxle around 2nd = 0.43 */
    prm->ri[0] = 0.28;
    prm->ri[1] = 0.43;
    prm->ri[2] = 0.66;
    prm->ri[3] = 0.91;
    prm->ri[4] = 1.18;
    prm->ks = 9000.0;
    /* critical damping of the shaft mode is 2 sqrt(k_s J_eq) = 94 Nm s/rad with
     * J_eq = (J_o/R_d^2) J_v / (J_o/R_d^2 + J_v) = 0.245 kg m^2: 5 Nm s/rad is ~5 % */
    prm->cs = 5.0;
    prm->rt = 0.3;
    prm->mu_r = 0.012;
    prm->rho = 1.23;
    prm->ca = 0.33;
    prm->area = 2.0;
    prm->roll_w_eps = 0.1; /* 3 cm/s */
    prm->je = 0.2;         /* crank, flywheel and pump impeller */
    prm->te_peak = 200.0;  /* gross; net ~180 Nm at 4000 rpm after friction */
    prm->fric0 = 8.0;
    prm->fric1 = 0.025;
    prm->w_idle = 80.0;    /* 764 rpm */
    prm->gov_kp = 2.0;     /* with J_e = 0.2: closed loop w_n ~ 7 rad/s, near critical damping */
    prm->gov_ki = 10.0;
    prm->gov_max = 50.0;
    prm->road_std = 20.0;
    prm->road_bw = 10.0;
    prm->road_w_ref = 5.0; /* 1.5 m/s */
}

/* ---- torque converter (eq. 9) ------------------------------------------------------------ */

/* Eq. 9 with its coupling/overrun extension: one implementation, in c_core/src/vh_tc.c, so the
 * plant and the ECU's input model share the converter's characteristic (see vh_tc.h). */
void vh_dlp_converter(double we, double wt, double *tp, double *ti)
{
    vh_tc_torques(we, wt, tp, ti); /* the characteristic the ECU's input model uses too */
}

/* ---- engine, road load --------------------------------------------------------------------- */

double vh_dlp_full_load_torque(const vh_dlp_params_t *prm, double we)
{
    double f;
    int i;
    if (!(we > 0.0)) {
        return prm->te_peak * TE_SHAPE[0];
    }
    if (!(we < WE_CUT)) {
        return 0.0; /* fuel cut */
    }
    f = we * (1.0 / BP_STEP);
    i = (int)f;
    f -= (double)i;
    return prm->te_peak * (TE_SHAPE[i] + f * (TE_SHAPE[i + 1] - TE_SHAPE[i]));
}

/* Road-load coefficients: T_l = c_roll s(w_w) + c_aero w_w |w_w|, s(w) = w / sqrt(w^2 + eps^2). */
static void road_coeffs(const vh_dlp_params_t *prm, double *c_roll, double *c_aero, double *eps2)
{
    const double m = prm->jv / (prm->rt * prm->rt); /* J_v = m r_t^2 */
    /* eq. 3 with g, and the tyre radius in the aero term: r_t (mu_r m g + rho/2 C_a A (r_t w_w)^2) */
    *c_roll = prm->rt * prm->mu_r * m * VH_DLP_GRAVITY;
    *c_aero = 0.5 * prm->rho * prm->ca * prm->area * prm->rt * prm->rt * prm->rt;
    *eps2 = prm->roll_w_eps * prm->roll_w_eps;
}

/* The smooth sign makes the rolling resistance fade at rest (no chatter at w_w = 0) and act
 * there as a stiff viscous drag, which cannot push a standing car backwards. */
static double road_load(double c_roll, double c_aero, double eps2, double ww)
{
    return c_roll * ww / sqrt(ww * ww + eps2) + c_aero * ww * fabs(ww);
}

double vh_dlp_road_load(const vh_dlp_params_t *prm, double ww)
{
    double c_roll, c_aero, eps2;
    road_coeffs(prm, &c_roll, &c_aero, &eps2);
    return road_load(c_roll, c_aero, eps2, ww);
}

/* ---- dynamics ------------------------------------------------------------------------------ */

typedef struct {
    double te, tp, ti, wt, to, tl;
} aux_t;

/* Time derivative of x with throttle thr, inverse gear ratio 1/R_i (0: neutral) and roughness
 * torque td. */
static void deriv(const vh_dlp_t *p, const double x[VH_DLP_NX], double thr, double inv_ri,
                  double td, double dx[VH_DLP_NX], aux_t *aux)
{
    const vh_dlp_params_t *prm = &p->prm;
    const double we = x[VH_DLP_X_WE];
    const double wo = x[VH_DLP_X_WO];
    const double ww = x[VH_DLP_X_WW];
    const double err = prm->w_idle - we;
    const double slip = prm->rd * wo - ww; /* shaft twist rate */
    double gov = prm->gov_kp * err + x[VH_DLP_X_GOV];
    double tp = 0.0, ti = 0.0, wt = we, to, tl, te;

    gov = gov < 0.0 ? 0.0 : (gov > prm->gov_max ? prm->gov_max : gov);
    te = thr * vh_dlp_full_load_torque(prm, we) + gov - prm->fric0 * we / sqrt(we * we + 25.0) - prm->fric1 * we;
    if (inv_ri > 0.0) {
        wt = wo * inv_ri; /* turbine tied to the output shaft: w_o = R_i w_t */
        vh_dlp_converter(we, wt, &tp, &ti);
    }
    to = x[VH_DLP_X_TS] + prm->cs * slip; /* spring + damper */
    tl = road_load(p->c_roll, p->c_aero, p->eps2, ww);

    dx[VH_DLP_X_WE] = (te - tp) * p->inv_je;                                  /* J_e w_e' = T_e - T_p */
    dx[VH_DLP_X_WO] = (ti * inv_ri - prm->rd * to) * p->inv_jo;               /* eq. 1 */
    dx[VH_DLP_X_WW] = (to - tl - td) * p->inv_jv;                             /* eq. 2 / 5 (J_v) */
    dx[VH_DLP_X_TS] = prm->ks * slip;                                         /* eq. 7 */
    /* integrator with anti-windup: it stops at its limits instead of winding past them */
    if ((x[VH_DLP_X_GOV] >= prm->gov_max && err > 0.0) || (x[VH_DLP_X_GOV] <= 0.0 && err < 0.0)) {
        dx[VH_DLP_X_GOV] = 0.0;
    } else {
        dx[VH_DLP_X_GOV] = prm->gov_ki * err;
    }
    if (aux != NULL) {
        aux->te = te;
        aux->tp = tp;
        aux->ti = ti;
        aux->wt = wt;
        aux->to = to;
        aux->tl = tl;
    }
}

static void rk4(const vh_dlp_t *p, double x[VH_DLP_NX], double thr, double inv_ri, double td, double h)
{
    double k1[VH_DLP_NX], k2[VH_DLP_NX], k3[VH_DLP_NX], k4[VH_DLP_NX], xt[VH_DLP_NX];
    int i;
    deriv(p, x, thr, inv_ri, td, k1, NULL);
    for (i = 0; i < VH_DLP_NX; ++i) {
        xt[i] = x[i] + 0.5 * h * k1[i];
    }
    deriv(p, xt, thr, inv_ri, td, k2, NULL);
    for (i = 0; i < VH_DLP_NX; ++i) {
        xt[i] = x[i] + 0.5 * h * k2[i];
    }
    deriv(p, xt, thr, inv_ri, td, k3, NULL);
    for (i = 0; i < VH_DLP_NX; ++i) {
        xt[i] = x[i] + h * k3[i];
    }
    deriv(p, xt, thr, inv_ri, td, k4, NULL);
    for (i = 0; i < VH_DLP_NX; ++i) {
        x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    }
}

/* Fill p->truth from the state after a step. */
static void update_truth(vh_dlp_t *p, double thr, int gear, double td)
{
    const vh_dlp_params_t *prm = &p->prm;
    const double inv_ri = gear > 0 ? 1.0 / prm->ri[gear - 1] : 0.0;
    double dx[VH_DLP_NX];
    aux_t aux;
    vh_dlp_truth_t *t = &p->truth;
    deriv(p, p->x, thr, inv_ri, td, dx, &aux);
    t->t = (double)p->steps * VH_DLP_DT;
    t->throttle = thr;
    t->gear = gear;
    t->we = p->x[VH_DLP_X_WE];
    t->wt = aux.wt;
    t->wo = p->x[VH_DLP_X_WO];
    t->ww = p->x[VH_DLP_X_WW];
    t->to = aux.to;
    t->ti = aux.ti;
    t->tp = aux.tp;
    t->te = aux.te;
    t->tl = aux.tl;
    t->td = td;
    t->v = prm->rt * t->ww;
    t->sr = t->we > 1e-3 ? t->wt / t->we : 0.0;
}

/* ---- parameter check ----------------------------------------------------------------------- */

/* Upper bound of the fastest gear-independent rate [1/s] of the linearised dynamics. */
static double base_rate(const vh_dlp_params_t *prm)
{
    const double inv_j = prm->rd * prm->rd / prm->jo + 1.0 / prm->jv; /* J_o seen from the wheel end */
    double lam, l;
    lam = sqrt(prm->ks * inv_j);                                        /* shaft mode */
    l = prm->cs * inv_j;                                                /* shaft damper */
    lam = l > lam ? l : lam;
    l = (prm->gov_kp + prm->fric1 + prm->fric0 / 5.0 + WE_CUT * (2.0 * 1.874e-3 /* eq. 9: C_f(0) */ + BLEND_A)) / prm->je;
    lam = l > lam ? l : lam;                                            /* engine side */
    l = prm->mu_r * VH_DLP_GRAVITY / (prm->rt * prm->roll_w_eps);       /* rolling resistance at rest */
    return l > lam ? l : lam;
}

/* Upper bound of the converter's turbine-side rate [1/s] at engine speed we: the capacity's
 * steepest slope (BLEND_A, near coupling) times w_e, over the output inertia seen at the turbine. */
static double conv_rate(double inv_ri, double inv_jo, double we)
{
    return BLEND_A * we * inv_ri * inv_ri * inv_jo;
}

/* Sub-steps keeping rate * h <= MAX_LAMBDA_H; more than VH_DLP_MAX_SUBSTEPS gives 0. */
static unsigned substeps(double rate)
{
    const double need = ceil(rate * VH_DLP_DT / MAX_LAMBDA_H);
    if (!(need <= (double)VH_DLP_MAX_SUBSTEPS)) {
        return 0u;
    }
    return need < 1.0 ? 1u : (unsigned)need;
}

static int params_ok(const vh_dlp_params_t *prm)
{
    const double positive[] = {prm->jo, prm->jv, prm->rd, prm->ks, prm->rt, prm->roll_w_eps, prm->je,
                               prm->te_peak, prm->w_idle, prm->road_bw, prm->road_w_ref};
    const double nonneg[] = {prm->cs, prm->mu_r, prm->rho, prm->ca, prm->area, prm->fric0, prm->fric1,
                             prm->gov_kp, prm->gov_ki, prm->gov_max, prm->road_std};
    const size_t np = sizeof positive / sizeof positive[0];
    const size_t nn = sizeof nonneg / sizeof nonneg[0];
    double lam, l;
    size_t i;
    int g;

    if (!vh_mat_finite(positive, (int)np) || !vh_mat_finite(nonneg, (int)nn) || !vh_mat_finite(prm->ri, VH_DLP_NGEARS)) {
        return 0;
    }
    for (i = 0; i < np; ++i) {
        if (!(positive[i] > 0.0)) {
            return 0;
        }
    }
    for (i = 0; i < nn; ++i) {
        if (!(nonneg[i] >= 0.0)) {
            return 0;
        }
    }
    lam = base_rate(prm);
    if (substeps(lam) == 0u) {
        return 0;
    }
    for (g = 0; g < VH_DLP_NGEARS; ++g) {
        if (!(prm->ri[g] > 0.0)) {
            return 0;
        }
        l = conv_rate(1.0 / prm->ri[g], 1.0 / prm->jo, WE_CUT);
        if (substeps(l > lam ? l : lam) == 0u) {
            return 0; /* a gear the fixed step cannot resolve up to the fuel-cut speed */
        }
    }
    return prm->road_bw < 0.5 / VH_DLP_DT; /* above Nyquist the OU process is not coloured */
}

/* ---- public -------------------------------------------------------------------------------- */

int vh_dlp_init(vh_dlp_t *p, const vh_dlp_params_t *prm, uint64_t seed)
{
    if (p == NULL || prm == NULL || !params_ok(prm)) {
        return VH_EINVAL;
    }
    p->prm = *prm;
    p->seed = seed;
    p->rough_a = exp(-TWO_PI * prm->road_bw * VH_DLP_DT);
    p->rough_b = sqrt(1.0 - p->rough_a * p->rough_a);
    p->inv_je = 1.0 / prm->je;
    p->inv_jo = 1.0 / prm->jo;
    p->inv_jv = 1.0 / prm->jv;
    road_coeffs(prm, &p->c_roll, &p->c_aero, &p->eps2);
    p->rate_base = base_rate(prm);
    vh_dlp_reset(p);
    return VH_OK;
}

void vh_dlp_reset(vh_dlp_t *p)
{
    int i;
    for (i = 0; i < VH_DLP_NX; ++i) {
        p->x[i] = 0.0;
    }
    p->x[VH_DLP_X_WE] = p->prm.w_idle;
    p->steps = 0u;
    p->bad_inputs = 0u;
    vh_rng_seed(&p->rng, p->seed);
    p->rough = p->prm.road_std * vh_rng_gauss(&p->rng); /* start in the stationary distribution */
    update_truth(p, 0.0, 0, 0.0);
}

int vh_dlp_set_rolling(vh_dlp_t *p, double v, int gear)
{
    const vh_dlp_params_t *prm = &p->prm;
    double wt;
    if (!(v >= 0.0 && v <= 100.0) || gear < 0 || gear > VH_DLP_NGEARS) {
        return VH_EINVAL;
    }
    p->x[VH_DLP_X_WW] = v / prm->rt;
    p->x[VH_DLP_X_WO] = p->x[VH_DLP_X_WW] / prm->rd;
    p->x[VH_DLP_X_TS] = 0.0;
    p->x[VH_DLP_X_GOV] = 0.0;
    wt = gear > 0 ? p->x[VH_DLP_X_WO] / prm->ri[gear - 1] : 0.0;
    p->x[VH_DLP_X_WE] = wt > prm->w_idle ? wt : prm->w_idle;
    update_truth(p, 0.0, gear, 0.0);
    return VH_OK;
}

void vh_dlp_step(vh_dlp_t *p, double throttle, int gear)
{
    const vh_dlp_params_t *prm = &p->prm;
    double inv_ri, td, wabs, rate, h;
    unsigned k, nsub;
    int bad = 0;

    if (isnan(throttle) || throttle < 0.0) {
        bad = 1;
        throttle = 0.0;
    } else if (throttle > 1.0) {
        bad = 1;
        throttle = 1.0;
    }
    if (gear < 0 || gear > VH_DLP_NGEARS) {
        bad = 1;
        gear = 0;
    }
    if (bad && p->bad_inputs < UINT32_MAX) {
        ++p->bad_inputs;
    }
    inv_ri = gear > 0 ? 1.0 / prm->ri[gear - 1] : 0.0;

    /* roughness excitation grows with speed (the profile is swept faster) and is gone at rest;
     * held over the step */
    wabs = fabs(p->x[VH_DLP_X_WW]);
    td = p->rough * (wabs < prm->road_w_ref ? wabs / prm->road_w_ref : 1.0);

    /* sub-steps for this step: the converter's rate grows with w_e, which moves < 1 rad/s per
     * step; 10 % + 10 rad/s margin. Beyond VH_DLP_MAX_SUBSTEPS (w_e far past fuel cut, only
     * if the wheels overspeed the engine) the maximum is used: RK4 stays stable to 2.78. */
    rate = p->rate_base;
    if (gear > 0) {
        const double lc = conv_rate(inv_ri, p->inv_jo, 1.1 * p->x[VH_DLP_X_WE] + 10.0);
        rate = lc > rate ? lc : rate;
    }
    nsub = substeps(rate);
    nsub = nsub == 0u ? VH_DLP_MAX_SUBSTEPS : nsub;
    h = VH_DLP_DT / (double)nsub;
    for (k = 0; k < nsub; ++k) {
        rk4(p, p->x, throttle, inv_ri, td, h);
    }
    if (p->x[VH_DLP_X_GOV] < 0.0) {
        p->x[VH_DLP_X_GOV] = 0.0;
    } else if (p->x[VH_DLP_X_GOV] > prm->gov_max) {
        p->x[VH_DLP_X_GOV] = prm->gov_max;
    }
    if (p->x[VH_DLP_X_WE] < 0.0) {
        p->x[VH_DLP_X_WE] = 0.0; /* a stalled engine does not run backwards */
    }
    /* exact discretisation of the OU process: the stationary std stays road_std for any dt */
    p->rough = p->rough_a * p->rough + p->rough_b * prm->road_std * vh_rng_gauss(&p->rng);
    ++p->steps;
    update_truth(p, throttle, gear, td);
}

size_t vh_dlp_run(vh_dlp_t *p, size_t n, const double *throttle, int gear, vh_dlp_truth_t *out)
{
    size_t i;
    for (i = 0; i < n; ++i) {
        vh_dlp_step(p, throttle != NULL ? throttle[i] : 0.0, gear);
        if (out != NULL) {
            out[i] = p->truth;
        }
    }
    return n;
}
