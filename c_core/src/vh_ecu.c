/* vh_ecu.c - the ECU tick: RX checks, driveline filters, TX. See vh_ecu.h. */
#include <math.h>
#include <stdbool.h>
#include <string.h>

#include "vh_ch.h"
#include "vh_ch_meta.h"
#include "vh_ecu.h"
#include "vh_pt.h"
#include "vh_pt_meta.h"

/* Signal order of vh_ecu_dls_t.valid */
enum { SIG_WO = 0, SIG_WWL, SIG_WWR, SIG_TO, SIG_WE, SIG_WT, N_SIG };
#define GEAR_SNA 15u
/* RX timeouts in ticks: RxTimeoutCycles of the DBC times the cycle time */
#define DLS_TIMEOUT_TICKS (VH_PT_DLS_SENSORS_RX_TIMEOUT_CYCLES * (VH_PT_DLS_SENSORS_CYCLE_TIME_US / VH_TICK_US))
#define CIS_TIMEOUT_TICKS (VH_PT_CIS_ACCEL_RX_TIMEOUT_CYCLES * (VH_PT_CIS_ACCEL_CYCLE_TIME_US / VH_TICK_US))
#define CAMBER_PERIOD_TICKS (VH_PT_VEHEST_CAMBER_CYCLE_TIME_US / VH_TICK_US)
#define CHS_TIMEOUT_TICKS (VH_CH_CHS_SENSORS_RX_TIMEOUT_CYCLES * (VH_CH_CHS_SENSORS_CYCLE_TIME_US / VH_TICK_US))
#define TFE_PERIOD_TICKS (VH_CH_VEHEST_TIRE_FORCE_EST_CYCLE_TIME_US / VH_TICK_US)
#define CST_PERIOD_TICKS (VH_CH_VEHEST_CHASSIS_STATUS_CYCLE_TIME_US / VH_TICK_US)
#define CHS_ALL_INPUTS 0x1FF0u /* channels 4..12 of vh_skf_input_t: steer, wheel speeds, torques */

static void inc(uint16_t *c)
{
    if (*c < UINT16_MAX) {
        ++*c;
    }
}

void vh_ecu_config_default(vh_ecu_config_t *cfg)
{
    memset(cfg, 0, sizeof *cfg);
    vh_dkf_config_default(&cfg->dkf[VH_ECU_DKF_T], VH_DKF_SPEEDS_TORQUE);
    vh_dkf_config_default(&cfg->dkf[VH_ECU_DKF_S], VH_DKF_SPEEDS);
    /* w_o = R_i w_t; 2nd gear = 0.43 (Table 1), the others a typical 5-speed transaxle */
    cfg->gear_ratio[1] = 0.28;
    cfg->gear_ratio[2] = 0.43;
    cfg->gear_ratio[3] = 0.66;
    cfg->gear_ratio[4] = 0.91;
    cfg->gear_ratio[5] = 1.18;
    cfg->we_min = 40.0; /* well below idle (~80 rad/s): an engine this slow is stalling */
    cfg->status_period_ticks = (uint16_t)(VH_PT_VEHEST_STATUS_CYCLE_TIME_US / VH_TICK_US);
    vh_camber_config_default(&cfg->camber);
    cfg->camber_still_ww = 0.5; /* 0.15 m/s at the wheel: parked, not rolling */
    cfg->rx_burst_frames = VH_ECU_BURST_FRAMES;
    vh_skf_config_default(&cfg->skf, VH_SKF_SKFMEC);
}

int vh_ecu_init(vh_ecu_t *ecu, const vh_ecu_config_t *cfg)
{
    int i;
    vh_dkf_t probe;
    vh_camber_t cprobe;
    vh_skfq_params_t prm;
    vh_skfq_t qprobe;
    if (cfg->status_period_ticks == 0u || !(cfg->we_min > 0.0) || !isfinite(cfg->we_min) ||
        !(cfg->camber_still_ww >= 0.0) || !isfinite(cfg->camber_still_ww) ||
        vh_camber_init(&cprobe, &cfg->camber, NULL) != VH_OK) {
        return VH_EINVAL;
    }
    for (i = 1; i < VH_ECU_N_GEARS; ++i) {
        if (!(cfg->gear_ratio[i] >= 0.0) || !isfinite(cfg->gear_ratio[i])) {
            return VH_EINVAL;
        }
    }
    for (i = 0; i < VH_ECU_N_DKF; ++i) {
        if (vh_dkf_init(&probe, &cfg->dkf[i]) != VH_OK) {
            return VH_EINVAL;
        }
    }
    /* the SKFMEC steps once per tick on the 500 us CHS_Sensors samples */
    if (fabs(cfg->skf.ts - VH_TICK_US * 1e-6) > 1e-12 || vh_skfq_params_from_config(&cfg->skf, &prm) != VH_OK ||
        vh_skfq_init(&qprobe, &prm) != VH_OK) {
        return VH_EINVAL;
    }
    memset(ecu, 0, sizeof *ecu);
    ecu->cfg = *cfg;
    ecu->chs.skf.prm = prm; /* the filter keeps its constants; vh_ecu_reset re-initialises from them */
    vh_ecu_reset(ecu);
    return VH_OK;
}

