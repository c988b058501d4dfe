/* vh_e2e.c - see vh_e2e.h. */
#include "vh_e2e.h"

uint8_t vh_crc8_j1850_update(uint8_t crc, const uint8_t *data, size_t len)
{
    size_t i;
    for (i = 0; i < len; ++i) {
        unsigned bit;
        crc ^= data[i];
        for (bit = 0; bit < 8u; ++bit) {
            crc = (uint8_t)((crc & 0x80u) ? ((unsigned)(crc << 1) ^ 0x1Du) : (unsigned)(crc << 1));
        }
    }
    return crc;
}

uint8_t vh_crc8_j1850(const uint8_t *data, size_t len)
{
    return (uint8_t)(vh_crc8_j1850_update(0xFFu, data, len) ^ 0xFFu);
}

uint8_t vh_e2e_p01_crc(const uint8_t *payload, size_t len, uint16_t data_id)
{
    const uint8_t id[2] = {(uint8_t)(data_id & 0xFFu), (uint8_t)(data_id >> 8)};
    uint8_t crc = vh_crc8_j1850_update(0xFFu, id, 2u);
    if (len > 1u) {
        crc = vh_crc8_j1850_update(crc, payload + 1, len - 1u);
    }
    return (uint8_t)(crc ^ 0xFFu);
}

void vh_e2e_p01_protect(uint8_t *payload, size_t len, uint16_t data_id, uint8_t *counter)
{
    if (len < 2u) {
        return;
    }
    payload[1] = (uint8_t)((payload[1] & 0xF0u) | (*counter & 0x0Fu));
    payload[0] = vh_e2e_p01_crc(payload, len, data_id);
    *counter = (uint8_t)((*counter >= 14u) ? 0u : (*counter + 1u));
}

void vh_e2e_rx_init(vh_e2e_rx_t *rx)
{
    rx->last_counter = 0u;
    rx->have_last = 0u;
}

vh_e2e_status_t vh_e2e_p01_check(vh_e2e_rx_t *rx, const uint8_t *payload, size_t len,
                                 uint16_t data_id)
{
    uint8_t counter;
    unsigned delta;
    if (len < 2u) {
        return VH_E2E_BAD_LEN;
    }
    counter = (uint8_t)(payload[1] & 0x0Fu);
    if (counter > 14u || payload[0] != vh_e2e_p01_crc(payload, len, data_id)) {
        return VH_E2E_WRONG_CRC;
    }
    if (!rx->have_last) {
        rx->have_last = 1u;
        rx->last_counter = counter;
        return VH_E2E_INITIAL;
    }
    delta = (counter + 15u - rx->last_counter) % 15u; /* counter runs 0..14 */
    if (delta == 0u) {
        return VH_E2E_REPEATED;
    }
    rx->last_counter = counter;
    return (delta == 1u) ? VH_E2E_OK : VH_E2E_SKIPPED;
}
