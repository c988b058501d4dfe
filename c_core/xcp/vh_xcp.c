/* vh_xcp.c - see vh_xcp.h. Command and error codes: ASAM MCD-1 XCP V1.x, Part 2 (protocol
 * layer); CAN transport: Part 3 (no header, no tail: one XCP packet per CAN frame). */
#include "vh_xcp.h"

#include <string.h>

/* Packet identifiers, slave -> master */
#define PID_RES 0xFFu
#define PID_ERR 0xFEu

/* Error codes (Part 2, "error codes") */
#define ERR_CMD_SYNCH 0x00u
#define ERR_DAQ_ACTIVE 0x11u
#define ERR_CMD_UNKNOWN 0x20u
#define ERR_CMD_SYNTAX 0x21u
#define ERR_OUT_OF_RANGE 0x22u
#define ERR_WRITE_PROTECTED 0x23u
#define ERR_ACCESS_DENIED 0x24u
#define ERR_ACCESS_LOCKED 0x25u
#define ERR_PAGE_NOT_VALID 0x26u
#define ERR_MODE_NOT_VALID 0x27u
#define ERR_SEGMENT_NOT_VALID 0x28u
#define ERR_SEQUENCE 0x29u
#define ERR_DAQ_CONFIG 0x2Au
#define ERR_MEMORY_OVERFLOW 0x30u
#define ERR_RESOURCE_TEMPORARY_NOT_ACCESSIBLE 0x33u /* XCP 1.1 */

/* DAQ allocation sequence (Part 2, "dynamic DAQ configuration"): FREE_DAQ, ALLOC_DAQ, then all
 * ALLOC_ODT, then all ALLOC_ODT_ENTRY. */
#define DAQ_FREED 0u
#define DAQ_LISTS 1u
#define DAQ_ODTS 2u
#define DAQ_ENTRIES 3u
#define DAQ_NONE 4u /* before the first FREE_DAQ */

#define MODE_SELECTED 0x01u
#define MODE_STIM 0x02u
#define MODE_TIMESTAMP 0x10u
#define MODE_PID_OFF 0x20u
#define MODE_RUNNING 0x40u

#define TS_SIZE 4u         /* DAQ timestamp: 4 bytes, the tick count */
#define PAGE_WORK 0u
#define PAGE_REF 1u
#define CHAR_PENDING 0x01u
#define CHAR_OPEN 0x02u

static uint16_t rd16(const uint8_t *p, bool be)
{
    return be ? (uint16_t)((p[0] << 8) | p[1]) : (uint16_t)(p[0] | (p[1] << 8));
}

static uint32_t rd32(const uint8_t *p, bool be)
{
    return be ? ((uint32_t)p[0] << 24) | ((uint32_t)p[1] << 16) | ((uint32_t)p[2] << 8) | p[3]
              : ((uint32_t)p[3] << 24) | ((uint32_t)p[2] << 16) | ((uint32_t)p[1] << 8) | p[0];
}

static void wr16(uint8_t *p, uint16_t v, bool be)
{
    p[be ? 1 : 0] = (uint8_t)(v & 0xFFu);
    p[be ? 0 : 1] = (uint8_t)(v >> 8);
}

static void wr32(uint8_t *p, uint32_t v, bool be)
{
    unsigned i;
    for (i = 0; i < 4u; ++i) {
        p[be ? 3u - i : i] = (uint8_t)(v >> (8u * i));
    }
}

static const uint8_t FD_LENGTHS[] = {12u, 16u, 20u, 24u, 32u, 48u, 64u};

/* CAN FD carries 0..8, 12, 16, 20, 24, 32, 48 or 64 bytes: pad to the next one. */
static uint8_t frame_len(const vh_xcp_t *x, uint8_t len)
{
    unsigned i;
    if (len <= 8u) {
        return (!x->cfg.fd && x->cfg.pad8) ? 8u : len;
    }
    for (i = 0; i < sizeof FD_LENGTHS; ++i) {
        if (len <= FD_LENGTHS[i]) {
            return FD_LENGTHS[i];
        }
    }
    return VH_XCP_FRAME_MAX;
}

static void frame_init(const vh_xcp_t *x, vh_xcp_frame_t *f)
{
    memset(f, 0, sizeof *f);
    f->id = x->cfg.dto_id & 0x1FFFFFFFu;
    f->ext = (uint8_t)((x->cfg.dto_id >> 31) & 1u);
    f->fd = x->cfg.fd;
}

/* The response slot; `len` bytes including the PID. */
static uint8_t *res_begin(vh_xcp_t *x, uint8_t len)
{
    frame_init(x, &x->res);
    x->res.data[0] = PID_RES;
    x->res.len = frame_len(x, len);
    x->res_pending = 1u;
    return x->res.data;
}

static void res_ok(vh_xcp_t *x)
{
    (void)res_begin(x, 1u);
}

static void res_err(vh_xcp_t *x, uint8_t code)
{
    uint8_t *r = res_begin(x, 2u);
    r[0] = PID_ERR;
    r[1] = code;
    x->n.err++;
    switch (code) {
    case ERR_CMD_UNKNOWN: x->n.err_unknown++; break;
    case ERR_CMD_SYNTAX: x->n.err_syntax++; break;
    case ERR_ACCESS_DENIED:
    case ERR_WRITE_PROTECTED: x->n.err_access++; break;
    case ERR_OUT_OF_RANGE: x->n.err_range++; break;
    case ERR_ACCESS_LOCKED: x->n.err_locked++; break;
    case ERR_SEQUENCE:
    case ERR_MEMORY_OVERFLOW:
    case ERR_DAQ_CONFIG:
    case ERR_DAQ_ACTIVE: x->n.err_daq++; break;
    default: x->n.err_other++; break;
    }
}

/* [a, a+len) inside [base, base+size), without overflow. */
static bool inside(uint32_t a, uint32_t len, uint32_t base, uint32_t size)
{
    return a >= base && (a - base) <= size && len <= size - (a - base);
}

static const uint8_t *cal_page(const vh_xcp_t *x, uint8_t page)
{
    return (page == PAGE_REF) ? x->cfg.cal_ref : x->cfg.cal_work;
}

/* Memory for reading [a, a+len) with `need` access; NULL when it is not described memory.
 * UPLOAD reads the page the master is on; DAQ samples what the ECU uses. */
static const uint8_t *resolve(const vh_xcp_t *x, uint32_t a, uint32_t len, uint8_t need)
{
    unsigned i;
    if (x->cfg.cal_size > 0u && inside(a, len, x->cfg.cal_address, x->cfg.cal_size)) {
        const uint8_t *base = (need == VH_XCP_ACC_DAQ) ? x->cfg.cal_ecu : cal_page(x, x->page_xcp);
        return base + (a - x->cfg.cal_address);
    }
    for (i = 0; i < x->cfg.n_regions; ++i) {
        const vh_xcp_region_t *r = &x->cfg.regions[i];
        if ((r->access & need) && inside(a, len, r->address, r->size)) {
            return r->mem + (a - r->address);
        }
    }
    return NULL;
}

