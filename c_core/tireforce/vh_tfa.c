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
        prm->k_lo <= 0 || prm->k_hi <= prm->k_lo || prm->m_num <= 0 || prm->m_den <= 0) {
        return VH_EINVAL;
    }
    for (i = 0; i < NZ * NA; ++i) {
        if (prm->table[i] < 0) {
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
    for (i = 0; i < 4; ++i) {
        a->fy[i] = 0;
        a->fz[i] = 0;
    }
    a->sat = 0u;
    a->health = VH_HEALTH_INIT;
}

/* One RLS update of y = m a_x in the mass ratio k (adaptive.rls_step): K = P phi / (1 + phi P phi),
 * k += K (y - phi k) (clamped), P = (1 - K phi) P / lambda in [P_floor, P0]. */
static void rls(vh_tfa_t *a, uint32_t *sat)
{
    const vh_tfa_params_t *k = &a->prm;
    const int32_t ph = KM(k->k_phi, a->ax_lp, FA, FQ);
    const int32_t yv = KM(k->k_y, a->y_lp, FN, FQ);
    const int32_t u = MUL(a->p, FP, ph, FQ, 24);                       /* P phi, Q24 */
    const int32_t s = ADD(INT32_C(1) << 16, MUL(ph, FQ, u, 24, 16));    /* 1 + phi P phi, Q16 */
    const int32_t g = vh_fix_div(u, s, 16, sat);                        /* K, Q24 */
    const int32_t e = SUB(yv, MUL(ph, FQ, a->k, FK, FQ));               /* y - phi k, Q21 */
    const int64_t kn = (int64_t)a->k + vh_fix_asr64((int64_t)g * e + (INT64_C(1) << 15), 16); /* Q29 */
    const int32_t kp = MUL(g, 24, ph, FQ, 30);                          /* K phi in [0, 1), Q30 */
    int32_t p = MUL(MUL(a->p, FP, SUB(ONE30, kp), 30, FP), FP, k->inv_forget, 30, FP);
    a->k = kn > k->k_hi ? k->k_hi : (kn < k->k_lo ? k->k_lo : (int32_t)kn);
    a->p = p > k->p0 ? k->p0 : (p < k->p_floor ? k->p_floor : p);
    ++a->updates;
}

/* The tyre's force at load knot weight (iz, wz) and every slip-angle knot, FN. */
static void forces_at(const vh_tfa_params_t *k, int32_t fz, int32_t out[NA], uint32_t *sat)
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
    for (j = 0; j < NA; ++j) {
        const int64_t v = (int64_t)k->table[iz * NA + j] * ((INT32_C(1) << FZW) - wz) +
                          (int64_t)k->table[(iz + 1) * NA + j] * wz;
        out[j] = vh_fix_rshift_rnd(v, FZW, sat);
    }
}

/* An axle's 2 F_axle (FN) to its two tyres: the first slip-angle knot where the pair's sum reaches
 * it, linear between that knot and the one before; beyond the pair's peak, the share at the peak. */
static void split(const vh_tfa_params_t *k, const int32_t *fz, int32_t two_axle, int32_t *out, uint32_t *sat)
{
    int32_t f0[NA], f1[NA], tot[NA];
    const int32_t want = abs32(two_axle);
    int32_t share;
    int j, top = 0;
    forces_at(k, fz[0], f0, sat);
    forces_at(k, fz[1], f1, sat);
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
    } else if (want == 0) {
        share = vh_fix_div(f0[1], tot[1], 30, sat);
    } else {
        const int32_t dt = tot[j] - tot[j - 1];
        const int32_t t = dt > 0 ? vh_fix_div(want - tot[j - 1], dt, 30, sat) : 0;  /* Q30 */
        const int32_t fin = ADD(f0[j - 1], MUL(t, 30, SUB(f0[j], f0[j - 1]), FN, FN));
        share = vh_fix_div(fin, want, 30, sat);
    }
    out[0] = MUL(two_axle, FN, share, 30, FN);
    out[1] = SUB(two_axle, out[0]);
}

void vh_tfa_step(vh_tfa_t *a, const vh_skfq_t *f, const vh_skfq_input_t *in, unsigned mask)
{
    const vh_tfa_params_t *k = &a->prm;
    uint32_t *sat = &a->sat;
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
        if (a->valid_run < UINT32_MAX) {
            ++a->valid_run;
        }
    } else {
        a->valid_run = 0u;
    }
    if (a->steps % k->decim == 0u && a->valid_run > k->valid_min && abs32(a->ax_lp) >= k->ax_gate &&
        abs32(in->ay) <= k->ay_gate && f->x[VH_SKF_VX] >= k->vx_gate) {
        rls(a, sat);
    }
    for (i = 0; i < 4; ++i) {
        a->fz[i] = MUL(f->fz[i], FN, a->k, FK, FN);
    }
    split(k, &a->fz[0], MUL(ADD(f->fy[0], f->fy[1]), FN, a->k, FK, FN), &a->fy[0], sat);
    split(k, &a->fz[2], MUL(ADD(f->fy[2], f->fy[3]), FN, a->k, FK, FN), &a->fy[2], sat);
    a->health = f->health;
    if (a->health == VH_HEALTH_OK && a->p > k->p_ok) {
        a->health = VH_HEALTH_DEGRADED; /* the mass estimate has not converged */
    }
}

void vh_tfa_run(vh_tfa_t *a, vh_skfq_t *f, size_t n, const int32_t *u, const uint8_t *mask, int32_t *fy_out,
                int32_t *fz_out, int32_t *k_out, int32_t *p_out, uint8_t *health_out)
{
    size_t t;
    int i;
    for (t = 0; t < n; ++t) {
        const vh_skfq_input_t *in = (const vh_skfq_input_t *)(const void *)(u + t * VH_SKFQ_NU); /* same layout */
        const unsigned m = mask ? mask[t] : (unsigned)VH_SKF_ALL_VALID;
        (void)vh_skfq_step(f, in, m);
        vh_tfa_step(a, f, in, m);
        for (i = 0; i < 4; ++i) {
            fy_out[t * 4 + (size_t)i] = a->fy[i];
            fz_out[t * 4 + (size_t)i] = a->fz[i];
        }
        k_out[t] = a->k;
        p_out[t] = a->p;
        health_out[t] = a->health;
    }
}
