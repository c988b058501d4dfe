/* vh_veh14.c - see vh_veh14.h. Equation numbers refer to seed 000 (Kim & Huh 2000). */
#include "vh_veh14.h"

#include <math.h>

#define G VH_V14_GRAVITY
/* Largest rate (1/s) times the sub-step allowed. Heun's real-axis stability limit is 2; at 1 the
 * fastest (wheel-spin) mode decays without overshoot (amplification 1 - z + z^2/2 > 0). */
#define MAX_LAMBDA_H 1.0
/* Margin on the wheel-spin rate: the loads, hence the slip stiffness, move within a step. */
#define SPIN_MARGIN 1.25
/* Brake torque fades linearly below this wheel speed [rad/s] (a Coulomb brake, regularised). */
#define BRAKE_W_EPS 0.05
/* Input limits. */
#define STEER_MAX 0.6
#define MU_MAX 3.0

/* Per-step constants of the right-hand side. */
typedef struct {
    double cd, sd;                 /* cos, sin of the steer angle */
    double drive[VH_V14_NW];
    double brake[VH_V14_NW];
    double inv_brake_eps[VH_V14_NW]; /* [s/rad] */
    double mu[VH_V14_NW];
    /* parameter combinations, so the right-hand side multiplies instead of divides */
    double inv_iw, inv_mu[VH_V14_NW], jack[VH_V14_NW], arb_f, arb_r;
    unsigned refresh;              /* bit i: the truth stage refreshes tyre i's peak slips */
    int arc_on;                    /* an active roll moment acts this step (else: the passive plant, untouched) */
    double arc_f[VH_V14_NW];       /* its vertical force on each body corner, + up [N] */
} ctx_t;

/* What the right-hand side computes besides the derivative (for the truth). */
typedef struct {
    double fx[VH_V14_NW], fy[VH_V14_NW], fxv[VH_V14_NW], fyv[VH_V14_NW], fz[VH_V14_NW];
    double kappa[VH_V14_NW], tan_alpha[VH_V14_NW], torque[VH_V14_NW];
    double ck[VH_V14_NW];
    vh_mft_state_t pk[VH_V14_NW];
} aux_t;

void vh_v14_params_default(vh_v14_params_t *prm)
{
    prm->ms = 1661.0;
    prm->ix = 580.0;
    prm->iz = 2560.0;
    prm->lf = 1.076;
    prm->lr = 1.617;
    prm->h = 0.55;
    prm->tf = 0.784;
    prm->tr = 0.760;
    prm->hf = 0.114;
    prm->hr = 0.004;
    prm->kphi_f = 108205.8;
    prm->kphi_r = 81436.7;
    prm->cphi_f = 826.8;
    prm->cphi_r = 658.9;
    prm->rw = 0.305;
    prm->iw = 2.0;
    /* Pitch inertia of the sprung body ~0.96 Iz, usual for a sedan. */
    prm->iy = 2450.0;
    /* m - ms = 153 kg unsprung, split so the unsprung CG is at the vehicle CG (2 m_uf lf =
     * 2 m_ur lr): sprung and total CG then coincide in plan, as the paper's model assumes.
     * 45.9 kg front (McPherson knuckle, brake, wheel, half strut), 30.6 kg rear. */
    prm->m_uf = 153.0 / 2.0 * prm->lr / (prm->lf + prm->lr);
    prm->m_ur = 153.0 / 2.0 * prm->lf / (prm->lf + prm->lr);
    /* Ride frequencies 1.17 Hz front, 1.32 Hz rear (with the tyres in series). */
    prm->k_f = 30000.0;
    prm->k_r = 25000.0;
    prm->kt = 250000.0; /* 215-235/60 R16 at 2.2 bar */
    prm->ct = 100.0;
    prm->rho = 1.2;
    prm->cda = 0.73;    /* C_d 0.33 x A 2.2 m^2 */
    prm->v_low = 1.0;
    prm->relax_x = 0.0;
    prm->relax_y = 0.0;
    prm->min_substeps = 1;
    vh_mft_coef_default(&prm->tyre);
    /* The published tyre's cornering stiffness peaks at 5.6 kN, about this car's static front
     * load (5.3 kN): a tyre sized for a smaller car. Scaled by 1.75 it peaks at 9.8 kN, 1.8 times
     * the front load, as for a 225/60 R16 98 on a 1.8 t sedan. */
    prm->tyre.fz_scale = 1.75;
}

void vh_v14_input_init(vh_v14_input_t *in, double mu)
{
    int i;
    in->steer = 0.0;
    for (i = 0; i < VH_V14_NW; ++i) {
        in->drive[i] = 0.0;
        in->brake[i] = 0.0;
        in->mu[i] = mu;
    }
}

