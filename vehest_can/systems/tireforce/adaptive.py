"""SKFMEC-A: the paper's SKFMEC with an online mass estimate and a load-sensitive split (double).

A second tyre-force variant beside the paper's SKFMEC (which stays as it is, the baseline). It runs
the SKFMEC unchanged and adds, per step (docs/tireforce.md, "SKFMEC-A"):

1. **mass** m̂ by recursive least squares on the longitudinal balance of the body (the plant's
   equation of motion, docs/chassis_plant.md: m (v̇x − r vy) = ΣFx − F_aero, with a_x = v̇x − r vy
   the accelerometer's reading): y = cos δ (Fx1 + Fx2) + Fx3 + Fx4 − sin δ (Fy1 + Fy2) − ½ρ CdA vx²,
   φ = a_x, y = m φ, the wheel forces from the wheel equation (eq. 30, Fxi = (Ti − Iw ω̇i)/rw).
   Both sides low-passed by the same filter (keeps y = m φ), updated at 100 Hz only when the
   longitudinal excitation makes m observable (|φ| ≥ ``ax_gate``), with forgetting λ and a
   covariance floor (it keeps adapting) and ceiling (no wind-up while gated out);
2. **axle forces** times m̂/m: ΣFy = m a_y (the a_y residual's only handle on the forces) and the yaw
   balance both scale with the mass, so a payload at the CG scales the SKFMEC's axle estimate by
   m_true/m_model (a first-order correction: Iz and the CG height are kept);
3. **normal loads** times m̂/m (every term of eq. 39 is proportional to the mass);
4. **load-sensitive split** instead of Fyi/Fyf = Fzi/Fzf (eq. 33-34): at one slip angle per axle,
   the tyres' Magic Formula forces (Bakker, Nyborg & Pacejka 1987, from a table over slip angle
   and load) that add up to the axle's: small forces share as the cornering stiffnesses
   Cα(Fz) = a3 sin(a4 atan(a5 Fz)), which grow less than the load, large ones as the friction limits;
6. **per-side friction**: each side's μ from the axle's excess differential slip (the wheels' slip
   difference beyond the one their linear stiffnesses give; the absolute slip is not observable),
   inverted through the combined-slip model's similarity in μ; each tyre's curve at its side's μ,
   μ F(α/μ) (``estimate_friction``, ``slip_observation``);
7. **combined-slip capacity**: each tyre's curve times the friction ellipse's √(1 − (Fx/μDx)²)
   with its eq.-30 Fx (``ellipse``);
8. **mass from the ride heights** (where the car has ride-height sensors, ``CHS_RideHeight``): the
   sprung mass carries its weight on the four springs in any manoeuvre (the anti-roll bars' forces
   cancel per axle, the dampers' and the heave's average out), so m_s g = Σ k_i s_i + the roll-centre
   links' vertical forces (h_f/t_f)(Fy2 − Fy1) + (h_r/t_r)(Fy4 − Fy3) (docs/chassis_plant.md; from
   the SKFMEC's forces), s_i each spring's deflection from its free length. Low-passed like the
   balance (the filter starting at the first sample, updates after one time constant), it is a
   second measurement of m (= it/g + the unsprung mass, a regressor of 1, std ``sigma_ride``) in
   the same RLS: the mass is then known from 0.2 s on, in steady cornering too, where the balance
   sees nothing (updated while |a_y| ≤ ``ay_gate``, as the balance: the roll-centre term, the least
   certain, stays moderate there).
9. **the road's friction** from the axles' kinematic slip-angle coupling α_f − α_r = δ − L r / v_x
   (v_x from a free-rolling axle) against the split's at one friction: a scalar EKF, used where it is
   lower than a side's while no side has seen a split (``estimate_friction``, ``kinematic_model``);
10. **each axle's lateral load transfer from the ride heights** (``ride_transfer``): the springs',
   bars' and links' forces, in place of eq. 39's transfer where the ride heights are usable.

Health (item 5): INIT while the SKFMEC is, DEGRADED until the mass estimate has converged (its standard
deviation below ``mass_sigma_ok`` of the model mass), whenever the SKFMEC is DEGRADED, and while the car
is outside the model (slower than vx_gate, or sliding sideways: ``implausible``); FAULT with the SKFMEC.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ...errors import ConfigError
from ...native import check, ffi, lib
from . import api as tf

ADAPTIVE = "skfmec-a"
H_INIT, H_OK, H_DEGRADED, H_FAULT = 0, 1, 2, 3


@dataclass(frozen=True)
class AdaptiveConfig:
    """What SKFMEC-A adds to the SKFMEC's configuration (the car's model parameters come from it)."""

    cda: float = 0.73            # drag area C_d A [m^2] of the car (docs/chassis_plant.md)
    rho: float = 1.2             # air density [kg/m^3]
    tau_lp: float = 0.2          # low-pass of both sides of the balance [s]
    decim: int = 20              # RLS update every 20 steps (100 Hz at Ts = 0.5 ms)
    ax_gate: float = 0.3         # |a_x| (low-passed) at least this for an update [m/s^2]
    ay_gate: float = 6.0         # |a_y| at most this (tyres far from saturation) [m/s^2]
    vx_gate: float = 5.0         # vx at least this [m/s]
    forget: float = 0.999        # λ per update (memory 1/(1 − λ) = 1000 updates = 10 s)
    sigma_y: float = 60.0        # std of the balance's residual (wheel-force and drag errors) [N]
    mass_sigma0: float = 0.2     # prior std of the mass, fraction of the model mass
    mass_sigma_floor: float = 0.005  # covariance floor (std), fraction of the model mass
    mass_sigma_ok: float = 0.02  # converged below this std (fraction): DEGRADED until then
    mass_range: tuple = (0.7, 1.6)   # m̂ clamped to these fractions of the model mass
    # the tyre's lateral Magic Formula coefficients a0..a8 (its published set, Wong's table of
    # Bakker et al. 1987), its size factor, the friction the split assumes and the bisection's range
    tyre_a: tuple = (1.30, -22.1, 1011.0, 1078.0, 1.82, 0.208, 0.0, -0.354, 0.707)
    tyre_fz_scale: float = 1.75
    mu: float = 1.0
    # per-side friction (docs/tireforce.md, "per-side friction"): the longitudinal coefficients b0..b8
    # of the same data sheet, the differential slip's low-pass, the gates, the estimate's time
    # constants (towards an observation; back to ``mu`` when there is none) and its floor
    tyre_b: tuple = (1.65, -21.3, 1144.0, 49.6, 226.0, 0.069, -0.006, 0.056, 0.486)
    tau_slip: float = 0.25       # low-pass of the excess differential slip [s]
    fx_gate: float = 200.0       # |Fx| of both wheels of the axle at least this [N]
    q_gate: float = 0.85         # secant/linear slip stiffness below this: the tyre is nonlinear
    tau_mu: float = 0.25         # the side's estimate follows its observations [s]
    tau_mu_forget: float = 3.0   # and returns to ``mu`` without them [s]
    mu_floor: float = 0.1
    ellipse_floor: float = 0.2   # the friction ellipse's factor never below this
    mass: bool = True            # ablation switches
    split: bool = True
    friction: bool = True        # per-side friction estimate
    combined: bool = True        # lateral capacity reduced by the wheel's Fx (friction ellipse)
    ride: bool = True            # the mass from the ride heights, where they are usable
    road: bool = True            # the road's friction from the axles' kinematic slip-angle coupling
    transfer: bool = True        # each axle's lateral load transfer from the ride heights, where they are usable
    spring_front: float = 30000.0  # spring rate at the wheel per corner [N/m] (the car's, docs/chassis_plant.md)
    spring_rear: float = 25000.0
    sigma_ride: float = 0.01     # std of one ride-height mass measurement, fraction of the model mass
    tyre_kz: float = 250000.0    # the tyre's vertical stiffness [N/m] (the car's data sheet: the bars' rate from k_phi)
    # the tyre's form: 0 the 1987 Magic Formula of tyre_a, tyre_b; 1 a PAC2002 set with load-proportional
    # slip stiffnesses (CommonRoad's), tyre_p = (p_cy1, p_dy1, p_ey1, |p_ky1|, p_cx1, p_dx1, p_ex1, p_kx1)
    tyre_model: int = 0
    tyre_p: tuple = (1.3507, 1.0489, -0.0074722, 21.92, 1.6411, 1.1739, 0.46403, 22.303)
    tyre_klt: float = 0.0        # the tyre's lateral compliance [m/N] (contact patch shift per lateral force)
    # contradictions (health): the SKFMEC's v_x outside the wheels' speed range by more than vx_tol + vx_tol_rel v
    vx_tol: float = 1.0          # [m/s]
    vx_tol_rel: float = 0.1
    # and the longitudinal balance's residual |y − m̂ a_x| (low-passed) beyond bal_tol + bal_tol_rel |y|
    bal_tol: float = 1000.0      # [N]
    bal_tol_rel: float = 0.25
    # plausibility (health): the body's sideways sliding a_y - r v low-passed, its gate, the hold after
    tau_vyd: float = 0.1         # [s]
    vyd_gate: float = 4.0        # [m/s^2]
    hold_implausible: float = 0.5  # DEGRADED this long after the last implausible step [s]
    # the road's friction (docs/tireforce.md, "road friction"): the measurement's low-pass, its gates (the
    # lateral excitation; the free-rolling axle whose wheels give v_x), the scalar EKF's noises, prior
    # and finite difference, and the side estimates above which it is used (no split seen)
    tau_kin: float = 0.05        # low-pass of delta - L r / v_x [s]
    ay_kin_gate: float = 1.0     # |a_y| at least this [m/s^2]
    fx_free: float = 400.0       # |Fx| of both wheels of an axle at most this: free-rolling [N]
    kin_q: float = 0.02          # std of the friction's random walk per update
    kin_r_deg: float = 0.1       # std of the measured alpha_f - alpha_r [deg]
    kin_sigma0: float = 0.2      # prior std of the road's friction (and its ceiling)
    kin_dmu: float = 0.05        # the finite difference of the measurement's derivative in mu
    kin_dh_max: float = 30.0     # that derivative bounded to this [deg per unit mu]
    kin_side_min: float = 0.95   # used (and updated) only while both sides' estimates are at least this
    kin_nis_gate: float = 9.0    # an update whose normalised innovation squared exceeds this is refused (3 sigma)
    # each tyre's bound (docs/tireforce.md, "Per-tyre bound"): bound_z sigma; the axle model's std (N, and a
    # fraction of |F_axle|) and the lateral load transfer's (N, and a fraction of |dFz|), chosen on the design
    # runs; a bound wider than bound_max [N] makes the health DEGRADED
    bound_z: float = 1.96
    bound_axle_abs: float = 150.0
    bound_axle_rel: float = 0.08
    bound_lt_abs: float = 200.0
    bound_lt_rel: float = 0.1
    bound_max: float = 2000.0

    @classmethod
    def for_car(cls, car, **overrides) -> AdaptiveConfig:
        """The defaults with a car's data (:func:`car_fields`)."""
        return replace(cls(), **car_fields(car), **overrides)


