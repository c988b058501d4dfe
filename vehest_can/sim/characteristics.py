"""The plants' characteristic figures: the same car data in each plant of the 14-DOF car (ours, veh14,
and CommonRoad's multi-body model, commonroad_mb), driven through one quasi-steady-state manoeuvre
(constant speed, slow steer ramp), and the handling figures fitted in the linear range:

* roll gradient [deg/g]: roll φ against the lateral acceleration a_y;
* understeer gradient [deg/g]: δ − L r / v_x (steer minus the Ackermann angle) against a_y;
* steady lateral load transfer per axle [N/g], ΔF_z = (F_z,outer − F_z,inner) / 2, also as a fraction
  of a rigid car's per-axle value (the axle's static mass share m l_other / L, whole-car CG height
  h_cg, its half-track t: m_axle h_cg g / (2 t));
* the front share of the load transfer, ΔF_zf / (ΔF_zf + ΔF_zr).

Each figure is a least-squares line over the samples with |a_y| up to ``ay_max`` (its R² reported).
``vehest-can characterise`` prints them; the table measured on the paper car is in
``docs/chassis_plant.md``.

The car: the paper car with a scenario's ``[vehicle]`` overrides, as a ``vehicle`` dict of the keys of
that table (the interface a car data file feeds too); ``mass_delta_kg`` is the payload of each run.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ConfigError
from . import PLANTS

G = 9.81
#: a run's tick [s]
DT = 0.0005
#: ticks per recorded sample and speed-control update (5 ms: far faster than the quasi-steady ramp)
CHUNK = 10


@dataclass(frozen=True)
class Manoeuvre:
    """Constant speed, straight for ``settle_s``, then the road-wheel angle ramped 0 → ``steer_deg``
    over ``ramp_s`` on friction ``mu``; the figures fitted where |a_y| <= ``ay_max``."""

    speed_kmh: float = 80.0
    steer_deg: float = 4.0
    ramp_s: float = 20.0
    settle_s: float = 1.0
    mu: float = 1.0
    ay_max: float = 4.0

    @property
    def duration_s(self) -> float:
        return self.settle_s + self.ramp_s


@dataclass(frozen=True)
class Fit:
    slope: float
    intercept: float
    r2: float


@dataclass
class Figures:
    """One plant's figures for one payload (slopes per g of lateral acceleration)."""

    plant: str
    mass_delta_kg: float
    roll_gradient_deg_per_g: float
    understeer_gradient_deg_per_g: float
    load_transfer_front_n_per_g: float
    load_transfer_rear_n_per_g: float
    load_transfer_front_of_rigid: float   # ΔF_zf over m (l_r/L) h_cg g / (2 t_f)
    load_transfer_rear_of_rigid: float    # ΔF_zr over m (l_f/L) h_cg g / (2 t_r)
    load_transfer_front_share: float      # ΔF_zf / (ΔF_zf + ΔF_zr)
    r2: dict[str, float] = field(default_factory=dict)  # per fitted figure
    ay_fitted_m_s2: float = 0.0           # the largest |a_y| in the fit
    samples: int = 0
    speed_kmh_min: float = 0.0            # the speed held over the fit
    speed_kmh_max: float = 0.0
    car: dict[str, float] = field(default_factory=dict)  # m, h_cg, L, tracks: what the rigid values use
    car_name: str = "paper"  # the car file's


def fit_line(x: np.ndarray, y: np.ndarray) -> Fit:
    """Least-squares y = intercept + slope x, and its coefficient of determination."""
    a = np.column_stack([np.ones_like(x), x])
    (c0, c1), *_ = np.linalg.lstsq(a, y, rcond=None)
    res = y - (c0 + c1 * x)
    ss = float(np.sum((y - y.mean()) ** 2))
    return Fit(float(c1), float(c0), 1.0 - float(np.sum(res ** 2)) / ss if ss > 0 else math.nan)


