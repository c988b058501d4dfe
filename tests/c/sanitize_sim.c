/* sanitize_sim.c - the in-process lockstep (plant + sensor node + ECU) under the sanitizers,
 * with hostile driver inputs and a failing sensor part of the way. */
#include <math.h>
#include <stdio.h>

#include "vh_dlsim.h"

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
    n = vh_lockstep_run(&sim, &ecu, N_TICKS / 2, throttle, gear, truth, frames, ticks, N_TICKS * 3);
    sim.node.cfg.fail_mask = 0x3Fu; /* every sensor reports SNA */
    n += vh_lockstep_run(&sim, &ecu, N_TICKS / 2, throttle + N_TICKS / 2, gear + N_TICKS / 2, truth,
                         frames, ticks, N_TICKS);
    printf("sim: %lu frames, signal invalid %u, input invalid %u, resets %u\n", (unsigned long)n,
           ecu.cnt.signal_invalid, ecu.cnt.input_invalid, ecu.cnt.filter_reset);
    return (n > 0u && isfinite(truth[N_TICKS / 2 - 1].to)) ? 0 : 1;
}
