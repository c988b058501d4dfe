/* vh_camber_app.h - the camber inspection ECU application (seed 002) on the powertrain bus.
 *
 * RX: CIS_Accel (length, E2E), timeout and burst. Step: one window step per present device on
 * every fresh frame, "stationary" from the wheel-speed gate an app before it publishes
 * (vh_app_signals_t: the driveline's). Counts into the ECU's counters (ctx->cnt). TX: VEHEST_Camber
 * at its DBC cycle while the devices talk.
 */
#ifndef VH_CAMBER_APP_H
#define VH_CAMBER_APP_H

#include "vh_app.h"
#include "vh_camber.h"
#include "vh_rx.h"
#include "vh_types.h"

#define VH_ECU_N_WHEELS 4 /* camber inspection devices: FL, FR, RL, RR */
#define VH_ECU_CAMBER_NO_RESULT 7u /* CamberReason SNA: no window completed yet */

typedef struct {
    vh_camber_config_t cmb; /* inspection window and acceptance */
    double still_ww;        /* |wheel speed| below which the car counts as stationary [rad/s] */
} vh_camber_app_config_t;

/* Its tuning (XCP): -> cfg and each window's */
typedef struct {
    double still_ww;
    float mag_tol_g;
    float std_max_g;
} vh_camber_app_cal_t;

/* Camber inspection: last raw sample per device and the running windows. */
typedef struct {
    vh_camber_app_config_t cfg;
    int16_t raw[VH_ECU_N_WHEELS][3];
    uint8_t present;  /* bit i: device i sampling */
    vh_ecu_rxmsg_t rx;
    vh_camber_t cmb[VH_ECU_N_WHEELS];
    vh_camber_result_t last[VH_ECU_N_WHEELS];
    uint8_t have[VH_ECU_N_WHEELS]; /* a window completed since reset */
    uint8_t tx_counter;            /* E2E counter of VEHEST_Camber */
} vh_camber_app_t;

/* The application's entry points (vh_app.h). check: VH_EINVAL for a configuration vh_camber_init
 * refuses or a negative or non-finite still_ww. reset re-initialises every window; the devices'
 * calibrations are data and survive. */
void vh_camber_app_config_default(vh_camber_app_config_t *cfg);
int vh_camber_app_config_host(vh_camber_app_config_t *cfg);
int vh_camber_app_check(const vh_camber_app_config_t *cfg);
void vh_camber_app_init(vh_camber_app_t *a, const vh_camber_app_config_t *cfg);
void vh_camber_app_reset(vh_camber_app_t *a);
void vh_camber_app_rx(vh_camber_app_t *a, vh_app_ctx_t *ctx, const vh_frame_t *f);
void vh_camber_app_cal_gather(const vh_camber_app_t *a, vh_camber_app_cal_t *c);
void vh_camber_app_cal_apply(vh_camber_app_t *a, const vh_camber_app_cal_t *c);
unsigned vh_camber_app_safety(vh_camber_app_t *a, int hold);
/* Runnables: RX timeout/burst and, on a fresh frame, a window step per device; the payload of
 * VEHEST_Camber (0, send nothing, while CIS_Accel is timed out). */
void vh_camber_app_step(vh_camber_app_t *a, vh_app_ctx_t *ctx);
int vh_camber_app_fill(vh_camber_app_t *a, vh_app_ctx_t *ctx, uint8_t *data);
/* Load one device's calibration (seed 002 eq. 19); VH_EINVAL for a wheel >= 4 or an invalid
 * calibration (the wheel then reports NOT_CALIBRATED). Survives reset. */
int vh_camber_app_set_calibration(vh_camber_app_t *a, unsigned wheel, const vh_camber_cal_t *cal);

#endif /* VH_CAMBER_APP_H */
