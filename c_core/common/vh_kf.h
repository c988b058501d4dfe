/* vh_kf.h - the life cycle the Kalman filters share (vh_dkf, vh_skf, vh_skfq): steps since the
 * last (re)start, divergence resets and the health of vh_health.h, as one policy.
 *
 * Integer only: the fixed-point filter includes it (no double anywhere in this header).
 */
#ifndef VH_KF_H
#define VH_KF_H

#include <stdint.h>

#include "vh_health.h"

/* A (re)start: no step yet, the state not seeded, INIT. */
static inline void vh_kf_restart(uint32_t *steps, uint8_t *x_init, uint8_t *health)
{
    *steps = 0u;
    *x_init = 0u;
    *health = VH_HEALTH_INIT;
}

/* A step that kept the filter sane: one more step (the count saturates), and its health:
 * DEGRADED when something was missing, else INIT for the first init_steps steps, then OK. */
static inline uint8_t vh_kf_step_health(uint32_t *steps, int degraded, uint32_t init_steps)
{
    if (*steps < UINT32_MAX) {
        ++*steps;
    }
    if (degraded) {
        return VH_HEALTH_DEGRADED;
    }
    return *steps >= init_steps ? VH_HEALTH_OK : VH_HEALTH_INIT;
}

/* A step that found divergence, after the caller's restart: one more reset, FAULT for this step.
 * Returns 1, the step functions' "had to reset". */
static inline int vh_kf_fault(uint32_t *resets, uint8_t *health)
{
    ++*resets;
    *health = VH_HEALTH_FAULT;
    return 1;
}

#endif /* VH_KF_H */
