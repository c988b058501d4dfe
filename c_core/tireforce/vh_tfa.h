/* vh_tfa.h - SKFMEC-A in fixed point: what it adds to the fixed-point SKFMEC (seed 000, beyond the
 * paper; docs/tireforce.md "SKFMEC-A"). Integer only.
 *
 * After each vh_skfq_step, on the same inputs: (1) the mass ratio k = m^/m by a scalar RLS on the
 * longitudinal balance y = m a_x (y = cos d (Fx1 + Fx2) + Fx3 + Fx4 - sin d 2 Fyf k - drag, the
 * wheel forces Fxi of the SKFMEC's eq. 30), both sides low-passed, updated every `decim` steps
 * when gated in, with forgetting, a covariance floor and ceiling; (2) loads and axle forces times k;
 * (3) the split of each axle's force by the tyre's force table at one slip angle (the exact
 * inverse of the piecewise-linear pair sum), each tyre's curve at its side's friction mu F(alpha / mu)
 * and times the friction ellipse's sqrt(1 - (Fx / mu Dx)^2); (4) each side's mu from the axle's
 * excess differential slip through the combined-slip model's secant table; (5) where ride-height
 * sensors are fitted, a second measurement of the mass in the same RLS: the sprung weight
 * sum k_i s_i of the four springs' deflections s_i plus the roll-centre links' vertical forces
 * (hf/tf)(Fy2 - Fy1) + (hr/tr)(Fy4 - Fy3) of the SKFMEC's forces, low-passed, plus the unsprung
 * mass; (6) the road's friction by a scalar EKF on the kinematic coupling alpha_f - alpha_r = delta -
 * L r / v (v from a free-rolling axle's wheels) against the split's at that friction, used where it is
 * lower than a side's while neither side has seen a split; (7) where the ride heights are usable, each
 * axle's lateral load transfer from them: (1/2)((k + 2 k_arb / 4t^2)(s_R - s_L) + (h/t) 2 F_axle).
 * Each tyre's force carries a bound: z sigma_i from the SKFMEC's covariance of the axle force and the
 * mass's, propagated through the split, and the split's model term from the load transfer's uncertainty.
 * Health: the SKFMEC's, DEGRADED until the mass has converged, while the car is outside the model
 * (its fastest wheel slower than vx_gate, or a_y - r v beyond vyd_gate: sliding sideways) and while a
 * bound is wider than bound_max.
 * The same algorithm as vehest_can/systems/tireforce/adaptive.py (double); the constants come
 * from there (host side).
 *
 * Formats: forces FN (vh_skfq.h), a_x FA, k Q2.29, P Q1.30 (in units of k^2), the normalised
 * regressor and output phi = m a_x / sigma, y / sigma in Q10.21, the table's load weights Q15.
 */
#ifndef VH_TFA_H
#define VH_TFA_H

#include <stdint.h>

#include "vh_fix.h"
#include "vh_skfq.h"

#define VH_TFA_NA 33 /* slip-angle knots 0, 0.25, ..., 8 deg */
#define VH_TFA_NZ 29 /* load knots 0, 500, ..., 14 000 N */
#define VH_TFA_FK 29 /* Q2.29 the mass ratio k */
#define VH_TFA_FP 30 /* Q1.30 its variance P */
#define VH_TFA_FN 21 /* Q10.21 normalised regressor and output */
#define VH_TFA_FZW 15 /* Q15 load-knot weight */
#define VH_TFA_NS 41 /* normalised combined-slip knots 0, 0.05, ..., 2 (the secant table) */
#define VH_TFA_FS 29 /* Q2.29 slips, the excess differential slip, the friction mu */
#define VH_TFA_FC 40 /* longitudinal slip compliance 1/C_kappa [1/N] */
#define VH_TFA_FG 24 /* Q7.24 knot positions (slip angle, normalised slip) and normalised slips */
#define VH_TFA_FH 29 /* Q2.29 spring deflections from the free length [m] (ride heights) */
#define VH_TFA_FB 4  /* Q27.4 the bound's standard deviations [N] (their squares summed in 64 bits) */

/* Contradictions (vh_tfa_t.contra): the SKFMEC's v_x outside the wheels' speed range, the mass at its
 * clamp, a load below zero or a friction at its floor, the balance against the mass. Each makes the health DEGRADED. */
#define VH_TFA_C_VX 1u
#define VH_TFA_C_MASS 2u
#define VH_TFA_C_BOUNDS 4u
#define VH_TFA_C_BALANCE 8u /* the longitudinal balance's residual |y - m^ a_x| beyond its bound */

