"""The powertrain car: the plant of seed 001 (engine, converter, gearbox, shafts, wheels) and its sensor
node DLS (``vh_dlsim_t``), with the four inspection accelerometers CIS of seed 002 clamped on when a
scenario carries them, driven by one throttle and gear per tick; and the scenarios that drive it
(their schema: ``docs/scenarios.md``).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from ..bus.frames import TICK_S
from ..errors import ScenarioError
from ..native import check, ffi, lib
from ..schema import Checker, Num
from .car import Car
from .scenario import DT, SCENARIO_TOP, ScenarioBase, _native, kind_checker, scenario_top

# ---- schema --------------------------------------------------------------------------------

_TOP: dict[str, Any] = {"kind": "string", **SCENARIO_TOP}
_TABLES = ("driver", "road", "vehicle", "sensors")

_DRIVER = {"gear": Num(0, 5, integer=True)}  # plus "throttle", a profile
_ROAD = {
    # TOML key -> (vh_dlp_params_t field, range)
    "roughness_std_nm": ("road_std", Num(0.0, 2000.0)),
    "roughness_bandwidth_hz": ("road_bw", Num(0.0, 500.0, lo_open=True)),
}
# [vehicle] overrides: TOML key -> (vh_dlp_params_t field, range). The ranges are physical
# plausibility; the plant itself then refuses combinations its fixed step cannot resolve.
_VEHICLE = {
    "output_inertia_kgm2": ("jo", Num(0.008, 1.0)),
    "vehicle_inertia_kgm2": ("jv", Num(10.0, 5000.0)),
    "final_drive_ratio": ("rd", Num(0.1, 1.0)),
    "shaft_stiffness_nm_per_rad": ("ks", Num(100.0, 100000.0)),
    "shaft_damping_nms_per_rad": ("cs", Num(0.0, 100.0)),
    "wheel_radius_m": ("rt", Num(0.15, 0.6)),
    "rolling_resistance": ("mu_r", Num(0.0, 0.1)),
    "air_density_kg_m3": ("rho", Num(0.0, 2.0)),
    "drag_coefficient": ("ca", Num(0.0, 2.0)),
    "frontal_area_m2": ("area", Num(0.0, 10.0)),
    "engine_inertia_kgm2": ("je", Num(0.02, 2.0)),
    "engine_peak_torque_nm": ("te_peak", Num(10.0, 1000.0)),
    "idle_speed_rad_s": ("w_idle", Num(40.0, 150.0)),
}
_GEAR_RATIO = Num(0.2, 3.0)  # each of vehicle.gear_ratios, w_o = R_i w_t
# [sensors] noise standard deviations: TOML key -> (vh_dls_config_t array, channel indices, range)
_SENSORS = {
    "out_shaft_speed_std_rad_s": ("noise_std", (0,), Num(0.0, 100.0)),
    "wheel_speed_std_rad_s": ("noise_std", (1, 2), Num(0.0, 100.0)),
    "shaft_torque_std_nm": ("noise_std", (3,), Num(0.0, 1000.0)),
    "engine_speed_std_rad_s": ("noise_std", (4,), Num(0.0, 100.0)),
    "turbine_speed_std_rad_s": ("noise_std", (5,), Num(0.0, 100.0)),
}


@dataclass(frozen=True)
class PowertrainScenario(ScenarioBase, node="vh_dls", truth="vh_dlp_truth_t", seed_salt=0x444C53, sensors=_SENSORS):
    """One validated powertrain scenario. Times in s, speeds in rad/s unless the name says otherwise."""

    gear: int
    throttle: tuple[tuple[float, float], ...]  # (t, value) points, t strictly increasing
    road_std_nm: float
    road_bandwidth_hz: float
    vehicle: tuple[tuple[str, Any], ...] = ()  # [vehicle] overrides as written (TOML key, value)
    sensors: tuple[tuple[str, float], ...] = ()  # every [sensors] key, defaults filled in
    path: Path | None = None

    def times(self) -> np.ndarray:
        """Time after each plant step: DT, 2 DT, ..., n_steps DT."""
        return (np.arange(self.n_steps) + 1) * DT

    def throttle_at(self, t) -> np.ndarray:
        """Throttle at times t: piecewise linear, held before the first and after the last point."""
        ts = np.array([p[0] for p in self.throttle], dtype=float)
        vs = np.array([p[1] for p in self.throttle], dtype=float)
        return np.interp(np.asarray(t, dtype=float), ts, vs)

    def plant_params(self, ffi, lib):
        """A ``vh_dlp_params_t *``: the plant's defaults with this scenario's road and vehicle."""
        prm = ffi.new("vh_dlp_params_t *")
        lib.vh_dlp_params_default(prm)
        prm.road_std = self.road_std_nm
        prm.road_bw = self.road_bandwidth_hz
        for key, value in self.vehicle:
            if key == "gear_ratios":
                for i, r in enumerate(value):
                    prm.ri[i] = r
            else:
                setattr(prm, _VEHICLE[key][0], value)
        return prm

    def inspection_devices(self, ffi, lib):
        """(``vh_cambernode_config_t[4]``, pose) of inspection devices clamped on, or None (none here)."""
        return None

    def make_plant(self, ffi, lib):
        """An initialised ``vh_dlp_t *`` at the initial speed in the scenario's gear."""
        p = ffi.new("vh_dlp_t *")
        if lib.vh_dlp_init(p, self.plant_params(ffi, lib), self.seed) != lib.VH_OK:
            raise ScenarioError(f"{self._where()}: vehicle: the plant refuses these parameters "
                                "(a mode too fast for its 0.5 ms step)")
        if self.initial_speed_kmh > 0.0:
            lib.vh_dlp_set_rolling(p, self.initial_speed_kmh / 3.6, self.gear)
        return p

    def _run(self, ffi, lib, plant, n: int, out) -> None:
        thr = np.ascontiguousarray(self.throttle_at(self.times()))
        lib.vh_dlp_run(plant, n, ffi.cast("double *", ffi.from_buffer(thr)), self.gear, out)


