/* vh_ecu.h - the ECU firmware: RX checks, the 2 kHz estimator tasks, TX, as one fixed-step tick.
 *
 * A pure function of frames and ticks: the caller hands in received frames (vh_ecu_rx) and then
 * calls vh_ecu_step once per 500 us tick, which returns the frames to transmit. No clock, no I/O,
 * no heap: deterministic and replayable from a log.
 *
 * RX checks per message (from the DBC): length, E2E P01 CRC and alive counter, qualifier bits and
 * SNA values per signal, timeout after RxTimeoutCycles cycles without a good frame. Inputs keep their
 * last good value (zero-order hold) for the turbine torque input; the filters' measurement update
 * uses only samples that arrived fresh since the previous tick.
 *
 * Two buses, one tick: the powertrain bus (vehest_pt.dbc: driveline filters, camber inspection)
 * and the chassis bus (vehest_ch.dbc: the fixed-point SKFMEC of seed 000, a step per tick on each
 * fresh CHS_Sensors sample). Frame IDs are unique across both DBCs, so frames are told apart by
 * ID; the chassis side transmits only once CHS_Sensors has been heard (a powertrain-only car sees
 * no chassis frames), and has its own counters in VEHEST_ChassisStatus.
 */
#ifndef VH_ECU_H
#define VH_ECU_H

#include "vh_camber.h"
#include "vh_dkf.h"
#include "vh_e2e.h"
#include "vh_skf.h"
#include "vh_skfq.h"
#include "vh_types.h"

/* The two driveline filters: T = speeds + torque transducer, S = speeds only. */
enum { VH_ECU_DKF_T = 0, VH_ECU_DKF_S = 1, VH_ECU_N_DKF = 2 };
#define VH_ECU_MAX_TX 6
#define VH_ECU_N_GEARS 6 /* index = GearEngaged 1..5; 0 = neutral */
#define VH_ECU_N_WHEELS 4 /* camber inspection devices: FL, FR, RL, RR */
#define VH_ECU_CAMBER_NO_RESULT 7u /* CamberReason SNA: no window completed yet */

typedef struct {
    vh_dkf_config_t dkf[VH_ECU_N_DKF]; /* ri is taken from gear_ratio[gear] at run time */
    double gear_ratio[VH_ECU_N_GEARS]; /* R_i per gear (w_o = R_i w_t); 0 = gear not usable */
    double we_min;                     /* engine speed below which eq. 9 is not used [rad/s] */
    uint16_t status_period_ticks;      /* VEHEST_Status every N ticks (20 = 10 ms) */
    vh_camber_config_t camber;         /* inspection window and acceptance (seed 002) */
    double camber_still_ww;            /* |wheel speed| below which the car counts as stationary [rad/s] */
    uint8_t rx_burst_frames;           /* burst limit per message and tick (VH_ECU_BURST_FRAMES); 0 = off,
                                          for transports that deliver in batches (UML's 100 Hz timer) */
    vh_skf_config_t skf;               /* tyre-force SKFMEC (seed 000), scaled = mec = 1; the ECU runs its
                                          fixed-point translation (vh_skfq_params_from_config) */
} vh_ecu_config_t;

/* Saturating fault counters (uint16, as on the bus). */
typedef struct {
    uint16_t crc_error;
    uint16_t counter_repeat;
    uint16_t counter_skip;
    uint16_t dlc_error;
    uint16_t timeout;
    uint16_t unknown_id;
    uint16_t signal_invalid;
    uint16_t input_invalid;
    uint16_t filter_reset;
    uint16_t deadline_miss;
    uint16_t rx_burst;
    uint16_t saturation; /* fixed-point SKFMEC steps that saturated (chassis only) */
} vh_ecu_counters_t;

