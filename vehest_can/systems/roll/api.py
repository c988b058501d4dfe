"""The roll system's C (in ``vehest_can._native``) over numpy arrays: the UKF and the sliding-mode
controller in the float32 (ECU) and double (reference) builds of one source."""
from __future__ import annotations

import numpy as np

from vehest_can.native import ffi, lib

NX, NZ, NU, NS = lib.VH_ROLL_NX_, lib.VH_ROLL_NZ_, lib.VH_ROLL_NU_, lib.VH_ROLL_NS_
ALL_VALID = (1 << NZ) - 1
PRECISIONS = {"f32": np.float32, "f64": np.float64}
_CTYPE = {"f32": "float", "f64": "double"}

STATE_NAMES = ["vy", "r", "z", "vz", "phi", "p", "theta", "q",
               "zu_fl", "zu_fr", "zu_rl", "zu_rr", "vzu_fl", "vzu_fr", "vzu_rl", "vzu_rr", "d_knm",
               "dfz_fl_kn", "dfz_fr_kn", "dfz_rl_kn", "dfz_rr_kn"]
#: the variants (vh_roll_params_t.variant): the paper's UKF and the robust one (docs/roll.md)
VARIANTS = {"paper": lib.VH_ROLL_V_PAPER, "robust": lib.VH_ROLL_V_ROBUST}
MEAS_NAMES = (["ay"] + [f"azu_{w}" for w in ("fl", "fr", "rl", "rr")]
              + [f"dt_{w}" for w in ("fl", "fr", "rl", "rr")]
              + [f"ds_{w}" for w in ("fl", "fr", "rl", "rr")] + ["r"])


class RollError(Exception):
    """A parameter set the C refuses."""


def default_params():
    """A fresh ``vh_roll_params_t`` with the defaults (the 14-DOF plant's car)."""
    prm = ffi.new("vh_roll_params_t *")
    lib.vh_roll_params_default(prm)
    return prm


def params_dict(prm) -> dict:
    out = {}
    for name, fld in ffi.typeof(prm[0]).fields:
        v = getattr(prm, name)
        out[name] = list(v) if fld.type.kind == "array" else v
    return out


def car_fields(car) -> dict[str, float]:
    """The UKF's vehicle of a car (:class:`~vehest_can.carfile.CarFile`), as ``vh_roll_params_t`` fields (k_phi,
    c_phi per axle; the tyre's simplified model stays the default's)."""
    return {"ms": car.sprung_mass_kg, "ix": car.roll_inertia_kgm2, "iy": car.pitch_inertia_kgm2,
            "iz": car.yaw_inertia_kgm2, "lf": car.cg_to_front_axle_m, "lr": car.cg_to_rear_axle_m,
            "tf": car.half_track_front_m, "tr": car.half_track_rear_m, "h": car.cg_height_m,
            "hf": car.roll_centre_height_front_m, "hr": car.roll_centre_height_rear_m,
            "kphi_f": car.roll_stiffness("front"), "kphi_r": car.roll_stiffness("rear"),
            "cphi_f": car.roll_damping("front"), "cphi_r": car.roll_damping("rear"),
            "m_uf": car.unsprung_mass_front_kg, "m_ur": car.unsprung_mass_rear_kg,
            "k_f": car.spring_rate_front_n_per_m, "k_r": car.spring_rate_rear_n_per_m,
            "kt": car.tyre_stiffness_n_per_m, "ct": car.tyre_damping_ns_per_m}


def write_car(cfg, car) -> None:
    """A car into a ``vh_roll_app_config_t *``: the UKF's vehicle, the wheel radius, and the controller's
    model terms of eq. 27 from them (``vh_roll_smc_params_default``, as the app's default does)."""
    for k, v in car_fields(car).items():
        setattr(cfg.ukf, k, v)
    cfg.rw = car.wheel_radius_m
    lib.vh_roll_smc_params_default(ffi.addressof(cfg, "smc"), ffi.addressof(cfg, "ukf"))


def configure_variant(cfg, variant: str) -> None:
    """The UKF variant (``"paper"`` or ``"robust"``) into a ``vh_roll_app_config_t *``; the controller's
    defaults follow it (``vh_roll_smc_params_default``: the paper's law with the paper's UKF, the
    robust law with the robust one), so set the controller's own fields after this."""
    if variant not in VARIANTS:
        raise RollError(f"roll variant must be one of {sorted(VARIANTS)}, not {variant!r}")
    cfg.ukf.variant = VARIANTS[variant]
    lib.vh_roll_smc_params_default(ffi.addressof(cfg, "smc"), ffi.addressof(cfg, "ukf"))


def make_params(**over):
    prm = default_params()
    for k, v in over.items():
        if isinstance(v, (list, tuple, np.ndarray)):
            arr = getattr(prm, k)
            for i, x in enumerate(v):
                arr[i] = float(x)
        else:
            setattr(prm, k, v)
    return prm


def _fn(prec: str, name: str):
    return getattr(lib, f"{name}_{prec}")


def _ptr(prec: str, a: np.ndarray):
    return ffi.cast(f"{_CTYPE[prec]} *", ffi.from_buffer(a))


