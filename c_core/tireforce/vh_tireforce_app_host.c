/* vh_tireforce_app_host.c - the tyre-force application's host side (not flashed): its default
 * configuration and the translation of the double configurations into the fixed-point constants
 * the flashed init takes (the "calibration tool"). */
#include <math.h>
#include <string.h>

#include "vh_skfq_host.h"
#include "vh_tfa_host.h"
#include "vh_tireforce_app.h"

void vh_tf_app_config_default(vh_tf_app_config_t *cfg)
{
    memset(cfg, 0, sizeof *cfg);
    vh_skf_config_default(&cfg->skf, VH_SKF_SKFMEC);
    vh_tfa_config_default(&cfg->tfa);
}

int vh_tf_app_config_host(vh_tf_app_config_t *cfg)
{
    /* the SKFMEC steps once per tick on the 500 us CHS_Sensors samples */
    if (fabs(cfg->skf.ts - VH_TICK_US * 1e-6) > 1e-12 || vh_skfq_params_from_config(&cfg->skf, &cfg->skfq) != VH_OK ||
        vh_tfa_params_from_config(&cfg->skf, &cfg->tfa, &cfg->tfaq) != VH_OK) {
        return VH_EINVAL;
    }
    return VH_OK;
}