/* ---- right-hand side ----------------------------------------------------------------------- */

/* dx = f(x) for the inputs in c; aux (may be NULL) receives forces and slips. The tyres' peak slips
 * (the combined-slip normalisation, never the pure-slip curves) are those of the truth stage, p->pk,
 * held over the step. */
static void deriv(const vh_v14_t *p, const ctx_t *c, const double *x, double *dx, aux_t *aux)
{
    const vh_v14_params_t *prm = &p->prm;
    const double vx = x[VH_V14_X_VX], vy = x[VH_V14_X_VY], r = x[VH_V14_X_R];
    const double z = x[VH_V14_X_Z], vz = x[VH_V14_X_VZ];
    const double phi = x[VH_V14_X_PHI], pr = x[VH_V14_X_P];
    const double th = x[VH_V14_X_THETA], qr = x[VH_V14_X_Q];
    const double ms = prm->ms, a_c = ms * p->hp, b_c = ms * p->e;
    double d[VH_V14_NW], fsd[VH_V14_NW], fb[VH_V14_NW], farb[VH_V14_NW];
    double sfx = 0.0, sfy = 0.0, smz = 0.0, smx, smy, sfz_body = 0.0, faero, rx, ry, rp, rq;
    int i;

    for (i = 0; i < VH_V14_NW; ++i) {
        const double xi = p->cx[i], yi = p->cy[i];
        const double zs = z + yi * phi - xi * th; /* body corner height (small angles) */
        const double vzs = vz + yi * pr - xi * qr;
        const double k = i < 2 ? prm->k_f : prm->k_r;
        const double cdmp = i < 2 ? p->c_f : p->c_r;
        d[i] = x[VH_V14_X_ZU + i] - zs;                                  /* compression */
        fsd[i] = k * d[i] + cdmp * (x[VH_V14_X_VZU + i] - vzs);           /* on the body, up */
    }
    /* anti-roll bars: V = k_arb / 2 ((d_L - d_R) / 2t)^2 */
    farb[0] = c->arb_f * (d[0] - d[1]);
    farb[1] = -farb[0];
    farb[2] = c->arb_r * (d[2] - d[3]);
    farb[3] = -farb[2];

    for (i = 0; i < VH_V14_NW; ++i) {
        const double xi = p->cx[i], yi = p->cy[i];
        const double vxc = vx - r * yi, vyc = vy + r * xi; /* contact-point velocity, body axes */
        const double w = x[VH_V14_X_W + i];
        const double zu = x[VH_V14_X_ZU + i], vzu = x[VH_V14_X_VZU + i];
        const int front = i < 2;
        double vxw, vyw, vden, kappa, ta, fz, fx, fy, fxv, fyv, fj, tb, torque, inv;
        vh_mft_state_t ts;

        if (front) {
            vxw = vxc * c->cd + vyc * c->sd;
            vyw = -vxc * c->sd + vyc * c->cd;
        } else {
            vxw = vxc;
            vyw = vyc;
        }
        vden = fabs(vxw);
        vden = vden > prm->v_low ? vden : prm->v_low;
        inv = 1.0 / vden;
        kappa = (w * prm->rw - vxw) * inv;
        ta = -vyw * inv;
        /* relaxation (not in the paper): the slips the tyre uses lag the kinematic ones, a
         * first-order carcass lag at the rate |v| / L */
        if (prm->relax_x > 0.0) {
            dx[VH_V14_X_SK + i] = vden / prm->relax_x * (kappa - x[VH_V14_X_SK + i]);
            kappa = x[VH_V14_X_SK + i];
        } else {
            dx[VH_V14_X_SK + i] = 0.0;
        }
        if (prm->relax_y > 0.0) {
            dx[VH_V14_X_SA + i] = vden / prm->relax_y * (ta - x[VH_V14_X_SA + i]);
            ta = x[VH_V14_X_SA + i];
        } else {
            dx[VH_V14_X_SA + i] = 0.0;
        }

        fz = p->fz0[i] - prm->kt * zu - prm->ct * vzu; /* tyre load from the unsprung motion */
        fz = fz > 0.0 ? fz : 0.0;                       /* lift-off */
        if (aux != NULL) {
            /* the truth stage: the tyre exactly at its load. Its peak slips (the combined-slip
             * normalisation, never the pure-slip curves) are refreshed for one tyre per tick, each
             * every 2 ms (one Newton iteration from the last: E moves ~1e-5 per tick), else held */
            vh_mft_load(&ts, &prm->tyre, fz, c->mu[i]);
            if (c->refresh & (1u << i)) {
                vh_mft_peaks(&ts, p->pk[i].ux, p->pk[i].uy, 1);
            } else {
                vh_mft_hold_peaks(&ts, &p->pk[i]);
            }
        } else {
            /* later stages: slip stiffness on its tangent about the truth stage's load (error
             * O(dFz^2) = O(h^2): Heun stays second order), peak slips held */
            vh_mft_load_near(&ts, &p->pk[i], &prm->tyre, fz, c->mu[i]);
            vh_mft_hold_peaks(&ts, &p->pk[i]);
        }
        vh_mft_forces(&ts, kappa, ta, &fx, &fy);
        if (front) {
            fxv = fx * c->cd - fy * c->sd;
            fyv = fx * c->sd + fy * c->cd;
        } else {
            fxv = fx;
            fyv = fy;
        }
        fj = c->jack[i] * fyv; /* vertical part of the link force through the roll centre */
        fb[i] = fsd[i] + farb[i] + fj;
        if (c->arc_on) {
            fb[i] += c->arc_f[i]; /* active roll actuator: on the body, reaction on the wheel */
        }
        sfz_body += fb[i];

        sfx += fxv;
        sfy += fyv;
        smz += xi * fyv - yi * fxv; /* the appendix's sum Mz, with x_i = lf, -lr and y_i = +-t */

        /* unsprung vertical: tyre load change against suspension and link forces */
        dx[VH_V14_X_ZU + i] = vzu;
        dx[VH_V14_X_VZU + i] = (fz - p->fz0[i] - fb[i]) * c->inv_mu[i];

        /* wheel spin (eq. 30): the brake acts against the spin, faded in near standstill */
        tb = w * c->inv_brake_eps[i];
        tb = tb > 1.0 ? 1.0 : (tb < -1.0 ? -1.0 : tb);
        torque = c->drive[i] - c->brake[i] * tb;
        dx[VH_V14_X_W + i] = (torque - fx * prm->rw) * c->inv_iw;

        if (aux != NULL) {
            aux->fx[i] = fx;
            aux->fy[i] = fy;
            aux->fxv[i] = fxv;
            aux->fyv[i] = fyv;
            aux->fz[i] = fz;
            aux->kappa[i] = kappa;
            aux->tan_alpha[i] = ta;
            aux->torque[i] = torque;
            aux->ck[i] = ts.kx;
            aux->pk[i] = ts;
        }
    }

    /* roll moment about the roll axis: springs, dampers and bars. The lateral link forces act
     * through the roll centres: their vertical parts (fj) and horizontal parts (at ground level,
     * h_rc below the axis) have equal and opposite moments, so neither appears here. */
    smx = 0.0;
    smy = 0.0;
    for (i = 0; i < VH_V14_NW; ++i) {
        smx += p->cy[i] * (fsd[i] + farb[i]);
        smy -= p->cx[i] * fb[i];
    }
    if (c->arc_on) {
        for (i = 0; i < VH_V14_NW; ++i) {
            smx += p->cy[i] * c->arc_f[i]; /* the actuators' roll moment, Mf + Mr */
        }
    }
    smx += ms * G * p->e * sin(phi); /* gravity on the rolled sprung mass */
    faero = 0.5 * prm->rho * prm->cda * vx * fabs(vx);
    smy += ms * G * p->hp * sin(th) - p->hp * faero;

    /* eq. 29-30 and the matrix E of eq. 35, extended by pitch: the coupled (vx, q) and (vy, p)
     * blocks of a symmetric mass matrix, solved in closed form */
    rx = sfx - faero + p->m * r * vy - b_c * pr * r;
    rq = smy + a_c * r * vy;
    ry = sfy - p->m * r * vx - a_c * qr * r;
    rp = smx + b_c * r * vx;
    dx[VH_V14_X_VX] = (p->iq * rx - a_c * rq) / p->det_x;
    dx[VH_V14_X_Q] = (p->m * rq - a_c * rx) / p->det_x;
    dx[VH_V14_X_VY] = (p->ip * ry + b_c * rp) / p->det_y;
    dx[VH_V14_X_P] = (p->m * rp + b_c * ry) / p->det_y;
    dx[VH_V14_X_R] = smz / prm->iz;
    dx[VH_V14_X_VZ] = sfz_body / ms; /* static spring loads balance the sprung weight */
    dx[VH_V14_X_Z] = vz;
    dx[VH_V14_X_PHI] = pr;
    dx[VH_V14_X_THETA] = qr;
    dx[VH_V14_X_PX] = 0.0; /* the world position follows each sub-step (advance_position) */
    dx[VH_V14_X_PY] = 0.0;
    dx[VH_V14_X_YAW] = r;
}