static void rxmsg_init(vh_ecu_rxmsg_t *m)
{
    vh_e2e_rx_init(&m->e2e);
    m->age = 0u;
    m->fresh = 0u;
    m->timed_out = 1u; /* nothing received yet: not a fault, so not counted */
}

void vh_ecu_reset(vh_ecu_t *ecu)
{
    int i;
    const vh_ecu_config_t cfg = ecu->cfg;
    const vh_skfq_params_t prm = ecu->chs.skf.prm;
    vh_camber_cal_t cal[VH_ECU_N_WHEELS]; /* calibrations are data, not state: they survive */
    for (i = 0; i < VH_ECU_N_WHEELS; ++i) {
        cal[i] = ecu->cis.cmb[i].cal;
    }
    memset(ecu, 0, sizeof *ecu);
    ecu->cfg = cfg;
    for (i = 0; i < VH_ECU_N_DKF; ++i) {
        (void)vh_dkf_init(&ecu->dkf[i], &cfg.dkf[i]); /* validated in vh_ecu_init */
    }
    for (i = 0; i < VH_ECU_N_WHEELS; ++i) {
        (void)vh_camber_init(&ecu->cis.cmb[i], &cfg.camber, cal[i].valid ? &cal[i] : NULL);
    }
    ecu->gear = 0u;
    ecu->dls.gear = GEAR_SNA;
    rxmsg_init(&ecu->dls.rx);
    rxmsg_init(&ecu->cis.rx);
    rxmsg_init(&ecu->chs.rx);
    (void)vh_skfq_init(&ecu->chs.skf, &prm); /* validated in vh_ecu_init */
}

int vh_ecu_set_camber_calibration(vh_ecu_t *ecu, unsigned wheel, const vh_camber_cal_t *cal)
{
    if (wheel >= VH_ECU_N_WHEELS) {
        return VH_EINVAL;
    }
    ecu->cis.have[wheel] = 0u;
    return vh_camber_set_calibration(&ecu->cis.cmb[wheel], cal);
}

static int known_id(uint32_t id)
{
    return id == VH_PT_DLS_SENSORS_FRAME_ID || id == VH_PT_VEHEST_DRIVELINE_EST_FRAME_ID ||
           id == VH_PT_VEHEST_STATUS_FRAME_ID || id == VH_PT_SIM_SYNC_FRAME_ID ||
           id == VH_PT_VEHEST_SYNC_ACK_FRAME_ID || id == VH_PT_CIS_ACCEL_FRAME_ID ||
           id == VH_PT_VEHEST_CAMBER_FRAME_ID || id == VH_CH_CHS_SENSORS_FRAME_ID ||
           id == VH_CH_VEHEST_TIRE_FORCE_EST_FRAME_ID || id == VH_CH_VEHEST_CHASSIS_STATUS_FRAME_ID;
}

/* One speed/torque signal: raw SNA value or a cleared qualifier makes it invalid. */
static int take(vh_ecu_t *ecu, int ok, double value, double *dst, int sig)
{
    if (!ok) {
        inc(&ecu->cnt.signal_invalid);
        ecu->dls.valid &= (uint8_t)~(1u << sig);
        return 0;
    }
    *dst = value;
    ecu->dls.valid |= (uint8_t)(1u << sig);
    return 1;
}

/* Length and E2E checks of one received frame, counted; 1 if its data may be used. */
static int rx_accept(vh_ecu_counters_t *cnt, vh_ecu_rxmsg_t *m, const vh_frame_t *f, size_t len, uint16_t data_id)
{
    if (f->len != len) {
        inc(&cnt->dlc_error);
        return 0;
    }
    switch (vh_e2e_p01_check(&m->e2e, f->data, f->len, data_id)) {
    case VH_E2E_OK:
    case VH_E2E_INITIAL:
        break;
    case VH_E2E_SKIPPED: /* frames were lost, but this one is good */
        inc(&cnt->counter_skip);
        break;
    case VH_E2E_REPEATED:
        inc(&cnt->counter_repeat);
        return 0;
    case VH_E2E_WRONG_CRC:
    case VH_E2E_BAD_LEN:
    default:
        inc(&cnt->crc_error);
        return 0;
    }
    m->fresh = 1u;
    if (m->n_tick < UINT8_MAX) {
        ++m->n_tick;
    }
    return 1;
}

