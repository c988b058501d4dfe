/* fuzz_ecu.c - coverage-guided fuzz target (libFuzzer) for the ECU's RX + tick path.
 *
 * The input is a mode byte, then a program of records, each starting with an op byte:
 *   mode bit 0: SecOC on (a fixed test key, RFC 4493's: never a real key); bit 1: XCP MAX_CTO 64;
 *   bit 2: XCP calibration mode (roll held passive); bit 3: XCP on a bus of its own
 *   0  raw frame:        id selector, flags, len, payload  (anything, CRC almost never right)
 *   1  protected frame:  which RX message, counter step, payload; the E2E CRC and alive counter
 *                        are made right, so the fuzzer reaches the decode, the checks behind
 *                        E2E (SNA, qualifiers, ranges) and the filters
 *   2  ticks:            step the ECU 1..16 times with a fuzzed TX capacity
 *   3  deadline misses / reset
 *   4  XCP CRO frame:    len, payload on the slave's CRO identifier (anything); with its own bus,
 *                        op bit 4 sends it on the vehicle bus (not answered, counted)
 *   5  XCP session:      CONNECT, then GET_SEED/UNLOCK with the key (from the configured key, the
 *                        slave's vh_xcp_key) for CAL/PAG and DAQ as selected, so the fuzzer reaches
 *                        SET_MTA, DOWNLOAD, DAQ setup behind them; op bit 7 a wrong key instead (the
 *                        delay, the lockout); the right key unlocks unless a delay or lockout holds
 *   6  secured frame:    as op 1, then secured by a twin of its sending node (CHS, ROLL, DLS, CIS;
 *                        its sync frame first when due): with SecOC on it must verify (genuine
 *                        traffic is never rejected)
 * The camber calibration is loaded and the XCP slave enabled (as the daemon runs). After every step
 * the transmitted frames are checked: known IDs only, the DBC length, within the capacity (never
 * above VH_ECU_MAX_TX); XCP responses within MAX_CTO, DTOs within MAX_DTO; the driveline and roll
 * estimates stay finite. After every received frame: a frame SecOC rejected is counted once in
 * cnt.secoc_reject and changed nothing else; a CRO frame changed nothing but the slave and the working calibration page; the
 * reference page is never written; outside the ECU's safe state no safety-relevant characteristic of
 * the running page changes. A violation is a crash (abort), like a sanitizer report.
 */
#define _GNU_SOURCE /* RTLD_NEXT */
#include <dlfcn.h>
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "vh_ch.h"
#include "vh_ch_meta.h"
#include "vh_e2e.h"
#include "vh_ecu.h"
#include "vh_pt.h"
#include "vh_pt_meta.h"
#include "vh_secoc_bus.h"
#include "vh_secoc_table.h"
#include "vh_sim.h"
#include "vh_xcp.h"

typedef struct {
    uint32_t id;
    uint8_t len;
    const vh_e2e_cfg_t *e2e;
} rx_msg_t;

static const rx_msg_t RX[] = {
    {VH_PT_DLS_SENSORS_FRAME_ID, VH_PT_DLS_SENSORS_LENGTH, VH_PT_DLS_SENSORS_E2E},
    {VH_PT_CIS_ACCEL_FRAME_ID, VH_PT_CIS_ACCEL_LENGTH, VH_PT_CIS_ACCEL_E2E},
    {VH_CH_CHS_SENSORS_FRAME_ID, VH_CH_CHS_SENSORS_LENGTH, VH_CH_CHS_SENSORS_E2E},
    {VH_CH_ROLL_SENSORS_FRAME_ID, VH_CH_ROLL_SENSORS_LENGTH, VH_CH_ROLL_SENSORS_E2E},
    {VH_CH_ROLL_YAW_RATE_FRAME_ID, VH_CH_ROLL_YAW_RATE_LENGTH, VH_CH_ROLL_YAW_RATE_E2E},
    {VH_CH_ROLL_ACTUATOR_STATUS_FRAME_ID, VH_CH_ROLL_ACTUATOR_STATUS_LENGTH, VH_CH_ROLL_ACTUATOR_STATUS_E2E},
    {VH_CH_ROLL_MODE_CMD_FRAME_ID, VH_CH_ROLL_MODE_CMD_LENGTH, VH_CH_ROLL_MODE_CMD_E2E},
    {VH_CH_CHS_RIDE_HEIGHT_FRAME_ID, VH_CH_CHS_RIDE_HEIGHT_LENGTH, VH_CH_CHS_RIDE_HEIGHT_E2E},
};
#define N_RX (sizeof RX / sizeof RX[0]) /* all of them secured in the DBCs (op 6 secures them) */

