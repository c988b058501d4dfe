/* vh_skfq.c - SKFMEC in fixed point, see vh_skfq.h. Integer only: no float, no double.
 *
 * The code follows vh_skf.c step by step (same names); every line says which format it produces
 * when that is not the destination's. KM(k, v, fin, fout) multiplies by an off-line constant.
 */
#include "vh_kf.h"
#include "vh_skfq.h"
#include "vh_tf_types.h"
#include "vh_types.h"

#define NX VH_SKFQ_NX
#define NY VH_SKFQ_NY
#define FX VH_SKFQ_FX
#define FA VH_SKFQ_FA
#define FW VH_SKFQ_FW
#define FD VH_SKFQ_FD
#define FO VH_SKFQ_FO
#define FT VH_SKFQ_FT
#define FN VH_SKFQ_FN
#define FR VH_SKFQ_FR
#define FWD VH_SKFQ_FWD
#define FP VH_SKFQ_FP
#define FPHI VH_SKFQ_FPHI
#define FH VH_SKFQ_FH
#define FU VH_SKFQ_FU
#define FK VH_SKFQ_FK

#define INIT_STEPS 400u

#define KM(k, v, fin, fout) vh_fix_kmul((k), (v), (fin), (fout), sat)
#define ADD(a, b) vh_fix_add((a), (b), sat)
#define SUB(a, b) vh_fix_sub((a), (b), sat)
#define MUL(a, fa, b, fb, fo) vh_fix_mul((a), (fa), (b), (fb), (fo), sat)

/* Every guarded dot product here is at most NX long: within vh_fix_row_pack's precondition. */
typedef char dot_length_check[(NX <= VH_FIX_DOT_MAX) ? 1 : -1];

/* vh_skfq_input_row passes rows of 13 int32 as vh_skfq_input_t: no padding allowed. */
typedef char input_layout_check[(sizeof(vh_skfq_input_t) == VH_SKFQ_NU * sizeof(int32_t)) ? 1 : -1];

/* No <string.h>: the integer-only check builds this file with a bare cross compiler. */
static void zero32(int32_t *d, int n)
{
    int i;
    for (i = 0; i < n; ++i) {
        d[i] = 0;
    }
}

static void copy32(int32_t *d, const int32_t *s, int n)
{
    int i;
    for (i = 0; i < n; ++i) {
        d[i] = s[i];
    }
}

/* round(sum a[i] b[i sb]) from Q.fab products to Q.fo, through the guarded accumulator, with a packed
 * row a: Phi's and H's rows are sparse (at most 31 of 49 and 11 of 28 entries nonzero) */
static int32_t rowq(const vh_fix_row_t *a, const int32_t *b, int sb, int fab, int fo, uint32_t *sat)
{
    return vh_fix_rshift_rnd(vh_fix_row_dot(a, b, sb), fab - VH_FIX_GUARD - fo, sat);
}

static int k_ok(vh_fix_k_t k)
{
    return k.m == 0 || ((k.m >= (INT32_C(1) << 30) || k.m <= -(INT32_C(1) << 30)) && k.e > -31 && k.e < 120);
}

