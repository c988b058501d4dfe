"""Tire lateral force estimators (seed 000) over numpy arrays: SKFMEC (double), SKFMEC (fixed point,
the ECU's version) and the plain EKF baseline.

All three run the ECU's own C (``c_core/tireforce/vh_skf.c``, ``vh_skfq.c``); this module only marshals
arrays. ``reference.py`` is the independent numpy implementation; the truth they are checked
against is the 14-DOF chassis plant (``scenario.py``).
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from ...errors import ConfigError
from ...native import check, config_class, ffi, from_c_default, lib
from ...sim import WHEELS  # noqa: F401 - the per-wheel order of this API's arrays

SKFMEC = "skfmec"
EKF = "ekf"
FIXED = "skfmec-fixed"
VARIANTS = (SKFMEC, FIXED, EKF)
_VARIANT_C = {SKFMEC: lib.VH_SKF_SKFMEC, FIXED: lib.VH_SKF_SKFMEC, EKF: lib.VH_SKF_EKF}
STATES = ("vx", "vy", "r", "phi", "p", "fyf", "fyr")
_VEC = {"s": 7, "q": 7, "p0": 7, "r": 4, "gp": 7, "gy": 2}


_C_CONFIG: Any = config_class(
    "vh_skf_config_t", "SkfConfig", defaults=lambda c: lib.vh_skf_config_default(c, _VARIANT_C[SKFMEC]),
    flags=("scaled", "mec"))


class SkfConfig(_C_CONFIG):
    """Estimator configuration, field for field ``vh_skf_config_t`` (derived from the C struct:
    :func:`vehest_can.native.config_class`); defaults are the C core's (``vh_skf_config_default``)."""

    @classmethod
    def default(cls, variant: str = SKFMEC, **overrides) -> SkfConfig:
        if variant not in _VARIANT_C:
            raise ConfigError(f"estimator {variant!r}: expected one of {list(VARIANTS)}")
        return from_c_default(cls, lambda c: lib.vh_skf_config_default(c, _VARIANT_C[variant]), overrides,
                              "estimator setting", lambda k, v: tuple(float(x) for x in v) if k in _VEC else v)

    @classmethod
    def for_car(cls, car, variant: str = SKFMEC, **overrides) -> SkfConfig:
        """The default configuration with a car's model (:func:`car_fields`); the paper's car gives the
        C default bit for bit."""
        return cls.default(variant, **car_fields(car), **overrides)


def car_fields(car) -> dict[str, float]:
    """The SKFMEC's vehicle of a car (:class:`~vehest_can.carfile.CarFile`), as ``vh_skf_config_t`` fields:
    m the total mass, e roll axis to sprung CG, k_phi and c_phi per axle, and zeta1, zeta2 of the model's
    own steady cornering (``vh_skf_zeta_steady``). What the ECU and the off-line references both write."""
    f = {"m": car.total_mass_kg, "ms": car.sprung_mass_kg, "iz": car.yaw_inertia_kgm2, "ix": car.roll_inertia_kgm2,
         "lf": car.cg_to_front_axle_m, "lr": car.cg_to_rear_axle_m, "h": car.cg_height_m, "e": car.roll_lever_m,
         "hf": car.roll_centre_height_front_m, "hr": car.roll_centre_height_rear_m,
         "kphif": car.roll_stiffness("front"), "kphir": car.roll_stiffness("rear"),
         "cphif": car.roll_damping("front"), "cphir": car.roll_damping("rear"), "rw": car.wheel_radius_m,
         "iw": car.wheel_inertia_kgm2, "tf": car.half_track_front_m, "tr": car.half_track_rear_m}
    c = ffi.new("vh_skf_config_t *")
    lib.vh_skf_config_default(c, lib.VH_SKF_SKFMEC)
    for k, v in f.items():
        setattr(c, k, v)
    z = ffi.new("double[2]")
    lib.vh_skf_zeta_steady(c, z, z + 1)
    f["zeta1"], f["zeta2"] = z[0], z[1]
    return f


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