/* Once per tick: age, timeout (counted on entry), cleared by a fresh frame; a burst makes the
 * message untrusted (not fresh) until it has been regular for its timeout. Returns 1 when the
 * frames of this tick may be used. */
static int rx_tick(const vh_ecu_t *ecu, vh_ecu_counters_t *cnt, vh_ecu_rxmsg_t *m, unsigned timeout_ticks)
{
    if (ecu->cfg.rx_burst_frames != 0u && m->n_tick > ecu->cfg.rx_burst_frames) {
        m->resync = (uint16_t)timeout_ticks;
        inc(&cnt->rx_burst);
    } else if (m->resync > 0u) {
        --m->resync;
    }
    m->n_tick = 0u;
    if (m->fresh) {
        m->age = 0u;
        m->timed_out = 0u;
    } else if (m->age < UINT16_MAX) {
        ++m->age;
    }
    if (!m->timed_out && m->age >= timeout_ticks) {
        m->timed_out = 1u;
        inc(&cnt->timeout);
    }
    return m->resync == 0u;
}

static void rx_cis(vh_ecu_t *ecu, const vh_frame_t *f)
{
    struct vh_pt_cis_accel_t m;
    vh_ecu_cis_t *c = &ecu->cis;
    if (!rx_accept(&ecu->cnt, &c->rx, f, VH_PT_CIS_ACCEL_LENGTH, VH_PT_CIS_ACCEL_E2E_DATA_ID)) {
        return;
    }
    (void)vh_pt_cis_accel_unpack(&m, f->data, f->len);
    c->raw[0][0] = m.cis_acc_x_fl; c->raw[0][1] = m.cis_acc_y_fl; c->raw[0][2] = m.cis_acc_z_fl;
    c->raw[1][0] = m.cis_acc_x_fr; c->raw[1][1] = m.cis_acc_y_fr; c->raw[1][2] = m.cis_acc_z_fr;
    c->raw[2][0] = m.cis_acc_x_rl; c->raw[2][1] = m.cis_acc_y_rl; c->raw[2][2] = m.cis_acc_z_rl;
    c->raw[3][0] = m.cis_acc_x_rr; c->raw[3][1] = m.cis_acc_y_rr; c->raw[3][2] = m.cis_acc_z_rr;
    c->present = m.cis_present;
}

static void rx_dls(vh_ecu_t *ecu, const vh_frame_t *f)
{
    struct vh_pt_dls_sensors_t m;
    vh_ecu_dls_t *d = &ecu->dls;
    if ((f->flags & VH_FRAME_EXT) != 0u) {
        inc(&ecu->cnt.dlc_error);
        return;
    }
    if (!rx_accept(&ecu->cnt, &d->rx, f, VH_PT_DLS_SENSORS_LENGTH, VH_PT_DLS_SENSORS_E2E_DATA_ID)) {
        return;
    }
    (void)vh_pt_dls_sensors_unpack(&m, f->data, f->len);
    d->valid = 0u;
    take(ecu, m.qf_out_shaft_speed && m.out_shaft_speed != VH_PT_DLS_SENSORS_OUT_SHAFT_SPEED_SNA_CHOICE,
         vh_pt_dls_sensors_out_shaft_speed_decode(m.out_shaft_speed), &d->wo, SIG_WO);
    take(ecu, m.qf_wheel_speed_l && m.wheel_speed_l != VH_PT_DLS_SENSORS_WHEEL_SPEED_L_SNA_CHOICE,
         vh_pt_dls_sensors_wheel_speed_l_decode(m.wheel_speed_l), &d->wwl, SIG_WWL);
    take(ecu, m.qf_wheel_speed_r && m.wheel_speed_r != VH_PT_DLS_SENSORS_WHEEL_SPEED_R_SNA_CHOICE,
         vh_pt_dls_sensors_wheel_speed_r_decode(m.wheel_speed_r), &d->wwr, SIG_WWR);
    take(ecu, m.qf_shaft_torque && m.shaft_torque != VH_PT_DLS_SENSORS_SHAFT_TORQUE_SNA_CHOICE,
         vh_pt_dls_sensors_shaft_torque_decode(m.shaft_torque), &d->to, SIG_TO);
    take(ecu, m.qf_engine_speed && m.engine_speed != VH_PT_DLS_SENSORS_ENGINE_SPEED_SNA_CHOICE,
         vh_pt_dls_sensors_engine_speed_decode(m.engine_speed), &d->we, SIG_WE);
    take(ecu, m.qf_turbine_speed && m.turbine_speed != VH_PT_DLS_SENSORS_TURBINE_SPEED_SNA_CHOICE,
         vh_pt_dls_sensors_turbine_speed_decode(m.turbine_speed), &d->wt, SIG_WT);
    if (m.gear_engaged >= VH_ECU_N_GEARS || (m.gear_engaged > 0u && !(ecu->cfg.gear_ratio[m.gear_engaged] > 0.0))) {
        if (m.gear_engaged != GEAR_SNA) {
            inc(&ecu->cnt.signal_invalid); /* a gear the ECU has no ratio for */
        }
        d->gear = GEAR_SNA;
    } else {
        d->gear = m.gear_engaged;
    }
}

