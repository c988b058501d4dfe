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

static void restart(vh_dkf_t *f)
{
    memset(f->x, 0, sizeof f->x);
    memset(f->k, 0, sizeof f->k);
    vh_mat_diag(f->p, f->cfg.p0, NX);
    vh_kf_restart(&f->steps, &f->x_init, &f->health);
}

void vh_dkf_reset(vh_dkf_t *f)
{
    restart(f);
    f->resets = 0u;
}

/* Rows of z the measurement set uses and the caller marked valid. */
static int select_rows(const vh_dkf_t *f, unsigned mask, int rows[NZ])
{
    int n = 0, i;
    const unsigned used = (f->cfg.meas == VH_DKF_SPEEDS) ? (VH_DKF_Z_WO | VH_DKF_Z_WW) : VH_DKF_Z_ALL;
    for (i = 0; i < NZ; ++i) {
        if ((mask & used & (1u << i)) != 0u) {
            rows[n++] = i;
        }
    }
    return n;
}

static int sane(const vh_dkf_t *f)
{
    int i;
    if (!vh_mat_finite(f->x, NX) || !vh_mat_finite(f->p, NX * NX)) {
        return 0;
    }
    for (i = 0; i < NX; ++i) {
        const double d = f->p[i * NX + i];
        if (!(d > 0.0) || d > f->cfg.p_max || fabs(f->x[i]) > f->cfg.x_max) {
            return 0;
        }
    }
    return 1;
}

/* First usable sample: start from the measurements instead of zero, so an ECU that boots
 * with the car moving does not spend its first second unlearning x = 0. */
static void seed_state(vh_dkf_t *f, double u, const double z[NZ], unsigned mask)
{
    f->x[0] = (mask & VH_DKF_Z_WO) ? z[0] : 0.0;
    f->x[1] = (mask & VH_DKF_Z_WW) ? z[1] : 0.0;
    if (f->cfg.meas == VH_DKF_SPEEDS_TORQUE && (mask & VH_DKF_Z_TO)) {
        f->x[2] = z[2];
    } else { /* quasi-static eq. 1 with J_o -> 0: T_o = T_i / (R_i R_d) */
        f->x[2] = f->cfg.use_input ? u / (f->cfg.ri * f->cfg.rd) : 0.0;
    }
    f->x[3] = 0.0;
    f->x_init = 1u;
}