int vh_skfq_init(vh_skfq_t *f, const vh_skfq_params_t *prm)
{
    /* every constant normalised: catches hand-made or corrupted parameter sets */
    const vh_fix_k_t ks[] = {prm->c_vx0, prm->c_vy1, prm->c_vy4, prm->c_r2, prm->c_p1, prm->c_p4, prm->c_phi_p,
                             prm->c_fy_p[0], prm->c_fy_p[1], prm->k_m_rvy, prm->k_m_rvx, prm->k_mse_pr,
                             prm->k_mse_rvx, prm->k_kphi, prm->k_cphi, prm->k_lf, prm->k_lr, prm->k_tf, prm->k_tr,
                             prm->k_hf, prm->k_hr, prm->k_fz_ax, prm->k_lat_ay[0], prm->k_lat_ay[1],
                             prm->k_lat_phi[0], prm->k_lat_phi[1], prm->k_gy[0], prm->k_gy[1], prm->k_inv_fz[0],
                             prm->k_inv_fz[1], prm->k_drho[0], prm->k_drho[1], prm->k_phi, prm->k_inv_sf[0],
                             prm->k_inv_sf[1], prm->k_inv_ts, prm->k_alpha, prm->k_inv_rw, prm->k_iw_rw, prm->k_sr,
                             prm->k_sp, prm->k_inv_m, prm->k_mse_pr_m, prm->k_ixx_det, prm->k_mse_det,
                             prm->k_seed_vx, prm->k_seed_fy[0], prm->k_seed_fy[1], prm->k_seed_phi};
    int i;
    for (i = 0; i < (int)(sizeof ks / sizeof ks[0]); ++i) {
        if (!k_ok(ks[i])) {
            return VH_EINVAL;
        }
    }
    for (i = 0; i < NX; ++i) {
        if (prm->q[i] < 0 || prm->p0[i] <= 0 || !k_ok(prm->k_gp[i]) || prm->s_num[i] <= 0 || prm->s_den[i] <= 0) {
            return VH_EINVAL;
        }
    }
    for (i = 0; i < NY; ++i) {
        if (prm->r[i] <= 0) {
            return VH_EINVAL;
        }
    }
    if (prm->p_cap <= 0 || prm->p_max <= prm->p_cap || prm->x_max <= 0 || (prm->mec != 0 && prm->mec != 1)) {
        return VH_EINVAL;
    }
    {
        static const vh_skfq_t zero = {0};
        *f = zero;
    }
    f->prm = *prm;
    vh_skfq_reset(f);
    return VH_OK;
}

static void restart(vh_skfq_t *f)
{
    int i;
    zero32(f->x, (int)(sizeof f->x / sizeof f->x[0]));
    zero32(f->p, (int)(sizeof f->p / sizeof f->p[0]));
    zero32(f->innov, (int)(sizeof f->innov / sizeof f->innov[0]));
    zero32(f->wdot, (int)(sizeof f->wdot / sizeof f->wdot[0]));
    zero32(f->fx, (int)(sizeof f->fx / sizeof f->fx[0]));
    zero32(f->fz, (int)(sizeof f->fz / sizeof f->fz[0]));
    zero32(f->fy, (int)(sizeof f->fy / sizeof f->fy[0]));
    f->cs_delta[0] = INT32_C(1) << FD;
    f->cs_delta[1] = 0;
    for (i = 0; i < NX; ++i) {
        f->p[i * NX + i] = f->prm.p0[i];
    }
    f->nu_ay = 0;
    vh_kf_restart(&f->steps, &f->x_init, &f->health);
}

void vh_skfq_reset(vh_skfq_t *f)
{
    restart(f);
    f->resets = 0u;
    f->caps = 0u;
    f->sat = 0u;
    f->sat_step = 0u;
}

typedef struct {
    int32_t c, s;      /* FD */
    int32_t fx[4];     /* FN */
    int32_t ax, ay;    /* FA, 0 when not valid */
    int32_t nu_ay;     /* FX, 0 without the MEC */
} ctx_t;

typedef struct {
    int32_t sfx, sfy_front, sfy, smz, smx;         /* FN; smx includes -kphi phi - cphi p */
    int32_t d_sfx[3], d_sfy[3], d_smz[3], d_smx[3]; /* FN per unit of phi*, Fyf*, Fyr*; d_smx[0] has -kphi */
    int32_t fz[4], fy[4];                          /* FN */
} sums_t;

