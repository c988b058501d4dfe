/* vh_tfa_host.h - host side (off-line) of the fixed-point SKFMEC-A: its double configuration (the
 * fields of vehest_can.systems.tireforce.adaptive.AdaptiveConfig) and its integer constants from it.
 * Not flashed. */
#ifndef VH_TFA_HOST_H
#define VH_TFA_HOST_H

#include "vh_skf.h"
#include "vh_tfa.h"

typedef struct {
    double cda, rho;             /* drag area [m^2], air density [kg/m^3] */
    double tau_lp;               /* low-pass of the balance [s] */
    int decim;                   /* steps per RLS update */
    double ax_gate, ay_gate, vx_gate; /* |a_x| >=, |a_y| <= [m/s^2], vx >= [m/s] */
    double forget;               /* lambda per update */
    double sigma_y;              /* std of the balance's residual [N] */
    double mass_sigma0, mass_sigma_floor, mass_sigma_ok; /* fractions of the model mass */
    double mass_lo, mass_hi;     /* clamp, fractions of the model mass */
    double tyre_a[9];            /* lateral Magic Formula a0..a8 */
    double tyre_fz_scale;        /* size factor */
    double mu;                   /* friction the split assumes (the nominal one) */
    double tyre_b[9];            /* longitudinal Magic Formula b0..b8 */
    double tau_slip;             /* low-pass of the excess differential slip [s] */
    double fx_gate;              /* |Fx| of both wheels of an axle at least [N] */
    double q_gate;               /* secant / linear slip stiffness below this: nonlinear */
    double tau_mu, tau_mu_forget; /* the side's estimate to its observations, back to mu [s] */
    double mu_floor;
    double ellipse_floor;
    int friction, combined;      /* 1: on */
    int ride;                    /* 1: the mass from the ride heights where they are usable */
    double spring_front, spring_rear; /* spring rate at the wheel, per corner [N/m] */
    double sigma_ride;           /* std of one ride-height mass measurement, fraction of the model mass */
    int road;                    /* 1: the road's friction from the kinematic slip-angle coupling */
    int transfer;                /* 1: each axle's lateral load transfer from the ride heights */
    double tyre_kz;              /* the tyre's vertical stiffness [N/m] (the bars' rate from k_phi) */
    double tau_vyd;              /* low-pass of a_y - r v (the body's sideways sliding) [s] */
    double vyd_gate;             /* beyond this, implausible [m/s^2] */
    double hold_implausible;     /* DEGRADED this long after the last implausible step [s] */
    double tau_kin;              /* low-pass of delta - L r / v [s] */
    double ay_kin_gate;          /* |a_y| at least this [m/s^2] */
    double fx_free;              /* |Fx| of both wheels of an axle at most this: free-rolling [N] */
    double kin_q;                /* std of the road friction's random walk per update */
    double kin_r_deg;            /* std of the measured alpha_f - alpha_r [deg] */
    double kin_sigma0;           /* prior std of the road friction (its ceiling) */
    double kin_dmu;              /* the finite difference of the derivative in mu */
    double kin_dh_max;           /* that derivative's bound [deg per unit mu] */
    double kin_side_min;         /* used while both sides' estimates are at least this */
    double kin_nis_gate;         /* an update whose normalised innovation squared exceeds this is refused */
    int tyre_model;              /* 0: the 1987 Magic Formula of tyre_a, tyre_b; 1: PAC2002 with load-proportional
                                  * slip stiffnesses (CommonRoad's), tyre_p */
    double tyre_p[8];            /* p_cy1, p_dy1, p_ey1, |p_ky1|, p_cx1, p_dx1, p_ex1, p_kx1 */
    double tyre_klt;             /* the tyre's lateral compliance [m/N] (0: none) */
    double vx_tol, vx_tol_rel;   /* v_x outside the wheels' speed range by more than vx_tol [m/s] + vx_tol_rel v:
                                  * a contradiction */
    double bal_tol, bal_tol_rel; /* the balance's residual |y - m^ a_x| beyond bal_tol [N] + bal_tol_rel |y|: one */
    double bound_z;              /* each tyre's bound is bound_z sigma (1.96: a 95 % interval) */
    double bound_axle_abs, bound_axle_rel; /* the axle model's std: [N] + a fraction of |F_axle| */
    double bound_lt_abs, bound_lt_rel;     /* the lateral load transfer's std: [N] + a fraction of |dFz| */
    double bound_max;            /* a bound wider than this [N] makes the health DEGRADED */
} vh_tfa_config_t;

void vh_tfa_config_default(vh_tfa_config_t *c);
/* The tyre's pure-slip lateral force [N] at alpha [deg] >= 0 and load fz [N] (adaptive.lateral_force). */
double vh_tfa_lateral_force(const vh_tfa_config_t *c, double alpha_deg, double fz);
/* The pure-slip longitudinal force [N] at kappa [%] >= 0 (adaptive.longitudinal_force). */
double vh_tfa_longitudinal_force(const vh_tfa_config_t *c, double kappa_pct, double fz);
/* VH_OK, or VH_EINVAL if the configuration is invalid or a constant does not fit its format. */
int vh_tfa_params_from_config(const vh_skf_config_t *skf, const vh_tfa_config_t *c, vh_tfa_params_t *p);

#endif /* VH_TFA_HOST_H */