def car_fields(car) -> dict:
    """What SKFMEC-A takes from a car (:class:`~vehest_can.carfile.CarFile`), as ``vh_tfa_config_t`` fields:
    drag, springs, the tyre's vertical stiffness and, where the car file has them, its Magic Formula
    coefficients. What the ECU and the off-line references both write."""
    f = {"cda": car.drag_area_m2, "rho": car.air_density_kg_m3, "spring_front": car.spring_rate_front_n_per_m,
         "spring_rear": car.spring_rate_rear_n_per_m, "tyre_kz": car.tyre_stiffness_n_per_m}
    if car.lateral_coefficients is not None:
        f["tyre_a"] = tuple(car.lateral_coefficients)
    if car.longitudinal_coefficients is not None:
        f["tyre_b"] = tuple(car.longitudinal_coefficients)
    if car.pac2002_coefficients is not None:  # |p_ky1|: its sign is the convention's, not the tyre's
        pac = car.pac2002_coefficients
        f["tyre_model"], f["tyre_p"] = 1, (*pac[:3], abs(pac[3]), *pac[4:])
    f["tyre_klt"] = car.lateral_compliance_m_per_n
    return f


@dataclass
class AdaptiveRun(tf.TireForceRun):
    """A TireForceRun (x: the SKFMEC's states underneath; fy, fz, health: SKFMEC-A's) plus the mass."""

    mass: np.ndarray | None = None      # (n,) m̂ [kg]
    mass_std: np.ndarray | None = None  # (n,) its standard deviation [kg]
    raw: dict | None = None             # fixed point: the integers (fy, fz FN; k Q2.29; p Q1.30)
    mu: np.ndarray | None = None        # (n, 4) the friction each tyre's split assumed (None: ``mu``)
    road_mu: np.ndarray | None = None   # (n,) the road's friction from the kinematic coupling (None: off)
    contra: np.ndarray | None = None    # (n,) contradictions (C_VX, C_MASS, C_BOUNDS bits)
    bound: np.ndarray | None = None     # (n, 4) each tyre's bound: |F_y - fy| within it with 95 % [N]


def _pac(c: float, mu: float, e: float, k: float, x: np.ndarray, fz: np.ndarray) -> np.ndarray:
    """A PAC2002 pure-slip curve with load-proportional slip stiffness (CommonRoad's tyre model,
    no camber, no shifts): D = μ Fz, B = k Fz / (C D), x in rad (slip angle) or as a fraction (κ)."""
    bx = k / (c * mu) * x
    return mu * np.maximum(fz, 1.0) * np.sin(c * np.arctan(bx - e * (bx - np.arctan(bx))))


def lateral_force(alpha_deg: np.ndarray, fz: np.ndarray, cfg: AdaptiveConfig) -> np.ndarray:
    """The tyre's pure-slip lateral Magic Formula (Bakker, Nyborg & Pacejka 1987) at friction
    ``cfg.mu``, with the tyre's size factor: F = sc F_pub(α, Fz / sc). α in degrees, ≥ 0. A PAC2002 tyre
    (``tyre_model`` 1): ``_pac`` with its peak friction p_dy1 times ``cfg.mu``."""
    if cfg.tyre_model == 1:
        p = cfg.tyre_p
        return _pac(p[0], p[1] * cfg.mu, p[2], p[3], np.radians(alpha_deg), fz)
    a = cfg.tyre_a
    sc = cfg.tyre_fz_scale
    f = np.maximum(fz, 1.0) * 1e-3 / sc
    d = (a[1] * f * f + a[2] * f) * cfg.mu / (a[2] * 1e-3)
    b = a[3] * np.sin(a[4] * np.arctan(a[5] * f)) / (a[0] * d)
    e = a[6] * f * f + a[7] * f + a[8]
    bx = b * alpha_deg
    return sc * d * np.sin(a[0] * np.arctan(bx - e * (bx - np.arctan(bx))))


N_ALPHA, ALPHA_STEP_DEG = 33, 0.25  # the split's table: slip angle knots 0, 0.25, ..., 8 deg
N_FZ, FZ_STEP_N = 29, 500.0         # and load knots 0, 500, ..., 14 000 N
N_S, S_STEP = 41, 0.05              # normalised combined slip knots 0, 0.05, ..., 2 (the secant table)


def _mf(coef: tuple, x: np.ndarray, f: np.ndarray, bcd: np.ndarray) -> np.ndarray:
    """Bakker-Nyborg-Pacejka 1987 at μ = 1 (D scaled by 1/μ0, μ0 = coef[2]/1000): x the slip in the
    formula's unit (deg or %), f the load in kN (already divided by the size factor)."""
    d = (coef[1] * f * f + coef[2] * f) / (coef[2] * 1e-3)
    e = coef[6] * f * f + coef[7] * f + coef[8]
    bx = bcd / (coef[0] * d) * x
    return d * np.sin(coef[0] * np.arctan(bx - e * (bx - np.arctan(bx))))


