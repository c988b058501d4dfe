/* toy_main.c - drives the ECU built with the toy application (tests/systems/test_toy_app.py):
 * 100 ticks, a toy frame before each, and prints what the toy and the scheduler did; then reads
 * the toy's runnable counter over XCP (CONNECT, SHORT_UPLOAD of 4 bytes at argv[1], the address
 * the XCP description gives it). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "vh_cmac.h"
#include "vh_ecu.h"

#define CRO_ID 0x7E0u
#define DTO_ID 0x7E1u

static vh_ecu_t ecu;

/* One command: the CRO through the ECU's dispatch, its answer (8 bytes) out of the next tick's TX. */
static int cro(const uint8_t *data, uint8_t len, uint8_t *res)
{
    vh_frame_t f, tx[VH_ECU_MAX_TX];
    size_t i, n;
    memset(&f, 0, sizeof f);
    f.id = CRO_ID;
    f.len = len;
    memcpy(f.data, data, len);
    vh_ecu_rx(&ecu, &f);
    n = vh_ecu_step(&ecu, tx, VH_ECU_MAX_TX);
    for (i = 0; i < n; ++i) {
        if (tx[i].id == DTO_ID) {
            memcpy(res, tx[i].data, 8);
            return tx[i].data[0] == 0xFFu;
        }
    }
    return 0;
}

/* RFC 4493's published AES-128 test key: a test, not a secret (UPLOAD needs no unlock) */
static const uint8_t TEST_KEY[16] = {0x2b, 0x7e, 0x15, 0x16, 0x28, 0xae, 0xd2, 0xa6,
                                     0xab, 0xf7, 0x15, 0x88, 0x09, 0xcf, 0x4f, 0x3c};

int main(int argc, char **argv)
{
    static vh_cmac_key_t key;
    vh_ecu_config_t cfg;
    vh_ecu_xcp_config_t xcfg;
    vh_frame_t in, tx[VH_ECU_MAX_TX];
    unsigned k, toy_tx = 0u, toy_tx_ticks = 0u;
    uint32_t last_sum = 0u, addr, xcp_runs;
    uint8_t res[8];
    static const uint8_t connect[] = {0xFF, 0x00};
    uint8_t upload[8] = {0xF4, 4u, 0u, 0u, 0u, 0u, 0u, 0u};
    if (argc != 2) {
        return 2;
    }
    addr = (uint32_t)strtoul(argv[1], NULL, 0);
    vh_ecu_config_default(&cfg);
    memset(&xcfg, 0, sizeof xcfg);
    xcfg.cro_id = CRO_ID;
    xcfg.dto_id = DTO_ID;
    xcfg.max_cto = 8u;
    xcfg.max_dto = 8u;
    xcfg.key = &key;
    if (vh_cmac_init(&key, TEST_KEY) != 0 || vh_ecu_init(&ecu, &cfg) != VH_OK || vh_ecu_xcp_enable(&ecu, &xcfg) != VH_OK) {
        printf("init failed\n");
        return 1;
    }
    for (k = 0u; k < 100u; ++k) {
        size_t i, n;
        memset(&in, 0, sizeof in);
        in.id = VH_TOY_IN_FRAME_ID;
        in.len = 8u;
        in.data[0] = (uint8_t)k;
        vh_ecu_rx(&ecu, &in);
        n = vh_ecu_step(&ecu, tx, VH_ECU_MAX_TX);
        for (i = 0u; i < n; ++i) {
            if (tx[i].id == VH_TOY_OUT_FRAME_ID) {
                ++toy_tx;
                toy_tx_ticks += k;
                memcpy(&last_sum, tx[i].data, sizeof last_sum);
            }
        }
    }
    upload[4] = (uint8_t)addr; /* the slave's byte order: little-endian */
    upload[5] = (uint8_t)(addr >> 8);
    upload[6] = (uint8_t)(addr >> 16);
    upload[7] = (uint8_t)(addr >> 24);
    if (!cro(connect, 2u, res) || !cro(upload, 8u, res)) {
        printf("XCP failed %02x %02x\n", res[0], res[1]);
        return 1;
    }
    memcpy(&xcp_runs, &res[1], 4);
    printf("xcp_runs %u runs_now %u ", (unsigned)xcp_runs, (unsigned)ecu.app.toy.runs);
    printf("apps %d frames %u runs %u sum %u gain %u unknown_id %u toy_tx %u toy_tx_ticks %u last_sum %u\n",
           VH_ECU_N_APPS, (unsigned)ecu.app.toy.frames, (unsigned)ecu.app.toy.runs, (unsigned)ecu.app.toy.sum,
           (unsigned)ecu.app.toy.cfg.gain, (unsigned)ecu.cnt.unknown_id, toy_tx, toy_tx_ticks, (unsigned)last_sum);
    return 0;
}
