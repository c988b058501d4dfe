/* vh_roll.h - roll system of seed 003 (Zhang et al. 2017): UKF roll angle / roll rate estimator
 * (eq. 13-26) on a 9-DOF vehicle model (eq. 1-10), and the sliding-mode active roll controller
 * (eq. 27-35). docs/roll.md has the model, its derivation and the choices.
 *
 * One source (vh_roll_impl.inc) compiled twice: vh_roll_*_f32 in single precision (what a
 * Cortex-M4F/M33 FPU does in hardware: the ECU's build) and vh_roll_*_f64 in double (the
 * reference build). Caller-owned instances, no heap, no globals holding state; flat row-major
 * arrays. This folder includes nothing from the rest of c_core.
 *
 * Axes as the project's 14-DOF plant (firmware_sim/include/vh_veh14.h): ISO, x forward, y left,
 * z up; roll + lifts the left side; wheels 0..3 = FL, FR, RL, RR. The paper's SAE axes (y right,
 * z down) map by y -> -y, z -> -z: roll + lifts the left side, so a left turn rolls the body to
 * phi > 0 (docs/roll.md).
 */
#ifndef VH_ROLL_H
#define VH_ROLL_H

#ifndef VH_ROLL_CDEF /* the cffi build reads this header through the preprocessor with it set */
#include <stddef.h>
#include <stdint.h>
#endif

#define VH_ROLL_NX 21  /* UKF states at most: the paper's 16 and the robust variant's five disturbances */
#define VH_ROLL_NX_PAPER 16 /* the paper's variant runs the first 16 */
#define VH_ROLL_NZ 14  /* measurements (the paper's 14) */
#define VH_ROLL_NU 4   /* inputs */
#define VH_ROLL_NS 43  /* sigma points at most, 2 NX + 1 (symmetric set, eq. 15) */
#define VH_ROLL_NW 4   /* wheels */

enum {
    VH_ROLL_NX_ = VH_ROLL_NX, VH_ROLL_NZ_ = VH_ROLL_NZ, VH_ROLL_NU_ = VH_ROLL_NU, VH_ROLL_NS_ = VH_ROLL_NS
};

/* State layout (heights, angles and zu from the static equilibrium). */
enum {
    VH_ROLL_X_VY = 0,     /* lateral velocity, body axes [m/s] */
    VH_ROLL_X_R = 1,      /* yaw rate [rad/s] */
    VH_ROLL_X_Z = 2,      /* sprung heave [m] */
    VH_ROLL_X_VZ = 3,
    VH_ROLL_X_PHI = 4,    /* roll [rad] */
    VH_ROLL_X_P = 5,      /* roll rate [rad/s] */
    VH_ROLL_X_THETA = 6,  /* pitch [rad] */
    VH_ROLL_X_Q = 7,
    VH_ROLL_X_ZU = 8,     /* 8..11 unsprung heave [m] */
    VH_ROLL_X_VZU = 12,   /* 12..15 */
    VH_ROLL_X_D = 16,     /* robust variant: unknown roll moment on the body [kN m] (eq. 4d), a random walk */
    VH_ROLL_X_DFZ = 17    /* 17..20 robust variant: unknown tyre load per corner [kN] (eq. 10d), random walks */
};

/* Variants (vh_roll_params_t.variant). */
enum {
    VH_ROLL_V_PAPER = 0,  /* the paper's UKF: 16 states, the nominal car's roll balance */
    VH_ROLL_V_ROBUST = 1  /* + the roll-moment and tyre-load disturbances (21 states, docs/roll.md) */
};

/* Measurement layout: the paper's z = [ay, xui, xsi, wr] (eq. below eq. 26) with the unsprung
 * vertical accelerations it lists. */
enum {
    VH_ROLL_Z_AY = 0,     /* lateral acceleration vy' + r vx [m/s^2] */
    VH_ROLL_Z_AZU = 1,    /* 1..4 unsprung vertical acceleration [m/s^2] */
    VH_ROLL_Z_DT = 5,     /* 5..8 tyre deflection change, compression + [m] (= -zu) */
    VH_ROLL_Z_DS = 9,     /* 9..12 suspension deflection change, compression + [m] */
    VH_ROLL_Z_R = 13      /* yaw rate [rad/s] */
};

/* Input layout. */
enum {
    VH_ROLL_U_STEER = 0,  /* front road-wheel angle [rad], + left */
    VH_ROLL_U_VX = 1,     /* forward speed [m/s] (wheel speeds) */
    VH_ROLL_U_MF = 2,     /* front actuator roll moment on the body [Nm], + as roll */
    VH_ROLL_U_MR = 3      /* rear */
};

