"""Tire lateral force estimators (seed 000) over numpy arrays: SKFMEC (double), SKFMEC (fixed point,
the ECU's version) and the plain EKF baseline.

All three run the ECU's own C (``c_core/src/vh_skf.c``, ``vh_skfq.c``); this module only marshals
arrays. ``skf_ref.py`` is the independent numpy implementation. ``synthetic_manoeuvre`` makes
test drives with a simple nonlinear vehicle until the 14-DOF plant is available.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from ...errors import ConfigError
from ...native import check, ffi, lib

SKFMEC = "skfmec"
EKF = "ekf"
FIXED = "skfmec-fixed"
VARIANTS = (SKFMEC, FIXED, EKF)
_VARIANT_C = {SKFMEC: lib.VH_SKF_SKFMEC, FIXED: lib.VH_SKF_SKFMEC, EKF: lib.VH_SKF_EKF}
STATES = ("vx", "vy", "r", "phi", "p", "fyf", "fyr")
WHEELS = ("FL", "FR", "RL", "RR")
_VEC = {"s": 7, "q": 7, "p0": 7, "r": 4, "gp": 7, "gy": 2}


@dataclass
class SkfConfig:
    """Estimator configuration (``vh_skf_config_t``); defaults come from the C core."""

    m: float
    ms: float
    iz: float
    ix: float
    lf: float
    lr: float
    h: float
    e: float
    hf: float
    hr: float
    kphif: float
    kphir: float
    cphif: float
    cphir: float
    rw: float
    iw: float
    tf: float
    tr: float
    g: float
    zeta1: float
    zeta2: float
    lt_gain: float
    ts: float
    tau_wdot: float
    s: tuple
    q: tuple
    p0: tuple
    r: tuple
    gp: tuple
    gy: tuple
    p_cap: float
    p_max: float
    x_max: float
    scaled: bool = True
    mec: bool = True

    @classmethod
    def default(cls, variant: str = SKFMEC, **overrides) -> SkfConfig:
        if variant not in _VARIANT_C:
            raise ConfigError(f"estimator {variant!r}: expected one of {list(VARIANTS)}")
        c = ffi.new("vh_skf_config_t *")
        lib.vh_skf_config_default(c, _VARIANT_C[variant])
        cfg = cls.from_c(c)
        names = {f.name for f in fields(cls)}
        for key, value in overrides.items():
            if key not in names:
                raise ConfigError(f"unknown estimator setting {key!r}")
            setattr(cfg, key, tuple(float(v) for v in value) if key in _VEC else value)
        return cfg

    @classmethod
    def from_c(cls, c) -> SkfConfig:
        kw: dict[str, Any] = {}
        for f in fields(cls):
            v = getattr(c, f.name)
            kw[f.name] = tuple(v) if f.name in _VEC else (bool(v) if f.name in ("scaled", "mec") else float(v))
        return cls(**kw)

    def to_c(self, c=None):
        c = c if c is not None else ffi.new("vh_skf_config_t *")
        for f in fields(self):
            v = getattr(self, f.name)
            if f.name in _VEC:
                v = tuple(v)
                if len(v) != _VEC[f.name]:
                    raise ConfigError(f"{f.name}: expected {_VEC[f.name]} values, got {len(v)}")
                setattr(c, f.name, [float(x) for x in v])
            elif f.name in ("scaled", "mec"):
                setattr(c, f.name, int(bool(v)))
            else:
                setattr(c, f.name, float(v))
        return c


@dataclass
class Inputs:
    """One drive's sensor samples at the estimator step: (n,) arrays and (n, 4) wheel arrays."""

    ax: np.ndarray
    ay: np.ndarray
    r: np.ndarray
    p: np.ndarray
    delta: np.ndarray
    omega: np.ndarray
    torque: np.ndarray

    def __len__(self) -> int:
        return len(self.ax)

    def matrix(self) -> np.ndarray:
        """(n, 13) rows laid out as ``vh_skf_input_t``."""
        n = len(np.asarray(self.ax))
        cols = []
        for name in ("ax", "ay", "r", "p", "delta"):
            a = np.asarray(getattr(self, name), dtype=np.float64)
            if a.shape != (n,):
                raise ConfigError(f"{name} must have shape ({n},), got {a.shape}")
            cols.append(a[:, None])
        for name in ("omega", "torque"):
            a = np.asarray(getattr(self, name), dtype=np.float64)
            if a.shape != (n, 4):
                raise ConfigError(f"{name} must have shape ({n}, 4), got {a.shape}")
            cols.append(a)
        return np.ascontiguousarray(np.hstack(cols))

    def slice(self, a: int, b: int) -> Inputs:
        return Inputs(**{f.name: np.asarray(getattr(self, f.name))[a:b] for f in fields(self)})


