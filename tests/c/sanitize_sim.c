/* sanitize_sim.c - the in-process lockstep (car + ECU, vh_car.h) under the sanitizers: the powertrain
 * car with hostile driver inputs and a failing sensor part of the way, then the 14-DOF car with the
 * roll node closing the loop over the ECU's commands. */
#include <math.h>
#include <stdio.h>

#include "vh_dlsim.h"
#include "vh_v14car.h"

#define N_TICKS 20000

int vh_sanitize_sim(void);

int vh_sanitize_sim(void)
{
    static vh_dlsim_t sim;
    static vh_ecu_t ecu;
    static vh_frame_t frames[N_TICKS * 3];
    static uint32_t ticks[N_TICKS * 3];
    static double throttle[N_TICKS];
    static uint8_t gear[N_TICKS];
    static vh_dlp_truth_t truth[N_TICKS];
    static vh_v14car_t v14;
    static vh_v14_input_t in[N_TICKS / 10];
    static uint8_t active[N_TICKS / 10];
    static vh_v14car_truth_t v14_truth[N_TICKS / 10];
    vh_v14_params_t v14_prm;
    vh_chs_config_t chs;
    vh_rln_config_t rln;
    vh_v14_arc_params_t arc[2];
    vh_car_t car;
    vh_dlp_params_t prm;
    vh_dls_config_t node;
    vh_ecu_config_t cfg;
    size_t n, i;

    vh_dlp_params_default(&prm);
    vh_dls_config_default(&node);
    vh_ecu_config_default(&cfg);
    if (vh_dlsim_init(&sim, &prm, 7u, &node) != VH_OK || vh_ecu_init(&ecu, &cfg) != VH_OK) {
        fprintf(stderr, "sim init failed\n");
        return 1;
    }
    for (i = 0; i < N_TICKS; ++i) {
        throttle[i] = (i % 3000u < 1500u) ? 1.0 : 0.0;
        gear[i] = (uint8_t)((i / 2500u) % 7u); /* 0..6: 6 is not a gear */
    }
    throttle[100] = NAN;
    vh_dlsim_car(&sim, throttle, gear, N_TICKS, &car);
    n = vh_lockstep_run(&car, &ecu, 0, N_TICKS / 2, truth, frames, ticks, N_TICKS * 3);
    sim.node.cfg.fail_mask = 0x3Fu; /* every sensor reports SNA */
    n += vh_lockstep_run(&car, &ecu, N_TICKS / 2, N_TICKS / 2, truth, frames, ticks, N_TICKS);

    vh_v14_params_default(&v14_prm);
    vh_chs_config_default(&chs);
    vh_rln_config_default(&rln);
    vh_v14_arc_params_default(&arc[0]);
    vh_v14_arc_params_default(&arc[1]);
    for (i = 0; i < N_TICKS / 10; ++i) {
        vh_v14_input_init(&in[i], 1.0);
        in[i].steer = i < 200u ? 0.0 : 0.05;
        active[i] = (uint8_t)(i >= 100u);
    }
    in[300].steer = NAN;
    if (vh_v14car_init(&v14, &v14_prm, 20.0, &chs, &rln, arc) != VH_OK) {
        fprintf(stderr, "14-DOF car init failed\n");
        return 1;
    }
    vh_ecu_reset(&ecu);
    vh_v14car_car(&v14, in, active, N_TICKS / 10, &car);
    /* one tick more than the drive: its last input holds */
    n += vh_lockstep_run(&car, &ecu, 0, N_TICKS / 10 + 1, NULL, frames, ticks, N_TICKS);
    (void)vh_lockstep_run(&car, &ecu, 0, N_TICKS / 10, v14_truth, frames, ticks, N_TICKS);
    printf("sim: %lu frames, signal invalid %u, input invalid %u, resets %u\n", (unsigned long)n,
           ecu.cnt.signal_invalid, ecu.cnt.input_invalid, ecu.cnt.filter_reset);
    return (n > 0u && isfinite(truth[N_TICKS / 2 - 1].to) && isfinite(v14_truth[N_TICKS / 10 - 1].plant.phi)) ? 0 : 1;
}