/* One chassis channel: a raw SNA value or a cleared qualifier makes it invalid (counted). */
static void take_ch(vh_ecu_chs_t *c, int ok, double value, int ch)
{
    if (!ok) {
        inc(&c->cnt.signal_invalid);
        c->valid &= (uint16_t)~(1u << ch);
        return;
    }
    c->u[ch] = value;
    c->valid |= (uint16_t)(1u << ch);
}

static void rx_chs(vh_ecu_t *ecu, const vh_frame_t *f)
{
    struct vh_ch_chs_sensors_t m;
    vh_ecu_chs_t *c = &ecu->chs;
    if ((f->flags & VH_FRAME_EXT) != 0u) {
        inc(&c->cnt.dlc_error);
        return;
    }
    if (!rx_accept(&c->cnt, &c->rx, f, VH_CH_CHS_SENSORS_LENGTH, VH_CH_CHS_SENSORS_E2E_DATA_ID)) {
        return;
    }
    (void)vh_ch_chs_sensors_unpack(&m, f->data, f->len);
    c->heard = 1u;
    take_ch(c, m.qf_long_accel && m.long_accel != VH_CH_CHS_SENSORS_LONG_ACCEL_SNA_CHOICE,
            vh_ch_chs_sensors_long_accel_decode(m.long_accel), 0);
    take_ch(c, m.qf_lat_accel && m.lat_accel != VH_CH_CHS_SENSORS_LAT_ACCEL_SNA_CHOICE,
            vh_ch_chs_sensors_lat_accel_decode(m.lat_accel), 1);
    take_ch(c, m.qf_yaw_rate && m.yaw_rate != VH_CH_CHS_SENSORS_YAW_RATE_SNA_CHOICE,
            vh_ch_chs_sensors_yaw_rate_decode(m.yaw_rate), 2);
    take_ch(c, m.qf_roll_rate && m.roll_rate != VH_CH_CHS_SENSORS_ROLL_RATE_SNA_CHOICE,
            vh_ch_chs_sensors_roll_rate_decode(m.roll_rate), 3);
    take_ch(c, m.qf_steer_angle && m.steer_angle != VH_CH_CHS_SENSORS_STEER_ANGLE_SNA_CHOICE,
            vh_ch_chs_sensors_steer_angle_decode(m.steer_angle), 4);
    take_ch(c, m.qf_wheel_speed_fl && m.wheel_speed_fl != VH_CH_CHS_SENSORS_WHEEL_SPEED_FL_SNA_CHOICE,
            vh_ch_chs_sensors_wheel_speed_fl_decode(m.wheel_speed_fl), 5);
    take_ch(c, m.qf_wheel_speed_fr && m.wheel_speed_fr != VH_CH_CHS_SENSORS_WHEEL_SPEED_FR_SNA_CHOICE,
            vh_ch_chs_sensors_wheel_speed_fr_decode(m.wheel_speed_fr), 6);
    take_ch(c, m.qf_wheel_speed_rl && m.wheel_speed_rl != VH_CH_CHS_SENSORS_WHEEL_SPEED_RL_SNA_CHOICE,
            vh_ch_chs_sensors_wheel_speed_rl_decode(m.wheel_speed_rl), 7);
    take_ch(c, m.qf_wheel_speed_rr && m.wheel_speed_rr != VH_CH_CHS_SENSORS_WHEEL_SPEED_RR_SNA_CHOICE,
            vh_ch_chs_sensors_wheel_speed_rr_decode(m.wheel_speed_rr), 8);
    take_ch(c, m.qf_wheel_torque_fl && m.wheel_torque_fl != VH_CH_CHS_SENSORS_WHEEL_TORQUE_FL_SNA_CHOICE,
            vh_ch_chs_sensors_wheel_torque_fl_decode(m.wheel_torque_fl), 9);
    take_ch(c, m.qf_wheel_torque_fr && m.wheel_torque_fr != VH_CH_CHS_SENSORS_WHEEL_TORQUE_FR_SNA_CHOICE,
            vh_ch_chs_sensors_wheel_torque_fr_decode(m.wheel_torque_fr), 10);
    take_ch(c, m.qf_wheel_torque_rl && m.wheel_torque_rl != VH_CH_CHS_SENSORS_WHEEL_TORQUE_RL_SNA_CHOICE,
            vh_ch_chs_sensors_wheel_torque_rl_decode(m.wheel_torque_rl), 11);
    take_ch(c, m.qf_wheel_torque_rr && m.wheel_torque_rr != VH_CH_CHS_SENSORS_WHEEL_TORQUE_RR_SNA_CHOICE,
            vh_ch_chs_sensors_wheel_torque_rr_decode(m.wheel_torque_rr), 12);
}

