"""SKFMEC-A: the paper's SKFMEC with an online mass estimate and a load-sensitive split (double).

A second tyre-force variant beside the paper's SKFMEC (which stays as it is, the baseline). It runs
the SKFMEC unchanged and adds, per step (docs/skfmec.md, "SKFMEC-A"):

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
   Cα(Fz) = a3 sin(a4 atan(a5 Fz)), which grow less than the load, large ones as the friction limits.

Health: INIT while the SKFMEC is, DEGRADED until the mass estimate has converged (its standard
deviation below ``mass_sigma_ok`` of the model mass) or whenever the SKFMEC is DEGRADED; FAULT with it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

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
    mass: bool = True            # ablation switches
    split: bool = True


@dataclass
class AdaptiveRun(tf.TireForceRun):
    """A TireForceRun (x: the SKFMEC's states underneath; fy, fz, health: SKFMEC-A's) plus the mass."""

    mass: np.ndarray | None = None      # (n,) m̂ [kg]
    mass_std: np.ndarray | None = None  # (n,) its standard deviation [kg]
    raw: dict | None = None             # fixed point: the integers (fy, fz FN; k Q2.29; p Q1.30)


def lateral_force(alpha_deg: np.ndarray, fz: np.ndarray, cfg: AdaptiveConfig) -> np.ndarray:
    """The tyre's pure-slip lateral Magic Formula (Bakker, Nyborg & Pacejka 1987) at friction
    ``cfg.mu``, with the tyre's size factor: F = sc F_pub(α, Fz / sc). α in degrees, ≥ 0."""
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


def force_table(cfg: AdaptiveConfig) -> np.ndarray:
    """(N_FZ, N_ALPHA) lateral force [N] of the tyre at the knots (made off-line: the ECU's table)."""
    al, fz = np.meshgrid(np.arange(N_ALPHA) * ALPHA_STEP_DEG, np.arange(N_FZ) * FZ_STEP_N)
    tab = lateral_force(al, fz, cfg)
    tab[0] = 0.0
    return tab


def load_sensitive_split(axle: np.ndarray, fz: np.ndarray, cfg: AdaptiveConfig,
                         table: np.ndarray | None = None) -> np.ndarray:
    """Per-tyre forces from the (n, 2) axle means and (n, 4) loads: the one slip angle α per axle at
    which the two tyres' forces add up to the axle's, each tyre's force at it. The tyre's force is
    the table of its Magic Formula, linear between the knots (in load, then in α), so the pair's
    sum is piecewise linear in α and its inverse is exact: the first knot j where the sum reaches
    the axle's force, then linear between j - 1 and j (the fixed-point version does the same).
    Small forces share as the cornering stiffnesses (the first segment), large ones as the
    friction limits; beyond the pair's peak, as at the peak."""
    tab = force_table(cfg) if table is None else table
    out = np.empty_like(fz)
    rows = np.arange(len(fz))
    for a, (i, j) in enumerate(((0, 1), (2, 3))):
        f = []
        for w in (i, j):
            x = np.clip(fz[:, w] / FZ_STEP_N, 0.0, N_FZ - 1.0)
            iz = np.minimum(x.astype(int), N_FZ - 2)
            wz = (x - iz)[:, None]
            f.append(tab[iz] * (1.0 - wz) + tab[iz + 1] * wz)  # (n, N_ALPHA)
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
    return out


def rls_step(m_hat: float, p: float, phi: float, y: float, r_y: float, forget: float,
             p_floor: float, p_ceil: float) -> tuple[float, float]:
    """One scalar recursive-least-squares update of y = m φ with forgetting λ (Ljung & Söderström,
    *Theory and Practice of Recursive Identification*, 1983, ch. 2): K = P φ / (σ² + φ P φ),
    m̂ += K (y − φ m̂), P = (1 − K φ) P / λ, P kept in [P_floor, P_ceil]."""
    gain = p * phi / (r_y + phi * p * phi)
    return m_hat + gain * (y - phi * m_hat), min(p_ceil, max(p_floor, (1.0 - gain * phi) * p / forget))


def estimate_mass(u: tf.Inputs, base: tf.TireForceRun, mask: np.ndarray, skf: tf.SkfConfig,
                  cfg: AdaptiveConfig) -> tuple[np.ndarray, np.ndarray]:
    """m̂ and its std per step (held between the 100 Hz updates)."""
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
    for k in range(n):
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
        if (k + 1) % cfg.decim == 0:
            gated = (valid_run > 5 * cfg.tau_lp / ts and abs(phif) >= cfg.ax_gate
                     and abs(u.ay[k]) <= cfg.ay_gate and base.x[k, 0] >= cfg.vx_gate)
            if gated:
                m_hat, p = rls_step(m_hat, p, phif, yf, r_y, cfg.forget, p_floor, p_ceil)
                m_hat = min(hi, max(lo, m_hat))
        mass[k], std[k] = m_hat, math.sqrt(p)
    return mass, std


