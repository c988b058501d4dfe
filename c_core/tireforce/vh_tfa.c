/* vh_tfa.c - SKFMEC-A in fixed point, see vh_tfa.h. Integer only: no float, no double.
 *
 * Step by step the same as vehest_can/systems/tireforce/adaptive.py (estimate_mass, the split);
 * each line says which format it produces when that is not the destination's.
 */
#include "vh_health.h"
#include "vh_tf_types.h"
#include "vh_tfa.h"
#include "vh_types.h"

#define NA VH_TFA_NA
#define NZ VH_TFA_NZ
#define FK VH_TFA_FK
#define FP VH_TFA_FP
#define FQ VH_TFA_FN /* the normalised regressor and output */
#define FZW VH_TFA_FZW
#define NS VH_TFA_NS
#define FS VH_TFA_FS
#define FC VH_TFA_FC
#define FG VH_TFA_FG
#define FH VH_TFA_FH
#define FB VH_TFA_FB
#define FO VH_SKFQ_FO
#define FW VH_SKFQ_FW
#define FV 21 /* speeds [m/s] of the differential slip */
#define FX VH_SKFQ_FX
#define FA VH_SKFQ_FA
#define FD VH_SKFQ_FD
#define FN VH_SKFQ_FN
#define ONE30 (INT32_C(1) << 30)

#define KM(k, v, fin, fout) vh_fix_kmul((k), (v), (fin), (fout), sat)
#define ADD(a, b) vh_fix_add((a), (b), sat)
#define SUB(a, b) vh_fix_sub((a), (b), sat)
#define MUL(a, fa, b, fb, fo) vh_fix_mul((a), (fa), (b), (fb), (fo), sat)

static int k_ok(vh_fix_k_t k)
{
    return k.m == 0 || ((k.m >= (INT32_C(1) << 30) || k.m <= -(INT32_C(1) << 30)) && k.e > -31 && k.e < 120);
}

static int32_t abs32(int32_t x)
{
    return x < 0 ? (x == INT32_MIN ? INT32_MAX : -x) : x;
}

int vh_tfa_check(const vh_tfa_params_t *prm)
{
    int i;
    if (!k_ok(prm->k_inv_fz_step) || !k_ok(prm->k_phi) || !k_ok(prm->k_y) || !k_ok(prm->k_drag) ||
        prm->k_inv_fz_step.m <= 0 || prm->k_phi.m <= 0 || prm->k_y.m <= 0 || prm->k_drag.m < 0 ||
        prm->alpha_lp <= 0 || prm->alpha_lp > ONE30 || prm->decim == 0u || prm->ax_gate < 0 || prm->ay_gate < 0 ||
        prm->inv_forget < ONE30 || prm->p_floor <= 0 || prm->p0 < prm->p_floor || prm->p_ok <= 0 ||
        prm->k_lo <= 0 || prm->k_hi <= prm->k_lo || prm->m_num <= 0 || prm->m_den <= 0 || !k_ok(prm->k_rw) ||
        !k_ok(prm->k_inv_svx) || !k_ok(prm->k_half[0]) || !k_ok(prm->k_half[1]) || prm->k_rw.m <= 0 ||
        prm->k_inv_svx.m <= 0 || prm->alpha_slip <= 0 || prm->alpha_slip > ONE30 || prm->g_obs <= 0 ||
        prm->g_obs > ONE30 || prm->g_forget <= 0 || prm->g_forget > ONE30 || prm->mu_floor <= 0 ||
        prm->mu_nom < prm->mu_floor || prm->q_gate <= 0 || prm->q_gate >= ONE30 || prm->s_step <= 0 ||
        prm->ellipse_floor2 <= 0 || prm->ellipse_floor2 > ONE30 || !k_ok(prm->k_spring[0]) ||
        !k_ok(prm->k_spring[1]) || !k_ok(prm->k_link[0]) || !k_ok(prm->k_link[1]) || !k_ok(prm->k_ride) ||
        (prm->ride && (prm->k_spring[0].m <= 0 || prm->k_spring[1].m <= 0 || prm->k_ride.m <= 0 ||
                       prm->ride_phi <= 0 || prm->ride_unsprung < 0)) ||
        !k_ok(prm->k_roll[0]) || !k_ok(prm->k_roll[1]) || !k_ok(prm->k_wheelbase) || !k_ok(prm->k_knot) || !k_ok(prm->k_kin) || !k_ok(prm->k_kin_dh) ||
        prm->alpha_vyd <= 0 || prm->alpha_vyd > ONE30 || prm->vyd_gate <= 0 ||
        prm->bound_z <= 0 || prm->bound_axle_abs < 0 || prm->bound_axle_rel < 0 || prm->bound_lt_abs < 0 ||
        prm->bound_lt_rel < 0 || prm->bound_max <= 0 ||
        (prm->klt && (!k_ok(prm->k_klt[0]) || !k_ok(prm->k_klt[1]) || prm->k_klt[0].m <= 0 || prm->k_klt[1].m <= 0)) ||
        (prm->road && (prm->alpha_kin <= 0 || prm->alpha_kin > ONE30 || prm->ay_kin_gate < 0 || prm->fx_free < 0 ||
                       prm->k_wheelbase.m <= 0 || prm->k_knot.m <= 0 || prm->k_kin.m <= 0 || prm->k_kin_dh.m <= 0 ||
                       prm->kin_dh_max <= 0 || prm->kin_dh_max > (INT32_C(1000) << FQ) || prm->kin_dmu <= 0 ||
                       prm->kin_q <= 0 || prm->kin_p0 < prm->kin_q || prm->kin_side_min < 0 || prm->kin_nis <= 0 ||
                       /* 1 + H P H within Q16 */
                       (int64_t)((((int64_t)prm->kin_dh_max * prm->kin_dh_max) >> (2 * FQ)) * prm->kin_p0 >> 30) > 16000))) {
        return VH_EINVAL;
    }
    for (i = 0; i < NZ * NA; ++i) {
        if (prm->table[i] < 0) {
            return VH_EINVAL;
        }
    }
    for (i = 0; i < NZ; ++i) {
        if (prm->compliance[i] <= 0 || prm->dx[i] <= 0 || prm->inv_kappa_m[i] <= 0 || prm->inv_alpha_m[i] <= 0) {
            return VH_EINVAL;
        }
    }
    return VH_OK;
}