void vh_ecu_rx(vh_ecu_t *ecu, const vh_frame_t *frame)
{
    if (frame->id == VH_PT_DLS_SENSORS_FRAME_ID) {
        rx_dls(ecu, frame);
    } else if (frame->id == VH_CH_CHS_SENSORS_FRAME_ID) {
        rx_chs(ecu, frame);
    } else if (frame->id == VH_PT_CIS_ACCEL_FRAME_ID && (frame->flags & VH_FRAME_EXT) == 0u) {
        rx_cis(ecu, frame);
    } else if (!known_id(frame->id)) {
        inc(&ecu->cnt.unknown_id);
    }
}

static int16_t enc_s16(double v, double scale)
{
    double r = floor(v / scale + 0.5);
    r = r > 32767.0 ? 32767.0 : (r < -32767.0 ? -32767.0 : r); /* -32768 is SNA */
    return (int16_t)r;
}

static uint16_t enc_u16(double v, double scale)
{
    double r = floor(v / scale + 0.5);
    r = r > 65534.0 ? 65534.0 : (r < 0.0 ? 0.0 : r); /* 65535 is SNA */
    return (uint16_t)r;
}

/* Update inputs for this tick: timeout, gear, turbine torque (eq. 9, held when not usable). */
static unsigned update_inputs(vh_ecu_t *ecu)
{
    vh_ecu_dls_t *d = &ecu->dls;
    const int fresh = d->rx.fresh;
    unsigned mask = 0u;
    int i;
    if (!rx_tick(ecu, &ecu->cnt, &d->rx, DLS_TIMEOUT_TICKS) || d->rx.timed_out) { /* burst or silence: no usable sample */
        d->valid = 0u;
    }
    if (d->gear != GEAR_SNA && d->gear != ecu->gear && !d->rx.timed_out) {
        if (d->gear > 0u) {
            for (i = 0; i < VH_ECU_N_DKF; ++i) {
                (void)vh_dkf_set_ratio(&ecu->dkf[i], ecu->cfg.gear_ratio[d->gear]);
            }
        }
        ecu->gear = d->gear;
    }
    /* turbine torque reaches the output only with a gear engaged; neutral gives u = 0 */
    if (d->rx.timed_out || d->gear == GEAR_SNA) {
        ecu->ti_valid = 0u;
    } else if (d->gear == 0u) {
        ecu->ti = 0.0;
        ecu->ti_valid = 1u;
    } else if ((d->valid & (1u << SIG_WE)) && (d->valid & (1u << SIG_WT))) {
        double ti;
        ecu->ti_valid = (uint8_t)(vh_dkf_turbine_torque(d->we, d->wt, ecu->cfg.we_min, &ti) == 0);
        if (ecu->ti_valid) {
            ecu->ti = ti;
        }
    } else {
        ecu->ti_valid = 0u;
    }
    if (!ecu->ti_valid) {
        inc(&ecu->cnt.input_invalid);
    } else {
        mask |= VH_DKF_U_VALID;
    }
    if (d->valid & (1u << SIG_WO)) {
        mask |= VH_DKF_Z_WO;
    }
    if ((d->valid & (1u << SIG_WWL)) && (d->valid & (1u << SIG_WWR))) {
        mask |= VH_DKF_Z_WW;
    }
    if (d->valid & (1u << SIG_TO)) {
        mask |= VH_DKF_Z_TO;
    }
    if (!fresh) { /* measurement update only with samples new since the last tick */
        mask |= VH_DKF_STALE;
    }
    d->rx.fresh = 0u;
    return mask;
}

static size_t emit(vh_frame_t *tx, size_t n, size_t cap, uint32_t id, size_t len, int fd)
{
    if (n >= cap) {
        return n;
    }
    tx[n].id = id;
    tx[n].len = (uint8_t)len;
    tx[n].flags = fd ? (uint8_t)(VH_FRAME_FD | VH_FRAME_BRS) : 0u;
    return n + 1u;
}

/* One wheel's result in VEHEST_Camber units; no completed window yet: reason SNA. */
static void camber_fields(const vh_ecu_cis_t *c, int w, int16_t *theta, int16_t *psi, uint16_t *bound, uint8_t *reason)
{
    const double rad2deg = 57.29577951308232;
    if (!c->have[w]) {
        *reason = VH_ECU_CAMBER_NO_RESULT;
        return;
    }
    *reason = c->last[w].reason;
    if (c->last[w].reason == VH_CAMBER_OK) {
        *theta = enc_s16(c->last[w].theta_rad * rad2deg, 0.001);
        *psi = enc_s16(c->last[w].psi_rad * rad2deg, 0.01);
        *bound = enc_u16(c->last[w].bound_rad * rad2deg, 0.0001);
    }
}