static const struct {
    uint32_t id;
    uint8_t len;
} TX[] = {
    {VH_PT_VEHEST_DRIVELINE_EST_FRAME_ID, VH_PT_VEHEST_DRIVELINE_EST_LENGTH},
    {VH_PT_VEHEST_STATUS_FRAME_ID, VH_PT_VEHEST_STATUS_LENGTH},
    {VH_PT_VEHEST_CAMBER_FRAME_ID, VH_PT_VEHEST_CAMBER_LENGTH},
    {VH_SIM_VEHEST_SYNC_ACK_FRAME_ID, VH_SIM_VEHEST_SYNC_ACK_LENGTH},
    {VH_PT_VEHEST_SEC_OC_SYNC_PT_FRAME_ID, VH_PT_VEHEST_SEC_OC_SYNC_PT_LENGTH},
    {VH_CH_VEHEST_TIRE_FORCE_EST_FRAME_ID, VH_CH_VEHEST_TIRE_FORCE_EST_LENGTH},
    {VH_CH_VEHEST_CHASSIS_STATUS_FRAME_ID, VH_CH_VEHEST_CHASSIS_STATUS_LENGTH},
    {VH_CH_VEHEST_TIRE_FORCE_ADAPTIVE_FRAME_ID, VH_CH_VEHEST_TIRE_FORCE_ADAPTIVE_LENGTH},
    {VH_CH_VEHEST_ROLL_CMD_FRAME_ID, VH_CH_VEHEST_ROLL_CMD_LENGTH},
    {VH_CH_VEHEST_ROLL_EST_FRAME_ID, VH_CH_VEHEST_ROLL_EST_LENGTH},
    {VH_CH_VEHEST_SEC_OC_SYNC_CH_FRAME_ID, VH_CH_VEHEST_SEC_OC_SYNC_CH_LENGTH},
};

/* The XCP slave as vehest_can/xcp/ecu.toml describes it, and the bench's seed & key secret. */
#define XCP_CRO 0x7E0u
#define XCP_DTO 0x7E1u
#define XCP_WAIT_TICKS 256u /* a response may queue behind a full DTO queue (VH_XCP_TXQ) */

/* RFC 4493's published AES-128 test key: a test vector, not a secret. */
static const uint8_t TEST_KEY[16] = {0x2b, 0x7e, 0x15, 0x16, 0x28, 0xae, 0xd2, 0xa6,
                                     0xab, 0xf7, 0x15, 0x88, 0x09, 0xcf, 0x4f, 0x3c};

typedef struct {
    const uint8_t *p;
    size_t n;
} input_t;

/* The harness's own helpers (reading the input, the checks) are left out of coverage tracing:
 * their branches and compares are the harness's, not the ECU's, and they run for every byte and
 * every tick. noinline keeps their code out of the instrumented callers. */
#define HARNESS_ONLY __attribute__((no_sanitize("coverage"), noinline))

/* fuzzing harness state (not firmware): re-initialised per input; static for their size */
static vh_ecu_t ecu, before;
/* ecu as every input starts it, per XCP variant (MAX_CTO 8/64 x calibration mode x own bus):
 * vh_ecu_init (its tyre-model peak search was 80 % of an input's time), the camber calibration and
 * vh_ecu_xcp_enable, done once each; copied back into the same object, so the pointers into it stay valid */
#define N_XCP_VARIANTS 8u
static vh_ecu_t initialised[N_XCP_VARIANTS];
static vh_cmac_key_t xcp_key; /* the slave's seed & key key (the test key), outside the ECU as the host keeps it */
static int have_initialised;
static vh_ecu_cal_t ref;               /* the reference page as enabled: never written */
static vh_secoc_bus_t sec, twin[VH_SECOC_N_NODES]; /* the ECU's SecOC (node VEHEST), each sending node's twin */
static vh_secoc_bus_t sec_keyed, twin_keyed[VH_SECOC_N_NODES], twin_off[VH_SECOC_N_NODES]; /* start states */
static uint8_t secoc_on, max_cto, own_bus;

