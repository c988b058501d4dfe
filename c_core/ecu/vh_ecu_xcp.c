/* vh_ecu_xcp.c - the ECU's XCP application: the slave's memory is the ECU itself, its
 * calibration segment the tuning block vh_ecu_cal_t (see vh_ecu_xcp.h). */
#include <math.h>
#include <string.h>

#include "vh_ecu.h"
#include "vh_ecu_xcp_table.inc" /* generated: VH_ECU_XCP_CHARS (limits, safety classes), VH_ECU_XCP_REGIONS */

typedef char vh_ecu_xcp_regions_fit[(VH_ECU_XCP_N_REGIONS <= VH_XCP_MAX_REGIONS) ? 1 : -1];

#define EXT_BIT 0x80000000u /* XCP-on-CAN convention: bit 31 of an identifier = 29-bit */

/* The roll tuning: one list of the members, for gather and apply (the same names on both sides). */
#define ROLL_UKF_SCALARS(X) X(reg_eps) X(nis_max) X(phi_max)
#define ROLL_SMC_SCALARS(X) X(lambda) X(k) X(p) X(ref_frac) X(ref_tau) X(ay_tau) X(front_share) \
    X(m_max_f) X(m_max_r) X(rate_max_f) X(rate_max_r) X(fade_time) X(recover_time) X(not_ok_debounce)

static void roll_gather(const vh_roll_app_config_t *cfg, vh_ecu_cal_roll_t *c)
{
    memcpy(c->ukf.q, cfg->ukf.q, sizeof c->ukf.q);
    memcpy(c->ukf.r, cfg->ukf.r, sizeof c->ukf.r);
    memcpy(c->ukf.p0, cfg->ukf.p0, sizeof c->ukf.p0);
#define GET_UKF(m) c->ukf.m = cfg->ukf.m;
#define GET_SMC(m) c->smc.m = cfg->smc.m;
    ROLL_UKF_SCALARS(GET_UKF)
    ROLL_SMC_SCALARS(GET_SMC)
    c->stuck_samples = cfg->stuck_samples;
}

/* Into the configuration (vh_roll_app_reset starts from it) and into the running float32 UKF and
 * SMC, converted as their inits convert (a plain cast): the same as a start with these values.
 * Nothing of the filters derives from these at init, except p0, which only a reset reads. */
