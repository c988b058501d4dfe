/* vh_rx.h - what every ECU application shares on the bus: the RX checks of one cyclic message
 * (length, AUTOSAR E2E, burst, timeout), the saturating fault counters and a TX slot.
 *
 * Each application owns its messages' vh_ecu_rxmsg_t and counts into the counters of its bus;
 * the checks and their order are the same for every message.
 */
#ifndef VH_RX_H
#define VH_RX_H

#include "vh_e2e.h"
#include "vh_types.h"

/* Default burst limit: more good frames of one message in a tick than this is a burst (a sender's
 * transmit queue draining after the bus was blocked, i.e. samples that may be far older than they
 * look: their CRC and counters are fine). Two allows one late frame plus the on-time one. */
#define VH_ECU_BURST_FRAMES 2u

/* Fault counters, uint32, saturating at UINT32_MAX (vh_sat_add_u32: never wrapping). On the bus
 * each is a 16-bit field that saturates at 65535, and the status frame's CntSaturated bit says a
 * counter of it reached its field's maximum (vh_sat_field_u32); XCP and the host read all 32 bits. */
typedef struct {
    uint32_t crc_error;
    uint32_t counter_repeat;
    uint32_t counter_skip;
    uint32_t dlc_error;
    uint32_t timeout;
    uint32_t unknown_id;
    uint32_t signal_invalid;
    uint32_t input_invalid;
    uint32_t filter_reset;
    uint32_t deadline_miss;
    uint32_t rx_burst;
    uint32_t saturation; /* fixed-point SKFMEC steps that saturated (chassis only) */
    uint32_t secoc_reject; /* secured frames that failed SecOC (both buses; powertrain counters only) */
} vh_ecu_counters_t;

/* Reception state of one cyclic message: E2E, freshness, timeout. */
typedef struct {
    vh_e2e_rx_t e2e;
    uint16_t age;      /* ticks since the last good frame */
    uint16_t resync;   /* ticks until the data is trusted again after a burst */
    uint8_t fresh;     /* a good frame arrived since the last tick */
    uint8_t n_tick;    /* good frames since the last tick */
    uint8_t timed_out; /* no good frame for the message's timeout (set at start) */
} vh_ecu_rxmsg_t;

/* Add one to a counter, saturating (vh_sat_add_u32). */
void vh_rx_count(uint32_t *c);
/* Nothing received yet: timed out (not counted as a fault). */
void vh_rx_init(vh_ecu_rxmsg_t *m);
/* Length and E2E checks of one received frame, counted; 1 if its data may be used. */
int vh_rx_accept(vh_ecu_counters_t *cnt, vh_ecu_rxmsg_t *m, const vh_frame_t *f, size_t len,
                 const vh_e2e_cfg_t *e2e);
/* Once per tick: age, timeout (counted on entry), cleared by a fresh frame; more than burst_limit
 * frames in a tick (0 = no limit) make the message untrusted until it has been regular for its
 * timeout. Returns 1 when the frames of this tick may be used. Does not clear `fresh`. */
int vh_rx_tick(vh_ecu_counters_t *cnt, vh_ecu_rxmsg_t *m, unsigned timeout_ticks, unsigned burst_limit);
/* The next TX slot with its header set and its payload zeroed, or NULL when tx[0..cap) is full;
 * *n counts the slot. The caller packs the payload and protects it (vh_e2e_protect). */
vh_frame_t *vh_tx_slot(vh_frame_t *tx, size_t *n, size_t cap, uint32_t id, size_t len, unsigned is_fd);

#endif /* VH_RX_H */