/* ---- truth --------------------------------------------------------------------------------- */

/* The truth of time steps * DT: p->x, and its derivative dx with the forces in aux under the
 * step's inputs (Heun's first stage). Stores the peak arguments and slip stiffness for later. */
static void fill_truth(vh_v14_t *p, const ctx_t *c, const double *dx, const aux_t *aux, double steer, int nsub)
{
    vh_v14_truth_t *t = &p->truth;
    const double *x = p->x;
    int i;

#define STATE(f, X) t->f = x[VH_V14_X_##X]
    t->t = (double)p->steps * VH_V14_DT;
    STATE(px, PX); STATE(py, PY); STATE(yaw, YAW); STATE(vx, VX); STATE(vy, VY); STATE(r, R);
    t->ax = dx[VH_V14_X_VX] - t->r * t->vy;
    t->ay = dx[VH_V14_X_VY] + t->r * t->vx;
    STATE(z, Z); STATE(vz, VZ); STATE(phi, PHI); STATE(p, P); STATE(theta, THETA); STATE(q, Q);
#undef STATE
    t->steer = steer;
    for (i = 0; i < VH_V14_NW; ++i) {
        t->fx[i] = aux->fx[i];
        t->fy[i] = aux->fy[i];
        t->fxv[i] = aux->fxv[i];
        t->fyv[i] = aux->fyv[i];
        t->fz[i] = aux->fz[i];
        t->kappa[i] = aux->kappa[i];
        t->alpha[i] = atan(aux->tan_alpha[i]);
        t->omega[i] = x[VH_V14_X_W + i];
        t->torque[i] = aux->torque[i];
        t->mu[i] = c->mu[i];
        t->zu[i] = x[VH_V14_X_ZU + i];
        /* spring deflection from its free length: the static one of this car's sprung weight plus
         * the compression zu - z_s,i of the dynamics (small angles, as in the derivative) */
        t->spring_defl[i] = p->fs0[i] / (i < 2 ? p->prm.k_f : p->prm.k_r) + x[VH_V14_X_ZU + i] -
                            (t->z + p->cy[i] * t->phi - p->cx[i] * t->theta);
        /* peak slips at the truth loads, held for the rest of the step; slip stiffness for the
         * next step's sub-step count */
        p->ck[i] = aux->ck[i];
        p->pk[i] = aux->pk[i];
    }
    t->fyf = 0.5 * (t->fy[0] + t->fy[1]);
    t->fyr = 0.5 * (t->fy[2] + t->fy[3]);
    t->substeps = nsub;
}

