/* vh_dkf.h - 2 kHz discrete Kalman filter for driveline output-shaft torque (seed 001).
 *
 * State x = [w_o, w_w, T_o, T_Le]: output-shaft speed, wheel speed, output-shaft torque,
 * road-load error torque. Input u = T_i, turbine torque (eq. 9, vh_dkf_turbine_torque).
 * Measurements: rows of z = [w_o, w_w, T_o] picked by the measurement set, i.e. the paper's
 * H = diag[1 1 1 0] (speeds + torque transducer) or diag[1 1 0 0] (speeds only); the zero rows
 * of the paper's 4x4 H add nothing and are left out.
 *
 * Numerics: Joseph-form covariance update, then symmetrised, so P stays symmetric positive
 * definite indefinitely (the textbook P = (I-KH)P- loses symmetry and goes to NaN in a few
 * thousand steps at Ts = 0.5 ms). A non-finite value in x or P, a non-positive diagonal or a
 * diagonal above p_max resets the filter to its initial state and counts a reset.
 */
#ifndef VH_DKF_H
#define VH_DKF_H

#include "vh_health.h"
#include "vh_types.h"

#define VH_DKF_NX 4
#define VH_DKF_NZ 3

typedef enum { VH_DKF_EULER = 0, VH_DKF_ZOH = 1 } vh_dkf_disc_t;
typedef enum { VH_DKF_SPEEDS_TORQUE = 0, VH_DKF_SPEEDS = 1 } vh_dkf_meas_t;

/* Measurement-valid bits for vh_dkf_step's mask. */
enum { VH_DKF_Z_WO = 1u, VH_DKF_Z_WW = 2u, VH_DKF_Z_TO = 4u, VH_DKF_Z_ALL = 7u };
/* Input-valid bit of the same mask: without it u is still used (the caller's held value)
 * but the filter reports DEGRADED. A non-finite u is replaced by 0 and also clears it. */
enum { VH_DKF_U_VALID = 8u, VH_DKF_ALL_VALID = 15u };
/* The valid rows are the last good samples, not new ones: predict only, health unaffected
 * (a sample late by less than the RX timeout is normal operation, not a fault). */
enum { VH_DKF_STALE = 16u };

typedef struct {
    /* Model (Table 1). */
    double jo;  /* output-side inertia J_o [kg m^2] */
    double jv;  /* vehicle inertia at the wheel J_v [kg m^2] */
    double rd;  /* final drive ratio R_d */
    double ri;  /* gear ratio R_i */
    double ks;  /* output-shaft stiffness k_s [Nm/rad] */
    double c;   /* linearised road-load coefficient [Nm s/rad], eq. 4 */
    double ts;  /* sample time [s] */
    /* Tuning: diagonals of Q (discrete process noise) and R (z = [w_o, w_w, T_o]). */
    double q[VH_DKF_NX];
    double r[VH_DKF_NZ];
    double p0[VH_DKF_NX]; /* initial covariance diagonal */
    double p_max;         /* divergence limit on any P diagonal */
    double x_max;         /* divergence limit on any |x| (far beyond any physical speed or torque) */
    int meas;             /* vh_dkf_meas_t */
    int disc;             /* vh_dkf_disc_t */
    int use_input;        /* 0: run with u = 0 (the paper's "without input torque" case) */
} vh_dkf_config_t;

typedef struct {
    vh_dkf_config_t cfg;
    double ad[VH_DKF_NX * VH_DKF_NX]; /* discrete A, row-major */
    double bd[VH_DKF_NX];             /* discrete B */
    double x[VH_DKF_NX];
    double p[VH_DKF_NX * VH_DKF_NX];
    double k[VH_DKF_NX * VH_DKF_NZ];  /* last gain; columns of unused rows are zero */
    double innov[VH_DKF_NZ];          /* last innovation z - H x- per row; 0 for rows not used */
    uint32_t steps;                   /* steps since the last (re)start */
    uint32_t resets;                  /* divergence resets since init */
    uint8_t health;                   /* vh_health_t */
    uint8_t x_init;                   /* 0 until the state is seeded from a measurement */
} vh_dkf_t;

/* Paper's defaults (Table 1 and the tuning of sec. 4) for a measurement set; ZOH. */
void vh_dkf_config_default(vh_dkf_config_t *cfg, int meas);
/* c = r_t * rho_a * C_a * A * w_wo, eq. 4 as printed. */
double vh_dkf_road_load_coeff(double rt, double rho_a, double ca, double area, double wwo);
/* Continuous A (row-major 4x4) and B (4) of eq. 1-8 for a configuration. */
void vh_dkf_model(const vh_dkf_config_t *cfg, double a[16], double b[4]);
/* Discretise (A, B) at ts: x+ = Ad x + Bd u. Euler: Ad = I + ts A (eq. 10); ZOH: exact. */
void vh_dkf_discretise(const double a[16], const double b[4], double ts, int disc, double ad[16], double bd[4]);

