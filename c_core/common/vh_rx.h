/* vh_rx.h - what every ECU application shares on the bus: the RX checks of one cyclic message
 * (length, AUTOSAR E2E, burst, timeout), the wrapping fault counters and a TX slot.
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

/* Fault counters, uint16 as on the bus, wrapping modulo 2^16 (never stuck at a limit): a reader
 * takes the difference of two readings modulo 65536, which is exact while fewer than 65536 counts
 * happen between them; the host accumulates those differences into wide totals
 * (vehest_can.systems.ecu). */
typedef struct {
    uint16_t crc_error;
    uint16_t counter_repeat;
    uint16_t counter_skip;
    uint16_t dlc_error;
    uint16_t timeout;
    uint16_t unknown_id;
    uint16_t signal_invalid;
    uint16_t input_invalid;
    uint16_t filter_reset;
    uint16_t deadline_miss;
    uint16_t rx_burst;
    uint16_t saturation; /* fixed-point SKFMEC steps that saturated (chassis only) */
    uint16_t secoc_reject; /* secured frames that failed SecOC (both buses; powertrain counters only) */
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

/* Add one to a counter, modulo 2^16. */
void vh_rx_count(uint16_t *c);
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
