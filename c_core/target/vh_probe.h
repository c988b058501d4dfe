/* vh_probe.h - each application's SysTick counts in the current tick (vh_probe.c). */
#ifndef VH_PROBE_H
#define VH_PROBE_H

#include <stdint.h>

#include "vh_ecu_apps.h"

#define VH_PROBE_MAX_APPS 16
extern const char *const vh_probe_app_name[VH_ECU_N_APPS];
extern uint32_t vh_probe_counts[VH_ECU_N_APPS]; /* zeroed by the caller before each tick */

#endif
