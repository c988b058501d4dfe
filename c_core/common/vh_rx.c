/* vh_rx.c - RX checks and TX slots shared by the ECU applications, see vh_rx.h. */
#include <string.h>

#include "vh_rx.h"

void vh_rx_count(uint32_t *c)
{
    *c = vh_sat_add_u32(*c, 1u);
}

void vh_rx_init(vh_ecu_rxmsg_t *m)
{
    vh_e2e_rx_init(&m->e2e);
    m->age = 0u;
    m->resync = 0u;
    m->fresh = 0u;
    m->n_tick = 0u;
    m->timed_out = 1u; /* nothing received yet: not a fault, so not counted */
}

int vh_rx_accept(vh_ecu_counters_t *cnt, vh_ecu_rxmsg_t *m, const vh_frame_t *f, size_t len, const vh_e2e_cfg_t *e2e)
{
    if (f->len != len) {
        vh_rx_count(&cnt->dlc_error);
        return 0;
    }
    switch (vh_e2e_check(e2e, &m->e2e, f->data, f->len)) {
    case VH_E2E_OK:
    case VH_E2E_INITIAL:
        break;
    case VH_E2E_SKIPPED: /* frames were lost, but this one is good */
        vh_rx_count(&cnt->counter_skip);
        break;
    case VH_E2E_REPEATED:
        vh_rx_count(&cnt->counter_repeat);
        return 0;
    case VH_E2E_WRONG_CRC:
    case VH_E2E_BAD_LEN:
    default:
        vh_rx_count(&cnt->crc_error);
        return 0;
    }
    m->fresh = 1u;
    if (m->n_tick < UINT8_MAX) {
        ++m->n_tick;
    }
    return 1;
}

int vh_rx_tick(vh_ecu_counters_t *cnt, vh_ecu_rxmsg_t *m, unsigned timeout_ticks, unsigned burst_limit)
{
    if (burst_limit != 0u && m->n_tick > burst_limit) {
        m->resync = (uint16_t)timeout_ticks;
        vh_rx_count(&cnt->rx_burst);
    } else if (m->resync > 0u) {
        --m->resync;
    }
    m->n_tick = 0u;
    if (m->fresh) {
        m->age = 0u;
        m->timed_out = 0u;
    } else if (m->age < UINT16_MAX) {
        ++m->age;
    }
    if (!m->timed_out && m->age >= timeout_ticks) {
        m->timed_out = 1u;
        vh_rx_count(&cnt->timeout);
    }
    return m->resync == 0u;
}

vh_frame_t *vh_tx_slot(vh_frame_t *tx, size_t *n, size_t cap, uint32_t id, size_t len, unsigned is_fd)
{
    vh_frame_t *f;
    if (*n >= cap) {
        return NULL;
    }
    f = &tx[(*n)++];
    f->id = id;
    f->len = (uint8_t)len;
    f->flags = is_fd ? (uint8_t)(VH_FRAME_FD | VH_FRAME_BRS) : 0u;
    memset(f->data, 0, sizeof f->data);
    return f;
}
