/* vh_tfa_host.c - SKFMEC-A's constants from doubles, see vh_tfa_host.h. Host side only. */
#include <math.h>
#include <string.h>

#include "vh_skfq_host.h"
#include "vh_tfa_host.h"

void vh_tfa_config_default(vh_tfa_config_t *c)
{
    /* Bakker, Nyborg & Pacejka 1987 passenger-car tyre (Wong's table), as the plant's */
    static const double a[9] = {1.30, -22.1, 1011.0, 1078.0, 1.82, 0.208, 0.0, -0.354, 0.707};
    static const double b[9] = {1.65, -21.3, 1144.0, 49.6, 226.0, 0.069, -0.006, 0.056, 0.486};
    memset(c, 0, sizeof *c);
    c->cda = 0.73; c->rho = 1.2;
    c->tau_lp = 0.2; c->decim = 20;
    c->ax_gate = 0.3; c->ay_gate = 6.0; c->vx_gate = 5.0;
    c->forget = 0.999; c->sigma_y = 60.0;
    c->mass_sigma0 = 0.2; c->mass_sigma_floor = 0.005; c->mass_sigma_ok = 0.02;
    c->mass_lo = 0.7; c->mass_hi = 1.6;
    memcpy(c->tyre_a, a, sizeof a);
    c->tyre_fz_scale = 1.75;
    c->mu = 1.0;
    memcpy(c->tyre_b, b, sizeof b);
    c->tau_slip = 0.25; c->fx_gate = 200.0; c->q_gate = 0.85;
    c->tau_mu = 0.25; c->tau_mu_forget = 3.0; c->mu_floor = 0.1; c->ellipse_floor = 0.2;
    c->friction = 1; c->combined = 1;
    c->ride = 1; c->spring_front = 30000.0; c->spring_rear = 25000.0; c->sigma_ride = 0.01;
    c->road = 1; c->tau_kin = 0.05; c->ay_kin_gate = 1.0; c->fx_free = 400.0;
    c->kin_q = 0.02; c->kin_r_deg = 0.1; c->kin_sigma0 = 0.2; c->kin_dmu = 0.05; c->kin_dh_max = 30.0; c->kin_nis_gate = 9.0;
    c->kin_side_min = 0.95;
    c->transfer = 1; c->tyre_kz = 250000.0;
    c->tau_vyd = 0.1; c->vyd_gate = 4.0; c->hold_implausible = 0.5;
    {   /* CommonRoad's PAC2002 set (vehicles 1-3), used where tyre_model is 1 */
        static const double pac[8] = {1.3507, 1.0489, -0.0074722, 21.92, 1.6411, 1.1739, 0.46403, 22.303};
        memcpy(c->tyre_p, pac, sizeof pac);
    }
    c->vx_tol = 1.0; c->vx_tol_rel = 0.1;
    c->bal_tol = 1000.0; c->bal_tol_rel = 0.25;
    /* the bound's model terms, chosen on the design runs (docs/tireforce.md, "Per-tyre bound") */
    c->bound_z = 1.96;
    c->bound_axle_abs = 150.0; c->bound_axle_rel = 0.08;
    c->bound_lt_abs = 200.0; c->bound_lt_rel = 0.1;
    c->bound_max = 2000.0;
}

/* A PAC2002 pure-slip curve with load-proportional slip stiffness (adaptive._pac): D = mu Fz,
 * B = k Fz / (C D), x in rad or as a fraction */
static double pac(double cc, double mu, double e, double k, double x, double fz)
{
    const double bx = k / (cc * mu) * x;
    return mu * (fz > 1.0 ? fz : 1.0) * sin(cc * atan(bx - e * (bx - atan(bx))));
}

