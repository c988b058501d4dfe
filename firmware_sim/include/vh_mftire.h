/* vh_mftire.h - Magic Formula tyre: pure slip (Bakker, Nyborg & Pacejka 1987) and combined slip by
 * normalised theoretical slip (Bakker, Pacejka & Lidner 1989), with road-friction scaling.
 *
 * Pure slip, with Fz in kN inside the coefficient polynomials (as published):
 *
 *     F = D sin(C atan(B x - E (B x - atan(B x))))                                        (MF)
 *     lateral:      C = a0, D = a1 Fz^2 + a2 Fz, BCD = a3 sin(a4 atan(a5 Fz)) [N/deg],
 *                   E = a6 Fz^2 + a7 Fz + a8, x = slip angle alpha
 *     longitudinal: C = b0, D = b1 Fz^2 + b2 Fz, BCD = (b3 Fz^2 + b4 Fz) exp(-b5 Fz) [N/%],
 *                   E = b6 Fz^2 + b7 Fz + b8, x = longitudinal slip kappa
 *
 * No shifts, no camber: the curves are odd in their slip, zero at zero slip. Internally slips
 * are in rad and as a fraction (B converted from per-degree and per-percent).
 *
 * Road friction: D is scaled by lambda = mu / mu0 with mu0 = a2 / 1000 (lateral) and b2 / 1000
 * (longitudinal), the coefficient set's friction coefficient at vanishing load. So D = mu Fz
 * (1 + (a1/a2) Fz[kN]): mu is the friction limit, the tyre's load sensitivity (a1, b1 < 0) lowers
 * it as the load grows, and no pure-slip force exceeds mu Fz. BCD (the slip stiffness) does not
 * depend on mu, so on a slippery road the peak moves to smaller slip.
 *
 * Combined slip (Bakker, Pacejka & Lidner 1989, "normalised slip"):
 *
 *     sigma_x = kappa / (1 + kappa),  sigma_y = tan(alpha) / (1 + kappa)      theoretical slips
 *     sigma_xm, sigma_ym: the theoretical slips at the pure-slip peaks (kappa_m, alpha_m)
 *     s_x = sigma_x / sigma_xm,  s_y = sigma_y / sigma_ym,  s = sqrt(s_x^2 + s_y^2)
 *     Fx = (s_x / s) Fx0(kappa_eq),  Fy = (s_y / s) Fy0(alpha_eq)
 *
 * where kappa_eq and alpha_eq are the pure slips whose theoretical slip is s sigma_xm and
 * s sigma_ym (kappa_eq = sigma/(1 - sigma) driving, sigma/(1 + sigma) braking; alpha_eq =
 * atan(s sigma_ym)). With one slip zero this is the pure-slip curve exactly; at s = 1 both
 * components are at their peaks and (Fx/Dx)^2 + (Fy/Dy)^2 = 1 (the friction ellipse), which it
 * never exceeds. Force and slip velocity always point opposite ways: the tyre only dissipates.
 */
#ifndef VH_MFTIRE_H
#define VH_MFTIRE_H

/* Loads beyond which vh_mft_check does not vouch for the coefficients [N]. */
#define VH_MFT_FZ_MAX 20000.0

/* vh_mft_coef_t.model */
enum { VH_MFT_MF87 = 0, VH_MFT_PAC2002 = 1 };

typedef struct {
    double a[9];     /* lateral: a[0] = C_y, a[1..8] as published (Fz in kN, alpha in deg) */
    double b[9];     /* longitudinal: b[0] = C_x, b[1..8] as published (Fz in kN, kappa in %) */
    double fz_scale; /* tyre size by similarity: at load Fz the tyre acts as the published one at
                      * Fz / fz_scale with every force times fz_scale (1: the published tyre) */
    int model;       /* VH_MFT_MF87: a, b, fz_scale; VH_MFT_PAC2002: p instead */
    double p[8];     /* PAC2002 with load-proportional slip stiffness (CommonRoad's tyre, no camber,
                      * no shifts): p_cy1, p_dy1, p_ey1, p_ky1, p_cx1, p_dx1, p_ex1, p_kx1;
                      * C = p_c*1, D = mu p_d*1 Fz, E = p_e*1, BCD = |p_k*1| Fz */
} vh_mft_coef_t;

