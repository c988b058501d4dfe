/* vh_roll_impl.c - the roll UKF (eq. 13-26) and sliding-mode controller (eq. 27-35) in one
 * precision. Not compiled on its own: vh_roll_f32.c and vh_roll_f64.c include it after defining
 *   VH_ROLL_REAL    float or double
 *   VH_ROLL_NAME(n) n##_f32 or n##_f64
 *   VH_SQRT, VH_SIN, VH_COS, VH_ATAN, VH_FABS   the libm functions of that precision
 * Every constant is cast to the build's type (RL()), so the float32 build does single-precision
 * arithmetic only (built with -Wdouble-promotion to hold it to that). Equations: docs/roll.md. */

typedef VH_ROLL_REAL real_t;
typedef VH_ROLL_NAME(vh_roll_ukf) ukf_t;
typedef VH_ROLL_NAME(vh_roll_smc) smc_t;
#define RL(v) ((real_t)(v))
#define NX VH_ROLL_NX
#define NZ VH_ROLL_NZ
#define NS VH_ROLL_NS

static int finite_r(real_t v)
{
    return v == v && v - v == v - v; /* not NaN and not Inf (Inf - Inf is NaN) */
}

/* ---- model (eq. 1-10) ----------------------------------------------------------------------- */

/* dx = f(x, u) (eq. 1-10); ay and the unsprung accelerations come out with it. */
static void deriv(const ukf_t *f, const real_t *x, const real_t *u, real_t *dx, real_t *ay)
{
    const real_t vx = u[VH_ROLL_U_VX], cd = VH_COS(u[VH_ROLL_U_STEER]), sd = VH_SIN(u[VH_ROLL_U_STEER]);
    const real_t vy = x[VH_ROLL_X_VY], r = x[VH_ROLL_X_R], z = x[VH_ROLL_X_Z], vz = x[VH_ROLL_X_VZ];
    const real_t phi = x[VH_ROLL_X_PHI], p = x[VH_ROLL_X_P], th = x[VH_ROLL_X_THETA], q = x[VH_ROLL_X_Q];
    const real_t mom[VH_ROLL_NW] = {u[VH_ROLL_U_MF], u[VH_ROLL_U_MF], u[VH_ROLL_U_MR], u[VH_ROLL_U_MR]};
    real_t d[VH_ROLL_NW], fsd[VH_ROLL_NW], farb[VH_ROLL_NW], fa[VH_ROLL_NW];
    real_t sfx = RL(0), sfy = RL(0), smz = RL(0), smx = RL(0), smy = RL(0), sfb = RL(0);
    real_t rx, ry, rp, rq;
    int i;

    for (i = 0; i < VH_ROLL_NW; ++i) {
        const real_t zs = z + f->cy[i] * phi - f->cx[i] * th;   /* eq. 9: body corner height */
        const real_t vzs = vz + f->cy[i] * p - f->cx[i] * q;
        d[i] = x[VH_ROLL_X_ZU + i] - zs;                          /* compression */
        fsd[i] = f->kw[i] * d[i] + f->cw[i] * (x[VH_ROLL_X_VZU + i] - vzs); /* eq. 8 */
        /* actuator: +M/(2t) up on the left body corner, -M/(2t) on the right (roll moment M) */
        fa[i] = (f->cy[i] > RL(0) ? mom[i] : -mom[i]) * f->inv_2t[i];
    }
    farb[0] = f->arb_f * (d[0] - d[1]);                           /* eq. 8: anti-roll bars */
    farb[1] = -farb[0];
    farb[2] = f->arb_r * (d[2] - d[3]);
    farb[3] = -farb[2];

    for (i = 0; i < VH_ROLL_NW; ++i) {
        const real_t vxc = vx - r * f->cy[i], vyc = vy + r * f->cx[i];
        const real_t zu = x[VH_ROLL_X_ZU + i], vzu = x[VH_ROLL_X_VZU + i];
        real_t vxw = vxc, vyw = vyc, vden, ta, fz, fy, fxv, fyv, fb;
        if (i < 2) {
            vxw = vxc * cd + vyc * sd;
            vyw = -vxc * sd + vyc * cd;
        }
        vden = VH_FABS(vxw);
        vden = vden > f->v_low ? vden : f->v_low;
        ta = -vyw / vden;                                          /* eq. 7: tan of the slip angle */
        fz = f->fz0[i] - f->kt * zu - f->ct * vzu;                 /* eq. 10: tyre load */
        fz = fz > RL(0) ? fz : RL(0);
        fy = f->mf_d[i] * fz * VH_SIN(f->mf_c * VH_ATAN(f->mf_b[i] * ta)); /* eq. 11-12 */
        if (i < 2) {
            fxv = -fy * sd;
            fyv = fy * cd;
        } else {
            fxv = RL(0);
            fyv = fy;
        }
        fb = fsd[i] + farb[i] + f->jack[i] * fyv + fa[i];          /* all vertical forces on the body corner */
        sfb += fb;
        sfx += fxv;
        sfy += fyv;
        smz += f->cx[i] * fyv - f->cy[i] * fxv;
        smx += f->cy[i] * (fsd[i] + farb[i] + fa[i]);
        smy -= f->cx[i] * fb;
        dx[VH_ROLL_X_ZU + i] = vzu;
        dx[VH_ROLL_X_VZU + i] = (fz - f->fz0[i] - fb) * f->inv_mu[i]; /* eq. 6 */
    }
    smx += f->ms * f->g * f->e * VH_SIN(phi);                      /* eq. 4: ms g h phi */
    smy += f->ms * f->g * f->hp * VH_SIN(th);                      /* eq. 5 */
    /* eq. 1, 4 (lateral and roll, coupled through ms e) and eq. 5 with the longitudinal balance
     * (pitch coupled through ms hp; vx itself is an input) */
    rx = sfx + f->m * r * vy - f->b_c * p * r;
    rq = smy + f->a_c * r * vy;
    ry = sfy - f->m * r * vx - f->a_c * q * r;
    rp = smx + f->b_c * r * vx;
    dx[VH_ROLL_X_VY] = (f->ip * ry + f->b_c * rp) / f->det_y;     /* eq. 1 */
    dx[VH_ROLL_X_P] = (f->m * rp + f->b_c * ry) / f->det_y;       /* eq. 4 */
    dx[VH_ROLL_X_Q] = (f->m * rq - f->a_c * rx) / f->det_x;       /* eq. 5 */
    dx[VH_ROLL_X_R] = smz / f->iz;                                /* eq. 2 */
    dx[VH_ROLL_X_VZ] = sfb / f->ms;                               /* eq. 3 */
    dx[VH_ROLL_X_Z] = vz;
    dx[VH_ROLL_X_PHI] = p;
    dx[VH_ROLL_X_THETA] = q;
    *ay = dx[VH_ROLL_X_VY] + r * vx;
}