/* Camber inspection (seed 002): a window step per device on every fresh CIS_Accel frame, with
 * "stationary" from the driveline wheel speeds; VEHEST_Camber every 100 ms while devices talk. */
static size_t camber_task(vh_ecu_t *ecu, vh_frame_t *tx, size_t n, size_t cap)
{
    vh_ecu_cis_t *c = &ecu->cis;
    const vh_ecu_dls_t *d = &ecu->dls;
    const int fresh = c->rx.fresh;
    struct vh_pt_vehest_camber_t m;
    int w;
    if (rx_tick(ecu, &ecu->cnt, &c->rx, CIS_TIMEOUT_TICKS) && fresh) {
        const double lim = ecu->cfg.camber_still_ww;
        const bool still = !d->rx.timed_out && (d->valid & (1u << SIG_WWL)) && (d->valid & (1u << SIG_WWR)) &&
                           fabs(d->wwl) < lim && fabs(d->wwr) < lim;
        for (w = 0; w < VH_ECU_N_WHEELS; ++w) {
            if (c->present & (1u << w)) {
                vh_camber_result_t r;
                if (vh_camber_step(&c->cmb[w], c->raw[w], still, &r)) {
                    c->last[w] = r;
                    c->have[w] = 1u;
                }
            }
        }
    }
    c->rx.fresh = 0u;
    if (c->rx.timed_out || ecu->tick % CAMBER_PERIOD_TICKS != 0u || n >= cap) {
        return n;
    }
    memset(&m, 0, sizeof m);
    camber_fields(c, 0, &m.camber_fl, &m.misalign_fl, &m.camber_bound_fl, &m.camber_reason_fl);
    camber_fields(c, 1, &m.camber_fr, &m.misalign_fr, &m.camber_bound_fr, &m.camber_reason_fr);
    camber_fields(c, 2, &m.camber_rl, &m.misalign_rl, &m.camber_bound_rl, &m.camber_reason_rl);
    camber_fields(c, 3, &m.camber_rr, &m.misalign_rr, &m.camber_bound_rr, &m.camber_reason_rr);
    memset(tx[n].data, 0, sizeof tx[n].data);
    (void)vh_pt_vehest_camber_pack(tx[n].data, &m, VH_PT_VEHEST_CAMBER_LENGTH);
    vh_e2e_p01_protect(tx[n].data, VH_PT_VEHEST_CAMBER_LENGTH, VH_PT_VEHEST_CAMBER_E2E_DATA_ID, &ecu->tx_counter[2]);
    return emit(tx, n, cap, VH_PT_VEHEST_CAMBER_FRAME_ID, VH_PT_VEHEST_CAMBER_LENGTH, VH_PT_VEHEST_CAMBER_IS_FD);
}

static int16_t enc_s16_sna(double v, double scale, int ok)
{
    return ok ? enc_s16(v, scale) : (int16_t)INT16_MIN;
}

/* Tyre lateral force (seed 000): one fixed-point SKFMEC step per tick on the fresh CHS_Sensors
 * sample (prediction only, DEGRADED, without one), restarted after a timeout so that it re-seeds
 * from live data; VEHEST_TireForceEst every 1 ms and VEHEST_ChassisStatus every 10 ms once the
 * chassis bus has been heard. */
