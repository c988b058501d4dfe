/* SecOC-style authenticated frames (AUTOSAR SWS SecOC, CMAC/AES-128 profile 1 layout on the bus:
 * 24-bit truncated MAC, 8-bit truncated freshness value), with a counter-based freshness manager.
 *
 * Secured frame = authentic part | truncated FV (1 byte) | truncated MAC (3 bytes)   (SWS_SecOC_00037)
 * MAC = CMAC-AES-128(key, data ID (16 bit, big endian) | authentic part | full FV (64 bit, big
 *       endian))                                                                 (SWS_SecOC_00031)
 * truncated to its most significant 24 bits; the truncated FV is the full FV's 8 least significant
 * bits. Each sending node keeps one 64-bit counter, incremented for every secured frame it sends,
 * so a receiver reconstructs the full FV from the latest one it accepted from that node.
 * No heap; every state is caller-owned. See docs/secoc.md. */
#ifndef VH_SECOC_H
#define VH_SECOC_H

#include <stdint.h>

#include "vh_cmac.h"

#define VH_SECOC_FV_TX_BITS 8
#define VH_SECOC_MAC_TX_BYTES 3
#define VH_SECOC_TAIL_BYTES 4       /* truncated FV + truncated MAC */
#define VH_SECOC_MAX_AUTHENTIC 60   /* a CAN FD frame of 64 bytes less the tail */
#define VH_SECOC_VERIFY_ATTEMPTS 4  /* FV candidates tried per frame (SecOCAuthenticationVerifyAttempts) */
#define VH_SECOC_SYNC_AUTHENTIC 8   /* a sync frame's authentic part: the sender's full FV */

typedef enum {
    VH_SECOC_OK = 0,
    VH_SECOC_E_MAC = 1,       /* no candidate FV gives this MAC: spoofed, corrupted, or lost sync */
    VH_SECOC_E_REPLAY = 2,    /* the MAC is right for an FV already used: a replayed frame */
    VH_SECOC_E_UNSYNCED = 3,  /* the receiver has no freshness base for this sender: wait for a sync frame */
    VH_SECOC_E_LENGTH = 4,    /* authentic part longer than VH_SECOC_MAX_AUTHENTIC */
    VH_SECOC_E_EXHAUSTED = 5  /* sender: the persisted FV reservation is used up, nothing sent */
} vh_secoc_result_t;

/* A sending node's freshness. fv may only be used below reserved_until, the bound the host has
 * stored persistently (so a restart resumes above every FV ever sent). */
typedef struct {
    uint64_t fv;             /* the next FV to send */
    uint64_t reserved_until; /* first FV not yet covered by the persisted reservation */
    uint32_t sent;
    uint32_t exhausted;      /* frames refused for want of a reservation */
} vh_secoc_tx_t;

/* A receiver's view of one sending node. Counters are 32-bit and saturate. */
typedef struct {
    uint64_t latest;         /* the latest FV accepted from this sender */
    uint8_t synced;          /* 0: no freshness base yet, only a sync frame is accepted */
    uint32_t accepted;
    uint32_t bad_mac;
    uint32_t replayed;
    uint32_t unsynced;
    uint32_t resyncs;
} vh_secoc_rx_t;

void vh_secoc_tx_init(vh_secoc_tx_t *tx, uint64_t fv_start, uint64_t reserved_until);
/* Moves the reservation bound up once the host has stored it. */
void vh_secoc_tx_reserve(vh_secoc_tx_t *tx, uint64_t reserved_until);

/* Receiver state: synced from a restored latest FV (e.g. the host's state file), or not. */
void vh_secoc_rx_init(vh_secoc_rx_t *rx, uint64_t latest, int synced);

/* The full 128-bit CMAC of (data ID | authentic | fv). */
void vh_secoc_mac(const vh_cmac_key_t *k, uint16_t data_id, const uint8_t *authentic, uint8_t len,
                  uint64_t fv, uint8_t mac[VH_AES_BLOCK]);

/* Writes the tail after frame[0..len) (the frame holds len + VH_SECOC_TAIL_BYTES bytes) with the
 * sender's next FV, which it then consumes. */
vh_secoc_result_t vh_secoc_protect(vh_secoc_tx_t *tx, const vh_cmac_key_t *k, uint16_t data_id,
                                   uint8_t *frame, uint8_t len);

/* Checks a secured frame of len + VH_SECOC_TAIL_BYTES bytes; on OK, *fv_out is its full FV and the
 * receiver's latest moves to it. Nothing of a frame that is not OK may be used. */
vh_secoc_result_t vh_secoc_verify(vh_secoc_rx_t *rx, const vh_cmac_key_t *k, uint16_t data_id,
                                  const uint8_t *frame, uint8_t len, uint64_t *fv_out);

/* A sync frame: authentic part = the sender's full FV (8 bytes, big endian), secured like any frame
 * (its FV is that value itself). frame holds VH_SECOC_SYNC_AUTHENTIC + VH_SECOC_TAIL_BYTES bytes. */
vh_secoc_result_t vh_secoc_sync_build(vh_secoc_tx_t *tx, const vh_cmac_key_t *k, uint16_t data_id,
                                      uint8_t *frame);
/* Accepts a sync frame whose MAC is right and whose FV is above the receiver's latest (also when
 * unsynced: the latest restored from storage, or 0; senders start at FV 1) and moves the receiver
 * to it: the way back after more than VH_SECOC_VERIFY_ATTEMPTS * 256 lost frames of a sender, or a
 * receiver restarted without its state. Failures never unsynchronise a receiver (a flood of forged
 * frames cannot lock it out). */
vh_secoc_result_t vh_secoc_sync_accept(vh_secoc_rx_t *rx, const vh_cmac_key_t *k, uint16_t data_id,
                                       const uint8_t *frame);

#endif
