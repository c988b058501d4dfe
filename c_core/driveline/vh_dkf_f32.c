/* vh_dkf_f32.c - the driveline filter in float32, the ECU's build (see vh_dkf.h). The step is
 * vh_dkf_step.inc, the same source as the double build in vh_dkf.c. */
#include <math.h>
#include <string.h>

#include "vh_dkf.h"
#include "vh_kf.h"

/* single precision only in the step: a double here would be libgcc's software routines on the M4F */
#pragma GCC diagnostic error "-Wdouble-promotion"

#define VH_MAT_REAL float
#define VH_MAT_FN(n) vh_matf_##n
#define VH_MAT_SQRT sqrtf
#include "vh_mat_ops.inc"

static void round_into(float *dst, const double *src, int n)
{
    int i;
    for (i = 0; i < n; ++i) {
        dst[i] = (float)src[i];
    }
}

void vh_dkf_f32_tune(vh_dkf_f32_t *f, const vh_dkf_config_t *cfg)
{
    round_into(f->cfg.q, cfg->q, VH_DKF_NX);
    round_into(f->cfg.r, cfg->r, VH_DKF_NZ);
    round_into(f->cfg.p0, cfg->p0, VH_DKF_NX);
    f->cfg.p_max = (float)cfg->p_max;
    f->cfg.x_max = (float)cfg->x_max;
}

int vh_dkf_f32_init(vh_dkf_f32_t *f, const vh_dkf_config_t *cfg)
{
    vh_dkf_t d; /* the checks and the model of the double build (init only) */
    if (vh_dkf_init(&d, cfg) != VH_OK) {
        return VH_EINVAL;
    }
    memset(f, 0, sizeof *f);
    vh_dkf_f32_tune(f, cfg);
    f->cfg.ri = (float)cfg->ri;
    f->cfg.rd = (float)cfg->rd;
    f->cfg.meas = cfg->meas;
    f->cfg.use_input = cfg->use_input;
    round_into(f->ad, d.ad, VH_DKF_NX * VH_DKF_NX);
    round_into(f->bd, d.bd, VH_DKF_NX);
    vh_dkf_f32_reset(f);
    return VH_OK;
}

void vh_dkf_f32_use_gear_model(vh_dkf_f32_t *f, const vh_dkf_gear_model_t *m)
{
    f->cfg.ri = (float)m->ri;
    round_into(f->ad, m->ad, VH_DKF_NX * VH_DKF_NX);
    round_into(f->bd, m->bd, VH_DKF_NX);
}

#define VH_DKF_SELF vh_dkf_f32_t
#define VH_DKF_REAL float
#define VH_DKF_FN(n) vh_dkf_f32_##n
#define VH_DKF_MAT(n) vh_matf_##n
#define VH_DKF_FABS fabsf
#include "vh_dkf_step.inc"
