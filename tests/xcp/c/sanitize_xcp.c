/* sanitize_xcp.c - drives the XCP slave under AddressSanitizer + UndefinedBehaviorSanitizer.
 *
 * Built by tests/xcp/test_xcp_sanitize.py from c_core/xcp/vh_xcp.c alone. A scripted session
 * (connect, seed & key, a DAQ list, downloads) and then random CROs - raw bytes and frames that
 * start with a real command code - with ticks and events in between, over every configuration
 * variant (classic/FD, byte order, padding). After every CRO: at most one answer, well formed;
 * the reference page and the measurement memory unchanged; every characteristic the ECU sees
 * within limits.
 * Any sanitizer report aborts with a non-zero status (-fno-sanitize-recover=all).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "vh_xcp.h"

static uint64_t rng_state = 0x9E3779B97F4A7C15ull;

static uint32_t rnd(void)
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return (uint32_t)(rng_state >> 16);
}

#define FAIL(...) do { printf("FAIL line %d: ", __LINE__); printf(__VA_ARGS__); printf("\n"); exit(1); } while (0)

static const uint8_t KNOWN[] = {0xFF, 0xFE, 0xFD, 0xFC, 0xFB, 0xFA, 0xF8, 0xF7, 0xF6, 0xF5, 0xF4, 0xF0,
                                0xED, 0xEB, 0xEA, 0xE9, 0xE3, 0xE2, 0xE1, 0xE0, 0xDF, 0xDE, 0xDD, 0xDC,
                                0xDA, 0xD9, 0xD7, 0xD6, 0xD5, 0xD4, 0xD3};

#define MEAS_ADDR 0x10000000u
#define CAL_ADDR 0x20000000u

static uint8_t meas[64], meas_copy[64];
static uint8_t safe = 1u; /* the caller's safe state: toggled by the random run */
/* RFC 4493's published AES-128 test key: a test vector, not a secret */
static const uint8_t TEST_KEY[16] = {0x2b, 0x7e, 0x15, 0x16, 0x28, 0xae, 0xd2, 0xa6,
                                     0xab, 0xf7, 0x15, 0x88, 0x09, 0xcf, 0x4f, 0x3c};
static vh_cmac_key_t key;
static uint8_t cal_ref[40], cal_work[40], cal_ecu[40];
static const vh_xcp_char_t CHARS[] = {
    {CAL_ADDR + 0u, 4u, VH_XCP_F32, 0u, 0.0, 100.0},   /* float[4] */
    {CAL_ADDR + 16u, 1u, VH_XCP_I16, VH_XCP_CHAR_SAFETY, -400.0, 400.0}, /* written only while `safe` */
    {CAL_ADDR + 18u, 1u, VH_XCP_U8, 0u, 1.0, 200.0},
    {CAL_ADDR + 24u, 2u, VH_XCP_F64, VH_XCP_CHAR_SAFETY, -1.0, 1.0},    /* double[2], a gap before it */
};
static const vh_xcp_region_t REGIONS[] = {
    {MEAS_ADDR, 48u, VH_XCP_ACC_READ | VH_XCP_ACC_DAQ, meas},
    {MEAS_ADDR + 48u, 16u, VH_XCP_ACC_READ, meas + 48},
};
static const vh_xcp_event_t EVENTS[] = {{"tick", 50u, 4u}, {"1ms", 1u, 6u}, {NULL, 10u, 6u}};

static void check_limits(const uint8_t *page)
{
    size_t i;
    uint16_t e;
    for (i = 0; i < sizeof CHARS / sizeof CHARS[0]; ++i) {
        const vh_xcp_char_t *c = &CHARS[i];
        const uint8_t *p = page + (c->address - CAL_ADDR);
        for (e = 0; e < c->count; ++e) {
            double v;
            if (c->type == VH_XCP_F32) { float f; memcpy(&f, p + 4u * e, 4); v = f; }
            else if (c->type == VH_XCP_F64) { memcpy(&v, p + 8u * e, 8); }
            else if (c->type == VH_XCP_I16) { int16_t s; memcpy(&s, p, 2); v = s; }
            else { v = p[0]; }
            if (!(v >= c->min && v <= c->max)) {
                FAIL("characteristic %u element %u = %g outside [%g, %g]", (unsigned)i, (unsigned)e, v, c->min, c->max);
            }
        }
    }
}

