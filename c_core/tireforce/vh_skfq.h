/* vh_skfq.h - SKFMEC in fixed point: the ECU's version of vh_skf (seed 000). Integer only.
 *
 * The same filter as vh_skf with scaled = 1 (same model, discretisation, step order, sequential
 * symmetric-Joseph update, variance cap), in int32 storage with int64 accumulators. Every quantity
 * has its own Q format, chosen by the range analysis in docs/tireforce.md; the scaling S is what
 * makes it possible: the states x* = S x are O(1..100) and share one format, while P, the gains
 * and the innovation variances each get theirs. Measurements that are states (r, p) are scaled
 * like those states (z* = T y, T = diag(1, 1, s_r, s_p)), so the innovations share the state format.
 *
 * All constants (vh_skfq_params_t) are integers computed off-line from a vh_skf_config_t by
 * vh_skfq_params_from_config (vh_skfq_host.c, the double-precision "calibration tool", not flashed).
 * Arithmetic: round-half-up everywhere, saturating operations that count (vh_fix.h); a step with
 * a saturation is DEGRADED, the count is kept (`sat`), the filter carries on. Divergence (a
 * non-positive variance, a variance above p_max, |x*| above x_max) resets it (FAULT), as vh_skf;
 * the unobservable vx*, vy* are clamped to x_max instead.
 */
#ifndef VH_SKFQ_H
#define VH_SKFQ_H

#include <stddef.h>
#include <stdint.h>

#include "vh_fix.h"

/* Q formats: fractional bits of int32 values (Qi.f, i = 31 - f). */
#define VH_SKFQ_FX 21   /* Q10.21 scaled states x*, scaled measurements z*, innovations */
#define VH_SKFQ_FA 24   /* Q7.24  input ax, ay [m/s^2] */
#define VH_SKFQ_FW 27   /* Q4.27  input r, p [rad/s] */
#define VH_SKFQ_FD 30   /* Q1.30  input delta [rad]; sin, cos; roll angle for sin/cos */
#define VH_SKFQ_FO 21   /* Q10.21 input wheel speeds [rad/s] */
#define VH_SKFQ_FT 16   /* Q15.16 input wheel torques [Nm] */
#define VH_SKFQ_FN 14   /* Q17.14 forces [N], moments [Nm], model derivatives per scaled unit */
#define VH_SKFQ_FR 28   /* Q3.28  load ratios Fzi/Fzf and their roll derivative */
#define VH_SKFQ_FWD 15  /* Q16.15 wheel accelerations [rad/s^2] */
#define VH_SKFQ_FP 26   /* Q5.26  covariance P*, process noise Q* */
#define VH_SKFQ_FPHI 29 /* Q2.29  transition matrix Phi* = I + Ts F* */
#define VH_SKFQ_FH 27   /* Q4.27  measurement Jacobian H* = T H S^-1 */
#define VH_SKFQ_FU 24   /* Q7.24  P* h^T, innovation variance s, gains k, R* */
#define VH_SKFQ_FK 15   /* Q16.15 products of two scaled states (r* vx*, r* vy*, p* r*) */

#define VH_SKFQ_NX 7
#define VH_SKFQ_NY 4

/* One step's inputs in the formats above (from the RX layer's raw signals by integer scaling). */
typedef struct {
    int32_t ax, ay;       /* FA */
    int32_t r, p;         /* FW */
    int32_t delta;        /* FD */
    int32_t omega[4];     /* FO */
    int32_t torque[4];    /* FT */
} vh_skfq_input_t;
#define VH_SKFQ_NU 13

/* Row t of an array of VH_SKFQ_NU int32 per step (vh_skfq_run's u) as one step's inputs: the same
 * layout, no padding (checked at compile time in vh_skfq.c). */
static inline const vh_skfq_input_t *vh_skfq_input_row(const int32_t *u, size_t t)
{
    return (const vh_skfq_input_t *)(const void *)(u + t * VH_SKFQ_NU);
}

