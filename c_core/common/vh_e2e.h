/* vh_e2e.h - AUTOSAR E2E protection (E2E Protocol Specification, Profiles 1, 2 and 5).
 *
 * A frame's profile and its parameters come from its DBC (attributes E2EProfile, E2EDataID,
 * E2EDataIDMode, E2EDataIDList; c_core/dbcgen.py writes one vh_e2e_cfg_t per message). Layouts are
 * the profiles' standard variants, which dbcgen checks against the DBC's CRC and counter signals:
 *
 *   P01 (1A/1B/1C)  byte 0 CRC-8 SAE J1850; byte 1 low nibble the counter 0..14; in NIBBLE mode the
 *                   high nibble of byte 1 carries data ID bits 8..11. CRC over the data ID (as the
 *                   mode says) then bytes 1..n-1, start value 0x00, no final XOR (what the chained
 *                   Crc_CalculateCRC8 calls of E2E_P01Protect amount to).
 *   P02             byte 0 CRC-8H2F; byte 1 low nibble the counter 0..15. CRC over bytes 1..n-1 then
 *                   the data ID DataIDList[counter], start 0xFF, final XOR 0xFF.
 *   P05 (CAN FD)    bytes 0..1 CRC-16 CCITT-FALSE, little endian; byte 2 the counter 0..255. CRC over
 *                   bytes 2..n-1 then the data ID (low byte, high byte), start 0xFFFF, no final XOR.
 *
 * The receiver's state machine is the same for every profile: the counter modulo its range.
 */
#ifndef VH_E2E_H
#define VH_E2E_H

#include "vh_types.h"

/* vh_e2e_cfg_t.profile: the profile's number. */
#define VH_E2E_NONE 0
#define VH_E2E_P01 1
#define VH_E2E_P02 2
#define VH_E2E_P05 5

/* vh_e2e_cfg_t.id_mode (P01): how the 16-bit data ID enters the CRC. */
#define VH_E2E_ID_BOTH 0   /* low byte, then high byte */
#define VH_E2E_ID_ALT 1    /* low byte for even counters, high byte for odd ones */
#define VH_E2E_ID_LOW 2    /* low byte only (8-bit data IDs) */
#define VH_E2E_ID_NIBBLE 3 /* low byte, then 0x00; ID bits 8..11 sent in byte 1's high nibble */

typedef struct {
    uint8_t profile;      /* VH_E2E_* */
    uint8_t id_mode;      /* P01: VH_E2E_ID_* */
    uint16_t data_id;     /* P01, P05 */
    uint8_t id_list[16];  /* P02: the data ID of each counter value */
} vh_e2e_cfg_t;

/* CRC-8 SAE J1850: poly 0x1D; `crc` is the running value (no start value or final XOR applied
 * here): vh_crc8_j1850_update(0xFF, "123456789", 9) ^ 0xFF = 0x4B (the check value). */
uint8_t vh_crc8_j1850_update(uint8_t crc, const uint8_t *data, size_t len);
/* CRC-8H2F: poly 0x2F, same convention: update(0xFF, "123456789", 9) ^ 0xFF = 0xDF. */
uint8_t vh_crc8h2f_update(uint8_t crc, const uint8_t *data, size_t len);
/* CRC-16 CCITT-FALSE: poly 0x1021, update(0xFFFF, "123456789", 9) = 0x29B1. */
uint16_t vh_crc16_ccitt_update(uint16_t crc, const uint8_t *data, size_t len);

/* The counter's range: 15 for P01 (0..14), 16 for P02, 256 for P05, 0 unprotected. */
unsigned vh_e2e_counter_range(const vh_e2e_cfg_t *cfg);
/* The counter a protected frame carries (its header must be there: len >= 3, P05 >= 4). */
uint8_t vh_e2e_counter(const vh_e2e_cfg_t *cfg, const uint8_t *payload);

/* Sender: writes the counter (and P01 NIBBLE's ID nibble) and the CRC into payload, advances
 * *counter within the profile's range. Nothing happens for a frame too short for the profile. */
void vh_e2e_protect(const vh_e2e_cfg_t *cfg, uint8_t *payload, size_t len, uint8_t *counter);

typedef enum {
    VH_E2E_OK = 0,        /* CRC right, counter +1 */
    VH_E2E_INITIAL = 1,   /* CRC right, first frame after init: counter taken as reference */
    VH_E2E_REPEATED = 2,  /* CRC right, same counter as before: stale data, not used */
    VH_E2E_SKIPPED = 3,   /* CRC right, counter jumped by more than 1: frames lost, data used */
    VH_E2E_WRONG_CRC = 4, /* CRC wrong (or P01 counter 15, or P01 NIBBLE's ID nibble wrong): not used */
    VH_E2E_BAD_LEN = 5    /* payload too short to carry the E2E header */
} vh_e2e_status_t;

typedef struct {
    uint8_t last_counter;
    uint8_t have_last; /* 0 until the first frame with a good CRC */
} vh_e2e_rx_t;

void vh_e2e_rx_init(vh_e2e_rx_t *rx);
/* Receiver: checks one frame against cfg; an unprotected frame (VH_E2E_NONE) is VH_E2E_OK. */
vh_e2e_status_t vh_e2e_check(const vh_e2e_cfg_t *cfg, vh_e2e_rx_t *rx, const uint8_t *payload, size_t len);

#endif /* VH_E2E_H */