int vh_tfa_init(vh_tfa_t *a, const vh_tfa_params_t *prm)
{
    if (vh_tfa_check(prm) != VH_OK) {
        return VH_EINVAL;
    }
    {
        static const vh_tfa_t zero = {0};
        *a = zero;
    }
    a->prm = *prm;
    vh_tfa_reset(a);
    return VH_OK;
}

void vh_tfa_reset(vh_tfa_t *a)
{
    int i;
    a->y_lp = 0;
    a->ax_lp = 0;
    a->k = INT32_C(1) << FK;
    a->p = a->prm.p0;
    a->valid_run = 0u;
    a->steps = 0u;
    a->updates = 0u;
    a->w_lp = 0;
    a->ride_run = 0u;
    for (i = 0; i < 4; ++i) {
        a->fy[i] = 0;
        a->fz[i] = 0;
        a->bound[i] = 0;
    }
    for (i = 0; i < 2; ++i) {
        a->slip_e[i] = 0;
        a->mu[i] = a->prm.mu_nom;
        a->alpha[i] = 0;
    }
    a->z_lp = 0;
    a->kin_run = 0u;
    a->mu_road = a->prm.mu_nom;
    a->p_road = a->prm.kin_p0;
    a->vyd_lp = 0;
    a->implausible = 0u;
    a->contra = 0u;
    a->n_contra = 0u;
    a->bal = 0u;
    a->sat = 0u;
    a->health = VH_HEALTH_INIT;
}

/* One RLS update of y = x phi (adaptive.rls_step), both normalised by the measurement's sigma
 * (ph = phi / sigma, yv = y / sigma, FQ; x in Q29, its variance p in Q30): K = P ph / (1 + ph P ph),
 * x += K (yv - ph x) clamped to [x_lo, x_hi], P = (1 - K ph) P / lambda in [p_lo, p_hi]. The mass
 * ratio's (k, P) and the road friction's (mu, P). */
static int32_t innovation_var(int32_t pv, int32_t ph, uint32_t *sat) /* 1 + ph P ph, Q16 */
{
    return ADD(INT32_C(1) << 16, MUL(ph, FQ, MUL(pv, FP, ph, FQ, 24), 24, 16));
}

static void rls(int32_t *x, int32_t *pv, int32_t ph, int32_t yv, int32_t inv_forget, int32_t p_lo, int32_t p_hi,
                int32_t x_lo, int32_t x_hi, uint32_t *sat)
{
    const int32_t u = MUL(*pv, FP, ph, FQ, 24);                         /* P phi, Q24 */
    const int32_t s = innovation_var(*pv, ph, sat);                     /* 1 + phi P phi, Q16 */
    const int32_t g = vh_fix_div(u, s, 16, sat);                        /* K, Q24 */
    const int32_t e = SUB(yv, MUL(ph, FQ, *x, FK, FQ));                 /* y - phi x, Q21 */
    const int64_t xn = (int64_t)*x + vh_fix_asr64((int64_t)g * e + (INT64_C(1) << 15), 16); /* Q29 */
    const int32_t kp = MUL(g, 24, ph, FQ, 30);                          /* K phi in [0, 1), Q30 */
    int32_t p = MUL(MUL(*pv, FP, SUB(ONE30, kp), 30, FP), FP, inv_forget, 30, FP);
    *x = xn > x_hi ? x_hi : (xn < x_lo ? x_lo : (int32_t)xn);
    *pv = p > p_hi ? p_hi : (p < p_lo ? p_lo : p);
}

/* The mass ratio's update (the balance, or the ride heights). */
static void mass_rls(vh_tfa_t *a, int32_t ph, int32_t yv, uint32_t *sat)
{
    const vh_tfa_params_t *k = &a->prm;
    rls(&a->k, &a->p, ph, yv, k->inv_forget, k->p_floor, k->p0, k->k_lo, k->k_hi, sat);
    ++a->updates;
}

/* floor(sqrt(v)) of v >= 0 (bit by bit) */
static int32_t isqrt64(int64_t v)
{
    uint64_t x = v > 0 ? (uint64_t)v : 0u, r = 0u, b = UINT64_C(1) << 62;
    while (b > x) {
        b >>= 2;
    }
    while (b != 0u) {
        if (x >= r + b) {
            x -= r + b;
            r = (r >> 1) + b;
        } else {
            r >>= 1;
        }
        b >>= 2;
    }
    return r > (uint64_t)INT32_MAX ? INT32_MAX : (int32_t)r;
}

/* A per-load-knot table's row (n columns) at load fz (FN), linear in the load, clamped to the knots. */
static void row_at(const vh_tfa_params_t *k, const int32_t *tab, int n, int32_t fz, int32_t *out, uint32_t *sat)
{
    const int32_t top = (NZ - 1) << FZW;
    int32_t idx = KM(k->k_inv_fz_step, fz, FN, FZW);
    int iz, j;
    int32_t wz;
    idx = idx < 0 ? 0 : (idx > top ? top : idx);
    iz = (int)(idx >> FZW);
    if (iz > NZ - 2) {
        iz = NZ - 2;
    }
    wz = idx - (int32_t)(iz << FZW);
    for (j = 0; j < n; ++j) {
        const int64_t v = (int64_t)tab[iz * n + j] * ((INT32_C(1) << FZW) - wz) + (int64_t)tab[(iz + 1) * n + j] * wz;
        out[j] = vh_fix_rshift_rnd(v, FZW, sat);
    }
}