@dataclass
class TireForceRun:
    x: np.ndarray          # (n, 7) physical: vx vy r phi p Fyf Fyr
    fy: np.ndarray         # (n, 4) per-tire lateral force FL FR RL RR (eq. 36-37)
    fz: np.ndarray         # (n, 4) normal loads (eq. 39)
    health: np.ndarray     # (n,) vh_health_t
    resets: int
    saturations: int = 0   # fixed point only: saturating operations that clipped during the run
    p: np.ndarray | None = None  # (n, 7, 7) covariance in filter coordinates, when asked for


def _ptr(a, t):
    return ffi.NULL if a is None else ffi.cast(t, ffi.from_buffer(a))


def _mask(mask, n):
    if mask is None:
        return None
    m = np.ascontiguousarray(mask, dtype=np.uint8)
    if m.shape != (n,):
        raise ConfigError(f"mask must have shape ({n},), got {m.shape}")
    return m


class TireForceKF:
    """SKFMEC or the plain EKF in double precision: one ``vh_skf_t``."""

    def __init__(self, config: SkfConfig | None = None, variant: str = SKFMEC):
        if variant == FIXED:
            raise ConfigError("the fixed-point estimator is TireForceFixed")
        self.config = config or SkfConfig.default(variant)
        self._f = ffi.new("vh_skf_t *")
        check(lib.vh_skf_init(self._f, self.config.to_c()), "tire force estimator configuration")

    def reset(self) -> None:
        lib.vh_skf_reset(self._f)

    @property
    def caps(self) -> int:
        return int(self._f.caps)

    def run(self, inputs: Inputs, mask=None, *, covariances: bool = False) -> TireForceRun:
        u = inputs.matrix()
        n = u.shape[0]
        m = _mask(mask, n)
        x, fy, fz = np.empty((n, 7)), np.empty((n, 4)), np.empty((n, 4))
        health = np.empty(n, dtype=np.uint8)
        p = np.empty((n, 7, 7)) if covariances else None
        resets = lib.vh_skf_run(self._f, n, _ptr(u, "double *"), _ptr(m, "uint8_t *"), _ptr(x, "double *"),
                                _ptr(fy, "double *"), _ptr(fz, "double *"), _ptr(p, "double *"),
                                _ptr(health, "uint8_t *"))
        return TireForceRun(x=x, fy=fy, fz=fz, health=health, resets=int(resets), p=p)


# --------------------------------------------------------------------------------------------
# Synthetic manoeuvres: a stand-in truth until the 14-DOF plant lands.
#
# 9 DOF (x, y, yaw, roll, 4 wheel spins) with the paper's rigid-body equations (eq. 29-30, the
# appendix sums) but *not* the monitoring model's shortcuts: tire forces from slip (a
# Magic-Formula-like curve with friction mu and a friction-circle limit), rigid-body load
# transfer with the half-tracks (twice eq. 39's lateral bracket, and the roll term with gravity's
# sign), a heavier vehicle than the estimator's. Integrated by RK4 at the estimator step.
# --------------------------------------------------------------------------------------------

VEHICLE = dict(m=1814.0, ms=1661.0, iz=2560.0, ix=580.0, lf=1.076, lr=1.617, h=0.55, e=0.48, hf=0.114,
               hr=0.004, kphif=108205.8, kphir=81436.7, cphif=826.8, cphir=658.9, rw=0.305, iw=2.0,
               tf=0.784, tr=0.760, g=9.81)
