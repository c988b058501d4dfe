/* vh_roll_decl.h - declarations of one precision of the roll system; included twice by vh_roll.h
 * with VH_ROLL_REAL (float, double) and VH_ROLL_NAME (suffix _f32, _f64). No include guard on
 * purpose. */

typedef VH_ROLL_REAL VH_ROLL_NAME(vh_roll_real);

typedef struct {
    /* estimate (eq. 25-26) */
    VH_ROLL_REAL x[VH_ROLL_NX];
    VH_ROLL_REAL P[VH_ROLL_NX * VH_ROLL_NX];
    /* last step: predicted measurement, innovation (masked entries 0), normalised innovation
     * squared and the number of measurements used; ay of the posterior (for the controller) */
    VH_ROLL_REAL zhat[VH_ROLL_NZ];
    VH_ROLL_REAL nu[VH_ROLL_NZ];
    VH_ROLL_REAL nis;
    VH_ROLL_REAL ay_post;
    uint32_t n_used;
    uint32_t health;        /* VH_ROLL_H_* of the last step */
    uint32_t flags;         /* VH_ROLL_F_* of the last step */
    uint32_t flags_seen;    /* every flag since init */
    uint32_t resets;        /* filter resets since init */
    uint32_t regularised;   /* regularised factorisations since init */
    uint64_t steps;
    /* tuning, in the build's precision */
    VH_ROLL_REAL q[VH_ROLL_NX], r[VH_ROLL_NZ], p0[VH_ROLL_NX];
    VH_ROLL_REAL reg_eps, nis_max, phi_max;
    /* sigma-point set (eq. 15): spread gamma = sqrt(n + kappa), weights w0 = kappa/(n + kappa),
     * wi = 1/(2(n + kappa)) */
    VH_ROLL_REAL gamma, w0, wi;
    /* model constants derived at init (docs/roll.md) */
    VH_ROLL_REAL dt, g, ms, m, iz, e, hp, ip, iq, det_x, det_y, a_c, b_c;
    VH_ROLL_REAL cx[VH_ROLL_NW], cy[VH_ROLL_NW], kw[VH_ROLL_NW], cw[VH_ROLL_NW];
    VH_ROLL_REAL fz0[VH_ROLL_NW], inv_mu[VH_ROLL_NW], jack[VH_ROLL_NW], inv_2t[VH_ROLL_NW];
    VH_ROLL_REAL mf_b[VH_ROLL_NW], mf_d[VH_ROLL_NW];
    VH_ROLL_REAL arb_f, arb_r, kt, ct, mf_c, v_low;
    /* workspace (no heap): sigma points, their images, factors */
    VH_ROLL_REAL sig[VH_ROLL_NS * VH_ROLL_NX];
    VH_ROLL_REAL sigz[VH_ROLL_NS * VH_ROLL_NZ];
    VH_ROLL_REAL L[VH_ROLL_NX * VH_ROLL_NX];
    VH_ROLL_REAL Szz[VH_ROLL_NZ * VH_ROLL_NZ];
    VH_ROLL_REAL Pxz[VH_ROLL_NX * VH_ROLL_NZ];
} VH_ROLL_NAME(vh_roll_ukf);

typedef struct {
    VH_ROLL_REAL lambda, k, p, ref_frac, ref_tau, ay_tau, front_share;
    VH_ROLL_REAL m_max_f, m_max_r, rate_max_f, rate_max_r, fade_time, recover_time, not_ok_debounce, dt;
    VH_ROLL_REAL i_roll, ms_e, kphi, cphi, g;
    /* state */
    VH_ROLL_REAL m_f, m_r;     /* commanded roll moments on the body [Nm] (eq. 34, limited) */
    VH_ROLL_REAL fade;         /* 0..1 */
    VH_ROLL_REAL ok_time;      /* time the estimator has been OK [s] */
    VH_ROLL_REAL bad_time;     /* time it has been not OK [s] */
    uint32_t tripped;          /* 1: fading out / faded, until OK for recover_time */
    VH_ROLL_REAL ay_f;         /* low-passed ay [m/s^2] */
    VH_ROLL_REAL ref_a;        /* first stage of the reference's second-order low-pass */
    VH_ROLL_REAL phi_ref, dphi_ref; /* reference roll and its rate */
    VH_ROLL_REAL s;            /* sliding variable (eq. 28) */
    VH_ROLL_REAL m_demand;     /* total moment before limits and fade (eq. 34) */
    uint32_t health;           /* VH_ROLL_S_* bits of the last step */
    uint32_t sat_steps, rate_steps;
    uint64_t steps;
} VH_ROLL_NAME(vh_roll_smc);

