/* vh_ecu_host.c - the ECU's host-side entry: its default configuration and vh_ecu_init, which
 * translates the double tyre-force configuration into the fixed-point filter's constants (the
 * "calibration tool") before the flashed vh_ecu_init_params. Not flashed (firmware-size skips it). */
#include <math.h>
#include <string.h>

#include "vh_ecu.h"
#include "vh_skfq_host.h"
#include "vh_tfa_host.h"

void vh_ecu_config_default(vh_ecu_config_t *cfg)
{
    memset(cfg, 0, sizeof *cfg);
    vh_dkf_config_default(&cfg->dkf[VH_ECU_DKF_T], VH_DKF_SPEEDS_TORQUE);
    vh_dkf_config_default(&cfg->dkf[VH_ECU_DKF_S], VH_DKF_SPEEDS);
    /* w_o = R_i w_t; 2nd gear = 0.43 (Table 1), the others a typical 5-speed transaxle */
    cfg->gear_ratio[1] = 0.28;
    cfg->gear_ratio[2] = 0.43;
    cfg->gear_ratio[3] = 0.66;
    cfg->gear_ratio[4] = 0.91;
    cfg->gear_ratio[5] = 1.18;
    cfg->we_min = 40.0; /* well below idle (~80 rad/s): an engine this slow is stalling */
    vh_camber_config_default(&cfg->camber);
    cfg->camber_still_ww = 0.5; /* 0.15 m/s at the wheel: parked, not rolling */
    cfg->rx_burst_frames = VH_ECU_BURST_FRAMES;
    vh_skf_config_default(&cfg->skf, VH_SKF_SKFMEC);
    vh_roll_app_config_default(&cfg->roll);
    vh_tfa_config_default(&cfg->tfa);
}

int vh_ecu_init(vh_ecu_t *ecu, const vh_ecu_config_t *cfg)
{
    vh_skfq_params_t prm;
    vh_tfa_params_t tprm;
    /* the SKFMEC steps once per tick on the 500 us CHS_Sensors samples */
    if (fabs(cfg->skf.ts - VH_TICK_US * 1e-6) > 1e-12 || vh_skfq_params_from_config(&cfg->skf, &prm) != VH_OK ||
        vh_tfa_params_from_config(&cfg->skf, &cfg->tfa, &tprm) != VH_OK) {
        return VH_EINVAL;
    }
    return vh_ecu_init_params(ecu, cfg, &prm, &tprm);
}