NOISE = dict(ax=0.05, ay=0.05, r=0.002, p=0.003, omega=0.02, torque=1.0)


def _ramp(t, t0, t1, a, b):
    if t <= t0:
        return a
    if t >= t1:
        return b
    return a + (b - a) * (t - t0) / (t1 - t0)


def paper_profile(t):
    """Sec. 4: steer 1 deg then 2 deg, brake 60 Nm front / 40 Nm rear, friction 1.1 -> 0.2."""
    delta = math.radians(_ramp(t, 0.5, 1.0, 0.0, 1.0) + _ramp(t, 3.0, 3.5, 0.0, 1.0))
    b = 1.0 if t >= 1.5 else 0.0
    return delta, (-60 * b, -60 * b, -40 * b, -40 * b), _ramp(t, 5.5, 5.7, 1.1, 0.2)


def ramp_profile(t):
    """Sec. 3.1: steer 0 -> 4 deg over 10 s, no brake, dry road."""
    return math.radians(_ramp(t, 0.0, 10.0, 0.0, 4.0)), (0.0, 0.0, 0.0, 0.0), 1.1


def sine_profile(t):
    """0.5 Hz, 2 deg sine steer with a light drive torque, dry road."""
    return math.radians(2.0 * math.sin(2 * math.pi * 0.5 * t)) if t > 0.5 else 0.0, (20.0, 20.0, 0.0, 0.0), 1.1


PROFILES = {"paper": paper_profile, "ramp": ramp_profile, "sine": sine_profile}


