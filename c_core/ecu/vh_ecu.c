/* vh_ecu.c - the ECU scheduler: dispatch by frame ID, the runnable table, the counters. */
#include <string.h>

#include "vh_ch.h"
#include "vh_ch_meta.h"
#include "vh_ecu.h"
#include "vh_pt.h"
#include "vh_pt_meta.h"

/* Ticks per cycle of a message; the meta headers refuse a cycle that is not whole ticks. */
#define TICKS(cycle_us) ((cycle_us) / VH_TICK_US)
/* room in a tick's TX for the XCP frames (vh_ecu_xcp_tx) beside the systems' nine */
typedef char vh_ecu_tx_room_check[(VH_ECU_MAX_TX >= 9 + 2 + VH_ECU_XCP_MAX_TX) ? 1 : -1];

int vh_ecu_init_params(vh_ecu_t *ecu, const vh_ecu_config_t *cfg, const vh_skfq_params_t *prm,
                       const vh_tfa_params_t *tprm)
{
    vh_skfq_t qprobe; /* vh_skfq_init's own checks, on a scratch instance */
    if (vh_drv_app_check(cfg->gear_ratio, cfg->we_min, cfg->dkf) != VH_OK ||
        vh_cmb_app_check(&cfg->camber, cfg->camber_still_ww) != VH_OK || vh_skfq_init(&qprobe, prm) != VH_OK ||
        !vh_tf_app_check(prm, tprm) || vh_roll_app_check(&cfg->roll) != VH_OK) {
        return VH_EINVAL;
    }
    memset(ecu, 0, sizeof *ecu); /* SecOC off */
    ecu->cfg = *cfg;
    ecu->chs.skf.prm = *prm; /* the filter keeps its constants; vh_ecu_reset re-initialises from them */
    ecu->chs.tfa.prm = *tprm;
    vh_ecu_reset(ecu);
    return VH_OK;
}

void vh_ecu_reset(vh_ecu_t *ecu)
{
    int i;
    for (i = 0; i < VH_ECU_N_DKF; ++i) {
        (void)vh_dkf_init(&ecu->dkf[i], &ecu->cfg.dkf[i]); /* validated in vh_ecu_init */
    }
    vh_drv_app_reset(&ecu->drv, ecu->cfg.dkf, ecu->cfg.gear_ratio);
    vh_cmb_app_reset(&ecu->cis, &ecu->cfg.camber);
    vh_tf_app_reset(&ecu->chs);
    vh_roll_app_reset(&ecu->roll, &ecu->cfg.roll);
    memset(&ecu->cnt, 0, sizeof ecu->cnt);
    ecu->tick = 0u;
    if (ecu->secoc != NULL) {
        vh_secoc_bus_resync(ecu->secoc);
    }
}

int vh_ecu_set_camber_calibration(vh_ecu_t *ecu, unsigned wheel, const vh_camber_cal_t *cal)
{
    return vh_cmb_app_set_calibration(&ecu->cis, wheel, cal);
}

/* ---- RX: dispatch by frame ID ---- */

static void rx_dls(vh_ecu_t *ecu, const vh_frame_t *f) { vh_drv_app_rx(&ecu->drv, ecu->cfg.gear_ratio, &ecu->cnt, f); }
static void rx_chs(vh_ecu_t *ecu, const vh_frame_t *f)
{
    vh_tf_app_rx(&ecu->chs, f);
    vh_roll_app_rx(&ecu->roll, &ecu->cfg.roll, f); /* steer and wheel speeds: the roll UKF's inputs */
}
static void rx_chs_ride(vh_ecu_t *ecu, const vh_frame_t *f) { vh_tf_app_rx_ride(&ecu->chs, f); }
static void rx_roll(vh_ecu_t *ecu, const vh_frame_t *f) { vh_roll_app_rx(&ecu->roll, &ecu->cfg.roll, f); }
static void rx_cis(vh_ecu_t *ecu, const vh_frame_t *f) { vh_cmb_app_rx(&ecu->cis, &ecu->cnt, f); }