static int32_t at_load(const vh_tfa_params_t *k, const int32_t *tab, int32_t fz, uint32_t *sat)
{
    int32_t v;
    row_at(k, tab, 1, fz, &v, sat);
    return v;
}

/* The friction ellipse's lateral factor sqrt(1 - (Fx / (mu Dx))^2), floored, Q30 (adaptive.ellipse). */
static int32_t ellipse(const vh_tfa_params_t *k, int32_t fx, int32_t fz, int32_t mu, uint32_t *sat)
{
    const int32_t lim = MUL(mu, FS, at_load(k, k->dx, fz, sat), FN, FN);
    int32_t v = k->ellipse_floor2;
    if (abs32(fx) < lim) {
        const int32_t r = vh_fix_div(fx, lim, 30, sat);
        const int32_t w = SUB(ONE30, MUL(r, 30, r, 30, 30));
        v = w > v ? w : v;
    }
    return isqrt64((int64_t)v << 30);
}

/* The tyre's curve at its load, friction mu (FS) and ellipse factor cap (Q30) at every slip-angle
 * knot (adaptive.load_sensitive_split): cap mu F(alpha_j / mu), alpha_j / mu linear between the knots. */
static void curve(const vh_tfa_params_t *k, int32_t fz, int32_t mu, int32_t cap, int32_t out[NA], uint32_t *sat)
{
    int32_t g[NA];
    int j;
    row_at(k, k->table, NA, fz, g, sat);
    if (mu == (INT32_C(1) << FS)) {
        for (j = 0; j < NA; ++j) {
            out[j] = g[j];
        }
    } else {
        const int32_t inv = vh_fix_div(INT32_C(1) << FS, mu, FG, sat); /* 1 / mu, FG */
        for (j = 0; j < NA; ++j) {
            int64_t xa = (int64_t)inv * j;
            int ia;
            int32_t wa;
            if (xa > ((int64_t)(NA - 1) << FG)) {
                xa = (int64_t)(NA - 1) << FG;
            }
            ia = (int)(xa >> FG);
            if (ia > NA - 2) {
                ia = NA - 2;
            }
            wa = (int32_t)(xa - ((int64_t)ia << FG));
            out[j] = MUL(vh_fix_rshift_rnd((int64_t)g[ia] * ((INT32_C(1) << FG) - wa) + (int64_t)g[ia + 1] * wa, FG, sat),
                         FN, mu, FS, FN);
        }
    }
    if (cap != ONE30) {
        for (j = 0; j < NA; ++j) {
            out[j] = MUL(out[j], FN, cap, 30, FN);
        }
    }
}

/* An axle's 2 F_axle (FN) to its two tyres: the first slip-angle knot where the pair's sum reaches
 * it, linear between that knot and the one before; beyond the pair's peak, the share at the peak.
 * alpha: the axle's slip angle (knots, FG); peak (if not NULL): the pair's largest sum (FN). */
static void split(const vh_tfa_params_t *k, const int32_t *fz, const int32_t *mu, const int32_t *cap, int32_t two_axle,
                  int32_t *out, int32_t *alpha, int32_t *peak, uint32_t *sat)
{
    int32_t f0[NA], f1[NA], tot[NA];
    const int32_t want = abs32(two_axle);
    int32_t share;
    int j, top = 0;
    curve(k, fz[0], mu[0], cap[0], f0, sat);
    curve(k, fz[1], mu[1], cap[1], f1, sat);
    for (j = 0; j < NA; ++j) {
        tot[j] = ADD(f0[j], f1[j]);
        if (tot[j] > tot[top]) {
            top = j;
        }
    }
    for (j = 1; j < NA && tot[j] < want; ++j) {
    }
    if (j == NA) {
        share = vh_fix_div(f0[top], tot[top], 30, sat);
        *alpha = (int32_t)top << FG;
    } else if (want == 0) {
        share = vh_fix_div(f0[1], tot[1], 30, sat);
        *alpha = 0;
    } else {
        const int32_t dt = tot[j] - tot[j - 1];
        const int32_t t = dt > 0 ? vh_fix_div(want - tot[j - 1], dt, 30, sat) : 0;  /* Q30 */
        const int32_t fin = ADD(f0[j - 1], MUL(t, 30, SUB(f0[j], f0[j - 1]), FN, FN));
        share = vh_fix_div(fin, want, 30, sat);
        *alpha = ((int32_t)(j - 1) << FG) + vh_fix_rshift_rnd(t > ONE30 ? ONE30 : (t < 0 ? 0 : t), 30 - FG, sat);
    }
    out[0] = MUL(two_axle, FN, share, 30, FN);
    out[1] = SUB(two_axle, out[0]);
    if (peak != NULL) {
        *peak = tot[top];
    }
}

/* A tyre's linear slip |Fx| / C_kappa(Fz), FS */
static int32_t linear_slip(const vh_tfa_params_t *k, int32_t fx, int32_t fz, uint32_t *sat)
{
    return MUL(abs32(fx), FN, at_load(k, k->compliance, fz, sat), FC, FS);
}

/* hypot(kappa / kappa_m, alpha / alpha_m) at the load (FG): the normalised combined slip times mu */
static int32_t combined_slip(const vh_tfa_params_t *k, int32_t kappa, int32_t fz, int32_t alpha, uint32_t *sat)
{
    const int32_t xk = MUL(kappa, FS, at_load(k, k->inv_kappa_m, fz, sat), FG, FG);
    const int32_t xa = MUL(alpha, FG, at_load(k, k->inv_alpha_m, fz, sat), 30, FG);
    return isqrt64((int64_t)xk * xk + (int64_t)xa * xa);
}

/* The friction under the tyre that slips ex (FS, > 0) more than its linear slip (adaptive.slip_observation):
 * Q(s) = kappa_lin / (kappa_lin + ex) gives the normalised combined slip s, mu = hypot(kappa / kappa_m,
 * alpha / alpha_m) / s. Returns 0 if the tyre is linear (mu not observable), else mu (FS). */
