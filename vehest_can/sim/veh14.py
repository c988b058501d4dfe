"""The 14-DOF car: scenarios that drive the 14-DOF chassis plant (vh_veh14) and its chassis sensor node
(vh_chsnode), and the car they make (``vh_v14car_t``; with the ROLL node and the active roll actuators it
supervises where a system fits them). The systems of the chassis bus read their scenario files through
:func:`veh14_scenario_from_dict`; the schema is in ``docs/chassis_plant.md``.

:func:`veh14_scenario_from_dict` checks every key (unknown keys, types, ranges, time profiles, split-μ
consistency, and finally whether the plant accepts the vehicle) and raises
:class:`~vehest_can.errors.ScenarioError` naming the file, the dotted key and the problem.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..carfile import DATA_SHEET
from ..errors import ConfigError, ScenarioError
from ..schema import Checker, Num, type_name
from . import WHEELS
from .car import PLANTS, Car
from .scenario import DT, SCENARIO_TOP, ScenarioBase, _native, kind_checker, scenario_top

# ---- schema --------------------------------------------------------------------------------

_TOP: dict[str, Any] = {"kind": "string", "plant": "string", "car": "string", **SCENARIO_TOP}
_TABLES = ("driver", "road", "vehicle", "tyre", "sensors")

_STEER_DEG = Num(-30.0, 30.0)     # road-wheel angle; the plant clamps at 0.6 rad (34 deg)
_DRIVE_NM = Num(-5000.0, 5000.0)  # per wheel; negative is engine braking
_BRAKE_NM = Num(0.0, 10000.0)     # per wheel, a magnitude
_MU = Num(0.0, 2.0)

# [vehicle] overrides: TOML key -> (vh_v14_params_t field, range). Plausibility ranges; the plant then
# checks the combination (a roll stiffness the tyres can carry, springs softer in roll than k_phi, ...).
_VEHICLE = {
    **DATA_SHEET,
    # the paper's form of the roll stiffness and damping, per axle (a car file may give bars and dampers)
    "roll_stiffness_front_nm_per_rad": ("kphi_f", Num(1e3, 1e6)),
    "roll_stiffness_rear_nm_per_rad": ("kphi_r", Num(1e3, 1e6)),
    "roll_damping_front_nms_per_rad": ("cphi_f", Num(0.0, 1e5)),
    "roll_damping_rear_nms_per_rad": ("cphi_r", Num(0.0, 1e5)),
}
#: The true car is this much heavier than the paper's (the estimator's model): payload at the sprung CG.
_MASS_DELTA = Num(-500.0, 2000.0)
_TYRE = {
    "relaxation_length_x_m": ("relax_x", Num(0.0, 2.0)),
    "relaxation_length_y_m": ("relax_y", Num(0.0, 2.0)),
}
_TYRE_COEF = {"lateral_coefficients": "a", "longitudinal_coefficients": "b"}  # 9 numbers each
# [sensors]: TOML key -> (vh_chs_config_t array, channel indices, range)
_SENSORS = {
    "ax_std_m_s2": ("noise_std", (0,), Num(0.0, 10.0)),
    "ay_std_m_s2": ("noise_std", (1,), Num(0.0, 10.0)),
    "yaw_rate_std_rad_s": ("noise_std", (2,), Num(0.0, 1.0)),
    "roll_rate_std_rad_s": ("noise_std", (3,), Num(0.0, 1.0)),
    "steer_std_rad": ("noise_std", (4,), Num(0.0, 0.1)),
    "wheel_speed_std_rad_s": ("noise_std", (5, 6, 7, 8), Num(0.0, 10.0)),
    "wheel_torque_std_nm": ("noise_std", (9, 10, 11, 12), Num(0.0, 1000.0)),
    "ax_bias_m_s2": ("bias", (0,), Num(-10.0, 10.0)),
    "ay_bias_m_s2": ("bias", (1,), Num(-10.0, 10.0)),
    "yaw_rate_bias_rad_s": ("bias", (2,), Num(-1.0, 1.0)),
    "roll_rate_bias_rad_s": ("bias", (3,), Num(-1.0, 1.0)),
    "steer_bias_rad": ("bias", (4,), Num(-0.1, 0.1)),
    "wheel_speed_bias_rad_s": ("bias", (5, 6, 7, 8), Num(-10.0, 10.0)),
    "wheel_torque_bias_nm": ("bias", (9, 10, 11, 12), Num(-1000.0, 1000.0)),
    "ride_height_std_m": ("noise_std", (13, 14, 15, 16), Num(0.0, 0.01)),
    "ride_height_bias_m": ("bias", (13, 14, 15, 16), Num(-0.05, 0.05)),
}
_FLAGS = ("accel_gravity", "ride_height")  # [sensors] booleans


@dataclass(frozen=True)
class Veh14Scenario(ScenarioBase, node="vh_chs", truth="vh_v14_truth_t", seed_salt=0x434853, sensors=_SENSORS):
    """One validated 14-DOF scenario. Profiles are (t, value...) points, piecewise linear in time."""

    steer_deg: tuple[tuple[float, float], ...]
    drive_nm: tuple[tuple[float, ...], ...]      # (t, FL, FR, RL, RR)
    brake_nm: tuple[tuple[float, ...], ...]
    mu_left: tuple[tuple[float, float], ...]
    mu_right: tuple[tuple[float, float], ...]
    mass_delta_kg: float = 0.0
    vehicle: tuple[tuple[str, float], ...] = ()  # [vehicle] overrides as written
    tyre: tuple[tuple[str, Any], ...] = ()
    sensors: tuple[tuple[str, float], ...] = ()  # only the keys written
    accel_gravity: bool = False
    ride_height: bool = True                     # the car's ride-height sensors (CHS_RideHeight) fitted
    plant: str = "veh14"                         # one of PLANTS
    plant_fixed: bool = False                    # the file names its plant (the demo runs it on that one only)
    path: Path | None = None
    car: Any = None                              # the car it names (a vehest_can.carfile.CarFile); None: the paper's

    def with_plant(self, plant: str) -> Veh14Scenario:
        """The same run on another plant, named ``<name>@<plant>`` unless it is ours."""
        name = self.name.split("@")[0] + ("" if plant == "veh14" else f"@{plant}")
        return replace(self, plant=plant, plant_fixed=True, name=name)

    # ---- time and inputs ----

    def times(self) -> np.ndarray:
        """Sample time of each step: 0, DT, ..., (n_steps - 1) DT (the truth of step k is at k DT)."""
        return np.arange(self.n_steps) * DT

    @staticmethod
    def _interp(points, t, column: int = 1) -> np.ndarray:
        ts = np.array([p[0] for p in points], dtype=float)
        vs = np.array([p[column] for p in points], dtype=float)
        return np.interp(np.asarray(t, dtype=float), ts, vs)

    def steer_rad_at(self, t) -> np.ndarray:
        return np.radians(self._interp(self.steer_deg, t))

    def drive_at(self, t) -> np.ndarray:
        """Drive torque per wheel at times t: shape (len(t), 4)."""
        return np.stack([self._interp(self.drive_nm, t, 1 + w) for w in range(4)], axis=-1)

    def brake_at(self, t) -> np.ndarray:
        return np.stack([self._interp(self.brake_nm, t, 1 + w) for w in range(4)], axis=-1)

    def mu_at(self, t) -> np.ndarray:
        """Friction under each wheel: left wheels (FL, RL) see mu_left, right ones mu_right."""
        left, right = self._interp(self.mu_left, t), self._interp(self.mu_right, t)
        return np.stack([left, right, left, right], axis=-1)

    def input_array(self) -> np.ndarray:
        """Inputs of every step as an (n_steps, 13) float64 array laid out like ``vh_v14_input_t``."""
        t = self.times()
        return np.ascontiguousarray(np.column_stack(
            [self.steer_rad_at(t), self.drive_at(t), self.brake_at(t), self.mu_at(t)]))

    def inputs(self, ffi):
        """``vh_v14_input_t[n_steps]`` (cdata owning its memory)."""
        arr = self.input_array()
        if ffi.sizeof("vh_v14_input_t") != arr.shape[1] * 8:
            raise AssertionError("vh_v14_input_t is not 13 packed doubles")
        out = ffi.new("vh_v14_input_t[]", len(arr))
        ffi.memmove(out, arr.tobytes(), arr.nbytes)
        return out

    # ---- C structs ----

    def plant_params(self, ffi, lib):
        """``vh_v14_params_t *``: the scenario's car (the paper's unless it names one) with its overrides
        and extra mass."""
        if self.car is not None:
            prm = self.car.veh14_params(ffi, lib)
        else:
            prm = ffi.new("vh_v14_params_t *")
            lib.vh_v14_params_default(prm)
        for key, value in self.vehicle:
            setattr(prm, _VEHICLE[key][0], value)
        prm.ms += self.mass_delta_kg
        for key, value in self.tyre:
            if key in _TYRE_COEF:
                arr = getattr(prm.tyre, _TYRE_COEF[key])
                for i, v in enumerate(value):
                    arr[i] = v
            else:
                setattr(prm, _TYRE[key][0], value)
        return prm

    def node_config(self, ffi, lib):
        cfg = super().node_config(ffi, lib)
        cfg.accel_gravity = int(self.accel_gravity)
        cfg.ride_period = lib.VH_CHS_RIDE_PERIOD_DEFAULT if self.ride_height else 0
        return cfg

    def make_plant(self, ffi, lib):
        """An initialised ``vh_v14_t *`` rolling straight at the initial speed."""
        p = ffi.new("vh_v14_t *")
        if lib.vh_v14_init(p, self.plant_params(ffi, lib)) != lib.VH_OK:
            raise ScenarioError(f"{self._where()}: vehicle: the plant refuses these parameters")
        lib.vh_v14_set_rolling(p, self.initial_speed_kmh / 3.6)
        return p

    # ---- runs ----

    def _run(self, ffi, lib, plant, n: int, out) -> None:
        lib.vh_v14_run(plant, n, self.inputs(ffi), out)

    def run_truth(self, ffi, lib) -> np.ndarray:
        """The plant alone over the whole scenario (another plant than ours: through the car)."""
        return super().run_truth(ffi, lib) if self.plant == "veh14" else self.run_with_frames(ffi, lib)[0]

    def run_with_frames(self, ffi, lib):
        """The car (plant and sensor node, on this scenario's plant) tick by tick without an ECU:
        (truth record array, the node's frames in the order sent as (frame ID, payload): CHS_Sensors
        every tick, CHS_RideHeight every 10 ms where fitted)."""
        car = Veh14Car(self)
        truth = np.empty(car.n, dtype=car.truth_dtype)
        frames = []
        for k in range(car.n):
            frames += [(int(f.id), bytes(ffi.buffer(f.data, f.len))) for f in car.tick(k)]
            truth[k] = car.truth()
        return truth, frames


class Veh14Car(Car):
    """The 14-DOF plant and its chassis sensor node (``vh_v14car_t``) behind the car contract; with
    `actuators`, the ROLL node and the active roll actuators it supervises fitted too."""

    SECOC_NODES: tuple[str, ...] = ("CHS",)

    def __init__(self, sc: Veh14Scenario, duration_s: float | None = None, *, actuators=None):
        """`actuators`: (``vh_rln_config_t *``, ``vh_v14_arc_params_t[2]``, the driver's switch per tick)
        to fit the ROLL node and the actuators, or None."""
        from ..native import ffi, lib

        super().__init__(sc.name, sc.car_steps(duration_s), "vh_v14car_truth_t")
        self.truth_dtype = self.c_truth_dtype["plant"]
        self.scenario = sc
        self._inputs = sc.inputs(ffi)
        self.car = ffi.new("vh_v14car_t *")
        chs = sc.node_config(ffi, lib)
        rln_cfg, arc, active = (ffi.NULL, ffi.NULL, None) if actuators is None else actuators
        self._active: np.ndarray | None = None
        if actuators is not None:
            chs.ride_period = 0  # a car with the ROLL node sends no ride heights
            self._active = np.ascontiguousarray(active, dtype=np.uint8)
        prm = sc.plant_params(ffi, lib)
        if lib.vh_v14car_init(self.car, prm, sc.initial_speed_kmh / 3.6, chs, rln_cfg, arc) != lib.VH_OK:
            raise ScenarioError(f"{sc._where()}: the plant, its sensor nodes or its actuators refuse this scenario")
        self.mb = None
        if sc.plant == "commonroad_mb":
            from .mbplant import MbPlant, base_vehicle, mb_parameters

            klt = sc.car.lateral_compliance_m_per_n if sc.car is not None else None
            self.mb = MbPlant(mb_parameters(prm, base_vehicle(sc.car), klt), sc.initial_speed_kmh / 3.6,
                              drag=0.5 * prm.rho * prm.cda)
            self.mb.attach(self.car)
        self.reset()

    def _start(self) -> None:
        from ..native import ffi, lib

        if self.mb is not None:
            self.mb.reset()
        lib.vh_v14car_reset(self.car)
        active = ffi.NULL if self._active is None else ffi.from_buffer("uint8_t[]", self._active)
        lib.vh_v14car_car(self.car, self._inputs, active, self.n, self.c)

    def _attach_secoc(self) -> None:
        from ..native import ffi, lib

        lib.vh_chs_set_secoc(ffi.addressof(self.car, "chs"), self.secoc["CHS"].c)

    def truths(self, raw: np.ndarray) -> np.ndarray:
        return raw["plant"].copy()


def truth_to_numpy(ffi, truth_array, n: int) -> np.ndarray:
    """Copy n ``vh_v14_truth_t`` from a cffi array into a numpy record array."""
    from ..native import struct_array

    return struct_array("vh_v14_truth_t", truth_array, n)


# ---- loading -------------------------------------------------------------------------------

def _vector_profile(c: Checker, value, key: str, spec: Num) -> tuple[tuple[float, ...], ...]:
    """[[t, FL, FR, RL, RR], ...] with t strictly increasing."""
    return c.profile(value, key, spec, columns=WHEELS)


def veh14_scenario_from_dict(doc: dict, path: str | Path, kind: str) -> Veh14Scenario:
    """Validate an already parsed TOML document of kind `kind` (``path`` only names it in errors)."""
    ffi, lib = _native()
    c = kind_checker(doc, path, (kind,), f'"{kind}"', missing=f'missing: a {kind} scenario starts with kind = "{kind}"')
    top = scenario_top(c, doc, _TOP, _TABLES)

    if "driver" not in doc:
        c.fail("driver", "missing (required table with steer_deg)")
    driver = c.table(doc["driver"], "driver", {"steer_deg", "drive_nm", "brake_nm"})
    if "steer_deg" not in driver:
        c.fail("driver.steer_deg", "missing (required: [[time_s, road-wheel angle in degrees], ...])")
    steer = c.profile(driver["steer_deg"], "driver.steer_deg", _STEER_DEG)
    zero = ((0.0, 0.0, 0.0, 0.0, 0.0),)
    drive = _vector_profile(c, driver["drive_nm"], "driver.drive_nm", _DRIVE_NM) if "drive_nm" in driver else zero
    brake = _vector_profile(c, driver["brake_nm"], "driver.brake_nm", _BRAKE_NM) if "brake_nm" in driver else zero

    road = c.table(doc.get("road", {}), "road", {"mu", "mu_left", "mu_right"})
    split = [k for k in ("mu_left", "mu_right") if k in road]
    if "mu" in road and split:
        c.fail(f"road.{split[0]}", "give either mu (both sides) or mu_left and mu_right (split-mu), not both")
    if len(split) == 1:
        other = "mu_right" if split[0] == "mu_left" else "mu_left"
        c.fail(f"road.{other}", f"missing: split-mu needs both mu_left and mu_right ({split[0]} is given)")
    if split:
        mu_l = c.profile(road["mu_left"], "road.mu_left", _MU)
        mu_r = c.profile(road["mu_right"], "road.mu_right", _MU)
    else:
        mu_l = mu_r = c.profile(road["mu"], "road.mu", _MU) if "mu" in road else ((0.0, 1.0),)

    vehicle_doc = c.table(doc.get("vehicle", {}), "vehicle", set(_VEHICLE) | {"mass_delta_kg"})
    mass_delta = 0.0
    vehicle = []
    for k, v in vehicle_doc.items():
        if k == "mass_delta_kg":
            mass_delta = c.number(v, "vehicle.mass_delta_kg", _MASS_DELTA)
        else:
            vehicle.append((k, c.number(v, f"vehicle.{k}", _VEHICLE[k][1])))

    tyre_doc = c.table(doc.get("tyre", {}), "tyre", set(_TYRE) | set(_TYRE_COEF))
    tyre = []
    for k, v in tyre_doc.items():
        if k in _TYRE_COEF:
            if not isinstance(v, list) or len(v) != 9:
                c.fail(f"tyre.{k}", "must be a list of 9 Magic Formula coefficients (C, then 1..8 as published)")
            tyre.append((k, tuple(c.number(x, f"tyre.{k}[{i}]", Num(-1e6, 1e6)) for i, x in enumerate(v))))
        else:
            tyre.append((k, c.number(v, f"tyre.{k}", _TYRE[k][1])))

    sensors_doc = c.table(doc.get("sensors", {}), "sensors", set(_SENSORS) | set(_FLAGS))
    flags = {"accel_gravity": False, "ride_height": True}
    sensors = []
    for k, v in sensors_doc.items():
        if k in _FLAGS:
            if not isinstance(v, bool):
                c.fail(f"sensors.{k}", f"must be true or false, not {type_name(v)}")
            flags[k] = v
        else:
            sensors.append((k, c.number(v, f"sensors.{k}", _SENSORS[k][2])))

    plant = c.string(doc.get("plant", "veh14"), "plant")
    if plant not in PLANTS:
        c.fail("plant", f"unknown plant {plant!r}: one of {', '.join(PLANTS)}")
    if plant == "commonroad_mb":
        if split and mu_l != mu_r:
            c.fail("road.mu_left", "split friction: the commonroad_mb plant's tyre has one friction for all wheels")
        if tyre_doc:
            c.fail("tyre", "is the veh14 plant's tyre; the commonroad_mb plant keeps its own (remove the table)")
        _require_mb(c)
    car = None
    if "car" in doc:
        from ..carfile import load_car

        try:
            car = load_car(c.string(doc["car"], "car"), relative_to=Path(path).parent)
        except ScenarioError:
            raise
        except ConfigError as exc:
            c.fail("car", str(exc))

    sc = Veh14Scenario(**top, plant=plant, plant_fixed="plant" in doc, steer_deg=steer, drive_nm=drive, brake_nm=brake,
                         mu_left=mu_l, mu_right=mu_r, mass_delta_kg=mass_delta, vehicle=tuple(sorted(vehicle)),
                         tyre=tuple(sorted(tyre)), sensors=tuple(sorted(sensors)),
                         accel_gravity=flags["accel_gravity"], ride_height=flags["ride_height"], path=Path(path),
                         car=car)
    prm = sc.plant_params(ffi, lib)
    if tyre_doc.keys() & set(_TYRE_COEF) and prm.tyre.model == lib.VH_MFT_PAC2002:
        c.fail("tyre", "the car's tyre is a PAC2002 set (its car file): 1987 coefficients do not apply to it")
    if not prm.ms > 0:
        c.fail("vehicle.mass_delta_kg", f"leaves a sprung mass of {prm.ms:g} kg")
    if lib.vh_v14_init(ffi.new("vh_v14_t *"), prm) != lib.VH_OK:
        if tyre_doc.keys() & set(_TYRE_COEF) and not lib.vh_mft_check(ffi.addressof(prm, "tyre")):
            c.fail("tyre", "the Magic Formula coefficients do not give a peaked curve for loads up to "
                           "20 kN (need 1 < C < 2, D > 0, BCD > 0, E < 1)")
        c.fail("vehicle", "the plant refuses this combination: the roll stiffness must be below the tyres' "
                          "own (2 kt t^2), and the roll centres below the CG")
    if lib.vh_chs_init(ffi.new("vh_chs_t *"), sc.node_config(ffi, lib)) != lib.VH_OK:
        c.fail("sensors", "the sensor node refuses this configuration")
    return sc


def _require_mb(c: Checker) -> None:
    """The commonroad_mb plant needs its package and numba: a clear error where they are missing."""
    import importlib.util

    missing = [m for m in ("vehiclemodels", "numba") if importlib.util.find_spec(m) is None]
    if missing:
        c.fail("plant", f"commonroad_mb needs the Python packages {', '.join(missing)} "
                        "(pip install commonroad-vehicle-models numba)")


# ---- speed ----------------------------------------------------------------------------------

def bench(sc: Veh14Scenario, seconds: float = 10.0, repeats: int = 9) -> dict[str, float]:
    """The plant alone on the scenario's inputs, repeated to `seconds` (vh_v14_run in C, inputs
    prepared): best and median of `repeats`, CPU and wall time.

    On a shared machine the best of several runs is the figure of the code; the median shows the load.
    """
    ffi, lib = _native()
    n = int(round(seconds / DT))
    reps = int(math.ceil(n / sc.n_steps))
    inputs = np.tile(sc.input_array(), (reps, 1))[:n]
    cin = ffi.new("vh_v14_input_t[]", n)
    ffi.memmove(cin, inputs.tobytes(), inputs.nbytes)
    out = ffi.new("vh_v14_truth_t[]", n)
    wall, cpu = [], []
    for _ in range(repeats):
        p = sc.make_plant(ffi, lib)
        t0, c0 = time.perf_counter(), time.process_time()
        lib.vh_v14_run(p, n, cin, out)
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return {"simulated_s": n * DT, "steps": n,
            "x_real_time_cpu_best": n * DT / min(cpu), "x_real_time_cpu_median": n * DT / float(np.median(cpu)),
            "x_real_time_wall_median": n * DT / float(np.median(wall)),
            "us_per_step_cpu_best": min(cpu) / n * 1e6}


__all__ = ["DT", "WHEELS", "Veh14Scenario", "Veh14Car", "veh14_scenario_from_dict",
           "truth_to_numpy", "bench"]
