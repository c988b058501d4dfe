/* vh_skfq_host.c - the fixed-point SKFMEC's constants and inputs from doubles, see vh_skfq_host.h.
 *
 * Host side only (the "calibration tool"): not part of the flashed firmware (firmware-size skips
 * *_host.c); on a target the vh_skfq_params_t block would be a calibration constant.
 */
#include <math.h>
#include <string.h>

#include "vh_skfq_host.h"

#define NX VH_SKF_NX

vh_fix_k_t vh_skfq_kconst(double v, int *ok)
{
    vh_fix_k_t k = {0, 0};
    int ex;
    double fr, mm;
    if (!isfinite(v)) {
        *ok = 0;
        return k;
    }
    if (v == 0.0) {
        return k;
    }
    fr = frexp(v, &ex); /* v = fr 2^ex, |fr| in [0.5, 1) */
    mm = floor(ldexp(fr, 31) + 0.5);
    k.e = 31 - ex;
    if (fabs(mm) >= 2147483648.0) { /* rounded up to 2^31: one bit less */
        mm = floor(ldexp(fr, 30) + 0.5);
        k.e -= 1;
    }
    if (k.e <= -31 || k.e >= 120) {
        *ok = 0;
    }
    k.m = (int32_t)mm;
    return k;
}

int32_t vh_skfq_qconst(double v, int frac, int *ok)
{
    const double r = floor(ldexp(v, frac) + 0.5);
    if (!isfinite(r) || r > 2147483647.0 || r < -2147483648.0) {
        *ok = 0;
        return 0;
    }
    return (int32_t)r;
}

/* The fraction n/d with the smallest d whose double is exactly v (> 0): the continued-fraction
 * convergents of v, so 0.1 -> 1/10, 1e-3 -> 1/1000. None with n <= 2^30, d <= 2^20: *ok = 0. */
static void exact_fraction(double v, int32_t *num, int32_t *den, int *ok)
{
    double n0 = 0.0, d0 = 1.0, n1 = 1.0, d1 = 0.0, rest = v; /* the last two convergents n/d */
    int it;
    *num = 0;
    *den = 1;
    for (it = 0; it < 64 && isfinite(rest) && v > 0.0; ++it) {
        const double a = floor(rest), n = a * n1 + n0, d = a * d1 + d0;
        if (n > 1073741824.0 || d > 1048576.0) {
            break;
        }
        n0 = n1;
        d0 = d1;
        n1 = n;
        d1 = d;
        if (n1 > 0.0 && n1 / d1 == v) {
            *num = (int32_t)n1;
            *den = (int32_t)d1;
            return;
        }
        rest = 1.0 / (rest - a);
    }
    *ok = 0;
}