/* Reception state of one cyclic message: E2E, freshness, timeout. */
typedef struct {
    vh_e2e_rx_t e2e;
    uint16_t age;      /* ticks since the last good frame */
    uint16_t resync;   /* ticks until the data is trusted again after a burst */
    uint8_t fresh;     /* a good frame arrived since the last tick */
    uint8_t n_tick;    /* good frames since the last tick */
    uint8_t timed_out; /* no good frame for the message's timeout (set at start) */
} vh_ecu_rxmsg_t;

/* Default burst limit: more good frames of one message in a tick than this is a burst (a sender's
 * transmit queue draining after the bus was blocked, i.e. samples that may be far older than they
 * look: their CRC and counters are fine). Two allows one late frame plus the on-time one. */
#define VH_ECU_BURST_FRAMES 2u

/* Last good driveline sensor sample (physical units) with per-signal validity. */
typedef struct {
    double wo, wwl, wwr, to, we, wt;
    uint8_t valid;   /* bit i: signal i valid (order as above) */
    uint8_t gear;    /* 0..14, 15 = SNA */
    vh_ecu_rxmsg_t rx;
} vh_ecu_dls_t;

/* Camber inspection: last raw sample per device and the running windows. */
typedef struct {
    int16_t raw[VH_ECU_N_WHEELS][3];
    uint8_t present;  /* bit i: device i sampling */
    vh_ecu_rxmsg_t rx;
    vh_camber_t cmb[VH_ECU_N_WHEELS];
    vh_camber_result_t last[VH_ECU_N_WHEELS];
    uint8_t have[VH_ECU_N_WHEELS]; /* a window completed since reset */
} vh_ecu_cis_t;

/* Chassis side (seed 000): last good CHS_Sensors sample, the fixed-point SKFMEC, its counters. */
typedef struct {
    double u[VH_SKF_NU];  /* last good sample in vh_skf_input_t order (physical units) */
    uint16_t valid;       /* bit i: channel i of u valid */
    uint8_t heard;        /* a good CHS_Sensors frame has arrived since reset: the chassis bus is alive */
    vh_ecu_rxmsg_t rx;
    vh_skfq_t skf;        /* its integer constants (skf.prm) come from cfg.skf in vh_ecu_init */
    vh_ecu_counters_t cnt;
} vh_ecu_chs_t;

typedef struct {
    vh_ecu_config_t cfg;
    vh_dkf_t dkf[VH_ECU_N_DKF];
    vh_ecu_dls_t dls;
    vh_ecu_cis_t cis;
    vh_ecu_chs_t chs;
    vh_ecu_counters_t cnt;
    double ti;        /* last turbine torque input (eq. 9) */
    uint8_t ti_valid;
    uint8_t gear;     /* gear the filters are discretised for */
    uint32_t tick;
    uint8_t tx_counter[5]; /* E2E counters: DrivelineEst, Status, Camber, TireForceEst, ChassisStatus */
} vh_ecu_t;

void vh_ecu_config_default(vh_ecu_config_t *cfg);
int vh_ecu_init(vh_ecu_t *ecu, const vh_ecu_config_t *cfg);
void vh_ecu_reset(vh_ecu_t *ecu);
/* Hand in one received frame; checked and counted now, used at the next vh_ecu_step. */
void vh_ecu_rx(vh_ecu_t *ecu, const vh_frame_t *frame);
/* One 500 us tick. Writes up to cap frames to tx; returns how many (VH_ECU_MAX_TX is enough). */
size_t vh_ecu_step(vh_ecu_t *ecu, vh_frame_t *tx, size_t cap);
/* Load one device's calibration (seed 002 eq. 19); VH_EINVAL for a wheel index >= 4 or an invalid
 * calibration (the wheel then reports NOT_CALIBRATED). Survives vh_ecu_reset. */
int vh_ecu_set_camber_calibration(vh_ecu_t *ecu, unsigned wheel, const vh_camber_cal_t *cal);
/* The daemon's wall-clock scheduler reports ticks that started late; published in VEHEST_Status. */
void vh_ecu_note_deadline_miss(vh_ecu_t *ecu, uint32_t n);

#endif /* VH_ECU_H */