class Ukf:
    """One C UKF instance of precision ``prec`` ("f32" ECU build, "f64" reference build)."""

    def __init__(self, prm=None, prec: str = "f64"):
        self.prec = prec
        self.dtype = PRECISIONS[prec]
        self.prm = prm if prm is not None else default_params()
        self.c = ffi.new(f"vh_roll_ukf_{prec} *")
        if _fn(prec, "vh_roll_ukf_init")(self.c, self.prm) != 0:
            raise RollError("vh_roll_ukf_init refused the parameters")

    def reset(self):
        _fn(self.prec, "vh_roll_ukf_reset")(self.c)

    @property
    def x(self) -> np.ndarray:
        return np.array(list(self.c.x), dtype=self.dtype)

    @property
    def P(self) -> np.ndarray:
        return np.array(list(self.c.P), dtype=self.dtype).reshape(NX, NX)

    def set_state(self, x=None, P=None):
        if x is not None:
            for i, v in enumerate(np.asarray(x, float)):
                self.c.x[i] = v
        if P is not None:
            for i, v in enumerate(np.asarray(P, float).ravel()):
                self.c.P[i] = v

    def step(self, u, z, mask: int = ALL_VALID) -> int:
        u = np.ascontiguousarray(u, self.dtype)
        z = np.ascontiguousarray(z, self.dtype)
        return _fn(self.prec, "vh_roll_ukf_step")(self.c, _ptr(self.prec, u), _ptr(self.prec, z), mask)

    def f(self, x, u) -> np.ndarray:
        return self._model("vh_roll_model_f", NX, x, u)

    def h(self, x, u) -> np.ndarray:
        return self._model("vh_roll_model_h", NZ, x, u)

    def _model(self, name: str, size: int, x, u) -> np.ndarray:
        """One of the C model functions (state transition f, measurement h) at (x, u): `size` values."""
        x = np.ascontiguousarray(x, self.dtype)
        u = np.ascontiguousarray(u, self.dtype)
        out = np.zeros(size, self.dtype)
        _fn(self.prec, name)(self.c, _ptr(self.prec, x), _ptr(self.prec, u), _ptr(self.prec, out))
        return out

    def run(self, u: np.ndarray, z: np.ndarray, mask: np.ndarray | None = None):
        """n steps over arrays u (n, NU), z (n, NZ), mask (n,) of valid bits. Returns
        (x (n, NX), P diagonal (n, NX), health (n,))."""
        u = np.ascontiguousarray(u, self.dtype)
        z = np.ascontiguousarray(z, self.dtype)
        n = len(u)
        if u.shape != (n, NU) or z.shape != (n, NZ):
            raise ValueError(f"u must be (n, {NU}) and z (n, {NZ})")
        xo = np.zeros((n, NX), self.dtype)
        po = np.zeros((n, NX), self.dtype)
        ho = np.zeros(n, np.uint32)
        mp = ffi.NULL
        if mask is not None:
            mask = np.ascontiguousarray(mask, np.uint32)
            mp = ffi.cast("uint32_t *", ffi.from_buffer(mask))
        _fn(self.prec, "vh_roll_ukf_run")(self.c, n, _ptr(self.prec, u), _ptr(self.prec, z), mp,
                                         _ptr(self.prec, xo), _ptr(self.prec, po),
                                         ffi.cast("uint32_t *", ffi.from_buffer(ho)))
        return xo, po, ho


def default_smc_params(prm=None):
    c = ffi.new("vh_roll_smc_params_t *")
    lib.vh_roll_smc_params_default(c, prm if prm is not None else default_params())
    return c


class Smc:
    """One C sliding-mode roll controller."""

    def __init__(self, sprm=None, prec: str = "f64"):
        self.prec = prec
        self.sprm = sprm if sprm is not None else default_smc_params()
        self.c = ffi.new(f"vh_roll_smc_{prec} *")
        if _fn(prec, "vh_roll_smc_init")(self.c, self.sprm) != 0:
            raise RollError("vh_roll_smc_init refused the parameters")

    def step(self, phi, p, ay, est_health, active=True, d=0.0) -> tuple[float, float, int]:
        """One step; `d` the estimated roll-moment disturbance [N m] (the robust variant's)."""
        h = _fn(self.prec, "vh_roll_smc_step")(self.c, phi, p, ay, d, est_health, 1 if active else 0)
        return self.c.m_f, self.c.m_r, h

    def run(self, phi, p, ay, est_health, active=True, d=None):
        """Arrays in, (m_f, m_r, health, s) arrays out."""
        n = len(phi)
        out = np.zeros((n, 2))
        hs = np.zeros(n, np.uint32)
        ss = np.zeros(n)
        act = np.broadcast_to(np.asarray(active), (n,))
        eh = np.broadcast_to(np.asarray(est_health), (n,))
        dd = np.zeros(n) if d is None else np.broadcast_to(np.asarray(d, float), (n,))
        fn = _fn(self.prec, "vh_roll_smc_step")
        for k in range(n):
            hs[k] = fn(self.c, float(phi[k]), float(p[k]), float(ay[k]), float(dd[k]), int(eh[k]), int(bool(act[k])))
            out[k] = (self.c.m_f, self.c.m_r)
            ss[k] = self.c.s
        return out[:, 0], out[:, 1], hs, ss
