/* bench_xcp.c - cost of the XCP slave per ECU tick, in a C loop (host build, -O2).
 *
 * Not firmware: uses the heap-free slave with a clock (CLOCK_MONOTONIC) around it. One line per
 * benchmark, "name n median_ns p99_ns", the clock's own cost subtracted (vh_bench_common.h):
 *   idle           vh_xcp_tick + the three events + draining the TX queue, no DAQ running
 *   daq20_classic  the same with 20 float32 (+ timestamp) on the every-tick event, MAX_DTO 8: 12 DTOs
 *   daq20_fd       the same on CAN FD, MAX_DTO 64: 2 DTOs
 *   short_upload   one SHORT_UPLOAD of 4 bytes and its RES
 *   download       one DOWNLOAD of a float32 characteristic (range check) and its RES
 * Usage: bench_xcp [samples]
 */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "vh_bench_common.h"
#include "vh_xcp.h"

#define MEAS 0x10000000u
#define CAL 0x20000000u

static float meas[20];
static uint8_t ref[16], work[16], ecu[16];
static const vh_xcp_region_t REG[] = {{MEAS, sizeof meas, VH_XCP_ACC_READ | VH_XCP_ACC_DAQ, (const uint8_t *)meas}};
static const vh_xcp_char_t CHARS[] = {{CAL, 4u, VH_XCP_F32, 0u, 0.0, 1000.0}};
static const vh_xcp_event_t EVENTS[] = {{"tick", 50u, 4u}, {"1ms", 1u, 6u}, {"10ms", 10u, 6u}};

static void cro(vh_xcp_t *x, const uint8_t *c, size_t len)
{
    vh_xcp_frame_t f;
    vh_xcp_rx(x, c, len, 0u);
    while (vh_xcp_tx_pop(x, &f)) {
    }
}

static void setup(vh_xcp_t *x, int fd, int daq)
{
    vh_xcp_config_t cfg;
    memset(&cfg, 0, sizeof cfg);
    cfg.cro_id = 0x7F0u; cfg.dto_id = 0x7F1u;
    cfg.max_cto = fd ? 64u : 8u; cfg.max_dto = fd ? 64u : 8u; cfg.fd = (uint8_t)fd;
    cfg.tick_us = 500u; cfg.regions = REG; cfg.n_regions = 1u;
    cfg.cal_address = CAL; cfg.cal_size = sizeof ref; cfg.cal_ref = ref; cfg.cal_work = work; cfg.cal_ecu = ecu;
    cfg.chars = CHARS; cfg.n_chars = 1u; cfg.events = EVENTS; cfg.n_events = 3u;
    if (vh_xcp_init(x, &cfg) != VH_XCP_OK) {
        printf("init failed\n");
        exit(1);
    }
    {
        const uint8_t c[2] = {0xFF, 0x00};
        cro(x, c, 2);
    }
    if (daq) {
        /* 80 bytes of measurements after a 4-byte timestamp, cut into ODTs of MAX_DTO - 1 bytes */
        unsigned cap = cfg.max_dto - 1u, first = cap - 4u, n_odt = 1u + (80u - first + cap - 1u) / cap, j, off = 0;
        uint8_t c[8] = {0xD6};
        cro(x, c, 1);
        c[0] = 0xD5; c[1] = 0; c[2] = 1; c[3] = 0;
        cro(x, c, 4);
        c[0] = 0xD4; c[2] = 0; c[4] = (uint8_t)n_odt;
        cro(x, c, 5);
        for (j = 0; j < n_odt; ++j) {
            c[0] = 0xD3; c[4] = (uint8_t)j; c[5] = 1u;
            cro(x, c, 6);
        }
        for (j = 0; j < n_odt; ++j) {
            unsigned size = (j == 0u) ? first : cap;
            if (size > 80u - off) size = 80u - off;
            c[0] = 0xE2; c[2] = 0; c[3] = 0; c[4] = (uint8_t)j; c[5] = 0;
            cro(x, c, 6);
            c[0] = 0xE1; c[1] = 0xFF; c[2] = (uint8_t)size; c[3] = 0; vh_bench_le32(&c[4], MEAS + off);
            cro(x, c, 8);
            off += size;
        }
        {
            const uint8_t m[8] = {0xE0, 0x10, 0, 0, 0, 0, 1, 0};
            const uint8_t s[4] = {0xDE, 0x01, 0, 0};
            cro(x, m, 8);
            cro(x, s, 4);
        }
        if (x->n.err != 0u || x->n_odt != n_odt) {
            printf("DAQ setup failed (%u errors)\n", x->n.err);
            exit(1);
        }
    }
}

static void bench_tick(const char *name, int fd, int daq, double *s, int n, double clock_ns)
{
    vh_xcp_t *x = malloc(sizeof *x);
    vh_xcp_frame_t f;
    int i;
    setup(x, fd, daq);
    for (i = 0; i < n; ++i) {
        double t0 = vh_bench_now_ns();
        vh_xcp_tick(x, (uint32_t)i);
        vh_xcp_event(x, 0u);
        if (i % 2 == 0) vh_xcp_event(x, 1u);
        if (i % 20 == 0) vh_xcp_event(x, 2u);
        while (vh_xcp_tx_pop(x, &f)) {
        }
        s[i] = vh_bench_now_ns() - t0;
        meas[i % 20] = (float)i;
    }
    vh_bench_report(name, s, n, clock_ns);
    free(x);
}

int main(int argc, char **argv)
{
    int n = (argc > 1) ? atoi(argv[1]) : 200000, i;
    double *s = malloc(sizeof *s * (size_t)(n > 1000 ? n : 1000)), clock_ns;
    vh_xcp_t *x = malloc(sizeof *x);
    vh_xcp_frame_t f;
    clock_ns = vh_bench_clock(s, 1000);
    bench_tick("idle", 0, 0, s, n, clock_ns);
    bench_tick("daq20_classic", 0, 1, s, n, clock_ns);
    bench_tick("daq20_fd", 1, 1, s, n, clock_ns);
    setup(x, 0, 0);
    {
        uint8_t c[8] = {0xF4, 4, 0, 0};
        vh_bench_le32(&c[4], MEAS + 8u);
        for (i = 0; i < n; ++i) {
            double t0 = vh_bench_now_ns();
            vh_xcp_rx(x, c, 8, 0u);
            while (vh_xcp_tx_pop(x, &f)) {
            }
            s[i] = vh_bench_now_ns() - t0;
        }
        vh_bench_report("short_upload", s, n, clock_ns);
    }
    {
        /* the master's seed & key is not configured here (protect = 0): writes are open */
        uint8_t mta[8] = {0xF6, 0, 0, 0}, c[6] = {0xF0, 4};
        float v = 12.5f;
        memcpy(&c[2], &v, 4);
        vh_bench_le32(&mta[4], CAL);
        for (i = 0; i < n; ++i) {
            double t0;
            vh_xcp_rx(x, mta, 8, 0u);
            while (vh_xcp_tx_pop(x, &f)) {
            }
            t0 = vh_bench_now_ns();
            vh_xcp_rx(x, c, 6, 0u);
            while (vh_xcp_tx_pop(x, &f)) {
            }
            s[i] = vh_bench_now_ns() - t0;
        }
        vh_bench_report("download", s, n, clock_ns);
        if (x->n.cal_writes != (uint32_t)n) {
            printf("downloads refused\n");
            return 1;
        }
    }
    free(x);
    free(s);
    return 0;
}