void VH_ROLL_NAME(vh_roll_model_f)(const ukf_t *f, const real_t *x, const real_t *u, real_t *xn)
{
    /* eq. 16: Heun (explicit trapezoid) over one step dt */
    real_t k1[NX], k2[NX], x1[NX], ay;
    int i;
    deriv(f, x, u, k1, &ay);
    for (i = 0; i < NX; ++i) {
        x1[i] = x[i] + f->dt * k1[i];
    }
    deriv(f, x1, u, k2, &ay);
    for (i = 0; i < NX; ++i) {
        xn[i] = x[i] + RL(0.5) * f->dt * (k1[i] + k2[i]);
    }
}

void VH_ROLL_NAME(vh_roll_model_h)(const ukf_t *f, const real_t *x, const real_t *u, real_t *z)
{
    /* eq. 20: the 14 measurements of the state */
    real_t dx[NX], ay;
    int i;
    deriv(f, x, u, dx, &ay);
    z[VH_ROLL_Z_AY] = ay;
    for (i = 0; i < VH_ROLL_NW; ++i) {
        const real_t zs = x[VH_ROLL_X_Z] + f->cy[i] * x[VH_ROLL_X_PHI] - f->cx[i] * x[VH_ROLL_X_THETA];
        z[VH_ROLL_Z_AZU + i] = dx[VH_ROLL_X_VZU + i];
        z[VH_ROLL_Z_DT + i] = -x[VH_ROLL_X_ZU + i];
        z[VH_ROLL_Z_DS + i] = x[VH_ROLL_X_ZU + i] - zs;
    }
    z[VH_ROLL_Z_R] = x[VH_ROLL_X_R];
}

/* ---- linear algebra ------------------------------------------------------------------------- */

/* Lower Cholesky factor L of the n x n symmetric A (row-major; only the lower triangle read),
 * A = L L^T. 0, or -1 at a pivot that is not positive and finite. */
static int chol(const real_t *a, real_t *l, int n)
{
    int i, j, k;
    for (i = 0; i < n; ++i) {
        for (j = 0; j <= i; ++j) {
            real_t s = a[i * n + j];
            for (k = 0; k < j; ++k) {
                s -= l[i * n + k] * l[j * n + k];
            }
            if (i == j) {
                if (!(s > RL(0)) || !finite_r(s)) {
                    return -1;
                }
                l[i * n + i] = VH_SQRT(s);
            } else {
                l[i * n + j] = s / l[j * n + j];
            }
        }
        for (j = i + 1; j < n; ++j) {
            l[i * n + j] = RL(0);
        }
    }
    return 0;
}