static void roll_apply(vh_roll_app_config_t *cfg, vh_roll_app_t *a, const vh_ecu_cal_roll_t *c)
{
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

void vh_ecu_cal_gather(const vh_ecu_t *ecu, vh_ecu_cal_t *c)
{
    int i;
    memset(c, 0, sizeof *c); /* padding too: the pages compare and upload byte for byte */
    for (i = 0; i < VH_ECU_N_DKF; ++i) {
        memcpy(c->dkf[i].q, ecu->cfg.dkf[i].q, sizeof c->dkf[i].q);
        memcpy(c->dkf[i].r, ecu->cfg.dkf[i].r, sizeof c->dkf[i].r);
        c->dkf[i].p_max = ecu->cfg.dkf[i].p_max;
    }
    memcpy(c->skf.q, ecu->chs.skf.prm.q, sizeof c->skf.q);
    memcpy(c->skf.r, ecu->chs.skf.prm.r, sizeof c->skf.r);
    c->we_min = ecu->cfg.we_min;
    c->camber_still_ww = ecu->cfg.camber_still_ww;
    c->camber_mag_tol_g = ecu->cfg.camber.mag_tol_g;
    c->camber_std_max_g = ecu->cfg.camber.std_max_g;
    c->rx_burst_frames = ecu->cfg.rx_burst_frames;
    roll_gather(&ecu->cfg.roll, &c->roll);
}

/* Into the configuration (so vh_ecu_reset keeps it) and into the running filters. The values
 * are within the A2L limits (the slave checked them), which keep every filter's init checks. */
void vh_ecu_cal_apply(vh_ecu_t *ecu, const vh_ecu_cal_t *c)
{
    int i;
    for (i = 0; i < VH_ECU_N_DKF; ++i) {
        vh_dkf_config_t *cfg[2];
        int k;
        cfg[0] = &ecu->cfg.dkf[i];
        cfg[1] = &ecu->dkf[i].cfg;
        for (k = 0; k < 2; ++k) {
            memcpy(cfg[k]->q, c->dkf[i].q, sizeof c->dkf[i].q);
            memcpy(cfg[k]->r, c->dkf[i].r, sizeof c->dkf[i].r);
            cfg[k]->p_max = c->dkf[i].p_max;
        }
    }
    memcpy(ecu->chs.skf.prm.q, c->skf.q, sizeof c->skf.q); /* vh_tf_app_reset restarts from prm */
    memcpy(ecu->chs.skf.prm.r, c->skf.r, sizeof c->skf.r);
    ecu->cfg.we_min = c->we_min;
    ecu->cfg.camber_still_ww = c->camber_still_ww;
    ecu->cfg.camber.mag_tol_g = c->camber_mag_tol_g;
    ecu->cfg.camber.std_max_g = c->camber_std_max_g;
    for (i = 0; i < VH_ECU_N_WHEELS; ++i) {
        ecu->cis.cmb[i].cfg.mag_tol_g = c->camber_mag_tol_g;
        ecu->cis.cmb[i].cfg.std_max_g = c->camber_std_max_g;
    }
    ecu->cfg.rx_burst_frames = c->rx_burst_frames;
    roll_apply(&ecu->cfg.roll, &ecu->roll, &c->roll);
}

int vh_ecu_xcp_enable(vh_ecu_t *ecu, const vh_ecu_xcp_config_t *cfg)
{
    vh_ecu_xcp_t *a = &ecu->xcp;
    vh_xcp_config_t s;
    unsigned i;
    if (cfg->key == NULL) {
        return VH_EINVAL; /* no key, no XCP: nothing here works without the user's key */
    }
    memset(a, 0, sizeof *a);
    vh_ecu_cal_gather(ecu, &a->ref);
    for (i = 0; i < VH_ECU_XCP_N_REGIONS; ++i) { /* the described members only, never the whole instance */
        a->regions[i].address = VH_ECU_XCP_MEAS_ADDRESS + VH_ECU_XCP_REGIONS[i].offset;
        a->regions[i].size = VH_ECU_XCP_REGIONS[i].size;
        a->regions[i].access = VH_XCP_ACC_READ | VH_XCP_ACC_DAQ;
        a->regions[i].mem = (const uint8_t *)ecu + VH_ECU_XCP_REGIONS[i].offset;
    }
    /* cycle in units of 10 us (4) or 100 us (5): 500 us, 1 ms, 10 ms */
    a->events[0].name = "tick";
    a->events[0].cycle = 50u;
    a->events[0].unit = 4u;
    a->events[1].name = "1ms";
    a->events[1].cycle = 100u;
    a->events[1].unit = 4u;
    a->events[2].name = "10ms";
    a->events[2].cycle = 100u;
    a->events[2].unit = 5u;
    memset(&s, 0, sizeof s);
    s.cro_id = cfg->cro_id;
    s.dto_id = cfg->dto_id;
    s.max_cto = cfg->max_cto;
    s.max_dto = cfg->max_dto;
    s.fd = cfg->fd;
    s.protect = VH_XCP_RES_CALPAG | VH_XCP_RES_DAQ;
    s.key = cfg->key;
    memcpy(s.salt, cfg->salt, sizeof s.salt);
    s.unlock_delay_ticks = VH_ECU_XCP_UNLOCK_DELAY_TICKS;
    s.unlock_attempts = VH_ECU_XCP_UNLOCK_ATTEMPTS;
    s.safe = &a->safe;
    s.tick_us = VH_TICK_US;
    s.open_ticks = 200u; /* 100 ms: an array edited in the middle commits without its last byte */
    s.regions = a->regions;
    s.n_regions = (uint8_t)VH_ECU_XCP_N_REGIONS;
    s.cal_address = VH_ECU_XCP_CAL_ADDRESS;
    s.cal_size = (uint32_t)sizeof(vh_ecu_cal_t);
    s.cal_ref = (const uint8_t *)&a->ref;
    s.cal_work = (uint8_t *)&a->work;
    s.cal_ecu = (uint8_t *)&a->page;
    s.chars = VH_ECU_XCP_CHARS;
    s.n_chars = VH_ECU_XCP_N_CHARS;
    s.events = a->events;
    s.n_events = VH_ECU_XCP_N_EVENTS;
    s.id_ascii = "vehest-can ECU";
    s.id_a2l = VH_ECU_XCP_A2L_NAME;
    if ((cfg->cro_id & ~EXT_BIT) == (cfg->dto_id & ~EXT_BIT) || vh_xcp_init(&a->slave, &s) != VH_XCP_OK) {
        memset(a, 0, sizeof *a);
        return VH_EINVAL;
    }
    a->own_bus = cfg->own_bus ? 1u : 0u;
    a->cal_mode = cfg->cal_mode ? 1u : 0u;
    a->enabled = 1u;
    return VH_OK;
}

/* A frame on the CRO or DTO identifier heard on `own` (the XCP bus) or the vehicle bus. */
static int xcp_rx(vh_ecu_t *ecu, const vh_frame_t *f, int own)
{
    vh_ecu_xcp_t *a = &ecu->xcp;
    const uint32_t id = f->id | (((f->flags & VH_FRAME_EXT) != 0u) ? EXT_BIT : 0u);
    if (!a->enabled || (id != a->slave.cfg.cro_id && id != a->slave.cfg.dto_id)) {
        return 0;
    }
    if (id == a->slave.cfg.cro_id) {
        if (a->own_bus && !own) {
            a->slave.n.cro_foreign++; /* the slave listens on its own bus only: not answered */
        } else {
            vh_xcp_rx(&a->slave, f->data, f->len, a->ticks);
        }
    } /* else our own RES/DTO heard back (a loopback bus): known, not input, like our DBC TX */
    return 1;
}

int vh_ecu_xcp_rx(vh_ecu_t *ecu, const vh_frame_t *f) { return xcp_rx(ecu, f, 0); }

int vh_ecu_xcp_rx_own(vh_ecu_t *ecu, const vh_frame_t *f) { return xcp_rx(ecu, f, 1); }

/* The safe state of this tick, decided here (the ECU's, not the host's): see vh_ecu_xcp.h. */
static uint8_t safe_state(vh_ecu_t *ecu)
{
    vh_ecu_xcp_t *a = &ecu->xcp;
    const int dls = !ecu->drv.dls.rx.timed_out, chs = !ecu->roll.rx[VH_ROLL_RX_CHS].timed_out;
    const int passive = ecu->roll.smc.fade <= 0.0f && ecu->roll.smc.m_f == 0.0f && ecu->roll.smc.m_r == 0.0f;
    int still;
    a->heard = (uint8_t)(a->heard | (dls ? 1u : 0u) | (chs ? 2u : 0u));
    /* a source heard once and silent now is unknown, not still */
    still = (dls ? vh_drv_app_still(&ecu->drv, VH_ECU_XCP_STILL_WW) : !(a->heard & 1u)) &&
            (chs ? (ecu->roll.u_ok && fabsf(ecu->roll.vx) < (float)VH_ECU_XCP_STILL_VX) : !(a->heard & 2u));
    return (uint8_t)(passive && (still || a->cal_mode));
}

void vh_ecu_xcp_tick(vh_ecu_t *ecu)
{
    vh_ecu_xcp_t *a = &ecu->xcp;
    if (!a->enabled) {
        return;
    }
    if (a->cal_mode) {
        ecu->roll.mode_active = 0u; /* calibration mode: the roll actuators passive (before roll steps) */
    }
    a->safe = safe_state(ecu);
    vh_xcp_tick(&a->slave, a->ticks);
    if (a->slave.n.cal_commits != a->applied || a->slave.page_ecu != a->applied_page) {
        vh_ecu_cal_apply(ecu, &a->page);
        a->applied = a->slave.n.cal_commits;
        a->applied_page = a->slave.page_ecu;
    }
}

void vh_ecu_xcp_event(vh_ecu_t *ecu, uint16_t channel)
{
    if (ecu->xcp.enabled) {
        vh_xcp_event(&ecu->xcp.slave, channel);
    }
}

size_t vh_ecu_xcp_tx(vh_ecu_t *ecu, vh_frame_t *tx, size_t n, size_t cap)
{
    vh_ecu_xcp_t *a = &ecu->xcp;
    size_t sent = 0u;
    vh_xcp_frame_t x;
    if (!a->enabled) {
        return n;
    }
    ++a->ticks;
    while (n < cap && sent < VH_ECU_XCP_MAX_TX && vh_xcp_tx_pop(&a->slave, &x)) {
        vh_frame_t *f = &tx[n++];
        f->id = x.id & ~EXT_BIT;
        f->len = x.len;
        f->flags = (uint8_t)((x.ext ? VH_FRAME_EXT : 0u) | (x.fd ? VH_FRAME_FD : 0u));
        memset(f->data, 0, sizeof f->data);
        memcpy(f->data, x.data, x.len);
        ++sent;
    }
    return n;
}