/* The snapshots' copies and compares (tens of kB, several per input): libc's own memcpy and memcmp,
 * not ASan's wrappers, which first scan the shadow of both ranges, as long as the copy itself. Only
 * for the harness's own statics, whole objects and offsetof ranges of them: nothing for ASan there. */
static void *(*libc_memcpy)(void *, const void *, size_t);
static int (*libc_memcmp)(const void *, const void *, size_t);

HARNESS_ONLY static int take(input_t *in, uint8_t *b)
{
    if (in->n == 0u) {
        return 0;
    }
    *b = *in->p++;
    in->n--;
    return 1;
}

/* up to n bytes into b (fewer at the end of the input), as a loop of take() would */
HARNESS_ONLY static void take_n(input_t *in, uint8_t *b, size_t n)
{
    if (n > in->n) {
        n = in->n;
    }
    memcpy(b, in->p, n);
    in->p += n;
    in->n -= n;
}

static int fd_length(uint8_t len)
{
    return len <= 8u || len == 12u || len == 16u || len == 20u || len == 24u || len == 32u || len == 48u ||
           len == 64u;
}

HARNESS_ONLY static void check_tx(const vh_frame_t *tx, size_t n, size_t cap)
{
    size_t i, k;
    int known;
    if (n > cap || cap > VH_ECU_MAX_TX) {
        abort();
    }
    for (i = 0; i < n; ++i) {
        if ((tx[i].flags & VH_FRAME_EXT) || !fd_length(tx[i].len)) {
            abort();
        }
        known = 0;
        for (k = 0; k < sizeof TX / sizeof TX[0]; ++k) {
            if (tx[i].id == TX[k].id) {
                known = 1;
                if (tx[i].len != TX[k].len) {
                    abort();
                }
            }
        }
        if (tx[i].id == XCP_DTO) { /* RES/ERR/EV/SERV (PID >= 0xFC) within MAX_CTO, a DTO within MAX_DTO */
            known = 1;
            if (tx[i].len == 0u || tx[i].len > (tx[i].data[0] >= 0xFCu ? max_cto : ecu.xcp.slave.cfg.max_dto)) {
                abort();
            }
        }
        if (!known) {
            abort();
        }
    }
    for (i = 0; i < VH_ECU_N_DKF; ++i) {
        if (!isfinite(ecu.app.drv.dkf[i].x[2])) {
            abort();
        }
    }
    for (i = 0; i < VH_ROLL_NX; ++i) {
        if (!isfinite(ecu.app.roll.ukf.x[i]) || !isfinite(ecu.app.roll.ukf.P[i * (VH_ROLL_NX + 1u)])) {
            abort();
        }
    }
    if (libc_memcmp(&ecu.xcp.ref, &ref, sizeof ref) != 0) { /* page 1 is never written */
        abort();
    }
}

/* Outside the safe state of the tick (the ECU's decision) no safety-relevant characteristic of the
 * running page changed in it. */
HARNESS_ONLY static void check_safe(const vh_ecu_cal_t *page_before)
{
    const vh_xcp_config_t *c = &ecu.xcp.slave.cfg;
    unsigned i;
    if (ecu.xcp.safe) {
        return;
    }
    for (i = 0; i < c->n_chars; ++i) {
        const size_t off = c->chars[i].address - c->cal_address;
        const size_t len = (size_t)c->chars[i].count * (c->chars[i].type >= VH_XCP_F64 ? 8u : c->chars[i].type >= VH_XCP_U32 ? 4u : c->chars[i].type >= VH_XCP_U16 ? 2u : 1u);
        if ((c->chars[i].flags & VH_XCP_CHAR_SAFETY) &&
            libc_memcmp((const uint8_t *)page_before + off, (const uint8_t *)&ecu.xcp.page + off, len) != 0) {
            abort();
        }
    }
}

static size_t tick(vh_frame_t *tx, size_t cap)
{
    static vh_ecu_cal_t page;
    size_t n;
    libc_memcpy(&page, &ecu.xcp.page, sizeof page);
    n = vh_ecu_step(&ecu, tx, cap);
    check_tx(tx, n, cap);
    check_safe(&page);
    return n;
}