/* ---- parameters ---------------------------------------------------------------------------- */

static int finite_positive(const double *v, size_t n)
{
    size_t i;
    for (i = 0; i < n; ++i) {
        if (!isfinite(v[i]) || !(v[i] > 0.0)) {
            return 0;
        }
    }
    return 1;
}

static int finite_nonneg(const double *v, size_t n)
{
    size_t i;
    for (i = 0; i < n; ++i) {
        if (!isfinite(v[i]) || !(v[i] >= 0.0)) {
            return 0;
        }
    }
    return 1;
}

/* Suspension roll stiffness of an axle whose roll stiffness with the tyres in series is kphi:
 * 1/kphi = 1/k_susp + 1/(2 kt t^2). Returns <= 0 when the tyres alone are softer than kphi. */
static double susp_roll_stiffness(double kphi, double kt, double t)
{
    const double inv = 1.0 / kphi - 1.0 / (2.0 * kt * t * t);
    return inv > 0.0 ? 1.0 / inv : -1.0;
}

static int params_ok(const vh_v14_params_t *prm)
{
    const double pos[] = {prm->ms, prm->ix, prm->iz, prm->lf, prm->lr, prm->h, prm->tf, prm->tr, prm->kphi_f,
                          prm->kphi_r, prm->rw, prm->iw, prm->iy, prm->m_uf, prm->m_ur, prm->k_f, prm->k_r,
                          prm->kt, prm->v_low};
    const double nonneg[] = {prm->hf, prm->hr, prm->cphi_f, prm->cphi_r, prm->ct, prm->rho, prm->cda, prm->relax_x,
                             prm->relax_y};
    double ks;
    if (!finite_positive(pos, sizeof pos / sizeof pos[0]) || !finite_nonneg(nonneg, sizeof nonneg / sizeof nonneg[0])) {
        return 0;
    }
    /* roll axis below the sprung CG, relaxation lengths either off or not absurdly short */
    if (!(prm->hf < prm->h && prm->hr < prm->h) || (prm->relax_x > 0.0 && prm->relax_x < 0.01) ||
        (prm->relax_y > 0.0 && prm->relax_y < 0.01) || prm->min_substeps < 1 ||
        prm->min_substeps > VH_V14_MAX_SUBSTEPS) {
        return 0;
    }
    /* the tyres must be stiffer in roll than k_phi (a positive suspension roll stiffness); the bar,
     * what the springs leave of it, may be negative (CommonRoad's auxiliary torsion stiffness is) */
    ks = susp_roll_stiffness(prm->kphi_f, prm->kt, prm->tf);
    if (!(ks > 0.0)) {
        return 0;
    }
    ks = susp_roll_stiffness(prm->kphi_r, prm->kt, prm->tr);
    if (!(ks > 0.0)) {
        return 0;
    }
    return vh_mft_check(&prm->tyre);
}