static int32_t slip_observation(const vh_tfa_params_t *k, int32_t ex, int32_t fx, int32_t fz, int32_t alpha, uint32_t *sat)
{
    int32_t row[NS];
    const int32_t klin = linear_slip(k, fx, fz, sat);
    const int32_t kap = ADD(klin, ex);
    const int32_t qv = vh_fix_div(klin, kap, 30, sat);
    int32_t sk, mu;
    int j;
    if (kap <= 0 || qv >= k->q_gate) {
        return 0;
    }
    row_at(k, k->secant, NS, fz, row, sat);
    for (j = 0; j < NS && row[j] > qv; ++j) {
    }
    if (j < NS && j > 0) {
        sk = ((int32_t)(j - 1) << FG) + vh_fix_div(SUB(row[j - 1], qv), SUB(row[j - 1], row[j]), FG, sat);
    } else {
        sk = (int32_t)(NS - 1) << FG;
    }
    mu = vh_fix_div(combined_slip(k, kap, fz, alpha, sat), MUL(sk, FG, k->s_step, 30, FG), FS, sat);
    return mu > k->mu_nom ? k->mu_nom : (mu < k->mu_floor ? k->mu_floor : mu);
}

/* The secant ratio Q(s) (Q30) of a tyre at its linear slip |Fx| / C_kappa and slip angle alpha on friction mu
 * (adaptive.linear_share); s beyond the table's last knot is read there. */
static int32_t linear_share(const vh_tfa_params_t *k, int32_t fx, int32_t fz, int32_t alpha, int32_t mu, uint32_t *sat)
{
    int32_t row[NS];
    const int64_t top = (int64_t)(NS - 1) << FG;
    const int32_t den = MUL(mu, FS, k->s_step, 30, FS);
    const int64_t s = (int64_t)combined_slip(k, linear_slip(k, fx, fz, sat), fz, alpha, sat) << FS;
    int64_t x = den > 0 ? s / den : top; /* knots, FG */
    int j;
    if (x > top) {
        x = top;
    }
    j = (int)(x >> FG);
    if (j > NS - 2) {
        j = NS - 2;
    }
    row_at(k, k->secant, NS, fz, row, sat);
    return ADD(row[j], MUL((int32_t)(x - ((int64_t)j << FG)), FG, SUB(row[j + 1], row[j]), 30, 30));
}

/* The friction tyre i's curve is taken at: its side's, or the road's where lower while no side has seen a split. */
static int32_t tyre_mu(const vh_tfa_t *a, int i)
{
    const vh_tfa_params_t *k = &a->prm;
    const int uniform = k->road && a->mu[0] >= k->kin_side_min && a->mu[1] >= k->kin_side_min;
    return uniform && a->mu_road < a->mu[i & 1] ? a->mu_road : a->mu[i & 1];
}

/* Per axle, the excess differential slip e += a ((kR - kL) - (FxR / CR - FxL / CL) - e) at the yaw-corrected
 * wheel speeds vx -+ r t (adaptive.estimate_friction). */
static void slip_lowpass(vh_tfa_t *a, const vh_skfq_t *f, const vh_skfq_input_t *in, uint32_t *sat)
{
    const vh_tfa_params_t *k = &a->prm;
    const int32_t vx = KM(k->k_inv_svx, f->x[VH_SKF_VX], FX, FV);
    int ax;
    for (ax = 0; ax < 2; ++ax) {
        const int i = 2 * ax, j = i + 1;
        const int32_t rt = KM(k->k_half[ax], in->r, FW, FV);
        const int32_t dk = SUB(vh_fix_div(KM(k->k_rw, in->omega[j], FO, FV), ADD(vx, rt), FS, sat),
                               vh_fix_div(KM(k->k_rw, in->omega[i], FO, FV), SUB(vx, rt), FS, sat));
        const int32_t dl = SUB(MUL(f->fx[j], FN, at_load(k, k->compliance, a->fz[j], sat), FC, FS),
                               MUL(f->fx[i], FN, at_load(k, k->compliance, a->fz[i], sat), FC, FS));
        a->slip_e[ax] = ADD(a->slip_e[ax], MUL(k->alpha_slip, 30, SUB(SUB(dk, dl), a->slip_e[ax]), FS, FS));
    }
}

/* At an update: each axle's observation of its low-mu side's friction; a side without one returns to mu_nom. */
static void friction_update(vh_tfa_t *a, const vh_skfq_t *f, uint32_t *sat)
{
    const vh_tfa_params_t *k = &a->prm;
    int seen[2] = {0, 0}, ax, side;
    if (a->valid_run > k->valid_min && f->x[VH_SKF_VX] >= k->vx_gate && a->steps > 1u) {
        for (ax = 0; ax < 2; ++ax) {
            const int i = 2 * ax, j = i + 1;
            const int32_t fi = f->fx[i], fj = f->fx[j];
            int32_t ex, obs;
            int w, o;
            if (!(((fi > 0 && fj > 0) || (fi < 0 && fj < 0)) && abs32(fi) >= k->fx_gate && abs32(fj) >= k->fx_gate)) {
                continue;
            }
            ex = fj > 0 ? a->slip_e[ax] : SUB(0, a->slip_e[ax]); /* > 0: the right wheel slips more */
            side = ex > 0 ? 1 : 0;
            w = ex > 0 ? j : i;
            o = ex > 0 ? i : j;
            /* the differential slip is the low side's excess only while the other tyre is linear */
            if (linear_share(k, f->fx[o], a->fz[o], a->alpha[ax], tyre_mu(a, o), sat) < k->q_gate) {
                continue;
            }
            obs = slip_observation(k, abs32(ex), f->fx[w], a->fz[w], a->alpha[ax], sat);
            if (obs > 0) {
                a->mu[side] = ADD(a->mu[side], MUL(k->g_obs, 30, SUB(obs, a->mu[side]), FS, FS));
                seen[side] = 1;
            }
        }
    }
    for (side = 0; side < 2; ++side) {
        if (!seen[side]) {
            a->mu[side] = ADD(a->mu[side], MUL(k->g_forget, 30, SUB(k->mu_nom, a->mu[side]), FS, FS));
        }
    }
}