static uint8_t type_size(uint8_t t)
{
    static const uint8_t SZ[8] = {1u, 1u, 2u, 2u, 4u, 4u, 4u, 8u};
    return (t < 8u) ? SZ[t] : 0u;
}

/* Element value as a double (native byte order, memcpy: no alignment assumed). */
static double element(const uint8_t *p, uint8_t t)
{
    switch (t) {
    case VH_XCP_U8: return (double)p[0];
    case VH_XCP_I8: return (double)(int8_t)p[0];
    case VH_XCP_U16: { uint16_t v; memcpy(&v, p, 2); return (double)v; }
    case VH_XCP_I16: { int16_t v; memcpy(&v, p, 2); return (double)v; }
    case VH_XCP_U32: { uint32_t v; memcpy(&v, p, 4); return (double)v; }
    case VH_XCP_I32: { int32_t v; memcpy(&v, p, 4); return (double)v; }
    case VH_XCP_F32: { float v; memcpy(&v, p, 4); return (double)v; }
    default: { double v; memcpy(&v, p, 8); return v; }
    }
}

static uint32_t char_size(const vh_xcp_char_t *c)
{
    return (uint32_t)c->count * type_size(c->type);
}

static bool in_limits(const vh_xcp_char_t *c, double v)
{
    return v >= c->min && v <= c->max; /* false for a NaN */
}

/* Every element of characteristic c (its bytes at p) within its limits. */
static bool char_valid(const vh_xcp_char_t *c, const uint8_t *p)
{
    uint16_t e;
    uint8_t es = type_size(c->type);
    for (e = 0; e < c->count; ++e) {
        if (!in_limits(c, element(p + (uint32_t)e * es, c->type))) {
            return false;
        }
    }
    return true;
}

int vh_xcp_init(vh_xcp_t *x, const vh_xcp_config_t *cfg)
{
    unsigned i, j;
    memset(x, 0, sizeof *x);
    if (cfg == NULL || cfg->max_cto < 8u || cfg->max_cto > VH_XCP_FRAME_MAX || cfg->max_dto < 8u ||
        cfg->max_dto > VH_XCP_FRAME_MAX || (!cfg->fd && (cfg->max_cto > 8u || cfg->max_dto > 8u)) ||
        cfg->n_regions > VH_XCP_MAX_REGIONS || cfg->n_chars > VH_XCP_MAX_CHARS ||
        cfg->n_events > VH_XCP_MAX_EVENTS || (cfg->n_regions > 0u && cfg->regions == NULL) ||
        (cfg->n_chars > 0u && cfg->chars == NULL) || (cfg->n_events > 0u && cfg->events == NULL) ||
        (cfg->cal_size > 0u && (cfg->cal_ref == NULL || cfg->cal_work == NULL || cfg->cal_ecu == NULL)) ||
        (cfg->cal_size == 0u && cfg->n_chars > 0u) || (cfg->protect != 0u && cfg->key == NULL) ||
        cfg->cal_size > 0xFFFFFFFFu - cfg->cal_address) {
        return VH_XCP_EINVAL;
    }
    for (i = 0; i < cfg->n_regions; ++i) {
        const vh_xcp_region_t *r = &cfg->regions[i];
        if (r->mem == NULL || r->size == 0u || r->size > 0xFFFFFFFFu - r->address) {
            return VH_XCP_EINVAL;
        }
    }
    for (i = 0; i < cfg->n_chars; ++i) {
        const vh_xcp_char_t *c = &cfg->chars[i];
        if (type_size(c->type) == 0u || c->count == 0u || !(c->min <= c->max) ||
            !inside(c->address, char_size(c), cfg->cal_address, cfg->cal_size)) {
            return VH_XCP_EINVAL;
        }
        for (j = 0; j < i; ++j) { /* apart: a written byte belongs to one characteristic */
            const vh_xcp_char_t *d = &cfg->chars[j];
            if (c->address < d->address + char_size(d) && d->address < c->address + char_size(c)) {
                return VH_XCP_EINVAL;
            }
        }
    }
    x->cfg = *cfg;
    vh_xcp_reset(x);
    return VH_XCP_OK;
}

static void daq_free(vh_xcp_t *x)
{
    x->n_daq = 0u;
    x->n_odt = 0u;
    x->n_entries = 0u;
    x->ptr_valid = 0u;
    memset(x->daq, 0, sizeof x->daq);
    memset(x->odt, 0, sizeof x->odt);
    memset(x->entry, 0, sizeof x->entry);
}

static void disconnect(vh_xcp_t *x)
{
    unsigned i;
    x->connected = false;
    x->locked = x->cfg.protect;
    x->seed_for = 0u;
    for (i = 0; i < x->n_daq; ++i) { /* no RESUME mode: DAQ ends with the session */
        x->daq[i].mode = (uint8_t)(x->daq[i].mode & ~(MODE_RUNNING | MODE_SELECTED));
    }
}

void vh_xcp_reset(vh_xcp_t *x)
{
    vh_xcp_config_t cfg = x->cfg;
    memset(x, 0, sizeof *x); /* the lockout and the delay end here, and only here */
    x->cfg = cfg;
    x->daq_state = DAQ_NONE;
    x->page_ecu = x->page_xcp = x->page_ecu_next = PAGE_WORK;
    if (cfg.cal_size > 0u) {
        memcpy(cfg.cal_work, cfg.cal_ref, cfg.cal_size);
        memcpy(cfg.cal_ecu, cfg.cal_ref, cfg.cal_size);
    }
    disconnect(x);
}

static bool safe_now(const vh_xcp_t *x)
{
    return x->cfg.safe == NULL || *x->cfg.safe != 0u;
}

static bool any_safety_char(const vh_xcp_t *x)
{
    unsigned i;
    for (i = 0; i < x->cfg.n_chars; ++i) {
        if (x->cfg.chars[i].flags & VH_XCP_CHAR_SAFETY) {
            return true;
        }
    }
    return false;
}