static const struct {
    uint32_t id;
    void (*rx)(vh_ecu_t *ecu, const vh_frame_t *f);
} RX_TABLE[] = {
    {VH_PT_DLS_SENSORS_FRAME_ID, rx_dls},
    {VH_CH_CHS_SENSORS_FRAME_ID, rx_chs},
    {VH_CH_CHS_RIDE_HEIGHT_FRAME_ID, rx_chs_ride},
    {VH_PT_CIS_ACCEL_FRAME_ID, rx_cis},
    {VH_CH_ROLL_SENSORS_FRAME_ID, rx_roll},
    {VH_CH_ROLL_YAW_RATE_FRAME_ID, rx_roll},
    {VH_CH_ROLL_ACTUATOR_STATUS_FRAME_ID, rx_roll},
    {VH_CH_ROLL_MODE_CMD_FRAME_ID, rx_roll},
};

void vh_ecu_rx(vh_ecu_t *ecu, const vh_frame_t *frame)
{
    size_t i;
    vh_frame_t verified;
    /* SecOC before any application sees the frame: a rejected one is counted, a sync frame is its own */
    const vh_secoc_bus_result_t sr = ecu->secoc != NULL ? vh_secoc_bus_rx(ecu->secoc, frame, &verified) : VH_SECOC_BUS_PASS;
    if (sr == VH_SECOC_BUS_REJECTED) {
        vh_rx_count(&ecu->cnt.secoc_reject);
    }
    if (sr != VH_SECOC_BUS_PASS && sr != VH_SECOC_BUS_OK) {
        return;
    }
    frame = sr == VH_SECOC_BUS_OK ? &verified : frame;
    for (i = 0; i < sizeof RX_TABLE / sizeof RX_TABLE[0]; ++i) {
        if (RX_TABLE[i].id == frame->id) {
            RX_TABLE[i].rx(ecu, frame);
            return;
        }
    }
    /* a known frame that is not the ECU's input (its own TX, the lockstep sync, SecOC sync frames
     * when SecOC is off); the XCP CRO identifier is configuration, not in the DBC */
    if (!VH_PT_KNOWN_ID(frame->id) && !VH_CH_KNOWN_ID(frame->id) && !vh_ecu_xcp_rx(ecu, frame)) {
        vh_rx_count(&ecu->cnt.unknown_id);
    }
}

/* ---- runnables: each system's step every tick, each TX frame at its DBC cycle ---- */

static void drv_step(vh_ecu_t *ecu)
{
    vh_drv_app_step(&ecu->drv, ecu->dkf, ecu->cfg.we_min, &ecu->cnt, ecu->cfg.rx_burst_frames);
}
/* camber after the driveline: "stationary" is this tick's wheel-speed reading */
static void cmb_step(vh_ecu_t *ecu)
{
    vh_cmb_app_step(&ecu->cis, vh_drv_app_still(&ecu->drv, ecu->cfg.camber_still_ww), &ecu->cnt,
                    ecu->cfg.rx_burst_frames);
}
static void tf_step(vh_ecu_t *ecu) { vh_tf_app_step(&ecu->chs, ecu->cfg.rx_burst_frames); }

static int drv_est(vh_ecu_t *ecu, uint8_t *d) { return vh_drv_app_fill_est(&ecu->drv, ecu->dkf, d); }
static int drv_status(vh_ecu_t *ecu, uint8_t *d)
{
    return vh_drv_app_fill_status(&ecu->drv, ecu->dkf, &ecu->cnt, ecu->tick, d);
}
static int cmb_tx(vh_ecu_t *ecu, uint8_t *d) { return vh_cmb_app_fill(&ecu->cis, d); }
static int tf_est(vh_ecu_t *ecu, uint8_t *d) { return vh_tf_app_fill_est(&ecu->chs, d); }
static int tf_status(vh_ecu_t *ecu, uint8_t *d) { return vh_tf_app_fill_status(&ecu->chs, d); }
static int tf_adaptive(vh_ecu_t *ecu, uint8_t *d) { return vh_tf_app_fill_adaptive(&ecu->chs, d); }
static void roll_tick(vh_ecu_t *ecu) { vh_roll_app_tick(&ecu->roll, ecu->cfg.rx_burst_frames); }
static void roll_step(vh_ecu_t *ecu) { vh_roll_app_step(&ecu->roll); }
static int roll_cmd(vh_ecu_t *ecu, uint8_t *d) { return vh_roll_app_fill_cmd(&ecu->roll, d); }
static int roll_est(vh_ecu_t *ecu, uint8_t *d) { return vh_roll_app_fill_est(&ecu->roll, d); }
/* XCP: calibration reaches the systems at the tick boundary, before any of them steps; DAQ
 * samples after all of them, on the event channels 0 (tick), 1 (1 ms), 2 (10 ms) */