/* Cholesky with one regularised retry: on failure A += eps (mean |diag| + tiny) I, in place, and
 * again. 0 first time, 1 after the retry, -1 if it failed both times. */
static int chol_reg(real_t *a, real_t *l, int n, real_t eps)
{
    real_t tr = RL(0);
    int i;
    if (chol(a, l, n) == 0) {
        return 0;
    }
    for (i = 0; i < n; ++i) {
        tr += VH_FABS(a[i * n + i]);
    }
    tr = tr / (real_t)n;
    if (!finite_r(tr)) {
        return -1;
    }
    for (i = 0; i < n; ++i) {
        a[i * n + i] += eps * tr + RL(1e-30);
    }
    return chol(a, l, n) == 0 ? 1 : -1;
}

/* ---- UKF -------------------------------------------------------------------------------------- */

int VH_ROLL_NAME(vh_roll_ukf_init)(ukf_t *f, const vh_roll_params_t *prm)
{
    const double g = 9.81;
    double l, h_ra, e, ip, iq, m, vals[26];
    int i, ok = 1;
    if (f == NULL || prm == NULL) {
        return -1;
    }
    vals[0] = prm->ms; vals[1] = prm->ix; vals[2] = prm->iy; vals[3] = prm->iz; vals[4] = prm->lf;
    vals[5] = prm->lr; vals[6] = prm->tf; vals[7] = prm->tr; vals[8] = prm->h; vals[9] = prm->kphi_f;
    vals[10] = prm->kphi_r; vals[11] = prm->cphi_f; vals[12] = prm->cphi_r; vals[13] = prm->m_uf;
    vals[14] = prm->m_ur; vals[15] = prm->k_f; vals[16] = prm->k_r; vals[17] = prm->kt;
    vals[18] = prm->calpha_f; vals[19] = prm->calpha_r; vals[20] = prm->mf_c; vals[21] = prm->mu;
    vals[22] = prm->mu_load; vals[23] = prm->v_low; vals[24] = prm->dt; vals[25] = prm->ct + 1.0;
    for (i = 0; i < 26; ++i) {
        ok = ok && vals[i] > 0.0 && vals[i] < 1e12;
    }
    for (i = 0; i < NX; ++i) {
        ok = ok && prm->q[i] >= 0.0 && prm->q[i] < 1e12 && prm->p0[i] > 0.0 && prm->p0[i] < 1e12;
    }
    for (i = 0; i < NZ; ++i) {
        ok = ok && prm->r[i] > 0.0 && prm->r[i] < 1e12;
    }
    ok = ok && prm->kappa >= 0.0 && prm->kappa < 1e6 && prm->hf < prm->h && prm->hr < prm->h &&
         prm->hf >= 0.0 && prm->hr >= 0.0 && prm->cphi_f >= 0.0 && prm->cphi_r >= 0.0 &&
         prm->reg_eps > 0.0 && prm->reg_eps < 1.0 && prm->nis_max >= 0.0 && prm->phi_max > 0.0;
    if (!ok) {
        return -1;
    }
    l = prm->lf + prm->lr;
    h_ra = prm->hf + (prm->hr - prm->hf) * prm->lf / l; /* roll axis under the CG */
    e = prm->h - h_ra;
    m = prm->ms + 2.0 * prm->m_uf + 2.0 * prm->m_ur;
    ip = prm->ix + prm->ms * e * e;
    iq = prm->iy + prm->ms * prm->h * prm->h;
    f->dt = RL(prm->dt);
    f->g = RL(g);
    f->ms = RL(prm->ms);
    f->m = RL(m);
    f->iz = RL(prm->iz);
    f->e = RL(e);
    f->hp = RL(prm->h);
    f->ip = RL(ip);
    f->iq = RL(iq);
    f->a_c = RL(prm->ms * prm->h);
    f->b_c = RL(prm->ms * e);
    f->det_x = RL(m * iq - (prm->ms * prm->h) * (prm->ms * prm->h));
    f->det_y = RL(m * ip - (prm->ms * e) * (prm->ms * e));
    {
        /* suspension roll stiffness with the tyres in series removed, the bar is what the
         * springs leave (as the plant, docs/chassis_plant.md) */
        const double ksf = 1.0 / (1.0 / prm->kphi_f - 1.0 / (2.0 * prm->kt * prm->tf * prm->tf));
        const double ksr = 1.0 / (1.0 / prm->kphi_r - 1.0 / (2.0 * prm->kt * prm->tr * prm->tr));
        const double arbf = ksf - 2.0 * prm->k_f * prm->tf * prm->tf;
        const double arbr = ksr - 2.0 * prm->k_r * prm->tr * prm->tr;
        if (!(ksf > 0.0 && ksr > 0.0 && arbf >= 0.0 && arbr >= 0.0)) {
            return -1;
        }
        f->arb_f = RL(arbf / (4.0 * prm->tf * prm->tf));
        f->arb_r = RL(arbr / (4.0 * prm->tr * prm->tr));
    }
    for (i = 0; i < VH_ROLL_NW; ++i) {
        const int front = i < 2;
        const double t = front ? prm->tf : prm->tr;
        const double fs0 = prm->ms * g * (front ? prm->lr : prm->lf) / (2.0 * l);
        const double dpk = prm->mu * prm->mu_load;
        f->cx[i] = RL(front ? prm->lf : -prm->lr);
        f->cy[i] = RL(i % 2 == 0 ? t : -t);
        f->kw[i] = RL(front ? prm->k_f : prm->k_r);
        f->cw[i] = RL((front ? prm->cphi_f : prm->cphi_r) / (2.0 * t * t));
        f->fz0[i] = RL(fs0 + (front ? prm->m_uf : prm->m_ur) * g);
        f->inv_mu[i] = RL(1.0 / (front ? prm->m_uf : prm->m_ur));
        f->jack[i] = RL((front ? prm->hf : prm->hr) / t * (i % 2 == 0 ? -1.0 : 1.0));
        f->inv_2t[i] = RL(0.5 / t);
        f->mf_d[i] = RL(dpk);
        f->mf_b[i] = RL((front ? prm->calpha_f : prm->calpha_r) / (prm->mf_c * dpk));
    }
    f->kt = RL(prm->kt);
    f->ct = RL(prm->ct);
    f->mf_c = RL(prm->mf_c);
    f->v_low = RL(prm->v_low);
    for (i = 0; i < NX; ++i) {
        f->q[i] = RL(prm->q[i]);
        f->p0[i] = RL(prm->p0[i]);
    }
    for (i = 0; i < NZ; ++i) {
        f->r[i] = RL(prm->r[i]);
    }
    f->reg_eps = RL(prm->reg_eps);
    f->nis_max = RL(prm->nis_max);
    f->phi_max = RL(prm->phi_max);
    /* eq. 15: symmetric set, gamma = sqrt(n + kappa); weights */
    f->gamma = RL(sqrt((double)NX + prm->kappa));
    f->w0 = RL(prm->kappa / ((double)NX + prm->kappa));
    f->wi = RL(0.5 / ((double)NX + prm->kappa));
    f->flags_seen = 0u;
    f->resets = 0u;
    f->regularised = 0u;
    VH_ROLL_NAME(vh_roll_ukf_reset)(f);
    return 0;
}