/* The kinematic coupling alpha_f - alpha_r = delta - L r / v [knots, FG], low-passed (adaptive.estimate_friction):
 * v from a free-rolling axle's wheels (|Fx| <= fx_free on both), the rear's mean speed, else the front's over
 * cos delta; none (or v below the gate): not measured this step. */
static void road_lowpass(vh_tfa_t *a, const vh_skfq_t *f, const vh_skfq_input_t *in, uint32_t *sat)
{
    const vh_tfa_params_t *k = &a->prm;
    int32_t v, z;
    if (abs32(f->fx[2]) <= k->fx_free && abs32(f->fx[3]) <= k->fx_free) {
        v = KM(k->k_rw, vh_fix_rshift_rnd((int64_t)in->omega[2] + in->omega[3], 1, sat), FO, FV);
    } else if (abs32(f->fx[0]) <= k->fx_free && abs32(f->fx[1]) <= k->fx_free && f->cs_delta[0] > 0) {
        v = vh_fix_div(KM(k->k_rw, vh_fix_rshift_rnd((int64_t)in->omega[0] + in->omega[1], 1, sat), FO, FV),
                       f->cs_delta[0], FD, sat);
    } else {
        a->kin_run = 0u;
        return;
    }
    if (v < k->v_gate) {
        a->kin_run = 0u;
        return;
    }
    z = KM(k->k_knot, SUB(vh_fix_rshift_rnd(in->delta, FD - FG, sat),
                          vh_fix_div(KM(k->k_wheelbase, in->r, FW, FV), v, FG, sat)), FG, FG);
    a->z_lp = a->kin_run == 0u ? z : ADD(a->z_lp, MUL(k->alpha_kin, 30, SUB(z, a->z_lp), FG, FG));
    if (a->kin_run < UINT32_MAX) {
        ++a->kin_run;
    }
}

/* The split's alpha_f - alpha_r (each axle's slip angle signed as its force; knots, FG) on a road of friction
 * mu (FS) under all four tyres (adaptive.kinematic_model); peak (if not NULL): the pairs' largest sums. */
static int32_t kin_model(const vh_tfa_t *a, const vh_skfq_t *f, const int32_t *two, int32_t mu, int32_t *peak,
                         uint32_t *sat)
{
    const vh_tfa_params_t *k = &a->prm;
    int32_t mu4[4], cap[4], fy[2], al[2];
    int i, ax;
    for (i = 0; i < 4; ++i) {
        mu4[i] = mu;
        cap[i] = k->combined ? ellipse(k, f->fx[i], a->fz[i], mu, sat) : ONE30;
    }
    for (ax = 0; ax < 2; ++ax) {
        split(k, &a->fz[2 * ax], &mu4[2 * ax], &cap[2 * ax], two[ax], fy, &al[ax], peak != NULL ? &peak[ax] : NULL, sat);
        al[ax] = two[ax] < 0 ? -al[ax] : (two[ax] == 0 ? 0 : al[ax]);
    }
    return SUB(al[0], al[1]);
}

/* At an update: the road's friction by the scalar EKF (adaptive.estimate_friction): the random walk, then
 * the RLS's update on the linearised y = z - h(mu^) + H mu^ = H mu (H by a finite difference, bounded),
 * kept where the pairs' peaks carry the axle forces; without an observation back to mu_nom. */
static void road_update(vh_tfa_t *a, const vh_skfq_t *f, const vh_skfq_input_t *in, const int32_t *two, uint32_t *sat)
{
    const vh_tfa_params_t *k = &a->prm;
    const int32_t q = ADD(a->p_road, k->kin_q);
    a->p_road = q > k->kin_p0 ? k->kin_p0 : q;
    if (a->valid_run > k->valid_min && a->kin_run > k->kin_min && abs32(in->ay) >= k->ay_kin_gate &&
        a->mu[0] >= k->kin_side_min && a->mu[1] >= k->kin_side_min) {
        const int32_t mu = a->mu_road;
        int32_t peak[2], h0, dh, carried = 0;
        int ax;
        h0 = kin_model(a, f, two, mu, peak, sat);
        dh = KM(k->k_kin_dh, SUB(kin_model(a, f, two, ADD(mu, k->kin_dmu), NULL, sat), h0), FG, FQ);
        dh = dh > k->kin_dh_max ? k->kin_dh_max : (dh < -k->kin_dh_max ? -k->kin_dh_max : dh);
        for (ax = 0; ax < 2; ++ax) { /* mu times the axle force over the pair's peak (FG), at least 1 N */
            const int32_t c = MUL(mu, FS, vh_fix_div(abs32(two[ax]), peak[ax] > (INT32_C(1) << FN) ? peak[ax] :
                                                     (INT32_C(1) << FN), FG, sat), FG, FS);
            carried = c > carried ? c : carried;
        }
        {   /* an innovation the model cannot explain at any nearby mu (nu^2 / (1 + H P H) beyond the gate) is not used */
            const int32_t nu = KM(k->k_kin, SUB(a->z_lp, h0), FG, FQ);
            const int64_t gate = ((int64_t)k->kin_nis * innovation_var(a->p_road, dh, sat)) >> 16;
            if (vh_fix_asr64((int64_t)nu * nu, 2 * FQ - 16) <= gate) {
                rls(&a->mu_road, &a->p_road, dh, ADD(nu, MUL(dh, FQ, mu, FS, FQ)), ONE30, k->kin_q, k->kin_p0,
                    k->mu_floor, k->mu_nom, sat);
            }
        }
        if (carried > a->mu_road) {
            a->mu_road = carried > k->mu_nom ? k->mu_nom : carried;
        }
    } else if (!(a->valid_run > k->valid_min && abs32(in->ay) >= k->ay_kin_gate && a->kin_run == 0u)) {
        /* held while the car corners with no axle rolling free (still on the road it was measured on) */
        a->mu_road = ADD(a->mu_road, MUL(k->g_forget, 30, SUB(k->mu_nom, a->mu_road), FS, FS));
    }
}

