"""Python API of the driveline Kalman filter (seed 001): the ECU's own C filter over numpy arrays.

The ECU firmware and this API share one C implementation (``c_core/driveline/vh_dkf.c``); this
module only marshals arrays. See ``dkf_ref.py`` for the independent numpy implementation.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ...errors import ConfigError
from ...native import check, config_class, ffi, from_c_default, lib

SPEEDS_TORQUE = "speeds+torque"
SPEEDS = "speeds"
_MEAS = {SPEEDS_TORQUE: lib.VH_DKF_SPEEDS_TORQUE, SPEEDS: lib.VH_DKF_SPEEDS}
_DISC = {"euler": lib.VH_DKF_EULER, "zoh": lib.VH_DKF_ZOH}


_C_CONFIG: Any = config_class(
    "vh_dkf_config_t", "DkfConfig", defaults=lambda c: lib.vh_dkf_config_default(c, _MEAS[SPEEDS_TORQUE]),
    enums={"meas": ("measurement set", _MEAS), "disc": ("discretisation", _DISC)}, flags=("use_input",))


class DkfConfig(_C_CONFIG):
    """Filter configuration, field for field ``vh_dkf_config_t`` (derived from the C struct:
    :func:`vehest_can.native.config_class`); defaults are the paper's (Table 1, sec. 4) for the
    measurement set, as the C core's ``vh_dkf_config_default`` writes them."""

    @classmethod
    def default(cls, meas: str = SPEEDS_TORQUE, **overrides) -> DkfConfig:
        if meas not in _MEAS:
            raise ConfigError(f"measurement set {meas!r}: expected one of {sorted(_MEAS)}")
        return from_c_default(cls, lambda c: lib.vh_dkf_config_default(c, _MEAS[meas]), overrides, "filter setting",
                              lambda _, v: tuple(v) if isinstance(v, (list, tuple, np.ndarray)) else v)


@dataclass
class DkfRun:
    x: np.ndarray       # (n, 4): w_o, w_w, T_o, T_Le
    k: np.ndarray | None  # (n, 4, 3) gains, when asked for
    p: np.ndarray | None  # (n, 4, 4) covariances, when asked for
    resets: int


class DrivelineKF:
    """One C filter instance (``vh_dkf_t``)."""

    def __init__(self, config: DkfConfig | None = None):
        self.config = config or DkfConfig.default()
        self._f = ffi.new("vh_dkf_t *")
        check(lib.vh_dkf_init(self._f, self.config.to_c()), "driveline filter configuration")

    @property
    def ad(self) -> np.ndarray:
        return np.frombuffer(ffi.buffer(self._f.ad), dtype=np.float64).reshape(4, 4).copy()

    @property
    def bd(self) -> np.ndarray:
        return np.frombuffer(ffi.buffer(self._f.bd), dtype=np.float64).copy()

    def reset(self) -> None:
        lib.vh_dkf_reset(self._f)

    def run(self, u, z, mask=None, *, gains: bool = False, covariances: bool = False) -> DkfRun:
        """Run len(u) steps: u (n,), z (n, 3) = [w_o, w_w, T_o], mask (n,) of VH_DKF_* bits."""
        u = np.ascontiguousarray(u, dtype=np.float64)
        z = np.ascontiguousarray(z, dtype=np.float64)
        n = u.shape[0]
        if z.shape != (n, 3):
            raise ConfigError(f"z must have shape ({n}, 3), got {z.shape}")
        m = None if mask is None else np.ascontiguousarray(mask, dtype=np.uint8)
        if m is not None and m.shape != (n,):
            raise ConfigError(f"mask must have shape ({n},), got {m.shape}")
        x = np.empty((n, 4))
        k = np.empty((n, 4, 3)) if gains else None
        p = np.empty((n, 4, 4)) if covariances else None

        def ptr(a, t):
            return ffi.NULL if a is None else ffi.cast(t, ffi.from_buffer(a))

        resets = lib.vh_dkf_run(
            self._f, n, ptr(u, "double *"), ptr(z, "double *"), ptr(m, "uint8_t *"),
            ptr(x, "double *"), ptr(k, "double *"), ptr(p, "double *"),
        )
        return DkfRun(x=x, k=k, p=p, resets=int(resets))


def turbine_torque(we, wt, we_min: float = 40.0) -> np.ndarray:
    """Eq. 9 over arrays through the ECU's C function; NaN where the input is not usable."""
    we = np.asarray(we, dtype=np.float64)
    wt = np.broadcast_to(np.asarray(wt, dtype=np.float64), we.shape)
    out = np.full(we.shape, np.nan)
    ti = ffi.new("double *")
    for i, (e, t) in enumerate(zip(we.ravel(), wt.ravel())):
        if lib.vh_dkf_turbine_torque(float(e), float(t), we_min, ti) == 0:
            out.flat[i] = ti[0]
    return out