void VH_ROLL_NAME(vh_roll_ukf_reset)(ukf_t *f)
{
    int i;
    for (i = 0; i < NX * NX; ++i) {
        f->P[i] = RL(0);
    }
    for (i = 0; i < NX; ++i) {
        f->x[i] = RL(0);                                /* eq. 13: static straight-ahead equilibrium */
        f->P[i * NX + i] = f->p0[i];                    /* eq. 14 */
    }
    for (i = 0; i < NZ; ++i) {
        f->zhat[i] = RL(0);
        f->nu[i] = RL(0);
    }
    f->nis = RL(0);
    f->ay_post = RL(0);
    f->n_used = 0u;
    f->health = VH_ROLL_H_INIT;
    f->flags = 0u;
    f->steps = 0u;
}

/* Symmetric sigma points of (x, P) into f->sig (eq. 15 / eq. 19). 0, 1 regularised, -1 failed. */
static int sigma_points(ukf_t *f, const real_t *x)
{
    int i, j, rc;
    rc = chol_reg(f->P, f->L, NX, f->reg_eps);
    if (rc < 0) {
        return rc;
    }
    for (j = 0; j < NX; ++j) {
        f->sig[j] = x[j];
    }
    for (i = 0; i < NX; ++i) {
        for (j = 0; j < NX; ++j) {
            const real_t d = f->gamma * f->L[j * NX + i];   /* column i of gamma L */
            f->sig[(1 + i) * NX + j] = x[j] + d;
            f->sig[(1 + NX + i) * NX + j] = x[j] - d;
        }
    }
    return rc;
}

static real_t weight(const ukf_t *f, int i)
{
    return i == 0 ? f->w0 : f->wi;
}

static int state_ok(const ukf_t *f)
{
    int i;
    for (i = 0; i < NX; ++i) {
        if (!finite_r(f->x[i])) {
            return 0;
        }
    }
    for (i = 0; i < NX * NX; ++i) {
        if (!finite_r(f->P[i])) {
            return 0;
        }
    }
    return 1;
}