def longitudinal_force(kappa_pct: np.ndarray, fz: np.ndarray, cfg: AdaptiveConfig) -> np.ndarray:
    """The tyre's pure-slip longitudinal Magic Formula at μ = 1 (BCD = (b3 Fz² + b4 Fz) e^(−b5 Fz)
    per %), with the size factor; κ in %, ≥ 0. A PAC2002 tyre: ``_pac`` with p_dx1."""
    if cfg.tyre_model == 1:
        p = cfg.tyre_p
        return _pac(p[4], p[5], p[6], p[7], np.asarray(kappa_pct) / 100.0, fz)
    b, sc = cfg.tyre_b, cfg.tyre_fz_scale
    f = np.maximum(fz, 1.0) * 1e-3 / sc
    return sc * _mf(b, kappa_pct, f, (b[3] * f * f + b[4] * f) * np.exp(-b[5] * f))


def _peak(fun, hi: float) -> float:
    """The slip of a pure-slip curve's maximum on (0, hi] (golden section after a scan: off-line)."""
    x = np.linspace(hi / 400, hi, 400)
    j = int(np.argmax(fun(x)))
    lo, up = x[max(j - 1, 0)], x[min(j + 1, len(x) - 1)]
    for _ in range(60):
        a, b = up - 0.618034 * (up - lo), lo + 0.618034 * (up - lo)
        if fun(np.array([a]))[0] < fun(np.array([b]))[0]:
            lo = a
        else:
            up = b
    return 0.5 * (lo + up)


def slip_stiffness_pct(fz: float, cfg: AdaptiveConfig) -> float:
    """The longitudinal slip stiffness C_κ [N per %]: (b3 f² + b4 f) e^(−b5 f) of the 1987 formula (f the
    load in kN over the size factor, times it), p_kx1 Fz / 100 of a PAC2002 tyre."""
    if cfg.tyre_model == 1:
        return cfg.tyre_p[7] * fz / 100.0
    b, sc = cfg.tyre_b, cfg.tyre_fz_scale
    f = fz * 1e-3 / sc
    return sc * (b[3] * f * f + b[4] * f) * np.exp(-b[5] * f)


def friction_tables(cfg: AdaptiveConfig) -> dict:
    """Per load knot (made off-line, the ECU's tables): the longitudinal slip compliance 1/Cκ
    [1/N], the friction limit Dx [N], 1/κ_m and 1/α_m (the pure-slip peak slips, κ as a fraction,
    α in rad), and the secant ratio of the longitudinal curve at the normalised slip s_j = j S_STEP,
    Q(s) = Fx0(s κ_m) / (Cκ s κ_m) (1 at s = 0). Row 0 (no load) repeats row 1."""
    out = {k: np.empty(N_FZ) for k in ("compliance", "dx", "inv_kappa_m", "inv_alpha_m")}
    out["secant"] = np.empty((N_FZ, N_S))
    for i in range(N_FZ):
        fz = max(i, 1) * FZ_STEP_N
        c_pct = slip_stiffness_pct(fz, cfg)   # N per %
        km = _peak(lambda x, z=fz: longitudinal_force(x, np.full_like(x, z), cfg), 40.0)  # %
        am = _peak(lambda x, z=fz: lateral_force(x, np.full_like(x, z), cfg), 30.0)        # deg
        out["compliance"][i] = 1.0 / (100.0 * c_pct)
        out["dx"][i] = longitudinal_force(np.array([km]), np.array([fz]), cfg)[0]
        out["inv_kappa_m"][i] = 100.0 / km
        out["inv_alpha_m"][i] = 1.0 / math.radians(am)
        sj = np.arange(1, N_S) * S_STEP
        out["secant"][i, 0] = 1.0
        out["secant"][i, 1:] = longitudinal_force(sj * km, np.full_like(sj, fz), cfg) / (c_pct * sj * km)
    return out


def _at_load(tab: np.ndarray, fz: np.ndarray) -> np.ndarray:
    """A per-load-knot table (N_FZ, ...) linear in the load (clamped to the knots)."""
    x = np.clip(fz / FZ_STEP_N, 0.0, N_FZ - 1.0)
    iz = np.minimum(x.astype(int), N_FZ - 2)
    wz = x - iz
    if tab.ndim > 1:
        wz = wz[..., None]
    return tab[iz] * (1.0 - wz) + tab[iz + 1] * wz


def force_table(cfg: AdaptiveConfig) -> np.ndarray:
    """(N_FZ, N_ALPHA) lateral force [N] of the tyre at the knots (made off-line: the ECU's table)."""
    al, fz = np.meshgrid(np.arange(N_ALPHA) * ALPHA_STEP_DEG, np.arange(N_FZ) * FZ_STEP_N)
    tab = lateral_force(al, fz, cfg)
    tab[0] = 0.0
    return tab


def load_sensitive_split(axle: np.ndarray, fz: np.ndarray, cfg: AdaptiveConfig,
                         table: np.ndarray | None = None, mu: np.ndarray | None = None,
                         cap: np.ndarray | None = None, alpha: np.ndarray | None = None,
                         peak: np.ndarray | None = None) -> np.ndarray:
    """Per-tyre forces from the (n, 2) axle means and (n, 4) loads: the one slip angle α per axle at
    which the two tyres' forces add up to the axle's, each tyre's force at it. The tyre's force is
    the table of its Magic Formula, linear between the knots (in load, then in α), so the pair's
    sum is piecewise linear in α and its inverse is exact: the first knot j where the sum reaches
    the axle's force, then linear between j - 1 and j (the fixed-point version does the same).
    Small forces share as the cornering stiffnesses (the first segment), large ones as the
    friction limits; beyond the pair's peak, as at the peak.

    With ``mu`` (n, 4) each tyre's curve is the Magic Formula's similarity at that friction,
    μ F(α/μ) (D times μ, B over μ: the slip stiffness kept; exact for this formula), sampled at the
    knots (α/μ linear between the table's knots, held beyond its last); with ``cap`` (n, 4) it is
    scaled by the friction ellipse's factor. ``alpha`` (n, 2), if given, receives each axle's slip
    angle [deg] (the knots' position where the pair's sum is reached; the peak's beyond it), ``peak``
    (n, 2) the pair's largest sum at the knots [N] (twice the axle force it can carry)."""
    tab = force_table(cfg) if table is None else table
    out = np.empty_like(fz)
    rows = np.arange(len(fz))
    knots = np.arange(N_ALPHA, dtype=np.float64)
    for a, (i, j) in enumerate(((0, 1), (2, 3))):
        f = []
        for w in (i, j):
            g = _at_load(tab, fz[:, w])  # (n, N_ALPHA)
            if mu is not None:
                xa = np.minimum(knots[None, :] / mu[:, w:w + 1], N_ALPHA - 1.0)
                ia = np.minimum(xa.astype(int), N_ALPHA - 2)
                wa = xa - ia
                g = (np.take_along_axis(g, ia, 1) * (1.0 - wa) + np.take_along_axis(g, ia + 1, 1) * wa) * mu[:, w:w + 1]
            if cap is not None:
                g = g * cap[:, w:w + 1]
            f.append(g)
        tot = f[0] + f[1]
        want = 2.0 * np.abs(axle[:, a])
        reach = tot[:, 1:] >= want[:, None]
        k = np.where(reach.any(1), reach.argmax(1) + 1, 0)  # first knot that reaches it; 0: none
        top = tot.argmax(1)
        kk = np.where(k > 0, k, 1)
        lo_t, hi_t = tot[rows, kk - 1], tot[rows, kk]
        lo_f, hi_f = f[0][rows, kk - 1], f[0][rows, kk]
        t = np.where(hi_t > lo_t, (want - lo_t) / np.where(hi_t > lo_t, hi_t - lo_t, 1.0), 0.0)
        f_in = lo_f + t * (hi_f - lo_f)
        share = np.where(want > 0, f_in / np.where(want > 0, want, 1.0), f[0][:, 1] / tot[:, 1])
        share = np.where(k > 0, share, f[0][rows, top] / tot[rows, top])
        out[:, i] = 2.0 * axle[:, a] * share
        out[:, j] = 2.0 * axle[:, a] - out[:, i]
        if alpha is not None:
            alpha[:, a] = np.where(k > 0, kk - 1 + np.clip(t, 0.0, 1.0), top) * ALPHA_STEP_DEG
        if peak is not None:
            peak[:, a] = tot[rows, top]
    return out