def truth_to_numpy(ffi, truth_array, n: int) -> np.ndarray:
    """Copy n ``vh_dlp_truth_t`` from a cffi array into a numpy record array."""
    from ..native import struct_array

    return struct_array("vh_dlp_truth_t", truth_array, n)



# ---- loading -------------------------------------------------------------------------------

def read_powertrain(doc: dict, path: str | Path, kind: str, tables: tuple[str, ...] = ()) -> tuple[Checker, dict]:
    """The checker and the fields of a powertrain scenario document of kind `kind`, which may have the
    extra `tables` (read by the caller)."""
    ffi, lib = _native()
    c = kind_checker(doc, path, (kind,), f'"{kind}"', missing=f'missing: a {kind} scenario starts with kind = "{kind}"')
    top = scenario_top(c, doc, _TOP, _TABLES + tables)

    if "driver" not in doc:
        c.fail("driver", "missing (required table with throttle and gear)")
    driver = c.table(doc["driver"], "driver", set(_DRIVER) | {"throttle"})
    for key in ("throttle", "gear"):
        if key not in driver:
            c.fail(f"driver.{key}", "missing (required)")
    throttle = c.profile(driver["throttle"], "driver.throttle", Num(0.0, 1.0))
    gear = c.number(driver["gear"], "driver.gear", _DRIVER["gear"])

    prm = ffi.new("vh_dlp_params_t *")
    lib.vh_dlp_params_default(prm)
    road = c.table(doc.get("road", {}), "road", _ROAD)
    road_v = {k: c.number(road[k], f"road.{k}", spec) if k in road else getattr(prm, field)
              for k, (field, spec) in _ROAD.items()}

    vehicle_doc = c.table(doc.get("vehicle", {}), "vehicle", set(_VEHICLE) | {"gear_ratios"})
    vehicle = []
    for k, v in vehicle_doc.items():
        if k == "gear_ratios":
            if not isinstance(v, list) or len(v) != 5:
                c.fail("vehicle.gear_ratios", "must be a list of 5 ratios R_i (gears 1..5, w_o = R_i w_t)")
            vehicle.append((k, tuple(c.number(r, f"vehicle.gear_ratios[{i}]", _GEAR_RATIO)
                                     for i, r in enumerate(v))))
        else:
            vehicle.append((k, c.number(v, f"vehicle.{k}", _VEHICLE[k][1])))

    cfg = ffi.new("vh_dls_config_t *")
    lib.vh_dls_config_default(cfg)
    sensors_doc = c.table(doc.get("sensors", {}), "sensors", _SENSORS)
    sensors = tuple((k, c.number(sensors_doc[k], f"sensors.{k}", spec) if k in sensors_doc
                     else getattr(cfg, array)[chans[0]]) for k, (array, chans, spec) in _SENSORS.items())

    return c, dict(**top, gear=gear, throttle=throttle, road_std_nm=road_v["roughness_std_nm"],
                   road_bandwidth_hz=road_v["roughness_bandwidth_hz"], vehicle=tuple(sorted(vehicle)),
                   sensors=sensors, path=Path(path))


