"""Tyre-force scenarios: TOML files of ``kind = "tireforce"`` that drive the 14-DOF car
(:mod:`vehest_can.sim.veh14`: the plant and its chassis sensor node); the schema is in
``docs/chassis_plant.md``. Shipped ones live in ``firmware_sim/scenarios/tireforce/``."""
from __future__ import annotations

from ...sim.scenario import Kind
from ...sim.veh14 import veh14_scenario_from_dict

KIND = Kind("tireforce", veh14_scenario_from_dict)
KINDS = (KIND.kind,)
_SHIPPED = KIND.shipped
tireforce_scenario_dir, list_tireforce_scenarios, tireforce_scenario_path = _SHIPPED.dir, _SHIPPED.names, _SHIPPED.path
tireforce_scenario_from_dict, load_tireforce_scenario = KIND.from_dict, KIND.load

__all__ = ["KIND", "KINDS", "load_tireforce_scenario", "tireforce_scenario_from_dict", "tireforce_scenario_dir",
           "tireforce_scenario_path", "list_tireforce_scenarios"]
