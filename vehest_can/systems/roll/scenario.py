"""Roll scenarios (``kind = "roll"``): the 14-DOF chassis plant with its active roll actuators, the
chassis sensor node and the roll node (vh_rollnode: roll sensors, actuator supervision, the driver's
mode switch), and the car they make.

A roll scenario is a 14-DOF scenario (``driver``, ``road``, ``vehicle``, ``tyre``, ``sensors``:
the plant and the chassis sensor node, read by :mod:`vehest_can.sim.veh14`) plus three tables of its
own, read here with the one schema reader (:mod:`vehest_can.schema`):

* ``[control] mode = [[t, "passive" | "active"], ...]``: the driver's switch over time (ROLL_ModeCmd),
  held from each point to the next;
* ``[actuators]``: per axle the roll-moment limit on the body, the rate limit, the lag (defaults of
  ``vh_v14_arc_params_default``: 4800 N m, 16 kN m/s, 30 ms; docs/roll.md);
* ``[roll_sensors]``: noise (per 2 kHz sample) and bias of the roll node's channels.

Shipped roll scenarios are in ``firmware_sim/scenarios/roll/``.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ...paths import ShippedSet
from ...schema import Num
from ...sim.scenario import DT, _native, derived_seed, kind_checker, load_shipped, set_channels
from ...sim.veh14 import Veh14Car, Veh14Scenario, veh14_scenario_from_dict

KINDS = ("roll",)
#: the tables a roll scenario adds to a 14-DOF scenario
_ROLL_TABLES = ("control", "actuators", "roll_sensors")
MODES = ("passive", "active")

# [actuators]: key -> (axle, vh_v14_arc_params_t field, range)
_ACTUATORS = {
    "moment_limit_front_nm": (0, "m_max", Num(0.0, 20000.0)),
    "moment_limit_rear_nm": (1, "m_max", Num(0.0, 20000.0)),
    "rate_limit_front_nm_per_s": (0, "rate_max", Num(1.0, 1e6)),
    "rate_limit_rear_nm_per_s": (1, "rate_max", Num(1.0, 1e6)),
    "lag_front_s": (0, "tau", Num(0.0, 1.0)),
    "lag_rear_s": (1, "tau", Num(0.0, 1.0)),
}
# [roll_sensors]: key -> (vh_rln_config_t array, channels, range); channels in the UKF's order
_AY, _AZU, _DT, _DS, _R = (0,), (1, 2, 3, 4), (5, 6, 7, 8), (9, 10, 11, 12), (13,)
_ROLL_SENSORS = {
    "lat_accel_std_m_s2": ("noise_std", _AY, Num(0.0, 10.0)),
    "wheel_accel_std_m_s2": ("noise_std", _AZU, Num(0.0, 50.0)),
    "tyre_deflection_std_m": ("noise_std", _DT, Num(0.0, 0.01)),
    "suspension_deflection_std_m": ("noise_std", _DS, Num(0.0, 0.01)),
    "yaw_rate_std_rad_s": ("noise_std", _R, Num(0.0, 1.0)),
    "lat_accel_bias_m_s2": ("bias", _AY, Num(-10.0, 10.0)),
    "wheel_accel_bias_m_s2": ("bias", _AZU, Num(-50.0, 50.0)),
    "tyre_deflection_bias_m": ("bias", _DT, Num(-0.05, 0.05)),
    "suspension_deflection_bias_m": ("bias", _DS, Num(-0.05, 0.05)),
    "yaw_rate_bias_rad_s": ("bias", _R, Num(-1.0, 1.0)),
}
#: the roll node's channels by name (for the dead / stuck sensor faults)
CHANNELS = ("lat_accel", "wheel_accel_fl", "wheel_accel_fr", "wheel_accel_rl", "wheel_accel_rr",
            "tyre_defl_fl", "tyre_defl_fr", "tyre_defl_rl", "tyre_defl_rr",
            "susp_defl_fl", "susp_defl_fr", "susp_defl_rl", "susp_defl_rr", "yaw_rate")


SCENARIOS = ShippedSet("scenarios/roll", "firmware_sim/scenarios/roll")
roll_scenario_dir, list_roll_scenarios, roll_scenario_path = SCENARIOS.dir, SCENARIOS.names, SCENARIOS.path


def _chassis_attr(name: str) -> Any:
    """A read-only attribute of a RollScenario that is its 14-DOF scenario's."""
    return property(lambda self: getattr(self.chassis, name), doc=f"The 14-DOF scenario's {name}.")