/* UKF health (vh_roll_ukf_*_t.health) and flags (bits of .flags, sticky until _reset). */
enum {
    VH_ROLL_H_INIT = 0,      /* before the first update, and until the filter has converged after
                              * each init or reset (P's roll and roll-rate variances below conv_sd_*) */
    VH_ROLL_H_OK = 1,
    VH_ROLL_H_DEGRADED = 2,  /* this step: measurements masked or a factorisation regularised */
    VH_ROLL_H_RESET = 3      /* this step: the filter was reset (NaN, divergence, failed factorisation) */
};
enum {
    VH_ROLL_F_REGULARISED = 1,   /* a Cholesky factorisation needed the regularised retry */
    VH_ROLL_F_CHOL_RESET = 2,    /* a factorisation failed even regularised: reset */
    VH_ROLL_F_NONFINITE = 4,     /* NaN/Inf in the state or covariance: reset */
    VH_ROLL_F_DIVERGED = 8,      /* state out of its physical range or innovation test failed: reset */
    VH_ROLL_F_MASKED = 16,       /* measurements were masked */
    VH_ROLL_F_NO_UPDATE = 32,    /* every measurement masked: prediction only */
    VH_ROLL_F_BAD_INPUT = 64     /* a non-finite input, taken as 0 (vx: as its floor) */
};

/* Parameters (double: configuration; init converts to the build's precision). Defaults are the
 * project's 14-DOF plant (vh_v14_params_default), so the UKF can be checked against its truth. */
typedef struct {
    double ms, ix, iy, iz;        /* sprung mass [kg], its roll, pitch inertias about its CG, yaw inertia [kg m^2] */
    double lf, lr, tf, tr;        /* CG to axles, half-tracks [m] */
    double h, hf, hr;             /* sprung CG height, roll-centre heights [m] */
    double kphi_f, kphi_r;        /* roll stiffness per axle, tyres in series [Nm/rad] */
    double cphi_f, cphi_r;        /* roll damping per axle [Nm s/rad] */
    double m_uf, m_ur;            /* unsprung mass per corner [kg] */
    double k_f, k_r;              /* spring rate per corner [N/m] */
    double kt, ct;                /* tyre vertical stiffness [N/m], damping [N s/m] */
    /* tyre lateral force, eq. 11-12 simplified: Fy = D sin(C atan(B tan(alpha))),
     * D = mu * mu_load * Fz, B = calpha / (C mu mu_load) with calpha per unit load */
    double calpha_f, calpha_r;    /* cornering stiffness per unit load at static load [1/rad] */
    double mf_c;                  /* shape factor C */
    double mu;                    /* road friction */
    double mu_load;               /* friction fraction the loaded tyre reaches (load sensitivity) */
    double v_low;                 /* floor of |vx| in the slip denominator [m/s] */
    /* filter */
    double dt;                    /* step [s] */
    double kappa;                 /* sigma-point spread: n + kappa (eq. 15), kappa >= 0 */
    double q[VH_ROLL_NX];         /* process noise variance per step (diagonal Q) */
    double r[VH_ROLL_NZ];         /* measurement noise variance (diagonal R) */
    double p0[VH_ROLL_NX];        /* initial covariance diagonal (eq. 14) */
    double reg_eps;               /* regularisation of the retry, relative to the mean diagonal */
    double nis_max;               /* innovation test: NIS per measurement above this -> reset; 0 off */
    double phi_max;               /* |roll| above this [rad] -> diverged, reset */
    double conv_sd_phi, conv_sd_p; /* converged (health leaves INIT) once sqrt(P) of roll [rad] and of
                                    * roll rate [rad/s] are both at or below these */
    /* robust variant: process noise that follows the innovations (eq. 18a-b, docs/roll.md): q_p s^2,
     * s = the NIS per body-motion measurement low-passed over qp_adapt_tau, within [1, qp_adapt_max];
     * q_vy and q_r the same from the lateral measurements (a_y, r) */
    double qp_adapt_tau;          /* [s]; 0: off */
    double qp_adapt_max;          /* s at most this, >= 1 */
    uint32_t variant;             /* VH_ROLL_V_*: the paper's 16 states or the robust 17 */
    uint32_t ay_gravity;          /* 1: the lateral accelerometer is body-fixed and feels gravity,
                                   * z_ay = ay cos(phi) + g sin(phi) (eq. 20g); 0: it sends the
                                   * kinematic ay (a node that compensates) */
} vh_roll_params_t;

