/* vh_app.h - the one shape of an ECU application: what the scheduler (c_core/ecu/vh_ecu.c) calls
 * and what it shares with each.
 *
 * An application <m> (the member of vh_ecu_t.app, e.g. drv, camber, tf, roll) lives in its
 * system's folder: vh_<m>_app_t (its configuration, filters, RX state and counters, all of it),
 * vh_<m>_app_config_t, vh_<m>_app_cal_t (its share of the XCP calibration segment) and
 *   void vh_<m>_app_config_default(vh_<m>_app_config_t *cfg);   defaults
 *   int  vh_<m>_app_config_host(vh_<m>_app_config_t *cfg);      host only: what the host derives
 *                                                               (VH_OK; VH_EINVAL: does not fit)
 *   int  vh_<m>_app_check(const vh_<m>_app_config_t *cfg);      VH_OK / VH_EINVAL, nothing changed
 *   void vh_<m>_app_init(vh_<m>_app_t *a, const vh_<m>_app_config_t *cfg);  a checked cfg; resets
 *   void vh_<m>_app_reset(vh_<m>_app_t *a);                     restart; configuration survives
 *   void vh_<m>_app_rx(vh_<m>_app_t *a, vh_app_ctx_t *ctx, const vh_frame_t *f);  one of its IDs
 *   void vh_<m>_app_cal_gather(const vh_<m>_app_t *a, vh_<m>_app_cal_t *c);
 *   void vh_<m>_app_cal_apply(vh_<m>_app_t *a, const vh_<m>_app_cal_t *c);  values within limits
 *   unsigned vh_<m>_app_safety(vh_<m>_app_t *a, int hold);      VH_APP_* flags for XCP's safe state
 * and the runnables its descriptor (vh_<system>_app.def) lists, at their rates:
 *   void vh_<m>_app_<step>(vh_<m>_app_t *a, vh_app_ctx_t *ctx);
 *   int  vh_<m>_app_<fill>(vh_<m>_app_t *a, vh_app_ctx_t *ctx, uint8_t *data);  payload; 1: send it
 *
 * The descriptor is an X-macro list (see c_core/ecu/vh_ecu.c for the macros' meaning):
 *   VH_APP(m, order)                 the application; apps run in ascending order
 *   VH_APP_RX(m, frame_id)           a frame ID it receives (an ID may go to several apps)
 *   VH_APP_STEP(m, fn, period)       a runnable every period ticks
 *   VH_APP_TX(m, fn, MSG, period)    a TX frame: the codec's MSG_FRAME_ID, _LENGTH, _IS_FD
 *   VH_APP_MEAS(m, "path", "fields", "comment")  an XCP measurement: a member of vh_<m>_app_t
 *   VH_APP_CAL(m, "path", "fields", "comment")   an XCP characteristic: a member of vh_<m>_app_cal_t
 * VH_CYCLE_TICKS(MSG) is the DBC cycle time of MSG in ticks. The XCP items' fields are the body of
 * a TOML inline table (unit, min, max, factor, offset, elements, class: vehest_can/xcp/ecu_desc.py);
 * c_core/ecu_gen.py gathers them into vehest_can/xcp/ecu.toml under app.<m>.
 */
#ifndef VH_APP_H
#define VH_APP_H

#include "vh_rx.h"
#include "vh_types.h"

/* What one app publishes in its step for the apps after it in the same tick. */
typedef struct {
    double wheel_speed_lp; /* max |wheel speed| low-passed over frames: the stationary gate [rad/s] */
    uint8_t wheel_speed_ok; /* from valid wheel speeds of a message that has not timed out */
} vh_app_signals_t;

/* What the scheduler hands each entry point. */
typedef struct {
    vh_ecu_counters_t *cnt; /* the ECU's counters (VEHEST_Status), for apps without their own */
    vh_app_signals_t *sig;
    uint32_t tick;
    unsigned burst_limit;   /* vh_rx_tick's burst limit (0: off) */
} vh_app_ctx_t;

/* vh_<m>_app_safety: what the XCP slave's safe state needs of an app (hold: the calibration mode,
 * which holds actuators passive; the app does so before it answers). */
enum {
    VH_APP_SPEED = 1,      /* it measures the car's speed */
    VH_APP_SPEED_LIVE = 2, /* ... and that source is live now */
    VH_APP_STILL = 4,      /* ... and says the car stands still */
    VH_APP_ACTIVE = 8      /* its actuators are not passive */
};

#endif /* VH_APP_H */
