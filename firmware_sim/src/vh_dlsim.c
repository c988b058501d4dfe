/* vh_dlsim.c - see vh_dlsim.h. */
#include "vh_dlsim.h"

int vh_dlsim_init(vh_dlsim_t *sim, const vh_dlp_params_t *prm, uint64_t plant_seed, const vh_dls_config_t *node)
{
    if (vh_dlp_init(&sim->plant, prm, plant_seed) != VH_OK || vh_dls_init(&sim->node, node) != VH_OK) {
        return VH_EINVAL;
    }
    return VH_OK;
}

void vh_dlsim_reset(vh_dlsim_t *sim)
{
    vh_dlp_reset(&sim->plant);
    vh_dls_reset(&sim->node);
}

size_t vh_dlsim_tick(vh_dlsim_t *sim, double throttle, int gear, vh_frame_t *out, size_t cap)
{
    vh_dlp_step(&sim->plant, throttle, gear);
    return vh_dls_step(&sim->node, &sim->plant.truth, out, cap);
}

size_t vh_lockstep_run(vh_dlsim_t *sim, vh_ecu_t *ecu, size_t n, const double *throttle, const uint8_t *gear,
                       vh_dlp_truth_t *truth, vh_frame_t *frames, uint32_t *frame_tick, size_t cap)
{
    vh_frame_t buf[VH_DLSIM_MAX_TX + VH_ECU_MAX_TX];
    size_t t, i, total = 0u;
    for (t = 0; t < n; ++t) {
        const size_t ncar = vh_dlsim_tick(sim, throttle[t], gear ? gear[t] : 2, buf, VH_DLSIM_MAX_TX);
        size_t nall;
        for (i = 0; i < ncar; ++i) {
            vh_ecu_rx(ecu, &buf[i]);
        }
        nall = ncar + vh_ecu_step(ecu, buf + ncar, VH_ECU_MAX_TX);
        for (i = 0; i < nall; ++i, ++total) {
            if (total < cap) {
                frames[total] = buf[i];
                frame_tick[total] = (uint32_t)t;
            }
        }
        if (truth) {
            truth[t] = sim->plant.truth;
        }
    }
    return total;
}
