/* vh_bench_ecu_xcp.c - the ECU tick with the XCP slave, beside the tick without it (`vehest-can bench`).
 *
 * Three ECUs step on the same DLS_Sensors frames of a launch, tick by tick in turn (so a loaded
 * machine slows all three alike); each tick is timed (vh_bench_common.h):
 *   ecu_tick_no_xcp     XCP not enabled
 *   ecu_tick_xcp_idle   XCP enabled, a master connected, no DAQ
 *   ecu_tick_xcp_daq    a 20-measurement DAQ list on the 1 ms event (2 DTOs per sample, the
 *                       documented rate), its DTO drained into the tick's TX
 * plus a check line "xcp_daq_dtos ticks dtos overruns" (the DAQ did run, within its budget).
 * The master's commands are raw CRO frames through vh_ecu_rx, as on the bus.
 */
#define _POSIX_C_SOURCE 199309L
#include <stddef.h>
#include <stdio.h>
#include <string.h>

#include "vh_bench_common.h"
#include "vh_bench_drive.h"

#include "vh_dlsim.h"
#include "vh_ecu.h"

#define N_SAMPLES 40000
#define CRO_ID 0x7E0u
#define DTO_ID 0x7E1u

static double s_none[N_SAMPLES], s_idle[N_SAMPLES], s_daq[N_SAMPLES];

/* One command: the CRO through the ECU's dispatch, its answer out of the next tick's TX. */
static int cro(vh_ecu_t *ecu, const uint8_t *data, uint8_t len, uint8_t *res)
{
    vh_frame_t f, tx[VH_ECU_MAX_TX];
    size_t i, n;
    memset(&f, 0, sizeof f);
    f.id = CRO_ID;
    f.len = len;
    f.flags = VH_FRAME_FD;
    memcpy(f.data, data, len);
    vh_ecu_rx(ecu, &f);
    n = vh_ecu_step(ecu, tx, VH_ECU_MAX_TX);
    for (i = 0; i < n; ++i) {
        if (tx[i].id == DTO_ID) {
            if (res != NULL) {
                memcpy(res, tx[i].data, 8);
            }
            return tx[i].data[0] == 0xFFu;
        }
    }
    return 0;
}

/* RFC 4493's published AES-128 test key: a bench, not a secret */
static const uint8_t BENCH_KEY[16] = {0x2b, 0x7e, 0x15, 0x16, 0x28, 0xae, 0xd2, 0xa6,
                                      0xab, 0xf7, 0x15, 0x88, 0x09, 0xcf, 0x4f, 0x3c};
static vh_cmac_key_t bench_key;

static int connect_unlocked(vh_ecu_t *ecu)
{
    static const uint8_t connect[] = {0xFF, 0x00};
    uint8_t res[8];
    uint8_t resource;
    if (!cro(ecu, connect, 2u, NULL)) {
        return 0;
    }
    for (resource = 1u; resource <= 4u; resource = (uint8_t)(resource * 4u)) { /* CAL/PAG, DAQ */
        uint8_t get_seed[3] = {0xF8, 0x00, 0x00}, unlock[2 + VH_XCP_KEY_LEN] = {0xF7, VH_XCP_KEY_LEN};
        get_seed[2] = resource;
        if (!cro(ecu, get_seed, 3u, res)) {
            return 0;
        }
        vh_xcp_key(&bench_key, resource, &res[2], &unlock[2]);
        if (!cro(ecu, unlock, sizeof unlock, NULL)) {
            return 0;
        }
    }
    return 1;
}

/* each element its whole size (the counters are uint32); an ODT fits MAX_DTO 48 less the PID, the
 * first less the 4-byte timestamp too: 42 + 44 bytes */
#define M(member) {offsetof(vh_ecu_t, member), (uint8_t)sizeof(((vh_ecu_t *)0)->member)}
static const struct { size_t off; uint8_t size; } ODT0[] = {
    M(tick), M(app.drv.dkf[0].health), M(app.drv.dkf[1].health), M(cnt.crc_error), M(cnt.counter_repeat),
    M(cnt.counter_skip), M(cnt.dlc_error), M(cnt.timeout), M(cnt.unknown_id), M(cnt.signal_invalid),
    M(cnt.input_invalid), M(cnt.filter_reset)};
static const struct { size_t off; uint8_t size; } ODT1[] = {
    M(cnt.deadline_miss), M(app.drv.dkf[0].x[2]), M(app.drv.dkf[0].x[0]), M(app.drv.dkf[0].innov[2]),
    M(app.drv.dkf[0].p[10]), M(app.drv.dkf[1].x[2])};

/* Dynamic DAQ (ASAM sequence: FREE, ALLOC_DAQ, ALLOC_ODT, ALLOC_ODT_ENTRY, SET_DAQ_PTR,
 * WRITE_DAQ, SET_DAQ_LIST_MODE, START_STOP_DAQ_LIST): 18 measurements, 2 ODTs, event 1. */