/* The anti-roll bar of an axle, k_susp - 2 k t^2. A car without a bar whose k_phi was computed from
 * the springs alone comes back as a rounding residue (~1e-12 of k_susp): that is no bar. */
static double bar_rate(double ks, double k, double t)
{
    const double bar = ks - 2.0 * k * t * t;
    return fabs(bar) <= 1e-9 * ks ? 0.0 : bar;
}

/* ---- public -------------------------------------------------------------------------------- */

int vh_v14_init(vh_v14_t *p, const vh_v14_params_t *prm)
{
    double l, h_ra, kfast;
    int i;
    if (p == NULL || prm == NULL || !params_ok(prm)) {
        return VH_EINVAL;
    }
    p->prm = *prm;
    l = prm->lf + prm->lr;
    p->m = prm->ms + 2.0 * prm->m_uf + 2.0 * prm->m_ur;
    h_ra = prm->hf + (prm->hr - prm->hf) * prm->lf / l; /* roll axis under the CG */
    p->e = prm->h - h_ra;
    p->hp = prm->h;
    p->ip = prm->ix + prm->ms * p->e * p->e;
    p->iq = prm->iy + prm->ms * p->hp * p->hp;
    p->det_x = p->m * p->iq - (prm->ms * p->hp) * (prm->ms * p->hp);
    p->det_y = p->m * p->ip - (prm->ms * p->e) * (prm->ms * p->e);
    p->cx[0] = p->cx[1] = prm->lf;
    p->cx[2] = p->cx[3] = -prm->lr;
    p->cy[0] = prm->tf;
    p->cy[1] = -prm->tf;
    p->cy[2] = prm->tr;
    p->cy[3] = -prm->tr;
    /* static loads: sprung weight by the lever rule, plus the unsprung weight */
    for (i = 0; i < VH_V14_NW; ++i) {
        p->fs0[i] = prm->ms * G * (i < 2 ? prm->lr : prm->lf) / (2.0 * l);
        p->fz0[i] = p->fs0[i] + (i < 2 ? prm->m_uf : prm->m_ur) * G;
    }
    p->k_arb_f = bar_rate(susp_roll_stiffness(prm->kphi_f, prm->kt, prm->tf), prm->k_f, prm->tf);
    p->k_arb_r = bar_rate(susp_roll_stiffness(prm->kphi_r, prm->kt, prm->tr), prm->k_r, prm->tr);
    p->c_f = prm->cphi_f / (2.0 * prm->tf * prm->tf); /* c_phi = 2 c t^2 */
    p->c_r = prm->cphi_r / (2.0 * prm->tr * prm->tr);
    /* fastest non-tyre rates: wheel hop (spring, bar and tyre on the unsprung mass) and its
     * damping; bounds, not eigenvalues */
    kfast = prm->kt + prm->k_f + p->k_arb_f / (2.0 * prm->tf * prm->tf);
    p->rate_fixed = sqrt(kfast / prm->m_uf);
    kfast = (prm->ct + p->c_f) / prm->m_uf;
    p->rate_fixed = kfast > p->rate_fixed ? kfast : p->rate_fixed;
    kfast = prm->kt + prm->k_r + p->k_arb_r / (2.0 * prm->tr * prm->tr);
    kfast = sqrt(kfast / prm->m_ur);
    p->rate_fixed = kfast > p->rate_fixed ? kfast : p->rate_fixed;
    vh_v14_arc_params_default(&p->arc.prm[0]);
    vh_v14_arc_params_default(&p->arc.prm[1]);
    vh_v14_reset(p);
    return VH_OK;
}

