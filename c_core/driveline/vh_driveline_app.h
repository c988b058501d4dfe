/* vh_driveline_app.h - the driveline ECU application (seed 001) on the powertrain bus.
 *
 * RX: DLS_Sensors (length, E2E, extended-ID refusal, per-signal qualifier and SNA, the engaged
 * gear), timeout and burst. Step: the turbine torque input (eq. 9), the filters' ratio for the
 * engaged gear, one step of each driveline filter. TX: VEHEST_DrivelineEst every tick and
 * VEHEST_Status (the ECU's counters, ctx->cnt) at its DBC cycle. Publishes the stationary gate
 * (vh_app_signals_t) for the apps after it (camber inspection).
 */
#ifndef VH_DRIVELINE_APP_H
#define VH_DRIVELINE_APP_H

#include "vh_app.h"
#include "vh_dkf.h"
#include "vh_rx.h"
#include "vh_types.h"

/* The stationary gate's low-pass: 1/32 per DLS frame, tau = 16 ms at 2 kHz. One sample of
 * wheel-speed noise above the limit must not make a parked car "moving" (the ABS sensor's noise
 * at standstill reaches 0.6 rad/s in a few seconds, against a 0.5 rad/s gate); the filter cuts it
 * ~8x and costs a rolling car (0.5 rad/s and up) under 2 ms. */
#define VH_DRV_STILL_LP (1.0 / 32.0)

/* The two driveline filters: T = speeds + torque transducer, S = speeds only. */
enum { VH_ECU_DKF_T = 0, VH_ECU_DKF_S = 1, VH_ECU_N_DKF = 2 };
#define VH_ECU_N_GEARS 6 /* index = GearEngaged 1..5; 0 = neutral */
#define VH_DRV_XCP_STILL_WW 0.5 /* XCP's standstill: wheel speeds below [rad/s] */

typedef struct {
    vh_dkf_config_t dkf[VH_ECU_N_DKF]; /* ri is taken from gear_ratio[gear] at run time */
    double gear_ratio[VH_ECU_N_GEARS]; /* R_i per gear (w_o = R_i w_t); 0 = gear not usable */
    double we_min;                     /* engine speed below which eq. 9 is not used [rad/s] */
} vh_drv_app_config_t;

/* The driveline filters' tuning (XCP): -> dkf[i].cfg.q, .r, .p_max and the configuration's */
typedef struct {
    double q[VH_DKF_NX]; /* diagonal of Q */
    double r[VH_DKF_NZ]; /* diagonal of R, z = [w_o, w_w, T_o] */
    double p_max;        /* divergence limit on a P diagonal */
} vh_drv_app_cal_dkf_t;

typedef struct {
    vh_drv_app_cal_dkf_t dkf[VH_ECU_N_DKF];
    double we_min;       /* -> cfg.we_min [rad/s] */
} vh_drv_app_cal_t;

/* Last good driveline sensor sample (physical units) with per-signal validity. */
typedef struct {
    double wo, wwl, wwr, to, we, wt;
    double still_lp; /* max(|wwl|, |wwr|) low-passed over frames (VH_DRV_STILL_LP): the stationary gate */
    uint8_t valid;   /* bit i: signal i valid (order as above) */
    uint8_t gear;    /* 0..14, 15 = SNA */
    vh_ecu_rxmsg_t rx;
} vh_ecu_dls_t;

typedef struct {
    vh_drv_app_config_t cfg;
    vh_dkf_f32_t dkf[VH_ECU_N_DKF]; /* the two filters, float32 (vh_dkf.h) */
    vh_ecu_dls_t dls;
    double ti;        /* last turbine torque input (eq. 9) */
    uint8_t ti_valid;
    uint8_t gear;     /* gear the filters are discretised for */
    uint8_t tx_counter[2]; /* E2E counters: DrivelineEst, Status */
    uint32_t secoc_seen;   /* ctx->cnt->secoc_reject at the last VEHEST_Status (RxFaultActive bit 3) */
    /* each filter's discrete model per usable gear, computed at reset: a gear change in the tick
     * is a copy, not a matrix exponential (ri = 0: gear not usable) */
    vh_dkf_gear_model_t gears[VH_ECU_N_DKF][VH_ECU_N_GEARS];
} vh_drv_app_t;

/* The application's entry points (vh_app.h). check: VH_EINVAL for a negative or non-finite ratio,
 * a non-positive we_min or a filter configuration vh_dkf_init refuses. reset discretises each
 * filter's model for every usable gear. */
void vh_drv_app_config_default(vh_drv_app_config_t *cfg);
int vh_drv_app_config_host(vh_drv_app_config_t *cfg);
int vh_drv_app_check(const vh_drv_app_config_t *cfg);
void vh_drv_app_init(vh_drv_app_t *a, const vh_drv_app_config_t *cfg);
void vh_drv_app_reset(vh_drv_app_t *a);
void vh_drv_app_rx(vh_drv_app_t *a, vh_app_ctx_t *ctx, const vh_frame_t *f);
void vh_drv_app_cal_gather(const vh_drv_app_t *a, vh_drv_app_cal_t *c);
void vh_drv_app_cal_apply(vh_drv_app_t *a, const vh_drv_app_cal_t *c);
unsigned vh_drv_app_safety(vh_drv_app_t *a, int hold);
/* Runnables: the tick's inputs and one step of both filters; the payloads (packed, E2E-protected,
 * zeroed beforehand by the scheduler) of VEHEST_DrivelineEst and VEHEST_Status. */
void vh_drv_app_step(vh_drv_app_t *a, vh_app_ctx_t *ctx);
int vh_drv_app_fill_est(vh_drv_app_t *a, vh_app_ctx_t *ctx, uint8_t *data);
int vh_drv_app_fill_status(vh_drv_app_t *a, vh_app_ctx_t *ctx, uint8_t *data);
/* 1 when both wheel speeds are valid, fresh enough and below lim [rad/s]: the car stands still. */
int vh_drv_app_still(const vh_drv_app_t *a, double lim);

#endif /* VH_DRIVELINE_APP_H */