void vh_xcp_tick(vh_xcp_t *x, uint32_t tick)
{
    unsigned i;
    const bool safe = safe_now(x);
    x->tick = tick;
    if (x->cfg.cal_size == 0u) {
        return;
    }
    if (x->page_ecu_next != x->page_ecu && !safe && any_safety_char(x)) {
        /* the state left safe between SET_CAL_PAGE and this boundary: the switch is dropped */
        x->page_ecu_next = x->page_ecu;
        x->n.cal_unsafe++;
    }
    if (x->page_ecu_next != x->page_ecu) { /* page switch: the whole segment at once */
        x->page_ecu = x->page_ecu_next;
        memcpy(x->cfg.cal_ecu, cal_page(x, x->page_ecu), x->cfg.cal_size);
        memset(x->char_state, 0, sizeof x->char_state);
        return;
    }
    if (x->page_ecu != PAGE_WORK) {
        return; /* writes wait in the working page until the ECU switches to it */
    }
    for (i = 0; i < x->cfg.n_chars; ++i) {
        /* a characteristic written part-way (the master has not reached its last byte) waits,
         * for cfg.open_ticks at most (a master that edits one element of an array) */
        bool stale = (x->char_state[i] & CHAR_OPEN) && x->cfg.open_ticks > 0u &&
                     (uint32_t)(tick - x->char_tick[i]) >= x->cfg.open_ticks;
        if (x->char_state[i] == CHAR_PENDING || stale) {
            const vh_xcp_char_t *c = &x->cfg.chars[i];
            uint32_t off = c->address - x->cfg.cal_address;
            if ((c->flags & VH_XCP_CHAR_SAFETY) && !safe) {
                /* written in the safe state, due after it ended (an array left open): dropped */
                memcpy(x->cfg.cal_work + off, x->cfg.cal_ecu + off, char_size(c));
                x->n.cal_unsafe++;
            } else if (char_valid(c, x->cfg.cal_work + off)) {
                memcpy(x->cfg.cal_ecu + off, x->cfg.cal_work + off, char_size(c));
                x->n.cal_commits++;
            } else {
                /* an element left half written (its range check never ran) holds a value out of
                 * range: the write is dropped, the working page takes the ECU's value back */
                memcpy(x->cfg.cal_work + off, x->cfg.cal_ecu + off, char_size(c));
                x->n.cal_dropped++;
            }
            x->char_state[i] = 0u;
        }
    }
}

void vh_xcp_key(const vh_cmac_key_t *k, uint8_t resource, const uint8_t seed[VH_XCP_SEED_LEN],
                uint8_t key[VH_XCP_KEY_LEN])
{
    uint8_t msg[5u + VH_XCP_SEED_LEN], tag[VH_AES_BLOCK];
    msg[0] = 'X';
    msg[1] = 'C';
    msg[2] = 'P';
    msg[3] = 'K';
    msg[4] = resource; /* a key unlocks the resource its seed was for, no other */
    memcpy(&msg[5], seed, VH_XCP_SEED_LEN);
    vh_cmac(k, msg, sizeof msg, tag);
    memcpy(key, tag, VH_XCP_KEY_LEN);
}

/* A seed nobody can predict without K, different on every request and, with the host's salt, on
 * every start: CMAC(K, "XCPS" | salt | seeds issued | tick). */
static void make_seed(vh_xcp_t *x)
{
    uint8_t msg[4u + VH_XCP_SALT_LEN + 8u], tag[VH_AES_BLOCK];
    msg[0] = 'X';
    msg[1] = 'C';
    msg[2] = 'P';
    msg[3] = 'S';
    memcpy(&msg[4], x->cfg.salt, VH_XCP_SALT_LEN);
    wr32(&msg[4u + VH_XCP_SALT_LEN], ++x->seeds, false);
    wr32(&msg[8u + VH_XCP_SALT_LEN], x->tick, false);
    vh_cmac(x->cfg.key, msg, sizeof msg, tag);
    memcpy(x->seed, tag, VH_XCP_SEED_LEN);
}

/* Seed & key refused now: locked out after unlock_attempts wrong keys (until reset), or inside the
 * delay after a wrong key. The answer is sent and counted here. */
static bool unlock_refused(vh_xcp_t *x)
{
    if (x->locked_out) {
        x->n.unlock_lockout++;
        res_err(x, ERR_ACCESS_DENIED);
        return true;
    }
    if (x->fail_streak > 0u && (int32_t)(x->penalty_until - x->tick) > 0) {
        x->n.unlock_delayed++;
        res_err(x, ERR_RESOURCE_TEMPORARY_NOT_ACCESSIBLE);
        return true;
    }
    return false;
}

/* ---- commands ---------------------------------------------------------------------------- */

static bool be(const vh_xcp_t *x)
{
    return x->cfg.big_endian != 0u;
}

static void cmd_connect(vh_xcp_t *x)
{
    uint8_t *r = res_begin(x, 8u);
    if (!x->connected) {
        x->connected = true;
        x->locked = x->cfg.protect;
    }
    r[1] = (uint8_t)((x->cfg.cal_size > 0u ? VH_XCP_RES_CALPAG : 0u) | VH_XCP_RES_DAQ); /* RESOURCE */
    /* COMM_MODE_BASIC: byte order, byte granularity, no slave block mode, OPTIONAL (GET_COMM_MODE_INFO) */
    r[2] = (uint8_t)((x->cfg.big_endian ? 0x01u : 0x00u) | 0x80u);
    r[3] = x->cfg.max_cto;
    wr16(&r[4], x->cfg.max_dto, be(x));
    r[6] = 0x01u; /* protocol layer version 1 */
    r[7] = 0x01u; /* CAN transport layer version 1 */
}

static void cmd_get_status(vh_xcp_t *x)
{
    unsigned i;
    uint8_t running = 0u;
    uint8_t *r = res_begin(x, 6u);
    for (i = 0; i < x->n_daq; ++i) {
        running |= (uint8_t)(x->daq[i].mode & MODE_RUNNING);
    }
    r[1] = running ? 0x40u : 0x00u; /* SESSION_STATUS: DAQ_RUNNING */
    r[2] = x->locked;               /* RESOURCE_PROTECTION_STATUS */
    r[3] = 0u;
    wr16(&r[4], 0u, be(x));         /* SESSION_CONFIGURATION_ID */
}

static void cmd_get_comm_mode_info(vh_xcp_t *x)
{
    uint8_t *r = res_begin(x, 8u);
    r[2] = 0x00u; /* COMM_MODE_OPTIONAL: no master block mode, no interleaved mode */
    r[4] = 0u;    /* MAX_BS */
    r[5] = 0u;    /* MIN_ST */
    r[6] = 0u;    /* QUEUE_SIZE */
    r[7] = 0x10u; /* driver version 1.0 */
}

static void cmd_get_id(vh_xcp_t *x, uint8_t type)
{
    const char *s = (type == 0u) ? x->cfg.id_ascii : (type == 1u) ? x->cfg.id_a2l : NULL;
    size_t n = (s != NULL) ? strlen(s) : 0u;
    uint8_t *r;
    if (n > VH_XCP_ID_MAX) {
        n = VH_XCP_ID_MAX;
    }
    r = res_begin(x, 8u);
    r[1] = 0u; /* MODE: identification is uploaded from the MTA */
    wr32(&r[4], (uint32_t)n, be(x));
    x->mta_is_id = 1u;
    x->mta_id = s;
    x->mta = 0u;
}

static void cmd_get_seed(vh_xcp_t *x, const uint8_t *c)
{
    uint8_t *r;
    uint8_t res = c[2];
    if (c[1] != 0u || (res != VH_XCP_RES_CALPAG && res != VH_XCP_RES_DAQ)) {
        res_err(x, ERR_OUT_OF_RANGE); /* one resource per request; the seed fits one frame */
        return;
    }
    if (!(x->locked & res)) {
        r = res_begin(x, 2u);
        r[1] = 0u; /* not protected: seed length 0 */
        x->seed_for = 0u;
        return;
    }
    if (unlock_refused(x)) {
        x->seed_for = 0u;
        return;
    }
    make_seed(x);
    x->seed_for = res;
    r = res_begin(x, (uint8_t)(2u + VH_XCP_SEED_LEN));
    r[1] = VH_XCP_SEED_LEN;
    memcpy(&r[2], x->seed, VH_XCP_SEED_LEN);
}

