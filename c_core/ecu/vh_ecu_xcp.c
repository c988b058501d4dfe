/* vh_ecu_xcp.c - the ECU's XCP application: the slave's memory is the ECU itself, its
 * calibration segment the tuning block vh_ecu_cal_t (see vh_ecu_xcp.h). */
#include <string.h>

#include "vh_ecu.h"
#include "vh_ecu_xcp_table.inc" /* generated: VH_ECU_XCP_CHARS (limits, safety classes), VH_ECU_XCP_REGIONS */

typedef char vh_ecu_xcp_regions_fit[(VH_ECU_XCP_N_REGIONS <= VH_XCP_MAX_REGIONS) ? 1 : -1];

#define EXT_BIT 0x80000000u /* XCP-on-CAN convention: bit 31 of an identifier = 29-bit */

typedef char vh_ecu_xcp_heard_fits[(VH_ECU_N_APPS <= 8) ? 1 : -1]; /* a bit each in heard */

void vh_ecu_cal_gather(const vh_ecu_t *ecu, vh_ecu_cal_t *c)
{
    memset(c, 0, sizeof *c); /* padding too: the pages compare and upload byte for byte */
#define GATHER(m) vh_##m##_app_cal_gather(&ecu->app.m, &c->app.m);
    VH_ECU_APPS(GATHER)
#undef GATHER
    c->rx_burst_frames = ecu->rx_burst_frames;
}

/* Into each application's configuration (so vh_ecu_reset keeps it) and its running filters. The
 * values are within the A2L limits (the slave checked them), which keep every filter's init checks. */
void vh_ecu_cal_apply(vh_ecu_t *ecu, const vh_ecu_cal_t *c)
{
#define APPLY(m) vh_##m##_app_cal_apply(&ecu->app.m, &c->app.m);
    VH_ECU_APPS(APPLY)
#undef APPLY
    ecu->rx_burst_frames = c->rx_burst_frames;
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

/* The safe state of this tick, decided here (the ECU's, not the host's): see vh_ecu_xcp.h. In
 * calibration mode each application holds its actuators passive first (before any of them steps). */
static uint8_t safe_state(vh_ecu_t *ecu)
{
    vh_ecu_xcp_t *a = &ecu->xcp;
    unsigned s[VH_ECU_N_APPS], i = 0u;
    int passive = 1, still = 1;
#define SAFETY(m) s[i++] = vh_##m##_app_safety(&ecu->app.m, a->cal_mode);
    VH_ECU_APPS(SAFETY)
#undef SAFETY
    for (i = 0u; i < VH_ECU_N_APPS; ++i) {
        const uint8_t bit = (uint8_t)(1u << i);
        if (s[i] & VH_APP_ACTIVE) {
            passive = 0;
        }
        if (!(s[i] & VH_APP_SPEED)) {
            continue;
        }
        if (s[i] & VH_APP_SPEED_LIVE) {
            a->heard = (uint8_t)(a->heard | bit);
            still = still && (s[i] & VH_APP_STILL) != 0u;
        } else {
            still = still && !(a->heard & bit); /* a source heard once and silent now is unknown, not still */
        }
    }
    return (uint8_t)(passive && (still || a->cal_mode));
}

void vh_ecu_xcp_tick(vh_ecu_t *ecu)
{
    vh_ecu_xcp_t *a = &ecu->xcp;
    if (!a->enabled) {
        return;
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
