/* vh_dkf.c - driveline output-torque Kalman filter (seed 001), see vh_dkf.h. */
#include <math.h>
#include <string.h>

#include "vh_dkf.h"
#include "vh_kf.h"
#include "vh_mat.h"
#include "vh_tc.h"

#define NX VH_DKF_NX
#define NZ VH_DKF_NZ


double vh_dkf_road_load_coeff(double rt, double rho_a, double ca, double area, double wwo)
{
    return rt * rho_a * ca * area * wwo; /* eq. 4 */
}

void vh_dkf_config_default(vh_dkf_config_t *cfg, int meas)
{
    memset(cfg, 0, sizeof *cfg);
    /* Table 1 */
    cfg->jo = 0.016; cfg->jv = 160.0; cfg->rd = 0.255; cfg->ri = 0.43; cfg->ks = 9000.0;
    cfg->c = vh_dkf_road_load_coeff(0.3, 0.123, 0.33, 2.0, 80.0); /* rho_a as printed */
    cfg->ts = 0.0005; cfg->meas = meas; cfg->disc = VH_DKF_ZOH; cfg->use_input = 1;
    if (meas == VH_DKF_SPEEDS) { /* sec. 4, speeds only */
        cfg->q[0] = 1e4; cfg->q[1] = 1000.0; cfg->q[2] = 1.0; cfg->q[3] = 2e4;
        cfg->r[0] = 500.0; cfg->r[1] = 50.0; cfg->r[2] = 1e5;
    } else { /* sec. 4, speeds + torque transducer */
        cfg->q[0] = 1e4; cfg->q[1] = 1000.0; cfg->q[2] = 1.0; cfg->q[3] = 1e4;
        cfg->r[0] = 415.0; cfg->r[1] = 27.0; cfg->r[2] = 22500.0;
    }
    /* P0 = Q: the filter starts as uncertain as one step of process noise. */
    cfg->p0[0] = cfg->q[0]; cfg->p0[1] = cfg->q[1]; cfg->p0[2] = cfg->q[2]; cfg->p0[3] = cfg->q[3];
    cfg->p_max = 1e12;
    cfg->x_max = 1e6;
}

void vh_dkf_model(const vh_dkf_config_t *cfg, double a[16], double b[4])
{
    /* eq. 8 with eq. 1, 5 (J_v, not the misprinted J_o), 6, 7 */
    memset(a, 0, 16 * sizeof a[0]);
    a[0 * 4 + 2] = -cfg->rd / cfg->jo;
    a[1 * 4 + 1] = -cfg->c / cfg->jv;
    a[1 * 4 + 2] = 1.0 / cfg->jv;
    a[1 * 4 + 3] = -1.0 / cfg->jv;
    a[2 * 4 + 0] = cfg->ks * cfg->rd;
    a[2 * 4 + 1] = -cfg->ks;
    b[0] = 1.0 / (cfg->jo * cfg->ri);
    b[1] = 0.0;
    b[2] = 0.0;
    b[3] = 0.0;
}

void vh_dkf_discretise(const double a[16], const double b[4], double ts, int disc, double ad[16], double bd[4])
{
    int i, j;
    if (disc == VH_DKF_EULER) { /* eq. 10: A_a = I + Ts A, B_a = Ts B */
        for (i = 0; i < 16; ++i) {
            ad[i] = ts * a[i];
        }
        for (i = 0; i < 4; ++i) {
            ad[i * 4 + i] += 1.0;
            bd[i] = ts * b[i];
        }
    } else { /* exact ZOH: expm([[A, B], [0, 0]] Ts) = [[Ad, Bd], [0, 1]] */
        double m[25], e[25];
        memset(m, 0, sizeof m);
        for (i = 0; i < 4; ++i) {
            for (j = 0; j < 4; ++j) {
                m[i * 5 + j] = a[i * 4 + j] * ts;
            }
            m[i * 5 + 4] = b[i] * ts;
        }
        vh_mat_expm(m, e, 5);
        for (i = 0; i < 4; ++i) {
            for (j = 0; j < 4; ++j) {
                ad[i * 4 + j] = e[i * 5 + j];
            }
            bd[i] = e[i * 5 + 4];
        }
    }
}

