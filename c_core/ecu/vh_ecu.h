/* vh_ecu.h - the ECU firmware: a thin scheduler over the applications of each system.
 *
 * A pure function of frames and ticks: the caller hands in received frames (vh_ecu_rx) and then
 * calls vh_ecu_step once per 500 us tick, which returns the frames to transmit. No clock, no I/O,
 * no heap: deterministic and replayable from a log.
 *
 * vh_ecu_rx dispatches each frame by ID to the application that receives it (unknown IDs are
 * counted); vh_ecu_step runs a fixed table of runnables, each at its rate in ticks (the DBC
 * cycle time of the frame it sends). The applications own their RX checks, steps and TX:
 * driveline (vh_driveline_app.h, seed 001) and camber inspection (vh_camber_app.h, seed 002) on
 * the powertrain bus, tyre force (vh_tireforce_app.h, seed 000) and roll (vh_roll_app.h, seed 003)
 * on the chassis bus. Frame IDs
 * are unique across both DBCs, so frames are told apart by ID.
 */
#ifndef VH_ECU_H
#define VH_ECU_H

#include "vh_camber.h"
#include "vh_camber_app.h"
#include "vh_dkf.h"
#include "vh_driveline_app.h"
#include "vh_ecu_xcp.h"
#include "vh_roll_app.h"
#include "vh_rx.h"
#include "vh_secoc_bus.h"
#include "vh_skf.h"
#include "vh_tfa_host.h"
#include "vh_tireforce_app.h"
#include "vh_types.h"

#define VH_ECU_MAX_TX 12 /* the systems' 9 + SecOC's 2 sync frames + VH_ECU_XCP_MAX_TX */

typedef struct {
    vh_dkf_config_t dkf[VH_ECU_N_DKF]; /* ri is taken from gear_ratio[gear] at run time */
    double gear_ratio[VH_ECU_N_GEARS]; /* R_i per gear (w_o = R_i w_t); 0 = gear not usable */
    double we_min;                     /* engine speed below which eq. 9 is not used [rad/s] */
    vh_camber_config_t camber;         /* inspection window and acceptance (seed 002) */
    double camber_still_ww;            /* |wheel speed| below which the car counts as stationary [rad/s] */
    uint8_t rx_burst_frames;           /* burst limit per message and tick (VH_ECU_BURST_FRAMES); 0 = off,
                                          for transports that deliver in batches (UML's 100 Hz timer) */
    vh_skf_config_t skf;               /* tyre-force SKFMEC (seed 000), scaled = mec = 1; the ECU runs its
                                          fixed-point translation (vh_skfq_params_from_config) */
    vh_roll_app_config_t roll;         /* roll UKF + sliding-mode control (seed 003), float32 */
    vh_tfa_config_t tfa;               /* SKFMEC-A over it (vh_tfa_params_from_config) */
} vh_ecu_config_t;

typedef struct {
    vh_ecu_config_t cfg;
    vh_dkf_t dkf[VH_ECU_N_DKF]; /* the driveline filters (the application's, kept here for the host API) */
    vh_drv_app_t drv;
    vh_ecu_cis_t cis;
    vh_ecu_chs_t chs;
    vh_roll_app_t roll;         /* roll (seed 003): its own counters */
    vh_ecu_counters_t cnt;      /* the powertrain bus's counters (VEHEST_Status); chassis: chs.cnt */
    uint32_t tick;
    vh_ecu_xcp_t xcp;           /* the XCP slave (vh_ecu_xcp.h); off until vh_ecu_xcp_enable */
    vh_secoc_bus_t *secoc;      /* SecOC (vh_secoc_bus.h) as node VEHEST, NULL: off. Caller-owned, outside this
                                   struct: the keys stay out of the memory XCP may read. Its freshness survives
                                   vh_ecu_reset (a reset re-sends the sync frames) */
} vh_ecu_t;

/* Host side (vh_ecu_host.c, not flashed): the defaults, and init from a configuration whose
 * tyre-force part is translated into the fixed-point constants here (VH_EINVAL if it does not fit). */
void vh_ecu_config_default(vh_ecu_config_t *cfg);
int vh_ecu_init(vh_ecu_t *ecu, const vh_ecu_config_t *cfg);
/* The flashed init: the filter's constants come ready (on a target, a calibration block).
 * VH_OK, or VH_EINVAL for an invalid configuration or constants (nothing changed). */
int vh_ecu_init_params(vh_ecu_t *ecu, const vh_ecu_config_t *cfg, const vh_skfq_params_t *prm,
                       const vh_tfa_params_t *tprm);
void vh_ecu_reset(vh_ecu_t *ecu);
/* Hand in one received frame; checked and counted now, used at the next vh_ecu_step. With SecOC on, a
 * secured frame is verified first, here for every application; one that fails is counted
 * (cnt.secoc_reject, and by reason in secoc.cnt) and reaches none of them. */
void vh_ecu_rx(vh_ecu_t *ecu, const vh_frame_t *frame);
/* One 500 us tick. Writes up to cap frames to tx; returns how many (VH_ECU_MAX_TX is enough). */
size_t vh_ecu_step(vh_ecu_t *ecu, vh_frame_t *tx, size_t cap);
/* Load one device's calibration (seed 002 eq. 19); VH_EINVAL for a wheel index >= 4 or an invalid
 * calibration (the wheel then reports NOT_CALIBRATED). Survives vh_ecu_reset. */
int vh_ecu_set_camber_calibration(vh_ecu_t *ecu, unsigned wheel, const vh_camber_cal_t *cal);
/* The daemon's wall-clock scheduler reports ticks that started late; published in VEHEST_Status. */
void vh_ecu_note_deadline_miss(vh_ecu_t *ecu, uint32_t n);
/* SecOC on the ECU's frames: s keyed and started as node VEHEST (vh_secoc_bus_init, _set_key,
 * _start), or NULL: off (the default). Survives vh_ecu_reset. */
void vh_ecu_set_secoc(vh_ecu_t *ecu, vh_secoc_bus_t *s);

/* XCP (vh_ecu_xcp.c). Enable the slave on the ECU as configured now (its tuning becomes the
 * reference page); survives vh_ecu_reset, which keeps the calibration. VH_EINVAL: bad config or
 * no key. */
int vh_ecu_xcp_enable(vh_ecu_t *ecu, const vh_ecu_xcp_config_t *cfg);
/* The tuning block of the ECU as configured / into the configuration and the running filters. */
void vh_ecu_cal_gather(const vh_ecu_t *ecu, vh_ecu_cal_t *cal);
void vh_ecu_cal_apply(vh_ecu_t *ecu, const vh_ecu_cal_t *cal);
/* The scheduler's hooks: a frame on the CRO or DTO identifier (1 if it was one), the tick boundary, an event channel,
 * and the XCP frames after the systems' TX (returns the new count). */
int vh_ecu_xcp_rx(vh_ecu_t *ecu, const vh_frame_t *f);
/* A frame heard on the XCP bus of its own (own_bus): its CRO reaches the slave; nothing else there
 * is input of the ECU (1 if it was the CRO or DTO identifier). */
int vh_ecu_xcp_rx_own(vh_ecu_t *ecu, const vh_frame_t *f);
void vh_ecu_xcp_tick(vh_ecu_t *ecu);
void vh_ecu_xcp_event(vh_ecu_t *ecu, uint16_t channel);
size_t vh_ecu_xcp_tx(vh_ecu_t *ecu, vh_frame_t *tx, size_t n, size_t cap);

#endif /* VH_ECU_H */