static uint32_t fail_reset(ukf_t *f, uint32_t flag)
{
    const uint64_t steps = f->steps;
    VH_ROLL_NAME(vh_roll_ukf_reset)(f);
    f->steps = steps;
    f->flags = flag;
    f->flags_seen |= flag;
    f->resets += 1u;
    f->health = VH_ROLL_H_RESET;
    return f->health;
}

uint32_t VH_ROLL_NAME(vh_roll_ukf_step)(ukf_t *f, const real_t *u_in, const real_t *z, uint32_t valid_mask)
{
    real_t u[VH_ROLL_NU], xp[NX], zp[NZ];
    int idx[NZ];
    uint32_t flags = 0u;
    int i, j, k, s, m = 0, rc;

    f->steps += 1u;
    for (i = 0; i < VH_ROLL_NU; ++i) {
        u[i] = u_in[i];
        if (!finite_r(u[i])) {
            u[i] = RL(0);
            flags |= VH_ROLL_F_BAD_INPUT;
        }
    }
    for (i = 0; i < NZ; ++i) {
        if (((valid_mask >> i) & 1u) != 0u && finite_r(z[i])) {
            idx[m++] = i;  /* masked (or non-finite) measurements leave this step's update */
        }
    }
    if (m < NZ) {
        flags |= VH_ROLL_F_MASKED;
    }
    if (!state_ok(f)) {
        return fail_reset(f, flags | VH_ROLL_F_NONFINITE);
    }

    /* eq. 15: sigma points of the estimate */
    rc = sigma_points(f, f->x);
    if (rc < 0) {
        return fail_reset(f, flags | VH_ROLL_F_REGULARISED | VH_ROLL_F_CHOL_RESET);
    }
    if (rc > 0) {
        flags |= VH_ROLL_F_REGULARISED;
        f->regularised += 1u;
    }
    /* eq. 16: through the model */
    for (s = 0; s < NS; ++s) {
        real_t xn[NX];
        VH_ROLL_NAME(vh_roll_model_f)(f, &f->sig[s * NX], u, xn);
        for (j = 0; j < NX; ++j) {
            f->sig[s * NX + j] = xn[j];
        }
    }
    /* eq. 17: predicted mean */
    for (j = 0; j < NX; ++j) {
        real_t acc = RL(0);
        for (s = 0; s < NS; ++s) {
            acc += weight(f, s) * f->sig[s * NX + j];
        }
        xp[j] = acc;
    }
    /* eq. 18: predicted covariance, P = sum W (X - x)(X - x)^T + Q */
    for (i = 0; i < NX; ++i) {
        for (j = 0; j <= i; ++j) {
            real_t acc = RL(0);
            for (s = 0; s < NS; ++s) {
                acc += weight(f, s) * (f->sig[s * NX + i] - xp[i]) * (f->sig[s * NX + j] - xp[j]);
            }
            f->P[i * NX + j] = acc;
            f->P[j * NX + i] = acc;
        }
        f->P[i * NX + i] += f->q[i];
    }
    for (j = 0; j < NX; ++j) {
        f->x[j] = xp[j];
    }
    if (!state_ok(f)) {
        return fail_reset(f, flags | VH_ROLL_F_NONFINITE);
    }

    /* eq. 19: sigma points redrawn from the prediction */
    rc = sigma_points(f, f->x);
    if (rc < 0) {
        return fail_reset(f, flags | VH_ROLL_F_REGULARISED | VH_ROLL_F_CHOL_RESET);
    }
    if (rc > 0) {
        flags |= VH_ROLL_F_REGULARISED;
        f->regularised += 1u;
    }
    /* eq. 20: through the measurement function (all 14; the mask selects below) */
    for (s = 0; s < NS; ++s) {
        VH_ROLL_NAME(vh_roll_model_h)(f, &f->sig[s * NX], u, &f->sigz[s * NZ]);
    }
    /* eq. 21: predicted measurement */
    for (k = 0; k < NZ; ++k) {
        real_t acc = RL(0);
        for (s = 0; s < NS; ++s) {
            acc += weight(f, s) * f->sigz[s * NZ + k];
        }
        zp[k] = acc;
        f->zhat[k] = acc;
        f->nu[k] = RL(0);
    }
    f->n_used = (uint32_t)m;
    f->nis = RL(0);
    if (m == 0) {
        flags |= VH_ROLL_F_NO_UPDATE;
    } else {
        real_t w[NZ];
        /* eq. 22 (with the two covariances of eq. 23-24): Pzz = sum W (Z - z)(Z - z)^T + R over
         * the valid rows, Pxz = sum W (X - x)(Z - z)^T */
        for (i = 0; i < m; ++i) {
            for (j = 0; j <= i; ++j) {
                real_t acc = RL(0);
                for (s = 0; s < NS; ++s) {
                    acc += weight(f, s) * (f->sigz[s * NZ + idx[i]] - zp[idx[i]]) *
                           (f->sigz[s * NZ + idx[j]] - zp[idx[j]]);
                }
                f->Szz[i * m + j] = acc;
                f->Szz[j * m + i] = acc;
            }
            f->Szz[i * m + i] += f->r[idx[i]];
        }
        for (i = 0; i < NX; ++i) {
            for (j = 0; j < m; ++j) {
                real_t acc = RL(0);
                for (s = 0; s < NS; ++s) {
                    acc += weight(f, s) * (f->sig[s * NX + i] - f->x[i]) * (f->sigz[s * NZ + idx[j]] - zp[idx[j]]);
                }
                f->Pxz[i * m + j] = acc;
            }
        }
        /* Pzz = Lz Lz^T; L reused for Lz (m <= NZ < NX) */
        rc = chol_reg(f->Szz, f->L, m, f->reg_eps);
        if (rc < 0) {
            return fail_reset(f, flags | VH_ROLL_F_REGULARISED | VH_ROLL_F_CHOL_RESET);
        }
        if (rc > 0) {
            flags |= VH_ROLL_F_REGULARISED;
            f->regularised += 1u;
        }
        /* A = Pxz Lz^-T (row by row forward substitution, in place), w = Lz^-1 nu:
         * eq. 22 K = Pxz Pzz^-1 = A Lz^-1, eq. 25 x += K nu = A w, eq. 26 P -= K Pzz K^T = A A^T */
        for (i = 0; i < NX; ++i) {
            for (j = 0; j < m; ++j) {
                real_t acc = f->Pxz[i * m + j];
                for (k = 0; k < j; ++k) {
                    acc -= f->Pxz[i * m + k] * f->L[j * m + k];
                }
                f->Pxz[i * m + j] = acc / f->L[j * m + j];
            }
        }
        for (j = 0; j < m; ++j) {
            real_t acc = z[idx[j]] - zp[idx[j]];
            f->nu[idx[j]] = acc;
            for (k = 0; k < j; ++k) {
                acc -= w[k] * f->L[j * m + k];
            }
            w[j] = acc / f->L[j * m + j];
            f->nis += w[j] * w[j];
        }
        for (i = 0; i < NX; ++i) {
            real_t acc = RL(0);
            for (j = 0; j < m; ++j) {
                acc += f->Pxz[i * m + j] * w[j];
            }
            f->x[i] += acc;                                                    /* eq. 25 */
        }
        for (i = 0; i < NX; ++i) {
            for (j = 0; j <= i; ++j) {
                real_t acc = RL(0);
                for (k = 0; k < m; ++k) {
                    acc += f->Pxz[i * m + k] * f->Pxz[j * m + k];
                }
                f->P[i * NX + j] -= acc;                                       /* eq. 26 */
                f->P[j * NX + i] = f->P[i * NX + j];
            }
        }
        if (f->nis_max > RL(0) && f->nis > f->nis_max * (real_t)m) {
            return fail_reset(f, flags | VH_ROLL_F_DIVERGED);
        }
    }
    if (!state_ok(f)) {
        return fail_reset(f, flags | VH_ROLL_F_NONFINITE);
    }
    if (!(VH_FABS(f->x[VH_ROLL_X_PHI]) <= f->phi_max)) {
        return fail_reset(f, flags | VH_ROLL_F_DIVERGED);
    }
    {
        real_t zpost[NZ];
        VH_ROLL_NAME(vh_roll_model_h)(f, f->x, u, zpost);
        f->ay_post = zpost[VH_ROLL_Z_AY];
    }
    f->flags = flags;
    f->flags_seen |= flags;
    f->health = (flags & (VH_ROLL_F_MASKED | VH_ROLL_F_REGULARISED | VH_ROLL_F_NO_UPDATE | VH_ROLL_F_BAD_INPUT)) != 0u
                    ? VH_ROLL_H_DEGRADED
                    : VH_ROLL_H_OK;
    return f->health;
}