/* adaptive.implausible: the fastest wheel's speed v and a_y - r v low-passed; outside the model (v below the
 * gate, or |a_y - r v| beyond vyd_gate: the body sliding sideways) restarts the hold. */
static void plausibility(vh_tfa_t *a, const vh_skfq_input_t *in, uint32_t *sat)
{
    const vh_tfa_params_t *k = &a->prm;
    int32_t w = in->omega[0], v;
    int i;
    for (i = 1; i < 4; ++i) {
        w = in->omega[i] > w ? in->omega[i] : w;
    }
    v = KM(k->k_rw, w, FO, FV);
    a->vyd_lp = ADD(a->vyd_lp, MUL(k->alpha_vyd, 30, SUB(SUB(in->ay, MUL(in->r, FW, v, FV, FA)), a->vyd_lp), FA, FA));
    if (v < k->v_gate || abs32(a->vyd_lp) > k->vyd_gate) {
        a->implausible = k->hold_implausible;
    } else if (a->implausible > 0u) {
        --a->implausible;
    }
}

/* adaptive.contradictions, the v_x part: the SKFMEC's v_x against the wheels' speeds r_w w_i: outside
 * [min - tol, max + tol], tol = vx_tol + vx_tol_rel max, is a contradiction (every wheel braking or driving
 * slips by less than that; a yaw rate's r t is inside it). */
static uint32_t vx_contradicts(const vh_tfa_t *a, const vh_skfq_t *f, const vh_skfq_input_t *in, uint32_t *sat)
{
    const vh_tfa_params_t *k = &a->prm;
    int32_t lo = in->omega[0], hi = in->omega[0], vlo, vhi, tol, vx;
    int i;
    for (i = 1; i < 4; ++i) {
        lo = in->omega[i] < lo ? in->omega[i] : lo;
        hi = in->omega[i] > hi ? in->omega[i] : hi;
    }
    vlo = KM(k->k_rw, lo, FO, FV);
    vhi = KM(k->k_rw, hi, FO, FV);
    tol = ADD(k->vx_tol, MUL(k->vx_tol_rel, 30, abs32(vhi), FV, FV));
    vx = KM(k->k_inv_svx, f->x[VH_SKF_VX], FX, FV);
    return vx > ADD(vhi, tol) || vx < SUB(vlo, tol) ? VH_TFA_C_VX : 0u;
}

/* The sprung weight from the ride heights (adaptive.estimate_mass): sum k_i s_i plus the links' vertical
 * forces (hf/tf)(Fy2 - Fy1) + (hr/tr)(Fy4 - Fy3) of the SKFMEC's forces [N], low-passed as the balance
 * (the filter starts at the first usable sample). */
static void ride_lowpass(vh_tfa_t *a, const vh_skfq_t *f, const int32_t *ride, uint32_t *sat)
{
    const vh_tfa_params_t *k = &a->prm;
    int32_t w = ADD(KM(k->k_link[0], SUB(f->fy[1], f->fy[0]), FN, FN), KM(k->k_link[1], SUB(f->fy[3], f->fy[2]), FN, FN));
    int i;
    for (i = 0; i < 4; ++i) {
        w = ADD(w, KM(k->k_spring[i >> 1], ride[i], FH, FN));
    }
    a->w_lp = a->ride_run == 0u ? w : ADD(a->w_lp, MUL(k->alpha_lp, 30, SUB(w, a->w_lp), FN, FN));
    if (a->ride_run < UINT32_MAX) {
        ++a->ride_run;
    }
}

/* sqrt(v0^2 + ... ) of n standard deviations in FB: the squares summed in 64 bits, each |v| clamped to
 * 2^29 (counted) so that four of them fit. */
static int32_t hypot_fb(const int32_t *v, int n, uint32_t *sat)
{
    int64_t acc = 0;
    int i;
    for (i = 0; i < n; ++i) {
        int32_t x = abs32(v[i]);
        if (x > (INT32_C(1) << 29)) {
            x = INT32_C(1) << 29;
            ++*sat;
        }
        acc += (int64_t)x * x;
    }
    return isqrt64(acc);
}

/* Each tyre's bound (adaptive.tyre_bounds; docs/tireforce.md, "Per-tyre bound"): the axle mean's std
 *   sigma_a^2 = k^2 P*_F / s_F^2 + F^2 sigma_k^2 + axle_abs^2 + (axle_rel F_axle)^2
 * (F the SKFMEC's axle mean, F_axle = k F), through the split's share g_i = F_i / F_axle, and the split's own
 *   sigma_i^2 = g_i^2 sigma_a^2 + (F_axle sigma_dFz / Fz_mean)^2,  sigma_dFz = lt_abs + lt_rel |dFz|;
 * bound_i = z sigma_i. */