def tyre_bounds(fy: np.ndarray, fz: np.ndarray, axle: np.ndarray, base_axle: np.ndarray, var_base: np.ndarray,
                k: np.ndarray, var_k: np.ndarray, cfg: AdaptiveConfig) -> np.ndarray:
    """Each tyre's bound z σ_i (docs/tireforce.md, "Per-tyre bound"; vh_tfa.c ``bounds``): the axle mean's
    variance σ_a² = k² P_F + F² σ_k² + axle_abs² + (axle_rel F_axle)² (F the SKFMEC's axle mean with its
    filter variance P_F, F_axle = k F), through the split's share g_i = F_i / F_axle, plus the split's own
    term from the load transfer's std σ_ΔFz = lt_abs + lt_rel |ΔFz|: σ_i² = g_i² σ_a² + (F_axle σ_ΔFz / F̄z)².
    fy, fz (n, 4); axle, base_axle, var_base (n, 2); k, var_k (n,)."""
    out = np.empty_like(fy)
    for a, (i, j) in enumerate(((0, 1), (2, 3))):
        mag = np.abs(axle[:, a])
        var_a = (k ** 2 * var_base[:, a] + base_axle[:, a] ** 2 * var_k + cfg.bound_axle_abs ** 2
                 + (cfg.bound_axle_rel * mag) ** 2)
        mean, dz = 0.5 * (fz[:, i] + fz[:, j]), 0.5 * (fz[:, j] - fz[:, i])
        sdz = cfg.bound_lt_abs + cfg.bound_lt_rel * np.abs(dz)
        split = mag * np.where(mean > sdz, sdz / np.where(mean > sdz, mean, 1.0), 1.0)
        for w in (i, j):
            g = np.where(mag >= 1.0, np.clip(fy[:, w] / np.where(mag >= 1.0, axle[:, a], 1.0), 0.0, 2.0), 1.0)
            out[:, w] = cfg.bound_z * np.sqrt(g ** 2 * var_a + split ** 2)
    return out


def rls_step(m_hat: float, p: float, phi: float, y: float, r_y: float, forget: float,
             p_floor: float, p_ceil: float) -> tuple[float, float]:
    """One scalar recursive-least-squares update of y = m φ with forgetting λ (Ljung & Söderström,
    *Theory and Practice of Recursive Identification*, 1983, ch. 2): K = P φ / (σ² + φ P φ),
    m̂ += K (y − φ m̂), P = (1 − K φ) P / λ, P kept in [P_floor, P_ceil]."""
    gain = p * phi / (r_y + phi * p * phi)
    return m_hat + gain * (y - phi * m_hat), min(p_ceil, max(p_floor, (1.0 - gain * phi) * p / forget))


