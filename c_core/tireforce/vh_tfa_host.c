/* vh_tfa_host.c - SKFMEC-A's constants from doubles, see vh_tfa_host.h. Host side only. */
#include <math.h>
#include <string.h>

#include "vh_tfa_host.h"

void vh_tfa_config_default(vh_tfa_config_t *c)
{
    /* Bakker, Nyborg & Pacejka 1987 passenger-car tyre (Wong's table), as the plant's */
    static const double a[9] = {1.30, -22.1, 1011.0, 1078.0, 1.82, 0.208, 0.0, -0.354, 0.707};
    memset(c, 0, sizeof *c);
    c->cda = 0.73;
    c->rho = 1.2;
    c->tau_lp = 0.2;
    c->decim = 20;
    c->ax_gate = 0.3;
    c->ay_gate = 6.0;
    c->vx_gate = 5.0;
    c->forget = 0.999;
    c->sigma_y = 60.0;
    c->mass_sigma0 = 0.2;
    c->mass_sigma_floor = 0.005;
    c->mass_sigma_ok = 0.02;
    c->mass_lo = 0.7;
    c->mass_hi = 1.6;
    memcpy(c->tyre_a, a, sizeof a);
    c->tyre_fz_scale = 1.75;
    c->mu = 1.0;
}

double vh_tfa_lateral_force(const vh_tfa_config_t *c, double alpha_deg, double fz)
{
    const double *a = c->tyre_a, sc = c->tyre_fz_scale;
    const double f = (fz > 1.0 ? fz : 1.0) * 1e-3 / sc;
    const double d = (a[1] * f * f + a[2] * f) * c->mu / (a[2] * 1e-3);
    const double b = a[3] * sin(a[4] * atan(a[5] * f)) / (a[0] * d);
    const double e = a[6] * f * f + a[7] * f + a[8], bx = b * alpha_deg;
    return sc * d * sin(a[0] * atan(bx - e * (bx - atan(bx))));
}

/* m 2^-e with |m| in [2^30, 2^31), rounded half up (as vh_skfq_host.c) */
static vh_fix_k_t kconst(double v, int *ok)
{
    vh_fix_k_t k = {0, 0};
    int ex;
    double mm;
    if (!isfinite(v) || v == 0.0) {
        *ok = *ok && isfinite(v);
        return k;
    }
    mm = floor(ldexp(frexp(v, &ex), 31) + 0.5);
    k.e = 31 - ex;
    if (fabs(mm) >= 2147483648.0) {
        mm = floor(ldexp(frexp(v, &ex), 30) + 0.5);
        k.e -= 1;
    }
    k.m = (int32_t)mm;
    return k;
}

static int32_t q(double v, int frac, int *ok)
{
    const double r = floor(ldexp(v, frac) + 0.5);
    if (!isfinite(r) || r > 2147483647.0 || r < -2147483648.0) {
        *ok = 0;
        return 0;
    }
    return (int32_t)r;
}

int vh_tfa_params_from_config(const vh_skf_config_t *skf, const vh_tfa_config_t *c, vh_tfa_params_t *p)
{
    vh_tfa_params_t z;
    int ok = 1, i, j;
    const double s_vx = skf->s[VH_SKF_VX];
    if (!(c->tau_lp > 0.0 && c->decim >= 1 && c->forget > 0.0 && c->forget <= 1.0 && c->sigma_y > 0.0 &&
          c->mass_sigma0 >= c->mass_sigma_floor && c->mass_sigma_floor > 0.0 && c->mass_sigma_ok > 0.0 &&
          c->mass_lo > 0.0 && c->mass_hi > c->mass_lo && c->mass_hi < 4.0 && c->mu > 0.0 && c->tyre_fz_scale > 0.0 &&
          skf->m > 0.0 && skf->ts > 0.0 && s_vx > 0.0)) {
        return VH_EINVAL;
    }
    memset(&z, 0, sizeof z);
    for (i = 1; i < VH_TFA_NZ; ++i) { /* row 0 (no load) stays 0 */
        for (j = 0; j < VH_TFA_NA; ++j) {
            z.table[i * VH_TFA_NA + j] = q(vh_tfa_lateral_force(c, 0.25 * j, 500.0 * i), VH_SKFQ_FN, &ok);
        }
    }
    z.k_inv_fz_step = kconst(1.0 / 500.0, &ok);
    z.k_phi = kconst(skf->m / c->sigma_y, &ok);
    z.k_y = kconst(1.0 / c->sigma_y, &ok);
    z.k_drag = kconst(0.5 * c->rho * c->cda / (s_vx * s_vx), &ok);
    z.alpha_lp = q(skf->ts / (c->tau_lp + skf->ts), 30, &ok);
    z.ax_gate = q(c->ax_gate, VH_SKFQ_FA, &ok);
    z.ay_gate = q(c->ay_gate, VH_SKFQ_FA, &ok);
    z.vx_gate = q(c->vx_gate * s_vx, VH_SKFQ_FX, &ok);
    z.valid_min = (uint32_t)floor(5.0 * c->tau_lp / skf->ts + 0.5);
    z.decim = (uint32_t)c->decim;
    z.inv_forget = q(1.0 / c->forget, 30, &ok);
    z.p0 = q(c->mass_sigma0 * c->mass_sigma0, VH_TFA_FP, &ok);
    z.p_floor = q(c->mass_sigma_floor * c->mass_sigma_floor, VH_TFA_FP, &ok);
    z.p_ok = q(c->mass_sigma_ok * c->mass_sigma_ok, VH_TFA_FP, &ok);
    z.k_lo = q(c->mass_lo, VH_TFA_FK, &ok);
    z.k_hi = q(c->mass_hi, VH_TFA_FK, &ok);
    z.m_num = 0;
    z.m_den = 0;
    {   /* the model mass as an exact fraction m_num / m_den (the TX of the mass estimate, integer only) */
        int32_t d;
        for (d = 1; d <= 1000000; d *= 10) {
            const double n = skf->m * d;
            if (n == floor(n) && n <= 2147483647.0) {
                z.m_num = (int32_t)n;
                z.m_den = d;
                break;
            }
        }
        ok = ok && z.m_num > 0;
    }
    if (!ok) {
        return VH_EINVAL;
    }
    *p = z;
    return VH_OK;
}