static void cmd_unlock(vh_xcp_t *x, const uint8_t *c, size_t len)
{
    uint8_t *r, want[VH_XCP_KEY_LEN], diff = 0u, res;
    unsigned i;
    if (unlock_refused(x)) {
        x->seed_for = 0u;
        return;
    }
    if (x->seed_for == 0u) {
        res_err(x, ERR_SEQUENCE);
        return;
    }
    vh_xcp_key(x->cfg.key, x->seed_for, x->seed, want);
    for (i = 0; i < VH_XCP_KEY_LEN; ++i) { /* every byte compared: no early exit on the first wrong one */
        diff |= (uint8_t)((len >= 2u + VH_XCP_KEY_LEN ? c[2u + i] : 0u) ^ want[i]);
    }
    res = x->seed_for;
    x->seed_for = 0u; /* one attempt per seed */
    if (len < 2u + VH_XCP_KEY_LEN || c[1] != VH_XCP_KEY_LEN || diff != 0u) {
        /* wrong key: ERR_ACCESS_LOCKED (Part 2, UNLOCK), counted, and a delay that doubles with
         * each wrong key in a row, then a lockout. The session stays: on CAN any node can send a
         * CRO, and a node that guesses must not end the master's session (where the standard has
         * the slave disconnect). */
        x->n.key_fail++;
        if (x->fail_streak < 0xFFu) {
            x->fail_streak++;
        }
        if (x->cfg.unlock_attempts != 0u && x->fail_streak >= x->cfg.unlock_attempts) {
            x->locked_out = 1u;
        } else if (x->cfg.unlock_delay_ticks != 0u) {
            uint32_t d = x->cfg.unlock_delay_ticks;
            for (i = 1u; i < x->fail_streak && d < 0x40000000u; ++i) {
                d *= 2u;
            }
            x->penalty_until = x->tick + d;
        }
        res_err(x, ERR_ACCESS_LOCKED);
        return;
    }
    x->fail_streak = 0u;
    x->locked = (uint8_t)(x->locked & ~res);
    r = res_begin(x, 2u);
    r[1] = x->locked;
}

static void set_mta(vh_xcp_t *x, uint32_t a)
{
    x->mta = a;
    x->mta_is_id = 0u;
}

/* UPLOAD from the MTA: n bytes into r[1..n]. */
static bool upload(vh_xcp_t *x, uint8_t n)
{
    if (n == 0u || n > x->cfg.max_cto - 1u) {
        res_err(x, ERR_OUT_OF_RANGE); /* no slave block mode: one frame per UPLOAD */
        return false;
    }
    if (x->mta_is_id) {
        size_t len = (x->mta_id != NULL) ? strlen(x->mta_id) : 0u;
        uint8_t *r;
        if (len > VH_XCP_ID_MAX) {
            len = VH_XCP_ID_MAX;
        }
        if (!inside(x->mta, n, 0u, (uint32_t)len)) {
            res_err(x, ERR_ACCESS_DENIED);
            return false;
        }
        r = res_begin(x, (uint8_t)(1u + n));
        memcpy(&r[1], x->mta_id + x->mta, n);
    } else {
        const uint8_t *m = resolve(x, x->mta, n, VH_XCP_ACC_READ);
        uint8_t *r;
        if (m == NULL) {
            res_err(x, ERR_ACCESS_DENIED);
            return false;
        }
        r = res_begin(x, (uint8_t)(1u + n));
        memmove(&r[1], m, n); /* memmove: a region may map the slave itself (its counters) */
    }
    x->mta += n;
    return true;
}

/* DOWNLOAD of n bytes at the MTA into the working page: only inside characteristics, every
 * element completed by this write within its limits, else nothing is written. */
static void download(vh_xcp_t *x, const uint8_t *data, uint8_t n)
{
    uint32_t a = x->mta, end, covered = 0u, off;
    uint8_t undo[VH_XCP_FRAME_MAX];
    unsigned i;
    if (x->locked & VH_XCP_RES_CALPAG) {
        res_err(x, ERR_ACCESS_LOCKED);
        return;
    }
    if (n == 0u) {
        res_ok(x);
        return;
    }
    if (x->mta_is_id || x->cfg.cal_size == 0u || !inside(a, n, x->cfg.cal_address, x->cfg.cal_size)) {
        res_err(x, ERR_ACCESS_DENIED);
        return;
    }
    if (x->page_xcp == PAGE_REF) {
        res_err(x, ERR_WRITE_PROTECTED);
        return;
    }
    end = a + n;
    for (i = 0; i < x->cfg.n_chars; ++i) {
        const vh_xcp_char_t *c = &x->cfg.chars[i];
        uint32_t lo = (c->address > a) ? c->address : a;
        uint32_t hi = (c->address + char_size(c) < end) ? c->address + char_size(c) : end;
        if (lo < hi) {
            covered += hi - lo;
        }
    }
    if (covered != n) {
        res_err(x, ERR_ACCESS_DENIED); /* a byte between characteristics: not calibration data */
        return;
    }
    if (!safe_now(x)) {
        for (i = 0; i < x->cfg.n_chars; ++i) {
            const vh_xcp_char_t *c = &x->cfg.chars[i];
            if ((c->flags & VH_XCP_CHAR_SAFETY) && c->address < end && a < c->address + char_size(c)) {
                /* safety-relevant, outside the safe state: write protected now (nothing written) */
                x->n.cal_unsafe++;
                res_err(x, ERR_WRITE_PROTECTED);
                return;
            }
        }
    }
    off = a - x->cfg.cal_address;
    memcpy(undo, x->cfg.cal_work + off, n);
    memcpy(x->cfg.cal_work + off, data, n);
    for (i = 0; i < x->cfg.n_chars; ++i) {
        const vh_xcp_char_t *c = &x->cfg.chars[i];
        uint8_t es = type_size(c->type);
        uint32_t e;
        if (c->address >= end || c->address + char_size(c) <= a) {
            continue;
        }
        for (e = 0; e < c->count; ++e) {
            uint32_t last = c->address + e * es + es - 1u; /* an element is checked when complete */
            double v;
            if (last < a || last >= end) {
                continue;
            }
            v = element(x->cfg.cal_work + (c->address - x->cfg.cal_address) + e * es, c->type);
            if (!in_limits(c, v)) {
                const uint32_t eo = (c->address - x->cfg.cal_address) + e * es;
                memcpy(x->cfg.cal_work + off, undo, n);
                /* and the element's bytes of earlier DOWNLOADs (a double over classic CAN takes
                 * two): no part of a refused value stays, the element is the ECU's again */
                memcpy(x->cfg.cal_work + eo, x->cfg.cal_ecu + eo, es);
                res_err(x, ERR_OUT_OF_RANGE);
                return;
            }
        }
    }
    for (i = 0; i < x->cfg.n_chars; ++i) {
        const vh_xcp_char_t *c = &x->cfg.chars[i];
        uint32_t cend = c->address + char_size(c);
        if (c->address >= end || cend <= a) {
            continue;
        }
        x->char_state[i] = (uint8_t)(CHAR_PENDING | ((end < cend) ? CHAR_OPEN : 0u));
        x->char_tick[i] = x->tick;
    }
    x->mta = end;
    x->n.cal_writes++;
    res_ok(x);
}