int vh_dkf_step(vh_dkf_t *f, double u, const double z[VH_DKF_NZ], unsigned mask)
{
    double xp[NX], pp[NX * NX], tmp[NX * NX];
    double s[NZ * NZ], sinv[NZ], pht[NX * NZ], kt[NZ * NX], ikh[NX * NX];
    int rows[NZ], nz, i, j, l;
    const unsigned needed = VH_DKF_U_VALID |
                            ((f->cfg.meas == VH_DKF_SPEEDS) ? (VH_DKF_Z_WO | VH_DKF_Z_WW) : VH_DKF_Z_ALL);

    if (!isfinite(u)) {
        u = 0.0;
        mask &= ~(unsigned)VH_DKF_U_VALID;
    }
    if (!f->cfg.use_input) {
        u = 0.0;
    }
    nz = (mask & VH_DKF_STALE) ? 0 : select_rows(f, mask, rows);
    if (!f->x_init) {
        if (mask & VH_DKF_STALE) {
            return 0;
        }
        if ((mask & (VH_DKF_Z_WO | VH_DKF_Z_WW)) != (VH_DKF_Z_WO | VH_DKF_Z_WW)) {
            return 0; /* wait for both speeds before starting */
        }
        seed_state(f, u, z, mask);
    }

    /* predict: x- = A x + B u (eq. 10), P- = A P A^T + Q (eq. 15) */
    vh_mat_mul(f->ad, f->x, xp, NX, NX, 1);
    for (i = 0; i < NX; ++i) {
        xp[i] += f->bd[i] * u;
    }
    vh_mat_mul(f->ad, f->p, tmp, NX, NX, NX);
    vh_mat_mul_bt(tmp, f->ad, pp, NX, NX, NX);
    for (i = 0; i < NX; ++i) {
        pp[i * NX + i] += f->cfg.q[i];
    }

    memset(f->k, 0, sizeof f->k);
    memset(f->innov, 0, sizeof f->innov);
    if (nz > 0) {
        for (j = 0; j < nz; ++j) {
            f->innov[rows[j]] = z[rows[j]] - xp[rows[j]]; /* z - H x-: measured in the A2L */
        }
        /* H selects rows, so P- H^T is columns of P- and H P- H^T a sub-block */
        for (i = 0; i < NX; ++i) {
            for (j = 0; j < nz; ++j) {
                pht[i * nz + j] = pp[i * NX + rows[j]];
            }
        }
        for (i = 0; i < nz; ++i) {
            for (j = 0; j < nz; ++j) {
                s[i * nz + j] = pp[rows[i] * NX + rows[j]];
            }
            s[i * nz + i] += f->cfg.r[rows[i]];
        }
        /* K = P- H^T (H P- H^T + R)^-1 (eq. 13), as S K^T = H P- via Cholesky */
        if (vh_mat_chol(s, sinv, nz) != 0) {
            goto diverged;
        }
        for (i = 0; i < nz; ++i) {
            for (j = 0; j < NX; ++j) {
                kt[i * NX + j] = pht[j * nz + i];
            }
        }
        vh_mat_chol_solve(s, sinv, kt, nz, NX);
        for (i = 0; i < NX; ++i) {
            double innov_gain = 0.0;
            for (j = 0; j < nz; ++j) {
                const double kij = kt[j * NX + i];
                f->k[i * NZ + rows[j]] = kij;
                innov_gain += kij * f->innov[rows[j]];
            }
            f->x[i] = xp[i] + innov_gain;
        }
        /* P = (I - KH) P- (I - KH)^T + K R K^T: Joseph form of eq. 14, symmetric PD by construction */
        vh_mat_identity(ikh, NX);
        for (i = 0; i < NX; ++i) {
            for (j = 0; j < nz; ++j) {
                ikh[i * NX + rows[j]] -= kt[j * NX + i];
            }
        }
        vh_mat_mul(ikh, pp, tmp, NX, NX, NX);
        vh_mat_mul_bt(tmp, ikh, f->p, NX, NX, NX);
        for (l = 0; l < nz; ++l) { /* + K R K^T, R diagonal: one outer product per row */
            const double *kl = kt + l * NX;
            const double rl = f->cfg.r[rows[l]];
            for (i = 0; i < NX; ++i) {
                const double rki = rl * kl[i];
                for (j = 0; j < NX; ++j) {
                    f->p[i * NX + j] += rki * kl[j];
                }
            }
        }
        vh_mat_symmetrise(f->p, NX);
    } else { /* no measurement this step: prediction only */
        memcpy(f->x, xp, sizeof xp);
        memcpy(f->p, pp, sizeof pp);
    }

    if (!sane(f)) {
        goto diverged;
    }
    f->health = vh_kf_step_health(&f->steps, (mask & needed) != needed,
                                  2u * (f->cfg.meas == VH_DKF_SPEEDS ? 1000u : 20u));
    return 0;

diverged:
    restart(f);
    return vh_kf_fault(&f->resets, &f->health);
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

uint32_t vh_dkf_run(vh_dkf_t *f, size_t n, const double *u, const double *z, const uint8_t *mask,
                    double *x_out, double *k_out, double *p_out)
{
    size_t t;
    uint32_t resets = 0u;
    for (t = 0; t < n; ++t) {
        resets += (uint32_t)vh_dkf_step(f, u[t], z + t * NZ, mask ? mask[t] : VH_DKF_ALL_VALID);
        memcpy(x_out + t * NX, f->x, sizeof f->x);
        if (k_out) {
            memcpy(k_out + t * NX * NZ, f->k, sizeof f->k);
        }
        if (p_out) {
            memcpy(p_out + t * NX * NX, f->p, sizeof f->p);
        }
    }
    return resets;
}

int vh_dkf_turbine_torque(double we, double wt, double we_min, double *ti)
{
    double tp;
    if (!isfinite(we) || !isfinite(wt) || !(we >= we_min) || !(we > 0.0) || !(wt >= 0.0) || wt > 2.0 * we) {
        return -1;
    }
    vh_tc_torques(we, wt, &tp, ti); /* eq. 9 in the drive range, see vh_tc.h */
    return 0;
}