/* eq. 39 (+ rear), eq. 36-37 and the appendix sums with their derivatives, at the scaled state x. */
static void sums(const vh_skfq_params_t *k, const ctx_t *u, const int32_t x[NX], sums_t *sm, uint32_t *sat)
{
    int32_t sphi, cphi, rho[4], drho[2], fyn[2], dfy[3][4];
    int v, a;
    vh_fix_sincos(KM(k->k_phi, x[VH_SKF_PHI], FX, FD), &sphi, &cphi, sat);
    for (a = 0; a < 2; ++a) { /* axle: 0 front (Fz1, Fz2), 1 rear (Fz3, Fz4) */
        const int32_t dax = KM(k->k_fz_ax, u->ax, FA, FN);
        const int32_t base = a == 0 ? SUB(k->fz0[0], dax) : ADD(k->fz0[1], dax);
        const int32_t lat = SUB(KM(k->k_lat_ay[a], u->ay, FA, FN), KM(k->k_lat_phi[a], sphi, FD, FN));
        sm->fz[2 * a] = SUB(base, lat);
        sm->fz[2 * a + 1] = ADD(base, lat);
        if (a == 0) { /* eq. 39's compensation */
            sm->fz[0] = ADD(sm->fz[0], KM(k->k_gy[0], u->nu_ay, FX, FN));
            sm->fz[1] = ADD(sm->fz[1], KM(k->k_gy[1], u->nu_ay, FX, FN));
        }
        rho[2 * a] = KM(k->k_inv_fz[a], sm->fz[2 * a], FN, FR);
        rho[2 * a + 1] = KM(k->k_inv_fz[a], sm->fz[2 * a + 1], FN, FR);
        drho[a] = KM(k->k_drho[a], cphi, FD, FR);
        fyn[a] = KM(k->k_inv_sf[a], x[VH_SKF_FYF + a], FX, FN);
    }
    for (v = 0; v < 4; ++v) {
        const int a = v / 2;
        sm->fy[v] = MUL(fyn[a], FN, rho[v], FR, FN); /* eq. 36-37 */
        dfy[0][v] = MUL(fyn[a], FN, (v % 2 == 0) ? drho[a] : SUB(0, drho[a]), FR, FN);
        dfy[1][v] = a == 0 ? KM(k->k_inv_sf[0], rho[v], FR, FN) : 0;
        dfy[2][v] = a == 1 ? KM(k->k_inv_sf[1], rho[v], FR, FN) : 0;
    }
    {
        const int32_t fx12 = ADD(u->fx[0], u->fx[1]);
        const int32_t fy12 = ADD(sm->fy[0], sm->fy[1]), fy34 = ADD(sm->fy[2], sm->fy[3]);
        const int32_t tf_term = ADD(MUL(u->c, FD, SUB(u->fx[1], u->fx[0]), FN, FN),
                                    MUL(u->s, FD, SUB(sm->fy[0], sm->fy[1]), FN, FN));
        /* appendix */
        sm->sfx = ADD(SUB(MUL(u->c, FD, fx12, FN, FN), MUL(u->s, FD, fy12, FN, FN)), ADD(u->fx[2], u->fx[3]));
        sm->sfy_front = ADD(MUL(u->s, FD, fx12, FN, FN), MUL(u->c, FD, fy12, FN, FN));
        sm->sfy = ADD(sm->sfy_front, fy34);
        sm->smz = ADD(SUB(KM(k->k_lf, sm->sfy_front, FN, FN), KM(k->k_lr, fy34, FN, FN)),
                      ADD(KM(k->k_tf, tf_term, FN, FN), KM(k->k_tr, SUB(u->fx[3], u->fx[2]), FN, FN)));
        sm->smx = SUB(ADD(KM(k->k_hf, sm->sfy_front, FN, FN), KM(k->k_hr, fy34, FN, FN)),
                      ADD(KM(k->k_kphi, x[VH_SKF_PHI], FX, FN), KM(k->k_cphi, x[VH_SKF_P], FX, FN)));
    }
    for (v = 0; v < 3; ++v) {
        const int32_t *d = dfy[v];
        const int32_t d12 = ADD(d[0], d[1]), d34 = ADD(d[2], d[3]);
        const int32_t dfront = MUL(u->c, FD, d12, FN, FN);
        sm->d_sfx[v] = SUB(0, MUL(u->s, FD, d12, FN, FN));
        sm->d_sfy[v] = ADD(dfront, d34);
        sm->d_smz[v] = ADD(SUB(KM(k->k_lf, dfront, FN, FN), KM(k->k_lr, d34, FN, FN)),
                           KM(k->k_tf, MUL(u->s, FD, SUB(d[0], d[1]), FN, FN), FN, FN));
        sm->d_smx[v] = ADD(KM(k->k_hf, dfront, FN, FN), KM(k->k_hr, d34, FN, FN));
    }
    sm->d_smx[0] = SUB(sm->d_smx[0], KM(k->k_kphi, INT32_C(1) << FX, FX, FN));
}