static size_t chassis_task(vh_ecu_t *ecu, vh_frame_t *tx, size_t n, size_t cap)
{
    vh_ecu_chs_t *c = &ecu->chs;
    vh_skfq_t *f = &c->skf;
    const int fresh = c->rx.fresh;
    const int was_out = c->rx.timed_out;
    const int usable = rx_tick(ecu, &c->cnt, &c->rx, CHS_TIMEOUT_TICKS) && fresh;
    c->rx.fresh = 0u;
    if (!c->heard) {
        return n;
    }
    if (c->rx.timed_out) {
        if (!was_out) {
            vh_skfq_reset(f);
        }
    } else {
        unsigned mask = 0u;
        int32_t q[VH_SKF_NU];
        if (usable) {
            mask = (c->valid & 0xFu) | ((c->valid & CHS_ALL_INPUTS) == CHS_ALL_INPUTS ? VH_SKF_U_VALID : 0u);
        }
        vh_skfq_quantise_inputs(1u, c->u, q);
        {
            const uint32_t sat0 = f->sat;
            if (vh_skfq_step(f, (const vh_skfq_input_t *)(const void *)q, mask)) {
                inc(&c->cnt.filter_reset);
            }
            if (f->sat != sat0) {
                inc(&c->cnt.saturation);
            }
        }
    }
    if (ecu->tick % TFE_PERIOD_TICKS == 0u && n < cap) {
        struct vh_ch_vehest_tire_force_est_t m;
        const double *s = ecu->cfg.skf.s;
        const double fx = 1.0 / (double)(1L << VH_SKFQ_FX), fn = 1.0 / (double)(1L << VH_SKFQ_FN);
        const int ok = !c->rx.timed_out && (f->health == VH_HEALTH_OK || f->health == VH_HEALTH_DEGRADED);
        memset(&m, 0, sizeof m);
        m.skfmec_q_health = f->health;
        m.skfmec_q_valid = !c->rx.timed_out && f->health == VH_HEALTH_OK;
        m.fy1 = enc_s16_sna(f->fy[0] * fn, 0.5, ok);
        m.fy2 = enc_s16_sna(f->fy[1] * fn, 0.5, ok);
        m.fy3 = enc_s16_sna(f->fy[2] * fn, 0.5, ok);
        m.fy4 = enc_s16_sna(f->fy[3] * fn, 0.5, ok);
        m.fyf = enc_s16_sna(f->x[VH_SKF_FYF] * fx / s[VH_SKF_FYF], 0.5, ok);
        m.fyr = enc_s16_sna(f->x[VH_SKF_FYR] * fx / s[VH_SKF_FYR], 0.5, ok);
        m.est_vx = ok ? enc_u16(f->x[VH_SKF_VX] * fx / s[VH_SKF_VX], 0.005) : (uint16_t)UINT16_MAX;
        m.est_vy = enc_s16_sna(f->x[VH_SKF_VY] * fx / s[VH_SKF_VY], 0.001, ok);
        m.est_yaw_rate = enc_s16_sna(f->x[VH_SKF_R] * fx / s[VH_SKF_R], 0.0001, ok);
        m.est_roll_angle = enc_s16_sna(f->x[VH_SKF_PHI] * fx / s[VH_SKF_PHI], 0.00001, ok);
        memset(tx[n].data, 0, sizeof tx[n].data);
        (void)vh_ch_vehest_tire_force_est_pack(tx[n].data, &m, VH_CH_VEHEST_TIRE_FORCE_EST_LENGTH);
        vh_e2e_p01_protect(tx[n].data, VH_CH_VEHEST_TIRE_FORCE_EST_LENGTH, VH_CH_VEHEST_TIRE_FORCE_EST_E2E_DATA_ID,
                           &ecu->tx_counter[3]);
        n = emit(tx, n, cap, VH_CH_VEHEST_TIRE_FORCE_EST_FRAME_ID, VH_CH_VEHEST_TIRE_FORCE_EST_LENGTH,
                 VH_CH_VEHEST_TIRE_FORCE_EST_IS_FD);
    }
    if (ecu->tick % CST_PERIOD_TICKS == 0u && n < cap) {
        struct vh_ch_vehest_chassis_status_t st;
        const uint32_t cnt_err = (uint32_t)c->cnt.counter_repeat + c->cnt.counter_skip;
        memset(&st, 0, sizeof st);
        st.skfmec_q_health_sts = f->health;
        st.cnt_rx_crc_error = c->cnt.crc_error;
        st.cnt_rx_counter_error = (uint16_t)(cnt_err > UINT16_MAX ? UINT16_MAX : cnt_err);
        st.cnt_rx_timeout = c->cnt.timeout;
        st.cnt_signal_invalid = c->cnt.signal_invalid;
        st.cnt_saturation = c->cnt.saturation;
        st.cnt_filter_reset = c->cnt.filter_reset;
        st.rx_fault_active = (uint8_t)((c->rx.timed_out || c->rx.resync ? 1u : 0u) |
                                       ((c->valid & 0x1FFFu) != 0x1FFFu ? 2u : 0u));
        memset(tx[n].data, 0, sizeof tx[n].data);
        (void)vh_ch_vehest_chassis_status_pack(tx[n].data, &st, VH_CH_VEHEST_CHASSIS_STATUS_LENGTH);
        vh_e2e_p01_protect(tx[n].data, VH_CH_VEHEST_CHASSIS_STATUS_LENGTH, VH_CH_VEHEST_CHASSIS_STATUS_E2E_DATA_ID,
                           &ecu->tx_counter[4]);
        n = emit(tx, n, cap, VH_CH_VEHEST_CHASSIS_STATUS_FRAME_ID, VH_CH_VEHEST_CHASSIS_STATUS_LENGTH,
                 VH_CH_VEHEST_CHASSIS_STATUS_IS_FD);
    }
    return n;
}