def vehicle_from_toml(path: str | Path) -> dict[str, Any]:
    """The ``[vehicle]`` table of a scenario-like TOML file (only that table is read; its keys are
    checked when the runs are built)."""
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"{p}: no such file")
    try:
        doc = tomllib.loads(p.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{p}: not valid TOML: {exc}") from None
    vehicle = doc.get("vehicle")
    if not isinstance(vehicle, dict):
        raise ConfigError(f"{p}: has no [vehicle] table (the car's overrides of the paper car)")
    return dict(vehicle)


def scenario_doc(plant: str, mass_delta_kg: float, vehicle: dict[str, Any] | None, m: Manoeuvre,
                 car: str | None = None) -> dict:
    """The 14-DOF scenario document of the manoeuvre (drive torque 0: the run's speed control sets it);
    `car` a car file or shipped car's name (docs/car.md), None the paper's."""
    vehicle = dict(vehicle or {})
    if "mass_delta_kg" in vehicle:
        raise ConfigError("vehicle.mass_delta_kg: the payloads are the runs' own (--mass-delta-kg); "
                          "remove it from the car's overrides")
    ramp_end = m.settle_s + m.ramp_s
    return {"kind": "tireforce", "name": f"characterise_{plant}", "duration_s": ramp_end,
            "initial_speed_kmh": m.speed_kmh, "plant": plant,
            "driver": {"steer_deg": [[0.0, 0.0], [m.settle_s, 0.0], [ramp_end, m.steer_deg]]},
            "road": {"mu": [[0.0, m.mu]]},
            "vehicle": {**vehicle, "mass_delta_kg": mass_delta_kg},
            "sensors": {"ride_height": False}, **({"car": car} if car else {})}


def scenario(plant: str, mass_delta_kg: float = 0.0, vehicle: dict[str, Any] | None = None,
             manoeuvre: Manoeuvre = Manoeuvre(), source: str | Path = "<characterise>", car: str | None = None):
    """The validated ``Veh14Scenario`` of one run (errors name `source` and the key)."""
    from .veh14 import veh14_scenario_from_dict

    if plant not in PLANTS:
        raise ConfigError(f"unknown plant {plant!r}: one of {', '.join(PLANTS)}")
    return veh14_scenario_from_dict(scenario_doc(plant, mass_delta_kg, vehicle, manoeuvre, car), Path(source),
                                    "tireforce")


def _run(car, v_ref: float, prm) -> dict[str, np.ndarray]:
    """The car alone (no ECU) in chunks of CHUNK ticks, a PI speed controller setting the front
    wheels' drive torque for the next chunk (the car reads its inputs tick by tick, so the inputs
    written ahead are the ones it uses). Returns the truth at the end of each chunk."""
    from ..native import ffi, lib

    inputs = np.frombuffer(ffi.buffer(car._inputs), dtype=np.float64).reshape(car.n, 13)
    mass = prm.ms + 2.0 * prm.m_uf + 2.0 * prm.m_ur
    drag = 0.5 * prm.rho * prm.cda
    # PI on the speed error: 1/s and 0.3/s^2 hold the speed within a few 0.1 km/h against the tyres'
    # cornering drag, and are slow beside the tyres' and wheels' own dynamics
    kp, ki, integ = 1.0, 0.3, 0.0
    car.reset()
    keys = ("t", "vx", "r", "ay", "phi", "steer")
    out: dict[str, list] = {k: [] for k in (*keys, "fz")}
    vx = v_ref
    for k0 in range(0, car.n, CHUNK):
        err = v_ref - vx
        integ += err * CHUNK * DT
        force = drag * vx * abs(vx) + mass * (kp * err + ki * integ)
        inputs[k0:k0 + CHUNK, 1:3] = 0.5 * force * prm.rw  # front-wheel drive, as the paper car
        lib.vh_car_run(car.c, k0, min(CHUNK, car.n - k0))
        t = car.truth()
        for k in keys:
            out[k].append(float(t[k]))
        out["fz"].append(np.array(t["fz"], dtype=float))
        vx = out["vx"][-1]
    return {k: np.asarray(v) for k, v in out.items()}


def car_geometry(prm) -> dict[str, float]:
    """What the rigid-car values use, from the plant's parameters: whole mass, whole-car CG height
    (unsprung masses at the wheel centres), wheelbase, half-tracks."""
    m_u = 2.0 * prm.m_uf + 2.0 * prm.m_ur
    m = prm.ms + m_u
    return {"m_kg": m, "h_cg_m": (prm.ms * prm.h + m_u * prm.rw) / m, "wheelbase_m": prm.lf + prm.lr,
            "lf_m": prm.lf, "lr_m": prm.lr, "half_track_front_m": prm.tf, "half_track_rear_m": prm.tr}


def figures(run: dict[str, np.ndarray], prm, plant: str, mass_delta_kg: float, m: Manoeuvre) -> Figures:
    """The figures of one run: least squares over the ramp up to the first |a_y| > ay_max."""
    car = car_geometry(prm)
    big_l = car["wheelbase_m"]
    ay = run["ay"]
    on_ramp = run["t"] >= m.settle_s
    over = np.flatnonzero(on_ramp & (np.abs(ay) > m.ay_max))
    end = over[0] if over.size else len(ay)
    sel = np.flatnonzero(on_ramp[:end])
    if sel.size < 20 or np.ptp(ay[sel]) < 0.25 * m.ay_max:
        raise ConfigError(f"{plant}: the manoeuvre reaches only |a_y| = {np.max(np.abs(ay)):.2f} m/s^2: too little "
                          f"of the linear range (up to {m.ay_max:g}) to fit; steer more or drive faster")
    x = ay[sel] / G
    sign = 1.0 if np.mean(ay[sel]) >= 0 else -1.0  # right wheels outside in a left turn
    fz = run["fz"][sel]
    ackermann = big_l * run["r"][sel] / run["vx"][sel]
    fits = {
        "roll_gradient": fit_line(x, np.degrees(run["phi"][sel])),
        "understeer_gradient": fit_line(x, np.degrees(run["steer"][sel] - ackermann)),
        "load_transfer_front": fit_line(x, sign * 0.5 * (fz[:, 1] - fz[:, 0])),
        "load_transfer_rear": fit_line(x, sign * 0.5 * (fz[:, 3] - fz[:, 2])),
    }
    lt_f, lt_r = sign * fits["load_transfer_front"].slope, sign * fits["load_transfer_rear"].slope
    rigid_f = car["m_kg"] * prm.lr / big_l * car["h_cg_m"] * G / (2.0 * prm.tf)
    rigid_r = car["m_kg"] * prm.lf / big_l * car["h_cg_m"] * G / (2.0 * prm.tr)
    return Figures(plant=plant, mass_delta_kg=mass_delta_kg,
                   roll_gradient_deg_per_g=fits["roll_gradient"].slope,
                   understeer_gradient_deg_per_g=fits["understeer_gradient"].slope,
                   load_transfer_front_n_per_g=lt_f, load_transfer_rear_n_per_g=lt_r,
                   load_transfer_front_of_rigid=lt_f / rigid_f, load_transfer_rear_of_rigid=lt_r / rigid_r,
                   load_transfer_front_share=lt_f / (lt_f + lt_r),
                   r2={k: f.r2 for k, f in fits.items()}, ay_fitted_m_s2=float(np.max(np.abs(ay[sel]))),
                   samples=int(sel.size), speed_kmh_min=float(np.min(run["vx"][sel]) * 3.6),
                   speed_kmh_max=float(np.max(run["vx"][sel]) * 3.6), car=car)


def characterise(plant: str, mass_delta_kg: float = 0.0, vehicle: dict[str, Any] | None = None,
                 manoeuvre: Manoeuvre = Manoeuvre(), source: str | Path = "<characterise>",
                 car: str | None = None) -> Figures:
    """One plant's figures for the paper car with the `vehicle` overrides (keys of a scenario's
    ``[vehicle]`` table) and `mass_delta_kg` of payload. `source` names the overrides in errors."""
    from ..native import ffi, lib
    from .veh14 import Veh14Car

    sc = scenario(plant, mass_delta_kg, vehicle, manoeuvre, source, car)
    prm = sc.plant_params(ffi, lib)
    run = _run(Veh14Car(sc), manoeuvre.speed_kmh / 3.6, prm)
    return replace(figures(run, prm, plant, mass_delta_kg, manoeuvre), car_name=sc.car.name if sc.car else "paper")


def characterise_all(plants=PLANTS, payloads=(0.0, 200.0), vehicle: dict[str, Any] | None = None,
                     manoeuvre: Manoeuvre = Manoeuvre(), source: str | Path = "<characterise>",
                     cars: tuple[str | None, ...] = (None,)) -> list[Figures]:
    """Every car (car files or shipped names; None the paper's) on every plant with every payload."""
    return [characterise(p, dm, vehicle, manoeuvre, source, car) for car in cars for p in plants for dm in payloads]


#: the table's columns: (heading, format of a Figures)
_COLUMNS = (
    ("car", lambda f: f.car_name),
    ("plant", lambda f: f.plant),
    ("payload kg", lambda f: f"{f.mass_delta_kg:g}"),
    ("roll deg/g", lambda f: f"{f.roll_gradient_deg_per_g:.3f}"),
    ("understeer deg/g", lambda f: f"{f.understeer_gradient_deg_per_g:.3f}"),
    ("LT front N/g", lambda f: f"{f.load_transfer_front_n_per_g:.0f}"),
    ("LT rear N/g", lambda f: f"{f.load_transfer_rear_n_per_g:.0f}"),
    ("front/rigid", lambda f: f"{f.load_transfer_front_of_rigid:.3f}"),
    ("rear/rigid", lambda f: f"{f.load_transfer_rear_of_rigid:.3f}"),
    ("front share", lambda f: f"{f.load_transfer_front_share:.3f}"),
    ("R^2 roll", lambda f: f"{f.r2['roll_gradient']:.4f}"),
    ("R^2 US", lambda f: f"{f.r2['understeer_gradient']:.4f}"),
    ("R^2 LT", lambda f: f"{min(f.r2['load_transfer_front'], f.r2['load_transfer_rear']):.4f}"),
)


def table(rows: list[Figures]) -> list[str]:
    """The figures as text lines, one row per plant and payload."""
    cells = [[c[0] for c in _COLUMNS]] + [[fmt(f) for _, fmt in _COLUMNS] for f in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(_COLUMNS))]
    return ["  ".join(c.ljust(w) if i == 0 else c.rjust(w) for i, (c, w) in enumerate(zip(r, widths))).rstrip()
            for r in cells]


def to_json(rows: list[Figures], manoeuvre: Manoeuvre, vehicle: dict[str, Any] | None) -> dict:
    return {"manoeuvre": asdict(manoeuvre), "vehicle": dict(vehicle or {}), "figures": [asdict(f) for f in rows]}


__all__ = ["Manoeuvre", "Figures", "Fit", "PLANTS", "fit_line", "vehicle_from_toml", "scenario_doc", "scenario", "characterise",
           "characterise_all", "car_geometry", "figures", "table", "to_json"]
