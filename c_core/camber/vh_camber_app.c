/* vh_camber_app.c - the camber inspection ECU application, see vh_camber_app.h. */
#include <math.h>
#include <string.h>

#include "vh_camber_app.h"
#include "vh_e2e.h"
#include "vh_pt.h"
#include "vh_pt_enc.h"
#include "vh_pt_meta.h"

#define CIS_TIMEOUT_TICKS (VH_PT_CIS_ACCEL_RX_TIMEOUT_CYCLES * (VH_PT_CIS_ACCEL_CYCLE_TIME_US / VH_TICK_US))

void vh_camber_app_config_default(vh_camber_app_config_t *cfg)
{
    memset(cfg, 0, sizeof *cfg);
    vh_camber_config_default(&cfg->cmb);
    cfg->still_ww = 0.5; /* 0.15 m/s at the wheel: parked, not rolling */
}

int vh_camber_app_config_host(vh_camber_app_config_t *cfg)
{
    (void)cfg; /* nothing derived */
    return VH_OK;
}

int vh_camber_app_check(const vh_camber_app_config_t *cfg)
{
    vh_camber_t probe; /* vh_camber_init's own checks, on a scratch instance */
    return cfg->still_ww >= 0.0 && isfinite(cfg->still_ww) && vh_camber_init(&probe, &cfg->cmb, NULL) == VH_OK
               ? VH_OK
               : VH_EINVAL;
}

void vh_camber_app_init(vh_camber_app_t *a, const vh_camber_app_config_t *cfg)
{
    memset(a, 0, sizeof *a); /* no calibration yet */
    a->cfg = *cfg;
    vh_camber_app_reset(a);
}

void vh_camber_app_reset(vh_camber_app_t *a)
{
    int i;
    const vh_camber_app_config_t cfg = a->cfg;
    vh_camber_cal_t cal[VH_ECU_N_WHEELS];
    for (i = 0; i < VH_ECU_N_WHEELS; ++i) {
        cal[i] = a->cmb[i].cal;
    }
    memset(a, 0, sizeof *a);
    a->cfg = cfg;
    for (i = 0; i < VH_ECU_N_WHEELS; ++i) {
        (void)vh_camber_init(&a->cmb[i], &cfg.cmb, cal[i].valid ? &cal[i] : NULL); /* cfg checked at init */
    }
    vh_rx_init(&a->rx);
}

void vh_camber_app_cal_gather(const vh_camber_app_t *a, vh_camber_app_cal_t *c)
{
    c->still_ww = a->cfg.still_ww;
    c->mag_tol_g = a->cfg.cmb.mag_tol_g;
    c->std_max_g = a->cfg.cmb.std_max_g;
}

void vh_camber_app_cal_apply(vh_camber_app_t *a, const vh_camber_app_cal_t *c)
{
    int i;
    a->cfg.still_ww = c->still_ww;
    a->cfg.cmb.mag_tol_g = c->mag_tol_g;
    a->cfg.cmb.std_max_g = c->std_max_g;
    for (i = 0; i < VH_ECU_N_WHEELS; ++i) {
        a->cmb[i].cfg.mag_tol_g = c->mag_tol_g;
        a->cmb[i].cfg.std_max_g = c->std_max_g;
    }
}

unsigned vh_camber_app_safety(vh_camber_app_t *a, int hold)
{
    (void)a; /* no speed source, no actuators */
    (void)hold;
    return 0u;
}

int vh_camber_app_set_calibration(vh_camber_app_t *c, unsigned wheel, const vh_camber_cal_t *cal)
{
    if (wheel >= VH_ECU_N_WHEELS) {
        return VH_EINVAL;
    }
    c->have[wheel] = 0u;
    return vh_camber_set_calibration(&c->cmb[wheel], cal);
}