/* Per-step constants from a sanitised input and the sub-step h. */
static void make_ctx(const vh_v14_t *p, const vh_v14_input_t *in, double h, ctx_t *c)
{
    int i;
    c->cd = cos(in->steer);
    c->sd = sin(in->steer);
    const vh_v14_params_t *prm = &p->prm;
    for (i = 0; i < VH_V14_NW; ++i) {
        const double eps = in->brake[i] * h / prm->iw; /* keeps the brake's rate at or below 1/h */
        const int front = i < 2;
        c->drive[i] = in->drive[i];
        c->brake[i] = in->brake[i];
        c->inv_brake_eps[i] = 1.0 / (eps > BRAKE_W_EPS ? eps : BRAKE_W_EPS);
        c->mu[i] = in->mu[i];
        c->inv_mu[i] = 1.0 / (front ? prm->m_uf : prm->m_ur);
        /* link force through the roll centre: vertical part -Fy h_rc / t on the left (y > 0)
         * body corner, +Fy h_rc / t on the right; reaction on the unsprung mass */
        c->jack[i] = (front ? prm->hf / prm->tf : prm->hr / prm->tr) * (p->cy[i] > 0.0 ? -1.0 : 1.0);
    }
    c->inv_iw = 1.0 / prm->iw;
    c->refresh = 1u << (unsigned)(p->steps % VH_V14_NW);
    c->arb_f = p->k_arb_f / (4.0 * prm->tf * prm->tf); /* bar force per compression difference */
    c->arb_r = p->k_arb_r / (4.0 * prm->tr * prm->tr);
    c->arc_on = p->arc.m[0] != 0.0 || p->arc.m[1] != 0.0;
    c->arc_f[0] = p->arc.m[0] / (2.0 * prm->tf);
    c->arc_f[1] = -c->arc_f[0];
    c->arc_f[2] = p->arc.m[1] / (2.0 * prm->tr);
    c->arc_f[3] = -c->arc_f[2];
}

/* Truth of the current state with no input on a road of friction 1; MF peaks from scratch. */
static void settle(vh_v14_t *p)
{
    vh_v14_input_t in;
    ctx_t c;
    aux_t aux;
    double dx[VH_V14_NX];
    int i;
    for (i = 0; i < VH_V14_NW; ++i) {
        p->pk[i].ux = 0.0; /* peak slips from scratch */
        p->pk[i].uy = 0.0;
    }
    vh_v14_input_init(&in, 1.0);
    make_ctx(p, &in, VH_V14_DT, &c);
    c.refresh = 0xFu;
    deriv(p, &c, p->x, dx, &aux);
    fill_truth(p, &c, dx, &aux, 0.0, 0);
}

void vh_v14_arc_params_default(vh_v14_arc_params_t *a)
{
    a->m_max = 4800.0;    /* ~1.2 kNm at the bar through ~4:1 lever arms and links (docs/roll.md) */
    a->rate_max = 16000.0;
    a->tau = 0.03;
}

static int arc_params_ok(const vh_v14_arc_params_t *a)
{
    return a != NULL && isfinite(a->m_max) && a->m_max >= 0.0 && isfinite(a->rate_max) &&
           a->rate_max > 0.0 && isfinite(a->tau) && a->tau >= 0.0;
}

int vh_v14_arc_config(vh_v14_t *p, const vh_v14_arc_params_t *front, const vh_v14_arc_params_t *rear)
{
    if (p == NULL || !arc_params_ok(front) || !arc_params_ok(rear)) {
        return VH_EINVAL;
    }
    p->arc.prm[0] = *front;
    p->arc.prm[1] = *rear;
    return VH_OK;
}

void vh_v14_set_roll_moment(vh_v14_t *p, double m_front, double m_rear)
{
    p->arc.cmd[0] = isfinite(m_front) ? m_front : 0.0;
    p->arc.cmd[1] = isfinite(m_rear) ? m_rear : 0.0;
}

void vh_v14_roll_fail_safe(vh_v14_t *p)
{
    int j;
    for (j = 0; j < 2; ++j) {
        p->arc.cmd[j] = 0.0;
        p->arc.lim[j] = 0.0;
    }
}

/* One step of the actuators: rate limit, torque limit, then the lag; the result acts over the step. */
static void arc_advance(vh_v14_arc_t *a)
{
    int j;
    for (j = 0; j < 2; ++j) {
        const vh_v14_arc_params_t *q = &a->prm[j];
        const double step = q->rate_max * VH_V14_DT;
        double v = a->cmd[j];
        if (a->cmd[j] == 0.0 && a->lim[j] == 0.0 && a->m[j] == 0.0) {
            continue; /* passive: nothing moves */
        }
        v = v > a->lim[j] + step ? a->lim[j] + step : (v < a->lim[j] - step ? a->lim[j] - step : v);
        v = v > q->m_max ? q->m_max : (v < -q->m_max ? -q->m_max : v);
        a->lim[j] = v;
        a->m[j] = q->tau > 0.0 ? a->m[j] + (1.0 - exp(-VH_V14_DT / q->tau)) * (v - a->m[j]) : v;
        if (fabs(a->m[j]) < 1e-9 && v == 0.0) {
            a->m[j] = 0.0; /* back to exactly passive */
        }
    }
}