static void bounds(vh_tfa_t *a, const vh_skfq_t *f, const int32_t *two, uint32_t *sat)
{
    const vh_tfa_params_t *k = &a->prm;
    const int32_t sk = vh_tfa_mass_std(a); /* sigma_k, Q(FP / 2) */
    int ax, i;
    for (ax = 0; ax < 2; ++ax) {
        const int l = 2 * ax, r = l + 1, j = VH_SKF_FYF + ax;
        const int32_t fax = vh_fix_rshift_rnd(two[ax], 1, sat);                      /* F_axle, FN */
        const int32_t mag = abs32(fax);
        const int32_t f0 = vh_fix_rshift_rnd((int64_t)f->fy[l] + f->fy[r], 1, sat); /* F, FN */
        /* sqrt(P*) in FX: P* (FP) shifted to 2 FX */
        const int32_t sp = isqrt64((int64_t)f->p[j * VH_SKFQ_NX + j] * ((int64_t)1 << (2 * FX - VH_SKFQ_FP)));
        const int32_t mean = vh_fix_rshift_rnd((int64_t)a->fz[l] + a->fz[r], 1, sat);
        const int32_t dz = vh_fix_rshift_rnd((int64_t)a->fz[r] - a->fz[l], 1, sat);
        const int32_t sdz = ADD(k->bound_lt_abs, MUL(k->bound_lt_rel, 30, abs32(dz), FN, FN));
        int32_t t[4], sa;
        t[0] = MUL(KM(f->prm.k_inv_sf[ax], sp, FX, FN), FN, a->k, FK, FB);
        t[1] = MUL(f0, FN, sk, FP / 2, FB);
        t[2] = k->bound_axle_abs;
        t[3] = MUL(k->bound_axle_rel, 30, mag, FN, FB);
        sa = hypot_fb(t, 4, sat);
        /* the split's: |F_axle| sigma_dFz / Fz_mean, the ratio at most 1 (a pair without load: anything) */
        t[1] = MUL(mag, FN, mean > sdz ? vh_fix_div(sdz, mean, 29, sat) : INT32_C(1) << 29, 29, FB);
        for (i = l; i <= r; ++i) {
            /* g_i in [0, 2] (Q29); 1 below 1 N of axle force, where the share is the loads' and sigma_a its floor */
            int32_t g = INT32_C(1) << 29;
            if (mag >= (INT32_C(1) << FN)) {
                /* F_i with F_axle's sign: the divisor > 0 (a saturated -2^31 negates to 2^31 - 1) */
                const int32_t same = fax < 0 ? (a->fy[i] == INT32_MIN ? INT32_MAX : -a->fy[i]) : a->fy[i];
                g = (int64_t)abs32(a->fy[i]) > 2 * (int64_t)mag ? INT32_C(1) << 30 : vh_fix_div(same, mag, 29, sat);
                g = g < 0 ? 0 : g;
            }
            t[0] = MUL(sa, FB, g, 29, FB);
            a->bound[i] = MUL(k->bound_z, 29, hypot_fb(t, 2, sat), FB, FN);
        }
    }
}