static void cmd_set_cal_page(vh_xcp_t *x, const uint8_t *c)
{
    uint8_t mode = c[1], seg = c[2], page = c[3];
    if (x->locked & VH_XCP_RES_CALPAG) {
        res_err(x, ERR_ACCESS_LOCKED);
        return;
    }
    if (x->cfg.cal_size == 0u || (seg != 0u && !(mode & 0x80u))) {
        res_err(x, ERR_SEGMENT_NOT_VALID);
        return;
    }
    if (page > PAGE_REF) {
        res_err(x, ERR_PAGE_NOT_VALID);
        return;
    }
    if (!(mode & 0x03u)) {
        res_err(x, ERR_MODE_NOT_VALID);
        return;
    }
    if ((mode & 0x01u) && page != x->page_ecu_next && !safe_now(x) && any_safety_char(x)) {
        x->n.cal_unsafe++; /* the ECU's page holds safety-relevant characteristics */
        res_err(x, ERR_WRITE_PROTECTED);
        return;
    }
    if (mode & 0x01u) {
        x->page_ecu_next = page; /* the ECU switches at the next tick boundary */
    }
    if (mode & 0x02u) {
        x->page_xcp = page;
    }
    res_ok(x);
}

static void cmd_get_cal_page(vh_xcp_t *x, const uint8_t *c)
{
    uint8_t *r;
    if (x->cfg.cal_size == 0u || c[2] != 0u) {
        res_err(x, ERR_SEGMENT_NOT_VALID);
        return;
    }
    if (c[1] != 0x01u && c[1] != 0x02u) {
        res_err(x, ERR_MODE_NOT_VALID);
        return;
    }
    r = res_begin(x, 4u);
    r[3] = (c[1] == 0x01u) ? x->page_ecu_next : x->page_xcp;
}

static void cmd_get_pag_processor_info(vh_xcp_t *x)
{
    uint8_t *r = res_begin(x, 3u);
    r[1] = (x->cfg.cal_size > 0u) ? 1u : 0u; /* MAX_SEGMENT */
    r[2] = 0u;                               /* PAG_PROPERTIES: no FREEZE */
}

/* ---- DAQ ------------------------------------------------------------------------------------ */

static bool daq_running(const vh_xcp_t *x)
{
    unsigned i;
    for (i = 0; i < x->n_daq; ++i) {
        if (x->daq[i].mode & MODE_RUNNING) {
            return true;
        }
    }
    return false;
}

static void cmd_get_daq_processor_info(vh_xcp_t *x)
{
    uint8_t *r = res_begin(x, 8u);
    /* DAQ_PROPERTIES: dynamic config, prescaler, timestamps */
    r[1] = (uint8_t)(0x01u | 0x02u | 0x10u);
    wr16(&r[2], VH_XCP_MAX_DAQ, be(x));   /* MAX_DAQ */
    wr16(&r[4], x->cfg.n_events, be(x));  /* MAX_EVENT_CHANNEL */
    r[6] = 0u;                            /* MIN_DAQ: no predefined lists */
    r[7] = 0x00u; /* DAQ_KEY_BYTE: absolute ODT number, same address extension, default optimisation */
}

static void cmd_get_daq_resolution_info(vh_xcp_t *x)
{
    uint8_t *r = res_begin(x, 8u);
    r[1] = 1u;                           /* GRANULARITY_ODT_ENTRY_SIZE_DAQ */
    r[2] = (uint8_t)(x->cfg.max_dto - 1u); /* MAX_ODT_ENTRY_SIZE_DAQ */
    r[3] = 1u;
    r[4] = 0u;                           /* no STIM */
    r[5] = (uint8_t)(TS_SIZE | (3u << 4)); /* TIMESTAMP_MODE: 4 bytes, not fixed, unit 1 us */
    wr16(&r[6], (uint16_t)x->cfg.tick_us, be(x)); /* TIMESTAMP_TICKS: one per ECU tick */
}

static void cmd_get_daq_event_info(vh_xcp_t *x, uint16_t ev)
{
    const char *name;
    size_t n;
    uint8_t *r;
    if (ev >= x->cfg.n_events) {
        res_err(x, ERR_OUT_OF_RANGE);
        return;
    }
    name = x->cfg.events[ev].name;
    n = (name != NULL) ? strlen(name) : 0u;
    if (n > VH_XCP_ID_MAX) {
        n = VH_XCP_ID_MAX;
    }
    r = res_begin(x, 7u);
    /* DAQ_EVENT_PROPERTIES: DAQ; CONSISTENCY = EVENT (every list of the event is sampled in one
     * call, with no ECU code running in between) */
    r[1] = 0x84u;
    r[2] = 0xFFu;  /* MAX_DAQ_LIST: any number */
    r[3] = (uint8_t)n;
    r[4] = x->cfg.events[ev].cycle;
    r[5] = x->cfg.events[ev].unit;
    r[6] = 0u;
    x->mta_is_id = 1u; /* the name is uploaded from the MTA */
    x->mta_id = name;
    x->mta = 0u;
}

static void cmd_get_daq_clock(vh_xcp_t *x)
{
    uint8_t *r = res_begin(x, 8u);
    wr32(&r[4], x->tick, be(x));
}

static void cmd_free_daq(vh_xcp_t *x)
{
    daq_free(x);
    x->daq_state = DAQ_FREED;
    res_ok(x);
}

static void cmd_alloc_daq(vh_xcp_t *x, uint16_t count)
{
    if (x->daq_state != DAQ_FREED) {
        res_err(x, ERR_SEQUENCE);
        return;
    }
    if (count > VH_XCP_MAX_DAQ) {
        res_err(x, ERR_MEMORY_OVERFLOW);
        return;
    }
    x->n_daq = count;
    x->daq_state = DAQ_LISTS;
    res_ok(x);
}

static void cmd_alloc_odt(vh_xcp_t *x, uint16_t list, uint8_t count)
{
    vh_xcp_daq_t *d;
    if (x->daq_state != DAQ_LISTS && x->daq_state != DAQ_ODTS) {
        res_err(x, ERR_SEQUENCE);
        return;
    }
    if (list >= x->n_daq) {
        res_err(x, ERR_OUT_OF_RANGE);
        return;
    }
    if (x->daq[list].odt_count != 0u) {
        res_err(x, ERR_SEQUENCE); /* one ALLOC_ODT per list */
        return;
    }
    if (count == 0u || (uint32_t)x->n_odt + count > VH_XCP_MAX_ODT) {
        res_err(x, ERR_MEMORY_OVERFLOW);
        return;
    }
    d = &x->daq[list];
    d->first_odt = x->n_odt;
    d->odt_count = count;
    x->n_odt = (uint16_t)(x->n_odt + count);
    x->daq_state = DAQ_ODTS;
    res_ok(x);
}

