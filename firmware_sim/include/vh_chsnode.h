/* vh_chsnode.h - firmware of the chassis sensor node (CHS): every 500 us it samples the
 * inertial cluster (a_x, a_y, yaw rate, roll rate), the steering angle, the four wheel speeds
 * and the four wheel torques of the 14-DOF plant, adds each sensor's bias and Gaussian noise,
 * quantises to the DBC resolution through the generated codec (vh_ch.h) and sends one
 * E2E-protected CHS_Sensors frame (dbc/vehest_ch.dbc). Where ride-height sensors are fitted
 * (ride_period > 0) it also samples the four springs' deflections every ride_period ticks and sends
 * them in CHS_RideHeight. With SecOC on (vh_chs_set_secoc) both frames are secured through the node's
 * vh_secoc_bus hook, as the roll node's are, and its sync frame goes first at 1 Hz.
 *
 * The noise of all CHS_Sensors channels is drawn every tick in a fixed order, so changing one
 * channel's standard deviation (or failing it) leaves the other channels' noise sequences
 * unchanged; the ride-height channels draw from a stream of their own, so fitting them changes
 * no CHS_Sensors frame.
 */
#ifndef VH_CHSNODE_H
#define VH_CHSNODE_H

#include <stddef.h>
#include <stdint.h>

#include "vh_rng.h"
#include "vh_secoc_bus.h"
#include "vh_types.h"
#include "vh_veh14.h"

/* Channels, in the order of CHS_Sensors and of the noise draws. */
enum {
    VH_CHS_CH_AX = 0,    /* longitudinal acceleration [m/s^2] */
    VH_CHS_CH_AY = 1,    /* lateral acceleration [m/s^2] */
    VH_CHS_CH_YAW = 2,   /* yaw rate [rad/s] */
    VH_CHS_CH_ROLL = 3,  /* roll rate [rad/s] */
    VH_CHS_CH_STEER = 4, /* road-wheel steering angle [rad] */
    VH_CHS_CH_W = 5,     /* 5..8 wheel speed FL, FR, RL, RR [rad/s] */
    VH_CHS_CH_T = 9,     /* 9..12 wheel torque FL, FR, RL, RR [Nm] */
    VH_CHS_NCH = 13,     /* the channels of CHS_Sensors */
    VH_CHS_CH_RH = 13,   /* 13..16 spring deflection FL, FR, RL, RR [m] (CHS_RideHeight) */
    VH_CHS_NCH_ALL = 17
};

/* CHS_RideHeight every 20 ticks (10 ms, its DBC cycle) where ride-height sensors are fitted */
#define VH_CHS_RIDE_PERIOD_DEFAULT 20u

typedef struct {
    double noise_std[VH_CHS_NCH_ALL]; /* per channel, in the channel's unit; >= 0 */
    double bias[VH_CHS_NCH_ALL];      /* constant offset per channel, in the channel's unit */
    uint64_t seed;                /* of the node's own random stream */
    uint32_t fail_mask;           /* bit (1 << VH_CHS_CH_*): channel sends SNA, qualifier INVALID */
    int accel_gravity;            /* 1: the accelerometers sit on the sprung body and feel gravity
                                   * through its roll and pitch (a_y + g sin phi, a_x - g sin theta);
                                   * 0: the kinematic accelerations of the vehicle frame (the paper) */
    uint32_t ride_period;         /* ticks between CHS_RideHeight frames; 0 (the default): no
                                   * ride-height sensors fitted */
} vh_chs_config_t;

typedef struct {
    vh_chs_config_t cfg;          /* cfg.fail_mask and cfg.bias may be changed between steps */
    vh_rng_t rng;
    vh_rng_t rng_ride;            /* the ride-height channels' own stream */
    double meas[VH_CHS_NCH_ALL];  /* last sample with bias and noise, before quantisation */
    uint8_t counter;              /* E2E alive counter of the next CHS_Sensors frame, 0..14 */
    uint8_t counter_ride;         /* and of the next CHS_RideHeight frame */
    uint32_t tick;                /* steps since reset */
    uint32_t frames;              /* frames sent since reset */
    vh_secoc_bus_t *secoc;        /* the node's SecOC (caller-owned, kept across resets), NULL: off */
} vh_chs_t;

void vh_chs_config_default(vh_chs_config_t *cfg);
/* VH_OK, or VH_EINVAL (nothing changed) for a negative or non-finite noise level or a
 * non-finite bias. */
int vh_chs_init(vh_chs_t *n, const vh_chs_config_t *cfg);
/* Counters to 0, random streams restarted from cfg.seed; SecOC's sync frames at the next step. */
void vh_chs_reset(vh_chs_t *n);
/* SecOC for the node's frames (vh_secoc_bus_init'ed for VH_SECOC_NODE_CHS, keyed, started), or NULL
 * (vh_chs_init sets NULL). */
void vh_chs_set_secoc(vh_chs_t *n, vh_secoc_bus_t *s);
/* Sample truth and write one CHS_Sensors frame (FD|BRS, 32 bytes) to out[0], then, on a ride-height
 * tick (every ride_period ticks from the first), one CHS_RideHeight frame (16 bytes) to out[1] when
 * cap >= 2. With SecOC on, both are secured and the sync frame, when due, goes first if there is room
 * (cap 3 leaves room for all). Returns the number of frames written: 1 to 3, or 0 when cap is 0 or out
 * or truth is NULL. */
size_t vh_chs_step(vh_chs_t *n, const vh_v14_truth_t *truth, vh_frame_t *out, size_t cap);

#endif /* VH_CHSNODE_H */