void vh_v14_arc_step(vh_v14_t *p)
{
    arc_advance(&p->arc);
}

void vh_v14_reset(vh_v14_t *p)
{
    int i;
    for (i = 0; i < VH_V14_NX; ++i) {
        p->x[i] = 0.0;
    }
    for (i = 0; i < 2; ++i) {
        p->arc.cmd[i] = 0.0;
        p->arc.lim[i] = 0.0;
        p->arc.m[i] = 0.0;
    }
    p->steps = 0u;
    p->bad_inputs = 0u;
    settle(p);
}

int vh_v14_set_rolling(vh_v14_t *p, double vx)
{
    int i;
    if (!(fabs(vx) <= 100.0)) {
        return VH_EINVAL;
    }
    for (i = VH_V14_X_VX; i < VH_V14_NX; ++i) {
        p->x[i] = 0.0;
    }
    p->x[VH_V14_X_VX] = vx;
    for (i = 0; i < VH_V14_NW; ++i) {
        p->x[VH_V14_X_W + i] = vx / p->prm.rw;
    }
    settle(p);
    return VH_OK;
}

/* A finite value in [lo, hi]; *bad set when it had to change. NaN -> 0 (or lo if 0 is outside). */
static double sanitise(double v, double lo, double hi, int *bad)
{
    if (!isfinite(v)) {
        *bad = 1;
        return lo > 0.0 ? lo : (hi < 0.0 ? hi : 0.0);
    }
    if (v < lo) {
        *bad = 1;
        return lo;
    }
    if (v > hi) {
        *bad = 1;
        return hi;
    }
    return v;
}

/* World position over a sub-step from x0 to x1: trapezoidal velocities at the mean heading
 * (second order, as Heun; kept out of the right-hand side, which then needs no trigonometry). */
static void advance_position(const double *x0, double *x1, double h)
{
    const double yaw = 0.5 * (x0[VH_V14_X_YAW] + x1[VH_V14_X_YAW]);
    const double vx = 0.5 * (x0[VH_V14_X_VX] + x1[VH_V14_X_VX]);
    const double vy = 0.5 * (x0[VH_V14_X_VY] + x1[VH_V14_X_VY]);
    const double cy = cos(yaw), sy = sin(yaw);
    x1[VH_V14_X_PX] = x0[VH_V14_X_PX] + h * (vx * cy - vy * sy);
    x1[VH_V14_X_PY] = x0[VH_V14_X_PY] + h * (vx * sy + vy * cy);
}

/* Sub-steps for this step: wheel spin C_kappa rw^2 / (Iw v), relaxation v / L, the fixed rates. */
static unsigned substeps(const vh_v14_t *p)
{
    const vh_v14_params_t *prm = &p->prm;
    const double vmin = fabs(p->x[VH_V14_X_VX]) - fabs(p->x[VH_V14_X_R]) * (prm->tf > prm->tr ? prm->tf : prm->tr);
    const double vden = vmin > prm->v_low ? vmin : prm->v_low;
    const double vmax = fabs(p->x[VH_V14_X_VX]) + fabs(p->x[VH_V14_X_VY]) + 3.0 * fabs(p->x[VH_V14_X_R]) + 1.0;
    double ck = 0.0, rate, need, l;
    int i;
    for (i = 0; i < VH_V14_NW; ++i) {
        ck = p->ck[i] > ck ? p->ck[i] : ck;
    }
    rate = SPIN_MARGIN * ck * prm->rw * prm->rw / (prm->iw * vden);
    rate = p->rate_fixed > rate ? p->rate_fixed : rate;
    if (prm->relax_x > 0.0) {
        l = vmax / prm->relax_x;
        rate = l > rate ? l : rate;
    }
    if (prm->relax_y > 0.0) {
        l = vmax / prm->relax_y;
        rate = l > rate ? l : rate;
    }
    need = ceil(rate * VH_V14_DT / MAX_LAMBDA_H);
    if (!(need <= (double)VH_V14_MAX_SUBSTEPS)) {
        return VH_V14_MAX_SUBSTEPS; /* below ~0.5 m/s under heavy load: Heun is stable to 2 */
    }
    return need < (double)prm->min_substeps ? (unsigned)prm->min_substeps : (unsigned)need;
}