void VH_ROLL_NAME(vh_roll_ukf_run)(ukf_t *f, size_t n, const real_t *u, const real_t *z, const uint32_t *mask,
                                   real_t *x_out, real_t *pdiag_out, uint32_t *health_out)
{
    size_t t;
    int i;
    for (t = 0; t < n; ++t) {
        const uint32_t h = VH_ROLL_NAME(vh_roll_ukf_step)(f, &u[t * VH_ROLL_NU], &z[t * NZ],
                                                           mask != NULL ? mask[t] : 0x3FFFu);
        if (x_out != NULL) {
            for (i = 0; i < NX; ++i) {
                x_out[t * NX + i] = f->x[i];
            }
        }
        if (pdiag_out != NULL) {
            for (i = 0; i < NX; ++i) {
                pdiag_out[t * NX + i] = f->P[i * NX + i];
            }
        }
        if (health_out != NULL) {
            health_out[t] = h;
        }
    }
}

/* ---- sliding-mode controller (eq. 27-35) ----------------------------------------------------- */

int VH_ROLL_NAME(vh_roll_smc_init)(smc_t *c, const vh_roll_smc_params_t *prm)
{
    double v[16];
    int i, ok = 1;
    if (c == NULL || prm == NULL) {
        return -1;
    }
    v[0] = prm->lambda; v[1] = prm->k; v[2] = prm->p; v[3] = prm->ref_tau; v[4] = prm->m_max_f;
    v[5] = prm->m_max_r; v[6] = prm->rate_max_f; v[7] = prm->rate_max_r; v[8] = prm->fade_time;
    v[9] = prm->dt; v[10] = prm->i_roll; v[11] = prm->ms_e; v[12] = prm->kphi;
    v[13] = prm->recover_time + 1.0; v[14] = prm->cphi + 1.0; v[15] = prm->ay_tau;
    for (i = 0; i < 16; ++i) {
        ok = ok && v[i] > 0.0 && v[i] < 1e12;
    }
    ok = ok && prm->ref_frac >= 0.0 && prm->ref_frac <= 1.0 && prm->front_share >= 0.0 &&
         prm->front_share <= 1.0 && prm->recover_time >= 0.0 && prm->not_ok_debounce >= 0.0 &&
         prm->not_ok_debounce < 1e3 && prm->cphi >= 0.0 &&
         prm->fade_time * prm->rate_max_f >= prm->m_max_f * (1.0 - 1e-9) &&
         prm->fade_time * prm->rate_max_r >= prm->m_max_r * (1.0 - 1e-9); /* the rate limit can follow the fade */
    if (!ok) {
        return -1;
    }
    c->lambda = RL(prm->lambda);
    c->k = RL(prm->k);
    c->p = RL(prm->p);
    c->ref_frac = RL(prm->ref_frac);
    c->ref_tau = RL(prm->ref_tau);
    c->ay_tau = RL(prm->ay_tau);
    c->front_share = RL(prm->front_share);
    c->m_max_f = RL(prm->m_max_f);
    c->m_max_r = RL(prm->m_max_r);
    c->rate_max_f = RL(prm->rate_max_f);
    c->rate_max_r = RL(prm->rate_max_r);
    c->fade_time = RL(prm->fade_time);
    c->recover_time = RL(prm->recover_time);
    c->not_ok_debounce = RL(prm->not_ok_debounce);
    c->dt = RL(prm->dt);
    c->i_roll = RL(prm->i_roll);
    c->ms_e = RL(prm->ms_e);
    c->kphi = RL(prm->kphi);
    c->cphi = RL(prm->cphi);
    c->g = RL(9.81);
    VH_ROLL_NAME(vh_roll_smc_reset)(c);
    return 0;
}

