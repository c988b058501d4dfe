/* vh_camber_app.h - the camber inspection ECU application (seed 002) on the powertrain bus.
 *
 * RX: CIS_Accel (length, E2E), timeout and burst. Step: one window step per present device on
 * every fresh frame, "stationary" given by the caller (the driveline's wheel speeds). TX:
 * VEHEST_Camber at its DBC cycle while the devices talk.
 */
#ifndef VH_CAMBER_APP_H
#define VH_CAMBER_APP_H

#include "vh_camber.h"
#include "vh_rx.h"
#include "vh_types.h"

#define VH_ECU_N_WHEELS 4 /* camber inspection devices: FL, FR, RL, RR */
#define VH_ECU_CAMBER_NO_RESULT 7u /* CamberReason SNA: no window completed yet */

/* Camber inspection: last raw sample per device and the running windows. */
typedef struct {
    int16_t raw[VH_ECU_N_WHEELS][3];
    uint8_t present;  /* bit i: device i sampling */
    vh_ecu_rxmsg_t rx;
    vh_camber_t cmb[VH_ECU_N_WHEELS];
    vh_camber_result_t last[VH_ECU_N_WHEELS];
    uint8_t have[VH_ECU_N_WHEELS]; /* a window completed since reset */
    uint8_t tx_counter;            /* E2E counter of VEHEST_Camber */
} vh_ecu_cis_t;

/* VH_OK, or VH_EINVAL for a configuration vh_camber_init refuses or a negative or non-finite
 * still_ww (the wheel speed under which the car counts as standing, rad/s). */
int vh_cmb_app_check(const vh_camber_config_t *cfg, double still_ww);
/* Re-initialise every window from cfg; the devices' calibrations are data and survive. */
void vh_cmb_app_reset(vh_ecu_cis_t *c, const vh_camber_config_t *cfg);
/* Load one device's calibration; VH_EINVAL for a wheel >= 4 or an invalid calibration. */
int vh_cmb_app_set_calibration(vh_ecu_cis_t *c, unsigned wheel, const vh_camber_cal_t *cal);
/* One received CIS_Accel frame, checked and counted into cnt. */
void vh_cmb_app_rx(vh_ecu_cis_t *c, vh_ecu_counters_t *cnt, const vh_frame_t *f);
/* Once per tick: RX timeout/burst and, on a fresh frame, a window step per device. */
void vh_cmb_app_step(vh_ecu_cis_t *c, int still, vh_ecu_counters_t *cnt, unsigned burst_limit);
/* The payload of VEHEST_Camber; 0 (send nothing) while CIS_Accel is timed out. */
int vh_cmb_app_fill(vh_ecu_cis_t *c, uint8_t *data);

#endif /* VH_CAMBER_APP_H */