size_t vh_ecu_step(vh_ecu_t *ecu, vh_frame_t *tx, size_t cap)
{
    const unsigned mask = update_inputs(ecu);
    const vh_ecu_dls_t *d = &ecu->dls;
    const double z[VH_DKF_NZ] = {d->wo, 0.5 * (d->wwl + d->wwr), d->to};
    struct vh_pt_vehest_driveline_est_t est;
    size_t n = 0u;
    int i;

    for (i = 0; i < VH_ECU_N_DKF; ++i) {
        if (vh_dkf_step(&ecu->dkf[i], ecu->ti, z, mask)) {
            inc(&ecu->cnt.filter_reset);
        }
    }

    memset(&est, 0, sizeof est);
    est.dkf_t_health = ecu->dkf[VH_ECU_DKF_T].health;
    est.dkf_s_health = ecu->dkf[VH_ECU_DKF_S].health;
    est.dkf_t_shaft_torque = enc_s16(ecu->dkf[VH_ECU_DKF_T].x[2], 0.25);
    est.dkf_t_road_load_err = enc_s16(ecu->dkf[VH_ECU_DKF_T].x[3], 0.25);
    est.dkf_s_shaft_torque = enc_s16(ecu->dkf[VH_ECU_DKF_S].x[2], 0.25);
    est.dkf_s_road_load_err = enc_s16(ecu->dkf[VH_ECU_DKF_S].x[3], 0.25);
    est.dkf_t_wheel_speed = enc_u16(ecu->dkf[VH_ECU_DKF_T].x[1], 0.02);
    est.turbine_torque = enc_s16(ecu->ti, 0.02);
    /* valid only from valid inputs: OK means every input of the filter was good this tick */
    est.dkf_t_valid = ecu->dkf[VH_ECU_DKF_T].health == VH_HEALTH_OK;
    est.dkf_s_valid = ecu->dkf[VH_ECU_DKF_S].health == VH_HEALTH_OK;
    est.turbine_torque_valid = ecu->ti_valid;
    if (n < cap) {
        memset(tx[n].data, 0, sizeof tx[n].data);
        (void)vh_pt_vehest_driveline_est_pack(tx[n].data, &est, VH_PT_VEHEST_DRIVELINE_EST_LENGTH);
        vh_e2e_p01_protect(tx[n].data, VH_PT_VEHEST_DRIVELINE_EST_LENGTH, VH_PT_VEHEST_DRIVELINE_EST_E2E_DATA_ID,
                           &ecu->tx_counter[0]);
        n = emit(tx, n, cap, VH_PT_VEHEST_DRIVELINE_EST_FRAME_ID, VH_PT_VEHEST_DRIVELINE_EST_LENGTH,
                 VH_PT_VEHEST_DRIVELINE_EST_IS_FD);
    }

    if (ecu->tick % ecu->cfg.status_period_ticks == 0u && n < cap) {
        struct vh_pt_vehest_status_t st;
        memset(&st, 0, sizeof st);
        st.dkf_t_health_sts = est.dkf_t_health;
        st.dkf_s_health_sts = est.dkf_s_health;
        st.ecu_tick = ecu->tick;
        st.cnt_crc_error = ecu->cnt.crc_error;
        st.cnt_counter_repeat = ecu->cnt.counter_repeat;
        st.cnt_counter_skip = ecu->cnt.counter_skip;
        st.cnt_dlc_error = ecu->cnt.dlc_error;
        st.cnt_timeout = ecu->cnt.timeout;
        st.cnt_unknown_id = ecu->cnt.unknown_id;
        st.cnt_signal_invalid = ecu->cnt.signal_invalid;
        st.cnt_input_invalid = ecu->cnt.input_invalid;
        st.cnt_filter_reset = ecu->cnt.filter_reset;
        st.cnt_deadline_miss = ecu->cnt.deadline_miss;
        st.cnt_rx_burst = ecu->cnt.rx_burst;
        st.rx_fault_active = (uint8_t)((d->rx.timed_out ? 1u : 0u) |
                                       (((d->valid & 0x3Fu) != 0x3Fu) ? 2u : 0u) | (ecu->ti_valid ? 0u : 4u));
        memset(tx[n].data, 0, sizeof tx[n].data);
        (void)vh_pt_vehest_status_pack(tx[n].data, &st, VH_PT_VEHEST_STATUS_LENGTH);
        vh_e2e_p01_protect(tx[n].data, VH_PT_VEHEST_STATUS_LENGTH, VH_PT_VEHEST_STATUS_E2E_DATA_ID,
                           &ecu->tx_counter[1]);
        n = emit(tx, n, cap, VH_PT_VEHEST_STATUS_FRAME_ID, VH_PT_VEHEST_STATUS_LENGTH, VH_PT_VEHEST_STATUS_IS_FD);
    }
    n = camber_task(ecu, tx, n, cap);
    n = chassis_task(ecu, tx, n, cap);
    ++ecu->tick;
    return n;
}

void vh_ecu_note_deadline_miss(vh_ecu_t *ecu, uint32_t n)
{
    const uint32_t sum = (uint32_t)ecu->cnt.deadline_miss + n;
    ecu->cnt.deadline_miss = (uint16_t)(sum > UINT16_MAX ? UINT16_MAX : sum);
}
