/* vh_roll_app.h - the roll ECU application (seed 003) on the chassis bus.
 *
 * RX: ROLL_Sensors and ROLL_YawRate (the UKF's 14 measurements), CHS_Sensors (its inputs: steer and
 * the wheel speeds, vx = rw x their mean), ROLL_ActuatorStatus (the applied moments, the UKF's known
 * inputs, and the actuators' state) and ROLL_ModeCmd (passive / active), each with the shared checks
 * (length, E2E P01, burst, timeout: vh_rx.h). Each measurement's qualifier, SNA value and a stuck
 * check (the same raw value stuck_samples frames in a row: a live sensor's noise spans several LSB)
 * give the UKF's valid mask; a measurement whose frame did not arrive since the last step, timed
 * out or failed a check is removed from that update, never replaced by a stale value.
 * Step (on each ROLL_Sensors frame, 5 ms; without one, on that cycle): one float32 UKF step, one
 * sliding-mode controller step on its estimates; the controller sees the estimate as not OK also when its inputs are missing or the
 * actuators report HOLD / FAILSAFE or go silent, so it fades to passive (docs/roll.md).
 * TX: VEHEST_RollCmd in the tick of every step, VEHEST_RollEst (estimates and health) every 10 ms, once the
 * roll sensors have been heard. Every scale is the DBC's (generated encoders and decoders).
 */
#ifndef VH_ROLL_APP_H
#define VH_ROLL_APP_H

#include "vh_app.h"
#include "vh_roll.h"
#include "vh_rx.h"
#include "vh_types.h"

/* RX messages of the application (index into vh_roll_app_t.rx). */
enum { VH_ROLL_RX_SENS = 0, VH_ROLL_RX_YAW = 1, VH_ROLL_RX_CHS = 2, VH_ROLL_RX_ACT = 3, VH_ROLL_RX_MODE = 4, VH_ROLL_N_RX = 5 };

/* RollRxFault bits of VEHEST_RollEst. */
enum {
    VH_ROLL_RXF_SENS = 1,      /* ROLL_Sensors timed out */
    VH_ROLL_RXF_YAW = 2,       /* ROLL_YawRate timed out */
    VH_ROLL_RXF_INPUT = 4,     /* CHS_Sensors timed out, or steer / wheel speeds invalid */
    VH_ROLL_RXF_ACT = 8,       /* ROLL_ActuatorStatus timed out */
    VH_ROLL_RXF_ARC = 16,      /* actuators in HOLD or FAILSAFE */
    VH_ROLL_RXF_MODE = 32,     /* ROLL_ModeCmd timed out: passive */
    VH_ROLL_RXF_STUCK = 64     /* a measurement is stuck */
};

typedef struct {
    vh_roll_params_t ukf;       /* dt must be the ROLL_Sensors cycle */
    vh_roll_smc_params_t smc;   /* dt likewise */
    double rw;                  /* wheel radius for vx [m] */
    uint8_t stuck_samples;      /* identical raw values in a row that make a measurement stuck; 0: off */
} vh_roll_app_config_t;

#define VH_ROLL_XCP_STILL_VX 0.2 /* XCP's standstill: vx from CHS_Sensors below [m/s] */

/* The roll UKF's tuning (XCP), as in vh_roll_params_t: -> cfg.ukf and ukf */
typedef struct {
    double q[VH_ROLL_NX];  /* process noise Q diagonal, per step */
    double r[VH_ROLL_NZ];  /* measurement noise R diagonal */
    double p0[VH_ROLL_NX]; /* initial covariance diagonal (eq. 14): used at the filter's next reset */
    double reg_eps;        /* regularisation of the Cholesky retry, relative to the mean diagonal */
    double nis_max;        /* innovation test per measurement (0 off) */
    double phi_max;        /* |roll| above this: diverged, reset [rad] */
} vh_roll_app_cal_ukf_t;

/* The sliding-mode controller's tuning, as in vh_roll_smc_params_t: -> cfg.smc and smc. Its model
 * terms (i_roll, ms_e, kphi, cphi) and dt are the vehicle's, not tuning. */
typedef struct {
    double lambda, k, p;                    /* eq. 28, eq. 32-33, eq. 34-35 */
    double ref_frac, ref_tau, ay_tau, front_share;
    double m_max_f, m_max_r, rate_max_f, rate_max_r;
    double fade_time, recover_time, not_ok_debounce;
} vh_roll_app_cal_smc_t;