_P = TypeVar("_P", bound="PowertrainScenario")


def checked(c: Checker, sc: _P) -> _P:
    """sc, once the plant accepts its vehicle."""
    ffi, lib = _native()
    probe = ffi.new("vh_dlp_t *")
    if lib.vh_dlp_init(probe, sc.plant_params(ffi, lib), sc.seed) != lib.VH_OK:
        c.fail("vehicle", "the plant refuses this combination of parameters (a mode too fast for "
                          "its 0.5 ms step: raise the inertias or the gear ratios, or lower stiffness or damping)")
    return sc


def powertrain_scenario_from_dict(doc: dict, path: str | Path, kind: str) -> PowertrainScenario:
    """Validate an already parsed TOML document of kind `kind` (``path`` only names it in errors)."""
    c, fields = read_powertrain(doc, path, kind)
    return checked(c, PowertrainScenario(**fields))



# ---- the car ---------------------------------------------------------------------------------

class PowertrainCar(Car):
    """``vh_dlsim_t`` behind the car contract. ``throttle`` (in [0, 1]) and ``gear`` per tick may be
    changed between runs; each ``reset`` binds the car to them."""

    SECOC_NODES = ("DLS", "CIS")

    def __init__(self, name: str, throttle, gear, plant_params, plant_seed: int, node_config, *,
                 initial_speed: float = 0.0, devices: tuple | None = None):
        """`plant_params`: ``vh_dlp_params_t *``; `node_config`: ``vh_dls_config_t *``; `initial_speed`
        [m/s] > 0 starts rolling in gear[0]; `devices`: (``vh_cambernode_config_t[4]``, pose) of the
        inspection devices, or None."""
        super().__init__(name, len(throttle), "vh_dlp_truth_t")
        self.throttle = np.ascontiguousarray(throttle, dtype=np.float64)
        self.gear = np.ascontiguousarray(gear, dtype=np.uint8)
        self.initial_speed = initial_speed
        self.sim = ffi.new("vh_dlsim_t *")
        check(lib.vh_dlsim_init(self.sim, plant_params, plant_seed, node_config), "car set-up")
        if devices is not None:
            check(lib.vh_dlsim_set_camber(self.sim, *devices), "inspection devices")
        self.reset()

    def _start(self) -> None:
        self.throttle = np.ascontiguousarray(self.throttle, dtype=np.float64)
        self.gear = np.ascontiguousarray(self.gear, dtype=np.uint8)
        if len(self.gear) != len(self.throttle) or not len(self.throttle):
            raise ValueError(f"car {self.name}: throttle and gear need one value per tick, alike in number")
        self.n = len(self.throttle)
        lib.vh_dlsim_reset(self.sim)
        if self.initial_speed > 0:
            check(lib.vh_dlp_set_rolling(ffi.addressof(self.sim.plant), self.initial_speed, int(self.gear[0])),
                  "initial speed")
        lib.vh_dlsim_car(self.sim, ffi.from_buffer("double[]", self.throttle),
                         ffi.from_buffer("uint8_t[]", self.gear), len(self.throttle), self.c)

    def _attach_secoc(self) -> None:
        lib.vh_dlsim_set_secoc(self.sim, self.secoc["DLS"].c, self.secoc["CIS"].c)


def powertrain_car(scenario: PowertrainScenario, duration_s: float | None = None) -> PowertrainCar:
    """A powertrain scenario's car. A longer duration repeats the scenario's driver profile."""
    duration = scenario.duration_s if duration_s is None else duration_s
    n = int(round(duration / TICK_S))
    t = ((np.arange(n) + 1) * TICK_S) % scenario.duration_s  # the scenario's times(), repeated
    return PowertrainCar(scenario.name, scenario.throttle_at(t), np.full(n, scenario.gear, dtype=np.uint8),
                        scenario.plant_params(ffi, lib), scenario.seed, scenario.node_config(ffi, lib),
                        initial_speed=scenario.initial_speed_kmh / 3.6, devices=scenario.inspection_devices(ffi, lib))


__all__ = ["PowertrainScenario", "read_powertrain", "checked", "powertrain_scenario_from_dict", "PowertrainCar",
           "powertrain_car", "truth_to_numpy"]
