/* vh_tireforce_app.h - the tyre-force ECU application (seed 000) on the chassis bus.
 *
 * RX: CHS_Sensors (length, E2E, extended-ID refusal, per-signal qualifier and SNA), timeout and
 * burst; each raw signal to the filter's Q format by an exact integer scaling (the DBC's scale as a
 * fraction, vh_ch_q.h: no double). Step: one fixed-point SKFMEC step per tick on the fresh sample (prediction only,
 * DEGRADED, without one), restarted after a timeout so that it re-seeds from live data. TX:
 * VEHEST_TireForceEst, VEHEST_ChassisStatus and VEHEST_TireForceAdaptive (SKFMEC-A, vh_tfa.h, stepped
 * after the SKFMEC on the same sample) at their DBC cycles, once the chassis bus has been
 * heard (a powertrain-only car sees no chassis frames), each estimate raw by an exact integer
 * scaling (the DBC's fraction, times the filter's scaling S for the states): raw frame to raw
 * frame, no double. Its own counters (VEHEST_ChassisStatus).
 *
 * CHS_RideHeight (where the car has ride-height sensors): the same RX checks into the same
 * counters; its four spring deflections go to SKFMEC-A's mass while the message has not timed out
 * and all four are valid. A car without them never sends it: not a fault, SKFMEC-A then has the
 * longitudinal balance alone. RxFaultActive bit 2: heard once, and now timed out or a channel invalid.
 *
 * Its configuration is the filters' fixed-point constants (skfq, tfaq: on a target, a calibration
 * block); on the host vh_tf_app_config_host derives them from the double configurations (skf, tfa).
 */
#ifndef VH_TIREFORCE_APP_H
#define VH_TIREFORCE_APP_H

#include "vh_app.h"
#include "vh_rx.h"
#include "vh_skf.h"
#include "vh_skfq.h"
#include "vh_tfa.h"
#include "vh_tfa_host.h"
#include "vh_tf_types.h"
#include "vh_types.h"

typedef struct {
    vh_skf_config_t skf;   /* host: the SKFMEC (seed 000), scaled = mec = 1; its ts the tick */
    vh_tfa_config_t tfa;   /* host: SKFMEC-A over it */
    vh_skfq_params_t skfq; /* the fixed-point SKFMEC's constants (vh_skfq_params_from_config of skf) */
    vh_tfa_params_t tfaq;  /* SKFMEC-A's (vh_tfa_params_from_config) */
} vh_tf_app_config_t;

/* The fixed-point SKFMEC's tuning (XCP): -> skf.prm.q, .r */
typedef struct {
    int32_t q[VH_SKFQ_NX]; /* process noise Q* (VH_SKFQ_FP) */
    int32_t r[VH_SKFQ_NY]; /* measurement noise R* (VH_SKFQ_FU) */
} vh_tf_app_cal_skf_t;

typedef struct {
    vh_tf_app_cal_skf_t skf;
} vh_tf_app_cal_t;

/* Tyre force (seed 000): last good CHS_Sensors sample, the fixed-point SKFMEC, its counters. */
typedef struct {
    int32_t u[VH_SKFQ_NU]; /* last good sample as vh_skfq_input_t: the raw signals in the filter's Q formats */
    uint16_t valid;        /* bit i: channel i of u valid */
    uint8_t heard;         /* a good CHS_Sensors frame has arrived since reset: the chassis bus is alive */
    vh_ecu_rxmsg_t rx;
    vh_skfq_t skf;         /* its integer constants (skf.prm: the configuration's skfq) */
    vh_tfa_t tfa;          /* SKFMEC-A over it (tfa.prm likewise) */
    int32_t ride[4];       /* last good CHS_RideHeight: spring deflections, Q.VH_TFA_FH [m] */
    uint8_t ride_valid;    /* all four channels of it valid */
    uint8_t ride_heard;    /* a good CHS_RideHeight has arrived since reset: the car has the sensors */
    vh_ecu_rxmsg_t ride_rx;
    vh_ecu_counters_t cnt;
    uint8_t tx_counter[3]; /* E2E counters: TireForceEst, ChassisStatus, TireForceAdaptive */
} vh_tf_app_t;

/* The application's entry points (vh_app.h). config_host (host only, vh_tireforce_app_host.c):
 * VH_EINVAL when skf.ts is not the tick or the constants do not fit. check: the filters' own
 * checks, and whether the filter's scaling S (s_num/s_den) times each state's DBC scale is a
 * fraction the integer TX can use (vh_ch_q.h ..._qs_ok). rx: CHS_Sensors and CHS_RideHeight. */
void vh_tf_app_config_default(vh_tf_app_config_t *cfg);
int vh_tf_app_config_host(vh_tf_app_config_t *cfg);
int vh_tf_app_check(const vh_tf_app_config_t *cfg);
void vh_tf_app_init(vh_tf_app_t *a, const vh_tf_app_config_t *cfg);
void vh_tf_app_reset(vh_tf_app_t *a);
void vh_tf_app_rx(vh_tf_app_t *a, vh_app_ctx_t *ctx, const vh_frame_t *f);
void vh_tf_app_cal_gather(const vh_tf_app_t *a, vh_tf_app_cal_t *c);
void vh_tf_app_cal_apply(vh_tf_app_t *a, const vh_tf_app_cal_t *c);
unsigned vh_tf_app_safety(vh_tf_app_t *a, int hold);
/* Runnables: once per tick RX timeout/burst and one filter step; the payloads of
 * VEHEST_TireForceEst, VEHEST_ChassisStatus and VEHEST_TireForceAdaptive, integer only (raw frame
 * out); 0 (send nothing) before the chassis bus is heard. */
void vh_tf_app_step(vh_tf_app_t *a, vh_app_ctx_t *ctx);
int vh_tf_app_fill_est(vh_tf_app_t *a, vh_app_ctx_t *ctx, uint8_t *data);
int vh_tf_app_fill_status(vh_tf_app_t *a, vh_app_ctx_t *ctx, uint8_t *data);
int vh_tf_app_fill_adaptive(vh_tf_app_t *a, vh_app_ctx_t *ctx, uint8_t *data);

#endif /* VH_TIREFORCE_APP_H */
