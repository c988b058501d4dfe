/* vh_secoc_bus.h - SecOC on the bus: the one RX/TX hook of every node that secures frames (the ECU's
 * scheduler, the plant's roll node). Which frames are secured, their data IDs, authentic lengths and
 * sending nodes come from the DBCs (attribute SecOCDataID; the generated vh_secoc_table.h), so no node
 * names a secured frame.
 *
 * RX: a secured frame is verified (vh_secoc_verify) before any application sees it; a frame that
 * fails is counted and dropped (for the application it is a lost frame), a good one is handed on with
 * its tail zeroed, as its sender's application packed it (the E2E CRC covers those zeros). TX: once
 * per tick, after the applications filled their frames, the node's own secured frames get their tail
 * (its FV counter, one for all of them), and its sync frames (the full FV) go first at 1 Hz and at the
 * first tick after start or a reset. Off (vh_secoc_bus_init) nothing is checked or added: the tails
 * stay zero. No heap; caller-owned state; see docs/secoc.md. */
#ifndef VH_SECOC_BUS_H
#define VH_SECOC_BUS_H

#include "vh_secoc.h"
#include "vh_types.h"

#define VH_SECOC_MAX_NODES 8
#define VH_SECOC_SYNC_PERIOD_TICKS 2000u /* 1 Hz at the 500 us tick */

/* One secured message of the DBCs (generated into vh_secoc_table.h). */
typedef struct {
    uint32_t id;
    uint16_t data_id;
    uint8_t authentic; /* bytes before the tail: the DBC length less VH_SECOC_TAIL_BYTES */
    uint8_t node;      /* its sending node, VH_SECOC_NODE_* */
    uint8_t sync;      /* 1: the node's freshness sync frame */
} vh_secoc_msg_t;

typedef enum {
    VH_SECOC_BUS_PASS = 0,     /* not a secured frame here (or SecOC off): use it as it is */
    VH_SECOC_BUS_OK = 1,       /* verified: use the copy (tail zeroed) */
    VH_SECOC_BUS_CONSUMED = 2, /* a sync frame (accepted, or our own): nothing for the applications */
    VH_SECOC_BUS_REJECTED = 3  /* counted; nothing of it may be used */
} vh_secoc_bus_result_t;

/* Counters since start, 32-bit, saturating. rejected = bad_mac + replayed + unsynced + malformed + no_key. */
typedef struct {
    uint32_t accepted;  /* verified frames handed on */
    uint32_t bad_mac;   /* spoofed, corrupted, or out of reach of the FV window */
    uint32_t replayed;  /* right MAC for an FV already used */
    uint32_t unsynced;  /* no freshness base for that sender yet (waiting for its sync frame) */
    uint32_t malformed; /* wrong length for its DBC message */
    uint32_t no_key;    /* a secured frame of a sender whose key this node lacks */
    uint32_t rejected;
    uint32_t syncs;     /* sync frames accepted */
    uint32_t secured;    /* own frames secured */
    uint32_t tx_dropped; /* own frames not sent: the FV reservation was used up (host did not extend it) */
    uint32_t sync_sent;
} vh_secoc_bus_counters_t;

typedef struct {
    uint8_t on;
    uint8_t self; /* this node, VH_SECOC_NODE_* */
    uint8_t have_key[VH_SECOC_MAX_NODES];
    vh_cmac_key_t key[VH_SECOC_MAX_NODES];
    vh_secoc_tx_t tx;                     /* own freshness */
    vh_secoc_rx_t rx[VH_SECOC_MAX_NODES]; /* each sender's freshness as seen here */
    uint32_t tick;                        /* ticks since start or vh_secoc_bus_resync: sync at 0 */
    vh_secoc_bus_counters_t cnt;
} vh_secoc_bus_t;

/* Off, no keys; `self` is the node's VH_SECOC_NODE_* index. */
void vh_secoc_bus_init(vh_secoc_bus_t *s, unsigned self);
/* The key of a sending node (VH_SECOC_NODE_*); VH_EINVAL for a bad node or a key the cipher refuses. */
int vh_secoc_bus_set_key(vh_secoc_bus_t *s, unsigned node, const uint8_t key[VH_AES_BLOCK]);
/* A receiver restored from stored state: synchronised at `latest` (0: unsynced until a sync frame). */
int vh_secoc_bus_restore_rx(vh_secoc_bus_t *s, unsigned node, uint64_t latest);
/* On: own FVs from fv_start, usable below reserved_until (the host's persisted bound, raised later with
 * vh_secoc_tx_reserve(&s->tx, ...)). VH_EINVAL without the node's own key or with fv_start 0. */
int vh_secoc_bus_start(vh_secoc_bus_t *s, uint64_t fv_start, uint64_t reserved_until);
/* Send the sync frames at the next tick (after a reset of the node: its peers may have restarted). */
void vh_secoc_bus_resync(vh_secoc_bus_t *s);
/* Wipes the keys and switches off. */
void vh_secoc_bus_wipe(vh_secoc_bus_t *s);
/* The VH_SECOC_NODE_* index of a DBC node name, or -1. */
int vh_secoc_bus_node(const char *name);

/* One received frame: PASS (use `in`), OK (use `out`), CONSUMED or REJECTED (use nothing). */
vh_secoc_bus_result_t vh_secoc_bus_rx(vh_secoc_bus_t *s, const vh_frame_t *in, vh_frame_t *out);
/* Once per tick, after the node filled tx[0..n): secures its own frames in place, puts the sync
 * frames first when due (up to cap), drops a frame it cannot secure. Returns the new count. */
size_t vh_secoc_bus_tx(vh_secoc_bus_t *s, vh_frame_t *tx, size_t n, size_t cap);

#endif /* VH_SECOC_BUS_H */