void vh_camber_app_rx(vh_camber_app_t *c, vh_app_ctx_t *ctx, const vh_frame_t *f)
{
    vh_ecu_counters_t *cnt = ctx->cnt;
    struct vh_pt_cis_accel_t m;
    if ((f->flags & VH_FRAME_EXT) != 0u) { /* an extended-ID twin is not ours: ignored, not counted */
        return;
    }
    if (!vh_rx_accept(cnt, &c->rx, f, VH_PT_CIS_ACCEL_LENGTH, VH_PT_CIS_ACCEL_E2E)) {
        return;
    }
    (void)vh_pt_cis_accel_unpack(&m, f->data, f->len);
    c->raw[0][0] = m.cis_acc_x_fl; c->raw[0][1] = m.cis_acc_y_fl; c->raw[0][2] = m.cis_acc_z_fl;
    c->raw[1][0] = m.cis_acc_x_fr; c->raw[1][1] = m.cis_acc_y_fr; c->raw[1][2] = m.cis_acc_z_fr;
    c->raw[2][0] = m.cis_acc_x_rl; c->raw[2][1] = m.cis_acc_y_rl; c->raw[2][2] = m.cis_acc_z_rl;
    c->raw[3][0] = m.cis_acc_x_rr; c->raw[3][1] = m.cis_acc_y_rr; c->raw[3][2] = m.cis_acc_z_rr;
    c->present = m.cis_present;
}

void vh_camber_app_step(vh_camber_app_t *c, vh_app_ctx_t *ctx)
{
    const int fresh = c->rx.fresh;
    /* the stationary gate of this tick (vh_drv_app_still with this app's limit) */
    const int still = ctx->sig->wheel_speed_ok && ctx->sig->wheel_speed_lp < c->cfg.still_ww;
    int w;
    if (vh_rx_tick(ctx->cnt, &c->rx, CIS_TIMEOUT_TICKS, ctx->burst_limit) && fresh) {
        for (w = 0; w < VH_ECU_N_WHEELS; ++w) {
            if (c->present & (1u << w)) {
                vh_camber_result_t r;
                if (vh_camber_step(&c->cmb[w], c->raw[w], still != 0, &r)) {
                    c->last[w] = r;
                    c->have[w] = 1u;
                }
            }
        }
    }
    c->rx.fresh = 0u;
}

/* One wheel's result in VEHEST_Camber units (degrees); no completed window yet: reason SNA. */
#define RAD2DEG 57.29577951308232
#define CAMBER_FIELDS(W, wheel)                                                                                  \
    do {                                                                                                       \
        if (!c->have[W]) {                                                                                     \
            m.camber_reason_##wheel = VH_ECU_CAMBER_NO_RESULT;                                                  \
        } else {                                                                                               \
            m.camber_reason_##wheel = c->last[W].reason;                                                       \
            if (c->last[W].reason == VH_CAMBER_OK) {                                                           \
                m.camber_##wheel = vh_pt_vehest_camber_camber_##wheel##_encode_round(c->last[W].theta_rad * RAD2DEG); \
                m.misalign_##wheel = vh_pt_vehest_camber_misalign_##wheel##_encode_round(c->last[W].psi_rad * RAD2DEG); \
                m.camber_bound_##wheel =                                                                       \
                    vh_pt_vehest_camber_camber_bound_##wheel##_encode_round(c->last[W].bound_rad * RAD2DEG);    \
            }                                                                                                  \
        }                                                                                                      \
    } while (0)

int vh_camber_app_fill(vh_camber_app_t *c, vh_app_ctx_t *ctx, uint8_t *data)
{
    struct vh_pt_vehest_camber_t m;
    (void)ctx;
    if (c->rx.timed_out) {
        return 0;
    }
    memset(&m, 0, sizeof m);
    CAMBER_FIELDS(0, fl);
    CAMBER_FIELDS(1, fr);
    CAMBER_FIELDS(2, rl);
    CAMBER_FIELDS(3, rr);
    (void)vh_pt_vehest_camber_pack(data, &m, VH_PT_VEHEST_CAMBER_LENGTH);
    vh_e2e_protect(VH_PT_VEHEST_CAMBER_E2E, data, VH_PT_VEHEST_CAMBER_LENGTH, &c->tx_counter);
    return 1;
}
