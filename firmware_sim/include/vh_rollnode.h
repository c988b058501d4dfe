/* vh_rollnode.h - the car's roll node (seed 003, dbc/vehest_ch.dbc node ROLL): the roll sensor
 * node, the supervision of the two active roll actuators of the 14-DOF plant, and the driver's
 * roll-mode switch.
 *
 * Sensors: every 0.5 ms plant tick it samples the lateral acceleration, the four unsprung vertical
 * accelerations (the mean over the tick), the four tyre and four suspension deflection changes
 * (compression +) and the yaw rate, each with its bias and Gaussian noise (noise_std per 2 kHz
 * sample); every 5 ms (the DBC cycle of ROLL_Sensors) it sends the mean of the samples since its
 * last frame (a boxcar decimation filter: 10 samples, so the noise of a frame is noise_std / sqrt(10)),
 * quantised to the DBC resolution by the generated codec: ROLL_Sensors (13 channels) and ROLL_YawRate
 * (its own gyro), E2E protected. A channel in fail_mask sends SNA with its qualifier INVALID (a dead
 * sensor); one in stuck_mask repeats the value it last sent with its qualifier VALID (a stuck sensor).
 * The noise of every channel is drawn every tick in a fixed order, so failing one channel leaves the
 * others' noise unchanged.
 *
 * Actuators: VEHEST_RollCmd frames (E2E checked) set the plant's commanded roll moments from the
 * tick after the one they arrived in. Without a good command for the message's timeout
 * (RxTimeoutCycles x cycle = 20 ms) the actuators HOLD the last command for one more timeout, then
 * FAIL SAFE: zero moment at once (vh_v14_roll_fail_safe: the motors shorted), until a good command
 * arrives again. ROLL_ActuatorStatus reports the applied moments and that state every 5 ms.
 * ROLL_ModeCmd carries the driver's switch (mode_active) every 100 ms.
 */
#ifndef VH_ROLLNODE_H
#define VH_ROLLNODE_H

#include <stddef.h>
#include <stdint.h>

#include "vh_e2e.h"
#include "vh_rng.h"
#include "vh_secoc_bus.h"
#include "vh_types.h"
#include "vh_veh14.h"

/* Channels: the roll UKF's measurement order (c_core/roll/vh_roll.h, VH_ROLL_Z_*). */
enum {
    VH_RLN_CH_AY = 0,   /* lateral acceleration [m/s^2] */
    VH_RLN_CH_AZU = 1,  /* 1..4 unsprung vertical acceleration FL, FR, RL, RR [m/s^2] */
    VH_RLN_CH_DT = 5,   /* 5..8 tyre deflection change, compression + [m] */
    VH_RLN_CH_DS = 9,   /* 9..12 suspension deflection change, compression + [m] */
    VH_RLN_CH_R = 13,   /* yaw rate [rad/s] (ROLL_YawRate) */
    VH_RLN_NCH = 14
};

/* Actuator supervision state (ROLL_ActuatorStatus.ArcState). */
enum {
    VH_RLN_ARC_PASSIVE = 0,  /* no command heard yet, or commanded zero in passive mode */
    VH_RLN_ARC_ACTIVE = 1,   /* following the commands */
    VH_RLN_ARC_HOLD = 2,     /* commands timed out: the last one held for one more timeout */
    VH_RLN_ARC_FAILSAFE = 3  /* then zero moment, until a good command arrives */
};

typedef struct {
    double noise_std[VH_RLN_NCH]; /* per channel and 2 kHz sample, in the channel's unit; >= 0 */
    double bias[VH_RLN_NCH];      /* constant offset per channel */
    uint64_t seed;                /* of the node's own random stream */
    uint32_t fail_mask;           /* bit (1 << VH_RLN_CH_*): sends SNA, qualifier INVALID */
    uint32_t stuck_mask;          /* bit (1 << VH_RLN_CH_*): repeats its last value, qualifier VALID */
    uint8_t mode_active;          /* the driver's roll-mode switch: 1 active, 0 passive */
} vh_rln_config_t;

typedef struct {
    vh_rln_config_t cfg;          /* fail_mask, stuck_mask, bias and mode_active may change between ticks */
    vh_rng_t rng;
    double acc[VH_RLN_NCH];       /* sum of the samples since the last frame */
    uint32_t n_acc;
    double vzu[VH_V14_NW];        /* unsprung vertical velocities at the end of the last tick */
    double sent[VH_RLN_NCH];      /* the values of the last frame, before quantisation */
    uint32_t tick;                /* plant ticks since reset */
    uint8_t counter[4];           /* E2E alive counters: Sensors, YawRate, ActuatorStatus, ModeCmd */
    /* actuator supervision */
    vh_e2e_rx_t cmd_e2e;
    uint8_t cmd_new;              /* a good command arrived since the last tick */
    uint8_t heard;                /* a good command has arrived since reset */
    uint8_t state;                /* VH_RLN_ARC_* */
    uint8_t cmd_mode;             /* RollModeCmd of the last good command */
    double cmd[2];                /* its moments front, rear [Nm] */
    uint32_t cmd_age;             /* ticks since the last good command */
    uint32_t cnt_timeout;         /* entries into HOLD */
    uint32_t cnt_rejected;        /* command frames refused (length, CRC, repeated counter) */
    uint32_t applied_tick;        /* tick at which the last good command was first applied */
    vh_secoc_bus_t *secoc;        /* the node's SecOC (caller-owned, kept across resets), NULL: off */
} vh_rln_t;

void vh_rln_config_default(vh_rln_config_t *cfg);
/* VH_OK, or VH_EINVAL (nothing changed) for a negative or non-finite noise level or a
 * non-finite bias. */
int vh_rln_init(vh_rln_t *n, const vh_rln_config_t *cfg);
/* Counters, filter and supervision to their start, random stream restarted from cfg.seed; the
 * plant is taken to start in its static equilibrium (unsprung velocities 0). */
void vh_rln_reset(vh_rln_t *n);
/* SecOC for the node's frames (vh_secoc_bus_init'ed for VH_SECOC_NODE_ROLL, keyed, started), or NULL. */
void vh_rln_set_secoc(vh_rln_t *n, vh_secoc_bus_t *s);
/* One frame from the bus: VEHEST_RollCmd is checked (SecOC when on, length, E2E) and kept for the
 * next tick; the ECU's SecOC sync frame resynchronises; any other frame is ignored. A command that
 * fails its MAC or freshness is counted as rejected and, like a lost one, never applied. */
void vh_rln_rx(vh_rln_t *n, const vh_frame_t *f);
/* Before the plant's step of a tick: the supervision's moment commands into the plant. */
void vh_rln_actuate(vh_rln_t *n, vh_v14_t *p);
/* After the plant's step: sample, and write this tick's frames (at most 4, 5 with SecOC's sync
 * frame) to out[0..cap). Returns the number written. */
size_t vh_rln_step(vh_rln_t *n, const vh_v14_t *p, vh_frame_t *out, size_t cap);

#endif /* VH_ROLLNODE_H */