typedef struct {
    int32_t table[VH_TFA_NZ * VH_TFA_NA]; /* lateral force of the tyre at (load i, slip angle j), FN */
    vh_fix_k_t k_inv_fz_step;   /* 1 / 500 N: Fz (FN) -> load knot index in Q15 */
    int32_t alpha_lp;           /* Ts / (tau_lp + Ts), Q30 */
    vh_fix_k_t k_phi;           /* m / sigma: a_x (FA) -> phi (FN of this header) */
    vh_fix_k_t k_y;             /* 1 / sigma: y (N, FN) -> y / sigma */
    vh_fix_k_t k_drag;          /* rho CdA / (2 s_vx^2): vx*^2 (Q21) -> N */
    int32_t ax_gate, ay_gate;   /* FA */
    int32_t vx_gate;            /* vx* (FX) */
    uint32_t valid_min;         /* valid steps before an update */
    uint32_t decim;             /* steps per RLS update */
    int32_t inv_forget;         /* 1 / lambda, Q30 */
    int32_t p0, p_floor, p_ok;  /* Q30: prior (= ceiling), floor, converged below */
    int32_t k_lo, k_hi;         /* Q29: the ratio's clamp */
    int32_t m_num, m_den;       /* the model mass m = m_num / m_den [kg] (exact, or rounded within 0.5 / m_den:
                                 * vh_tfa_params_from_config): m^ = k m to raw, integer only */
    /* per-side friction and the friction ellipse (0: off) */
    int32_t friction, combined;
    int32_t compliance[VH_TFA_NZ];  /* 1 / C_kappa per load knot, FC */
    int32_t dx[VH_TFA_NZ];          /* longitudinal friction limit at mu = 1, FN */
    int32_t inv_kappa_m[VH_TFA_NZ]; /* 1 / kappa_m (pure-slip peak), FG */
    int32_t inv_alpha_m[VH_TFA_NZ]; /* (0.25 deg in rad) / alpha_m: per slip-angle knot, Q30 */
    int32_t secant[VH_TFA_NZ * VH_TFA_NS]; /* Q(s) per (load, s knot), Q30 */
    vh_fix_k_t k_rw;            /* rw: omega (FO) -> wheel speed [m/s] Q21 */
    vh_fix_k_t k_inv_svx;       /* 1 / s_vx: vx* (FX) -> vx [m/s] Q21 */
    vh_fix_k_t k_half[2];       /* tf, tr: r (FW) -> r t [m/s] Q21 */
    int32_t alpha_slip;         /* Ts / (tau_slip + Ts), Q30 */
    int32_t fx_gate;            /* FN */
    int32_t q_gate;             /* Q30 */
    int32_t g_obs, g_forget;    /* decim Ts / tau_mu, decim Ts / tau_mu_forget, Q30 */
    int32_t mu_nom, mu_floor;   /* FS */
    int32_t s_step;             /* 0.05, Q30 */
    int32_t ellipse_floor2;     /* its square, Q30 */
    /* the mass from the ride heights (ride: 0 off) */
    int32_t ride;
    vh_fix_k_t k_spring[2];     /* spring rate front, rear [N/m]: deflection (FH) -> force (FN) */
    vh_fix_k_t k_link[2];       /* hf / tf, hr / tr: a force difference (FN) -> the links' vertical force */
    vh_fix_k_t k_ride;          /* 1 / (g sigma_h): the sprung weight (FN) -> its mass / sigma_h (FN of this header) */
    int32_t ride_unsprung;      /* (m - ms) / sigma_h, FN of this header */
    int32_t ride_phi;           /* the regressor m / sigma_h, FN of this header */
    uint32_t ride_min;          /* usable steps before an update (the low-pass starts at the first sample) */
    /* the road's friction from the kinematic slip-angle coupling (road: 0 off) */
    int32_t road;
    int32_t alpha_kin;          /* Ts / (tau_kin + Ts), Q30 */
    uint32_t kin_min;           /* measured steps before an update */
    int32_t ay_kin_gate;        /* FA */
    int32_t fx_free;            /* FN */
    int32_t v_gate;             /* the free-rolling axle's speed at least this [m/s], FV (Q21) */
    vh_fix_k_t k_wheelbase;     /* lf + lr: r (FW) -> L r [m/s] Q21 */
    vh_fix_k_t k_knot;          /* 1 / 0.25 deg: an angle [rad] (FG) -> slip-angle knots (FG) */
    vh_fix_k_t k_kin;           /* 1 / sigma_z: knots (FG) -> normalised (FN of this header) */
    vh_fix_k_t k_kin_dh;        /* 1 / (dmu sigma_z): a difference of knots (FG) -> normalised derivative */
    int32_t kin_dh_max;         /* that derivative's bound, normalised (FN of this header) */
    int32_t kin_dmu;            /* FS */
    int32_t kin_q, kin_p0;      /* Q30: the random walk's variance per update (and the floor), the prior (ceiling) */
    int32_t kin_side_min;       /* FS */
    int32_t kin_nis;            /* the innovation gate on nu^2 / (1 + H P H), Q16 */
    /* each axle's lateral load transfer from the ride heights (transfer: 0 off) */
    int32_t transfer;
    vh_fix_k_t k_roll[2];       /* k + 2 k_arb / (4 t^2) front, rear: a compression difference (FH) -> force (FN) */
    /* plausibility: the car outside the model (health DEGRADED) */
    int32_t alpha_vyd;          /* Ts / (tau_vyd + Ts), Q30 */
    int32_t vyd_gate;           /* FA */
    uint32_t hold_implausible;  /* steps */
    int32_t vx_tol;             /* v_x may leave the wheels' speed range by vx_tol + vx_tol_rel v, FV (Q21 m/s) */
    int32_t vx_tol_rel;         /* Q30 */
    int32_t bal_tol;            /* the balance's residual may reach bal_tol / sigma (FQ) + bal_tol_rel |y| */
    int32_t bal_tol_rel;        /* Q30 */
    int32_t klt;                /* 1: the tyres' lateral compliance shifts the loads (item 10) */
    vh_fix_k_t k_klt[2];        /* K_lt / (2 t) front, rear [1/N]: 2 F_axle (FN) -> a fraction (Q30) */
    /* each tyre's bound (docs/tireforce.md, "Per-tyre bound"): z sigma_i, sigma_i^2 = (F_i / F_axle)^2 sigma_axle^2
     * + (F_axle sigma_dFz / Fz_mean)^2 */
    int32_t bound_z;            /* the interval's multiple of sigma, Q29 */
    int32_t bound_axle_abs;     /* the axle model's std floor [N], FB */
    int32_t bound_axle_rel;     /* and its part proportional to |F_axle|, Q30 */
    int32_t bound_lt_abs;       /* the lateral load transfer's std floor [N], FN */
    int32_t bound_lt_rel;       /* and its part proportional to |dFz|, Q30 */
    int32_t bound_max;          /* a bound wider than this makes the health DEGRADED [N], FN */
} vh_tfa_params_t;