def estimate_mass(u: tf.Inputs, base: tf.TireForceRun, mask: np.ndarray, skf: tf.SkfConfig,
                  cfg: AdaptiveConfig, ride: np.ndarray | None = None,
                  balance: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """m̂ and its std per step (held between the 100 Hz updates). ``ride``: (n, 4) the springs'
    deflections [m] where usable, NaN rows elsewhere (None: no ride-height sensors). ``balance`` (n,) bool,
    if given, receives where the balance contradicts the mass: |y_lp − m̂ a_x,lp| > bal_tol + bal_tol_rel
    |y_lp| with the inputs valid for 5τ, v_x ≥ vx_gate and |a_y| ≤ ay_gate (held otherwise)."""
    n = len(u)
    m0 = skf.m
    ts = skf.ts
    alpha_w = ts / (skf.tau_wdot + ts)
    alpha_lp = ts / (cfg.tau_lp + ts)
    lo, hi = cfg.mass_range[0] * m0, cfg.mass_range[1] * m0
    p_floor, p_ceil = (cfg.mass_sigma_floor * m0) ** 2, (cfg.mass_sigma0 * m0) ** 2
    r_y = cfg.sigma_y ** 2
    m_hat, p = m0, p_ceil
    mass, std = np.empty(n), np.empty(n)
    wdot = np.zeros(4)
    w_prev = u.omega[0].copy()
    yf = phif = 0.0
    all_valid = int(lib.VH_SKF_ALL_VALID)
    valid_run = 0
    springs = np.array([cfg.spring_front, cfg.spring_front, cfg.spring_rear, cfg.spring_rear])
    # usable ride heights per step (none without the sensors or with item 8 off)
    ride_ok = np.all(np.isfinite(ride), axis=1) if cfg.ride and ride is not None else np.zeros(n, bool)
    r_ride = (cfg.sigma_ride * m0) ** 2
    ride_min = math.floor(cfg.tau_lp / ts + 0.5)  # the ride heights' low-pass starts at their first sample
    w_lp, ride_run = 0.0, 0
    bal = False
    for k in range(n):
        if ride_ok[k]:
            assert ride is not None
            # the sprung weight: the springs' forces and the roll-centre links' vertical forces
            fy = base.fy[k]
            w_k = (float(springs @ ride[k]) + skf.hf / skf.tf * (fy[1] - fy[0]) + skf.hr / skf.tr * (fy[3] - fy[2]))
            w_lp = w_k if ride_run == 0 else w_lp + alpha_lp * (w_k - w_lp)
            ride_run += 1
        else:
            ride_run = 0
        w = u.omega[k]
        ok = (int(mask[k]) & all_valid) == all_valid and np.all(np.isfinite(w)) and math.isfinite(u.ax[k])
        if ok:
            wdot += alpha_w * ((w - w_prev) / ts - wdot)       # eq. 30's filtered ω̇ (τ as the SKFMEC's)
            w_prev = w
            fx = (u.torque[k] - skf.iw * wdot) / skf.rw         # eq. 30
            d = u.delta[k]
            fy_front = 2.0 * base.x[k, 5] * m_hat / m0          # 2 Fyf, mass-corrected
            vx = base.x[k, 0]
            y = (math.cos(d) * (fx[0] + fx[1]) + fx[2] + fx[3] - math.sin(d) * fy_front
                 - 0.5 * cfg.rho * cfg.cda * vx * abs(vx))
            yf += alpha_lp * (y - yf)
            phif += alpha_lp * (u.ax[k] - phif)
            valid_run += 1
        else:
            valid_run = 0
        if balance is not None:
            if valid_run > 5 * cfg.tau_lp / ts and base.x[k, 0] >= cfg.vx_gate and abs(u.ay[k]) <= cfg.ay_gate:
                bal = abs(yf - phif * m_hat) > cfg.bal_tol + cfg.bal_tol_rel * abs(yf)
            balance[k] = bal
        if (k + 1) % cfg.decim == 0:
            gated = (valid_run > 5 * cfg.tau_lp / ts and abs(phif) >= cfg.ax_gate
                     and abs(u.ay[k]) <= cfg.ay_gate and base.x[k, 0] >= cfg.vx_gate)
            if gated:
                m_hat, p = rls_step(m_hat, p, phif, yf, r_y, cfg.forget, p_floor, p_ceil)
                m_hat = min(hi, max(lo, m_hat))
            if ride_run > ride_min and abs(u.ay[k]) <= cfg.ay_gate:  # m = sprung weight / g + the unsprung mass
                m_hat, p = rls_step(m_hat, p, 1.0, w_lp / skf.g + (m0 - skf.ms), r_ride, cfg.forget, p_floor, p_ceil)
                m_hat = min(hi, max(lo, m_hat))
        mass[k], std[k] = m_hat, math.sqrt(p)
    return mass, std


def bar_rates(skf: tf.SkfConfig, cfg: AdaptiveConfig) -> tuple[float, float]:
    """Each axle's anti-roll bar as a force per compression difference [N/m], k_arb / (4 t²) (the car's data
    sheet, docs/chassis_plant.md): the suspension's roll stiffness is what k_φ leaves after the tyres in
    series, k_susp = 1/(1/k_φ − 1/(2 k_t t²)), and the bar what the springs leave of it, k_susp − 2 k t²."""
    out = []
    for kphi, k, t in ((skf.kphif, cfg.spring_front, skf.tf), (skf.kphir, cfg.spring_rear, skf.tr)):
        inv = 1.0 / kphi - 1.0 / (2.0 * cfg.tyre_kz * t * t)
        if inv <= 0.0:
            raise ConfigError(f"k_phi {kphi} Nm/rad: the tyres alone ({cfg.tyre_kz} N/m) are softer in roll")
        out.append((1.0 / inv - 2.0 * k * t * t) / (4.0 * t * t))
    return out[0], out[1]


def ride_transfer(fz: np.ndarray, axle: np.ndarray, ride: np.ndarray, skf: tf.SkfConfig,
                  cfg: AdaptiveConfig) -> np.ndarray:
    """(n, 4) the loads with each axle's lateral load transfer from the ride heights where they are usable
    (item 10; rows of ``ride`` NaN elsewhere: the model's kept): the tyre carries its corner's spring, bar
    and link forces (and its unsprung weight, the same on both sides), so at the axle's mean load
    F̄z the right tyre has F̄z + ΔF and the left F̄z − ΔF with
    ΔF = ½ ((k + 2 k_arb/(4t²)) (s_R − s_L) + (h/t) 2 F_y,axle) (the link term: the roll centre's
    vertical forces ∓F_y h/t of both tyres, from the axle force, not the split; dampers and the
    unsprung dynamics left out), plus, for a tyre with a lateral compliance K_lt, the patches' shift
    K_lt F_yi under each load: ΔF += K_lt/(2t) · 2 F_y,axle (F̄z² + ΔF²)/F̄z (the pair split as its loads;
    ΔF of the springs on the right)."""
    out = fz.copy()
    usable = np.all(np.isfinite(ride), axis=1)
    bars = bar_rates(skf, cfg)
    for a, (i, j, k, h, t) in enumerate(((0, 1, cfg.spring_front, skf.hf, skf.tf),
                                         (2, 3, cfg.spring_rear, skf.hr, skf.tr))):
        mean = 0.5 * (fz[usable, i] + fz[usable, j])
        d = 0.5 * ((k + 2.0 * bars[a]) * (ride[usable, j] - ride[usable, i]) + h / t * 2.0 * axle[usable, a])
        if cfg.tyre_klt > 0.0:
            # the contact patches shift by K_lt F_yi under the lateral forces: the loads' moment about the
            # axle grows by K_lt (F_zL F_yL + F_zR F_yR), with the pair split as its loads, 2 F̄ (F̄z² + d²)/F̄z
            d = d + cfg.tyre_klt / (2.0 * t) * 2.0 * axle[usable, a] * (mean * mean + d * d) / mean
        out[usable, i], out[usable, j] = mean - d, mean + d
    return out


def wheel_forces(u: tf.Inputs, mask: np.ndarray, skf: tf.SkfConfig) -> np.ndarray:
    """(n, 4) eq. 30's Fxi = (Ti − Iw ω̇i)/rw as the SKFMEC computes them (its filtered ω̇, updated
    on steps whose inputs are valid, held otherwise)."""
    ts = skf.ts
    alpha_w = ts / (skf.tau_wdot + ts)
    out = np.zeros((len(u), 4))
    wdot, w_prev, fx = np.zeros(4), None, np.zeros(4)
    for k in range(len(u)):
        if int(mask[k]) & int(lib.VH_SKF_U_VALID):
            w = u.omega[k]
            if w_prev is None:
                w_prev = w.copy()
            wdot += alpha_w * ((w - w_prev) / ts - wdot)
            w_prev = w
            fx = (u.torque[k] - skf.iw * wdot) / skf.rw
        out[k] = fx
    return out


def ellipse(fx: np.ndarray, fz: np.ndarray, mu: np.ndarray, tabs: dict, cfg: AdaptiveConfig) -> np.ndarray:
    """The friction ellipse's lateral factor √(1 − (Fx / (μ Dx(Fz)))²), floored (Pacejka, *Tire and
    Vehicle Dynamics*, 3rd ed. 2012, sec. 4.3.2; the plant's combined slip never exceeds it)."""
    r = fx / (mu * _at_load(tabs["dx"], fz))
    return np.sqrt(np.maximum(cfg.ellipse_floor ** 2, 1.0 - r * r))


def _linear_slip(fx: float, fz: float, tabs: dict) -> float:
    """A tyre's linear slip |Fx|/Cκ(Fz)."""
    return abs(fx) * float(_at_load(tabs["compliance"], np.array(fz)))


def _combined_slip(kappa: float, alpha_deg: float, fz: float, tabs: dict) -> float:
    """√((κ/κ_m)² + (α/α_m)²) at the load: the normalised combined slip times μ."""
    fzv = np.array(fz)
    return math.hypot(kappa * float(_at_load(tabs["inv_kappa_m"], fzv)),
                      math.radians(alpha_deg) * float(_at_load(tabs["inv_alpha_m"], fzv)))


def slip_observation(ex: float, fx_low: float, fz_low: float, alpha_deg: float, tabs: dict,
                     cfg: AdaptiveConfig) -> float | None:
    """The friction under the tyre that slips ``ex`` more than its linear (nominal-μ) slip
    |Fx|/Cκ, from the combined-slip model of Bakker, Pacejka & Lidner 1989 under its similarity in
    μ (the plant's tyre, docs/chassis_plant.md): the longitudinal secant stiffness Fx/κ =
    Cκ Q(s) depends only on the normalised combined slip s = √((κ/κ_m)² + (α/α_m)²)/μ, so
    Q(s) = κ_lin/(κ_lin + ex) gives s, then μ = √((κ/κ_m)² + (α/α_m)²)/s. None: the tyre is
    linear (Q ≥ ``q_gate``), μ not observable."""
    k_lin = _linear_slip(fx_low, fz_low, tabs)
    kap = k_lin + ex
    q = k_lin / kap
    if q >= cfg.q_gate:
        return None
    row = _at_load(tabs["secant"], np.array(fz_low))
    j = int(np.argmax(row <= q)) if np.any(row <= q) else N_S - 1
    if row[j] <= q and j > 0:
        s_n = (j - 1 + (row[j - 1] - q) / (row[j - 1] - row[j])) * S_STEP
    else:
        s_n = (N_S - 1) * S_STEP
    return min(cfg.mu, max(cfg.mu_floor, _combined_slip(kap, alpha_deg, fz_low, tabs) / s_n))


def linear_share(fx: float, fz: float, alpha_deg: float, mu: float, tabs: dict) -> float:
    """The secant ratio Q(s) of a tyre at its linear slip |Fx|/Cκ and slip angle α on friction μ (s beyond
    the table's last knot is read there)."""
    x = min(_combined_slip(_linear_slip(fx, fz, tabs), alpha_deg, fz, tabs) / (mu * S_STEP), N_S - 1.0)
    row = _at_load(tabs["secant"], np.array(fz))
    j = min(int(x), N_S - 2)
    return float(row[j] + (x - j) * (row[j + 1] - row[j]))


def effective_mu(side: np.ndarray, road: np.ndarray, cfg: AdaptiveConfig) -> np.ndarray:
    """(n, 4) the friction each tyre's curve is taken at: its side's estimate, and the road's where it
    is lower while neither side has seen a split (both at least ``kin_side_min``)."""
    side, road = np.atleast_2d(side), np.atleast_1d(road)
    mu = side[:, [0, 1, 0, 1]]
    uniform = (side.min(1) >= cfg.kin_side_min)[:, None]
    return np.where(uniform, np.minimum(mu, road[:, None]), mu)


def kinematic_model(axle: np.ndarray, fz: np.ndarray, fx: np.ndarray, mu: float, tabs: dict,
                    cfg: AdaptiveConfig) -> tuple[float, np.ndarray]:
    """The split's α_f − α_r [deg] (each axle's slip angle signed as its force) on a road of friction
    ``mu`` under all four tyres, and the pairs' largest sums (2,) [N]; axle (1, 2), fz and fx (1, 4)."""
    mu4 = np.full((1, 4), mu)
    cap = ellipse(fx, fz, mu4, tabs, cfg) if cfg.combined else None
    alpha, peak = np.zeros((1, 2)), np.zeros((1, 2))
    load_sensitive_split(axle, fz, cfg, mu=mu4, cap=cap, alpha=alpha, peak=peak)
    return float(np.sign(axle[0, 0]) * alpha[0, 0] - np.sign(axle[0, 1]) * alpha[0, 1]), peak[0]


def free_rolling_speed(omega: np.ndarray, fx: np.ndarray, delta: float, rw: float, fx_free: float) -> float | None:
    """v_x [m/s] from an axle whose wheels neither brake nor drive (|Fx| ≤ fx_free on both: their slip is
    below ~0.3 %): the rear's mean r_w (ω3 + ω4)/2, else the front's over cos δ (the yaw terms ∓ r t
    cancel in the mean); None when neither rolls free."""
    if max(abs(fx[2]), abs(fx[3])) <= fx_free:
        return rw * 0.5 * (omega[2] + omega[3])
    if max(abs(fx[0]), abs(fx[1])) <= fx_free and math.cos(delta) > 0.0:
        return rw * 0.5 * (omega[0] + omega[1]) / math.cos(delta)
    return None


def estimate_friction(u: tf.Inputs, base: tf.TireForceRun, mask: np.ndarray, skf: tf.SkfConfig,
                      cfg: AdaptiveConfig, fx: np.ndarray, fz: np.ndarray, axle: np.ndarray,
                      tabs: dict) -> tuple[np.ndarray, np.ndarray]:
    """(n, 2) friction of the left and right side and (n,) the road's (held between the 100 Hz updates).

    **Per side** (item 6, ``friction``): per axle, the excess differential slip e = (κR − κL) −
    (FxR/CκR − FxL/CκL), low-passed (the wheel-speed difference at the yaw-corrected wheel speeds
    vx ∓ r t: an error of vx is common to both and cancels); the side that slips more than its
    linear slip is the low-μ side, its μ from ``slip_observation`` with the axle's slip angle of the
    previous step's split. Gated: inputs valid, vx ≥ vx_gate, |Fx| ≥ fx_gate on both wheels in one
    direction. Without an observation a side returns to ``mu`` (time constant tau_mu_forget); never
    below mu_floor.

    **The road** (item 9, ``road``): the kinematic coupling of the axles' slip angles
    α_f − α_r = δ − (l_f + l_r) r / v_x (no v_y in it), with v_x from a free-rolling axle's wheel
    speeds (``free_rolling_speed``), low-passed (τ_kin), against the split's α_f − α_r at
    one friction μ̂ under all four tyres: a scalar EKF on μ̂ (random walk kin_q per update, R =
    kin_r_deg², H by a finite difference kin_dmu, bounded by kin_dh_max), so that it moves only as far as the coupling
    can see μ (near saturation; on a dry road at small slip angles H is ~0); an update whose normalised
    innovation squared (z − h)²/(R + H P H) exceeds kin_nis_gate is refused (the model cannot explain it at
    any nearby μ: near the pairs' peaks under braking H turns small while the residual stays). Gated: inputs valid
    for 5τ_lp, the measurement for 5τ_kin, |a_y| ≥ ay_kin_gate, v_x ≥ vx_gate, and neither side
    estimate below kin_side_min (one μ under the axle: the model's assumption). Kept at least at
    the friction whose pair peaks carry the axle forces, at most ``mu``; without an update it
    returns to ``mu`` (tau_mu_forget), except while the car corners (|a_y| ≥ ay_kin_gate, inputs valid)
    with no axle rolling free, when it is held; its variance grows to the prior."""
    n, ts = len(u), skf.ts
    a_lp = ts / (cfg.tau_slip + ts)
    a_kin = ts / (cfg.tau_kin + ts)
    valid_min = 5 * cfg.tau_lp / ts
    kin_min = math.floor(5.0 * cfg.tau_kin / ts + 0.5)
    g_obs = cfg.decim * ts / cfg.tau_mu
    g_fgt = cfg.decim * ts / cfg.tau_mu_forget
    half = np.array([skf.tf, skf.tr])
    wheelbase = skf.lf + skf.lr
    comp = _at_load(tabs["compliance"], fz)  # (n, 4)
    mu_side = np.array([cfg.mu, cfg.mu])
    p_road_max = cfg.kin_sigma0 ** 2
    mu_road, p_road = cfg.mu, p_road_max
    q_road, r_road = cfg.kin_q ** 2, cfg.kin_r_deg ** 2
    out, road = np.empty((n, 2)), np.empty(n)
    e = np.zeros(2)
    z_lp, kin_run = 0.0, 0
    all_valid = int(lib.VH_SKF_ALL_VALID)
    valid_run = 0
    alpha = np.zeros((1, 2))
    for k in range(n):
        vx = base.x[k, 0]
        valid = (int(mask[k]) & all_valid) == all_valid
        if valid:
            if cfg.friction and vx >= cfg.vx_gate:
                for a in range(2):
                    i, j = 2 * a, 2 * a + 1
                    rt = u.r[k] * half[a]
                    dk = skf.rw * (u.omega[k, j] / (vx + rt) - u.omega[k, i] / (vx - rt))
                    e[a] += a_lp * (dk - (fx[k, j] * comp[k, j] - fx[k, i] * comp[k, i]) - e[a])
            valid_run += 1
        else:
            valid_run = 0
        v_free = free_rolling_speed(u.omega[k], fx[k], u.delta[k], skf.rw, cfg.fx_free) if valid and cfg.road else None
        if v_free is not None and v_free >= cfg.vx_gate:
            z = math.degrees(u.delta[k] - wheelbase * u.r[k] / v_free)
            z_lp = z if kin_run == 0 else z_lp + a_kin * (z - z_lp)
            kin_run += 1
        else:
            kin_run = 0
        if (k + 1) % cfg.decim == 0:
            seen = [False, False]
            if cfg.friction and valid_run > valid_min and vx >= cfg.vx_gate and k > 0:
                mu4 = effective_mu(mu_side, np.array([mu_road]), cfg)
                cap = ellipse(fx[k - 1:k], fz[k - 1:k], mu4, tabs, cfg) if cfg.combined else None
                load_sensitive_split(axle[k - 1:k], fz[k - 1:k], cfg, mu=mu4, cap=cap, alpha=alpha)
                for a in range(2):
                    i, j = 2 * a, 2 * a + 1
                    if not (fx[k, i] * fx[k, j] > 0 and min(abs(fx[k, i]), abs(fx[k, j])) >= cfg.fx_gate):
                        continue
                    ex = e[a] * math.copysign(1.0, fx[k, j])  # > 0: the right wheel slips more
                    side, w = (1, j) if ex > 0 else (0, i)
                    o = i if w == j else j
                    # the differential slip is the low side's excess only while the other tyre is linear
                    if linear_share(fx[k, o], fz[k, o], alpha[0, a], float(mu4[0, o]), tabs) < cfg.q_gate:
                        continue
                    obs = slip_observation(abs(ex), fx[k, w], fz[k, w], alpha[0, a], tabs, cfg)
                    if obs is not None:
                        mu_side[side] += g_obs * (obs - mu_side[side])
                        seen[side] = True
            for side in range(2):
                if not seen[side]:
                    mu_side[side] += g_fgt * (cfg.mu - mu_side[side])
            p_road = min(p_road_max, p_road + q_road)  # the random walk, updated or not
            if (cfg.road and valid_run > valid_min and kin_run > kin_min and abs(u.ay[k]) >= cfg.ay_kin_gate
                    and mu_side.min() >= cfg.kin_side_min):
                h0, peak = kinematic_model(axle[k:k + 1], fz[k:k + 1], fx[k:k + 1], mu_road, tabs, cfg)
                h1, _ = kinematic_model(axle[k:k + 1], fz[k:k + 1], fx[k:k + 1], mu_road + cfg.kin_dmu, tabs, cfg)
                dh = min(cfg.kin_dh_max, max(-cfg.kin_dh_max, (h1 - h0) / cfg.kin_dmu))
                carried = mu_road * float(np.max(2.0 * np.abs(axle[k]) / np.maximum(peak, 1.0)))
                # the EKF's update is the RLS's on the linearised y = z - h(mu^) + H mu^ = H mu, without forgetting;
                # an innovation the model cannot explain at any nearby mu (its NIS beyond the gate) is not used
                if (z_lp - h0) ** 2 <= cfg.kin_nis_gate * (r_road + dh * p_road * dh):
                    mu_road, p_road = rls_step(mu_road, p_road, dh, z_lp - h0 + dh * mu_road, r_road, 1.0, q_road,
                                               p_road_max)
                mu_road = min(cfg.mu, max(cfg.mu_floor, carried, mu_road))
            elif not (valid_run > valid_min and abs(u.ay[k]) >= cfg.ay_kin_gate and kin_run == 0):
                # held while the car corners with no axle rolling free (still on the road it was measured on)
                mu_road += g_fgt * (cfg.mu - mu_road)
        out[k] = mu_side
        road[k] = mu_road
    return out, road


def implausible(u: tf.Inputs, mask: np.ndarray, skf: tf.SkfConfig, cfg: AdaptiveConfig,
                contra: np.ndarray | None = None) -> np.ndarray:
    """(n,) True where the car is outside what the estimator's model describes, and for ``hold_implausible``
    after: slower than vx_gate by its fastest wheel (v = r_w max ω_i), or sliding sideways, the body's
    lateral acceleration relative to its axes v̇_y = a_y − r v_x (the plant's own equation,
    docs/chassis_plant.md) beyond ``vyd_gate`` after a low-pass (τ_vyd): the single-track model's
    quasi-steady cornering (|v̇_y| ≤ 2.7 m/s² on every shipped and stress run, 0.8 g steps included)
    against a car that spins (> 4 m/s² at a sideslip of 3°). Updated on steps whose inputs are valid."""
    n, ts = len(u), skf.ts
    a = ts / (cfg.tau_vyd + ts)
    hold = math.floor(cfg.hold_implausible / ts + 0.5)
    out = np.zeros(n, bool)
    all_valid = int(lib.VH_SKF_ALL_VALID)
    vyd, left = 0.0, 0
    for k in range(n):
        if (int(mask[k]) & all_valid) == all_valid:
            v = skf.rw * float(np.max(u.omega[k]))
            vyd += a * (u.ay[k] - u.r[k] * v - vyd)
            if v < cfg.vx_gate or abs(vyd) > cfg.vyd_gate:
                left = hold
            elif left > 0:
                left -= 1
        if contra is not None and contra[k]:  # a contradiction restarts the hold too
            left = hold
        out[k] = left > 0
    return out


C_VX, C_MASS, C_BOUNDS, C_BALANCE = 1, 2, 4, 8  # contradictions (vh_tfa.h VH_TFA_C_*)


def contradictions(u: tf.Inputs, mask: np.ndarray, base: tf.TireForceRun, mass: np.ndarray, fz: np.ndarray,
                   side: np.ndarray | None, road: np.ndarray | None, skf: tf.SkfConfig,
                   cfg: AdaptiveConfig) -> np.ndarray:
    """(n,) the published states that contradict a measurement, as bits: ``C_VX`` the SKFMEC's v_x outside the
    wheels' speed range [r_w min ω − tol, r_w max ω + tol], tol = vx_tol + vx_tol_rel r_w max ω (a braking or
    driving wheel slips by less; held while the inputs are not valid); ``C_MASS`` the mass at its clamp;
    ``C_BOUNDS`` a normal load below zero, or a friction estimate at its floor. (``C_BALANCE``, the mass
    against the longitudinal balance, comes from :func:`estimate_mass`.)"""
    n = len(u)
    out = np.zeros(n, np.uint8)
    valid = (mask.astype(int) & int(lib.VH_SKF_ALL_VALID)) == int(lib.VH_SKF_ALL_VALID)
    v = skf.rw * u.omega
    lo, hi = v.min(1), v.max(1)
    tol = cfg.vx_tol + cfg.vx_tol_rel * np.abs(hi)
    vx = base.x[:, 0]
    now = (vx > hi + tol) | (vx < lo - tol)
    held = False
    for k in range(n):  # held where not evaluated
        if valid[k]:
            held = bool(now[k])
        out[k] = C_VX if held else 0
    m0 = skf.m
    at_clamp = (mass <= cfg.mass_range[0] * m0 * (1 + 1e-12)) | (mass >= cfg.mass_range[1] * m0 * (1 - 1e-12))
    out[at_clamp] |= C_MASS
    bad = (fz < 0.0).any(1)
    if side is not None:
        bad |= (side <= cfg.mu_floor).any(1)
    if road is not None and cfg.road:
        bad |= road <= cfg.mu_floor
    out[bad] |= C_BOUNDS
    return out


class AdaptiveSkfmec:
    """SKFMEC-A over a drive (double): the SKFMEC (default configuration) and what it adds."""

    def __init__(self, config: tf.SkfConfig | None = None, adaptive: AdaptiveConfig | None = None):
        self.config = config or tf.SkfConfig.default(tf.SKFMEC)
        self.adaptive = adaptive or AdaptiveConfig()
        fixed_params(self.config, self.adaptive)  # the one validator of a configuration: the C host's

    def with_options(self, **kw) -> AdaptiveSkfmec:
        return AdaptiveSkfmec(self.config, replace(self.adaptive, **kw))

    def run(self, inputs: tf.Inputs, mask=None, ride: np.ndarray | None = None) -> AdaptiveRun:
        """``ride``: (n, 4) the springs' deflections [m] usable at each step, NaN rows elsewhere
        (:attr:`~vehest_can.systems.tireforce.report.DecodedInputs.ride`); None: no ride-height sensors."""
        cfg, skf = self.adaptive, self.config
        n = len(inputs)
        m = np.full(n, int(lib.VH_SKF_ALL_VALID), np.uint8) if mask is None else np.asarray(mask, np.uint8)
        base = tf.estimator(tf.SKFMEC, skf).run(inputs, m, covariances=True)
        ride_n = _ride(ride, n)
        balance = np.zeros(n, bool)
        if cfg.mass:
            mass, std = estimate_mass(inputs, base, m, skf, cfg, ride_n, balance)
        else:
            mass, std = np.full(n, skf.m), np.zeros(n)
        k = (mass / skf.m)[:, None]
        axle = np.c_[base.fy[:, :2].mean(1), base.fy[:, 2:].mean(1)] * k
        fz = base.fz * k
        if cfg.transfer and ride_n is not None:
            fz = ride_transfer(fz, axle, ride_n, skf, cfg)
        mu = road = side = None
        if cfg.split and (cfg.friction or cfg.combined or cfg.road):
            tabs = friction_tables(cfg)
            fx = wheel_forces(inputs, m, skf)
            if cfg.friction or cfg.road:
                side, road = estimate_friction(inputs, base, m, skf, cfg, fx, fz, axle, tabs)
                mu = effective_mu(side, road, cfg)
            mu4 = np.full((n, 4), cfg.mu) if mu is None else mu
            cap = ellipse(fx, fz, mu4, tabs, cfg) if cfg.combined else None
            fy = load_sensitive_split(axle, fz, cfg, mu=mu, cap=cap)
        elif cfg.split:
            fy = load_sensitive_split(axle, fz, cfg)
        else:
            fy = base.fy * k
        base_axle = np.c_[base.fy[:, :2].mean(1), base.fy[:, 2:].mean(1)]
        var_base = base.p[:, (5, 6), (5, 6)] / (np.asarray(skf.s)[5:] ** 2 if skf.scaled else 1.0)
        bound = tyre_bounds(fy, fz, axle, base_axle, var_base, k[:, 0], (std / skf.m) ** 2, cfg)
        base.p = None
        health = base.health.copy()
        unconverged = (std > cfg.mass_sigma_ok * skf.m) & (health == H_OK) & cfg.mass
        health[unconverged] = H_DEGRADED
        contra = contradictions(inputs, m, base, mass, fz, side, road, skf, cfg)
        contra[balance] |= C_BALANCE
        health[(health == H_OK) & implausible(inputs, m, skf, cfg, contra)] = H_DEGRADED
        health[(health == H_OK) & (bound > cfg.bound_max).any(1)] = H_DEGRADED
        return AdaptiveRun(x=base.x, fy=fy, fz=fz, health=health, resets=base.resets, mass=mass, mass_std=std,
                           mu=mu, road_mu=road, contra=contra, bound=bound)


STRESS_DIR = "stress"  # firmware_sim/scenarios/tireforce/stress/: scenarios of SKFMEC-A, not in any tuning


def _ride(ride, n: int) -> np.ndarray | None:
    if ride is None:
        return None
    r = np.asarray(ride, dtype=np.float64)
    if r.shape != (n, 4):
        raise ConfigError(f"ride must have shape ({n}, 4), got {r.shape}")
    return r


# ---- fixed point (c_core/tireforce/vh_tfa.c): its constants, made here (the host side) -----------

def config_to_c(cfg: AdaptiveConfig):
    """The ``vh_tfa_config_t`` of a configuration (its fields, for the C calibration function)."""
    c = ffi.new("vh_tfa_config_t *")
    for name in ("cda", "rho", "tau_lp", "decim", "ax_gate", "ay_gate", "vx_gate", "forget", "sigma_y",
                 "mass_sigma0", "mass_sigma_floor", "mass_sigma_ok", "tyre_fz_scale", "mu", "tau_slip", "fx_gate",
                 "q_gate", "tau_mu", "tau_mu_forget", "mu_floor", "ellipse_floor", "friction", "combined", "ride",
                 "spring_front", "spring_rear", "sigma_ride", "road", "tau_kin", "ay_kin_gate", "fx_free", "kin_q",
                 "kin_r_deg", "kin_sigma0", "kin_dmu", "kin_dh_max", "kin_side_min", "kin_nis_gate", "transfer",
                 "tyre_kz", "tau_vyd", "vyd_gate", "hold_implausible", "vx_tol", "vx_tol_rel", "bal_tol", "bal_tol_rel",
                 "bound_z", "bound_axle_abs", "bound_axle_rel", "bound_lt_abs", "bound_lt_rel", "bound_max"):
        setattr(c, name, getattr(cfg, name))
    c.mass_lo, c.mass_hi = cfg.mass_range
    for i, v in enumerate(cfg.tyre_a):
        c.tyre_a[i] = v
    for i, v in enumerate(cfg.tyre_b):
        c.tyre_b[i] = v
    c.tyre_model = cfg.tyre_model
    for i, v in enumerate(cfg.tyre_p):
        c.tyre_p[i] = v
    c.tyre_klt = cfg.tyre_klt
    return c


def fixed_params(skf: tf.SkfConfig, cfg: AdaptiveConfig):
    """The ``vh_tfa_params_t`` of a configuration, by the C calibration function (vh_tfa_host.c),
    the same one the ECU uses."""
    p = ffi.new("vh_tfa_params_t *")
    check(lib.vh_tfa_params_from_config(skf.to_c(), config_to_c(cfg), p), "SKFMEC-A constants")
    return p


class AdaptiveFixed:
    """SKFMEC-A in fixed point (``vh_tfa_t`` over ``vh_skfq_t``): the ECU's version."""

    def __init__(self, config: tf.SkfConfig | None = None, adaptive: AdaptiveConfig | None = None):
        self.config = config or tf.SkfConfig.default(tf.SKFMEC)
        self.adaptive = adaptive or AdaptiveConfig()
        self._skf = tf.TireForceFixed(self.config)
        self.params = fixed_params(self.config, self.adaptive)
        self._a = ffi.new("vh_tfa_t *")
        check(lib.vh_tfa_init(self._a, self.params), "SKFMEC-A fixed-point constants")

    @property
    def saturations(self) -> int:
        return int(self._a.sat) + self._skf.saturations

    def run(self, inputs: tf.Inputs, mask=None, ride: np.ndarray | None = None) -> AdaptiveRun:
        """As AdaptiveSkfmec.run; the ride heights quantised to Q.VH_TFA_FH (round half up, as the ECU's
        exact decoding of the raw signal)."""
        q = np.ascontiguousarray(self._skf.quantise(inputs), dtype=np.int32)
        n = len(q)
        m = np.full(n, int(lib.VH_SKF_ALL_VALID), np.uint8) if mask is None else np.array(mask, np.uint8)
        m[~np.all(np.isfinite(inputs.matrix()), axis=1)] = 0  # an integer cannot carry NaN (as TireForceFixed)
        r = _ride(ride, n)
        ride_ok = None if r is None else np.ascontiguousarray(np.all(np.isfinite(r), axis=1), np.uint8)
        rq = None if r is None else np.ascontiguousarray(
            np.floor(np.nan_to_num(r) * 2.0 ** lib.VH_TFA_FH + 0.5), dtype=np.int32)
        fy, fz = np.empty((n, 4), np.int32), np.empty((n, 4), np.int32)
        k, p, health = np.empty(n, np.int32), np.empty(n, np.int32), np.empty(n, np.uint8)
        bound = np.empty((n, 4), np.int32)
        sat0 = self.saturations
        ptr = tf._ptr
        lib.vh_tfa_run(self._a, self._skf._f, n, ptr(q, "int32_t *"), ptr(m, "uint8_t *"), ptr(rq, "int32_t *"),
                       ptr(ride_ok, "uint8_t *"), ptr(fy, "int32_t *"), ptr(fz, "int32_t *"), ptr(k, "int32_t *"),
                       ptr(p, "int32_t *"), ptr(health, "uint8_t *"), ptr(bound, "int32_t *"))
        fn = 2.0 ** -lib.VH_SKFQ_FN
        m0 = self.params.m_num / self.params.m_den  # the model mass as the ECU sends it (vh_tfa_params_from_config)
        return AdaptiveRun(x=np.zeros((n, 7)), fy=fy * fn, fz=fz * fn, health=health, resets=0,
                           saturations=self.saturations - sat0, mass=k * 2.0 ** -lib.VH_TFA_FK * m0,
                           mass_std=np.sqrt(p * 2.0 ** -lib.VH_TFA_FP) * m0, bound=bound * fn,
                           raw={"fy": fy, "fz": fz, "k": k, "p": p, "bound": bound})