/* One tyre's Magic Formula factors at one load and friction (slips in rad and as a fraction). */
typedef struct {
    double fz;             /* normal load [N], >= 0 */
    double bx, cx, dx, ex; /* longitudinal: B [1/1], C, D [N], E */
    double by, cy, dy, ey; /* lateral: B [1/rad], C, D [N], E */
    double ux, uy;         /* B x at the pure-slip peaks: solve u - E (u - atan u) = tan(pi / 2C) */
    double kappa_m;        /* longitudinal slip at the peak, kappa_m = ux / bx */
    double alpha_m;        /* slip angle at the peak [rad], alpha_m = uy / by */
    double tan_alpha_m;    /* sigma_ym, the lateral theoretical slip at the peak */
    double sxm_drive;      /* sigma_xm driving, kappa_m / (1 + kappa_m) */
    double sxm_brake;      /* sigma_xm braking, kappa_m / (1 - kappa_m) (magnitude) */
    double inv_sxm_drive, inv_sxm_brake, inv_sym; /* their reciprocals */
    double ky, kx;         /* slip stiffnesses BCD [N/rad], [N] */
    double dky, dkx;       /* their slopes over the load [1/rad], [1] (for vh_mft_load_near) */
} vh_mft_state_t;

/* The passenger-car tyre of Bakker, Nyborg & Pacejka 1987 (SAE 870421), as reproduced in Wong,
 * Theory of Ground Vehicles: C_y 1.30, C_x 1.65, ... (values in vh_mftire.c). */
void vh_mft_coef_default(vh_mft_coef_t *c);
/* 1 when the coefficients give a proper peaked curve for 0 < Fz <= VH_MFT_FZ_MAX: 1 < C < 2,
 * D > 0, BCD > 0, E < 1, mu0 > 0 (the model's set); else 0. */
int vh_mft_check(const vh_mft_coef_t *c);

/* u_m of the MF peak for shape C (1 < C < 2) and curvature E (< 1), by Newton from u0 (<= 0:
 * from the E = 0 solution) with `iters` iterations (<= 0: until converged).
 * g(u) = (1 - E) u + E atan(u) - tan(pi/2C) has g' >= min(1, 1 - E) > 0: the root is unique. */
double vh_mft_peak_u(double c, double e, double u0, int iters);

/* Factors B, C, D, E at load fz [N] (negative taken as 0) and road friction mu (>= 0). */
void vh_mft_load(vh_mft_state_t *s, const vh_mft_coef_t *c, double fz, double mu);
/* As vh_mft_load, but the slip stiffnesses (the only transcendental functions of the load) from
 * their tangents at the load of `near` (loaded by vh_mft_load): exact D and E, stiffness error
 * second order in fz - near->fz. An integrator's later stages use it about its first stage. */
void vh_mft_load_near(vh_mft_state_t *s, const vh_mft_state_t *near, const vh_mft_coef_t *c, double fz, double mu);
/* Peak slips of a loaded state (the combined-slip normalisation; they never change the pure-slip
 * curves): Newton for u_x, u_y from ux, uy with `iters` iterations (ux or uy <= 0: from scratch,
 * to convergence), then kappa_m, alpha_m, tan(alpha_m). */
void vh_mft_peaks(vh_mft_state_t *s, double ux, double uy, int iters);
/* Take the peak slips of `from` (a caller stepping in time holds them over the step). */
void vh_mft_hold_peaks(vh_mft_state_t *s, const vh_mft_state_t *from);

/* Pure slip: Fx0(kappa), Fy0(alpha) [N] (alpha in rad, |alpha| < pi/2). */
double vh_mft_fx0(const vh_mft_state_t *s, double kappa);
double vh_mft_fy0(const vh_mft_state_t *s, double alpha);

/* Combined slip: kappa = (w r - v_x) / |v_x|, tan_alpha = -v_y / |v_x| (wheel axes; positive
 * slip gives positive force). 1 + kappa is floored at 1e-6 (a wheel turning backwards against
 * the travel is taken as locked). */
void vh_mft_forces(const vh_mft_state_t *s, double kappa, double tan_alpha, double *fx, double *fy);

/* Convenience: vh_mft_load, vh_mft_peaks from scratch, then vh_mft_forces. */
void vh_mft_eval(const vh_mft_coef_t *c, double fz, double mu, double kappa, double tan_alpha, double *fx,
                 double *fy);

#endif /* VH_MFTIRE_H */