typedef struct {
    vh_tfa_params_t prm;
    int32_t y_lp;               /* N, FN */
    int32_t ax_lp;              /* FA */
    int32_t k;                  /* Q29 */
    int32_t p;                  /* Q30 */
    uint32_t valid_run, steps, updates;
    int32_t w_lp;               /* the sprung weight from the ride heights, low-passed, FN */
    uint32_t ride_run;          /* consecutive steps with usable ride heights */
    int32_t fy[4], fz[4];       /* FN */
    int32_t slip_e[2];          /* the excess differential slip per axle (low-passed), FS */
    int32_t mu[2];              /* friction of the left and right side, FS */
    int32_t alpha[2];           /* each axle's slip angle in the last split, knots FG */
    int32_t z_lp;               /* delta - L r / v, low-passed, knots FG */
    uint32_t kin_run;           /* consecutive steps with it measured */
    int32_t mu_road;            /* the road's friction, FS */
    int32_t p_road;             /* its variance, Q30 */
    int32_t vyd_lp;             /* a_y - r v low-passed, FA */
    uint32_t implausible;       /* steps left of DEGRADED after the last implausible step */
    uint32_t contra;            /* the published states that contradict a measurement now (VH_TFA_C_*) */
    uint32_t n_contra;          /* how often a contradiction began since init */
    uint32_t bal;               /* VH_TFA_C_BALANCE while the balance contradicts the mass (held when not gated) */
    int32_t bound[4];           /* each tyre's 95 % half-width of fy (bound_z sigma) [N], FN */
    uint32_t sat;               /* saturations since init */
    uint8_t health;             /* vh_health_t */
} vh_tfa_t;

/* VH_OK, or VH_EINVAL if a constant is out of its documented range. */
int vh_tfa_check(const vh_tfa_params_t *prm);
/* VH_OK, or VH_EINVAL if a constant is out of its documented range (nothing changed). */
int vh_tfa_init(vh_tfa_t *a, const vh_tfa_params_t *prm);
/* Back to the prior: k = 1, P = p0, filters and counters cleared (the constants kept). */
void vh_tfa_reset(vh_tfa_t *a);
/* One step after vh_skfq_step(f, in, mask) on the same inputs and mask; ride: the four springs'
 * deflections (FH, FL FR RL RR) when ride-height sensors give usable ones this step, else NULL. */
void vh_tfa_step(vh_tfa_t *a, const vh_skfq_t *f, const vh_skfq_input_t *in, unsigned mask, const int32_t *ride);
/* The mass ratio's standard deviation sqrt(P), rounded down, in Q(VH_TFA_FP / 2). */
int32_t vh_tfa_mass_std(const vh_tfa_t *a);
/* The array API: n steps of both filters from their current state, inputs as vh_skfq_run; ride (n x 4,
 * FH) with ride_ok (n: 1 usable) or both NULL (no ride-height sensors). Per step: fy, fz (4 each, FN),
 * k, p, health and, when non-NULL, bound (4, FN). */
void vh_tfa_run(vh_tfa_t *a, vh_skfq_t *f, size_t n, const int32_t *u, const uint8_t *mask, const int32_t *ride,
                const uint8_t *ride_ok, int32_t *fy_out, int32_t *fz_out, int32_t *k_out, int32_t *p_out,
                uint8_t *health_out, int32_t *bound_out);

#endif /* VH_TFA_H */