static void xcp_ev_tick(vh_ecu_t *ecu) { vh_ecu_xcp_event(ecu, 0u); }
static void xcp_ev_1ms(vh_ecu_t *ecu) { vh_ecu_xcp_event(ecu, 1u); }
static void xcp_ev_10ms(vh_ecu_t *ecu) { vh_ecu_xcp_event(ecu, 2u); }

/* A step (step != NULL) or a TX frame (fill: its payload; 0 = nothing to send this time), run in
 * this order every period_ticks ticks (at tick 0, then each multiple). */
#define TX(fill, MSG) NULL, fill, MSG##_FRAME_ID, MSG##_LENGTH, MSG##_IS_FD, TICKS(MSG##_CYCLE_TIME_US)
static const struct {
    void (*step)(vh_ecu_t *ecu);
    int (*fill)(vh_ecu_t *ecu, uint8_t *data);
    uint32_t id;
    uint8_t len, is_fd;
    uint32_t period_ticks;
} RUNNABLES[] = {
    {vh_ecu_xcp_tick, NULL, 0u, 0u, 0u, 1u},
    {drv_step, NULL, 0u, 0u, 0u, 1u},
    {TX(drv_est, VH_PT_VEHEST_DRIVELINE_EST)},
    {TX(drv_status, VH_PT_VEHEST_STATUS)},
    {cmb_step, NULL, 0u, 0u, 0u, 1u},
    {TX(cmb_tx, VH_PT_VEHEST_CAMBER)},
    {tf_step, NULL, 0u, 0u, 0u, 1u},
    {TX(tf_est, VH_CH_VEHEST_TIRE_FORCE_EST)},
    {TX(tf_status, VH_CH_VEHEST_CHASSIS_STATUS)},
    {TX(tf_adaptive, VH_CH_VEHEST_TIRE_FORCE_ADAPTIVE)},
    /* roll: RX ages every tick; UKF + SMC on each ROLL_Sensors frame (every 5 ms: its 30-45 us stay
     * out of 9 ticks in 10), the command in the same tick (checked every tick, sent after a step) */
    {roll_tick, NULL, 0u, 0u, 0u, 1u},
    {roll_step, NULL, 0u, 0u, 0u, 1u},
    {NULL, roll_cmd, VH_CH_VEHEST_ROLL_CMD_FRAME_ID, VH_CH_VEHEST_ROLL_CMD_LENGTH, VH_CH_VEHEST_ROLL_CMD_IS_FD, 1u},
    {TX(roll_est, VH_CH_VEHEST_ROLL_EST)},
    {xcp_ev_tick, NULL, 0u, 0u, 0u, 1u},
    {xcp_ev_1ms, NULL, 0u, 0u, 0u, TICKS(1000u)},
    {xcp_ev_10ms, NULL, 0u, 0u, 0u, TICKS(10000u)},
};

size_t vh_ecu_step(vh_ecu_t *ecu, vh_frame_t *tx, size_t cap)
{
    size_t i, n = 0u;
    for (i = 0; i < sizeof RUNNABLES / sizeof RUNNABLES[0]; ++i) {
        if (ecu->tick % RUNNABLES[i].period_ticks != 0u) {
            continue;
        }
        if (RUNNABLES[i].step != NULL) {
            RUNNABLES[i].step(ecu);
        } else {
            vh_frame_t *f = vh_tx_slot(tx, &n, cap, RUNNABLES[i].id, RUNNABLES[i].len, RUNNABLES[i].is_fd);
            if (f != NULL && !RUNNABLES[i].fill(ecu, f->data)) {
                --n; /* nothing to send: the slot is free again */
            }
        }
    }
    if (ecu->secoc != NULL) { /* the systems' frames secured, sync frames when due */
        n = vh_secoc_bus_tx(ecu->secoc, tx, n, cap);
    }
    n = vh_ecu_xcp_tx(ecu, tx, n, cap);
    ++ecu->tick;
    return n;
}

void vh_ecu_set_secoc(vh_ecu_t *ecu, vh_secoc_bus_t *s) { ecu->secoc = s; }

void vh_ecu_note_deadline_miss(vh_ecu_t *ecu, uint32_t n)
{
    ecu->cnt.deadline_miss = (uint16_t)(ecu->cnt.deadline_miss + n); /* modulo 2^16, like every counter */
}
