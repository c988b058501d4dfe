/* vh_veh14.h - 14-DOF vehicle of seed 000 (Kim & Huh 2000) with combined-slip Magic Formula tyres:
 * the truth the tyre-lateral-force estimator (SKFMEC) is judged against.
 *
 * Degrees of freedom: body x, y, yaw (planar motion of the whole car), sprung-mass heave, roll and
 * pitch, four unsprung vertical motions and four wheel spins. Axes: x forward, y left, z up (ISO);
 * roll + lifts the left side, pitch + lowers the nose, yaw + turns left. Wheels 0..3 = FL, FR, RL,
 * RR: the paper's 1..4 in a left turn (1 front inner, 2 front outer, 3 rear inner, 4 rear outer).
 *
 * Model (docs/chassis_plant.md has the derivation):
 * - The unsprung masses move with the body in the plane and vertically on their own. The sprung
 *   mass rolls about the roll axis (height hf, hr at the axles) and pitches about an axis at ground
 *   level (no anti-dive or anti-squat geometry).
 * - Horizontal and rotational equations carry the paper's inertial coupling (eq. 29-30, matrix E
 *   of eq. 35) extended by pitch: with a = ms hp, b = ms e,
 *       m (vx' - r vy) + b p r + a q'           = sum Fx - F_aero
 *       m (vy' + r vx) - b p' + a q r           = sum Fy
 *       (Ix + ms e^2) p' - b (vy' + r vx)       = sum Mx          (about the roll axis)
 *       (Iy + ms hp^2) q' + a (vx' - r vy)      = sum My          (about the ground-level pitch axis)
 *       Iz r' = sum Mz,   ms z'' = sum of suspension forces,   Iw w_i' = T_i - Fx_i rw   (eq. 30)
 *   A symmetric mass matrix with these gyroscopic terms: without forces, kinetic energy is kept.
 * - Suspension per corner: spring, damper, anti-roll bar; the lateral tyre force reaches the body
 *   through the roll centre, whose link force has a vertical part -Fy h_rc / t on the inner side
 *   and +Fy h_rc / t on the outer (geometric load transfer). Load transfer is not computed from a
 *   formula: tyre loads are Fz = Fz0 - kt zu - ct zu' (>= 0) of the unsprung dynamics.
 * - Roll stiffness per axle is the paper's k_phi with the tyres in series (suspension roll
 *   stiffness 1 / (1/k_phi - 1/(2 kt t^2)), the anti-roll bar is what the springs leave); the
 *   dampers give the paper's roll damping c_phi = 2 c t^2.
 * - Tyres: vh_mftire.h (MF 1987 pure slip, Bakker-Pacejka-Lidner 1989 combined slip), road
 *   friction per wheel, optional first-order relaxation of the slips.
 *
 * Integration: Heun (explicit trapezoid, RK2) at VH_V14_DT = 0.5 ms with 1..VH_V14_MAX_SUBSTEPS
 * sub-steps chosen each step from the fastest rate (the wheel-spin mode, C_kappa rw^2/(Iw v)):
 * one sub-step at road speeds. Heun's first stage is the truth of the step: the state at the
 * step's start with the forces of the step's inputs, the tyres evaluated exactly. Its second stage
 * takes the tyres' slip stiffness on its tangent in the load (an O(h^2) change of the stage, so
 * still second order). The peak slips normalising combined slip are refreshed for one tyre per
 * step (each every 2 ms) and held in between; docs/chassis_plant.md has the figures.
 */
#ifndef VH_VEH14_H
#define VH_VEH14_H

#include <stddef.h>
#include <stdint.h>

#include "vh_mftire.h"
#include "vh_types.h"

#define VH_V14_DT 0.0005
#define VH_V14_MAX_SUBSTEPS 16
#define VH_V14_GRAVITY 9.81
#define VH_V14_NW 4

enum { VH_V14_FL = 0, VH_V14_FR = 1, VH_V14_RL = 2, VH_V14_RR = 3 };