static void init_pages(void)
{
    float f[4] = {1.0f, 2.0f, 3.0f, 4.0f};
    int16_t s = 10;
    double d[2] = {0.5, -0.5};
    memset(cal_ref, 0, sizeof cal_ref);
    memcpy(cal_ref, f, sizeof f);
    memcpy(cal_ref + 16, &s, 2);
    cal_ref[18] = 5u;
    memcpy(cal_ref + 24, d, sizeof d);
}

static unsigned answers(vh_xcp_t *x, uint8_t max_cto, uint8_t max_dto, int expect_res)
{
    vh_xcp_frame_t f;
    unsigned n = 0u, res = 0u;
    while (vh_xcp_tx_pop(x, &f)) {
        if (f.len == 0u || f.len > VH_XCP_FRAME_MAX) {
            FAIL("frame length %u", f.len);
        }
        if (f.data[0] >= 0xFCu) {
            res++;
            if (f.data[0] != 0xFFu && f.data[0] != 0xFEu) {
                FAIL("PID %02X", f.data[0]);
            }
            if (!x->cfg.fd && f.len > max_cto) {
                FAIL("RES of %u bytes > MAX_CTO", f.len);
            }
        } else if (!x->cfg.fd && f.len > max_dto) {
            FAIL("DTO of %u bytes > MAX_DTO", f.len);
        }
        n++;
    }
    if (res > 1u || (expect_res >= 0 && (int)res != expect_res)) {
        FAIL("%u answers to one CRO", res);
    }
    return n;
}

static void send(vh_xcp_t *x, const uint8_t *c, size_t len, uint32_t tick)
{
    vh_xcp_rx(x, c, len, tick);
}

static uint8_t ok(vh_xcp_t *x, const uint8_t *c, size_t len, uint32_t tick, uint8_t *resp)
{
    vh_xcp_frame_t f;
    vh_xcp_rx(x, c, len, tick);
    if (!vh_xcp_tx_pop(x, &f)) {
        FAIL("no answer to %02X", c[0]);
    }
    if (resp != NULL) {
        memcpy(resp, f.data, f.len);
    }
    return f.data[0];
}

static void wr32le(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); p[2] = (uint8_t)(v >> 16); p[3] = (uint8_t)(v >> 24);
}

static void unlock(vh_xcp_t *x, uint8_t res)
{
    uint8_t r[64], c[8] = {0xF8, 0x00, 0};
    c[2] = res;
    if (ok(x, c, 3, 0, r) != 0xFFu) {
        FAIL("GET_SEED");
    }
    if (r[1] == 0u) {
        return;
    }
    vh_xcp_key(&key, res, &r[2], &c[2]);
    c[0] = 0xF7; c[1] = VH_XCP_KEY_LEN;
    if (ok(x, c, 2 + VH_XCP_KEY_LEN, 0, r) != 0xFFu) {
        FAIL("UNLOCK");
    }
}

/* A list of 3 ODTs over the first region on the 1 ms event (channel 1), started. */
static void scripted_daq(vh_xcp_t *x, int big)
{
    uint8_t c[8];
    unsigned j, k;
    uint8_t seq[][6] = {{0xD6}, {0xD5, 0, 1, 0}, {0xD4, 0, 0, 0, 3}};
    if (big) {
        seq[1][2] = 0u; seq[1][3] = 1u; /* DAQ_COUNT is a WORD in the slave's byte order */
    }
    for (j = 0; j < 3u; ++j) {
        if (ok(x, seq[j], 6, 0, NULL) != 0xFFu) FAIL("DAQ setup %u", j);
    }
    for (j = 0; j < 3u; ++j) {
        uint8_t a[6] = {0xD3, 0, 0, 0, 0, 3};
        a[4] = (uint8_t)j;
        if (ok(x, a, 6, 0, NULL) != 0xFFu) FAIL("ALLOC_ODT_ENTRY");
    }
    for (j = 0; j < 3u; ++j) {
        uint8_t p[6] = {0xE2, 0, 0, 0, 0, 0};
        p[4] = (uint8_t)j;
        if (ok(x, p, 6, 0, NULL) != 0xFFu) FAIL("SET_DAQ_PTR");
        for (k = 0; k < 3u; ++k) {
            c[0] = 0xE1; c[1] = 0xFF; c[2] = (j == 0u) ? 1u : 2u; c[3] = 0;
            {
                uint32_t a = MEAS_ADDR + 8u * j + 2u * k;
                if (big) { c[4] = (uint8_t)(a >> 24); c[5] = (uint8_t)(a >> 16); c[6] = (uint8_t)(a >> 8); c[7] = (uint8_t)a; }
                else { wr32le(&c[4], a); }
            }
            if (ok(x, c, 8, 0, NULL) != 0xFFu) FAIL("WRITE_DAQ");
        }
    }
    {
        uint8_t m[8] = {0xE0, 0x10, 0, 0, 1, 0, 1, 0};
        const uint8_t s[4] = {0xDE, 0x02, 0, 0};
        const uint8_t go[2] = {0xDD, 0x01};
        if (big) { m[4] = 0u; m[5] = 1u; }
        if (ok(x, m, 8, 0, NULL) != 0xFFu || ok(x, s, 4, 0, NULL) != 0xFFu || ok(x, go, 2, 0, NULL) != 0xFFu) {
            FAIL("DAQ start");
        }
    }
}

