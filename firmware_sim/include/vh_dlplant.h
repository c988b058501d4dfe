/* vh_dlplant.h - driveline plant of seed 001: engine, open torque converter, gearbox, compliant
 * output shaft, wheel and vehicle with a nonlinear road load and road-roughness torque.
 *
 * States x = [w_e, w_o, w_w, T_s, I_gov]: engine speed, transmission output-shaft speed, wheel
 * speed [rad/s], shaft spring torque [Nm] (eq. 7), idle-governor integrator [Nm]. The turbine is
 * rigidly tied to the output shaft (w_t = w_o / R_i), so it has no state of its own.
 *
 * Sign and ratio conventions (seed 001): w_o = R_i w_t (R_i = 0.43 in 2nd gear), the wheel end of
 * the shaft turns at R_d w_o (R_d = 0.255); T_o is the wheel-side shaft torque of eq. 1, 2, 7.
 *
 * One call of vh_dlp_step advances VH_DLP_DT = 0.5 ms (one ECU tick) with one or more RK4
 * sub-steps (see VH_DLP_MAX_SUBSTEPS); the road-roughness torque is held over the step.
 */
#ifndef VH_DLPLANT_H
#define VH_DLPLANT_H

#include <stddef.h>
#include <stdint.h>

#include "vh_rng.h"
#include "vh_tc.h"
#include "vh_types.h"

#define VH_DLP_NGEARS 5
#define VH_DLP_DT 0.0005
/* RK4 sub-steps per 0.5 ms step, chosen every step. The 30 Hz shaft mode needs none
 * (w dt = 0.096). The fastest mode is the converter's turbine-side damping acting on the tiny
 * output inertia J_o: rate ~ a w_e / (R_i^2 J_o) with a ~ 12.7e-3 Nm s^2/rad^2 the steepest slope
 * of the capacity (near coupling). At the 7000 rpm fuel cut that is ~7.4e3 1/s in 1st gear (3.7
 * per step: outside RK4's stability interval (-2.78, 0]) and ~3.1e3 1/s in 2nd. Each step takes
 * the fewest sub-steps that keep every rate bound times the sub-step <= 1: stable with margin,
 * and on a full-throttle launch within 0.25 Nm of the shaft torque (1e-4 of its range) of a run
 * with 20x finer sub-steps. With the defaults 1-2 sub-steps at low engine speed, up to 4 in 1st
 * gear at high speed. vh_dlp_init refuses parameters that would need more than the maximum up to the
 * fuel-cut speed. */
#define VH_DLP_MAX_SUBSTEPS 8
/* Speed ratio up to which the converter follows eq. 9 exactly; see vh_dlp_converter. */
#define VH_DLP_CONV_RC VH_TC_RC
#define VH_DLP_GRAVITY 9.81

enum { VH_DLP_X_WE = 0, VH_DLP_X_WO = 1, VH_DLP_X_WW = 2, VH_DLP_X_TS = 3, VH_DLP_X_GOV = 4, VH_DLP_NX = 5 };

typedef struct {
    /* Driveline: Table 1 where the paper gives a value. */
    double jo;                   /* output-side inertia J_o [kg m^2], 0.016 (Table 1) */
    double jv;                   /* vehicle inertia at the wheel J_v [kg m^2], 160 (Table 1) */
    double rd;                   /* final drive R_d, w_w = R_d w_o nominally, 0.255 (Table 1) */
    double ri[VH_DLP_NGEARS];    /* gear ratio R_i of gears 1..5, w_o = R_i w_t; 2nd 0.43 (Table 1) */
    double ks;                   /* shaft stiffness k_s [Nm/rad], 9000 (Table 1) */
    double cs;                   /* shaft damping [Nm s/rad], not in the paper: ~5 % of critical */
    double rt;                   /* tyre radius r_t [m], 0.3 (Table 1); mass m = J_v / r_t^2 */
    /* Road load T_l = r_t (mu_r m g s(w_w) + rho/2 C_a A (r_t w_w)^2), eq. 3 made physical. */
    double mu_r;                 /* rolling-resistance coefficient */
    double rho;                  /* air density [kg/m^3] (Table 1 prints 0.123: a typo for 1.23) */
    double ca;                   /* drag coefficient C_a, 0.33 (Table 1) */
    double area;                 /* frontal area A [m^2], 2 (Table 1) */
    double roll_w_eps;           /* s(w) = w / sqrt(w^2 + eps^2): rolling resistance fades at rest [rad/s] */
    /* Engine (~2 L petrol) and idle governor. */
    double je;                   /* engine + pump impeller inertia J_e [kg m^2] */
    double te_peak;              /* peak of the full-load (gross) torque curve [Nm] */
    double fric0;                /* friction: fric0 w_e / sqrt(w_e^2 + 25) + fric1 w_e [Nm] */
    double fric1;                /* [Nm s/rad] */
    double w_idle;               /* idle speed target [rad/s] */
    double gov_kp;               /* idle governor PI: proportional gain [Nm s/rad] */
    double gov_ki;               /* integral gain [Nm/rad] */
    double gov_max;              /* governor torque limit [Nm] */
    /* Road roughness: torque at the wheel, first-order coloured Gaussian noise (OU process). */
    double road_std;             /* standard deviation at speed [Nm] */
    double road_bw;              /* corner frequency [Hz], below the 1 kHz Nyquist limit */
    double road_w_ref;           /* wheel speed above which roughness is at full strength [rad/s] */
} vh_dlp_params_t;