HARNESS_ONLY static int secured(uint32_t id)
{
    size_t i;
    for (i = 0; i < sizeof VH_SECOC_MSGS / sizeof VH_SECOC_MSGS[0]; ++i) {
        if (VH_SECOC_MSGS[i].id == id) {
            return 1;
        }
    }
    return 0;
}

/* The parts of the ECU a CRO frame must leave alone: all of it but the slave's own state and the
 * working calibration page (xcp.slave, xcp.work); the reference and running pages are in it. */
#define OFF(m) offsetof(vh_ecu_t, m)
static const struct {
    size_t off, len;
} NOT_XCP[] = {
    {0u, OFF(xcp.slave)},
    {OFF(xcp.ref), OFF(xcp.work) - OFF(xcp.ref)},
    {OFF(xcp.work) + sizeof ecu.xcp.work, sizeof ecu - (OFF(xcp.work) + sizeof ecu.xcp.work)},
};
typedef char not_xcp_covers_the_rest[(OFF(xcp.slave) + sizeof ecu.xcp.slave == OFF(xcp.ref) &&
                                      OFF(xcp.ref) + sizeof ecu.xcp.ref == OFF(xcp.work)) ? 1 : -1];

HARNESS_ONLY static void snapshot_not_xcp(void)
{
    size_t i;
    for (i = 0; i < sizeof NOT_XCP / sizeof NOT_XCP[0]; ++i) {
        libc_memcpy((uint8_t *)&before + NOT_XCP[i].off, (const uint8_t *)&ecu + NOT_XCP[i].off, NOT_XCP[i].len);
    }
}

HARNESS_ONLY static int changed_not_xcp(void)
{
    size_t i;
    for (i = 0; i < sizeof NOT_XCP / sizeof NOT_XCP[0]; ++i) {
        if (libc_memcmp((const uint8_t *)&before + NOT_XCP[i].off, (const uint8_t *)&ecu + NOT_XCP[i].off,
                        NOT_XCP[i].len) != 0) {
            return 1;
        }
    }
    return 0;
}

/* One received frame, and what it may have changed (the snapshot only where there is a check:
 * the ECU is over 40 kB; for a CRO frame only the part it must not change, two thirds of it).
 * `xcp_bus`: heard on XCP's own bus (vh_ecu_xcp_rx_own), else on the vehicle bus (vh_ecu_rx). */
static void deliver(const vh_frame_t *f, int xcp_bus)
{
    if (xcp_bus) {
        (void)vh_ecu_xcp_rx_own(&ecu, f);
    } else {
        vh_ecu_rx(&ecu, f);
    }
}

HARNESS_ONLY static void rx_on(const vh_frame_t *f, int xcp_bus)
{
    const uint32_t rejected = sec.cnt.rejected;
    if (!(secoc_on && secured(f->id))) {
        if (f->id != XCP_CRO) {
            deliver(f, xcp_bus);
        } else {
            snapshot_not_xcp(); /* cnt is in it */
            deliver(f, xcp_bus);
            if (ecu.cnt.secoc_reject != before.cnt.secoc_reject) {
                abort(); /* nothing but a rejection is counted there */
            }
            if (!(f->flags & VH_FRAME_EXT) && changed_not_xcp()) { /* the slave writes itself and page 0 only */
                abort();
            }
        }
        if (secoc_on && sec.cnt.rejected != rejected) {
            abort(); /* only a secured frame can fail SecOC */
        }
        return;
    }
    libc_memcpy(&before, &ecu, sizeof ecu);
    deliver(f, xcp_bus);
    if (ecu.cnt.secoc_reject != (uint16_t)(before.cnt.secoc_reject + (sec.cnt.rejected != rejected))) {
        abort(); /* each rejection counted once (the 16-bit counter wraps), nothing else counted there */
    }
    if (sec.cnt.rejected != rejected) { /* a rejected frame reaches no application */
        memcpy(&before.cnt, &ecu.cnt, sizeof ecu.cnt);
        if (libc_memcmp(&before, &ecu, sizeof ecu) != 0) {
            abort();
        }
    }
    if (f->id == XCP_CRO && !(f->flags & VH_FRAME_EXT)) { /* a CRO identifier SecOC secures (none does) */
        memcpy(&before.xcp.slave, &ecu.xcp.slave, sizeof ecu.xcp.slave);
        memcpy(&before.xcp.work, &ecu.xcp.work, sizeof ecu.xcp.work);
        if (libc_memcmp(&before, &ecu, sizeof ecu) != 0) {
            abort();
        }
    }
}

