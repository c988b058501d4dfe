/* vh_skf.h - tire lateral force monitoring (seed 000): SKFMEC and the plain EKF, double precision.
 *
 * Monitoring model (eq. 29-37 + appendix sums), states x = [vx vy r phi p Fyf Fyr]: body-frame
 * speeds, yaw rate, roll angle and rate, and the average lateral force of one front / one rear
 * tire. Measurements y = [ax ay r p]. Inputs: front road-wheel angle, 4 wheel speeds and 4
 * drive(+)/brake(-) torques; longitudinal tire forces from the wheel equation (eq. 30) with a
 * filtered wheel-speed derivative. Wheels 1..4 = FL, FR, RL, RR; ISO axes (x forward, y left,
 * z up), so in a left turn (ay > 0) wheels 1, 3 are inner and 2, 4 outer, as in eq. 33-34.
 *
 * One code path, two flags: `scaled` runs the filter in x* = S x (eq. 2-4, 28), `mec` adds the
 * model error compensator Gp (r - r^) (eq. 38) and the a_y-residual load compensation Gy (eq. 39).
 * SKFMEC = scaled + mec; the paper's plain EKF baseline = neither, with the same Q, R, P0
 * (converted from scaled coordinates, so in exact arithmetic only the compensator differs).
 *
 * Discretisation at the ECU step Ts (docs/tireforce.md): forward Euler for the state (eq. 38),
 * Phi* = I + Ts F* for the covariance, discrete measurement update every step (sequential scalar
 * updates in the symmetric expanded Joseph form), Qd = Qc Ts, R = per-sample variances.
 * Unobservable states (vx, vy: no output depends on them) get their variance capped by a
 * congruence P <- D P D with D = diag(1, .., 1/2, .., 1), which keeps P symmetric PSD and
 * leaves every other state's estimate untouched; their values are clamped to |x*| <= x_max.
 * Non-finite or divergent state/covariance resets the filter (health FAULT), as vh_dkf.
 */
#ifndef VH_SKF_H
#define VH_SKF_H

#include "vh_health.h"
#include "vh_tf_types.h"
#include "vh_types.h"

typedef enum { VH_SKF_SKFMEC = 0, VH_SKF_EKF = 1 } vh_skf_variant_t;

/* One step's inputs; the layout is VH_SKF_NU doubles (the Python API passes rows of an array). */
typedef struct {
    double ax, ay;       /* measured accelerations [m/s^2] */
    double r, p;         /* measured yaw and roll rate [rad/s] */
    double delta;        /* front road-wheel angle [rad] */
    double omega[4];     /* wheel speeds FL FR RL RR [rad/s] */
    double torque[4];    /* wheel drive(+)/brake(-) torques [Nm] */
} vh_skf_input_t;

typedef struct {
    /* Vehicle (paper's nomenclature; tf, tr = half-tracks). */
    double m, ms, iz, ix, lf, lr, h, e, hf, hr;
    double kphif, kphir, cphif, cphir, rw, iw, tf, tr, g;
    double zeta1, zeta2; /* Fyf = zeta1 phi, Fyr = zeta2 phi (eq. 31-32) [N/rad] */
    double lt_gain;      /* factor on eq. 39's lateral load-transfer bracket (1 = as printed) */
    double ts;           /* step [s] */
    double tau_wdot;     /* time constant of the wheel-acceleration filter [s] */
    double s[VH_SKF_NX]; /* scaling S = diag(s) (eq. 2) */
    /* Tuning. q, p0, gp in scaled coordinates x* = S x whatever `scaled` says. */
    double q[VH_SKF_NX];   /* discrete process noise variances per step */
    double p0[VH_SKF_NX];  /* initial covariance diagonal */
    double r[VH_SKF_NY];   /* measurement noise variances [ax ay r p] */
    double gp[VH_SKF_NX];  /* MEC gain on r - r^ [(scaled unit)/s per rad/s] (eq. 38) */
    double gy[2];          /* Gy1, Gy2 [N per m/s^2] (eq. 39) */
    double p_cap;          /* scaled variance above which the congruence halving applies */
    double p_max;          /* divergence limit on any scaled variance (fixed point: at most 30) */
    double x_max;          /* divergence limit on |x*|; vx*, vy* are clamped to it (fixed point: <= 1000) */
    int scaled;            /* 1: filter in x* = S x; 0: in x */
    int mec;               /* 1: apply Gp and Gy */
} vh_skf_config_t;

typedef struct {
    vh_skf_config_t cfg;
    double d[VH_SKF_NX];   /* filter coordinates x_f = diag(d) x: d = s (scaled) or 1 */
    double w[VH_SKF_NX];   /* (s/d)^2: filter variance -> scaled variance */
    double qf[VH_SKF_NX], gpf[VH_SKF_NX]; /* Q and Gp in filter coordinates */
    double x[VH_SKF_NX];   /* estimate, filter coordinates */
    double p[VH_SKF_NX * VH_SKF_NX];
    double k[VH_SKF_NX * VH_SKF_NY]; /* last step's sequential gains (column j: row j's update) */
    double innov[VH_SKF_NY];         /* last prior innovations (0 for unused rows) */
    double nu_ay;                    /* a_y innovation driving Gy (eq. 39), one step old in the model */
    double w_prev[4], wdot[4];      /* last wheel speeds, filtered wheel accelerations */
    double fx[4], fz[4], fy[4];      /* eq. 30, 39, 36-37 at the last estimate */
    double cs_delta[2];              /* cos, sin of the last valid steering angle */
    uint32_t steps;  /* since the last (re)start */
    uint32_t resets; /* divergence resets since init */
    uint32_t caps;   /* congruence halvings since init */
    uint8_t health;  /* vh_health_t */
    uint8_t x_init;
} vh_skf_t;

/* The paper's vehicle and S, the project's tuning (docs/tireforce.md) for a variant. */
void vh_skf_config_default(vh_skf_config_t *cfg, int variant);
/* zeta1, zeta2 that make eq. 31-32 consistent with the model's own steady cornering. */
void vh_skf_zeta_steady(const vh_skf_config_t *cfg, double *zeta1, double *zeta2);
/* 1 when the configuration is physical and finite (what vh_skf_init accepts), else 0. */
int vh_skf_config_check(const vh_skf_config_t *cfg);
/* VH_OK, or VH_EINVAL for a non-physical or non-finite configuration (nothing changed). */
int vh_skf_init(vh_skf_t *f, const vh_skf_config_t *cfg);
void vh_skf_reset(vh_skf_t *f);
/* One step with this sample's inputs and mask (VH_SKF_* bits). Returns 1 if the filter was reset. */
int vh_skf_step(vh_skf_t *f, const vh_skf_input_t *in, unsigned mask);
/* The estimate in physical units. */
void vh_skf_state(const vh_skf_t *f, double x[VH_SKF_NX]);
/* n steps over arrays: u[n*VH_SKF_NU] rows laid out as vh_skf_input_t, mask[n] (NULL: all valid).
 * Writes x_out[n*7] (physical), fy_out[n*4], fz_out[n*4] and, when non-NULL, p_out[n*49]
 * (filter coordinates) and health_out[n]. Returns the resets during the run. */
uint32_t vh_skf_run(vh_skf_t *f, size_t n, const double *u, const uint8_t *mask, double *x_out,
                    double *fy_out, double *fz_out, double *p_out, uint8_t *health_out);

#endif /* VH_SKF_H */
