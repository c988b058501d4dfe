/* vh_roll_app.c - the roll ECU application, see vh_roll_app.h. */
#include <math.h>
#include <string.h>

#include "vh_ch.h"
#include "vh_ch_enc.h"
#include "vh_ch_meta.h"
#include "vh_e2e.h"
#include "vh_roll_app.h"

#define TICKS(cycle_us) ((cycle_us) / VH_TICK_US)
#define STEP_TICKS TICKS(VH_CH_ROLL_SENSORS_CYCLE_TIME_US)
#define STEP_S ((double)VH_CH_ROLL_SENSORS_CYCLE_TIME_US * 1e-6)
#define TIMEOUT(MSG) (VH_CH_##MSG##_RX_TIMEOUT_CYCLES * TICKS(VH_CH_##MSG##_CYCLE_TIME_US))
#define ALL_Z ((1u << VH_ROLL_NZ) - 1u)
#define RL32(v) ((float)(v))

void vh_roll_app_config_default(vh_roll_app_config_t *cfg)
{
    int i;
    memset(cfg, 0, sizeof *cfg);
    vh_roll_params_default(&cfg->ukf);
    cfg->ukf.dt = STEP_S;
    /* the robust variant (docs/roll.md); the roll node's lateral accelerometer is body-fixed */
    cfg->ukf.variant = VH_ROLL_V_ROBUST;
    cfg->ukf.ay_gravity = 1u;
    /* R: the default is the variance of one 2 kHz sample; the node sends the mean of STEP_TICKS */
    for (i = 0; i < VH_ROLL_NZ; ++i) {
        cfg->ukf.r[i] /= (double)STEP_TICKS;
    }
    vh_roll_smc_params_default(&cfg->smc, &cfg->ukf);
    cfg->rw = 0.305; /* the plant's wheel (vh_v14_params_default) */
    cfg->stuck_samples = 8u; /* 40 ms; with the default noise a live channel repeats a raw value
                              * 8 times in a row with probability below 1e-9 */
}

int vh_roll_app_check(const vh_roll_app_config_t *cfg)
{
    /* the parameter checks of the inits, without an instance on the stack (7 KB for the UKF) */
    if (fabs(cfg->ukf.dt - STEP_S) > 1e-12 || fabs(cfg->smc.dt - STEP_S) > 1e-12 || !(cfg->rw > 0.0) ||
        !isfinite(cfg->rw) || vh_roll_params_check(&cfg->ukf) != 0 || vh_roll_smc_params_check(&cfg->smc) != 0) {
        return VH_EINVAL;
    }
    return VH_OK;
}

int vh_roll_app_config_host(vh_roll_app_config_t *cfg)
{
    (void)cfg; /* nothing derived */
    return VH_OK;
}

void vh_roll_app_init(vh_roll_app_t *a, const vh_roll_app_config_t *cfg)
{
    a->cfg = *cfg;
    vh_roll_app_reset(a);
}

void vh_roll_app_reset(vh_roll_app_t *a)
{
    int i;
    const vh_roll_app_config_t cfg = a->cfg; /* the configuration survives */
    memset(a, 0, sizeof *a);
    a->cfg = cfg;
    (void)vh_roll_ukf_init_f32(&a->ukf, &cfg.ukf); /* checked at init */
    (void)vh_roll_smc_init_f32(&a->smc, &cfg.smc);
    for (i = 0; i < VH_ROLL_N_RX; ++i) {
        vh_rx_init(&a->rx[i]);
    }
}

/* One measurement: qualifier set, not SNA and not stuck -> z[ch] valid. Stuck: the same decoded
 * value (i.e. the same raw value) as in the last frame, stuck_samples frames in a row. */