int vh_skfq_params_from_config(const vh_skf_config_t *c, vh_skfq_params_t *k)
{
    const double l = c->lf + c->lr, mse = c->ms * c->e, ixx = c->ix + c->ms * c->e * c->e;
    const double det = c->m * ixx - mse * mse, ts = c->ts;
    const double kf = c->kphif / (c->kphif + c->kphir), kr = c->kphir / (c->kphif + c->kphir);
    const double *s = c->s;
    const double fzs[2] = {c->m * c->g * c->lr / (2.0 * l), c->m * c->g * c->lf / (2.0 * l)};
    const double tt[2] = {c->tf, c->tr}, kk[2] = {kf, kr}, zeta[2] = {c->zeta1, c->zeta2};
    vh_skfq_params_t z;
    int ok = 1, i;
    if (!vh_skf_config_check(c)) {
        return VH_EINVAL;
    }
    memset(&z, 0, sizeof z);
    z.c_vx0 = vh_skfq_kconst(ts * s[VH_SKF_VX] / c->m, &ok);
    z.c_vy1 = vh_skfq_kconst(ts * s[VH_SKF_VY] * ixx / det, &ok);
    z.c_vy4 = vh_skfq_kconst(ts * s[VH_SKF_VY] * mse / det, &ok);
    z.c_r2 = vh_skfq_kconst(ts * s[VH_SKF_R] / c->iz, &ok);
    z.c_p1 = vh_skfq_kconst(ts * s[VH_SKF_P] * mse / det, &ok);
    z.c_p4 = vh_skfq_kconst(ts * s[VH_SKF_P] * c->m / det, &ok);
    z.c_phi_p = vh_skfq_kconst(ts * s[VH_SKF_PHI] / s[VH_SKF_P], &ok);
    z.phi_row[0] = vh_skfq_qconst(ts * s[VH_SKF_PHI] / s[VH_SKF_P], VH_SKFQ_FPHI, &ok);
    for (i = 0; i < 2; ++i) {
        const double v = ts * s[VH_SKF_FYF + i] * zeta[i] / s[VH_SKF_P];
        z.c_fy_p[i] = vh_skfq_kconst(v, &ok);
        z.phi_row[1 + i] = vh_skfq_qconst(v, VH_SKFQ_FPHI, &ok);
        z.fz0[i] = vh_skfq_qconst(fzs[i], VH_SKFQ_FN, &ok);
        z.k_lat_ay[i] = vh_skfq_kconst(c->lt_gain * kk[i] * c->m * c->h / (4.0 * tt[i]), &ok);
        z.k_lat_phi[i] = vh_skfq_kconst(c->lt_gain * kk[i] * c->g * c->ms * c->e / (4.0 * tt[i]), &ok);
        z.k_gy[i] = vh_skfq_kconst(c->mec ? c->gy[i] : 0.0, &ok);
        z.k_inv_fz[i] = vh_skfq_kconst(1.0 / fzs[i], &ok);
        z.k_drho[i] = vh_skfq_kconst(c->lt_gain * kk[i] * c->g * c->ms * c->e / (4.0 * tt[i]) / (fzs[i] * s[VH_SKF_PHI]),
                                     &ok);
        z.k_inv_sf[i] = vh_skfq_kconst(1.0 / s[VH_SKF_FYF + i], &ok);
    }
    z.k_m_rvy = vh_skfq_kconst(c->m / (s[VH_SKF_R] * s[VH_SKF_VY]), &ok);
    z.k_m_rvx = vh_skfq_kconst(c->m / (s[VH_SKF_R] * s[VH_SKF_VX]), &ok);
    z.k_mse_pr = vh_skfq_kconst(mse / (s[VH_SKF_P] * s[VH_SKF_R]), &ok);
    z.k_mse_rvx = vh_skfq_kconst(mse / (s[VH_SKF_R] * s[VH_SKF_VX]), &ok);
    z.k_kphi = vh_skfq_kconst((c->kphif + c->kphir) / s[VH_SKF_PHI], &ok);
    z.k_cphi = vh_skfq_kconst((c->cphif + c->cphir) / s[VH_SKF_P], &ok);
    z.k_lf = vh_skfq_kconst(c->lf, &ok);
    z.k_lr = vh_skfq_kconst(c->lr, &ok);
    z.k_tf = vh_skfq_kconst(c->tf, &ok);
    z.k_tr = vh_skfq_kconst(c->tr, &ok);
    z.k_hf = vh_skfq_kconst(c->hf, &ok);
    z.k_hr = vh_skfq_kconst(c->hr, &ok);
    z.k_fz_ax = vh_skfq_kconst(c->m * c->h / (2.0 * l), &ok);
    z.k_phi = vh_skfq_kconst(1.0 / s[VH_SKF_PHI], &ok);
    z.k_inv_ts = vh_skfq_kconst(1.0 / ts, &ok);
    z.k_alpha = vh_skfq_kconst(ts / (c->tau_wdot + ts), &ok);
    z.k_inv_rw = vh_skfq_kconst(1.0 / c->rw, &ok);
    z.k_iw_rw = vh_skfq_kconst(c->iw / c->rw, &ok);
    z.k_sr = vh_skfq_kconst(s[VH_SKF_R], &ok);
    z.k_sp = vh_skfq_kconst(s[VH_SKF_P], &ok);
    z.k_inv_m = vh_skfq_kconst(1.0 / c->m, &ok);
    z.k_mse_pr_m = vh_skfq_kconst(mse / (c->m * s[VH_SKF_P] * s[VH_SKF_R]), &ok);
    z.k_ixx_det = vh_skfq_kconst(ixx / det, &ok);
    z.k_mse_det = vh_skfq_kconst(mse / det, &ok);
    for (i = 0; i < NX; ++i) {
        z.k_gp[i] = vh_skfq_kconst(c->mec ? ts * c->gp[i] / s[VH_SKF_R] : 0.0, &ok);
        z.q[i] = vh_skfq_qconst(c->q[i], VH_SKFQ_FP, &ok);
        z.p0[i] = vh_skfq_qconst(c->p0[i], VH_SKFQ_FP, &ok);
    }
    z.r[VH_SKF_AX] = vh_skfq_qconst(c->r[VH_SKF_AX], VH_SKFQ_FU, &ok); /* R* = T^2 R */
    z.r[VH_SKF_AY] = vh_skfq_qconst(c->r[VH_SKF_AY], VH_SKFQ_FU, &ok);
    z.r[VH_SKF_YR] = vh_skfq_qconst(c->r[VH_SKF_YR] * s[VH_SKF_R] * s[VH_SKF_R], VH_SKFQ_FU, &ok);
    z.r[VH_SKF_YP] = vh_skfq_qconst(c->r[VH_SKF_YP] * s[VH_SKF_P] * s[VH_SKF_P], VH_SKFQ_FU, &ok);
    z.p_cap = vh_skfq_qconst(c->p_cap, VH_SKFQ_FP, &ok);
    z.p_max = vh_skfq_qconst(c->p_max < 30.0 ? c->p_max : 30.0, VH_SKFQ_FP, &ok); /* the format's range */
    z.x_max = vh_skfq_qconst(c->x_max < 1000.0 ? c->x_max : 1000.0, VH_SKFQ_FX, &ok);
    z.mec = c->mec;
    z.k_seed_vx = vh_skfq_kconst(s[VH_SKF_VX] * c->rw / 4.0, &ok);
    z.k_seed_fy[0] = vh_skfq_kconst(s[VH_SKF_FYF] * c->m * c->lr / (2.0 * l), &ok);
    z.k_seed_fy[1] = vh_skfq_kconst(s[VH_SKF_FYR] * c->m * c->lf / (2.0 * l), &ok);
    z.k_seed_phi = vh_skfq_kconst(s[VH_SKF_PHI] * c->m * c->lr / (2.0 * l * c->zeta1), &ok);
    for (i = 0; i < NX; ++i) {
        exact_fraction(s[i], &z.s_num[i], &z.s_den[i], &ok);
    }
    if (!ok || !c->scaled) { /* the fixed-point filter only exists scaled */
        return VH_EINVAL;
    }
    *k = z;
    return VH_OK;
}

static int32_t quant(double v, int frac)
{
    const double r = floor(ldexp(v, frac) + 0.5);
    if (!(r < 2147483647.0)) { /* NaN saturates high: the step's validity mask must flag it */
        return INT32_MAX;
    }
    return r < -2147483648.0 ? INT32_MIN : (int32_t)r;
}

void vh_skfq_quantise_inputs(size_t n, const double *u, int32_t *q)
{
    static const int frac[VH_SKF_NU] = {VH_SKFQ_FA, VH_SKFQ_FA, VH_SKFQ_FW, VH_SKFQ_FW, VH_SKFQ_FD,
                                        VH_SKFQ_FO, VH_SKFQ_FO, VH_SKFQ_FO, VH_SKFQ_FO,
                                        VH_SKFQ_FT, VH_SKFQ_FT, VH_SKFQ_FT, VH_SKFQ_FT};
    size_t t;
    int i;
    for (t = 0; t < n; ++t) {
        for (i = 0; i < VH_SKF_NU; ++i) {
            q[t * VH_SKF_NU + i] = quant(u[t * VH_SKF_NU + i], frac[i]);
        }
    }
}