/* State vector layout. Positions z, phi, theta, zu are from the static equilibrium. */
enum {
    VH_V14_X_PX = 0,     /* world position of the CG [m] */
    VH_V14_X_PY = 1,
    VH_V14_X_YAW = 2,    /* heading [rad] */
    VH_V14_X_VX = 3,     /* velocity in body axes [m/s] */
    VH_V14_X_VY = 4,
    VH_V14_X_R = 5,      /* yaw rate [rad/s] */
    VH_V14_X_Z = 6,      /* sprung-mass heave [m] */
    VH_V14_X_VZ = 7,
    VH_V14_X_PHI = 8,    /* roll [rad] */
    VH_V14_X_P = 9,
    VH_V14_X_THETA = 10, /* pitch [rad] */
    VH_V14_X_Q = 11,
    VH_V14_X_ZU = 12,    /* 12..15 unsprung heave [m] */
    VH_V14_X_VZU = 16,   /* 16..19 */
    VH_V14_X_W = 20,     /* 20..23 wheel spin [rad/s] */
    VH_V14_X_SK = 24,    /* 24..27 relaxed longitudinal slip (used when relax_x > 0) */
    VH_V14_X_SA = 28,    /* 28..31 relaxed tan(slip angle) (used when relax_y > 0) */
    VH_V14_NX = 32
};

typedef struct {
    /* The paper's nomenclature (seed 000, Ford FC/HVE, McPherson strut). */
    double ms;       /* sprung mass [kg], 1661 */
    double ix;       /* roll inertia of the sprung mass about its CG [kg m^2], 580 */
    double iz;       /* yaw inertia [kg m^2], 2560 */
    double lf, lr;   /* CG to front / rear axle [m], 1.076 / 1.617 */
    double h;        /* CG height of the sprung mass [m], 0.55 (roll axis to CG e = h - h_ra = 0.48) */
    double tf, tr;   /* half-tracks [m], 0.784 / 0.760 (the nomenclature's lateral "lf, lr") */
    double hf, hr;   /* roll-centre heights [m], 0.114 / 0.004 */
    double kphi_f;   /* roll stiffness front [Nm/rad], 108205.8 (suspension and tyres in series) */
    double kphi_r;   /* roll stiffness rear [Nm/rad], 81436.7 */
    double cphi_f;   /* roll damping front [Nm s/rad], 826.8 */
    double cphi_r;   /* roll damping rear [Nm s/rad], 658.9 */
    double rw;       /* wheel radius [m], 0.305 */
    double iw;       /* wheel spin inertia [kg m^2], 2.0 */
    /* Not in the paper: chosen for a 1.8 t front-heavy sedan (docs/chassis_plant.md). */
    double iy;       /* pitch inertia of the sprung mass about its CG [kg m^2] */
    double m_uf;     /* unsprung mass per front corner [kg] */
    double m_ur;     /* unsprung mass per rear corner [kg] */
    double k_f, k_r; /* suspension spring rate at the wheel, per corner [N/m] */
    double kt;       /* tyre vertical stiffness [N/m] */
    double ct;       /* tyre vertical damping [N s/m] */
    double rho;      /* air density [kg/m^3] */
    double cda;      /* drag area C_d A [m^2]; 0: no aerodynamic drag */
    double v_low;    /* floor of |v_x| in the slip denominators [m/s] (low-speed regularisation) */
    double relax_x;  /* longitudinal relaxation length [m]; 0: slips act at once */
    double relax_y;  /* lateral relaxation length [m]; 0: slips act at once */
    int min_substeps; /* at least this many sub-steps per step (1..VH_V14_MAX_SUBSTEPS); 1 by default,
                       * more only to measure the integration error against finer steps */
    vh_mft_coef_t tyre;
} vh_v14_params_t;

/* Inputs of one step, held over the step. */
typedef struct {
    double steer;             /* front road-wheel angle delta [rad], + left; both wheels alike */
    double drive[VH_V14_NW];  /* drive torque per wheel [Nm], + forward */
    double brake[VH_V14_NW];  /* brake torque magnitude per wheel [Nm], >= 0, opposes the spin */
    double mu[VH_V14_NW];     /* road friction under each wheel, >= 0 */
} vh_v14_input_t;

