/* vh_bench_drive.h - the driveline launch the ECU benches feed their ECUs (vh_bench.c,
 * vh_bench_ecu_xcp.c, vh_bench_ecu_secoc.c): the default plant and sensor node, 1 s standing
 * in 2nd gear, then throttle 0.6. One DLS_Sensors frame per tick.
 * Header-only, like vh_bench_common.h; needs the bench include path (vh_dlsim.h).
 */
#ifndef VH_BENCH_DRIVE_H
#define VH_BENCH_DRIVE_H

#include "vh_dlsim.h"

/* The launch's car: the default driveline plant (seed 1) and sensor node. 1, or 0 on failure. */
static inline int vh_bench_launch_init(vh_dlsim_t *sim)
{
    vh_dlp_params_t prm;
    vh_dls_config_t node;
    vh_dlp_params_default(&prm);
    vh_dls_config_default(&node);
    return vh_dlsim_init(sim, &prm, 1u, &node) == VH_OK;
}

/* Tick i of the launch: its frames into out[0..cap), their count. */
static inline size_t vh_bench_launch_tick(vh_dlsim_t *sim, int i, vh_frame_t *out, size_t cap)
{
    return vh_dlsim_tick(sim, i < 2000 ? 0.0 : 0.6, 2, out, cap);
}

/* The frames of n ticks of the launch, one per tick, made once; sim stays for further use. */
static inline int vh_bench_launch(vh_dlsim_t *sim, vh_frame_t *frames, int n)
{
    int i;
    if (!vh_bench_launch_init(sim)) {
        return 0;
    }
    for (i = 0; i < n; ++i) {
        (void)vh_bench_launch_tick(sim, i, &frames[i], 1u);
    }
    return 1;
}

#endif /* VH_BENCH_DRIVE_H */