/* Bakker-Nyborg-Pacejka 1987 at mu = 1 (adaptive._mf): x in the formula's unit, f in kN / size */
static double mf(const double *k, double x, double f, double bcd)
{
    const double d = (k[1] * f * f + k[2] * f) / (k[2] * 1e-3);
    const double e = k[6] * f * f + k[7] * f + k[8], bx = bcd / (k[0] * d) * x;
    return d * sin(k[0] * atan(bx - e * (bx - atan(bx))));
}

static double bcd_x(const vh_tfa_config_t *c, double f)
{
    const double *b = c->tyre_b;
    return (b[3] * f * f + b[4] * f) * exp(-b[5] * f);
}

double vh_tfa_longitudinal_force(const vh_tfa_config_t *c, double kappa_pct, double fz)
{
    const double f = (fz > 1.0 ? fz : 1.0) * 1e-3 / c->tyre_fz_scale;
    if (c->tyre_model == 1) {
        return pac(c->tyre_p[4], c->tyre_p[5], c->tyre_p[6], c->tyre_p[7], kappa_pct / 100.0, fz);
    }
    return c->tyre_fz_scale * mf(c->tyre_b, kappa_pct, f, bcd_x(c, f));
}

/* the slip of a pure-slip curve's maximum on (0, hi]: a scan of 400, then golden section (adaptive._peak) */
static double peak(const vh_tfa_config_t *c, int lon, double fz, double hi)
{
    double lo, up, best = -1.0;
    int j, jb = 0;
    for (j = 0; j < 400; ++j) {
        const double x = hi / 400 + j * (hi - hi / 400) / 399.0;
        const double v = lon ? vh_tfa_longitudinal_force(c, x, fz) : vh_tfa_lateral_force(c, x, fz);
        if (v > best) {
            best = v;
            jb = j;
        }
    }
    lo = hi / 400 + (jb > 0 ? jb - 1 : 0) * (hi - hi / 400) / 399.0;
    up = hi / 400 + (jb < 399 ? jb + 1 : 399) * (hi - hi / 400) / 399.0;
    for (j = 0; j < 60; ++j) {
        const double a = up - 0.618034 * (up - lo), b = lo + 0.618034 * (up - lo);
        const double fa = lon ? vh_tfa_longitudinal_force(c, a, fz) : vh_tfa_lateral_force(c, a, fz);
        const double fb = lon ? vh_tfa_longitudinal_force(c, b, fz) : vh_tfa_lateral_force(c, b, fz);
        if (fa < fb) {
            lo = a;
        } else {
            up = b;
        }
    }
    return 0.5 * (lo + up);
}

static double mf_lateral(const vh_tfa_config_t *c, double alpha_deg, double fz)
{
    const double *a = c->tyre_a, sc = c->tyre_fz_scale;
    const double f = (fz > 1.0 ? fz : 1.0) * 1e-3 / sc;
    const double d = (a[1] * f * f + a[2] * f) * c->mu / (a[2] * 1e-3);
    const double b = a[3] * sin(a[4] * atan(a[5] * f)) / (a[0] * d);
    const double e = a[6] * f * f + a[7] * f + a[8], bx = b * alpha_deg;
    return sc * d * sin(a[0] * atan(bx - e * (bx - atan(bx))));
}

double vh_tfa_lateral_force(const vh_tfa_config_t *c, double alpha_deg, double fz)
{
    if (c->tyre_model == 1) {
        return pac(c->tyre_p[0], c->tyre_p[1] * c->mu, c->tyre_p[2], c->tyre_p[3],
                   alpha_deg * 3.14159265358979323846 / 180.0, fz);
    }
    return mf_lateral(c, alpha_deg, fz);
}