typedef struct {
    double t;        /* time since reset [s] */
    double throttle; /* throttle applied in the last step, after sanitising, [0, 1] */
    int gear;        /* gear engaged in the last step, 0 = neutral */
    double we;       /* engine (pump) speed [rad/s] */
    double wt;       /* turbine speed [rad/s] */
    double wo;       /* output-shaft speed [rad/s] */
    double ww;       /* wheel speed [rad/s] */
    double to;       /* shaft torque a transducer sees: spring + damper [Nm] */
    double ti;       /* turbine torque, eq. 9 [Nm] */
    double tp;       /* pump torque [Nm] */
    double te;       /* engine torque net of friction, idle governor included [Nm] */
    double tl;       /* road load T_l [Nm] */
    double td;       /* road-roughness torque applied in the last step [Nm] */
    double v;        /* vehicle speed r_t w_w [m/s] */
    double sr;       /* converter speed ratio r = w_t / w_e */
} vh_dlp_truth_t;

typedef struct {
    vh_dlp_params_t prm;
    vh_dlp_truth_t truth;     /* the state after the last step, in physical quantities */
    double x[VH_DLP_NX];      /* integrator state, VH_DLP_X_* */
    double rough;             /* OU state [Nm], stationary std road_std */
    double rough_a;           /* OU decay per step, exp(-2 pi road_bw dt) */
    double rough_b;           /* OU innovation gain, sqrt(1 - a^2) */
    vh_rng_t rng;
    uint64_t seed;
    uint64_t steps;           /* steps since reset */
    uint32_t bad_inputs;      /* steps whose throttle or gear had to be sanitised */
    /* derived from prm at init */
    double rate_base;              /* fastest gear-independent rate [1/s], for the sub-steps */
    double inv_je, inv_jo, inv_jv; /* 1/J */
    double c_roll, c_aero, eps2;   /* road load T_l = c_roll s(w_w) + c_aero w_w |w_w| */
} vh_dlp_t;

/* Paper's Table 1 plus the documented plausible rest. */
void vh_dlp_params_default(vh_dlp_params_t *prm);
/* VH_OK, or VH_EINVAL (nothing changed) for non-finite or non-physical parameters, or ones that
 * make a mode too fast for the fixed step. Starts at rest (vh_dlp_reset). */
int vh_dlp_init(vh_dlp_t *p, const vh_dlp_params_t *prm, uint64_t seed);
/* Back to rest: vehicle standing, shaft unwound, engine at idle, random stream restarted. */
void vh_dlp_reset(vh_dlp_t *p);
/* Put the vehicle at speed v [m/s] in gear (0..5) with the shaft unwound and the converter at
 * coupling (w_e = max(w_t, idle)); time and random stream untouched. VH_EINVAL if out of range. */
int vh_dlp_set_rolling(vh_dlp_t *p, double v, int gear);
/* One 0.5 ms step. throttle is clamped to [0, 1] (NaN -> 0); a gear outside 0..5 is taken as
 * neutral. Either counts in bad_inputs. */
void vh_dlp_step(vh_dlp_t *p, double throttle, int gear);
/* n steps with throttle[i] (NULL: 0) in one gear; copies the truth of each step to out[i] when
 * out is not NULL. Returns n. */
size_t vh_dlp_run(vh_dlp_t *p, size_t n, const double *throttle, int gear, vh_dlp_truth_t *out);

/* Torque converter, lock-up open: pump torque *tp and turbine torque *ti at pump speed we and
 * turbine speed wt. Eq. 9 exactly for r = wt/we <= VH_DLP_CONV_RC; above it the capacity
 * C_f blends (C1) to zero at r = 1 and continues linearly negative (overrun: the wheels drive
 * the engine, T_i = T_p < 0). r < 0 is taken as stall (r = 0). */
void vh_dlp_converter(double we, double wt, double *tp, double *ti);
/* Full-load gross engine torque at speed we [Nm] (throttle 1, before friction). */
double vh_dlp_full_load_torque(const vh_dlp_params_t *prm, double we);
/* Road load T_l at wheel speed ww [Nm]. */
double vh_dlp_road_load(const vh_dlp_params_t *prm, double ww);

#endif /* VH_DLPLANT_H */