def synthetic_manoeuvre(profile="paper", duration=8.0, ts=5e-4, v0=70 / 3.6, dm=200.0, seed=0, noise=True):
    """Simulate a drive. Returns (truth dict, Inputs): truth has t, x (n,7 with Fyf/Fyr the axle
    averages), fy, fz, fx (n,4) wheel-frame tire forces, mu."""
    prof = PROFILES[profile] if isinstance(profile, str) else profile
    p = VEHICLE
    m, ms = p["m"] + dm, p["ms"] + dm
    lf, lr, h, e, tf, tr, g, rw, iw = (p[k] for k in ("lf", "lr", "h", "e", "tf", "tr", "g", "rw", "iw"))
    l = lf + lr
    kphi, cphi = p["kphif"] + p["kphir"], p["cphif"] + p["cphir"]
    kf = p["kphif"] / kphi
    ixx = p["ix"] + ms * e * e
    det = m * ixx - (ms * e) ** 2

    def forces(s, delta, mu, acc):
        vx, vy, r, phi = s[0], s[1], s[2], s[3]
        ax, ay = acc
        dfx = m * h * ax / (2 * l)
        roll_m = m * ay * h + ms * g * e * math.sin(phi)
        latf, latr = kf * roll_m / (2 * tf), (1 - kf) * roll_m / (2 * tr)
        fz0f, fz0r = m * g * lr / (2 * l), m * g * lf / (2 * l)
        fz = [max(v, 0.0) for v in (fz0f - dfx - latf, fz0f - dfx + latf, fz0r + dfx - latr, fz0r + dfx + latr)]
        fx, fy = [0.0] * 4, [0.0] * 4
        for i in range(4):
            front, side = i < 2, (1.0 if i % 2 == 0 else -1.0)  # left wheels at y = +t
            vxi = vx - side * (tf if front else tr) * r
            vyi = vy + (lf if front else -lr) * r
            d = delta if front else 0.0
            vw = vxi * math.cos(d) + vyi * math.sin(d)
            vlat = -vxi * math.sin(d) + vyi * math.cos(d)
            alpha = -math.atan2(vlat, max(abs(vw), 0.5))
            kap = (s[5 + i] * rw - vw) / max(abs(vw), 0.5)
            dmax = mu * fz[i] * (1.0 - 0.08 * fz[i] / 5000.0)
            fy0 = dmax * math.sin(1.3 * math.atan(10.0 * alpha))
            fx0 = dmax * math.sin(1.6 * math.atan(12.0 * kap))
            tot = math.hypot(fx0, fy0)
            if tot > dmax > 0.0:
                fx0, fy0 = fx0 * dmax / tot, fy0 * dmax / tot
            fx[i], fy[i] = fx0, fy0
        return fx, fy, fz

    def deriv(s, delta, tq, mu, acc):
        vx, vy, r, phi, pp = s[:5]
        fx, fy, fz = forces(s, delta, mu, acc)
        c, sn = math.cos(delta), math.sin(delta)
        sfyf = sum(fx[i] * sn + fy[i] * c for i in (0, 1))
        sfx = sum(fx[i] * c - fy[i] * sn for i in (0, 1)) + fx[2] + fx[3]
        sfy = sfyf + fy[2] + fy[3]
        smz = (lf * sfyf - lr * (fy[2] + fy[3]) + tf * (-(fx[0] * c - fy[0] * sn) + (fx[1] * c - fy[1] * sn))
               + tr * (fx[3] - fx[2]))
        smx = p["hf"] * sfyf + p["hr"] * (fy[2] + fy[3]) - kphi * phi - cphi * pp
        g1, g4 = sfy - m * r * vx, smx + ms * e * r * vx
        d = np.empty(9)
        d[0] = (sfx + m * r * vy - ms * e * pp * r) / m
        d[1] = (ixx * g1 + ms * e * g4) / det
        d[2] = smz / p["iz"]
        d[3] = pp
        d[4] = (ms * e * g1 + m * g4) / det
        d[5:] = [(tq[i] - fx[i] * rw) / iw for i in range(4)]
        return d, fx, fy, fz

    n = int(round(duration / ts))
    s = np.array([v0, 0.0, 0.0, 0.0, 0.0] + [v0 / rw] * 4)
    acc = (0.0, 0.0)
    tr_ = {k: np.empty((n,) + sh) for k, sh in dict(t=(), x=(7,), fy=(4,), fz=(4,), fx=(4,), mu=()).items()}
    meas = {k: np.empty((n,) + sh) for k, sh in dict(ax=(), ay=(), r=(), p=(), delta=(), omega=(4,),
                                                       torque=(4,)).items()}
    for k in range(n):
        t = k * ts
        delta, tq, mu = prof(t)
        k1, fx, fy, fz = deriv(s, delta, tq, mu, acc)
        ax, ay = k1[0] - s[2] * s[1], k1[1] + s[2] * s[0]
        tr_["t"][k], tr_["mu"][k] = t, mu
        tr_["x"][k] = [s[0], s[1], s[2], s[3], s[4], 0.5 * (fy[0] + fy[1]), 0.5 * (fy[2] + fy[3])]
        tr_["fy"][k], tr_["fz"][k], tr_["fx"][k] = fy, fz, fx
        meas["ax"][k], meas["ay"][k], meas["r"][k], meas["p"][k] = ax, ay, s[2], s[4]
        meas["delta"][k], meas["omega"][k], meas["torque"][k] = delta, s[5:], tq
        acc = (ax, ay)
        k2 = deriv(s + ts / 2 * k1, delta, tq, mu, acc)[0]
        k3 = deriv(s + ts / 2 * k2, delta, tq, mu, acc)[0]
        k4 = deriv(s + ts * k3, delta, tq, mu, acc)[0]
        s = s + ts / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    if noise:
        rng = np.random.default_rng(seed)
        for name, sigma in NOISE.items():
            meas[name] = meas[name] + rng.normal(0.0, sigma, meas[name].shape)
    return tr_, Inputs(**meas)


