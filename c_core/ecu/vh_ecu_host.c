/* vh_ecu_host.c - the ECU's host-side entry: its default configuration and vh_ecu_init, which lets
 * each application complete its configuration (vh_<m>_app_config_host: e.g. the tyre-force
 * filter's fixed-point constants, the "calibration tool") before the flashed vh_ecu_init_params.
 * Not flashed (firmware-size skips it). */
#include <string.h>

#include "vh_ecu.h"

void vh_ecu_config_default(vh_ecu_config_t *cfg)
{
    memset(cfg, 0, sizeof *cfg);
#define DEFAULT(m) vh_##m##_app_config_default(&cfg->app.m);
    VH_ECU_APPS(DEFAULT)
#undef DEFAULT
    cfg->rx_burst_frames = VH_ECU_BURST_FRAMES;
}

int vh_ecu_config_complete(vh_ecu_config_t *cfg)
{
#define HOST(m) || vh_##m##_app_config_host(&cfg->app.m) != VH_OK
    if (0 VH_ECU_APPS(HOST)) {
        return VH_EINVAL;
    }
#undef HOST
    return VH_OK;
}

int vh_ecu_init(vh_ecu_t *ecu, const vh_ecu_config_t *cfg)
{
    vh_ecu_config_t c = *cfg; /* completed here, the caller's left as it is */
    if (vh_ecu_config_complete(&c) != VH_OK) {
        return VH_EINVAL;
    }
    return vh_ecu_init_params(ecu, &c);
}