int vh_tfa_params_from_config(const vh_skf_config_t *skf, const vh_tfa_config_t *c, vh_tfa_params_t *p)
{
    vh_tfa_params_t z;
    int ok = 1, i, j;
    const double s_vx = skf->s[VH_SKF_VX];
    if (!(c->tau_lp > 0.0 && c->decim >= 1 && c->forget > 0.0 && c->forget <= 1.0 && c->sigma_y > 0.0 &&
          c->mass_sigma0 >= c->mass_sigma_floor && c->mass_sigma_floor > 0.0 && c->mass_sigma_ok > 0.0 &&
          c->mass_lo > 0.0 && c->mass_hi > c->mass_lo && c->mass_hi < 4.0 && c->mu > 0.0 && c->mu < 4.0 &&
          c->tyre_fz_scale > 0.0 && c->tau_slip > 0.0 && c->tau_mu > 0.0 && c->tau_mu_forget > 0.0 &&
          c->mu_floor > 0.0 && c->mu_floor <= c->mu && c->q_gate > 0.0 && c->q_gate < 1.0 && c->fx_gate >= 0.0 &&
          c->ellipse_floor > 0.0 && c->ellipse_floor <= 1.0 && c->spring_front > 0.0 && c->spring_rear > 0.0 &&
          c->sigma_ride > 0.0 && skf->m > 0.0 && skf->ms > 0.0 && skf->ms <= skf->m && skf->g > 0.0 &&
          skf->tf > 0.0 && skf->tr > 0.0 && skf->ts > 0.0 && s_vx > 0.0 && c->tau_kin > 0.0 &&
          c->ay_kin_gate >= 0.0 && c->fx_free >= 0.0 && c->kin_q > 0.0 && c->kin_r_deg > 0.0 &&
          c->kin_sigma0 >= c->kin_q && c->kin_dmu > 0.0 && c->kin_dh_max > 0.0 && c->kin_side_min >= 0.0 &&
          c->kin_nis_gate > 0.0 && c->kin_nis_gate <= 1000.0 &&
          skf->lf + skf->lr > 0.0 && c->tyre_kz > 0.0 && c->tau_vyd > 0.0 && c->vyd_gate > 0.0 &&
          c->hold_implausible >= 0.0 && c->hold_implausible < 1e5 &&
          (c->tyre_model == 0 || (c->tyre_model == 1 && c->tyre_p[0] > 0.0 && c->tyre_p[1] > 0.0 && c->tyre_p[2] < 1.0 &&
                                  c->tyre_p[3] > 0.0 && c->tyre_p[4] > 0.0 && c->tyre_p[5] > 0.0 && c->tyre_p[6] < 1.0 &&
                                  c->tyre_p[7] > 0.0)) &&
          c->tyre_klt >= 0.0 && c->tyre_klt < 1e-3 && c->vx_tol > 0.0 && c->vx_tol < 100.0 &&
          c->vx_tol_rel >= 0.0 && c->vx_tol_rel < 1.0 && c->bal_tol > 0.0 && c->bal_tol / c->sigma_y < 1000.0 &&
          c->bal_tol_rel >= 0.0 && c->bal_tol_rel < 1.0 &&
          /* the bound's: z in Q2.29, the fractions in Q30, the stds within 10^5 N */
          c->bound_z > 0.0 && c->bound_z < 4.0 && c->bound_axle_abs >= 0.0 && c->bound_axle_abs < 1e5 &&
          c->bound_axle_rel >= 0.0 && c->bound_axle_rel < 1.0 && c->bound_lt_abs >= 0.0 && c->bound_lt_abs < 1e5 &&
          c->bound_lt_rel >= 0.0 && c->bound_lt_rel < 1.0 && c->bound_max > 0.0 && c->bound_max < 1e5 &&
          /* the normalised derivative and 1 + H P H in the RLS's formats (Q10.21, Q15.16) */
          c->kin_dh_max / c->kin_r_deg <= 1000.0 &&
          c->kin_sigma0 * c->kin_sigma0 * (c->kin_dh_max / c->kin_r_deg) * (c->kin_dh_max / c->kin_r_deg) <= 16000.0)) {
        return VH_EINVAL;
    }
    memset(&z, 0, sizeof z);
    for (i = 1; i < VH_TFA_NZ; ++i) { /* row 0 (no load) stays 0 */
        for (j = 0; j < VH_TFA_NA; ++j) {
            z.table[i * VH_TFA_NA + j] = vh_skfq_qconst(vh_tfa_lateral_force(c, 0.25 * j, 500.0 * i), VH_SKFQ_FN, &ok);
        }
    }
    z.k_inv_fz_step = vh_skfq_kconst(1.0 / 500.0, &ok);
    z.k_phi = vh_skfq_kconst(skf->m / c->sigma_y, &ok);
    z.k_y = vh_skfq_kconst(1.0 / c->sigma_y, &ok);
    z.k_drag = vh_skfq_kconst(0.5 * c->rho * c->cda / (s_vx * s_vx), &ok);
    z.alpha_lp = vh_skfq_qconst(skf->ts / (c->tau_lp + skf->ts), 30, &ok);
    z.ax_gate = vh_skfq_qconst(c->ax_gate, VH_SKFQ_FA, &ok);
    z.ay_gate = vh_skfq_qconst(c->ay_gate, VH_SKFQ_FA, &ok);
    z.vx_gate = vh_skfq_qconst(c->vx_gate * s_vx, VH_SKFQ_FX, &ok);
    z.valid_min = (uint32_t)floor(5.0 * c->tau_lp / skf->ts + 0.5);
    z.decim = (uint32_t)c->decim;
    z.inv_forget = vh_skfq_qconst(1.0 / c->forget, 30, &ok);
    z.p0 = vh_skfq_qconst(c->mass_sigma0 * c->mass_sigma0, VH_TFA_FP, &ok);
    z.p_floor = vh_skfq_qconst(c->mass_sigma_floor * c->mass_sigma_floor, VH_TFA_FP, &ok);
    z.p_ok = vh_skfq_qconst(c->mass_sigma_ok * c->mass_sigma_ok, VH_TFA_FP, &ok);
    z.k_lo = vh_skfq_qconst(c->mass_lo, VH_TFA_FK, &ok);
    z.k_hi = vh_skfq_qconst(c->mass_hi, VH_TFA_FK, &ok);
    z.m_num = 0;
    z.m_den = 0;
    {   /* the model mass as a fraction m_num / m_den (the TX of the mass estimate and its std, integer
         * only: vh_tf_app_check wants m_num times the DBC scale's denominator, 10 for the std, within
         * 2^30, so m_num <= 2^26): the shortest exact decimal fraction that fits, else the nearest with
         * the finest power-of-ten denominator (<= 10^6) that fits, within 0.5 / m_den kg (5e-5 kg for
         * 671..6710 kg) */
        const double n_max = 67108864.0;
        int32_t d;
        for (d = 1; d <= 1000000; d *= 10) {
            const double n = skf->m * d;
            if (n == floor(n) && n <= n_max) {
                z.m_num = (int32_t)n;
                z.m_den = d;
                break;
            }
        }
        for (d = 1000000; z.m_num == 0 && d >= 1; d /= 10) {
            const double n = floor(skf->m * d + 0.5);
            if (n <= n_max) {
                z.m_num = (int32_t)n;
                z.m_den = d;
            }
        }
        ok = ok && z.m_num > 0;
    }
    z.friction = c->friction != 0;
    z.combined = c->combined != 0;
    for (i = 0; i < VH_TFA_NZ; ++i) { /* adaptive.friction_tables; row 0 (no load) repeats row 1 */
        const double fz = 500.0 * (i > 0 ? i : 1), f = fz * 1e-3 / c->tyre_fz_scale;
        const double c_pct = c->tyre_model == 1 ? c->tyre_p[7] * fz / 100.0 : c->tyre_fz_scale * bcd_x(c, f); /* N per % */
        const double km = peak(c, 1, fz, 40.0), am = peak(c, 0, fz, 30.0);
        z.compliance[i] = vh_skfq_qconst(1.0 / (100.0 * c_pct), VH_TFA_FC, &ok);
        z.dx[i] = vh_skfq_qconst(vh_tfa_longitudinal_force(c, km, fz), VH_SKFQ_FN, &ok);
        z.inv_kappa_m[i] = vh_skfq_qconst(100.0 / km, VH_TFA_FG, &ok);
        z.inv_alpha_m[i] = vh_skfq_qconst((0.25 * 3.14159265358979323846 / 180.0) / (am * 3.14159265358979323846 / 180.0),
                                          30, &ok);
        z.secant[i * VH_TFA_NS] = vh_skfq_qconst(1.0, 30, &ok);
        for (j = 1; j < VH_TFA_NS; ++j) {
            const double sj = 0.05 * j;
            z.secant[i * VH_TFA_NS + j] =
                vh_skfq_qconst(vh_tfa_longitudinal_force(c, sj * km, fz) / (c_pct * sj * km), 30, &ok);
        }
    }
    z.k_rw = vh_skfq_kconst(skf->rw, &ok);
    z.k_inv_svx = vh_skfq_kconst(1.0 / s_vx, &ok);
    z.k_half[0] = vh_skfq_kconst(skf->tf, &ok);
    z.k_half[1] = vh_skfq_kconst(skf->tr, &ok);
    z.alpha_slip = vh_skfq_qconst(skf->ts / (c->tau_slip + skf->ts), 30, &ok);
    z.fx_gate = vh_skfq_qconst(c->fx_gate, VH_SKFQ_FN, &ok);
    z.q_gate = vh_skfq_qconst(c->q_gate, 30, &ok);
    z.g_obs = vh_skfq_qconst(c->decim * skf->ts / c->tau_mu, 30, &ok);
    z.g_forget = vh_skfq_qconst(c->decim * skf->ts / c->tau_mu_forget, 30, &ok);
    z.mu_nom = vh_skfq_qconst(c->mu, VH_TFA_FS, &ok);
    z.mu_floor = vh_skfq_qconst(c->mu_floor, VH_TFA_FS, &ok);
    z.s_step = vh_skfq_qconst(0.05, 30, &ok);
    z.ellipse_floor2 = vh_skfq_qconst(c->ellipse_floor * c->ellipse_floor, 30, &ok);
    z.ride = c->ride != 0;
    z.k_spring[0] = vh_skfq_kconst(c->spring_front, &ok);
    z.k_spring[1] = vh_skfq_kconst(c->spring_rear, &ok);
    z.k_link[0] = vh_skfq_kconst(skf->hf / skf->tf, &ok);
    z.k_link[1] = vh_skfq_kconst(skf->hr / skf->tr, &ok);
    {   /* one ride-height measurement's std sigma_h = sigma_ride m [kg] normalises it */
        const double sigma_h = c->sigma_ride * skf->m;
        z.k_ride = vh_skfq_kconst(1.0 / (skf->g * sigma_h), &ok);
        z.ride_unsprung = vh_skfq_qconst((skf->m - skf->ms) / sigma_h, VH_TFA_FN, &ok);
        z.ride_phi = vh_skfq_qconst(skf->m / sigma_h, VH_TFA_FN, &ok);
    }
    z.ride_min = (uint32_t)floor(c->tau_lp / skf->ts + 0.5);
    z.road = c->road != 0;
    z.alpha_kin = vh_skfq_qconst(skf->ts / (c->tau_kin + skf->ts), 30, &ok);
    z.kin_min = (uint32_t)floor(5.0 * c->tau_kin / skf->ts + 0.5);
    z.ay_kin_gate = vh_skfq_qconst(c->ay_kin_gate, VH_SKFQ_FA, &ok);
    z.fx_free = vh_skfq_qconst(c->fx_free, VH_SKFQ_FN, &ok);
    z.v_gate = vh_skfq_qconst(c->vx_gate, 21, &ok);
    z.k_wheelbase = vh_skfq_kconst(skf->lf + skf->lr, &ok);
    {   /* angles in slip-angle knots of 0.25 deg; the measurement's std sigma_z in them */
        const double knot = 0.25 * 3.14159265358979323846 / 180.0, sigma_z = c->kin_r_deg / 0.25;
        z.k_knot = vh_skfq_kconst(1.0 / knot, &ok);
        z.k_kin = vh_skfq_kconst(1.0 / sigma_z, &ok);
        z.k_kin_dh = vh_skfq_kconst(1.0 / (c->kin_dmu * sigma_z), &ok);
        z.kin_dh_max = vh_skfq_qconst(c->kin_dh_max / c->kin_r_deg, VH_TFA_FN, &ok);
    }
    z.kin_dmu = vh_skfq_qconst(c->kin_dmu, VH_TFA_FS, &ok);
    z.kin_q = vh_skfq_qconst(c->kin_q * c->kin_q, 30, &ok);
    z.kin_p0 = vh_skfq_qconst(c->kin_sigma0 * c->kin_sigma0, 30, &ok);
    z.kin_side_min = vh_skfq_qconst(c->kin_side_min, VH_TFA_FS, &ok);
    z.kin_nis = vh_skfq_qconst(c->kin_nis_gate, 16, &ok);
    z.transfer = c->transfer != 0;
    z.alpha_vyd = vh_skfq_qconst(skf->ts / (c->tau_vyd + skf->ts), 30, &ok);
    z.vyd_gate = vh_skfq_qconst(c->vyd_gate, VH_SKFQ_FA, &ok);
    z.hold_implausible = (uint32_t)floor(c->hold_implausible / skf->ts + 0.5);
    z.vx_tol = vh_skfq_qconst(c->vx_tol, 21, &ok);
    z.vx_tol_rel = vh_skfq_qconst(c->vx_tol_rel, 30, &ok);
    z.bal_tol = vh_skfq_qconst(c->bal_tol / c->sigma_y, VH_TFA_FN, &ok);
    z.bal_tol_rel = vh_skfq_qconst(c->bal_tol_rel, 30, &ok);
    z.bound_z = vh_skfq_qconst(c->bound_z, 29, &ok);
    z.bound_axle_abs = vh_skfq_qconst(c->bound_axle_abs, VH_TFA_FB, &ok);
    z.bound_axle_rel = vh_skfq_qconst(c->bound_axle_rel, 30, &ok);
    z.bound_lt_abs = vh_skfq_qconst(c->bound_lt_abs, VH_SKFQ_FN, &ok);
    z.bound_lt_rel = vh_skfq_qconst(c->bound_lt_rel, 30, &ok);
    z.bound_max = vh_skfq_qconst(c->bound_max, VH_SKFQ_FN, &ok);
    z.klt = c->tyre_klt > 0.0;
    z.k_klt[0] = vh_skfq_kconst(c->tyre_klt / (2.0 * skf->tf), &ok);
    z.k_klt[1] = vh_skfq_kconst(c->tyre_klt / (2.0 * skf->tr), &ok);
    {   /* adaptive.bar_rates: the bar is what the springs leave of the suspension's roll stiffness */
        const double kphi[2] = {skf->kphif, skf->kphir}, t[2] = {skf->tf, skf->tr};
        const double k[2] = {c->spring_front, c->spring_rear};
        for (i = 0; i < 2; ++i) {
            const double inv = 1.0 / kphi[i] - 1.0 / (2.0 * c->tyre_kz * t[i] * t[i]);
            if (!(inv > 0.0)) {
                return VH_EINVAL;
            }
            z.k_roll[i] = vh_skfq_kconst(k[i] + 2.0 * ((1.0 / inv - 2.0 * k[i] * t[i] * t[i]) / (4.0 * t[i] * t[i])), &ok);
        }
    }
    if (!ok) {
        return VH_EINVAL;
    }
    *p = z;
    return VH_OK;
}