typedef struct {
    double t;                   /* time since reset [s] */
    double px, py, yaw;         /* world position of the CG [m], heading [rad] */
    double vx, vy, r;           /* body-axis velocity [m/s], yaw rate [rad/s] */
    double ax, ay;              /* body-axis acceleration vx' - r vy, vy' + r vx [m/s^2] */
    double z, vz;               /* sprung-mass heave [m], [m/s] */
    double phi, p;              /* roll [rad], roll rate [rad/s] */
    double theta, q;            /* pitch [rad], pitch rate [rad/s] */
    double steer;               /* road-wheel angle applied [rad] */
    double fx[VH_V14_NW];       /* tyre longitudinal force, wheel axes [N] */
    double fy[VH_V14_NW];       /* tyre lateral force, wheel axes [N] */
    double fxv[VH_V14_NW];      /* the same in body axes [N] */
    double fyv[VH_V14_NW];
    double fz[VH_V14_NW];       /* tyre normal load [N] */
    double kappa[VH_V14_NW];    /* longitudinal slip the tyre uses */
    double alpha[VH_V14_NW];    /* slip angle the tyre uses [rad] */
    double omega[VH_V14_NW];    /* wheel spin [rad/s] */
    double torque[VH_V14_NW];   /* net wheel torque: drive minus the brake torque acting [Nm] */
    double mu[VH_V14_NW];       /* road friction applied */
    double zu[VH_V14_NW];       /* unsprung heave [m] */
    double spring_defl[VH_V14_NW]; /* spring deflection from its free length, compression + [m]:
                                    * k times it is the spring's force (the ride-height sensors) */
    double fyf, fyr;            /* mean tyre lateral force per axle, (Fy1 + Fy2)/2, (Fy3 + Fy4)/2 [N] */
    int substeps;               /* sub-steps of the last step */
} vh_v14_truth_t;

/* Active roll actuators (roll system, seed 003): per axle a commanded roll moment on the body,
 * applied as equal and opposite vertical forces +-M/(2t) between the body and the wheels of that
 * axle (left up for M > 0), through a torque limit, a rate limit and a first-order lag. Defaults:
 * a 48 V electromechanical stabiliser, ~1.2 kNm at the bar, ~4.8 kNm of body roll moment per axle
 * (docs/roll.md). With both applied moments zero the plant is exactly the passive one. */
typedef struct {
    double m_max;     /* roll moment limit on the body [Nm] */
    double rate_max;  /* rate limit [Nm/s] */
    double tau;       /* first-order lag [s]; 0: none */
} vh_v14_arc_params_t;

typedef struct {
    vh_v14_arc_params_t prm[2]; /* front, rear */
    double cmd[2];              /* last commanded moment [Nm], held until the next command */
    double lim[2];              /* after the torque and rate limits */
    double m[2];                /* applied (after the lag) over the last step [Nm] */
} vh_v14_arc_t;

typedef struct {
    vh_v14_params_t prm;
    vh_v14_truth_t truth;       /* state at the start of the last step, with the forces of its inputs */
    double x[VH_V14_NX];
    uint64_t steps;             /* steps since reset */
    uint32_t bad_inputs;        /* steps with an input that had to be sanitised */
    /* derived at init */
    double m;                   /* total mass [kg] */
    double e;                   /* roll axis to sprung CG [m] */
    double hp;                  /* pitch axis (ground) to sprung CG [m] */
    double fz0[VH_V14_NW];      /* static tyre loads [N] */
    double fs0[VH_V14_NW];      /* static spring loads (sprung weight per corner) [N] */
    double k_arb_f, k_arb_r;    /* anti-roll bar roll stiffness [Nm/rad] */
    double c_f, c_r;            /* damper rate per corner [N s/m] */
    double cx[VH_V14_NW];       /* corner positions in body axes [m] */
    double cy[VH_V14_NW];
    double ip, iq;              /* Ix + ms e^2, Iy + ms hp^2 */
    double det_x, det_y;        /* determinants of the (vx, q) and (vy, p) mass blocks */
    double rate_fixed;          /* fastest rate not from the tyres [1/s] */
    vh_mft_state_t pk[VH_V14_NW]; /* tyres at the step-start loads (tangent base, held peak slips) */
    double ck[VH_V14_NW];       /* longitudinal slip stiffness at the step-start loads [N] */
    vh_v14_arc_t arc;           /* active roll actuators (moments zero unless commanded) */
} vh_v14_t;