HARNESS_ONLY static void rx(const vh_frame_t *f) { rx_on(f, 0); }

/* A CRO command; the response (RES or ERR) into res, 0 if none came. */
static int xcp_cmd(const uint8_t *cmd, uint8_t len, uint8_t res[VH_XCP_FRAME_MAX])
{
    vh_frame_t f, tx[VH_ECU_MAX_TX];
    size_t n, i;
    unsigned k;
    memset(&f, 0, sizeof f);
    f.id = XCP_CRO;
    f.flags = VH_FRAME_FD | VH_FRAME_BRS;
    f.len = len;
    memcpy(f.data, cmd, len);
    rx_on(&f, own_bus); /* the master on the slave's bus */
    for (k = 0; k < XCP_WAIT_TICKS; ++k) {
        n = tick(tx, VH_ECU_MAX_TX);
        for (i = 0; i < n; ++i) {
            if (tx[i].id == XCP_DTO && tx[i].data[0] >= 0xFEu) {
                memcpy(res, tx[i].data, VH_XCP_FRAME_MAX);
                return 1;
            }
        }
    }
    return 0;
}

/* CONNECT, then seed & key for the resources in `unlock` (VH_XCP_RES_CALPAG, VH_XCP_RES_DAQ), with
 * the right key, or a wrong one when `wrong`. */
static void xcp_session(uint8_t unlock, int wrong)
{
    static const uint8_t resources[2] = {VH_XCP_RES_CALPAG, VH_XCP_RES_DAQ};
    uint8_t cmd[8] = {0xFFu, 0x00u}, res[VH_XCP_FRAME_MAX];
    unsigned i;
    if (!xcp_cmd(cmd, 2u, res) || res[0] != 0xFFu) {
        abort(); /* a CONNECT is always answered */
    }
    for (i = 0; i < 2u; ++i) {
        if (!(unlock & resources[i])) {
            continue;
        }
        cmd[0] = 0xF8u; /* GET_SEED mode 0 */
        cmd[1] = 0u;
        cmd[2] = resources[i];
        if (!xcp_cmd(cmd, 3u, res)) {
            abort();
        }
        if (res[0] == 0xFEu && (res[1] == 0x33u || res[1] == 0x24u) &&
            (ecu.xcp.slave.fail_streak > 0u || ecu.xcp.slave.locked_out)) {
            continue; /* in the delay after a wrong key, or locked out: seed & key waits */
        }
        if (res[0] != 0xFFu || (res[1] != VH_XCP_SEED_LEN && res[1] != 0u)) {
            abort();
        }
        if (res[1] == 0u) {
            continue; /* unlocked already */
        }
        cmd[0] = 0xF7u; /* UNLOCK */
        cmd[1] = VH_XCP_KEY_LEN;
        vh_xcp_key(&xcp_key, resources[i], &res[2], &cmd[2]);
        cmd[2] = (uint8_t)(cmd[2] ^ (wrong ? 0x5Au : 0u));
        if (!xcp_cmd(cmd, 2u + VH_XCP_KEY_LEN, res) || (res[0] == 0xFFu) == (wrong != 0)) {
            abort(); /* the right key unlocks, a wrong one never */
        }
    }
}

static int keyed(vh_secoc_bus_t *s, unsigned self)
{
    unsigned i;
    vh_secoc_bus_init(s, self);
    for (i = 0; i < VH_SECOC_N_NODES; ++i) {
        if (vh_secoc_bus_set_key(s, i, TEST_KEY) != VH_OK) {
            return 0;
        }
    }
    return vh_secoc_bus_start(s, 1u, UINT64_MAX) == VH_OK;
}

/* The sending node of a secured frame (VH_SECOC_NODE_*), or -1. */
HARNESS_ONLY static int sender(uint32_t id)
{
    size_t i;
    for (i = 0; i < sizeof VH_SECOC_MSGS / sizeof VH_SECOC_MSGS[0]; ++i) {
        if (VH_SECOC_MSGS[i].id == id) {
            return VH_SECOC_MSGS[i].node;
        }
    }
    return -1;
}

/* What every input starts from, made once: the ECU initialised, the camber calibration loaded
 * and the XCP slave enabled (MAX_CTO 8 and 64), and the SecOC nodes keyed and started. */
