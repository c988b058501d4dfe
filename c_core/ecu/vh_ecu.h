/* vh_ecu.h - the ECU firmware: a thin scheduler over the applications of each system.
 *
 * A pure function of frames and ticks: the caller hands in received frames (vh_ecu_rx) and then
 * calls vh_ecu_step once per 500 us tick, which returns the frames to transmit. No clock, no I/O,
 * no heap: deterministic and replayable from a log.
 *
 * The applications (vh_app.h: one shape for all) are listed by their descriptors, one per system
 * (c_core/<system>/vh_<system>_app.def), gathered by c_core/ecu_gen.py into vh_ecu_apps.h (their
 * state, configuration and calibration structs) and vh_ecu_apps.inc. vh_ecu_rx hands each frame to
 * every application whose descriptor lists its ID (unknown IDs are counted); vh_ecu_step runs the
 * descriptors' runnables in order, each at its rate in ticks (a TX frame's: its DBC cycle time).
 * The applications own their configuration, filters, RX checks, counters, steps and TX. Frame IDs
 * are unique across both DBCs, so frames are told apart by ID.
 */
#ifndef VH_ECU_H
#define VH_ECU_H

#include "vh_app.h"
#include "vh_ecu_apps.h"
#include "vh_ecu_xcp.h"
#include "vh_rx.h"
#include "vh_secoc_bus.h"
#include "vh_types.h"

#define VH_ECU_MAX_TX 16 /* the applications' frames + SecOC's 2 sync frames + VH_ECU_XCP_MAX_TX (checked in vh_ecu.c) */

typedef struct {
    vh_ecu_apps_config_t app;          /* each application's (vh_<m>_app_config_default) */
    uint8_t rx_burst_frames;           /* burst limit per message and tick (VH_ECU_BURST_FRAMES); 0 = off,
                                          for transports that deliver in batches (UML's 100 Hz timer) */
} vh_ecu_config_t;

typedef struct {
    vh_ecu_apps_t app;          /* the applications, each with its configuration, filters and counters */
    vh_ecu_counters_t cnt;      /* the ECU's counters (VEHEST_Status), shared by the apps without their own */
    vh_app_signals_t sig;       /* what an app publishes for those after it */
    uint32_t tick;
    uint8_t rx_burst_frames;
    vh_ecu_xcp_t xcp;           /* the XCP slave (vh_ecu_xcp.h); off until vh_ecu_xcp_enable */
    vh_secoc_bus_t *secoc;      /* SecOC (vh_secoc_bus.h) as node VEHEST, NULL: off. Caller-owned, outside this
                                   struct: the keys stay out of the memory XCP may read. Its freshness survives
                                   vh_ecu_reset (a reset re-sends the sync frames) */
} vh_ecu_t;

/* Host side (vh_ecu_host.c, not flashed): the defaults, and init from a configuration each
 * application completes first (vh_<m>_app_config_host, e.g. fixed-point constants; VH_EINVAL if
 * it does not fit). */
void vh_ecu_config_default(vh_ecu_config_t *cfg);
/* What vh_ecu_init does before the flashed init: each application completes cfg in place (the
 * calibration block a target is sent); VH_EINVAL if one does not fit. */
int vh_ecu_config_complete(vh_ecu_config_t *cfg);
int vh_ecu_init(vh_ecu_t *ecu, const vh_ecu_config_t *cfg);
/* The flashed init: the configuration comes complete (on a target, a calibration block).
 * VH_OK, or VH_EINVAL for an invalid configuration (nothing changed). */
int vh_ecu_init_params(vh_ecu_t *ecu, const vh_ecu_config_t *cfg);
void vh_ecu_reset(vh_ecu_t *ecu);
/* Hand in one received frame; checked and counted now, used at the next vh_ecu_step. With SecOC on, a
 * secured frame is verified first, here for every application; one that fails is counted
 * (cnt.secoc_reject, and by reason in secoc.cnt) and reaches none of them. */
void vh_ecu_rx(vh_ecu_t *ecu, const vh_frame_t *frame);
/* One 500 us tick. Writes up to cap frames to tx; returns how many (VH_ECU_MAX_TX is enough). */
size_t vh_ecu_step(vh_ecu_t *ecu, vh_frame_t *tx, size_t cap);
/* The daemon's wall-clock scheduler reports ticks that started late; published in VEHEST_Status. */
void vh_ecu_note_deadline_miss(vh_ecu_t *ecu, uint32_t n);
/* SecOC on the ECU's frames: s keyed and started as node VEHEST (vh_secoc_bus_init, _set_key,
 * _start), or NULL: off (the default). Survives vh_ecu_reset. */
void vh_ecu_set_secoc(vh_ecu_t *ecu, vh_secoc_bus_t *s);

/* XCP (vh_ecu_xcp.c). Enable the slave on the ECU as configured now (its tuning becomes the
 * reference page); survives vh_ecu_reset, which keeps the calibration. VH_EINVAL: bad config or
 * no key. */
int vh_ecu_xcp_enable(vh_ecu_t *ecu, const vh_ecu_xcp_config_t *cfg);
/* The tuning block of the ECU as configured / into the configuration and the running filters. */
void vh_ecu_cal_gather(const vh_ecu_t *ecu, vh_ecu_cal_t *cal);
void vh_ecu_cal_apply(vh_ecu_t *ecu, const vh_ecu_cal_t *cal);
/* The scheduler's hooks: a frame on the CRO or DTO identifier (1 if it was one), the tick boundary, an event channel,
 * and the XCP frames after the systems' TX (returns the new count). */
int vh_ecu_xcp_rx(vh_ecu_t *ecu, const vh_frame_t *f);
/* A frame heard on the XCP bus of its own (own_bus): its CRO reaches the slave; nothing else there
 * is input of the ECU (1 if it was the CRO or DTO identifier). */
int vh_ecu_xcp_rx_own(vh_ecu_t *ecu, const vh_frame_t *f);
void vh_ecu_xcp_tick(vh_ecu_t *ecu);
void vh_ecu_xcp_event(vh_ecu_t *ecu, uint16_t channel);
size_t vh_ecu_xcp_tx(vh_ecu_t *ecu, vh_frame_t *tx, size_t n, size_t cap);

#endif /* VH_ECU_H */
