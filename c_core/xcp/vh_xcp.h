/* vh_xcp.h - XCP-on-CAN slave (ASAM MCD-1 XCP 1.x protocol layer, CAN transport layer).
 *
 * A caller-owned instance: no heap, no state in globals, no clock (the tick is an argument), so
 * the slave is deterministic and replayable like the rest of the firmware. Per tick the ECU:
 *   vh_xcp_tick(x, tick)       at the tick boundary: calibration writes become visible here
 *   vh_xcp_rx(x, cro, len, tick) for every frame on the CRO identifier
 *   vh_xcp_event(x, channel)   at each event channel that fires this tick (DAQ sampling)
 *   vh_xcp_tx_pop(x, &frame)   until it returns 0: the RES/ERR and DTO frames to send
 *
 * Memory: the master sees a 32-bit address space made only of the described regions (measurement
 * memory, read and/or DAQ) and one calibration segment of two pages of equal size:
 *   page 0  working page: RAM given by the caller (`work`), written by DOWNLOAD
 *   page 1  reference page: read-only (`ref`, flash-like), never written
 * The ECU's application reads a third buffer (`ecu`), which only vh_xcp_tick() writes: a
 * characteristic is copied whole from the page the ECU uses, so a filter never sees half a
 * matrix. Anything outside the described memory is refused (ERR_ACCESS_DENIED) and counted.
 *
 * Seed & key: GET_SEED returns VH_XCP_SEED_LEN bytes, the first bytes of CMAC-AES-128(K, "XCPS" |
 * salt | seeds issued | tick), and UNLOCK wants the first VH_XCP_KEY_LEN bytes of CMAC-AES-128(K,
 * "XCPK" | resource | seed) (vh_xcp_key). K is the integrator's key (a key file on the host, the HSM
 * on a target), held outside the slave and outside every described region. A wrong key is refused
 * and counted; the session stays (a node that guesses cannot end the master's session). After a
 * wrong key, GET_SEED and UNLOCK wait `unlock_delay_ticks`, doubled with every further wrong key
 * (ERR_RESOURCE_TEMPORARY_NOT_ACCESSIBLE in the window); `unlock_attempts` wrong keys in a row lock
 * seed & key until vh_xcp_reset (ERR_ACCESS_DENIED): a restart.
 *
 * Safety classes: a characteristic flagged VH_XCP_CHAR_SAFETY is written (DOWNLOAD) and committed
 * (tick) only while the caller's `*safe` is non-zero; otherwise ERR_WRITE_PROTECTED, counted in
 * cal_unsafe. The decision is the caller's (the ECU's safe state), read at every write and commit.
 *
 * Byte order: memory is moved as raw bytes; CONNECT reports the byte order given in the config
 * (the host's: little endian on x86 and Cortex-M).
 *
 * Only this header is read by cffi (c_core/xcp/xcp_build.py drops the preprocessor lines), so
 * it holds plain declarations and integer #defines.
 */
#ifndef VH_XCP_H
#define VH_XCP_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "vh_cmac.h"

/* Capacities: the instance is sized at compile time (no heap). */
#define VH_XCP_FRAME_MAX 64    /* CAN FD payload */
#define VH_XCP_MAX_REGIONS 96   /* the ECU's measurements, adjacent ones merged: 70 */
#define VH_XCP_MAX_CHARS 64    /* characteristics in the calibration segment */
#define VH_XCP_MAX_EVENTS 8
#define VH_XCP_MAX_DAQ 8       /* dynamic DAQ lists */
#define VH_XCP_MAX_ODT 64      /* ODTs over all lists; absolute ODT numbers stay below 0xFC */
#define VH_XCP_MAX_ENTRIES 256 /* ODT entries over all ODTs */
#define VH_XCP_TXQ 128         /* DTO frames queued between two vh_xcp_tx_pop drains */
#define VH_XCP_ID_MAX 48       /* GET_ID strings */
#define VH_XCP_SEED_LEN 6      /* GET_SEED and UNLOCK each fit one classic CAN frame */
#define VH_XCP_KEY_LEN 6
#define VH_XCP_SALT_LEN 8

/* Region access bits. */
#define VH_XCP_ACC_READ 1 /* UPLOAD / SHORT_UPLOAD */
#define VH_XCP_ACC_DAQ 2  /* WRITE_DAQ may sample it */

/* Characteristic flags. */
#define VH_XCP_CHAR_SAFETY 1 /* safety-relevant: written and committed only while *cfg.safe */

/* Resource bits (CONNECT RESOURCE, GET_STATUS protection, GET_SEED resource). */
#define VH_XCP_RES_CALPAG 1
#define VH_XCP_RES_DAQ 4

/* Element types of a characteristic (the A2L datatypes UBYTE .. FLOAT64_IEEE). */
typedef enum {
    VH_XCP_U8 = 0, VH_XCP_I8 = 1, VH_XCP_U16 = 2, VH_XCP_I16 = 3,
    VH_XCP_U32 = 4, VH_XCP_I32 = 5, VH_XCP_F32 = 6, VH_XCP_F64 = 7
} vh_xcp_type_t;