void VH_ROLL_NAME(vh_roll_smc_reset)(smc_t *c)
{
    c->m_f = RL(0);
    c->m_r = RL(0);
    c->fade = RL(0);
    c->ok_time = RL(0);
    c->bad_time = RL(0);
    c->tripped = 1u; /* starts passive: on once the estimate has been OK for recover_time */
    c->ay_f = RL(0);
    c->ref_a = RL(0);
    c->phi_ref = RL(0);
    c->dphi_ref = RL(0);
    c->s = RL(0);
    c->m_demand = RL(0);
    c->health = VH_ROLL_S_EST_NOT_OK;
    c->sat_steps = 0u;
    c->rate_steps = 0u;
    c->steps = 0u;
}

/* sat(s / p) (eq. 35) */
static real_t sat_r(real_t v)
{
    return v > RL(1) ? RL(1) : (v < RL(-1) ? RL(-1) : v);
}

/* Torque limit (scaled by the fade), then rate limit of one axle; sets the health bits it used.
 * The rate limit acts last, so it always holds; the bound fade * m_max shrinks no faster than the
 * rate limit can follow (init checks fade_time >= m_max / rate_max), so the moment is zero when
 * the fade is. */
static real_t limit_axle(real_t want, real_t last, real_t m_max, real_t rate_max, real_t dt, real_t fade, uint32_t *h)
{
    const real_t step = rate_max * dt;
    const real_t bound = m_max * fade;
    real_t v = want;
    if (v > bound) {
        v = bound;
        *h |= fade >= RL(1) ? VH_ROLL_S_SAT : 0u;
    } else if (v < -bound) {
        v = -bound;
        *h |= fade >= RL(1) ? VH_ROLL_S_SAT : 0u;
    }
    if (v > last + step) {
        v = last + step;
        *h |= VH_ROLL_S_RATE;
    } else if (v < last - step) {
        v = last - step;
        *h |= VH_ROLL_S_RATE;
    }
    return v;
}