class TireForceFixed:
    """SKFMEC in fixed point (``vh_skfq_t``): the ECU's integer filter.

    Its integer constants come from the double configuration through the C calibration function
    (``vh_skfq_params_from_config``); inputs are quantised to the documented Q formats by the C core
    (round half up, saturating), outputs converted back to physical units here.
    """

    def __init__(self, config: SkfConfig | None = None):
        self.config = config or SkfConfig.default(SKFMEC)
        if not self.config.scaled:
            raise ConfigError("the fixed-point estimator runs scaled only (scaled=True)")
        self.params = ffi.new("vh_skfq_params_t *")
        check(lib.vh_skfq_params_from_config(self.config.to_c(), self.params), "fixed-point constants")
        self._f = ffi.new("vh_skfq_t *")
        check(lib.vh_skfq_init(self._f, self.params), "fixed-point estimator")

    def reset(self) -> None:
        lib.vh_skfq_reset(self._f)

    @property
    def saturations(self) -> int:
        return int(self._f.sat)

    @property
    def caps(self) -> int:
        return int(self._f.caps)

    @staticmethod
    def quantise(inputs: Inputs) -> np.ndarray:
        """(n, 13) int32 rows laid out as ``vh_skfq_input_t`` (the C core's own rounding)."""
        u = inputs.matrix()
        q = np.empty(u.shape, dtype=np.int32)
        lib.vh_skfq_quantise_inputs(u.shape[0], _ptr(u, "double *"), _ptr(q, "int32_t *"))
        return q

    def run_raw(self, q: np.ndarray, mask=None, *, covariances: bool = False) -> dict:
        """Run on quantised inputs; returns the raw integer outputs (x in Q.FX scaled, fy/fz in Q.FN)."""
        q = np.ascontiguousarray(q, dtype=np.int32)
        if q.ndim != 2 or q.shape[1] != 13:
            raise ConfigError(f"quantised inputs must have shape (n, 13), got {q.shape}")
        n = q.shape[0]
        m = _mask(mask, n)
        out = {"x": np.empty((n, 7), np.int32), "fy": np.empty((n, 4), np.int32), "fz": np.empty((n, 4), np.int32),
               "health": np.empty(n, np.uint8), "p": np.empty((n, 7, 7), np.int32) if covariances else None}
        sat0 = self._f.sat
        out["resets"] = int(lib.vh_skfq_run(self._f, n, _ptr(q, "int32_t *"), _ptr(m, "uint8_t *"),
                                            _ptr(out["x"], "int32_t *"), _ptr(out["fy"], "int32_t *"),
                                            _ptr(out["fz"], "int32_t *"), _ptr(out["p"], "int32_t *"),
                                            _ptr(out["health"], "uint8_t *")))
        out["saturations"] = int(self._f.sat - sat0)
        return out

    def run(self, inputs: Inputs, mask=None, *, covariances: bool = False) -> TireForceRun:
        """As TireForceKF.run. A row with a non-finite input gets an empty mask (the double filter's
        rule), since an integer cannot carry NaN: the quantiser saturates it."""
        u = inputs.matrix()
        bad = ~np.all(np.isfinite(u), axis=1)
        if bad.any():
            m = np.full(len(u), lib.VH_SKF_ALL_VALID, np.uint8) if mask is None else _mask(mask, len(u)).copy()
            m[bad] = 0
            mask = m
        raw = self.run_raw(self.quantise(inputs), mask, covariances=covariances)
        s = np.asarray(self.config.s)
        return TireForceRun(
            x=raw["x"] / 2.0 ** lib.VH_SKFQ_FX / s,
            fy=raw["fy"] / 2.0 ** lib.VH_SKFQ_FN,
            fz=raw["fz"] / 2.0 ** lib.VH_SKFQ_FN,
            health=raw["health"], resets=raw["resets"], saturations=raw["saturations"],
            p=None if raw["p"] is None else raw["p"] / 2.0 ** lib.VH_SKFQ_FP,
        )


def estimator(variant: str = SKFMEC, config: SkfConfig | None = None):
    """The estimator object for a variant name: 'skfmec', 'skfmec-fixed' or 'ekf'."""
    if variant == FIXED:
        return TireForceFixed(config)
    if variant in (SKFMEC, EKF):
        return TireForceKF(config, variant)
    raise ConfigError(f"estimator {variant!r}: expected one of {list(VARIANTS)}")