@dataclass(frozen=True)
class RollScenario:
    """A validated roll scenario: the car's part (a 14-DOF scenario) and the roll node's."""

    chassis: Veh14Scenario
    mode: tuple[tuple[float, str], ...]            # (t, "passive" | "active")
    actuators: tuple[tuple[str, float], ...] = ()  # only the keys written
    roll_sensors: tuple[tuple[str, float], ...] = ()

    # name, description, length, file and plant: the 14-DOF scenario's
    name = _chassis_attr("name")
    description = _chassis_attr("description")
    duration_s = _chassis_attr("duration_s")
    n_steps = _chassis_attr("n_steps")
    path = _chassis_attr("path")
    plant = _chassis_attr("plant")
    plant_fixed = _chassis_attr("plant_fixed")
    car = _chassis_attr("car")

    def active_at(self, t) -> np.ndarray:
        """The driver's switch at times t: True where active."""
        ts = np.array([p[0] for p in self.mode])
        on = np.array([p[1] == "active" for p in self.mode])
        i = np.searchsorted(ts, np.asarray(t, dtype=float), side="right") - 1
        return np.where(i >= 0, on[np.maximum(i, 0)], False)

    @property
    def active(self) -> bool:
        """Active at any time of the run."""
        return any(m == "active" for _, m in self.mode)

    def with_plant(self, plant: str) -> RollScenario:
        """The same run on another plant (Veh14Scenario.with_plant)."""
        return replace(self, chassis=self.chassis.with_plant(plant))

    def with_mode(self, mode: str) -> RollScenario:
        """The same run in one mode throughout (e.g. the passive twin of an active case)."""
        return replace(self, mode=((0.0, mode),))

    def arc_params(self, ffi, lib):
        arc = ffi.new("vh_v14_arc_params_t[2]")
        lib.vh_v14_arc_params_default(ffi.addressof(arc[0]))
        lib.vh_v14_arc_params_default(ffi.addressof(arc[1]))
        for key, value in self.actuators:
            axle, field, _ = _ACTUATORS[key]
            setattr(arc[axle], field, value)
        return arc

    @property
    def node_seed(self) -> int:
        """The roll node's random stream, derived from the scenario's seed (apart from the CHS node's)."""
        return derived_seed(self.chassis.seed, 0x524F4C4C)

    def node_config(self, ffi, lib):
        cfg = ffi.new("vh_rln_config_t *")
        lib.vh_rln_config_default(cfg)
        set_channels(cfg, self.roll_sensors, _ROLL_SENSORS)
        cfg.seed = self.node_seed
        cfg.mode_active = int(self.active_at(0.0))
        return cfg


def roll_truth_dtype() -> np.dtype:
    """The car's truth (``vh_v14car_truth_t``) with the plant's record flattened into it: the plant's
    fields, then the actuators' (applied and commanded moments, supervision state, the driver's switch)."""
    from ...native import struct_dtype

    car = struct_dtype("vh_v14car_truth_t")
    plant = car["plant"]
    return np.dtype([(n, plant.fields[n][0]) for n in plant.names]
                    + [(n, car.fields[n][0]) for n in car.names if n != "plant"])


class RollCar(Veh14Car):
    """The 14-DOF plant with its active roll actuators, the chassis sensor node and the roll node
    (``vh_v14car_t`` with the roll system fitted) behind the car contract. It listens: the ECU's
    frames reach the roll node, which applies a command from the tick after the one it arrived in."""

    SECOC_NODES: tuple[str, ...] = ("CHS", "ROLL")

    def __init__(self, sc: RollScenario, duration_s: float | None = None):
        ffi, lib = _native()
        self.roll_scenario = sc
        active = sc.active_at(np.arange(sc.n_steps) * DT)
        super().__init__(sc.chassis, duration_s, actuators=(sc.node_config(ffi, lib), sc.arc_params(ffi, lib), active))
        self.truth_dtype = roll_truth_dtype()
        self.node = ffi.addressof(self.car, "rln")  # its cfg (fail and stuck masks, bias) may change between ticks

    def _attach_secoc(self) -> None:
        super()._attach_secoc()
        _native()[1].vh_rln_set_secoc(self.node, self.secoc["ROLL"].c)

    def truths(self, raw: np.ndarray) -> np.ndarray:
        out = np.zeros(len(raw), dtype=self.truth_dtype)
        plant = raw["plant"]
        for name in out.dtype.names or ():
            out[name] = plant[name] if name in (plant.dtype.names or ()) else raw[name]
        return out


# ---- loading -------------------------------------------------------------------------------------

def load_roll_scenario(path: str | Path) -> RollScenario:
    return load_shipped(SCENARIOS, path, roll_scenario_from_dict)


def roll_scenario_from_dict(doc: dict, path: str | Path = "<scenario>") -> RollScenario:
    """Validate a parsed roll scenario (``path`` names it in errors)."""
    ffi, lib = _native()
    c = kind_checker(doc, path, KINDS, '"roll"')
    chassis = veh14_scenario_from_dict({k: v for k, v in doc.items() if k not in _ROLL_TABLES}, path, KINDS[0])

    control = c.table(doc.get("control", {}), "control", {"mode"})
    mode = c.profile(control.get("mode", [[0.0, "passive"]]), "control.mode", MODES, columns=("mode",))

    act_doc = c.table(doc.get("actuators", {}), "actuators", set(_ACTUATORS))
    actuators = tuple(sorted((k, c.number(v, f"actuators.{k}", _ACTUATORS[k][2])) for k, v in act_doc.items()))
    rs_doc = c.table(doc.get("roll_sensors", {}), "roll_sensors", set(_ROLL_SENSORS))
    roll_sensors = tuple(sorted((k, c.number(v, f"roll_sensors.{k}", _ROLL_SENSORS[k][2])) for k, v in rs_doc.items()))
    sc = RollScenario(chassis=chassis, mode=tuple(mode), actuators=actuators, roll_sensors=roll_sensors)
    arc = sc.arc_params(ffi, lib)
    if lib.vh_v14_arc_config(chassis.make_plant(ffi, lib), ffi.addressof(arc[0]), ffi.addressof(arc[1])) != lib.VH_OK:
        c.fail("actuators", "the plant refuses these actuator limits")
    if lib.vh_rln_init(ffi.new("vh_rln_t *"), sc.node_config(ffi, lib)) != lib.VH_OK:
        c.fail("roll_sensors", "the roll node refuses this configuration")
    return sc


__all__ = ["KINDS", "CHANNELS", "RollScenario", "RollCar", "load_roll_scenario", "roll_scenario_from_dict",
           "roll_scenario_dir", "roll_scenario_path", "list_roll_scenarios", "roll_truth_dtype"]
