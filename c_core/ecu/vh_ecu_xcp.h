/* vh_ecu_xcp.h - the XCP-on-CAN slave (vh_xcp.h) as an application of the ECU.
 *
 * Off until vh_ecu_xcp_enable, which the host calls only when the user turns XCP on with a key.
 *
 * Measurement: the master's address space VH_ECU_XCP_MEAS_ADDRESS + offsetof(vh_ecu_t, member)
 * reads the members of the ECU instance the description names (UPLOAD and DAQ), nothing else:
 * the readable regions are the generated table's (vh_ecu_xcp_table.inc, the measurements with
 * adjacent ones merged), so pointers, the slave's own state and configuration stay unreadable.
 * The seed & key key is not in vh_ecu_t at all (caller-owned, like SecOC's keys).
 *
 * Safe state (the ECU's decision, every tick, from each application's vh_<m>_app_safety): every
 * application's actuators passive (e.g. faded out, zero moment) AND the car at standstill (every
 * speed source heard since enable says so now; a source heard once and silent now is not
 * standstill), or the calibration mode
 * (cal_mode, the host's start option) with the actuators held passive.
 * Safety-relevant characteristics are written and committed only then (ERR_WRITE_PROTECTED).
 *
 * Calibration: one segment at VH_ECU_XCP_CAL_ADDRESS + offsetof(vh_ecu_cal_t, member), the
 * tuning of every application gathered in one block (vh_<m>_app_cal_gather, _apply). Page 1 (reference, never written) is the tuning
 * the ECU was configured with; page 0 (working, RAM) is what DOWNLOAD writes, range-checked
 * against the limits of the generated table (vh_ecu_xcp_table.inc, from
 * vehest_can/xcp/ecu.toml: the same limits as the A2L). A characteristic reaches `page`, the
 * block the systems run on, whole at a tick boundary; the ECU then copies it into the filters
 * (vh_ecu_cal_apply) before any system steps, so a filter never runs on half a matrix.
 *
 * Events: 0 every tick (500 us), 1 every 1 ms, 2 every 10 ms, after the systems have stepped.
 * TX: at most VH_ECU_XCP_MAX_TX frames per tick (the bus budget, docs/xcp.md); the rest wait in
 * the slave's queue, and a DAQ sample that does not fit it is dropped whole and counted.
 */
#ifndef VH_ECU_XCP_H
#define VH_ECU_XCP_H

#include "vh_ecu_apps.h"
#include "vh_xcp.h"

#define VH_ECU_XCP_MEAS_ADDRESS 0x10000000
#define VH_ECU_XCP_CAL_ADDRESS 0x20000000
#define VH_ECU_XCP_N_EVENTS 3
#define VH_ECU_XCP_MAX_TX 1 /* XCP frames per tick: one 64-byte DTO per 500 us is the budget */
#define VH_ECU_XCP_UNLOCK_DELAY_TICKS 1000 /* 0.5 s after a wrong key, doubled with each further one */
#define VH_ECU_XCP_UNLOCK_ATTEMPTS 5       /* wrong keys in a row: seed & key locked until restart */

/* Every application's tuning the master may change (the calibration segment). */
typedef struct {
    vh_ecu_apps_cal_t app;
    uint8_t rx_burst_frames;  /* -> the ECU's rx_burst_frames */
} vh_ecu_cal_t;

/* What the integrator chooses (the rest is fixed by the ECU). */
typedef struct {
    uint32_t cro_id;  /* bit 31: 29-bit identifier */
    uint32_t dto_id;
    uint8_t max_cto;  /* 8 .. 64 (above 8: fd) */
    uint8_t max_dto;
    uint8_t fd;
    const vh_cmac_key_t *key;    /* seed & key: the user's key, caller-owned outside vh_ecu_t */
    uint8_t salt[VH_XCP_SALT_LEN]; /* random per start (the host's) */
    uint8_t own_bus;  /* XCP on a bus of its own: a CRO through vh_ecu_rx (the vehicle bus) is not
                       * answered, only counted (cro_foreign); vh_ecu_xcp_rx_own takes the XCP bus */
    uint8_t cal_mode; /* calibration mode: actuators held passive; the safe state needs no standstill */
} vh_ecu_xcp_config_t;

typedef struct {
    vh_xcp_t slave;
    vh_ecu_cal_t ref;    /* page 1: the configured tuning; the slave never writes it */
    vh_ecu_cal_t work;   /* page 0 */
    vh_ecu_cal_t page;   /* what the systems run on; only vh_xcp_tick writes it */
    vh_xcp_region_t regions[VH_XCP_MAX_REGIONS]; /* the measurements (the generated table) */
    vh_xcp_event_t events[VH_ECU_XCP_N_EVENTS];
    uint32_t ticks;      /* never reset: the slave's clock and DAQ timestamps survive vh_ecu_reset */
    uint32_t applied;    /* slave.n.cal_commits already copied into the systems */
    uint8_t applied_page;
    uint8_t stale;       /* the systems were re-initialised: copy the tuning again */
    uint8_t enabled;
    uint8_t own_bus;
    uint8_t cal_mode;
    uint8_t safe;        /* the safe state of this tick (the slave reads it at every write) */
    uint8_t heard;       /* speed sources heard since enable: bit i, the i-th application's */
} vh_ecu_xcp_t;

#endif /* VH_ECU_XCP_H */