/* Return codes of the API (not XCP error codes). */
typedef enum { VH_XCP_OK = 0, VH_XCP_EINVAL = -1 } vh_xcp_status_t;

typedef struct {
    uint32_t address;   /* XCP address of the first byte */
    uint32_t size;
    uint8_t access;     /* VH_XCP_ACC_* */
    const uint8_t *mem; /* caller-owned memory the region maps to */
} vh_xcp_region_t;

/* A characteristic: `count` elements of `type` at `address` in the calibration segment; every
 * element written must satisfy min <= value <= max (raw values, limits from the description;
 * a NaN is out of range). */
typedef struct {
    uint32_t address;
    uint16_t count;
    uint8_t type; /* vh_xcp_type_t */
    uint8_t flags; /* VH_XCP_CHAR_* */
    double min;
    double max;
} vh_xcp_char_t;

typedef struct {
    const char *name; /* GET_DAQ_EVENT_INFO: uploaded from the MTA, like GET_ID */
    uint8_t cycle;    /* EVENT_CHANNEL_TIME_CYCLE ... */
    uint8_t unit;     /* ... in EVENT_CHANNEL_TIME_UNIT (3 = 1 us, 4 = 10 us, 5 = 100 us, 6 = 1 ms) */
} vh_xcp_event_t;

typedef struct {
    uint32_t cro_id;  /* master -> slave; bit 31 set = 29-bit identifier (XCP-on-CAN convention) */
    uint32_t dto_id;  /* slave -> master: RES, ERR and DTO */
    uint8_t max_cto;  /* 8 .. 64 */
    uint8_t max_dto;  /* 8 .. 64 */
    uint8_t fd;       /* 1: CAN FD frames (padded to the next FD length) */
    uint8_t pad8;     /* classic CAN: pad every frame to DLC 8 */
    uint8_t big_endian;
    uint8_t protect;  /* VH_XCP_RES_* that need GET_SEED/UNLOCK after CONNECT */
    const vh_cmac_key_t *key; /* seed & key (caller-owned, outside the described memory); NULL only
                               * when nothing is protected */
    uint8_t salt[VH_XCP_SALT_LEN]; /* the host's random bytes per start: seeds differ between starts */
    uint32_t unlock_delay_ticks;   /* after a wrong key; doubled with each further one (0: none) */
    uint8_t unlock_attempts;       /* wrong keys in a row that lock seed & key until reset (0: never) */
    const uint8_t *safe;           /* the caller's safe state (non-zero: safe); NULL: always safe */
    uint32_t tick_us; /* DAQ timestamp: one timestamp tick per ECU tick */
    uint32_t open_ticks; /* a characteristic written part-way commits after this many ticks
                          * without a write (0: only once its last byte is written) */
    const vh_xcp_region_t *regions; /* sorted or not; apart or adjacent */
    uint8_t n_regions;
    uint32_t cal_address; /* the calibration segment, same size on every page */
    uint32_t cal_size;
    const uint8_t *cal_ref; /* page 1, reference */
    uint8_t *cal_work;      /* page 0, working (what DOWNLOAD writes) */
    uint8_t *cal_ecu;       /* what the application reads; written only by vh_xcp_tick */
    const vh_xcp_char_t *chars;
    uint8_t n_chars;
    const vh_xcp_event_t *events;
    uint8_t n_events;
    const char *id_ascii; /* GET_ID type 0 */
    const char *id_a2l;   /* GET_ID type 1: the A2L file name without extension */
} vh_xcp_config_t;

typedef struct {
    uint32_t id;
    uint8_t len;
    uint8_t fd;
    uint8_t ext;
    uint8_t data[VH_XCP_FRAME_MAX];
} vh_xcp_frame_t;

/* Counters: every refused or malformed input lands in one of them. */
typedef struct {
    uint32_t cro;           /* CRO frames taken */
    uint32_t ignored;       /* frames while disconnected (not CONNECT): no answer, per ASAM */
    uint32_t err;           /* ERR packets sent, all causes */
    uint32_t err_unknown;   /* ERR_CMD_UNKNOWN */
    uint32_t err_syntax;    /* ERR_CMD_SYNTAX: short CRO, bad parameters */
    uint32_t err_access;    /* ERR_ACCESS_DENIED / ERR_WRITE_PROTECTED: outside described memory */
    uint32_t err_range;     /* ERR_OUT_OF_RANGE: a value outside its limits, bad sizes */
    uint32_t err_locked;    /* ERR_ACCESS_LOCKED: seed & key not done */
    uint32_t err_daq;       /* ERR_SEQUENCE / ERR_MEMORY_OVERFLOW / ERR_DAQ_CONFIG / ERR_DAQ_ACTIVE */
    uint32_t err_other;
    uint32_t key_fail;      /* wrong keys (refused; the session stays) */
    uint32_t unlock_delayed; /* GET_SEED/UNLOCK refused in the delay after a wrong key */
    uint32_t unlock_lockout; /* GET_SEED/UNLOCK refused after unlock_attempts wrong keys */
    uint32_t cal_unsafe;    /* safety-relevant writes, commits, page switches refused: not in the safe state */
    uint32_t cro_foreign;   /* CROs heard on a bus the slave does not serve (counted by the caller) */
    uint32_t cal_writes;    /* DOWNLOADs accepted */
    uint32_t cal_commits;   /* characteristics copied to the ECU page at a tick boundary */
    uint32_t cal_dropped;   /* written part-way, out of range when due (never reach the ECU) */
    uint32_t dto;           /* DTO frames queued */
    uint32_t dto_overrun;   /* samples dropped: TX queue full */
} vh_xcp_counters_t;