static void cmd_alloc_odt_entry(vh_xcp_t *x, uint16_t list, uint8_t odt, uint8_t count)
{
    vh_xcp_odt_t *o;
    if (x->daq_state != DAQ_ODTS && x->daq_state != DAQ_ENTRIES) {
        res_err(x, ERR_SEQUENCE);
        return;
    }
    if (list >= x->n_daq || odt >= x->daq[list].odt_count) {
        res_err(x, ERR_OUT_OF_RANGE);
        return;
    }
    o = &x->odt[x->daq[list].first_odt + odt];
    if (o->allocated) {
        res_err(x, ERR_SEQUENCE); /* one ALLOC_ODT_ENTRY per ODT */
        return;
    }
    /* zero entries is legal: on classic CAN a first ODT may have room for its timestamp only */
    if ((uint32_t)x->n_entries + count > VH_XCP_MAX_ENTRIES) {
        res_err(x, ERR_MEMORY_OVERFLOW);
        return;
    }
    o->first_entry = x->n_entries;
    o->entry_count = count;
    o->allocated = 1u;
    x->n_entries = (uint16_t)(x->n_entries + count);
    x->daq_state = DAQ_ENTRIES;
    res_ok(x);
}

static void cmd_set_daq_ptr(vh_xcp_t *x, uint16_t list, uint8_t odt, uint8_t entry)
{
    if (list >= x->n_daq || odt >= x->daq[list].odt_count ||
        entry >= x->odt[x->daq[list].first_odt + odt].entry_count) {
        x->ptr_valid = 0u;
        res_err(x, ERR_OUT_OF_RANGE);
        return;
    }
    if (x->daq[list].mode & MODE_RUNNING) {
        res_err(x, ERR_DAQ_ACTIVE);
        return;
    }
    x->ptr_daq = list;
    x->ptr_odt = odt;
    x->ptr_entry = entry;
    x->ptr_valid = 1u;
    res_ok(x);
}

static unsigned odt_bytes(const vh_xcp_t *x, const vh_xcp_odt_t *o)
{
    unsigned i, sum = 0u;
    for (i = 0; i < o->entry_count; ++i) {
        sum += x->entry[o->first_entry + i].size;
    }
    return sum;
}

static void cmd_write_daq(vh_xcp_t *x, const uint8_t *c)
{
    uint8_t bit = c[1], size = c[2];
    uint32_t a = rd32(&c[4], be(x));
    const vh_xcp_odt_t *o;
    vh_xcp_entry_t *e;
    const uint8_t *m;
    if (!x->ptr_valid) {
        res_err(x, ERR_SEQUENCE);
        return;
    }
    if (x->daq[x->ptr_daq].mode & MODE_RUNNING) {
        /* the cursor was set before the list started: its ODTs are fixed while it runs (a
         * timestamped list's ODT 0 would otherwise outgrow the DTO: found by the fuzzer) */
        res_err(x, ERR_DAQ_ACTIVE);
        return;
    }
    o = &x->odt[x->daq[x->ptr_daq].first_odt + x->ptr_odt];
    if (x->ptr_entry >= o->entry_count) {
        res_err(x, ERR_OUT_OF_RANGE); /* the cursor ran past the ODT */
        return;
    }
    if (bit != 0xFFu || size == 0u || size > x->cfg.max_dto - 1u) {
        res_err(x, ERR_OUT_OF_RANGE); /* no bit-wise entries */
        return;
    }
    m = resolve(x, a, size, VH_XCP_ACC_DAQ);
    if (m == NULL) {
        res_err(x, ERR_ACCESS_DENIED);
        return;
    }
    e = &x->entry[o->first_entry + x->ptr_entry];
    if (odt_bytes(x, o) - e->size + size > x->cfg.max_dto - 1u) {
        res_err(x, ERR_DAQ_CONFIG); /* the ODT would not fit one DTO */
        return;
    }
    e->mem = m;
    e->size = size;
    x->ptr_entry++;
    res_ok(x);
}

static void cmd_set_daq_list_mode(vh_xcp_t *x, const uint8_t *c)
{
    uint8_t mode = c[1];
    uint16_t list = rd16(&c[2], be(x)), ev = rd16(&c[4], be(x));
    vh_xcp_daq_t *d;
    if (list >= x->n_daq || ev >= x->cfg.n_events) {
        res_err(x, ERR_OUT_OF_RANGE);
        return;
    }
    if (mode & (MODE_STIM | MODE_PID_OFF)) {
        res_err(x, ERR_MODE_NOT_VALID);
        return;
    }
    d = &x->daq[list];
    if (d->mode & MODE_RUNNING) {
        res_err(x, ERR_DAQ_ACTIVE);
        return;
    }
    d->mode = (uint8_t)((d->mode & MODE_SELECTED) | (mode & MODE_TIMESTAMP));
    d->event = ev;
    d->prescaler = (c[6] == 0u) ? 1u : c[6];
    d->prescale_count = 0u;
    d->priority = c[7];
    res_ok(x);
}

static void cmd_get_daq_list_mode(vh_xcp_t *x, uint16_t list)
{
    uint8_t *r;
    if (list >= x->n_daq) {
        res_err(x, ERR_OUT_OF_RANGE);
        return;
    }
    r = res_begin(x, 8u);
    r[1] = x->daq[list].mode;
    wr16(&r[4], x->daq[list].event, be(x));
    r[6] = x->daq[list].prescaler;
    r[7] = x->daq[list].priority;
}

/* A list can run when every ODT has its entries allocated and written, and fits a DTO. */
static bool daq_list_valid(const vh_xcp_t *x, const vh_xcp_daq_t *d)
{
    unsigned j, k;
    for (j = 0; j < d->odt_count; ++j) {
        const vh_xcp_odt_t *o = &x->odt[d->first_odt + j];
        unsigned cap = x->cfg.max_dto - 1u - ((j == 0u && (d->mode & MODE_TIMESTAMP)) ? TS_SIZE : 0u);
        if (!o->allocated) {
            return false;
        }
        for (k = 0; k < o->entry_count; ++k) {
            if (x->entry[o->first_entry + k].size == 0u) {
                return false;
            }
        }
        if (odt_bytes(x, o) > cap) {
            return false;
        }
    }
    return d->odt_count > 0u;
}