class AdaptiveSkfmec:
    """SKFMEC-A over a drive (double): the SKFMEC (default configuration) and what it adds."""

    def __init__(self, config: tf.SkfConfig | None = None, adaptive: AdaptiveConfig | None = None):
        self.config = config or tf.SkfConfig.default(tf.SKFMEC)
        self.adaptive = adaptive or AdaptiveConfig()

    def with_options(self, **kw) -> AdaptiveSkfmec:
        return AdaptiveSkfmec(self.config, replace(self.adaptive, **kw))

    def run(self, inputs: tf.Inputs, mask=None) -> AdaptiveRun:
        cfg, skf = self.adaptive, self.config
        n = len(inputs)
        m = np.full(n, int(lib.VH_SKF_ALL_VALID), np.uint8) if mask is None else np.asarray(mask, np.uint8)
        base = tf.estimator(tf.SKFMEC, skf).run(inputs, m)
        if cfg.mass:
            mass, std = estimate_mass(inputs, base, m, skf, cfg)
        else:
            mass, std = np.full(n, skf.m), np.zeros(n)
        k = (mass / skf.m)[:, None]
        axle = np.c_[base.fy[:, :2].mean(1), base.fy[:, 2:].mean(1)] * k
        fz = base.fz * k
        if cfg.split:
            fy = load_sensitive_split(axle, fz, cfg)
        else:
            fy = base.fy * k
        health = base.health.copy()
        unconverged = (std > cfg.mass_sigma_ok * skf.m) & (health == H_OK) & cfg.mass
        health[unconverged] = H_DEGRADED
        return AdaptiveRun(x=base.x, fy=fy, fz=fz, health=health, resets=base.resets, mass=mass, mass_std=std)


STRESS_DIR = "stress"  # firmware_sim/scenarios/chassis/stress/: scenarios of SKFMEC-A, not in any tuning


# ---- fixed point (c_core/tireforce/vh_tfa.c): its constants, made here (the host side) -----------

def config_to_c(cfg: AdaptiveConfig):
    """The ``vh_tfa_config_t`` of a configuration (its fields, for the C calibration function)."""
    c = ffi.new("vh_tfa_config_t *")
    for name in ("cda", "rho", "tau_lp", "decim", "ax_gate", "ay_gate", "vx_gate", "forget", "sigma_y",
                 "mass_sigma0", "mass_sigma_floor", "mass_sigma_ok", "tyre_fz_scale", "mu"):
        setattr(c, name, getattr(cfg, name))
    c.mass_lo, c.mass_hi = cfg.mass_range
    for i, v in enumerate(cfg.tyre_a):
        c.tyre_a[i] = v
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

    def run(self, inputs: tf.Inputs, mask=None) -> AdaptiveRun:
        q = np.ascontiguousarray(self._skf.quantise(inputs), dtype=np.int32)
        n = len(q)
        m = np.full(n, int(lib.VH_SKF_ALL_VALID), np.uint8) if mask is None else np.array(mask, np.uint8)
        m[~np.all(np.isfinite(inputs.matrix()), axis=1)] = 0  # an integer cannot carry NaN (as TireForceFixed)
        fy, fz = np.empty((n, 4), np.int32), np.empty((n, 4), np.int32)
        k, p, health = np.empty(n, np.int32), np.empty(n, np.int32), np.empty(n, np.uint8)
        sat0 = self.saturations
        ptr = tf._ptr
        lib.vh_tfa_run(self._a, self._skf._f, n, ptr(q, "int32_t *"), ptr(m, "uint8_t *"), ptr(fy, "int32_t *"),
                       ptr(fz, "int32_t *"), ptr(k, "int32_t *"), ptr(p, "int32_t *"), ptr(health, "uint8_t *"))
        fn = 2.0 ** -lib.VH_SKFQ_FN
        m0 = self.config.m
        return AdaptiveRun(x=np.zeros((n, 7)), fy=fy * fn, fz=fz * fn, health=health, resets=0,
                           saturations=self.saturations - sat0, mass=k * 2.0 ** -lib.VH_TFA_FK * m0,
                           mass_std=np.sqrt(p * 2.0 ** -lib.VH_TFA_FP) * m0, raw={"fy": fy, "fz": fz, "k": k, "p": p})