/* First usable sample, as vh_skf's seed_state. */
static void seed_state(vh_skfq_t *f, const vh_skfq_input_t *in, const int32_t z[NY], unsigned mask, uint32_t *sat)
{
    const vh_skfq_params_t *k = &f->prm;
    const int64_t wsum = (int64_t)in->omega[0] + in->omega[1] + in->omega[2] + in->omega[3];
    int i;
    f->x[VH_SKF_VX] = KM(k->k_seed_vx, vh_fix_sat32(wsum, sat), FO, FX);
    f->x[VH_SKF_VY] = 0;
    f->x[VH_SKF_R] = z[VH_SKF_YR];
    f->x[VH_SKF_PHI] = KM(k->k_seed_phi, in->ay, FA, FX);
    f->x[VH_SKF_P] = (mask & VH_SKF_Y_P) ? z[VH_SKF_YP] : 0;
    f->x[VH_SKF_FYF] = KM(k->k_seed_fy[0], in->ay, FA, FX);
    f->x[VH_SKF_FYR] = KM(k->k_seed_fy[1], in->ay, FA, FX);
    for (i = 0; i < 4; ++i) {
        f->w_prev[i] = in->omega[i];
        f->wdot[i] = 0;
    }
    f->x_init = 1u;
}

static int sane(const vh_skfq_t *f)
{
    int i;
    for (i = 0; i < NX; ++i) {
        const int32_t d = f->p[i * NX + i];
        const int observable = i != VH_SKF_VX && i != VH_SKF_VY; /* vx, vy are clamped instead */
        if (d <= 0 || d > f->prm.p_max || (observable && (f->x[i] > f->prm.x_max || f->x[i] < -f->prm.x_max))) {
            return 0;
        }
    }
    return 1;
}

/* sat += sat_step, saturating: a diverged step's saturations count as well */
static void add_step_saturations(vh_skfq_t *f)
{
    f->sat = (UINT32_MAX - f->sat < f->sat_step) ? UINT32_MAX : f->sat + f->sat_step;
}

