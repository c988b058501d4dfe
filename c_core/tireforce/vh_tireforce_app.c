/* vh_tireforce_app.c - the tyre-force ECU application, see vh_tireforce_app.h. */
#include <string.h>

#include "vh_ch.h"
#include "vh_ch_meta.h"
#include "vh_ch_q.h"
#include "vh_e2e.h"
#include "vh_health.h"
#include "vh_tireforce_app.h"

#define CHS_TIMEOUT_TICKS (VH_CH_CHS_SENSORS_RX_TIMEOUT_CYCLES * (VH_CH_CHS_SENSORS_CYCLE_TIME_US / VH_TICK_US))
#define CHS_ALL_INPUTS 0x1FF0u /* channels 4..12 of vh_skf_input_t: steer, wheel speeds, torques */
#define RIDE_TIMEOUT_TICKS \
    (VH_CH_CHS_RIDE_HEIGHT_RX_TIMEOUT_CYCLES * (VH_CH_CHS_RIDE_HEIGHT_CYCLE_TIME_US / VH_TICK_US))

void vh_tf_app_init(vh_tf_app_t *a, const vh_tf_app_config_t *cfg)
{
    a->skf.prm = cfg->skfq; /* the filters keep their constants; a reset re-initialises from them */
    a->tfa.prm = cfg->tfaq;
    vh_tf_app_reset(a);
}

void vh_tf_app_reset(vh_tf_app_t *c)
{
    const vh_skfq_params_t prm = c->skf.prm;
    memset(c->u, 0, sizeof c->u);
    c->valid = 0u;
    c->heard = 0u;
    memset(&c->cnt, 0, sizeof c->cnt);
    memset(c->tx_counter, 0, sizeof c->tx_counter);
    memset(&c->rx, 0, sizeof c->rx);
    vh_rx_init(&c->rx);
    memset(c->ride, 0, sizeof c->ride);
    c->ride_valid = 0u;
    c->ride_heard = 0u;
    memset(&c->ride_rx, 0, sizeof c->ride_rx);
    vh_rx_init(&c->ride_rx);
    (void)vh_skfq_init(&c->skf, &prm); /* checked at init */
    vh_tfa_reset(&c->tfa);             /* in place: its constants (a 3.7 KB table) are not copied */
}

/* One chassis channel: a raw SNA value or a cleared qualifier makes it invalid (counted). */
static void take_ch(vh_tf_app_t *c, int ok, int32_t value, int ch)
{
    if (!ok) {
        vh_rx_count(&c->cnt.signal_invalid);
        c->valid &= (uint16_t)~(1u << ch);
        return;
    }
    c->u[ch] = value;
    c->valid |= (uint16_t)(1u << ch);
}

/* take_ch of one signal: qualifier set and not the SNA value, then raw -> Q.frac exactly (the same
 * integer as rounding the double decode; saturation as that rounding's, not counted). */
