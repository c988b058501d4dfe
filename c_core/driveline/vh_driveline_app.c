/* vh_driveline_app.c - the driveline ECU application, see vh_driveline_app.h. */
#include <math.h>
#include <string.h>

#include "vh_driveline_app.h"
#include "vh_e2e.h"
#include "vh_pt.h"
#include "vh_pt_enc.h"
#include "vh_pt_meta.h"

/* Signal order of vh_ecu_dls_t.valid */
enum { SIG_WO = 0, SIG_WWL, SIG_WWR, SIG_TO, SIG_WE, SIG_WT, N_SIG };
#define GEAR_SNA 15u
/* RX timeout in ticks: RxTimeoutCycles of the DBC times the cycle time */
#define DLS_TIMEOUT_TICKS (VH_PT_DLS_SENSORS_RX_TIMEOUT_CYCLES * (VH_PT_DLS_SENSORS_CYCLE_TIME_US / VH_TICK_US))

void vh_drv_app_config_default(vh_drv_app_config_t *cfg)
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
}

int vh_drv_app_config_host(vh_drv_app_config_t *cfg)
{
    (void)cfg; /* nothing derived: the flashed init takes it as it is */
    return VH_OK;
}

int vh_drv_app_check(const vh_drv_app_config_t *cfg)
{
    int i;
    vh_dkf_t probe; /* vh_dkf_init's own checks, on a scratch instance */
    if (!(cfg->we_min > 0.0) || !isfinite(cfg->we_min)) {
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
    return VH_OK;
}

void vh_drv_app_init(vh_drv_app_t *a, const vh_drv_app_config_t *cfg)
{
    a->cfg = *cfg;
    vh_drv_app_reset(a);
}

void vh_drv_app_reset(vh_drv_app_t *a)
{
    const vh_drv_app_config_t cfg = a->cfg; /* the configuration survives */
    int i, g;
    memset(a, 0, sizeof *a);
    a->cfg = cfg;
    for (i = 0; i < VH_ECU_N_DKF; ++i) {
        (void)vh_dkf_f32_init(&a->dkf[i], &cfg.dkf[i]); /* checked at init */
    }
    for (i = 0; i < VH_ECU_N_DKF; ++i) {
        for (g = 1; g < VH_ECU_N_GEARS; ++g) {
            (void)vh_dkf_gear_model(&cfg.dkf[i], cfg.gear_ratio[g], &a->gears[i][g]); /* 0: not usable, left zero */
        }
    }
    a->gear = 0u;
    a->dls.gear = GEAR_SNA;
    vh_rx_init(&a->dls.rx);
}

/* One speed/torque signal: raw SNA value or a cleared qualifier makes it invalid. */
static void take(vh_ecu_dls_t *d, vh_ecu_counters_t *cnt, int ok, double value, double *dst, int sig)
{
    if (!ok) {
        vh_rx_count(&cnt->signal_invalid);
        d->valid &= (uint8_t)~(1u << sig);
        return;
    }
    *dst = value;
    d->valid |= (uint8_t)(1u << sig);
}

/* take() of one DLS_Sensors signal through the generated decoder, into d->dst */
#define TAKE(sig, SIG, dst, bit)                                              \
    take(d, cnt, m.qf_##sig && m.sig != VH_PT_DLS_SENSORS_##SIG##_SNA_CHOICE, \
         vh_pt_dls_sensors_##sig##_decode(m.sig), &d->dst, bit)

void vh_drv_app_rx(vh_drv_app_t *a, vh_app_ctx_t *ctx, const vh_frame_t *f)
{
    vh_ecu_counters_t *cnt = ctx->cnt;
    const double *gear_ratio = a->cfg.gear_ratio;
    struct vh_pt_dls_sensors_t m;
    vh_ecu_dls_t *d = &a->dls;
    if ((f->flags & VH_FRAME_EXT) != 0u) {
        vh_rx_count(&cnt->dlc_error);
        return;
    }
    if (!vh_rx_accept(cnt, &d->rx, f, VH_PT_DLS_SENSORS_LENGTH, VH_PT_DLS_SENSORS_E2E)) {
        return;
    }
    (void)vh_pt_dls_sensors_unpack(&m, f->data, f->len);
    d->valid = 0u;
    TAKE(out_shaft_speed, OUT_SHAFT_SPEED, wo, SIG_WO);
    TAKE(wheel_speed_l, WHEEL_SPEED_L, wwl, SIG_WWL);
    TAKE(wheel_speed_r, WHEEL_SPEED_R, wwr, SIG_WWR);
    TAKE(shaft_torque, SHAFT_TORQUE, to, SIG_TO);
    TAKE(engine_speed, ENGINE_SPEED, we, SIG_WE);
    TAKE(turbine_speed, TURBINE_SPEED, wt, SIG_WT);
    if ((d->valid & (1u << SIG_WWL)) && (d->valid & (1u << SIG_WWR))) {
        d->still_lp += VH_DRV_STILL_LP * (fmax(fabs(d->wwl), fabs(d->wwr)) - d->still_lp);
    }
    if (m.gear_engaged >= VH_ECU_N_GEARS || (m.gear_engaged > 0u && !(gear_ratio[m.gear_engaged] > 0.0))) {
        if (m.gear_engaged != GEAR_SNA) {
            vh_rx_count(&cnt->signal_invalid); /* a gear the ECU has no ratio for */
        }
        d->gear = GEAR_SNA;
    } else {
        d->gear = m.gear_engaged;
    }
}

/* Inputs for this tick: timeout, gear, turbine torque (eq. 9, held when not usable). */
static unsigned update_inputs(vh_drv_app_t *a, vh_ecu_counters_t *cnt, unsigned burst_limit)
{
    vh_dkf_f32_t *dkf = a->dkf;
    const double we_min = a->cfg.we_min;
    vh_ecu_dls_t *d = &a->dls;
    const int fresh = d->rx.fresh;
    unsigned mask = 0u;
    int i;
    if (!vh_rx_tick(cnt, &d->rx, DLS_TIMEOUT_TICKS, burst_limit) || d->rx.timed_out) {
        d->valid = 0u; /* burst or silence: no usable sample */
    }
    if (d->gear != GEAR_SNA && d->gear != a->gear && !d->rx.timed_out) {
        if (d->gear > 0u) {
            for (i = 0; i < VH_ECU_N_DKF; ++i) {
                vh_dkf_f32_use_gear_model(&dkf[i], &a->gears[i][d->gear]); /* rx_dls admits usable gears only */
            }
        }
        a->gear = d->gear;
    }
    /* turbine torque reaches the output only with a gear engaged; neutral gives u = 0 */
    if (d->rx.timed_out || d->gear == GEAR_SNA) {
        a->ti_valid = 0u;
    } else if (d->gear == 0u) {
        a->ti = 0.0;
        a->ti_valid = 1u;
    } else if ((d->valid & (1u << SIG_WE)) && (d->valid & (1u << SIG_WT))) {
        double ti;
        a->ti_valid = (uint8_t)(vh_dkf_turbine_torque(d->we, d->wt, we_min, &ti) == 0);
        if (a->ti_valid) {
            a->ti = ti;
        }
    } else {
        a->ti_valid = 0u;
    }
    if (!a->ti_valid && a->dls.rx.e2e.have_last) {
        /* not before the first DLS_Sensors: a bus never heard is absent (not configured), not a fault */
        vh_rx_count(&cnt->input_invalid);
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

void vh_drv_app_step(vh_drv_app_t *a, vh_app_ctx_t *ctx)
{
    const unsigned mask = update_inputs(a, ctx->cnt, ctx->burst_limit);
    const vh_ecu_dls_t *d = &a->dls;
    /* the filters run in float32 (vh_dkf.h); the decoded signals are rounded once into them */
    const float z[VH_DKF_NZ] = {(float)d->wo, (float)(0.5 * (d->wwl + d->wwr)), (float)d->to};
    int i;
    for (i = 0; i < VH_ECU_N_DKF; ++i) {
        if (vh_dkf_f32_step(&a->dkf[i], (float)a->ti, z, mask)) {
            vh_rx_count(&ctx->cnt->filter_reset);
        }
    }
    /* the stationary gate for the apps after this one (vh_drv_app_still with their own limit) */
    ctx->sig->wheel_speed_lp = d->still_lp;
    ctx->sig->wheel_speed_ok = (uint8_t)(!d->rx.timed_out && (d->valid & (1u << SIG_WWL)) && (d->valid & (1u << SIG_WWR)));
}

int vh_drv_app_still(const vh_drv_app_t *a, double lim)
{
    const vh_ecu_dls_t *d = &a->dls;
    return !d->rx.timed_out && (d->valid & (1u << SIG_WWL)) && (d->valid & (1u << SIG_WWR)) && d->still_lp < lim;
}

unsigned vh_drv_app_safety(vh_drv_app_t *a, int hold)
{
    (void)hold; /* no actuators */
    if (a->dls.rx.timed_out) {
        return VH_APP_SPEED;
    }
    return VH_APP_SPEED | VH_APP_SPEED_LIVE | (vh_drv_app_still(a, VH_DRV_XCP_STILL_WW) ? VH_APP_STILL : 0u);
}

void vh_drv_app_cal_gather(const vh_drv_app_t *a, vh_drv_app_cal_t *c)
{
    int i;
    for (i = 0; i < VH_ECU_N_DKF; ++i) {
        memcpy(c->dkf[i].q, a->cfg.dkf[i].q, sizeof c->dkf[i].q);
        memcpy(c->dkf[i].r, a->cfg.dkf[i].r, sizeof c->dkf[i].r);
        c->dkf[i].p_max = a->cfg.dkf[i].p_max;
    }
    c->we_min = a->cfg.we_min;
}

/* Into the configuration (a reset keeps it) and into the running filters. */
void vh_drv_app_cal_apply(vh_drv_app_t *a, const vh_drv_app_cal_t *c)
{
    int i;
    for (i = 0; i < VH_ECU_N_DKF; ++i) {
        vh_dkf_config_t *cfg = &a->cfg.dkf[i];
        memcpy(cfg->q, c->dkf[i].q, sizeof c->dkf[i].q);
        memcpy(cfg->r, c->dkf[i].r, sizeof c->dkf[i].r);
        cfg->p_max = c->dkf[i].p_max;
        vh_dkf_f32_tune(&a->dkf[i], cfg);
    }
    a->cfg.we_min = c->we_min;
}

int vh_drv_app_fill_est(vh_drv_app_t *a, vh_app_ctx_t *ctx, uint8_t *data)
{
    const vh_dkf_f32_t *dkf = a->dkf;
    struct vh_pt_vehest_driveline_est_t est;
    (void)ctx;
    memset(&est, 0, sizeof est);
    est.dkf_t_health = dkf[VH_ECU_DKF_T].health;
    est.dkf_s_health = dkf[VH_ECU_DKF_S].health;
    est.dkf_t_shaft_torque = vh_pt_vehest_driveline_est_dkf_t_shaft_torque_encode_round(dkf[VH_ECU_DKF_T].x[2]);
    est.dkf_t_road_load_err = vh_pt_vehest_driveline_est_dkf_t_road_load_err_encode_round(dkf[VH_ECU_DKF_T].x[3]);
    est.dkf_s_shaft_torque = vh_pt_vehest_driveline_est_dkf_s_shaft_torque_encode_round(dkf[VH_ECU_DKF_S].x[2]);
    est.dkf_s_road_load_err = vh_pt_vehest_driveline_est_dkf_s_road_load_err_encode_round(dkf[VH_ECU_DKF_S].x[3]);
    est.dkf_t_wheel_speed = vh_pt_vehest_driveline_est_dkf_t_wheel_speed_encode_round(dkf[VH_ECU_DKF_T].x[1]);
    est.turbine_torque = vh_pt_vehest_driveline_est_turbine_torque_encode_round(a->ti);
    /* valid only from valid inputs: OK means every input of the filter was good this tick */
    est.dkf_t_valid = dkf[VH_ECU_DKF_T].health == VH_HEALTH_OK;
    est.dkf_s_valid = dkf[VH_ECU_DKF_S].health == VH_HEALTH_OK;
    est.turbine_torque_valid = a->ti_valid;
    (void)vh_pt_vehest_driveline_est_pack(data, &est, VH_PT_VEHEST_DRIVELINE_EST_LENGTH);
    vh_e2e_protect(VH_PT_VEHEST_DRIVELINE_EST_E2E, data, VH_PT_VEHEST_DRIVELINE_EST_LENGTH,
                       &a->tx_counter[0]);
    return 1;
}

/* The fault counters VEHEST_Status carries, each as its 16-bit field cnt_<name>, saturated there
 * (CntSaturated: one of them is at 65535); saturation is the chassis estimator's, in its own status */
#define STATUS_COUNTERS(X)                                                               \
    X(crc_error) X(counter_repeat) X(counter_skip) X(dlc_error) X(timeout) X(unknown_id) \
    X(signal_invalid) X(input_invalid) X(filter_reset) X(deadline_miss) X(rx_burst) X(secoc_reject)

int vh_drv_app_fill_status(vh_drv_app_t *a, vh_app_ctx_t *ctx, uint8_t *data)
{
    const vh_dkf_f32_t *dkf = a->dkf;
    const vh_ecu_counters_t *cnt = ctx->cnt;
    const uint32_t tick = ctx->tick;
    struct vh_pt_vehest_status_t st;
    uint8_t saturated = 0u;
    const vh_ecu_dls_t *d = &a->dls;
    memset(&st, 0, sizeof st);
    st.dkf_t_health_sts = dkf[VH_ECU_DKF_T].health;
    st.dkf_s_health_sts = dkf[VH_ECU_DKF_S].health;
    st.ecu_tick = tick;
#define COPY(name) st.cnt_##name = (uint16_t)vh_sat_field_u32(cnt->name, UINT16_MAX, &saturated);
    STATUS_COUNTERS(COPY)
#undef COPY
    st.cnt_saturated = saturated;
    st.rx_fault_active = (uint8_t)((d->rx.timed_out ? 1u : 0u) | (((d->valid & 0x3Fu) != 0x3Fu) ? 2u : 0u) |
                                   (a->ti_valid ? 0u : 4u) | (cnt->secoc_reject != a->secoc_seen ? 8u : 0u));
    a->secoc_seen = cnt->secoc_reject;
    (void)vh_pt_vehest_status_pack(data, &st, VH_PT_VEHEST_STATUS_LENGTH);
    vh_e2e_protect(VH_PT_VEHEST_STATUS_E2E, data, VH_PT_VEHEST_STATUS_LENGTH, &a->tx_counter[1]);
    return 1;
}