int vh_skfq_step(vh_skfq_t *f, const vh_skfq_input_t *in, unsigned mask)
{
    const vh_skfq_params_t *k = &f->prm;
    uint32_t *sat = &f->sat_step;
    int32_t z[NY], dx[NX], dg[4][NX], phi[NX * NX], tmp[NX * NX], yhat[NY], hj[NY * NX];
    int32_t xprior[NX], dxu[NX], u[NX], kc[NX], sk[NX];
    vh_fix_row_t phi_row[NX], h_row;
    int32_t rvx, rvy, pr, cphi_unit;
    sums_t sm;
    ctx_t ctx;
    int i, j, l;

    f->sat_step = 0u;
    /* scaled measurements z* = T y: ax, ay in m/s^2, r* = s_r r, p* = s_p p */
    z[VH_SKF_AX] = vh_fix_convert(in->ax, FA, FX, sat);
    z[VH_SKF_AY] = vh_fix_convert(in->ay, FA, FX, sat);
    z[VH_SKF_YR] = KM(k->k_sr, in->r, FW, FX);
    z[VH_SKF_YP] = KM(k->k_sp, in->p, FW, FX);
    if (!f->x_init) {
        if ((mask & VH_SKF_SEED_VALID) != VH_SKF_SEED_VALID) {
            return 0; /* wait for a usable first sample */
        }
        seed_state(f, in, z, mask, sat);
    }

    /* wheel accelerations and eq. 30 */
    if (mask & VH_SKF_U_VALID) {
        for (i = 0; i < 4; ++i) {
            const int32_t rate = KM(k->k_inv_ts, SUB(in->omega[i], f->w_prev[i]), FO, FWD);
            f->wdot[i] = ADD(f->wdot[i], KM(k->k_alpha, SUB(rate, f->wdot[i]), FWD, FWD));
            f->w_prev[i] = in->omega[i];
            f->fx[i] = SUB(KM(k->k_inv_rw, in->torque[i], FT, FN), KM(k->k_iw_rw, f->wdot[i], FWD, FN));
        }
        vh_fix_sincos(in->delta, &f->cs_delta[1], &f->cs_delta[0], sat);
    }
    ctx.c = f->cs_delta[0];
    ctx.s = f->cs_delta[1];
    copy32(ctx.fx, f->fx, (int)(sizeof ctx.fx / sizeof ctx.fx[0]));
    ctx.ax = (mask & VH_SKF_Y_AX) ? in->ax : 0;
    ctx.ay = (mask & VH_SKF_Y_AY) ? in->ay : 0;
    ctx.nu_ay = k->mec ? f->nu_ay : 0;

    /* predict: x* += C g(x) + Ts Gp (r* - r^*)  (eq. 35, 38) */
    sums(k, &ctx, f->x, &sm, sat);
    rvx = MUL(f->x[VH_SKF_R], FX, f->x[VH_SKF_VX], FX, FK);
    rvy = MUL(f->x[VH_SKF_R], FX, f->x[VH_SKF_VY], FX, FK);
    pr = MUL(f->x[VH_SKF_P], FX, f->x[VH_SKF_R], FX, FK);
    {
        const int32_t g0 = SUB(ADD(sm.sfx, KM(k->k_m_rvy, rvy, FK, FN)), KM(k->k_mse_pr, pr, FK, FN));
        const int32_t g1 = SUB(sm.sfy, KM(k->k_m_rvx, rvx, FK, FN));
        const int32_t g4 = ADD(sm.smx, KM(k->k_mse_rvx, rvx, FK, FN));
        const int32_t p_s = f->x[VH_SKF_P];
        dx[VH_SKF_VX] = KM(k->c_vx0, g0, FN, FX);
        dx[VH_SKF_VY] = ADD(KM(k->c_vy1, g1, FN, FX), KM(k->c_vy4, g4, FN, FX));
        dx[VH_SKF_R] = KM(k->c_r2, sm.smz, FN, FX);
        dx[VH_SKF_PHI] = KM(k->c_phi_p, p_s, FX, FX);
        dx[VH_SKF_P] = ADD(KM(k->c_p1, g1, FN, FX), KM(k->c_p4, g4, FN, FX));
        dx[VH_SKF_FYF] = KM(k->c_fy_p[0], p_s, FX, FX);
        dx[VH_SKF_FYR] = KM(k->c_fy_p[1], p_s, FX, FX);
    }
    if (k->mec && (mask & VH_SKF_Y_R)) {
        const int32_t nu_r = SUB(z[VH_SKF_YR], f->x[VH_SKF_R]);
        for (i = 0; i < NX; ++i) {
            dx[i] = ADD(dx[i], KM(k->k_gp[i], nu_r, FX, FX));
        }
    }
    /* Jacobian of g per scaled unit (rows g0, g1, g2, g4), FN */
    cphi_unit = KM(k->k_cphi, INT32_C(1) << FX, FX, FN);
    zero32(&dg[0][0], 4 * NX);
    dg[0][VH_SKF_VY] = KM(k->k_m_rvy, f->x[VH_SKF_R], FX, FN);
    dg[0][VH_SKF_R] = SUB(KM(k->k_m_rvy, f->x[VH_SKF_VY], FX, FN), KM(k->k_mse_pr, f->x[VH_SKF_P], FX, FN));
    dg[0][VH_SKF_P] = SUB(0, KM(k->k_mse_pr, f->x[VH_SKF_R], FX, FN));
    dg[1][VH_SKF_VX] = SUB(0, KM(k->k_m_rvx, f->x[VH_SKF_R], FX, FN));
    dg[1][VH_SKF_R] = SUB(0, KM(k->k_m_rvx, f->x[VH_SKF_VX], FX, FN));
    dg[3][VH_SKF_VX] = KM(k->k_mse_rvx, f->x[VH_SKF_R], FX, FN);
    dg[3][VH_SKF_R] = KM(k->k_mse_rvx, f->x[VH_SKF_VX], FX, FN);
    dg[3][VH_SKF_P] = SUB(0, cphi_unit);
    for (j = 0; j < 3; ++j) {
        const int col = j == 0 ? VH_SKF_PHI : VH_SKF_FYF + j - 1;
        dg[0][col] = sm.d_sfx[j];
        dg[1][col] = sm.d_sfy[j];
        dg[2][col] = sm.d_smz[j];
        dg[3][col] = sm.d_smx[j];
    }
    for (i = 0; i < NX; ++i) {
        f->x[i] = ADD(f->x[i], dx[i]);
    }
    /* Phi* = I + C dg (FPHI) */
    zero32(phi, (int)(sizeof phi / sizeof phi[0]));
    for (j = 0; j < NX; ++j) {
        phi[VH_SKF_VX * NX + j] = KM(k->c_vx0, dg[0][j], FN, FPHI);
        phi[VH_SKF_VY * NX + j] = ADD(KM(k->c_vy1, dg[1][j], FN, FPHI), KM(k->c_vy4, dg[3][j], FN, FPHI));
        phi[VH_SKF_R * NX + j] = KM(k->c_r2, dg[2][j], FN, FPHI);
        phi[VH_SKF_P * NX + j] = ADD(KM(k->c_p1, dg[1][j], FN, FPHI), KM(k->c_p4, dg[3][j], FN, FPHI));
    }
    phi[VH_SKF_PHI * NX + VH_SKF_P] = k->phi_row[0];
    phi[VH_SKF_FYF * NX + VH_SKF_P] = k->phi_row[1];
    phi[VH_SKF_FYR * NX + VH_SKF_P] = k->phi_row[2];
    for (i = 0; i < NX; ++i) {
        phi[i * NX + i] = ADD(phi[i * NX + i], INT32_C(1) << FPHI);
    }
    /* P- = Phi P Phi^T + Q: tmp = Phi P (FP), then the upper triangle of tmp Phi^T, mirrored */
    for (i = 0; i < NX; ++i) {
        vh_fix_row_pack(phi + i * NX, NX, &phi_row[i]);
    }
    for (i = 0; i < NX; ++i) {
        for (j = 0; j < NX; ++j) {
            tmp[i * NX + j] = rowq(&phi_row[i], f->p + j, NX, FPHI + FP, FP, sat);
        }
    }
    for (i = 0; i < NX; ++i) {
        for (j = i; j < NX; ++j) {
            const int32_t v = rowq(&phi_row[j], tmp + i * NX, 1, FPHI + FP, FP, sat);
            f->p[i * NX + j] = v;
            f->p[j * NX + i] = v;
        }
        f->p[i * NX + i] = ADD(f->p[i * NX + i], k->q[i]);
    }

    /* update: outputs and H* at the prior, sequential scalar updates */
    sums(k, &ctx, f->x, &sm, sat);
    pr = MUL(f->x[VH_SKF_P], FX, f->x[VH_SKF_R], FX, FK);
    yhat[VH_SKF_AX] = SUB(KM(k->k_inv_m, sm.sfx, FN, FX), KM(k->k_mse_pr_m, pr, FK, FX));
    yhat[VH_SKF_AY] = ADD(KM(k->k_ixx_det, sm.sfy, FN, FX), KM(k->k_mse_det, sm.smx, FN, FX));
    yhat[VH_SKF_YR] = f->x[VH_SKF_R];
    yhat[VH_SKF_YP] = f->x[VH_SKF_P];
    zero32(hj, (int)(sizeof hj / sizeof hj[0]));
    hj[VH_SKF_AX * NX + VH_SKF_R] = SUB(0, KM(k->k_mse_pr_m, f->x[VH_SKF_P], FX, FH));
    hj[VH_SKF_AX * NX + VH_SKF_P] = SUB(0, KM(k->k_mse_pr_m, f->x[VH_SKF_R], FX, FH));
    for (j = 0; j < 3; ++j) {
        const int col = j == 0 ? VH_SKF_PHI : VH_SKF_FYF + j - 1;
        hj[VH_SKF_AX * NX + col] = KM(k->k_inv_m, sm.d_sfx[j], FN, FH);
        hj[VH_SKF_AY * NX + col] = ADD(KM(k->k_ixx_det, sm.d_sfy[j], FN, FH), KM(k->k_mse_det, sm.d_smx[j], FN, FH));
    }
    hj[VH_SKF_AY * NX + VH_SKF_P] = KM(k->k_mse_det, SUB(0, cphi_unit), FN, FH);
    hj[VH_SKF_YR * NX + VH_SKF_R] = INT32_C(1) << FH;
    hj[VH_SKF_YP * NX + VH_SKF_P] = INT32_C(1) << FH;
    copy32(xprior, f->x, (int)(sizeof xprior / sizeof xprior[0]));
    for (i = 0; i < NY; ++i) {
        const int32_t *h = hj + i * NX;
        int32_t e, s;
        f->innov[i] = (mask & (1u << i)) ? SUB(z[i], yhat[i]) : 0;
        if (!(mask & (1u << i))) {
            continue;
        }
        for (j = 0; j < NX; ++j) {
            dxu[j] = SUB(f->x[j], xprior[j]);
        }
        vh_fix_row_pack(h, NX, &h_row);
        e = SUB(f->innov[i], rowq(&h_row, dxu, 1, FH + FX, FX, sat));
        for (j = 0; j < NX; ++j) { /* u = P h^T (FU) */
            u[j] = rowq(&h_row, f->p + j * NX, 1, FH + FP, FU, sat);
        }
        s = ADD(k->r[i], rowq(&h_row, u, 1, FH + FU, FU, sat));
        if (s <= 0) {
            goto diverged;
        }
        for (j = 0; j < NX; ++j) { /* k = u / s (FU); x += k e */
            kc[j] = vh_fix_div(u[j], s, FU, sat);
            sk[j] = MUL(s, FU, kc[j], FU, FU);
            f->x[j] = ADD(f->x[j], MUL(kc[j], FU, e, FX, FX));
        }
        /* expanded Joseph form P - k u^T - u k^T + s k k^T, upper triangle mirrored */
        for (j = 0; j < NX; ++j) {
            for (l = j; l < NX; ++l) {
                int32_t v = SUB(f->p[j * NX + l], MUL(kc[j], FU, u[l], FU, FP));
                v = SUB(v, MUL(u[j], FU, kc[l], FU, FP));
                v = ADD(v, MUL(sk[j], FU, kc[l], FU, FP));
                f->p[j * NX + l] = v;
                f->p[l * NX + j] = v;
            }
        }
    }
    f->nu_ay = f->innov[VH_SKF_AY];

    /* variance cap by congruence with 1/2 at i: row and column halved, the diagonal quartered */
    for (i = 0; i < NX; ++i) {
        if (f->p[i * NX + i] > k->p_cap) {
            for (j = 0; j < NX; ++j) {
                if (j != i) {
                    f->p[i * NX + j] = vh_fix_rshift_rnd(f->p[i * NX + j], 1, sat);
                    f->p[j * NX + i] = f->p[i * NX + j];
                }
            }
            f->p[i * NX + i] = vh_fix_rshift_rnd(f->p[i * NX + i], 2, sat);
            ++f->caps;
        }
    }
    /* vx, vy: unobservable, held in |x*| <= x_max (as vh_skf) */
    for (i = VH_SKF_VX; i <= VH_SKF_VY; ++i) {
        f->x[i] = f->x[i] > k->x_max ? k->x_max : (f->x[i] < -k->x_max ? -k->x_max : f->x[i]);
    }
    if (!sane(f)) {
        goto diverged;
    }

    /* outputs at the estimate (eq. 39 with this step's a_y innovation, eq. 36-37) */
    ctx.nu_ay = k->mec ? f->nu_ay : 0;
    sums(k, &ctx, f->x, &sm, sat);
    copy32(f->fz, sm.fz, (int)(sizeof f->fz / sizeof f->fz[0]));
    copy32(f->fy, sm.fy, (int)(sizeof f->fy / sizeof f->fy[0]));
    f->health = vh_kf_step_health(&f->steps, (mask & VH_SKF_ALL_VALID) != VH_SKF_ALL_VALID || f->sat_step != 0u,
                                  INIT_STEPS);
    add_step_saturations(f);
    return 0;

diverged:
    restart(f);
    add_step_saturations(f);
    return vh_kf_fault(&f->resets, &f->health);
}

uint32_t vh_skfq_run(vh_skfq_t *f, size_t n, const int32_t *u, const uint8_t *mask, int32_t *x_out,
                     int32_t *fy_out, int32_t *fz_out, int32_t *p_out, uint8_t *health_out)
{
    size_t t;
    uint32_t resets = 0u;
    for (t = 0; t < n; ++t) {
        resets += (uint32_t)vh_skfq_step(f, vh_skfq_input_row(u, t), mask ? mask[t] : VH_SKF_ALL_VALID);
        copy32(x_out + t * NX, f->x, NX);
        copy32(fy_out + t * 4, f->fy, 4);
        copy32(fz_out + t * 4, f->fz, 4);
        if (p_out) {
            copy32(p_out + t * NX * NX, f->p, NX * NX);
        }
        if (health_out) {
            health_out[t] = f->health;
        }
    }
    return resets;
}
