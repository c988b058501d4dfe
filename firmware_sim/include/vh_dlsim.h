/* vh_dlsim.h - the simulated car of seed 001 (driveline plant + sensor node, and the camber
 * inspection devices of seed 002 when clamped on), behind the car interface (vh_car.h).
 *
 * One tick = plant step of 0.5 ms, then the sensor node samples the new state and sends its
 * frames. The same vh_dlsim_tick drives every mode (vh_car.h), so all modes see bit-identical frames.
 */
#ifndef VH_DLSIM_H
#define VH_DLSIM_H

#include "vh_cambernode.h"
#include "vh_dlplant.h"
#include "vh_car.h"
#include "vh_dlsnode.h"
#include "vh_secoc_bus.h"
#include "vh_types.h"

/* DLS_Sensors and CIS_Accel, each with its node's SecOC sync frame */
#define VH_DLSIM_MAX_TX 4

#define VH_DLSIM_N_CIS 4 /* camber inspection devices FL, FR, RL, RR */

typedef struct {
    vh_dlp_t plant;
    vh_dls_t node;
    vh_cambernode_t cis[VH_DLSIM_N_CIS];
    uint8_t cis_on;      /* devices clamped on: CIS_Accel every 10 ms */
    uint8_t cis_counter; /* E2E alive counter of CIS_Accel */
    uint32_t ticks;      /* since reset */
    vh_secoc_bus_t *dls_secoc; /* SecOC of the DLS node and of the CIS devices (caller-owned, kept */
    vh_secoc_bus_t *cis_secoc; /* across resets), NULL: off */
    const double *throttle;    /* the drive (vh_dlsim_car): throttle and gear per tick, caller-owned */
    const uint8_t *gear;
    size_t n;
} vh_dlsim_t;

int vh_dlsim_init(vh_dlsim_t *sim, const vh_dlp_params_t *prm, uint64_t plant_seed, const vh_dls_config_t *node);
void vh_dlsim_reset(vh_dlsim_t *sim);
/* Clamp the four camber inspection devices on (seed 002), in a fixture pose
 * (vh_cambernode_pose_t); NULL switches them off. VH_EINVAL for a bad config (nothing changed). */
int vh_dlsim_set_camber(vh_dlsim_t *sim, const vh_cambernode_config_t cfg[VH_DLSIM_N_CIS], int pose);
/* SecOC for the nodes' frames: dls for node DLS (DLS_Sensors), cis for node CIS (CIS_Accel), each
 * vh_secoc_bus_init'ed for its node, keyed and started; NULL leaves that node's frames unsecured.
 * vh_dlsim_init clears both. */
void vh_dlsim_set_secoc(vh_dlsim_t *sim, vh_secoc_bus_t *dls, vh_secoc_bus_t *cis);
/* One tick of the car with the driver's throttle and gear; returns the frames written to out. */
size_t vh_dlsim_tick(vh_dlsim_t *sim, double throttle, int gear, vh_frame_t *out, size_t cap);

/* The car interface (vh_car.h) of sim, driven by throttle[k] and gear[k] for k < n (n >= 1; the last of
 * them after); the arrays are the caller's and must outlive the runs. Truth: vh_dlp_truth_t. */
void vh_dlsim_car(vh_dlsim_t *sim, const double *throttle, const uint8_t *gear, size_t n, vh_car_t *car);

#endif /* VH_DLSIM_H */
