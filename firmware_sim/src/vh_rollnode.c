/* vh_rollnode.c - see vh_rollnode.h. */
#include "vh_rollnode.h"

#include <math.h>

#include "vh_ch.h"
#include "vh_ch_enc.h"
#include "vh_ch_meta.h"
#include "vh_node_common.h"
#include "vh_node_impl.h"
#include "vh_secoc_bus.h"

#define TICKS(cycle_us) ((cycle_us) / VH_TICK_US)
#define SENS_TICKS TICKS(VH_CH_ROLL_SENSORS_CYCLE_TIME_US)
#define MODE_TICKS TICKS(VH_CH_ROLL_MODE_CMD_CYCLE_TIME_US)
#define CMD_TIMEOUT_TICKS (VH_CH_VEHEST_ROLL_CMD_RX_TIMEOUT_CYCLES * TICKS(VH_CH_VEHEST_ROLL_CMD_CYCLE_TIME_US))

/* One channel through the generated encoder, or its SNA value when the sensor is dead; and its
 * qualifier. */
#define SENS(sig, SIG, c) VH_NODE_CHANNEL(m, ch, CH, roll_sensors, ROLL_SENSORS, sig, SIG, ok[c], n->sent[c])

void vh_rln_config_default(vh_rln_config_t *cfg)
{
    int i;
    /* Per 2 kHz sample, the figures of docs/roll.md: a_y 0.05 m/s^2 (MEMS, as the chassis cluster),
     * unsprung accelerometers 0.2 m/s^2, tyre deflection 0.2 mm (a wheel-centre height sensor),
     * suspension deflection 0.5 mm (ride-height sensor), yaw rate 0.005 rad/s. */
    cfg->noise_std[VH_RLN_CH_AY] = 0.05;
    for (i = 0; i < 4; ++i) {
        cfg->noise_std[VH_RLN_CH_AZU + i] = 0.2;
        cfg->noise_std[VH_RLN_CH_DT + i] = 0.0002;
        cfg->noise_std[VH_RLN_CH_DS + i] = 0.0005;
    }
    cfg->noise_std[VH_RLN_CH_R] = 0.005;
    for (i = 0; i < VH_RLN_NCH; ++i) {
        cfg->bias[i] = 0.0;
    }
    cfg->seed = 0x524F4C4Cu; /* "ROLL" */
    cfg->fail_mask = 0u;
    cfg->stuck_mask = 0u;
    cfg->mode_active = 0u;
}

int vh_rln_init(vh_rln_t *n, const vh_rln_config_t *cfg)
{
    if (n == NULL || cfg == NULL || vh_node_check(cfg->noise_std, cfg->bias, VH_RLN_NCH) != VH_OK) {
        return VH_EINVAL;
    }
    n->cfg = *cfg;
    n->secoc = NULL;
    vh_rln_reset(n);
    return VH_OK;
}

void vh_rln_reset(vh_rln_t *n)
{
    int i;
    vh_node_restart(&n->rng, n->cfg.seed, n->acc, VH_RLN_NCH);
    for (i = 0; i < VH_RLN_NCH; ++i) {
        n->sent[i] = 0.0;
    }
    for (i = 0; i < VH_V14_NW; ++i) {
        n->vzu[i] = 0.0;
    }
    for (i = 0; i < 4; ++i) {
        n->counter[i] = 0u;
    }
    n->n_acc = 0u;
    n->tick = 0u;
    vh_e2e_rx_init(&n->cmd_e2e);
    n->cmd_new = n->heard = n->cmd_mode = 0u;
    n->state = VH_RLN_ARC_PASSIVE;
    n->cmd[0] = n->cmd[1] = 0.0;
    n->cmd_age = 0u;
    n->cnt_timeout = n->cnt_rejected = 0u;
    n->applied_tick = 0u;
    if (n->secoc != NULL) {
        vh_secoc_bus_resync(n->secoc); /* the ECU may have restarted too */
    }
}

void vh_rln_set_secoc(vh_rln_t *n, vh_secoc_bus_t *s) { n->secoc = s; }