void vh_v14_step(vh_v14_t *p, const vh_v14_input_t *in)
{
    vh_v14_input_t u;
    ctx_t c;
    double k1[VH_V14_NX], k2[VH_V14_NX], xt[VH_V14_NX], h;
    unsigned n, k;
    int i, bad = 0;

    u.steer = sanitise(in->steer, -STEER_MAX, STEER_MAX, &bad);
    for (i = 0; i < VH_V14_NW; ++i) {
        u.drive[i] = sanitise(in->drive[i], -1e5, 1e5, &bad);
        u.brake[i] = sanitise(in->brake[i], 0.0, 1e5, &bad);
        u.mu[i] = sanitise(in->mu[i], 0.0, MU_MAX, &bad);
    }
    if (bad && p->bad_inputs < UINT32_MAX) {
        ++p->bad_inputs;
    }
    arc_advance(&p->arc);
    n = substeps(p);
    h = VH_V14_DT / (double)n;
    make_ctx(p, &u, h, &c);
    /* Heun: x+ = x + h/2 (f(x) + f(x + h f(x))). The first stage of the first sub-step is the
     * truth of this step: the state at its start and the forces of its inputs. */
    for (k = 0; k < n; ++k) {
        if (k == 0) {
            aux_t aux;
            deriv(p, &c, p->x, k1, &aux);
            fill_truth(p, &c, k1, &aux, u.steer, (int)n);
        } else {
            deriv(p, &c, p->x, k1, NULL);
        }
        for (i = 0; i < VH_V14_NX; ++i) {
            xt[i] = p->x[i] + h * k1[i];
        }
        deriv(p, &c, xt, k2, NULL);
        for (i = 0; i < VH_V14_NX; ++i) {
            xt[i] = p->x[i] + 0.5 * h * (k1[i] + k2[i]);
        }
        advance_position(p->x, xt, h);
        for (i = 0; i < VH_V14_NX; ++i) {
            p->x[i] = xt[i];
        }
    }
    ++p->steps;
}

size_t vh_v14_run(vh_v14_t *p, size_t n, const vh_v14_input_t *in, vh_v14_truth_t *out)
{
    size_t i;
    for (i = 0; i < n; ++i) {
        vh_v14_step(p, &in[i]);
        if (out != NULL) {
            out[i] = p->truth;
        }
    }
    return n;
}

double vh_v14_energy(const vh_v14_t *p)
{
    const vh_v14_params_t *prm = &p->prm;
    const double *x = p->x;
    const double vx = x[VH_V14_X_VX], vy = x[VH_V14_X_VY], pr = x[VH_V14_X_P], qr = x[VH_V14_X_Q];
    const double ms = prm->ms;
    double t, v, d[VH_V14_NW], da, db;
    int i;

    t = 0.5 * p->m * (vx * vx + vy * vy) + ms * p->hp * vx * qr - ms * p->e * vy * pr + 0.5 * p->ip * pr * pr +
        0.5 * p->iq * qr * qr + 0.5 * prm->iz * x[VH_V14_X_R] * x[VH_V14_X_R] +
        0.5 * ms * x[VH_V14_X_VZ] * x[VH_V14_X_VZ];
    v = ms * G * p->e * (cos(x[VH_V14_X_PHI]) - 1.0) + ms * G * p->hp * (cos(x[VH_V14_X_THETA]) - 1.0);
    for (i = 0; i < VH_V14_NW; ++i) {
        const double zs = x[VH_V14_X_Z] + p->cy[i] * x[VH_V14_X_PHI] - p->cx[i] * x[VH_V14_X_THETA];
        const double mu = i < 2 ? prm->m_uf : prm->m_ur;
        const double zu = x[VH_V14_X_ZU + i];
        const double defl = p->fz0[i] / prm->kt; /* tyre deflection at rest: contact lost above */
        d[i] = zu - zs;
        t += 0.5 * mu * x[VH_V14_X_VZU + i] * x[VH_V14_X_VZU + i] + 0.5 * prm->iw * x[VH_V14_X_W + i] * x[VH_V14_X_W + i];
        v += 0.5 * (i < 2 ? prm->k_f : prm->k_r) * d[i] * d[i];
        /* tyre spring: quadratic while in contact; in the air only the unsprung weight's work */
        v += zu < defl ? 0.5 * prm->kt * zu * zu : 0.5 * prm->kt * defl * defl + p->fz0[i] * (zu - defl);
    }
    da = (d[0] - d[1]) / (2.0 * prm->tf);
    db = (d[2] - d[3]) / (2.0 * prm->tr);
    v += 0.5 * p->k_arb_f * da * da + 0.5 * p->k_arb_r * db * db;
    return t + v;
}
