/* vh_e2e.h - AUTOSAR E2E Profile 1 style protection: CRC-8 SAE J1850 + 4-bit alive counter.
 *
 * Layout used on every cyclic frame of the project (see dbc/): byte 0 holds the CRC,
 * the low nibble of byte 1 the counter (0..14; 15 is never sent). The CRC runs over the
 * 16-bit data ID (low byte, then high byte: P01 "both" mode) and then bytes 1..len-1.
 */
#ifndef VH_E2E_H
#define VH_E2E_H

#include "vh_types.h"

/* CRC-8 SAE J1850: poly 0x1D, init 0xFF, final XOR 0xFF; check("123456789") = 0x4B.
 * `crc` is the running value before the final XOR: start with 0xFF. */
uint8_t vh_crc8_j1850_update(uint8_t crc, const uint8_t *data, size_t len);
uint8_t vh_crc8_j1850(const uint8_t *data, size_t len);

uint8_t vh_e2e_p01_crc(const uint8_t *payload, size_t len, uint16_t data_id);

/* Sender: writes counter and CRC into payload, advances *counter (0..14). */
void vh_e2e_p01_protect(uint8_t *payload, size_t len, uint16_t data_id, uint8_t *counter);

typedef enum {
    VH_E2E_OK = 0,        /* CRC right, counter +1 */
    VH_E2E_INITIAL = 1,   /* CRC right, first frame after init: counter taken as reference */
    VH_E2E_REPEATED = 2,  /* CRC right, same counter as before: stale data, not used */
    VH_E2E_SKIPPED = 3,   /* CRC right, counter jumped by 2..14: frames lost, data used */
    VH_E2E_WRONG_CRC = 4, /* CRC wrong (or counter 15): not used */
    VH_E2E_BAD_LEN = 5    /* payload too short to carry the E2E header */
} vh_e2e_status_t;

typedef struct {
    uint8_t last_counter;
    uint8_t have_last; /* 0 until the first frame with a good CRC */
} vh_e2e_rx_t;

void vh_e2e_rx_init(vh_e2e_rx_t *rx);
vh_e2e_status_t vh_e2e_p01_check(vh_e2e_rx_t *rx, const uint8_t *payload, size_t len,
                                 uint16_t data_id);

#endif /* VH_E2E_H */