static void cmd_start_stop_daq_list(vh_xcp_t *x, uint8_t mode, uint16_t list)
{
    vh_xcp_daq_t *d;
    uint8_t *r;
    if (list >= x->n_daq) {
        res_err(x, ERR_OUT_OF_RANGE);
        return;
    }
    if (mode > 2u) {
        res_err(x, ERR_MODE_NOT_VALID);
        return;
    }
    d = &x->daq[list];
    if (mode != 0u && !daq_list_valid(x, d)) {
        res_err(x, ERR_DAQ_CONFIG);
        return;
    }
    if (mode == 0u) {
        d->mode = (uint8_t)(d->mode & ~MODE_RUNNING);
    } else if (mode == 1u) {
        d->mode |= MODE_RUNNING;
        d->prescale_count = 0u;
    } else {
        d->mode |= MODE_SELECTED;
    }
    r = res_begin(x, 2u);
    r[1] = (uint8_t)d->first_odt; /* FIRST_PID: absolute ODT numbers */
}

static void cmd_start_stop_synch(vh_xcp_t *x, uint8_t mode)
{
    unsigned i;
    if (mode > 2u) {
        res_err(x, ERR_MODE_NOT_VALID);
        return;
    }
    for (i = 0; mode == 1u && i < x->n_daq; ++i) {
        /* a selected list may have changed since it was selected (WRITE_DAQ, SET_DAQ_LIST_MODE's
         * timestamp): one that no longer fits a DTO starts none (found by the fuzzer) */
        if ((x->daq[i].mode & MODE_SELECTED) && !daq_list_valid(x, &x->daq[i])) {
            res_err(x, ERR_DAQ_CONFIG);
            return;
        }
    }
    for (i = 0; i < x->n_daq; ++i) {
        vh_xcp_daq_t *d = &x->daq[i];
        if (mode == 0u) {
            d->mode = (uint8_t)(d->mode & ~(MODE_RUNNING | MODE_SELECTED));
        } else if (d->mode & MODE_SELECTED) {
            d->mode = (uint8_t)(d->mode & ~MODE_SELECTED);
            if (mode == 1u) {
                d->mode |= MODE_RUNNING;
                d->prescale_count = 0u;
            } else {
                d->mode = (uint8_t)(d->mode & ~MODE_RUNNING);
            }
        }
    }
    res_ok(x);
}

static void cmd_clear_daq_list(vh_xcp_t *x, uint16_t list)
{
    unsigned j, k;
    vh_xcp_daq_t *d;
    if (list >= x->n_daq) {
        res_err(x, ERR_OUT_OF_RANGE);
        return;
    }
    d = &x->daq[list];
    d->mode = 0u;
    for (j = 0; j < d->odt_count; ++j) {
        const vh_xcp_odt_t *o = &x->odt[d->first_odt + j];
        for (k = 0; k < o->entry_count; ++k) {
            x->entry[o->first_entry + k].size = 0u;
            x->entry[o->first_entry + k].mem = NULL;
        }
    }
    res_ok(x);
}

void vh_xcp_event(vh_xcp_t *x, uint16_t channel)
{
    unsigned i, j, k;
    if (!x->connected) {
        return;
    }
    for (i = 0; i < x->n_daq; ++i) {
        vh_xcp_daq_t *d = &x->daq[i];
        if (!(d->mode & MODE_RUNNING) || d->event != channel) {
            continue;
        }
        if (++d->prescale_count < d->prescaler) {
            continue;
        }
        d->prescale_count = 0u;
        if ((unsigned)x->txq_count + d->odt_count > VH_XCP_TXQ) {
            x->n.dto_overrun++; /* a whole sample or nothing: never a list with ODTs missing */
            continue;
        }
        for (j = 0; j < d->odt_count; ++j) {
            const vh_xcp_odt_t *o = &x->odt[d->first_odt + j];
            vh_xcp_frame_t *f = &x->txq[(x->txq_head + x->txq_count) % VH_XCP_TXQ];
            uint8_t pos = 1u;
            frame_init(x, f);
            f->data[0] = (uint8_t)(d->first_odt + j); /* PID: absolute ODT number */
            if (j == 0u && (d->mode & MODE_TIMESTAMP)) {
                wr32(&f->data[1], x->tick, be(x));
                pos = (uint8_t)(pos + TS_SIZE);
            }
            for (k = 0; k < o->entry_count; ++k) {
                const vh_xcp_entry_t *e = &x->entry[o->first_entry + k];
                /* fits: checked when the list started; memmove: an entry may sample the slave's
                 * own memory, this very DTO included (the fuzzer's overlap) */
                memmove(&f->data[pos], e->mem, e->size);
                pos = (uint8_t)(pos + e->size);
            }
            f->len = frame_len(x, pos);
            x->txq_count++;
            x->n.dto++;
        }
    }
}

int vh_xcp_tx_pop(vh_xcp_t *x, vh_xcp_frame_t *out)
{
    if (x->res_pending) {
        *out = x->res;
        x->res_pending = 0u;
        return 1;
    }
    if (x->txq_count == 0u) {
        return 0;
    }
    *out = x->txq[x->txq_head];
    x->txq_head = (uint16_t)((x->txq_head + 1u) % VH_XCP_TXQ);
    x->txq_count--;
    return 1;
}

/* Minimum CRO length per command (PID included); 0: unknown command. */
static uint8_t cro_min_len(uint8_t pid)
{
    switch (pid) {
    case 0xFFu: return 2u; /* CONNECT */
    case 0xFEu: return 1u; /* DISCONNECT */
    case 0xFDu: return 1u; /* GET_STATUS */
    case 0xFCu: return 1u; /* SYNCH */
    case 0xFBu: return 1u; /* GET_COMM_MODE_INFO */
    case 0xFAu: return 2u; /* GET_ID */
    case 0xF8u: return 3u; /* GET_SEED */
    case 0xF7u: return 2u; /* UNLOCK */
    case 0xF6u: return 8u; /* SET_MTA */
    case 0xF5u: return 2u; /* UPLOAD */
    case 0xF4u: return 8u; /* SHORT_UPLOAD */
    case 0xF0u: return 2u; /* DOWNLOAD (+ data, checked below) */
    case 0xEDu: return 8u; /* SHORT_DOWNLOAD (+ data) */
    case 0xEBu: return 4u; /* SET_CAL_PAGE */
    case 0xEAu: return 3u; /* GET_CAL_PAGE */
    case 0xE9u: return 1u; /* GET_PAG_PROCESSOR_INFO */
    case 0xE3u: return 4u; /* CLEAR_DAQ_LIST */
    case 0xE2u: return 6u; /* SET_DAQ_PTR */
    case 0xE1u: return 8u; /* WRITE_DAQ */
    case 0xE0u: return 8u; /* SET_DAQ_LIST_MODE */
    case 0xDFu: return 4u; /* GET_DAQ_LIST_MODE */
    case 0xDEu: return 4u; /* START_STOP_DAQ_LIST */
    case 0xDDu: return 2u; /* START_STOP_SYNCH */
    case 0xDCu: return 1u; /* GET_DAQ_CLOCK */
    case 0xDAu: return 1u; /* GET_DAQ_PROCESSOR_INFO */
    case 0xD9u: return 1u; /* GET_DAQ_RESOLUTION_INFO */
    case 0xD7u: return 4u; /* GET_DAQ_EVENT_INFO */
    case 0xD6u: return 1u; /* FREE_DAQ */
    case 0xD5u: return 4u; /* ALLOC_DAQ */
    case 0xD4u: return 5u; /* ALLOC_ODT */
    case 0xD3u: return 6u; /* ALLOC_ODT_ENTRY */
    default: return 0u;
    }
}