static int daq_18_at_1ms(vh_ecu_t *ecu)
{
    static const uint8_t free_daq[] = {0xD6}, alloc_daq[] = {0xD5, 0, 1, 0}, alloc_odt[] = {0xD4, 0, 0, 0, 2};
    static const uint8_t mode[] = {0xE0, 0x10, 0, 0, 1, 0, 1, 0}, start[] = {0xDE, 0x01, 0, 0};
    uint8_t entries[6] = {0xD3, 0, 0, 0, 0, 0}, ptr[6] = {0xE2, 0, 0, 0, 0, 0}, w[8] = {0xE1, 0xFF};
    const size_t n0 = sizeof ODT0 / sizeof ODT0[0], n1 = sizeof ODT1 / sizeof ODT1[0];
    size_t odt, i;
    if (!cro(ecu, free_daq, 1u, NULL) || !cro(ecu, alloc_daq, 4u, NULL) || !cro(ecu, alloc_odt, 5u, NULL)) {
        return 0;
    }
    for (odt = 0; odt < 2u; ++odt) {
        entries[4] = (uint8_t)odt;
        entries[5] = (uint8_t)(odt == 0u ? n0 : n1);
        if (!cro(ecu, entries, 6u, NULL)) {
            return 0;
        }
    }
    for (odt = 0; odt < 2u; ++odt) {
        ptr[4] = (uint8_t)odt;
        if (!cro(ecu, ptr, 6u, NULL)) {
            return 0;
        }
        for (i = 0; i < (odt == 0u ? n0 : n1); ++i) {
            const uint32_t a = VH_ECU_XCP_MEAS_ADDRESS + (uint32_t)(odt == 0u ? ODT0[i].off : ODT1[i].off);
            w[2] = odt == 0u ? ODT0[i].size : ODT1[i].size;
            w[3] = 0u;
            vh_bench_le32(&w[4], a);
            if (!cro(ecu, w, 8u, NULL)) {
                return 0;
            }
        }
    }
    return cro(ecu, mode, 8u, NULL) && cro(ecu, start, 4u, NULL);
}

int main(void)
{
    static vh_dlsim_t sim;
    static vh_ecu_t none, idle, daq;
    static vh_frame_t frames[N_SAMPLES];
    vh_ecu_config_t ecfg;
    vh_ecu_xcp_config_t xcfg;
    vh_frame_t tx[VH_ECU_MAX_TX];
    double clock_ns, t0;
    uint32_t dto0;
    int i;
    volatile size_t sink = 0u;

    clock_ns = vh_bench_clock(s_none, N_SAMPLES);
    if (!vh_bench_launch(&sim, frames, N_SAMPLES)) {
        return 1;
    }
    vh_ecu_config_default(&ecfg);
    memset(&xcfg, 0, sizeof xcfg);
    xcfg.cro_id = CRO_ID;
    xcfg.dto_id = DTO_ID;
    xcfg.max_cto = 8u;
    xcfg.max_dto = 48u;
    xcfg.fd = 1u;
    xcfg.key = &bench_key;
    if (vh_cmac_init(&bench_key, BENCH_KEY) != 0) {
        return 1;
    }
    if (vh_ecu_init(&none, &ecfg) != VH_OK || vh_ecu_init(&idle, &ecfg) != VH_OK || vh_ecu_init(&daq, &ecfg) != VH_OK ||
        vh_ecu_xcp_enable(&idle, &xcfg) != VH_OK || vh_ecu_xcp_enable(&daq, &xcfg) != VH_OK ||
        !connect_unlocked(&idle) || !connect_unlocked(&daq) || !daq_18_at_1ms(&daq)) {
        fprintf(stderr, "XCP setup failed\n");
        return 1;
    }
    vh_ecu_reset(&none); /* all three start the drive at tick 0; XCP sessions survive the reset */
    vh_ecu_reset(&idle);
    vh_ecu_reset(&daq);
    dto0 = daq.xcp.slave.n.dto;
    for (i = 0; i < N_SAMPLES; ++i) {
        t0 = vh_bench_now_ns();
        vh_ecu_rx(&none, &frames[i]);
        sink += vh_ecu_step(&none, tx, VH_ECU_MAX_TX);
        s_none[i] = vh_bench_now_ns() - t0;
        t0 = vh_bench_now_ns();
        vh_ecu_rx(&idle, &frames[i]);
        sink += vh_ecu_step(&idle, tx, VH_ECU_MAX_TX);
        s_idle[i] = vh_bench_now_ns() - t0;
        t0 = vh_bench_now_ns();
        vh_ecu_rx(&daq, &frames[i]);
        sink += vh_ecu_step(&daq, tx, VH_ECU_MAX_TX);
        s_daq[i] = vh_bench_now_ns() - t0;
    }
    vh_bench_report("ecu_tick_no_xcp", s_none, N_SAMPLES, clock_ns);
    vh_bench_report("ecu_tick_xcp_idle", s_idle, N_SAMPLES, clock_ns);
    vh_bench_report("ecu_tick_xcp_daq", s_daq, N_SAMPLES, clock_ns);
    printf("xcp_daq_dtos %d %u %u\n", N_SAMPLES, (unsigned)(daq.xcp.slave.n.dto - dto0),
           (unsigned)daq.xcp.slave.n.dto_overrun);
    return sink == 0u; /* keeps the ticks from being optimised away */
}
