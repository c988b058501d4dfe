/* vh_chsnode.c - see vh_chsnode.h. */
#include "vh_chsnode.h"

#include <math.h>

#include "vh_ch.h"
#include "vh_ch_enc.h"
#include "vh_ch_meta.h"
#include "vh_e2e.h"
#include "vh_node_common.h"
#include "vh_node_impl.h"

/* One channel: raw = round(phys / scale) clamped to the DBC range (the generated encoder), or
 * the signal's SNA value when the sensor failed; and its qualifier. */
#define CHAN(sig, SIG, c) VH_NODE_CHANNEL(m, ch, CH, chs_sensors, CHS_SENSORS, sig, SIG, ok[c], n->meas[c])

void vh_chs_config_default(vh_chs_config_t *cfg)
{
    int i;
    /* Automotive MEMS inertial cluster sampled at 2 kHz (no filtering in the node): 0.05 m/s^2
     * and 0.3 deg/s rms. Steering-angle sensor 0.1 deg at the steering wheel over a 16:1 ratio:
     * ~0.1 mrad at the road wheel. ABS wheel speeds 0.1 rad/s (tooth jitter at 2 kHz). Wheel
     * torques (powertrain torque model and caliper pressure) 2 Nm. */
    cfg->noise_std[VH_CHS_CH_AX] = 0.05;
    cfg->noise_std[VH_CHS_CH_AY] = 0.05;
    cfg->noise_std[VH_CHS_CH_YAW] = 0.005;
    cfg->noise_std[VH_CHS_CH_ROLL] = 0.005;
    cfg->noise_std[VH_CHS_CH_STEER] = 0.0001;
    for (i = 0; i < 4; ++i) {
        cfg->noise_std[VH_CHS_CH_W + i] = 0.1;
        cfg->noise_std[VH_CHS_CH_T + i] = 2.0;
    }
    for (i = 0; i < VH_CHS_NCH; ++i) {
        cfg->bias[i] = 0.0;
    }
    cfg->seed = 0x434853u; /* "CHS" */
    cfg->fail_mask = 0u;
    cfg->accel_gravity = 0;
}

VH_NODE_LIFECYCLE(chs, VH_CHS_NCH, cfg->bias)

size_t vh_chs_step(vh_chs_t *n, const vh_v14_truth_t *truth, vh_frame_t *out, size_t cap)
{
    struct vh_ch_chs_sensors_t m;
    double phys[VH_CHS_NCH];
    uint8_t ok[VH_CHS_NCH];
    int i;

    if (out == NULL || cap == 0u || truth == NULL) {
        return 0u;
    }
    phys[VH_CHS_CH_AX] = truth->ax;
    phys[VH_CHS_CH_AY] = truth->ay;
    if (n->cfg.accel_gravity) {
        /* specific force along the rolled and pitched body axes (y up-tilted by phi, x nose-down
         * by theta): f = a + g z_up projected, small vertical acceleration left out */
        phys[VH_CHS_CH_AX] = truth->ax * cos(truth->theta) - VH_V14_GRAVITY * sin(truth->theta);
        phys[VH_CHS_CH_AY] = truth->ay * cos(truth->phi) + VH_V14_GRAVITY * sin(truth->phi);
    }
    phys[VH_CHS_CH_YAW] = truth->r;
    phys[VH_CHS_CH_ROLL] = truth->p;
    phys[VH_CHS_CH_STEER] = truth->steer;
    for (i = 0; i < 4; ++i) {
        phys[VH_CHS_CH_W + i] = truth->omega[i];
        phys[VH_CHS_CH_T + i] = truth->torque[i];
    }
    vh_node_sample(&n->rng, phys, n->cfg.bias, n->cfg.noise_std, VH_CHS_NCH, n->meas);
    vh_node_qualify(n->meas, n->cfg.fail_mask, VH_CHS_NCH, ok);
    (void)vh_ch_chs_sensors_init(&m);
    CHAN(long_accel, LONG_ACCEL, VH_CHS_CH_AX);
    CHAN(lat_accel, LAT_ACCEL, VH_CHS_CH_AY);
    CHAN(yaw_rate, YAW_RATE, VH_CHS_CH_YAW);
    CHAN(roll_rate, ROLL_RATE, VH_CHS_CH_ROLL);
    CHAN(steer_angle, STEER_ANGLE, VH_CHS_CH_STEER);
    VH_NODE_CORNERS(CHAN, wheel_speed, WHEEL_SPEED, VH_CHS_CH_W);
    VH_NODE_CORNERS(CHAN, wheel_torque, WHEEL_TORQUE, VH_CHS_CH_T);

    vh_node_frame_init(out, VH_CH_CHS_SENSORS_FRAME_ID, VH_CH_CHS_SENSORS_LENGTH);
    (void)vh_ch_chs_sensors_pack(out->data, &m, VH_CH_CHS_SENSORS_LENGTH);
    vh_e2e_p01_protect(out->data, VH_CH_CHS_SENSORS_LENGTH, VH_CH_CHS_SENSORS_E2E_DATA_ID, &n->counter);
    vh_node_count(&n->frames);
    return 1u;
}