typedef struct {
    vh_roll_app_cal_ukf_t ukf;
    vh_roll_app_cal_smc_t smc;
    uint8_t stuck_samples;  /* -> cfg.stuck_samples */
} vh_roll_app_cal_t;

typedef struct {
    vh_roll_app_config_t cfg;
    vh_roll_ukf_f32 ukf;
    vh_roll_smc_f32 smc;
    vh_ecu_rxmsg_t rx[VH_ROLL_N_RX];
    vh_ecu_counters_t cnt;
    float z[VH_ROLL_NZ];        /* the last good sample of each measurement */
    uint32_t z_ok;              /* bit i: z[i] passed its checks in its last frame */
    uint32_t z_new;             /* bit i: z[i] arrived since the last step */
    double last[VH_ROLL_NZ];    /* each measurement's value in its last frame (stuck check) */
    uint8_t same[VH_ROLL_NZ];   /* frames in a row with the same raw value */
    uint32_t stuck;             /* bit i: z[i] is stuck */
    float steer, vx;            /* inputs from CHS_Sensors */
    uint8_t u_ok;               /* both valid in the last CHS_Sensors frame */
    float m_applied[2];         /* from ROLL_ActuatorStatus */
    uint8_t arc_state;
    uint8_t mode_active;        /* ROLL_ModeCmd's request */
    uint8_t heard;              /* a good ROLL_Sensors frame since reset */
    uint8_t stepped;            /* the UKF has stepped since reset */
    uint8_t stepped_now;        /* it stepped in this tick: the command goes out */
    uint8_t sens_arrived;       /* a good ROLL_Sensors frame since the last step */
    uint8_t yaw_arrived;        /* a good ROLL_YawRate frame since the last step */
    uint8_t sens_wait;          /* ticks the step has waited for the yaw-rate frame of the same sample */
    uint16_t since_step;        /* ticks since the last step */
    uint32_t missing;           /* measurements removed from the last update */
    uint32_t flags_acc;         /* UKF flags since the last VEHEST_RollEst */
    uint32_t rx_fault;          /* VH_ROLL_RXF_* of the last step */
    uint8_t tx_counter[2];      /* E2E counters: RollCmd, RollEst */
} vh_roll_app_t;

/* The application's entry points (vh_app.h). Defaults: the roll system's parameters at the
 * ROLL_Sensors cycle, R for the node's averaged samples, the plant's wheel radius, stuck after 8
 * frames. check: VH_EINVAL for a configuration the UKF or SMC refuses or a step that is not the
 * cycle. rx: CHS_Sensors and ROLL_*. safety: roll control passive, vx from CHS_Sensors; hold
 * sets the mode passive. */
void vh_roll_app_config_default(vh_roll_app_config_t *cfg);
int vh_roll_app_config_host(vh_roll_app_config_t *cfg);
int vh_roll_app_check(const vh_roll_app_config_t *cfg);
void vh_roll_app_init(vh_roll_app_t *a, const vh_roll_app_config_t *cfg);
void vh_roll_app_reset(vh_roll_app_t *a);
void vh_roll_app_rx(vh_roll_app_t *a, vh_app_ctx_t *ctx, const vh_frame_t *f);
void vh_roll_app_cal_gather(const vh_roll_app_t *a, vh_roll_app_cal_t *c);
void vh_roll_app_cal_apply(vh_roll_app_t *a, const vh_roll_app_cal_t *c);
unsigned vh_roll_app_safety(vh_roll_app_t *a, int hold);
/* Runnables. tick: every tick, ages and timeouts of the RX messages. step: every tick, one UKF
 * and controller step when a ROLL_Sensors frame has arrived (one step per sample, whatever the
 * arrival jitter), or, without one, on the nominal cycle (prediction only). The payloads of
 * VEHEST_RollCmd and VEHEST_RollEst; 0 (send nothing) before the roll sensors are heard. */
void vh_roll_app_tick(vh_roll_app_t *a, vh_app_ctx_t *ctx);
void vh_roll_app_step(vh_roll_app_t *a, vh_app_ctx_t *ctx);
int vh_roll_app_fill_cmd(vh_roll_app_t *a, vh_app_ctx_t *ctx, uint8_t *data);
int vh_roll_app_fill_est(vh_roll_app_t *a, vh_app_ctx_t *ctx, uint8_t *data);

#endif /* VH_ROLL_APP_H */
