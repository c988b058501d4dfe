/* vh_probe.c - each application's share of a tick, timed without touching the scheduler: the image
 * is linked with -Wl,--wrap=<each runnable's function> (c_core/firmware_image.py reads them from the
 * same descriptors), so the scheduler's call of vh_<m>_app_<fn> reaches the wrapper here, which reads
 * the SysTick around the real function and adds the counts to its application's total. */
#include "vh_ecu.h"
#include "vh_probe.h"
#include "vh_target.h"

#define INDEX(m) VH_PROBE_APP_##m,
enum { VH_ECU_APPS(INDEX) VH_PROBE_N };
#undef INDEX
typedef char vh_probe_n_check[(VH_PROBE_N == VH_ECU_N_APPS && VH_PROBE_N <= VH_PROBE_MAX_APPS) ? 1 : -1];

#define NAME(m) #m,
const char *const vh_probe_app_name[VH_ECU_N_APPS] = {VH_ECU_APPS(NAME)};
#undef NAME

uint32_t vh_probe_counts[VH_ECU_N_APPS];

#define VH_APP(m, order)
#define VH_APP_RX(m, id)
#define VH_APP_MEAS(m, path, fields, comment)
#define VH_APP_CAL(m, path, fields, comment)
#define VH_APP_STEP(m, fn, period)                                                   \
    void __real_vh_##m##_app_##fn(vh_##m##_app_t *a, vh_app_ctx_t *c);               \
    void __wrap_vh_##m##_app_##fn(vh_##m##_app_t *a, vh_app_ctx_t *c);               \
    void __wrap_vh_##m##_app_##fn(vh_##m##_app_t *a, vh_app_ctx_t *c)                \
    {                                                                                \
        const uint32_t t0 = vh_systick_now();                                        \
        __real_vh_##m##_app_##fn(a, c);                                              \
        vh_probe_counts[VH_PROBE_APP_##m] += vh_systick_since(t0);                   \
    }
#define VH_APP_TX(m, fn, MSG, period)                                                \
    int __real_vh_##m##_app_##fn(vh_##m##_app_t *a, vh_app_ctx_t *c, uint8_t *d);    \
    int __wrap_vh_##m##_app_##fn(vh_##m##_app_t *a, vh_app_ctx_t *c, uint8_t *d);    \
    int __wrap_vh_##m##_app_##fn(vh_##m##_app_t *a, vh_app_ctx_t *c, uint8_t *d)     \
    {                                                                                \
        const uint32_t t0 = vh_systick_now();                                        \
        const int r = __real_vh_##m##_app_##fn(a, c, d);                             \
        vh_probe_counts[VH_PROBE_APP_##m] += vh_systick_since(t0);                   \
        return r;                                                                    \
    }
#include "vh_ecu_apps.inc"