/* Integer constants of the filter; each vh_fix_k_t documents the physical formula it holds. */
typedef struct vh_skfq_params_s {
    /* state increments per step, g [N or Nm] -> x* (C = Ts S E^-1) */
    vh_fix_k_t c_vx0;             /* Ts s_vx / m */
    vh_fix_k_t c_vy1, c_vy4;      /* Ts s_vy Ixx / det, Ts s_vy ms e / det */
    vh_fix_k_t c_r2;              /* Ts s_r / Iz */
    vh_fix_k_t c_p1, c_p4;        /* Ts s_p ms e / det, Ts s_p m / det */
    vh_fix_k_t c_phi_p;           /* Ts s_phi / s_p  (phi' = p) */
    vh_fix_k_t c_fy_p[2];         /* Ts s_Fyf zeta1 / s_p, Ts s_Fyr zeta2 / s_p (eq. 31-32) */
    int32_t phi_row[3];           /* the same three in FPHI: Phi* entries (phi,p), (Fyf,p), (Fyr,p) */
    /* kinematic terms [N per unit of the product of two scaled states, FK] */
    vh_fix_k_t k_m_rvy, k_m_rvx;  /* m / (s_r s_vy), m / (s_r s_vx) */
    vh_fix_k_t k_mse_pr, k_mse_rvx; /* ms e / (s_p s_r), ms e / (s_r s_vx) */
    vh_fix_k_t k_kphi, k_cphi;    /* (kphif + kphir) / s_phi, (cphif + cphir) / s_p */
    /* appendix sums: lengths [m] */
    vh_fix_k_t k_lf, k_lr, k_tf, k_tr, k_hf, k_hr;
    /* eq. 39 and its rear counterpart */
    int32_t fz0[2];               /* m g lr / 2l, m g lf / 2l  [N, FN] */
    vh_fix_k_t k_fz_ax;           /* m h / 2l  [N per m/s^2] */
    vh_fix_k_t k_lat_ay[2];       /* lt kf m h / 4 tf, lt kr m h / 4 tr  [N per m/s^2] */
    vh_fix_k_t k_lat_phi[2];      /* lt kf g ms e / 4 tf, lt kr g ms e / 4 tr  [N per unit sin phi] */
    vh_fix_k_t k_gy[2];           /* Gy1, Gy2 [N per m/s^2]; zero without the MEC */
    vh_fix_k_t k_inv_fz[2];       /* 1 / Fzf, 1 / Fzr */
    vh_fix_k_t k_drho[2];         /* k_lat_phi / (Fz s_phi): d(Fzi/Fz)/dphi* per unit cos phi */
    vh_fix_k_t k_phi;             /* 1 / s_phi: phi* -> phi [rad] */
    vh_fix_k_t k_inv_sf[2];       /* 1 / s_Fyf, 1 / s_Fyr: Fy* -> N */
    /* wheels (eq. 30) */
    vh_fix_k_t k_inv_ts;          /* 1 / Ts */
    vh_fix_k_t k_alpha;           /* Ts / (tau + Ts) */
    vh_fix_k_t k_inv_rw, k_iw_rw; /* 1 / rw, Iw / rw */
    /* outputs */
    vh_fix_k_t k_sr, k_sp;        /* s_r, s_p: measured r, p -> z* */
    vh_fix_k_t k_inv_m;           /* 1 / m */
    vh_fix_k_t k_mse_pr_m;        /* ms e / (m s_p s_r) */
    vh_fix_k_t k_ixx_det, k_mse_det; /* Ixx / det, ms e / det */
    /* tuning */
    vh_fix_k_t k_gp[VH_SKFQ_NX];  /* Ts gp_i / s_r: per-step increment per unit r* residual */
    int32_t q[VH_SKFQ_NX];        /* FP */
    int32_t p0[VH_SKFQ_NX];       /* FP */
    int32_t r[VH_SKFQ_NY];        /* R* = T^2 R, FU */
    int32_t p_cap, p_max;         /* FP */
    int32_t x_max;                /* FX: divergence limit; vx*, vy* are clamped to it */
    int32_t mec;
    /* seeding */
    vh_fix_k_t k_seed_vx;         /* s_vx rw / 4: sum of wheel speeds -> vx* */
    vh_fix_k_t k_seed_fy[2];      /* s_Fyf m lr / 2l, s_Fyr m lf / 2l: ay -> Fy* */
    vh_fix_k_t k_seed_phi;        /* s_phi m lr / (2l zeta1): ay -> phi* */
    /* the scaling S as exact fractions s_i = s_num[i] / s_den[i] (the configuration's double s_i
     * exactly): x* -> physical units without a double, so the ECU's TX is integer only */
    int32_t s_num[VH_SKFQ_NX], s_den[VH_SKFQ_NX];
} vh_skfq_params_t;

typedef struct {
    vh_skfq_params_t prm;
    int32_t x[VH_SKFQ_NX];                 /* FX */
    int32_t p[VH_SKFQ_NX * VH_SKFQ_NX];    /* FP */
    int32_t innov[VH_SKFQ_NY];             /* FX */
    int32_t nu_ay;                         /* FX (= m/s^2) */
    int32_t w_prev[4];                     /* FO */
    int32_t wdot[4];                       /* FWD */
    int32_t fx[4], fz[4], fy[4];           /* FN */
    int32_t cs_delta[2];                   /* FD */
    uint32_t steps, resets, caps;
    uint32_t sat;                          /* saturations since init */
    uint32_t sat_step;                     /* saturations in the last step */
    uint8_t health;                        /* vh_health_t */
    uint8_t x_init;
} vh_skfq_t;

/* VH_OK, or VH_EINVAL if a constant is out of its documented range (nothing changed). */
int vh_skfq_init(vh_skfq_t *f, const vh_skfq_params_t *prm);
void vh_skfq_reset(vh_skfq_t *f);
/* One step (mask: VH_SKF_* bits). Returns 1 if the filter was reset. */
int vh_skfq_step(vh_skfq_t *f, const vh_skfq_input_t *in, unsigned mask);
/* n steps: u[n*13] rows laid out as vh_skfq_input_t, mask[n] (NULL: all valid); writes x_out[n*7]
 * (FX, scaled), fy_out[n*4], fz_out[n*4] (FN) and, when non-NULL, p_out[n*49] (FP), health_out[n].
 * Returns the resets during the run. */
uint32_t vh_skfq_run(vh_skfq_t *f, size_t n, const int32_t *u, const uint8_t *mask, int32_t *x_out,
                     int32_t *fy_out, int32_t *fz_out, int32_t *p_out, uint8_t *health_out);

#endif /* VH_SKFQ_H */