typedef struct {
    uint16_t first_odt;
    uint8_t odt_count;
    uint8_t mode;     /* GET_DAQ_LIST_MODE bits: 0x01 selected, 0x10 timestamp, 0x40 running */
    uint16_t event;
    uint8_t prescaler;
    uint8_t prescale_count;
    uint8_t priority;
} vh_xcp_daq_t;

typedef struct {
    uint16_t first_entry;
    uint8_t entry_count; /* 0 is allowed: an ODT that carries only the timestamp */
    uint8_t allocated;
} vh_xcp_odt_t;

typedef struct {
    const uint8_t *mem; /* resolved at WRITE_DAQ: sampling is a plain copy */
    uint8_t size;       /* 0: not written */
} vh_xcp_entry_t;

typedef struct {
    vh_xcp_config_t cfg;
    vh_xcp_counters_t n;
    bool connected;
    uint8_t locked;      /* VH_XCP_RES_* still locked */
    uint8_t seed_for;    /* resource the last GET_SEED was for (0: none) */
    uint8_t seed[VH_XCP_SEED_LEN];
    uint32_t seeds;      /* seeds issued since reset (the seed's counter) */
    uint8_t fail_streak; /* wrong keys in a row */
    uint8_t locked_out;  /* unlock_attempts reached: seed & key refused until reset */
    uint32_t penalty_until; /* tick before which GET_SEED/UNLOCK are refused */
    uint32_t tick;
    /* MTA: memory address, or a string (GET_ID, GET_DAQ_EVENT_INFO) */
    uint32_t mta;
    uint8_t mta_is_id;
    const char *mta_id;
    /* calibration pages: 0 working, 1 reference */
    uint8_t page_ecu;
    uint8_t page_xcp;
    uint8_t page_ecu_next;
    uint8_t char_state[VH_XCP_MAX_CHARS]; /* 0x01 written, not yet in `ecu`; 0x02 written part-way */
    uint32_t char_tick[VH_XCP_MAX_CHARS]; /* tick of the last write */
    /* dynamic DAQ */
    uint8_t daq_state;   /* allocation sequence: FREE_DAQ, ALLOC_DAQ, ALLOC_ODT, ALLOC_ODT_ENTRY */
    uint16_t n_daq;
    uint16_t n_odt;
    uint16_t n_entries;
    vh_xcp_daq_t daq[VH_XCP_MAX_DAQ];
    vh_xcp_odt_t odt[VH_XCP_MAX_ODT];
    vh_xcp_entry_t entry[VH_XCP_MAX_ENTRIES];
    uint16_t ptr_daq;    /* SET_DAQ_PTR / WRITE_DAQ cursor */
    uint8_t ptr_odt;
    uint8_t ptr_entry;
    uint8_t ptr_valid;
    /* TX: one response slot (a CRO gets one RES/ERR) and a DTO ring */
    vh_xcp_frame_t res;
    uint8_t res_pending;
    vh_xcp_frame_t txq[VH_XCP_TXQ];
    uint16_t txq_head;
    uint16_t txq_count;
} vh_xcp_t;

/* Validates the configuration (regions, characteristics inside the segment and apart, sizes);
 * copies the reference page into the working and the ECU pages. VH_XCP_EINVAL if invalid. */
int vh_xcp_init(vh_xcp_t *x, const vh_xcp_config_t *cfg);
/* Back to the state after init (disconnected, pages from the reference, DAQ freed). */
void vh_xcp_reset(vh_xcp_t *x);
/* Tick boundary: pending calibration writes and page switches reach the ECU page. */
void vh_xcp_tick(vh_xcp_t *x, uint32_t tick);
/* One CRO frame (payload bytes). Never fails: bad input becomes an ERR packet and a count. */
void vh_xcp_rx(vh_xcp_t *x, const uint8_t *cro, size_t len, uint32_t tick);
/* DAQ sampling at event channel `channel`. */
void vh_xcp_event(vh_xcp_t *x, uint16_t channel);
/* Next frame to transmit (the response first, then DTOs in order); 0 when none is left. */
int vh_xcp_tx_pop(vh_xcp_t *x, vh_xcp_frame_t *out);
/* The key for a seed of a resource (VH_XCP_RES_*): the first VH_XCP_KEY_LEN bytes of
 * CMAC-AES-128(k, "XCPK" | resource | seed). A master computes the same from the key file. */
void vh_xcp_key(const vh_cmac_key_t *k, uint8_t resource, const uint8_t seed[VH_XCP_SEED_LEN],
                uint8_t key[VH_XCP_KEY_LEN]);

#endif /* VH_XCP_H */
