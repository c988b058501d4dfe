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
 */
#ifndef VH_TIREFORCE_APP_H
#define VH_TIREFORCE_APP_H

#include "vh_rx.h"
#include "vh_skfq.h"
#include "vh_tfa.h"
#include "vh_tf_types.h"
#include "vh_types.h"

/* Chassis side (seed 000): last good CHS_Sensors sample, the fixed-point SKFMEC, its counters. */
typedef struct {
    int32_t u[VH_SKFQ_NU]; /* last good sample as vh_skfq_input_t: the raw signals in the filter's Q formats */
    uint16_t valid;        /* bit i: channel i of u valid */
    uint8_t heard;         /* a good CHS_Sensors frame has arrived since reset: the chassis bus is alive */
    vh_ecu_rxmsg_t rx;
    vh_skfq_t skf;         /* its integer constants (skf.prm) are set once, at vh_ecu_init */
    vh_tfa_t tfa;          /* SKFMEC-A over it (tfa.prm likewise) */
    int32_t ride[4];       /* last good CHS_RideHeight: spring deflections, Q.VH_TFA_FH [m] */
    uint8_t ride_valid;    /* all four channels of it valid */
    uint8_t ride_heard;    /* a good CHS_RideHeight has arrived since reset: the car has the sensors */
    vh_ecu_rxmsg_t ride_rx;
    vh_ecu_counters_t cnt;
    uint8_t tx_counter[3]; /* E2E counters: TireForceEst, ChassisStatus, TireForceAdaptive */
} vh_ecu_chs_t;

/* Restart from the filter's constants (kept in c->skf.prm). */
void vh_tf_app_reset(vh_ecu_chs_t *c);
/* One received CHS_Sensors frame, checked and counted. */
void vh_tf_app_rx(vh_ecu_chs_t *c, const vh_frame_t *f);
/* One received CHS_RideHeight frame, checked and counted. */
void vh_tf_app_rx_ride(vh_ecu_chs_t *c, const vh_frame_t *f);
/* Once per tick: RX timeout/burst and one filter step. */
void vh_tf_app_step(vh_ecu_chs_t *c, unsigned burst_limit);
/* 1 if the filter's scaling S (prm->s_num/s_den) times each state's DBC scale is a fraction the
 * integer TX can use (vh_ch_q.h ..._qs_ok), else 0: checked once, at vh_ecu_init. */
int vh_tf_app_check(const vh_skfq_params_t *prm, const vh_tfa_params_t *tprm);
/* The payloads of VEHEST_TireForceEst and VEHEST_ChassisStatus, integer only (raw frame out);
 * 0 (send nothing) before the chassis bus is heard. */
int vh_tf_app_fill_est(vh_ecu_chs_t *c, uint8_t *data);
int vh_tf_app_fill_status(vh_ecu_chs_t *c, uint8_t *data);
/* The payload of VEHEST_TireForceAdaptive (SKFMEC-A: forces, mass, its std, its health), integer only. */
int vh_tf_app_fill_adaptive(vh_ecu_chs_t *c, uint8_t *data);

#endif /* VH_TIREFORCE_APP_H */