static void run_variant(int fd, int big, int pad8, unsigned rounds)
{
    vh_xcp_t *x = malloc(sizeof *x); /* the test driver may use the heap; the slave does not */
    vh_xcp_config_t cfg;
    uint8_t c[VH_XCP_FRAME_MAX];
    unsigned i, dto = 0u;
    uint32_t tick = 0u;
    memset(&cfg, 0, sizeof cfg);
    cfg.cro_id = 0x7F0u; cfg.dto_id = 0x800007F1u;
    cfg.max_cto = fd ? 64u : 8u; cfg.max_dto = fd ? 64u : 8u;
    cfg.fd = (uint8_t)fd; cfg.pad8 = (uint8_t)pad8; cfg.big_endian = (uint8_t)big;
    cfg.protect = VH_XCP_RES_CALPAG | VH_XCP_RES_DAQ; cfg.key = &key; cfg.safe = &safe;
    /* no delay, no lockout here: random UNLOCKs would lock the scripted parts out (the fuzz target has them) */
    cfg.tick_us = 500u; cfg.open_ticks = 50u;
    cfg.regions = REGIONS; cfg.n_regions = 2u;
    cfg.cal_address = CAL_ADDR; cfg.cal_size = sizeof cal_ref;
    cfg.cal_ref = cal_ref; cfg.cal_work = cal_work; cfg.cal_ecu = cal_ecu;
    cfg.chars = CHARS; cfg.n_chars = 4u; cfg.events = EVENTS; cfg.n_events = 3u;
    cfg.id_ascii = "sanitize"; cfg.id_a2l = "SAN";
    init_pages();
    for (i = 0; i < sizeof meas; ++i) {
        meas[i] = (uint8_t)rnd();
    }
    memcpy(meas_copy, meas, sizeof meas);
    if (vh_xcp_init(x, &cfg) != VH_XCP_OK) {
        FAIL("init");
    }
    /* configurations that must be refused */
    {
        vh_xcp_config_t bad = cfg;
        vh_xcp_t *y = malloc(sizeof *y);
        bad.max_cto = 7u;
        if (vh_xcp_init(y, &bad) == VH_XCP_OK) FAIL("MAX_CTO 7 accepted");
        bad = cfg; bad.fd = 0u; bad.max_dto = 64u;
        if (vh_xcp_init(y, &bad) == VH_XCP_OK) FAIL("classic MAX_DTO 64 accepted");
        bad = cfg; bad.cal_size = 20u; /* the double[2] at offset 24 falls outside */
        if (vh_xcp_init(y, &bad) == VH_XCP_OK) FAIL("characteristic outside the segment accepted");
        free(y);
    }
    {
        const uint8_t con[2] = {0xFF, 0x00};
        if (ok(x, con, 2, 0, NULL) != 0xFFu) FAIL("CONNECT");
    }
    unlock(x, VH_XCP_RES_CALPAG);
    unlock(x, VH_XCP_RES_DAQ);
    scripted_daq(x, big);
    for (i = 0; i < rounds; ++i) {
        size_t len = rnd() % (cfg.max_cto + 3u), k;
        uint32_t r = rnd() % 16u;
        for (k = 0; k < sizeof c; ++k) {
            c[k] = (uint8_t)rnd();
        }
        if (r < 12u) {
            c[0] = KNOWN[rnd() % sizeof KNOWN];
        }
        if (r < 6u && (c[0] == 0xF6u || c[0] == 0xF4u || c[0] == 0xE1u || c[0] == 0xEDu)) {
            /* aim addresses near the described memory so the deep paths run */
            uint32_t base = (rnd() & 1u) ? MEAS_ADDR : CAL_ADDR;
            uint32_t a = base + (rnd() % 80u) - 8u;
            if (big) { c[4] = (uint8_t)(a >> 24); c[5] = (uint8_t)(a >> 16); c[6] = (uint8_t)(a >> 8); c[7] = (uint8_t)a; }
            else { wr32le(&c[4], a); }
            c[3] = 0u;
            if (c[0] == 0xE1u) c[1] = 0xFFu;
            c[2] = (uint8_t)(rnd() % 9u);
            if (c[0] == 0xF4u) c[1] = (uint8_t)(1u + rnd() % (cfg.max_cto - 1u));
        }
        if (c[0] == 0xF0u && r < 8u) {
            c[1] = (uint8_t)(rnd() % (cfg.max_cto - 1u));
            len = 2u + c[1];
        }
        if (len > sizeof c) len = sizeof c;
        send(x, (len == 0u && (rnd() & 1u)) ? NULL : c, len, tick);
        (void)answers(x, cfg.max_cto, cfg.max_dto, -1);
        if ((rnd() % 4u) == 0u) {
            uint8_t held[40];
            tick++;
            safe = (uint8_t)((rnd() % 3u) != 0u);
            memcpy(held, cal_ecu, sizeof held);
            vh_xcp_tick(x, tick);
            /* outside the safe state no safety-relevant byte of the ECU page changes */
            if (!safe && (memcmp(held + 16, cal_ecu + 16, 2) != 0 || memcmp(held + 24, cal_ecu + 24, 16) != 0)) {
                FAIL("a safety-relevant characteristic changed outside the safe state");
            }
            meas[0] = (uint8_t)tick; /* the ECU writing its measurements */
            meas_copy[0] = meas[0];
            vh_xcp_event(x, (uint16_t)(rnd() % 4u)); /* channel 3 does not exist */
            dto += answers(x, cfg.max_cto, cfg.max_dto, 0);
        }
        if (memcmp(meas, meas_copy, sizeof meas) != 0) FAIL("measurement memory written");
        check_limits(cal_ecu); /* the working page may hold a half-written element */
        check_limits(cal_ref);
        if (!x->connected && (rnd() % 8u) == 0u) {
            const uint8_t con[2] = {0xFF, 0x00};
            send(x, con, 2, tick);
            (void)answers(x, cfg.max_cto, cfg.max_dto, 1);
            unlock(x, VH_XCP_RES_CALPAG);
            unlock(x, VH_XCP_RES_DAQ);
            scripted_daq(x, big); /* DISCONNECT stopped DAQ: set it up again */
        }
    }
    {
        float f[4] = {1.0f, 2.0f, 3.0f, 4.0f};
        if (memcmp(cal_ref, f, sizeof f) != 0) FAIL("reference page written");
    }
    printf("variant fd=%d big=%d pad8=%d: %u CROs, %u DTO frames, %u errors, %u writes, %u commits\n",
           fd, big, pad8, x->n.cro, dto, x->n.err, x->n.cal_writes, x->n.cal_commits);
    vh_xcp_reset(x);
    free(x);
}

int main(int argc, char **argv)
{
    unsigned rounds = (argc > 1) ? (unsigned)strtoul(argv[1], NULL, 10) : 200000u;
    int fd, big, pad8;
    if (vh_cmac_init(&key, TEST_KEY) != 0) {
        FAIL("key");
    }
    for (fd = 0; fd < 2; ++fd) {
        for (big = 0; big < 2; ++big) {
            for (pad8 = 0; pad8 < 2; ++pad8) {
                run_variant(fd, big, pad8, rounds);
            }
        }
    }
    printf("sanitize_xcp: ok\n");
    return 0;
}
