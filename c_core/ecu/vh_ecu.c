/* vh_ecu.c - the ECU scheduler: the applications' descriptors (vh_ecu_apps.inc) expanded into the
 * RX table and the runnable table; dispatch by frame ID, the runnables at their rates, the counters. */
#include <string.h>

#include "vh_ch.h"
#include "vh_ch_meta.h"
#include "vh_ecu.h"
#include "vh_pt.h"
#include "vh_pt_meta.h"
#include "vh_sim_meta.h"

/* Ticks per cycle of a message; the meta headers refuse a cycle that is not whole ticks. */
#define TICKS(cycle_us) ((cycle_us) / VH_TICK_US)
#define VH_CYCLE_TICKS(MSG) TICKS(MSG##_CYCLE_TIME_US)

/* the XCP items are c_core/ecu_gen.py's (into the XCP description): nothing here */
#define VH_APP_MEAS(m, path, fields, comment)
#define VH_APP_CAL(m, path, fields, comment)

typedef void (*rx_fn_t)(vh_ecu_t *ecu, vh_app_ctx_t *ctx, const vh_frame_t *f);
typedef void (*step_fn_t)(vh_ecu_t *ecu, vh_app_ctx_t *ctx);
typedef int (*fill_fn_t)(vh_ecu_t *ecu, vh_app_ctx_t *ctx, uint8_t *data);

/* ---- the descriptors, expanded (each block defines the four entry macros, includes the list and
 * undefines them) ---- */
/* 1. each entry point as a function of the ECU: the one place that knows an application's member
 * of vh_ecu_t.app */
#define VH_APP(m, order) \
    static void rx_##m(vh_ecu_t *e, vh_app_ctx_t *c, const vh_frame_t *f) { vh_##m##_app_rx(&e->app.m, c, f); }
#define VH_APP_RX(m, id)
#define VH_APP_STEP(m, fn, period) \
    static void run_##m##_##fn(vh_ecu_t *e, vh_app_ctx_t *c) { vh_##m##_app_##fn(&e->app.m, c); }
#define VH_APP_TX(m, fn, MSG, period) \
    static int tx_##m##_##fn(vh_ecu_t *e, vh_app_ctx_t *c, uint8_t *d) { return vh_##m##_app_##fn(&e->app.m, c, d); }
#include "vh_ecu_apps.inc"
#undef VH_APP
#undef VH_APP_RX
#undef VH_APP_STEP
#undef VH_APP_TX

/* 2. the applications' TX frames: room for them in a tick's TX beside SecOC's and XCP's */
#define VH_APP(m, order)
#define VH_APP_RX(m, id)
#define VH_APP_STEP(m, fn, period)
#define VH_APP_TX(m, fn, MSG, period) +1
enum { N_APP_TX = 0
#include "vh_ecu_apps.inc"
};
typedef char vh_ecu_tx_room_check[(VH_ECU_MAX_TX >= N_APP_TX + 2 + VH_ECU_XCP_MAX_TX) ? 1 : -1];
#undef VH_APP
#undef VH_APP_RX
#undef VH_APP_STEP
#undef VH_APP_TX

/* 3. RX: every application that receives an ID, in the applications' order */
#define VH_APP(m, order)
#define VH_APP_RX(m, id) {(id), rx_##m},
#define VH_APP_STEP(m, fn, period)
#define VH_APP_TX(m, fn, MSG, period)
static const struct {
    uint32_t id;
    rx_fn_t rx;
} RX_TABLE[] = {
#include "vh_ecu_apps.inc"
};
#undef VH_APP
#undef VH_APP_RX
#undef VH_APP_STEP
#undef VH_APP_TX

/* XCP: calibration reaches the applications at the tick boundary, before any of them steps; DAQ
 * samples after all of them, on the event channels 0 (tick), 1 (1 ms), 2 (10 ms) */
static void xcp_tick(vh_ecu_t *ecu, vh_app_ctx_t *c) { (void)c; vh_ecu_xcp_tick(ecu); }
static void xcp_ev_tick(vh_ecu_t *ecu, vh_app_ctx_t *c) { (void)c; vh_ecu_xcp_event(ecu, 0u); }
static void xcp_ev_1ms(vh_ecu_t *ecu, vh_app_ctx_t *c) { (void)c; vh_ecu_xcp_event(ecu, 1u); }
static void xcp_ev_10ms(vh_ecu_t *ecu, vh_app_ctx_t *c) { (void)c; vh_ecu_xcp_event(ecu, 2u); }

/* 4. the runnables: a step (step != NULL) or a TX frame (fill: its payload; 0 = nothing to send
 * this time), run in this order every period_ticks ticks (at tick 0, then each multiple) */
#define VH_APP(m, order)
#define VH_APP_RX(m, id)
#define VH_APP_STEP(m, fn, period) {run_##m##_##fn, NULL, 0u, 0u, 0u, (period)},
#define VH_APP_TX(m, fn, MSG, period) {NULL, tx_##m##_##fn, MSG##_FRAME_ID, MSG##_LENGTH, MSG##_IS_FD, (period)},
static const struct {
    step_fn_t step;
    fill_fn_t fill;
    uint32_t id;
    uint8_t len, is_fd;
    uint32_t period_ticks;
} RUNNABLES[] = {
    {xcp_tick, NULL, 0u, 0u, 0u, 1u},
#include "vh_ecu_apps.inc"
    {xcp_ev_tick, NULL, 0u, 0u, 0u, 1u},
    {xcp_ev_1ms, NULL, 0u, 0u, 0u, TICKS(1000u)},
    {xcp_ev_10ms, NULL, 0u, 0u, 0u, TICKS(10000u)},
};
#undef VH_APP
#undef VH_APP_RX
#undef VH_APP_STEP
#undef VH_APP_TX

