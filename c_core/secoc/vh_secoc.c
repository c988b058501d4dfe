/* SecOC-style frame authentication and freshness management; see vh_secoc.h. */
#include "vh_secoc.h"

#include <string.h>

#define FV_MASK ((uint64_t)((1u << VH_SECOC_FV_TX_BITS) - 1u))

static void put_be64(uint8_t *p, uint64_t v)
{
    for (int i = 7; i >= 0; --i) {
        p[i] = (uint8_t)(v & 0xffu);
        v >>= 8;
    }
}

static uint64_t get_be64(const uint8_t *p)
{
    uint64_t v = 0;
    for (int i = 0; i < 8; ++i)
        v = (v << 8) | p[i];
    return v;
}

static void count(uint32_t *c)
{
    if (*c != UINT32_MAX)
        ++*c;
}

void vh_secoc_tx_init(vh_secoc_tx_t *tx, uint64_t fv_start, uint64_t reserved_until)
{
    memset(tx, 0, sizeof *tx);
    tx->fv = fv_start;
    tx->reserved_until = reserved_until;
}

void vh_secoc_tx_reserve(vh_secoc_tx_t *tx, uint64_t reserved_until)
{
    if (reserved_until > tx->reserved_until)
        tx->reserved_until = reserved_until;
}

void vh_secoc_rx_init(vh_secoc_rx_t *rx, uint64_t latest, int synced)
{
    memset(rx, 0, sizeof *rx);
    rx->latest = latest;
    rx->synced = synced ? 1u : 0u;
}

/* DataToAuthenticator = data ID | authentic part | complete FV (SWS_SecOC_00031). */
void vh_secoc_mac(const vh_cmac_key_t *k, uint16_t data_id, const uint8_t *authentic, uint8_t len,
                  uint64_t fv, uint8_t mac[VH_AES_BLOCK])
{
    uint8_t buf[2 + VH_SECOC_MAX_AUTHENTIC + 8];
    if (len > VH_SECOC_MAX_AUTHENTIC)
        len = VH_SECOC_MAX_AUTHENTIC; /* callers check; never read past the buffer */
    buf[0] = (uint8_t)(data_id >> 8);
    buf[1] = (uint8_t)data_id;
    memcpy(buf + 2, authentic, len);
    put_be64(buf + 2 + len, fv);
    vh_cmac(k, buf, (size_t)len + 10u, mac);
    memset(buf, 0, sizeof buf);
}

/* The tail: truncated FV (its LSBs), then the MAC's most significant bytes (SWS_SecOC_00036). */
static void write_tail(const vh_cmac_key_t *k, uint16_t data_id, uint8_t *frame, uint8_t len, uint64_t fv)
{
    uint8_t mac[VH_AES_BLOCK];
    vh_secoc_mac(k, data_id, frame, len, fv, mac);
    frame[len] = (uint8_t)(fv & FV_MASK);
    memcpy(frame + len + 1, mac, VH_SECOC_MAC_TX_BYTES);
}

/* Constant-time compare of the truncated MAC. */
static int mac_matches(const vh_cmac_key_t *k, uint16_t data_id, const uint8_t *frame, uint8_t len, uint64_t fv)
{
    uint8_t mac[VH_AES_BLOCK], diff = 0;
    vh_secoc_mac(k, data_id, frame, len, fv, mac);
    for (int i = 0; i < VH_SECOC_MAC_TX_BYTES; ++i)
        diff |= (uint8_t)(mac[i] ^ frame[len + 1 + i]);
    return diff == 0;
}

vh_secoc_result_t vh_secoc_protect(vh_secoc_tx_t *tx, const vh_cmac_key_t *k, uint16_t data_id,
                                   uint8_t *frame, uint8_t len)
{
    if (len > VH_SECOC_MAX_AUTHENTIC)
        return VH_SECOC_E_LENGTH;
    if (tx->fv >= tx->reserved_until) {
        count(&tx->exhausted);
        return VH_SECOC_E_EXHAUSTED;
    }
    write_tail(k, data_id, frame, len, tx->fv);
    ++tx->fv;
    count(&tx->sent);
    return VH_SECOC_OK;
}

static vh_secoc_result_t fail(vh_secoc_rx_t *rx, vh_secoc_result_t why)
{
    count(why == VH_SECOC_E_REPLAY ? &rx->replayed : &rx->bad_mac);
    return why;
}

vh_secoc_result_t vh_secoc_verify(vh_secoc_rx_t *rx, const vh_cmac_key_t *k, uint16_t data_id,
                                  const uint8_t *frame, uint8_t len, uint64_t *fv_out)
{
    if (len > VH_SECOC_MAX_AUTHENTIC)
        return fail(rx, VH_SECOC_E_LENGTH);
    if (!rx->synced) {
        count(&rx->unsynced);
        return VH_SECOC_E_UNSYNCED;
    }
    uint64_t t = frame[len], low = rx->latest & FV_MASK, high = rx->latest & ~FV_MASK;
    /* The smallest FV above latest with these low bits, then the next wraps of the truncated FV
     * (frames lost in between), up to VH_SECOC_VERIFY_ATTEMPTS candidates. */
    uint64_t cand = (t > low ? high : high + FV_MASK + 1u) | t;
    for (int a = 0; a < VH_SECOC_VERIFY_ATTEMPTS; ++a, cand += FV_MASK + 1u) {
        if (cand < rx->latest) /* the 64-bit counter wrapped: never accept */
            break;
        if (mac_matches(k, data_id, frame, len, cand)) {
            rx->latest = cand;
            count(&rx->accepted);
            if (fv_out)
                *fv_out = cand;
            return VH_SECOC_OK;
        }
    }
    /* Not fresh: is it a genuine frame already seen (the FV with these low bits at or below latest)? */
    uint64_t old = (t <= low ? high : high - FV_MASK - 1u) | t;
    if (old <= rx->latest && mac_matches(k, data_id, frame, len, old))
        return fail(rx, VH_SECOC_E_REPLAY);
    return fail(rx, VH_SECOC_E_MAC);
}

vh_secoc_result_t vh_secoc_sync_build(vh_secoc_tx_t *tx, const vh_cmac_key_t *k, uint16_t data_id,
                                      uint8_t *frame)
{
    put_be64(frame, tx->fv);
    return vh_secoc_protect(tx, k, data_id, frame, VH_SECOC_SYNC_AUTHENTIC);
}

vh_secoc_result_t vh_secoc_sync_accept(vh_secoc_rx_t *rx, const vh_cmac_key_t *k, uint16_t data_id,
                                       const uint8_t *frame)
{
    uint64_t fv = get_be64(frame);
    if ((fv & FV_MASK) != frame[VH_SECOC_SYNC_AUTHENTIC] || !mac_matches(k, data_id, frame, VH_SECOC_SYNC_AUTHENTIC, fv))
        return fail(rx, VH_SECOC_E_MAC);
    if (fv <= rx->latest)
        return fail(rx, VH_SECOC_E_REPLAY);
    if (!rx->synced)
        count(&rx->resyncs);
    rx->latest = fv;
    rx->synced = 1;
    count(&rx->accepted);
    return VH_SECOC_OK;
}
