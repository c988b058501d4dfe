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
#define RIDE(sig, SIG, c) VH_NODE_CHANNEL(m, ch, CH, chs_ride_height, CHS_RIDE_HEIGHT, sig, SIG, ok[c], meas[c])

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
    /* ride-height sensors (angle sensors on the control arms): 0.1 mm at the wheel */
    for (i = 0; i < 4; ++i) {
        cfg->noise_std[VH_CHS_CH_RH + i] = 1e-4;
    }
    for (i = 0; i < VH_CHS_NCH_ALL; ++i) {
        cfg->bias[i] = 0.0;
    }
    cfg->seed = 0x434853u; /* "CHS" */
    cfg->fail_mask = 0u;
    cfg->accel_gravity = 0;
    cfg->ride_period = 0u;
}

int vh_chs_init(vh_chs_t *n, const vh_chs_config_t *cfg)
{
    if (n == NULL || cfg == NULL || vh_node_check(cfg->noise_std, cfg->bias, VH_CHS_NCH_ALL) != VH_OK) {
        return VH_EINVAL;
    }
    n->cfg = *cfg;
    n->secoc = NULL;
    vh_chs_reset(n);
    return VH_OK;
}

void vh_chs_reset(vh_chs_t *n)
{
    vh_node_restart(&n->rng, n->cfg.seed, n->meas, VH_CHS_NCH_ALL);
    vh_rng_seed(&n->rng_ride, n->cfg.seed ^ UINT64_C(0x5249444548474854)); /* "RIDEHGHT" */
    n->counter = 0u;
    n->counter_ride = 0u;
    n->tick = 0u;
    n->frames = 0u;
    if (n->secoc != NULL) {
        vh_secoc_bus_resync(n->secoc); /* the ECU may have restarted too */
    }
}

void vh_chs_set_secoc(vh_chs_t *n, vh_secoc_bus_t *s) { n->secoc = s; }

/* CHS_RideHeight: the four springs' deflections, sampled now, into f. */
static void ride_frame(vh_chs_t *n, const vh_v14_truth_t *truth, vh_frame_t *f)
{
    struct vh_ch_chs_ride_height_t m;
    double *meas = &n->meas[VH_CHS_CH_RH];
    uint8_t ok[4];
    vh_node_sample(&n->rng_ride, truth->spring_defl, &n->cfg.bias[VH_CHS_CH_RH], &n->cfg.noise_std[VH_CHS_CH_RH], 4,
                   meas);
    vh_node_qualify(meas, n->cfg.fail_mask >> VH_CHS_CH_RH, 4, ok);
    (void)vh_ch_chs_ride_height_init(&m);
    VH_NODE_CORNERS(RIDE, spring_defl, SPRING_DEFL, 0);
    vh_node_frame_init(f, VH_CH_CHS_RIDE_HEIGHT_FRAME_ID, VH_CH_CHS_RIDE_HEIGHT_LENGTH);
    (void)vh_ch_chs_ride_height_pack(f->data, &m, VH_CH_CHS_RIDE_HEIGHT_LENGTH);
    vh_e2e_protect(VH_CH_CHS_RIDE_HEIGHT_E2E, f->data, VH_CH_CHS_RIDE_HEIGHT_LENGTH, &n->counter_ride);
    vh_node_count(&n->frames);
}

size_t vh_chs_step(vh_chs_t *n, const vh_v14_truth_t *truth, vh_frame_t *out, size_t cap)
{
    struct vh_ch_chs_sensors_t m;
    double phys[VH_CHS_NCH];
    uint8_t ok[VH_CHS_NCH];
    size_t k;
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
    vh_e2e_protect(VH_CH_CHS_SENSORS_E2E, out->data, VH_CH_CHS_SENSORS_LENGTH, &n->counter);
    vh_node_count(&n->frames);
    k = 1u;
    if (n->cfg.ride_period > 0u && n->tick % n->cfg.ride_period == 0u && cap >= 2u) {
        ride_frame(n, truth, &out[1]);
        k = 2u;
    }
    ++n->tick;
    return n->secoc != NULL ? vh_secoc_bus_tx(n->secoc, out, k, cap) : k;
}