void vh_rln_rx(vh_rln_t *n, const vh_frame_t *f)
{
    struct vh_ch_vehest_roll_cmd_t m;
    vh_e2e_status_t st;
    vh_frame_t verified;
    if ((f->id != VH_CH_VEHEST_ROLL_CMD_FRAME_ID && f->id != VH_CH_VEHEST_SEC_OC_SYNC_CH_FRAME_ID) ||
        (f->flags & VH_FRAME_EXT) != 0u) {
        return;
    }
    if (n->secoc != NULL) { /* SecOC first: a rejected command is a lost one (hold, then fail safe) */
        switch (vh_secoc_bus_rx(n->secoc, f, &verified)) {
        case VH_SECOC_BUS_OK:
            f = &verified;
            break;
        case VH_SECOC_BUS_PASS:
            break;
        case VH_SECOC_BUS_REJECTED:
            ++n->cnt_rejected;
            return;
        default: /* the sync frame */
            return;
        }
    }
    if (f->id != VH_CH_VEHEST_ROLL_CMD_FRAME_ID) {
        return;
    }
    st = f->len == VH_CH_VEHEST_ROLL_CMD_LENGTH
             ? vh_e2e_check(VH_CH_VEHEST_ROLL_CMD_E2E, &n->cmd_e2e, f->data, f->len)
             : VH_E2E_BAD_LEN;
    if (st != VH_E2E_OK && st != VH_E2E_INITIAL && st != VH_E2E_SKIPPED) {
        ++n->cnt_rejected;
        return;
    }
    (void)vh_ch_vehest_roll_cmd_unpack(&m, f->data, f->len);
    if (m.moment_cmd_f == VH_CH_VEHEST_ROLL_CMD_MOMENT_CMD_F_SNA_CHOICE ||
        m.moment_cmd_r == VH_CH_VEHEST_ROLL_CMD_MOMENT_CMD_R_SNA_CHOICE) {
        ++n->cnt_rejected;
        return;
    }
    n->cmd[0] = vh_ch_vehest_roll_cmd_moment_cmd_f_decode(m.moment_cmd_f);
    n->cmd[1] = vh_ch_vehest_roll_cmd_moment_cmd_r_decode(m.moment_cmd_r);
    n->cmd_mode = m.roll_mode_cmd;
    n->cmd_new = 1u;
}

void vh_rln_actuate(vh_rln_t *n, vh_v14_t *p)
{
    if (n->cmd_new) {
        n->cmd_new = 0u;
        n->heard = 1u;
        n->cmd_age = 0u;
        n->applied_tick = n->tick;
        n->state = (n->cmd_mode || n->cmd[0] != 0.0 || n->cmd[1] != 0.0) ? VH_RLN_ARC_ACTIVE : VH_RLN_ARC_PASSIVE;
        vh_v14_set_roll_moment(p, n->cmd[0], n->cmd[1]);
        return;
    }
    if (!n->heard) {
        return; /* nothing commanded yet: passive, not a timeout */
    }
    if (n->cmd_age < UINT32_MAX) {
        ++n->cmd_age;
    }
    if (n->cmd_age == CMD_TIMEOUT_TICKS) {
        n->state = VH_RLN_ARC_HOLD; /* the last command stays in the plant */
        ++n->cnt_timeout;
    } else if (n->cmd_age == 2u * CMD_TIMEOUT_TICKS) {
        n->state = VH_RLN_ARC_FAILSAFE;
    }
    if (n->state == VH_RLN_ARC_FAILSAFE) {
        vh_v14_roll_fail_safe(p);
    }
}

static uint8_t sat8(uint32_t v) { return (uint8_t)(v > 255u ? 255u : v); }