/* 0, or -1 (nothing usable) for missing pointers or non-finite / non-physical parameters. */
int VH_ROLL_NAME(vh_roll_ukf_init)(VH_ROLL_NAME(vh_roll_ukf) *f, const vh_roll_params_t *prm);
/* Estimate to the static straight-ahead equilibrium, P to diag(p0) (eq. 13-14); counters kept. */
void VH_ROLL_NAME(vh_roll_ukf_reset)(VH_ROLL_NAME(vh_roll_ukf) *f);
/* One step: predict with u over dt (eq. 15-18), update with the measurements whose bit is set
 * in valid_mask (bit i = z[i] valid; eq. 19-26). Returns the health (VH_ROLL_H_*). */
uint32_t VH_ROLL_NAME(vh_roll_ukf_step)(VH_ROLL_NAME(vh_roll_ukf) *f, const VH_ROLL_REAL *u,
                                        const VH_ROLL_REAL *z, uint32_t valid_mask);
/* The model, for tests and the reference: one discrete step xn = F(x, u) (eq. 16), and the
 * measurement function z = H(x, u) (eq. 20). */
void VH_ROLL_NAME(vh_roll_model_f)(const VH_ROLL_NAME(vh_roll_ukf) *f, const VH_ROLL_REAL *x,
                                   const VH_ROLL_REAL *u, VH_ROLL_REAL *xn);
void VH_ROLL_NAME(vh_roll_model_h)(const VH_ROLL_NAME(vh_roll_ukf) *f, const VH_ROLL_REAL *x,
                                   const VH_ROLL_REAL *u, VH_ROLL_REAL *z);
/* Runs n steps over flat arrays u[n][NU], z[n][NZ], mask[n]; writes x_out[n][NX] and
 * health_out[n] when not NULL, and the covariance diagonal to pdiag_out[n][NX] when not NULL. */
void VH_ROLL_NAME(vh_roll_ukf_run)(VH_ROLL_NAME(vh_roll_ukf) *f, size_t n, const VH_ROLL_REAL *u,
                                   const VH_ROLL_REAL *z, const uint32_t *mask, VH_ROLL_REAL *x_out,
                                   VH_ROLL_REAL *pdiag_out, uint32_t *health_out);

/* 0, or -1 for missing pointers or non-finite / non-positive gains and limits. */
int VH_ROLL_NAME(vh_roll_smc_init)(VH_ROLL_NAME(vh_roll_smc) *c, const vh_roll_smc_params_t *prm);
/* Moments zero, fade 0 (the controller starts passive and ramps in once the estimate is OK). */
void VH_ROLL_NAME(vh_roll_smc_reset)(VH_ROLL_NAME(vh_roll_smc) *c);
/* One step from the UKF's estimates phi, p [rad, rad/s], its lateral acceleration ay [m/s^2] and
 * health (VH_ROLL_H_*), active != 0 for active mode. Writes c->m_f, c->m_r; returns c->health. */
uint32_t VH_ROLL_NAME(vh_roll_smc_step)(VH_ROLL_NAME(vh_roll_smc) *c, VH_ROLL_REAL phi, VH_ROLL_REAL p,
                                        VH_ROLL_REAL ay, uint32_t est_health, int active);