static bool daq_cmd_locked(vh_xcp_t *x, uint8_t pid)
{
    /* DAQ configuration and start/stop need the DAQ resource; the info commands do not */
    bool cfg = (pid >= 0xD3u && pid <= 0xD6u) || (pid >= 0xDDu && pid <= 0xE3u && pid != 0xDFu);
    if (cfg && (x->locked & VH_XCP_RES_DAQ)) {
        res_err(x, ERR_ACCESS_LOCKED);
        return true;
    }
    return false;
}

void vh_xcp_rx(vh_xcp_t *x, const uint8_t *c, size_t len, uint32_t tick)
{
    uint8_t pid, need;
    bool b = be(x);
    x->tick = tick;
    x->n.cro++;
    if (len > x->cfg.max_cto) {
        len = x->cfg.max_cto; /* bytes past MAX_CTO are padding */
    }
    if (len == 0u || c == NULL) {
        if (x->connected) {
            res_err(x, ERR_CMD_SYNTAX);
        } else {
            x->n.ignored++;
        }
        return;
    }
    pid = c[0];
    if (!x->connected && pid != 0xFFu) {
        x->n.ignored++; /* a slave that is not connected answers only CONNECT */
        return;
    }
    need = cro_min_len(pid);
    if (need == 0u) {
        res_err(x, ERR_CMD_UNKNOWN);
        return;
    }
    if (len < need) {
        res_err(x, ERR_CMD_SYNTAX);
        return;
    }
    if (daq_cmd_locked(x, pid)) {
        return;
    }
    switch (pid) {
    case 0xFFu: /* CONNECT */
        cmd_connect(x);
        break;
    case 0xFEu: /* DISCONNECT */
        disconnect(x);
        res_ok(x);
        break;
    case 0xFDu: /* GET_STATUS */
        cmd_get_status(x);
        break;
    case 0xFCu: /* SYNCH: its answer is an ERR_CMD_SYNCH by definition (not counted as an error) */
        {
            uint8_t *r = res_begin(x, 2u);
            r[0] = PID_ERR;
            r[1] = ERR_CMD_SYNCH;
        }
        break;
    case 0xFBu: /* GET_COMM_MODE_INFO */
        cmd_get_comm_mode_info(x);
        break;
    case 0xFAu: /* GET_ID */
        cmd_get_id(x, c[1]);
        break;
    case 0xF8u: /* GET_SEED */
        cmd_get_seed(x, c);
        break;
    case 0xF7u: /* UNLOCK */
        cmd_unlock(x, c, len);
        break;
    case 0xF6u: /* SET_MTA: address extension c[3] is 0 (one address space) */
        if (c[3] != 0u) {
            res_err(x, ERR_OUT_OF_RANGE);
            break;
        }
        set_mta(x, rd32(&c[4], b));
        res_ok(x);
        break;
    case 0xF5u: /* UPLOAD */
        (void)upload(x, c[1]);
        break;
    case 0xF4u: /* SHORT_UPLOAD */
        if (c[3] != 0u) {
            res_err(x, ERR_OUT_OF_RANGE);
            break;
        }
        set_mta(x, rd32(&c[4], b));
        (void)upload(x, c[1]);
        break;
    case 0xF0u: /* DOWNLOAD */
        if (c[1] > x->cfg.max_cto - 2u) {
            res_err(x, ERR_OUT_OF_RANGE);
        } else if (len < 2u + (size_t)c[1]) {
            res_err(x, ERR_CMD_SYNTAX);
        } else {
            download(x, &c[2], c[1]);
        }
        break;
    case 0xEDu: /* SHORT_DOWNLOAD */
        if (c[1] > x->cfg.max_cto - 8u || c[3] != 0u) {
            res_err(x, ERR_OUT_OF_RANGE);
        } else if (len < 8u + (size_t)c[1]) {
            res_err(x, ERR_CMD_SYNTAX);
        } else {
            uint32_t keep = x->mta;
            uint8_t keep_id = x->mta_is_id;
            set_mta(x, rd32(&c[4], b));
            download(x, &c[8], c[1]);
            if (x->res.data[0] == PID_ERR) {
                x->mta = keep;
                x->mta_is_id = keep_id;
            }
        }
        break;
    case 0xEBu: /* SET_CAL_PAGE */
        cmd_set_cal_page(x, c);
        break;
    case 0xEAu: /* GET_CAL_PAGE */
        cmd_get_cal_page(x, c);
        break;
    case 0xE9u: /* GET_PAG_PROCESSOR_INFO */
        cmd_get_pag_processor_info(x);
        break;
    case 0xE3u: /* CLEAR_DAQ_LIST */
        cmd_clear_daq_list(x, rd16(&c[2], b));
        break;
    case 0xE2u: /* SET_DAQ_PTR */
        cmd_set_daq_ptr(x, rd16(&c[2], b), c[4], c[5]);
        break;
    case 0xE1u: /* WRITE_DAQ */
        cmd_write_daq(x, c);
        break;
    case 0xE0u: /* SET_DAQ_LIST_MODE */
        cmd_set_daq_list_mode(x, c);
        break;
    case 0xDFu: /* GET_DAQ_LIST_MODE */
        cmd_get_daq_list_mode(x, rd16(&c[2], b));
        break;
    case 0xDEu: /* START_STOP_DAQ_LIST */
        cmd_start_stop_daq_list(x, c[1], rd16(&c[2], b));
        break;
    case 0xDDu: /* START_STOP_SYNCH */
        cmd_start_stop_synch(x, c[1]);
        break;
    case 0xDCu: /* GET_DAQ_CLOCK */
        cmd_get_daq_clock(x);
        break;
    case 0xDAu: /* GET_DAQ_PROCESSOR_INFO */
        cmd_get_daq_processor_info(x);
        break;
    case 0xD9u: /* GET_DAQ_RESOLUTION_INFO */
        cmd_get_daq_resolution_info(x);
        break;
    case 0xD7u: /* GET_DAQ_EVENT_INFO */
        cmd_get_daq_event_info(x, rd16(&c[2], b));
        break;
    case 0xD6u: /* FREE_DAQ */
        if (daq_running(x)) {
            res_err(x, ERR_DAQ_ACTIVE);
        } else {
            cmd_free_daq(x);
        }
        break;
    case 0xD5u: /* ALLOC_DAQ */
        cmd_alloc_daq(x, rd16(&c[2], b));
        break;
    case 0xD4u: /* ALLOC_ODT */
        cmd_alloc_odt(x, rd16(&c[2], b), c[4]);
        break;
    case 0xD3u: /* ALLOC_ODT_ENTRY */
        cmd_alloc_odt_entry(x, rd16(&c[2], b), c[4], c[5]);
        break;
    default: /* unreachable: cro_min_len() knows the same set */
        res_err(x, ERR_CMD_UNKNOWN);
        break;
    }
}