size_t vh_rln_step(vh_rln_t *n, const vh_v14_t *p, vh_frame_t *out, size_t cap)
{
    const vh_v14_truth_t *t = &p->truth;
    double phys[VH_RLN_NCH];
    uint8_t ok[VH_RLN_NCH];
    size_t k = 0u;
    vh_frame_t *f;
    int i;

    /* the lateral accelerometer is body-fixed: specific force along the rolled body's y axis, as the
     * chassis node's accel_gravity (docs/roll.md, "The roll node") */
    phys[VH_RLN_CH_AY] = t->ay * cos(t->phi) + VH_V14_GRAVITY * sin(t->phi);
    for (i = 0; i < VH_V14_NW; ++i) {
        const double vzu = p->x[VH_V14_X_VZU + i];
        const double zs = t->z + p->cy[i] * t->phi - p->cx[i] * t->theta; /* body corner height */
        phys[VH_RLN_CH_AZU + i] = (vzu - n->vzu[i]) / VH_V14_DT; /* mean over the tick */
        n->vzu[i] = vzu;
        phys[VH_RLN_CH_DT + i] = -t->zu[i];
        phys[VH_RLN_CH_DS + i] = t->zu[i] - zs;
    }
    phys[VH_RLN_CH_R] = t->r;
    vh_node_sample(&n->rng, phys, n->cfg.bias, n->cfg.noise_std, VH_RLN_NCH, phys);
    for (i = 0; i < VH_RLN_NCH; ++i) {
        n->acc[i] += phys[i];
    }
    ++n->n_acc;

    if (n->tick % SENS_TICKS == 0u) {
        struct vh_ch_roll_sensors_t m;
        struct vh_ch_roll_yaw_rate_t y;
        struct vh_ch_roll_actuator_status_t s;
        for (i = 0; i < VH_RLN_NCH; ++i) {
            const double v = n->acc[i] / (double)n->n_acc;
            if (!(n->cfg.stuck_mask & (1u << i))) {
                n->sent[i] = v;
            }
            n->acc[i] = 0.0;
        }
        vh_node_qualify(n->sent, n->cfg.fail_mask, VH_RLN_NCH, ok);
        n->n_acc = 0u;
        (void)vh_ch_roll_sensors_init(&m);
        SENS(roll_lat_accel, ROLL_LAT_ACCEL, VH_RLN_CH_AY);
        VH_NODE_CORNERS(SENS, wheel_vert_accel, WHEEL_VERT_ACCEL, VH_RLN_CH_AZU);
        VH_NODE_CORNERS(SENS, tyre_defl, TYRE_DEFL, VH_RLN_CH_DT);
        VH_NODE_CORNERS(SENS, susp_defl, SUSP_DEFL, VH_RLN_CH_DS);
        if ((f = vh_node_slot(out, &k, cap, VH_CH_ROLL_SENSORS_FRAME_ID, VH_CH_ROLL_SENSORS_LENGTH)) != NULL) {
            (void)vh_ch_roll_sensors_pack(f->data, &m, VH_CH_ROLL_SENSORS_LENGTH);
            vh_e2e_protect(VH_CH_ROLL_SENSORS_E2E, f->data, VH_CH_ROLL_SENSORS_LENGTH, &n->counter[0]);
        }

        (void)vh_ch_roll_yaw_rate_init(&y);
        VH_NODE_CHANNEL(y, ch, CH, roll_yaw_rate, ROLL_YAW_RATE, roll_yaw_rate, ROLL_YAW_RATE, ok[VH_RLN_CH_R],
                        n->sent[VH_RLN_CH_R]);
        if ((f = vh_node_slot(out, &k, cap, VH_CH_ROLL_YAW_RATE_FRAME_ID, VH_CH_ROLL_YAW_RATE_LENGTH)) != NULL) {
            (void)vh_ch_roll_yaw_rate_pack(f->data, &y, VH_CH_ROLL_YAW_RATE_LENGTH);
            vh_e2e_protect(VH_CH_ROLL_YAW_RATE_E2E, f->data, VH_CH_ROLL_YAW_RATE_LENGTH, &n->counter[1]);
        }

        (void)vh_ch_roll_actuator_status_init(&s);
        s.arc_state = n->state;
        s.applied_moment_f = vh_ch_roll_actuator_status_applied_moment_f_encode_round(p->arc.m[0]);
        s.applied_moment_r = vh_ch_roll_actuator_status_applied_moment_r_encode_round(p->arc.m[1]);
        s.cnt_cmd_timeout = sat8(n->cnt_timeout);
        s.cnt_cmd_rejected = sat8(n->cnt_rejected);
        f = vh_node_slot(out, &k, cap, VH_CH_ROLL_ACTUATOR_STATUS_FRAME_ID, VH_CH_ROLL_ACTUATOR_STATUS_LENGTH);
        if (f != NULL) {
            (void)vh_ch_roll_actuator_status_pack(f->data, &s, VH_CH_ROLL_ACTUATOR_STATUS_LENGTH);
            vh_e2e_protect(VH_CH_ROLL_ACTUATOR_STATUS_E2E, f->data, VH_CH_ROLL_ACTUATOR_STATUS_LENGTH,
                               &n->counter[2]);
        }
    }
    if (n->tick % MODE_TICKS == 0u) {
        struct vh_ch_roll_mode_cmd_t mc;
        (void)vh_ch_roll_mode_cmd_init(&mc);
        mc.roll_mode_req = n->cfg.mode_active ? 1u : 0u;
        if ((f = vh_node_slot(out, &k, cap, VH_CH_ROLL_MODE_CMD_FRAME_ID, VH_CH_ROLL_MODE_CMD_LENGTH)) != NULL) {
            (void)vh_ch_roll_mode_cmd_pack(f->data, &mc, VH_CH_ROLL_MODE_CMD_LENGTH);
            vh_e2e_protect(VH_CH_ROLL_MODE_CMD_E2E, f->data, VH_CH_ROLL_MODE_CMD_LENGTH, &n->counter[3]);
        }
    }
    ++n->tick;
    return n->secoc != NULL ? vh_secoc_bus_tx(n->secoc, out, k, cap) : k;
}