static void init_once(void)
{
    static const float x[3] = {1.0f, 0.0f, 0.0f}, z[3] = {0.0f, 0.0f, 1.0f}, lsb[3] = {0.004f, 0.004f, 0.004f};
    vh_ecu_config_t cfg;
    vh_ecu_xcp_config_t xcfg;
    vh_camber_cal_t cal;
    unsigned m, w;

    *(void **)&libc_memcpy = dlsym(RTLD_NEXT, "memcpy");
    *(void **)&libc_memcmp = dlsym(RTLD_NEXT, "memcmp");
    if (libc_memcpy == NULL || libc_memcmp == NULL) {
        abort();
    }
    vh_ecu_config_default(&cfg);
    if (vh_ecu_init(&ecu, &cfg) != VH_OK || vh_camber_cal_from_axes(&cal, x, z, lsb, 1e-3f) != VH_OK ||
        vh_cmac_init(&xcp_key, TEST_KEY) != 0) {
        abort();
    }
    memcpy(&before, &ecu, sizeof ecu);
    for (m = 0; m < N_XCP_VARIANTS; ++m) {
        memcpy(&ecu, &before, sizeof ecu);
        for (w = 0; w < VH_ECU_N_WHEELS; ++w) {
            (void)vh_camber_app_set_calibration(&ecu.app.camber, w, &cal);
        }
        memset(&xcfg, 0, sizeof xcfg);
        xcfg.cro_id = XCP_CRO;
        xcfg.dto_id = XCP_DTO;
        xcfg.max_cto = (m & 1u) ? 64u : 8u;
        xcfg.max_dto = 48u;
        xcfg.fd = 1u;
        xcfg.key = &xcp_key;
        xcfg.cal_mode = (uint8_t)((m >> 1) & 1u);
        xcfg.own_bus = (uint8_t)((m >> 2) & 1u);
        if (vh_ecu_xcp_enable(&ecu, &xcfg) != VH_OK) {
            abort();
        }
        /* a short delay after a wrong key (the same code, 4 ticks doubling instead of 1000): the
         * lockout is then a few records away, not 15000 ticks of input */
        ecu.xcp.slave.cfg.unlock_delay_ticks = 4u;
        memcpy(&initialised[m], &ecu, sizeof ecu); /* the same object: pointers into it stay valid */
    }
    if (!keyed(&sec_keyed, VH_SECOC_NODE_VEHEST)) {
        abort();
    }
    for (m = 0; m < VH_SECOC_N_NODES; ++m) {
        vh_secoc_bus_init(&twin_off[m], m); /* off: tails stay zero, no sync frames */
        if (!keyed(&twin_keyed[m], m)) {
            abort();
        }
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    vh_frame_t f, tx[VH_ECU_MAX_TX], sf[3];
    uint8_t counter[N_RX] = {0u};
    input_t in = {data, size};
    uint8_t mode, op, a, b, c;
    unsigned k;
    size_t n, i;
    uint32_t accepted;
    int node;

    if (!take(&in, &mode)) {
        return 0;
    }
    secoc_on = mode & 1u;
    max_cto = (mode & 2u) ? 64u : 8u;
    own_bus = (uint8_t)((mode >> 3) & 1u);
    if (!have_initialised) {
        init_once();
        have_initialised = 1;
    }
    libc_memcpy(&ecu, &initialised[(mode >> 1) & 7u], sizeof ecu);
    memcpy(&ref, &ecu.xcp.ref, sizeof ref);
    memcpy(twin, secoc_on ? twin_keyed : twin_off, sizeof twin);
    if (secoc_on) {
        sec = sec_keyed;
        vh_ecu_set_secoc(&ecu, &sec);
    }
    while (take(&in, &op)) {
        switch (op & 7u) {
        case 0: /* raw frame */
            if (!take(&in, &a) || !take(&in, &b) || !take(&in, &c)) {
                return 0;
            }
            memset(&f, 0, sizeof f);
            f.id = (a < 2u * N_RX) ? RX[a % N_RX].id : ((uint32_t)a << 3 | (op >> 3)) & 0x7FFu;
            f.flags = b & 7u;
            f.len = (uint8_t)(c % 65u);
            take_n(&in, f.data, f.len);
            rx(&f);
            break;
        case 1: /* a frame the E2E check accepts (or, with a counter step of 0 or > 1, flags) */
        case 6: /* the same, secured by its sending node's twin (SecOC off: as it sends without) */
            if (!take(&in, &a) || !take(&in, &b)) {
                return 0;
            }
            node = sender(RX[a % N_RX].id);
            memset(&f, 0, sizeof f);
            f.id = RX[a % N_RX].id;
            f.len = RX[a % N_RX].len;
            f.flags = VH_FRAME_FD | VH_FRAME_BRS;
            /* byte 0 is the CRC; protect writes the counter and what else its profile owns, the rest
             * of byte 1 is payload (CHS_Sensors' first qualifiers) */
            take_n(&in, &f.data[1], f.len > 1u ? f.len - 1u : 0u);
            if ((op & 7u) == 6u && node >= 0) { /* the SecOC tail: zero under E2E, then the node's FV and MAC */
                memset(&f.data[f.len - VH_SECOC_TAIL_BYTES], 0, VH_SECOC_TAIL_BYTES);
            }
            counter[a % N_RX] = (uint8_t)(counter[a % N_RX] + (b & 3u) - 1u); /* protect adds 1 */
            vh_e2e_protect(RX[a % N_RX].e2e, f.data, f.len, &counter[a % N_RX]);
            if ((op & 7u) == 1u || node < 0) {
                rx(&f);
                break;
            }
            sf[0] = f;
            n = vh_secoc_bus_tx(&twin[node], sf, 1u, 3u);
            for (i = 0; i < n; ++i) {
                accepted = sec.cnt.accepted + sec.cnt.syncs;
                rx(&sf[i]);
                if (secoc_on && sec.cnt.accepted + sec.cnt.syncs != accepted + 1u) {
                    abort(); /* genuine traffic verifies */
                }
            }
            break;
        case 2: /* ticks */
            if (!take(&in, &a)) {
                return 0;
            }
            for (k = 0; k <= (a & 15u); ++k) {
                (void)tick(tx, (size_t)((a >> 4) % (VH_ECU_MAX_TX + 1u)));
            }
            break;
        case 3: /* deadline misses, now and then a reset */
            if (!take(&in, &a)) {
                return 0;
            }
            if (a == 0xFFu) {
                vh_ecu_reset(&ecu);
            } else {
                vh_ecu_note_deadline_miss(&ecu, a);
            }
            break;
        case 4: /* a CRO frame, any content */
            if (!take(&in, &a)) {
                return 0;
            }
            memset(&f, 0, sizeof f);
            f.id = XCP_CRO;
            f.flags = (op & 8u) ? 0u : (VH_FRAME_FD | VH_FRAME_BRS);
            f.len = (uint8_t)(a % 65u);
            take_n(&in, f.data, f.len);
            rx_on(&f, own_bus && !(op & 16u)); /* op bit 4 with its own bus: heard on the vehicle bus */
            break;
        default: /* 5, 7: an XCP session (CONNECT, seed & key; op bit 7: a wrong key) */
            xcp_session((uint8_t)(op >> 3), op & 0x80u);
            break;
        }
    }
    (void)tick(tx, VH_ECU_MAX_TX);
#ifdef VH_FUZZ_CANARY
    /* The suite's positive controls: a "bug" the fuzzer must get to (and report) from its seeds, or
     * the harness reaches too little. 1: behind an accepted chassis frame and a filter step;
     * 2: behind an XCP calibration write committed (after seed & key); 3: behind a roll UKF step
     * on frames that passed SecOC; 4: behind seed & key locked out by wrong keys; 5: behind a
     * safety-relevant write refused outside the safe state. */
    if ((VH_FUZZ_CANARY == 1 && ecu.app.tf.heard && ecu.app.tf.skf.steps > 0u) ||
        (VH_FUZZ_CANARY == 2 && ecu.xcp.slave.n.cal_commits > 0u) ||
        (VH_FUZZ_CANARY == 3 && secoc_on && sec.cnt.accepted > 0u && ecu.app.roll.stepped) ||
        (VH_FUZZ_CANARY == 4 && ecu.xcp.slave.locked_out) ||
        (VH_FUZZ_CANARY == 5 && ecu.xcp.slave.n.cal_unsafe > 0u)) {
        abort();
    }
#endif
    return 0;
}
