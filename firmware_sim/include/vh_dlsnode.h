/* vh_dlsnode.h - firmware of the driveline sensor node (DLS): every 500 us it samples the
 * output-shaft speed, left and right wheel speed, the shaft-torque transducer, engine and turbine
 * speed and the engaged gear, adds each sensor's Gaussian noise, quantises to the DBC resolution
 * through the generated codec (vh_pt.h) and sends one E2E-protected DLS_Sensors frame.
 *
 * The noise of all six channels is drawn every tick in a fixed order, so changing one
 * channel's standard deviation leaves the other channels' noise sequences unchanged.
 */
#ifndef VH_DLSNODE_H
#define VH_DLSNODE_H

#include <stddef.h>
#include <stdint.h>

#include "vh_dlplant.h"
#include "vh_rng.h"
#include "vh_types.h"

/* Channels, in the order of DLS_Sensors and of the noise draws. */
enum {
    VH_DLS_CH_WO = 0, /* output-shaft speed [rad/s] */
    VH_DLS_CH_WL = 1, /* left wheel speed (ABS) [rad/s] */
    VH_DLS_CH_WR = 2, /* right wheel speed (ABS) [rad/s] */
    VH_DLS_CH_TO = 3, /* shaft torque (magneto-elastic transducer) [Nm] */
    VH_DLS_CH_WE = 4, /* engine speed [rad/s] */
    VH_DLS_CH_WT = 5, /* turbine speed [rad/s] */
    VH_DLS_NCH = 6
};

typedef struct {
    double noise_std[VH_DLS_NCH]; /* per channel, in the channel's unit; >= 0 */
    uint64_t seed;                /* of the node's own random stream */
    uint32_t fail_mask;           /* bit (1 << VH_DLS_CH_*): channel sends SNA, qualifier INVALID */
} vh_dls_config_t;

typedef struct {
    vh_dls_config_t cfg;          /* cfg.fail_mask may be changed between steps (fault injection) */
    vh_rng_t rng;
    double meas[VH_DLS_NCH];      /* last sample with noise, before quantisation */
    uint8_t counter;              /* E2E alive counter of the next frame, 0..14 */
    uint32_t frames;              /* frames sent since reset */
} vh_dls_t;

void vh_dls_config_default(vh_dls_config_t *cfg);
/* VH_OK, or VH_EINVAL (nothing changed) for a negative or non-finite noise level. */
int vh_dls_init(vh_dls_t *n, const vh_dls_config_t *cfg);
/* Counter to 0, random stream restarted from cfg.seed. */
void vh_dls_reset(vh_dls_t *n);
/* Sample truth and write one DLS_Sensors frame (FD|BRS, its DBC length: 20 bytes with the SecOC
 * tail, zero until vh_dlsim secures it) to out[0].
 * Returns the number of frames written: 1, or 0 when cap is 0 or out or truth is NULL. */
size_t vh_dls_step(vh_dls_t *n, const vh_dlp_truth_t *truth, vh_frame_t *out, size_t cap);

#endif /* VH_DLSNODE_H */
