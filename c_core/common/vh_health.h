/* vh_health.h - the health state every estimator publishes with its estimates.
 *
 * INIT after a (re)start until the filter has settled, OK with every input valid, DEGRADED when
 * an input or measurement is missing (prediction only) or a fixed-point step saturated, FAULT
 * for the step that found divergence or a non-finite value and reset the filter.
 */
#ifndef VH_HEALTH_H
#define VH_HEALTH_H

typedef enum { VH_HEALTH_INIT = 0, VH_HEALTH_OK = 1, VH_HEALTH_DEGRADED = 2, VH_HEALTH_FAULT = 3 } vh_health_t;

#endif /* VH_HEALTH_H */