static vh_app_ctx_t ctx_of(vh_ecu_t *ecu)
{
    vh_app_ctx_t c;
    c.cnt = &ecu->cnt;
    c.sig = &ecu->sig;
    c.tick = ecu->tick;
    c.burst_limit = ecu->rx_burst_frames;
    return c;
}

int vh_ecu_init_params(vh_ecu_t *ecu, const vh_ecu_config_t *cfg)
{
#define CHECK(m) || vh_##m##_app_check(&cfg->app.m) != VH_OK
    if (0 VH_ECU_APPS(CHECK)) {
        return VH_EINVAL;
    }
#undef CHECK
    memset(ecu, 0, sizeof *ecu); /* SecOC off */
#define INIT(m) vh_##m##_app_init(&ecu->app.m, &cfg->app.m);
    VH_ECU_APPS(INIT)
#undef INIT
    ecu->rx_burst_frames = cfg->rx_burst_frames;
    return VH_OK;
}

void vh_ecu_reset(vh_ecu_t *ecu)
{
#define RESET(m) vh_##m##_app_reset(&ecu->app.m);
    VH_ECU_APPS(RESET)
#undef RESET
    memset(&ecu->cnt, 0, sizeof ecu->cnt);
    memset(&ecu->sig, 0, sizeof ecu->sig);
    ecu->tick = 0u;
    if (ecu->secoc != NULL) {
        vh_secoc_bus_resync(ecu->secoc);
    }
}

void vh_ecu_rx(vh_ecu_t *ecu, const vh_frame_t *frame)
{
    size_t i;
    int taken = 0;
    vh_frame_t verified;
    vh_app_ctx_t ctx;
    /* SecOC before any application sees the frame: a rejected one is counted, a sync frame is its own */
    const vh_secoc_bus_result_t sr = ecu->secoc != NULL ? vh_secoc_bus_rx(ecu->secoc, frame, &verified) : VH_SECOC_BUS_PASS;
    if (sr == VH_SECOC_BUS_REJECTED) {
        vh_rx_count(&ecu->cnt.secoc_reject);
    }
    if (sr != VH_SECOC_BUS_PASS && sr != VH_SECOC_BUS_OK) {
        return;
    }
    frame = sr == VH_SECOC_BUS_OK ? &verified : frame;
    ctx = ctx_of(ecu);
    for (i = 0; i < sizeof RX_TABLE / sizeof RX_TABLE[0]; ++i) {
        if (RX_TABLE[i].id == frame->id) {
            RX_TABLE[i].rx(ecu, &ctx, frame);
            taken = 1;
        }
    }
    /* a known frame not the ECU's input (its own TX, the lockstep frames: vehest_sim.dbc, SecOC sync
     * frames when SecOC is off); the XCP CRO identifier is configuration, not in the DBC */
    if (!taken && !VH_PT_KNOWN_ID(frame->id) && !VH_CH_KNOWN_ID(frame->id) && !VH_SIM_KNOWN_ID(frame->id) && !vh_ecu_xcp_rx(ecu, frame)) {
        vh_rx_count(&ecu->cnt.unknown_id);
    }
}

size_t vh_ecu_step(vh_ecu_t *ecu, vh_frame_t *tx, size_t cap)
{
    size_t i, n = 0u;
    vh_app_ctx_t ctx = ctx_of(ecu);
    for (i = 0; i < sizeof RUNNABLES / sizeof RUNNABLES[0]; ++i) {
        if (ecu->tick % RUNNABLES[i].period_ticks != 0u) {
            continue;
        }
        ctx.burst_limit = ecu->rx_burst_frames; /* XCP's tick may have calibrated it */
        if (RUNNABLES[i].step != NULL) {
            RUNNABLES[i].step(ecu, &ctx);
        } else {
            vh_frame_t *f = vh_tx_slot(tx, &n, cap, RUNNABLES[i].id, RUNNABLES[i].len, RUNNABLES[i].is_fd);
            if (f != NULL && !RUNNABLES[i].fill(ecu, &ctx, f->data)) {
                --n; /* nothing to send: the slot is free again */
            }
        }
    }
    if (ecu->secoc != NULL) { /* the applications' frames secured, sync frames when due */
        n = vh_secoc_bus_tx(ecu->secoc, tx, n, cap);
    }
    n = vh_ecu_xcp_tx(ecu, tx, n, cap);
    ++ecu->tick;
    return n;
}

void vh_ecu_set_secoc(vh_ecu_t *ecu, vh_secoc_bus_t *s) { ecu->secoc = s; }

void vh_ecu_note_deadline_miss(vh_ecu_t *ecu, uint32_t n) { ecu->cnt.deadline_miss = vh_sat_add_u32(ecu->cnt.deadline_miss, n); }
