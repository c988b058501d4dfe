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

/* Capacities: the instance is sized at compile time (no heap). */
#define VH_XCP_FRAME_MAX 64    /* CAN FD payload */
#define VH_XCP_MAX_REGIONS 16
#define VH_XCP_MAX_CHARS 64    /* characteristics in the calibration segment */
#define VH_XCP_MAX_EVENTS 8
#define VH_XCP_MAX_DAQ 8       /* dynamic DAQ lists */
#define VH_XCP_MAX_ODT 64      /* ODTs over all lists; absolute ODT numbers stay below 0xFC */
#define VH_XCP_MAX_ENTRIES 256 /* ODT entries over all ODTs */
#define VH_XCP_TXQ 128         /* DTO frames queued between two vh_xcp_tx_pop drains */
#define VH_XCP_ID_MAX 48       /* GET_ID strings */

/* Region access bits. */
#define VH_XCP_ACC_READ 1 /* UPLOAD / SHORT_UPLOAD */
#define VH_XCP_ACC_DAQ 2  /* WRITE_DAQ may sample it */

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
    uint32_t secret;  /* seed & key: key = vh_xcp_key(seed, secret) */
    uint32_t tick_us; /* DAQ timestamp: one timestamp tick per ECU tick */
    uint32_t open_ticks; /* a characteristic written part-way commits after this many ticks
                          * without a write (0: only once its last byte is written) */
    const vh_xcp_region_t *regions;
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
    uint32_t key_fail;      /* wrong keys (the slave disconnects) */
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
    uint32_t seed;
    uint32_t seed_state; /* LCG, deterministic */
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
/* The seed & key algorithm, exposed so a test master and the bench tool compute the same key.
 * A bench algorithm, not a secret one: a production ECU derives keys in its HSM. */
uint32_t vh_xcp_key(uint32_t seed, uint32_t secret);

#endif /* VH_XCP_H */