void vh_tfa_step(vh_tfa_t *a, const vh_skfq_t *f, const vh_skfq_input_t *in, unsigned mask, const int32_t *ride)
{
    const vh_tfa_params_t *k = &a->prm;
    uint32_t *sat = &a->sat;
    int32_t two[2];
    int i;
    ++a->steps;
    if ((mask & VH_SKF_ALL_VALID) == VH_SKF_ALL_VALID) {
        /* y = cos d (Fx1 + Fx2) + Fx3 + Fx4 - sin d 2 Fyf k - rho CdA vx |vx| / 2  [N] */
        const int32_t fyf = MUL(KM(f->prm.k_inv_sf[0], f->x[VH_SKF_FYF], FX, FN), FN, a->k, FK, FN);
        const int32_t vx = f->x[VH_SKF_VX];
        const int32_t vx2 = MUL(vx, FX, abs32(vx), FX, FX);
        const int64_t y = (int64_t)MUL(f->cs_delta[0], FD, ADD(f->fx[0], f->fx[1]), FN, FN) + f->fx[2] + f->fx[3] -
                          2 * (int64_t)MUL(f->cs_delta[1], FD, fyf, FN, FN) - KM(k->k_drag, vx2, FX, FN);
        a->y_lp = ADD(a->y_lp, MUL(k->alpha_lp, 30, SUB(vh_fix_sat32(y, sat), a->y_lp), FN, FN));
        a->ax_lp = ADD(a->ax_lp, MUL(k->alpha_lp, 30, SUB(in->ax, a->ax_lp), FA, FA));
        plausibility(a, in, sat);
        if (a->valid_run < UINT32_MAX) {
            ++a->valid_run;
        }
        if (a->valid_run > k->valid_min && f->x[VH_SKF_VX] >= k->vx_gate && abs32(in->ay) <= k->ay_gate) {
            /* the balance against the mass, normalised by sigma: |y - m^ a_x| > bal_tol + bal_tol_rel |y| */
            const int32_t yn = KM(k->k_y, a->y_lp, FN, FQ);
            const int32_t res = SUB(yn, MUL(KM(k->k_phi, a->ax_lp, FA, FQ), FQ, a->k, FK, FQ));
            a->bal = abs32(res) > ADD(k->bal_tol, MUL(k->bal_tol_rel, 30, abs32(yn), FQ, FQ)) ? VH_TFA_C_BALANCE : 0u;
        }
    } else {
        a->valid_run = 0u;
    }
    if (k->ride && ride != NULL) {
        ride_lowpass(a, f, ride, sat);
    } else {
        a->ride_run = 0u;
    }
    if (a->steps % k->decim == 0u && a->valid_run > k->valid_min && abs32(a->ax_lp) >= k->ax_gate &&
        abs32(in->ay) <= k->ay_gate && f->x[VH_SKF_VX] >= k->vx_gate) {
        mass_rls(a, KM(k->k_phi, a->ax_lp, FA, FQ), KM(k->k_y, a->y_lp, FN, FQ), sat); /* the balance, y = m a_x */
    }
    if (a->steps % k->decim == 0u && a->ride_run > k->ride_min && abs32(in->ay) <= k->ay_gate) {
        /* the ride heights: m = sprung weight / g + the unsprung mass, a regressor of 1; within the
         * balance's |a_y| gate too, where the roll-centre links' term (the least certain) is moderate */
        mass_rls(a, k->ride_phi, ADD(KM(k->k_ride, a->w_lp, FN, FQ), k->ride_unsprung), sat);
    }
    for (i = 0; i < 4; ++i) {
        a->fz[i] = MUL(f->fz[i], FN, a->k, FK, FN);
    }
    two[0] = MUL(ADD(f->fy[0], f->fy[1]), FN, a->k, FK, FN); /* 2 F_axle, mass-corrected */
    two[1] = MUL(ADD(f->fy[2], f->fy[3]), FN, a->k, FK, FN);
    if (k->transfer && ride != NULL) {
        /* adaptive.ride_transfer: at the axle's mean load, -+ (1/2)((k + 2 k_arb / 4t^2)(s_R - s_L) + (h/t) 2 F_axle) */
        int ax;
        for (ax = 0; ax < 2; ++ax) {
            const int l = 2 * ax, r = l + 1;
            const int32_t mean = vh_fix_rshift_rnd((int64_t)a->fz[l] + a->fz[r], 1, sat);
            int32_t d = vh_fix_rshift_rnd((int64_t)KM(k->k_roll[ax], SUB(ride[r], ride[l]), FH, FN) +
                                              KM(k->k_link[ax], two[ax], FN, FN), 1, sat);
            if (k->klt && mean > 0) {
                /* the patches' shift: + K_lt / (2t) 2 F_axle (mean^2 + d^2) / mean = ... mean (1 + (d / mean)^2) */
                const int32_t ratio = vh_fix_div(d, mean, 29, sat);            /* d / mean, Q29 */
                const int32_t q = ADD(mean, MUL(d, FN, ratio, 29, FN));          /* FN */
                d = ADD(d, MUL(KM(k->k_klt[ax], two[ax], FN, 30), 30, q, FN, FN));
            }
            a->fz[l] = SUB(mean, d);
            a->fz[r] = ADD(mean, d);
        }
    }
    if (k->friction) {
        if ((mask & VH_SKF_ALL_VALID) == VH_SKF_ALL_VALID && f->x[VH_SKF_VX] >= k->vx_gate) {
            slip_lowpass(a, f, in, sat);
        }
        if (a->steps % k->decim == 0u) {
            friction_update(a, f, sat);
        }
    }
    if (k->road) {
        if ((mask & VH_SKF_ALL_VALID) == VH_SKF_ALL_VALID) {
            road_lowpass(a, f, in, sat);
        } else {
            a->kin_run = 0u;
        }
        if (a->steps % k->decim == 0u) {
            road_update(a, f, in, two, sat);
        }
    }
    {
        int32_t mu4[4], cap[4];
        for (i = 0; i < 4; ++i) {
            mu4[i] = tyre_mu(a, i);
            cap[i] = k->combined ? ellipse(k, f->fx[i], a->fz[i], mu4[i], sat) : ONE30;
        }
        split(k, &a->fz[0], &mu4[0], &cap[0], two[0], &a->fy[0], &a->alpha[0], NULL, sat);
        split(k, &a->fz[2], &mu4[2], &cap[2], two[1], &a->fy[2], &a->alpha[1], NULL, sat);
    }
    bounds(a, f, two, sat);
    {
        /* contradictions: v_x against the wheels (held while the inputs are not valid), the mass at its clamp,
         * a load below zero or a friction at its floor; each starts the hold of DEGRADED */
        uint32_t c = (a->contra & VH_TFA_C_VX) | a->bal;
        if ((mask & VH_SKF_ALL_VALID) == VH_SKF_ALL_VALID) {
            c = vx_contradicts(a, f, in, sat);
        }
        if (a->k <= k->k_lo || a->k >= k->k_hi) {
            c |= VH_TFA_C_MASS;
        }
        for (i = 0; i < 4; ++i) {
            if (a->fz[i] < 0) {
                c |= VH_TFA_C_BOUNDS;
            }
        }
        if (a->mu[0] <= k->mu_floor || a->mu[1] <= k->mu_floor || (k->road && a->mu_road <= k->mu_floor)) {
            c |= VH_TFA_C_BOUNDS;
        }
        if (c != 0u && a->contra == 0u) {
            a->n_contra = vh_sat_add_u32(a->n_contra, 1u);
        }
        if (c != 0u) {
            a->implausible = k->hold_implausible;
        }
        a->contra = c;
    }
    a->health = f->health;
    if (a->health == VH_HEALTH_OK && (a->p > k->p_ok || a->implausible > 0u || a->contra != 0u)) {
        a->health = VH_HEALTH_DEGRADED; /* the mass estimate has not converged, or the car is outside the model */
    }
    for (i = 0; i < 4; ++i) {
        if (a->health == VH_HEALTH_OK && a->bound[i] > k->bound_max) {
            a->health = VH_HEALTH_DEGRADED; /* a force too uncertain to be used */
        }
    }
}

int32_t vh_tfa_mass_std(const vh_tfa_t *a)
{
    return isqrt64(a->p);
}

void vh_tfa_run(vh_tfa_t *a, vh_skfq_t *f, size_t n, const int32_t *u, const uint8_t *mask, const int32_t *ride,
                const uint8_t *ride_ok, int32_t *fy_out, int32_t *fz_out, int32_t *k_out, int32_t *p_out,
                uint8_t *health_out, int32_t *bound_out)
{
    size_t t;
    int i;
    for (t = 0; t < n; ++t) {
        const vh_skfq_input_t *in = vh_skfq_input_row(u, t);
        const unsigned m = mask ? mask[t] : (unsigned)VH_SKF_ALL_VALID;
        (void)vh_skfq_step(f, in, m);
        vh_tfa_step(a, f, in, m, ride != NULL && ride_ok != NULL && ride_ok[t] ? &ride[t * 4] : NULL);
        for (i = 0; i < 4; ++i) {
            fy_out[t * 4 + (size_t)i] = a->fy[i];
            fz_out[t * 4 + (size_t)i] = a->fz[i];
            if (bound_out != NULL) {
                bound_out[t * 4 + (size_t)i] = a->bound[i];
            }
        }
        k_out[t] = a->k;
        p_out[t] = a->p;
        health_out[t] = a->health;
    }
}
