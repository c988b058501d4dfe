/* bench_secoc.c - cost of SecOC per frame, in a C loop (host build, -O2). Not firmware.
 *
 * One line per benchmark, "name n median_ns p99_ns" (vh_bench_common.h; first the clock's own
 * cost), each sample a batch of 64 operations less that cost, per operation:
 *   aes_block       one AES-128 block encryption (the backend: OpenSSL), the floor of everything below
 *   cmac_38         CMAC of 38 bytes (data ID 2 + authentic 28 + FV 8: 3 blocks)
 *   protect_28      securing a 28-byte authentic part (the tail written, the FV consumed)
 *   verify_28       checking a genuine 32-byte secured frame
 *   verify_forged   checking a forged or a replayed one, alternately (every candidate FV and
 *                   the replay test: 5 CMACs, the worst case)
 * Usage: bench_secoc [samples]
 */
#define _POSIX_C_SOURCE 199309L
#include <string.h>

#include "vh_bench_common.h"
#include "vh_secoc.h"

#define BATCH 64

static double clock_ns; /* one clock reading's cost (vh_bench_clock) */

/* Per operation: each sample timed a batch of BATCH, less the clock's cost. */
static void report(const char *name, double *s, int n)
{
    for (int i = 0; i < n; ++i)
        s[i] = (s[i] - clock_ns) / BATCH;
    vh_bench_report(name, s, n, 0.0);
}

int main(int argc, char **argv)
{
    int n = argc > 1 ? atoi(argv[1]) : 2000;
    if (n < 10)
        n = 10;
    double *s = malloc(sizeof(double) * (size_t)n); /* the bench's own buffer, not the firmware's */
    if (!s)
        return 1;
    clock_ns = vh_bench_clock(s, n);
    static const uint8_t key[16] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16};
    vh_cmac_key_t k;
    vh_cmac_init(&k, key);
    uint8_t block[16] = {0}, tag[16], msg[38] = {0}, frames[BATCH][32];
    volatile uint8_t sink = 0;

    for (int i = 0; i < n; ++i) {
        double t0 = vh_bench_now_ns();
        for (int j = 0; j < BATCH; ++j) {
            vh_aes128_encrypt(&k.aes, block, block);
        }
        s[i] = vh_bench_now_ns() - t0;
    }
    sink ^= block[0];
    report("aes_block", s, n);

    for (int i = 0; i < n; ++i) {
        double t0 = vh_bench_now_ns();
        for (int j = 0; j < BATCH; ++j) {
            msg[0] = (uint8_t)j;
            vh_cmac(&k, msg, sizeof msg, tag);
        }
        s[i] = vh_bench_now_ns() - t0;
        sink ^= tag[0];
    }
    report("cmac_38", s, n);

    vh_secoc_tx_t tx;
    vh_secoc_rx_t rx;
    vh_secoc_tx_init(&tx, 1, UINT64_MAX);
    vh_secoc_rx_init(&rx, 0, 1);
    for (int i = 0; i < n; ++i) {
        double t0 = vh_bench_now_ns();
        for (int j = 0; j < BATCH; ++j) {
            memset(frames[j], j, 28);
            vh_secoc_protect(&tx, &k, 0x110, frames[j], 28);
        }
        s[i] = vh_bench_now_ns() - t0;
    }
    report("protect_28", s, n);

    for (int i = 0; i < n; ++i) {
        vh_secoc_tx_init(&tx, 1 + (uint64_t)i * BATCH, UINT64_MAX);
        for (int j = 0; j < BATCH; ++j) {
            memset(frames[j], j, 28);
            vh_secoc_protect(&tx, &k, 0x110, frames[j], 28);
        }
        double t0 = vh_bench_now_ns();
        for (int j = 0; j < BATCH; ++j)
            sink ^= (uint8_t)vh_secoc_verify(&rx, &k, 0x110, frames[j], 28, NULL);
        s[i] = vh_bench_now_ns() - t0;
    }
    report("verify_28", s, n);

    for (int i = 0; i < n; ++i) {
        for (int j = 0; j < BATCH; ++j)
            frames[j][29] ^= 0x5a; /* forged, then (flipped back) a replay of an accepted frame */
        double t0 = vh_bench_now_ns();
        for (int j = 0; j < BATCH; ++j)
            sink ^= (uint8_t)vh_secoc_verify(&rx, &k, 0x110, frames[j], 28, NULL);
        s[i] = vh_bench_now_ns() - t0;
    }
    report("verify_forged", s, n);
    if (rx.accepted != (uint32_t)n * BATCH || rx.bad_mac + rx.replayed != (uint32_t)n * BATCH) {
        printf("bench_secoc: unexpected verdicts: accepted %u bad %u replayed %u\n", rx.accepted, rx.bad_mac, rx.replayed);
        return 1;
    }
    free(s);
    (void)sink;
    return 0;
}