static void take(vh_roll_app_t *a, const vh_roll_app_config_t *cfg, int ch, int ok, double value)
{
    const uint32_t bit = 1u << ch;
    if (ok && value == a->last[ch]) {
        a->same[ch] = (uint8_t)(a->same[ch] < UINT8_MAX ? a->same[ch] + 1u : UINT8_MAX);
    } else {
        a->same[ch] = 0u;
    }
    a->last[ch] = value;
    if (cfg->stuck_samples != 0u && a->same[ch] + 1u >= cfg->stuck_samples) {
        a->stuck |= bit;
    } else {
        a->stuck &= ~bit;
    }
    if (!ok || (a->stuck & bit) != 0u) {
        vh_rx_count(&a->cnt.signal_invalid);
        a->z_ok &= ~bit;
    } else {
        a->z[ch] = (float)value;
        a->z_ok |= bit;
    }
    a->z_new |= bit;
}

/* take() of one ROLL_Sensors signal through the generated decoder */
#define TAKE(sig, SIG, ch) \
    take(a, cfg, ch, m.qf_##sig && m.sig != VH_CH_ROLL_SENSORS_##SIG##_SNA_CHOICE, vh_ch_roll_sensors_##sig##_decode(m.sig))
/* the four corners' signals sig_fl, sig_fr, sig_rl, sig_rr into channels ch0 + 0..3 */
#define TAKE_CORNERS(sig, SIG, ch0)      \
    TAKE(sig##_fl, SIG##_FL, (ch0) + 0); \
    TAKE(sig##_fr, SIG##_FR, (ch0) + 1); \
    TAKE(sig##_rl, SIG##_RL, (ch0) + 2); \
    TAKE(sig##_rr, SIG##_RR, (ch0) + 3)

/* The handlers below get frames vh_rx_accept has passed (vh_roll_app_rx, RX_MSGS). */
static void rx_sensors(vh_roll_app_t *a, const vh_roll_app_config_t *cfg, const vh_frame_t *f)
{
    struct vh_ch_roll_sensors_t m;
    (void)vh_ch_roll_sensors_unpack(&m, f->data, f->len);
    a->heard = 1u;
    a->sens_arrived = 1u;
    a->sens_wait = 0u;
    TAKE(roll_lat_accel, ROLL_LAT_ACCEL, VH_ROLL_Z_AY);
    TAKE_CORNERS(wheel_vert_accel, WHEEL_VERT_ACCEL, VH_ROLL_Z_AZU);
    TAKE_CORNERS(tyre_defl, TYRE_DEFL, VH_ROLL_Z_DT);
    TAKE_CORNERS(susp_defl, SUSP_DEFL, VH_ROLL_Z_DS);
}

static void rx_yaw(vh_roll_app_t *a, const vh_roll_app_config_t *cfg, const vh_frame_t *f)
{
    struct vh_ch_roll_yaw_rate_t y;
    (void)vh_ch_roll_yaw_rate_unpack(&y, f->data, f->len);
    a->yaw_arrived = 1u;
    take(a, cfg, VH_ROLL_Z_R, y.qf_roll_yaw_rate && y.roll_yaw_rate != VH_CH_ROLL_YAW_RATE_ROLL_YAW_RATE_SNA_CHOICE,
         vh_ch_roll_yaw_rate_roll_yaw_rate_decode(y.roll_yaw_rate));
}

/* the wheel speeds' valid channels into vx: their mean times rw (at least two needed) */
#define WHEEL(sig, SIG)                                                                    \
    if (m.qf_##sig && m.sig != VH_CH_CHS_SENSORS_##SIG##_SNA_CHOICE) {                     \
        w_sum += vh_ch_chs_sensors_##sig##_decode(m.sig);                                  \
        ++n_w;                                                                             \
    }

static void rx_chs(vh_roll_app_t *a, const vh_roll_app_config_t *cfg, const vh_frame_t *f)
{
    struct vh_ch_chs_sensors_t m;
    double w_sum = 0.0;
    int n_w = 0;
    (void)vh_ch_chs_sensors_unpack(&m, f->data, f->len);
    WHEEL(wheel_speed_fl, WHEEL_SPEED_FL)
    WHEEL(wheel_speed_fr, WHEEL_SPEED_FR)
    WHEEL(wheel_speed_rl, WHEEL_SPEED_RL)
    WHEEL(wheel_speed_rr, WHEEL_SPEED_RR)
    a->u_ok = (uint8_t)(n_w >= 2 && m.qf_steer_angle && m.steer_angle != VH_CH_CHS_SENSORS_STEER_ANGLE_SNA_CHOICE);
    if (a->u_ok) {
        a->steer = (float)vh_ch_chs_sensors_steer_angle_decode(m.steer_angle);
        a->vx = (float)(cfg->rw * w_sum / n_w);
    }
}

static void rx_act(vh_roll_app_t *a, const vh_roll_app_config_t *cfg, const vh_frame_t *f)
{
    struct vh_ch_roll_actuator_status_t s;
    (void)cfg;
    (void)vh_ch_roll_actuator_status_unpack(&s, f->data, f->len);
    a->arc_state = s.arc_state;
    if (s.arc_state == 2u || s.arc_state == 3u) { /* HOLD, FAILSAFE: the commands do not arrive */
        vh_rx_count(&a->cnt.input_invalid);
    }
    if (s.applied_moment_f != VH_CH_ROLL_ACTUATOR_STATUS_APPLIED_MOMENT_F_SNA_CHOICE &&
        s.applied_moment_r != VH_CH_ROLL_ACTUATOR_STATUS_APPLIED_MOMENT_R_SNA_CHOICE) {
        a->m_applied[0] = (float)vh_ch_roll_actuator_status_applied_moment_f_decode(s.applied_moment_f);
        a->m_applied[1] = (float)vh_ch_roll_actuator_status_applied_moment_r_decode(s.applied_moment_r);
    } else {
        vh_rx_count(&a->cnt.signal_invalid);
    }
}

static void rx_mode(vh_roll_app_t *a, const vh_roll_app_config_t *cfg, const vh_frame_t *f)
{
    struct vh_ch_roll_mode_cmd_t mc;
    (void)cfg;
    (void)vh_ch_roll_mode_cmd_unpack(&mc, f->data, f->len);
    a->mode_active = mc.roll_mode_req;
}

/* The application's RX messages in the order of a->rx (VH_ROLL_RX_*): frame ID, what vh_rx_accept
 * checks (length, E2E configuration), the timeout in ticks, and what an accepted frame goes to. */
typedef void (*rx_handler_t)(vh_roll_app_t *a, const vh_roll_app_config_t *cfg, const vh_frame_t *f);
#define RX_MSG(MSG, handler) \
    {VH_CH_##MSG##_FRAME_ID, VH_CH_##MSG##_LENGTH, VH_CH_##MSG##_E2E, TIMEOUT(MSG), handler}
static const struct {
    uint32_t id;
    uint8_t len;
    const vh_e2e_cfg_t *e2e;
    uint16_t timeout;
    rx_handler_t handler;
} RX_MSGS[VH_ROLL_N_RX] = {RX_MSG(ROLL_SENSORS, rx_sensors), RX_MSG(ROLL_YAW_RATE, rx_yaw),
                           RX_MSG(CHS_SENSORS, rx_chs), RX_MSG(ROLL_ACTUATOR_STATUS, rx_act),
                           RX_MSG(ROLL_MODE_CMD, rx_mode)};

void vh_roll_app_rx(vh_roll_app_t *a, vh_app_ctx_t *ctx, const vh_frame_t *f)
{
    const vh_roll_app_config_t *cfg = &a->cfg;
    int i;
    (void)ctx; /* its own counters */
    if ((f->flags & VH_FRAME_EXT) != 0u) {
        vh_rx_count(&a->cnt.dlc_error);
        return;
    }
    for (i = 0; i < VH_ROLL_N_RX; ++i) {
        if (f->id == RX_MSGS[i].id) {
            if (vh_rx_accept(&a->cnt, &a->rx[i], f, RX_MSGS[i].len, RX_MSGS[i].e2e)) {
                RX_MSGS[i].handler(a, cfg, f);
            }
            return;
        }
    }
    vh_rx_count(&a->cnt.unknown_id);
}

void vh_roll_app_tick(vh_roll_app_t *a, vh_app_ctx_t *ctx)
{
    const unsigned burst_limit = ctx->burst_limit;
    int i;
    for (i = 0; i < VH_ROLL_N_RX; ++i) {
        if (!vh_rx_tick(&a->cnt, &a->rx[i], RX_MSGS[i].timeout, burst_limit)) {
            /* a burst: the frames of this tick are not trusted (the measurements' new bits go) */
            if (i == VH_ROLL_RX_SENS) {
                a->z_new &= (1u << VH_ROLL_Z_R);
            } else if (i == VH_ROLL_RX_YAW) {
                a->z_new &= ~(1u << VH_ROLL_Z_R);
            }
        }
        a->rx[i].fresh = 0u;
    }
}

void vh_roll_app_step(vh_roll_app_t *a, vh_app_ctx_t *ctx)
{
    float u[VH_ROLL_NU];
    uint32_t mask, h, est;
    const int act_ok = !a->rx[VH_ROLL_RX_ACT].timed_out;
    const int arc_ok = act_ok && a->arc_state != 2u && a->arc_state != 3u; /* not HOLD, not FAILSAFE */
    const int u_ok = !a->rx[VH_ROLL_RX_CHS].timed_out && a->u_ok;
    (void)ctx;
    a->stepped_now = 0u;
    if (!a->heard) {
        return;
    }
    if (a->since_step < UINT16_MAX) {
        ++a->since_step;
    }
    /* event-triggered on the sensors' frame, so the ECU's own tick phase adds no lost samples; a
     * frame later than half a cycle past due: step without it, then keep the nominal cycle */
    if (!a->sens_arrived) {
        if (a->since_step < STEP_TICKS + STEP_TICKS / 2u) {
            return;
        }
        a->since_step = STEP_TICKS / 2u;
    } else if (!a->yaw_arrived && a->sens_wait == 0u) {
        a->sens_wait = 1u; /* the gyro's frame of the same sample may come one tick later: wait for it */
        return;
    } else {
        a->since_step = 0u;
    }
    a->sens_arrived = 0u;
    a->yaw_arrived = 0u;
    a->stepped_now = 1u;
    mask = a->z_new & a->z_ok;
    if (a->rx[VH_ROLL_RX_SENS].timed_out) {
        mask &= (1u << VH_ROLL_Z_R);
    }
    if (a->rx[VH_ROLL_RX_YAW].timed_out) {
        mask &= ~(1u << VH_ROLL_Z_R);
    }
    a->z_new = 0u;
    u[VH_ROLL_U_STEER] = a->steer; /* the last good inputs; the estimate counts as not OK without them */
    u[VH_ROLL_U_VX] = a->vx;
    /* the applied moments, known inputs of eq. 4; without the status, this ECU's own commands */
    u[VH_ROLL_U_MF] = act_ok ? a->m_applied[0] : a->smc.m_f;
    u[VH_ROLL_U_MR] = act_ok ? a->m_applied[1] : a->smc.m_r;
    h = vh_roll_ukf_step_f32(&a->ukf, u, a->z, mask);
    a->stepped = 1u;
    a->missing = ~mask & ALL_Z;
    a->flags_acc |= a->ukf.flags;
    a->rx_fault = (a->rx[VH_ROLL_RX_SENS].timed_out ? VH_ROLL_RXF_SENS : 0u) |
                  (a->rx[VH_ROLL_RX_YAW].timed_out ? VH_ROLL_RXF_YAW : 0u) | (u_ok ? 0u : VH_ROLL_RXF_INPUT) |
                  (act_ok ? 0u : VH_ROLL_RXF_ACT) | (act_ok && !arc_ok ? VH_ROLL_RXF_ARC : 0u) |
                  (a->rx[VH_ROLL_RX_MODE].timed_out ? VH_ROLL_RXF_MODE : 0u) | (a->stuck != 0u ? VH_ROLL_RXF_STUCK : 0u);
    /* the controller acts only on an OK estimate with its inputs and working actuators */
    est = (h == VH_ROLL_H_OK && (!u_ok || !arc_ok)) ? (uint32_t)VH_ROLL_H_DEGRADED : h;
    (void)vh_roll_smc_step_f32(&a->smc, a->ukf.x[VH_ROLL_X_PHI], a->ukf.x[VH_ROLL_X_P], a->ukf.ay_post,
                               RL32(1000) * a->ukf.x[VH_ROLL_X_D], est,
                               a->mode_active && !a->rx[VH_ROLL_RX_MODE].timed_out);
}

int vh_roll_app_fill_cmd(vh_roll_app_t *a, vh_app_ctx_t *ctx, uint8_t *data)
{
    struct vh_ch_vehest_roll_cmd_t m;
    (void)ctx;
    if (!a->stepped_now) {
        return 0;
    }
    (void)vh_ch_vehest_roll_cmd_init(&m);
    m.roll_mode_cmd = (uint8_t)((a->smc.health & VH_ROLL_S_PASSIVE) == 0u);
    m.moment_cmd_f = vh_ch_vehest_roll_cmd_moment_cmd_f_encode_round((double)a->smc.m_f);
    m.moment_cmd_r = vh_ch_vehest_roll_cmd_moment_cmd_r_encode_round((double)a->smc.m_r);
    (void)vh_ch_vehest_roll_cmd_pack(data, &m, VH_CH_VEHEST_ROLL_CMD_LENGTH);
    vh_e2e_protect(VH_CH_VEHEST_ROLL_CMD_E2E, data, VH_CH_VEHEST_ROLL_CMD_LENGTH, &a->tx_counter[0]);
    return 1;
}

static uint8_t sat8(uint32_t v) { return (uint8_t)(v > 255u ? 255u : v); }

int vh_roll_app_fill_est(vh_roll_app_t *a, vh_app_ctx_t *ctx, uint8_t *data)
{
    struct vh_ch_vehest_roll_est_t m;
    const uint32_t h = a->ukf.health;
    const int ok = a->stepped && h != VH_ROLL_H_INIT && !a->rx[VH_ROLL_RX_SENS].timed_out;
    (void)ctx;
    if (!a->stepped) {
        return 0;
    }
    (void)vh_ch_vehest_roll_est_init(&m);
    /* the UKF's health on the bus scale: INIT, OK, DEGRADED, and a reset as FAULT */
    m.roll_ukf_health = (uint8_t)h;
    m.roll_ukf_valid = (uint8_t)(ok && h == VH_ROLL_H_OK);
    m.roll_est_angle = vh_ch_vehest_roll_est_roll_est_angle_encode_round(ok ? (double)a->ukf.x[VH_ROLL_X_PHI] : (double)NAN);
    m.roll_est_rate = vh_ch_vehest_roll_est_roll_est_rate_encode_round(ok ? (double)a->ukf.x[VH_ROLL_X_P] : (double)NAN);
    m.roll_est_lat_accel = vh_ch_vehest_roll_est_roll_est_lat_accel_encode_round(ok ? (double)a->ukf.ay_post : (double)NAN);
    m.roll_meas_missing = (uint16_t)a->missing;
    m.roll_smc_health = (uint8_t)(a->smc.health & 0x7Fu);
    m.roll_fade = vh_ch_vehest_roll_est_roll_fade_encode_round((double)a->smc.fade);
    m.roll_ukf_flags = (uint8_t)(a->flags_acc & 0x7Fu);
    m.roll_cnt_reset = sat8(a->ukf.resets);
    m.roll_rx_fault = (uint8_t)a->rx_fault;
    a->flags_acc = 0u;
    (void)vh_ch_vehest_roll_est_pack(data, &m, VH_CH_VEHEST_ROLL_EST_LENGTH);
    vh_e2e_protect(VH_CH_VEHEST_ROLL_EST_E2E, data, VH_CH_VEHEST_ROLL_EST_LENGTH, &a->tx_counter[1]);
    return 1;
}

/* ---- XCP: the tuning, and what the safe state needs ---- */

/* One list of the members, for gather and apply (the same names on both sides). */
#define ROLL_UKF_SCALARS(X) X(reg_eps) X(nis_max) X(phi_max)
#define ROLL_SMC_SCALARS(X) X(lambda) X(k) X(p) X(ref_frac) X(ref_tau) X(ay_tau) X(front_share) \
    X(m_max_f) X(m_max_r) X(rate_max_f) X(rate_max_r) X(fade_time) X(recover_time) X(not_ok_debounce)

void vh_roll_app_cal_gather(const vh_roll_app_t *a, vh_roll_app_cal_t *c)
{
    const vh_roll_app_config_t *cfg = &a->cfg;
    memcpy(c->ukf.q, cfg->ukf.q, sizeof c->ukf.q);
    memcpy(c->ukf.r, cfg->ukf.r, sizeof c->ukf.r);
    memcpy(c->ukf.p0, cfg->ukf.p0, sizeof c->ukf.p0);
#define GET_UKF(m) c->ukf.m = cfg->ukf.m;
#define GET_SMC(m) c->smc.m = cfg->smc.m;
    ROLL_UKF_SCALARS(GET_UKF)
    ROLL_SMC_SCALARS(GET_SMC)
    c->stuck_samples = cfg->stuck_samples;
}

/* Into the configuration (a reset starts from it) and into the running float32 UKF and SMC,
 * converted as their inits convert (a plain cast): the same as a start with these values.
 * Nothing of the filters derives from these at init, except p0, which only a reset reads. */
void vh_roll_app_cal_apply(vh_roll_app_t *a, const vh_roll_app_cal_t *c)
{
    vh_roll_app_config_t *cfg = &a->cfg;
    int i;
    for (i = 0; i < VH_ROLL_NX; ++i) {
        cfg->ukf.q[i] = c->ukf.q[i];
        cfg->ukf.p0[i] = c->ukf.p0[i];
        a->ukf.q[i] = (float)c->ukf.q[i];
        a->ukf.p0[i] = (float)c->ukf.p0[i];
    }
    for (i = 0; i < VH_ROLL_NZ; ++i) {
        cfg->ukf.r[i] = c->ukf.r[i];
        a->ukf.r[i] = (float)c->ukf.r[i];
    }
#define SET_UKF(m) cfg->ukf.m = c->ukf.m; a->ukf.m = (float)c->ukf.m;
#define SET_SMC(m) cfg->smc.m = c->smc.m; a->smc.m = (float)c->smc.m;
    ROLL_UKF_SCALARS(SET_UKF)
    ROLL_SMC_SCALARS(SET_SMC)
    cfg->stuck_samples = c->stuck_samples;
}

unsigned vh_roll_app_safety(vh_roll_app_t *a, int hold)
{
    const int live = !a->rx[VH_ROLL_RX_CHS].timed_out;
    unsigned s = VH_APP_SPEED;
    if (hold) {
        a->mode_active = 0u; /* the actuators passive (before roll steps) */
    }
    if (!(a->smc.fade <= 0.0f && a->smc.m_f == 0.0f && a->smc.m_r == 0.0f)) {
        s |= VH_APP_ACTIVE;
    }
    if (live) {
        s |= VH_APP_SPEED_LIVE | ((a->u_ok && fabsf(a->vx) < (float)VH_ROLL_XCP_STILL_VX) ? VH_APP_STILL : 0u);
    }
    return s;
}