#define TAKE(sig, SIG, ch, frac)                                                                  \
    take_ch(c, m.qf_##sig && m.sig != VH_CH_CHS_SENSORS_##SIG##_SNA_CHOICE,                        \
            vh_ch_chs_sensors_##sig##_decode_q(m.sig, (frac), &ignored), ch)

static void rx_sensors(vh_tf_app_t *c, const vh_frame_t *f)
{
    struct vh_ch_chs_sensors_t m;
    uint32_t ignored = 0u;
    if ((f->flags & VH_FRAME_EXT) != 0u) {
        vh_rx_count(&c->cnt.dlc_error);
        return;
    }
    if (!vh_rx_accept(&c->cnt, &c->rx, f, VH_CH_CHS_SENSORS_LENGTH, VH_CH_CHS_SENSORS_E2E)) {
        return;
    }
    (void)vh_ch_chs_sensors_unpack(&m, f->data, f->len);
    c->heard = 1u;
    TAKE(long_accel, LONG_ACCEL, 0, VH_SKFQ_FA);
    TAKE(lat_accel, LAT_ACCEL, 1, VH_SKFQ_FA);
    TAKE(yaw_rate, YAW_RATE, 2, VH_SKFQ_FW);
    TAKE(roll_rate, ROLL_RATE, 3, VH_SKFQ_FW);
    TAKE(steer_angle, STEER_ANGLE, 4, VH_SKFQ_FD);
    TAKE(wheel_speed_fl, WHEEL_SPEED_FL, 5, VH_SKFQ_FO);
    TAKE(wheel_speed_fr, WHEEL_SPEED_FR, 6, VH_SKFQ_FO);
    TAKE(wheel_speed_rl, WHEEL_SPEED_RL, 7, VH_SKFQ_FO);
    TAKE(wheel_speed_rr, WHEEL_SPEED_RR, 8, VH_SKFQ_FO);
    TAKE(wheel_torque_fl, WHEEL_TORQUE_FL, 9, VH_SKFQ_FT);
    TAKE(wheel_torque_fr, WHEEL_TORQUE_FR, 10, VH_SKFQ_FT);
    TAKE(wheel_torque_rl, WHEEL_TORQUE_RL, 11, VH_SKFQ_FT);
    TAKE(wheel_torque_rr, WHEEL_TORQUE_RR, 12, VH_SKFQ_FT);
}

/* One ride-height channel: valid (qualifier set, not SNA: else counted) into v[i], raw -> Q.FH exactly. */
#define RIDE(sig, SIG, i)                                                                                 \
    if (!(m.qf_##sig && m.sig != VH_CH_CHS_RIDE_HEIGHT_##SIG##_SNA_CHOICE)) {                              \
        vh_rx_count(&c->cnt.signal_invalid);                                                              \
        ok = 0u;                                                                                          \
    }                                                                                                     \
    v[i] = vh_ch_chs_ride_height_##sig##_decode_q(m.sig, VH_TFA_FH, &ignored)

static void rx_ride(vh_tf_app_t *c, const vh_frame_t *f)
{
    struct vh_ch_chs_ride_height_t m;
    uint32_t ignored = 0u;
    int32_t v[4];
    unsigned ok = 1u;
    if ((f->flags & VH_FRAME_EXT) != 0u) {
        vh_rx_count(&c->cnt.dlc_error);
        return;
    }
    if (!vh_rx_accept(&c->cnt, &c->ride_rx, f, VH_CH_CHS_RIDE_HEIGHT_LENGTH, VH_CH_CHS_RIDE_HEIGHT_E2E)) {
        return;
    }
    (void)vh_ch_chs_ride_height_unpack(&m, f->data, f->len);
    c->ride_heard = 1u;
    RIDE(spring_defl_fl, SPRING_DEFL_FL, 0);
    RIDE(spring_defl_fr, SPRING_DEFL_FR, 1);
    RIDE(spring_defl_rl, SPRING_DEFL_RL, 2);
    RIDE(spring_defl_rr, SPRING_DEFL_RR, 3);
    c->ride_valid = (uint8_t)ok; /* the four together: the sum needs every corner */
    if (ok) {
        memcpy(c->ride, v, sizeof v);
    }
}

void vh_tf_app_rx(vh_tf_app_t *a, vh_app_ctx_t *ctx, const vh_frame_t *f)
{
    (void)ctx; /* its own counters */
    if (f->id == VH_CH_CHS_RIDE_HEIGHT_FRAME_ID) {
        rx_ride(a, f);
    } else {
        rx_sensors(a, f);
    }
}

void vh_tf_app_cal_gather(const vh_tf_app_t *a, vh_tf_app_cal_t *c)
{
    memcpy(c->skf.q, a->skf.prm.q, sizeof c->skf.q);
    memcpy(c->skf.r, a->skf.prm.r, sizeof c->skf.r);
}

void vh_tf_app_cal_apply(vh_tf_app_t *a, const vh_tf_app_cal_t *c)
{
    memcpy(a->skf.prm.q, c->skf.q, sizeof c->skf.q); /* a reset restarts from prm */
    memcpy(a->skf.prm.r, c->skf.r, sizeof c->skf.r);
}

unsigned vh_tf_app_safety(vh_tf_app_t *a, int hold)
{
    (void)a; /* no speed source of the safe state, no actuators */
    (void)hold;
    return 0u;
}

void vh_tf_app_step(vh_tf_app_t *c, vh_app_ctx_t *ctx)
{
    const unsigned burst_limit = ctx->burst_limit;
    vh_skfq_t *f = &c->skf;
    const int fresh = c->rx.fresh;
    const int was_out = c->rx.timed_out;
    const int usable = vh_rx_tick(&c->cnt, &c->rx, CHS_TIMEOUT_TICKS, burst_limit) && fresh;
    /* the ride heights: held between their 10 ms frames, until their timeout */
    const int ride_ok = vh_rx_tick(&c->cnt, &c->ride_rx, RIDE_TIMEOUT_TICKS, burst_limit) && c->ride_heard &&
                        !c->ride_rx.timed_out && c->ride_valid;
    c->rx.fresh = 0u;
    c->ride_rx.fresh = 0u;
    if (!c->heard) {
        return;
    }
    if (c->rx.timed_out) {
        if (!was_out) {
            vh_skfq_reset(f);
            vh_tfa_reset(&c->tfa);
        }
    } else {
        unsigned mask = 0u;
        const uint32_t sat0 = f->sat;
        if (usable) {
            mask = (c->valid & 0xFu) | ((c->valid & CHS_ALL_INPUTS) == CHS_ALL_INPUTS ? VH_SKF_U_VALID : 0u);
        }
        const vh_skfq_input_t *in = vh_skfq_input_row(c->u, 0); /* the one row of this step */
        const uint32_t tsat0 = c->tfa.sat;
        if (vh_skfq_step(f, in, mask)) {
            vh_rx_count(&c->cnt.filter_reset);
        }
        vh_tfa_step(&c->tfa, f, in, mask, ride_ok ? c->ride : NULL);
        if (f->sat != sat0 || c->tfa.sat != tsat0) {
            vh_rx_count(&c->cnt.saturation);
        }
    }
}

/* The published states: their scaling S is the exact fraction s_num/s_den of the configuration,
 * so x* (Q.FX) -> raw is one integer rounding of an exact rational (vh_ch_q.h, no double). */
#define STATES(X)                                                                                  \
    X(fyf, FYF, VH_SKF_FYF) X(fyr, FYR, VH_SKF_FYR) X(est_vx, EST_VX, VH_SKF_VX) X(est_vy, EST_VY, VH_SKF_VY) \
    X(est_yaw_rate, EST_YAW_RATE, VH_SKF_R) X(est_roll_angle, EST_ROLL_ANGLE, VH_SKF_PHI)
#define QS_OK(sig, SIG, i) &&vh_ch_vehest_tire_force_est_##sig##_qs_ok(prm->s_num[i], prm->s_den[i])

int vh_tf_app_check(const vh_tf_app_config_t *cfg)
{
    const vh_skfq_params_t *prm = &cfg->skfq;
    const vh_tfa_params_t *tprm = &cfg->tfaq;
    vh_skfq_t probe; /* vh_skfq_init's own checks, on a scratch instance */
    return vh_skfq_init(&probe, prm) == VH_OK && vh_tfa_check(tprm) == VH_OK &&
           vh_ch_vehest_tire_force_adaptive_est_mass_qs_ok(tprm->m_den, tprm->m_num) &&
           vh_ch_vehest_tire_force_adaptive_est_mass_std_qs_ok(tprm->m_den, tprm->m_num) STATES(QS_OK)
               ? VH_OK
               : VH_EINVAL;
}

/* Every frame: none before the first CHS_Sensors frame (0), else m zeroed to be filled (1). */
static int begin(const vh_tf_app_t *c, void *m, size_t size)
{
    if (!c->heard) {
        return 0;
    }
    memset(m, 0, size);
    return 1;
}

/* The SKFMEC's published health: its own, DEGRADED while its v_x contradicts the wheels (SKFMEC-A's check,
 * vh_tfa.c): the filter as printed is not changed, only what it is said to be worth. */
static uint8_t skf_health(const vh_tf_app_t *c)
{
    return c->skf.health == VH_HEALTH_OK && (c->tfa.contra & VH_TFA_C_VX) != 0u ? VH_HEALTH_DEGRADED
               : c->skf.health;
}

/* An estimate frame's filter: its health, its valid flag (OK while CHS_Sensors has not timed out);
 * returns whether its estimates go out (not timed out, OK or DEGRADED; else their SNA). */
static int report(const vh_tf_app_t *c, uint8_t health, uint8_t *health_sig, uint8_t *valid_sig)
{
    *health_sig = health;
    *valid_sig = (uint8_t)(!c->rx.timed_out && health == VH_HEALTH_OK);
    return !c->rx.timed_out && (health == VH_HEALTH_OK || health == VH_HEALTH_DEGRADED);
}

/* Pack m as message msg and protect it (E2E profile 1, the message's own counter i). */
#define SEND(msg, MSG, i)                                                                        \
    (void)vh_ch_##msg##_pack(data, &m, VH_CH_##MSG##_LENGTH);                                    \
    vh_e2e_protect(VH_CH_##MSG##_E2E, data, VH_CH_##MSG##_LENGTH, &c->tx_counter[i])

/* An estimate while the filter is usable, else the signal's SNA. */
#define EST(sig, SIG, i)                                                                                  \
    m.sig = ok ? vh_ch_vehest_tire_force_est_##sig##_encode_qs(f->x[i], VH_SKFQ_FX, f->prm.s_num[i], \
                                                               f->prm.s_den[i])                   \
               : VH_CH_VEHEST_TIRE_FORCE_EST_##SIG##_SNA_CHOICE;
/* A tyre force (Q.FN -> raw, exact) the same way; the four tyres of Fy1..4 and of FyA1..4. */
#define TYRE(msg, MSG, sig, SIG, v) \
    m.sig = ok ? vh_ch_##msg##_##sig##_encode_q((v), VH_SKFQ_FN) : VH_CH_##MSG##_##SIG##_SNA_CHOICE;
#define TYRES(X) X(0, 1) X(1, 2) X(2, 3) X(3, 4)
#define FY(k, n) TYRE(vehest_tire_force_est, VEHEST_TIRE_FORCE_EST, fy##n, FY##n, f->fy[k])
#define FYA(k, n) TYRE(vehest_tire_force_adaptive, VEHEST_TIRE_FORCE_ADAPTIVE, fy_a##n, FY_A##n, a->fy[k])
/* each tyre's bound (Q.FN -> raw, round half up; the signal's range clamps a wider one) */
#define FYB(k, n) TYRE(vehest_tire_force_adaptive, VEHEST_TIRE_FORCE_ADAPTIVE, fy_a##n##_bound, FY_A##n##_BOUND, a->bound[k])

int vh_tf_app_fill_est(vh_tf_app_t *c, vh_app_ctx_t *ctx, uint8_t *data)
{
    struct vh_ch_vehest_tire_force_est_t m;
    const vh_skfq_t *f = &c->skf;
    int ok;
    (void)ctx; /* its own counters */
    if (!begin(c, &m, sizeof m)) {
        return 0;
    }
    ok = report(c, skf_health(c), &m.skfmec_q_health, &m.skfmec_q_valid);
    /* Q.FN -> raw and x* -> raw: exact integer scalings, the DBC's fraction (times S for the states) */
    TYRES(FY)
    STATES(EST)
    SEND(vehest_tire_force_est, VEHEST_TIRE_FORCE_EST, 0);
    return 1;
}

int vh_tf_app_fill_status(vh_tf_app_t *c, vh_app_ctx_t *ctx, uint8_t *data)
{
    struct vh_ch_vehest_chassis_status_t m;
    uint8_t sat = 0u; /* CntSaturated: a counter field at 65535 */
    (void)ctx; /* its own counters */
    if (!begin(c, &m, sizeof m)) {
        return 0;
    }
    m.skfmec_q_health_sts = skf_health(c);
#define FIELD(count) (uint16_t)vh_sat_field_u32((count), UINT16_MAX, &sat)
    m.cnt_rx_crc_error = FIELD(c->cnt.crc_error);
    m.cnt_rx_counter_error = FIELD(vh_sat_add_u32(c->cnt.counter_repeat, c->cnt.counter_skip));
    m.cnt_rx_timeout = FIELD(c->cnt.timeout);
    m.cnt_signal_invalid = FIELD(c->cnt.signal_invalid);
    m.cnt_saturation = FIELD(c->cnt.saturation);
    m.cnt_filter_reset = FIELD(c->cnt.filter_reset);
#undef FIELD
    m.cnt_saturated = sat;
    m.rx_fault_active = (uint8_t)((c->rx.timed_out || c->rx.resync ? 1u : 0u) |
                                  ((c->valid & 0x1FFFu) != 0x1FFFu ? 2u : 0u) |
                                  (c->ride_heard && (c->ride_rx.timed_out || c->ride_rx.resync || !c->ride_valid) ? 4u : 0u));
    m.missing_inputs = (uint8_t)((~c->valid & 0xFu) | ((c->valid & CHS_ALL_INPUTS) != CHS_ALL_INPUTS ? 0x10u : 0u));
    SEND(vehest_chassis_status, VEHEST_CHASSIS_STATUS, 1);
    return 1;
}

int vh_tf_app_fill_adaptive(vh_tf_app_t *c, vh_app_ctx_t *ctx, uint8_t *data)
{
    struct vh_ch_vehest_tire_force_adaptive_t m;
    const vh_tfa_t *a = &c->tfa;
    int ok;
    (void)ctx; /* its own counters */
    if (!begin(c, &m, sizeof m)) {
        return 0;
    }
    ok = report(c, a->health, &m.skfmec_a_health, &m.skfmec_a_valid);
    TYRES(FYA)
    TYRES(FYB)
    /* the mass ratio k (Q.FK) and its std sqrt(P) (Q.FP/2) times m = m_num / m_den: exact, integer */
    m.est_mass = ok ? vh_ch_vehest_tire_force_adaptive_est_mass_encode_qs(a->k, VH_TFA_FK, a->prm.m_den, a->prm.m_num)
                    : VH_CH_VEHEST_TIRE_FORCE_ADAPTIVE_EST_MASS_SNA_CHOICE;
    m.est_mass_std = ok ? vh_ch_vehest_tire_force_adaptive_est_mass_std_encode_qs(vh_tfa_mass_std(a), VH_TFA_FP / 2,
                                                                                  a->prm.m_den, a->prm.m_num)
                        : VH_CH_VEHEST_TIRE_FORCE_ADAPTIVE_EST_MASS_STD_SNA_CHOICE;
    m.skfmec_a_contradiction = (uint8_t)a->contra;
    {
        uint8_t at_max = 0u; /* the 12-bit field says 4095 for "4095 or more" */
        m.cnt_contradiction = (uint16_t)vh_sat_field_u32(a->n_contra, 0xFFFu, &at_max);
    }
    SEND(vehest_tire_force_adaptive, VEHEST_TIRE_FORCE_ADAPTIVE, 2);
    return 1;
}