static int config_ok(const vh_dkf_config_t *c)
{
    int i;
    const double pos[] = {c->jo, c->jv, c->rd, c->ri, c->ks, c->ts, c->p_max, c->x_max};
    for (i = 0; i < (int)(sizeof pos / sizeof pos[0]); ++i) {
        if (!(pos[i] > 0.0) || !isfinite(pos[i])) {
            return 0;
        }
    }
    if (!(c->c >= 0.0) || !isfinite(c->c) || c->ts > 0.1) {
        return 0;
    }
    for (i = 0; i < NX; ++i) {
        if (!(c->q[i] >= 0.0) || !isfinite(c->q[i]) || !(c->p0[i] > 0.0) || !isfinite(c->p0[i])) {
            return 0;
        }
    }
    for (i = 0; i < NZ; ++i) {
        if (!(c->r[i] > 0.0) || !isfinite(c->r[i])) {
            return 0;
        }
    }
    return (c->meas == VH_DKF_SPEEDS_TORQUE || c->meas == VH_DKF_SPEEDS) &&
           (c->disc == VH_DKF_EULER || c->disc == VH_DKF_ZOH);
}

int vh_dkf_init(vh_dkf_t *f, const vh_dkf_config_t *cfg)
{
    double a[16], b[4];
    if (!config_ok(cfg)) {
        return VH_EINVAL;
    }
    memset(f, 0, sizeof *f);
    f->cfg = *cfg;
    vh_dkf_model(cfg, a, b);
    vh_dkf_discretise(a, b, cfg->ts, cfg->disc, f->ad, f->bd);
    vh_dkf_reset(f);
    return VH_OK;
}

int vh_dkf_set_ratio(vh_dkf_t *f, double ri)
{
    double a[16], b[4];
    if (!(ri > 0.0) || !isfinite(ri)) {
        return VH_EINVAL;
    }
    f->cfg.ri = ri;
    vh_dkf_model(&f->cfg, a, b);
    vh_dkf_discretise(a, b, f->cfg.ts, f->cfg.disc, f->ad, f->bd);
    return VH_OK;
}

int vh_dkf_gear_model(const vh_dkf_config_t *cfg, double ri, vh_dkf_gear_model_t *m)
{
    vh_dkf_config_t c = *cfg;
    double a[16], b[4];
    if (!(ri > 0.0) || !isfinite(ri)) {
        return VH_EINVAL;
    }
    c.ri = ri;
    vh_dkf_model(&c, a, b);
    vh_dkf_discretise(a, b, c.ts, c.disc, m->ad, m->bd);
    m->ri = ri;
    return VH_OK;
}

void vh_dkf_use_gear_model(vh_dkf_t *f, const vh_dkf_gear_model_t *m)
{
    f->cfg.ri = m->ri;
    memcpy(f->ad, m->ad, sizeof f->ad);
    memcpy(f->bd, m->bd, sizeof f->bd);
}

#undef NX
#undef NZ
#define VH_DKF_SELF vh_dkf_t
#define VH_DKF_REAL double
#define VH_DKF_FN(n) vh_dkf_##n
#define VH_DKF_MAT(n) vh_mat_##n
#define VH_DKF_FABS fabs
#include "vh_dkf_step.inc"

int vh_dkf_turbine_torque(double we, double wt, double we_min, double *ti)
{
    double tp;
    if (!isfinite(we) || !isfinite(wt) || !(we >= we_min) || !(we > 0.0) || !(wt >= 0.0) || wt > 2.0 * we) {
        return -1;
    }
    vh_tc_torques(we, wt, &tp, ti); /* eq. 9 in the drive range, see vh_tc.h */
    return 0;
}