/* The paper's parameters plus the documented plausible rest. */
void vh_v14_params_default(vh_v14_params_t *prm);
/* VH_OK, or VH_EINVAL (nothing changed) for missing pointers, non-finite or non-physical
 * parameters, a roll stiffness the tyres alone cannot give (the bar k_susp - 2 k t^2 may be
 * negative; within 1e-9 of k_susp it is taken as no bar), or tyre coefficients vh_mft_check refuses. Starts at rest (vh_v14_reset). */
int vh_v14_init(vh_v14_t *p, const vh_v14_params_t *prm);
/* At rest in static equilibrium, time 0. */
void vh_v14_reset(vh_v14_t *p);
/* Straight ahead at vx [m/s] (|vx| <= 100), wheels free-rolling, static equilibrium; time and
 * position kept. VH_EINVAL if out of range. */
int vh_v14_set_rolling(vh_v14_t *p, double vx);
/* One 0.5 ms step: truth := the state now with the forces of `in` (what a sensor sampling at the
 * tick sees), then the state advances to the next tick. Non-finite inputs are taken as 0,
 * negative brake or friction as 0, friction above 3 as 3, |steer| above 0.6 rad clamped; each
 * such step counts in bad_inputs. */
void vh_v14_step(vh_v14_t *p, const vh_v14_input_t *in);
/* n steps with in[i]; copies the truth of each step to out[i] when out is not NULL (out[i] is the
 * state at i steps from now under in[i]). Returns n. */
size_t vh_v14_run(vh_v14_t *p, size_t n, const vh_v14_input_t *in, vh_v14_truth_t *out);
/* Mechanical energy [J]: kinetic (with the roll/pitch coupling) + springs, anti-roll bars, tyres
 * in contact and gravity (sprung-mass roll and pitch), from the static equilibrium. */
double vh_v14_energy(const vh_v14_t *p);
/* All torques and steer zero, friction mu under every wheel. */
void vh_v14_input_init(vh_v14_input_t *in, double mu);
/* Active roll actuators. Defaults: m_max 4800 Nm, rate_max 16000 Nm/s, tau 0.03 s (docs/roll.md). */
void vh_v14_arc_params_default(vh_v14_arc_params_t *a);
/* Limits and lag per axle (front, rear); VH_EINVAL (nothing changed) unless m_max >= 0,
 * rate_max > 0, tau >= 0, all finite. vh_v14_init sets the defaults; reset zeroes the moments. */
int vh_v14_arc_config(vh_v14_t *p, const vh_v14_arc_params_t *front, const vh_v14_arc_params_t *rear);
/* Roll moment command per axle [Nm] for the next steps (non-finite: 0). Each step moves the
 * limited command by at most rate_max dt towards it, clamps it to +-m_max, and the applied moment
 * follows with the lag (exact first-order discretisation over the step) and acts over that step. */
void vh_v14_set_roll_moment(vh_v14_t *p, double m_front, double m_rear);
/* Fail safe: both commands and limited commands to zero at once, past the rate limit (the
 * stabiliser's motor is shorted, the bar goes passive); the applied moments decay with the lag. */
void vh_v14_roll_fail_safe(vh_v14_t *p);
/* One tick of the actuators alone (rate limit, torque limit, lag), as vh_v14_step does before it
 * integrates: for a car whose plant is another model (vh_v14car_set_plant). */
void vh_v14_arc_step(vh_v14_t *p);

#endif /* VH_VEH14_H */