uint32_t VH_ROLL_NAME(vh_roll_smc_step)(smc_t *c, real_t phi, real_t p, real_t ay, uint32_t est_health, int active)
{
    uint32_t h = 0u;
    real_t target, e, de, fpass, mdem = RL(0), want_f, want_r, m_tot;
    const int inputs_ok = finite_r(phi) && finite_r(p) && finite_r(ay);

    c->steps += 1u;
    /* fade: the moment's scale ramps to 0 over fade_time once the estimate trips (a filter reset or
     * non-finite estimate at once; any other not-OK health after it lasted longer than
     * not_ok_debounce) or in passive mode; after a trip it comes back at the same rate only when the
     * estimate has been OK for recover_time. While not OK within the debounce the fade holds. */
    if (est_health == VH_ROLL_H_OK && inputs_ok) {
        c->ok_time += c->dt;
        c->bad_time = RL(0);
    } else {
        c->bad_time += c->dt;
        h |= VH_ROLL_S_EST_NOT_OK;
        if (!inputs_ok || est_health == VH_ROLL_H_RESET || est_health == VH_ROLL_H_INIT ||
            c->bad_time > c->not_ok_debounce) {
            c->tripped = 1u;
            c->ok_time = RL(0);
        }
    }
    if (c->tripped != 0u && c->ok_time >= c->recover_time) {
        c->tripped = 0u;
    }
    if (!inputs_ok) {
        h |= VH_ROLL_S_BAD_INPUT;
    }
    if (!active) {
        h |= VH_ROLL_S_PASSIVE;
    }
    if (c->tripped != 0u) {
        h |= VH_ROLL_S_TRIPPED;
    }
    if (!active || c->tripped != 0u) {
        c->fade -= c->dt / c->fade_time;
        c->fade = c->fade < RL(0) ? RL(0) : c->fade;
    } else if ((h & VH_ROLL_S_EST_NOT_OK) == 0u) {
        c->fade += c->dt / c->fade_time;
        c->fade = c->fade > RL(1) ? RL(1) : c->fade;
    } /* else: not OK within the debounce: hold */
    if (c->fade > RL(0) && c->fade < RL(1)) {
        h |= VH_ROLL_S_FADING;
    }

    if (inputs_ok) {
        /* reference: ref_frac of the passive steady roll the estimated ay would give,
         * phi_pass = ms e ay / (k_phi - ms g e), through two first-order low-passes (tau each):
         * its rate is that of the second stage, smooth; its second derivative is neglected
         * (docs/roll.md) */
        c->ay_f += c->dt * (ay - c->ay_f) / c->ay_tau;
        target = c->ref_frac * c->ms_e * c->ay_f / (c->kphi - c->ms_e * c->g);
        c->ref_a += c->dt * (target - c->ref_a) / c->ref_tau;
        c->dphi_ref = (c->ref_a - c->phi_ref) / c->ref_tau;
        c->phi_ref += c->dt * c->dphi_ref;
        e = phi - c->phi_ref;
        de = p - c->dphi_ref;
        c->s = de + c->lambda * e;                                           /* eq. 28 */
        /* eq. 27: I phi'' = ms g e phi + ms e ay - k_phi phi - c_phi p + M; eq. 29-31: s' = -k
         * sat(s/p) with the equivalent control, eq. 32-35: switching term with the boundary layer */
        fpass = c->ms_e * c->g * phi + c->ms_e * c->ay_f - c->kphi * phi - c->cphi * p;
        mdem = c->i_roll * (-c->lambda * de - c->k * sat_r(c->s / c->p)) - fpass; /* eq. 31, 34 */
        c->m_demand = mdem;
    } else {
        c->m_demand = RL(0);
    }
    m_tot = mdem * c->fade;
    want_f = c->front_share * m_tot;                 /* split: the passive roll-stiffness ratio */
    want_r = (RL(1) - c->front_share) * m_tot;
    c->m_f = limit_axle(want_f, c->m_f, c->m_max_f, c->rate_max_f, c->dt, c->fade, &h);
    c->m_r = limit_axle(want_r, c->m_r, c->m_max_r, c->rate_max_r, c->dt, c->fade, &h);
    if ((h & VH_ROLL_S_SAT) != 0u) {
        c->sat_steps += 1u;
    }
    if ((h & VH_ROLL_S_RATE) != 0u) {
        c->rate_steps += 1u;
    }
    c->health = h;
    return h;
}