/* The discrete model (Ad, Bd) of a configuration for one gear ratio. */
typedef struct {
    double ri;
    double ad[VH_DKF_NX * VH_DKF_NX];
    double bd[VH_DKF_NX];
} vh_dkf_gear_model_t;
/* Discretise cfg's model with ratio ri (the matrix exponential: do it at init, once per gear);
 * VH_EINVAL for a ratio that is not positive and finite (m unchanged). */
int vh_dkf_gear_model(const vh_dkf_config_t *cfg, double ri, vh_dkf_gear_model_t *m);
/* Switch a running filter to a precomputed gear model: a copy, no exponential in the tick.
 * The same Ad, Bd as vh_dkf_set_ratio(f, m->ri), bit for bit. */
void vh_dkf_use_gear_model(vh_dkf_t *f, const vh_dkf_gear_model_t *m);

/* VH_OK, or VH_EINVAL for a non-physical or non-finite configuration (nothing changed). */
int vh_dkf_init(vh_dkf_t *f, const vh_dkf_config_t *cfg);
void vh_dkf_reset(vh_dkf_t *f);
/* One 0.5 ms step: predict with u, update with the valid rows of z (mask of VH_DKF_Z_*).
 * z rows the measurement set does not use are ignored. Returns 1 if the filter had to be reset. */
int vh_dkf_step(vh_dkf_t *f, double u, const double z[VH_DKF_NZ], unsigned mask);
/* Gear change: new R_i, rediscretised; state and covariance carry over. VH_EINVAL if ri <= 0. */
int vh_dkf_set_ratio(vh_dkf_t *f, double ri);
/* Run n steps over arrays (the Python API): u[n], z[n*3], mask[n] (NULL: all valid).
 * Writes x_out[n*4] and, when non-NULL, k_out[n*12] and p_out[n*16]. Returns total resets. */
uint32_t vh_dkf_run(vh_dkf_t *f, size_t n, const double *u, const double *z, const uint8_t *mask,
                    double *x_out, double *k_out, double *p_out);

/* The ECU's filter: the same step, reset and run (one source, vh_dkf_step.inc) in float32, which a
 * Cortex-M4F's FPU runs in hardware (in double, libgcc's software routines are 80 % of the step).
 * The configuration is checked and the model discretised in double (vh_dkf_init, vh_dkf_gear_model),
 * then rounded once into these. Accuracy against the double build: docs/firmware.md. */
typedef struct {
    float q[VH_DKF_NX];
    float r[VH_DKF_NZ];
    float p0[VH_DKF_NX];
    float p_max, x_max, ri, rd;
    int meas, use_input;
} vh_dkf_f32_config_t;

typedef struct {
    vh_dkf_f32_config_t cfg;
    float ad[VH_DKF_NX * VH_DKF_NX];
    float bd[VH_DKF_NX];
    float x[VH_DKF_NX];
    float p[VH_DKF_NX * VH_DKF_NX];
    float k[VH_DKF_NX * VH_DKF_NZ];
    float innov[VH_DKF_NZ];
    uint32_t steps;
    uint32_t resets;
    uint8_t health;
    uint8_t x_init;
} vh_dkf_f32_t;

/* vh_dkf_init's checks and model, rounded to float32; VH_EINVAL as vh_dkf_init. */
int vh_dkf_f32_init(vh_dkf_f32_t *f, const vh_dkf_config_t *cfg);
/* The tuning a running filter takes from a configuration (q, r, p0, p_max, x_max; XCP). */
void vh_dkf_f32_tune(vh_dkf_f32_t *f, const vh_dkf_config_t *cfg);
void vh_dkf_f32_reset(vh_dkf_f32_t *f);
int vh_dkf_f32_step(vh_dkf_f32_t *f, float u, const float z[VH_DKF_NZ], unsigned mask);
/* A precomputed gear model (double), rounded into the filter: a gear change, no exponential. */
void vh_dkf_f32_use_gear_model(vh_dkf_f32_t *f, const vh_dkf_gear_model_t *m);
uint32_t vh_dkf_f32_run(vh_dkf_f32_t *f, size_t n, const float *u, const float *z, const uint8_t *mask,
                        float *x_out, float *k_out, float *p_out);

/* Turbine torque from engine and turbine speed: eq. 9 (with the coupling/overrun extension of
 * vh_tc.h). Returns 0 and sets *ti when w_e >= we_min and the speed ratio is in [0, 2]; else -1
 * (input not usable: stalled engine, implausible ratio, non-finite speed). */
int vh_dkf_turbine_torque(double we, double wt, double we_min, double *ti);

#endif /* VH_DKF_H */