/* Sliding-mode controller parameters (eq. 27-35). */
typedef struct {
    double lambda;         /* sliding surface slope [1/s] (eq. 28) */
    double k;              /* switching gain [rad/s^2] (eq. 32-33) */
    double p;              /* boundary layer thickness [rad/s] (eq. 34-35) */
    double ref_frac;       /* reference roll: this fraction of the estimated passive roll */
    double ref_tau;        /* low-pass time constant of the reference [s] (two stages) */
    double ay_tau;         /* low-pass time constant of the estimated ay in eq. 27 [s] */
    double front_share;    /* front part of the total moment (rule: the passive roll-stiffness split) */
    double m_max_f, m_max_r;   /* actuator roll-moment limit per axle, on the body [Nm] */
    double rate_max_f, rate_max_r; /* rate limit per axle [Nm/s] */
    double fade_time;      /* moment fades from full to zero over this [s] when the estimator is not OK
                            * (>= m_max / rate_max per axle: the rate limit holds during the fade) */
    double recover_time;   /* estimator OK this long before the moment comes back (same ramp) [s] */
    double not_ok_debounce; /* a not-OK health (other than RESET) this long trips the fade [s] */
    double dt;             /* step [s] */
    /* model terms of eq. 27 (from vh_roll_params_t by vh_roll_smc_params_default) */
    double i_roll;         /* Ix + ms e^2 [kg m^2] */
    double ms_e;           /* ms e [kg m] */
    double kphi, cphi;     /* total roll stiffness [Nm/rad] and damping [Nm s/rad] */
    double dist_gain;      /* share of the estimated roll-moment disturbance in eq. 27 (robust: 1,
                            * paper: 0; the disturbance argument of vh_roll_smc_step) */
    uint32_t law;          /* VH_ROLL_L_*: the paper's equivalent control or the robust law (docs/roll.md) */
    /* the robust law only */
    double eta;            /* actuator effectiveness: steady roll per moment relative to eq. 27's, the
                            * moment acts against the suspension alone (sum share_i k_phi,i / k_susp,i) */
    double ki;             /* integral gain on the roll error [1/s^3] (M_i = -I_p ki integral e dt) */
    double i_frac;         /* the integral's moment bound, a fraction of m_max_f + m_max_r */
} vh_roll_smc_params_t;

/* Control laws of the SMC (vh_roll_smc_params_t.law). */
enum {
    VH_ROLL_L_PAPER = 0,  /* eq. 31-35: the equivalent control cancels the model's roll stiffness */
    VH_ROLL_L_ROBUST = 1  /* stiffness at the reference (feedforward), bandwidth-sized layer, integral */
};

/* SMC health bits (.health of the controller; 0 = active, acting on an OK estimate). */
enum {
    VH_ROLL_S_PASSIVE = 1,     /* passive mode selected: moment zero (after the fade) */
    VH_ROLL_S_EST_NOT_OK = 2,  /* the UKF's health is not OK: fading / faded out */
    VH_ROLL_S_FADING = 4,      /* fade factor between 0 and 1 */
    VH_ROLL_S_SAT = 8,         /* a torque limit acted this step */
    VH_ROLL_S_RATE = 16,       /* a rate limit acted this step */
    VH_ROLL_S_BAD_INPUT = 32,  /* non-finite estimate input: moment held at zero demand */
    VH_ROLL_S_TRIPPED = 64     /* the estimate tripped the fade; set until it is OK for recover_time */
};

void vh_roll_params_default(vh_roll_params_t *prm);
void vh_roll_smc_params_default(vh_roll_smc_params_t *c, const vh_roll_params_t *prm);
/* The robust law and its gains into c (vh_roll_smc_params_default does it for the robust variant). */
void vh_roll_smc_law_robust(vh_roll_smc_params_t *c);
/* 0, or -1 for missing pointers or non-finite / non-physical parameters: what the inits refuse,
 * checked without an instance (an ECU checks its configuration before it touches its state). */
int vh_roll_params_check(const vh_roll_params_t *prm);
int vh_roll_smc_params_check(const vh_roll_smc_params_t *prm);

/* The two precisions, declared from one template. */
#define VH_ROLL_REAL float
#define VH_ROLL_NAME(n) n##_f32
#include "vh_roll_decl.inc"
#undef VH_ROLL_REAL
#undef VH_ROLL_NAME
#define VH_ROLL_REAL double
#define VH_ROLL_NAME(n) n##_f64
#include "vh_roll_decl.inc"
#undef VH_ROLL_REAL
#undef VH_ROLL_NAME

#endif /* VH_ROLL_H */
